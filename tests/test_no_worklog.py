"""The project speaks of itself only: no ticket or work-log numbers, branch or date tags.

Scans every tracked text file (code, docs, cases, benchmarks, CI) for words that say how
the project was developed rather than what it does: ticket numbers, work-session numbers
and tags (an ``s`` and two digits), calendar dates, "measured" followed by "to-day", and
commit hashes quoted as the
code's history. History lives in git; result files say what and how, not when.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SUFFIXES = {".py", ".md", ".toml", ".yml", ".yaml", ".txt", ".cfg", ".ini", ".sh"}

# Each pattern is assembled from parts so that this file does not match itself.
PATTERNS = {
    "ticket number": r"\b" + "issue" + r"s?\s*#?\d+",
    "work-session number": r"\b" + "session" + r"s?\s+\d+",
    "work-session tag": r"(?<![\w.])s(1\d|2\d)(?![\w.])",
    "this work session": r"\bthis " + "session" + r"\b",
    "date": r"\b20\d\d-[01]\d-[0-3]\d\b",
    "measured + today": r"\bmeasured " + "today" + r"\b",
    "commit quoted as history": r"\b(commit|main at)\s+[0-9a-f]{7,40}\b",
    "the ticket as a source": r"\bthe " + "issue" + r"('s| names| asks| says)\b",
}
REGEX = re.compile("|".join(f"(?P<g{i}>{p})" for i, p in enumerate(PATTERNS.values())), re.I)
NAMES = list(PATTERNS)


def tracked_text_files() -> list[Path]:
    try:
        out = subprocess.run(
            ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [ROOT / f for f in out.split() if Path(f).suffix in SUFFIXES]


def test_no_word_refers_to_how_the_project_was_developed():
    hits = []
    for path in tracked_text_files():
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            continue
        for number, line in enumerate(text.splitlines(), 1):
            for match in REGEX.finditer(line):
                kind = NAMES[int(match.lastgroup[1:])]
                rel = path.relative_to(ROOT)
                hits.append(f"{rel}:{number}: {kind}: {match.group(0)!r}")
    assert not hits, "\n".join(hits[:60]) + f"\n({len(hits)} in all)"


def _example(text: str) -> str:
    """A line of history written with a '|' inside its key word, so that this file itself
    holds none (the scan covers it too)."""
    return text.replace("|", "")


@pytest.mark.parametrize(
    "line, found",
    [
        (_example("see iss|ue 13"), True),
        (_example("(iss|ues 11, 14)"), True),
        (_example("re-measured in sess|ion 21"), True),
        (_example("--tag s|22-fma"), True),
        (_example("20|26-11-22 18:14"), True),
        (_example("was main at 52e|ef76"), True),
        (_example("the floor the iss|ue names"), True),
        ("an open issue of numba's tracker", False),
        ("A[6, 0] = 3.7109375e-2", False),
        ("the s-plane and 12 sessions of a sweep", False),
        ("K = 17.6, mu = 0.03", False),
    ],
)
def test_the_patterns_catch_what_they_should_and_only_that(line, found):
    assert "|" not in line
    assert bool(REGEX.search(line)) is found

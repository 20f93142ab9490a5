"""The first run on a machine: `rubcli run` with numba's cache empty, per method.

Run from the repository root: ``python benchmarks/compile_time.py`` (a few minutes).
Each method runs ``rubcli run cases/paper/fig3a.toml -m METHOD --periods 1`` in a fresh
process whose ``NUMBA_CACHE_DIR`` is a new empty directory, so that every kernel the
command needs is compiled (the solver's in the start-up, the energy balance's and the
CSV formatter's after the solve); then once more with that cache, as every later run
finds it. The table gives the wall time of both commands and the start-up the run
reports. With ``--source DIR --label NAME`` (repeatable) the CLI is imported from
another source tree (an older commit extracted with ``git archive``), the trees
alternating per method, as in ``end_to_end.py``. ``--method readme`` times the README's
first command as it stands (``rubcli run cases/paper/fig3a.toml``), ``--method orbits``
``rubcli orbits cases/paper/fig3-orbits.toml --quick`` (its flows' compiled loops). Writes
``benchmarks/compile_time[-TAG].md``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from end_to_end import LAUNCH  # the CLI imported from a given source tree
from machine import describe

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
CASE = "cases/paper/fig3a.toml"
ORBITS_CASE = "cases/paper/fig3-orbits.toml"
METHODS = ("analytic", "analytic-polar", "taylor", "dop853-jit", "rk45")


README = "readme"  # --method readme: the README's first command as it stands
ORBITS = "orbits"  # --method orbits: `rubcli orbits` on the paper's rub, --quick


def run_once(source: Path, method: str, cache: Path, out: Path) -> dict:
    """One `rubcli run` from ``source`` with ``cache`` as numba's cache dir; for the
    method ``readme``, `rubcli run cases/paper/fig3a.toml` as the README gives it (the
    case's methods, analytic and rk45, its 50 periods, its CSVs and figures)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    if method == README:
        args = ["run", CASE, "--out", str(out), "--force"]
    elif method == ORBITS:
        args = ["orbits", ORBITS_CASE, "--quick", "--out", str(out), "--force"]
    else:
        args = ["run", CASE, "-m", method, "--periods", "1", "--out", str(out), "--force"]
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", LAUNCH, str(source.resolve()), *args],
        cwd=ROOT, env=env, capture_output=True, text=True,
    )  # fmt: skip
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{method} from {source} failed:\n{proc.stderr[-2000:]}")
    if method == ORBITS:  # no start-up reported: the flows compile inside the command
        return {"wall_s": wall, "startup_s": float("nan")}
    report = json.loads((out / "report.json").read_text())
    entry = (
        next(iter(report["methods"].values())) if method == README else report["methods"][method]
    )
    return {"wall_s": wall, "startup_s": entry.get("startup_s", float("nan"))}


def _seconds(value: float, digits: int) -> str:
    """A start-up time as the table gives it ("-" where the command reports none)."""
    return "-" if value != value else f"{value:.{digits}f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", action="append",
                    help=f"default: all five; {README}: the README's command; {ORBITS}: "
                         f"rubcli orbits {ORBITS_CASE} --quick")  # fmt: skip
    ap.add_argument("--source", action="append", type=Path, help="source tree (default .)")
    ap.add_argument("--label", action="append", help="a name for each --source")
    ap.add_argument("--tag", default="", help="suffix of the output file")
    opts = ap.parse_args(argv)
    sources = opts.source or [ROOT]
    # the tree a label names, never a machine's path: "this tree" for the default
    labels = opts.label or ["this tree" if not opts.source else str(s) for s in sources]
    if len(labels) != len(sources):
        ap.error("give one --label per --source")
    methods = opts.method or list(METHODS)
    rows = []
    with tempfile.TemporaryDirectory(prefix="rubcli-compile-") as scratch:
        for method in methods:
            for source, label in zip(sources, labels, strict=True):
                cache = Path(scratch) / f"cache-{label}-{method}"
                out = Path(scratch) / "out"
                cold = run_once(source, method, cache, out)
                warm = run_once(source, method, cache, out)
                rows.append((method, label, cold, warm))
                print(
                    f"{method:15s} {label:10s} empty cache {cold['wall_s']:6.1f} s "
                    f"(start-up {cold['startup_s']:5.1f} s), cached {warm['wall_s']:5.2f} s "
                    f"(start-up {warm['startup_s']:.2f} s)",
                    flush=True,
                )
    command = "python benchmarks/compile_time.py" + (" " + " ".join(argv or sys.argv[1:])).rstrip()
    lines = [
        "# The first run on a machine: `rubcli run` with numba's cache empty",
        "",
        f"Command: `{command}`. {describe()}",
        "",
        f"`rubcli run {CASE} -m METHOD --periods 1` (method `{README}`: `rubcli run {CASE}` as "
        "the README gives it: analytic and rk45 over 50 periods, CSVs and figures; method "
        f"`{ORBITS}`: `rubcli orbits {ORBITS_CASE} --quick`), wall time of the whole command.",
        "",
        "| method | version | empty cache: wall s | start-up s | cached: wall s | start-up s |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for method, label, cold, warm in rows:
        cold_start, warm_start = _seconds(cold["startup_s"], 1), _seconds(warm["startup_s"], 2)
        lines.append(
            f"| {method} | {label} | {cold['wall_s']:.1f} | {cold_start} | "
            f"{warm['wall_s']:.2f} | {warm_start} |"
        )
    name = f"compile_time{'-' + opts.tag if opts.tag else ''}.md"
    (HERE / name).write_text("\n".join(lines) + "\n")
    print(f"wrote benchmarks/{name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Files rubcli did not write are never moved, replaced or removed, whatever the dir holds.

rubcli acts only on what it can prove is its own: a commit journal it signed with the
user's key, for that staging dir, naming files that are still the very ones it recorded;
an output dir whose manifest it can sign (no private place for the key: refused before
anything is computed); file names, never directories, in place of its outputs.
"""

from __future__ import annotations

import json
import os
import signal

import pytest

from .conftest import SMALL_CASE, fsize_limit, snapshot

STAGING = ".rubcli-staging-4242-planted"
JOURNAL = ".rubcli-journal.json"
# If a refused command went on to solve, this kills it: a refusal up front exits 2.
NO_SOLVE = {"at": "call:rubcli.solvers:solve", "do": "kill"}


def _hidden(directory) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.name.startswith("."))


def _users_files(out_dir) -> dict[str, bytes]:
    out_dir.mkdir()
    (out_dir / "thesis.tex").write_text("my thesis\n")
    (out_dir / "data.csv").write_text("t,x\n0,1\n")
    return snapshot(out_dir)


@pytest.mark.slow
@pytest.mark.parametrize(
    "journal",
    [
        {"pid": 1, "out": ["thesis.tex", "data.csv"], "in": []},
        {"pid": 1, "out": [], "in": ["thesis.tex"]},
        "not json",
    ],
    ids=["moves-out", "moves-in", "unreadable"],
)
def test_a_planted_commit_journal_moves_nothing(run_cli, case_file, out_dir, journal):
    """A staging dir with a journal rubcli did not sign, naming the user's files: the
    command refuses (exit 2, naming it) before anything else, and the dir, the staging
    dir and what it holds are left exactly as they were."""
    before = _users_files(out_dir)
    staging = out_dir / STAGING
    staging.mkdir()
    (staging / JOURNAL).write_text(journal if isinstance(journal, str) else json.dumps(journal))
    (staging / "thesis.tex").write_text("someone else's text\n")
    run = run_cli("run", case_file(), "--out", out_dir, "--force", fault=NO_SOLVE)
    assert run.code == 2, run.stderr
    assert f"{STAGING} holds a commit journal that rubcli did not sign" in run.stderr
    assert "nothing in the dir was moved or removed" in run.stderr
    assert snapshot(out_dir) == before
    assert sorted(os.listdir(staging)) == [JOURNAL, "thesis.tex"]
    assert _hidden(out_dir) == [STAGING]


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["no-mark", "mark-of-another-dir", "a-subdir"])
def test_a_staging_dir_rubcli_did_not_make_is_not_removed(
    run_cli, case_file, out_dir, previous, kind
):
    """A staging dir without a journal is removed only when its mark shows rubcli made
    it and it holds only staged files: a planted one, one holding a mark copied from
    another staging dir, or one holding more than files, is refused (exit 2, naming it)
    with everything in it kept."""
    case = case_file()
    previous(out_dir)
    staging = out_dir / STAGING
    if kind == "no-mark":
        staging.mkdir()
    else:
        fault = {"at": "call:rubcli.io:write_solution_csv", "do": "kill"}
        assert run_cli("run", case, "--out", out_dir, fault=fault).code == -signal.SIGKILL
        (made,) = [p for p in out_dir.iterdir() if p.name.startswith(".rubcli-staging-")]
        if kind == "a-subdir":
            made.rename(staging)
            (staging / "chapter").mkdir()
        else:
            staging.mkdir()
            os.rename(made / ".rubcli-staged.json", staging / ".rubcli-staged.json")
            made.rmdir()
    (staging / "thesis.tex").write_text("my thesis\n")
    left = snapshot(out_dir)
    held = sorted(os.listdir(staging))
    run = run_cli("run", case, "--out", out_dir, fault=NO_SOLVE)
    assert run.code == 2, run.stderr
    assert f"{STAGING} is a staging dir that rubcli cannot show it made" in run.stderr
    assert snapshot(out_dir) == left
    assert sorted(os.listdir(staging)) == held


@pytest.mark.slow
def test_a_genuine_journal_moved_to_another_staging_dir_is_refused(
    run_cli, case_file, out_dir, previous
):
    """A journal is signed for its own staging dir: the same journal under another
    staging dir's name is not rubcli's."""
    case = case_file()
    previous(out_dir)
    fault = {"at": "move:1", "do": "kill"}
    run = run_cli("run", case, "--out", out_dir, "-m", "dop853", fault=fault)
    assert run.code == -signal.SIGKILL
    (staging,) = [p for p in out_dir.iterdir() if p.name.startswith(".rubcli-staging-")]
    staging.rename(out_dir / STAGING)
    left = snapshot(out_dir)
    run = run_cli("run", case, "--out", out_dir, fault=NO_SOLVE)
    assert run.code == 2, run.stderr
    assert "journal that rubcli did not sign" in run.stderr
    assert snapshot(out_dir) == left


@pytest.mark.slow
def test_a_file_made_since_an_interrupted_commit_is_never_moved(
    run_cli, case_file, out_dir, previous
):
    """SIGKILL after a commit moved the old report.json out; the user then puts their own
    rk45.csv where the old one was (the commit would have moved it out as stale). The
    next command completes nothing it would have to move the user's file for: it
    refuses, naming the file, and moves nothing."""
    case = case_file()
    previous(out_dir)
    fault = {"at": "move:1", "do": "kill"}
    run = run_cli("run", case, "--out", out_dir, "-m", "dop853", fault=fault)
    assert run.code == -signal.SIGKILL
    (out_dir / "rk45.csv").unlink()
    (out_dir / "rk45.csv").write_text("my own numbers\n")
    left = snapshot(out_dir)
    run = run_cli("run", case, "--out", out_dir, fault=NO_SOLVE)
    assert run.code == 2, run.stderr
    refused = "cannot be completed: rk45.csv changed since it began; nothing was moved"
    assert refused in run.stderr
    assert snapshot(out_dir) == left
    assert (out_dir / "rk45.csv").read_text() == "my own numbers\n"


# ------------------------------------------------------- a directory in the way


@pytest.mark.slow
@pytest.mark.parametrize("force", [False, True], ids=["plain", "force"])
def test_a_directory_named_like_an_output_is_refused_up_front(
    run_cli, case_file, out_dir, previous, force
):
    """A dir called rk45.csv in a rubcli dir: refused before anything is computed, with a
    message that does not offer --force (which cannot replace a directory); its content
    is kept."""
    before = previous(out_dir)
    (out_dir / "rk45.csv").unlink()
    (out_dir / "rk45.csv").mkdir()
    (out_dir / "rk45.csv" / "notes.txt").write_text("mine\n")
    extra = ["--force"] if force else []
    run = run_cli("run", case_file(), "--out", out_dir, *extra, fault=NO_SOLVE)
    assert run.code == 2, run.stderr
    assert "rk45.csv is a directory, and this command writes a file of that name" in run.stderr
    assert "move it away" in run.stderr
    assert "pass --force" not in run.stderr
    assert (out_dir / "rk45.csv" / "notes.txt").read_text() == "mine\n"
    assert (out_dir / "report.json").read_bytes() == before["report.json"]


# ----------------------------------------------------------- the manifest key


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["world-writable", "a-file"])
def test_no_private_place_for_the_key_is_refused_before_computing(
    run_cli, case_file, out_dir, tmp_path, kind
):
    """An output dir rubcli cannot sign would be refused by the next command as not
    rubcli's: so it is not written at all; exit 2 before anything is computed, naming
    the state dir and what to do."""
    state = tmp_path / "state"
    if kind == "a-file":
        state.write_text("not a dir\n")
    else:
        state.mkdir()
        state.chmod(0o777)
    run = run_cli("run", case_file(), "--out", out_dir, env={"RUBCLI_STATE_DIR": str(state)},
                  fault=NO_SOLVE)  # fmt: skip
    assert run.code == 2, run.stderr
    assert "no private place for the key that signs rubcli's output dirs" in run.stderr
    assert str(state) in run.stderr and "RUBCLI_STATE_DIR" in run.stderr
    assert not out_dir.exists()


@pytest.mark.slow
def test_a_key_that_does_not_fit_on_its_disk_is_exit_74(run_cli, case_file, out_dir, tmp_path):
    """A new state dir on a full disk: the key cannot be written; exit 74 naming it,
    before anything is computed, and no output dir made."""
    state = tmp_path / "state"
    run = run_cli("run", case_file(), "--out", out_dir, env={"RUBCLI_STATE_DIR": str(state)},
                  preexec=fsize_limit(0), fault=NO_SOLVE)  # fmt: skip
    assert run.code == 74, run.stderr
    assert "no private place for the key that signs rubcli's output dirs" in run.stderr
    assert "File too large" in run.stderr
    assert not out_dir.exists() and os.listdir(state) == []


# --------------------------------------------------------------- the dir's name


@pytest.mark.slow
def test_a_nul_byte_in_the_output_dir_is_refused(run_cli, case_file):
    """`[output] dir` with a NUL byte: validate and run refuse it (exit 2, the field)."""
    case = case_file(SMALL_CASE.replace("plots = []", 'plots = []\ndir = "out\\u0000x"'))
    for command in ("validate", "run"):
        run = run_cli(command, case)
        assert run.code == 2, (command, run.stderr)
        assert "output.dir: holds a NUL byte" in run.stderr


def test_a_nul_byte_in_an_output_dir_of_the_library_is_refused(tmp_path):
    """The library's output dirs (``staged_output_dir``, ``open_output_dir``): an
    ``OutputError`` naming the problem, nothing made."""
    from rubcli import io

    for target in (tmp_path / "out\0x", f"{tmp_path}/a\0b/out"):
        with pytest.raises(io.OutputError, match="holds a NUL byte"):
            io.open_output_dir(target)
        with pytest.raises(io.OutputError, match="holds a NUL byte"), io.staged_output_dir(target):
            pass
    assert os.listdir(tmp_path) == []

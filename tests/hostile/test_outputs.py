"""Output dirs: committed as a whole, never a file rubcli did not write replaced or removed.

The rules (README "Outputs", rubcli/io/outputs.py): a run's files are staged inside the
output dir and moved in together (a move that fails is undone; a commit cut by SIGKILL is
completed by the next command on the dir); report.json carries a manifest signed with a
key private to the user, and only files it lists, byte for byte, are rubcli's: anything
else (a hand-made report.json, a user's file named like an output, an output edited
since) is refused unless --force, and never removed.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import signal
import sys

import pytest

from rubcli import io
from rubcli.io import outputs, signals

from .conftest import (
    ORBITS_CASE,
    SMALL_CASE,
    SWEEP_CASE,
    fsize_limit,
    snapshot,
    visible,
    wait_for,
)

GOOD = SMALL_CASE


def _hidden(directory) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.name.startswith("."))


def _consistent(directory) -> dict:
    report = json.loads((directory / "report.json").read_text())
    assert sorted(report["files"]) == visible(directory)
    return report


# ------------------------------------------------------------------ manifests


@pytest.mark.slow
def test_a_hand_made_report_json_deletes_nothing(run_cli, case_file, out_dir):
    """The audit's forgery: a report.json naming thesis.tex made a plain run delete it."""
    out_dir.mkdir()
    (out_dir / "thesis.tex").write_text("my thesis")
    (out_dir / "report.json").write_text('{"rubcli_version": "x", "files": ["thesis.tex"]}')
    run = run_cli("run", case_file(), "--out", out_dir)
    assert run.code == 2
    assert "thesis.tex" in run.stderr and "not written by rubcli" in run.stderr
    assert (out_dir / "thesis.tex").read_text() == "my thesis"
    run = run_cli("run", case_file(), "--out", out_dir, "--force")  # beside it, never over it
    assert run.code == 0, run.stderr
    assert (out_dir / "thesis.tex").read_text() == "my thesis"
    assert visible(out_dir) == ["report.json", "rk45.csv", "thesis.tex"]


@pytest.mark.slow
def test_a_manifest_edited_to_list_a_users_file_is_not_believed(
    run_cli, case_file, out_dir, previous
):
    """A genuine report.json whose manifest was edited to list thesis.tex with its true
    size and hash: the signature no longer matches, so nothing in the dir is rubcli's."""
    previous(out_dir)
    thesis = b"my thesis"
    (out_dir / "thesis.tex").write_bytes(thesis)
    report = json.loads((out_dir / "report.json").read_text())
    report["files"].append("thesis.tex")
    entry = {"size": len(thesis), "sha256": hashlib.sha256(thesis).hexdigest()}
    report["manifest"]["files"]["thesis.tex"] = entry
    (out_dir / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    other = case_file(GOOD.replace('methods = ["rk45"]', 'methods = ["dop853"]'), "b.toml")
    run = run_cli("run", other, "--out", out_dir)
    assert run.code == 2
    assert "signature does not match" in run.stderr
    assert (out_dir / "thesis.tex").read_bytes() == thesis


@pytest.mark.slow
def test_a_manifest_of_another_user_is_not_believed(run_cli, case_file, out_dir, previous,
                                                    tmp_path):  # fmt: skip
    """The same dir as read by another user (another key): none of its files are theirs."""
    previous(out_dir)
    other_key = tmp_path / "someone-else"
    run = run_cli("run", case_file(), "--out", out_dir, env={"RUBCLI_STATE_DIR": str(other_key)})
    assert run.code == 2
    assert "signed with another key" in run.stderr


@pytest.mark.slow
def test_a_users_file_named_like_an_output_is_never_replaced(run_cli, case_file, out_dir, previous):
    """A user's own dop853.csv in a rubcli dir: `-m dop853` refuses, naming it; --force
    replaces it."""
    previous(out_dir)
    (out_dir / "dop853.csv").write_text("my own numbers")
    run = run_cli("run", case_file(), "--out", out_dir, "-m", "dop853")
    assert run.code == 2
    assert "dop853.csv was not written by rubcli" in run.stderr and "--force" in run.stderr
    assert (out_dir / "dop853.csv").read_text() == "my own numbers"
    assert run_cli("run", case_file(), "--out", out_dir, "-m", "dop853", "--force").code == 0
    assert (out_dir / "dop853.csv").read_text().startswith("tau,")


@pytest.mark.slow
def test_an_output_edited_since_is_kept_and_named(run_cli, case_file, out_dir, previous):
    """An output the user edited is theirs: a rerun that does not write it keeps it (and
    says so), one that would replace it refuses."""
    case = case_file()
    previous(out_dir, "rk45", "dop853")
    with open(out_dir / "dop853.csv", "a") as handle:
        handle.write("# checked by hand\n")
    edited = (out_dir / "dop853.csv").read_bytes()
    run = run_cli("run", case, "--out", out_dir, "-m", "dop853")
    assert run.code == 2 and "dop853.csv was changed since rubcli wrote it" in run.stderr
    run = run_cli("run", case, "--out", out_dir, "-m", "rk45")
    assert run.code == 0, run.stderr
    assert "kept dop853.csv" in run.stderr
    assert (out_dir / "dop853.csv").read_bytes() == edited


@pytest.mark.slow
def test_a_rerun_removes_only_its_own_stale_files(run_cli, case_file, out_dir, previous):
    case = case_file()
    previous(out_dir, "rk45", "dop853")
    (out_dir / "notes.txt").write_text("mine")
    run = run_cli("run", case, "--out", out_dir, "-m", "rk45")
    assert run.code == 0
    assert "removed 1 files of the previous run that this run did not produce: dop853.csv" in (
        run.stderr
    )
    assert visible(out_dir) == ["notes.txt", "report.json", "rk45.csv"]


# ---------------------------------------------------------------------- commit


@pytest.mark.slow
def test_a_failed_move_is_undone_whole(run_cli, case_file, out_dir, previous):
    """The third move of the commit fails as across file systems (EXDEV): the two before
    are undone, the previous outputs are as they were, exit 74 with the reason."""
    case, before = case_file(), previous(out_dir)
    fault = {"at": "move:3", "do": "exdev"}
    run = run_cli("run", case, "--out", out_dir, "-m", "dop853", "-m", "bdf", fault=fault)
    assert run.code == 74, run.stderr
    assert "could not move the outputs into place: Invalid cross-device link" in run.stderr
    assert "nothing of this run was written, the previous outputs are unchanged" in run.stderr
    assert snapshot(out_dir) == before
    assert _hidden(out_dir) == []


def test_a_signal_between_moves_in_process_completes_the_commit(tmp_path, monkeypatch):
    """In-process: SIGTERM sent between the first two moves of a commit; the commit goes
    on to the end, then Terminated is raised."""
    target = tmp_path / "out"
    with io.staged_output_dir(target) as staged:
        io.write_text(staged.path("a.csv"), "old a\n")
        io.write_text(staged.path("b.csv"), "old b\n")
    moves = []
    real = os.rename

    def rename(src, dst):
        real(src, dst)
        moves.append(dst)
        if len(moves) == 1:
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(outputs.os, "rename", rename)
    with (
        signals.termination_as_exception(),
        pytest.raises(signals.Terminated),
        io.staged_output_dir(target) as staged,
    ):
        io.write_text(staged.path("a.csv"), "new a\n")
        io.write_text(staged.path("b.csv"), "new b\n")
    assert len(moves) >= 4  # the commit went on after the signal
    assert (target / "a.csv").read_text() == "new a\n"
    assert (target / "b.csv").read_text() == "new b\n"
    assert io.read_manifest(target) == ["a.csv", "b.csv", "report.json"]
    assert _hidden(target) == []


@pytest.mark.slow
def test_sigkill_during_the_commit_is_completed_by_the_next_command(
    run_cli, case_file, out_dir, previous
):
    """SIGKILL after the third move of a commit: the journal left in the dir lets the
    next command complete it before it starts (and say so); then the dir is whole."""
    case = case_file()
    previous(out_dir)
    fault = {"at": "move:3", "do": "kill"}
    run = run_cli("run", case, "--out", out_dir, "-m", "dop853", "-m", "bdf", fault=fault)
    assert run.code == -signal.SIGKILL
    assert [n for n in _hidden(out_dir) if n.startswith(".rubcli-staging-")]
    run = run_cli("run", case, "--out", out_dir, "-m", "rk45")
    assert run.code == 0, run.stderr
    assert "completed the interrupted commit of an earlier command" in run.stderr
    assert "bdf.csv, dop853.csv" in run.stderr
    _consistent(out_dir)
    assert visible(out_dir) == ["report.json", "rk45.csv"]  # and the stale ones removed
    assert _hidden(out_dir) == []


@pytest.mark.slow
def test_sigkill_during_the_writing_leaves_nothing_beside_and_is_cleared(
    run_cli, case_file, out_dir, previous, tmp_path
):
    """SIGKILL mid-run: nothing appears beside the output dir; the next run clears the
    killed run's staging (its owner is dead: the dir's lock is free)."""
    case, before = case_file(), previous(out_dir)
    marker = tmp_path / "writing"
    fault = {"at": "call:rubcli.io:write_solution_csv", "do": "kill", "marker": str(marker)}
    run = run_cli("run", case, "--out", out_dir, fault=fault)
    assert run.code == -signal.SIGKILL and marker.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.toml", "out", "writing"]
    assert snapshot(out_dir) == before
    run = run_cli("run", case, "--out", out_dir)
    assert run.code == 0, run.stderr
    assert "left by an interrupted command" in run.stderr
    assert _hidden(out_dir) == []


@pytest.mark.slow
def test_a_commit_into_a_bind_mount_is_renames_and_whole(in_namespace, case_file, tmp_path):
    """A bind-mounted output dir: staging on the parent's mount made every move EXDEV (a
    copy); staged inside the dir, the commit is renames, and SIGTERM during it waits for
    it to complete."""
    case = case_file()
    (tmp_path / "real").mkdir()
    (tmp_path / "mnt").mkdir()
    launcher = os.path.join(os.path.dirname(__file__), "launcher.py")
    fault = json.dumps({"at": "move:2", "do": "signal", "signal": 15})
    script = f"""
set -e
mount --bind real mnt
$RUBCLI run {case} --out mnt -m rk45
set +e
RUBCLI_HOSTILE_FAULT='{fault}' {sys.executable} {launcher} run {case} --out mnt -m dop853 -m bdf
echo "code=$?"
"""
    run = in_namespace(script)
    assert "code=143" in run.stdout, run.stderr
    assert "stopped after the outputs of this run were written" in run.stderr
    assert "Traceback" not in run.stderr
    real = tmp_path / "real"
    _consistent(real)
    assert visible(real) == ["bdf.csv", "dop853.csv", "report.json"]
    assert _hidden(real) == [] and sorted(os.listdir(tmp_path)) == ["case.toml", "mnt", "real"]


# ----------------------------------------------------------- rubcli's own entries


@pytest.mark.slow
def test_a_stopped_sweep_does_not_make_its_case_dir_foreign(run_cli, case_file, tmp_path):
    """Ctrl-C on a default `rubcli sweep CASE` leaves its resume store in out/NAME; then
    `rubcli run CASE` into out/NAME must accept it (the store is rubcli's own)."""
    case = case_file(SWEEP_CASE + '\n[solver]\nmethods = ["rk45"]\n[output]\nplots = []\n')
    marker = tmp_path / "second-point"
    fault = {"at": "call:rubcli.analysis.sweep.store:PointStore.save", "nth": 2, "do": "hold",
             "hold": 60, "marker": str(marker)}  # fmt: skip
    proc = run_cli("sweep", case, "--workers", "1", fault=fault, background=True)
    wait_for(marker, proc)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=60)
    assert proc.returncode == 130
    case_dir = tmp_path / "out" / "free"
    stores = [p.name for p in (case_dir / "sweep").iterdir() if p.name.startswith(".rubcli-sweep-")]
    assert stores  # the store is there, inside the sweep's dir
    run = run_cli("run", case, "--periods", "1")
    assert run.code == 0, run.stderr
    assert {"report.json", "rk45.csv"} <= set(visible(case_dir))


@pytest.mark.slow
def test_a_sweep_into_the_working_dir_resumes_from_its_own_store(run_cli, case_file, tmp_path):
    """`rubcli sweep CASE --out .` keeps its store inside the dir, as rubcli's own: a
    sweep cut by a full disk leaves only it, and the same command then resumes."""
    case = case_file(SWEEP_CASE)
    work = tmp_path / "work"
    work.mkdir()
    args = ("sweep", case, "--out", ".", "--workers", "1")
    run = run_cli(*args, cwd=work, preexec=fsize_limit(16000))
    assert run.code == 74, run.stderr
    assert visible(work) == []
    run = run_cli(*args, cwd=work)
    assert run.code == 0, run.stderr
    assert json.loads((work / "report.json").read_text())["points_resumed"] == 5
    assert _hidden(work) == [] and _hidden(tmp_path) == []


@pytest.mark.slow
def test_the_store_of_a_changed_sweep_is_removed_and_named(run_cli, case_file, out_dir, tmp_path):
    """A sweep cut by a full disk keeps its points; the case then changes and its sweep
    completes: the earlier store, which no run will resume, is removed and named."""
    first = case_file(SWEEP_CASE)
    run = run_cli("sweep", first, "--out", out_dir, "--workers", "1",
                  preexec=fsize_limit(16000))  # fmt: skip
    assert run.code == 74, run.stderr
    changed = SWEEP_CASE.replace("values = [0.5, 0.8, 1.0, 1.3, 2.0]", "values = [0.6, 1.1]")
    run = run_cli("sweep", case_file(changed, "changed.toml"), "--out", out_dir, "--workers", "1")
    assert run.code == 0, run.stderr
    assert "the finished points of an earlier sweep into" in run.stderr
    assert "whose settings have changed since" in run.stderr
    assert _hidden(out_dir) == []
    assert [p for p in os.listdir(tmp_path) if ".sweep-" in p] == []


@pytest.mark.slow
def test_every_command_takes_out_and_follows_the_dir_rule(run_cli, case_file, tmp_path):
    """`-o/--out` on every command; without it `run` writes out/<case name>, the others
    out/<case name>/<command> (orbits wrote into the run's dir)."""
    from typer.testing import CliRunner

    from rubcli.cli.app import app

    for command in ("run", "compare", "forces-map", "stress", "sweep", "orbits"):
        text = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "200"}).output
        assert "-o" in text and "--out" in text and "--wait" in text, command
    case = case_file(ORBITS_CASE)
    run = run_cli("orbits", case)  # no starting orbit (max_newton = 1): report.json only
    assert run.code == 1, run.stderr
    assert visible(tmp_path / "out" / "small" / "orbits") == ["report.json"]
    assert run_cli("run", case).code == 0  # no clash with the run's own dir
    assert visible(tmp_path / "out" / "small") == ["orbits", "report.json", "rk45.csv"]


@pytest.mark.parametrize("code", [errno.ENOSPC])
def test_write_failures_are_recognised(code):
    assert io.is_write_failure(OSError(code, os.strerror(code)))
    assert io.is_write_failure(OSError(None, "Can't write data (errno = 28, error message = "
                                             "'No space left on device')"))  # fmt: skip
    assert not io.is_write_failure(FileNotFoundError(errno.ENOENT, "No such file"))

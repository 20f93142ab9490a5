"""One command per output dir at a time: a second is refused (exit 75) or waits (--wait).

Without a lock, two runs into one dir both exited 0 and left a CSV that report.json did
not list (8 of 8 trials of the audit), and two sweeps shared one store.
"""

from __future__ import annotations

import json
import os
import signal

import pytest

from rubcli import io

from .conftest import SWEEP_CASE, finish, visible, wait_for


def _held_run(run_cli, case, out_dir, marker, *args):
    """A run held in its solve (the second solve: the first is the warm-up) until killed."""
    fault = {"at": "call:rubcli.solvers:solve", "nth": 2, "do": "hold", "hold": 60,
             "marker": str(marker)}  # fmt: skip
    proc = run_cli("run", case, "--out", out_dir, *args, fault=fault, background=True)
    wait_for(marker, proc)
    return proc


@pytest.mark.slow
def test_a_second_command_on_a_busy_dir_is_refused(run_cli, case_file, out_dir, tmp_path):
    case = case_file()
    first = _held_run(run_cli, case, out_dir, tmp_path / "held")
    try:
        second = run_cli("run", case, "--out", out_dir, "-m", "dop853")
        assert second.code == 75
        assert f"output dir is in use by rubcli run (pid {first.pid}" in second.stderr
        assert "--wait" in second.stderr
        other = run_cli("stress", "--quick", "--case", "grazing-touch", "--method", "rk45",
                        "--out", out_dir)  # fmt: skip
        assert other.code == 75  # any command
    finally:
        first.send_signal(signal.SIGTERM)
        assert finish(first).code == 143
    assert visible(out_dir) == []


@pytest.mark.slow
def test_wait_waits_for_the_first_then_runs(run_cli, case_file, out_dir, tmp_path):
    case = case_file()
    first = run_cli("run", case, "--out", out_dir, "-m", "rk45", background=True,
                    fault={"at": "call:rubcli.solvers:solve", "nth": 2, "do": "hold",
                           "hold": 2, "marker": str(tmp_path / "held")})  # fmt: skip
    wait_for(tmp_path / "held", first)
    second = run_cli("run", case, "--out", out_dir, "-m", "dop853", "--wait")
    assert second.code == 0, second.stderr
    assert "in use by rubcli run" in second.stderr and "waiting for it (--wait)" in second.stderr
    assert finish(first).code == 0  # it finished first, then the second ran
    report = json.loads((out_dir / "report.json").read_text())
    assert list(report["methods"]) == ["dop853"]
    assert visible(out_dir) == ["dop853.csv", "report.json"]


@pytest.mark.slow
def test_concurrent_runs_never_leave_a_csv_the_report_does_not_list(run_cli, case_file, out_dir):
    """The audit's race, twice: two runs with different methods started together into
    one dir (with --wait): the last to commit wins whole."""
    case = case_file()
    for _ in range(2):
        procs = [run_cli("run", case, "--out", out_dir, "-m", m, "--wait", background=True)
                 for m in ("rk45", "dop853")]  # fmt: skip
        assert [finish(p).code for p in procs] == [0, 0]
        report = json.loads((out_dir / "report.json").read_text())
        assert sorted(report["files"]) == visible(out_dir)
        assert len(report["methods"]) == 1


@pytest.mark.slow
def test_the_lock_of_a_killed_command_is_free(run_cli, case_file, out_dir, tmp_path):
    """SIGKILL releases the OS lock: the next command is not refused."""
    case = case_file()
    first = _held_run(run_cli, case, out_dir, tmp_path / "held")
    first.kill()
    first.communicate()
    run = run_cli("run", case, "--out", out_dir)
    assert run.code == 0, run.stderr


@pytest.mark.slow
def test_a_sweep_holds_its_output_dir(run_cli, case_file, out_dir, tmp_path):
    """Two sweeps into one dir shared one store and the second crashed: now the second is
    refused while the first runs."""
    case = case_file(SWEEP_CASE)
    marker = tmp_path / "first-point"
    fault = {"at": "call:rubcli.analysis.sweep.store:PointStore.save", "do": "hold",
             "hold": 60, "marker": str(marker)}  # fmt: skip
    first = run_cli("sweep", case, "--out", out_dir, "--workers", "1", fault=fault,
                    background=True)  # fmt: skip
    try:
        wait_for(marker, first)
        second = run_cli("sweep", case, "--out", out_dir, "--workers", "1")
        assert second.code == 75, second.stderr
        assert "in use by" in second.stderr
    finally:
        first.send_signal(signal.SIGINT)
        assert finish(first).code == 130


def test_lock_in_process(tmp_path):
    """The lock itself: a second open of the same dir is refused while the first holds
    it, the lock file goes with the last holder, and a waiter takes over."""
    target = tmp_path / "out"
    first = io.open_output_dir(target)
    with pytest.raises(io.OutputBusy, match="in use by"):
        io.open_output_dir(target)
    first.close()
    assert not target.exists()  # made for a command that wrote nothing: removed again
    with io.open_output_dir(target) as again:
        assert again.target == target
    assert not target.exists()


@pytest.mark.slow
def test_waiting_is_interrupted_by_a_signal(run_cli, case_file, out_dir, tmp_path):
    """A command waiting with --wait stops cleanly on Ctrl-C (exit 130, nothing written)."""
    case = case_file()
    first = _held_run(run_cli, case, out_dir, tmp_path / "held")
    try:
        waiting = run_cli("run", case, "--out", out_dir, "--wait", background=True)
        line = ""
        while "waiting for it" not in line:  # its warning: it is in its wait now
            line = waiting.stderr.readline()
            assert line or waiting.poll() is None, "ended before waiting"
        waiting.send_signal(signal.SIGINT)
        run = finish(waiting)
        assert run.code == 130, run.stderr
    finally:
        first.send_signal(signal.SIGTERM)
        finish(first)


@pytest.mark.slow
def test_a_hard_linked_lock_writes_nothing_outside_the_dir(run_cli, case_file, out_dir,
                                                            tmp_path):  # fmt: skip
    """`ln v.txt DIR/.rubcli.lock`: writing the lock would write v.txt, outside the dir;
    the command refuses (exit 2, saying what the lock is) and v.txt is unchanged."""
    outside = tmp_path / "v.txt"
    outside.write_text("my own file\n")
    out_dir.mkdir()
    os.link(outside, out_dir / ".rubcli.lock")
    run = run_cli("run", case_file(), "--out", out_dir)
    assert run.code == 2, run.stderr
    assert ".rubcli.lock is a hard link (one of 2 names of one file), not rubcli's lock" in (
        run.stderr
    )
    assert "remove it" in run.stderr
    assert outside.read_text() == "my own file\n"
    assert visible(out_dir) == [] and os.path.exists(out_dir / ".rubcli.lock")


@pytest.mark.slow
def test_a_symlinked_lock_is_named_for_what_it_is(run_cli, case_file, out_dir, tmp_path):
    outside = tmp_path / "v.txt"
    outside.write_text("my own file\n")
    out_dir.mkdir()
    (out_dir / ".rubcli.lock").symlink_to(outside)
    run = run_cli("run", case_file(), "--out", out_dir)
    assert run.code == 2, run.stderr
    assert ".rubcli.lock is a symbolic link, not rubcli's lock file" in run.stderr
    assert "Too many levels" not in run.stderr
    assert outside.read_text() == "my own file\n"
    assert os.path.islink(out_dir / ".rubcli.lock")

"""Termination signals at every phase of a command: a clean exit, nothing half-written.

SIGTERM, SIGINT and SIGHUP end a command with exit code 128 + N and one line on stderr
that says whether the run's outputs were written (README, "Exit codes"); never a
traceback (``KeyboardInterrupt`` from an import, ``SystemError`` from a compiled call), and
the output dir is as before, or wholly the new run's when the signal came during the
commit (the commit is finished first).
"""

from __future__ import annotations

import fcntl
import json
import os
import random
import signal
import subprocess
import sys
import time

import pytest

from rubcli.io.lock import LOCK_NAME

from .conftest import (
    LONG_CASE,
    ORBITS_CASE,
    SMALL_CASE,
    SWEEP_CASE,
    _child_environment,
    finish,
    snapshot,
    visible,
    wait_for,
)

TERM, INT, HUP = signal.SIGTERM, signal.SIGINT, signal.SIGHUP


def _stopped(run, signum, written=False) -> None:
    assert run.code == 128 + signum, (run.code, run.stderr)
    assert f"terminated by {signal.Signals(signum).name}" in run.stderr
    if written:
        assert "stopped after the outputs of this run were written" in run.stderr
    else:
        assert "no outputs of this run were written" in run.stderr


def _consistent(directory) -> dict:
    """The dir holds exactly the files its report.json lists (no mix of two runs)."""
    report = json.loads((directory / "report.json").read_text())
    assert sorted(report["files"]) == visible(directory)
    assert not [p.name for p in directory.iterdir() if p.name.startswith(".")]
    return report


@pytest.mark.slow
@pytest.mark.parametrize(
    ("module", "signum"),
    [("numpy", INT), ("numba", TERM), ("typer", HUP), ("matplotlib", TERM)],
)  # fmt: skip
def test_a_signal_during_the_start_up_imports_exits_cleanly(
    run_cli, case_file, out_dir, module, signum
):
    """The entry point handles signals before numpy is imported: a Ctrl-C in the first
    tenth of a second is no ``KeyboardInterrupt`` traceback from inside numpy's import."""
    case = case_file(SMALL_CASE.replace("plots = []", 'plots = ["orbit"]'))
    fault = {"at": f"import:{module}", "do": "signal", "signal": signum}
    run = run_cli("run", case, "--out", out_dir, fault=fault)
    _stopped(run, signum)
    assert visible(out_dir) == [] and not out_dir.exists()


PHASES = {
    # the timed solve (the first call is the start-up's warm-up)
    "solve": {"at": "call:rubcli.solvers:solve", "nth": 2, "delay": 0.05},
    # inside the compiled energy balance (it runs 10 ms)
    "energy balance": {"at": "call:rubcli.analysis.energy.kernel:balance_pass", "delay": 0.003},
    # the audit's case, made certain: the signal is handled while the compiled energy
    # balance has called back into numba's Python code (it unpickles a constant); a
    # handler raising there was lost by numba's dispatcher ("SystemError:
    # CPUDispatcher(balance_pass) returned a result with an exception set")
    "energy balance, in numba's code": {
        "at": "call:numba.core.serialize:_numba_unpickle",
        "frame": "callee",
        "within": "rubcli.analysis.energy.kernel:balance_pass",
    },
    "csv": {"at": "call:rubcli.io:write_solution_csv", "delay": 0.02},
    "figure": {"at": "call:rubcli.io:save_figure", "delay": 0.01},
}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("phase", "signum"),
    [("solve", INT), ("energy balance", TERM), ("energy balance, in numba's code", TERM),
     ("energy balance, in numba's code", INT), ("csv", HUP), ("figure", TERM)],
)  # fmt: skip
def test_a_signal_at_each_phase_of_a_run_keeps_the_previous_outputs(
    run_cli, case_file, out_dir, previous, phase, signum
):
    before = previous(out_dir)
    fault = {**PHASES[phase], "do": "signal", "signal": signum}
    run = run_cli("run", case_file(LONG_CASE, "long.toml"), "--out", out_dir, fault=fault)
    _stopped(run, signum)
    assert snapshot(out_dir) == before
    assert [p.name for p in out_dir.iterdir() if p.name.startswith(".")] == []  # no staging


@pytest.mark.slow
def test_a_signal_during_the_commit_is_held_until_the_commit_is_whole(run_cli, case_file, out_dir):
    """SIGTERM between two moves of the commit: the commit completes, then the command
    stops and says that the outputs were written."""
    case = case_file()
    assert run_cli("run", case, "--out", out_dir, "-m", "rk45").code == 0
    fault = {"at": "move:2", "do": "signal", "signal": TERM}
    run = run_cli("run", case, "--out", out_dir, "-m", "dop853", "-m", "bdf", fault=fault)
    _stopped(run, TERM, written=True)
    report = _consistent(out_dir)
    assert visible(out_dir) == ["bdf.csv", "dop853.csv", "report.json"]
    assert list(report["methods"]) == ["dop853", "bdf"]


@pytest.mark.serial
@pytest.mark.slow
def test_signals_from_outside_at_random_moments(run_cli, case_file, out_dir, previous):
    """Real signals sent from outside while a long run is anywhere between its start and
    its end: every time a clean exit, and a dir that is the previous run's or the new."""
    before = previous(out_dir)
    long_case = case_file(LONG_CASE, "long.toml")
    started = time.monotonic()
    assert run_cli("run", long_case, "--out", out_dir).code == 0
    span = time.monotonic() - started
    after = snapshot(out_dir)
    chooser = random.Random(20)
    for trial in range(4):
        signum = (TERM, INT, HUP)[trial % 3]
        # from 0.3 s on: the interpreter's own start (before rubcli's first line, tens of
        # milliseconds, longer on a loaded machine) is Python's
        delay = chooser.uniform(0.3, span)
        proc = run_cli("run", long_case, "--out", out_dir, background=True)
        time.sleep(delay)
        proc.send_signal(signum)
        run = finish(proc)
        assert run.code in (0, 128 + signum), (delay, run.code, run.stderr)  # never -signum
        now = snapshot(out_dir)
        if run.code == 0 or "stopped after the outputs of this run were written" in run.stderr:
            _consistent(out_dir)
            assert now.keys() == after.keys()
        else:
            assert now == before or now.keys() == after.keys(), delay
        assert not [p.name for p in out_dir.iterdir() if p.name.startswith(".")], delay
        before = now


FREE_COMPARE = (
    SMALL_CASE.replace("periods = 2\n", "periods = 1\n")
    + """
[compare]
work_precision = false
"""
)
MAP_CASE = (
    SMALL_CASE
    + """
[forces_map]
products = ["eigen"]
resolution = 5
extent = 2.0
"""
)

COMMANDS = {
    "compare": (FREE_COMPARE, ["compare", "{case}", "--quick"], "call:rubcli.io:save_figure"),
    "forces-map": (MAP_CASE, ["forces-map", "{case}"], "call:rubcli.io:save_figure"),
    "stress": (None, ["stress", "--quick", "--case", "grazing-touch", "--method", "rk45"],
               "call:rubcli.io:write_rows_csv"),
    "orbits": (ORBITS_CASE, ["orbits", "{case}"],
               "call:rubcli.analysis.orbits.continuation:continue_branch"),
}  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("command", list(COMMANDS))
def test_every_command_stops_cleanly_on_a_signal(run_cli, case_file, out_dir, command):
    text, args, where = COMMANDS[command]
    case = case_file(text) if text else None
    args = [str(case) if a == "{case}" else a for a in args]
    run = run_cli(*args, "--out", out_dir, fault={"at": where, "do": "signal", "signal": TERM})
    _stopped(run, TERM)
    assert not out_dir.exists()


@pytest.mark.slow
def test_a_sweep_stops_cleanly_on_a_signal_and_keeps_its_points(run_cli, case_file, out_dir):
    """Ctrl-C while the sweep computes (held at its second stored point): exit 130, the
    finished point kept in the store for the next run, nothing in the output dir."""
    marker = out_dir.parent / "second-point"
    fault = {"at": "call:rubcli.analysis.sweep.store:PointStore.save", "nth": 2, "do": "hold",
             "hold": 60, "marker": str(marker)}  # fmt: skip
    args = ("sweep", case_file(SWEEP_CASE), "--out", out_dir, "--workers", "1")
    proc = run_cli(*args, fault=fault, background=True)
    wait_for(marker, proc)
    proc.send_signal(INT)
    run = finish(proc)
    assert run.code == 130, run.stderr
    assert "1 of 5 points are kept in" in run.stderr
    assert visible(out_dir) == []
    (store,) = out_dir.glob(".rubcli-sweep-*")
    assert len(list(store.glob("*.point"))) == 1


def test_start_up_loop_of_real_sigint(run_cli, case_file, out_dir):
    """Ctrl-C sent from outside during the start-up's imports (after the interpreter's
    own first tens of milliseconds, which are Python's): a clean 130."""
    case = case_file()
    for delay in (0.2, 0.4):
        proc = run_cli("run", case, "--out", out_dir, background=True)
        time.sleep(delay)
        proc.send_signal(INT)
        run = finish(proc)
        assert run.code in (0, 130), (delay, run.stderr)
        if run.code == 130:
            assert "terminated by SIGINT" in run.stderr


# A basin grid of 141 x 141 starts on two workers: after the seed, every chunk's task
# carries the basin cells learned so far (a few hundred KB, more than a pipe holds), so
# that at any moment a task may be half-written into a worker's pipe and a result
# half-written back. A short budget keeps the seed to a few seconds.
BASIN_GRID = """\
[case]
name = "basins"
[model]
nu = 0.05
eta = 2.0
e = 0.3
K = 10.0
mu = 0.02
Rp = 5.0
[initial]
x = 0.0
y = 0.0
[time]
periods = 50
samples_per_period = 32
[solver]
methods = ["dop853-jit"]
rtol = 1e-8
atol = 1e-10
[sweep]
direction = "independent"
transient_periods = 40
record_periods = 16
[sweep.recognition]
seed_points = 16
[[sweep.axes]]
parameter = "x"
start = -1.5
stop = 1.5
num = 141
[[sweep.axes]]
parameter = "y"
start = -1.5
stop = 1.5
num = 141
"""


def _group_gone(pgid: int, timeout: float = 10.0) -> bool:
    """Whether every process of the group has ended (within ``timeout``)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


@pytest.mark.serial
@pytest.mark.slow
@pytest.mark.parametrize("signum", [INT, TERM])
def test_a_signal_to_the_process_group_stops_a_pooled_basin_sweep(
    state_dir, case_file, out_dir, signum
):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) or SIGTERM to
    the group while two workers compute basin chunks: the command exits with its
    signal's code within seconds, whatever the pipes between the workers and the parent
    hold; no worker is left, the output dir is unlocked and empty, and the finished
    chunks are kept for the next run."""
    case = case_file(BASIN_GRID)
    env = {**_child_environment(), "RUBCLI_STATE_DIR": str(state_dir)}
    command = [sys.executable, "-m", "rubcli", "sweep", str(case), "--workers", "2",
               "--out", str(out_dir)]  # fmt: skip
    proc = subprocess.Popen(command, cwd=out_dir.parent, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)  # fmt: skip
    try:
        # the first round's 4 chunks and one of the second's stored: the second round's
        # other 7 chunks submitted, 3 of them in the pipes or the workers
        deadline = time.monotonic() + 120
        while len(list(out_dir.glob(".rubcli-sweep-*/chunk-*"))) < 5:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no chunk of the second round stored"
            time.sleep(0.01)
        time.sleep(0.3)
        os.killpg(proc.pid, signum)
        run = finish(proc, timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert run.code == 128 + signum, run.stderr
    assert "points are kept in" in run.stderr
    assert _group_gone(proc.pid), "a worker outlived the command"
    assert visible(out_dir) == []
    lock = out_dir / LOCK_NAME
    if lock.exists():
        with open(lock) as handle:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)  # BlockingIOError: still held


def test_a_ctrl_c_from_the_entry_points_first_moments_exits_cleanly(run_cli, case_file, out_dir):
    """SIGINT at the entry point's first moments: as it imports the ``signal`` module,
    and 0 to 80 ms after it imports ``rubcli.io`` (its imports, typer's, numpy's): every
    time exit 130 with one line, never a ``KeyboardInterrupt`` traceback."""
    case = case_file()
    moments = [{"at": "import:signal"}] + [
        {"at": "import:rubcli.io", "delay": delay}
        for delay in (0, 0.005, 0.01, 0.02, 0.04, 0.08)
    ]  # fmt: skip
    for moment in moments:
        run = run_cli("run", case, "--out", out_dir, fault={**moment, "do": "signal",
                                                            "signal": INT})  # fmt: skip
        assert run.code == 130, (moment, run.code, run.stderr)
        assert run.stderr.count("\n") == 1 and "terminated by SIGINT" in run.stderr, moment
        assert not out_dir.exists()


DROPPED_IN_A_FORK_HOOK = """
import os, signal, sys, time
from rubcli.io import signals

def hook():  # as logging's lock release after a fork: Python ignores what it raises
    os.kill(os.getpid(), signal.SIGTERM)
    for _ in range(10**5):
        pass

signals.install()
os.register_at_fork(after_in_parent=hook)
try:
    child = os.fork()
    if child == 0:
        os._exit(0)
    os.waitpid(child, 0)
    for _ in range(500):
        time.sleep(0.002)
except signals.Terminated as exc:
    sys.exit(exc.exit_code)
sys.exit(signals.finish() or 0)
"""


def test_a_signal_python_drops_in_a_fork_hook_still_stops_the_command(tmp_path):
    """A pool forking its workers runs logging's at-fork hook; a signal handled in it was
    printed as "Exception ignored" and lost, and the sweep went on to exit 0."""
    done = subprocess.run([sys.executable, "-c", DROPPED_IN_A_FORK_HOOK], cwd=tmp_path,
                          env=_child_environment(), capture_output=True, text=True,
                          timeout=60)  # fmt: skip
    assert done.returncode == 128 + TERM, done.stderr
    assert "Exception ignored" not in done.stderr
    assert "Traceback" not in done.stderr

"""What should end in a message ends in one, and what failed does not report success.

Every test runs the command line as a user would (``run_cli``) and checks the exit code
(README, "Exit codes"), the message on stderr, that no traceback is shown and that nothing
is written by a command that refuses.
"""

from __future__ import annotations

import os
import resource

import pytest

from .conftest import SMALL_CASE, SWEEP_CASE, snapshot, visible

# ------------------------------------------------------------------ no stdout at all


def _closed(*fds: int):
    """A ``preexec`` that starts the command with these file descriptors closed (``>&-``)."""

    def close() -> None:
        for fd in fds:
            os.close(fd)

    return close


COMMANDS = {
    "init": ["init", "new.toml"],
    "validate": ["validate", "case.toml"],
    "run": ["run", "case.toml", "--out", "out"],
    "forces-map": ["forces-map", "case.toml", "--out", "out"],
    "compare": ["compare", "case.toml", "--out", "out"],
    "stress": ["stress", "--out", "out"],
    "sweep": ["sweep", "case.toml", "--out", "out"],
    "orbits": ["orbits", "case.toml", "--out", "out"],
    "ensemble": ["ensemble", "case.toml", "--out", "out"],
    "chart": ["chart", "case.toml", "--out", "out"],
    "--version": ["--version"],
    "--help": ["--help"],
    "no arguments": [],
}


@pytest.mark.slow
@pytest.mark.parametrize("command", COMMANDS)
def test_a_closed_stdout_is_an_io_error_before_anything_runs(run_cli, case_file, command):
    case = case_file(SMALL_CASE)
    run = run_cli(*COMMANDS[command], cwd=case.parent, preexec=_closed(1))
    assert run.code == 74, run.stderr
    assert run.stderr.strip() == "error: cannot write to standard output: it is closed"
    assert visible(case.parent) == ["case.toml"]  # nothing written


def test_a_closed_stdout_and_stderr_exit_74_silently(run_cli, case_file):
    case = case_file(SMALL_CASE)
    run = run_cli("validate", case, preexec=_closed(1, 2))
    assert run.code == 74
    assert run.stderr == ""


# ------------------------------------------------------------------ no numba cache


@pytest.mark.slow
def test_a_read_only_install_without_a_writable_home_runs_uncached(in_namespace, case_file):
    """A system-wide install: numba can write neither the package's __pycache__ nor a user
    cache dir (the package is a read-only mount, and so is HOME). The kernels are compiled
    uncached, with a note, where numba refused to make them. forces-map compiles few."""
    case = case_file(SMALL_CASE)
    run = in_namespace(
        f"""
        set -e
        pkg=$(python -c "import os, rubcli; print(os.path.dirname(rubcli.__file__))")
        mount --bind "$pkg" "$pkg"
        mount -o remount,bind,ro "$pkg"
        unset NUMBA_CACHE_DIR XDG_CACHE_HOME
        export HOME="$pkg" MPLCONFIGDIR="{case.parent}"
        $RUBCLI forces-map {case} --out {case.parent / "out"}
        """
    )
    assert run.code == 0, run.stderr
    assert "Traceback" not in run.stderr
    assert "the kernels are compiled uncached" in run.stderr
    assert "report.json" in visible(case.parent / "out")


# ------------------------------------------------------------------ failures as failures

ALL_FAIL_SWEEP = SWEEP_CASE.replace("[sweep]", "[solver]\nmax_steps = 1\n[sweep]").replace(
    "values = [0.5, 0.8, 1.0, 1.3, 2.0]", "values = [0.5, 0.8]"
)


@pytest.mark.slow
def test_a_sweep_whose_every_point_failed_exits_1(run_cli, case_file, out_dir):
    run = run_cli("sweep", case_file(ALL_FAIL_SWEEP), "--out", out_dir, "--workers", "1")
    assert run.code == 1, run.stderr
    assert "every point failed (the first: transient:" in run.stderr
    assert "warning" not in run.stderr  # no stray warning of an empty figure's legend
    assert "report.json" in visible(out_dir)  # the failures are recorded


# ------------------------------------------------------------------ terminal escapes


@pytest.mark.slow
def test_control_characters_from_a_case_file_are_printed_escaped(run_cli, case_file):
    """A description, a name and a file name holding terminal escapes (a window title
    change, a bidirectional override): validate prints them escaped, never raw."""
    text = SMALL_CASE.replace(
        'name = "small"', 'name = "small"\ndescription = "x\\u001b]0;pwned\\u0007y"'
    )
    case = case_file(text, name="case\x1b[2J\u202e.toml")
    run = run_cli("validate", case)
    assert run.code == 0, run.stderr
    assert "x\\x1b]0;pwned\\x07y" in run.stdout
    assert "case\\x1b[2J\\u202e.toml" in run.stdout
    assert not any(c in run.stdout + run.stderr for c in "\x1b\x07\u202e")
    bad = case_file(text.replace("K = 17.6", "K = -1"), name="bad\x1b[2J.toml")
    run = run_cli("validate", bad)
    assert run.code == 2
    assert "bad\\x1b[2J.toml" in run.stderr and "\x1b" not in run.stderr


# ------------------------------------------------------------------ the paper's machine only

CHART = '\n[chart]\nx = "eta"\nx_min = 0.5\nx_max = 1.5\ny = "mu"\ny_min = 0.0\ny_max = 0.1\n'
WHIRL = '\n[orbits]\nkind = "whirl"\nparameter = "mu"\nmin = 0.0\nmax = 0.1\nstep = 0.01\n'


@pytest.mark.slow
@pytest.mark.parametrize(
    ("command", "general", "table", "named", "analysis"),
    [
        ("chart", "offset = [0.3, 0.0]", CHART, "offset=[0.3, 0]", "chart"),
        ("chart", "stiffness = [[1.0, 0.0], [0.0, 1.5]]", CHART, "stiffness=", "chart"),
        ("orbits", "load = [0.0, -0.2]", WHIRL, "load=[0, -0.2]", 'orbits.kind: "whirl"'),
        (
            "forces-map",
            "offset = [0.3, 0.0]",
            "",
            "offset=[0.3, 0]",
            'forces_map.products: "eigen"',
        ),
    ],
    ids=["chart-offset", "chart-stiffness", "whirl-load", "eigen-offset"],
)
def test_analyses_of_the_paper_machine_refuse_a_general_machine(
    run_cli, case_file, out_dir, command, general, table, named, analysis
):
    """The chart's closed forms, the whirls of unknown rate and the contact eigen map hold
    on the paper's machine: on a general one each refuses, naming what makes it general."""
    text = SMALL_CASE.replace("Rp = 46.16", f"Rp = 46.16\n{general}") + table
    if command == "orbits":
        text = text.replace("e = 7.52", "e = 0.0")  # a whirl needs e = 0
    run = run_cli(command, case_file(text), "--out", out_dir)
    assert run.code == 2, run.stderr
    assert f"case.toml: {analysis}" in run.stderr and "paper's machine only" in run.stderr
    assert f"model: {named}" in run.stderr and "makes this machine general" in run.stderr
    assert not out_dir.exists()


# ------------------------------------------------------------------ memory

# 10,000,001 output samples: valid (within the case's own 8 GiB bound), but more than a
# process limited to 3 GiB of address space can hold
BIG_RUN = SMALL_CASE.replace("periods = 2", "periods = 1000").replace(
    "samples_per_period = 20", "samples_per_period = 10000"
)


def _address_space(n_bytes: int):
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (n_bytes, n_bytes))

    return limit


@pytest.mark.slow
def test_a_run_that_cannot_fit_in_memory_is_refused_before_solving(run_cli, case_file, out_dir):
    run = run_cli("run", case_file(BIG_RUN), "--out", out_dir, preexec=_address_space(3 * 1024**3))
    assert run.code == 2, run.stderr
    assert "time.periods, time.samples_per_period: 10,000,001 output samples" in run.stderr
    assert "GiB of memory, and this process may take" in run.stderr  # 3 GiB or less
    assert not out_dir.exists()


@pytest.mark.slow
def test_a_compare_that_cannot_fit_in_memory_is_refused_before_solving(run_cli, case_file, out_dir):
    # the orbit panel holds the run of each method and their reference over [time] periods
    run = run_cli(
        "compare", case_file(BIG_RUN), "--out", out_dir, preexec=_address_space(3 * 1024**3)
    )
    assert run.code == 2, run.stderr
    assert "time.periods, time.samples_per_period: 10,000,001 output samples x 2" in run.stderr
    assert "GiB of memory, and this process may take" in run.stderr
    assert not out_dir.exists()


@pytest.mark.slow
def test_an_ensemble_whose_runs_cannot_fit_in_memory_is_refused_before_solving(
    run_cli, case_file, out_dir
):
    # each process holds one run of [ensemble] periods (default [time] periods) at a time
    case = case_file(BIG_RUN + "\n[ensemble]\nruns = 2\n")
    run = run_cli("ensemble", case, "--out", out_dir, preexec=_address_space(3 * 1024**3))
    assert run.code == 2, run.stderr
    assert "ensemble.periods (default time.periods), time.samples_per_period: 10,000,001" in (
        run.stderr
    )
    assert "GiB of memory, and this process may take" in run.stderr
    assert not out_dir.exists()


@pytest.mark.slow
def test_running_out_of_memory_is_a_message(run_cli, case_file, out_dir, previous):
    before = previous(out_dir)
    fault = {"at": "call:rubcli.solvers:solve", "nth": 2, "do": "nomemory"}  # 1: start-up
    run = run_cli("run", case_file(), "--out", out_dir, fault=fault)
    assert run.code == 2, run.stderr
    assert run.stderr.strip().startswith("error: out of memory:"), run.stderr
    assert snapshot(out_dir) == before  # the previous outputs kept

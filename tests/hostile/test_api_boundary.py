"""Hostile input at every API boundary: the Python API (ModelParams, Problem, solve,
load_case, continuation) and the command line (real subprocesses with hostile case files).

Each bad argument raises a TypeError or ValueError that names it, as scipy's solve_ivp
does, at the boundary: never a deep internal error, a hang, or a success that is not one
(negative K once gave status success; rtol = nan ran past every budget). Each bad case
file ends in exit 2 with the file and the field named, at once and with nothing written.
"""

from __future__ import annotations

import math
import os
import re
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rubcli import model
from rubcli.analysis.orbits import continuation as cn
from rubcli.analysis.orbits import periodic as ob
from rubcli.case import CaseError, load_case
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import options_for, solve

TIMEOUT_S = 60
TRACEBACK = re.compile(r'Traceback|^\s*File "', re.M)
FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "mu": 0.03, "Rp": 46.16}
START = (0.88544, -0.8039, 0.0, 0.0)
NAN, INF = math.nan, math.inf


@pytest.fixture(scope="module")
def problem() -> Problem:
    return Problem.from_periods(ModelParams(**FIG3), START, 1, 10)


# ---------------------------------------------------------------- ModelParams


@pytest.mark.parametrize(
    ("change", "error", "words"),
    [
        ({"K": NAN}, ValueError, "K must be finite"),
        ({"K": -17.6}, ValueError, "K must be > 0"),
        ({"K": 0.0}, ValueError, "K must be > 0"),
        ({"nu": -0.01}, ValueError, "nu must be >= 0"),
        ({"mu": -0.1}, ValueError, "mu must be >= 0"),
        ({"Rp": -1.0}, ValueError, "Rp must be >= 0"),
        ({"e": -1.0}, ValueError, "e must be >= 0"),
        ({"eta": 0.0}, ValueError, "eta must be > 0"),
        ({"eta": -0.5}, ValueError, "eta must be > 0"),
        ({"eta": 1e300}, ValueError, "eta must be at most 1e+100"),  # E = e eta^2 overflows
        ({"eta": 1e-320}, ValueError, "eta must be at least 1e-100"),  # period overflows
        ({"e": 1e308}, ValueError, "e must be at most 1e+100"),
        ({"phi0": INF}, ValueError, "phi0 must be finite"),
        ({"nu": True}, TypeError, "nu must be a real number, got bool"),
        ({"K": "17.6"}, TypeError, "K must be a real number, got str"),
        ({"K": None}, TypeError, "K must be a real number, got NoneType"),
        ({"K": np.array([1.0, 2.0])}, TypeError, "K must be a real number, got ndarray"),
        ({"K": 10**400}, ValueError, "K must be finite"),  # once an OverflowError
    ],
)
def test_model_params_refuse_values_outside_the_domain(change, error, words):
    with pytest.raises(error, match=re.escape(f"ModelParams: {words}")):
        ModelParams(**{**FIG3, **change})


def test_model_params_keep_valid_values_as_floats():
    p = ModelParams(nu=0, eta=np.float32(0.5), e=1, K=np.int64(10))
    assert all(type(v) is float for v in p.as_dict().values())
    assert math.isfinite(p.period) and math.isfinite(p.E)


# ---------------------------------------------------------------------- Problem


@pytest.mark.parametrize(
    ("initial", "error", "words"),
    [
        ((1.0, 2.0, 3.0), ValueError, "initial must hold 4 numbers"),
        ((1.0, 2.0, 3.0, 4.0, 5.0), ValueError, "initial must hold 4 numbers"),
        ((1.0, NAN, 0.0, 0.0), ValueError, "initial y must be finite"),
        ((1e200, 0.0, 0.0, 0.0), ValueError, "initial x must be at most 1e+100"),
        ("abcd", TypeError, "initial must be a sequence of 4 numbers"),
        (None, TypeError, "initial must be a sequence of 4 numbers"),
        ((1.0, 0.0, "0", 0.0), TypeError, "initial vx must be a real number"),
    ],
)
def test_problem_refuses_a_bad_initial_state(initial, error, words):
    with pytest.raises(error, match=re.escape(f"Problem: {words}")):
        Problem(ModelParams(**FIG3), initial, np.linspace(0.0, 1.0, 3))


@pytest.mark.parametrize(
    ("t_eval", "error", "words"),
    [
        ([1.0, 0.0], ValueError, "t_eval must be strictly increasing"),
        ([0.0, 1.0, 1.0], ValueError, "t_eval must be strictly increasing"),
        ([0.0, NAN], ValueError, "t_eval must be finite"),
        ([0.0, INF], ValueError, "t_eval must be finite"),
        ([[0.0, 1.0]], ValueError, "t_eval must be a 1-D array of at least 2 times"),
        ([0.0], ValueError, "t_eval must be a 1-D array of at least 2 times"),
        (None, TypeError, "t_eval must be an array of times"),
        ("0 1", TypeError, "t_eval must be an array of times"),
    ],
)
def test_problem_refuses_a_bad_time_grid(t_eval, error, words):
    with pytest.raises(error, match=re.escape(f"Problem: {words}")):
        Problem(ModelParams(**FIG3), START, t_eval)


def test_problem_refuses_what_is_not_a_problem():
    with pytest.raises(TypeError, match="Problem: params must be a ModelParams, got dict"):
        Problem(FIG3, START, [0.0, 1.0])
    with pytest.raises(ValueError, match="periods must be finite and > 0"):
        Problem.from_periods(ModelParams(**FIG3), START, NAN)
    with pytest.raises(TypeError, match="samples_per_period must be an int"):
        Problem.from_periods(ModelParams(**FIG3), START, 1, 2.5)
    with pytest.raises(ValueError, match="samples_per_period must be > 0"):
        Problem.from_periods(ModelParams(**FIG3), START, 1, 0)


@pytest.mark.parametrize(
    ("periods", "samples"), [(10**12, 100), (1e6, 11), (1, 10**400), (10**400, 100)]
)
def test_problem_from_periods_is_bounded_as_a_case_file(periods, samples):
    """10**12 periods once allocated a time grid of 1e14 samples (a MemoryError at best);
    10**400 periods ended in an OverflowError."""
    with pytest.raises(ValueError, match=r"Problem.from_periods: (periods \* samples_per_period is "
                       r"more than 10,000,000 samples|periods must be finite)"):  # fmt: skip
        Problem.from_periods(ModelParams(**FIG3), START, periods, samples)


def test_problem_refuses_a_stator_its_span_cannot_resolve():
    """K = 1e60: a contact oscillation of period 8e-30 at tau ~ 8, below 1e4 doubles."""
    with pytest.raises(ValueError, match=r"Problem: params.K = 1e\+60: a contact oscillation"):
        Problem.from_periods(ModelParams(**{**FIG3, "K": 1e60}), START, 1, 10)


# ------------------------------------------------------------------------ solve


@pytest.mark.parametrize(
    ("args", "options", "error", "words"),
    [
        ((None, "rk45"), {}, TypeError, "problem must be a rubcli Problem, got NoneType"),
        (("problem", "rk45"), {}, TypeError, "problem must be a rubcli Problem, got str"),
        (("P", None), {}, TypeError, "method must be a method name (a str), got NoneType"),
        (("P", 45), {}, TypeError, "method must be a method name (a str), got int"),
        (("P", "euler"), {}, ValueError, "unknown method 'euler'"),
        (("P", "rk45"), {"rtol": NAN}, ValueError, "option rtol must satisfy 0 < rtol < 1"),
        (("P", "rk45"), {"rtol": 0.0}, ValueError, "option rtol must satisfy 0 < rtol < 1"),
        (("P", "rk45"), {"rtol": -1.0}, ValueError, "option rtol must satisfy 0 < rtol < 1"),
        (("P", "rk45"), {"atol": INF}, ValueError, "option atol must be finite and > 0"),
        (("P", "rk45"), {"atol": 0.0}, ValueError, "option atol must be finite and > 0"),
        # a ZeroDivisionError in dop853-jit, an error norm of inf in radau
        (("P", "dop853-jit"), {"atol": 5e-324}, ValueError, "option atol must be at least 1e-100"),
        (("P", "radau"), {"atol": 1e-300}, ValueError, "option atol must be at least 1e-100"),
        (("P", "taylor"), {"rtol": 1e-300}, ValueError, "option rtol must be at least 1e-14"),
        (("P", "rk45"), {"rtol": 1e-20}, ValueError, "option rtol must be at least 1e-14"),
        (("P", "rk45"), {"max_wall_time_s": 10**400}, ValueError, "option max_wall_time_s must"),
        (("P", "rk45"), {"max_steps": 2.5}, TypeError, "option max_steps must be an int"),
        (("P", "rk45"), {"max_steps": 0}, ValueError, "option max_steps must be > 0"),
        (("P", "rk45"), {"max_steps": True}, TypeError, "option max_steps must be an int"),
        (("P", "rk45"), {"max_wall_time_s": NAN}, ValueError, "option max_wall_time_s must be"),
        (("P", "rk45"), {"max_wall_time_s": -1}, ValueError, "option max_wall_time_s must be"),
        (("P", "rk45"), {"compiled": "no"}, TypeError, "option compiled must be True or False"),
        (("P", "analytic"), {"steps_per_period": 0}, ValueError, "steps_per_period must be > 0"),
        (("P", "analytic"), {"steps_per_period": 2.5}, TypeError, "steps_per_period must be an"),
        (("P", "analytic"), {"analytic_tol": NAN}, ValueError, "analytic_tol must satisfy"),
        (("P", "taylor"), {"compiled_events": 1}, TypeError, "compiled_events must be True"),
        (("P", "rk45"), {"progress": 3}, TypeError, "option progress must be a callable"),
        (("P", "rk45"), {"rtoll": 1e-6}, TypeError, "did you mean 'rtol'"),
        (("P", "analytic"), {"rtol": 1e-12}, TypeError, "'analytic' does not take"),
    ],
)
def test_solve_refuses_bad_arguments_naming_them(problem, args, options, error, words):
    """Each once raised deep inside a solver, was dropped, or ran past every budget
    (rtol = nan, max_wall_time_s = nan)."""
    args = tuple(problem if a == "P" else a for a in args)
    with pytest.raises(error, match=re.escape(words)):
        solve(*args, **options)


def test_options_for_and_event_kinds_name_what_they_refuse():
    """A list for the method once ended in "unhashable type: 'list'", an unknown event
    kind in "'contact' is not in list"."""
    from rubcli.solution import Events

    with pytest.raises(TypeError, match=re.escape("method must be a method name (a str)")):
        options_for(["rk45"], {})
    with pytest.raises(ValueError, match=re.escape("Events.is_kind: unknown kind(s) 'contact'")):
        Events.empty().is_kind("contact")


def test_a_shared_settings_dict_goes_through_options_for(problem):
    settings = {"rtol": 1e-8, "atol": 1e-10, "steps_per_period": 200, "max_steps": 10_000}
    for method in ("analytic", "rk45", "dop853-jit"):
        assert solve(problem, method, **options_for(method, settings)).success


# ------------------------------------------------------------------- load_case


def test_load_case_refuses_what_is_not_a_case_file(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)  # reading it would wait for a writer for ever
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    huge = tmp_path / "huge.toml"
    with huge.open("wb") as f:
        f.truncate(9 * 1024**2)  # sparse: 9 MiB of zeros
    cases = {
        tmp_path: "is a directory",
        fifo: "is not a regular file (a FIFO)",
        Path("/dev/zero"): "is not a regular file (a character device)",
        huge: "is larger than 8 MiB",
        deep: "not a case file: arrays or tables nested too deeply",
        tmp_path / "missing.toml": "file not found",
    }
    for path, words in cases.items():
        with pytest.raises(CaseError, match=re.escape(f"{path}: {words}")):
            load_case(path)
    with pytest.raises(TypeError, match="load_case\\(\\): path must be a str or a path"):
        load_case(None)


def test_a_nul_byte_in_a_path_argument_is_named(tmp_path):
    from rubcli.sweeps import sweep

    with pytest.raises(ValueError, match=re.escape("load_case(): path holds a NUL byte")):
        load_case(f"{tmp_path}/a\0b.toml")
    with pytest.raises(ValueError, match=re.escape("sweep(): store_dir holds a NUL byte")):
        sweep(tmp_path / "missing.toml", store_dir=f"{tmp_path}/a\0b")


# ----------------------------------------------------------------- continuation


@pytest.mark.slow
def test_continuation_step_past_the_domain_stops_the_branch_with_a_message():
    """A corrector step to eta < 0 once ended in a TypeError traceback (_refine_extreme on
    an empty span); the direction now stops and says why."""
    p = ModelParams(nu=0.05, eta=0.05, e=0.1, K=10.0)
    w, v = model.free_steady_state(0.0, p)
    settings = cn.ContinuationSettings(
        parameter="eta",
        p_min=1e-3,
        p_max=0.5,
        step=0.1,
        min_step=0.06,
        max_step=0.2,
        max_points=5,
        directions=(-1,),
        rtol=1e-10,
        atol=1e-10,
    )
    branch = cn.continue_branch(p, (w.real, w.imag, v.real, v.imag), settings)
    assert branch.status == "ok" and len(branch.points) == 1
    assert re.search(r"eta = -0.0499\d* leaves the model.s domain", branch.stops["backward"])


FREE = ModelParams(nu=0.05, eta=0.5, e=0.1, K=10.0)  # a free whirl: the map is cheap
ORBIT_START = (0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    ("args", "options", "error", "words"),
    [
        ((FIG3, START), {}, TypeError, "params must be a ModelParams, got dict"),
        ((FREE, (1.0, 2.0, 3.0)), {}, ValueError, "guess must hold 4 numbers"),  # IndexError
        ((FREE, "0000"), {}, TypeError, "guess must be a sequence of 4 numbers"),
        ((FREE, (0.0, NAN, 0.0, 0.0)), {}, ValueError, "guess y must be finite"),
        ((FREE, START, 0), {}, ValueError, "k must be >= 1"),
        ((FREE, START, -1), {}, ValueError, "k must be >= 1"),
        ((FREE, START, 1.5), {}, TypeError, "k must be an int, got float"),
        ((FREE, START, 10**6), {}, ValueError, "k must be <= 64"),  # 14.5 GiB of samples
        ((FREE, START), {"tol": NAN}, ValueError, "tol must be finite"),
        ((FREE, START), {"tol": -1.0}, ValueError, "tol must be > 0"),
        ((FREE, START), {"tol": 0.0}, ValueError, "tol must be > 0"),  # never met: for ever
        ((FREE, START), {"max_iter": -1}, ValueError, "max_iter must be >= 1"),
        ((FREE, START), {"max_iter": 10**9}, ValueError, "max_iter must be <= 100"),
        ((FREE, START), {"rtol": 0.0}, ValueError, "rtol must be >= 1e-14"),
        ((FREE, START), {"atol": 5e-324}, ValueError, "atol must be >= 1e-100"),
        ((FREE, START), {"max_wall_time_s": INF}, ValueError, "max_wall_time_s must be finite"),
        ((FREE, START), {"max_wall_time_s": 0}, ValueError, "max_wall_time_s must be > 0"),
        ((FREE, START), {"deadline": "soon"}, TypeError, "deadline must be a real number"),
    ],
)
def test_shoot_refuses_bad_arguments_naming_them(args, options, error, words):
    """Each once raised deep inside the flow (an IndexError), allocated without bound
    (k = 10**6), or ran for ever (tol = 0: a residual that is never met)."""
    with pytest.raises(error, match=re.escape(f"shoot(): {words}")):
        ob.shoot(*args, **options)


def test_shoot_honours_its_wall_time_budget():
    """Without a budget, Newton with a tolerance it cannot meet ran as long as max_iter
    let it; a budget ends it with the orbits' budget exception."""
    guess = (0.9, -0.8, 0.0, 0.0)  # the Figure 3 machine: rubbing, each map costs
    with pytest.raises(ob.WallTimeBudgetError):
        ob.shoot(ModelParams(**FIG3), guess, tol=1e-20, max_iter=100, max_wall_time_s=0.5)


SETTINGS = {"parameter": "eta", "p_min": 0.45, "p_max": 0.55, "step": 0.02}


@pytest.mark.parametrize(
    ("change", "error", "words"),
    [
        ({"p_min": -0.5}, ValueError, "p_min: eta must be > 0"),
        ({"parameter": "mu", "p_min": -0.1, "p_max": 0.1}, ValueError, "p_min: mu must be >= 0"),
        ({"p_max": 1e200}, ValueError, "p_max: eta must be at most 1e+100"),
        ({"parameter": "phi0"}, ValueError, "parameter 'phi0' is not one of"),
        ({"min_step": 1e-300}, ValueError, "min_step 1e-300 is below 1e-12 of the window"),
        ({"step": 1.0, "max_step": 2.0}, ValueError, "step 1.0 is wider than the window"),
        ({"locate_xtol": NAN}, ValueError, "locate_xtol must satisfy"),
        ({"locate_xtol": 0.0}, ValueError, "locate_xtol must satisfy"),
        ({"locate": "no"}, TypeError, "locate must be True or False"),
        ({"k": 10**6}, ValueError, "k must be <= 64"),
        ({"max_points": 10**9}, ValueError, "max_points must be <= 100000"),
        ({"max_newton": 0}, ValueError, "max_newton must be >= 1"),
        ({"rtol": 1e-20}, ValueError, "rtol must be >= 1e-14"),
        ({"atol": 1e-300}, ValueError, "atol must be >= 1e-100"),
        ({"step": "0.02"}, TypeError, "step must be a real number, got str"),
        ({"directions": (True,)}, ValueError, "directions must hold 1 and/or -1"),
    ],
)
def test_continuation_settings_are_checked_as_the_orbits_table(change, error, words):
    """Each was once accepted (an eta window below 0, a step of 1e-300 that never moves the
    parameter, a Brent tolerance of nan) and failed later or ran for ever."""
    with pytest.raises(error, match=re.escape(f"ContinuationSettings: {words}")):
        cn.ContinuationSettings(**{**SETTINGS, **change})


def test_continuation_settings_have_a_wall_time_budget_by_default():
    assert cn.ContinuationSettings(**SETTINGS).max_wall_time_s == 3600.0


@pytest.mark.parametrize(
    ("args", "error", "words"),
    [
        ((FREE, ORBIT_START, SETTINGS), TypeError, "settings must be a ContinuationSettings"),
        ((FREE, (0.0, 0.0), "S"), ValueError, "start_state must hold 4 numbers"),
        ((FREE, ORBIT_START, "S", 3), TypeError, "progress must be a callable"),
        ((FIG3, ORBIT_START, "S"), TypeError, "params must be a ModelParams, got dict"),
        ((ModelParams(nu=0.05, eta=0.7, e=0.1, K=10.0), ORBIT_START, "S"), ValueError,
         "params.eta = 0.7 lies outside the window [p_min, p_max] = [0.45, 0.55]"),
    ],
)  # fmt: skip
def test_continue_branch_refuses_bad_arguments_naming_them(args, error, words):
    """A start outside the window once returned a branch with status "ok"; a dict for the
    settings or a 2-value start failed deep inside."""
    settings = cn.ContinuationSettings(**SETTINGS, max_points=2, directions=(1,))
    args = tuple(settings if a == "S" else a for a in args)
    with pytest.raises(error, match=re.escape(f"continue_branch(): {words}")):
        cn.continue_branch(*args)


@pytest.mark.parametrize(
    ("options", "words"),
    [
        ({"client": object()}, "client must be a distributed.Client or None, got object"),
        ({"workers": 2.0}, "workers must be an int or None, got float"),
        ({"store_dir": 5}, "store_dir must be a path (a str or a Path) or None, got int"),
        ({"quick": "no"}, "quick must be True or False, got str"),  # once taken as true
        ({"oversubscribe": 1}, "oversubscribe must be True or False, got int"),
        ({"scheduler": 8786}, "scheduler must be an address (a str) or None, got int"),
    ],
)
def test_sweep_refuses_arguments_of_the_wrong_type(tmp_path, options, words):
    """Checked before the case is read (here a file that does not exist)."""
    from rubcli.sweeps import sweep

    with pytest.raises(TypeError, match=re.escape(f"sweep(): {words}")):
        sweep(tmp_path / "missing.toml", **options)


# ------------------------------------------------------------ the command line

CASE = """\
[case]
name = "hostile"

[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6
mu = 0.03
Rp = 46.16

[initial]
x = 0.88544
y = -0.8039

[time]
periods = 2
samples_per_period = 20

[solver]
methods = ["rk45"]
"""


def rubcli(tmp_path: Path, *args, limit_memory: bool = False) -> subprocess.CompletedProcess:
    """``python -m rubcli ARGS`` in ``tmp_path`` with a timeout (a hang fails the test);
    ``limit_memory``: the child's address space capped at 2 GiB (a read of an endless
    file fails there instead of taking the machine's memory)."""

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 * 1024**3, 2 * 1024**3))

    env = {**os.environ, "RUBCLI_STATE_DIR": str(tmp_path / ".state")}
    done = subprocess.run(
        [sys.executable, "-m", "rubcli", *map(str, args)], cwd=tmp_path, env=env,
        capture_output=True, text=True, timeout=TIMEOUT_S, check=False,
        preexec_fn=cap if limit_memory else None,
    )  # fmt: skip
    assert not TRACEBACK.search(done.stderr), done.stderr
    return done


def with_line(text: str, table: str, line: str) -> str:
    key = line.split(" = ")[0]
    lines = [ln for ln in text.splitlines() if not ln.startswith(f"{key} = ")]
    return "\n".join(lines).replace(f"[{table}]", f"[{table}]\n{line}") + "\n"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("line", "field"),
    [
        ("eta = 1e300", "model.eta"),  # once an OverflowError traceback in period
        ("K = 1e300", "model.K"),
        ("e = 1e308", "model.e"),
        ("eta = 1e-300", "model.eta"),
        ("K = 1e60", "model.K"),
    ],
)
def test_model_table_is_checked_like_the_physical_one(tmp_path, line, field):
    path = tmp_path / "case.toml"
    path.write_text(with_line(CASE, "model", line))
    for command in (["validate"], ["run", "--out", "out"]):
        done = rubcli(tmp_path, *command[:1], path, *command[1:])
        assert done.returncode == 2, done.stderr
        assert f"case.toml: {field}: " in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == ["case.toml"]


ORBITS = '[orbits]\nparameter = "mu"\nmin = 0.0\nmax = 0.06\nstep = 0.002\n'


@pytest.mark.slow
@pytest.mark.parametrize(
    ("table", "line", "field"),
    [
        ("solver", "atol = 1e-300", "solver.atol"),
        ("solver", "rtol = 1e-20", "solver.rtol"),
        ("orbits", "atol = 1e-300", "orbits.atol"),
    ],
)
def test_tolerances_are_bounded_as_solve_bounds_them(tmp_path, table, line, field):
    """atol = 1e-300 once passed validation and failed in dop853-jit and radau."""
    path = tmp_path / "case.toml"
    path.write_text(with_line(CASE + "\n" + ORBITS, table, line))
    done = rubcli(tmp_path, "validate", path)
    assert done.returncode == 2, done.stderr
    assert f"case.toml: {field}: " in done.stderr


@pytest.mark.slow
def test_physical_table_converting_beyond_the_domain_names_the_value(tmp_path):
    physical = CASE.replace(
        "[model]\nnu = 0.009478\neta = 0.7818\ne = 7.52\nK = 17.6\nmu = 0.03\nRp = 46.16",
        "[physical]\nm = 4.0\nk_r = 4.0e4\nd_r = 8.0\nk_s = 8.0e200\nclearance = 1.0e-3\n"
        "e = 2.0e-3\nOmega = 80.0",
    ).replace("x = 0.88544\ny = -0.8039", "x = 5.0e-4\ny = 0.0")
    path = tmp_path / "case.toml"
    path.write_text(physical)
    done = rubcli(tmp_path, "validate", path)
    assert done.returncode == 2, done.stderr
    assert "case.toml: physical: converts to K = 2e+196: must be at most 1e+100" in done.stderr


@pytest.mark.slow
def test_validate_refuses_special_files_at_once(tmp_path):
    """A FIFO once hung ``rubcli validate`` until killed; /dev/zero ended in a MemoryError
    after 5.3 GB (here the child's memory is capped at 2 GiB: reading it would fail)."""
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for path, words in ((fifo, "a FIFO"), (Path("/dev/zero"), "a character device")):
        done = rubcli(tmp_path, "validate", path, limit_memory=True)
        assert done.returncode == 2, done.stderr
        assert f"{path}: is not a regular file ({words}), not a case file" in done.stderr


@pytest.mark.slow
def test_validate_refuses_deep_nesting_and_huge_files(tmp_path):
    """A deeply nested TOML once ended in a RecursionError traceback."""
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")
    huge = tmp_path / "huge.toml"
    huge.write_text("# " + "x" * (9 * 1024**2) + "\n")
    for path, words in ((deep, "nested too deeply"), (huge, "is larger than 8 MiB")):
        done = rubcli(tmp_path, "validate", path, limit_memory=True)
        assert done.returncode == 2, done.stderr
        assert words in done.stderr


@pytest.mark.slow
@pytest.mark.parametrize(
    ("table", "words"),
    [
        ('[sweep]\nparameter = "eta"\nvalues = [0.5, 1e-200]\n',
         "sweep: every value of eta must be at least 1e-100"),  # a traceback per point
        ('[sweep]\nparameter = "K"\nvalues = [10.0, 1e60]\n',
         "sweep: at K = 1e+60, eta = 0.7818: a contact oscillation"),
        ('[sweep]\nparameter = "x"\nvalues = [0.0, 1e200]\n',
         "sweep: every value of x must be at most 1e+100"),
        ('[orbits]\nparameter = "mu"\nmin = 0.0\nmax = 1e200\nstep = 1e198\n',
         "orbits: mu must be at most 1e+100"),
    ],
)  # fmt: skip
def test_sweep_and_orbit_values_are_checked_against_the_domain(tmp_path, table, words):
    """Every point a sweep or a continuation window can reach lies in the model's domain
    (a sweep over eta down to 1e-200 once failed point by point with a traceback)."""
    path = tmp_path / "case.toml"
    path.write_text(CASE + "\n" + table)
    done = rubcli(tmp_path, "validate", path)
    assert done.returncode == 2, done.stderr
    assert f"case.toml: {words}" in done.stderr

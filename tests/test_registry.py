"""The method registry (rubcli/solvers/registry.py) and solve()'s handling of options."""

import pytest

from rubcli.analysis.work_precision import ladder
from rubcli.case import KNOWN_METHODS
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import METHODS, registry, solve

PROBLEM = Problem.from_periods(ModelParams(0.01, 0.78, 0.1, 17.6), (0.1, 0.0, 0.0, 0.0), 1, 8)


def test_every_spec_has_a_solver_and_the_case_schema_lists_them():
    assert set(METHODS) == set(registry.SPECS) == set(KNOWN_METHODS)


def test_a_misspelled_option_is_a_type_error_naming_it():
    with pytest.raises(TypeError, match="'rtoll'"):
        solve(PROBLEM, "dop853-jit", rtoll=1e-9)
    with pytest.raises(TypeError, match="'step_per_period'"):
        solve(PROBLEM, "analytic", step_per_period=100)


def test_solver_functions_reject_unknown_keywords():
    """The solver functions themselves have no catch-all: a typo never vanishes."""
    for fn in METHODS.values():
        with pytest.raises(TypeError, match="no_such_option"):
            fn(PROBLEM, no_such_option=1)


def test_shared_settings_reach_each_method_as_its_own():
    settings = {"rtol": 1e-3, "atol": 1e-5, "steps_per_period": 7, "max_steps": 99}
    assert registry.options_for("analytic", settings) == {"steps_per_period": 7, "max_steps": 99}
    assert registry.options_for("rk45", settings) == {"rtol": 1e-3, "atol": 1e-5, "max_steps": 99}
    analytic = solve(PROBLEM, "analytic", **registry.options_for("analytic", settings))
    assert analytic.settings["steps_per_period"] == 7
    assert solve(PROBLEM, "rk45", **registry.options_for("rk45", settings)).settings["rtol"] == 1e-3


def test_an_option_of_another_method_is_refused_not_dropped():
    """``solve(p, "analytic", rtol=1e-12)`` once ran at the default steps without a word."""
    with pytest.raises(TypeError, match=r"'rtol'.*'analytic' does not take.*options_for"):
        solve(PROBLEM, "analytic", rtol=1e-12)
    with pytest.raises(TypeError, match="'steps_per_period'.*'dop853-jit' does not take"):
        solve(PROBLEM, "dop853-jit", steps_per_period=100)
    with pytest.raises(TypeError, match="did you mean 'rtol'"):
        solve(PROBLEM, "rk45", rtoll=1e-6)


def test_ladders_follow_each_methods_knob():
    rows = ladder(["analytic-polar", "dop853-jit"], rtols=(1e-4, 1e-6), steps_per_period=(50,))
    assert [(s.method, s.name, s.value) for s in rows] == [
        ("analytic-polar", "steps_per_period", 50),
        ("dop853-jit", "rtol", 1e-4),
        ("dop853-jit", "rtol", 1e-6),
    ]


def test_unknown_method():
    with pytest.raises(ValueError, match="unknown method 'rk99'"):
        solve(PROBLEM, "rk99")
    with pytest.raises(ValueError, match="choose from"):
        registry.spec("rk99")

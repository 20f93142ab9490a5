"""The method registry (rubcli/solvers/registry.py) and solve()'s handling of options."""

import pytest

from rubcli.analysis.accuracy.work_precision import ladder
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


def test_typed_options_reject_unknown_fields_and_bad_values():
    """Each method's options are a typed object with no catch-all: a typo never vanishes,
    and every field is checked on construction."""
    for spec in registry.SPECS.values():
        with pytest.raises(TypeError, match="no_such_option"):
            spec.options(no_such_option=1)
        assert spec.takes == spec.options.names()
        assert {"max_steps", "max_wall_time_s", "compiled", "progress"} <= set(spec.takes)
        assert spec.knob in spec.takes
        assert spec.adaptive is None or spec.adaptive in spec.takes
    with pytest.raises(ValueError, match="option rtol must satisfy 0 < rtol < 1"):
        registry.ToleranceOptions(rtol=2.0)
    with pytest.raises(TypeError, match="option steps_per_period must be an int"):
        registry.StepOptions(steps_per_period=2.5)


def test_every_family_has_its_module_and_every_method_its_family():
    """``solve`` imports a method's family module, which registers the method."""
    families = {spec.family for spec in registry.SPECS.values()}
    assert families == set(registry.FAMILY_MODULES)
    for name, spec in registry.SPECS.items():
        assert METHODS[name].__module__ == registry.FAMILY_MODULES[spec.family] or (
            spec.family == "scipy"  # partial objects of scipy_ivp.solve_scipy
            and METHODS[name].func.__module__ == registry.FAMILY_MODULES["scipy"]
        )


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


def test_the_method_table_of_the_docs_is_the_registrys():
    """docs/solvers.md shows ``registry.method_table()``, word for word."""
    from pathlib import Path

    docs = (Path(__file__).parents[1] / "docs" / "solvers.md").read_text()
    assert registry.method_table() in docs


def test_the_library_exports_orbits_continuation_and_events():
    """The studies a script needs are top-level names, typed (PEP 561)."""
    import importlib.resources

    import rubcli

    for name in rubcli.__all__:
        assert getattr(rubcli, name) is not None
    params = ModelParams(nu=0.05, eta=0.5, e=0.1, K=10.0)
    orbit = rubcli.shoot(params, [0.0, 0.0, 0.0, 0.0])
    assert orbit.stable and orbit.k == 1  # the free whirl, inside the clearance
    settings = rubcli.ContinuationSettings(
        parameter="eta", p_min=0.45, p_max=0.55, step=0.02, max_points=2, directions=(1,)
    )
    assert settings.min_step == 0.02 / 1000 and settings.max_step == 5 * 0.02
    branch = rubcli.continue_branch(params, orbit.state, settings)
    assert branch.status == "ok" and len(branch.points) == 3
    with pytest.raises(TypeError):
        rubcli.ContinuationSettings("eta", 0.45, 0.55, 0.02)  # keywords only
    with pytest.raises(ValueError, match="p_min must be below p_max"):
        rubcli.ContinuationSettings(parameter="eta", p_min=0.6, p_max=0.5, step=0.01)
    with pytest.raises(ValueError, match="parameter 'omega' is not one of"):
        rubcli.ContinuationSettings(parameter="omega", p_min=0.4, p_max=0.5, step=0.01)
    sol = solve(PROBLEM, "analytic")
    assert isinstance(sol.events, rubcli.Events)
    assert importlib.resources.files("rubcli").joinpath("py.typed").is_file()

"""`rubcli compare`: the reference is what it says, errors fall, the CLI writes what it says.

Numbers come from the exact solutions of model.py (free flight, synchronous rub), from an
independent method, or from a property of the equations (for mu = 0 the damping is
proportional to the mass, so every Floquet exponent of a stable orbit has real part -nu).
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.accuracy import reference as refm
from rubcli.analysis.accuracy import work_precision as wpm
from rubcli.analysis.orbits.synchronous import started_on_synchronous_rub, synchronous_rubs
from rubcli.cli.app import app
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16}


def fig3_params(mu: float) -> ModelParams:
    return ModelParams(mu=mu, **FIG3)


def on_rub_problem(mu: float, periods: float, samples: int = 50) -> Problem:
    params = fig3_params(mu)
    start = model.synchronous_rub(np.array([0.0]), params)[:, 0]
    return Problem.from_periods(params, start, periods, samples)


# ------------------------------------------------------------------- reference


def test_free_flight_reference_is_the_closed_form():
    params = ModelParams(nu=0.05, eta=0.5, e=0.5, K=10.0)  # steady radius 0.167 < 1
    problem = Problem.from_periods(params, (0.3, 0.0, 0.0, 0.1), 4, 40)
    ref = refm.reference_solution(problem)
    assert ref.kind == refm.EXACT_FREE_FLIGHT and ref.exact
    # independent: the free equation x'' + 2 nu x' + x = E cos(eta t) (and sin for y)
    # integrated by scipy's DOP853 at rtol 1e-13
    from scipy.integrate import solve_ivp

    def free(t, s):
        x, y, vx, vy = s
        phase = params.eta * t + params.phi0
        return [vx, vy, params.E * math.cos(phase) - 2 * params.nu * vx - x,
                params.E * math.sin(phase) - 2 * params.nu * vy - y]  # fmt: skip

    span = (problem.t_eval[0], problem.t_eval[-1])
    numeric = solve_ivp(free, span, problem.initial, method="DOP853", t_eval=problem.t_eval,
                        rtol=1e-13, atol=1e-14).y.T  # fmt: skip
    assert np.max(np.abs(ref.states - numeric)) < 1e-11
    assert ref.error_estimate < 1e-13
    assert not ref.horizon_limited


def test_a_free_flight_that_touches_the_stator_is_not_taken_as_exact():
    # Same rotor, larger unbalance: the free orbit reaches z > 1 (radius 0.67 * 2 ...).
    params = ModelParams(nu=0.05, eta=0.5, e=3.0, K=10.0)
    problem = Problem.from_periods(params, (0.9, 0.0, 0.0, 0.0), 3, 40)
    closed = model.free_flight(problem.t_eval, 0.0, problem.initial, params)
    assert np.hypot(closed[0], closed[1]).max() > 1.0
    assert not refm.free_flight_stays_free(problem)
    assert refm.exact_reference(problem) is None


def test_synchronous_rub_reference_is_exact_and_knows_its_stability():
    problem = on_rub_problem(0.0, 3)
    ref = refm.reference_solution(problem)
    assert ref.kind == refm.EXACT_SYNCHRONOUS_RUB
    np.testing.assert_allclose(np.hypot(ref.states[:, 0], ref.states[:, 1]), 1.23389475778)
    assert ref.synchronous.stable
    # A start slightly off the orbit is not exact.
    off = Problem(problem.params, (problem.initial[0] + 1e-6, *problem.initial[1:]), problem.t_eval)
    assert started_on_synchronous_rub(off.params, off.initial) is None


def test_synchronous_rub_stability_mu_zero_has_floquet_real_parts_minus_nu():
    # mu = 0: w = exp(-nu tau) v turns the linearisation into an undamped Hill equation,
    # so on a stable orbit every exponent has real part exactly -nu.
    (rub,) = synchronous_rubs(fig3_params(0.0))
    np.testing.assert_allclose(rub.eigenvalues.real, -FIG3["nu"], atol=1e-12)


@pytest.mark.parametrize("mu", [0.0, 0.02])
def test_synchronous_rub_stability_matches_a_perturbed_simulation(mu):
    """The predicted growth rate of a small perturbation, measured with dop853."""
    (rub,) = synchronous_rubs(fig3_params(mu))
    problem = on_rub_problem(mu, 14, 4)
    start = np.array(problem.initial) + np.array([1e-5, 0.0, 0.0, 0.0])
    perturbed = Problem(problem.params, tuple(start), problem.t_eval)
    sol = solve(perturbed, "dop853", rtol=1e-11, atol=1e-13)
    assert sol.success
    exact = model.synchronous_rub(sol.t, problem.params, rub.r).T
    dev = np.linalg.norm(sol.states - exact, axis=1)
    # Fit the envelope: log of the per-period maximum against time.
    per = dev.reshape(-1)[1:].reshape(14, 4).max(axis=1)
    rate = np.polyfit(problem.params.period * np.arange(1, 15), np.log(per), 1)[0]
    assert rate == pytest.approx(rub.growth_rate, abs=0.003)
    assert (rate > 0) == (not rub.stable)


def test_numerical_reference_error_estimate_is_honest():
    # Force the numerical path on a problem whose exact solution is known.
    problem = on_rub_problem(0.01, 4)
    ref = refm.numerical_reference(problem)
    exact = model.synchronous_rub(problem.t_eval, problem.params).T
    actual = np.abs((ref.states[:, 0] - exact[:, 0]) + 1j * (ref.states[:, 1] - exact[:, 1]))
    assert ref.kind == refm.NUMERICAL and not ref.exact
    assert 0.0 < ref.error_estimate < 1e-8
    assert actual.max() <= 2.0 * ref.error_estimate  # the estimate does not flatter
    assert not ref.horizon_limited


def test_predictability_horizon_cuts_where_the_references_separate():
    t = np.linspace(0.0, 10.0, 11)
    deviation = 1e-12 * np.exp(3.0 * t)  # crosses 1e-6 between t = 4 and t = 5
    assert refm.trusted_span(t, deviation, 1e-6) == 5
    assert refm.trusted_span(t, np.zeros(11), 1e-6) == 11
    assert refm.trusted_span(t, np.full(11, np.nan), 1e-6) == 1
    # On the rotor: a threshold below the references' difference limits the horizon.
    problem = Problem.from_periods(fig3_params(0.02), (0.88544, -0.8039, 0, 0), 3, 30)
    ref = refm.numerical_reference(problem, threshold=1e-13)
    assert ref.horizon_limited
    assert ref.error_estimate <= 1e-13
    assert np.all(ref.deviation[: ref.n_trusted] <= 1e-13)
    assert "horizon of predictability" in " ".join(ref.notes)


# --------------------------------------------------------------- work-precision


@pytest.fixture(scope="module")
def ladder_result():
    problem = on_rub_problem(0.0, 2)
    ref = refm.reference_solution(problem)
    settings = wpm.ladder(["rk45", "analytic"], (1e-3, 1e-6, 1e-9), (25, 100, 400))
    return problem, wpm.run_work_precision(problem, ref, settings, repeats=2)


def test_errors_fall_as_settings_tighten(ladder_result):
    _, result = ladder_result
    for method in ("rk45", "analytic"):
        rows = result.rows_of(method)
        errors = [r.error_max for r in rows]
        assert all(r.success for r in rows)
        assert errors[0] > 10 * errors[1] > 100 * errors[2]
    assert set(result.startup_s) == {"rk45", "analytic"}
    assert all(r.repeats == 2 for r in result.rows)


def test_row_errors_are_those_against_the_exact_orbit(ladder_result):
    problem, result = ladder_result
    (row,) = [r for r in result.rows if r.method == "rk45" and r.setting == 1e-6]
    sol = solve(problem, "rk45", rtol=1e-6, atol=1e-8)
    exact = model.synchronous_rub(sol.t, problem.params)
    err = np.abs(sol.w - (exact[0] + 1j * exact[1]))
    assert row.error_max == pytest.approx(err.max(), rel=1e-12)
    assert row.error_final == pytest.approx(err[-1], rel=1e-12)
    assert row.nsteps == sol.stats["nsteps"]


def test_cheapest_method_for_a_target():
    def row(method, time_s, err):
        return wpm.Row(method, "rtol", 1e-6, time_s, time_s, 1, err, err, 1, 1, 0, 0,
                       "success", "")  # fmt: skip

    rows = [row("a", 1.0, 1e-4), row("b", 0.5, 1e-2), row("c", 2.0, 1e-7)]
    assert wpm.cheapest_for(rows, 1e-3).method == "a"
    assert wpm.cheapest_for(rows, 1e-1).method == "b"
    assert wpm.cheapest_for(rows, 1e-6).method == "c"
    assert wpm.cheapest_for(rows, 1e-9) is None


# ------------------------------------------------------------------------ CLI


def _case_text(params: ModelParams, start, periods: float, extra: str = "") -> str:
    x, y, vx, vy = (repr(float(v)) for v in start)
    return f"""
[case]
name = "cli-compare"

[model]
nu = {params.nu!r}
eta = {params.eta!r}
e = {params.e!r}
K = {params.K!r}
mu = {params.mu!r}
Rp = {params.Rp!r}

[initial]
x = {x}
y = {y}
vx = {vx}
vy = {vy}

[time]
periods = {periods}
samples_per_period = 40

[solver]
methods = ["rk45", "analytic"]
rtol = 1e-6
atol = 1e-8
steps_per_period = 100
{extra}
"""


@pytest.mark.slow
def test_cli_compare_quick_writes_consistent_outputs(tmp_path):
    params = fig3_params(0.0)
    start = model.synchronous_rub(np.array([0.0]), params)[:, 0]
    case = tmp_path / "case.toml"
    case.write_text(_case_text(params, start, 2))
    out = tmp_path / "cmp"
    result = CliRunner().invoke(app, ["compare", str(case), "--out", str(out), "--quick"])
    assert result.exit_code == 0, result.output
    for name in ("work_precision.csv", "work_precision.png", "error_growth.png", "orbits.png",
                 "report.md", "report.json"):  # fmt: skip
        assert (out / name).is_file(), name
    assert not (out / "poincare.png").exists()  # not asked for
    rows = list(csv.DictReader((out / "work_precision.csv").open()))
    assert list(rows[0])[:5] == ["method", "setting", "wall_time_s", "error_max", "error_final"]
    assert {(r["method"], float(r["setting"])) for r in rows} >= {("rk45", 1e-6), ("analytic", 100)}
    report = json.loads((out / "report.json").read_text())
    assert report["reference"]["kind"] == refm.EXACT_SYNCHRONOUS_RUB
    assert report["response"] is None
    assert "Cheapest method" in (out / "report.md").read_text()

    # The same setting through `rubcli run`: its CSV has the error the ladder reported.
    run_dir = tmp_path / "run"
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(run_dir)])
    assert result.exit_code == 0, result.output
    for method, setting in (("rk45", 1e-6), ("analytic", 100.0)):
        data = np.genfromtxt(run_dir / f"{method}.csv", delimiter=",", names=True)
        exact = model.synchronous_rub(data["tau"], params)
        err = np.hypot(data["x"] - exact[0], data["y"] - exact[1])
        (row,) = [r for r in rows if r["method"] == method and float(r["setting"]) == setting]
        assert float(row["error_max"]) == pytest.approx(err.max(), rel=1e-6)
        assert float(row["error_final"]) == pytest.approx(err[-1], rel=1e-6, abs=1e-15)


@pytest.mark.slow
def test_cli_compare_response_and_mu_sweep(tmp_path):
    params = fig3_params(0.0)
    start = model.synchronous_rub(np.array([0.0]), params)[:, 0]
    extra = """
[compare]
work_precision = false
mu = [0.0, 0.01]

[analysis]
response = true
transient_periods = 1
lyapunov = false
"""
    case = tmp_path / "case.toml"
    case.write_text(_case_text(params, start, 10, extra).replace('"rk45", "analytic"', '"rk45"'))
    out = tmp_path / "sweep"
    result = CliRunner().invoke(app, ["compare", str(case), "--out", str(out), "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    assert json.loads(result.stdout) == report  # --json: stdout is the report, nothing else
    assert report["work_precision"] is None and not (out / "work_precision.csv").exists()
    # Started on the mu = 0 rub, which is stable: period 1.
    assert report["response"]["kind"] == "periodic" and report["response"]["period"] == 1
    sweep = list(csv.DictReader((out / "sweep.csv").open()))
    assert [float(r["mu"]) for r in sweep] == [0.0, 0.01]
    assert sweep[0]["sync_rub_stable"] == "true"
    assert (out / "poincare.png").is_file() and (out / "orbits.png").is_file()


def test_cli_compare_rejects_an_unknown_compare_key(tmp_path):
    params = fig3_params(0.0)
    case = tmp_path / "bad.toml"
    case.write_text(_case_text(params, (0.5, 0, 0, 0), 1, "[compare]\nrtol = 1e-3\n"))
    result = CliRunner().invoke(app, ["compare", str(case), "--out", str(tmp_path / "x")])
    assert result.exit_code == 2
    assert "compare.rtol" in result.output
    assert not (tmp_path / "x").exists()


def test_observed_order_of_a_known_power_law():
    rows = [
        wpm.Row(
            "analytic",
            "steps_per_period",
            n,
            1.0,
            1.0,
            1,
            3.0 * n**-2.0,
            0.0,
            1,
            1,
            0,
            0,
            "success",
            "",
        )  # fmt: skip
        for n in (25, 50, 100)
    ]
    assert wpm.observed_order(rows) == pytest.approx(2.0)


@pytest.mark.slow
def test_run_with_analysis_response_reports_the_class(tmp_path):
    params = fig3_params(0.0)
    start = model.synchronous_rub(np.array([0.0]), params)[:, 0]
    extra = "\n[analysis]\nresponse = true\ntransient_periods = 1\nlyapunov = false\n"
    case = tmp_path / "case.toml"
    case.write_text(_case_text(params, start, 10, extra).replace('"rk45", "analytic"', '"rk45"'))
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    assert (report["response"]["kind"], report["response"]["period"]) == ("periodic", 1)
    assert report["methods"]["rk45"]["response"]["kind"] == "periodic"
    assert (out / "poincare.png").is_file()
    # Without [analysis] nothing is computed or written.
    case.write_text(_case_text(params, start, 2).replace('"rk45", "analytic"', '"rk45"'))
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "plain")])
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "plain" / "report.json").read_text())["response"] is None
    assert not (tmp_path / "plain" / "poincare.png").exists()

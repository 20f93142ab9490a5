"""Run budgets, regime times and the energy balance through `rubcli run` (the real CLI).

``[solver] max_steps`` and ``max_wall_time_s`` reach every method from the case file; a
run that exceeds one stops with status ``failed``, the partial result kept (CSV rows up
to where it stopped, no NaN) and the reason in report.json. report.json carries, per
method, the time spent in each regime (from the located switch times) and the energy
residual; ``plots = ["energy"]`` adds energy.png, which is never written by default.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import model
from rubcli.case import load_case
from rubcli.cli.app import app
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import FAILED
from rubcli.solvers import METHODS, solve
from rubcli.solvers.registry import NAMES as ALL_METHODS

runner = CliRunner()

# The stick-slip case of tests/test_stick.py: contact all the time, stick and slip+.
R_ROLL = model.rolling_whirl_radius(model.ModelParams(0.01, 1.0, 0.05, 100.0, 0.02, 2.0))
CASE = f"""\
[case]
name = "stickslip"

[model]
nu = 0.01
eta = 1.0
e = 0.05
K = 100.0
mu = 0.02
Rp = 2.0

[initial]
x = {R_ROLL!r}
y = 0.0
vx = 0.0
vy = -2.0

[time]
periods = 2
samples_per_period = 50

[solver]
methods = ["dop853"]
rtol = 1e-10
atol = 1e-12
"""


def run(tmp_path: Path, solver: str = "", output: str = "plots = []\n", methods=None):
    text = CASE + solver + "\n[output]\n" + output
    path = tmp_path / "case.toml"
    path.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    args = ["run", str(path), "--out", str(out)]
    for method in methods or []:
        args += ["--method", method]
    result = runner.invoke(app, args)
    report = (
        json.loads((out / "report.json").read_text()) if (out / "report.json").exists() else None
    )
    return result, out, report


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_budget_keys_reach_every_method_from_the_case(tmp_path):
    case_text = CASE + "max_steps = 123\nmax_wall_time_s = 45.5\n"
    path = tmp_path / "case.toml"
    path.write_text(case_text, encoding="utf-8")
    case = load_case(path)
    assert case.solver_options["max_steps"] == 123
    assert case.solver_options["max_wall_time_s"] == 45.5
    result, _, report = run(
        tmp_path, "max_steps = 123\nmax_wall_time_s = 45.5\n", methods=list(METHODS)
    )
    for name in METHODS:
        settings = report["methods"][name]["settings"]
        assert settings["max_steps"] == 123 and settings["max_wall_time_s"] == 45.5, name


@pytest.mark.parametrize("method", ["analytic", "rk45", "radau"])
def test_step_budget_fails_cleanly_with_partial_result(tmp_path, method):
    result, out, report = run(tmp_path, "max_steps = 40\n", methods=[method])
    assert result.exit_code == 1
    entry = report["methods"][method]
    assert entry["status"] == "failed"
    assert "max_steps = 40" in entry["message"]
    assert f"method {method} failed" in result.stderr
    rows = read_rows(out / f"{method}.csv")
    assert 1 < len(rows) < 101  # partial: stopped before the last of the 101 samples
    values = np.array([[float(r[k]) for k in ("tau", "x", "y", "vx", "vy")] for r in rows])
    assert np.all(np.isfinite(values))
    assert entry["tau_end"] == pytest.approx(values[-1, 0])
    assert sum(entry["time_in_regime"].values()) == pytest.approx(values[-1, 0], rel=1e-12)
    assert math.isfinite(entry["energy_residual"])


def test_wall_time_budget_fails_cleanly(tmp_path):
    # 1 ms cannot cover 2000 periods of the stick-slip cycle with rk45
    text = "max_wall_time_s = 0.001\n"
    path = tmp_path / "case.toml"
    path.write_text(CASE.replace("periods = 2", "periods = 2000") + text, encoding="utf-8")
    out = tmp_path / "out"
    result = runner.invoke(
        app, ["run", str(path), "--out", str(out), "--method", "rk45", "--periods", "2000"]
    )
    assert result.exit_code == 1
    entry = json.loads((out / "report.json").read_text())["methods"]["rk45"]
    assert entry["status"] == "failed"
    assert "wall-time budget exhausted (max_wall_time_s = 0.001)" in entry["message"]
    assert entry["n_samples"] < 2000 * 50 + 1


def test_report_has_time_in_regimes_and_energy_residual(tmp_path):
    result, out, report = run(tmp_path)
    assert result.exit_code == 0, result.output
    entry = report["methods"]["dop853"]
    durations = entry["time_in_regime"]
    assert set(durations) == {"free", "slip+", "slip-", "stick"}
    assert durations["stick"] > 0 and durations["slip+"] > 0 and durations["free"] == 0.0
    span = report["case"]["nondimensional"]["t_span"][1]
    assert sum(durations.values()) == pytest.approx(span, rel=1e-12)
    assert entry["contact_fraction"] == pytest.approx(1.0)
    # dop853 at rtol 1e-10 balances to quadrature level at 50 samples per period
    # (the residual falls 16-20x per doubling of the samples: tests/test_energy.py)
    assert 0.0 <= entry["energy_residual"] < entry["energy"]["energy_quadrature_error"] < 1e-4
    # the reported terms: the mechanical energy change recomputed from the CSV's first and
    # last states (kinetic + rotor spring + stator K (z - 1)^2 / 2), and the residual from
    # the reported totals
    energy = entry["energy"]
    rows = read_rows(out / "dop853.csv")

    def mechanical(row):
        x, y, vx, vy = (float(row[k]) for k in ("x", "y", "vx", "vy"))
        z = math.hypot(x, y)
        return 0.5 * (vx * vx + vy * vy + x * x + y * y) + 0.5 * 100.0 * max(z - 1.0, 0.0) ** 2

    change = mechanical(rows[-1]) - mechanical(rows[0])
    assert energy["energy_change"] == pytest.approx(change, rel=1e-9, abs=1e-12)
    balance = energy["work_unbalance"] - energy["damping_dissipation"]
    balance -= energy["friction_dissipation"]
    recomputed = abs(energy["energy_change"] - balance) / energy["energy_throughput"]
    assert entry["energy_residual"] == pytest.approx(recomputed, rel=1e-6, abs=1e-15)
    names = [row["regime_name"] for row in read_rows(out / "dop853.csv")]
    assert set(names) == {"stick", "slip+"}
    assert "energy.png" not in {p.name for p in out.iterdir()}  # not by default


@pytest.mark.slow
def test_energy_plot_when_asked(tmp_path):
    result, out, report = run(tmp_path, output='plots = ["energy"]\n', methods=["dop853", "rk45"])
    assert result.exit_code == 0, result.output
    assert (out / "energy.png").stat().st_size > 10_000
    assert "energy.png" in report["files"]
    assert "orbit.png" not in report["files"]


ABSURD = {
    "K = 1e200": ({"K": 1e200}, "K must be at most 1e+100"),
    "K = 1e308, e = 1e300": ({"K": 1e308, "e": 1e300}, "e must be at most 1e+100"),
    "eta = 1e-300": ({"K": 17.6, "eta": 1e-300}, "eta must be at least 1e-100"),
}
# The edge of the model's domain (docs/cases.md): K where contact is only just resolvable
# in doubles over 50 periods, and the largest forcing.
EDGE = {
    "K = 1e19": {"K": 1e19},
    "e = 1e100": {"K": 17.6, "e": 1e100},
    "K = 1e19, e = 1e100": {"K": 1e19, "e": 1e100},
}


@pytest.mark.parametrize("label", list(ABSURD))
def test_absurd_magnitudes_are_refused_at_the_boundary(label):
    """Parameters beyond floating-point sense are refused by ModelParams, naming the
    parameter (they once ran a method's whole budget, or overflowed in ``period``)."""
    values, words = ABSURD[label]
    with pytest.raises(ValueError, match=re.escape(f"ModelParams: {words}")):
        ModelParams(**{"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16, **values})


@pytest.mark.slow
@pytest.mark.parametrize("method", sorted(ALL_METHODS))
@pytest.mark.parametrize("label", list(EDGE))
def test_magnitudes_at_the_edge_of_the_domain_fail_cleanly_within_the_budget(method, label):
    """At the edge of the domain every method ends as a failed method with its reason,
    within the step budget: no hang (the analytic methods once looped for ever balancing a
    matrix whose norm overflowed), no exception (dop853-jit once raised ZeroDivisionError)."""
    params = ModelParams(**{"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16, **EDGE[label]})
    problem = Problem.from_periods(params, (0.88544, -0.8039, 0.0, 0.0), 50, 100)
    sol = solve(problem, method, max_steps=1000, max_wall_time_s=1e9)
    assert sol.status == FAILED
    assert sol.message and "Traceback" not in sol.message
    assert sol.t.size >= 1 and sol.stats["nsteps"] <= 1000


def test_start_up_warm_up_has_budgets_of_its_own(tmp_path, monkeypatch):
    """The warm-up before the timed runs (``rubcli run``'s start-up, compare's warm-up
    solve) is bounded by its own small budgets, never the run's: ``K = 1e300 -m lsoda``
    once spent its 5e6-step budget there before the timed run spent it again."""
    from rubcli import solvers
    from rubcli.analysis.accuracy import work_precision
    from rubcli.studies import run

    path = tmp_path / "case.toml"
    path.write_text(CASE.replace('methods = ["dop853"]', 'methods = ["lsoda", "analytic"]'))
    case = load_case(path)
    assert case.options_for("lsoda")["max_steps"] == 5_000_000
    seen = []
    real_solve = solvers.solve

    def spy(problem, method, **options):
        seen.append((method, options["max_steps"], options["max_wall_time_s"]))
        return real_solve(problem, method, **options)

    monkeypatch.setattr(solvers, "solve", spy)
    run.start_up(case)
    work_precision.warm_up(case.problem, "lsoda", case.options_for("lsoda"))
    assert [m for m, _, _ in seen] == ["lsoda", "analytic", "lsoda"]
    for _, steps, wall in seen:
        assert steps <= solvers.WARM_UP_MAX_STEPS and wall <= solvers.WARM_UP_WALL_TIME_S

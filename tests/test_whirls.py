"""Whirls of unknown rate on the symmetric machine (analysis/orbits/whirls.py, `[orbits] kind =
"whirl"`), against closed forms and direct integration.

The paper's machine without unbalance (Figure 3 caption values, e = 0) at mu = 0.05 has
two whirls in contact: the rolling whirl of ``model.rolling_whirl_radius`` (the dry whip)
and a slipping backward whirl (the dry whirl), whose radius solves
``(mu K s / 2 nu)^2 = 1 + K s``, ``s = 1 - 1/r``. Their stability is checked by
integrating the full nonsmooth model (dop853-jit, which locates contact, slip reversal
and stick itself) from a small offset: the slipping whirl's offset grows at its positive
eigenvalue, the rolling whirl's decays at -nu, the real part of both eigenvalues of its
radial motion on the rolling constraint.
"""

import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.orbits import whirls as wh
from rubcli.cli.app import app
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

PAPER = {"nu": 0.009478, "eta": 0.7818, "e": 0.0, "K": 17.6, "Rp": 46.16}
REPO_CASE = "cases/paper/fig3-whirls.toml"


def paper(mu=0.05, **changes) -> ModelParams:
    return ModelParams(**{**PAPER, "mu": mu, **changes})


def slip_radius(p: ModelParams) -> float:
    """The quadratic of the module docstring, solved independently."""
    a = (p.mu * p.K / (2 * p.nu)) ** 2
    s = np.roots([a, -p.K, -1.0]).real.max()
    return 1.0 / (1.0 - s)


def test_the_paper_machine_has_a_slipping_saddle_and_the_rolling_whirl():
    p = paper()
    slipping, rolling = wh.whirls(p)
    assert (slipping.mode, rolling.mode) == (wh.SLIP_POSITIVE, wh.ROLLING)
    # rolling: the closed form of the model, v_r = 0, inside the friction cone
    assert rolling.radius == pytest.approx(model.rolling_whirl_radius(p), rel=1e-14)
    assert rolling.rate == pytest.approx(-p.Rp * p.eta / rolling.radius, rel=1e-14)
    assert rolling.order == pytest.approx(-5.2134, abs=1e-4)  # the dry whip's -5.21X
    assert rolling.friction_needed == pytest.approx(2 * p.nu * p.Rp * p.eta
                                                    / (p.K * (rolling.radius - 1)))  # fmt: skip
    assert rolling.friction_needed < p.mu and rolling.stable
    # slipping: backward, just outside the clearance, a saddle (one real positive root)
    assert slipping.radius == pytest.approx(slip_radius(p), rel=1e-12)
    assert slipping.rate < 0.0 and slipping.slip_velocity > 0.0
    assert slipping.rate**2 == pytest.approx(1 + p.K * (1 - 1 / slipping.radius), rel=1e-12)
    assert slipping.n_unstable == 1 and not slipping.stable
    lead = slipping.nontrivial[np.argmax(slipping.nontrivial.real)]
    assert lead.real > 0.0 and lead.imag == 0.0
    # the turn of the whole whirl is neutral: one eigenvalue is zero
    assert np.min(np.abs(slipping.eigenvalues)) < 1e-12


def test_slipping_whirl_departs_at_its_eigenvalue_in_a_direct_integration():
    p = paper()
    slipping = wh.whirls(p)[0]
    r0 = slipping.radius * (1.0 + 1e-8)
    problem = Problem.from_periods(p, (r0, 0.0, 0.0, r0 * slipping.rate), 30, 64)
    sol = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14)
    assert sol.success, sol.message
    offset = np.abs(sol.z - slipping.radius)
    window = (offset > 1e-6) & (offset < 1e-3)  # linear, above the start's transient
    rate = np.polyfit(sol.t[window], np.log(offset[window]), 1)[0]
    assert rate == pytest.approx(slipping.growth_rate, rel=0.01)


def test_rolling_whirl_holds_and_decays_at_minus_nu_in_a_direct_integration():
    p = paper()
    rolling = wh.whirls(p)[1]
    r0 = rolling.radius * (1.0 + 1e-3)  # rolling (v_r = 0) but off the radius
    problem = Problem.from_periods(p, (r0, 0.0, 0.0, -p.Rp * p.eta), 40, 64)
    sol = solve(problem, "dop853-jit", rtol=1e-10, atol=1e-12)
    assert sol.success, sol.message
    assert np.all(sol.regimes == model.STICK)  # it rolls throughout
    offset = np.abs(sol.z - rolling.radius)
    period = p.period
    first, last = offset[sol.t < period].max(), offset[sol.t > sol.t[-1] - period].max()
    decay = math.log(last / first) / (sol.t[-1] - period)
    assert decay == pytest.approx(rolling.growth_rate, rel=0.02)  # = -nu
    # and it rings at the imaginary part of that pair: sqrt(c - nu^2), c = (Rp eta/r)^2 + 1 + K
    signed = sol.z - rolling.radius
    crossings = np.count_nonzero(np.diff(np.sign(signed)) != 0)
    ring = math.pi * crossings / (sol.t[-1] - sol.t[0])
    assert ring == pytest.approx(abs(rolling.nontrivial[0].imag), rel=0.01)
    theta = np.unwrap(np.arctan2(sol.states[:, 1], sol.states[:, 0]))
    late = sol.t > sol.t[-1] - period
    rate = np.polyfit(sol.t[late], theta[late], 1)[0]
    assert rate == pytest.approx(rolling.rate, rel=1e-4)


def test_continuation_in_mu_joins_the_two_whirls_at_a_nonsmooth_fold():
    p = paper()
    settings = wh.WhirlSettings("mu", 0.0, 0.1, 0.002, 2e-6, 0.01)
    result = wh.continue_whirls(p, settings)
    assert result.status == "ok" and len(result.start_whirls) == 2
    (branch,) = result.branches  # the rolling whirl lies on the slipping whirl's branch
    (fold,) = result.events
    assert fold.kind == wh.NONSMOOTH_FOLD
    r_roll = model.rolling_whirl_radius(p)
    exact = 2 * p.nu * p.Rp * p.eta / (p.K * (r_roll - 1))  # rolling needs all of mu
    assert fold.value == pytest.approx(exact, rel=1e-10)
    assert fold.point.whirl.radius == pytest.approx(r_roll, rel=1e-10)
    # every slipping point on the closed form, every rolling point at the rolling radius
    for pt in branch.points:
        w = pt.whirl
        expected = slip_radius(w.params) if w.mode == wh.SLIP_POSITIVE else r_roll
        assert w.radius == pytest.approx(expected, rel=1e-9)
        assert w.params.mu == pytest.approx(pt.value, rel=1e-15)
    assert {pt.whirl.mode for pt in branch.points} == {wh.SLIP_POSITIVE, wh.ROLLING}
    assert branch.stops == {"up": "reached mu = 0.1", "down": "reached mu = 0.1"}


def test_continuation_in_speed_finds_where_the_rotor_outruns_its_slipping_whirl():
    p = paper()
    slipping = wh.whirls(p)[0]
    settings = wh.WhirlSettings("eta", 0.01, 2.0, 0.02, 2e-6, 0.1)
    result = wh.continue_whirls(p, settings)
    (fold,) = result.events
    # the slipping whirl does not depend on eta; it ends where v_r = Rp eta + r W = 0
    exact = slipping.radius * abs(slipping.rate) / p.Rp
    assert fold.kind == wh.NONSMOOTH_FOLD
    assert fold.value == pytest.approx(exact, rel=1e-10)


def test_no_whirl_below_the_friction_needed_and_asymmetric_machine_refused():
    assert wh.whirls(paper(mu=0.004)) == []  # below both the slip and the roll thresholds
    with pytest.raises(wh.WhirlError, match="e = 0"):
        wh.whirls(paper(e=0.1))


def _run(tmp_path, text: str, name="case.toml", *extra):
    case = tmp_path / name
    case.write_text(text)
    out = tmp_path / "out"
    return CliRunner().invoke(app, ["orbits", str(case), "--out", str(out), *extra]), out


def test_orbits_command_writes_the_whirl_branch(tmp_path):
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / REPO_CASE).read_text()
    result, out = _run(tmp_path, text, "case.toml", "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["kind"] == "whirl"  # --json: stdout is the report alone
    assert {p.name for p in out.iterdir()} == {"branch.csv", "branch.png", "report.json"}
    rows = list(csv.DictReader((out / "branch.csv").open()))
    usual = {"parameter", "value", "x", "y", "vx", "vy", "max_z", "stable", "label",
             "multiplier1_re", "n_unstable"}  # fmt: skip
    assert usual | {"whirl_rate", "radius"} <= set(rows[0])
    modes = {r["mode"] for r in rows}
    assert modes == {"slip+", "rolling"}
    for r in rows:
        assert float(r["radius"]) == float(r["max_z"]) == float(r["x"])
        assert float(r["vy"]) == pytest.approx(float(r["radius"]) * float(r["whirl_rate"]))
    report = json.loads((out / "report.json").read_text())
    kinds = [e["kind"] for e in report["whirls"]["events"]]
    assert kinds == ["nonsmooth_fold"]


BAD = """
[case]
name = "w"
[model]
nu = 0.009478
eta = 0.7818
e = {e}
K = 17.6
mu = 0.05
Rp = 46.16
[initial]
x = 0.5
y = 0.0
[time]
periods = 1
samples_per_period = 10
[orbits]
kind = "whirl"
parameter = "{parameter}"
min = 0.0
max = 0.1
step = 0.01
{extra}
"""


@pytest.mark.parametrize(
    ("e", "parameter", "extra", "message"),
    [
        (0.1, "mu", "", "needs the symmetric machine, e = 0"),
        (0.0, "e", "", "orbits.parameter: whirls are continued in"),
        (0.0, "mu", 'start = "transient"', 'orbits.start: not used with kind = "whirl"'),
    ],
)
def test_bad_whirl_cases_exit_2_and_write_nothing(tmp_path, e, parameter, extra, message):
    result, out = _run(tmp_path, BAD.format(e=e, parameter=parameter, extra=extra))
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split())
    assert not out.exists()


def test_no_whirl_at_the_start_exits_1_with_the_reason(tmp_path):
    text = BAD.format(e=0.0, parameter="mu", extra="").replace("mu = 0.05", "mu = 0.004")
    result, out = _run(tmp_path, text)
    assert result.exit_code == 1
    assert "no whirl in contact at mu = 0.004" in result.output
    assert {p.name for p in out.iterdir()} == {"report.json"}

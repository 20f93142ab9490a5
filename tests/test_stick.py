"""Stick (rolling) in every solver, model notes section 4.

Exact reference: without unbalance (e = 0) the backward whirl w = r exp(-i (Rp eta / r) tau)
rolls without slip when (1 + K) r^2 - K r - (Rp eta)^2 = 0; it needs the friction
T = 2 nu Rp eta and sticks while T <= mu K (r - 1).
"""

import math

import numpy as np
import pytest

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import SUCCESS
from rubcli.solvers import options_for, solve
from rubcli.solvers.rub import friction_force, slip_velocity

ALL = ["analytic", "analytic-polar", "rk45", "dop853", "radau", "bdf", "lsoda", "dop853-jit"]
OPTIONS = {"rtol": 1e-10, "atol": 1e-12, "steps_per_period": 800}


def rolling_start(p: ModelParams):
    r = model.rolling_whirl_radius(p)
    return r, (r, 0.0, 0.0, -p.Rp * p.eta)


def test_rolling_radius_and_needed_friction():
    p = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.3, Rp=2.0)
    r, s0 = rolling_start(p)
    assert (1 + p.K) * r * r - p.K * r - (p.Rp * p.eta) ** 2 == pytest.approx(0.0, abs=1e-12)
    assert model.slip_velocity(*s0, p.Rp, p.eta) == 0.0
    assert model.stick_friction(0.0, *s0, p) == pytest.approx(2 * p.nu * p.Rp * p.eta)
    assert model.regime_of_state(s0, p) == model.STICK
    weak = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.01, Rp=2.0)
    assert model.regime_of_state(s0, weak) == model.SLIP_POSITIVE


def test_stick_law_holds_slip_constant():
    p = ModelParams(nu=0.02, eta=0.7, e=3.0, K=100.0, mu=0.3, Rp=5.0, phi0=0.2)
    rng = np.random.default_rng(1)
    for _ in range(5):
        s = np.array([1.1, 0.3, 0.5, -2.0]) + 0.1 * rng.normal(size=4)
        s = model.project_to_rolling(s, p)  # a state on the rolling constraint
        assert model.slip_velocity(*s, p.Rp, p.eta) == pytest.approx(0.0, abs=1e-13)
        d = model.rhs(0.7, s, p, model.STICK)
        x, y, vx, vy = s
        z = math.hypot(x, y)
        v_r_rate = (x * d[3] - y * d[2]) / z - (x * vy - y * vx) * (x * vx + y * vy) / z**3
        assert abs(v_r_rate) < 1e-12


@pytest.mark.slow
@pytest.mark.parametrize("method", ALL)
def test_stays_on_exact_rolling_whirl(method):
    p = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.3, Rp=2.0)
    r, s0 = rolling_start(p)
    prob = Problem.from_periods(p, s0, 2, 20)
    sol = solve(prob, method, **options_for(method, OPTIONS))
    assert sol.status == SUCCESS and not sol.events
    assert np.all(sol.regimes == model.STICK)
    rate = p.Rp * p.eta / r
    exact = r * np.exp(-1j * rate * prob.t_eval)
    assert np.max(np.abs(sol.w - exact)) < (1e-5 if method.startswith("analytic") else 1e-6)
    assert np.max(np.abs(slip_velocity(sol))) < 1e-8
    whirl = (sol.x * sol.vy - sol.y * sol.vx) / sol.z**2
    np.testing.assert_allclose(whirl, -p.Rp * p.eta / sol.z, atol=1e-8)


@pytest.mark.parametrize("method", ALL)
def test_leaves_stick_when_friction_is_too_weak(method):
    p = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.01, Rp=2.0)
    _, s0 = rolling_start(p)  # needs T = 0.04 > mu K (r - 1) = 0.029
    sol = solve(Problem.from_periods(p, s0, 0.5, 40), method, **options_for(method, OPTIONS))
    assert sol.status == SUCCESS
    assert sol.regimes[0] == model.SLIP_POSITIVE and not sol.events
    assert np.all(np.diff(slip_velocity(sol)[:5]) > 0)  # slip grows forward


FORCED = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)


@pytest.mark.slow
def test_stick_slip_cycle_agrees_across_methods():
    """The unbalance makes the needed friction oscillate across the cone edge.

    Reference: dop853 at rtol = 1e-12. Each method sees the same stick/slip sequence;
    every stick exit lies on |T| = mu K (z - 1); in stick |v_r| stays at round-off.
    """
    _, s0 = rolling_start(FORCED)
    prob = Problem.from_periods(FORCED, s0, 3, 50)
    ref = solve(prob, "dop853", rtol=1e-12, atol=1e-13)
    kinds = [ev.kind for ev in ref.events]
    assert kinds[:4] == ["stick_exit", "stick_entry", "stick_exit", "stick_entry"]
    for method in ALL:
        sol = solve(prob, method, **options_for(method, {**OPTIONS, "steps_per_period": 1600}))
        assert sol.status == SUCCESS, method
        assert [ev.kind for ev in sol.events] == kinds, method
        times = np.array([ev.tau for ev in sol.events])
        ref_times = np.array([ev.tau for ev in ref.events])
        assert np.max(np.abs(times - ref_times)) < (1e-2 if method.startswith("analytic") else 1e-5)
        for ev in sol.events:
            s = ev.state
            limit = FORCED.mu * FORCED.K * (math.hypot(s[0], s[1]) - 1.0)
            needed = model.stick_friction(ev.tau, *s, FORCED)
            if ev.kind == "stick_exit":
                # stick ends where |T| exceeds mu F_N by model.STICK_EXIT_MARGIN
                edge = limit * (1.0 + model.STICK_EXIT_MARGIN)
                assert abs(abs(needed) - edge) < 1e-9 * limit
                assert ev.regime_after == (
                    model.SLIP_POSITIVE if needed > 0 else model.SLIP_NEGATIVE
                )
            else:
                assert abs(needed) < limit
        stick = sol.regimes == model.STICK
        assert stick.any() and (~stick).any()
        assert np.max(np.abs(slip_velocity(sol)[stick])) < 1e-8


def test_solution_reports_rolling_friction_in_stick():
    p = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.3, Rp=2.0)
    _, s0 = rolling_start(p)
    sol = solve(Problem.from_periods(p, s0, 1, 5), "dop853", rtol=1e-10, atol=1e-12)
    # the exact rolling whirl needs T = 2 nu Rp eta (module docstring)
    np.testing.assert_allclose(friction_force(sol), 2 * p.nu * p.Rp * p.eta, rtol=1e-6)

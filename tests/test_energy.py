"""Energy balance (rubcli.analysis.energy.balance) and regime pieces
(rubcli.analysis.energy.regimes).

Reference numbers come from exact solutions (model notes 5 and the rolling whirl of
section 4), on which every term of the balance has a closed form, and from independent
solvers at tight and loose settings.
"""

import math
import tracemalloc

import numpy as np
import pytest

from rubcli import model
from rubcli.analysis.energy.balance import (
    accelerations,
    energy_balance,
    energy_balance_numpy,
    energy_totals,
    powers,
)
from rubcli.analysis.energy.regimes import solution_pieces, time_in_regimes
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import SUCCESS, Solution
from rubcli.solvers import solve

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16}


def exact_solution(problem: Problem, states: np.ndarray, regime: int) -> Solution:
    """A Solution holding an exact motion that stays in one regime (no events)."""
    t = problem.t_eval
    return Solution(
        problem=problem,
        method="exact",
        t=t,
        states=np.asarray(states, dtype=float),
        regimes=np.full(t.size, regime),
    )


def test_free_flight_residual_is_at_quadrature_level_and_of_order_four():
    p = ModelParams(nu=0.05, eta=0.7818, e=0.2, K=17.6, mu=0.1, Rp=46.16, phi0=0.3)
    residuals = []
    for samples in (40, 80):
        prob = Problem.from_periods(p, (0.2, -0.1, 0.3, 0.0), 5, samples)
        states = model.free_flight(prob.t_eval, 0.0, prob.initial, p).T
        assert np.max(np.hypot(states[:, 0], states[:, 1])) < 1.0
        balance = energy_balance(exact_solution(prob, states, model.FREE))
        assert balance.friction[-1] == 0.0 and np.all(balance.stator == 0.0)
        residuals.append(balance.relative_residual)
    assert residuals[0] < 1e-6
    assert 10.0 < residuals[0] / residuals[1] < 25.0  # 16 for an order-4 rule


@pytest.mark.parametrize("mu", [0.0, 0.01])
def test_synchronous_rub_terms_have_their_closed_forms(mu):
    """On w = A exp(i eta tau), |v| = eta r and T = mu K (r - 1) are constant."""
    p = ModelParams(**FIG3, K=17.6, mu=mu)
    r = model.synchronous_rub_radii(p)[-1]
    prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p, r)), 3, 50)
    states = model.synchronous_rub(prob.t_eval, p, r).T
    balance = energy_balance(exact_solution(prob, states, model.SLIP_POSITIVE))
    tau = prob.t_eval[-1]
    T = mu * p.K * (r - 1.0)
    assert balance.relative_residual < 1e-11
    assert balance.damping[-1] == pytest.approx(2 * p.nu * (p.eta * r) ** 2 * tau, rel=1e-12)
    assert balance.friction[-1] == pytest.approx(T * r * p.eta * tau, rel=1e-12, abs=1e-14)
    assert balance.contact_dissipation[-1] == pytest.approx(
        T * (p.Rp + r) * p.eta * tau, rel=1e-12, abs=1e-14
    )
    assert balance.spin_drive[-1] == pytest.approx(T * p.Rp * p.eta * tau, rel=1e-12, abs=1e-14)
    # the unbalance feeds exactly what damping and friction take
    assert balance.work_unbalance[-1] == pytest.approx(
        balance.damping[-1] + balance.friction[-1], rel=1e-10
    )
    np.testing.assert_allclose(balance.stator, 0.5 * p.K * (r - 1.0) ** 2, rtol=1e-12)


def test_rolling_whirl_friction_is_driven_by_the_spin():
    """Exact rolling backward whirl (notes 4, e = 0): in stick v_r = 0, so friction
    dissipates nothing at the contact; its work on the whirl, T Rp eta = 2 nu (Rp eta)^2,
    comes from the spin drive and replaces exactly what damping takes."""
    p = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.3, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    prob = Problem.from_periods(p, (r, 0.0, 0.0, -p.Rp * p.eta), 3, 50)
    w = r * np.exp(-1j * (p.Rp * p.eta / r) * prob.t_eval)
    v = -1j * (p.Rp * p.eta / r) * w
    balance = energy_balance(
        exact_solution(prob, np.column_stack((w.real, w.imag, v.real, v.imag)), model.STICK)
    )
    drive = 2 * p.nu * (p.Rp * p.eta) ** 2 * prob.t_eval[-1]
    assert balance.relative_residual < 1e-12
    assert balance.damping[-1] == pytest.approx(drive, rel=1e-12)
    assert balance.friction[-1] == pytest.approx(-drive, rel=1e-10)
    assert balance.spin_drive[-1] == pytest.approx(drive, rel=1e-10)
    assert abs(balance.contact_dissipation[-1]) < 1e-12 * drive
    assert balance.work_unbalance[-1] == 0.0


def test_tight_solution_balances_and_loose_ones_do_not():
    """The Figure 3 machine with mu = 0.01 enters and leaves contact (piecewise pieces)."""
    p = ModelParams(**FIG3, K=17.6, mu=0.01)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 10, 100)
    tight = solve(prob, "dop853", rtol=1e-12, atol=1e-12)
    assert tight.status == SUCCESS and tight.n_contact_switches >= 4
    balance = energy_balance(tight)
    assert balance.n_pieces == len(tight.events) + 1
    assert balance.relative_residual < 1e-6
    loose_rk45 = energy_balance(solve(prob, "rk45", rtol=1e-3, atol=1e-5)).relative_residual
    loose_analytic = energy_balance(solve(prob, "analytic", steps_per_period=50))
    floor = max(balance.relative_residual, balance.quadrature_error)
    assert loose_rk45 > 30 * floor
    assert loose_analytic.relative_residual > 30 * floor


def test_powers_split_friction_into_contact_dissipation_and_spin_drive():
    p = ModelParams(nu=0.02, eta=0.7, e=3.0, K=100.0, mu=0.3, Rp=5.0, phi0=0.2)
    rng = np.random.default_rng(3)
    S = np.array([1.3, 0.3, 0.5, -2.0]) + 0.1 * rng.normal(size=(20, 4))
    assert np.all(np.hypot(S[:, 0], S[:, 1]) > 1.0)  # in contact
    tau = rng.uniform(0, 10, 20)
    for regime in (model.SLIP_POSITIVE, model.SLIP_NEGATIVE, model.STICK):
        states = model.project_to_rolling(S.T, p).T if regime == model.STICK else S
        P = powers(tau, states, p, regime)
        # -T r theta' = -T v_r + T Rp eta, since v_r = Rp eta + r theta'
        np.testing.assert_allclose(P[:, 2], P[:, 4] - P[:, 3], rtol=1e-12, atol=1e-12)
        if regime != model.STICK:
            # with the slip in the regime's direction, friction always dissipates
            rolling = model.project_to_rolling(S.T, p).T  # v_r = 0
            x, y = rolling[:, 0], rolling[:, 1]
            slip = regime * rng.uniform(0.1, 2.0, len(S))  # v_r added along theta_hat
            z = np.hypot(x, y)
            slipping = rolling + np.column_stack((0 * x, 0 * y, -slip * y / z, slip * x / z))
            np.testing.assert_allclose(
                model.slip_velocity(*slipping.T, p.Rp, p.eta), slip, rtol=1e-12
            )
            assert np.all(powers(tau, slipping, p, regime)[:, 3] > 0.0)


@pytest.mark.parametrize(
    "regime", [model.FREE, model.SLIP_POSITIVE, model.SLIP_NEGATIVE, model.STICK]
)
def test_accelerations_are_those_of_model_rhs(regime):
    p = ModelParams(nu=0.02, eta=0.7, e=3.0, K=100.0, mu=0.3, Rp=5.0, phi0=0.2)
    rng = np.random.default_rng(4)
    S = np.array([1.1, 0.3, 0.5, -2.0]) + 0.05 * rng.normal(size=(10, 4))
    if regime == model.STICK:
        S = model.project_to_rolling(S.T, p).T
    tau = rng.uniform(0, 10, 10)
    expected = np.array([model.rhs(t, s, p, regime)[2:] for t, s in zip(tau, S, strict=True)])
    np.testing.assert_allclose(accelerations(tau, S, p, regime), expected, rtol=1e-12, atol=1e-12)


def test_pieces_and_time_in_regimes_follow_the_located_events():
    """Stick-slip cycle (tests/test_stick.py): durations from the exact switch times."""
    p = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    prob = Problem.from_periods(p, (r, 0.0, 0.0, -p.Rp * p.eta), 3, 50)
    sol = solve(prob, "dop853", rtol=1e-10, atol=1e-12)
    assert sol.status == SUCCESS and len(sol.events) >= 4
    pieces = solution_pieces(sol)
    boundaries = [piece.tau[0] for piece in pieces[1:]]
    assert boundaries == [ev.tau for ev in sol.events]
    for piece, event in zip(pieces[1:], sol.events, strict=True):
        assert piece.regime == event.regime_after
        np.testing.assert_array_equal(piece.states[0], event.state)
        inside = (sol.t > piece.tau[0]) & (sol.t < piece.tau[-1])
        assert np.all(sol.regimes[inside] == piece.regime)
    durations = time_in_regimes(sol)
    assert set(durations) == set(model.REGIME_NAMES.values())
    assert sum(durations.values()) == pytest.approx(prob.t_eval[-1], rel=1e-14)
    pairs = zip(sol.events[:-1], sol.events[1:], strict=True)
    stick = sum(b.tau - a.tau for a, b in pairs if a.regime_after == model.STICK)
    if sol.events[-1].regime_after == model.STICK:
        stick += prob.t_eval[-1] - sol.events[-1].tau
    if sol.regimes[0] == model.STICK:
        stick += sol.events[0].tau
    assert durations["stick"] == pytest.approx(stick, rel=1e-12)
    assert 1.0 - durations["free"] / prob.t_eval[-1] == pytest.approx(sol.contact_fraction())


def test_failed_run_is_balanced_over_its_partial_span():
    p = ModelParams(**FIG3, K=17.6, mu=0.01)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 10, 100)
    sol = solve(prob, "dop853", rtol=1e-10, atol=1e-12, max_steps=300)
    assert sol.status == "failed" and sol.t.size < prob.t_eval.size
    balance = energy_balance(sol)
    assert balance.tau[-1] == sol.t[-1]
    assert math.isfinite(balance.relative_residual) and balance.relative_residual < 1e-5


# ------------------------------------------- the compiled one-pass core

_SERIES = ("tau", "kinetic", "rotor_spring", "stator", "work_unbalance", "damping", "friction",
           "contact_dissipation", "spin_drive", "residual")  # fmt: skip


def _stick_slip_solution() -> Solution:
    """Stick-slip cycle (as above): stick and slip."""
    p = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    prob = Problem.from_periods(p, (r, 0.0, 0.0, -p.Rp * p.eta), 3, 50)
    return solve(prob, "dop853", rtol=1e-10, atol=1e-12)


def _rubbing_solution() -> Solution:
    """Figure 3 machine, mu = 0.03: contact entries and exits, short contacts."""
    p = ModelParams(**FIG3, K=17.6, mu=0.03)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 20, 7)
    return solve(prob, "dop853", rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("make", [_stick_slip_solution, _rubbing_solution])
def test_compiled_balance_equals_the_numpy_path(make):
    """The one-pass compiled core (node by node) and the whole-array numpy path give the
    same series and totals to 1e-12 relative, on runs with stick, slip,
    free flight and pieces without an interior sample."""
    sol = make()
    pieces = solution_pieces(sol)
    assert sol.status == SUCCESS and len(sol.events) >= 4
    expected = {model.STICK, model.SLIP_POSITIVE} if make is _stick_slip_solution else {
        model.FREE, model.SLIP_POSITIVE}  # fmt: skip
    assert {pc.regime for pc in pieces} == expected
    assert any(pc.tau.size == 2 for pc in pieces)  # a piece with no interior sample
    compiled, reference = energy_balance(sol), energy_balance_numpy(sol)
    assert compiled.n_pieces == reference.n_pieces == len(solution_pieces(sol))
    for name in _SERIES:
        a, b = getattr(compiled, name), getattr(reference, name)
        assert a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.max(np.abs(b)), err_msg=name)
    assert compiled.throughput == pytest.approx(reference.throughput, rel=1e-12)
    assert compiled.quadrature_error == pytest.approx(reference.quadrature_error, rel=1e-9)
    totals = energy_totals(sol).summary()
    for key, value in reference.summary().items():
        assert totals[key] == pytest.approx(value, rel=1e-9 if "residual" in key else 1e-12,
                                            abs=1e-15), key  # fmt: skip


def _free_solution(n: int) -> Solution:
    p = ModelParams(nu=0.05, eta=0.5, e=0.5, K=10.0)
    t = np.linspace(0.0, 50.0, n)
    prob = Problem(p, (0.3, 0.0, 0.0, 0.1), t)
    states = np.ascontiguousarray(model.free_flight(t, 0.0, prob.initial, p).T)
    return Solution(prob, "exact", t, states, np.zeros(n, dtype=np.int64))


def test_energy_totals_need_no_memory_that_grows_with_the_samples():
    """The report's energy totals keep no per-sample array (the numpy path kept about 20
    floats per sample: 436 MB at a million samples)."""
    energy_totals(_free_solution(100))  # compiled / loaded outside the measurement
    peaks = {}
    for n in (20_000, 200_000):
        sol = _free_solution(n)
        tracemalloc.start()
        totals = energy_totals(sol)
        peaks[n] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert totals.relative_residual < 1e-9  # an exact free flight balances
    assert peaks[200_000] < 1.3 * peaks[20_000] + 100_000, peaks
    assert peaks[200_000] < 8 * 200_000  # less than one float per sample


@pytest.mark.slow
def test_work_of_the_unbalance_late_in_a_long_run_uses_exact_power_rates():
    """W_in over 300 forcing periods of the Figure 3 machine with friction (rubbing,
    tau up to ~2400) against the same corrected trapezoid with the power's rate written
    out (dP_in/dtau = E (eta (-sin vx + cos vy) + cos ax + sin ay)): an independent rate.
    The central differences must not lose the phase shift eta delta to the rounding of
    eta (tau +- delta) late in the run (which cost 1.8e-9 relative here, 1e-10 now)."""
    p = ModelParams(**FIG3, K=17.6, mu=0.02)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 300, 100)
    sol = solve(prob, "dop853-jit", rtol=1e-8, atol=1e-10)
    assert sol.status == SUCCESS and len(sol.events) > 10
    expected = 0.0
    for piece in solution_pieces(sol):
        tau, S = piece.tau, piece.states
        a = accelerations(tau, S, p, piece.regime)
        c, s = np.cos(p.eta * tau + p.phi0), np.sin(p.eta * tau + p.phi0)
        P = p.E * (c * S[:, 2] + s * S[:, 3])
        dP = p.E * (p.eta * (-s * S[:, 2] + c * S[:, 3]) + c * a[:, 0] + s * a[:, 1])
        h = np.diff(tau)
        expected += np.sum(0.5 * h * (P[:-1] + P[1:]) + h * h / 12.0 * (dP[:-1] - dP[1:]))
    assert energy_totals(sol).work_unbalance == pytest.approx(expected, rel=3e-10)
    assert energy_balance_numpy(sol).work_unbalance[-1] == pytest.approx(expected, rel=3e-10)

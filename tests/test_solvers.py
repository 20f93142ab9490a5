"""Every solver against exact solutions and against each other (model notes, section 5).

Tolerances: scipy methods are checked with the scaled error of scipy's own test-suite,
``|y - y_exact| / (atol + rtol |y_exact|)``, bounded by a factor that allows for the
global accumulation over the horizon; the analytic method by its own global order.
"""

import time

import numpy as np
import pytest

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import FAILED, SUCCESS
from rubcli.solvers import METHODS, options_for, solve
from rubcli.solvers.registry import SPECS

SCIPY = ["rk45", "dop853", "radau", "bdf", "lsoda"]
ALL = ["analytic", "analytic-polar", *SCIPY, "dop853-jit"]
TIGHT = {"rtol": 1e-10, "atol": 1e-12, "steps_per_period": 1600}


def test_registry_has_every_method():
    assert set(ALL) <= set(METHODS)
    with pytest.raises(ValueError, match="unknown method"):
        solve(Problem.from_periods(ModelParams(0.1, 0.5, 0.1, 1.0), (0, 0, 0, 0), 1), "euler")


@pytest.mark.slow
@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("nu", [0.009478, 0.0, 1.5])
def test_free_flight_matches_closed_form(method, nu):
    p = ModelParams(nu=nu, eta=0.7818, e=0.2, K=17.6, mu=0.1, Rp=46.16, phi0=0.3)
    prob = Problem.from_periods(p, (0.2, -0.1, 0.3, 0.0), periods=5, samples_per_period=20)
    exact = model.free_flight(prob.t_eval, 0.0, prob.initial, p).T
    assert np.max(np.hypot(exact[:, 0], exact[:, 1])) < 1.0  # never touches
    sol = solve(prob, method, **options_for(method, {"rtol": 1e-9, "atol": 1e-12}))
    assert sol.status == SUCCESS and not sol.events
    err = np.abs(sol.states - exact)
    if method.startswith("analytic"):
        assert err.max() < 1e-13  # the closed form itself
    else:
        # global error over 5 periods, scaled by the tolerance times the orbit size
        assert err.max() / (1e-12 + 1e-9 * np.abs(exact).max()) < 200


@pytest.mark.slow
@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("mu", [0.0, 0.01])
def test_stays_on_synchronous_full_annular_rub(method, mu, fig3_params):
    p = fig3_params(mu)
    r = model.synchronous_rub_radii(p)[-1]
    assert model.synchronous_rub_is_forward(r, p)
    prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p, r)), 5, 20)
    exact = model.synchronous_rub(prob.t_eval, p, r).T
    sol = solve(prob, method, **options_for(method, TIGHT))
    assert sol.status == SUCCESS
    assert not sol.events  # never leaves contact, never reverses slip
    assert np.all(sol.regimes == model.SLIP_POSITIVE)
    bound = 2e-5 if method.startswith("analytic") else 1e-6
    assert np.max(np.abs(sol.states - exact)) < bound


@pytest.mark.parametrize("method", ["analytic", "analytic-polar"])
def test_analytic_observed_order_is_its_registered_order(method, fig3_params):
    """The local linearisation error is O(h^2) in the force: global order 2, as the
    registry states (``SPECS[method].order``, the docs' method table)."""
    p = fig3_params(0.01)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 2, 25)
    ref = solve(prob, "dop853", rtol=1e-13, atol=1e-13)
    steps = [100, 200, 400, 800]
    errors = [np.max(np.abs(solve(prob, method, steps_per_period=n).w - ref.w)) for n in steps]
    slope = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert SPECS[method].order == 2
    assert slope == pytest.approx(SPECS[method].order, abs=0.2)
    assert errors[-1] < errors[0] / 30


def test_analytic_order_on_exact_rub(fig3_params):
    """Against the exact synchronous rub, the observed order is the registered one. (The
    polar linearisation is exact on this circular orbit: analytic-polar's order shows in
    ``test_analytic_observed_order_is_its_registered_order``.)"""
    method = "analytic"
    p = fig3_params(0.01)
    r = model.synchronous_rub_radii(p)[-1]
    prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p, r)), 2, 10)
    exact = model.synchronous_rub(prob.t_eval, p, r).T
    steps = [50, 100, 200, 400]
    errors = [np.max(np.abs(solve(prob, method, steps_per_period=n).states - exact)) for n in steps]
    slope = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert slope == pytest.approx(SPECS[method].order, abs=0.2)


@pytest.mark.slow
@pytest.mark.parametrize("method", ALL)
def test_switch_times_lie_on_the_surface(method, fig3_params):
    p = fig3_params(0.0)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 3, 20)
    sol = solve(prob, method, **options_for(method, TIGHT))
    assert sol.status == SUCCESS
    switches = [ev for ev in sol.events if ev.kind != "slip_reversal"]
    assert len(switches) >= 4
    for ev in switches:
        assert abs(np.hypot(ev.state[0], ev.state[1]) - 1.0) < 1e-9
    kinds = [ev.kind for ev in switches]
    assert all(a != b for a, b in zip(kinds, kinds[1:], strict=False))  # entry/exit alternate
    # samples are on the right side of the surface for their regime
    z = sol.z
    assert np.all(z[sol.contact == 1] >= 1.0 - 1e-9)
    assert np.all(z[sol.contact == 0] <= 1.0 + 1e-9)


SHORT_CONTACTS = ModelParams(nu=0.0, eta=1.0, e=0.0, K=17.6, mu=0.0, Rp=0.0)


@pytest.mark.parametrize(
    ("method", "options"),
    [(m, {"steps_per_period": 4}) for m in ("analytic", "analytic-polar")]
    # penetration 1e-3 is 10x the scipy methods' band (a contact shallower than rtol is
    # a touch to them, events.earliest_event)
    + [(m, {"rtol": 1e-4, "atol": 1e-7}) for m in [*SCIPY, "dop853-jit"]],
)
def test_brief_contacts_inside_one_step_are_not_missed(method, options):
    """An unforced ellipse peaking at z = 1.001: each contact lasts ~0.1, far below a step.

    The reference count of switches comes from the exact free ellipse x = 0.5 cos t,
    y = 1.001 sin t, which crosses z = 1 twice per half-turn: 12 crossings in 3 turns.
    """
    prob = Problem.from_periods(SHORT_CONTACTS, (0.5, 0.0, 0.0, 1.001), 3, 8)
    sol = solve(prob, method, **options)
    assert sol.status == SUCCESS
    assert len(sol.events) == 12
    if method.startswith("analytic"):
        durations = np.diff([ev.tau for ev in sol.events])[::2]
        assert np.all(durations < SHORT_CONTACTS.period / 4 / 10)  # the step is period / 4


@pytest.mark.slow
def test_methods_agree_on_paper_case(fig3_params):
    p = fig3_params(0.02)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 5, 20)
    ref = solve(prob, "dop853", rtol=1e-12, atol=1e-13)
    expected = {
        "rk45": 1e-6,
        "radau": 1e-6,
        "bdf": 1e-4,
        "lsoda": 1e-5,
        "analytic": 1e-4,
        "analytic-polar": 1e-4,
        "dop853-jit": 1e-9,
    }
    for method, bound in expected.items():
        sol = solve(prob, method, **options_for(method, {**TIGHT, "steps_per_period": 3200}))
        assert sol.status == SUCCESS
        assert len(sol.events) == len(ref.events), method
        assert np.max(np.abs(sol.w - ref.w)) < bound, method


@pytest.mark.parametrize("method", ALL)
def test_step_budget_gives_clean_failure_with_partial_result(method, fig3_params):
    prob = Problem.from_periods(fig3_params(0.0), (0.88544, -0.8039, 0.0, 0.0), 5, 20)
    sol = solve(prob, method, max_steps=20)
    assert sol.status == FAILED
    assert "max_steps" in sol.message
    assert 1 <= sol.t.size < prob.t_eval.size
    assert np.all(np.isfinite(sol.states))
    np.testing.assert_array_equal(sol.states[0], prob.initial)


class TickingClock:
    """An injected ``time.perf_counter``: every reading is ``tick`` seconds after the last."""

    def __init__(self, tick: float):
        self.now, self.tick, self.readings = 0.0, tick, 0

    def __call__(self) -> float:
        self.now += self.tick
        self.readings += 1
        return self.now


@pytest.mark.parametrize("method", ALL)
def test_wall_time_budget_is_honoured(method, fig3_params, monkeypatch):
    """With a clock that advances 1 s per reading, a 3.5 s budget bites after a few of the
    solver's budget checks, on any machine; the same run under a budget it cannot reach
    finishes. (A real clock made this test depend on the machine being slow.)"""
    prob = Problem.from_periods(fig3_params(0.0), (0.88544, -0.8039, 0.0, 0.0), 200, 20)
    solve(prob, method, max_steps=50)  # compile before the clock is replaced
    monkeypatch.setattr(time, "perf_counter", TickingClock(1.0))
    sol = solve(prob, method, max_wall_time_s=3.5)
    assert sol.status == FAILED and "max_wall_time_s = 3.5" in sol.message, sol.message
    assert 1 <= sol.t.size < prob.t_eval.size  # stopped early, partial result kept
    assert np.all(np.isfinite(sol.states))
    if method in ("analytic", "analytic-polar", "dop853-jit"):  # the fast ones
        short = Problem.from_periods(prob.params, prob.initial, 20, 20)
        assert solve(short, method, max_wall_time_s=1e15).status == SUCCESS


def test_progress_reaches_the_end(fig3_params):
    prob = Problem.from_periods(fig3_params(0.0), (0.88544, -0.8039, 0.0, 0.0), 3, 10)
    for method in ("analytic", "rk45", "dop853-jit"):
        seen = []
        solve(prob, method, progress=seen.append)
        assert seen and seen[-1] == pytest.approx(prob.t_span[1])
        assert seen == sorted(seen)


def test_polar_error_does_not_grow_with_stiffness(fig3_params):
    """On the exact synchronous rub at a fixed step (100 per period), across K = 17.6,
    1.76e4 and 1.75e6: the polar linearisation stays at round-off (3e-15 to 2e-11, the
    round-off of the stiff arithmetic) while the paper's Cartesian one grows with K
    (1.4e-3, 2.2e-2, 0.81): at least 5x per step in K, and 1e6x the polar error."""
    polar, cartesian = [], []
    for K in (17.6, 17.6e3, 1.75e6):
        p = fig3_params(0.01, K=K)
        r = model.synchronous_rub_radii(p)[-1]
        prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p, r)), 2, 10)
        exact = model.synchronous_rub(prob.t_eval, p, r).T
        sol = solve(prob, "analytic-polar", steps_per_period=100)
        assert sol.status == SUCCESS and not sol.events
        polar.append(np.max(np.abs(sol.states[:, :2] - exact[:, :2])))
        paper = solve(prob, "analytic", steps_per_period=100)
        cartesian.append(np.max(np.abs(paper.states[:, :2] - exact[:, :2])))
    assert max(polar) < 1e-10
    assert all(c > 1e6 * q for c, q in zip(cartesian, polar, strict=True))
    assert cartesian[1] > 5 * cartesian[0] and cartesian[2] > 5 * cartesian[1]


@pytest.mark.slow
def test_polar_error_does_not_grow_with_stiffness_off_the_exact_orbit(fig3_params):
    """Started off the orbit (a radial offset that excites the fast contact mode), against
    a tight dop853 reference: at a fixed step the polar position error does not grow
    with K, while the paper's Cartesian linearisation's does."""
    polar, cartesian = {}, {}
    for K in (17.6, 1.76e3, 17.6e3):
        p = fig3_params(0.01, K=K)
        r = model.synchronous_rub_radii(p)[-1]
        s0 = model.synchronous_rub(0.0, p, r)
        s0[:2] *= 1.0 + 0.5 * (r - 1.0)  # half the penetration again
        prob = Problem.from_periods(p, tuple(s0), 0.5, 20)
        ref = solve(prob, "dop853", rtol=1e-12, atol=1e-14)
        polar[K] = np.max(np.abs(solve(prob, "analytic-polar", steps_per_period=800).w - ref.w))
        cartesian[K] = np.max(np.abs(solve(prob, "analytic", steps_per_period=800).w - ref.w))
    assert polar[1.76e3] <= 2 * polar[17.6] and polar[17.6e3] <= 2 * polar[17.6]
    assert cartesian[17.6e3] > 3 * cartesian[17.6]


def test_adaptive_steps_meet_tolerance_on_exact_rub(fig3_params):
    """Step doubling holds the local error O(h^3) of each step at ``analytic_tol``, so the
    number of steps grows like tol^(-1/3) and the global error falls like tol^(2/3):
    observed orders of both between tol = 1e-5 and 1e-7, and a bound within 10x of the
    error (0.05 tol^(2/3) measured; 0.3 tol^(2/3) asserted)."""
    p = fig3_params(0.02)
    r = model.synchronous_rub_radii(p)[-1]
    prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p, r)), 2, 10)
    exact = model.synchronous_rub(prob.t_eval, p, r).T
    errors, steps = [], []
    for tol in (1e-5, 1e-7):
        sol = solve(prob, "analytic", analytic_tol=tol)
        assert sol.status == SUCCESS
        steps.append(sol.stats["n_contact_steps"])
        errors.append(np.max(np.abs(sol.states - exact)))
        assert tol < errors[-1] < 0.3 * tol ** (2 / 3)
    error_order = np.log10(errors[0] / errors[1]) / 2.0
    step_order = np.log10(steps[1] / steps[0]) / 2.0
    assert error_order == pytest.approx(2 / 3, abs=0.07)
    assert step_order == pytest.approx(1 / 3, abs=0.05)
    # the polar linearisation is exact on this orbit: its error is round-off at any tol
    for tol in (1e-5, 1e-7):
        polar = solve(prob, "analytic-polar", analytic_tol=tol)
        assert polar.status == SUCCESS
        assert np.max(np.abs(polar.states - exact)) < 1e-13


@pytest.mark.parametrize("method", ["analytic", "analytic-polar"])
def test_adaptive_steps_on_a_trajectory_with_switches(method, fig3_params):
    p = fig3_params(0.03)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 2, 25)
    ref = solve(prob, "dop853", rtol=1e-13, atol=1e-13)
    loose = solve(prob, method, analytic_tol=1e-4)
    tight = solve(prob, method, analytic_tol=1e-7)
    assert loose.status == tight.status == SUCCESS
    e_loose = np.max(np.abs(loose.w - ref.w))
    e_tight = np.max(np.abs(tight.w - ref.w))
    assert e_tight < e_loose / 20
    assert tight.stats["n_contact_steps"] > loose.stats["n_contact_steps"]


@pytest.mark.parametrize("compiled", [True, False])
def test_diverged_linearisation_fails_cleanly(compiled, fig3_params):
    """K = 17.6e3 from the Figure 3 start at 25 steps per period: the polar linearisation
    diverges (a frequency of ~1e7 per tau). The run must end with a clean failure and a
    reason, not allocate a scan of 1e14 points (it once did)."""
    p = fig3_params(0.0, K=17.6e3)
    prob = Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 10, 50)
    sol = solve(prob, "analytic-polar", steps_per_period=25, compiled=compiled)
    assert sol.status == FAILED
    assert "cannot resolve" in sol.message
    assert np.all(np.isfinite(sol.states))


def test_diverged_linearisation_with_nan_fails_cleanly(fig3_params):
    """K = 1.75e6, mu = 0.03 from the Figure 3 start at 25 steps per period: the polar
    linearisation of a violent bounce diverges to NaN inside a step. The run must end
    as a clean failure that says so (it raised ValueError from the root finder before)."""
    from rubcli.analysis.accuracy.reference import truncate_problem

    p = fig3_params(0.03, K=1.75e6)
    prob = truncate_problem(Problem.from_periods(p, (0.88544, -0.8039, 0.0, 0.0), 2, 50), 1.0)
    sol = solve(prob, "analytic-polar", steps_per_period=25, max_wall_time_s=30)
    assert sol.status == FAILED
    assert "diverged" in sol.message
    assert np.all(np.isfinite(sol.states))

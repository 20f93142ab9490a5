"""dop853-jit: scipy's DOP853 step for step, compiled (rubcli/solvers/dop853_jit.py).

The independent method is scipy's own ``DOP853`` (run by ``scipy_ivp``): the compiled
stepper uses its tableau and step-size control, so both must take the same number of
steps, evaluate the right-hand side as often, find the same events, and agree to
round-off amplified by the dynamics. Exact solutions (free flight, the synchronous rub)
check the accuracy itself, and the observed order on free flight must be near 8.
"""

import numpy as np
import pytest

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import FAILED, SUCCESS
from rubcli.solvers import solve

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16}
START = (0.88544, -0.8039, 0.0, 0.0)


def fig3_problem(mu: float, periods: float, samples: int = 50) -> Problem:
    return Problem.from_periods(ModelParams(**FIG3, mu=mu), START, periods, samples)


@pytest.mark.parametrize("mu", [0.0, 0.03])
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_same_steps_events_and_states_as_scipy_dop853(mu, rtol):
    prob = fig3_problem(mu, 10)
    jit = solve(prob, "dop853-jit", rtol=rtol, atol=rtol / 100)
    ref = solve(prob, "dop853", rtol=rtol, atol=rtol / 100)
    assert jit.status == ref.status == SUCCESS
    assert [ev.kind for ev in jit.events] == [ev.kind for ev in ref.events]
    times = np.array([ev.tau for ev in jit.events]) - [ev.tau for ev in ref.events]
    assert np.max(np.abs(times), initial=0.0) < 1e-9
    # the same steps: counts agree within the few events whose located time differs
    # by round-off (a step more or less after a restart)
    assert abs(jit.stats["nsteps"] - ref.stats["nsteps"]) <= max(2, len(ref.events) // 50)
    assert np.array_equal(jit.regimes, ref.regimes)
    assert np.max(np.abs(jit.w - ref.w)) < 1e-8


@pytest.mark.parametrize(
    ("K", "mu", "periods"),
    [(17.6, 0.0, 10), (17.6, 0.05, 10), (17.6e3, 0.03, 2), (1.75e6, 0.0, 0.5), (1.75e6, 0.03, 0.2)],
)
def test_compiled_events_match_the_python_event_code(K, mu, periods):
    """Events located and applied in the kernel (a transcription of
    events.earliest_event and apply_event) against the same run with every possible
    event handed to the Python code: the same events (entries, exits, slip reversals,
    stick entries and exits) at the same times, the same steps, the same states, to
    round-off (numpy and numba may round a rate differently, and stick-slip amplifies
    it). The stiff cases bounce ~700 times a period; with mu = 0.03 each bounce sticks."""
    p = ModelParams(**{**FIG3, "K": K}, mu=mu)
    prob = Problem.from_periods(p, START, periods, 50)
    fast = solve(prob, "dop853-jit", rtol=1e-8, atol=1e-10)
    slow = solve(prob, "dop853-jit", rtol=1e-8, atol=1e-10, compiled_events=False)
    assert fast.status == slow.status == SUCCESS
    assert len(fast.events) == len(slow.events) > 0
    assert [e.kind for e in fast.events] == [e.kind for e in slow.events]
    assert [e.regime_after for e in fast.events] == [e.regime_after for e in slow.events]
    times = np.array([e.tau for e in fast.events]) - [e.tau for e in slow.events]
    assert np.max(np.abs(times)) < 1e-10
    assert fast.stats["nsteps"] == slow.stats["nsteps"]
    assert np.array_equal(fast.regimes, slow.regimes)
    assert np.max(np.abs(fast.states - slow.states)) < 1e-8
    assert fast.stats["python_steps"] == 0 < slow.stats["python_steps"]
    if mu > 0 and K > 1e3:
        kinds = {e.kind for e in fast.events}
        assert {"slip_reversal", "stick_entry", "stick_exit"} <= kinds


def test_exact_free_flight_and_observed_order():
    """Free flight in closed form (model.free_flight): error falls like h^8."""
    p = ModelParams(**{**FIG3, "e": 0.1}, mu=0.0)
    start = (0.1, 0.2, 0.3, -0.1)  # small orbit: free for ever (steady amplitude 0.16)
    prob = Problem.from_periods(p, start, 3, 40)
    exact = model.free_flight(prob.t_eval, 0.0, start, p)
    errors, steps = [], []
    for rtol in (1e-5, 1e-7, 1e-9):
        sol = solve(prob, "dop853-jit", rtol=rtol, atol=rtol * 1e-3)
        assert sol.status == SUCCESS and not sol.events
        errors.append(np.max(np.abs(sol.states - exact.T)))
        steps.append(sol.stats["nsteps"])
    assert errors[-1] < 1e-9
    order = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert 6.0 < order < 10.0, (steps, errors)


@pytest.mark.parametrize("K", [17.6, 17.6e3])
def test_stays_on_the_exact_synchronous_rub(K):
    p = ModelParams(**{**FIG3, "K": K}, mu=0.01)
    prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p)), 3, 20)
    sol = solve(prob, "dop853-jit", rtol=1e-10, atol=1e-12)
    assert sol.status == SUCCESS and not sol.events
    exact = model.synchronous_rub(prob.t_eval, p).T
    assert np.max(np.abs(sol.states[:, :2] - exact[:, :2])) < 1e-7


def test_budget_stops_keep_the_partial_result():
    prob = fig3_problem(0.03, 20)
    sol = solve(prob, "dop853-jit", rtol=1e-9, atol=1e-11, max_steps=500)
    assert sol.status == FAILED and "step budget" in sol.message
    assert 1 < sol.t.size < prob.t_eval.size
    full = solve(prob, "dop853-jit", rtol=1e-9, atol=1e-11)
    n = sol.t.size
    assert np.max(np.abs(sol.states - full.states[:n])) == 0.0


def test_fallback_when_the_kernels_are_unusable(monkeypatch):
    """If the compiled kernels fail their probe (``kernels.ensure_fresh()`` is False),
    dop853-jit runs scipy's DOP853 instead: it says so (``compiled`` False) and is still
    right, against the closed-form free flight (a start that never reaches z = 1)."""
    from rubcli.solvers import compiled as kernels

    calls = []
    monkeypatch.setattr(kernels, "ensure_fresh", lambda: calls.append(1) or False)
    p = ModelParams(**{**FIG3, "e": 0.3}, mu=0.0)
    start = (0.2, -0.1, 0.05, 0.1)
    prob = Problem.from_periods(p, start, 3, 20)
    exact = model.free_flight(prob.t_eval, 0.0, start, p).T
    assert np.max(np.hypot(exact[:, 0], exact[:, 1])) < 0.9
    sol = solve(prob, "dop853-jit", rtol=1e-10, atol=1e-12)
    assert calls and sol.method == "dop853-jit" and sol.settings["compiled"] is False
    assert sol.status == SUCCESS and not sol.events
    assert 1e-15 < np.max(np.abs(sol.states - exact)) < 1e-8


def test_step_below_the_spacing_of_floats_fails_cleanly_with_the_reason():
    """A forcing of 1e100 from rest at tau = 1e10 (where doubles are 1.9e-6 apart): DOP853's
    initial step (scaled by 1 / |f|) is below the spacing of tau, so the run stops there
    with that reason, exactly as scipy's DOP853 does; one finite sample, no traceback."""
    p = ModelParams(nu=0.0, eta=1.0, e=1e100, K=17.6, mu=0.0, Rp=0.0)
    t0 = 1e10
    prob = Problem(p, (0.0, 0.0, 0.0, 0.0), t0 + np.linspace(0.0, 2 * p.period, 21))
    sol = solve(prob, "dop853-jit", rtol=1e-6, atol=1e-8)
    assert sol.status == FAILED
    assert sol.message == (
        f"dop853-jit failed at tau = {t0:g}: required step size is less than spacing between "
        "numbers"
    )
    assert sol.t.size == 1 and np.all(np.isfinite(sol.states))
    scipy_run = solve(prob, "dop853", rtol=1e-6, atol=1e-8)
    assert scipy_run.message.lower() == sol.message.replace("-jit", "").lower() + "."


def test_vendored_tableau_is_scipys():
    """The vendored DOP853 coefficients equal scipy's, array for array (bitwise)."""
    from scipy.integrate._ivp import dop853_coefficients as scipy_tableau

    from rubcli.solvers import dop853_coefficients as vendored

    for name in ("A", "B", "C", "D", "E3", "E5"):
        assert np.array_equal(getattr(vendored, name), getattr(scipy_tableau, name)), name
    assert vendored.N_STAGES == scipy_tableau.N_STAGES
    assert vendored.INTERPOLATOR_POWER == scipy_tableau.INTERPOLATOR_POWER

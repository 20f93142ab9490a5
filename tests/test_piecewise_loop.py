"""The analytic methods' compiled loop (compiled/piecewise_loop.py) and its free-flight
and stick propagators (compiled/piecewise.py) against the Python path (analytic.py).

The stick step is one definition (compiled/piecewise.py) that the Python path runs as
Python and the loop runs compiled (bitwise the same step on the same numbers; over a run
1e-13, through numpy's and libm's sin/cos in the rolling law), checked against the RK4
step written out independently. The free flight has a compiled copy of ``model.free_flight``
(numpy's closed form stays the Python path's): equal to 1e-13, because numpy evaluates
exp/cos/sin with its own vectorised routines, which may differ from libm's by an ulp.
"""

import numpy as np
import pytest

from rubcli import model
from rubcli.analysis.accuracy import stress
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import analytic, solve
from rubcli.solvers.compiled import piecewise

FIG3F = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.05, Rp=46.16)
PARAMS = [
    FIG3F,
    ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0, phi0=0.4),
    ModelParams(nu=1.5, eta=0.3, e=2.0, K=10.0),  # over-damped: cosh/sinh basis
    ModelParams(nu=1.0, eta=0.3, e=2.0, K=10.0),  # critically damped
    ModelParams(nu=0.0, eta=1.0, e=0.1, K=10.0),  # undamped resonance: secular solution
]


@pytest.mark.parametrize("params", PARAMS)
def test_compiled_free_flight_is_the_closed_form(params):
    pars = np.array(model.params_vector(params))
    rng = np.random.default_rng(3)
    ff, row, drow = np.empty(5), np.empty(4), np.empty(4)
    for _ in range(20):
        tau0 = rng.uniform(0.0, 50.0)
        s0 = rng.normal(size=4)
        prop = analytic.FreeFlight(tau0, s0, params)
        piecewise._free_prepare(tau0, s0, pars, ff)
        assert piecewise.free_omega_max(pars) == prop.omega_max
        for t in tau0 + rng.uniform(0.0, 30.0, size=5):
            piecewise.free_ev(t, True, (ff, pars), row, drow)
            want = prop.states(t)
            np.testing.assert_allclose(row, want, rtol=1e-13, atol=1e-13)
            np.testing.assert_allclose(drow, prop.derivatives(t, want), rtol=1e-13, atol=1e-13)


def _rk4_hermite(tau0, s0, h, params, times):
    """The rolling law's RK4 step and Hermite cubic, written independently in numpy."""

    def f(t, s):
        return model.rhs(t, s, params, model.STICK)

    k1 = f(tau0, s0)
    k2 = f(tau0 + h / 2, s0 + h / 2 * k1)
    k3 = f(tau0 + h / 2, s0 + h / 2 * k2)
    k4 = f(tau0 + h, s0 + h * k3)
    s1 = s0 + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    f1 = f(tau0 + h, s1)
    u = (times - tau0) / h
    basis = (2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, u**3 - u**2)
    return s1, sum(np.outer(c, b) for c, b in zip((s0, h * k1, s1, h * f1), basis, strict=True))


@pytest.mark.parametrize("params", PARAMS[:2])
def test_stick_step_compiled_python_and_independent(params):
    """The compiled stick step is bitwise the Python StickStep (the same definition run
    as Python), and both are the RK4 step and Hermite cubic written out in numpy."""
    pars = np.array(model.params_vector(params))
    rng = np.random.default_rng(5)
    st, meta, row, drow = np.empty((4, 4)), np.empty(2), np.empty(4), np.empty(4)
    for _ in range(20):
        tau0, h = rng.uniform(0.0, 50.0), rng.uniform(1e-3, 0.1)
        s0 = np.r_[rng.normal(size=2) * 0.3 + [1.01, 0.2], 0.0, 0.0]
        s0 = model.project_to_rolling(s0, params)
        prop = analytic.StickStep(tau0, s0, h, params)
        piecewise.stick_prepare(tau0, s0, h, pars, st, meta)
        assert piecewise.stick_omega_max(pars) == prop.omega_max
        np.testing.assert_array_equal(st, [prop.s0, prop.s1, prop.f0, prop.f1])
        times = tau0 + h * np.r_[0.0, rng.uniform(size=4), 1.0]
        s1, cubic = _rk4_hermite(tau0, s0, h, params, times)
        np.testing.assert_array_equal(prop.s1, s1)
        np.testing.assert_allclose(prop.states(times), cubic, rtol=1e-15, atol=1e-15)
        samples = prop.states(times)
        for i, t in enumerate(times):
            piecewise.stick_ev(t, True, (st, meta, pars), row, drow)
            np.testing.assert_array_equal(row, prop.states(t))
            np.testing.assert_array_equal(drow, model.rhs(t, row, params, model.STICK))
            np.testing.assert_array_equal(row, samples[:, i])


# ------------------------------------------------------------------ the compiled loop

ANALYTIC = ["analytic", "analytic-polar"]
FIG3F_START = (0.88544, -0.8039, 0.0, 0.0)
FORCED = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)  # stick-slip cycles


def both_paths(prob, method, **options):
    compiled = solve(prob, method, compiled=True, **options)
    python = solve(prob, method, compiled=False, **options)
    assert python.stats["n_compiled_steps"] == 0 and compiled.settings["compiled"]
    return compiled, python


def assert_same(compiled, python, state_tol, time_tol):
    """Same status, events (kinds, regimes; times to time_tol), regimes and step counts;
    states to state_tol relative to 1 + |state| (0: bitwise)."""
    assert compiled.status == python.status, compiled.message
    assert [(e.kind, e.regime_before, e.regime_after) for e in compiled.events] == [
        (e.kind, e.regime_before, e.regime_after) for e in python.events
    ]
    times = np.array([e.tau for e in compiled.events])
    np.testing.assert_allclose(times, [e.tau for e in python.events], rtol=0, atol=time_tol)
    np.testing.assert_array_equal(compiled.regimes, python.regimes)
    for key in ("nsteps", "n_free_segments", "n_contact_steps", "n_stick_steps"):
        assert compiled.stats[key] == python.stats[key], key
    err = np.max(np.abs(compiled.states - python.states) / (1.0 + np.abs(python.states)))
    assert err <= state_tol


def rolling_start(p):
    r = model.rolling_whirl_radius(p)
    return (r, 0.0, 0.0, -p.Rp * p.eta)


@pytest.mark.parametrize("method", ANALYTIC)
def test_loop_in_free_flight_is_the_closed_form_across_calls(method, monkeypatch):
    """A free flight that never touches, 40 periods, with the loop's work limited to 3
    scan chunks a call: the loop continues the same closed form across its calls (one
    free segment, one step), so every sample is model.free_flight from the start."""
    monkeypatch.setattr(analytic, "KERNEL_CHUNK_STEPS", 3)
    p = ModelParams(nu=0.02, eta=0.7, e=0.2, K=100.0, mu=0.1, Rp=2.0)
    prob = Problem.from_periods(p, (0.1, 0.0, 0.0, 0.0), 40, 20)
    compiled, python = both_paths(prob, method)
    assert compiled.stats["nsteps"] == compiled.stats["n_free_segments"] == 1
    assert not compiled.events and np.all(compiled.regimes == model.FREE)
    exact = model.free_flight(prob.t_eval, 0.0, np.array(prob.initial), p).T
    np.testing.assert_allclose(compiled.states, exact, rtol=0, atol=1e-13)
    assert_same(compiled, python, 1e-13, 0.0)


@pytest.mark.parametrize("method", ANALYTIC)
def test_loop_in_stick_is_the_python_stick(method):
    """On the exact rolling whirl the run stays in stick: the loop's steps are the
    Python steps, one definition of the step; equal to 1e-13, not bitwise, because the
    rolling law (``model.stick_friction_value``) calls numpy's sin/cos/hypot, which in
    Python are numpy's own routines on a scalar and in compiled code libm's."""
    p = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.3, Rp=2.0)
    prob = Problem.from_periods(p, rolling_start(p), 2, 20)
    compiled, python = both_paths(prob, method)
    assert np.all(compiled.regimes == model.STICK) and not compiled.events
    assert compiled.stats["n_compiled_steps"] == compiled.stats["n_stick_steps"] == 800
    assert_same(compiled, python, 1e-13, 0.0)


@pytest.mark.parametrize("method", ANALYTIC)
@pytest.mark.parametrize("scenario", ["stick-slip", "fig3f", "touch", "apex"])
def test_loop_events_agree_with_the_python_path(method, scenario):
    """Stick entries and exits (stick-slip cycles), contact entries and exits in
    the chaotic Figure 3(f) start, a tangential touch and a start at its apex (grazing):
    the same events, regimes and step counts as the Python path (no spurious contact at
    the touch); states to 1e-10 (the
    slip steps' eigenbasis: the loop's small eigensolver against LAPACK), event times
    to 1e-11 (Brent's method in the loop against scipy's brentq, both to 1e-14 in tau)."""
    if scenario == "stick-slip":
        prob, spp = Problem.from_periods(FORCED, rolling_start(FORCED), 2, 20), 400
    elif scenario == "fig3f":
        prob, spp = Problem.from_periods(FIG3F, FIG3F_START, 4, 50), 400
    else:
        touch = ModelParams(nu=0.05, eta=0.7818, e=0.0, K=1.75e4, mu=0.1, Rp=46.16)
        start, t_touch = stress.touching_start(touch, (0.3, -0.5, 0.4, 0.6))
        if scenario == "apex":
            start = tuple(model.free_flight(t_touch, 0.0, np.array(start), touch))
        prob = Problem.from_periods(touch, tuple(start), 1, 50)
        spp = 200
    compiled, python = both_paths(prob, method, steps_per_period=spp)
    kinds = {e.kind for e in compiled.events}
    if scenario == "stick-slip":
        assert {"stick_entry", "stick_exit"} <= kinds
        assert compiled.stats["n_stick_steps"] > 0
    if scenario == "fig3f":
        assert {"contact_entry", "contact_exit"} <= kinds
    assert compiled.stats["n_compiled_steps"] >= 0.99 * (
        compiled.stats["n_contact_steps"] + compiled.stats["n_stick_steps"]
    )
    assert_same(compiled, python, 1e-10, 1e-11)


@pytest.mark.parametrize("method", ANALYTIC)
def test_loop_chunks_and_event_buffer_do_not_change_the_run(method, monkeypatch):
    """The loop returns to Python every few steps and with a full event buffer of 2:
    the same run as in long calls (states to round-off: a slip step after a return
    starts its eigensolver cold)."""
    prob = Problem.from_periods(FORCED, rolling_start(FORCED), 2, 20)
    whole = solve(prob, method, steps_per_period=400)
    monkeypatch.setattr(analytic, "KERNEL_CHUNK_STEPS", 7)
    monkeypatch.setattr(analytic, "EVENT_BUFFER", 2)
    chunked = solve(prob, method, steps_per_period=400)
    assert len(whole.events) > 4
    assert_same(chunked, whole, 1e-12, 1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("method", ANALYTIC)
@pytest.mark.parametrize("analytic_tol", [None, 1e-8])
@pytest.mark.parametrize("start", ["rest", "rolling"])
def test_loop_grows_its_scan_buffers_without_changing_the_run(
    method, analytic_tol, start, monkeypatch
):
    """The compiled loops start from scan buffers of one point: each step whose grid
    needs more (free-flight chunks and slip steps from rest, stick steps of a twentieth
    of a period on the rolling whirl) returns untaken for larger ones, and the run is the
    one with large buffers (states to round-off: a slip step after a return starts its
    eigensolver cold)."""
    if start == "rest":
        prob, spp = Problem.from_periods(FORCED, (0.0, 0.0, 0.0, 0.0), 20, 20), 400
    else:
        prob, spp = Problem.from_periods(FORCED, rolling_start(FORCED), 2, 20), 20
    whole = solve(prob, method, steps_per_period=spp, analytic_tol=analytic_tol)
    grown = []
    grow = analytic.PiecewiseStepper._grow

    def spy(self, need):
        grown.append(need)
        grow(self, need)

    monkeypatch.setattr(analytic, "KERNEL_SCAN_POINTS", 1)
    monkeypatch.setattr(analytic.PiecewiseStepper, "_grow", spy)
    small = solve(prob, method, steps_per_period=spp, analytic_tol=analytic_tol)
    assert grown and all(b > a for a, b in zip(grown, grown[1:], strict=False))
    assert [e.kind for e in small.events] == [e.kind for e in whole.events]
    for key in ("nsteps", "n_free_segments", "n_stick_steps", "n_contact_steps"):
        assert small.stats[key] == whole.stats[key], key
    assert_same(small, whole, 1e-12, 1e-12)

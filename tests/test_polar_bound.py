"""The polar step's mode bounds (``precheck.polar_step_clear``): the compiled analytic
loops skip a contact step's scan grid where they prove that no event can occur.

The bound must hold for every point of the step (checked against the closed form
sampled densely, on random contact steps of soft and stiff stators, with and without
friction), and it must be tight enough to clear the steps of a ringing stiff rub
(otherwise the grid, some 1,000 evaluations a step at K = 1.75e6, comes back). That the
outputs do not change is tests/test_golden.py's (ring-K1.75e6: analytic-polar with
friction in persistent contact) and test_piecewise_loop.py's (compiled against the
Python path, which always scans).
"""

import numpy as np
import pytest

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.solvers.compiled import precheck, propagators

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16}


def _prepared(params, tau0, s0, mu_c):
    ws = propagators.workspace()
    pars = np.array(model.params_vector(params))
    cond, _ = propagators._prepare_polar(tau0, np.asarray(s0, float), pars, mu_c, ws, False)
    return ws, cond


def _polar_samples(ws, h, n=4001):
    """The polar state P(s) (r, theta, r', theta') of the step on a dense grid of [0, h]."""
    out, dout = np.empty(4), np.empty(4)
    P = np.empty((n, 4))
    for i, s in enumerate(np.linspace(0.0, h, n)):
        propagators._evaluate_polar(s, ws, out, dout)
        P[i] = ws[13]  # _evaluate_polar's polar state
    return P


@pytest.mark.slow
@pytest.mark.parametrize("K", [17.6, 1.76e4, 1.75e6])
@pytest.mark.parametrize("mu", [0.0, 0.05])
def test_component_ranges_hold_on_the_whole_step(K, mu):
    params = ModelParams(**FIG3, K=K, mu=mu)
    rng = np.random.default_rng(7)
    tighter = 0  # steps where the range is tighter than the integral bound alone
    for _ in range(12):
        r = 1.0 + rng.uniform(1e-6, 0.3) / np.sqrt(K / 17.6)
        theta = rng.uniform(0.0, 2 * np.pi)
        ur, ut = rng.normal(scale=0.3, size=2) * np.array([np.sqrt(1 + K) * (r - 1), 1.0])
        s0 = (
            r * np.cos(theta),
            r * np.sin(theta),
            ur * np.cos(theta) - r * ut * np.sin(theta),
            ur * np.sin(theta) + r * ut * np.cos(theta),
        )
        tau0 = rng.uniform(0.0, 50.0)
        ws, _ = _prepared(params, tau0, s0, mu * np.sign(rng.normal()))
        lam, V, coef = ws[0], ws[1], ws[3]
        for h in (params.period / 400, params.period / 25, params.period / 4):
            P = _polar_samples(ws, h)
            p0 = ws[5][:4]
            for i in (0, 3):  # r and theta'
                lo, hi = precheck._component_range(i, lam, V, coef, h)
                dev = P[:, i] - p0[i]
                slack = 1e-12 * (1.0 + np.max(np.abs(P[:, i])))
                assert lo - slack <= dev.min() and dev.max() <= hi + slack, (i, h, lo, hi)
                g = np.maximum(1.0, np.exp(lam.real * h))
                spread = np.abs(V[i]) * (np.abs(coef[0]) * h + 0.5 * np.abs(coef[1]) * h * h) * g
                tighter += int(hi - lo < 2.0 * np.sum(spread) * (1.0 - 1e-9))
    assert tighter  # the oscillation form of a mode (not the integral bound alone) was used


@pytest.mark.slow
def test_clearance_implies_no_event_anywhere_in_the_step():
    """Wherever the bound clears a step, r > 1 and sign v_r > 0 on the dense samples
    (with a small rotor radius, so that v_r = Rp eta + r theta' takes either sign)."""
    rng = np.random.default_rng(11)
    cleared = refused = backward = 0
    for K in (17.6, 1.76e4, 1.75e6):
        for mu, Rp in ((0.0, 46.16), (0.05, 46.16), (0.05, 0.4)):
            params = ModelParams(**{**FIG3, "Rp": Rp}, K=K, mu=mu)
            spin = params.Rp * params.eta
            for _ in range(40):
                r = 1.0 + rng.uniform(0.0, 0.3) / np.sqrt(K / 17.6)
                ur = rng.normal(scale=0.5 * np.sqrt(1 + K) * (r - 1))
                ut = rng.choice([-1.0, 1.0]) * params.eta + rng.normal(scale=0.3)
                s0 = (r, 0.0, ur, r * ut)
                sign = 1.0 if spin + r * ut > 0 else -1.0
                ws, cond = _prepared(params, 0.3, s0, mu * sign)
                h = params.period / rng.choice([25, 100, 400])
                if not precheck.polar_step_clear(ws, h, cond, sign, mu > 0.0, spin):
                    refused += 1
                    continue
                cleared += 1
                backward += int(mu > 0.0 and sign < 0.0)
                P = _polar_samples(ws, h)
                assert np.all(P[:, 0] > 1.0)
                if mu > 0.0:
                    assert np.all(sign * (spin + P[:, 0] * P[:, 3]) > 0.0)
    assert cleared > 20 and refused > 20 and backward > 5  # every outcome occurs


@pytest.mark.parametrize("steps_per_period", [10, 25])
def test_bound_clears_every_step_of_a_ringing_stiff_rub(steps_per_period):
    """K = 1.75e6, the synchronous rub with its radius raised by half its penetration:
    the contact mode rings between 1.2e-6 and 3.6e-6 clearances of penetration. At every
    step start of a run the bound must clear the step (a bound that takes every mode by
    its integral, |c0| h, cannot clear those that start near the trough; one that takes
    the whirl modes, |lam| h = 1.7 at 10 steps a period, by their integral cannot clear
    those of 10 steps a period)."""
    params = ModelParams(**FIG3, K=1.75e6, mu=0.0)
    r = model.synchronous_rub_radii(params)[-1]
    s0 = model.synchronous_rub(0.0, params, r)
    s0[:2] *= 1.0 + 0.5 * (r - 1.0)
    problem = Problem.from_periods(params, tuple(s0), 2, steps_per_period)
    sol = solve(problem, "analytic-polar", steps_per_period=steps_per_period)
    assert sol.success and len(sol.events) == 0
    h = params.period / steps_per_period
    depths = []
    for tau, s in zip(sol.t[:-1], sol.states[:-1], strict=True):
        ws, cond = _prepared(params, tau, s, 0.0)
        depths.append(np.hypot(s[0], s[1]) - 1.0)
        assert precheck.polar_step_clear(ws, h, cond, 1.0, False, params.Rp * params.eta)
    assert min(depths) < 1.5e-6 < 3.3e-6 < max(depths)  # troughs and crests both met


def test_a_near_zero_mode_is_bounded_by_its_integral():
    """A mode with lam ~ 0 (a slow drift): its oscillation form's terms (d ~ c1 / lam^2,
    5e16 here) cancel to rounding noise far wider than the drift, or, unwidened, give a
    range that misses it; the range must be the integral bound, |c0| h + |c1| h^2 / 2."""
    lam = np.array([1e-9j, 3.0j, -3.0j, -0.5 + 0j])
    V = np.eye(4, dtype=np.complex128)
    coef = np.array([[0.3, 0.1, 0.1, 0.2], [0.05, 0.02, 0.02, 0.01]], dtype=np.complex128)
    h = 0.7
    lo, hi = precheck._component_range(0, lam, V, coef, h)
    integral = abs(coef[0, 0]) * h + 0.5 * abs(coef[1, 0]) * h * h
    assert -integral * (1 + 1e-12) <= lo < 0.0 < hi <= integral * (1 + 1e-12)
    # and the drift itself lies inside: w(s) = c0 s + c1 s^2 / 2 for lam -> 0
    s = np.linspace(0.0, h, 101)
    drift = (coef[0, 0] * s + 0.5 * coef[1, 0] * s * s).real
    assert lo <= drift.min() and drift.max() <= hi

"""The analytic methods' compiled loop (compiled/piecewise_loop.py) and its free-flight
and stick propagators (compiled/piecewise.py) against the Python path (analytic.py).

The stick step is one definition (compiled/piecewise.py) that the Python path runs as
Python and the loop runs compiled: bitwise the same, and checked against the RK4 step
written out independently. The free flight has a compiled copy of ``model.free_flight``
(numpy's closed form stays the Python path's): equal to 1e-13, because numpy evaluates
exp/cos/sin with its own vectorised routines, which may differ from libm's by an ulp.
"""

import numba
import numpy as np
import pytest

from rubcli import model
from rubcli.model import ModelParams
from rubcli.solvers import analytic
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
            piecewise._free_ev(t, True, (ff, pars), row, drow)
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
            piecewise._stick_ev(t, True, (st, meta, pars), row, drow)
            np.testing.assert_array_equal(row, prop.states(t))
            np.testing.assert_array_equal(drow, model.rhs(t, row, params, model.STICK))
            _sample_compiled(t, st, meta, row)
            np.testing.assert_array_equal(row, samples[:, i])


@numba.njit
def _sample_compiled(t, st, meta, row):
    piecewise.stick_sample(t, st, meta, row)

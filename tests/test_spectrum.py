"""Full spectrum of the whirl (rubcli.analysis.response.spectrum) against exact signals and
orbits."""

import math

import numpy as np
import pytest

from rubcli import model
from rubcli.analysis.response.spectrum import (
    BACKWARD,
    FORWARD,
    STATIC,
    full_spectrum,
    solution_spectrum,
)
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

ETA = 0.7818
PERIOD = 2.0 * math.pi / ETA


def _record(periods=50, per_period=100):
    return np.linspace(0.0, periods * PERIOD, periods * per_period + 1)[:-1]


@pytest.mark.parametrize("order", [1.0, -0.37, 2.3, -3.14159, 0.511])
def test_lone_line_frequency_and_amplitude(order):
    """A line between bins (Hann + Grandke interpolation) is found to 1e-9 in frequency
    and amplitude, with a small second line and an offset beside it."""
    t = _record()
    w = 1.2 * np.exp(1j * (order * ETA * t + 0.3)) + 0.1 + 0.05 * np.exp(-1.7j * ETA * t)
    s = full_spectrum(t, w, ETA)
    assert s.dominant_order == pytest.approx(order, abs=1e-6)
    assert s.dominant_amplitude == pytest.approx(1.2, rel=1e-6)
    assert s.direction == (FORWARD if order > 0 else BACKWARD)
    assert s.static_offset == pytest.approx(0.1, rel=1e-3)
    # the full spectrum keeps the sign: the second line appears at -1.7X, not +1.7X
    k_minus = int(np.argmin(np.abs(s.order + 1.7)))
    k_plus = int(np.argmin(np.abs(s.order - 1.7)))
    assert s.amplitude[k_minus] == pytest.approx(0.05, rel=1e-4)  # leakage of the big line
    assert s.amplitude[k_plus] < 1e-4


def test_no_whirl_is_static():
    t = _record(10)
    s = full_spectrum(t, 0.3 + 0.0 * t, ETA)
    assert s.direction == STATIC and s.static_offset == pytest.approx(0.3)


@pytest.mark.parametrize(
    "t, w, why",
    [
        (np.arange(4.0), np.ones(4), "at least 8"),
        (np.r_[0.0, np.cumsum(np.linspace(1, 2, 15))], np.ones(16), "uniform"),
        (np.arange(16.0), np.r_[np.ones(15), np.nan], "not finite"),
    ],
)
def test_bad_input(t, w, why):
    with pytest.raises(ValueError, match=why):
        full_spectrum(t, w, ETA)


def test_synchronous_rub_is_forward_1x_at_its_radius(fig3_params):
    """Started on the exact synchronous rub (notes 5): +1X, amplitude r = 1.23389475778."""
    params = fig3_params(0.0)
    r = model.synchronous_rub_radii(params)[-1]
    start = model.synchronous_rub(0.0, params, r)
    problem = Problem.from_periods(params, start, 20, 64)
    sol = solve(problem, "dop853-jit", rtol=1e-10, atol=1e-12)
    s = solution_spectrum(sol)
    assert s.direction == FORWARD
    assert s.dominant_order == pytest.approx(1.0, abs=1e-9)
    assert s.dominant_amplitude == pytest.approx(1.23389475778, rel=1e-8)


def test_rolling_whirl_is_backward_at_minus_rp_over_r():
    """The exact rolling backward whirl (e = 0, notes 4): w = r exp(-i (Rp eta / r) tau),
    a line at order -Rp / r, whatever the running speed's own line."""
    params = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.1, Rp=2.0)
    r = model.rolling_whirl_radius(params)
    problem = Problem.from_periods(params, (r, 0.0, 0.0, -params.Rp * params.eta), 30, 64)
    sol = solve(problem, "dop853-jit", rtol=1e-10, atol=1e-12)
    assert sol.success
    s = solution_spectrum(sol, transient_periods=0.0)
    assert s.direction == BACKWARD
    assert s.dominant_order == pytest.approx(-params.Rp / r, rel=1e-6)
    assert s.dominant_amplitude == pytest.approx(r, rel=1e-6)


def test_solution_spectrum_needs_a_period(fig3_params):
    problem = Problem.from_periods(fig3_params(0.0), (0.1, 0.0, 0.0, 0.0), 2, 32)
    sol = solve(problem, "dop853-jit")
    with pytest.raises(ValueError, match="less than one forcing period"):
        solution_spectrum(sol, transient_periods=1.5)

"""Response classification and Lyapunov exponents on signals whose answer is known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rubcli.analysis import response as rsp

PERIOD = 2.0 * math.pi  # forcing period of the constructed signals (forcing frequency 1)
TIME = np.linspace(0.0, 300 * PERIOD, 300 * 50 + 1)


def _states(terms):
    """States (x, y, vx, vy) of w = sum a exp(i f t), with exact velocities."""
    w = sum(a * np.exp(1j * f * TIME) for a, f in terms)
    v = sum(1j * f * a * np.exp(1j * f * TIME) for a, f in terms)
    return np.column_stack([w.real, w.imag, v.real, v.imag])


def _classify(states, **options):
    section = rsp.stroboscopic_section(TIME, states, PERIOD, transient_periods=20)
    assert len(section) == 281
    return rsp.classify_section(section.points, **options)


def test_section_samples_one_point_per_period_and_interpolates_between_samples():
    states = _states([(1.2, 1.0), (0.3, 1.0 / 3.0)])
    # On the grid: the times are exact multiples of the period.
    section = rsp.stroboscopic_section(TIME, states, PERIOD, transient_periods=3)
    np.testing.assert_allclose(section.tau[:2], [3 * PERIOD, 4 * PERIOD])
    w3 = 1.2 + 0.3 * np.exp(1j * 2 * math.pi * 3 / 3)
    np.testing.assert_allclose(section.points[0, :2], [w3.real, w3.imag], atol=1e-12)
    # Off the grid (phase shift): cubic-spline interpolation, error O(h^4) ~ 1e-6 here.
    shifted = rsp.stroboscopic_section(TIME, states, PERIOD, transient_periods=3, phase=0.123)
    t = shifted.tau[0]
    w = 1.2 * np.exp(1j * t) + 0.3 * np.exp(1j * t / 3)
    np.testing.assert_allclose(shifted.points[0, :2], [w.real, w.imag], atol=1e-5)


def test_period_one_orbit():
    result = _classify(_states([(1.2, 1.0)]), scale=1.2)
    assert (result.kind, result.period) == (rsp.PERIODIC, 1)


def test_period_three_orbit():
    # The subharmonic at 1/3 of the forcing frequency repeats every three periods.
    result = _classify(_states([(1.2, 1.0), (0.3, 1.0 / 3.0)]))
    assert (result.kind, result.period) == (rsp.PERIODIC, 3)
    assert result.return_distances[1] > 0.1  # not period 1 or 2
    assert result.return_distances[2] > 0.1


def test_period_tolerance_is_relative_to_orbit_size():
    # The same period-1 orbit scaled by 1e-6 and by 1e6 is still period 1 ...
    for size in (1e-6, 1e3):
        result = _classify(_states([(1.2 * size, 1.0)]), scale=1.2 * size)
        assert (result.kind, result.period) == (rsp.PERIODIC, 1)
    # ... while a small incommensurate modulation (1e-2 of the orbit) is not periodic.
    result = _classify(_states([(1.2, 1.0), (0.012, math.sqrt(2.0))]), scale=1.2)
    assert result.kind != rsp.PERIODIC


def test_two_frequency_signal_is_quasi_periodic():
    # Incommensurate frequencies 1 and sqrt(2): the section fills a circle.
    result = _classify(_states([(1.2, 1.0), (0.3, math.sqrt(2.0))]))
    assert result.kind == rsp.QUASI_PERIODIC
    assert result.period is None
    assert result.birkhoff_digits > rsp.REGULAR_DIGITS


def test_diverging_signal_is_unbounded():
    w_growth = [(1.0, 1.0 - 0.01j)]  # exp(0.01 t) exp(i t): grows by e^18 over the run
    assert _classify(_states(w_growth)).kind == rsp.UNBOUNDED
    # A slower growth that stays below the norm bound is caught by the growth test.
    slow = [(1.0, 1.0 - 0.004j)]  # grows by e^7 over the run, stays below 1e6
    result = _classify(_states(slow), bound=math.inf)
    assert result.kind == rsp.UNBOUNDED
    assert "grows" in result.message


def test_non_finite_section_is_unbounded():
    points = np.ones((30, 4))
    points[20, 0] = np.nan
    assert rsp.classify_section(points).kind == rsp.UNBOUNDED


def test_too_short_a_section_is_undetermined():
    assert rsp.classify_section(np.ones((3, 4))).kind == rsp.UNDETERMINED


def lorenz(t, s, sigma=10.0, rho=28.0, beta=8.0 / 3.0):
    return np.array([sigma * (s[1] - s[0]), s[0] * (rho - s[2]) - s[1], s[0] * s[1] - beta * s[2]])


def test_lorenz_largest_lyapunov_exponent_matches_the_published_value():
    # J. C. Sprott, Chaos and Time-Series Analysis (Oxford, 2003), Table A.1 / sec. 5.6:
    # the Lorenz system (sigma = 10, rho = 28, beta = 8/3) has lambda_1 = 0.9056.
    propagate = rsp.propagator_from_rhs(lorenz, rtol=1e-10, atol=1e-10)
    est = rsp.largest_lyapunov(
        propagate,
        0.0,
        [1.0, 1.0, 20.0],
        interval=1.0,
        n_intervals=300,
        d0=1e-7,
        transient_intervals=20,
    )
    assert est.exponent == pytest.approx(0.9056, abs=0.05)
    assert 0.0 < est.stderr < 0.05
    assert est.running.shape == (300,)


def test_lyapunov_of_a_linear_flow_is_its_largest_eigenvalue():
    # ds/dt = diag(0.3, -1) s: exact exponent 0.3 from any generic start.
    def propagate(t, s, dt):
        return np.array([s[0] * math.exp(0.3 * dt), s[1] * math.exp(-dt)])

    est = rsp.largest_lyapunov(
        propagate, 0.0, [1.0, 1.0], interval=0.5, n_intervals=50, d0=1e-3, transient_intervals=40
    )
    assert est.exponent == pytest.approx(0.3, abs=1e-6)  # floor: cancellation in s2 - s1


def test_lorenz_is_chaotic_with_and_without_an_exponent():
    from scipy.integrate import solve_ivp

    sol = solve_ivp(
        lorenz,
        (0.0, 320.0),
        [1.0, 1.0, 20.0],
        method="DOP853",
        rtol=1e-10,
        atol=1e-10,
        dense_output=True,
    )
    points = sol.sol(np.arange(20.0, 320.0, 1.0)).T
    assert rsp.classify_section(points).kind == rsp.CHAOTIC  # Birkhoff test alone
    est = rsp.LyapunovEstimate(0.9, 0.01, 1.0, 300, 1e-7, np.full(300, 0.9))
    result = rsp.classify_section(points, lyapunov=est)
    assert result.kind == rsp.CHAOTIC
    assert result.to_dict()["lyapunov"] == 0.9


def test_lyapunov_sign_decides_between_torus_and_attracting_orbit():
    points = _states([(1.2, 1.0), (0.3, math.sqrt(2.0))])[::50][20:]
    zero = rsp.LyapunovEstimate(1e-4, 1e-4, 1.0, 100, 1e-7, np.zeros(100))
    assert rsp.classify_section(points, lyapunov=zero).kind == rsp.QUASI_PERIODIC
    negative = rsp.LyapunovEstimate(-0.05, 1e-3, 1.0, 100, 1e-7, np.zeros(100))
    result = rsp.classify_section(points, lyapunov=negative)
    assert result.kind == rsp.PERIODIC and "still being approached" in result.message


def test_lyapunov_is_not_computed_for_a_periodic_section():
    def never():
        raise AssertionError("the exponent should not be needed")

    result = _classify(_states([(1.2, 1.0)]), scale=1.2, lyapunov=never)
    assert result.kind == rsp.PERIODIC and result.lyapunov is None


def test_birkhoff_digits_separate_regular_from_chaotic_series():
    n = np.arange(400)
    rotation = np.cos(2 * math.pi * (math.sqrt(5.0) - 1.0) / 2.0 * n)
    assert rsp.weighted_birkhoff_digits(rotation) > 8
    x = [0.3]
    for _ in range(399):
        x.append(4.0 * x[-1] * (1.0 - x[-1]))  # logistic map at r = 4: chaotic
    assert rsp.weighted_birkhoff_digits(np.array(x)) < 3

"""Response classification and Lyapunov exponents on signals whose answer is known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rubcli.analysis.response import classification as rsp

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
    # Incommensurate frequencies 1 and sqrt(2): the section is a circle turned by
    # sqrt(2) - 1 of a turn each period, exactly; the section map is a rotation, which the
    # linear fit finds with modulus 1 and that rotation number.
    result = _classify(_states([(1.2, 1.0), (0.3, math.sqrt(2.0))]))
    assert result.kind == rsp.QUASI_PERIODIC
    assert result.period is None
    evidence = result.evidence()
    assert evidence["contraction_rate"] == pytest.approx(1.0, abs=1e-9)
    assert evidence["rotation_number"] == pytest.approx(math.sqrt(2.0) - 1.0, abs=1e-9)
    assert result.to_dict()["label"] == "quasi-periodic (torus)"
    # an exponent below zero cannot make a neutral section contract (it has not converged:
    # the dry whip's case); a positive one contradicts the torus
    points = rsp.stroboscopic_section(TIME, _states([(1.2, 1.0), (0.3, math.sqrt(2.0))]),
                                      PERIOD, transient_periods=20).points  # fmt: skip
    for exponent, kind in ((-0.0075, rsp.QUASI_PERIODIC), (0.0075, rsp.UNDECIDED)):
        lyap = rsp.LyapunovEstimate(exponent, 1e-3, PERIOD, 100, 1e-7, np.zeros(1))
        assert rsp.classify_section(points, lyapunov=lyap).kind == kind


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


def test_too_short_a_section_is_undecided():
    result = rsp.classify_section(np.ones((3, 4)))
    assert result.kind == rsp.UNDECIDED and result.label == "undecided: record too short"


def lorenz(t, s, sigma=10.0, rho=28.0, beta=8.0 / 3.0):
    return np.array([sigma * (s[1] - s[0]), s[0] * (rho - s[2]) - s[1], s[0] * s[1] - beta * s[2]])


@pytest.mark.slow
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


def test_henon_is_chaotic_with_an_exponent_and_undecided_without():
    # The Henon map (a = 1.4, b = 0.3) on its strange attractor, iterated in Python floats:
    # the same points on every machine (a chaotic flow integrated by a library is not: its
    # realisation after 300 time units depends on the rounding of its linear algebra).
    # Largest exponent 0.419 per iteration (Sprott, Chaos and Time-Series Analysis, A.1).
    x, y, section = 0.1, 0.1, []
    for k in range(1300):
        x, y = 1.0 - 1.4 * x * x + y, 0.3 * x
        if k >= 1000:
            section.append((x, y))
    points = np.array(section)
    # chaos is never claimed without a positive exponent: the irregular section alone is
    # "undecided"
    alone = rsp.classify_section(points)
    assert alone.kind == rsp.UNDECIDED and "chaos needs a positive exponent" in alone.message
    est = rsp.LyapunovEstimate(0.419, 0.01, 1.0, 300, 1e-7, np.full(300, 0.419))
    result = rsp.classify_section(points, lyapunov=est)
    assert result.kind == rsp.CHAOTIC
    assert result.to_dict()["lyapunov"] == 0.419
    assert result.to_dict()["evidence"]["lyapunov_significance"] == pytest.approx(41.9)


GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def _torus_section(n=200, rho=GOLDEN):
    """A nonlinear invariant circle turned by rho each period: z_k = f(2 pi rho k) with
    three harmonics, and velocities from a second smooth function of the same angle."""
    theta = 2.0 * math.pi * rho * np.arange(n)
    z = 1.5 * np.exp(1j * theta) + 0.4 * np.exp(2j * theta) + 0.25 * np.exp(-3j * theta)
    v = 0.7 * np.exp(1j * (theta + 0.3)) - 0.2 * np.exp(-2j * theta)
    return np.column_stack([z.real, z.imag, v.real, v.imag]), rho


def test_nonlinear_torus_is_quasi_periodic_with_its_rotation_number():
    points, rho = _torus_section()
    result = rsp.classify_section(points)
    assert result.kind == rsp.QUASI_PERIODIC, result.message
    # NAFF's dominant line is the rotation itself (the largest harmonic), located to far
    # below the Fourier resolution 1/100, and the same in both halves of the record
    assert result.frequencies.rotation_number == pytest.approx(rho - 1.0, abs=1e-7)
    assert result.frequencies.diffusion < 1e-6
    zero = rsp.LyapunovEstimate(1e-4, 1e-3, 1.0, 300, 1e-7, np.zeros(1))
    assert rsp.classify_section(points, lyapunov=zero).kind == rsp.QUASI_PERIODIC


def test_weakly_positive_exponent_is_undecided_not_a_torus():
    """0.009 +- 0.004 per unit time is 2.25 standard errors: neither zero nor positive."""
    points, _ = _torus_section()
    weak = rsp.LyapunovEstimate(0.009, 0.004, 1.0, 100, 1e-7, np.zeros(1))
    result = rsp.classify_section(points, lyapunov=weak)
    assert result.kind == rsp.UNDECIDED, result.message
    assert result.label == "undecided: record too short"
    assert "neither zero nor positive" in result.message
    # the same exponent with a quarter of the error is positive (9 standard errors)
    sharp = rsp.LyapunovEstimate(0.009, 0.001, 1.0, 1600, 1e-7, np.zeros(1))
    assert rsp.classify_section(points, lyapunov=sharp).kind == rsp.CHAOTIC
    # and zero within 2 errors that exclude 10 % growth a period: a torus
    small = rsp.LyapunovEstimate(0.001, 0.002, 1.0, 1600, 1e-7, np.zeros(1))
    assert rsp.classify_section(points, lyapunov=small).kind == rsp.QUASI_PERIODIC


def test_negative_exponent_on_a_nonlinear_section_is_converging_of_unknown_period():
    points, _ = _torus_section()
    negative = rsp.LyapunovEstimate(-0.05, 1e-3, 1.0, 100, 1e-7, np.zeros(100))
    result = rsp.classify_section(points, lyapunov=negative)
    assert result.kind == rsp.CONVERGING and result.period is None
    assert result.label == "converging" and "still being approached" in result.message


def _spiral(n, modulus, turn, centre=(1.0, -0.5, 0.2, 0.3), period=1, seed=1):
    """Section points of a linear map in 4-D: one complex pair (modulus, turn in cycles
    per period) and a faster one, about a fixed point (or a p-cycle of centres)."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(4, 4)))  # a generic basis: the modes mix
    lam1 = modulus * np.exp(2j * math.pi * turn)
    lam2 = 0.5 * np.exp(2j * math.pi * 0.31)
    k = np.arange(n)
    u = np.column_stack([(0.3 * lam1**k).real, (0.3 * lam1**k).imag,
                         (0.2 * lam2**k).real, (0.2 * lam2**k).imag])  # fmt: skip
    centres = np.array(centre, dtype=float) + np.array([[0.8 * (j % period), 0, 0, 0]
                                                          for j in range(n)])  # fmt: skip
    return centres + u @ q.T


def test_slow_spiral_turning_by_a_seventh_is_converging_to_period_1():
    """The failure near the Neimark-Sacker point of the paper's machine, built exactly:
    a spiral that turns 51.75 degrees a period (about 360/7) and contracts by 0.998 a
    period returns close to itself after 7 periods, never after 1. With a negative
    exponent the old rules called it "period 7"; it converges to a fixed point."""
    points = _spiral(100, 0.998, 51.75 / 360.0)
    distances = rsp.return_distances(points, 1.0)
    assert min(distances, key=distances.get) == 7  # the trap
    negative = rsp.LyapunovEstimate(-0.002, 1e-4, 1.0, 100, 1e-7, np.zeros(1))
    result = rsp.classify_section(points, scale=1.0, lyapunov=negative)
    assert (result.kind, result.period) == (rsp.CONVERGING, 1), result.message
    assert result.label == "converging to period 1"
    assert result.contraction.rate == pytest.approx(0.998, abs=1e-9)
    assert abs(result.contraction.rotation) * 360.0 == pytest.approx(51.75, abs=1e-7)
    assert result.lyapunov is None  # the section map decided: no exponent was needed
    # the same spiral growing by 1.002 a period: leaving an unstable orbit
    growing = rsp.classify_section(_spiral(100, 1.002, 51.75 / 360.0), scale=1.0)
    assert growing.kind == rsp.UNDECIDED and "leaving a period-1 orbit" in growing.message
    assert growing.evidence()["contraction_rate"] == pytest.approx(1.002, abs=1e-9)


def test_spiral_onto_a_two_cycle_is_converging_to_period_2():
    points = _spiral(120, 0.95, 0.1, period=2)
    result = rsp.classify_section(points, scale=1.0)
    assert (result.kind, result.period) == (rsp.CONVERGING, 2), result.message
    assert result.contraction.rate == pytest.approx(0.95, abs=1e-9)  # per forcing period


def test_exact_period_one_orbit_has_no_contraction_to_report():
    points = np.tile([1.0, -0.5, 0.2, 0.3], (50, 1))
    result = rsp.classify_section(points, scale=1.2)
    assert (result.kind, result.period, result.contraction) == (rsp.PERIODIC, 1, None)


def henon_propagator(a=1.4, b=0.3):
    """The Henon map as a propagator: dt (an integer) iterations per call."""

    def propagate(t, s, dt):
        x, y = s
        for _ in range(int(round(dt))):
            x, y = 1.0 - a * x * x + y, b * x
        return np.array([x, y])

    return propagate


def test_henon_map_is_chaotic_with_its_published_exponent():
    # J. C. Sprott, Chaos and Time-Series Analysis (Oxford, 2003), Table A.1 (Henon map,
    # a = 1.4, b = 0.3): lambda_1 = 0.41922 per iteration.
    propagate = henon_propagator()
    state = np.array([0.1, 0.1])
    for _ in range(100):
        state = propagate(0, state, 1)
    points = [state]
    for _ in range(199):
        points.append(propagate(0, points[-1], 1))
    est = rsp.largest_lyapunov(propagate, 0.0, points[-1], interval=1.0, n_intervals=2000,
                               d0=1e-9, transient_intervals=20)  # fmt: skip
    assert est.exponent == pytest.approx(0.41922, abs=0.02)
    result = rsp.classify_section(np.array(points), lyapunov=est)
    assert result.kind == rsp.CHAOTIC, result.message
    assert rsp.classify_section(np.array(points)).kind == rsp.UNDECIDED


def test_lyapunov_is_not_computed_for_a_periodic_section():
    def never():
        raise AssertionError("the exponent should not be needed")

    result = _classify(_states([(1.2, 1.0)]), scale=1.2, lyapunov=never)
    assert result.kind == rsp.PERIODIC and result.lyapunov is None


def test_refined_frequencies_locate_lines_far_below_the_fourier_resolution():
    """NAFF (Laskar 1993) on 64 samples of three lines: each within 1e-5 of the truth,
    where the FFT's bins are 1/64 apart (the error left is the lines' leakage into one
    another through the window)."""
    from rubcli.analysis.response.section_map import refined_frequencies

    k = np.arange(64)
    truth = [(0.1234567, 1.0), (-0.3141593, 0.5), (0.4142136, 0.25)]
    z = sum(a * np.exp(2j * math.pi * f * k) for f, a in truth)
    found = refined_frequencies(z, lines=3)
    for (f, a), (g, b) in zip(truth, found, strict=True):
        assert g == pytest.approx(f, abs=1e-5)
        assert b == pytest.approx(a, rel=1e-3)

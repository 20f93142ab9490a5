"""The data the figures draw: bounded point counts, round orbits, keyphasor dots, limits
that ignore failed methods, the spectrum's dominant line, the all-failed message.

Reference numbers come from exact solutions: the synchronous forward full annular rub
(``model.synchronous_rub``, notes section 5) and exact circular whirls; no figure here
needs a solver except the Figure 3(a) spectrum.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rubcli import model, units
from rubcli.analysis.response.spectrum import BACKWARD, FORWARD, steady_spectrum
from rubcli.case import load_case
from rubcli.plotting import display
from rubcli.plotting.energy import RESIDUAL_BOTTOM, residual_limits
from rubcli.plotting.orbit import draw_orbits
from rubcli.plotting.run import _new_figure, orbit_figure, time_figure
from rubcli.plotting.spectrum import order_range, spectrum_figure
from rubcli.problem import Problem
from rubcli.solution import FAILED, Solution

FIG3A = model.ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.0, Rp=46.16)


def exact_rub(periods: float, spp: int, method: str = "exact", params=FIG3A) -> Solution:
    """The exact synchronous rub of the Figure 3 parameters, sampled like a solver would."""
    r = model.synchronous_rub_radii(params)[-1]
    tau0 = np.zeros(1)
    initial = model.synchronous_rub(tau0, params, r)[:, 0]
    problem = Problem.from_periods(params, initial, periods, spp)
    states = model.synchronous_rub(problem.t_eval, params, r).T.copy()
    regimes = np.full(problem.t_eval.size, model.SLIP_POSITIVE)
    return Solution(problem, method, problem.t_eval.copy(), states, regimes)


def whirl(periods: float, spp: int, order: float, radius: float = 1.0) -> Solution:
    """An exact circular whirl w = radius exp(i order eta tau) (states with velocities)."""
    problem = Problem.from_periods(FIG3A, (radius, 0.0, 0.0, 0.0), periods, spp)
    t = problem.t_eval
    omega = order * FIG3A.eta
    w = radius * np.exp(1j * omega * t)
    v = 1j * omega * w
    states = np.column_stack((w.real, w.imag, v.real, v.imag))
    return Solution(problem, "whirl", t.copy(), states, np.zeros(t.size, dtype=np.int64))


def failed_copy(solution: Solution, n: int, blow_up: float = 1e6) -> Solution:
    """The first n samples of ``solution``, the last ones diverging to ``blow_up``, failed."""
    states = solution.states[:n].copy()
    states[-5:, :2] *= np.geomspace(1.0, blow_up, 5)[:, None]
    states[-1] = np.inf
    return Solution(
        solution.problem, "diverged", solution.t[:n].copy(), states, solution.regimes[:n].copy(),
        status=FAILED, message="step size underflow",
    )  # fmt: skip


# ------------------------------------------------------------------ display helpers


def test_envelope_in_chunks_equals_the_whole_reduction_with_bounded_memory(monkeypatch):
    """``envelope`` reduces runs of groups at a time: the same points as one reduction
    over the whole series (ties and a spike included), and its temporaries do not grow
    with the series (tracemalloc: 4x the samples, about the same peak)."""
    import tracemalloc

    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 50.0, 300_001)
    values = np.round(rng.normal(size=t.size), 1)  # many ties within each group
    values[77_777] = 40.0
    monkeypatch.setattr(display, "ENVELOPE_CHUNK", 10**12)  # one run: the whole series
    whole = display.envelope(t, values, bins=500)
    monkeypatch.setattr(display, "ENVELOPE_CHUNK", 1_000)
    chunked = display.envelope(t, values, bins=500)
    np.testing.assert_array_equal(whole[0], chunked[0])
    np.testing.assert_array_equal(whole[1], chunked[1])
    assert 40.0 in chunked[1]
    monkeypatch.setattr(display, "ENVELOPE_CHUNK", 65_536)
    peaks = []
    for n in (1_000_000, 4_000_000):
        tt, vv = np.linspace(0.0, 1.0, n), np.sin(np.linspace(0.0, 900.0, n))
        tracemalloc.start()
        display.envelope(tt, vv)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    # the finite-value mask (1 byte a sample) grows; the per-sample int64 temporaries
    # (group, positions: 16+ bytes a sample) must not
    assert peaks[1] < peaks[0] + 4 * 3_000_000


def test_envelope_keeps_every_extreme_and_bounds_the_points():
    t = np.linspace(0.0, 1000.0, 1_000_001)
    values = np.sin(t) * (1.0 + 0.001 * t)
    values[123_457] = 50.0  # a lone spike must survive
    te, ve = display.envelope(t, values, bins=500)
    assert te.size <= 1000
    assert ve.max() == 50.0 and ve.min() == values.min()
    assert np.all(np.diff(te) >= 0.0)  # still a function of time
    # each bin's own extremes survive: compare with a direct reduction per bin
    edges = np.linspace(0, t.size, 501).astype(int)
    for i in (0, 137, 499):
        chunk = values[edges[i] : edges[i + 1]]
        assert {chunk.min(), chunk.max()} == set(ve[2 * i : 2 * i + 2])
    short_t, short_v = display.envelope(t[:100], values[:100], bins=500)
    assert np.array_equal(short_v, values[:100])


def test_envelope_band_covers_the_envelope_of_every_group():
    """The time figure's band: per group of samples its min and max (checked against a
    direct numpy reduction of each group, and against ``envelope``'s extremes), as steps
    spanning the whole record; None for a short series."""
    t = np.linspace(0.0, 1000.0, 1_000_001)
    values = np.sin(t) * (1.0 + 0.001 * t)
    values[123_457] = 50.0
    values[5] = np.nan  # dropped, as by envelope
    steps, lo, hi = display.envelope_band(t, values, bins=500)
    assert steps.size == lo.size == hi.size == 501
    kept_t, kept = t[np.isfinite(values)], values[np.isfinite(values)]
    starts = np.linspace(0, kept.size, 501).astype(int)[:-1]
    np.testing.assert_array_equal(lo[:-1], np.minimum.reduceat(kept, starts))
    np.testing.assert_array_equal(hi[:-1], np.maximum.reduceat(kept, starts))
    np.testing.assert_array_equal(steps[:-1], kept_t[starts])
    te, ve = display.envelope(t, values, bins=500)
    np.testing.assert_array_equal(lo[:-1], np.minimum(ve[0::2], ve[1::2]))
    np.testing.assert_array_equal(hi[:-1], np.maximum(ve[0::2], ve[1::2]))
    assert steps[0] == t[0] and steps[-1] == t[-1] and np.all(np.diff(steps) > 0.0)
    assert hi.max() == 50.0 and lo[-1] == lo[-2]
    assert display.envelope_band(t[:1000], values[:1000], bins=500) is None


def test_finite_length_with_and_without_non_finite_states():
    sol = exact_rub(periods=4, spp=40)
    n = sol.t.size
    assert display.finite_length(sol) == n
    huge = failed_copy(sol, n)
    huge.states[:] = 1e308  # finite, but their sum overflows: the exact test decides
    assert display.finite_length(huge) == n
    huge.states[17, 2] = np.inf
    assert display.finite_length(huge) == 17


def test_hermite_is_exact_on_cubics_and_of_order_four_on_a_whirl():
    t = np.linspace(0.0, 2.0, 9)
    x, vx = 1.0 - 2.0 * t + 0.5 * t**3, -2.0 + 1.5 * t**2
    y, vy = t**2 - t**3, 2.0 * t - 3.0 * t**2
    tq = np.linspace(0.0, 2.0, 101)
    got = display.hermite(t, np.column_stack((x, y, vx, vy)), tq)
    assert np.allclose(got[:, 0], 1.0 - 2.0 * tq + 0.5 * tq**3, rtol=0, atol=1e-13)
    assert np.allclose(got[:, 1], tq**2 - tq**3, rtol=0, atol=1e-13)
    errors = []
    for spp in (10, 20, 40):
        sol = whirl(2, spp, 1.0)
        fine = display.fine_orbit(sol, 0.0)
        errors.append(np.max(np.abs(np.hypot(fine[:, 0], fine[:, 1]) - 1.0)))
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:], strict=False)]
    assert all(3.7 < p < 4.3 for p in orders), orders


def test_fine_orbit_is_round_where_the_samples_are_a_polygon():
    sol = whirl(3, 10, 1.0)  # 10 samples per period: chords sag by 1 - cos(pi/10) = 0.049
    chord_mid = 0.5 * (sol.states[:-1, :2] + sol.states[1:, :2])
    assert np.max(1.0 - np.hypot(chord_mid[:, 0], chord_mid[:, 1])) > 0.04
    fine = display.fine_orbit(sol, sol.t[0])
    assert fine.shape[0] >= 3 * display.FINE_POINTS_PER_PERIOD
    assert np.max(np.abs(np.hypot(fine[:, 0], fine[:, 1]) - 1.0)) < 1e-3
    # the drawn polyline itself (its chords) stays on the circle
    mid = 0.5 * (fine[:-1] + fine[1:])
    assert np.max(np.abs(np.hypot(mid[:, 0], mid[:, 1]) - 1.0)) < 1e-3


def test_keyphasor_dots_one_per_forcing_period_of_the_steady_span():
    sol = exact_rub(periods=40, spp=50)
    dots = display.keyphasor(sol)  # default steady span: the second half, periods 20..40
    assert dots.shape == (21, 2)
    dots = display.keyphasor(sol, transient_periods=30)
    assert dots.shape == (11, 2)
    # a period-one orbit shows one dot: every keyphasor point is the same state
    assert np.max(np.abs(dots - dots[0])) < 1e-9
    # a whirl at 1.5X is seen at two alternating places (a period-two section)
    two = display.keyphasor(whirl(10, 40, 1.5), transient_periods=0)
    assert two.shape == (11, 2)
    assert np.allclose(two[::2], two[0], atol=1e-9) and np.allclose(two[1::2], two[1], atol=1e-9)
    assert np.linalg.norm(two[1] - two[0]) > 1.0


def test_period_subset_bounds_a_long_transient_without_chords():
    sol = whirl(10_000, 100, 1.0)  # a million samples
    pts = display.period_subset(sol, sol.t[-1])
    assert pts.shape[0] <= 1.05 * display.FADED_POINTS
    breaks = np.isnan(pts[:, 0])
    assert breaks.any()  # skipped periods are separated by breaks
    # consecutive drawn points are neighbouring samples (no chord across skipped periods)
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    step_max = 2.0 * math.sin(math.pi / 100)
    assert np.nanmax(steps) <= step_max * (1 + 1e-9)


def test_orbit_radius_ignores_failed_methods():
    good = exact_rub(periods=4, spp=40)
    bad = failed_copy(good, 100)
    r = np.max(np.abs(good.w))
    assert display.orbit_radius([good, bad]) == pytest.approx(display.MARGIN * r)
    assert display.orbit_radius([bad, good]) == pytest.approx(display.MARGIN * r)
    # with nothing successful, the failed traces count, capped (never 1e6 clearances)
    assert display.orbit_radius([bad]) <= display.MARGIN * 10.0


# ------------------------------------------------------------------ orbit figures


def test_orbit_figure_axes_come_from_successful_methods_and_failures_are_labelled():
    good = exact_rub(periods=20, spp=40)
    bad = failed_copy(good, 300)
    fig = _new_figure(6, 6)
    ax = fig.add_subplot()
    drawing = draw_orbits(ax, [bad, good])
    r = display.MARGIN * np.max(np.abs(good.w))
    assert ax.get_xlim() == pytest.approx((-r, r)) and ax.get_ylim() == pytest.approx((-r, r))
    assert drawing.failed == {"diverged": pytest.approx(float(good.t[298]))}
    labels = ax.get_legend_handles_labels()[1]
    assert any(label.startswith("diverged: failed at tau = ") for label in labels)
    assert drawing.first == "exact" and drawing.keyphasor["exact"] == 11


def test_overlaid_methods_state_their_distance():
    a = exact_rub(periods=20, spp=40)
    b = exact_rub(periods=20, spp=40, method="shifted")
    b.states[:, 0] += 3e-4  # a constant offset: the distance is exactly 3e-4
    fig = _new_figure(6, 6)
    drawing = draw_orbits(fig.add_subplot(), [a, b])
    assert drawing.distance_steady["shifted"] == pytest.approx(3e-4, rel=1e-9)
    assert drawing.distance_all["shifted"] == pytest.approx(3e-4, rel=1e-9)
    fig = orbit_figure([a, b], "title")
    assert "0.0003 steady, 0.0003 whole run (clearances)" in fig.legends[0].get_title().get_text()


def test_long_run_figures_draw_a_bounded_number_of_points():
    sol = whirl(10_000, 100, 1.0)  # 10,000 periods at 100 samples per period
    fig = orbit_figure([sol], "long")
    drawn = sum(line.get_xdata().size for line in fig.axes[0].get_lines())
    assert drawn < display.FADED_POINTS + display.FINE_POINTS + 1000
    fig = time_figure([sol], "long")
    for ax in fig.axes:
        for line in ax.get_lines():
            assert np.size(line.get_xdata()) <= 2 * display.ENVELOPE_BINS


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


@pytest.mark.parametrize("make", [orbit_figure, time_figure])
def test_legends_never_cover_the_axes(make):
    a = exact_rub(periods=4, spp=40)
    fig = make([a, exact_rub(periods=4, spp=40, method="again")], "title")
    fig.canvas.draw()
    legends = fig.legends + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    assert legends
    for legend in legends:
        box = legend.get_window_extent()
        for ax in fig.axes:
            assert not _overlap(box, ax.get_window_extent())


def _texts(fig) -> str:
    return "\n".join(t.get_text() for ax in fig.axes for t in ax.texts)


def test_every_method_failed_gives_a_message_not_a_blank_figure():
    bad = failed_copy(exact_rub(periods=4, spp=40), 50)
    for make in (orbit_figure, time_figure):
        fig = make([bad], "title", failures={"rk45": "ValueError: boom"})
        text = _texts(fig)
        assert "Every method failed" in text
        assert "diverged: failed: step size underflow" in text and "rk45: ValueError" in text
    fig = orbit_figure([], "title", failures={"rk45": "ValueError: boom"})
    assert "rk45: ValueError: boom" in _texts(fig)
    assert "Every method failed" not in _texts(orbit_figure([exact_rub(4, 40)], "title"))
    labels = [t.get_text() for t in orbit_figure([bad], "t").legends[0].get_texts()]
    assert not any("keyphasor" in label for label in labels)  # no dots were drawn


# ------------------------------------------------------------------ spectrum


def test_spectrum_of_the_synchronous_rub_is_one_forward_line_at_1x():
    sol = exact_rub(periods=40, spp=50)
    spectrum = steady_spectrum(sol)
    r = model.synchronous_rub_radii(FIG3A)[-1]
    assert spectrum.direction == FORWARD
    assert spectrum.dominant_order == pytest.approx(1.0, abs=1e-9)
    assert spectrum.dominant_amplitude == pytest.approx(r, rel=1e-9)
    assert order_range(spectrum) == 2.5  # +-1X and room, nothing else above 1e-3
    back = steady_spectrum(whirl(40, 50, -2.7, radius=0.4))
    assert back.direction == BACKWARD and back.dominant_order == pytest.approx(-2.7, abs=1e-6)
    assert order_range(back) == pytest.approx(1.3 * 2.7)


def test_spectrum_figure_physical_axis_and_missing_panels():
    scale = units.physical_scale(m=4.0, k_r=4e5, k_s=4e6, clearance=2e-4)
    spectrum = steady_spectrum(exact_rub(periods=20, spp=40))
    fig = spectrum_figure([("exact", spectrum, ""), ("rk45", None, "failed: boom")], "t",
                          scale=scale)  # fmt: skip
    ax = fig.axes[0]
    assert ax.get_ylabel() == "whirl amplitude (m)"
    assert "rad/s" in ax.get_title()
    top = [c for c in ax.get_children() if type(c).__name__ == "SecondaryAxis"]
    assert top and top[0].get_xlabel() == "frequency (rad/s)"
    assert "rk45: no spectrum\nfailed: boom" in _texts(fig)


def test_fig3a_spectrum_dominant_line_is_1x_forward_at_the_synchronous_rub():
    """Figure 3(a) (mu = 0) settles on the synchronous forward rub (notes section 5)."""
    from rubcli import solvers

    case = load_case("cases/paper/fig3a.toml")
    solution = solvers.solve(case.problem, "dop853-jit", rtol=1e-9, atol=1e-11)
    spectrum = steady_spectrum(solution)
    r = model.synchronous_rub_radii(case.params)[-1]
    assert spectrum.direction == FORWARD
    assert abs(spectrum.dominant_order - 1.0) < 0.01 * spectrum.resolution / case.params.eta
    assert spectrum.dominant_amplitude == pytest.approx(r, rel=1e-3)


# ------------------------------------------------------------------ energy


def test_residual_axis_starts_near_the_quadrature_floor_not_at_1e_308():
    relative = np.concatenate(([0.0], np.geomspace(1e-12, 1e-9, 99)))
    bottom, top = residual_limits(relative, quadrature_error=1e-11)
    assert bottom == pytest.approx(1e-13)  # a decade below the 5th percentile
    assert top == pytest.approx(3e-9)
    bottom, _ = residual_limits(np.zeros(5), quadrature_error=0.0)
    assert bottom == RESIDUAL_BOTTOM


def test_spectrum_of_a_short_record_beside_a_large_static_offset():
    """One steady period: the whirl's bin is next to the 0X line, which is larger; the
    peak is returned unrefined instead of dividing by zero (found by `compare --quick`
    over 2 periods)."""
    problem = Problem.from_periods(FIG3A, (0.0, 0.0, 0.0, 0.0), 2, 40)
    t = problem.t_eval
    w = 5.0 + 0.3 * np.exp(1j * 1.2 * FIG3A.eta * t)  # an offset and a small 1.2X whirl
    states = np.column_stack((w.real, w.imag, np.zeros_like(t), np.zeros_like(t)))
    sol = Solution(problem, "offset", t.copy(), states, np.zeros(t.size, dtype=np.int64))
    spectrum = steady_spectrum(sol)
    assert spectrum is not None and spectrum.direction == FORWARD
    assert abs(spectrum.dominant_order - 1.2) <= spectrum.resolution / FIG3A.eta


def test_energy_figure_keeps_the_spin_drive_off_the_work_of_the_unbalance():
    """With friction the spin drive (its own right-hand axis) rises about like W_in; on an
    axis of its own range the two curves coincided. Its axis spans 1.8 times its range:
    its curve ends near the middle of the panel while W_in's reaches the top."""
    from rubcli.analysis.energy.balance import energy_balance
    from rubcli.plotting.energy import energy_figure
    from rubcli.solvers import solve

    params = model.ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.05, Rp=46.16)
    problem = Problem.from_periods(params, (0.88544, -0.8039, 0.0, 0.0), 30, 50)
    sol = solve(problem, "dop853-jit", rtol=1e-9, atol=1e-11)
    fig = energy_figure([sol], [energy_balance(sol)], "t")
    terms = fig.axes[0]
    (spin,) = [ax for ax in fig.axes if ax.get_ylabel().startswith("spin drive")]

    def top(ax, label):  # the curve's largest value as a fraction of its axis
        (line,) = [ln for ln in ax.get_lines() if ln.get_label().startswith(label)]
        low, high = ax.get_ylim()
        return (np.nanmax(line.get_ydata()) - low) / (high - low)

    assert top(terms, "W_in") > 0.85
    assert top(spin, "spin drive") < 0.7

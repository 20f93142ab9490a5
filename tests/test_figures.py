"""Report-ready figures: what each figure draws, checked on its artists and, where what
counts is what the eye sees, on the rendered pixels. Every solution here is exact (a
synchronous rub, circular whirls, a two-frequency torus) or a small synthetic data set;
nothing is solved.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr
from matplotlib.colors import rgb_to_hsv, to_rgba
from matplotlib.text import Text

from rubcli import model
from rubcli.analysis.charts.forces_map import (
    eigen_map,
    friction_flutter_radius,
    friction_flutter_threshold,
)
from rubcli.analysis.response.classification import PoincareSection, Response
from rubcli.analysis.response.spectrum import steady_spectrum
from rubcli.plotting import axes as ax_tools
from rubcli.plotting import display
from rubcli.plotting.compare import orbits_figure, poincare_figure, shared_radii
from rubcli.plotting.forces import eigen_map_figure
from rubcli.plotting.orbit import COLORS, draw_orbits
from rubcli.plotting.orbits import branch_figure, multipliers_figure
from rubcli.plotting.run import _new_figure, orbit_figure, time_figure
from rubcli.plotting.spectrum import spectrum_figure
from rubcli.plotting.sweep import DIRECTION_COLOURS, bifurcation_figure, cascade_figure
from rubcli.problem import Problem
from rubcli.solution import Solution

FIG3A = model.ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.0, Rp=46.16)


def exact_rub(periods: float, spp: int, method: str = "exact") -> Solution:
    """The exact synchronous rub of the Figure 3 parameters, sampled like a solver would."""
    r = model.synchronous_rub_radii(FIG3A)[-1]
    initial = model.synchronous_rub(np.zeros(1), FIG3A, r)[:, 0]
    problem = Problem.from_periods(FIG3A, initial, periods, spp)
    states = model.synchronous_rub(problem.t_eval, FIG3A, r).T.copy()
    regimes = np.full(problem.t_eval.size, model.SLIP_POSITIVE)
    return Solution(problem, method, problem.t_eval.copy(), states, regimes)


def whirls(periods: float, spp: int, terms, method: str = "whirl") -> Solution:
    """w = sum of radius * exp(i order eta tau) over ``terms`` [(order, radius)], exact."""
    problem = Problem.from_periods(FIG3A, (1.0, 0.0, 0.0, 0.0), periods, spp)
    t = problem.t_eval
    w = sum(r * np.exp(1j * o * FIG3A.eta * t) for o, r in terms)
    v = sum(1j * o * FIG3A.eta * r * np.exp(1j * o * FIG3A.eta * t) for o, r in terms)
    states = np.column_stack((w.real, w.imag, v.real, v.imag))
    return Solution(problem, method, t.copy(), states, np.zeros(t.size, dtype=np.int64))


def pixels(fig) -> np.ndarray:
    """The figure rendered as it is saved (rubcli.io.save_figure's dpi), RGB in [0, 1]."""
    fig.set_dpi(ax_tools.DPI)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(float) / 255.0


def inside(fig, ax, image) -> np.ndarray:
    """The pixels of ``ax`` (rows from the top, as the image)."""
    box = ax.get_window_extent()
    h = image.shape[0]
    return image[int(h - box.y1) + 2 : int(h - box.y0) - 2, int(box.x0) + 2 : int(box.x1) - 2]


# ------------------------------------------------------------------ orbit.png, time.png


def test_keyphasor_legend_entries_have_the_colours_of_the_dots():
    a, b = exact_rub(20, 40), exact_rub(20, 40, method="other")
    fig = orbit_figure([a, b], "title")
    legend = fig.legends[0]
    entries = {t.get_text(): h for t, h in zip(legend.get_texts(), legend.legend_handles,
                                               strict=True)}  # fmt: skip
    dots = [c for c in fig.axes[0].collections if len(c.get_offsets())]
    for index, name in enumerate(("exact", "other")):
        (label,) = [k for k in entries if k.startswith(f"{name}: keyphasor")]
        want = to_rgba(COLORS[index])
        assert to_rgba(entries[label].get_markerfacecolor()) == pytest.approx(want)
        # the newest dot of that method is drawn in exactly that colour
        assert any(np.allclose(c.get_facecolors()[-1], want) for c in dots)


def test_methods_that_agree_both_show_and_their_difference_is_drawn():
    a = exact_rub(20, 40)
    b = exact_rub(20, 40, method="shifted")
    b.states[:, 0] += 3e-4
    fig = orbit_figure([a, b], "title")
    orbit, diff = fig.axes[:2]
    lines = {line.get_label(): line for line in orbit.get_lines()}
    first, other = lines["exact"], lines["shifted"]
    # a thin solid line on top of a thick one: the thick one shows on both sides of it
    assert first.get_linewidth() > 2 * other.get_linewidth()
    assert other.get_zorder() > first.get_zorder() and other.get_linestyle() == "-"
    assert diff.get_yscale() == "log"
    drawn = np.concatenate([line.get_ydata() for line in diff.get_lines()])
    assert np.max(drawn) == pytest.approx(3e-4, rel=1e-9)


def test_time_figure_zooms_on_the_last_periods_and_shows_the_difference():
    a = exact_rub(50, 100)
    b = exact_rub(50, 100, method="shifted")
    b.states[:, 1] += 1e-3
    fig = time_figure([a, b], "title")
    grid = np.array(fig.axes[:8]).reshape(4, 2)
    period = FIG3A.period
    end = float(a.t[-1])
    for ax in grid[:, 1]:
        assert ax.get_xlim() == pytest.approx((end - 3 * period, end))
    for left, right in grid[:3]:  # one value axis for the run and its zoom
        assert left.get_ylim() == pytest.approx(right.get_ylim())
    assert grid[3, 0].get_yscale() == "log" and grid[3, 1].get_yscale() == "log"
    zoomed = np.concatenate([line.get_ydata() for line in grid[3, 1].get_lines()])
    assert np.max(zoomed) == pytest.approx(1e-3, rel=1e-9)
    assert len(time_figure([a], "one").axes) == 6  # one method: no difference row


def test_settled_tells_a_closed_orbit_from_a_band():
    t_from = lambda s: float(s.t[-1]) - 10 * FIG3A.period  # noqa: E731
    rub = exact_rub(30, 50)
    assert display.settled(rub, t_from(rub))
    two = whirls(30, 50, [(1.0, 1.0), (-2.0, 0.4)])  # period one, not circular
    assert display.settled(two, t_from(two))
    torus = whirls(30, 50, [(1.0, 1.0), (math.sqrt(2.0), 0.3)])  # incommensurate: a band
    assert not display.settled(torus, t_from(torus))
    fig = _new_figure(6, 6)
    drawing = draw_orbits(fig.add_subplot(), [torus])
    assert drawing.settled == {"whirl": False}
    span = (float(torus.t[-1]) - drawing.bold_from["whirl"]) / FIG3A.period
    assert span == pytest.approx(3.0)  # only the last periods, thin


# ------------------------------------------------------------------ compare


def test_compare_orbit_panels_share_their_axes():
    assert shared_radii([1.3, 1.9, 2.0, 9.5]) == [2.0, 2.0, 2.0, 9.5]
    assert shared_radii([1.3, 1.5]) == [1.5, 1.5]
    panels = [
        {"title": "a", "solutions": [exact_rub(12, 40)]},
        {"title": "b", "solutions": [whirls(12, 40, [(1.0, 1.6)])]},
        {"title": "c", "solutions": [whirls(12, 40, [(-5.0, 9.0)])]},
    ]
    fig = orbits_figure(panels, "title")
    a, b, c = fig.axes[:3]
    assert a.get_xlim() == pytest.approx(b.get_xlim())
    assert a.get_ylim() == pytest.approx(b.get_ylim())
    assert a.get_xlim()[1] == pytest.approx(display.MARGIN * 1.6)
    assert c.get_xlim()[1] == pytest.approx(display.MARGIN * 9.0)
    assert "the other panels' frame" in c.get_title()


def test_poincare_panels_share_their_axes_and_keep_data_clear():
    def section(radius: float, n: int = 50) -> PoincareSection:
        angle = np.linspace(0.0, 2.0 * np.pi, n)
        pts = radius * np.column_stack((np.cos(angle), np.sin(angle), 0 * angle, 0 * angle))
        return PoincareSection(np.arange(n, dtype=float), pts, 1.0, 0.0)

    response = Response("quasi-periodic", None, None, 50, 1.0, 1e-6)
    fig = poincare_figure([("a", section(1.2), response), ("b", section(1.7), response),
                           ("c", section(8.9), response)], "title")  # fmt: skip
    a, b, c = fig.axes[:3]
    assert a.get_xlim() == pytest.approx(b.get_xlim())
    assert b.get_xlim() == pytest.approx((-1.7 * display.MARGIN, 1.7 * display.MARGIN))
    assert c.get_xlim()[1] == pytest.approx(8.9 * display.MARGIN)
    assert all(ax.get_legend() is None for ax in fig.axes)  # no legend over the points
    assert "50 section points" in a.get_title()


def test_spectrum_panels_share_the_frequency_axis_and_show_every_method():
    slow = steady_spectrum(whirls(40, 50, [(1.0, 1.0)]))
    wide = steady_spectrum(whirls(40, 50, [(1.0, 1.0), (-5.2, 0.5)], method="other"))
    fig = spectrum_figure([("mu = 0", [("exact", slow), ("other", wide)], ""),
                           ("mu = 0.05", [("exact", wide)], "")], "title")  # fmt: skip
    first, second = fig.axes[:2]
    assert first.get_xlim() == pytest.approx(second.get_xlim())
    assert first.get_ylim() == pytest.approx(second.get_ylim())
    assert first.get_xlim()[0] < -5.2  # wide enough for the widest spectrum
    labels = [line.get_label() for line in first.get_lines()]
    assert "exact" in labels and "other" in labels
    # one spectrum per panel (rubcli run): the panels share their axes too
    fig = spectrum_figure([("exact", slow, ""), ("other", wide, "")], "title")
    assert fig.axes[0].get_xlim() == pytest.approx(fig.axes[1].get_xlim())


# ------------------------------------------------------------------ sweeps


def sweep_dataset(p, up_z, down_z, spectrum=None, orders=None) -> xr.Dataset:
    """A 1-D sweep in eta: stroboscopic z (sections) per direction; x = z."""
    z = np.stack([up_z, down_z])  # (direction, eta, section)
    data = {
        "section_z": (("direction", "eta", "section"), z),
        "section_x": (("direction", "eta", "section"), z.copy()),
        "status": (("direction", "eta"), np.zeros(z.shape[:2], dtype=np.int8)),
    }
    coords = {"direction": ["up", "down"], "eta": p, "section": np.arange(z.shape[2])}
    if spectrum is not None:
        data["spectrum"] = (("direction", "eta", "order"), spectrum)
        coords["order"] = orders
    return xr.Dataset(data, coords=coords)


def test_both_sweep_directions_are_visible_where_they_coincide():
    p = np.linspace(0.5, 4.0, 71)  # as cases/examples/run-up.toml
    z = (0.2 + 0.5 * np.sin(p))[:, None]
    fig = bifurcation_figure(sweep_dataset(p, z, z.copy()), "title")
    image = pixels(fig)
    counts = {"up": 0, "down": 0}
    for ax in fig.axes:  # the data areas only (the legend shows both colours anyway)
        hsv = rgb_to_hsv(inside(fig, ax, image))
        strong = hsv[..., 1] > 0.25
        for direction in counts:
            hue = rgb_to_hsv(np.array(to_rgba(DIRECTION_COLOURS[direction])[:3]))[0]
            counts[direction] += int((strong & (np.abs(hsv[..., 0] - hue) < 0.05)).sum())
    assert counts["up"] > 0.5 * counts["down"] > 0  # neither direction hidden


def test_a_gap_between_two_groups_of_z_breaks_the_axis():
    assert len(ax_tools.split_ranges([0.2, 0.5, 1.8])) == 1  # a few values: no bands
    bands = np.concatenate((np.linspace(0.2, 1.8, 40), np.linspace(8.4, 9.3, 40)))
    assert ax_tools.split_ranges(bands) == [(0.2, 1.8), (8.4, 9.3)]
    assert len(ax_tools.split_ranges(np.linspace(0.2, 9.3, 80))) == 1
    p = np.linspace(0.0, 0.06, 30)
    rng = np.random.default_rng(1)
    low = rng.uniform(0.2, 1.8, (30, 50))
    whip = rng.uniform(8.4, 9.3, (30, 50))
    fig = bifurcation_figure(sweep_dataset(p, low, whip), "title")
    fig.canvas.draw()
    limits = [ax.get_ylim() for ax in fig.axes]
    whip_axes = [ax for ax in fig.axes if ax.get_ylim()[0] > 8.0]
    rub_axes = [ax for ax, (lo, hi) in zip(fig.axes, limits, strict=True) if hi < 2.5]
    assert len(whip_axes) == 2 and len(rub_axes) == 2  # one part of each, in each column
    whole = whip_axes[0].get_position().y1 - rub_axes[0].get_position().y0
    assert rub_axes[0].get_position().height > 0.5 * whole  # the rub band is no strip


def test_markers_are_never_below_two_pixels():
    smallest = (2.0 * 72.0 / ax_tools.DPI) ** 2
    assert ax_tools.point_size(10**6, 2e5) == pytest.approx(smallest)
    assert ax_tools.point_size(10, 2e5) > smallest


def test_cascade_keeps_a_line_one_bin_wide_and_a_light_floor():
    orders = np.arange(-600, 601) / 100.0  # 1201 bins: each far narrower than a pixel
    p = np.linspace(0.0, 0.06, 121)
    spec = np.full((2, p.size, orders.size), 1e-9)  # the floor, 180 dB down
    spec[:, :, 700] = 1.0  # 1X
    weak = 837  # one bin at order 2.37, 40 dB below 1X
    spec[:, :, weak] = 1e-2
    z = np.ones((p.size, 1))
    fig = cascade_figure(sweep_dataset(p, z, z, spec, orders), "title")
    image = pixels(fig)
    ax = fig.axes[0]
    h = image.shape[0]
    x_px = int(round(ax.transData.transform((orders[weak], 0.0))[0]))
    box = ax.get_window_extent()
    column = image[int(h - box.y1) + 3 : int(h - box.y0) - 3, x_px - 2 : x_px + 3]
    coloured = np.ptp(column, axis=-1) > 0.15  # not white, not grey: a drawn line
    assert coloured.any(axis=1).mean() > 0.9  # the line is seen over the whole sweep
    panel = inside(fig, ax, image)
    dark = panel.mean(axis=-1) < 0.3
    assert dark.mean() < 0.1  # the floor is not drawn: the panel is light


# ------------------------------------------------------------------ orbits


def branch_point(value: float, z: float, multipliers, label: str = ""):
    m = np.asarray(multipliers, dtype=complex)
    return SimpleNamespace(parameter=value, max_z=z, label=label, multipliers=m,
                           stable=bool(np.max(np.abs(m)) < 1.0))  # fmt: skip


def fake_branch(points, bifurcations, parameter="mu"):
    return SimpleNamespace(parameter=parameter, points=points, bifurcations=bifurcations,
                           rows=lambda: points)  # fmt: skip


def test_a_flat_branch_is_drawn_flat_with_its_variation_below():
    mu = np.linspace(0.0, 0.06, 13)
    z = 1.23389 - 0.1 * mu**2
    points = [branch_point(m, v, [0.9, 0.8]) for m, v in zip(mu, z, strict=True)]
    fig = branch_figure(fake_branch(points, []), "title")
    main, detail = fig.axes[:2]
    lo, hi = main.get_ylim()
    assert hi - lo >= 0.1 * 1.2339 and lo <= 1.0  # flat, with the clearance in view
    assert "1.2339" in detail.get_ylabel() and "1e-4" in detail.get_ylabel()
    drawn = np.concatenate([line.get_ydata() for line in detail.get_lines()])
    assert np.ptp(drawn) > 1.0  # the variation fills the detail axis


def test_folds_and_grazings_have_their_own_markers_and_labels_do_not_overlap():
    m = [0.7 + 0.2j, 0.7 - 0.2j]
    pts = [branch_point(e, 0.5 + 0.5 * e, m) for e in np.linspace(0.6, 1.6, 11)]
    bifs = [
        SimpleNamespace(kind="fold", parameter=1.0378, located=True, note="",
                        point=branch_point(1.0378, 1.0, m, "fold")),
        SimpleNamespace(kind="grazing", parameter=1.0378, located=True, note="",
                        point=branch_point(1.0378, 1.0, m, "grazing")),
        SimpleNamespace(kind="fold", parameter=1.2463, located=True, note="",
                        point=branch_point(1.2463, 1.37, m, "fold")),
    ]  # fmt: skip
    branch = fake_branch(pts, bifs, parameter="eta")
    fig = multipliers_figure(branch, "title")
    lines = {line.get_label(): line for line in fig.axes[0].get_lines()}
    fold = next(v for k, v in lines.items() if "fold" in k)
    grazing = next(v for k, v in lines.items() if "grazing" in k)
    assert fold.get_marker() != grazing.get_marker()
    assert to_rgba(fold.get_markeredgecolor()) != to_rgba(grazing.get_markeredgecolor())
    assert fold.get_markersize() < grazing.get_markersize()  # the smaller on top shows
    assert fold.get_zorder() > grazing.get_zorder()
    fig = branch_figure(branch, "title")
    fig.canvas.draw()
    numbers = [t for t in fig.axes[0].texts if t.get_text().isdigit()]
    assert [t.get_text() for t in numbers] == ["1", "2", "3"]  # in order of the parameter
    boxes = [Text.get_window_extent(t) for t in numbers]  # the text, not its leader
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b)


# ------------------------------------------------------------------ forces-map


def test_flutter_threshold_inverts_the_flutter_radius():
    for mu in (0.02, 0.1, 0.5, 2.0):
        assert friction_flutter_threshold(friction_flutter_radius(mu)) == pytest.approx(mu)
    assert np.isnan(friction_flutter_threshold(0.9))


def test_eigen_map_left_panel_shows_structure_where_max_re_is_constant():
    params = model.ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6e3, mu=0.1, Rp=46.16)
    em = eigen_map(params, params.mu, extent=1.5, resolution=41)
    finite = em.max_real[np.isfinite(em.max_real)]
    assert np.ptp(finite) == 0.0 and finite[0] == -params.nu  # exact: no structure there
    fig = eigen_map_figure(em, "title", flutter_radius=friction_flutter_radius(params.mu))
    left = fig.axes[0]
    shown = left.get_images()[0].get_array()
    assert np.ptp(shown.compressed()) > 0.1 * np.max(shown)
    assert "-nu" in left.get_title() and "0.009478" in left.get_title()

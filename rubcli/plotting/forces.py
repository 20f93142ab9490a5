"""Figures of ``rubcli forces-map``: Figure 2 of the paper, the Taylor error, the eigenvalue map.

Built on matplotlib's Agg canvas (``Figure`` + ``FigureCanvasAgg``, no pyplot), from the
results of ``rubcli.analysis.charts.forces_map``; nothing is computed here beyond what is drawn.
Save the figures with ``rubcli.io.save_figure``.

Units: positions in clearances; forces nondimensional, in units of ``k_r * clearance``;
eigenvalues in units of the rotor natural frequency ``omega`` (per unit tau).
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LogNorm, TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from rubcli.analysis.charts.forces_map import (
    EigenMap,
    ForceMap,
    TaylorError,
    friction_flutter_threshold,
)

SIGN_CONVENTION = (
    "F = force of the stator on the rotor = -K f (z > 1), 0 inside the clearance; "
    "units of k_r*clearance. Positive F_x points to +x. "
    "mu_c > 0: friction opposes forward slip (v_r > 0)."
)
FORCE_CMAP = "RdBu_r"
CLEARANCE_STYLE = {"fill": False, "edgecolor": "k", "linestyle": "--", "linewidth": 0.9}
FLUTTER_STYLE = {"edgecolor": "m", "linestyle": ":", "linewidth": 1.4}
LINE_STYLES = ("-o", "-s", "-^", "-D", "-v", "-P")


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _clearance_circle(ax, radius: float = 1.0) -> None:
    ax.add_patch(Circle((0.0, 0.0), radius, **CLEARANCE_STYLE))


def _map_axes(ax, x: np.ndarray, y: np.ndarray) -> None:
    ax.set_xlim(x[0], x[-1])
    ax.set_ylim(y[0], y[-1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (clearances)")
    ax.set_ylabel("y (clearances)")


def _extent(x: np.ndarray, y: np.ndarray) -> list[float]:
    """imshow extent so that pixel centres sit on the grid points."""
    dx = (x[-1] - x[0]) / max(x.size - 1, 1)
    dy = (y[-1] - y[0]) / max(y.size - 1, 1)
    return [x[0] - dx / 2, x[-1] + dx / 2, y[0] - dy / 2, y[-1] + dy / 2]


def _symmetric_limit(*fields: np.ndarray) -> float:
    """max |value| over the fields, or 1 if they are all zero (a colour bar needs a range)."""
    vmax = max(float(np.nanmax(np.abs(f))) if np.any(np.isfinite(f)) else 0.0 for f in fields)
    return vmax if vmax > 0.0 else 1.0


def forces_map_figure(fm: ForceMap, title: str) -> Figure:
    """Figure 2 of the paper: rows F_x, F_y; columns exact, Taylor at own point, difference."""
    fig = _new_figure(15.0, 9.0)
    axes = fig.subplots(2, 3)
    extent = _extent(fm.x, fm.y)
    rows = (
        ("F_x", fm.Fx_exact, fm.Fx_taylor, fm.Fx_diff),
        ("F_y", fm.Fy_exact, fm.Fy_taylor, fm.Fy_diff),
    )
    for r, (name, exact, taylor, diff) in enumerate(rows):
        vmax = _symmetric_limit(exact, taylor)
        dmax = _symmetric_limit(diff)
        panels = (
            (exact, f"{name}, exact", vmax),
            (taylor, f"{name}, Taylor expansion at its own point", vmax),
            (diff, f"{name}: exact - Taylor (max |.| = {np.max(np.abs(diff)):.2g})", dmax),
        )
        for c, (field, label, limit) in enumerate(panels):
            ax = axes[r, c]
            image = ax.imshow(
                field,
                origin="lower",
                extent=extent,
                cmap=FORCE_CMAP,
                vmin=-limit,
                vmax=limit,
                interpolation="nearest",
            )
            _clearance_circle(ax)
            _map_axes(ax, fm.x, fm.y)
            ax.set_title(label, fontsize=10)
            bar = fig.colorbar(image, ax=ax, shrink=0.85)
            bar.set_label(f"{name} / (k_r clearance)" if c < 2 else f"difference in {name}")
    fig.suptitle(
        f"{title}\ncontact force, K = {fm.K:g}, mu_c = {fm.mu_c:+g}; "
        f"dashed circle: clearance z = 1",
        fontsize=11,
    )
    fig.supxlabel(
        SIGN_CONVENTION
        + "\nThe expansion evaluated at its own point is exact by construction: the "
        f"difference is round-off (largest |F| = {fm.max_abs_force:.4g}).",
        fontsize=8.5,
    )
    return fig


def taylor_error_figure(te: TaylorError, title: str) -> Figure:
    """Log-log error of the expansion against the distance delta, one line per K.

    One panel per direction; a dashed line of slope 2 for reference and the fitted slope of
    each K in the legend.
    """
    n = len(te.directions)
    fig = _new_figure(4.8 * n, 5.0)
    axes = fig.subplots(1, n, sharey=True, squeeze=False)[0]
    positive = te.max_abs_error[np.isfinite(te.max_abs_error) & (te.max_abs_error > 0)]
    for d, direction in enumerate(te.directions):
        ax = axes[d]
        for k, K in enumerate(te.K_values):
            errors = te.max_abs_error[k, d]
            shown = np.isfinite(errors) & (errors > 0.0)
            slope = te.slope(K, direction)
            slope_text = "round-off" if slope is None else f"slope {slope:.3f}"
            ax.loglog(
                te.deltas[shown],
                errors[shown],
                LINE_STYLES[k % len(LINE_STYLES)],
                markersize=4,
                linewidth=1.2,
                label=f"K = {K:g} ({slope_text})",
            )
        if positive.size:
            # reference delta^2 line, ten times above the largest error at the middle delta
            j = te.deltas.size // 2
            anchor = 10.0 * np.nanmax(te.max_abs_error[:, :, j])
            reference = anchor * (te.deltas / te.deltas[j]) ** 2
            ax.loglog(te.deltas, reference, "k--", linewidth=1.0, label="slope 2 (reference)")
        if direction == "radial":
            ax.text(
                0.04,
                0.96,
                "force is linear along rays in contact:\nthe expansion is exact up to round-off",
                transform=ax.transAxes,
                va="top",
                fontsize=8.5,
            )
        ax.set_title(f"{direction} displacement", fontsize=10)
        ax.set_xlabel("delta, distance from the expansion point (clearances)")
        ax.grid(True, which="major", linewidth=0.4, alpha=0.6)
        ax.legend(fontsize=8, loc="center right" if direction == "radial" else "lower right")
    axes[0].set_ylabel("max |F_exact - F_taylor| (units of k_r clearance)")
    z0 = te.band_radii
    fig.suptitle(
        f"{title}\nerror of the first-order expansion at a distance delta from its point, "
        f"mu_c = {te.mu_c:+g}; max over expansion points with z0 in "
        f"[{z0.min():.7g}, {z0.max():g}] (worst: also over all directions), "
        "displaced point in contact",
        fontsize=10,
    )
    return fig


def _growth_panel(fig, ax, em: EigenMap, extent, X, Y) -> None:
    """The left panel: the largest real part of the eigenvalues where it varies over the
    map (diverging colours centred on 0, Re > 0 hatched). Where it does not (every mode
    decays at exactly -nu, as it does at every point short of the radius where friction
    merges the two contact modes), a map of one colour would say nothing: the panel then
    states that value and colours each point by the friction coefficient at which its
    modes would merge (``analysis.charts.forces_map.friction_flutter_threshold``, log scale), with
    the case's own mu_c marked where the map reaches it: the margin to instability."""
    finite = em.max_real[np.isfinite(em.max_real)]
    spread = float(np.ptp(finite)) if finite.size else 0.0
    if finite.size and spread > 1e-9 * max(abs(em.nu), 1e-12):
        low = min(float(finite.min()), -em.nu, -1e-12)
        high = max(float(finite.max()), max(em.nu, 1e-12))
        norm = TwoSlopeNorm(vmin=1.05 * low, vcenter=0.0, vmax=1.05 * high)
        image = ax.imshow(em.max_real, origin="lower", extent=extent, cmap="RdBu_r", norm=norm)
        bar = fig.colorbar(image, ax=ax, shrink=0.85)
        bar.set_label("max Re(lambda) (units of omega); diverging colours centred on 0")
        if finite.max() > 0.0:
            positive = np.where(np.isfinite(em.max_real), em.max_real, -np.inf) > 0.0
            ax.contourf(X, Y, positive.astype(float), levels=[0.5, 1.5], colors="none",
                        hatches=["//"])  # fmt: skip
            ax.contour(X, Y, positive.astype(float), levels=[0.5], colors="k", linewidths=1.0)
            note = f"hatched: Re > 0 on {100 * em.positive_fraction:.1f}% of contact points"
        else:
            note = f"no growing mode: max Re = {em.max_real_overall:.6g}"
        ax.set_title("largest real part of the eigenvalues\n" + note, fontsize=10)
        return
    threshold = np.where(np.isfinite(em.max_real), friction_flutter_threshold(np.hypot(X, Y)),
                         np.nan)  # fmt: skip
    shown = threshold[np.isfinite(threshold)]
    if not shown.size:
        ax.set_title("largest real part of the eigenvalues\nno contact point on the map",
                     fontsize=10)  # fmt: skip
        return
    norm = LogNorm(vmin=float(shown.min()), vmax=float(shown.max()))
    image = ax.imshow(threshold, origin="lower", extent=extent, cmap="viridis", norm=norm)
    bar = fig.colorbar(image, ax=ax, shrink=0.85)
    bar.set_label("mu at which the two contact modes merge (log scale)")
    mu = abs(em.mu_c)
    if shown.min() <= mu <= shown.max():
        ax.contour(X, Y, threshold, levels=[mu], colors="m", linewidths=1.2)
        where = f"magenta: mu_c = {mu:g}"
    else:
        where = f"mu_c = {mu:g} below all"
    value = f"{finite[0]:.4g}" if finite.size else "-"
    ax.set_title(
        f"all modes decay at Re(lambda) = -nu = {value}\ncolour: mu where modes merge; {where}",
        fontsize=9,
    )


def eigen_map_figure(em: EigenMap, title: str, flutter_radius: float | None = None) -> Figure:
    """Largest real part (positive region hatched) and the two frequencies, on the grid.

    Where the largest real part is the same at every point the left panel shows the margin
    to mode merging instead (``_growth_panel``).

    ``flutter_radius``: the radius beyond which friction merges the two contact modes
    (undamped), drawn as a dotted circle when it lies within the map.
    """
    fig = _new_figure(15.0, 5.2)
    axes = fig.subplots(1, 3)
    extent = _extent(em.x, em.y)
    X, Y = np.meshgrid(em.x, em.y)

    _growth_panel(fig, axes[0], em, extent, X, Y)
    for ax, field, name in (
        (axes[1], em.freq_1, "freq_1"),
        (axes[2], em.freq_2, "freq_2"),
    ):
        image = ax.imshow(field, origin="lower", extent=extent, cmap="viridis")
        bar = fig.colorbar(image, ax=ax, shrink=0.85)
        bar.set_label(f"{name} = |Im lambda| (units of omega)")
        order = "lower" if name == "freq_1" else "higher"
        ax.set_title(f"{name}: the {order} of the two mode frequencies", fontsize=10)
    show_flutter = (
        flutter_radius is not None
        and math.isfinite(flutter_radius)
        and flutter_radius < math.hypot(em.x[-1], em.y[-1])
    )
    for ax in axes:
        _clearance_circle(ax)
        if show_flutter:
            ax.add_patch(Circle((0, 0), flutter_radius, fill=False, **FLUTTER_STYLE))
        _map_axes(ax, em.x, em.y)
    flutter = (
        f"; dotted circle: the two modes merge beyond z0 = {flutter_radius:.4g} (undamped)"
        if show_flutter
        else ""
    )
    fig.suptitle(
        f"{title}\neigenvalues of the linearised contact system (4x4), K = {em.K:g}, "
        f"nu = {em.nu:g}, mu_c = {em.mu_c:+g} (forward spin); blank: no contact (z <= 1)" + flutter,
        fontsize=10,
    )
    return fig

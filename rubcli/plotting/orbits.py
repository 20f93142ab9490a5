"""Figures of a continued branch: max z against the parameter, and the Floquet multipliers.

``branch_figure``: max z of each periodic orbit against the continued parameter, stable
parts solid, unstable parts dashed, every bifurcation marked and labelled, the clearance
z = 1 drawn; optionally over a sweep's bifurcation diagram (stroboscopic samples).
``multipliers_figure``: the multipliers of every point in the complex plane, coloured by
the parameter, with the unit circle and the multipliers of each bifurcation point.
These functions only draw; they never solve.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from rubcli.analysis.orbits.continuation import Branch

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from rubcli.analysis.charts.stability import Chart

MARKERS = {
    "fold": "s",
    "period_doubling": "D",
    "neimark_sacker": "*",
    "grazing": "v",
    "stick_onset": "^",
}
KIND_COLORS = {  # the same in branch.png and multipliers.png
    "fold": "C1",
    "period_doubling": "C2",
    "neimark_sacker": "C3",
    "grazing": "C4",
    "stick_onset": "C5",
}
# where points coincide (a nonsmooth fold at a grazing), the larger is drawn first and the
# smaller on top, so both show
KIND_SIZES = {"grazing": 15, "neimark_sacker": 15, "stick_onset": 12, "period_doubling": 10,
              "fold": 8}  # fmt: skip
FLAT = 0.02  # branch.png: a branch whose max z varies by less than this share is flat


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _segment_styles(rows) -> list[bool]:
    """Stable (True) or not for each segment between consecutive rows.

    A located bifurcation point belongs to both sides: a segment takes the stability of its
    other end, so the line changes style exactly at the bifurcation.
    """
    out = []
    for a, b in zip(rows[:-1], rows[1:], strict=True):
        if a.label and not b.label:
            out.append(b.stable)
        elif b.label and not a.label:
            out.append(a.stable)
        else:
            out.append(a.stable and b.stable)
    return out


def numbered(branch: Branch) -> list[tuple[int, object]]:
    """The bifurcations numbered 1, 2, ... in increasing order of the parameter (the order
    of the console's table), the same numbers in both figures."""
    ordered = sorted(branch.bifurcations, key=lambda b: b.parameter)
    return list(enumerate(ordered, start=1))


def kind_style(kind: str) -> tuple[str, str, float]:
    """(marker, colour, size) of a bifurcation kind."""
    return MARKERS.get(kind, "o"), KIND_COLORS.get(kind, "C7"), KIND_SIZES.get(kind, 10)


def _bifurcation_label(k: int, bif, name: str, digits: int = 8) -> str:
    text = f"{k}: {bif.kind.replace('_', ' ')} at {name} = {bif.parameter:.{digits}g}"
    return text if bif.located else text + " (not located)"


def _flat_reference(z: np.ndarray) -> float | None:
    """The reference level of a flat branch (its first point, to 5 digits), else None."""
    if z.size < 2:
        return None
    level = float(np.max(np.abs(z)))
    if level == 0.0 or np.ptp(z) >= FLAT * level:
        return None
    return float(f"{z[0]:.5g}")


def branch_figure(
    branch: Branch,
    title: str,
    overlay: tuple[np.ndarray, np.ndarray, str] | None = None,
) -> Figure:
    """max z against the parameter; ``overlay`` = (parameter values, z values, label).

    Bifurcations are numbered in increasing order of the parameter, drawn with one marker
    and colour per kind (``kind_style``) and labelled without overlapping. A flat branch
    (max z varying by less than ``FLAT`` of its level) is drawn on a value axis of at
    least 10 % of its level, where it reads as flat, and again below as its difference
    from a stated reference level, where its variation shows.
    """
    rows = branch.rows()
    p = np.array([pt.parameter for pt in rows])
    z = np.array([pt.max_z for pt in rows])
    ref = _flat_reference(z)
    fig = _new_figure(8.4, 6.6 if ref is not None else 5.0)
    if ref is not None:
        ax, detail = fig.subplots(2, 1, sharex=True, height_ratios=(2.0, 1.0))
    else:
        ax, detail = fig.add_subplot(), None
    name = branch.parameter
    handles = []
    if overlay is not None:
        px, pz, label = overlay
        ax.plot(px, pz, ",", color="0.45", alpha=0.8, zorder=1, rasterized=True)
        handles.append(Line2D([], [], marker=".", linestyle="", color="0.45", label=label))
    _branch_lines(ax, rows, p, z)
    handles.append(Line2D([], [], color="C0", lw=1.6, label="stable orbit (max z)"))
    handles.append(Line2D([], [], color="C0", lw=1.6, ls="--", label="unstable orbit (max z)"))
    handles.append(Line2D([], [], color="C0", marker=".", ls="", label="computed orbit"))
    if z.size and np.min(z) - 1.0 < 0.1 * max(np.ptp(z), 1e-3) or ref is not None:
        ax.axhline(1.0, color="0.2", lw=0.8, ls=":", zorder=2)
        handles.append(Line2D([], [], color="0.2", lw=0.8, ls=":", label="clearance z = 1"))
    if ref is not None:  # before the labels are placed: they follow the final limits
        ax.set_ylim(*_flat_limits(z))
    marks = numbered(branch)
    points = [(bif.parameter, bif.point.max_z) for _, bif in marks]
    for (k, bif), offset in zip(marks, label_offsets(ax, points), strict=True):
        marker, color, size = kind_style(bif.kind)
        ax.plot(bif.parameter, bif.point.max_z, marker, color=color, ms=size, mec="k",
                zorder=6 + 1.0 / size)  # fmt: skip
        ax.annotate(str(k), (bif.parameter, bif.point.max_z), xytext=offset,
                    textcoords="offset points", fontsize=9, weight="bold", zorder=8,
                    arrowprops={"arrowstyle": "-", "color": "0.4", "lw": 0.6}
                    if abs(offset[1]) > 12 else None)  # fmt: skip
        handles.append(Line2D([], [], marker=marker, linestyle="", color=color, mec="k",
                              ms=size * 0.8, label=_bifurcation_label(k, bif, name)))  # fmt: skip
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.set_ylabel("max z over the orbit (clearances)")
    if ref is not None:
        _flat_axes(detail, rows, p, z, ref, marks)
        detail.set_xlabel(f"{name} (nondimensional)")
    else:
        ax.set_xlabel(f"{name} (nondimensional)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    fig.legend(handles=handles, loc="outside right upper", fontsize=8)
    return fig


def _branch_lines(ax, rows, p, z) -> None:
    """The branch: one line per run of equal stability (solid stable, dashed unstable)."""
    styles = _segment_styles(rows)
    i = 0
    while i < len(styles):
        j = i
        while j + 1 < len(styles) and styles[j + 1] == styles[i]:
            j += 1
        ax.plot(p[i : j + 2], z[i : j + 2], "-" if styles[i] else "--", color="C0", lw=1.6,
                zorder=3)  # fmt: skip
        i = j + 1
    plain = [k for k, pt in enumerate(rows) if not pt.label]
    ax.plot(p[plain], z[plain], ".", color="C0", ms=3, zorder=4)


def _flat_axes(detail, rows, p, z, ref: float, marks) -> None:
    """A flat branch: ``detail`` shows max z - ``ref`` in a stated power of ten."""
    dz = z - ref
    span = float(np.max(np.abs(dz))) or 1.0
    power = int(np.floor(np.log10(span)))
    scale = 10.0**power
    _branch_lines(detail, rows, p, dz / scale)
    for _, bif in marks:
        marker, color, size = kind_style(bif.kind)
        detail.plot(bif.parameter, (bif.point.max_z - ref) / scale, marker, color=color,
                    ms=size * 0.8, mec="k", zorder=6 + 1.0 / size)  # fmt: skip
    detail.axhline(0.0, color="0.5", lw=0.6)
    detail.set_ylabel(f"(max z - {ref:g}) / 1e{power}\n(clearances)")
    detail.set_title(f"the same branch, as its difference from max z = {ref:g} "
                     f"(in units of 1e{power} clearances)", fontsize=9)  # fmt: skip
    detail.grid(True, alpha=0.3)


def _flat_limits(z: np.ndarray) -> tuple[float, float]:
    """Value axis of a flat branch: at least 10 % of its level wide, the clearance in view."""
    level = float(np.max(np.abs(z)))
    lo, hi = min(float(z.min()), 1.0), max(float(z.max()), 1.0)
    half = max(0.5 * (hi - lo) * 1.15, 0.05 * level)
    mid = 0.5 * (lo + hi)
    return mid - half, mid + half


def label_offsets(
    ax: Axes,
    points: Sequence[tuple[float, float]],
    base: tuple[float, float] = (7.0, 6.0),
    step: float = 11.0,
    near: float = 16.0,
) -> list[tuple[float, float]]:
    """Offsets (points) of number labels at ``points`` (data coordinates) so that labels
    of points closer than ``near`` points on the page are stacked ``step`` apart instead
    of drawn over each other."""
    if not points:
        return []
    fig = ax.figure
    ax.get_xlim(), ax.get_ylim()  # (the limits autoscaled to what is drawn so far)
    xy = ax.transData.transform(np.asarray(points, dtype=float)) * 72.0 / fig.dpi
    placed: list[tuple[float, float]] = []
    offsets = []
    for x, y in xy:
        dx, dy = base
        while any(abs(x + dx - px) < near and abs(y + dy - py) < step for px, py in placed):
            dy += step
        placed.append((x + dx, y + dy))
        offsets.append((dx, dy))
    return offsets


def multipliers_figure(branch: Branch, title: str) -> Figure:
    """Floquet multipliers of every branch point in the complex plane, with the unit circle.

    The multipliers at each bifurcation are drawn with its kind's marker and colour
    (``kind_style``, as in branch.png) and its number; where two coincide (a fold at a
    grazing) the larger ring is drawn under the smaller one, so both show.
    """
    fig = _new_figure(8.4, 7.8)
    ax = fig.add_subplot()
    theta = np.linspace(0.0, 2.0 * np.pi, 400)
    ax.plot(np.cos(theta), np.sin(theta), color="0.2", lw=1.0, label="unit circle")
    p = np.repeat(
        [pt.parameter for pt in branch.points], [pt.multipliers.size for pt in branch.points]
    )
    lam = (
        np.concatenate([pt.multipliers for pt in branch.points]) if branch.points else np.array([])
    )
    sc = ax.scatter(lam.real, lam.imag, c=p, s=10, cmap="viridis", zorder=3,
                    label="multipliers of each orbit")  # fmt: skip
    if branch.points:
        fig.colorbar(sc, ax=ax, label=f"{branch.parameter} (nondimensional)")
    for k, bif in numbered(branch):
        m = bif.point.multipliers
        marker, color, size = kind_style(bif.kind)
        ax.plot(m.real, m.imag, marker, mfc="none", mec=color, ms=size, mew=1.8,
                zorder=5 + 1.0 / size,
                label=_bifurcation_label(k, bif, branch.parameter, digits=6))  # fmt: skip
    ax.set_aspect("equal", adjustable="datalim")
    ax.axhline(0.0, color="0.7", lw=0.5)
    ax.axvline(0.0, color="0.7", lw=0.5)
    ax.set_xlabel("Re(multiplier)")
    ax.set_ylabel("Im(multiplier)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    fig.legend(loc="outside lower center", fontsize=8, ncols=2, markerscale=0.7)
    return fig


def overlay_points(parameter: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flatten a sweep's (parameter, section samples...) array into scatter points."""
    values = np.asarray(values, dtype=float)
    parameter = np.asarray(parameter, dtype=float)
    px = np.broadcast_to(parameter.reshape((-1,) + (1,) * (values.ndim - 1)), values.shape)
    keep = np.isfinite(values)
    return px[keep], values[keep]


__all__: Sequence[str] = ("branch_figure", "multipliers_figure", "overlay_points")


def curves_figure(
    curves: Sequence,
    names: tuple[str, str],
    windows: tuple[tuple[float, float], tuple[float, float]],
    branch_at: float,
    title: str,
    closed_form: Chart | None = None,
) -> Figure:
    """Bifurcations continued in two parameters (``analysis.orbits.curves.Curve``): each curve in
    its kind's colour as a wide translucent line through its computed points, its start
    (the point located on the branch) in its kind's marker; the branch itself as a dashed
    line at ``p2 = branch_at``; ``closed_form`` (an ``analysis.charts.stability.Chart`` of the same
    plane), its curves as thin dark lines on top, so that a continued curve lying on its
    closed form shows as a dark line inside a coloured band."""
    from rubcli.plotting.chart import CURVE_LABELS, CURVE_STYLES, SYMBOLS

    fig = _new_figure(8.6, 6.4)
    ax = fig.add_subplot()
    handles = []
    ax.axhline(branch_at, color="0.45", lw=1.0, ls="--", zorder=1)
    handles.append(Line2D([], [], color="0.45", lw=1.0, ls="--",
                          label=f"the branch ({names[1]} = {branch_at:g})"))  # fmt: skip
    seen = set()
    for curve in curves:
        marker, color, size = kind_style(curve.kind)
        if not curve.points:  # not continued (on another curve): its point on the branch
            ax.plot(curve.start.parameter, branch_at, marker=marker, color=color, ms=size,
                    mec="k", ls="", zorder=5)  # fmt: skip
            continue
        p1 = [pt.values[0] for pt in curve.points]
        p2 = [pt.values[1] for pt in curve.points]
        ax.plot(p1, p2, color=color, lw=6.0, alpha=0.35, solid_capstyle="round", zorder=2)
        ax.plot(p1, p2, "o", color=color, ms=3.0, zorder=3)
        start = curve.points[curve.start_index]
        ax.plot(*start.values, marker=marker, color=color, ms=size, mec="k", ls="", zorder=5)
        if curve.kind not in seen:
            seen.add(curve.kind)
            name = curve.kind.replace("_", " ")
            handles.append(Line2D([], [], color=color, lw=6.0, alpha=0.35, marker="o", ms=3.0,
                                  mfc=color, label=f"{name}, continued"))  # fmt: skip
            handles.append(Line2D([], [], color=color, marker=marker, ms=size * 0.7, mec="k",
                                  ls="", label=f"{name} located on the branch"))  # fmt: skip
    if closed_form is not None:
        for kind, field in closed_form.fields.items():
            if not np.any(np.isfinite(field)) or not curve_kind_present(curves, kind):
                continue
            style = CURVE_STYLES[kind][1]  # black, in the chart's dash for the kind
            ax.contour(closed_form.x, closed_form.y, field, levels=[0.0], colors=["k"],
                       linewidths=1.0, linestyles=[style], zorder=4)  # fmt: skip
            handles.append(Line2D([], [], color="k", lw=1.0, ls=style,
                                  label=f"closed form: {CURVE_LABELS[kind]}"))  # fmt: skip
    ax.set_xlim(*windows[0])
    ax.set_ylim(*windows[1])
    ax.set_xlabel(f"{SYMBOLS.get(names[0], names[0])}, nondimensional")
    ax.set_ylabel(f"{SYMBOLS.get(names[1], names[1])}, nondimensional")
    ax.grid(True, alpha=0.3)
    ax.set_title(title, fontsize=9)
    if not any(curve.points for curve in curves):
        ax.text(0.5, 0.5, "no bifurcation of the branch could be continued",
                transform=ax.transAxes, ha="center", va="center")  # fmt: skip
    fig.legend(handles=handles, loc="outside lower center", ncols=2, fontsize=8, frameon=False)
    return fig


def curve_kind_present(curves: Sequence, closed_kind: str) -> bool:
    """Whether a continued curve of the kind that ``closed_kind`` checks is drawn."""
    from rubcli.analysis.orbits.curves import CLOSED_FORMS

    return any(CLOSED_FORMS.get(c.kind) == closed_kind and c.points for c in curves)

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

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from rubcli.analysis.continuation import Branch

MARKERS = {
    "fold": "s",
    "period_doubling": "D",
    "neimark_sacker": "*",
    "grazing": "v",
    "stick_onset": "^",
}


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


def branch_figure(
    branch: Branch,
    title: str,
    overlay: tuple[np.ndarray, np.ndarray, str] | None = None,
) -> Figure:
    """max z against the parameter; ``overlay`` = (parameter values, z values, label)."""
    fig = _new_figure(8.0, 5.0)
    ax = fig.add_subplot()
    name = branch.parameter
    handles = []
    if overlay is not None:
        px, pz, label = overlay
        ax.plot(px, pz, ",", color="0.45", alpha=0.8, zorder=1, rasterized=True)
        handles.append(Line2D([], [], marker=".", linestyle="", color="0.45", label=label))
    rows = branch.rows()
    p = np.array([pt.parameter for pt in rows])
    z = np.array([pt.max_z for pt in rows])
    styles = _segment_styles(rows)
    i = 0
    while i < len(styles):  # one line per run of equal stability
        j = i
        while j + 1 < len(styles) and styles[j + 1] == styles[i]:
            j += 1
        ax.plot(p[i : j + 2], z[i : j + 2], "-" if styles[i] else "--", color="C0", lw=1.6,
                zorder=3)  # fmt: skip
        i = j + 1
    plain = [k for k, pt in enumerate(rows) if not pt.label]
    ax.plot(p[plain], z[plain], ".", color="C0", ms=3, zorder=4)
    handles.append(Line2D([], [], color="C0", lw=1.6, label="stable orbit (max z)"))
    handles.append(Line2D([], [], color="C0", lw=1.6, ls="--", label="unstable orbit (max z)"))
    handles.append(Line2D([], [], color="C0", marker=".", ls="", label="computed orbit"))
    if z.size and np.min(z) - 1.0 < 0.1 * max(np.ptp(z), 1e-3):
        ax.axhline(1.0, color="0.2", lw=0.8, ls=":", zorder=2)
        handles.append(Line2D([], [], color="0.2", lw=0.8, ls=":", label="clearance z = 1"))
    for k, bif in enumerate(branch.bifurcations, start=1):
        marker = MARKERS.get(bif.kind, "o")
        color = f"C{1 + list(MARKERS).index(bif.kind) if bif.kind in MARKERS else 1}"
        # points that coincide (a nonsmooth fold at a grazing) are drawn smaller on top
        size = {"grazing": 12, "neimark_sacker": 14}.get(bif.kind, 8)
        ax.plot(bif.parameter, bif.point.max_z, marker, color=color, ms=size, mec="k", zorder=6)
        ax.annotate(str(k), (bif.parameter, bif.point.max_z), xytext=(7, 5 + 9 * (k % 2)),
                    textcoords="offset points", fontsize=9, weight="bold")  # fmt: skip
        text = f"{k}: {bif.kind.replace('_', ' ')} at {name} = {bif.parameter:.8g}"
        if not bif.located:
            text += " (not located)"
        handles.append(Line2D([], [], marker=marker, linestyle="", color=color, mec="k",
                              ms=size * 0.8, label=text))  # fmt: skip
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.set_xlabel(f"{name} (nondimensional)")
    ax.set_ylabel("max z over the orbit (clearances)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(handles=handles, loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)
    return fig


def multipliers_figure(branch: Branch, title: str) -> Figure:
    """Floquet multipliers of every branch point in the complex plane, with the unit circle."""
    fig = _new_figure(8.0, 7.5)
    ax = fig.add_subplot()
    theta = np.linspace(0.0, 2.0 * np.pi, 400)
    ax.plot(np.cos(theta), np.sin(theta), color="0.2", lw=1.0, label="unit circle")
    p = np.repeat(
        [pt.parameter for pt in branch.points], [pt.multipliers.size for pt in branch.points]
    )
    lam = (
        np.concatenate([pt.multipliers for pt in branch.points]) if branch.points else np.array([])
    )
    sc = ax.scatter(lam.real, lam.imag, c=p, s=10, cmap="viridis", zorder=3, label="multipliers")
    if branch.points:
        fig.colorbar(sc, ax=ax, label=f"{branch.parameter} (nondimensional)")
    for bif in branch.bifurcations:
        m = bif.point.multipliers
        label = f"{bif.kind.replace('_', ' ')} at {branch.parameter}={bif.parameter:.6g}"
        marker = MARKERS.get(bif.kind, "o")
        ax.plot(m.real, m.imag, marker, mfc="none", mec="C3", ms=11, mew=1.5, label=label)
    ax.set_aspect("equal", adjustable="datalim")
    ax.axhline(0.0, color="0.7", lw=0.5)
    ax.axvline(0.0, color="0.7", lw=0.5)
    ax.set_xlabel("Re(multiplier)")
    ax.set_ylabel("Im(multiplier)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), fontsize=8, ncols=2)
    return fig


def overlay_points(parameter: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flatten a sweep's (parameter, section samples...) array into scatter points."""
    values = np.asarray(values, dtype=float)
    parameter = np.asarray(parameter, dtype=float)
    px = np.broadcast_to(parameter.reshape((-1,) + (1,) * (values.ndim - 1)), values.shape)
    keep = np.isfinite(values)
    return px[keep], values[keep]


__all__: Sequence[str] = ("branch_figure", "multipliers_figure", "overlay_points")

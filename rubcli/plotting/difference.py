"""The difference panel: how far each method is from the first one, against time.

Two methods that agree to 1e-4 clearances draw the same orbit and the same time trace;
no line style can show one beside the other at that scale. The difference panel shows
the distance itself, ``|w_b - w_a|`` (``display.difference``), on a log scale, for every
successful method against the first successful one, so that the agreement (and where it
is lost) is seen, not only stated. Used by orbit.png and time.png.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from rubcli import units
from rubcli.plotting import display
from rubcli.solution import Solution

if TYPE_CHECKING:
    from matplotlib.axes import Axes

FLOOR = 1e-16  # a distance of exactly zero is drawn at this fraction of the orbit size
DECADES = 8  # the axis spans at most this many decades below the largest distance


def comparable(solutions: Sequence[Solution]) -> list[Solution]:
    """The successful solutions with at least two finite samples (the first is the reference)."""
    return [s for s in solutions if s.success and display.finite_length(s) >= 2]


def draw_difference(
    ax: Axes,
    solutions: Sequence[Solution],
    *,
    colors: Mapping[str, str] | None = None,
    unit: float = 1.0,
    scale: units.PhysicalScale | None = None,
    steady_from: float | None = None,
    window: tuple[float, float] | None = None,
) -> dict[str, float]:
    """Draw ``|w_b - w_a|`` against time for each method b after the first a.

    Time in tau, or seconds with ``scale``; distances in clearances times ``unit``.
    ``steady_from`` (tau) shades the span before it as the transient; ``window`` (tau)
    restricts the drawing to a span (a zoom). Returns the largest distance per method.
    """
    good = comparable(solutions)
    out: dict[str, float] = {}
    if len(good) < 2:
        return out
    first = good[0]
    size = max(float(np.max(np.abs(first.w[: display.finite_length(first)]))), 1e-300)
    colors = colors or {}
    lows, highs = [], []
    for index, sol in enumerate(good[1:], start=1):
        t, dist = display.difference(first, sol)
        if window is not None:
            keep = (t >= window[0]) & (t <= window[1])
            t, dist = t[keep], dist[keep]
        if t.size == 0:
            continue
        out[sol.method] = float(np.max(dist))
        dist = np.maximum(dist, FLOOR * size)
        later = dist[1:] if dist.size > 1 else dist  # (both start from the same state)
        lows.append(float(np.percentile(later, 1.0)))
        highs.append(float(np.max(dist)))
        tt = t if scale is None else units.seconds(t, scale)
        color = colors.get(sol.method, f"C{index}")
        band = display.envelope_band(tt, unit * dist)
        label = f"|w_b - w_a|: {sol.method} - {first.method}"
        if band is None:
            ax.semilogy(tt, unit * dist, color=color, lw=1.0, label=label)
        else:
            steps, lo, hi = band
            ax.semilogy(steps, hi, color=color, lw=1.0, drawstyle="steps-post", label=label)
            ax.fill_between(steps, lo, hi, step="post", color=color, alpha=0.25, linewidth=0)
    if steady_from is not None and window is None:
        start = float(first.t[0])
        a, b = (start, steady_from) if scale is None else (
            units.seconds(start, scale), units.seconds(steady_from, scale)
        )  # fmt: skip
        ax.axvspan(a, b, color="0.9", zorder=0, label="transient (before the steady span)")
    if highs:  # the range of the distances, not of the exact zero at the start
        top = unit * max(highs)
        ax.set_ylim(max(unit * min(lows), top * 10.0**-DECADES) / 2.0, top * 3.0)
    ax.set_ylabel(
        "|w_b - w_a| / clearance" if scale is None else "|w_b - w_a| (m)", fontsize="small"
    )
    ax.grid(True, which="major", alpha=0.3)
    return out

"""Axes helpers shared by the figures: a broken value axis, and point sizes that survive
rasterisation.

- ``split_ranges`` and ``broken_axes``: when the values of a panel fall into two groups
  with an empty gap between them (a dry whip at 9 clearances beside a partial rub below
  2), one linear axis gives the gap most of the height and squeezes the smaller group
  into a strip. Two stacked axes, each on its own group's range and marked as broken,
  give each group its height and keep both linear.
- ``point_size``: scatter markers at least about two pixels wide, so that thousands of
  points at regular positions render as a density, not as sub-pixel dots that beat
  against the pixel grid (moire stripes).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.gridspec import SubplotSpec
    from numpy.typing import ArrayLike

GAP_FRACTION = 0.5  # split a value axis when an empty gap is over this share of the span
MIN_SHARE = 0.05  # ... and each side holds at least this share of the values
MIN_HEIGHT = 0.3  # the smaller part of a broken axis gets at least this share of the height
DPI = 120  # the resolution figures are saved at (rubcli.io.save_figure)


def split_ranges(
    values: ArrayLike, gap_fraction: float = GAP_FRACTION, min_share: float = MIN_SHARE
) -> list[tuple[float, float]]:
    """``[(lo, hi)]``, or ``[(lo, a), (b, hi)]`` (ascending) when the finite values leave
    an empty gap ``(a, b)`` wider than ``gap_fraction`` of their whole span and each side
    holds at least ``min_share`` of the values (and 10 of them): two populated bands, not
    a few scattered values."""
    v = np.asarray(values, dtype=float).ravel()
    v = np.sort(v[np.isfinite(v)])
    if v.size == 0:
        return [(0.0, 1.0)]
    lo, hi = float(v[0]), float(v[-1])
    if v.size < 2 or hi <= lo:
        return [(lo, hi)]
    gaps = np.diff(v)
    k = int(np.argmax(gaps))
    fewest = min(k + 1, v.size - k - 1)
    if gaps[k] <= gap_fraction * (hi - lo) or fewest < max(10, min_share * v.size):
        return [(lo, hi)]
    return [(lo, float(v[k])), (float(v[k + 1]), hi)]


def padded(lo: float, hi: float, scale: float, pad: float = 0.06) -> tuple[float, float]:
    """``(lo, hi)`` widened by ``pad`` of its span, and to at least ``pad * scale`` when
    the span is tiny (a single value)."""
    margin = max(pad * (hi - lo), pad * 0.5 * scale, 1e-12)
    return lo - margin, hi + margin


def broken_axes(
    fig: Figure,
    spec: SubplotSpec,
    ranges: list[tuple[float, float]],
    sharex: Axes | None = None,
    sharey: Sequence[Axes] | None = None,
) -> list[Axes]:
    """Axes in ``spec`` (a SubplotSpec) for the value ranges, the highest on top.

    One range: one axes. Two: two stacked axes whose heights follow their spans (the
    smaller at least ``MIN_HEIGHT`` of the whole), with diagonal break marks where the
    axis is cut. ``sharey``: axes (from another column, same ranges) to share the value
    axis with. Returns the axes, top first.
    """
    total = sum(hi - lo for lo, hi in ranges) or 1.0
    shares = [max((hi - lo) / total, MIN_HEIGHT) for lo, hi in reversed(ranges)]
    grid = spec.subgridspec(len(ranges), 1, height_ratios=shares, hspace=0.06)
    axes = []
    for i, (lo, hi) in enumerate(reversed(ranges)):
        ax = fig.add_subplot(grid[i], sharex=sharex if sharex is not None else None)
        if sharey is not None:
            ax.sharey(sharey[i])
        ax.set_ylim(*padded(lo, hi, total))
        axes.append(ax)
        sharex = sharex if sharex is not None else ax
    if len(axes) == 2:
        top, bottom = axes
        top.spines["bottom"].set_visible(False)
        bottom.spines["top"].set_visible(False)
        top.tick_params(labelbottom=False, bottom=False)
        marks = {"marker": [(-1, -0.5), (1, 0.5)], "markersize": 8, "linestyle": "none",
                 "color": "k", "mec": "k", "mew": 1, "clip_on": False}  # fmt: skip
        top.plot([0, 1], [0, 0], transform=top.transAxes, **marks)
        bottom.plot([0, 1], [1, 1], transform=bottom.transAxes, **marks)
    return axes


def point_size(n_points: int, axes_pixels: float, min_pixels: float = 2.0) -> float:
    """Scatter marker area (points^2) for ``n_points`` spread over an axes of
    ``axes_pixels`` square pixels: small enough that a dense cloud shows its density,
    never below ``min_pixels`` across (sub-pixel markers alias into moire stripes)."""
    per_point = axes_pixels / max(n_points, 1)  # square pixels each point may cover
    diameter_px = min(max(math.sqrt(per_point) * 0.8, min_pixels), 7.0)
    return (diameter_px * 72.0 / DPI) ** 2

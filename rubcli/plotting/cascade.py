"""The full-spectrum cascade: the lines of x + i y against frequency (orders, forward > 0,
backward < 0), one spectrum per value of a parameter (a sweep's speed or friction).

A spectrum is a few sharp lines, each one to three frequency bins wide, over a floor many
decades lower. Drawn as an image, a 1,200-bin spectrum on a 550-pixel axis loses the
lines that fall between pixels, and a floor 80 dB down paints the whole panel in the
colour map's darkest shade. So the cascade draws each spectrum's *lines* (local maxima
of the amplitude) as markers, their colour the level in dB of the largest line of the
figure and their area growing with it, over a white background: a line one bin wide is
a marker of a fixed size whatever the resolution of the image, and anything more than
``DYNAMIC_RANGE_DB`` below the largest line is not drawn at all (the colour bar starts
there). Lines that persist across parameter values stack into a visible track.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.colors import Normalize

if TYPE_CHECKING:
    from collections.abc import Iterable

    from matplotlib.axes import Axes
    from matplotlib.collections import PathCollection
    from numpy.typing import ArrayLike

DYNAMIC_RANGE_DB = 60.0  # lines more than this far below the largest line are not drawn
CMAP = "viridis_r"  # weak lines light (yellow), strong ones dark (purple) on white
MAX_LINES = 80  # per spectrum: at most this many of its strongest lines
SMALL, LARGE = 2.5, 9.0  # marker diameters (points) at the floor and at the largest line


def spectral_lines(amplitude: np.ndarray) -> np.ndarray:
    """Indices of the local maxima of one spectrum (a plateau counts once, at its start),
    the edges included; NaN bins are never lines."""
    a = np.asarray(amplitude, dtype=float)
    if a.size == 0:
        return np.empty(0, dtype=np.int64)
    padded = np.concatenate(([-np.inf], np.where(np.isfinite(a), a, -np.inf), [-np.inf]))
    mid = padded[1:-1]
    peak = (mid >= padded[:-2]) & (mid > padded[2:]) & np.isfinite(a)
    return np.flatnonzero(peak)


def cascade_points(
    orders: ArrayLike,
    params: ArrayLike,
    amplitude: ArrayLike,
    reference: float,
    dynamic_range_db: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(order, parameter, level_db)`` of every line drawn: per spectrum (row of
    ``amplitude``, one per parameter value) its local maxima within ``dynamic_range_db``
    of ``reference`` (the figure's largest line), at most ``MAX_LINES`` of them."""
    orders = np.asarray(orders, dtype=float)
    amplitude = np.asarray(amplitude, dtype=float)
    xs, ys, levels = [], [], []
    if not reference > 0:
        return np.empty(0), np.empty(0), np.empty(0)
    for row, p in zip(amplitude, np.asarray(params, dtype=float), strict=True):
        idx = spectral_lines(row)
        with np.errstate(divide="ignore"):
            db = 20.0 * np.log10(row[idx] / reference)
        keep = db >= -dynamic_range_db
        idx, db = idx[keep], db[keep]
        if idx.size > MAX_LINES:
            top = np.argsort(db)[-MAX_LINES:]
            idx, db = idx[top], db[top]
        xs.append(orders[idx])
        ys.append(np.full(idx.size, p))
        levels.append(db)
    if not xs:
        return np.empty(0), np.empty(0), np.empty(0)
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(levels)


def draw_cascade(
    ax: Axes,
    orders: ArrayLike,
    params: ArrayLike,
    amplitude: ArrayLike,
    *,
    reference: float | None = None,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    marked_orders: Iterable[float] = (-1.0, 1.0),
) -> PathCollection | None:
    """Draw the cascade of ``amplitude`` (rows: ``params``; columns: ``orders``) into
    ``ax``; returns the scatter (for a colour bar) or None when nothing was drawn.

    ``reference``: the amplitude of 0 dB (default the largest of ``amplitude``), shared
    by the panels of one figure. ``marked_orders`` get dotted vertical lines (1X, -1X);
    the backward half (order < 0) is shaded; rows whose spectrum is missing (a failed
    point) are marked with a red cross at the left edge.
    """
    orders = np.asarray(orders, dtype=float)
    params = np.asarray(params, dtype=float)
    amplitude = np.asarray(amplitude, dtype=float)
    if reference is None:
        finite = amplitude[np.isfinite(amplitude)]
        reference = float(finite.max()) if finite.size else 0.0
    x, y, db = cascade_points(orders, params, amplitude, reference, dynamic_range_db)
    lo, hi = (float(orders.min()), float(orders.max())) if orders.size else (-1.0, 1.0)
    ax.axvspan(lo, 0.0, color="0.95", zorder=0)
    for order in marked_orders:
        if lo <= order <= hi:
            ax.axvline(order, color="0.55", ls=":", lw=0.8, zorder=1)
    norm = Normalize(vmin=-dynamic_range_db, vmax=0.0)
    artist = None
    if x.size:
        share = np.clip((db + dynamic_range_db) / dynamic_range_db, 0.0, 1.0)
        sizes = (SMALL + (LARGE - SMALL) * share) ** 2
        order = np.argsort(db)  # the strongest drawn last, on top
        artist = ax.scatter(x[order], y[order], s=sizes[order], c=db[order], cmap=CMAP,
                            norm=norm, linewidths=0, zorder=3)  # fmt: skip
    missing = ~np.isfinite(amplitude).any(axis=1) if amplitude.size else np.zeros(0, bool)
    if missing.any():
        ax.plot(np.full(missing.sum(), lo), params[missing], "x", color="red", ms=7,
                mew=1.5, clip_on=False, zorder=4, label="failed point (no spectrum)")  # fmt: skip
    ax.set_xlim(lo, hi)
    if params.size:
        step = np.min(np.diff(np.unique(params)), initial=np.inf)
        pad = 0.5 * step if np.isfinite(step) else 0.5 * max(abs(params[0]), 1.0)
        ax.set_ylim(params.min() - pad, params.max() + pad)
        if np.unique(params).size <= 12:  # a few rows: tick each one, and nothing between
            ax.set_yticks(np.unique(params))
    return artist

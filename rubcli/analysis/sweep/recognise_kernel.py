"""The compiled scan of ``attractors.Recogniser.feed_block``: section points against the
learned clouds and the basin cells, one point after another, with no array made per
point. It does what the numpy path does, comparison by comparison (tests/test_basins.py
runs both on the same points), so a basin grid pays microseconds, not a hundred, per
look at a trajectory.
"""

from __future__ import annotations

import math

import numpy as np

from rubcli.cached_jit import njit

jit = njit(nogil=True)

# the scan's state, carried from block to block (``Recogniser``'s fields)
LABEL, RUN, RUN_START, BASIN_LABEL, BASIN_RUN, BASIN_ETA = range(6)
NONE = -9  # no attractor under the last point
AMBIGUOUS = -1  # as attractors.AMBIGUOUS
DIVERGED = -2  # as attractors.DIVERGED
HOW_ATTRACTOR, HOW_BASIN, HOW_DIVERGED = 1, 2, 3  # as basins.HOW
CELL_BITS = 15


@jit
def cell_key(point: np.ndarray, size: float) -> int:
    """The packed cell key of a point (attractors.CellMap.pack); -1 outside the range."""
    half = 1 << (CELL_BITS - 1)
    key = 0
    for j in range(4):
        index = math.floor(point[j] / size) + half
        if not (index >= 0 and index < 2 * half):
            return -1
        key = (key << CELL_BITS) | int(index)
    return key


@jit
def scan(
    points: np.ndarray, first_period: int, clouds: np.ndarray, offsets: np.ndarray,
    radii: np.ndarray, consecutive: int, keys: np.ndarray, labels: np.ndarray, left: np.ndarray,
    size: float, basin_hits: int, escape: float, state: np.ndarray,
) -> tuple[int, int, int, int]:  # fmt: skip
    """Feed ``points``; returns ``(index, label, how, convergence)`` of the point that
    completes a recognition, or index -1. ``keys`` empty: no basin cells."""
    n_attractors = radii.size
    for i in range(points.shape[0]):
        p = points[i]
        period = first_period + i
        norm2 = 0.0
        finite = True
        for j in range(4):
            if not math.isfinite(p[j]):
                finite = False
            norm2 += p[j] * p[j]
        if not finite or math.sqrt(norm2) > escape:
            return i, DIVERGED, HOW_DIVERGED, period
        best, best_gap = NONE, math.inf
        for a in range(n_attractors):
            nearest = math.inf
            for c in range(offsets[a], offsets[a + 1]):
                d = 0.0
                for j in range(4):
                    diff = p[j] - clouds[c, j]
                    d += diff * diff
                if d < nearest:
                    nearest = d
            gap = math.sqrt(nearest) / radii[a]
            if gap <= 1.0 and gap < best_gap:
                best, best_gap = a, gap
        if best == NONE:
            state[LABEL], state[RUN] = NONE, 0
        else:
            if best != state[LABEL]:
                state[LABEL], state[RUN], state[RUN_START] = best, 0, period
            state[RUN] += 1
            if state[RUN] >= consecutive:
                return i, best, HOW_ATTRACTOR, state[RUN_START]
        if keys.size == 0:
            continue
        key = cell_key(p, size)
        cell = AMBIGUOUS
        ahead = 0
        if key >= 0:
            at = np.searchsorted(keys, key)
            if at < keys.size and keys[at] == key:
                cell, ahead = labels[at], left[at]
        if cell == AMBIGUOUS:
            state[BASIN_LABEL], state[BASIN_RUN] = AMBIGUOUS, 0
            continue
        if cell != state[BASIN_LABEL]:
            state[BASIN_LABEL], state[BASIN_RUN] = cell, 0
            state[BASIN_ETA] = period + ahead
        state[BASIN_RUN] += 1
        if state[BASIN_RUN] >= basin_hits:
            return i, cell, HOW_BASIN, state[BASIN_ETA]
    return -1, NONE, 0, 0


def warm_up() -> None:
    """Compile (or load from numba's cache) the scan here, before workers start, as
    ``engine.warm_up`` does for the solver's kernels."""
    state = np.zeros(6, np.int64)
    scan(np.zeros((1, 4)), 1, np.zeros((1, 4)), np.array([0, 1]), np.ones(1), 1,
         np.zeros(1, np.int64), np.zeros(1, np.int16), np.zeros(1, np.int32), 0.05, 1, 1e3,
         state)  # fmt: skip

"""What a figure draws of a solution: bounded point counts, fine orbits, spans and limits.

A screen shows about a thousand pixels across a plot, so a figure never needs every
sample of a long run (10,000 forcing periods at 100 samples per period are a million
points; drawing them all costs memory and time and shows nothing more). The helpers
here reduce what is drawn, each in a way that keeps what the eye reads:

- ``envelope``: a time series as the min and max of each of at most ``bins`` consecutive
  groups of samples (the envelope a raster plot of every sample would show);
  ``envelope_band`` the same as a band to fill (the time figure);
- ``period_subset``: the faded transient of a long orbit as whole forcing periods (all of
  the first ones, then evenly spaced ones), separated by breaks, never chords;
- ``hermite``: positions between samples from the sampled positions *and velocities*
  (every state carries both), a cubic Hermite interpolant with error O(h^4) in the sample
  spacing where the motion is smooth and O(h^2) times the jump of the acceleration across
  a contact switch; the bold steady orbit is drawn from it at ``FINE_POINTS_PER_PERIOD``,
  so that a whirl looks round even at a few samples per period, without solving again;
- ``steady_start`` and ``keyphasor``: the steady span (after the transient) and the
  once-per-revolution points (one per forcing period: the stroboscopic section);
- ``orbit_radius``: the axis limits of an orbit plot from the successful methods and the
  clearance only, so a failed or diverged trace never sets them;
- ``settled``: whether the last periods of an orbit retrace one closed curve (a periodic
  orbit, drawn bold) or fill a band (a torus, chaos, a slow transient: drawn faint under
  its keyphasor points, which then carry the structure);
- ``difference``: ``|w_b - w_a|`` of two methods against time, for a difference panel.

Pure numpy on ``Solution`` arrays; no matplotlib here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from rubcli.analysis.response.classification import section_from_solution
from rubcli.analysis.response.spectrum import default_transient
from rubcli.solution import Solution

ENVELOPE_BINS = 2000  # time plots: at most 2 * ENVELOPE_BINS points per trace
FADED_POINTS = 60_000  # orbit plots: at most this many points of the faded transient
FADED_POINTS_PER_PERIOD = 200  # ... refined up to this many per period while they fit
FINE_POINTS_PER_PERIOD = 720  # the bold steady orbit: points per forcing period
FINE_POINTS = 20_000  # ... and at most this many in all
BOLD_PERIODS = 10.0  # the bold steady orbit: the last this many forcing periods
SETTLED_TOLERANCE = 0.03  # ``settled``: loops within this fraction of the orbit's size
SETTLED_PERIODS = 4  # ``settled``: ... of the curve of the last this many periods
MARGIN = 1.08  # orbit axes: this much beyond the largest radius drawn
ENVELOPE_CHUNK = 65_536  # samples reduced at a time by ``envelope``
# The clearance (z = 1) drawn in the orbit, time and comparison figures
CLEARANCE_STYLE = {"color": "0.2", "linestyle": "--", "linewidth": 1.0, "zorder": 5}


def envelope(
    t: np.ndarray, values: np.ndarray, bins: int = ENVELOPE_BINS
) -> tuple[np.ndarray, np.ndarray]:
    """``(t, values)`` reduced to the min and max of each of ``bins`` groups of samples.

    Each group contributes its two extreme samples in time order, so the extremes of
    the series and of every group survive and the result has at most ``2 * bins``
    points. Non-finite values are dropped first. Short series are returned as they are.
    """
    t, values, groups = _group_extremes(t, values, bins)
    if groups is None:
        return t, values
    _, lo, hi = groups
    idx = np.column_stack((np.minimum(lo, hi), np.maximum(lo, hi))).ravel()
    return t[idx], values[idx]


def envelope_band(
    t: np.ndarray, values: np.ndarray, bins: int = ENVELOPE_BINS
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(t, lo, hi)``: the band between the min and the max of each of ``bins`` groups of
    samples, as steps (group k spans ``t[k]`` to ``t[k + 1]``; the last value repeats
    at the end), or None for a series short enough to draw as it is (``envelope``'s
    rule). A figure fills it and draws its two edges: the same region as the min/max
    zigzag of ``envelope``, at a fraction of the drawing cost (a zigzag of long
    vertical strokes is what Agg is slowest at). Non-finite values are dropped first."""
    t, values, groups = _group_extremes(t, values, bins)
    if groups is None:
        return None
    edges, lo, hi = groups
    steps = np.append(t[edges[:-1]], t[-1])
    return steps, np.append(values[lo], values[lo[-1]]), np.append(values[hi], values[hi[-1]])


def _group_extremes(t: np.ndarray, values: np.ndarray, bins: int):
    """The finite samples ``(t, values)`` and, for a series of more than ``2 * bins`` of
    them, ``(edges, lo, hi)``: ``bins`` groups and the index of each one's first min and
    first max (else None)."""
    t = np.asarray(t, dtype=float)
    values = np.asarray(values, dtype=float)
    finite = np.isfinite(values) & np.isfinite(t)
    if not np.all(finite):
        t, values = t[finite], values[finite]
    if t.size <= 2 * bins:
        return t, values, None
    edges = np.linspace(0, t.size, bins + 1).astype(np.int64)
    lo, hi = _extreme_indices(values, edges)
    return t, values, (edges, lo, hi)


def _extreme_indices(values: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the first minimum and of the first maximum of each group
    ``edges[i]:edges[i+1]``, computed on runs of groups of about ``ENVELOPE_CHUNK``
    samples, so the temporaries stay bounded whatever the length of the series."""
    groups = edges.size - 1
    lo = np.empty(groups, dtype=np.int64)
    hi = np.empty(groups, dtype=np.int64)
    per_group = max(1, int(edges[-1] - edges[0]) // max(groups, 1))
    step = max(1, ENVELOPE_CHUNK // per_group)
    for a in range(0, groups, step):
        b = min(groups, a + step)
        local = edges[a : b + 1] - edges[a]
        part = values[edges[a] : edges[b]]
        lo[a:b] = edges[a:b] + _arg_reduce(part, local, np.minimum)
        hi[a:b] = edges[a:b] + _arg_reduce(part, local, np.maximum)
    return lo, hi


def _arg_reduce(values: np.ndarray, edges: np.ndarray, ufunc) -> np.ndarray:
    """Offset, within each group ``edges[i]:edges[i+1]``, of the group's reduced value."""
    reduced = ufunc.reduceat(values, edges[:-1])
    group = np.repeat(np.arange(edges.size - 1), np.diff(edges))
    hit = values == reduced[group]
    # first hit of each group: the smallest index where hit is true, per group
    positions = np.where(hit, np.arange(values.size), values.size)
    return np.minimum.reduceat(positions, edges[:-1]) - edges[:-1]


def finite_length(solution: Solution) -> int:
    """Number of leading samples whose state is finite (a diverged run ends in inf/nan)."""
    with np.errstate(over="ignore", invalid="ignore"):
        total = float(np.sum(solution.states))
    if math.isfinite(total):  # every state finite (a sum of finite values can overflow:
        return int(solution.t.size)  # then the test below decides); 10x cheaper than it
    ok = np.all(np.isfinite(solution.states), axis=1) if solution.t.size else np.ones(0, bool)
    bad = np.flatnonzero(~ok)
    return int(bad[0]) if bad.size else int(solution.t.size)


def recorded_periods(solution: Solution) -> float:
    """Forcing periods covered by the solution's (finite) samples."""
    n = finite_length(solution)
    if n < 2:
        return 0.0
    return float(solution.t[n - 1] - solution.t[0]) / solution.problem.params.period


def steady_start(solution: Solution, transient_periods: float | None = None) -> float:
    """tau from which the response is taken as steady.

    ``transient_periods`` after the problem's start when given and shorter than the
    record; otherwise half the recorded span, rounded down to whole forcing periods
    (``analysis.response.spectrum.default_transient``, the rule of the report's spectrum).
    """
    period = solution.problem.params.period
    t0 = float(solution.problem.t_eval[0])
    return t0 + default_transient(recorded_periods(solution), transient_periods) * period


def keyphasor(solution: Solution, transient_periods: float | None = None) -> np.ndarray:
    """Positions (k, 2) once per forcing period from ``steady_start`` to the end.

    These are the stroboscopic section's points (``analysis.response.classification``): one
    dot for a periodic orbit of period one, p dots for period p, a closed curve for a
    quasi-periodic orbit. Only the finite samples are used.
    """
    n = finite_length(solution)
    if n < 2:
        return np.empty((0, 2))
    period = solution.problem.params.period
    t0 = float(solution.problem.t_eval[0])
    start = (steady_start(solution, transient_periods) - t0) / period
    part = _head(solution, n)
    return section_from_solution(part, transient_periods=start).points[:, :2].copy()


def _head(solution: Solution, n: int) -> Solution:
    if n == solution.t.size:
        return solution
    return Solution(
        solution.problem, solution.method, solution.t[:n], solution.states[:n],
        solution.regimes[:n], status=solution.status, message=solution.message,
    )  # fmt: skip


def hermite(t: np.ndarray, states: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Positions (m, 2) at times ``tq`` from samples of (x, y, vx, vy) at ``t``.

    Piecewise cubic Hermite: it passes through every sample with the sampled velocity.
    ``tq`` must lie within ``[t[0], t[-1]]``.
    """
    t = np.asarray(t, dtype=float)
    states = np.asarray(states, dtype=float)
    tq = np.asarray(tq, dtype=float)
    i = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 2)
    h = t[i + 1] - t[i]
    safe = np.where(h > 0.0, h, 1.0)
    s = np.where(h > 0.0, (tq - t[i]) / safe, 0.0)[:, None]
    s2, s3 = s * s, s * s * s
    h00 = 2.0 * s3 - 3.0 * s2 + 1.0
    h10 = s3 - 2.0 * s2 + s
    h01 = -2.0 * s3 + 3.0 * s2
    h11 = s3 - s2
    p0, p1 = states[i, :2], states[i + 1, :2]
    v0, v1 = states[i, 2:4], states[i + 1, 2:4]
    hh = h[:, None]
    return h00 * p0 + h10 * hh * v0 + h01 * p1 + h11 * hh * v1


def fine_orbit(
    solution: Solution,
    t_from: float,
    points_per_period: int = FINE_POINTS_PER_PERIOD,
    max_points: int = FINE_POINTS,
) -> np.ndarray:
    """Positions (m, 2) from ``t_from`` to the last finite sample, at least
    ``points_per_period`` per forcing period (at most ``max_points``), by ``hermite``."""
    n = finite_length(solution)
    if n < 2:
        return solution.states[:n, :2].copy()
    t = solution.t[:n]
    t_from = min(max(float(t_from), float(t[0])), float(t[-1]))
    period = solution.problem.params.period
    m = int(min(max_points, max(2, math.ceil((t[-1] - t_from) / period * points_per_period))))
    tq = np.linspace(t_from, float(t[-1]), m + 1)
    return hermite(t, solution.states[:n], tq)


def period_subset(
    solution: Solution,
    t_until: float,
    max_points: int = FADED_POINTS,
    points_per_period: int = FADED_POINTS_PER_PERIOD,
) -> np.ndarray:
    """Positions (m, 2) of the motion before ``t_until``, at most about ``max_points``.

    When the samples before ``t_until`` fit the budget, all of them, each interval refined
    by ``hermite`` up to ``points_per_period`` per forcing period while the budget allows
    (so a faded transient sampled at 50 per period is no polygon). Otherwise whole forcing
    periods of samples: the first half of the budget on the first periods (where the
    transient changes most), the other half on periods evenly spaced over the rest;
    non-adjacent periods are separated by a row of NaN (a break in the line) so that no
    chord joins them.
    """
    n = finite_length(solution)
    t = solution.t[:n]
    stop = int(np.searchsorted(t, t_until, side="right"))
    stop = min(n, stop + 1) if stop < n else n  # join the faded part to the bold one
    if stop < 2:
        return solution.states[:stop, :2].copy()
    period = solution.problem.params.period
    if stop <= max_points:
        per_period = (stop - 1) / max((t[stop - 1] - t[0]) / period, 1e-300)
        refine = int(min(max(1, max_points // stop), math.ceil(points_per_period / per_period)))
        if refine <= 1:
            return solution.states[:stop, :2].copy()
        frac = np.arange(refine) / refine
        tq = (t[: stop - 1, None] + frac * np.diff(t[:stop])[:, None]).ravel()
        tq = np.append(tq, t[stop - 1])
        return hermite(t[:stop], solution.states[:stop], tq)
    k = np.floor((t[:stop] - t[0]) / period).astype(np.int64)
    n_periods = int(k[-1]) + 1
    per_period = max(1.0, stop / n_periods)
    budget = max(2, int(max_points / per_period))
    head = budget // 2
    rest = np.unique(np.linspace(head, n_periods - 1, budget - head).round().astype(np.int64))
    chosen = np.zeros(n_periods, dtype=bool)
    chosen[:head] = True
    chosen[rest] = True
    idx = np.flatnonzero(chosen[k])
    pts = solution.states[idx, :2]
    breaks = np.flatnonzero(np.diff(idx) > 1) + 1
    return np.insert(pts, breaks, np.nan, axis=0)


def orbit_radius(solutions: Sequence[Solution], cap_failed: float = 10.0) -> float:
    """Half-width of orbit axes, in clearances: the clearance and every successful orbit.

    Failed methods count only when none succeeded: then the 99th percentile of their
    finite radii, at most ``cap_failed`` clearances (a diverged trace is drawn clipped).
    """
    good = [s for s in solutions if s.success and s.t.size]
    radius = 1.0
    if good:
        for s in good:
            n = finite_length(s)
            if n:
                radius = max(radius, float(np.max(np.hypot(s.x[:n], s.y[:n]))))
    else:
        radii = [np.hypot(s.x[: finite_length(s)], s.y[: finite_length(s)]) for s in solutions]
        radii = [r for r in radii if r.size]
        if radii:
            r99 = float(np.percentile(np.concatenate(radii), 99.0))
            radius = min(max(radius, r99), cap_failed)
    return MARGIN * radius


def distance(a: Solution, b: Solution, t_from: float | None = None) -> float | None:
    """Largest |w_a - w_b| over the samples both have (from ``t_from``), or None."""
    n = min(finite_length(a), finite_length(b))
    if n == 0:
        return None
    keep = slice(0, n)
    if t_from is not None:
        first = int(np.searchsorted(a.t[:n], t_from - 1e-9 * a.problem.params.period))
        if first >= n:
            return None
        keep = slice(first, n)
    if not np.allclose(a.t[keep], b.t[keep], rtol=1e-12, atol=0.0):
        return None  # not sampled at the same times
    return float(np.max(np.hypot(a.x[keep] - b.x[keep], a.y[keep] - b.y[keep])))


def settled(
    solution: Solution,
    t_from: float,
    tolerance: float = SETTLED_TOLERANCE,
    periods: int = SETTLED_PERIODS,
) -> bool:
    """Whether the orbit from ``t_from`` to its end retraces one closed curve.

    True when every point of the span lies within ``tolerance`` times the span's radius
    of the curve drawn by its last ``periods`` forcing periods (or the whole span when
    shorter): a periodic orbit of period up to ``periods``, or one still drifting along
    its own loop. False when the loops fill a band (a torus, chaos, a transient that
    still changes shape): drawn bold, such loops are an unreadable tangle.
    """
    n = finite_length(solution)
    if n < 2:
        return True
    period = solution.problem.params.period
    t_end = float(solution.t[n - 1])
    t_from = max(float(t_from), float(solution.t[0]))
    per_period = 120  # chords of 3 degrees on a circular whirl: 0.07 % of its radius
    m = max(2, int(math.ceil((t_end - t_from) / period * per_period)))
    tq = np.linspace(t_from, t_end, m + 1)
    pts = hermite(solution.t[:n], solution.states[:n], tq)
    size = float(np.max(np.hypot(pts[:, 0] - pts[:, 0].mean(), pts[:, 1] - pts[:, 1].mean())))
    if not math.isfinite(size) or size == 0.0:
        return True
    last = pts[tq >= t_end - periods * period]
    if last.shape[0] == pts.shape[0]:
        return True
    w_all = pts[:, 0] + 1j * pts[:, 1]
    w_last = last[:, 0] + 1j * last[:, 1]
    worst = 0.0
    for chunk in np.array_split(w_all, max(1, w_all.size // 2000)):
        worst = max(worst, float(np.max(np.min(np.abs(chunk[:, None] - w_last), axis=1))))
    return worst <= tolerance * size


def difference(a: Solution, b: Solution) -> tuple[np.ndarray, np.ndarray]:
    """``(t, |w_b - w_a|)`` at the samples of ``a`` within the finite span of both.

    Where ``b`` was sampled at other times it is interpolated there (``hermite``), so two
    methods with different outputs still compare. Empty arrays when they do not overlap.
    """
    na, nb = finite_length(a), finite_length(b)
    if na < 1 or nb < 2:
        return np.empty(0), np.empty(0)
    ta, tb = a.t[:na], b.t[:nb]
    keep = (ta >= tb[0]) & (ta <= tb[-1])
    t = ta[keep]
    if t.size == 0:
        return t, np.empty(0)
    if tb.size == ta.size and np.allclose(ta, tb, rtol=1e-12, atol=0.0):
        wb = b.states[:nb, :2][keep]
    else:
        wb = hermite(tb, b.states[:nb], t)
    wa = a.states[:na, :2][keep]
    return t, np.hypot(wb[:, 0] - wa[:, 0], wb[:, 1] - wa[:, 1])

"""``dop853-jit`` on the composed machine's system: scipy's DOP853 step (compiled, the
state's size at run time), each accepted step's dense output scanned for the stations'
events, the samples of the steps without one written, in one compiled loop.

``advance`` returns to Python at the first step whose scan grid shows an event function
leaving its regime (``kernels.event_functions``: positive while the regime holds), with
the step's dense output, so that Python locates the event and applies the switch rule
(``rubcli.system.run``); or at the end of the span, or after ``max_steps`` steps (so
Python can check the run's wall-time budget between calls).
"""

from __future__ import annotations

import numpy as np

from rubcli.solvers.compiled.dop853 import DOP_STAGES, _dop853_dense_at, dop853_step
from rubcli.solvers.compiled.jit import jit, jit_loop
from rubcli.system.kernels import OK, event_functions, rhs_into

initial_step, accepted_step, dense_coefficients = dop853_step(rhs_into, 0, counted=False)

SCAN_POINTS = 4  # the scan grid of a step: its quarters, as the rotor's dop853-jit
# why advance returned
END, EVENT, LIMIT, SMALL_STEP, SINGULAR_STICK = 0, 1, 2, 3, 4


@jit
def first_step(
    t: float, y: np.ndarray, f: np.ndarray, t_end: float, ctx: tuple, rtol: float, atol: float
) -> float:
    """``f = f(t, y)`` and Hairer's initial step from (t, y) (a function of this module,
    so that its compiled code is cached with it: the step factory's own ``initial_step``
    is shared by every system's closure, and its cache entry with them)."""
    rhs_into(t, y, ctx, 0, f)
    return initial_step(t, y, f, t_end, ctx, 0, rtol, atol)


@jit_loop
def dense_point(
    t: float, t_old: float, h: float, y_old: np.ndarray, F: np.ndarray, out: np.ndarray
) -> None:
    """The step's dense output at t into out."""
    _dop853_dense_at(t, t_old, h, y_old, F, out)


@jit_loop
def advance(
    t: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, ctx: tuple,
    rtol: float, atol: float, t_eval: np.ndarray, k: int, samples: np.ndarray,
    sample_regimes: np.ndarray, max_steps: int, Kst: np.ndarray, y_new: np.ndarray,
    tmp: np.ndarray, F: np.ndarray, g_prev: np.ndarray, g: np.ndarray, vals: np.ndarray,
    out: np.ndarray, point: np.ndarray,
) -> tuple[int, float, float, int, int, int, float, float, int]:  # fmt: skip
    """Steps from ``(t, y)`` (``f = f(t, y)``, proposal ``h_abs``), writing the samples
    ``t_eval[k:]`` passed, until an event, the end or ``max_steps`` steps.

    Returns ``(stop, t, h_abs, k, steps, nfev, t_old, h, j)``: why (``END``, ``EVENT``,
    ``LIMIT``, ``SMALL_STEP``, ``SINGULAR_STICK``), the time reached (y and f updated in
    place), the next proposal, the next sample, the steps and evaluations taken; on an
    event, the step's start ``t_old`` and length ``h`` (its dense output in ``F``, its
    start state still in ``y``) and the scan point ``j`` (1..SCAN_POINTS) at which a
    function in ``g`` is at or below 0 while it was above 0 at point j - 1 (``g_prev``)."""
    regimes = ctx[12]
    n_samples = t_eval.shape[0]
    steps = 0
    nfev = 0
    while steps < max_steps:
        if t >= t_end:
            return END, t, h_abs, k, steps, nfev, t, 0.0, 0
        t_new, h, h_abs, evals = accepted_step(
            t, y, f, h_abs, t_end, ctx, 0, rtol, atol, Kst, y_new, tmp
        )
        nfev += evals
        if h == 0.0:
            return SMALL_STEP, t, h_abs, k, steps, nfev, t, 0.0, 0
        steps += 1
        nfev += dense_coefficients(t, h, y, y_new, ctx, 0, Kst, F, tmp)
        for j in range(1, SCAN_POINTS + 1):
            if j == SCAN_POINTS:
                for i in range(y.shape[0]):
                    point[i] = y_new[i]
                tj = t_new
            else:
                tj = t + h * j / SCAN_POINTS
                _dop853_dense_at(tj, t, h, y, F, point)
            if event_functions(tj, point, ctx, out, vals, g) != OK:
                return SINGULAR_STICK, t, h_abs, k, steps, nfev, t, h, j
            nfev += 1
            for s in range(g.shape[0]):
                for i in range(2):
                    if g_prev[s, i] > 0.0 and g[s, i] <= 0.0:
                        return EVENT, t, h_abs, k, steps, nfev, t, h, j
            for s in range(g.shape[0]):
                g_prev[s, 0] = g[s, 0]
                g_prev[s, 1] = g[s, 1]
        while k < n_samples and t_eval[k] <= t_new:
            if t_eval[k] == t_new:
                for i in range(y.shape[0]):
                    samples[k, i] = y_new[i]
            else:
                _dop853_dense_at(t_eval[k], t, h, y, F, samples[k])
            for s in range(regimes.shape[0]):
                sample_regimes[k, s] = regimes[s]
            k += 1
        for i in range(y.shape[0]):
            y[i] = y_new[i]
            f[i] = Kst[DOP_STAGES, i]
        t = t_new
    return LIMIT, t, h_abs, k, steps, nfev, t, 0.0, 0


@jit_loop
def _g_at(t, t_old, h, y_old, F, ctx, out, vals, g, point, s, i):
    _dop853_dense_at(t, t_old, h, y_old, F, point)
    event_functions(t, point, ctx, out, vals, g)
    return g[s, i]


@jit
def locate(
    t_old: float, h: float, j: int, y_old: np.ndarray, F: np.ndarray, ctx: tuple,
    g_prev: np.ndarray, out: np.ndarray, vals: np.ndarray, g: np.ndarray, point: np.ndarray,
) -> tuple[float, int, int]:  # fmt: skip
    """The earliest event in the scan interval j of the step ``(t_old, h)`` (dense output
    ``F`` from ``y_old``): every function above 0 at the interval's start (``g_prev``)
    and at or below 0 at its end, its crossing bracketed by the Illinois method to 4 ulp
    and put on the side beyond 0. Returns ``(t, s, i)``: the time, station and function
    (the state there in ``point``); a function already at or below 0 at the start of a
    segment's first interval crosses at that start."""
    ta = t_old + h * (j - 1) / SCAN_POINTS
    tb = t_old + h * j / SCAN_POINTS if j < SCAN_POINTS else t_old + h
    S = g.shape[0]
    gb = np.empty((S, 2))
    ga = np.empty((S, 2))
    _dop853_dense_at(tb, t_old, h, y_old, F, point)
    event_functions(tb, point, ctx, out, vals, g)
    gb[:, :] = g
    _dop853_dense_at(ta, t_old, h, y_old, F, point)
    event_functions(ta, point, ctx, out, vals, g)
    ga[:, :] = g
    best_t, best_s, best_i = tb + 1.0, -1, -1
    for s in range(S):
        for i in range(2):
            if not (g_prev[s, i] > 0.0 and gb[s, i] <= 0.0):
                continue
            if ga[s, i] <= 0.0:
                root = ta
            else:
                lo, hi = ta, best_t if best_t < tb else tb
                g_lo, g_hi = ga[s, i], _g_at(hi, t_old, h, y_old, F, ctx, out, vals, g, point,
                                             s, i)  # fmt: skip
                if g_hi > 0.0:  # crosses after an earlier function's event: not the first
                    continue
                side = 0
                for _ in range(200):
                    if hi - lo <= 4.0 * (np.nextafter(abs(hi), np.inf) - abs(hi)):
                        break
                    mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
                    if not (lo < mid < hi):
                        mid = 0.5 * (lo + hi)
                    g_mid = _g_at(mid, t_old, h, y_old, F, ctx, out, vals, g, point, s, i)
                    if g_mid > 0.0:
                        lo, g_lo = mid, g_mid
                        if side == 1:
                            g_hi *= 0.5
                        side = 1
                    else:
                        hi, g_hi = mid, g_mid
                        if side == -1:
                            g_lo *= 0.5
                        side = -1
                root = hi
            if root < best_t:
                best_t, best_s, best_i = root, s, i
    _dop853_dense_at(best_t, t_old, h, y_old, F, point)
    return best_t, best_s, best_i

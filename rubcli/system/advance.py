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

from rubcli.solvers.compiled.dop853 import DOP_STAGES, _dop853_dense_at, dop853_step
from rubcli.solvers.compiled.jit import jit
from rubcli.system.kernels import OK, event_functions, rhs_into

initial_step, accepted_step, dense_coefficients = dop853_step(rhs_into, 0)

SCAN_POINTS = 4  # the scan grid of a step: its quarters, as the rotor's dop853-jit
# why advance returned
END, EVENT, LIMIT, SMALL_STEP, SINGULAR_STICK = 0, 1, 2, 3, 4


@jit
def first_step(t, y, f, t_end, ctx, rtol, atol):
    """``f = f(t, y)`` and Hairer's initial step from (t, y) (a function of this module,
    so that its compiled code is cached with it: the step factory's own ``initial_step``
    is shared by every system's closure, and its cache entry with them)."""
    rhs_into(t, y, ctx, 0, f)
    return initial_step(t, y, f, t_end, ctx, 0, rtol, atol)


@jit
def dense_point(t, t_old, h, y_old, F, out):
    """The step's dense output at t into out."""
    _dop853_dense_at(t, t_old, h, y_old, F, out)


@jit
def advance(
    t, y, f, h_abs, t_end, ctx, rtol, atol, t_eval, k, samples, sample_regimes, max_steps,
    Kst, y_new, tmp, F, g_prev, g, vals, out, point,
):  # fmt: skip
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
                point[:] = y_new
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
            g_prev[:, :] = g
        while k < n_samples and t_eval[k] <= t_new:
            if t_eval[k] == t_new:
                samples[k] = y_new
            else:
                _dop853_dense_at(t_eval[k], t, h, y, F, samples[k])
            sample_regimes[k] = regimes
            k += 1
        y[:] = y_new
        f[:] = Kst[DOP_STAGES]
        t = t_new
    return LIMIT, t, h_abs, k, steps, nfev, t, 0.0, 0

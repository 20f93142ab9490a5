"""The analytic methods' compiled slip steps: the parts of a linearised contact step the
fixed-step loop (``piecewise_loop.advance_piecewise``) uses, and the adaptive steps.

``advance_contact_adaptive`` advances adaptive contact steps (``analytic_tol``) in one
slip regime with the Cartesian (``analytic``) or polar (``analytic-polar``)
linearisation, pair of half steps by pair, with the step doubling and control of
analytic.py's Python loop, exactly as the Python propagators do, and fills the output
samples of each step from its closed form. It hands control back before any pair that
might contain an event (the pre-check, ``precheck.py``), or that needs Python (an
ill-conditioned eigenbasis, a singular system, a non-finite state), so every event of an
adaptive run is located, and every regime change decided, by the driver's stepper in
analytic.py.
"""

from __future__ import annotations

import math

import numpy as np

from rubcli.model import (
    P_ETA,
    P_MU,
    P_RP,
    friction_sign,
)
from rubcli.solvers.compiled.jit import (
    STOP_END,
    STOP_EVENT,
    STOP_LIMIT,
    STOP_PYTHON,
    jit,
    jit_inline,
)
from rubcli.solvers.compiled.precheck import (
    _step_may_have_event,
    polar_step_clear,
)
from rubcli.solvers.compiled.propagators import (
    _evaluate,
    _prepare,
    _workspace,
)
from rubcli.solvers.control import doubling_error, next_step
from rubcli.solvers.events import MAX_SCAN_POINTS, linspace_into, run_time

STEP_CLEAR = -1  # _check_step: no event can occur in the step, the kernel may take it


@jit
def _scan_buffers(size):
    """(grid, S, dS, hv, hd) of a scan grid of ``size`` points."""
    return (
        np.empty(size),
        np.empty((size, 4)),
        np.empty((size, 4)),
        np.empty(size),
        np.empty(size),
    )


@jit
def _scan_points(tau, tb, omega_max, scan_fraction):
    """Intervals of the step's scan grid (analytic.py's ``search``), -1 beyond MAX_SCAN_POINTS."""
    spacing = scan_fraction * 2.0 * math.pi / max(omega_max, 1e-300)
    if (tb - tau) / spacing > MAX_SCAN_POINTS:
        return -1
    return max(1, math.ceil((tb - tau) / spacing))


@jit
def _clear_by_bound(polar, tau, tb, pars, ws, cond, event_args, end, dout):
    """True if the prepared step [tau, tb] surely holds no event by the polar step's mode
    bounds (``precheck.polar_step_clear``; the polar linearisation only, and not from an
    event surface), with its finite end state in ``end``: the step needs no scan grid.
    False leaves the step to the grid (``end`` is then overwritten there)."""
    sign, check_slip, spin, starts = event_args
    if not polar or starts[0] or starts[1]:
        return False
    if not polar_step_clear(ws, tb - tau, cond, sign, check_slip, spin):
        return False
    _evaluate(polar, tau, tb, pars, ws, end, dout)
    finite = True
    for j in range(4):
        finite = finite and math.isfinite(end[j])
    return finite


@jit_inline
def _fill_grid(polar, tau, tb, n, pars, ws, grid, S, dS, out, dout):
    """The step's closed form at n + 1 points from tau to tb: the points into grid, the
    states into S and their rates into dS. False if any value is not finite."""
    linspace_into(grid, tau, tb, n)
    finite = True
    for i in range(n + 1):
        _evaluate(polar, tau, grid[i], pars, ws, out, dout)
        for j in range(4):
            S[i, j] = out[j]
            dS[i, j] = dout[j]
            finite = finite and math.isfinite(out[j]) and math.isfinite(dout[j])
    return finite


@jit_inline
def _check_step(polar, tau, tb, n, ws, cond, pars, event_args, scan, end, work):
    """The event pre-check of one prepared contact step [tau, tb] (propagator in ``ws``).

    The step is evaluated on its scan grid
    of ``n`` intervals (``np.linspace(tau, tb, n + 1)``, ``n`` from ``_scan_points``)
    and ``_step_may_have_event`` decides. ``event_args`` = (sign, check_slip, spin,
    starts); ``scan`` = (grid, S, dS, hv, hd) of at least n + 1 points
    (``_scan_buffers``); ``end`` receives the state at tb (the grid's last point);
    ``work`` = (out, dout). Returns ``STEP_CLEAR`` if no event can occur, ``STOP_EVENT``
    if one might, ``STOP_PYTHON`` if a state is not finite (Python fails the run). A
    polar step cleared by its mode bounds (``_clear_by_bound``) skips the grid.
    """
    sign, check_slip, spin, starts = event_args
    grid, S, dS, hv, hd = scan
    out, dout = work
    if _clear_by_bound(polar, tau, tb, pars, ws, cond, event_args, end, dout):
        return STEP_CLEAR
    if not _fill_grid(polar, tau, tb, n, pars, ws, grid, S, dS, out, dout):
        return STOP_PYTHON
    for j in range(4):
        end[j] = S[n, j]
    if _step_may_have_event(grid, S, dS, n, sign, check_slip, spin, cond, hv, hd, starts):
        return STOP_EVENT
    return STEP_CLEAR


@jit_inline
def _fill_samples(polar, tau, tb, pars, ws, t_eval, out_states, k, work):
    """Write the samples of ``t_eval[k:]`` in (.., tb] from the step prepared at tau
    (as the fixed-step loop does); returns the new k. ``work`` = (out, dout)."""
    out, dout = work
    while k < t_eval.shape[0] and t_eval[k] <= tb:
        _evaluate(polar, tau, t_eval[k], pars, ws, out, dout)
        for j in range(4):
            out_states[k, j] = out[j]
        k += 1
    return k


@jit
def _event_args(regime, pars, starts):
    """(sign, check_slip, spin, starts) of a slip regime, for ``_check_step``."""
    eta, mu, Rp = pars[P_ETA], pars[P_MU], pars[P_RP]
    return float(regime), mu > 0.0, Rp * eta, starts


@jit
def advance_contact_adaptive(
    polar: bool,
    tau: float,
    state: np.ndarray,
    h: float,
    t_end: float,
    regime: int,
    pars: np.ndarray,
    t_eval: np.ndarray,
    out_states: np.ndarray,
    k: int,
    max_steps: int,
    scan_fraction: float,
    cond_limit: float,
    starts: tuple[bool, bool, bool],
    control: tuple[float, float, float, float, float, float],
) -> tuple[float, np.ndarray, int, int, int, float, int]:
    """Adaptive (step-doubling) contact steps in one slip regime while no event can occur.

    The step control of analytic.py's Python loop (``_doubling_error`` and the loop in
    ``solve_piecewise``), pair of half steps by pair: from (tau, s) a step of
    ``step = min(h, h_max, t_end - tau)`` is compared with two of ``step / 2``,
    ``err = max(|full - second| / (1 + |s|)) * 4/3``; the proposed next step is
    ``step * min(max_factor, max(min_factor, safety * (tol / err)^(1/3)))``, and the step
    is rejected (and retried with that step) unless ``err <= tol`` or
    ``step <= min_step``. An accepted pair is taken as its two half steps, each checked
    for events and sampled as the fixed-step loop checks and samples one step, each
    counted as one step. ``control`` = (tol, safety, min_factor, max_factor, h_max,
    min_step); ``starts`` = (on the contact surface, on the slip surface, slip start
    immediate) of the first step (``events.start_flags``), ``scan_fraction`` and
    ``cond_limit`` analytic.py's ``CONTACT_SCAN_FRACTION`` and ``EIGVEC_COND_LIMIT``.

    A pair is committed whole or not at all: if either half might hold an event, needs
    Python (conditioning, scan size, non-finite states), or the pair does not fit in
    ``max_steps``, the kernel returns *before* the pair, with the ``h`` it started the
    pair with, so Python's own adaptive loop recomputes that pair (its rejections
    included) exactly as it would have without the kernel.

    Returns ``(tau, state, k, steps, rejected, h, reason)``: ``rejected`` counts the
    rejected tries of the committed pairs only, ``h`` is the controller's proposed next
    step; with ``steps == 0`` and a limit too small for a pair the reason is
    ``STOP_PYTHON``, else ``STOP_LIMIT``.
    """
    tol, safety, min_factor, max_factor, h_max, min_step = control
    mu_c = pars[P_MU] * friction_sign(regime)
    first_args = _event_args(regime, pars, starts)
    later_args = _event_args(regime, pars, (False, False, False))
    s = state.copy()
    ws1 = _workspace()  # the full step and the first half: one propagator, at (tau, s)
    ws2 = _workspace()  # the second half, at (tau + step / 2, mid)
    full = np.empty(4)
    mid = np.empty(4)
    end = np.empty(4)
    dout = np.empty(4)
    work = (np.empty(4), dout)
    grid, S, dS, hv, hd = _scan_buffers(run_time(2))
    steps = 0
    rejected = 0
    while True:
        if tau >= t_end:
            return tau, s, k, steps, rejected, h, STOP_END
        if steps + 2 > max_steps:
            return tau, s, k, steps, rejected, h, STOP_LIMIT if steps > 0 else STOP_PYTHON
        if steps > 0:  # start the eigensolver from the last mid-point's eigenvalues
            for i in range(4):
                ws1[0][i] = ws2[0][i]
        cond1, omega1 = _prepare(polar, tau, s, pars, mu_c, ws1, steps > 0)
        # Python uses the eigenbasis while cond2(V) <= cond_limit, and cond2 <= 4 cond1:
        # proceed only where Python surely uses it too
        if not 8.0 * cond1 <= cond_limit:
            return tau, s, k, steps, rejected, h, STOP_PYTHON
        h_next = h
        tries = 0
        while True:
            step = min(h_next, h_max, t_end - tau)
            t_mid = tau + step / 2
            t_next = tau + step
            _evaluate(polar, tau, t_next, pars, ws1, full, dout)
            _evaluate(polar, tau, t_mid, pars, ws1, mid, dout)
            for i in range(4):
                ws2[0][i] = ws1[0][i]
            cond2, omega2 = _prepare(polar, t_mid, mid, pars, mu_c, ws2, run_time(True))
            if not 8.0 * cond2 <= cond_limit:
                return tau, s, k, steps, rejected, h, STOP_PYTHON
            _evaluate(polar, t_mid, t_next, pars, ws2, end, dout)
            err = doubling_error(full, end, s)
            if not math.isfinite(err):
                return tau, s, k, steps, rejected, h, STOP_PYTHON
            h_next, accept = next_step(step, err, tol, safety, min_factor, max_factor, min_step)
            if accept:
                break
            tries += 1
        # both halves are checked before either is taken (Python may redo the pair)
        n1 = _scan_points(tau, t_mid, omega1, scan_fraction)
        n2 = _scan_points(t_mid, t_next, omega2, scan_fraction)
        if n1 < 0 or n2 < 0:
            return tau, s, k, steps, rejected, h, STOP_PYTHON  # Python fails the run cleanly
        if grid.shape[0] < max(n1, n2) + 1:
            grid, S, dS, hv, hd = _scan_buffers(max(n1, n2) + 1)
        scan = (grid, S, dS, hv, hd)
        args = first_args if steps == 0 else later_args
        code = _check_step(polar, tau, t_mid, n1, ws1, cond1, pars, args, scan, mid, work)
        if code != STEP_CLEAR:
            return tau, s, k, steps, rejected, h, code
        code = _check_step(polar, t_mid, t_next, n2, ws2, cond2, pars, later_args, scan, end, work)
        if code != STEP_CLEAR:
            return tau, s, k, steps, rejected, h, code
        k = _fill_samples(polar, tau, t_mid, pars, ws1, t_eval, out_states, k, work)
        k = _fill_samples(polar, t_mid, t_next, pars, ws2, t_eval, out_states, k, work)
        for j in range(4):
            s[j] = end[j]
        tau = t_next
        h = h_next
        steps += 2
        rejected += tries

"""The analytic methods' linearised slip step in the one compiled event loop: its scan
grid and event pre-check (``slip_scan``), which the fixed-step loop
(``piecewise_loop.advance_piecewise``) shares, and the adaptive slip steps
(``advance_contact_adaptive``).

``advance_contact_adaptive`` advances adaptive contact steps (``analytic_tol``) in one
slip regime with the Cartesian (``analytic``) or polar (``analytic-polar``)
linearisation, pair of half steps by pair, with the step doubling and control of
analytic.py's Python loop, exactly as the Python propagators do, and fills the output
samples of each pair from its closed form. A pair is one step of the event loop
(``event_loop``), run with the events left to Python: the loop returns before any pair
that might contain an event (the pre-check, ``precheck.py``) or that needs Python (an
ill-conditioned eigenbasis, a singular system, a non-finite state), so every event of an
adaptive run is located, and every regime change decided, by the driver's stepper in
analytic.py, which redoes that pair itself.
"""

from __future__ import annotations

import math

import numpy as np

from rubcli.model import P_ETA, P_MU, P_RP, friction_sign
from rubcli.solvers.compiled.event_loop import (
    PYTHON_LOCATES,
    SCAN_NONE,
    SCAN_PYTHON,
    STOP_NONE,
    event_loop,
)
from rubcli.solvers.compiled.jit import (
    STOP_END,
    STOP_GROW,
    STOP_LIMIT,
    STOP_PYTHON,
    jit,
    jit_inline,
    jit_loop,
)
from rubcli.solvers.compiled.precheck import _step_may_have_event, polar_step_clear
from rubcli.solvers.compiled.propagators import _evaluate, _prepare, workspace
from rubcli.solvers.compiled.roots import rotor_project
from rubcli.solvers.control import doubling_error, next_step
from rubcli.solvers.events import MAX_SCAN_POINTS, linspace_into, run_time

SCAN_GRID = 1  # a pre-check's answer: an event may lie in the step, search its scan grid


def scan_buffers(size: int) -> tuple[np.ndarray, ...]:
    """(grid, S, dS, hv, hd, row, drow): a scan grid of ``size`` points, its states and
    rates, the search's work rows, and two state rows."""
    return (
        np.empty(size), np.empty((size, 4)), np.empty((size, 4)), np.empty(size),
        np.empty(size), np.empty(4), np.empty(4),
    )  # fmt: skip


@jit
def scan_points(tau: float, tb: float, omega_max: float, scan_fraction: float) -> int:
    """Intervals of the step's scan grid (analytic.py's ``search``), -1 beyond MAX_SCAN_POINTS."""
    spacing = scan_fraction * 2.0 * math.pi / max(omega_max, 1e-300)
    if (tb - tau) / spacing > MAX_SCAN_POINTS:
        return -1
    return max(1, math.ceil((tb - tau) / spacing))


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
def slip_scan(
    polar: bool, tau: float, tb: float, n: int, pars: np.ndarray, ws: tuple, cond: float,
    regime: int, starts: tuple[bool, bool, bool], scan: tuple,
) -> int:  # fmt: skip
    """The event pre-check of one prepared slip step [tau, tb] (propagator in ``ws``,
    its eigenbasis of condition ``cond``), on its scan grid of ``n`` intervals
    (``np.linspace(tau, tb, n + 1)``, ``n`` from ``scan_points``) into ``scan``
    (``scan_buffers`` of at least n + 1 points): ``SCAN_GRID`` if the event search might
    find an event there (``precheck._step_may_have_event``), ``SCAN_PYTHON`` if a state on
    the grid is not finite (Python fails the run), else ``SCAN_NONE``. A polar step not
    started on an event surface that its mode bounds clear
    (``precheck.polar_step_clear``) needs no grid.
    """
    sign = float(regime)
    check_slip = pars[P_MU] > 0.0
    spin = pars[P_RP] * pars[P_ETA]
    bound = polar and not (starts[0] or starts[1])
    if bound and polar_step_clear(ws, tb - tau, cond, sign, check_slip, spin):
        return SCAN_NONE
    grid, S, dS, hv, hd, row, drow = scan
    if not _fill_grid(polar, tau, tb, n, pars, ws, grid, S, dS, row, drow):
        return SCAN_PYTHON
    if _step_may_have_event(grid, S, dS, n, sign, check_slip, spin, cond, hv, hd, starts):
        return SCAN_GRID
    return SCAN_NONE


# The adaptive slip steps' parts. m = (setup, pars, ws1, ws2, full, mid, scan):
# setup = (polar, mu_c, (tol, safety, min_factor, max_factor, h_max, min_step),
# scan_fraction, cond_limit); ws1 holds the full step's and the first half's propagator
# (at tau), ws2 the second half's (at the mid-point). c = (h, rejected, h_next, tries,
# warm, t_mid, cond1, cond2, n1, n2, need): the step the pair began with and the
# rejections before it, what the pair proposes next and its rejected tries (taken over
# by the next pair), a warm eigensolver start, the pair's mid-point, conditions and
# scan intervals, and the scan size a pair needs (STOP_GROW).


@jit_inline
def _pair(
    tau: float, y: np.ndarray, t_end: float, pars: np.ndarray, regime: int, m: tuple,
    c: tuple, y_new: np.ndarray,
) -> tuple:  # fmt: skip
    """One accepted pair of half steps from (tau, y) (the step doubling and control of
    ``solve_piecewise``), its end into ``y_new``."""
    setup, _, ws1, ws2, full, mid, scan = m
    polar, mu_c, control, scan_fraction, cond_limit = setup
    tol, safety, min_factor, max_factor, h_max, min_step = control
    _, rejected, h, tries, warm, t_mid, cond1, cond2, n1, n2, need = c
    rejected += tries  # the committed pair's
    stay = (h, rejected, h, 0, warm, t_mid, cond1, cond2, n1, n2, need)
    dout = scan[6]
    if warm:  # start the eigensolver from the last mid-point's eigenvalues
        for i in range(4):
            ws1[0][i] = ws2[0][i]
    cond1, omega1 = _prepare(polar, tau, y, pars, mu_c, ws1, warm)
    # Python uses the eigenbasis while cond2(V) <= cond_limit, and cond2 <= 4 cond1:
    # proceed only where Python surely uses it too
    if not 8.0 * cond1 <= cond_limit:
        return tau, STOP_PYTHON, stay
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
            return tau, STOP_PYTHON, stay
        _evaluate(polar, t_mid, t_next, pars, ws2, y_new, dout)
        err = doubling_error(full, y_new, y)
        if not math.isfinite(err):
            return tau, STOP_PYTHON, stay
        h_next, accept = next_step(step, err, tol, safety, min_factor, max_factor, min_step)
        if accept:
            break
        tries += 1
    n1 = scan_points(tau, t_mid, omega1, scan_fraction)
    n2 = scan_points(t_mid, t_next, omega2, scan_fraction)
    if n1 < 0 or n2 < 0:
        return tau, STOP_PYTHON, stay  # Python fails the run cleanly
    if max(n1, n2) >= scan[0].shape[0]:
        return tau, STOP_GROW, (h, rejected, h, 0, warm, t_mid, cond1, cond2, n1, n2,
                                max(n1, n2) + 1)  # fmt: skip
    return t_next, STOP_NONE, (h, rejected, h_next, tries, run_time(True), t_mid, cond1,
                               cond2, n1, n2, need)  # fmt: skip


@jit_inline
def _pair_precheck(
    tau: float, t_new: float, y: np.ndarray, y_new: np.ndarray, pars: np.ndarray,
    regime: int, m: tuple, c: tuple, starts: tuple[bool, bool, bool], band: float,
) -> int:  # fmt: skip
    """Both halves' pre-checks, the first against the event that began the segment."""
    polar, ws1, ws2, scan = m[0][0], m[2], m[3], m[6]
    t_mid, cond1, cond2, n1, n2 = c[5], c[6], c[7], c[8], c[9]
    first = slip_scan(polar, tau, t_mid, n1, pars, ws1, cond1, regime, starts, scan)
    if first != SCAN_NONE:
        return first
    later = (run_time(False), run_time(False), run_time(False))
    return slip_scan(polar, t_mid, t_new, n2, pars, ws2, cond2, regime, later, scan)


@jit_inline
def _pair_at(
    t: float, tau: float, t_new: float, y: np.ndarray, m: tuple, c: tuple, row: np.ndarray
) -> None:
    """The pair's state at t: the first half's closed form up to the mid-point, then
    the second's."""
    polar, pars, dout, t_mid = m[0][0], m[1], m[6][6], c[5]
    if t <= t_mid:
        _evaluate(polar, tau, t, pars, m[2], row, dout)
    else:
        _evaluate(polar, t_mid, t, pars, m[3], row, dout)


@jit_inline
def _pair_commit(y: np.ndarray, y_new: np.ndarray, regime: int, m: tuple) -> None:
    for i in range(4):
        y[i] = y_new[i]


# every pair that may hold an event goes to Python: no search, no rule, no restart
_adaptive_loop = event_loop(4, _pair, _pair_precheck, None, _pair_at, rotor_project,
                            _pair_commit, None, None, inline=True)  # fmt: skip


def adaptive_work(size: int) -> tuple:
    """``advance_contact_adaptive``'s work arrays, numpy's (allocated in Python: nothing
    to compile), with scan buffers of ``size``
    points: the two propagators, the full step's and the mid-point's states, the scan
    buffers, the loop's new state and sample row, and its (unused) event buffers."""
    return (
        workspace(), workspace(), np.empty(4), np.empty(4), scan_buffers(size),
        np.empty(4), np.empty(4), np.empty(2), np.empty(0), np.empty(0, dtype=np.int64),
        np.empty((0, 4)), np.empty((0, 2), dtype=np.int64),
    )  # fmt: skip


@jit_loop
def advance_contact_adaptive(
    polar: bool, tau: float, y: np.ndarray, h: float, t_end: float, regime: int,
    pars: np.ndarray, t_eval: np.ndarray, out_states: np.ndarray, out_regimes: np.ndarray,
    k: int, max_pairs: int, scan_fraction: float, cond_limit: float,
    starts: tuple[bool, bool, bool],
    control: tuple[float, float, float, float, float, float], work: tuple,
) -> tuple[float, int, int, int, float, int, int]:  # fmt: skip
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
    ``cond_limit`` analytic.py's ``CONTACT_SCAN_FRACTION`` and ``EIGVEC_COND_LIMIT``;
    ``work`` the work arrays (``adaptive_work``, whose scan buffers' size bounds the
    halves' scan grids).

    A pair is committed whole or not at all: if either half might hold an event
    (reason EVENT), needs Python (conditioning, scan size, non-finite states: EVENT or
    PYTHON), or needs a larger scan grid than ``work`` holds (GROW), the kernel
    returns *before* the pair, with the ``h`` it started the pair with, so Python's own
    adaptive loop recomputes that pair (its rejections included) exactly as it would
    have without the kernel. At most ``max_pairs`` pairs (LIMIT).

    ``y`` is updated in place, the samples ``t_eval[k:]`` the pairs cover written to
    ``out_states`` and ``out_regimes``. Returns ``(tau, k, steps, rejected, h, reason,
    need)``: ``rejected`` counts the rejected tries of the committed pairs only, ``h`` is
    the controller's proposed next step, ``need`` the scan size a GROW asks for.
    """
    setup = (polar, pars[P_MU] * friction_sign(regime), control, scan_fraction, cond_limit)
    ws1, ws2, full, mid, scan, y_new, row, found, ev_tau, ev_kind, ev_state, ev_regimes = work
    m = (setup, pars, ws1, ws2, full, mid, scan)
    c = (h, 0, h, 0, run_time(False), tau, 0.0, 0.0, 0, 0, 0)
    tau, _, k, pairs, reason, _, _, _, c = _adaptive_loop(
        tau, y, y_new, t_end, pars, regime, t_eval, out_states, out_regimes, k, max_pairs,
        starts, 0.0, found, ev_tau, ev_kind, ev_state, ev_regimes, PYTHON_LOCATES, row, m, c,
    )  # fmt: skip
    h, rejected, h_next, tries, need = c[0], c[1], c[2], c[3], c[10]
    if reason in (STOP_END, STOP_LIMIT):  # the last pair committed: its proposal
        h, rejected = h_next, rejected + tries
    return tau, k, 2 * pairs, rejected, h, reason, need

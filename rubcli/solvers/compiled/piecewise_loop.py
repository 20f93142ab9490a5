"""The analytic methods' fixed-step loop: their parts in the one compiled event loop
(``event_loop``) and its entry point ``advance_piecewise``.

It advances ``analytic`` (Cartesian linearisation) and ``analytic-polar`` through every
regime as ``analytic.PiecewiseStepper`` does in Python, advance for advance. A step of
the loop is, by regime:

- free flight: a chunk of the closed form (``piecewise._free_at``; on the general
  machine the linear propagator, ``propagators.prepare_free_flight``), which the flight
  takes no steps of: the flight is prepared once, where it begins (``_begin_flight``),
  and scanned chunk by chunk for the contact entry (intervals of 1/32 of the fastest
  period, ``FREE_FIRST_CHUNK`` of them in the first chunk, twice as many in each next,
  up to ``FREE_SCAN_CHUNK``), every chunk searched;
- slip: one linearised step of ``h`` (``propagators._prepare``); its pre-check
  (``contact.slip_scan``) clears the steps with no possible event, the others go to the
  event search;
- stick: one RK4 step of the rolling law (``piecewise.stick_prepare``); a pre-check
  like the slip step's (``_stick_may_have_event``) clears the steps with no possible
  event, the others go to the event search.

Events are located by the one event search, ``events.event_search`` compiled over the
propagator's ``ev`` function (``_locate_free``, ``_locate_stick``, ``_locate_contact``),
on the scan grid the Python stepper builds (``np.linspace`` element for element), and
applied by the rotor's rule (``roots.rotor_apply``); they are recorded in the caller's
buffers, and the stepper records them in the run (with the storm guard). What the loop
leaves to Python, before taking the step: an eigenbasis too ill-conditioned for the
kernel (LAPACK's eig and the ``expm`` fallback), a singular system, a scan finer than
``MAX_SCAN_POINTS`` or a non-finite state (the Python step fails the run with its
message). A step whose scan grid outgrows the buffers the loop was given returns too
(``STOP_GROW``), before it is taken: the loop allocates nothing.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numba.extending import register_jitable

from rubcli.model import (
    FREE,
    P_E,
    P_ETA,
    P_K,
    P_MU,
    P_NU,
    P_PHI0,
    STICK,
    STICK_EXIT_MARGIN,
    friction_sign,
    is_general_record,
    is_paper_record,
    stick_friction_record,
    stick_friction_value,
)
from rubcli.solvers.compiled.contact import SCAN_GRID, scan_buffers, scan_points, slip_scan
from rubcli.solvers.compiled.event_loop import LOOP_APPLIES, SCAN_NONE, STOP_NONE, event_loop

# the ev functions are passed as piecewise.<name>: a dispatcher bound to a global name of
# this module and passed as an argument makes numba refuse to cache the loop
from rubcli.solvers.compiled.jit import STOP_GROW, STOP_PYTHON, jit, jit_inline, jit_loop
from rubcli.solvers.compiled.piecewise import (
    _free_at,
    _free_prepare,
    contact_ev,
    free_ev,
    free_omega_max,
    stick_at,
    stick_ev,
    stick_omega_max,
    stick_prepare,
)
from rubcli.solvers.compiled.precheck import _may_cross_relative, _surface_may_cross
from rubcli.solvers.compiled.propagators import (
    _evaluate,
    _prepare,
    prepare_free_flight,
    workspace,
)
from rubcli.solvers.compiled.roots import rotor_apply, rotor_project
from rubcli.solvers.events import event_search, linspace_into, run_time

# The one event search (events.event_search), compiled over each kind of segment
_locate_free, _ = event_search(free_ev, compile=jit)
_locate_stick, _ = event_search(stick_ev, compile=jit)
_locate_contact, _ = event_search(contact_ev, compile=jit)

# counts[] entries, and the run.stats key each adds to
C_STEPS, C_FREE, C_CONTACT, C_STICK, C_COMPILED = 0, 1, 2, 3, 4
N_COUNTS = 5
PIECEWISE_COUNTS = {
    "nsteps": C_STEPS,
    "n_free_segments": C_FREE,
    "n_contact_steps": C_CONTACT,
    "n_stick_steps": C_STICK,
    "n_compiled_steps": C_COMPILED,
}

# The parts. m = (setup, pars, ws, flight, stick, scan, counts): setup = (polar,
# general, h, free scan fraction, contact scan fraction, first and largest free scan
# chunk in intervals, cond_limit); ws the slip step's propagator; flight = (ff, wf), the
# free flight in progress (``ff``: its start, ``_free_prepare``'s on the paper's machine,
# (tau0, state) on the general one, whose propagator is ``wf``; ``ff[5]``: the intervals
# of its next chunk); stick = (st, meta), the stick step (``stick_prepare``); scan
# (``contact.scan_buffers``); counts the stats (``PIECEWISE_COUNTS``). c = (last, spacing,
# cond, n, python, need): the regime of the call's last step (FREE before the first: a
# slip step starts its eigensolver from the last one's eigenvalues only after a slip
# step of its own regime), the free flight's scan spacing, the slip step's condition,
# the step's scan intervals, a free flight that needs Python, the scan size a step
# needs (STOP_GROW).


@jit_inline
def _step(
    tau: float, y: np.ndarray, t_end: float, pars: np.ndarray, regime: int, m: tuple,
    c: tuple, y_new: np.ndarray,
) -> tuple:  # fmt: skip
    """One step from (tau, y): a free flight's next chunk, a stick step or a slip step,
    its scan grid prepared (filled in stick), its end into ``y_new``."""
    setup, _, ws, flight, stick, scan, _ = m
    polar, general, h, _, contact_frac, _, largest_chunk, cond_limit = setup
    last, spacing, cond, n, python, need = c
    grid, S, row, drow = scan[0], scan[1], scan[5], scan[6]
    if regime == FREE:
        if python:
            return tau, STOP_PYTHON, c
        ff, wf = flight
        t_new = min(t_end, tau + ff[5] * spacing)
        n = max(1, math.ceil((t_new - tau) / spacing))
        if n >= grid.shape[0]:
            return tau, STOP_GROW, (last, spacing, cond, n, python, n + 1)
        ff[5] = min(2.0 * ff[5], largest_chunk)
        linspace_into(grid, tau, t_new, n)
        _flight_at(general, t_new, ff, pars, wf, y_new, drow)
        return t_new, STOP_NONE, (FREE, spacing, cond, n, python, need)
    t_new = min(t_end, tau + h)
    if regime == STICK:
        st, meta = stick
        stick_prepare(tau, y, t_new - tau, pars, st, meta)
        n = scan_points(tau, t_new, stick_omega_max(pars), contact_frac)
        if n < 0:
            return tau, STOP_PYTHON, c
        if n >= grid.shape[0]:
            return tau, STOP_GROW, (last, spacing, cond, n, python, n + 1)
        linspace_into(grid, tau, t_new, n)
        finite = True
        for i in range(n + 1):
            stick_at(grid[i], st, meta, row)
            for j in range(4):
                S[i, j] = row[j]
                finite = finite and math.isfinite(row[j])
        if not finite:
            return tau, STOP_PYTHON, c
        for j in range(4):
            y_new[j] = S[n, j]
        return t_new, STOP_NONE, (STICK, spacing, cond, n, python, need)
    mu_c = pars[P_MU] * friction_sign(regime)
    cond, omega = _prepare(polar, tau, y, pars, mu_c, ws, last == regime)
    # Python uses the eigenbasis while cond2(V) <= cond_limit, and cond2 <= 4 cond1:
    # proceed only where Python surely uses it too
    if not 8.0 * cond <= cond_limit:
        return tau, STOP_PYTHON, c
    n = scan_points(tau, t_new, omega, contact_frac)
    if n < 0:
        return tau, STOP_PYTHON, c
    if n >= grid.shape[0]:
        return tau, STOP_GROW, (last, spacing, cond, n, python, n + 1)
    _evaluate(polar, tau, t_new, pars, ws, y_new, drow)
    return t_new, STOP_NONE, (regime, spacing, cond, n, python, need)


@jit_inline
def _precheck(
    tau: float, t_new: float, y: np.ndarray, y_new: np.ndarray, pars: np.ndarray,
    regime: int, m: tuple, c: tuple, starts: tuple[bool, bool, bool], band: float,
) -> int:  # fmt: skip
    """Every free-flight chunk is searched; a stick or slip step where an event may lie."""
    if regime == FREE:
        return SCAN_GRID
    n = c[3]
    scan = m[5]
    if regime == STICK:
        grid, S, W, hv, hd, row = scan[0], scan[1], scan[2], scan[3], scan[4], scan[5]
        st, meta = m[4]
        if _stick_may_have_event(grid, n, st, meta, pars, S, W, hv, hd, row, starts[0]):
            return SCAN_GRID
        return SCAN_NONE
    return slip_scan(m[0][0], tau, t_new, n, pars, m[2], c[2], regime, starts, scan)


@jit_inline
def _locate(
    tau: float, t_new: float, y: np.ndarray, pars: np.ndarray, regime: int, m: tuple,
    c: tuple, scan: int, starts: tuple[bool, bool, bool], band: float,
) -> tuple[float, int]:  # fmt: skip
    """The earliest event on the step's scan grid."""
    polar, general = m[0][0], m[0][1]
    grid, _, _, hv, hd, row, drow = m[5]
    n = c[3]
    if regime == FREE:
        ff, wf = m[3]
        if general:  # the Cartesian propagator's ctx, its flag a run-time bool as the slip's
            linear = (run_time(False), ff[0], pars, wf)
            return _locate_contact(linear, regime, pars, grid, n, starts, band, hv, hd, row, drow)
        return _locate_free((ff, pars), regime, pars, grid, n, starts, band, hv, hd, row, drow)
    if regime == STICK:
        st, meta = m[4]
        ctx = (st, meta, pars)
        return _locate_stick(ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow)
    ctx = (polar, tau, pars, m[2])
    return _locate_contact(ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow)


@jit_inline
def _state_at(
    t: float, tau: float, t_new: float, y: np.ndarray, m: tuple, c: tuple, row: np.ndarray
) -> None:
    """The step's state at t, from the closed form of the step's regime (``c[0]``)."""
    polar, general = m[0][0], m[0][1]
    pars, drow = m[1], m[5][6]
    if c[0] == FREE:
        ff, wf = m[3]
        _flight_at(general, t, ff, pars, wf, row, drow)
    elif c[0] == STICK:
        st, meta = m[4]
        stick_at(t, st, meta, row)
    else:
        _evaluate(polar, tau, t, pars, m[2], row, drow)


@jit_inline
def _count(regime: int, counts: np.ndarray) -> None:
    """A stick or slip step taken (a free flight counts once, where it begins)."""
    if regime != FREE:
        counts[C_STEPS] += 1
        counts[C_STICK if regime == STICK else C_CONTACT] += 1
        counts[C_COMPILED] += 1


@jit_inline
def _commit(y: np.ndarray, y_new: np.ndarray, regime: int, m: tuple) -> None:
    for i in range(4):
        y[i] = y_new[i]
    _count(regime, m[6])


@jit_inline
def _apply(
    kind: int, t: float, s: np.ndarray, regime: int, pars: np.ndarray, m: tuple,
    events_tau: np.ndarray, events_kind: np.ndarray, events_state: np.ndarray,
    events_regimes: np.ndarray, n_events: int, y: np.ndarray,
) -> tuple[int, int]:  # fmt: skip
    """The step up to its event counted, and the rotor's rule (``roots.rotor_apply``)."""
    _count(regime, m[6])
    return rotor_apply(kind, t, s, regime, pars, m, events_tau, events_kind, events_state,
                       events_regimes, n_events, y)  # fmt: skip


@jit_inline
def _begin_flight(
    tau: float, y: np.ndarray, pars: np.ndarray, m: tuple, c: tuple, new: bool
) -> tuple:  # fmt: skip
    """The free flight from (tau, y) prepared (``new``; counted as one step), or the one
    in progress (``ff``) taken up again: its scan spacing into ``c``, or a flight that
    needs Python (an eigenbasis too ill-conditioned for the kernel)."""
    _, general, _, free_frac, _, first_chunk, _, cond_limit = m[0]
    ff, wf = m[3]
    if new:
        if general:  # its start, from which prepare_free_flight solves it
            ff[0] = tau
            for j in range(4):
                ff[1 + j] = y[j]
        else:
            _free_prepare(tau, y, pars, ff)
        ff[5] = first_chunk
    if general:  # the exact linear flight (analytic.LinearFreeFlight)
        cond, omega = prepare_free_flight(ff[0], ff[1:5], pars, wf, run_time(False))
        if not 8.0 * cond <= cond_limit:  # Python's eig (or expm) takes it
            return c[0], c[1], c[2], c[3], run_time(True), c[5]
    else:
        omega = free_omega_max(pars)
    if new:
        counts = m[6]
        counts[C_FREE] += 1
        counts[C_STEPS] += 1
    spacing = free_frac * 2.0 * math.pi / max(omega, 1e-300)
    return c[0], spacing, c[2], c[3], run_time(False), c[5]


@jit_inline
def _restart(
    tau: float, y: np.ndarray, t_end: float, pars: np.ndarray, regime: int, m: tuple,
    c: tuple,
) -> tuple:  # fmt: skip
    """After an event: a free flight begins there."""
    if regime == FREE:
        return _begin_flight(tau, y, pars, m, c, run_time(True))
    return c


_loop = event_loop(4, _step, _precheck, _locate, _state_at, rotor_project, _commit, _restart,
                   _apply, inline=True)  # fmt: skip


def piecewise_work(size: int) -> tuple:
    """``advance_piecewise``'s work arrays, numpy's (allocated in Python: nothing to
    compile), with scan buffers of ``size`` points: the slip step's and the general free
    flight's propagators, the stick step, the scan buffers (``contact.scan_buffers``),
    and the loop's new state, sample row and event."""
    return (
        workspace(), workspace(), (np.empty((4, 4)), np.empty(2)), scan_buffers(size),
        np.empty(4), np.empty(4), np.empty(2),
    )  # fmt: skip


@jit_loop
def advance_piecewise(
    polar: bool, tau: float, state: np.ndarray, h: float, t_end: float, regime: int,
    starts: tuple[bool, bool, bool], pars: np.ndarray, t_eval: np.ndarray,
    out_states: np.ndarray, out_regimes: np.ndarray, k: int, max_work: int,
    fractions: tuple[float, float, float, float], cond_limit: float, band: float,
    ff: np.ndarray, free_active: bool, work: tuple, ev_tau: np.ndarray, ev_kind: np.ndarray,
    ev_state: np.ndarray, ev_regimes: np.ndarray, counts: np.ndarray,
) -> tuple[float, int, int, int, bool, int, int]:  # fmt: skip
    """Advance the piecewise method from (tau, state) in ``regime`` (fixed steps ``h``).

    ``starts``: the segment's start flags (``events.start_flags`` of the event that
    began it); ``fractions`` = (free scan fraction, contact scan fraction, first and
    largest free scan chunk in intervals) (analytic.py's ``FREE_SCAN_FRACTION``,
    ``CONTACT_SCAN_FRACTION``, ``FREE_FIRST_CHUNK``, ``FREE_SCAN_CHUNK``);
    ``cond_limit`` = ``EIGVEC_COND_LIMIT``; ``band`` the restart band of the event search
    (``earliest_event``'s default, 1e-12). ``ff`` (6) holds the free flight in progress;
    with ``free_active`` the call takes it up (a free flight the previous call left)
    instead of starting a new one. ``work``: the work arrays (``piecewise_work``, whose
    scan buffers' size bounds the steps' scan grids). Samples
    ``t_eval[k:]`` go to ``out_states``/``out_regimes`` (stick samples projected onto
    rolling), events to ``ev_*``; ``counts`` (int64, ``N_COUNTS``) accumulates the
    stats. At most ``max_work`` steps and free-flight scan chunks.

    ``state`` is updated in place. Returns ``(tau, k, regime, n_events, at_event,
    reason, need)``: reason END, LIMIT (work limit; possibly inside a free flight, which
    the next call takes up), FULL (event buffers full, the state at the last event, its
    segment not begun), PYTHON or EVENT (the next step, from ``(tau, state)`` in
    ``regime``, needs Python) or GROW (the next step needs ``need`` scan points);
    ``at_event``: ``tau`` is the last event's time.
    """
    free_frac, contact_frac, first_chunk, largest_chunk = fractions
    setup = (
        polar, is_general_record(pars), h, free_frac, contact_frac, first_chunk,
        largest_chunk, cond_limit,
    )  # fmt: skip
    ws, wf, stick, scan, y_new, row, found = work
    m = (setup, pars, ws, (ff, wf), stick, scan, counts)
    c = (FREE, 0.0, 0.0, 0, run_time(False), 0)
    if regime == FREE:
        c = _begin_flight(tau, state, pars, m, c, not free_active)
    tau, _, k, _, reason, regime, n_events, at_event, c = _loop(
        tau, state, y_new, t_end, pars, regime, t_eval, out_states, out_regimes, k,
        max_work, starts, band, found, ev_tau, ev_kind, ev_state, ev_regimes, LOOP_APPLIES,
        row, m, c,
    )  # fmt: skip
    return tau, k, regime, n_events, at_event, reason, c[5]


@jit
def _flight_at(general, t, ff, pars, wf, row, drow):
    """The free flight in progress at t, into row: the paper machine's closed form
    (``ff``) or the general machine's linear propagator (``wf``, prepared at ff[0])."""
    if general:
        _evaluate(False, ff[0], t, pars, wf, row, drow)
    else:
        _free_at(t, ff, pars, row)


def _stick_fill_with(needed: Callable[..., float]) -> Callable[..., None]:
    """``_stick_may_have_event``'s work ``W`` with the needed friction ``needed(t, x, y,
    vx, vy, pars, c)`` (``c``: the record's nu, eta, E, phi0, read once): T and the cone
    on the grid and their rates by the search's central differences (compilable core)."""

    def fill(
        grid: np.ndarray, n: int, st: np.ndarray, meta: np.ndarray, pars: np.ndarray,
        S: np.ndarray, W: np.ndarray, row: np.ndarray,
    ) -> None:  # fmt: skip
        cone = pars[P_MU] * pars[P_K] * (1.0 + STICK_EXIT_MARGIN)
        d = 1e-6 * max(1.0, grid[n] - grid[0])
        c = (pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0])
        for i in range(n + 1):
            t = grid[i]
            x, y = S[i, 0], S[i, 1]
            W[i, 0] = needed(t, x, y, S[i, 2], S[i, 3], pars, c)
            W[i, 1] = cone * (math.hypot(x, y) - 1.0)
            stick_at(t + d, st, meta, row)
            up_T = needed(t + d, row[0], row[1], row[2], row[3], pars, c)
            up_L = cone * (math.hypot(row[0], row[1]) - 1.0)
            stick_at(t - d, st, meta, row)
            down_T = needed(t - d, row[0], row[1], row[2], row[3], pars, c)
            down_L = cone * (math.hypot(row[0], row[1]) - 1.0)
            W[i, 2] = (up_T - down_T) / (2.0 * d)
            W[i, 3] = (up_L - down_L) / (2.0 * d)

    return register_jitable(fill)


@register_jitable
def _paper_needed(t, x, y, vx, vy, pars, c):
    """The rolling force on the paper's machine at a constant speed."""
    return stick_friction_value(t, x, y, vx, vy, c[0], c[1], c[2], c[3])


@register_jitable
def _general_needed(t, x, y, vx, vy, pars, c):
    """The rolling force of any machine and speed."""
    return stick_friction_record(t, x, y, vx, vy, pars)


_paper_stick_fill = _stick_fill_with(_paper_needed)
_general_stick_fill = _stick_fill_with(_general_needed)


@jit
def _stick_may_have_event(grid, n, st, meta, pars, S, W, hv, hd, row, on_surface):
    """Whether the event search might find an event in a stick step (its states on the
    grid in ``S``): False only if it surely finds none, as ``precheck`` decides for a slip
    step (margins ``EVENT_MARGIN``, relative). The contact exit on the grid values; the
    stick exit on both sides of the friction cone, the margins ``sign T - mu K (z - 1)
    (1 + STICK_EXIT_MARGIN)`` (``events.stick_margin``) and their rates by the search's
    central differences, with the needed friction T and the cone evaluated once for both
    sides (half the work of the search's fill). ``W`` (n + 1, >= 4): work.
    """
    if _surface_may_cross(grid, S, n, -1.0, 1.0, hv, hd, on_surface):
        return True
    # the paper's machine at a constant speed has its own fill, with the paper's rolling
    # force only (a branch to the general machine's in each evaluation cost about 30 %)
    if is_paper_record(pars):
        _paper_stick_fill(grid, n, st, meta, pars, S, W, row)
    else:
        _general_stick_fill(grid, n, st, meta, pars, S, W, row)
    for sign in (1.0, -1.0):
        for i in range(n + 1):
            hv[i] = sign * W[i, 0] - W[i, 1]
            hd[i] = sign * W[i, 2] - W[i, 3]
        if _may_cross_relative(grid, hv, hd, n):
            return True
    return False

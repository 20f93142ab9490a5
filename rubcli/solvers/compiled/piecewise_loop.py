"""The compiled loop of the analytic methods (fixed steps): ``advance_piecewise``.

It advances ``analytic`` (Cartesian linearisation) and ``analytic-polar`` through every
regime as ``analytic.PiecewiseStepper`` does in Python, advance for advance:

- free flight: no steps; the closed form (``piecewise._free_at``; on the general machine
  the linear propagator, ``propagators.prepare_free_flight``) is scanned chunk by
  chunk for the contact entry (intervals of 1/32 of the fastest period, ``FREE_FIRST_CHUNK``
  of them in the first chunk, twice as many in each next, up to ``FREE_SCAN_CHUNK``);
- slip: one linearised step of ``h`` (``propagators._prepare``); the conservative
  pre-check (``precheck._step_may_have_event``) clears the steps with no possible event,
  the others go to the event search;
- stick: one RK4 step of the rolling law (``piecewise.stick_prepare``); a pre-check
  like the slip step's (``_stick_may_have_event``) clears the steps with no possible
  event, the others go to the event search.

Events are located by the one event search, ``events.event_search`` compiled over the
propagator's ``ev`` function (``_locate_free``, ``_locate_stick``, ``_locate_contact``),
on the scan grid the Python stepper builds (``np.linspace`` element for element), and
applied by ``events.switch_regime`` (``roots._apply_event``); they are
recorded in the caller's buffers, and the stepper records them in the run (with the
storm guard). What the loop leaves to Python, before taking the step: an eigenbasis
too ill-conditioned for the kernel (LAPACK's eig and the ``expm`` fallback), a singular
system, a scan finer than ``MAX_SCAN_POINTS`` or a non-finite state on the grid (the
Python step fails the run with its message).
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
    P_RP,
    STICK,
    STICK_EXIT_MARGIN,
    friction_sign,
    is_general_record,
    is_paper_record,
    rolling_velocity,
    stick_friction_record,
    stick_friction_value,
)
from rubcli.solvers.compiled.contact import (
    _clear_by_bound,
    _fill_grid,
    _scan_buffers,
    _scan_points,
)

# the ev functions are passed as piecewise.<name>: a dispatcher bound to a global name of
# this module and passed as an argument makes numba refuse to cache the loop
from rubcli.solvers.compiled.jit import STOP_END, STOP_FULL, STOP_LIMIT, STOP_PYTHON, jit
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
from rubcli.solvers.compiled.precheck import (
    _may_cross_relative,
    _step_may_have_event,
    _surface_may_cross,
)
from rubcli.solvers.compiled.propagators import (
    _evaluate,
    _prepare,
    _workspace,
    prepare_free_flight,
)
from rubcli.solvers.compiled.roots import apply_and_record
from rubcli.solvers.events import NO_EVENT, event_search, linspace_into, run_time, start_flags

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


@jit
def advance_piecewise(
    polar: bool, tau: float, state: np.ndarray, h: float, t_end: float, regime: int,
    last_kind: int, pars: np.ndarray, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_work: int, fractions: tuple[float, float, float, float],
    cond_limit: float, band: float, ff: np.ndarray, free_active: bool, ev_tau: np.ndarray,
    ev_kind: np.ndarray, ev_state: np.ndarray, ev_regimes: np.ndarray, counts: np.ndarray,
) -> tuple[float, int, int, int, int, bool, int]:  # fmt: skip
    """Advance the piecewise method from (tau, state) in ``regime`` (fixed steps ``h``).

    ``last_kind``: the event that began the segment (``NO_EVENT`` if none);
    ``fractions`` = (free scan fraction, contact scan fraction, first and largest free
    scan chunk in intervals) (analytic.py's ``FREE_SCAN_FRACTION``,
    ``CONTACT_SCAN_FRACTION``, ``FREE_FIRST_CHUNK``, ``FREE_SCAN_CHUNK``);
    ``cond_limit`` = ``EIGVEC_COND_LIMIT``; ``band`` the restart band of the event search
    (``earliest_event``'s default, 1e-12). ``ff`` holds the free flight in progress
    (``_free_prepare``; ``ff[5]``: the intervals of its next scan chunk); with
    ``free_active`` the call continues it (a free flight the previous call left at its
    work limit) instead of starting a new one. Samples ``t_eval[k:]`` go to
    ``out_states``/``out_regimes`` (stick samples projected onto rolling), events to
    ``ev_*``; ``counts`` (int64, ``N_COUNTS``) accumulates the stats. At most ``max_work``
    steps and free-flight scan chunks.

    ``state`` is updated in place. Returns ``(tau, regime, last_kind, k, n_events,
    free_active, reason)``: reason END, LIMIT (work limit; possibly inside a free
    flight, then ``free_active``), FULL (event buffers full, the state at the last
    event) or PYTHON (the next step, from ``(tau, state)`` in ``regime``, needs Python).
    """
    free_frac, contact_frac, first_chunk, free_chunk = fractions
    capacity = ev_tau.shape[0]
    n_out = t_eval.shape[0]
    spin = pars[P_RP] * pars[P_ETA]
    check_slip = pars[P_MU] > 0.0
    ws = _workspace()
    general = is_general_record(pars)  # the free flight is then the linear propagator's
    wf = _workspace() if general else ws  # (unused on the paper's machine)
    st = np.empty((4, 4))
    meta = np.empty(2)
    row = np.empty(4)
    drow = np.empty(4)
    end = np.empty(4)
    size = 2
    grid, S, dS, hv, hd = _scan_buffers(run_time(size))
    work = 0
    n_events = 0
    warm = False  # the eigensolver may start from the last slip step's eigenvalues
    while True:
        if tau >= t_end:
            return tau, regime, last_kind, k, n_events, free_active, STOP_END
        if work >= max_work:
            return tau, regime, last_kind, k, n_events, free_active, STOP_LIMIT
        starts = start_flags(last_kind)
        kind = NO_EVENT
        if regime == FREE:
            warm = False
            if not free_active:  # a new free flight (PiecewiseStepper._free_flight)
                if general:  # its start, from which prepare_free_flight solves it
                    ff[0] = tau
                    for j in range(4):
                        ff[1 + j] = state[j]
                else:
                    _free_prepare(tau, state, pars, ff)
                ff[5] = first_chunk  # the next chunk's intervals
                counts[C_FREE] += 1
                counts[C_STEPS] += 1
                free_active = True
            if general:  # the exact linear flight (analytic.LinearFreeFlight)
                cond, omega = prepare_free_flight(ff[0], ff[1:5], pars, wf, run_time(False))
                if not 8.0 * cond <= cond_limit:  # Python's eig (or expm) takes it
                    return tau, regime, last_kind, k, n_events, False, STOP_PYTHON
            else:
                omega = free_omega_max(pars)
            spacing = free_frac * 2.0 * math.pi / max(omega, 1e-300)
            tb = tau
            ctx = (ff, pars)
            # the Cartesian propagator's ctx, its flag through run_time: a literal False
            # would compile the contact search a second time (beside the slip's bool)
            linear = (run_time(False), ff[0], pars, wf)
            while tb < t_end and work < max_work:
                ta = tb
                tb = min(t_end, tb + ff[5] * spacing)
                ff[5] = min(2.0 * ff[5], free_chunk)
                n = max(1, math.ceil((tb - ta) / spacing))
                if size < n + 1:
                    size = n + 1
                    grid, S, dS, hv, hd = _scan_buffers(run_time(size))
                linspace_into(grid, ta, tb, n)
                if general:
                    t_ev, kind = _locate_contact(
                        linear, regime, pars, grid, n, starts, band, hv, hd, row, drow
                    )
                else:
                    t_ev, kind = _locate_free(
                        ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow
                    )
                work += 1
                starts = start_flags(NO_EVENT)
                last_kind = NO_EVENT
                t_stop = t_ev if kind != NO_EVENT else tb
                while k < n_out and t_eval[k] <= t_stop:
                    _flight_at(general, t_eval[k], ff, pars, wf, row, drow)
                    for j in range(4):
                        out_states[k, j] = row[j]
                    out_regimes[k] = regime
                    k += 1
                if kind != NO_EVENT:
                    break
            if kind == NO_EVENT:  # the end, or the work limit inside the free flight
                _flight_at(general, tb, ff, pars, wf, row, drow)
                for j in range(4):
                    state[j] = row[j]
                tau = tb
                continue
            free_active = False
            _flight_at(general, t_ev, ff, pars, wf, row, drow)
        elif regime == STICK:
            warm = False
            tb = min(t_end, tau + h)
            stick_prepare(tau, state, tb - tau, pars, st, meta)
            n = _scan_points(tau, tb, stick_omega_max(pars), contact_frac)
            if n < 0:
                return tau, regime, last_kind, k, n_events, free_active, STOP_PYTHON
            if size < n + 1:
                size = n + 1
                grid, S, dS, hv, hd = _scan_buffers(run_time(size))
            linspace_into(grid, tau, tb, n)
            finite = True
            for i in range(n + 1):
                stick_at(grid[i], st, meta, row)
                for j in range(4):
                    S[i, j] = row[j]
                    finite = finite and math.isfinite(row[j])
            if not finite:
                return tau, regime, last_kind, k, n_events, free_active, STOP_PYTHON
            if _stick_may_have_event(grid, n, st, meta, pars, S, dS, hv, hd, row, starts[0]):
                ctx = (st, meta, pars)
                t_ev, kind = _locate_stick(
                    ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow
                )
            counts[C_STEPS] += 1
            counts[C_STICK] += 1
            counts[C_COMPILED] += 1
            work += 1
            last_kind = NO_EVENT
            t_stop = t_ev if kind != NO_EVENT else tb
            while k < n_out and t_eval[k] <= t_stop:
                stick_at(t_eval[k], st, meta, row)
                row[2], row[3] = rolling_velocity(row[0], row[1], row[2], row[3], spin)
                for j in range(4):
                    out_states[k, j] = row[j]
                out_regimes[k] = regime
                k += 1
            if kind == NO_EVENT:
                stick_at(tb, st, meta, row)
                for j in range(4):
                    state[j] = row[j]
                tau = tb
                continue
            stick_at(t_ev, st, meta, row)
        else:  # slip: one linearised contact step
            tb = min(t_end, tau + h)
            mu_c = pars[P_MU] * friction_sign(regime)
            cond, omega = _prepare(polar, tau, state, pars, mu_c, ws, run_time(warm))
            # Python uses the eigenbasis while cond2(V) <= cond_limit, and cond2 <= 4
            # cond1: proceed only where Python surely uses it too
            if not 8.0 * cond <= cond_limit:
                return tau, regime, last_kind, k, n_events, free_active, STOP_PYTHON
            n = _scan_points(tau, tb, omega, contact_frac)
            if n < 0:
                return tau, regime, last_kind, k, n_events, free_active, STOP_PYTHON
            sign = float(regime)
            event_args = (sign, check_slip, spin, starts)
            # the end state (into end): from the mode bounds alone, or the grid's last point
            if not _clear_by_bound(polar, tau, tb, pars, ws, cond, event_args, end, drow):
                if size < n + 1:
                    size = n + 1
                    grid, S, dS, hv, hd = _scan_buffers(run_time(size))
                if not _fill_grid(polar, tau, tb, n, pars, ws, grid, S, dS, row, drow):
                    return tau, regime, last_kind, k, n_events, free_active, STOP_PYTHON
                if _step_may_have_event(
                    grid, S, dS, n, sign, check_slip, spin, cond, hv, hd, starts
                ):
                    ctx = (polar, tau, pars, ws)
                    t_ev, kind = _locate_contact(
                        ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow
                    )
                for j in range(4):
                    end[j] = S[n, j]
            warm = True
            counts[C_STEPS] += 1
            counts[C_CONTACT] += 1
            counts[C_COMPILED] += 1
            work += 1
            last_kind = NO_EVENT
            t_stop = t_ev if kind != NO_EVENT else tb
            while k < n_out and t_eval[k] <= t_stop:
                _evaluate(polar, tau, t_eval[k], pars, ws, row, drow)
                for j in range(4):
                    out_states[k, j] = row[j]
                out_regimes[k] = regime
                k += 1
            if kind == NO_EVENT:
                for j in range(4):
                    state[j] = end[j]
                tau = tb
                continue
            _evaluate(polar, tau, t_ev, pars, ws, row, drow)
        # the event located at t_ev, the state there in row: apply and record it
        regime_before = regime
        recorded = run_time(n_events)
        regime, last_kind = apply_and_record(
            kind, t_ev, row, regime, pars, ev_tau, ev_kind, ev_state, ev_regimes, recorded, state
        )
        n_events += 1
        tau = t_ev
        if regime != regime_before:
            warm = False
        if n_events == capacity:
            return tau, regime, last_kind, k, n_events, free_active, STOP_FULL


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

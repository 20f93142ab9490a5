"""The compiled DOP853 loop with its events: ``advance_dop853`` (``dop853-jit``)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rubcli.model import (
    rolling_velocity,
)
from rubcli.solvers.compiled.dop853 import (
    DOP_A,
    DOP_SCAN_POINTS,
    DOP_STAGES,
    _dop853_accepted_step,
    _dop853_dense_at,
    _dop853_dense_coefficients,
    _paper_accepted_step,
    _paper_dense_coefficients,
    dop853_initial_step,
)
from rubcli.solvers.compiled.jit import (
    STOP_END,
    STOP_EVENT,
    STOP_FULL,
    STOP_LIMIT,
    STOP_PYTHON,
    STOP_SMALL_STEP,
    jit,
)
from rubcli.solvers.compiled.rhs import (
    _rhs_into,
)
from rubcli.solvers.compiled.roots import (
    STICK_REGIME,
    _dop853_locate,
    _dop853_may_have_event,
    _paper_may_have_event,
    apply_and_record,
)
from rubcli.solvers.events import run_time, spin_at, start_flags


def _dop853_loop(accepted_step: Callable[..., tuple], dense_coefficients: Callable[..., int],
                 may_have_event: Callable[..., bool]) -> Callable[..., tuple]:  # fmt: skip
    """The loop of ``advance_dop853`` on a DOP853 step and a pre-check built for one
    right-hand side (``dop853.dop853_step``, ``roots.dop853_precheck``), compiled."""

    def advance(
        tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float,
        pars: np.ndarray, regime: int, rtol: float, atol: float, t_eval: np.ndarray,
        out_states: np.ndarray, out_regimes: np.ndarray, k: int, max_steps: int,
        starts: tuple[bool, bool, bool], y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray,
        band: float, events_tau: np.ndarray, events_kind: np.ndarray,
        events_state: np.ndarray, events_regimes: np.ndarray, compiled_events: bool,
    ) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
        """``advance_dop853`` on the step's right-hand side."""
        Kst = np.empty((DOP_A.shape[0], 4))
        tmp = np.empty(4)
        row = np.empty(4)
        drow = np.empty(4)
        n = DOP_SCAN_POINTS
        grid = np.empty(n + 1)
        S = np.empty((n + 1, 4))
        dS = np.empty((n + 1, 4))
        hv = np.empty(n + 1)
        hd = np.empty(n + 1)
        n_out = t_eval.shape[0]
        capacity = events_tau.shape[0]
        steps = 0
        nfev = 0
        n_events = 0
        while True:
            at_event = starts[0] or starts[1]
            if tau >= t_end:
                return tau, tau, h_abs, k, steps, nfev, STOP_END, regime, n_events, at_event
            if steps >= max_steps:
                return tau, tau, h_abs, k, steps, nfev, STOP_LIMIT, regime, n_events, at_event
            t_new, h, h_abs, spent = accepted_step(
                tau, y, f, h_abs, t_end, pars, regime, rtol, atol, Kst, y_new, tmp
            )
            nfev += spent
            if h == 0.0:
                return tau, tau, h_abs, k, steps, nfev, STOP_SMALL_STEP, regime, n_events, at_event
            for i in range(4):
                f_new[i] = Kst[DOP_STAGES, i]
            nfev += dense_coefficients(tau, h, y, y_new, pars, regime, Kst, F, tmp)
            finite = True
            for i in range(4):
                finite = finite and math.isfinite(y_new[i])
            if not finite:
                return tau, t_new, h_abs, k, steps, nfev, STOP_PYTHON, regime, n_events, at_event
            kind = -1
            t_stop = t_new
            if may_have_event(tau, h, y, F, pars, regime, grid, S, dS, hv, hd, row, starts):
                if not compiled_events:
                    return tau, t_new, h_abs, k, steps, nfev, STOP_EVENT, regime, n_events, at_event
                t_ev, kind = _dop853_locate(
                    tau, h, y, F, pars, regime, grid, hv, hd, row, drow, starts, band
                )
                if kind >= 0:
                    t_stop = t_ev
            while k < n_out and t_eval[k] <= t_stop:
                _dop853_dense_at(t_eval[k], tau, h, y, F, row)
                if regime == STICK_REGIME:  # samples in stick are reported projected
                    row[2], row[3] = rolling_velocity(
                        row[0], row[1], row[2], row[3], spin_at(t_eval[k], pars)
                    )
                for i in range(4):
                    out_states[k, i] = row[i]
                out_regimes[k] = regime
                k += 1
            steps += 1
            if kind < 0:
                for i in range(4):
                    y[i] = y_new[i]
                    f[i] = f_new[i]
                tau = t_new
                starts = (False, False, True)
                continue
            # the event: events.apply_event, then a new segment as the driver starts one
            _dop853_dense_at(t_stop, tau, h, y, F, row)
            new_regime, kind = apply_and_record(
                kind, t_stop, row, regime, pars, events_tau, events_kind, events_state,
                events_regimes, run_time(n_events), y,
            )  # fmt: skip
            n_events += 1
            tau, regime = t_stop, new_regime
            starts = start_flags(kind)
            if n_events == capacity:
                return tau, tau, h_abs, k, steps, nfev, STOP_FULL, regime, n_events, True
            _rhs_into(tau, y, pars, regime, f)
            h_abs = dop853_initial_step(tau, y, f, t_end, pars, regime, rtol, atol)
            nfev += 2

    return jit(advance)


# the loop on any machine and speed, and on the paper's machine at a constant speed (its
# stages without the branch to the general machine's terms: ``rhs._rhs_paper_into``)
_advance_any = _dop853_loop(
    _dop853_accepted_step, _dop853_dense_coefficients, _dop853_may_have_event
)
_advance_paper = _dop853_loop(
    _paper_accepted_step, _paper_dense_coefficients, _paper_may_have_event
)


@jit
def advance_dop853(
    tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, pars: np.ndarray,
    regime: int, rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray, band: float, events_tau: np.ndarray,
    events_kind: np.ndarray, events_state: np.ndarray, events_regimes: np.ndarray,
    compiled_events: bool,
) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
    """Adaptive DOP853 steps with their events (scipy's algorithm, the scipy methods' events).

    Each step is scipy's DOP853 step exactly: the same tableau, error norm, step-size
    rule (safety 0.9, factors 0.2-10, no growth right after a rejection) and minimum
    step. After each accepted step its dense output goes through the conservative event
    pre-check (which treats the first step against the event that began the segment,
    ``starts``, as ``earliest_event`` does). A step where no event is possible is
    committed, and the samples ``t_eval[k:]`` it covers go to ``out_states`` and
    ``out_regimes`` (projected in stick). Otherwise:

    - with ``compiled_events``: the kernel runs ``events.earliest_event`` itself
      (``_dop853_locate``: ``events.event_search`` compiled on the dense output, ``band``
      the restart band) and, at an event, ``events.apply_event``
      (``_apply_event``), records it in ``events_*`` and starts the next segment as the
      Python driver would (new f, scipy's initial step);
    - without: the step is *not* committed; it is returned for Python, with ``y_new``,
      ``f_new`` and the dense coefficients ``F`` filled.

    ``y`` and ``f`` hold the last committed state. Returns ``(tau, t_new, h_abs, k,
    steps, nfev, reason, regime, n_events, at_event)``: reason END, LIMIT (``max_steps``
    steps), EVENT (a pending step from ``tau`` to ``t_new``), FULL (the event buffers
    are full; the state is at the last event, its segment not yet started), PYTHON (a
    non-finite state) or SMALL_STEP; ``at_event``: ``tau`` is the last event's time.

    Any machine and speed; ``advance_paper_dop853``, with the same arguments, is the
    paper's machine at a constant speed, whose stages are ``rhs._rhs_paper_into``'s (no
    branch to the general machine's terms). Two entry points, so that a run compiles only
    the loop it uses.
    """
    return _advance_any(
        tau, y, f, h_abs, t_end, pars, regime, rtol, atol, t_eval, out_states, out_regimes,
        k, max_steps, starts, y_new, f_new, F, band, events_tau, events_kind, events_state,
        events_regimes, compiled_events,
    )  # fmt: skip


@jit
def advance_paper_dop853(
    tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, pars: np.ndarray,
    regime: int, rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray, band: float, events_tau: np.ndarray,
    events_kind: np.ndarray, events_state: np.ndarray, events_regimes: np.ndarray,
    compiled_events: bool,
) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
    """``advance_dop853`` on the paper's machine at a constant speed (``pars`` must hold
    one: ``dop853_jit`` picks the entry)."""
    return _advance_paper(
        tau, y, f, h_abs, t_end, pars, regime, rtol, atol, t_eval, out_states, out_regimes,
        k, max_steps, starts, y_new, f_new, F, band, events_tau, events_kind, events_state,
        events_regimes, compiled_events,
    )  # fmt: skip

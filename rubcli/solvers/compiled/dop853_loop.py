"""``dop853-jit``'s parts in the one compiled event loop (``event_loop``): scipy's DOP853
step, its event pre-check and search on the step's dense output, and the entry points
``advance_dop853`` and ``advance_paper_dop853``."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

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
from rubcli.solvers.compiled.event_loop import (
    LOOP_APPLIES,
    PYTHON_LOCATES,
    SCAN_NONE,
    STOP_NONE,
    event_loop,
)
from rubcli.solvers.compiled.jit import STOP_SMALL_STEP, jit, jit_inline
from rubcli.solvers.compiled.rhs import (
    _rhs_into,
)
from rubcli.solvers.compiled.roots import (
    _dop853_locate,
    _dop853_may_have_event,
    _paper_may_have_event,
    rotor_apply,
    rotor_project,
)


def _dop853_loop(accepted_step: Callable[..., tuple], dense_coefficients: Callable[..., int],
                 may_have_event: Callable[..., bool]) -> Callable[..., tuple]:  # fmt: skip
    """``advance_dop853`` on a DOP853 step and a pre-check built for one right-hand side
    (``dop853.dop853_step``, ``roots.dop853_precheck``): their parts in the one event
    loop (``event_loop``), compiled. ``m = (f, f_new, F, Kst, tmp, grid, S, dS, hv, hd,
    drow, scratch)``, ``c = (h_abs, nfev, rtol, atol, h)``."""

    def step(
        tau: float, y: np.ndarray, t_end: float, pars: np.ndarray, regime: int, m: tuple,
        c: tuple, y_new: np.ndarray,
    ) -> tuple:  # fmt: skip
        f, f_new, F, Kst, tmp = m[0], m[1], m[2], m[3], m[4]
        h_abs, nfev, rtol, atol, _ = c
        t_new, h, h_abs, spent = accepted_step(
            tau, y, f, h_abs, t_end, pars, regime, rtol, atol, Kst, y_new, tmp
        )
        nfev += spent
        if h == 0.0:
            return tau, STOP_SMALL_STEP, (h_abs, nfev, rtol, atol, h)
        for i in range(4):
            f_new[i] = Kst[DOP_STAGES, i]
        nfev += dense_coefficients(tau, h, y, y_new, pars, regime, Kst, F, tmp)
        return t_new, STOP_NONE, (h_abs, nfev, rtol, atol, h)

    def precheck(
        tau: float, t_new: float, y: np.ndarray, y_new: np.ndarray, pars: np.ndarray,
        regime: int, m: tuple, c: tuple, starts: tuple[bool, bool, bool], band: float,
    ) -> int:  # fmt: skip
        F, grid, S, dS, hv, hd, scratch = m[2], m[5], m[6], m[7], m[8], m[9], m[11]
        if may_have_event(tau, c[4], y, F, pars, regime, grid, S, dS, hv, hd, scratch, starts):
            return 1
        return SCAN_NONE

    def locate(
        tau: float, t_new: float, y: np.ndarray, pars: np.ndarray, regime: int, m: tuple,
        c: tuple, scan: int, starts: tuple[bool, bool, bool], band: float,
    ) -> tuple[float, int]:  # fmt: skip
        F, grid, hv, hd, drow, scratch = m[2], m[5], m[8], m[9], m[10], m[11]
        return _dop853_locate(
            tau, c[4], y, F, pars, regime, grid, hv, hd, scratch, drow, starts, band
        )

    def dense_at(
        t: float, tau: float, t_new: float, y: np.ndarray, m: tuple, c: tuple, row: np.ndarray
    ) -> None:
        _dop853_dense_at(t, tau, c[4], y, m[2], row)

    def commit(y: np.ndarray, y_new: np.ndarray, regime: int, m: tuple) -> None:
        f, f_new = m[0], m[1]
        for i in range(4):
            y[i] = y_new[i]
            f[i] = f_new[i]

    def restart(
        tau: float, y: np.ndarray, t_end: float, pars: np.ndarray, regime: int, m: tuple,
        c: tuple,
    ) -> tuple:  # fmt: skip
        h_abs, nfev, rtol, atol, h = c
        f = m[0]
        _rhs_into(tau, y, pars, regime, f)
        h_abs = dop853_initial_step(tau, y, f, t_end, pars, regime, rtol, atol)
        return h_abs, nfev + 2, rtol, atol, h

    loop = event_loop(4, jit_inline(step), jit_inline(precheck), jit_inline(locate),
                      jit_inline(dense_at), rotor_project, jit_inline(commit),
                      jit_inline(restart), rotor_apply)  # fmt: skip

    def advance(
        tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float,
        pars: np.ndarray, regime: int, rtol: float, atol: float, t_eval: np.ndarray,
        out_states: np.ndarray, out_regimes: np.ndarray, k: int, max_steps: int,
        starts: tuple[bool, bool, bool], y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray,
        band: float, events_tau: np.ndarray, events_kind: np.ndarray,
        events_state: np.ndarray, events_regimes: np.ndarray, compiled_events: bool,
    ) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
        """``advance_dop853`` on the step's right-hand side."""
        n = DOP_SCAN_POINTS
        m = (
            f, f_new, F, np.empty((DOP_A.shape[0], 4)), np.empty(4), np.empty(n + 1),
            np.empty((n + 1, 4)), np.empty((n + 1, 4)), np.empty(n + 1), np.empty(n + 1),
            np.empty(4), np.empty(4),
        )  # fmt: skip
        tau, t_new, k, steps, reason, regime, n_events, at_event, c = loop(
            tau, y, y_new, t_end, pars, regime, t_eval, out_states, out_regimes, k,
            max_steps, starts, band, np.empty(2), events_tau, events_kind, events_state,
            events_regimes, LOOP_APPLIES if compiled_events else PYTHON_LOCATES, np.empty(4),
            m, (h_abs, 0, rtol, atol, 0.0),
        )  # fmt: skip
        return tau, t_new, c[0], k, steps, c[1], reason, regime, n_events, at_event

    # inlined into the entry point (advance_dop853, advance_paper_dop853)
    return jit_inline(advance)


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

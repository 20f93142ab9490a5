"""The compiled step-and-event loop, written once: ``event_loop`` builds it from a
method's parts, for every compiled method: ``dop853-jit`` (``dop853_loop``: scipy's
DOP853 step), ``taylor`` (``taylor``: the Taylor series) and the analytic methods
(``piecewise_loop``: a free flight's scan chunks and the linearised slip and RK4 stick
steps; ``contact``: the adaptive slip pairs) on the rotor, and ``dop853-jit`` and
``taylor`` on a system with more states (``extended_loop.step_loop``: the driven rotor,
the two bodies, ``orbits``' variational flow).

The loop owns what every method does the same: the budgets (the end time, the step
count, the event buffer's capacity), the check of the new state, the hand-back of a step
that may hold an event when Python locates the events, the samples a step covers
(projected onto the rolling constraint in stick, as Python reports them), the commit of
an event-free step, and at an event the samples up to it, its rule and record
(``roots.apply_and_record``: ``events.switch_regime``) and the start of the next segment
(``events.start_flags``). A method plugs in its step, its event pre-check, its event
search (``events.event_search`` compiled on its dense output), its dense output, what it
keeps of a committed step and how it restarts after an event; a system its projection
onto the rolling constraint and its event rule (the rotor's: ``roots.rotor_apply``; a
system's: ``extended_loop.step_loop``). A run that applies its own events (``orbits``'
flows) has the loop return at each event it locates, for Python.

The parts are inlined into the loop in numba IR, and the loop is compiled without
numba's reference counting (``jit.jit_loop``): a part that takes the method's arrays
binds them anew on every step, and with reference counting each binding is an atomic
increment and decrement that numba's pruning does not remove across the loop's blocks
(a tenth of a ``dop853-jit`` step). So the loop allocates nothing: its entry point
(``advance_dop853``, ``advance_taylor``, a system's ``advance``) allocates the method's
work arrays and calls it, or, built with ``inline``, is compiled as the loop is, with the
loop inlined and the work arrays from its caller (the analytic methods', whose scan grids
grow: the loop returns for larger arrays).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from rubcli.cached_jit import njit
from rubcli.solvers.compiled.jit import (
    STOP_END,
    STOP_EVENT,
    STOP_FULL,
    STOP_LIMIT,
    STOP_PYTHON,
    jit_inline,
    jit_loop,
)
from rubcli.solvers.compiled.roots import STICK_REGIME
from rubcli.solvers.events import run_time, start_flags

STOP_NONE = -1  # a plugged-in step's reason: it was taken
SCAN_NONE = 0  # a plugged-in pre-check's answer: no event can lie in the step
SCAN_PYTHON = -1  # a pre-check's answer: the step goes to Python whole, not searched
# who takes a step's events (the loop's ``events`` argument): Python locates and applies
# them (the loop hands the step back), the loop locates and Python applies (the loop
# returns at each), or the loop locates and applies them
PYTHON_LOCATES, PYTHON_APPLIES, LOOP_APPLIES = 0, 1, 2


def event_loop(
    n_states: int, step: Callable[..., tuple], precheck: Callable[..., int],
    locate: Callable[..., tuple] | None, dense_at: Callable[..., None],
    project: Callable[..., None], commit: Callable[..., None],
    restart: Callable[..., tuple] | None, apply: Callable[..., tuple] | None,
    inline: bool = False,
) -> Callable[..., tuple]:  # fmt: skip
    """The loop of one method on a system of ``n_states`` states (the first four the
    rotor's position and velocity), compiled with its parts (``jit_inline``; ``ctx`` the
    system's records, ``m`` the method's work arrays, ``c`` its scalars carried from step
    to step) as closure constants, as ``events.event_search`` is:

    - ``step(tau, y, t_end, ctx, regime, m, c, y_new) -> (t_new, reason, c)``: one
      accepted step from ``(tau, y)``, its end state into ``y_new``; ``reason``
      ``STOP_NONE``, or the stop code of a step that cannot be taken;
    - ``precheck(tau, t_new, y, y_new, ctx, regime, m, c, starts, band) -> scan``:
      SCAN_NONE only where the event search surely finds no event in the step,
      SCAN_PYTHON where the step goes to Python whole; else what the search must scan
      (the method's code);
    - ``locate(tau, t_new, y, ctx, regime, m, c, scan, starts, band) -> (tau, kind)``:
      the earliest event in the step (kind -1: none); None for a method whose runs all
      hand every step that may hold an event to Python (the analytic methods' adaptive
      slip steps): the loop does not compile the search;
    - ``dense_at(t, tau, t_new, y, m, c, row)``: the step's state at t into ``row``;
    - ``project(t, row, ctx)``: a state in stick onto the rolling constraint (samples in
      stick are reported projected);
    - ``commit(y, y_new, regime, m)``: the step committed (``y`` takes ``y_new``);
    - ``apply(kind, t, row, regime, ctx, m, events_tau, events_kind, events_state,
      events_regimes, n_events, y) -> (new regime, kind as recorded)``: the event's rule,
      its record as entry ``n_events`` and the state ``y`` the next segment starts from,
      and ``restart(tau, y, t_end, ctx, regime, m, c) -> c`` then begins that segment;
      None for a system whose runs all apply their own events (``orbits``' flows): the
      loop then returns at every event it locates, and does not compile the branch.

    The loop ``(tau, y, y_new, t_end, ctx, regime, t_eval, out_states, out_regimes, k,
    max_steps, starts, band, found, events_tau, events_kind, events_state,
    events_regimes, events, row, m, c)`` runs steps, each step's events sought where its
    pre-check says one may lie. A step without one is committed and fills the samples
    ``t_eval[k:]`` it covers. Unless Python locates the events (``events``
    PYTHON_LOCATES: the step is returned uncommitted, reason EVENT, ``y_new`` and ``m``
    holding it), the earliest event of a step is located and the samples up to it are
    filled; then it is applied and recorded in ``events_*`` and the next segment starts
    from it (LOOP_APPLIES), or the loop returns with it in ``found`` (PYTHON_APPLIES;
    ``found`` kind -1 when the loop returns for another reason). ``starts``: the current
    segment's (on the contact surface, on the slip surface, slip start immediate), as
    ``events.start_flags``.

    Returns ``(tau, t_new, k, steps, reason, regime, n_events, at_event, c)``: reason
    END, LIMIT (``max_steps`` steps), EVENT (a step from ``tau`` to ``t_new`` for Python:
    pending, or with its event in ``found``), FULL (the event buffers are full; the state
    is at the last event, its segment not yet started), PYTHON (a non-finite state) or
    the step's own; ``at_event``: ``tau`` is the last event's time.

    With ``inline`` the loop is built to be inlined into an entry point compiled as the
    loop is (``jit.jit_loop``), whose caller allocates the work arrays: numba generates
    each compiled function's code with its whole call tree, so an allocating entry that
    calls a loop compiled alone compiles the loop's call tree twice. The parts are then
    inlined into the entry after the loop, not into the loop (``_into_entry``): numba
    copies an inlined function's IR block by block, each block with the function's whole
    scope, so the loop is copied while it is small, and each part on its own.
    """
    N = n_states
    # closure constants: numba prunes the branches they decide
    python_locates = locate is None
    python_only = apply is None
    if inline:

        def into_entry(expr: Any, caller: Any, callee: Any) -> bool:
            return caller.func_id.func is not loop

        step, precheck, locate, dense_at, project, commit, restart, apply = (
            _into_entry(part, into_entry)
            for part in (step, precheck, locate, dense_at, project, commit, restart, apply)
        )

    def loop(
        tau: float, y: np.ndarray, y_new: np.ndarray, t_end: float, ctx: Any, regime: int,
        t_eval: np.ndarray, out_states: np.ndarray, out_regimes: np.ndarray, k: int,
        max_steps: int, starts: tuple[bool, bool, bool], band: float, found: np.ndarray,
        events_tau: np.ndarray, events_kind: np.ndarray, events_state: np.ndarray,
        events_regimes: np.ndarray, events: int, row: np.ndarray, m: tuple, c: tuple,
    ) -> tuple:  # fmt: skip
        n_out = t_eval.shape[0]
        capacity = events_tau.shape[0]
        steps = 0
        n_events = 0
        found[1] = -1.0
        while True:
            at_event = starts[0] or starts[1]
            if tau >= t_end:
                return tau, tau, k, steps, STOP_END, regime, n_events, at_event, c
            if steps >= max_steps:
                return tau, tau, k, steps, STOP_LIMIT, regime, n_events, at_event, c
            t_new, reason, c = step(tau, y, t_end, ctx, regime, m, c, y_new)
            if reason != STOP_NONE:
                return tau, t_new, k, steps, reason, regime, n_events, at_event, c
            finite = True
            for i in range(N):
                finite = finite and math.isfinite(y_new[i])
            if not finite:
                return tau, t_new, k, steps, STOP_PYTHON, regime, n_events, at_event, c
            kind = -1
            t_stop = t_new
            scan = precheck(tau, t_new, y, y_new, ctx, regime, m, c, starts, band)
            if scan != SCAN_NONE:
                if python_locates or scan == SCAN_PYTHON or events == PYTHON_LOCATES:
                    return tau, t_new, k, steps, STOP_EVENT, regime, n_events, at_event, c
                t_ev, kind = locate(tau, t_new, y, ctx, regime, m, c, scan, starts, band)
                if kind >= 0:
                    t_stop = t_ev
            while k < n_out and t_eval[k] <= t_stop:
                dense_at(t_eval[k], tau, t_new, y, m, c, row)
                if regime == STICK_REGIME:
                    project(t_eval[k], row, ctx)
                for i in range(N):
                    out_states[k, i] = row[i]
                out_regimes[k] = regime
                k += 1
            if kind < 0:
                steps += 1
                commit(y, y_new, regime, m)
                tau = t_new
                starts = (False, False, True)
                continue
            if python_only or events == PYTHON_APPLIES:
                found[0], found[1] = t_stop, float(kind)
                return tau, t_new, k, steps, STOP_EVENT, regime, n_events, at_event, c
            steps += 1
            dense_at(t_stop, tau, t_new, y, m, c, row)
            new_regime, kind = apply(
                kind, t_stop, row, regime, ctx, m, events_tau, events_kind, events_state,
                events_regimes, run_time(n_events), y,
            )  # fmt: skip
            n_events += 1
            tau, regime = t_stop, new_regime
            starts = start_flags(kind)
            if n_events == capacity:
                return tau, tau, k, steps, STOP_FULL, regime, n_events, True, c
            c = restart(tau, y, t_end, ctx, regime, m, c)

    return jit_inline(loop) if inline else jit_loop(loop)


def _into_entry(part: Any, where: Callable[..., bool]) -> Any:
    """A part (a ``jit_inline`` dispatcher, or None) inlined only where ``where(expr,
    caller IR, callee IR)`` allows (numba's inline cost model)."""
    if part is None:
        return None
    return njit(nogil=True, inline=where)(part.py_func)


@jit_inline
def no_restart(tau: float, y: np.ndarray, t_end: float, ctx: Any, regime: int, m: tuple,
               c: tuple) -> tuple:  # fmt: skip
    """The restart of a method that carries nothing from one segment to the next (a
    Taylor series starts from each step's own state)."""
    return c

"""The compiled DOP853 loop of a system with states beyond the rotor's four
(``solvers.extended``: the driven rotor, the stator with its own mass): scipy's DOP853
step on the system's states, a conservative pre-check of its events on each step's
scan grid, and the samples of the steps without one.

A system is its right-hand side ``into(row, ctx, regime, out) -> T`` (the derivatives
into ``out``, the rub's tangential force returned; ``ctx`` the system's records), its
projection onto the rolling constraint ``project(row, ctx)`` (in place) and its state
count. Its first four states are the rotor's position and velocity relative to the
stator's centre, the fifth and sixth the unbalance's phase and speed (so ``v_r = Rp
row[5] + (x vy - y vx) / z``, the events of every such system the same).

The events are located in the loop by the one event search (``events.event_search``,
compiled on the step's dense output with the surface speed ``Rp w`` a state and the
system's stick margin: ``system_search``), on each step the pre-check flags and on a
segment's first step, and applied in the loop by the rotor's rule
(``events.switch_rule``) with the system's stick friction and projection; or, for a run
that applies its own (``orbits``' flows), the loop returns at each for Python.

The loop is the one event loop (``event_loop.event_loop``, which the rotor's
``dop853-jit`` and ``taylor`` run too); ``step_loop`` plugs a system's parts into it:
the hand-back of a step that ends at a speed of 0 or below, the event pre-check on the
step's scan grid, the event search, and the samples' projection in stick. A method
plugs in its step and its dense output (``dop853_loop``: scipy's DOP853;
``driven_taylor`` and ``two_body_taylor``: the systems' Taylor series), inlined into
the loop in numba IR.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from rubcli.model import (
    P_K,
    P_MU,
    P_RP,
    STICK_EXIT_MARGIN,
    slip_velocity_rate,
    slip_velocity_value,
)
from rubcli.solvers.compiled.dop853 import (
    DOP_A,
    DOP_SCAN_POINTS,
    DOP_STAGES,
    _dop853_dense_at,
    dop853_step,
)
from rubcli.solvers.compiled.event_loop import (
    LOOP_APPLIES,
    PYTHON_APPLIES,
    SCAN_NONE,
    SCAN_PYTHON,
    STOP_NONE,
    event_loop,
)
from rubcli.solvers.compiled.jit import (
    STOP_SMALL_STEP,
    jit,
    jit_inline,
)
from rubcli.solvers.compiled.precheck import (
    EVENT_MARGIN,
    _may_cross,
    _may_cross_relative,
    _surface_may_cross,
)
from rubcli.solvers.compiled.roots import FREE_REGIME, STICK_REGIME
from rubcli.solvers.events import (
    ENTRY,
    EXIT,
    SPEED,
    event_search,
    linspace_into,
    run_time,
    switch_rule,
)


@functools.cache
def stick_law(into: Callable[..., float]) -> Callable[..., tuple[float, float]]:
    """The system's stick law at a state, compilable (inlined): ``law(row, ctx, out) ->
    (T, limit)``, T the friction that holds v_r = 0 (``into`` in stick; ``out`` work) and
    limit the cone's mu K (z - 1). The pre-check, the search's stick margin and the
    event's rule read it."""

    def law(row: np.ndarray, ctx: Any, out: np.ndarray) -> tuple[float, float]:
        pars = ctx[0]
        T = into(row, ctx, STICK_REGIME, out)
        return T, pars[P_MU] * pars[P_K] * (math.hypot(row[0], row[1]) - 1.0)

    return jit_inline(law)


def system_precheck(
    into: Callable[..., float], n_states: int, dense_at: Callable[..., None]
) -> Callable[..., bool]:
    """The event pre-check of a step of the system (``into``, ``n_states``: module
    docstring) on its dense output ``dense_at(t, dense, row)`` (``dense`` whatever it
    needs: a DOP853 step's coefficients, a Taylor polynomial), compiled with them as
    closure constants (as ``events.event_search``): ``may_have_event(dense, ctx, regime,
    grid, n, S, hv, hd, row, out)``.

    False only if the event search surely finds no event on the scan grid ``grid[:n +
    1]`` (``np.linspace`` of the step, as Python's): contact entry in free flight;
    contact exit, and the slip reversal or the stick exit, in contact. For a segment that
    has left the surface it began on (the loop searches a segment's first step
    whatever)."""
    N = n_states
    if N < 6:  # the stick pre-check keeps the stick law's six values in a state's row
        raise ValueError(f"a system of {N} states: the stick pre-check needs at least 6")
    law = stick_law(into)

    def slip_may_reverse(
        grid: np.ndarray, S: np.ndarray, ctx: Any, regime: int, n: int, hv: np.ndarray,
        hd: np.ndarray, row: np.ndarray, out: np.ndarray,
    ) -> bool:  # fmt: skip
        """The pre-check of the slip reversal, h = -sign v_r, and its rate from the
        accelerations (the spin's, ``Rp w'``, among them)."""
        Rp = ctx[0][P_RP]
        sign = float(regime)
        value_scale = 0.0
        rate_scale = 0.0
        for i in range(n + 1):
            for m in range(N):
                row[m] = S[i, m]
            into(row, ctx, regime, out)
            x, y, vx, vy, w = row[0], row[1], row[2], row[3], row[SPEED]
            hv[i] = -sign * slip_velocity_value(x, y, vx, vy, Rp * w)
            hd[i] = -sign * (slip_velocity_rate(x, y, vx, vy, out[2], out[3]) + Rp * out[SPEED])
            value_scale = max(value_scale, abs(Rp * w))
            rate_scale = max(rate_scale, abs(hd[i]))
        margin_v = EVENT_MARGIN * (1.0 + value_scale)
        margin_d = EVENT_MARGIN * (1.0 + rate_scale)
        return _may_cross(grid, hv, hd, n, margin_v, margin_d, run_time(False), run_time(True))

    def stick_may_exit(
        grid: np.ndarray, dense: Any, ctx: Any, n: int, S: np.ndarray, hv: np.ndarray,
        hd: np.ndarray, row: np.ndarray, out: np.ndarray,
    ) -> bool:  # fmt: skip
        """The pre-check of a stick exit on each side of the friction cone, ``sign T - mu
        K (z - 1) (1 + margin)`` (T the system's stick friction), its rate by central
        differences. T and the cone at each grid point and its two neighbours are
        evaluated once for both sides, into ``S``'s first six columns (free after the
        surface's pre-check; a system has at least six states)."""
        d = 1e-6 * max(1.0, grid[n] - grid[0])
        for i in range(n + 1):
            for j in range(3):
                t = grid[i] if j == 0 else (grid[i] + d if j == 1 else grid[i] - d)
                dense_at(t, dense, row)
                S[i, 2 * j], S[i, 2 * j + 1] = law(row, ctx, out)
        for sign in (1.0, -1.0):
            for i in range(n + 1):
                hv[i] = sign * S[i, 0] - S[i, 1] * (1.0 + STICK_EXIT_MARGIN)
                up = sign * S[i, 2] - S[i, 3] * (1.0 + STICK_EXIT_MARGIN)
                down = sign * S[i, 4] - S[i, 5] * (1.0 + STICK_EXIT_MARGIN)
                hd[i] = (up - down) / (2.0 * d)
            if _may_cross_relative(grid, hv, hd, n):
                return True
        return False

    def may_have_event(
        dense: Any, ctx: Any, regime: int, grid: np.ndarray, n: int, S: np.ndarray,
        hv: np.ndarray, hd: np.ndarray, row: np.ndarray, out: np.ndarray,
    ) -> bool:  # fmt: skip
        for k in range(n + 1):
            dense_at(grid[k], dense, row)
            for i in range(N):
                S[k, i] = row[i]
        direction = 1.0 if regime == FREE_REGIME else -1.0
        if _surface_may_cross(grid, S, n, direction, 1.0, hv, hd, run_time(False)):
            return True
        if regime == FREE_REGIME or ctx[0][P_MU] == 0.0:
            return False
        if regime == STICK_REGIME:
            return stick_may_exit(grid, dense, ctx, n, S, hv, hd, row, out)
        return slip_may_reverse(grid, S, ctx, regime, n, hv, hd, row, out)

    slip_may_reverse = jit(slip_may_reverse)
    stick_may_exit = jit(stick_may_exit)
    return jit(may_have_event)


@jit_inline
def keep_nothing(m: tuple) -> None:
    """``step_loop``'s commit of a method that keeps nothing of a step beyond its state
    (a Taylor series starts from each step's own state)."""


@functools.cache
def system_search(
    dense_at: Callable[..., None], into: Callable[..., float]
) -> Callable[..., tuple[float, int]]:
    """The event search (``events.event_search``, the one definition every path runs)
    on a step's dense output ``dense_at(t, dense, row)`` of the system ``into``,
    compiled: ``locate(ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow)``
    with ``ctx = (dense, the system's records, regime, out)``, ``out`` a work row of the
    system's states (the stick law's right-hand side). The surface speed is ``Rp w``,
    a state; the stick margin takes the system's stick friction. One per pair, so loops
    that share their dense output and their events' right-hand side (a system with and
    without its variational matrix) compile it once."""

    def ev(t: float, deriv: bool, ctx: Any, row: np.ndarray, drow: np.ndarray) -> None:
        dense_at(t, ctx[0], row)
        if deriv:
            into(row, ctx[1], ctx[2], drow)

    law = stick_law(into)

    def margin(ctx: Any, t: float, pars: np.ndarray, sign: float, row: np.ndarray) -> float:
        T, limit = law(row, ctx[1], ctx[3])
        return sign * T - limit * (1.0 + STICK_EXIT_MARGIN)

    return event_search(jit(ev), compile=jit, margin=jit(margin))[0]


def step_loop(
    step: Callable[..., tuple], intervals: Callable[..., int], commit: Callable[..., None],
    restart: Callable[..., tuple], dense: Callable[..., tuple], dense_at: Callable[..., None],
    into: Callable[..., float], project: Callable[..., None], n_states: int, max_scan: int,
    events_into: Callable[..., float] | None = None, loop_applies: bool = True,
) -> Callable[..., tuple]:  # fmt: skip
    """The one event loop (``event_loop``) of one method on one system (``into``,
    ``project``, ``n_states``: module docstring), compiled with the method's parts
    (``jit_inline``: ``m`` its work arrays, ``c`` its scalars carried from step to step)
    as closure constants:

    - ``step(tau, y, t_end, ctx, regime, m, c, y_new) -> (t_new, reason, c)``: one
      accepted step, its end state into ``y_new``; ``reason`` ``STOP_NONE``, or the stop
      code of a step that cannot be taken (SMALL_STEP, or PYTHON for a non-finite size);
    - ``dense(tau, y, m, c)``: what ``dense_at(t, dense, row)`` needs of the step taken
      (a DOP853 step's coefficients, a Taylor polynomial);
    - ``intervals(tau, t_new, y, y_new, ctx, regime, m, c) -> n``: the step's scan
      intervals (at most ``max_scan``);
    - ``commit(m)``: what the method keeps of a committed step beyond its state;
    - ``restart(tau, y, t_end, ctx, regime, m, c) -> c``: a segment begins at an event.

    ``events_into``: the right-hand side the pre-check and the event search evaluate
    (default ``into``): the first states' alone, where the system carries more that the
    events do not read (a variational matrix: ``compiled.variational``).
    ``loop_applies`` False: no run of the system has the loop apply its events (the
    variational systems), so the loop is compiled without that branch.

    ``advance(tau, y, t_end, ctx, regime, t_eval, out_states, out_regimes, k,
    max_steps, starts, band, found, y_new, events, applies, m, c) -> (tau, t_new, k,
    steps, reason, regime, n_events, at_event, c)``: the event loop's steps. Each step's events
    are sought (``system_search``) where the pre-check says one may lie, and on a
    segment's first step, begun on an event's surface (``starts``:
    ``events.start_flags``; ``band`` the restart band). A step without one, after which
    the speed is still positive, is committed, with its samples (in stick projected onto
    the rolling constraint). At an event, with ``applies``, the loop applies the
    system's rule (``events.switch_rule`` with the system's stick friction, and its
    projection) and records it in ``events`` (the event loop's four buffers, the state's
    of width up to ``n_states``); without (a run that applies its own: ``orbits``' flows,
    whose variational matrix jumps at each event), it returns with ``found = (tau,
    kind)`` of the event. A step that ends at a speed of 0 or
    below returns pending (``found`` kind -1); either leaves ``y_new`` and ``m`` holding
    the step (reason EVENT). Other reasons as the event loop's.
    """
    N = n_states
    rule_into = events_into or into
    may_have_event = system_precheck(rule_into, N, dense_at)
    search = system_search(dense_at, rule_into)
    law = stick_law(rule_into)

    def method_step(
        tau: float, y: np.ndarray, t_end: float, ctx: Any, regime: int, m: tuple, c: tuple,
        y_new: np.ndarray,
    ) -> tuple:  # fmt: skip
        return step(tau, y, t_end, ctx, regime, m[0], c, y_new)

    def precheck(
        tau: float, t_new: float, y: np.ndarray, y_new: np.ndarray, ctx: Any, regime: int,
        m: tuple, c: tuple, starts: tuple[bool, bool, bool], band: float,
    ) -> int:  # fmt: skip
        """The step's scan intervals where the search must run (always on a segment's
        first step); SCAN_PYTHON where the step ends at a speed of 0 or below."""
        grid, S, hv, hd, row, out = m[1][0], m[1][1], m[1][2], m[1][3], m[1][4], m[1][5]
        n = intervals(tau, t_new, y, y_new, ctx, regime, m[0], c)
        if y_new[SPEED] <= 0.0:
            return SCAN_PYTHON
        linspace_into(grid, tau, t_new, n)
        if starts[0] or starts[1]:
            return n
        if may_have_event(dense(tau, y, m[0], c), ctx, regime, grid, n, S, hv, hd, row, out):
            return n
        return SCAN_NONE

    def locate(
        tau: float, t_new: float, y: np.ndarray, ctx: Any, regime: int, m: tuple, c: tuple,
        scan: int, starts: tuple[bool, bool, bool], band: float,
    ) -> tuple[float, int]:  # fmt: skip
        grid, hv, hd, row, out, drow = m[1][0], m[1][2], m[1][3], m[1][4], m[1][5], m[1][6]
        return search((dense(tau, y, m[0], c), ctx, regime, out), regime, ctx[0], grid, scan,
                      starts, band, hv, hd, row, drow)  # fmt: skip

    def state_at(
        t: float, tau: float, t_new: float, y: np.ndarray, m: tuple, c: tuple, row: np.ndarray
    ) -> None:
        dense_at(t, dense(tau, y, m[0], c), row)

    def sample_project(t: float, row: np.ndarray, ctx: Any) -> None:
        project(row, ctx)

    def system_commit(y: np.ndarray, y_new: np.ndarray, regime: int, m: tuple) -> None:
        for i in range(N):
            y[i] = y_new[i]
        commit(m[0])

    def method_restart(
        tau: float, y: np.ndarray, t_end: float, ctx: Any, regime: int, m: tuple, c: tuple
    ) -> tuple:
        return restart(tau, y, t_end, ctx, regime, m[0], c)

    def apply(
        kind: int, t: float, row: np.ndarray, regime: int, ctx: Any, m: tuple,
        events_tau: np.ndarray, events_kind: np.ndarray, events_state: np.ndarray,
        events_regimes: np.ndarray, n_events: int, y: np.ndarray,
    ) -> tuple[int, int]:  # fmt: skip
        """The system's event: ``events.switch_rule`` with its stick friction, its
        projection where stick begins or ends, the record, and the state ``y`` from
        which the next segment starts."""
        pars = ctx[0]
        needed = limit = 0.0
        if kind != EXIT and kind != ENTRY:  # the rule reads the stick law
            needed, limit = law(row, ctx, m[1][5])
        new, recorded, to_project = switch_rule(
            kind, row[0], row[1], row[2], row[3], regime, pars[P_MU], pars[P_RP] * row[SPEED],
            needed, limit,
        )  # fmt: skip
        if to_project:
            project(row, ctx)
        events_tau[n_events] = t
        events_kind[n_events] = recorded
        events_regimes[n_events, 0] = regime
        events_regimes[n_events, 1] = new
        for i in range(events_state.shape[1]):
            events_state[n_events, i] = row[i]
        for i in range(N):
            y[i] = row[i]
        return new, recorded

    loop = event_loop(
        N, jit_inline(method_step), jit_inline(precheck), jit_inline(locate),
        jit_inline(state_at), jit_inline(sample_project), jit_inline(system_commit),
        jit_inline(method_restart) if loop_applies else None,
        jit_inline(apply) if loop_applies else None,
    )  # fmt: skip

    def advance(
        tau: float, y: np.ndarray, t_end: float, ctx: Any, regime: int, t_eval: np.ndarray,
        out_states: np.ndarray, out_regimes: np.ndarray, k: int, max_steps: int,
        starts: tuple[bool, bool, bool], band: float, found: np.ndarray, y_new: np.ndarray,
        events: tuple, applies: bool, m: tuple, c: tuple,
    ) -> tuple:  # fmt: skip
        work = (
            np.empty(max_scan + 1), np.empty((max_scan + 1, N)), np.empty(max_scan + 1),
            np.empty(max_scan + 1), np.empty(N), np.empty(N), np.empty(N),
        )  # fmt: skip
        return loop(
            tau, y, y_new, t_end, ctx, regime, t_eval, out_states, out_regimes, k,
            max_steps, starts, band, found, events[0], events[1], events[2], events[3],
            LOOP_APPLIES if applies else PYTHON_APPLIES, np.empty(N), (m, work), c,
        )  # fmt: skip

    # inlined into the method's entry point: one compiled function fewer per system
    return jit_inline(advance)


@jit
def _dop853_dense(t: float, dense: Any, row: np.ndarray) -> None:
    """A DOP853 step's dense output, dense = (t_old, h, y_old, F)."""
    _dop853_dense_at(t, dense[0], dense[1], dense[2], dense[3], row)


def dop853_loop(
    into: Callable[..., float], project: Callable[..., None], n_states: int,
    events_into: Callable[..., float] | None = None, loop_applies: bool = True,
) -> tuple[Callable[..., float], Callable[..., tuple]]:  # fmt: skip
    """scipy's DOP853 on the system (``into``, ``project``, ``n_states``: module
    docstring; ``events_into``, ``loop_applies``: ``step_loop``'s) in ``step_loop``,
    compiled once per system: ``(initial_step, advance)``, ``advance`` as below."""
    N = n_states

    def stage(t: float, y: np.ndarray, ctx: Any, regime: int, out: np.ndarray) -> None:
        into(y, ctx, regime, out)

    initial_step, accepted_step, dense_coefficients = dop853_step(jit(stage), N)

    def step(
        tau: float, y: np.ndarray, t_end: float, ctx: Any, regime: int, m: tuple, c: tuple,
        y_new: np.ndarray,
    ) -> tuple:  # fmt: skip
        f, f_new, F, Kst, tmp = m
        h_abs, nfev, rtol, atol, _ = c
        t_new, h, h_abs, spent = accepted_step(
            tau, y, f, h_abs, t_end, ctx, regime, rtol, atol, Kst, y_new, tmp
        )
        nfev += spent
        if h == 0.0:
            return tau, STOP_SMALL_STEP, (h_abs, nfev, rtol, atol, h)
        for i in range(N):
            f_new[i] = Kst[DOP_STAGES, i]
        nfev += dense_coefficients(tau, h, y, y_new, ctx, regime, Kst, F, tmp)
        return t_new, STOP_NONE, (h_abs, nfev, rtol, atol, h)

    def dense(tau: float, y: np.ndarray, m: tuple, c: tuple) -> tuple:
        """The step's dense output: (its start, its length, its start state, F)."""
        return tau, c[4], y, m[2]

    def intervals(
        tau: float, t_new: float, y: np.ndarray, y_new: np.ndarray, ctx: Any, regime: int,
        m: tuple, c: tuple,
    ) -> int:  # fmt: skip
        return DOP_SCAN_POINTS

    def commit(m: tuple) -> None:
        f, f_new = m[0], m[1]
        for i in range(N):
            f[i] = f_new[i]

    def restart(
        tau: float, y: np.ndarray, t_end: float, ctx: Any, regime: int, m: tuple, c: tuple
    ) -> tuple:
        """As scipy starts a solver: f and the initial step (two evaluations)."""
        h_abs, nfev, rtol, atol, h = c
        f = m[0]
        into(y, ctx, regime, f)
        h_abs = initial_step(tau, y, f, t_end, ctx, regime, rtol, atol)
        return h_abs, nfev + 2, rtol, atol, h

    loop = step_loop(jit_inline(step), jit_inline(intervals), jit_inline(commit),
                     jit_inline(restart), jit_inline(dense), _dop853_dense, into, project, N,
                     DOP_SCAN_POINTS, events_into, loop_applies)  # fmt: skip

    def advance(
        tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, ctx: Any,
        regime: int, rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
        out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
        band: float, found: np.ndarray, y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray,
        events: tuple, applies: bool,
    ) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
        """Adaptive DOP853 steps of the system with their events (``step_loop``'s
        advance), each scipy's DOP853 step. A step handed to Python leaves ``y_new``,
        ``f_new`` and the dense coefficients ``F`` filled. Returns ``(tau, t_new, h_abs,
        k, steps, nfev, reason, regime, n_events, at_event)``."""
        m = (f, f_new, F, np.empty((DOP_A.shape[0], N)), np.empty(N))
        tau, t_new, k, steps, reason, regime, n_events, at_event, c = loop(
            tau, y, t_end, ctx, regime, t_eval, out_states, out_regimes, k, max_steps,
            starts, band, found, y_new, events, applies, m, (h_abs, 0, rtol, atol, 0.0),
        )  # fmt: skip
        return tau, t_new, c[0], k, steps, c[1], reason, regime, n_events, at_event

    # inlined into the system's entry point (``compiled.drive``'s and the others')
    return initial_step, jit_inline(advance)

"""The event loop of a system with states beyond the rotor's four: the driven rotor
(``solvers.driven``, ``rubcli.drive``) and the stator with its own mass
(``solvers.two_body``, ``rubcli.stator``).

A system's state starts with the rotor's position and velocity relative to the stator's
centre and the unbalance's phase and speed, ``(x, y, vx, vy, p, w, ...)``: so the
contact (``z = |(x, y)|``), the slip ``v_r = Rp w + (x vy - y vx) / z`` and the events are
the same for every system, and a system is its right-hand side, its stick friction and
its projection onto the rolling constraint (``System``). A run is the driver's
(``driver.integrate``: budgets, storms, progress, failures) with the system's states
carried beside the rotor's (``ExtendedRun``) and the rules at an event (``switch``, on
the rotor's ``events.switch_rule``): contact entry takes the sign of v_r, a slip
reversal Filippov's rule with the system's stick friction, a stick exit the side the
needed friction points to. Stick begins and
ends with the velocities projected onto the rolling constraint along the kinetic
energy's metric (the system's ``project``).

``ExtendedStepper`` is one accepted scipy step per ``advance``: the regime's right-hand
side (compiled), the step's dense output scanned at ``SCAN_POINTS`` sub-intervals for
the regime's events by the rotor's own event search (``events.earliest_system_event``:
``events.event_search`` with the surface speed ``Rp w`` a state and the system's stick
friction in the stick margin ``s T - mu K (z - 1) (1 + margin)``), so every system and
the rotor switch on one definition of the event functions, the crossing rules (grazes
inside a scan interval, a segment begun on its surface, the restart band) and the Brent
iteration.

Implicit methods get forward differences of the right-hand side
(``ExtendedStepper._jacobian``).

``dop853-jit`` (``ExtendedJitStepper``) and ``taylor`` (``ExtendedTaylorStepper``, on the
driven rotor and the two bodies) run in the one compiled event loop
(``compiled.extended_loop.step_loop``), which locates the events with the same search
compiled and applies them with the same rule (``events.switch_rule``, the system's
stick law and projection compiled); a run whose ``switch`` does more (``orbits``'
flows: the variational matrix's jumps) has the loop return at each event instead.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import KIND_NAMES, Solution, SwitchEvent
from rubcli.solvers import compiled as kernels
from rubcli.solvers import driver
from rubcli.solvers.compiled.driven_taylor import polynomial_values
from rubcli.solvers.compiled.taylor import MAX_ORDER, taylor_order
from rubcli.solvers.events import (
    ENTRY,
    EXIT,
    NO_EVENT,
    SPEED,
    earliest_system_event,
    initial_kind,
    start_flags,
    switch_rule,
)
from rubcli.solvers.registry import SPECS
from rubcli.solvers.shared import (
    EVENT_BUFFER,
    SCAN_POINTS,
    Dop853Dense,
    OdeSolverStepper,
    kernel_failure,
)

Dense = Callable[[float], np.ndarray]  # a step's dense output (of one time, or of times)
CHUNK_STEPS = 2000  # committed steps per kernel call: budget and progress checks between


@dataclass(frozen=True)
class System:
    """A system with states beyond the rotor's four (module docstring): its state
    count, its right-hand side at one state ``rhs(s, *ctx, regime)`` and at the columns
    of states ``columns(S, *ctx, regime) -> (dS, T)`` (compiled, and the same run by the
    interpreter), its compiled DOP853 loop ``(initial_step, advance)``
    (``compiled.extended_loop.dop853_loop``) and its compiled Taylor loop (``taylor``;
    None for a system only ``dop853-jit`` runs: ``solvers.variational``'s)."""

    size: int
    rhs: Callable
    columns: Callable
    python_rhs: Callable
    python_columns: Callable
    loop: tuple[Callable, Callable]
    taylor: Callable | None


class ExtendedRun(driver.Run):
    """A driver run whose state is a system's (module docstring). A subclass gives the
    system, its records ``ctx`` and the initial state, the stick friction and the
    projection onto the rolling constraint, and the solution's extra states."""

    system: System
    # the compiled loops apply this run's events (False: a run whose ``switch`` does more
    # than the system's rule, and the loops return at each event for it)
    loop_applies_events = True

    def __init__(self, problem: Problem, method: str, ctx: tuple, state: np.ndarray,
                 locked: int | None = None, **budget) -> None:  # fmt: skip
        super().__init__(problem, method, **budget)
        self.ctx = ctx
        self.state = np.array(state, dtype=float)
        self.states = np.empty((self.t_eval.size, self.system.size))
        # locked: the run stays in this regime, with no event (the smooth extension of a
        # flow across its surfaces: ``analysis.orbits.periodic`` locates grazing with it)
        self.locked = locked
        self.regime = regime_of(self.state, self) if locked is None else int(locked)
        self.states[0], self.regimes[0] = self.state, self.regime
        # (at tau = 0 the system's speed is the start's: the constant-speed rule holds)
        self.last_kind = initial_kind(self.state[:4], self.regime, self.params, self.tau)

    def stick_friction(self, s: np.ndarray) -> float:
        """The friction T that holds v_r = 0 at the state ``s`` (the system's stick law)."""
        return float(self.system.columns(np.ascontiguousarray(s[:, None]), *self.ctx,
                                         model.STICK)[1][0])  # fmt: skip

    def project(self, s: np.ndarray) -> np.ndarray:
        """The state with v_r = 0 exactly, moved along the kinetic energy's metric."""
        raise NotImplementedError

    def record_events(
        self, n: int, taus: np.ndarray, kinds: np.ndarray, states: np.ndarray,
        regimes: np.ndarray,
    ) -> bool:  # fmt: skip
        """Record the ``n`` events a compiled loop applied (its buffers; ``states`` the
        system's states there, of which the rotor's four are recorded): False (and the
        run failed) on a switch storm (``driver.record_kernel_events``)."""
        return driver.record_kernel_events(self, n, taus, kinds, states[:, :4], regimes)

    def switch(self, tau: float, kind: int, state: np.ndarray) -> bool:
        """Apply and record the event ``kind`` at ``tau`` (module docstring); False (and
        the run failed) on a switch storm."""
        state = np.array(state, dtype=float)
        before = self.regime
        p = self.params
        needed = limit = 0.0
        if kind not in (EXIT, ENTRY):  # the rule reads the stick law
            needed = self.stick_friction(state)
            limit = p.mu * p.K * (math.hypot(state[0], state[1]) - 1.0)
        new, recorded, project = switch_rule(kind, *state[:4], before, p.mu,
                                             p.Rp * state[SPEED], needed, limit)  # fmt: skip
        if project:
            state = self.project(state)
        self.state, self.regime, self.last_kind, self.tau = state, new, recorded, tau
        event = SwitchEvent(tau, KIND_NAMES[recorded], tuple(state[:4]), before, new)
        return self.record(event)


def slip_velocity(S: np.ndarray, Rp: float) -> np.ndarray:
    """v_r of states (n,) or (n, m): ``model.slip_velocity`` with the spin a state."""
    return model.slip_velocity(S[0], S[1], S[2], S[3], Rp, S[SPEED])


def zero_slip_regime(s: np.ndarray, run: ExtendedRun) -> int:
    """Filippov's rule at v_r = 0 with the system's stick friction."""
    p = run.params
    limit = p.mu * p.K * (math.hypot(s[0], s[1]) - 1.0)
    return model.filippov_regime(run.stick_friction(s), limit)


def regime_of(s: np.ndarray, run: ExtendedRun) -> int:
    """The regime a system's state is in (``model.regime_of_state`` with the spin a
    state)."""
    p = run.params
    if math.hypot(s[0], s[1]) <= 1.0:
        return model.FREE
    if p.mu == 0.0:
        return model.SLIP_POSITIVE
    v_r = float(slip_velocity(s, p.Rp))
    if abs(v_r) <= 1e-12 * (1.0 + abs(p.Rp * s[SPEED])):
        return zero_slip_regime(s, run)
    return model.SLIP_POSITIVE if v_r >= 0.0 else model.SLIP_NEGATIVE


class ExtendedStepper(OdeSolverStepper):
    """One of scipy's ``OdeSolver`` classes on a system (module docstring): the
    constant-speed stepper's step and segments, with the system's right-hand side, events
    and samples."""

    intervals = SCAN_POINTS  # scan intervals of the step's dense output

    def _start_segment(self, run: ExtendedRun) -> None:
        ctx, regime, system = run.ctx, run.regime, run.system
        if self.compiled:
            one, columns = system.rhs, system.columns
        else:
            one, columns = system.python_rhs, system.python_columns

        def fun(t: float, s: np.ndarray) -> np.ndarray:
            return one(s, *ctx, regime)

        self.columns = lambda S: columns(np.ascontiguousarray(S), *ctx, regime)
        options = {"rtol": self.rtol, "atol": self.atol}
        if SPECS[self.name].implicit:
            options["jac"] = self._jacobian
        self.solver = self.cls(fun, run.tau, run.state, run.t_end, **options)
        run.stats["n_segments"] += 1

    def _jacobian(self, t: float, s: np.ndarray) -> np.ndarray:
        """Forward differences of the right-hand side, one column per state, each of
        step sqrt(eps) (1 + |s_i|), in one call of the columns. (scipy's own adaptive
        differences grow their step without bound on a column that is identically zero,
        as the angle's is without unbalance and the velocity along the rolling
        constraint's is in stick, until it overflows.)"""
        step = np.sqrt(np.finfo(float).eps) * (1.0 + np.abs(s))
        S = np.repeat(s[:, None], s.size + 1, axis=1)
        S[np.arange(s.size), np.arange(1, s.size + 1)] += step
        dS = self.columns(S)[0]
        return (dS[:, 1:] - dS[:, :1]) / step

    def advance(self, run: ExtendedRun) -> None:
        if self.step(run):
            solver = self.solver
            self.close_step(run, solver.dense_output(), solver.t_old, solver.t, solver.y[SPEED])

    def close_step(
        self, run: ExtendedRun, dense: Dense, t_old: float, t_new: float, w: float
    ) -> None:
        """An accepted step from t_old to t_new, ending at the speed ``w``: a stop of the
        rotor, or its earliest event, its samples, and the run moved on (``finish``)."""
        if w <= 0.0:  # stopped: the phase no longer advances
            stop = brentq(lambda t: dense(t)[SPEED], t_old, t_new)
            self._end_segment(run)
            k = self._fill(run, dense, stop)
            while k > 1 and run.states[k - 1, SPEED] <= 0.0:  # the samples keep speeds above 0
                k -= 1
            run.k = k
            run.fail(
                f"the speed fell to 0 at tau = {stop:.6g}: the rotor stopped, its load "
                "beyond what the motor gives (a rotor turning backward is outside the model)"
            )
            return
        event = self._earliest_event(run, dense, t_old, t_new)
        run.last_kind = NO_EVENT  # the segment's start concerns its first step only
        run.k = self._fill(run, dense, event[0] if event else t_new)
        self.finish(run, dense, event)

    @staticmethod
    def _fill(run: ExtendedRun, dense, t_stop: float) -> int:
        """The samples up to ``t_stop`` from a step's dense output (projected onto the
        rolling constraint in stick); returns the next sample to fill."""
        k = run.k
        while k < run.t_eval.size and run.t_eval[k] <= t_stop:
            sample = dense(run.t_eval[k])
            if run.regime == model.STICK:
                sample = run.project(sample)
            run.states[k], run.regimes[k] = sample, run.regime
            k += 1
        return k

    def _earliest_event(self, run: ExtendedRun, dense, t0: float, t1: float):
        """The earliest event in (t0, t1] on the step's dense output: (tau, kind) or None
        (``events.earliest_system_event``, the one event search, on the scan grid; none
        in a locked run)."""
        if run.locked is not None:
            return None
        grid = np.linspace(t0, t1, self.intervals + 1)
        return earliest_system_event(dense, self.columns, grid, run.regime, run.ctx[0],
                                     run.last_kind, self.restart_band)  # fmt: skip


class CompiledExtendedStepper(ExtendedStepper):
    """A compiled loop on a system (``dop853-jit``; ``taylor`` on the driven rotor and the
    two bodies): the one event loop (``compiled.extended_loop.step_loop``). The kernel
    commits the steps in which no event lies, with their samples, locates the events in
    the others with the one event search (``events.event_search``, compiled on the
    step's dense output: ``compiled.extended_loop.system_search``), and applies them
    itself (``events.switch_rule`` with the system's stick law and projection), recorded
    here with the storm guard (``ExtendedRun.record_events``); for a run that applies its
    own events (``ExtendedRun.loop_applies_events`` False: ``orbits``' flows) it returns
    at each and Python applies it (``ExtendedRun.switch``). A step that ends at a speed of
    0 or below comes back pending, and ``close_step`` takes it. A subclass runs its
    kernel (``_run_kernel``) and gives the dense output of the step it stopped in
    (``_pending``)."""

    def __init__(self, run: ExtendedRun, name: str, rtol: float, atol: float) -> None:
        super().__init__(run, "dop853", rtol, atol, compiled=True)
        self.name = name
        # scipy raises a too small rtol to 100 eps (with a warning); so do we, silently
        self.rtol = max(rtol, 100 * np.finfo(float).eps)
        self.ctx = run.ctx
        self.y_new = np.empty(run.system.size)
        self.t_new = 0.0
        self.found = np.empty(2)  # the kernel's event: (tau, kind), kind -1 if none
        self.applies = run.loop_applies_events and run.locked is None
        self.events = (
            np.empty(EVENT_BUFFER),
            np.empty(EVENT_BUFFER, dtype=np.int64),
            np.empty((EVENT_BUFFER, run.system.size)),
            np.empty((EVENT_BUFFER, 2), dtype=np.int64),
        )
        self.in_segment = False  # a segment is to start
        # the regime's right-hand side at columns of states (the Python paths' events):
        # the run's regime when called, which the kernel changes at its events
        self.columns = lambda S: run.system.columns(np.ascontiguousarray(S), *self.ctx,
                                                    run.regime)  # fmt: skip
        run.stats.update(python_steps=0)
        self.settings.update(rtol=self.rtol, compiled_events=True)

    def _start_segment(self, run: ExtendedRun) -> None:
        run.state = np.ascontiguousarray(run.state, dtype=float)
        run.stats["n_segments"] += 1
        self.in_segment = True

    def _end_segment(self, run: ExtendedRun) -> None:
        self.in_segment = False

    def advance(self, run: ExtendedRun) -> None:
        if not self.in_segment:
            self._start_segment(run)
        chunk = max(1, min(CHUNK_STEPS, run.steps_left))
        start = run.tau
        tau, reason, regime, n_events = self._run_kernel(run, start_flags(run.last_kind), chunk)
        run.tau = tau  # the kernel moved the state in place
        if n_events:
            run.regime = regime
            # segments the kernel started (with a full buffer the last one starts here)
            run.stats["n_segments"] += n_events - (reason == kernels.STOP_FULL)
            if not run.record_events(n_events, *self.events):
                return
            start = float(self.events[0][n_events - 1])
        if tau > start:
            run.last_kind = NO_EVENT  # the segment's first step is behind
        failure = kernel_failure(reason, self.name, tau, self.t_new)
        if failure:
            run.fail(failure)
        elif reason == kernels.STOP_FULL:
            self._end_segment(run)
        elif reason == kernels.STOP_EVENT:
            run.stats["nsteps"] += 1
            dense = self._pending(run, tau)
            if self.found[1] >= 0.0 and run.locked is not None:
                # a locked run has no events: the step is taken whole
                run.k = self._fill(run, dense, self.t_new)
                self.finish(run, dense, None)
                return
            if self.found[1] >= 0.0:  # located, its samples filled: the switch
                self._end_segment(run)
                run.switch(float(self.found[0]), int(self.found[1]), dense(self.found[0]))
                return
            run.stats["python_steps"] += 1
            self.close_step(run, dense, tau, self.t_new, self.y_new[SPEED])

    def finish(self, run: ExtendedRun, dense: Dense, event: tuple[float, int] | None) -> None:
        if event is None:
            run.tau = self.t_new
            run.state[:] = self.y_new
            return
        self._end_segment(run)
        run.switch(event[0], event[1], dense(event[0]))


class ExtendedJitStepper(CompiledExtendedStepper):
    """``dop853-jit`` on a system: scipy's DOP853 step for step, compiled
    (``compiled.extended_loop.dop853_loop``)."""

    def __init__(self, run: ExtendedRun, rtol: float, atol: float) -> None:
        super().__init__(run, "dop853-jit", rtol, atol)
        n = run.system.size
        self.f, self.f_new, self.F = np.empty(n), np.empty(n), np.empty((7, n))
        self.h_abs = 0.0
        self.initial_step, self.advance_kernel = run.system.loop

    def _start_segment(self, run: ExtendedRun) -> None:
        """As scipy starts a solver: f and the initial step."""
        super()._start_segment(run)
        self.f[:] = run.system.rhs(run.state, *self.ctx, run.regime)
        self.h_abs = self.initial_step(run.tau, run.state, self.f, run.t_end, self.ctx,
                                       run.regime, self.rtol, self.atol)  # fmt: skip
        run.stats["nfev"] += 2

    def _run_kernel(
        self, run: ExtendedRun, starts: tuple[bool, bool, bool], chunk: int
    ) -> tuple[float, int, int, int]:
        tau, self.t_new, self.h_abs, run.k, steps, nfev, reason, regime, n_events, _ = (
            self.advance_kernel(
                run.tau, run.state, self.f, self.h_abs, run.t_end, self.ctx, run.regime,
                self.rtol, self.atol, run.t_eval, run.states, run.regimes, run.k, chunk,
                starts, self.restart_band, self.found, self.y_new, self.f_new, self.F,
                self.events, self.applies,
            )
        )  # fmt: skip
        run.stats["nsteps"] += steps
        run.stats["nfev"] += nfev
        return tau, reason, regime, n_events

    def _pending(self, run: ExtendedRun, tau: float) -> Dense:
        return Dop853Dense(tau, self.t_new, run.state, self.F)

    def finish(self, run: ExtendedRun, dense: Dense, event: tuple[float, int] | None) -> None:
        if event is None:
            self.f[:] = self.f_new
        super().finish(run, dense, event)


class PolynomialDense:
    """A Taylor step's polynomial as a dense output: the state at a time, the states
    (size, n) at times (``compiled.driven_taylor.polynomial_values``, the kernels'
    operations)."""

    def __init__(self, t0: float, C: np.ndarray, order: int) -> None:
        self.t0, self.C, self.order = t0, C.copy(), order

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        times = np.atleast_1d(np.asarray(t, dtype=float))
        out = polynomial_values(times, self.t0, self.C, self.order)
        return out[:, 0] if np.ndim(t) == 0 else out


class ExtendedTaylorStepper(CompiledExtendedStepper):
    """``taylor`` on a system: its states' Taylor series (``System.taylor``), a pending
    step scanned on its own intervals (``taylor``'s rule)."""

    def __init__(self, run: ExtendedRun, rtol: float, atol: float) -> None:
        super().__init__(run, "taylor", rtol, atol)
        self.order = taylor_order(self.rtol)
        self.C = np.zeros((run.system.size, MAX_ORDER + 1))
        self.info = np.zeros(1, dtype=np.int64)
        self.kernel = run.system.taylor
        run.stats.update(order=self.order)
        self.settings.update(order=self.order)

    def _run_kernel(
        self, run: ExtendedRun, starts: tuple[bool, bool, bool], chunk: int
    ) -> tuple[float, int, int, int]:
        tau, self.t_new, run.k, steps, reason, regime, n_events, _ = self.kernel(
            run.tau, run.state, run.t_end, self.ctx, run.regime, self.order, self.rtol,
            self.atol, run.t_eval, run.states, run.regimes, run.k, chunk, starts,
            self.restart_band, self.found, self.C, self.info, self.events, self.applies,
        )  # fmt: skip
        run.stats["nsteps"] += steps
        run.stats["nfev"] = run.stats["nsteps"]  # one series expansion per step
        return tau, reason, regime, n_events

    def _pending(self, run: ExtendedRun, tau: float) -> Dense:
        run.stats["nfev"] += 1
        dense = PolynomialDense(tau, self.C, self.order)
        self.y_new = dense(self.t_new)
        self.intervals = int(self.info[0])
        return dense


def solve_extended(run: ExtendedRun, name: str, rtol: float, atol: float,
                   compiled: bool) -> Solution:  # fmt: skip
    """A system's run by a scipy method, ``dop853-jit`` or ``taylor`` (``dop853-jit``
    with ``compiled=False``, or its kernels unusable, is scipy's ``dop853`` under its
    name; ``taylor`` has no pure-Python path)."""
    if name == "taylor":
        kernels.ensure_fresh()
        return driver.integrate(run, ExtendedTaylorStepper(run, rtol, atol))
    if name == "dop853-jit" and compiled and kernels.ensure_fresh():
        return driver.integrate(run, ExtendedJitStepper(run, rtol, atol))
    scipy_name = "dop853" if name == "dop853-jit" else name
    return driver.integrate(run, ExtendedStepper(run, scipy_name, rtol, atol, compiled))

"""The event loop every method runs in: one driver, each method a stepper.

A run integrates one regime at a time (free flight, slip+, slip-, stick) and stops at
every event (contact entry/exit, slip reversal, stick entry/exit), so that no step
straddles a non-smoothness. What that takes is the same for every method and is written
here once:

- the output buffers (one state and one regime per sample of ``problem.t_eval``), the
  current ``tau``, state, regime and the kind of the event that began the segment;
- recording a located event, and the storm guard (too many events at one instant is a
  clean failure, ``events.StormGuard``);
- the run budget (``max_steps``, ``max_wall_time_s``), checked after every advance, and
  progress reports (about every 1 % of the span);
- failures: a non-finite state, an exhausted budget, or anything a stepper raises, ends
  the run as ``failed`` with its reason and keeps the partial result: no traceback
  reaches the user from a solver;
- building the ``Solution``.

A method is a **stepper**: an object with ``advance(run)`` that moves ``run`` forward by
some work of its own (one step, a compiled chunk of steps, a free flight to its next
event), writes the samples it covered into ``run.states``/``run.regimes`` (advancing
``run.k``), applies the events it located with ``run.switch`` (or ``run.record`` for an
event a compiled kernel applied itself), counts its work in ``run.stats``, and calls
``run.fail(message)`` when it cannot go on. ``settings`` is the dict reported with the
solution. docs/solvers.md ("How a method plugs in") shows a minimal stepper.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import FAILED, KIND_NAMES, SUCCESS, Events, Solution, SwitchEvent
from rubcli.solvers.events import STICK_EXIT, StormGuard, apply_event, initial_kind

PROGRESS_FRACTION = 0.01  # report progress about every 1 % of the span


@dataclass(frozen=True)
class Watch:
    """Ends a run early. The run goes in legs of ``every`` samples; at the end of each,
    ``check(samples)`` gets the states of the samples filled since its last call (an
    ``(n, 4)`` view); a string it returns ends the run there, with success and that
    string as its message. Every method's stepper reads the leg's end as ``run.t_end``,
    so a watched run is the same run stopped at a sample (its steps end on the legs'
    ends, as a run of that span would)."""

    every: int
    check: Callable[[np.ndarray], str | None]

    def __post_init__(self) -> None:
        if isinstance(self.every, bool) or not isinstance(self.every, int) or self.every < 1:
            raise ValueError(f"Watch: every must be an integer >= 1 (got {self.every!r})")
        if not callable(self.check):
            raise TypeError(f"Watch: check must be callable (got {self.check!r})")


WATCH: ContextVar[Watch | None] = ContextVar("rubcli_watch", default=None)  # solve(watch=)


class Stepper(Protocol):
    """What a method provides to the driver (module docstring). A method that runs a
    speed that changes (``rubcli.speed``) also has ``new_leg(run)``: the driver calls it
    where one leg of the profile ends and the next begins (``run.params`` is the new
    leg's); the stepper restarts its segment there, as after an event."""

    settings: dict

    def advance(self, run: Run) -> None: ...


class EventRecorder:
    """A run's events as growing columns (``Events``' layout): no Python object per
    event. The buffers are allocated at the first event and at least double when full
    (amortised copies; 43 bytes an event)."""

    MIN_CAPACITY = 64

    def __init__(self, capacity: int = 0) -> None:
        self.n = 0
        self.tau = np.empty(capacity)
        self.kind_code = np.empty(capacity, dtype=Events.CODE_DTYPE)
        self.state = np.empty((capacity, 4))
        self.regimes = np.empty((capacity, 2), dtype=Events.CODE_DTYPE)  # before, after

    @property
    def last_tau(self) -> float:
        """The time of the last event recorded (-inf if none)."""
        return float(self.tau[self.n - 1]) if self.n else -math.inf

    def append(self, event: SwitchEvent) -> None:
        self._reserve(1)
        i = self.n
        self.tau[i] = event.tau
        self.kind_code[i] = KIND_NAMES.index(event.kind)
        self.state[i] = event.state
        self.regimes[i] = event.regime_before, event.regime_after
        self.n = i + 1

    def extend(
        self, n: int, taus: np.ndarray, kinds: np.ndarray, states: np.ndarray, regimes: np.ndarray
    ) -> None:
        """Append the first ``n`` events of a compiled loop's buffers (``regimes``: (n, 2),
        before and after)."""
        self._reserve(n)
        a, b = self.n, self.n + n
        self.tau[a:b] = taus[:n]
        self.kind_code[a:b] = kinds[:n]
        self.state[a:b] = states[:n]
        self.regimes[a:b] = regimes[:n]
        self.n = b

    def events(self, copy: bool = False) -> Events:
        """The events recorded so far: views (later records do not change them), or with
        ``copy`` arrays of their own (the spare capacity is not kept alive with them)."""
        n = self.n
        columns = (self.tau[:n], self.kind_code[:n], self.state[:n])
        columns += (self.regimes[:n, 0], self.regimes[:n, 1])
        if copy:
            columns = tuple(np.array(c) for c in columns)
        return Events(*columns)

    def _reserve(self, n: int) -> None:
        capacity = self.tau.shape[0]
        if self.n + n <= capacity:
            return
        capacity = max(2 * capacity, self.n + n, self.MIN_CAPACITY)
        for name in ("tau", "kind_code", "state", "regimes"):
            old = getattr(self, name)
            new = np.empty((capacity, *old.shape[1:]), dtype=old.dtype)
            new[: self.n] = old[: self.n]
            setattr(self, name, new)


class Run:
    """The state of one run that every method shares (module docstring)."""

    def __init__(
        self,
        problem: Problem,
        method: str,
        *,
        max_steps: int,
        max_wall_time_s: float,
        progress=None,
    ):
        self.problem, self.method = problem, method
        # the legs of constant eta' (one at constant speed): run.params is the current one's
        self.legs = problem.legs()
        self.leg = 0
        self.params = self.legs[0][1]
        self.t_eval = problem.t_eval
        self.t_end = float(self.t_eval[-1])
        self.states = np.empty((self.t_eval.size, 4))
        self.regimes = np.empty(self.t_eval.size, dtype=int)
        self.state = np.array(problem.initial, dtype=float)
        self.tau = float(self.t_eval[0])
        self.regime = model.regime_of_state(self.state, self.params, self.tau)
        self.states[0], self.regimes[0] = self.state, self.regime
        self.k = 1  # the next sample to fill
        self.last_kind = initial_kind(self.state, self.regime, self.params, self.tau)
        self.recorder = EventRecorder()
        self.stats: dict[str, int] = {"nsteps": 0}
        self.status, self.message = SUCCESS, "reached the end of the time span"
        self.max_steps, self.max_wall_time_s = max_steps, max_wall_time_s
        self.start_clock = time.perf_counter()
        self._storms = StormGuard()
        self._progress = progress
        self._next_progress = self.tau

    @property
    def failed(self) -> bool:
        return self.status == FAILED

    @property
    def leg_end(self) -> float:
        """Where the current leg of the speed profile ends (inf on the last)."""
        return self.legs[self.leg + 1][0] if self.leg + 1 < len(self.legs) else math.inf

    def next_leg(self, stepper: Stepper) -> None:
        """Move to the next leg of the speed profile at its start (``run.tau``): the new
        leg's parameters, the stepper restarted; a stick whose friction the new eta'
        takes out of the friction cone ends there (Filippov's rule at the new rate)."""
        self.leg += 1
        self.params = self.legs[self.leg][1]
        stepper.new_leg(self)
        if self.regime == model.STICK:
            after = model.regime_at_zero_slip(self.tau, self.state, self.params)
            if after != model.STICK:
                self.switch(self.tau, STICK_EXIT, self.state)

    @property
    def steps_left(self) -> int:
        return self.max_steps - self.stats["nsteps"]

    def elapsed(self) -> float:
        return time.perf_counter() - self.start_clock

    def fail(self, message: str) -> None:
        """End the run as failed with ``message`` (the partial result is kept)."""
        self.status, self.message = FAILED, message

    @property
    def events(self) -> Events:
        """The events recorded so far."""
        return self.recorder.events()

    def record(self, event: SwitchEvent) -> bool:
        """Record an applied event; False (and the run failed) if it makes a storm."""
        self.recorder.append(event)
        return self.guard(event.tau)

    def guard(self, tau: float) -> bool:
        """Pass the event just recorded at ``tau`` through the storm guard; False (and the
        run failed) if it makes a storm."""
        if self._storms.storm(tau):
            self.fail(self._storms.message())
            return False
        return True

    def switch(self, tau: float, kind: int, state: np.ndarray) -> bool:
        """Apply and record the event ``kind`` located at ``tau`` with the state there.

        The run moves to the event: ``tau``, the state (projected onto the rolling
        constraint when stick begins or ends), the new regime and ``last_kind``.
        False (and the run failed) on a switch storm.
        """
        self.state, self.regime, self.last_kind, event = apply_event(
            tau, kind, state, self.regime, self.params
        )
        self.tau = tau
        return self.record(event)

    def budget_exceeded(self) -> str | None:
        """Why the run must stop for its budget, or None (only before the end)."""
        if self.tau >= self.t_end:
            return None
        if self.stats["nsteps"] >= self.max_steps:
            return f"step budget exhausted (max_steps = {self.max_steps}) at tau = {self.tau:.6g}"
        if self.elapsed() > self.max_wall_time_s:
            return (
                f"wall-time budget exhausted (max_wall_time_s = {self.max_wall_time_s:g}) "
                f"at tau = {self.tau:.6g}"
            )
        return None

    def report_progress(self, final: bool = False) -> None:
        """Report tau (about every 1 % of the span), and the end once (``final``)."""
        if self._progress is None:
            return
        if final:
            self._progress(self.t_end)
        elif self._next_progress <= self.tau < self.t_end:
            self._progress(self.tau)
            self._next_progress = self.tau + PROGRESS_FRACTION * (self.t_end - self.t_eval[0])

    def solution(self, settings: dict) -> Solution:
        """The run's Solution; it takes over the sample buffers (the run ends here)."""
        return Solution.from_samples(
            self.problem,
            self.method,
            self.k,
            self.states,
            self.regimes,
            events=self.recorder.events(copy=True),
            stats=self.stats,
            settings=settings,
            status=self.status,
            message=self.message,
        )


def integrate(run: Run, stepper: Stepper) -> Solution:
    """The event loop: advance the stepper until the end, a failure or the budget (or
    until the ``Watch`` set by ``solve(watch=...)`` ends the run)."""
    watch = WATCH.get()
    final = run.t_end
    seen = run.k  # samples shown to the watch so far
    watch_end = _leg_end(run, watch.every) if watch is not None else final
    if len(run.legs) > 1 and not hasattr(stepper, "new_leg"):
        run.fail(f"{run.method} does not run a speed that changes in time")
        return run.solution(stepper.settings)
    run.t_end = min(watch_end, run.leg_end)
    try:
        # a run that blows up is reported as a failed method, not by numpy warnings
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            while run.tau < final:
                if run.tau >= run.leg_end:
                    run.next_leg(stepper)
                    run.t_end = min(watch_end, run.leg_end)
                    if run.failed:
                        break
                stepper.advance(run)
                if run.failed:
                    break
                if not all(map(math.isfinite, run.state)):  # (4 floats: cheaper than numpy)
                    run.fail(f"non-finite state at tau = {run.tau:.6g}")
                    break
                reason = run.budget_exceeded()
                if reason:
                    run.fail(reason)
                    break
                if watch is not None and run.tau >= watch_end:
                    if run.k > seen:
                        stop = watch.check(run.states[seen : run.k])
                        seen = run.k
                        if stop is not None:
                            run.message = stop
                            break
                    watch_end = _leg_end(run, watch.every)
                    run.t_end = min(watch_end, run.leg_end)
                run.report_progress()
    except Exception as exc:  # noqa: BLE001 - a solver's exception is a failed method
        # e.g. arithmetic beyond the floating-point range (absurd parameters)
        run.fail(f"{run.method} failed at tau = {run.tau:.6g}: {type(exc).__name__}: {exc}")
    run.t_end = final
    if not run.failed and run.k == run.t_eval.size:
        run.report_progress(final=True)
    return run.solution(stepper.settings)


def _leg_end(run: Run, every: int) -> float:
    """The end of a watched run's next leg: ``every`` samples past the last one filled,
    and past ``run.tau`` in any case (so that every leg moves the run on)."""
    last = run.t_eval.size - 1
    after = int(np.searchsorted(run.t_eval, run.tau, side="right"))
    return float(run.t_eval[min(max(run.k - 1 + every, after), last)])


def record_kernel_events(
    run: Run, n: int, taus: np.ndarray, kinds: np.ndarray, states: np.ndarray, regimes: np.ndarray
) -> bool:
    """Record the ``n`` events a compiled loop located and applied itself (its event
    buffers, copied into the run's columns); False on a switch storm, with the samples
    past the storm dropped. The storm guard counts events at one instant, so a batch in
    which no event lies within an instant of the one before it (nor the first of the
    last event recorded) cannot make a storm: each event resets the count. Such a batch
    is copied in at once, only its last event through the guard (which it resets: the
    guard then holds the instant of the last event); any other goes through the guard
    event by event."""
    if n == 0:
        return True
    t = taus[:n]
    prev = np.empty(n)
    prev[1:] = t[:-1]
    prev[0] = run.recorder.last_tau
    instant = np.any(np.abs(t - prev) <= StormGuard.INSTANT * np.maximum(1.0, np.abs(t)))
    return _record_one_by_one(run, n, taus, kinds, states, regimes, 0 if instant else n - 1)


def _record_one_by_one(run: Run, n: int, taus, kinds, states, regimes, first: int = 0) -> bool:
    """``record_kernel_events`` with the events from ``first`` on through the storm guard
    one by one (by default all): on a storm, the events up to the one that made it are
    recorded and the samples past it dropped."""
    for i, t_ev in enumerate(taus[first:n].tolist(), first):
        if not run.guard(t_ev):
            run.recorder.extend(i + 1, taus, kinds, states, regimes)
            run.last_kind = int(kinds[i])
            run.k = int(np.searchsorted(run.t_eval, t_ev, side="right"))
            return False
    run.recorder.extend(n, taus, kinds, states, regimes)
    run.last_kind = int(kinds[n - 1])
    return True

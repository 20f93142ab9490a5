"""The event loop every method runs in: one driver, each method a stepper (issue 10).

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
from typing import Protocol

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import FAILED, SUCCESS, Solution, SwitchEvent
from rubcli.solvers.events import KIND_NAMES, StormGuard, apply_event, initial_kind

PROGRESS_FRACTION = 0.01  # report progress about every 1 % of the span


class Stepper(Protocol):
    """What a method provides to the driver (module docstring)."""

    settings: dict

    def advance(self, run: Run) -> None: ...


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
        self.problem, self.method, self.params = problem, method, problem.params
        self.t_eval = problem.t_eval
        self.t_end = float(self.t_eval[-1])
        self.states = np.empty((self.t_eval.size, 4))
        self.regimes = np.empty(self.t_eval.size, dtype=int)
        self.state = np.array(problem.initial, dtype=float)
        self.tau = float(self.t_eval[0])
        self.regime = model.regime_of_state(self.state, self.params)
        self.states[0], self.regimes[0] = self.state, self.regime
        self.k = 1  # the next sample to fill
        self.last_kind = initial_kind(self.state, self.regime, self.params)
        self.events: list[SwitchEvent] = []
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
    def steps_left(self) -> int:
        return self.max_steps - self.stats["nsteps"]

    def elapsed(self) -> float:
        return time.perf_counter() - self.start_clock

    def fail(self, message: str) -> None:
        """End the run as failed with ``message`` (the partial result is kept)."""
        self.status, self.message = FAILED, message

    def record(self, event: SwitchEvent) -> bool:
        """Record an applied event; False (and the run failed) if it makes a storm."""
        self.events.append(event)
        if self._storms.storm(event.tau):
            self.fail(self._storms.message())
            return False
        return True

    def switch(self, tau: float, kind: int, state) -> bool:
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
            events=self.events,
            stats=self.stats,
            settings=settings,
            status=self.status,
            message=self.message,
        )


def integrate(run: Run, stepper: Stepper) -> Solution:
    """The event loop: advance the stepper until the end, a failure or the budget."""
    try:
        # a run that blows up is reported as a failed method, not by numpy warnings
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            while run.tau < run.t_end:
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
                run.report_progress()
    except Exception as exc:  # noqa: BLE001 - a solver's exception is a failed method
        # e.g. arithmetic beyond the floating-point range (absurd parameters)
        run.fail(f"{run.method} failed at tau = {run.tau:.6g}: {type(exc).__name__}: {exc}")
    if not run.failed:
        run.report_progress(final=True)
    return run.solution(stepper.settings)


def record_kernel_events(run: Run, n: int, taus, kinds, states, regimes) -> bool:
    """Record the ``n`` events a compiled loop located and applied itself (its event
    buffers) as ``SwitchEvent`` records; False on a switch storm, with the samples past
    the storm dropped. The storm guard counts events at one instant, so a batch in
    which no event lies within an instant of the one before it (nor the first of the
    last event recorded) cannot make a storm: each event resets the count. Such a batch
    is appended at once; any other goes through the guard event by event
    (about 2 us an event in Python that way, 0.5 us in a batch)."""
    if n == 0:
        return True
    t = taus[:n]
    prev = np.empty(n)
    prev[1:] = t[:-1]
    prev[0] = run.events[-1].tau if run.events else -np.inf
    if np.any(np.abs(t - prev) <= StormGuard.INSTANT * np.maximum(1.0, np.abs(t))):
        return _record_one_by_one(run, n, taus, kinds, states, regimes)
    # flat lists: no list per event for the garbage collector to count and traverse
    tl, kl = t.tolist(), kinds[:n].tolist()
    sl, rl = states[:n].ravel().tolist(), regimes[:n].ravel().tolist()
    names, make = KIND_NAMES, _switch_event
    events = [
        make(tl[i], names[kl[i]], tuple(sl[4 * i : 4 * i + 4]), rl[2 * i], rl[2 * i + 1])
        for i in range(n)
    ]
    run.last_kind = kl[-1]
    # the last through the guard (which it resets): it holds the instant of the last event
    run.events.extend(events[:-1])
    return run.record(events[-1])


def _switch_event_fields(tau, kind, state, before, after) -> SwitchEvent:
    """A ``SwitchEvent`` with its fields set directly: the frozen dataclass's own
    ``__init__`` sets each field through ``object.__setattr__`` (0.7-1 us an event, most
    of the Python cost of a run with many events; this takes 0.35 us). Equal to
    ``SwitchEvent(...)`` in every field (``tests/test_taylor.py`` checks)."""
    event = _new(SwitchEvent)
    event.__dict__.update(tau=tau, kind=kind, state=state, regime_before=before, regime_after=after)
    return event


_new = object.__new__
# the direct construction only while SwitchEvent is a plain frozen dataclass (instance
# __dict__, no __post_init__): otherwise its own constructor
_switch_event = (
    _switch_event_fields
    if not hasattr(SwitchEvent, "__slots__") and not hasattr(SwitchEvent, "__post_init__")
    else SwitchEvent
)


def _record_one_by_one(run: Run, n: int, taus, kinds, states, regimes) -> bool:
    """``record_kernel_events`` event by event through the storm guard."""
    for i in range(n):
        run.last_kind = int(kinds[i])
        before, after = int(regimes[i, 0]), int(regimes[i, 1])
        state = tuple(map(float, states[i]))
        t_ev = float(taus[i])
        if not run.record(SwitchEvent(t_ev, KIND_NAMES[run.last_kind], state, before, after)):
            run.k = int(np.searchsorted(run.t_eval, t_ev, side="right"))
            return False
    return True

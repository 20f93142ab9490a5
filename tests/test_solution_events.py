"""A solution's events as columns (rubcli.solution.Events).

``Events`` must behave as the list of ``SwitchEvent`` it replaces (indexing, slicing,
iteration, equality with a list); the driver's batch record (``record_kernel_events``)
must give exactly the records a per-event loop gives, with the same storm guard.
"""

import dataclasses
import pickle

import numpy as np
import pytest

from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import KIND_NAMES, Events, Solution, SwitchEvent
from rubcli.solvers import driver
from rubcli.solvers.events import StormGuard

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16}
START = (0.88544, -0.8039, 0.0, 0.0)


def fig3_problem(periods: float, samples: int = 50, mu: float = 0.03) -> Problem:
    return Problem.from_periods(ModelParams(**FIG3, mu=mu), START, periods, samples)


def random_records(n: int, seed: int = 1) -> list[SwitchEvent]:
    rng = np.random.default_rng(seed)
    taus = np.sort(rng.uniform(0.0, 50.0, n))
    return [
        SwitchEvent(
            float(taus[i]),
            KIND_NAMES[int(rng.integers(0, 5))],
            tuple(float(v) for v in rng.normal(size=4)),
            int(rng.integers(-1, 3)),
            int(rng.integers(-1, 3)),
        )
        for i in range(n)
    ]


def reference_records(n, taus, kinds, states, regimes) -> list[SwitchEvent]:
    """The records the per-event path built from a compiled loop's buffers."""
    return [
        SwitchEvent(
            float(taus[i]),
            KIND_NAMES[int(kinds[i])],
            tuple(map(float, states[i])),
            int(regimes[i, 0]),
            int(regimes[i, 1]),
        )
        for i in range(n)
    ]


def new_run(periods: float = 10, samples: int = 50) -> driver.Run:
    return driver.Run(fig3_problem(periods, samples), "taylor", max_steps=10, max_wall_time_s=10.0)


def test_events_behave_as_the_list_of_records():
    """Indexing (negative too), slicing, iteration, equality with lists, tuples and
    other Events, the plain Python field types, read-only columns, pickling."""
    records = random_records(12)
    ev = Events.from_records(records)
    assert len(ev) == 12 and ev and list(ev) == records
    assert ev == records and ev == tuple(records) and records == list(ev)
    assert [ev[i] for i in range(-12, 12)] == records + records
    for i in (0, 5, -1, -12):
        got = ev[i]
        assert got == records[i]
        assert type(got.tau) is float and type(got.regime_after) is int
        assert type(got.state) is tuple and all(type(v) is float for v in got.state)
    with pytest.raises(IndexError):
        ev[12]
    with pytest.raises(IndexError):
        ev[-13]
    for part in (slice(2, 7), slice(None, None, -3), slice(10, 2), slice(-4, None)):
        assert isinstance(ev[part], Events) and ev[part] == records[part]
    assert ev[3:9][-1] == records[8]
    # equality looks at every field of every event
    changed = records[:5] + [dataclasses.replace(records[5], regime_after=7)] + records[6:]
    assert ev != changed and ev != records[:-1] and ev != Events.from_records(changed)
    assert ev == Events.from_records(list(records)) and ev != "not events"
    # the columns
    assert ev.kinds.tolist() == [r.kind for r in records]
    mask = ev.is_kind("contact_entry", "contact_exit")
    assert mask.tolist() == [r.kind in ("contact_entry", "contact_exit") for r in records]
    for column in (ev.tau, ev.kind_code, ev.state, ev.regime_before, ev.regime_after):
        assert not column.flags.writeable
    with pytest.raises(ValueError):
        ev.tau[0] = 1.0
    with pytest.raises(AttributeError):
        ev.tau = np.zeros(12)
    assert pickle.loads(pickle.dumps(ev)) == records
    assert repr(ev).startswith("Events(12 events")
    # empty
    empty = Events.empty()
    assert not empty and len(empty) == 0 and empty == [] and list(empty) == []
    assert ev[5:5] == [] and repr(empty) == "Events([])"
    assert Events.from_records([]) == empty and empty.kinds.size == 0


def test_a_solution_takes_a_list_of_records():
    """``Solution(events=[...])`` (and ``dataclasses.replace``, as io.tables does) keeps
    the events as ``Events``; the default is empty Events."""
    prob = fig3_problem(1)
    n = prob.t_eval.size
    states, regimes = np.zeros((n, 4)), np.zeros(n, dtype=int)
    records = random_records(3)
    sol = Solution(prob, "x", prob.t_eval, states, regimes, events=records)
    assert isinstance(sol.events, Events) and sol.events == records
    assert isinstance(dataclasses.replace(sol, events=[]).events, Events)
    assert Solution(prob, "x", prob.t_eval, states, regimes).events == []


def test_batch_record_gives_the_per_event_records():
    """Batches of a compiled loop's buffers (one empty, one of a single event, one with
    two events at one instant, enough to make the columns grow several times), with a
    Python stepper's event recorded between them, give exactly the records built event
    by event from the same buffers, in the run and in its Solution."""
    rng = np.random.default_rng(7)
    n = 700
    taus = np.sort(rng.uniform(0.0, 60.0, n))
    taus[401] = taus[400]  # two events at one instant: that batch goes one by one
    kinds = rng.integers(0, 5, n)
    states = rng.normal(size=(n, 4))
    regimes = rng.integers(-1, 3, (n, 2))
    run = new_run()
    expected: list[SwitchEvent] = []
    for a, b in ((0, 0), (0, 1), (1, 300), (300, 650), (650, 700)):
        buffers = (taus[a:], kinds[a:], states[a:], regimes[a:])
        assert driver.record_kernel_events(run, b - a, *buffers)
        expected += reference_records(b - a, *buffers)
        if b > a:
            assert run.last_kind == kinds[b - 1]
        if b == 300:  # an event of a Python stepper between two batches
            python_event = SwitchEvent(float(taus[300] - 1e-3), "slip_reversal", (1.0,) * 4, 1, -1)
            assert run.record(python_event)
            expected.append(python_event)
    assert run.events == expected and len(run.events) == n + 1
    assert run.status == "success"
    sol = run.solution({})
    assert sol.events == expected and sol.events == run.events


def test_a_storm_in_a_batch_fails_the_run_and_drops_the_later_samples():
    """21 events at one instant fail the run at the 21st with the guard's message; the
    events up to it are recorded and the samples past it dropped, also when the instant
    began in the previous batch (the guard and the instant check carry over: split at
    30, the second batch holds only the 21st event at that instant)."""
    n = 40
    taus = np.linspace(1.0, 60.0, n)
    taus[10:31] = taus[10]  # 21 events at one instant: the 21st (index 30) is a storm
    kinds = np.arange(n) % 5
    states = np.arange(4.0 * n).reshape(n, 4)
    regimes = np.tile([1, 0], (n, 1))
    for split in (0, 15, 30):
        run = new_run(10, 20)
        run.k = 150  # the kernel filled samples past the storm
        assert driver.record_kernel_events(run, split, taus, kinds, states, regimes)
        ok = driver.record_kernel_events(
            run, n - split, taus[split:], kinds[split:], states[split:], regimes[split:]
        )
        assert not ok and run.failed
        assert run.message == f"switch storm at tau = {taus[10]:.6g}: 21 events at one instant"
        assert run.events == reference_records(31, taus, kinds, states, regimes)
        assert run.last_kind == kinds[30]
        assert run.k == np.searchsorted(run.t_eval, taus[10], side="right") < 150
        sol = run.solution({})
        assert sol.status == "failed" and sol.t.size == run.k and len(sol.events) == 31
    assert StormGuard.LIMIT == 20  # (what 21 events at one instant assume)

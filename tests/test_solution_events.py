"""A solution's events as columns (rubcli.solution.Events).

``Events`` must behave as the list of ``SwitchEvent`` it replaces (indexing, slicing,
iteration, equality with a list).
"""

import dataclasses
import pickle

import numpy as np
import pytest

from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import KIND_NAMES, Events, Solution, SwitchEvent

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

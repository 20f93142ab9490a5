"""A solution's events as columns (rubcli.solution.Events) and what reads them.

``Events`` must behave as the list of ``SwitchEvent`` it replaces (indexing, slicing,
iteration, equality with a list); the driver's batch record (``record_kernel_events``)
must give exactly the records a per-event loop gives, with the same storm guard; and the
analyses that now read the columns vectorised (``Solution.n_contact_switches``,
``Solution.contact_fraction``, ``analysis.energy.regimes.piece_bounds`` and
``time_in_regimes``) must give exactly what their per-event loops gave, written out here
as the reference.
"""

import dataclasses
import pickle

import numpy as np
import pytest

from rubcli import model
from rubcli.analysis.energy.regimes import piece_bounds, time_in_regimes
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import KIND_NAMES, Events, Solution, SwitchEvent
from rubcli.solvers import driver, solve
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


# The per-event loops the vectorised analyses replace: the reference.


def n_contact_switches_loop(sol) -> int:
    return sum(1 for ev in sol.events if ev.kind in ("contact_entry", "contact_exit"))


def contact_fraction_loop(sol) -> float:
    t0, t1 = sol.problem.t_span
    end = float(sol.t[-1]) if sol.t.size else t0
    if end <= t0:
        return 0.0
    total, in_contact = end - t0, 0.0
    regime, last = model.regime_of_state(sol.problem.initial, sol.problem.params), t0
    for ev in sol.events:
        if ev.tau > end:
            break
        if regime != model.FREE:
            in_contact += ev.tau - last
        regime, last = ev.regime_after, ev.tau
    if regime != model.FREE:
        in_contact += end - last
    return in_contact / total


def piece_bounds_loop(solution) -> dict[str, np.ndarray]:
    t = np.asarray(solution.t, dtype=float)
    states = np.asarray(solution.states, dtype=float)
    regime, start_tau, start_state, end_tau, end_state, lo, hi = [], [], [], [], [], [], []
    if t.size:
        t_end = float(t[-1])
        bounds = [(float(t[0]), states[0], int(solution.regimes[0]))]
        for event in solution.events:
            if event.tau > t_end:
                break
            bounds.append(
                (float(event.tau), np.asarray(event.state, dtype=float), event.regime_after)
            )
        for i, (start, state, code) in enumerate(bounds):
            if i + 1 < len(bounds):
                end, final = bounds[i + 1][0], bounds[i + 1][1]
            else:
                end, final = t_end, states[-1]
            if not end > start:
                continue
            regime.append(code)
            start_tau.append(start)
            start_state.append(state)
            end_tau.append(end)
            end_state.append(final)
            lo.append(int(np.searchsorted(t, start, side="right")))
            hi.append(int(np.searchsorted(t, end, side="left")))
    return {
        "regime": np.asarray(regime, dtype=np.int64),
        "start_tau": np.asarray(start_tau, dtype=float),
        "start_state": np.asarray(start_state, dtype=float).reshape(-1, 4),
        "end_tau": np.asarray(end_tau, dtype=float),
        "end_state": np.asarray(end_state, dtype=float).reshape(-1, 4),
        "lo": np.asarray(lo, dtype=np.int64),
        "hi": np.asarray(hi, dtype=np.int64),
    }


def time_in_regimes_loop(sol) -> dict[str, float]:
    out = {name: 0.0 for name in model.REGIME_NAMES.values()}
    b = piece_bounds_loop(sol)
    for regime, start, end in zip(b["regime"].tolist(), b["start_tau"], b["end_tau"], strict=True):
        out[model.REGIME_NAMES[regime]] += float(end - start)
    return out


def assert_analyses_equal_the_loops(sol) -> None:
    assert sol.n_contact_switches == n_contact_switches_loop(sol)
    assert sol.contact_fraction() == contact_fraction_loop(sol)  # bit for bit
    got, want = piece_bounds(sol), piece_bounds_loop(sol)
    for name, value in want.items():
        column = getattr(got, name)
        assert column.dtype == value.dtype and column.shape == value.shape, name
        assert np.array_equal(column, value), name
    assert time_in_regimes(sol) == time_in_regimes_loop(sol)  # bit for bit


@pytest.mark.parametrize("method", ["taylor", "dop853-jit"])
def test_analyses_of_a_run_with_many_events_equal_their_loops(method):
    """The paper's case with friction over 100 periods (941 events): the counts, the
    contact fraction, the piece bounds and the time in each regime, exactly as the
    per-event loops give them (the sums bit for bit: the durations added in time order,
    which a pairwise sum is not here); and the same once the run is cut short (events
    past the last sample)."""
    sol = solve(fig3_problem(100, 20), method, rtol=1e-9, atol=1e-11)
    assert sol.success and len(sol.events) > 500
    assert sol.n_contact_switches > 0
    assert_analyses_equal_the_loops(sol)
    k = sol.t.size // 2
    cut = dataclasses.replace(sol, t=sol.t[:k], states=sol.states[:k], regimes=sol.regimes[:k])
    assert cut.events.tau[-1] > cut.t[-1]
    assert_analyses_equal_the_loops(cut)


def _hand_solution(taus, afters, n_samples=11, periods=1.0) -> Solution:
    """A solution on a hand-made grid with events at ``taus`` (regime after: ``afters``,
    which gives the kind: free, a contact exit; 1, an entry; -1, a slip reversal)."""
    prob = fig3_problem(periods, n_samples - 1)
    n = prob.t_eval.size
    states = np.arange(4.0 * n).reshape(n, 4)
    regimes = np.array([1] + [0] * (n - 1))
    names = {model.FREE: "contact_exit", 1: "contact_entry", -1: "slip_reversal"}
    kinds = [names[a] for a in afters]
    records = [
        SwitchEvent(float(t), kind, (float(t), 1.0, 2.0, 3.0), 0, int(a))
        for t, kind, a in zip(taus, kinds, afters, strict=True)
    ]
    return Solution(prob, "hand", prob.t_eval.copy(), states, regimes, events=records)


def _edge_cases():
    period = fig3_problem(1).t_eval[-1]
    t = np.linspace(0.0, period, 11)
    return {
        "no events": _hand_solution([], []),
        "events after the last sample": _hand_solution(
            [t[2] + 0.01, t[-1], period + 1.0, period + 2.0], [0, 1, 0, 1]
        ),
        "two events at one instant": _hand_solution([t[3], t[3], t[6]], [0, 1, 0]),
        "an event at the first sample": _hand_solution([0.0, t[4] + 0.1], [0, 1]),
        "events on samples and between": _hand_solution(
            [t[1], t[1] + 0.05, t[5] + 0.2, t[9]], [0, 1, -1, 0]
        ),
        "one sample": dataclasses.replace(
            _hand_solution([0.0, 1.0], [0, 1]),
            t=t[:1],
            states=np.zeros((1, 4)),
            regimes=np.zeros(1, dtype=int),
        ),  # fmt: skip
        "no samples": dataclasses.replace(
            _hand_solution([1.0], [0]),
            t=t[:0],
            states=np.zeros((0, 4)),
            regimes=np.zeros(0, dtype=int),
        ),  # fmt: skip
    }


@pytest.mark.parametrize("case", list(_edge_cases()))
def test_analyses_of_edge_cases_equal_their_loops(case):
    """No events, events after the last sample (one exactly at it), two events at one
    instant (a zero-duration piece), an event at the first sample, no or one sample."""
    assert_analyses_equal_the_loops(_edge_cases()[case])

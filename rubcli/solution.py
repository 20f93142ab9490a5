"""Solution: what every solver returns, whatever its method."""

from __future__ import annotations

import operator
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, overload

import numpy as np

from rubcli import model
from rubcli.problem import Problem

SUCCESS = "success"
FAILED = "failed"

# The names of the event kinds, by code (the codes rubcli.solvers.events and the compiled
# loops pass around: ENTRY, EXIT, REVERSAL, STICK_ENTRY, STICK_EXIT = 0..4).
KIND_NAMES = ("contact_entry", "contact_exit", "slip_reversal", "stick_entry", "stick_exit")


@dataclass(frozen=True)
class SwitchEvent:
    """A located change of regime: contact entry/exit or a slip reversal."""

    tau: float
    kind: str  # one of KIND_NAMES
    state: tuple[float, float, float, float]
    regime_before: int
    regime_after: int


class Events(Sequence[SwitchEvent]):
    """A run's located events, kept as columns: a read-only sequence of ``SwitchEvent``.

    A run may locate 100k events; one Python object each costs ~0.5 us to build and
    ~440 bytes to keep (and the garbage collector walks them all). Columns cost 43 bytes
    an event, are copied in by the driver with numpy, and let analyses work vectorised;
    an indexed or iterated event is built as a ``SwitchEvent`` on access. Columns:
    ``tau`` (n,) float64, ``kind_code`` (n,) int8 (``KIND_NAMES[code]`` is the kind),
    ``state`` (n, 4) float64, ``regime_before`` and ``regime_after`` (n,) int8.
    The arrays are read-only views of the ones given (not copied: the caller hands them
    over).
    """

    CODE_DTYPE = np.int8  # kind codes (0..4) and regime codes (-1..2)

    __slots__ = ("tau", "kind_code", "state", "regime_before", "regime_after")

    def __init__(self, tau, kind_code, state, regime_before, regime_after) -> None:
        columns = (
            _read_only(tau, np.float64),
            _read_only(kind_code, self.CODE_DTYPE),
            _read_only(state, np.float64),
            _read_only(regime_before, self.CODE_DTYPE),
            _read_only(regime_after, self.CODE_DTYPE),
        )
        n = columns[0].shape[0] if columns[0].ndim == 1 else -1
        shapes = [c.shape for c in columns]
        if n < 0 or shapes != [(n,), (n,), (n, 4), (n,), (n,)]:
            raise ValueError(f"event columns of shapes {shapes}, expected (n,) and (n, 4)")
        for name, column in zip(self.__slots__, columns, strict=True):
            object.__setattr__(self, name, column)

    @classmethod
    def empty(cls) -> Events:
        """No events (a Solution's default)."""
        return cls(np.empty(0), np.empty(0), np.empty((0, 4)), np.empty(0), np.empty(0))

    @classmethod
    def from_records(cls, records: Iterable[SwitchEvent]) -> Events:
        """The columns of ``records`` (``Events`` themselves are returned as they are)."""
        if isinstance(records, Events):
            return records
        records = list(records)
        if not records:
            return cls.empty()
        return cls(
            [ev.tau for ev in records],
            [KIND_NAMES.index(ev.kind) for ev in records],
            [ev.state for ev in records],
            [ev.regime_before for ev in records],
            [ev.regime_after for ev in records],
        )

    def __setattr__(self, name: str, value) -> None:
        raise AttributeError(f"Events are immutable (cannot set {name!r})")

    def __len__(self) -> int:
        return self.tau.shape[0]

    @overload
    def __getitem__(self, index: int) -> SwitchEvent: ...

    @overload
    def __getitem__(self, index: slice) -> Events: ...

    def __getitem__(self, index):
        if isinstance(index, slice):
            return Events(*(getattr(self, name)[index] for name in self.__slots__))
        i = operator.index(index)
        if not -len(self) <= i < len(self):
            raise IndexError(f"event index {index} out of range for {len(self)} events")
        return SwitchEvent(
            float(self.tau[i]),
            KIND_NAMES[self.kind_code[i]],
            tuple(self.state[i].tolist()),
            int(self.regime_before[i]),
            int(self.regime_after[i]),
        )

    def __iter__(self) -> Iterator[SwitchEvent]:
        columns = (self.tau, self.kind_code, self.state, self.regime_before, self.regime_after)
        for tau, code, state, before, after in zip(*(c.tolist() for c in columns), strict=True):
            yield SwitchEvent(tau, KIND_NAMES[code], tuple(state), before, after)

    def __eq__(self, other: object) -> bool:
        """Equal to another ``Events`` or any sequence of ``SwitchEvent`` (``== []``),
        event by event as ``SwitchEvent`` compares (columns compared vectorised)."""
        if isinstance(other, Events):
            return len(self) == len(other) and all(
                np.array_equal(getattr(self, name), getattr(other, name)) for name in self.__slots__
            )
        if isinstance(other, Sequence) and not isinstance(other, str):
            return len(self) == len(other) and all(map(operator.eq, self, other))
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]  # equal to lists, which are unhashable

    def __repr__(self) -> str:
        if not len(self):
            return "Events([])"
        return f"Events({len(self)} events, tau {self.tau[0]:.6g} .. {self.tau[-1]:.6g})"

    def __reduce__(self):
        return Events, tuple(getattr(self, name) for name in self.__slots__)

    @property
    def kinds(self) -> np.ndarray:
        """The kind names, one an event (an array of str)."""
        return np.asarray(KIND_NAMES)[self.kind_code]

    def is_kind(self, *names: str) -> np.ndarray:
        """Boolean mask of the events of any of the kinds ``names`` (from ``KIND_NAMES``;
        another name is a ValueError naming it)."""
        unknown = [name for name in names if name not in KIND_NAMES]
        if unknown:
            raise ValueError(
                f"Events.is_kind: unknown kind(s) {', '.join(map(repr, unknown))}; the kinds "
                f"are {', '.join(KIND_NAMES)}"
            )
        return np.isin(self.kind_code, [KIND_NAMES.index(name) for name in names])

    def until(self, tau: float) -> Events:
        """The events before the first one later than ``tau``: those a run whose last
        sample is at ``tau`` passed (a failed run may locate one past it before it stops)."""
        late = np.flatnonzero(self.tau > tau)
        return self[: late[0]] if late.size else self


def ordered_sum(values: np.ndarray) -> float:
    """The sum of ``values`` in their order (0.0 if none), rounded as a loop adding them
    one by one rounds: a cumulative sum, not numpy's pairwise ``sum``, so the vectorised
    analyses give the same bits as the per-event loops they replace."""
    return float(np.cumsum(values)[-1]) if values.size else 0.0


def _read_only(values, dtype) -> np.ndarray:
    """A read-only view of ``values`` as an array of ``dtype`` (a copy only to convert)."""
    array = np.asarray(values, dtype=dtype).view()
    array.flags.writeable = False
    return array


@dataclass
class Solution:
    """States at the problem's sample times, regimes, switch events and run statistics.

    ``t`` may be shorter than ``problem.t_eval`` when a run failed part way (the partial
    result is kept, ``status`` says ``failed`` and ``message`` why).
    """

    problem: Problem
    method: str
    t: np.ndarray
    states: np.ndarray  # shape (n, 4): x, y, vx, vy
    regimes: np.ndarray  # shape (n,), regime code per sample (model.FREE, ...)
    events: Events = field(default_factory=Events.empty)  # a list of SwitchEvent is converted
    stats: dict[str, int] = field(default_factory=dict)
    settings: dict[str, object] = field(default_factory=dict)
    status: str = SUCCESS
    message: str = ""
    wall_time_s: float = 0.0
    # a driven rotor's own states at the samples, shape (n, 2): phase p and speed w
    drive_states: np.ndarray | None = None
    # a stator with its own mass: its displacement and velocity (u, v, u', v') at the
    # samples, (n, 4), and at the events, (m, 4)
    stator_states: np.ndarray | None = None
    stator_events: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.events = Events.from_records(self.events)

    @classmethod
    def from_samples(
        cls,
        problem: Problem,
        method: str,
        k: int,
        states: np.ndarray,
        regimes: np.ndarray,
        **fields: Any,
    ) -> Solution:
        """The solution of a solver that filled ``states``/``regimes`` (buffers of the
        problem's sample count) up to sample ``k``; ``fields`` are the other fields.

        Full buffers become the solution's arrays as they are (the solver hands them
        over: a copy would double the peak memory of a long run, 40 bytes a sample);
        the filled part of partly filled ones is copied, so the rest can be freed."""
        t = problem.t_eval[:k].copy()
        if k == len(states) and k == len(regimes):
            return cls(problem, method, t, states, regimes, **fields)
        return cls(problem, method, t, states[:k].copy(), regimes[:k].copy(), **fields)

    @property
    def success(self) -> bool:
        return self.status == SUCCESS

    @property
    def x(self) -> np.ndarray:
        return self.states[:, 0]

    @property
    def y(self) -> np.ndarray:
        return self.states[:, 1]

    @property
    def vx(self) -> np.ndarray:
        return self.states[:, 2]

    @property
    def vy(self) -> np.ndarray:
        return self.states[:, 3]

    @property
    def z(self) -> np.ndarray:
        return np.hypot(self.x, self.y)

    @property
    def w(self) -> np.ndarray:
        """Complex position x + i y."""
        return self.x + 1j * self.y

    @property
    def contact(self) -> np.ndarray:
        """1 where the sample lies in a contact regime, else 0."""
        return (self.regimes != model.FREE).astype(int)

    @property
    def speed(self) -> np.ndarray:
        """The speed ratio eta at each sample (constant unless ``problem.speed``; a
        driven rotor's from its states)."""
        if self.drive_states is not None:
            return self.drive_states[:, 1]
        return np.asarray(self.problem.speed_at(self.t), dtype=float)

    @property
    def phase(self) -> np.ndarray:
        """The unbalance phase at each sample: phi0 + the integral of the speed (rad)."""
        if self.drive_states is not None:
            return self.drive_states[:, 0]
        p, speed = self.problem.params, self.problem.speed
        if speed is None:
            return p.eta * self.t + p.phi0
        return np.asarray(speed.phase(self.t, p.phi0), dtype=float)

    @property
    def n_contact_switches(self) -> int:
        return int(np.count_nonzero(self.events.is_kind("contact_entry", "contact_exit")))

    def contact_fraction(self) -> float:
        """Fraction of the simulated time spent in contact, from the located events.

        The phases run from event to event (events after the last sample ignored); their
        durations in contact are summed in time order (``ordered_sum``)."""
        t0, t1 = self.problem.t_span
        end = float(self.t[-1]) if self.t.size else t0
        if end <= t0:
            return 0.0
        events = self.events.until(end)
        first = model.regime_of_state(self.problem.initial, self.problem.params)
        starts = np.concatenate(([t0], events.tau))
        ends = np.concatenate((events.tau, [end]))
        regimes = np.concatenate(([first], events.regime_after))
        return ordered_sum((ends - starts)[regimes != model.FREE]) / (end - t0)

    def max_penetration(self) -> float:
        """Largest z - 1 over the samples (0 if never in contact)."""
        if self.t.size == 0:
            return 0.0
        return float(max(0.0, np.max(self.z - 1.0)))

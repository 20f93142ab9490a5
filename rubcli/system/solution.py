"""What a run of a composed machine returns: results only, no physics.

The forces, slips and penetrations of its samples are asked of the system
(``rubcli.system.station_series``), the energy of the machine
(``rubcli.system.energy_balance``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rubcli.machine import Machine

SUCCESS = "success"
FAILED = "failed"
# event kinds by code, as the rotor's (``rubcli.solution.KIND_NAMES``)
KIND_NAMES = ("contact_entry", "contact_exit", "slip_reversal", "stick_entry", "stick_exit")
ENTRY, EXIT, REVERSAL, STICK_ENTRY, STICK_EXIT = range(5)


@dataclass(frozen=True, eq=False)
class StationEvents:
    """Located events as columns: time, station index, kind code (``KIND_NAMES``), the
    station's regime before and after, and the state ``(q, v)`` at the event."""

    t: np.ndarray
    station: np.ndarray
    kind: np.ndarray
    before: np.ndarray
    after: np.ndarray
    state: np.ndarray

    def __len__(self) -> int:
        return self.t.shape[0]

    def kinds(self) -> list[str]:
        return [KIND_NAMES[k] for k in self.kind.tolist()]

    def at_station(self, s: int) -> StationEvents:
        keep = self.station == s
        return StationEvents(*(getattr(self, f)[keep] for f in _EVENT_FIELDS))


_EVENT_FIELDS = ("t", "station", "kind", "before", "after", "state")


@dataclass(eq=False)
class MachineSolution:
    """States ``(q, v)`` (k, 2 n) at the sample times ``t`` (k,), the work ``W`` done by
    the non-conservative forces (k,), each station's regime at each sample (k, S), the
    located events, statistics and status (``t`` ends early when a run failed)."""

    machine: Machine
    method: str
    t: np.ndarray
    states: np.ndarray
    work: np.ndarray
    regimes: np.ndarray
    events: StationEvents
    stats: dict[str, int] = field(default_factory=dict)
    settings: dict[str, object] = field(default_factory=dict)
    status: str = SUCCESS
    message: str = ""
    wall_time_s: float = 0.0

    @property
    def success(self) -> bool:
        return self.status == SUCCESS

    def coordinates(self, pair: tuple[int, int]) -> np.ndarray:
        """The samples of a coordinate pair (k, 2), e.g. a station's rotor point."""
        return self.states[:, list(pair)]

"""Solution: what every solver returns, whatever its method."""

from __future__ import annotations

from dataclasses import dataclass, field

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
    events: list[SwitchEvent] = field(default_factory=list)
    stats: dict[str, int] = field(default_factory=dict)
    settings: dict[str, object] = field(default_factory=dict)
    status: str = SUCCESS
    message: str = ""
    wall_time_s: float = 0.0

    @classmethod
    def from_samples(
        cls, problem: Problem, method: str, k: int, states, regimes, **fields
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
    def slip_velocity(self) -> np.ndarray:
        p = self.problem.params
        return model.slip_velocity(self.x, self.y, self.vx, self.vy, p.Rp, p.eta)

    @property
    def normal_force(self) -> np.ndarray:
        """K (z - 1) in contact regimes, 0 in free flight (nondimensional)."""
        return np.where(self.contact == 1, self.problem.params.K * (self.z - 1.0), 0.0)

    @property
    def friction_force(self) -> np.ndarray:
        """Signed tangential force (positive opposes positive slip): mu_c K (z - 1) when
        slipping, the rolling friction in stick, 0 in free flight (model.tangential_force)."""
        return model.tangential_force(
            self.t, self.x, self.y, self.vx, self.vy, self.problem.params, self.regimes
        )

    @property
    def n_contact_switches(self) -> int:
        return sum(1 for ev in self.events if ev.kind in ("contact_entry", "contact_exit"))

    def contact_fraction(self) -> float:
        """Fraction of the simulated time spent in contact, from the located events."""
        t0, t1 = self.problem.t_span
        end = float(self.t[-1]) if self.t.size else t0
        if end <= t0:
            return 0.0
        total, in_contact = end - t0, 0.0
        regime, last = model.regime_of_state(self.problem.initial, self.problem.params), t0
        for ev in self.events:
            if ev.tau > end:
                break
            if regime != model.FREE:
                in_contact += ev.tau - last
            regime, last = ev.regime_after, ev.tau
        if regime != model.FREE:
            in_contact += end - last
        return in_contact / total

    def max_penetration(self) -> float:
        """Largest z - 1 over the samples (0 if never in contact)."""
        if self.t.size == 0:
            return 0.0
        return float(max(0.0, np.max(self.z - 1.0)))

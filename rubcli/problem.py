"""Problem: parameters, initial state and time grid. Pure data, no solver choices."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rubcli.model import ModelParams


@dataclass(frozen=True)
class Problem:
    """One initial-value problem of the rubbing rotor, nondimensional.

    ``t_eval`` holds the sample times at which every solver reports the state; the
    span is ``(t_eval[0], t_eval[-1])``.
    """

    params: ModelParams
    initial: tuple[float, float, float, float]  # (x, y, vx, vy) at t_eval[0]
    t_eval: np.ndarray = field(repr=False)
    name: str = "problem"

    def __post_init__(self) -> None:
        t = np.asarray(self.t_eval, dtype=float)
        if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
            raise ValueError("t_eval must be a strictly increasing array of at least 2 times")
        if not all(math.isfinite(v) for v in self.initial):
            raise ValueError("initial state must be finite")
        object.__setattr__(self, "t_eval", t)
        object.__setattr__(self, "initial", tuple(float(v) for v in self.initial))

    @classmethod
    def from_periods(
        cls,
        params: ModelParams,
        initial,
        periods: float,
        samples_per_period: int = 100,
        name: str = "problem",
    ) -> Problem:
        """Sample ``periods`` forcing periods from tau = 0 at ``samples_per_period``."""
        n = max(2, int(round(periods * samples_per_period)) + 1)
        t_eval = np.linspace(0.0, periods * params.period, n)
        return cls(params=params, initial=tuple(initial), t_eval=t_eval, name=name)

    @property
    def t_span(self) -> tuple[float, float]:
        return float(self.t_eval[0]), float(self.t_eval[-1])

    @property
    def periods(self) -> float:
        return (self.t_span[1] - self.t_span[0]) / self.params.period

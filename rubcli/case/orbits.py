"""[orbits]: the branch `rubcli orbits` continues (docs/orbits.md): periodic orbits,
Floquet multipliers and pseudo-arclength continuation in one nondimensional parameter."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from rubcli import model
from rubcli.analysis.orbits.bounds import (
    MIN_ORBIT_STEP_FRACTION,
    ORBITS_BOUNDS,
    ORBITS_WALL_TIME_S,
)
from rubcli.case.base import _Section

OrbitParameter = Literal["eta", "mu", "K", "e", "nu", "Rp"]
# The smallest continuation step, as a fraction of the window: a step of 1e-300 leaves
# the parameter where it is and runs for ever. 1e-12 of the window still spans thousands
# of doubles and allows 1e12 steps across it.
OrbitStart = Literal["initial", "transient", "synchronous_rub"]
OrbitDirections = Literal["both", "up", "down"]
OrbitKind = Literal["periodic", "whirl"]


class OrbitsSection(_Section):
    """[orbits]: the branch to continue (nondimensional, also for [physical] cases)."""

    kind: OrbitKind = "periodic"  # periodic orbits of the map, or whirls of unknown rate (e = 0)
    parameter: OrbitParameter
    min: float  # parameter window; the case's value must lie in it
    max: float
    step: float = Field(**ORBITS_BOUNDS["step"])  # first step, parameter units
    min_step: float | None = Field(default=None, **ORBITS_BOUNDS["min_step"])  # step / 1000
    max_step: float | None = Field(default=None, **ORBITS_BOUNDS["max_step"])  # 5 step
    max_points: int = Field(default=200, **ORBITS_BOUNDS["max_points"])  # per direction
    directions: OrbitDirections = "both"
    period: int = Field(default=1, **ORBITS_BOUNDS["period"])  # k: orbits of k periods
    start: OrbitStart = "initial"  # guess: [initial], after a transient, or the exact rub
    transient_periods: int = Field(default=0, ge=0, le=100_000)  # with start = "transient"
    newton_tol: float = Field(default=1e-10, **ORBITS_BOUNDS["newton_tol"])
    max_newton: int = Field(default=10, **ORBITS_BOUNDS["max_newton"])
    rtol: float = Field(default=1e-12, **ORBITS_BOUNDS["rtol"])  # integration of the map
    atol: float = Field(default=1e-12, **ORBITS_BOUNDS["atol"])
    locate: bool = True  # locate each detected bifurcation on its test function
    max_wall_time_s: float = Field(  # the run's budget, seconds
        default=ORBITS_WALL_TIME_S, **ORBITS_BOUNDS["max_wall_time_s"]
    )
    # each located fold, period doubling, Neimark-Sacker point and grazing continued in a
    # second parameter over [second_min, second_max] (docs/orbits.md, "Two parameters")
    second_parameter: OrbitParameter | None = None
    second_min: float | None = None
    second_max: float | None = None
    curve_step: float = Field(default=0.02, gt=0, le=0.5)  # first step, fraction of windows
    curve_points: int = Field(default=100, ge=1, le=10_000)  # per direction of each curve

    @model_validator(mode="after")
    def _window(self) -> OrbitsSection:
        if not self.min < self.max:
            raise PydanticCustomError(
                "orbits_window", "min must be below max (got min = {lo}, max = {hi})",
                {"lo": self.min, "hi": self.max},
            )  # fmt: skip
        lower = {"eta": 0.0, "K": 0.0}.get(self.parameter)
        if lower is not None and self.min <= lower:
            raise PydanticCustomError(
                "orbits_window", "{name} must stay positive: min must be > 0 (got {lo})",
                {"name": self.parameter, "lo": self.min},
            )  # fmt: skip
        if self.parameter in ("mu", "e", "nu", "Rp") and self.min < 0.0:
            raise PydanticCustomError(
                "orbits_window", "{name} cannot be negative: min must be >= 0 (got {lo})",
                {"name": self.parameter, "lo": self.min},
            )  # fmt: skip
        for bound in (self.min, self.max):
            why = model.parameter_problem(self.parameter, bound)
            if why:
                raise PydanticCustomError(
                    "orbits_window", f"{self.parameter} {why} (got {bound!r} as a bound)"
                )
        width = self.max - self.min
        if self.step > width:
            raise PydanticCustomError(
                "orbits_step", "step {step} is wider than the window max - min = {w}",
                {"step": self.step, "w": width},
            )  # fmt: skip
        self._second_window()
        lo, hi = self.resolved_min_step(), self.resolved_max_step()
        if lo < MIN_ORBIT_STEP_FRACTION * width:
            raise PydanticCustomError(
                "orbits_step", f"min_step {lo:g} is below {MIN_ORBIT_STEP_FRACTION:g} of the "
                f"window max - min = {width:g}: so small a step does not move the parameter "
                "by a resolvable amount",
            )  # fmt: skip
        if not lo <= self.step <= hi:
            raise PydanticCustomError(
                "orbits_step", "need min_step <= step <= max_step (got {lo}, {s}, {hi})",
                {"lo": lo, "s": self.step, "hi": hi},
            )  # fmt: skip
        return self

    def _second_window(self) -> None:
        name, lo, hi = self.second_parameter, self.second_min, self.second_max
        if name is None:
            if lo is not None or hi is not None:
                raise PydanticCustomError(
                    "orbits_second", "second_min/second_max need second_parameter"
                )
            return
        if self.kind != "periodic":
            raise PydanticCustomError(
                "orbits_second", 'second_parameter continues bifurcations of kind = "periodic"'
            )
        if name == self.parameter:
            raise PydanticCustomError(
                "orbits_second", "second_parameter must differ from parameter (both are {n})",
                {"n": name},
            )  # fmt: skip
        if lo is None or hi is None:
            raise PydanticCustomError(
                "orbits_second", "second_parameter needs second_min and second_max"
            )
        if not lo < hi:
            raise PydanticCustomError(
                "orbits_second", "second_min must be below second_max (got {lo}, {hi})",
                {"lo": lo, "hi": hi},
            )  # fmt: skip
        for bound in (lo, hi):
            why = model.parameter_problem(name, bound)
            if why:
                raise PydanticCustomError(
                    "orbits_second", f"{name} {why} (got {bound!r} as a bound of second_min/max)"
                )

    def resolved_min_step(self) -> float:
        return self.min_step if self.min_step is not None else self.step / 1000.0

    def resolved_max_step(self) -> float:
        return self.max_step if self.max_step is not None else 5.0 * self.step

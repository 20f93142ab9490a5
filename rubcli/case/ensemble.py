"""[ensemble]: the runs of `rubcli ensemble` (docs/reproduction.md), a cloud of starts
x a tolerance ladder."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from rubcli import model
from rubcli.case.base import MethodName, _Section, _state_problem, _unique

EnsembleParameter = Literal["nu", "eta", "e", "K", "mu", "Rp"]
MAX_ENSEMBLE_VALUES = 1000  # values of [ensemble] parameter
ENSEMBLE_BOX_KEYS = ("box_x", "box_y", "box_vx", "box_vy")


class EnsembleSection(_Section):
    """[ensemble]: the runs of `rubcli ensemble` and how each run's end is analysed.

    With ``parameter`` (and ``values`` or start/stop/num) the same starts are run at every
    value: the basin stability along the parameter (``rubcli.analysis.ensembles.basin_stability``).
    ``starts = "box"`` draws the starts uniformly over a box of the state space instead of
    the cloud within ``spread`` of the case's start.
    """

    runs: int = Field(default=20, ge=1, le=100_000)  # starts: the case's own and runs - 1 more
    spread: float = Field(default=1e-6, ge=0)  # distance of the other starts, clearances
    seed: int = Field(default=0, ge=0)  # of the random directions (or the box's draws)
    starts: Literal["spread", "box"] = "spread"  # a cloud around [initial], or a box
    box_x: list[float] | None = Field(default=None, min_length=2, max_length=2)  # [lo, hi]
    box_y: list[float] | None = Field(default=None, min_length=2, max_length=2)
    box_vx: list[float] | None = Field(default=None, min_length=2, max_length=2)
    box_vy: list[float] | None = Field(default=None, min_length=2, max_length=2)
    parameter: EnsembleParameter | None = None  # run the starts at each of its values
    values: list[float] | None = Field(default=None, min_length=1, max_length=MAX_ENSEMBLE_VALUES)
    start: float | None = None  # or a linear range start ... stop in num values
    stop: float | None = None
    num: int | None = Field(default=None, ge=2, le=MAX_ENSEMBLE_VALUES)
    minimal_perturbation: bool = False  # per value: the smallest kick off the free whirl
    perturbation_directions: int = Field(default=8, ge=0, le=1000)  # random, beside the axes
    perturbation_max: float = Field(default=2.0, gt=0, le=1e3)  # largest size tried
    perturbation_rtol: float = Field(default=0.02, gt=0, lt=0.5)  # bisection's bracket
    periods: int | None = Field(default=None, gt=0, le=10_000_000)  # default [time] periods
    record_periods: int = Field(default=200, ge=16)  # the end analysed (section, exponent)
    methods: list[MethodName] | None = Field(default=None, min_length=1)  # default [solver]'s first
    rtols: list[float] | None = Field(default=None, min_length=1)  # default [solver] rtol
    lyapunov: bool = True  # compute the exponent where the section map does not decide
    lyapunov_periods: int = Field(default=300, gt=0)
    settle_tolerance: float = Field(default=0.05, gt=0, lt=1)  # reached: closer than this
    max_wall_time_s: float | None = Field(default=None, gt=0)  # the run's budget (None: none)

    _methods_unique = field_validator("methods")(_unique)
    _values_unique = field_validator("values")(_unique)

    @field_validator("rtols")
    @classmethod
    def _rtols(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and not all(0.0 < v < 1e-2 for v in value):
            raise PydanticCustomError("rtols", "each rtol must lie in (0, 1e-2)")
        return value

    @field_validator(*ENSEMBLE_BOX_KEYS)
    @classmethod
    def _box_side(cls, value: list[float] | None) -> list[float] | None:
        if value is None:
            return value
        for v in value:
            why = _state_problem(v)
            if why:
                raise PydanticCustomError("ensemble_box", f"each bound {why} (got {v!r})")
        if not value[0] < value[1]:
            raise PydanticCustomError(
                "ensemble_box", "give [lo, hi] with lo < hi (got {value})", {"value": value}
            )
        return value

    @model_validator(mode="after")
    def _starts_and_parameter(self) -> EnsembleSection:
        given_box = [k for k in ENSEMBLE_BOX_KEYS if getattr(self, k) is not None]
        if self.starts == "box" and not given_box:
            raise PydanticCustomError(
                "ensemble_box",
                'starts = "box" needs at least one of box_x, box_y, box_vx, box_vy = [lo, hi] '
                "(a side not given stays at the case's [initial] value)",
            )
        if self.starts == "spread" and given_box:
            raise PydanticCustomError(
                "ensemble_box",
                f'{given_box[0]}: a box side is for starts = "box" (the starts are the '
                'spread cloud around [initial]); set starts = "box" or remove it',
            )
        ranged = {"start": self.start, "stop": self.stop, "num": self.num}
        if self.parameter is None:
            given = [k for k, v in {"values": self.values, **ranged}.items() if v is not None]
            if given:
                raise PydanticCustomError(
                    "ensemble_parameter",
                    f"{given[0]}: values of what? give parameter (one of nu, eta, e, K, mu, "
                    "Rp) too",
                )
            if self.minimal_perturbation:
                raise PydanticCustomError(
                    "ensemble_parameter",
                    "minimal_perturbation: computed at each value of a parameter: give "
                    "parameter and its values",
                )
            return self
        if self.values is not None and any(v is not None for v in ranged.values()):
            raise PydanticCustomError(
                "ensemble_parameter",
                "values, start/stop/num: give either values = [...] or start, stop and num, "
                "not both",
            )
        if self.values is None and any(v is None for v in ranged.values()):
            missing = ", ".join(k for k, v in ranged.items() if v is None)
            raise PydanticCustomError(
                "ensemble_parameter",
                f"parameter = {self.parameter}: give values = [...] or start, stop and num "
                f"(missing: {missing})",
            )
        if self.values is None and self.start == self.stop:
            raise PydanticCustomError(
                "ensemble_parameter",
                f"start, stop: a range needs start != stop (both {self.start!r})",
            )
        for value in self.parameter_values():
            why = model.parameter_problem(self.parameter, value)
            if why:
                field = "values" if self.values is not None else "start/stop"
                raise PydanticCustomError(
                    "ensemble_parameter",
                    f"{field}: every value of {self.parameter} {why} (got {value!r})",
                )
        return self

    def parameter_values(self) -> tuple[float, ...]:
        """The values of ``parameter`` in the order given (a linear range start ... stop,
        each rounded to 12 significant digits: 1.8, not linspace's 1.7999999999999998);
        empty without a parameter."""
        if self.values is not None:
            return tuple(float(v) for v in self.values)
        if self.start is None or self.stop is None or self.num is None:
            return ()
        grid = np.linspace(self.start, self.stop, self.num)
        return tuple(float(f"{v:.12g}") for v in grid)

    def box(self) -> dict[str, tuple[float, float] | None]:
        """The box of starts by state coordinate (None: held at the case's [initial])."""
        return {k.removeprefix("box_"): (None if getattr(self, k) is None
                                         else tuple(getattr(self, k)))
                for k in ENSEMBLE_BOX_KEYS}  # fmt: skip

"""[chart]: the plane of two model parameters of `rubcli chart` (docs/charts.md)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from rubcli import model
from rubcli.case.base import _Section

ChartParameter = Literal["nu", "eta", "e", "K", "mu", "Rp"]
MAX_CHART_GRID = 2001  # grid values per axis


class ChartSection(_Section):
    """[chart]: the plane of the stability chart (nondimensional, also for [physical] cases);
    every other parameter is the case's."""

    x: ChartParameter  # the horizontal parameter
    x_min: float
    x_max: float
    y: ChartParameter  # the vertical parameter
    y_min: float
    y_max: float
    nx: int = Field(default=201, ge=2, le=MAX_CHART_GRID)  # grid values of x
    ny: int = Field(default=101, ge=2, le=MAX_CHART_GRID)  # grid values of y
    x_spacing: Literal["linear", "log"] = "linear"  # of the grid values of x
    y_spacing: Literal["linear", "log"] = "linear"
    check_points: int = Field(default=0, ge=0, le=50)  # values of x checked by continuation
    max_wall_time_s: float = Field(default=3600.0, gt=0)  # the run's budget, seconds

    @model_validator(mode="after")
    def _plane(self) -> ChartSection:
        if self.x == self.y:
            raise PydanticCustomError(
                "chart_plane", "x and y must be two different parameters (both are {name})",
                {"name": self.x},
            )  # fmt: skip
        for axis in ("x", "y"):
            name, lo, hi = (
                getattr(self, axis),
                getattr(self, f"{axis}_min"),
                getattr(self, f"{axis}_max"),
            )
            if not lo < hi:
                raise PydanticCustomError(
                    "chart_window", f"{axis}_min must be below {axis}_max (got {lo!r}, {hi!r})"
                )
            if getattr(self, f"{axis}_spacing") == "log" and not lo > 0.0:
                raise PydanticCustomError(
                    "chart_window",
                    f'{axis}_spacing = "log" needs {axis}_min > 0 (got {lo!r})',
                )
            for bound in (lo, hi):
                why = model.parameter_problem(name, bound)
                if why:
                    raise PydanticCustomError(
                        "chart_window", f"{axis} = {name}: {name} {why} (got {bound!r} as a bound)"
                    )
        return self

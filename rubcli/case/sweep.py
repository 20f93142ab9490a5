"""[sweep]: the schema of `rubcli sweep` (docs/sweeps.md), its memory estimate and the
checks of a sweep against the case's machine. The engine is rubcli.analysis.sweep."""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
from pydantic import Field, ValidationError, field_validator, model_validator
from pydantic_core import PydanticCustomError

from rubcli import model
from rubcli.case.base import MethodName, _Section, _state_problem, _unique
from rubcli.model import ModelParams
from rubcli.problem import resolution_problem

SweepParameter = Literal[
    "nu", "eta", "e", "K", "mu", "Rp", "phi0", "x", "y", "vx", "vy",
    # the general machine's (model.MACHINE_PARAMETERS)
    "offset", "offset_x", "offset_y", "load", "load_x", "load_y", "k_xx", "k_xy", "k_yx",
    "k_yy", "cross_coupling", "stator_mass", "stator_k_x", "stator_k_y",
]  # fmt: skip
# Pairs of sweep axes that set the same entry of the machine (model.with_value): a point
# of both would hold only the later one's value, so one axis would change nothing.
OVERLAPPING_AXES = {
    ("offset", "offset_x"): "the offset's c_x",
    ("offset", "offset_y"): "the offset's c_y",
    ("load", "load_x"): "the load's g_x",
    ("load", "load_y"): "the load's g_y",
    ("cross_coupling", "k_xy"): "the support stiffness k_xy",
    ("cross_coupling", "k_yx"): "the support stiffness k_yx",
}
SWEEP_MODEL_PARAMETERS: tuple[str, ...] = ("nu", "eta", "e", "K", "mu", "Rp", "phi0")
SWEEP_INITIAL_PARAMETERS: tuple[str, ...] = ("x", "y", "vx", "vy")
SweepDirection = Literal["up", "down", "both", "independent"]
DEFAULT_SWEEP_MAX_POINTS = 20_000


class SweepAxis(_Section):
    """One swept axis: a parameter and its values (a list, or start/stop/num)."""

    parameter: SweepParameter
    values: list[float] | None = Field(default=None, min_length=1)
    start: float | None = None
    stop: float | None = None
    num: int | None = Field(default=None, ge=1, le=1_000_000)
    spacing: Literal["linear", "log"] = "linear"

    _values_unique = field_validator("values")(_unique)

    @model_validator(mode="after")
    def _values_or_range(self) -> SweepAxis:
        ranged = (self.start, self.stop, self.num)
        if self.values is not None:
            if any(v is not None for v in ranged):
                raise PydanticCustomError(
                    "sweep_values", "give either values or start/stop/num, not both"
                )
        elif any(v is None for v in ranged):
            raise PydanticCustomError(
                "sweep_values", "give values = [...] or all of start, stop and num"
            )
        elif self.spacing == "log" and not (self.start > 0 and self.stop > 0):
            raise PydanticCustomError("sweep_values", "log spacing needs start > 0 and stop > 0")
        elif self.num == 1 and self.start != self.stop:
            raise PydanticCustomError("sweep_values", "num = 1 needs start = stop")
        return self

    def resolved_values(self) -> tuple[float, ...]:
        """The axis values in the order given (a range from start to stop)."""
        if self.values is not None:
            return tuple(float(v) for v in self.values)
        assert self.start is not None and self.stop is not None and self.num is not None
        if self.spacing == "log":
            grid = np.geomspace(self.start, self.stop, self.num)
        else:
            grid = np.linspace(self.start, self.stop, self.num)
        return tuple(float(v) for v in grid)


class RecognitionSection(_Section):
    """[sweep.recognition]: attractor recognition with early stopping on a basin grid
    (docs/sweeps.md, "Basins at full resolution"). On by default for a basin grid."""

    enabled: bool = True
    tolerance: float = Field(default=0.01, gt=0, le=1)  # normalised section distance
    consecutive: int = Field(default=10, ge=1, le=10_000)  # periods in a row on it
    basin_cell: float = Field(default=0.05, ge=0, le=1)  # 0: no basin cells
    basin_hits: int = Field(default=3, ge=1, le=10_000)  # periods in a row in its cells
    check_every: int = Field(default=5, ge=1, le=10_000)  # periods between looks
    seed_points: int = Field(default=64, ge=1, le=100_000)  # starts learned from first
    escape_radius: float = Field(default=1e3, gt=0, le=1e6)  # diverged beyond this


class SweepSection(_Section):
    """[sweep]: settings of `rubcli sweep` (bifurcation diagrams, maps, basins).

    A 1-D sweep can be written inline (``parameter`` with ``values`` or start/stop/num);
    a 2-D map or an initial-condition grid lists its axes as ``[[sweep.axes]]``.
    """

    parameter: SweepParameter | None = None
    values: list[float] | None = Field(default=None, min_length=1)
    start: float | None = None
    stop: float | None = None
    num: int | None = Field(default=None, ge=1, le=1_000_000)
    spacing: Literal["linear", "log"] = "linear"
    axes: list[SweepAxis] | None = Field(default=None, min_length=1, max_length=2)
    direction: SweepDirection = "independent"
    transient_periods: int = Field(default=200, ge=0)
    record_periods: int = Field(default=100, ge=8)  # section points (>= 8 to classify)
    method: MethodName = "dop853-jit"  # its settings come from [solver]
    energy: bool = True  # energy residual of the recorded window
    spectrum: bool = False  # keep each point's full spectrum (for the waterfall)
    spectrum_max_order: float = Field(default=3.0, gt=0)  # kept orders: -this ... +this
    lyapunov: bool = False  # largest Lyapunov exponent of every point (costly)
    lyapunov_periods: int = Field(default=100, gt=0)
    max_points: int = Field(default=DEFAULT_SWEEP_MAX_POINTS, ge=1)  # budget
    max_wall_time_s: float | None = Field(default=None, gt=0)  # the run's budget (None: none)
    scheduler: str | None = Field(default=None, min_length=1)  # Dask scheduler address
    scheduler_timeout_s: float = Field(default=10.0, gt=0, le=600)  # bounded connect wait
    # how long a Dask sweep waits for a lost scheduler, or for a worker when none is left
    scheduler_lost_timeout_s: float = Field(default=60.0, gt=0, le=3600)
    recognition: RecognitionSection = Field(default_factory=RecognitionSection)

    _values_unique = field_validator("values")(_unique)

    @model_validator(mode="after")
    def _check(self) -> SweepSection:
        inline = (self.values, self.start, self.stop, self.num)
        if self.axes is not None:
            if self.parameter is not None or any(v is not None for v in inline):
                raise PydanticCustomError(
                    "sweep_axes",
                    "give the axes either inline (parameter, values or start/stop/num) or as "
                    "[[sweep.axes]], not both",
                )
        elif self.parameter is None:
            raise PydanticCustomError(
                "sweep_axes", "missing parameter (or [[sweep.axes]]): what is swept?"
            )
        try:
            axes = self.resolved_axes()
        except ValidationError as exc:
            raise PydanticCustomError("sweep_values", exc.errors()[0]["msg"]) from None
        names = [a.parameter for a in axes]
        if len(set(names)) != len(names):
            raise PydanticCustomError("sweep_axes", "the two axes sweep the same parameter")
        for a, b in OVERLAPPING_AXES:
            if {a, b} <= set(names):
                raise PydanticCustomError(
                    "sweep_axes",
                    f"the axes {a} and {b} both set {OVERLAPPING_AXES[a, b]}, so the one "
                    "applied later overrides the other; sweep the components together or "
                    "one of them alone",
                )
        initial = [n in SWEEP_INITIAL_PARAMETERS for n in names]
        if any(initial) and not all(initial):
            raise PydanticCustomError(
                "sweep_axes",
                "mixes a model parameter and an initial-state axis; sweep either model "
                "parameters or the initial state (a basin grid), not both",
            )
        # (a table equal to the defaults is harmless: a case re-validated with overrides
        # carries every field, so "given" cannot be told from "defaulted")
        if not all(initial) and self.recognition != RecognitionSection():
            raise PydanticCustomError(
                "sweep_recognition",
                "[sweep.recognition] is for a grid of start states (basins): a point of a "
                "model-parameter sweep has attractors of its own; remove the table",
            )
        if all(initial) and self.direction != "independent":
            raise PydanticCustomError(
                "sweep_direction",
                "an initial-state grid (basins) starts every point from its own state: "
                "direction must be 'independent'",
            )
        for axis in axes:
            values = axis.resolved_values()
            for value in (min(values), max(values)):  # (each domain is an interval)
                if axis.parameter in SWEEP_MODEL_PARAMETERS:
                    why = model.parameter_problem(axis.parameter, value)
                elif axis.parameter in model.MACHINE_PARAMETERS:
                    why = None  # against the case's machine: _sweep_machine_problem
                else:
                    why = _state_problem(value)
                if why:
                    raise PydanticCustomError(
                        "sweep_values", f"every value of {axis.parameter} {why} (got {value!r})"
                    )
        n = self.n_points()
        if n > self.max_points:
            raise PydanticCustomError(
                "sweep_budget",
                "{n} points (values x directions) is more than max_points = {limit}",
                {"n": n, "limit": self.max_points},
            )
        return self

    def resolved_axes(self) -> list[SweepAxis]:
        """The axes, whichever way they were written."""
        if self.axes is not None:
            return list(self.axes)
        assert self.parameter is not None
        given = {"values": self.values, "start": self.start, "stop": self.stop, "num": self.num}
        given = {k: v for k, v in given.items() if v is not None}
        return [SweepAxis(parameter=self.parameter, spacing=self.spacing, **given)]

    def n_points(self) -> int:
        """Points to compute: product of the axis sizes, twice for direction = both."""
        n = 1
        for axis in self.resolved_axes():
            n *= len(axis.resolved_values())
        return n * (2 if self.direction == "both" else 1)


SWEEP_MIN_SAMPLES = 8  # as analysis.sweep.plan.SweepPlan requires
# What a sweep holds until its files are written (benchmarks/sweep_memory.py: the slope
# of the peak RSS between two sizes). A point of a model-parameter sweep measured 3,000
# bytes plus 174 per recorded period (247 with its spectrum); a start of a basin grid
# with recognition 340 (its label, time and cost, and its CSV row). With a margin:
SWEEP_POINT_BYTES = 4500
SWEEP_PERIOD_BYTES = 300
BASIN_START_BYTES = 500


def sweep_memory(sweep: SweepSection) -> tuple[float, str]:
    """The bytes a sweep holds until its files are written, and what they are for."""
    n = sweep.n_points()
    basin = all(a.parameter in SWEEP_INITIAL_PARAMETERS for a in sweep.resolved_axes())
    if basin and sweep.recognition.enabled:
        return n * BASIN_START_BYTES, f"{n} starts"
    per_point = SWEEP_POINT_BYTES + SWEEP_PERIOD_BYTES * sweep.record_periods
    return n * per_point, f"{n} points of {sweep.record_periods} recorded periods"


SWEEP_POINTS_IN_MEMORY = 8  # points solved at once on a machine of up to 8 cores


def _sweep_machine_problem(cfg: SweepSection, params: ModelParams) -> str | None:
    """Why a sweep over the general machine's parameters leaves the model's domain at an
    end of an axis (each entry's domain, a positive-definite stiffness among them, is an
    interval in that entry), or None."""
    axes = cfg.resolved_axes()
    if params.stator is not None and axes and axes[0].parameter in ("x", "y", "vx", "vy"):
        return ("an initial-state grid (basins) starts the rotor alone; with a [stator] sweep "
                "model parameters")  # fmt: skip
    for axis in axes:
        if axis.parameter not in model.MACHINE_PARAMETERS:
            continue
        values = axis.resolved_values()
        for value in (min(values), max(values)):
            try:
                model.with_value(params, axis.parameter, value)
            except ValueError as exc:
                why = str(exc).removeprefix("ModelParams: ")
                return f"{axis.parameter} = {value!r} makes a machine that is not one: {why}"
    return None


def _sweep_resolution_problem(cfg: SweepSection, params: ModelParams) -> str | None:
    """Why the stiffest, slowest point of a sweep (largest K, smallest eta over its axes)
    cannot be resolved over its longest run, or None (``problem.resolution_problem``)."""
    K, eta = params.K, params.eta
    for axis in cfg.resolved_axes():
        if axis.parameter == "K":
            K = max(axis.resolved_values())
        elif axis.parameter == "eta":
            eta = min(axis.resolved_values())
    worst = dataclasses.replace(params, K=K, eta=eta)
    periods = max(cfg.transient_periods, cfg.record_periods, cfg.lyapunov_periods, 1)
    t_end = periods * worst.period
    if not t_end <= model.MAX_MAGNITUDE:
        return f"at eta = {eta:g}, {periods} periods end beyond tau = {model.MAX_MAGNITUDE:g}"
    why = resolution_problem(worst, (0.0, t_end))
    return None if why is None else f"at K = {K:g}, eta = {eta:g}: {why}"

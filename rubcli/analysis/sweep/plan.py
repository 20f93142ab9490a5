"""What a sweep computes: the axes, the points and the chains that connect them.

A *point* is one set of parameters (and, for a basin grid, one start state) at one sweep
direction. A *chain* is a sequence of points run one after the other, each continuing
from the final state of the previous one (a run-up or run-down of the machine); a point
of an ``independent`` sweep is a chain of its own and starts from the case's initial
state (or its own grid state). Chains are independent of each other and run in parallel.

Axis values are kept in ascending order (the coordinates of the result); ``up`` walks the
first axis upwards, ``down`` downwards; a 2-D map has one chain per value of its second
axis. Nothing here imports pydantic or the case loader: ``rubcli.sweeps`` builds a plan
from a case.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from itertools import product
from typing import TYPE_CHECKING

from rubcli import model
from rubcli.analysis.sweep.attractors import Recognition
from rubcli.model import ModelParams

if TYPE_CHECKING:
    from collections.abc import Iterable

MODEL_AXES = ("nu", "eta", "e", "K", "mu", "Rp", "phi0", *model.MACHINE_PARAMETERS)
INITIAL_AXES = ("x", "y", "vx", "vy")
DIRECTIONS = ("up", "down", "both", "independent")
STATE_NAMES = ("x", "y", "vx", "vy")


def point_key(direction: str, index: Iterable[int]) -> str:
    """The name of a point in results and in the store: ``up-3``, ``independent-2-7``."""
    return f"{direction}-" + "-".join(str(int(i)) for i in index)


def dim_name(parameter: str) -> str:
    """The dimension name of an axis: the model name, or ``x0`` ... for a start state."""
    return f"{parameter}0" if parameter in INITIAL_AXES else parameter


@dataclass(frozen=True)
class Axis:
    """A swept parameter and its values (ascending, unique)."""

    parameter: str
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.parameter not in MODEL_AXES + INITIAL_AXES:
            raise ValueError(f"unknown sweep parameter {self.parameter!r}")
        values = tuple(sorted(float(v) for v in self.values))
        if not values or not all(math.isfinite(v) for v in values):
            raise ValueError(f"axis {self.parameter}: values must be finite and not empty")
        if len(set(values)) != len(values):
            raise ValueError(f"axis {self.parameter}: repeated values")
        object.__setattr__(self, "values", values)

    @property
    def dim(self) -> str:
        return dim_name(self.parameter)


@dataclass(frozen=True)
class Point:
    """One point: its direction, its index in the grid (one per axis) and its values."""

    direction: str  # "up", "down" or "independent"
    index: tuple[int, ...]
    params: ModelParams
    start: tuple[float, ...] | None  # None: continue the chain

    @property
    def key(self) -> str:
        return point_key(self.direction, self.index)


@dataclass(frozen=True)
class Chain:
    """Points run in order, each from the previous one's final state."""

    name: str
    points: tuple[Point, ...]


@dataclass(frozen=True)
class SweepPlan:
    """Everything that determines a sweep's numbers (and nothing about where it runs)."""

    params: ModelParams  # the case's machine; the swept parameters are replaced per point
    initial: tuple[float, ...]  # the rotor's state, and a moving stator's after it
    axes: tuple[Axis, ...]
    direction: str = "independent"
    transient_periods: int = 200
    record_periods: int = 100
    samples_per_period: int = 32
    method: str = "dop853-jit"
    options: dict = field(default_factory=dict)  # solver options (options_for the method)
    energy: bool = True
    spectrum: bool = False
    spectrum_max_order: float = 3.0
    lyapunov: bool = False
    lyapunov_periods: int = 100
    name: str = "sweep"
    recognition: Recognition | None = None  # a basin grid with early stopping (basins.py)

    def __post_init__(self) -> None:
        if not 1 <= len(self.axes) <= 2:
            raise ValueError("a sweep has one or two axes")
        if self.direction not in DIRECTIONS:
            raise ValueError(f"direction must be one of {', '.join(DIRECTIONS)}")
        kinds = {a.parameter in INITIAL_AXES for a in self.axes}
        if len(kinds) > 1:
            raise ValueError("cannot mix model parameters and initial-state axes")
        if self.is_basin and self.direction != "independent":
            raise ValueError("an initial-state grid needs direction = 'independent'")
        if self.recognition is not None and not self.is_basin:
            raise ValueError("attractor recognition is for a grid of start states (basins)")
        if self.record_periods < 8 or self.transient_periods < 0:
            raise ValueError("record_periods must be >= 8 and transient_periods >= 0")
        if self.samples_per_period < 8:
            raise ValueError("samples_per_period must be >= 8 (the spectrum and contact)")
        object.__setattr__(self, "axes", tuple(self.axes))
        object.__setattr__(self, "initial", tuple(float(v) for v in self.initial))

    # ---------------------------------------------------------------- structure

    @property
    def is_basin(self) -> bool:
        return self.axes[0].parameter in INITIAL_AXES

    @property
    def directions(self) -> tuple[str, ...]:
        """The values of the result's ``direction`` dimension."""
        if self.direction == "both":
            return ("up", "down")
        return (self.direction,)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(a.values) for a in self.axes)

    @property
    def n_points(self) -> int:
        return math.prod(self.shape) * len(self.directions)

    @property
    def n_chains(self) -> int:
        """Chains that can run side by side: every point when independent, else one per
        direction and row of the other axes."""
        per_direction = math.prod(self.shape[1:])
        return sum(
            math.prod(self.shape) if d == "independent" else per_direction for d in self.directions
        )

    def point(self, direction: str, index: tuple[int, ...]) -> Point:
        values = {a.parameter: a.values[i] for a, i in zip(self.axes, index, strict=True)}
        params = self.params
        for k, v in values.items():
            if k in MODEL_AXES:
                params = model.with_value(params, k, v)
        start: tuple[float, ...] | None = None
        if direction == "independent" or index[0] == self._first_index(direction):
            state = list(self.initial)
            for k, v in values.items():
                if k in INITIAL_AXES:
                    state[INITIAL_AXES.index(k)] = v
            start = tuple(state)  # (a moving stator's four states after the rotor's)
        return Point(direction, tuple(index), params, start)

    def _first_index(self, direction: str) -> int:
        return 0 if direction == "up" else self.shape[0] - 1

    def chains(self) -> list[Chain]:
        """The chains, in a fixed order (it does not change the numbers, only the schedule)."""
        out: list[Chain] = []
        rows = list(product(*(range(n) for n in self.shape[1:])))
        for direction in self.directions:
            if direction == "independent":
                for index in product(*(range(n) for n in self.shape)):
                    point = self.point(direction, index)
                    out.append(Chain(point.key, (point,)))
                continue
            first = range(self.shape[0])
            order = first if direction == "up" else reversed(first)
            ordered = list(order)
            for row in rows:
                points = tuple(self.point(direction, (i, *row)) for i in ordered)
                out.append(Chain(f"{direction}-row-" + "-".join(map(str, row)), points))
        return out

    # ---------------------------------------------------------------- identity

    def to_dict(self) -> dict:
        """The plan as plain data (echoed in the results and hashed for resumption)."""
        return {
            "name": self.name,
            "params": {**self.params.as_dict(), **self.params.machine_dict()},
            "initial": list(self.initial),
            "axes": [{"parameter": a.parameter, "values": list(a.values)} for a in self.axes],
            "direction": self.direction,
            "transient_periods": self.transient_periods,
            "record_periods": self.record_periods,
            "samples_per_period": self.samples_per_period,
            "method": self.method,
            "options": {k: self.options[k] for k in sorted(self.options)},
            "energy": self.energy,
            "spectrum": self.spectrum,
            "spectrum_max_order": self.spectrum_max_order,
            "lyapunov": self.lyapunov,
            "lyapunov_periods": self.lyapunov_periods,
            **({} if self.recognition is None else {"recognition": self.recognition.to_dict()}),
        }

    def digest(self) -> str:
        """A hash of everything that changes the numbers: the key of the resumable store."""
        from rubcli.version import __version__

        text = json.dumps({"plan": self.to_dict(), "rubcli": __version__}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

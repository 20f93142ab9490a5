"""Case files: the TOML schema (pydantic) and loading a case into a Problem plus settings.

Loading goes in three steps, each a function that can be used alone:

1. ``read_case_file(path)``: read the file and parse TOML (missing file, not TOML -> error);
2. ``validate_case(raw, source)``: validate against the schema (``CaseFile``);
3. ``assemble_case(settings, path)``: fill the defaults, convert physical units once
   (``rubcli.units``) and build the nondimensional ``Problem``.

``load_case(path)`` does all three. Every problem is reported as a ``CaseError`` whose
message has one line per problem, naming the file, the dotted field and what is wrong::

    my.toml: model.K: Input should be greater than 0 (got -1.0)

The key names are a contract with users: add keys, don't rename them. The full
reference is ``docs/cases.md``. The method names come from the registry's data
(``rubcli.solvers.registry``), which loads no solver.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import stat
import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from rubcli import model, units
from rubcli.analysis.orbit_bounds import (
    MIN_ORBIT_STEP_FRACTION,
    ORBITS_BOUNDS,
    ORBITS_WALL_TIME_S,
)
from rubcli.drive import Drive
from rubcli.model import ModelParams
from rubcli.problem import MAX_OUTPUT_SAMPLES, Problem, resolution_problem
from rubcli.solvers import registry
from rubcli.speed import SpeedProfile
from rubcli.stator import Stator

MethodName = Literal[registry.NAMES]  # every method of the registry
KNOWN_METHODS: tuple[str, ...] = get_args(MethodName)

PlotName = Literal["orbit", "time", "energy", "spectrum"]
KNOWN_PLOTS: tuple[str, ...] = get_args(PlotName)
DEFAULT_PLOTS: tuple[str, ...] = ("orbit", "time")  # "energy" only when asked

ForcesMapProduct = Literal["forces", "taylor_error", "eigen"]

# Defaults of [forces_map] when a list is not given (notes 2.8 and section 6).
DEFAULT_FORCES_MAP_DELTAS: tuple[float, ...] = tuple(float(d) for d in np.logspace(-6, -1, 11))
DEFAULT_FORCES_MAP_K_VALUES: tuple[float, ...] = (17.6, 1.76e3, 1.76e5, 1.75e6)

# Every size a case can set is bounded by a memory estimate, refused at validation:
# - a run holds, per method and output sample, t, the state, the regime and the arrays of
#   its report (energy balance, regimes): about RUN_BYTES_PER_SAMPLE bytes (measured: 580
#   bytes per sample for the paper's case over 1,000,001 samples, benchmarks/RESULTS.md);
# - `forces-map` holds at its peak FORCES_MAP_BYTES_PER_POINT bytes per grid point beside
#   the process's own FORCES_MAP_BASE_BYTES (measured for each product and for all three:
#   at most 172 bytes per point and 380 MiB, benchmarks/forces_map_memory.md), kept with
#   a 25 % margin. At run time it must also fit in the memory the process may take.
MAX_CASE_MEMORY_BYTES = 8 * 1024**3
RUN_BYTES_PER_SAMPLE = 600
RUN_BASE_BYTES = 640 * 1024**2  # a small run's own address space (609 MiB measured)
FORCES_MAP_BYTES_PER_POINT = 215
FORCES_MAP_BASE_BYTES = 512 * 1024**2


def run_memory_bytes(n_samples: int, n_methods: int) -> int:
    """The peak memory of ``rubcli run`` keeping ``n_samples`` output samples per method."""
    return RUN_BASE_BYTES + RUN_BYTES_PER_SAMPLE * n_samples * n_methods


def forces_map_memory_bytes(resolution: int) -> int:
    """The peak memory of ``rubcli forces-map`` on a ``resolution`` x ``resolution`` grid."""
    return FORCES_MAP_BASE_BYTES + FORCES_MAP_BYTES_PER_POINT * resolution * resolution


def largest_forces_map_resolution(memory_bytes: float) -> int:
    """The largest grid side whose ``forces_map_memory_bytes`` fits in ``memory_bytes``."""
    points = (memory_bytes - FORCES_MAP_BASE_BYTES) / FORCES_MAP_BYTES_PER_POINT
    return math.isqrt(int(max(points, 0)))


# A case file is a few kB of TOML (a sweep's value list some 100 kB): a larger file is
# refused before it is read.
MAX_CASE_FILE_BYTES = 8 * 1024**2

CASE_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]*$"

PositiveFloat = Annotated[float, Field(gt=0)]


def _gib(n_bytes: float) -> str:
    return f"{n_bytes / 1024**3:.3g} GiB"


def _short_repr(value: object, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (a 5 MB value is not echoed whole)."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f"{text[: limit - 25]}... ({len(text)} characters)"


class CaseError(Exception):
    """An invalid case: ``problems`` has one line per problem, each naming file and field."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


class _Section(BaseModel):
    """Common configuration: unknown keys are errors, no NaN or infinity, no coercion.

    ``strict`` keeps TOML's own types: a string is never read as a number, a float never
    as an integer (an integer is still accepted where a float is expected).
    """

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)


def _unique(values: list) -> list:
    """Field validator: a list without repeated entries."""
    seen = set()
    for value in values:
        if value in seen:
            raise PydanticCustomError("duplicate", "'{value}' is listed twice", {"value": value})
        seen.add(value)
    return values


# ============================================================================ [case]


class CaseSection(_Section):
    """[case]: the name (used for the default output dir) and an optional description."""

    name: str = Field(pattern=CASE_NAME_PATTERN, max_length=100)
    description: str = ""


# ============================================================ [model] or [physical]


# a vector [x, y] and a 2x2 matrix [[xx, xy], [yx, yy]] of a case file
Pair = Annotated[list[float], Field(min_length=2, max_length=2)]
Matrix = Annotated[list[Pair], Field(min_length=2, max_length=2)]


def _general_problem(name: str, value: Pair | Matrix | None) -> None:
    """A general machine's vector or matrix outside the model's domain (too large; a
    support matrix without a rest position or that feeds energy in): PydanticCustomError."""
    if value is None:
        return
    entries = [v for row in value for v in row] if name in ("stiffness", "damping") else value
    for v in entries:
        if abs(v) > model.MAX_MAGNITUDE:
            raise PydanticCustomError(
                "model_domain",
                f"entries must be at most {model.MAX_MAGNITUDE:g} in size (the model's domain, "
                "docs/cases.md)",
            )
    if name in ("stiffness", "damping"):
        why = model.support_problem(name, value)
        if why:
            raise PydanticCustomError("support_matrix", why)


class ModelSection(_Section):
    """[model]: nondimensional parameters (notes section 1), and the general machine's
    (docs/machines.md): all in the model's units (clearances, k_r clearance)."""

    nu: float | None = Field(default=None, ge=0)  # damping ratio d_r / (2 omega m)
    eta: float | None = Field(default=None, gt=0)  # speed ratio Omega / omega (or [speed])
    e: float = Field(ge=0)  # unbalance eccentricity / clearance
    K: float = Field(gt=0)  # stator / rotor stiffness ratio
    mu: float = Field(default=0.0, ge=0)  # Coulomb friction coefficient
    Rp: float = Field(default=0.0, ge=0)  # rotor radius / clearance
    phi0: float = 0.0  # unbalance phase, rad
    offset: Pair | None = None  # the stator's centre from the support's, clearances
    load: Pair | None = None  # a static force on the rotor, units of k_r clearance
    stiffness: Matrix | None = None  # the support stiffness matrix over k_r
    damping: Matrix | None = None  # the support damping matrix (forces 2 D w'), or nu

    @field_validator("nu", "eta", "e", "K", "mu", "Rp", "phi0")
    @classmethod
    def _in_the_models_domain(cls, value: float | None, info) -> float | None:
        """The model's domain (``model.parameter_problem``), the rule a [physical] table's
        converted values are checked against too."""
        if value is None:  # eta given by [speed]; nu by damping
            return value
        problem = model.parameter_problem(info.field_name, value)
        if problem:
            raise PydanticCustomError("model_domain", problem)
        return value

    @field_validator("offset", "load", "stiffness", "damping")
    @classmethod
    def _general_in_domain(cls, value, info):
        _general_problem(info.field_name, value)
        return value

    @model_validator(mode="after")
    def _damping_once(self) -> ModelSection:
        if self.nu is not None and self.damping is not None:
            raise PydanticCustomError(
                "damping_twice",
                "damping: the support damping is given twice, as nu and as damping; give one "
                "(damping = [[nu, 0], [0, nu]] is the isotropic nu)",
            )
        if self.nu is None and self.damping is None:
            raise PydanticCustomError("damping_missing", "nu: missing (or give damping)")
        return self

    def params(self) -> ModelParams:
        return ModelParams(**machine_values(self.model_dump()))


def machine_values(values: dict[str, Any]) -> dict[str, Any]:
    """A [model] table's (or [physical]'s converted) values as ``ModelParams`` takes them:
    the general machine's entries left out where not given, nu 0 with a damping matrix."""
    out = {k: v for k, v in values.items() if v is not None or k == "eta"}
    if out.get("damping") is not None:
        out["nu"] = 0.0
    return out


class PhysicalSection(_Section):
    """[physical]: the same machine in SI units, converted once by ``rubcli.units``."""

    m: float = Field(gt=0)  # rotor mass, kg
    k_r: float = Field(gt=0)  # rotor (shaft) stiffness, N/m
    d_r: float | None = Field(default=None, ge=0)  # rotor damping, N s/m (or damping)
    k_s: float = Field(gt=0)  # stator stiffness, N/m
    clearance: float = Field(gt=0)  # radial clearance, m
    e: float = Field(ge=0)  # unbalance eccentricity, m
    Omega: float | None = Field(default=None, gt=0)  # spin speed, rad/s (or [speed])
    Rp: float = Field(default=0.0, ge=0)  # rotor radius at the rub, m
    mu: float = Field(default=0.0, ge=0)  # Coulomb friction coefficient
    phi0: float = 0.0  # unbalance phase, rad
    offset: Pair | None = None  # the stator's centre from the support's, m
    load: Pair | None = None  # a static force on the rotor, N
    stiffness: Matrix | None = None  # the support stiffness matrix, N/m (k_r the reference)
    damping: Matrix | None = None  # the support damping matrix, N s/m (instead of d_r)

    @field_validator("stiffness", "damping")
    @classmethod
    def _support(cls, value, info):
        _general_problem(info.field_name, value)
        return value

    @model_validator(mode="after")
    def _damping_once(self) -> PhysicalSection:
        if self.d_r is not None and self.damping is not None:
            raise PydanticCustomError(
                "damping_twice",
                "damping: the support damping is given twice, as d_r and as damping; give one",
            )
        if self.d_r is None and self.damping is None:
            raise PydanticCustomError("damping_missing", "d_r: missing (or give damping)")
        return self


# ========================================================================== [stator]


class StatorSection(_Section):
    """[stator]: a stator (snubber ring) with its own mass on its own supports
    (``rubcli.stator``); no [stator] is the rigid stator. With [model]: the mass ratio
    M_s / m, the stiffness ratios k_s / k_r, the damping n_s (forces 2 n_s s'). With
    [physical]: kg, N/m and N s/m, converted once."""

    mass: float = Field(gt=0)
    stiffness: Pair
    damping: Pair = Field(default_factory=lambda: [0.0, 0.0])

    @field_validator("stiffness")
    @classmethod
    def _positive(cls, value: list[float]) -> list[float]:
        if not all(v > 0.0 for v in value):
            raise PydanticCustomError(
                "stator_stiffness",
                "both entries must be > 0 (a stator without support has no rest position)",
            )
        return value

    @field_validator("damping")
    @classmethod
    def _not_negative(cls, value: list[float]) -> list[float]:
        if not all(v >= 0.0 for v in value):
            raise PydanticCustomError("stator_damping", "both entries must be >= 0")
        return value

    def stator(self, physical: PhysicalSection | None) -> Stator:
        """The nondimensional stator (converted from SI with [physical]: over m, k_r and
        2 sqrt(k_r m), as the rotor's own)."""
        if physical is None:
            return Stator(self.mass, tuple(self.stiffness), tuple(self.damping))
        m, k_r = physical.m, physical.k_r
        unit = 2.0 * math.sqrt(k_r * m)
        return Stator(
            self.mass / m,
            (self.stiffness[0] / k_r, self.stiffness[1] / k_r),
            (self.damping[0] / unit, self.damping[1] / unit),
        )


# =========================================================================== [speed]

SpeedProfileName = Literal["ramp", "table", "driven"]
SpeedUnit = Literal["rpm", "rad/s"]


class SpeedSection(_Section):
    """[speed]: a speed that changes in time (docs/runup.md). With [model]: speeds as eta,
    ``rate`` in d eta / d tau, ``tau`` in tau. With [physical]: speeds in ``unit`` (rpm
    unless given), ``rate`` in that unit per second, ``t`` in seconds."""

    model_config = ConfigDict(populate_by_name=True)

    profile: SpeedProfileName
    start: float | None = Field(default=None, alias="from", gt=0)  # ramp; driven: at tau 0
    to: float | None = Field(default=None, gt=0)  # ramp
    rate: float | None = None  # ramp: signed, its sign that of to - from
    tau: list[float] | None = Field(default=None, min_length=2)  # table, [model]
    eta: list[float] | None = Field(default=None, min_length=2)  # table, [model]
    t: list[float] | None = Field(default=None, min_length=2)  # table, [physical]: s
    speed: list[float] | None = Field(default=None, min_length=2)  # table, [physical]
    unit: SpeedUnit | None = None  # [physical] only
    # driven: the polar moment about the geometric centre (j, or kg m^2 with [physical]),
    # the motor (linear: stall torque and no-load speed; or a table of speed and torque;
    # torques nondimensional, or N m) and the bearing drag (torque per speed; N m s)
    inertia: float | None = Field(default=None, gt=0)
    stall_torque: float | None = Field(default=None, gt=0)
    no_load_speed: float | None = Field(default=None, gt=0)
    motor_speed: list[Annotated[float, Field(ge=0)]] | None = Field(default=None, min_length=2)
    motor_torque: list[float] | None = Field(default=None, min_length=2)
    drag: float = Field(default=0.0, ge=0)
    # speeds (as the profile's) at which orbits.png draws a revolution (default: picked)
    snapshots: list[Annotated[float, Field(gt=0)]] | None = Field(default=None, min_length=1)

    @model_validator(mode="after")
    def _complete(self) -> SpeedSection:
        ramp = {"from": self.start, "to": self.to, "rate": self.rate}
        table = {"tau": self.tau, "eta": self.eta, "t": self.t, "speed": self.speed}
        drive = {"inertia": self.inertia, "stall_torque": self.stall_torque,
                 "no_load_speed": self.no_load_speed, "motor_speed": self.motor_speed,
                 "motor_torque": self.motor_torque}  # fmt: skip
        if self.drag and self.profile != "driven":
            drive["drag"] = self.drag
        if self.profile == "driven":
            return self._complete_driven(ramp, table, drive)
        mine, other = (ramp, table) if self.profile == "ramp" else (table, ramp)
        extra = [k for k, v in {**other, **drive}.items() if v is not None]
        if extra:
            raise PydanticCustomError(
                "speed_keys",
                f"{', '.join(extra)} do not belong to profile = '{self.profile}'",
            )
        if self.profile == "ramp":
            missing = [k for k, v in mine.items() if v is None]
            if missing:
                raise PydanticCustomError(
                    "speed_keys", f"profile = 'ramp' needs {', '.join(missing)}"
                )
        else:
            pairs = [(a, b) for a, b in (("tau", "eta"), ("t", "speed"))
                     if table[a] is not None or table[b] is not None]  # fmt: skip
            if len(pairs) != 1 or table[pairs[0][0]] is None or table[pairs[0][1]] is None:
                raise PydanticCustomError(
                    "speed_keys",
                    "profile = 'table' needs tau and eta (with [model]) or t and speed "
                    "(with [physical])",
                )
        return self

    def _complete_driven(self, ramp: dict, table: dict, drive: dict) -> SpeedSection:
        extra = [k for k, v in {**ramp, **table}.items() if v is not None and k != "from"]
        if extra:
            raise PydanticCustomError(
                "speed_keys", f"{', '.join(extra)} do not belong to profile = 'driven'"
            )
        missing = [k for k in ("start", "inertia") if getattr(self, k) is None]
        linear = self.stall_torque is not None or self.no_load_speed is not None
        tabled = self.motor_speed is not None or self.motor_torque is not None
        if linear and tabled:
            raise PydanticCustomError(
                "speed_keys",
                "profile = 'driven': give the motor as stall_torque and no_load_speed or as "
                "motor_speed and motor_torque, not both",
            )
        pair = ("stall_torque", "no_load_speed") if not tabled else ("motor_speed", "motor_torque")
        missing += [k for k in pair if getattr(self, k) is None]
        if missing:
            raise PydanticCustomError(
                "speed_keys", f"profile = 'driven' needs {', '.join(missing)}"
            )
        if tabled and len(self.motor_speed) != len(self.motor_torque):
            raise PydanticCustomError(
                "speed_keys",
                f"motor_speed has {len(self.motor_speed)} values and motor_torque "
                f"{len(self.motor_torque)}: give one torque per speed",
            )
        return self

    @property
    def driven(self) -> bool:
        return self.profile == "driven"

    def drive_of(self, scale: units.PhysicalScale | None) -> Drive:
        """The nondimensional drive (ValueError naming the problem). With [physical]:
        j = J omega^2 / (k_r gamma^2), torques over k_r gamma^2, speeds in ``unit``."""
        if scale is None:
            if self.unit is not None:
                raise ValueError("unit belongs to a [physical] case")
            speed_to_eta, torque_unit, j, drag = 1.0, 1.0, self.inertia, self.drag
        else:
            speed_to_eta = units.speed_unit(self.unit or "rpm") / scale.omega
            torque_unit = scale.k_r * scale.clearance**2
            j = self.inertia * scale.omega**2 / torque_unit
            drag = self.drag * scale.omega / torque_unit
        if self.stall_torque is not None:
            motor = {"stall_torque": self.stall_torque / torque_unit,
                     "no_load_speed": self.no_load_speed * speed_to_eta}  # fmt: skip
        else:
            motor = {"table_speed": tuple(v * speed_to_eta for v in self.motor_speed),
                     "table_torque": tuple(v / torque_unit for v in self.motor_torque)}  # fmt: skip
        return Drive(inertia=j, start=self.start * speed_to_eta, drag=drag, **motor)

    def snapshot_etas(self, scale: units.PhysicalScale | None) -> list[float] | None:
        """``snapshots`` as speed ratios."""
        if self.snapshots is None or scale is None:
            return self.snapshots
        per = units.speed_unit(self.unit or "rpm")
        return [v * per / scale.omega for v in self.snapshots]

    def profile_of(self, scale: units.PhysicalScale | None) -> SpeedProfile:
        """The nondimensional profile (ValueError naming the problem)."""
        assert not self.driven
        if scale is None:
            if self.unit is not None or self.t is not None:
                raise ValueError("unit and t belong to a [physical] case; use tau and eta")
            if self.profile == "ramp":
                return SpeedProfile.ramp(self.start, self.to, self.rate)
            return SpeedProfile(tau=tuple(self.tau), eta=tuple(self.eta))
        if self.tau is not None:
            raise ValueError("tau and eta belong to a [model] case; use t (s) and speed")
        per = units.speed_unit(self.unit or "rpm")  # rad/s per unit
        if self.profile == "ramp":
            start, end = self.start * per / scale.omega, self.to * per / scale.omega
            rate = self.rate * per / scale.omega**2  # (unit/s) -> d eta / d tau
            return SpeedProfile.ramp(start, end, rate)
        taus = tuple(t * scale.omega for t in self.t)
        return SpeedProfile(tau=taus, eta=tuple(v * per / scale.omega for v in self.speed))


# ========================================================================= [initial]


class InitialSection(_Section):
    """[initial]: state at tau = 0 (clearances and d/dtau; metres and m/s with [physical])."""

    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    # a stator with its own mass: its displacement from its rest position and velocity
    # [u, v, u', v'] (default: at rest there)
    stator: Annotated[list[float], Field(min_length=4, max_length=4)] | None = None


# ============================================================================ [time]


class TimeSection(_Section):
    """[time]: duration in forcing periods 2 pi / eta and the output sampling. With
    [speed]: ``end`` (tau, or seconds with [physical]; default the profile's end) and
    samples per revolution at the profile's highest speed."""

    periods: float | None = Field(default=None, gt=0)
    samples_per_period: int = Field(gt=0)
    end: float | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _not_too_many_samples(self) -> TimeSection:
        if self.periods is None:  # a [speed] run: checked once its span is known
            return self
        n = self.periods * self.samples_per_period
        if n > MAX_OUTPUT_SAMPLES:
            # pydantic fills {name} templates without format specs: format here
            raise PydanticCustomError(
                "too_many_samples",
                f"periods * samples_per_period = {n:.3g} output samples, more than "
                f"{MAX_OUTPUT_SAMPLES:,}",
            )
        return self


# ========================================================================== [solver]


class SolverSection(_Section):
    """[solver]: which methods run and their settings (each method takes the ones it uses)."""

    methods: list[MethodName] = Field(default_factory=lambda: ["analytic", "rk45"], min_length=1)
    rtol: float = Field(default=1e-8, ge=registry.MIN_RTOL, lt=1)  # scipy methods
    atol: float = Field(default=1e-10, ge=registry.MIN_ATOL)  # scipy methods
    steps_per_period: int = Field(default=400, gt=0)  # analytic: step = period / this
    # analytic methods: adaptive steps (step doubling) with this local error tolerance;
    # steps_per_period then sets the first step
    analytic_tol: float | None = Field(default=None, gt=0, lt=1)
    max_steps: int = Field(default=5_000_000, gt=0)
    max_wall_time_s: float = Field(default=600.0, gt=0)
    # the whole of `rubcli run`, every method's solve with it (None: none)
    total_wall_time_s: float | None = Field(default=None, gt=0)

    _methods_unique = field_validator("methods")(_unique)

    def options(self) -> dict[str, Any]:
        """The settings as keyword options (``Case.options_for`` picks one method's)."""
        return self.model_dump(exclude={"methods", "total_wall_time_s"})


# ========================================================================== [output]


class OutputSection(_Section):
    """[output]: where and what to write. Only what is asked is computed and written."""

    dir: str | None = Field(default=None, min_length=1)  # default out/<case name>
    csv: bool = True
    plots: list[PlotName] = Field(default_factory=lambda: list(DEFAULT_PLOTS))

    _plots_unique = field_validator("plots")(_unique)

    @field_validator("dir")
    @classmethod
    def _no_nul(cls, value: str | None) -> str | None:
        if value is not None and "\0" in value:
            raise PydanticCustomError(
                "nul_byte", "holds a NUL byte (\\0), which no file name may hold"
            )
        return value


# ====================================================================== [forces_map]


class ForcesMapSection(_Section):
    """[forces_map]: settings of ``rubcli forces-map`` (contact force and Taylor error maps)."""

    extent: float = Field(default=1.5, gt=1)  # half-width of the square grid, clearances
    resolution: int = Field(default=201, ge=3)  # grid points per side (memory-bounded)
    products: list[ForcesMapProduct] = Field(
        default_factory=lambda: ["forces", "taylor_error", "eigen"], min_length=1
    )
    deltas: list[PositiveFloat] | None = Field(default=None, min_length=1)
    K_values: list[PositiveFloat] | None = Field(default=None, min_length=1)
    max_wall_time_s: float = Field(default=3600.0, gt=0)  # the run's budget, seconds

    _products_unique = field_validator("products")(_unique)

    @field_validator("resolution")
    @classmethod
    def _resolution_fits_in_memory(cls, value: int) -> int:
        need = forces_map_memory_bytes(value)
        if need > MAX_CASE_MEMORY_BYTES:
            largest = largest_forces_map_resolution(MAX_CASE_MEMORY_BYTES)
            raise PydanticCustomError(
                "too_much_memory",
                f"a {value} x {value} grid needs about {_gib(need)} of memory, more than the "
                f"{_gib(MAX_CASE_MEMORY_BYTES)} a case may ask for; at most {largest}",
            )
        return value

    def resolved_deltas(self) -> tuple[float, ...]:
        """``deltas`` or the default: 11 points logarithmically spaced over 1e-6 ... 1e-1."""
        return tuple(self.deltas) if self.deltas is not None else DEFAULT_FORCES_MAP_DELTAS

    def resolved_K_values(self) -> tuple[float, ...]:
        """``K_values`` or the default: 17.6, 1.76e3, 1.76e5, 1.75e6 (the paper's range)."""
        if self.K_values is not None:
            return tuple(self.K_values)
        return DEFAULT_FORCES_MAP_K_VALUES


# ============================================================ [compare], [analysis]
# Owned by `rubcli compare` and the response analysis (docs/compare.md). Defaults of the
# ladders live in rubcli.analysis.work_precision; None means "use that default".

Rtol = Annotated[float, Field(gt=0, lt=1)]
PositiveInt = Annotated[int, Field(gt=0)]
NonNegativeFloat = Annotated[float, Field(ge=0)]


class CompareSection(_Section):
    """[compare]: `rubcli compare` (work-precision ladders, reference, mu sweep)."""

    methods: list[MethodName] | None = Field(default=None, min_length=1)  # default [solver]
    rtols: list[Rtol] | None = Field(default=None, min_length=1)  # default 1e-3 ... 1e-11
    atol_factor: float = Field(default=1e-2, gt=0)  # atol = rtol * atol_factor
    steps_per_period: list[PositiveInt] | None = Field(default=None, min_length=1)
    repeats: int = Field(default=3, ge=1)  # timing: median of this many runs
    horizon_periods: float | None = Field(default=None, gt=0)  # default [time] periods
    reference_threshold: float = Field(default=1e-6, gt=0)  # predictability horizon
    max_wall_time_s: float = Field(default=120.0, gt=0)  # per solve; tighter settings skipped
    total_wall_time_s: float | None = Field(default=None, gt=0)  # the run's budget (None: none)
    work_precision: bool = True  # run the ladders (false: sweep/orbits only)
    mu: list[NonNegativeFloat] | None = Field(default=None, min_length=1, max_length=12)

    _methods_unique = field_validator("methods")(_unique)
    _mu_unique = field_validator("mu")(_unique)


class AnalysisSection(_Section):
    """[analysis]: response classification in `run` and `compare` (Poincare, Lyapunov)."""

    response: bool = False
    transient_periods: float | None = Field(default=None, ge=0)  # default: half the run
    lyapunov: bool = True  # back a non-periodic class with the largest exponent
    lyapunov_periods: int = Field(default=100, gt=0)
    rel_tol: float = Field(default=1e-4, gt=0, lt=1)  # periodicity tolerance / orbit size
    max_period: int = Field(default=16, ge=1)


# =========================================================================== [sweep]
# Owned by `rubcli sweep` (docs/sweeps.md). The engine is rubcli.sweep; this is its schema.

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


# ========================================================================== [orbits]
# Owned by `rubcli orbits` (docs/orbits.md): periodic orbits, Floquet multipliers and
# pseudo-arclength continuation in one nondimensional parameter.

OrbitParameter = Literal["eta", "mu", "K", "e", "nu", "Rp"]
# The smallest continuation step, as a fraction of the window: a step of 1e-300 once left
# the parameter where it was and ran for ever. 1e-12 of the window still spans thousands
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


# ======================================================================== [ensemble]
# Owned by `rubcli ensemble` (docs/reproduction.md): a cloud of starts x a tolerance ladder.


EnsembleParameter = Literal["nu", "eta", "e", "K", "mu", "Rp"]
MAX_ENSEMBLE_VALUES = 1000  # values of [ensemble] parameter
ENSEMBLE_BOX_KEYS = ("box_x", "box_y", "box_vx", "box_vy")


class EnsembleSection(_Section):
    """[ensemble]: the runs of `rubcli ensemble` and how each run's end is analysed.

    With ``parameter`` (and ``values`` or start/stop/num) the same starts are run at every
    value: the basin stability along the parameter (``rubcli.analysis.basin_stability``).
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


# =========================================================================== [chart]
# Owned by `rubcli chart` (docs/charts.md): a plane of two model parameters.

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


# ======================================================================= whole file


class CaseFile(_Section):
    """The whole case file. Exactly one of [model] and [physical] must be given."""

    case: CaseSection
    model: ModelSection | None = None
    physical: PhysicalSection | None = None
    stator: StatorSection | None = None
    speed: SpeedSection | None = None
    initial: InitialSection
    time: TimeSection
    solver: SolverSection = Field(default_factory=SolverSection)
    output: OutputSection = Field(default_factory=OutputSection)
    forces_map: ForcesMapSection | None = None
    compare: CompareSection | None = None
    analysis: AnalysisSection | None = None
    sweep: SweepSection | None = None
    orbits: OrbitsSection | None = None
    ensemble: EnsembleSection | None = None
    chart: ChartSection | None = None

    @model_validator(mode="after")
    def _speed_given_once(self) -> CaseFile:
        """The speed comes from [model] eta ([physical] Omega) or from [speed], and
        [time] counts periods only at a constant speed."""
        table = self.model if self.model is not None else self.physical
        if table is None:
            return self
        name, where = ("eta", "model") if self.model is not None else ("Omega", "physical")
        given = getattr(table, name) is not None
        if self.speed is None:
            if not given:
                raise PydanticCustomError(
                    "speed_missing", f"{where}.{name}: missing (or give a [speed] table)"
                )
            if self.time.periods is None:
                raise PydanticCustomError("speed_missing", "time.periods: missing")
            if self.time.end is not None:
                raise PydanticCustomError(
                    "speed_time",
                    "time.end: belongs to a run with [speed]; at a constant speed give "
                    "time.periods",
                )
            return self
        if given:
            raise PydanticCustomError(
                "speed_twice", f"{where}.{name}: the speed is given by [speed]; remove {name}"
            )
        if self.time.periods is not None:
            raise PydanticCustomError(
                "speed_time",
                "time.periods: a speed that changes has no fixed period; a [speed] run spans "
                "its profile, or give time.end",
            )
        for other in ("sweep", "orbits", "ensemble", "chart", "forces_map", "analysis"):
            if getattr(self, other) is not None:
                raise PydanticCustomError(
                    "speed_table",
                    f"[{other}]: needs a constant speed, and [speed] makes it change; run it "
                    "from a case without [speed]",
                )
        # orbit.png, time.png, energy.png and spectrum.png count periods of one speed (the
        # keyphasor, the last periods, the spectrum's orders, the balance's power terms):
        # a run whose speed changes draws bode, polar, cascade and orbits.png instead
        if "plots" not in self.output.model_fields_set:
            output = self.output.model_copy(update={"plots": []})
            object.__setattr__(self, "output", output)
        elif self.output.plots:
            raise PydanticCustomError(
                "speed_plots",
                f"output.plots: {', '.join(self.output.plots)} count periods of a constant "
                "speed; with [speed] a run draws bode.png, polar.png, cascade.png and "
                "orbits.png (give plots = [] or leave it out)",
            )
        driven = self.speed.driven
        if driven and self.time.end is None:
            raise PydanticCustomError(
                "speed_time",
                "time.end: missing; a driven rotor's run has no profile to span (give tau, "
                "or seconds with [physical])",
            )
        if "methods" not in self.solver.model_fields_set:
            solver = self.solver.model_copy(update={"methods": ["dop853-jit"]})
            object.__setattr__(self, "solver", solver)
        feature = registry.DRIVEN if driven else registry.SPEED_PROFILE
        for method in self.solver.methods:
            why = registry.unsupported(method, feature)
            if why:
                raise PydanticCustomError("speed_method", f"solver.methods: {why}")
        return self

    @model_validator(mode="after")
    def _run_fits_in_memory(self) -> CaseFile:
        if self.time.periods is None:  # a [speed] run: checked once its span is known
            return self
        samples = self.time.periods * self.time.samples_per_period
        methods = len(self.solver.methods)
        need = samples * methods * RUN_BYTES_PER_SAMPLE
        if samples <= MAX_OUTPUT_SAMPLES and need > MAX_CASE_MEMORY_BYTES:
            raise PydanticCustomError(
                "too_much_memory",
                f"{samples:.3g} output samples x {methods} methods need about {_gib(need)} "
                f"of memory, more than the {_gib(MAX_CASE_MEMORY_BYTES)} a case may ask for; "
                "run fewer methods at a time or fewer time.samples_per_period",
            )
        return self

    @model_validator(mode="after")
    def _sweep_resolves_its_samples(self) -> CaseFile:
        if self.sweep is None:
            return self
        sps = self.time.samples_per_period
        if sps < SWEEP_MIN_SAMPLES:
            raise PydanticCustomError(
                "sweep_samples",
                f"time.samples_per_period: a sweep needs at least {SWEEP_MIN_SAMPLES} samples "
                f"per period (its spectrum and contact measures) (got {sps})",
            )
        if self.sweep.spectrum_max_order > sps / 2:
            raise PydanticCustomError(
                "sweep_spectrum",
                f"sweep.spectrum_max_order: at most time.samples_per_period / 2 = {sps / 2:g} "
                "(the highest order the recorded samples resolve) (got "
                f"{self.sweep.spectrum_max_order:g})",
            )
        need = self.sweep.record_periods * sps * RUN_BYTES_PER_SAMPLE
        if need > MAX_CASE_MEMORY_BYTES / SWEEP_POINTS_IN_MEMORY:
            raise PydanticCustomError(
                "sweep_memory",
                f"sweep.record_periods: {self.sweep.record_periods} recorded periods at "
                f"{sps} samples each need about {_gib(need)} per point in memory, and a "
                f"sweep holds up to {SWEEP_POINTS_IN_MEMORY} points at once (one per worker); "
                f"more than the {_gib(MAX_CASE_MEMORY_BYTES)} a case may ask for",
            )
        need, what = sweep_memory(self.sweep)
        if need > MAX_CASE_MEMORY_BYTES:
            raise PydanticCustomError(
                "sweep_memory",
                f"sweep: {what} need about {_gib(need)} of memory until the files are "
                f"written, more than the {_gib(MAX_CASE_MEMORY_BYTES)} a case may ask for; "
                "sweep fewer points (or record fewer periods) per case",
            )
        return self

    @model_validator(mode="after")
    def _stator_defaults(self) -> CaseFile:
        """With [stator]: the methods default to those that run it, and energy.png (the
        rigid stator's balance drawn term by term) is not drawn."""
        if self.stator is None:
            return self
        if "methods" not in self.solver.model_fields_set:
            solver = self.solver.model_copy(update={"methods": ["dop853-jit"]})
            object.__setattr__(self, "solver", solver)
        if "energy" in self.output.plots:
            raise PydanticCustomError(
                "stator_plots",
                "output.plots: energy.png is drawn for a rigid stator; with [stator] the "
                "energy balance is in report.json (leave energy out of plots)",
            )
        return self

    @model_validator(mode="after")
    def _model_xor_physical(self) -> CaseFile:
        # The loader reports this with a field name before pydantic runs; this keeps the
        # rule for anyone who validates a dict directly.
        if (self.model is None) == (self.physical is None):
            raise PydanticCustomError("model_or_physical", _MODEL_XOR_PHYSICAL)
        return self


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
_MODEL_XOR_PHYSICAL = "give exactly one of [model] (nondimensional) and [physical] (SI units)"
_TABLES = frozenset(CaseFile.model_fields)


# ============================================================================ loading


@dataclass(frozen=True)
class Case:
    """A validated case: its settings, the nondimensional Problem and the physical scale."""

    settings: CaseFile
    problem: Problem
    scale: units.PhysicalScale | None = None
    path: Path | None = None

    @property
    def name(self) -> str:
        return self.settings.case.name

    @property
    def source(self) -> str:
        return str(self.path) if self.path is not None else "<case>"

    def speed_text(self) -> str | None:
        """The profile or the drive in a few words for titles, in the case's own units
        (rpm, N m, kg m^2 with [physical]); None at a constant speed."""
        speed = self.settings.speed
        if self.scale is None or speed is None:
            return self.problem.speed_text()
        unit = speed.unit or "rpm"
        if speed.driven:
            if speed.stall_torque is not None:
                stall, free = speed.stall_torque, speed.no_load_speed
                motor = f"motor {stall:g} N m stall, {free:g} {unit} no-load"
            else:
                motor = f"motor table of {len(speed.motor_speed)} points"
            return f"driven from {speed.start:g} {unit}, J {speed.inertia:g} kg m^2, {motor}"
        if speed.profile == "ramp":
            return f"{speed.start:g} to {speed.to:g} {unit} at {speed.rate:g} {unit}/s"
        return f"{unit} by table, {min(speed.speed):g} to {max(speed.speed):g}"

    @property
    def params(self) -> ModelParams:
        return self.problem.params

    @property
    def methods(self) -> list[str]:
        return list(self.settings.solver.methods)

    @property
    def solver_options(self) -> dict[str, Any]:
        """The [solver] settings shared by every method (each takes its own part)."""
        return self.settings.solver.options()

    def options_for(self, method: str) -> dict[str, Any]:
        """The [solver] settings that ``method`` takes, for ``rubcli.solvers.solve``."""
        return registry.options_for(method, self.solver_options)

    @property
    def output_dir(self) -> Path:
        """``[output] dir``, or ``out/<case name>``; relative paths are from the working dir."""
        return Path(self.settings.output.dir or f"out/{self.name}")

    def with_overrides(
        self,
        *,
        methods: list[str] | None = None,
        periods: float | None = None,
        output_dir: str | Path | None = None,
    ) -> Case:
        """The same case with command-line overrides applied, validated again."""
        raw = self.settings.model_dump(exclude_none=True)
        if methods:
            raw["solver"]["methods"] = list(methods)
        if periods is not None:
            raw["time"]["periods"] = periods
        if output_dir is not None:
            raw["output"]["dir"] = str(output_dir)
        settings = validate_case(raw, self.source)
        return assemble_case(settings, self.path)

    def to_dict(self) -> dict[str, Any]:
        """The case echoed for report.json: settings with defaults, and what was derived."""
        p = self.problem
        return {
            "source": self.source,
            "settings": self.settings.model_dump(mode="json"),
            "output_dir": str(self.output_dir),
            "nondimensional": {
                "params": {**p.params.as_dict(), **p.params.machine_dict()},
                "stator": p.params.stator.as_dict() if p.params.stator is not None else None,
                "initial": dict(zip(("x", "y", "vx", "vy"), p.initial, strict=True)),
                "t_span": list(p.t_span),
                "n_samples": int(p.t_eval.size),
                "period": p.params.period,
                "speed": p.speed.describe() if p.speed is not None else None,
                "drive": asdict(p.drive) if p.drive is not None else None,
            },
            "scale": self.scale.as_dict() if self.scale is not None else None,
        }


def read_case_file(path: str | Path) -> dict[str, Any]:
    """Step 1: read and parse the TOML file. Raises CaseError naming the file.

    Only a regular file of at most ``MAX_CASE_FILE_BYTES`` is read: a directory, a FIFO
    (which would wait for a writer), a device (``/dev/zero`` never ends) or a larger file
    is refused before its content is read.
    """
    path = Path(path)
    try:
        # O_NONBLOCK: opening a FIFO does not wait for a writer; it is refused just below
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise CaseError([f"{path}: file not found"]) from None
    except IsADirectoryError:
        raise CaseError([f"{path}: is a directory, not a case file"]) from None
    except OSError as exc:
        raise CaseError([f"{path}: cannot read: {exc.strerror or exc}"]) from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        if stat.S_ISDIR(info.st_mode):
            raise CaseError([f"{path}: is a directory, not a case file"])
        raise CaseError(
            [f"{path}: is not a regular file ({_file_kind(info.st_mode)}), not a case file"]
        )
    with os.fdopen(fd, "rb") as handle:
        too_big = (
            f"{path}: is larger than {MAX_CASE_FILE_BYTES // 1024**2} MiB, the most a case "
            "file may hold (a case is a few kB of TOML)"
        )
        if info.st_size > MAX_CASE_FILE_BYTES:
            raise CaseError([too_big])
        try:
            data = handle.read(MAX_CASE_FILE_BYTES + 1)  # a file that grows while read
        except OSError as exc:
            raise CaseError([f"{path}: cannot read: {exc.strerror or exc}"]) from None
    if len(data) > MAX_CASE_FILE_BYTES:
        raise CaseError([too_big])
    return parse_case_text(data, str(path))


def _file_kind(mode: int) -> str:
    kinds = {stat.S_ISFIFO: "a FIFO", stat.S_ISCHR: "a character device",
             stat.S_ISBLK: "a block device", stat.S_ISSOCK: "a socket"}  # fmt: skip
    return next((name for test, name in kinds.items() if test(mode)), "a special file")


def parse_case_text(data: str | bytes, source: str = "<case>") -> dict[str, Any]:
    """Parse TOML text; a syntax error names the source and the line."""
    if isinstance(data, bytes):
        try:
            data = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise CaseError([f"{source}: not valid TOML: not UTF-8 text ({exc.reason})"]) from None
    try:
        return tomllib.loads(data)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        found = re.search(r"\(at line (\d+), column (\d+)\)", message)
        if found:
            reason = message[: found.start()].strip()
            where = f"line {found.group(1)}, column {found.group(2)}"
            raise CaseError([f"{source}: {where}: not valid TOML: {reason}"]) from None
        raise CaseError([f"{source}: not valid TOML: {message}"]) from None
    except RecursionError:
        raise CaseError(
            [f"{source}: not a case file: arrays or tables nested too deeply"]
        ) from None


# What a case with [rotor] (a machine given as matrices, rubcli.rotor_case) runs with.
MATRICES_CASE_COMMANDS = (
    "a machine given as matrices runs with `rubcli validate` and `rubcli run` (the other "
    "commands take the Jeffcott rotor's [model] or [physical])"
)


def validate_case(raw: dict[str, Any], source: str = "<case>") -> CaseFile:
    """Step 2: validate a parsed case against the schema. Raises CaseError."""
    if "rotor" in raw:  # a machine given as matrices: rubcli.rotor_case
        raise CaseError([f"{source}: rotor: {MATRICES_CASE_COMMANDS}"])
    problems: list[str] = []
    has_model, has_physical = "model" in raw, "physical" in raw
    if has_model and has_physical:
        problems.append(f"{source}: physical: {_MODEL_XOR_PHYSICAL}, not both")
    elif not has_model and not has_physical:
        problems.append(f"{source}: model: missing table; {_MODEL_XOR_PHYSICAL}")
    try:
        settings = CaseFile.model_validate(raw)
    except ValidationError as exc:
        for error in exc.errors():
            if error["type"] == "model_or_physical":
                continue  # already reported above with a field name
            problems.append(_format_error(source, error))
    if problems:
        raise CaseError(problems)
    return settings


def _assemble_speed_case(
    settings: CaseFile,
    values: dict[str, Any],
    initial: tuple[float, float, float, float],
    scale: units.PhysicalScale | None,
    path: Path | None,
    source: str,
) -> Case:
    """``assemble_case`` for a run with [speed]: the profile, its span (``time.end``, or
    the profile's last knot) sampled at ``samples_per_period`` per revolution at its
    highest speed."""
    assert settings.speed is not None
    if settings.speed.driven:
        return _assemble_driven_case(settings, values, initial, scale, path, source)
    try:
        profile = settings.speed.profile_of(scale)
    except (ValueError, ArithmeticError) as exc:
        raise CaseError([f"{source}: speed: {exc}"]) from None
    for i, eta in enumerate(profile.eta):
        why = model.parameter_problem("eta", eta)
        if why:
            converts = f"converts to eta = {eta!r}: " if scale is not None else ""
            raise CaseError([f"{source}: speed: speed {i + 1} of the profile: {converts}{why}"])
    params = ModelParams(**{**values, "eta": profile.speed(0.0)})
    end = settings.time.end
    t_end = profile.end if end is None else end * (scale.omega if scale is not None else 1.0)
    _check_span(params, t_end, scale, source)
    t_eval = _speed_samples(settings, max(profile.eta), t_end, source)
    problem = Problem(
        params=params, initial=initial, t_eval=t_eval, name=settings.case.name, speed=profile
    )
    return Case(settings=settings, problem=problem, scale=scale, path=path)


def _assemble_driven_case(
    settings: CaseFile,
    values: dict[str, Any],
    initial: tuple[float, float, float, float],
    scale: units.PhysicalScale | None,
    path: Path | None,
    source: str,
) -> Case:
    """``assemble_case`` for a driven rotor: the drive, the span ``time.end`` sampled at
    ``samples_per_period`` per revolution at the highest speed the motor drives to (its
    no-load speed, the table's last speed, or the start if higher)."""
    try:
        drive = settings.speed.drive_of(scale)
    except (ValueError, ArithmeticError) as exc:
        raise CaseError([f"{source}: speed: {exc}"]) from None
    why = model.parameter_problem("eta", drive.start)
    if why:
        raise CaseError([f"{source}: speed.start: converts to eta = {drive.start!r}: {why}"])
    params = ModelParams(**{**values, "eta": drive.start})
    try:
        drive.check(params.e)
    except ValueError as exc:
        raise CaseError([f"{source}: speed.inertia: {exc}"]) from None
    t_end = settings.time.end * (scale.omega if scale is not None else 1.0)
    _check_span(params, t_end, scale, source)
    top = drive.no_load_speed if drive.no_load_speed is not None else drive.table_speed[-1]
    t_eval = _speed_samples(settings, max(top, drive.start), t_end, source)
    problem = Problem(
        params=params, initial=initial, t_eval=t_eval, name=settings.case.name, drive=drive
    )
    return Case(settings=settings, problem=problem, scale=scale, path=path)


def _check_span(
    params: ModelParams, t_end: float, scale: units.PhysicalScale | None, source: str
) -> None:
    """CaseError unless a run whose speed changes may end at ``t_end``: within the
    model's domain, and the contact resolved in doubles all the way."""
    if not (0.0 < t_end <= model.MAX_MAGNITUDE):
        why = f"outside (0, {model.MAX_MAGNITUDE:g}] (the model's domain, docs/cases.md)"
        raise CaseError([f"{source}: time.end: the run ends at tau = {t_end!r}, {why}"])
    why = resolution_problem(params, (0.0, t_end))
    if why:
        where = "model.K" if scale is None else f"physical: converts to K = {params.K!r}"
        raise CaseError([f"{source}: {where}: {why}"])


def _speed_samples(settings: CaseFile, top: float, t_end: float, source: str) -> np.ndarray:
    """The sample times of a run whose speed changes: ``samples_per_period`` per
    revolution at the speed ``top``, over tau 0 .. t_end (CaseError past the limits)."""
    step = 2.0 * math.pi / (top * settings.time.samples_per_period)
    n = int(math.ceil(t_end / step)) + 1
    need = n * len(settings.solver.methods) * RUN_BYTES_PER_SAMPLE
    if n > MAX_OUTPUT_SAMPLES or need > MAX_CASE_MEMORY_BYTES:
        raise CaseError(
            [
                f"{source}: time.samples_per_period: {n:.3g} output samples over tau 0 .. "
                f"{t_end:.6g} ({settings.time.samples_per_period} per revolution at the "
                f"highest speed); at most {MAX_OUTPUT_SAMPLES:,} and "
                f"{_gib(MAX_CASE_MEMORY_BYTES)} for all methods"
            ]
        )
    return np.linspace(0.0, t_end, n)


def assemble_case(
    settings: CaseFile, path: str | Path | None = None, source: str | None = None
) -> Case:
    """Step 3: convert units once and build the nondimensional Problem.

    ``source`` names the case in error messages (default: ``path``).
    """
    path = Path(path) if path is not None else None
    if source is None:
        source = str(path) if path is not None else "<case>"
    init = settings.initial
    scale = None
    problems = []
    if settings.physical is not None:
        try:
            values, scale = units.nondimensional_values(**settings.physical.model_dump())
            initial = units.nondimensional_state(init.x, init.y, init.vx, init.vy, scale)
        except ArithmeticError as exc:  # values beyond floating-point range
            raise CaseError([f"{source}: physical: cannot be converted ({exc})"]) from None
        # SI values can be valid one by one and still convert to nonsense (an overflow,
        # an underflow to 0): the converted values must lie in [model]'s domain.
        for name, value in values.items():
            if value is None or name not in model.PARAMETER_SIGNS:  # eta from [speed]; the
                continue  # general machine's vectors and matrices: ``_check_machine``
            why = model.parameter_problem(name, value)
            if why:
                problems.append(f"{source}: physical: converts to {name} = {value!r}: {why}")
    else:
        assert settings.model is not None
        values = settings.model.model_dump()
        initial = (init.x, init.y, init.vx, init.vy)
    values = machine_values(values)
    if settings.stator is not None:
        try:
            values["stator"] = settings.stator.stator(settings.physical)
        except (TypeError, ValueError) as exc:
            raise CaseError([f"{source}: stator: {str(exc).removeprefix('stator: ')}"]) from None
    for name, value in zip(("x", "y", "vx", "vy"), initial, strict=True):
        why = _state_problem(value)
        if why:
            converts = f"converts to {value!r}: " if scale is not None else ""
            problems.append(f"{source}: initial.{name}: {converts}{why}")
    if problems:
        raise CaseError(problems)
    _check_machine(settings, values, source)
    if settings.speed is not None:
        return _assemble_speed_case(settings, values, initial, scale, path, source)
    params = ModelParams(**values)
    periods = settings.time.periods
    t_end = periods * params.period
    if not t_end <= model.MAX_MAGNITUDE:
        raise CaseError(
            [
                f"{source}: time.periods: {periods!r} periods end at tau = {t_end:.3g}, beyond "
                f"{model.MAX_MAGNITUDE:g} (the model's domain, docs/cases.md)"
            ]
        )
    why = resolution_problem(params, (0.0, t_end))
    if why:
        where = "model.K" if scale is None else f"physical: converts to K = {params.K!r}"
        raise CaseError([f"{source}: {where}: {why}"])
    if settings.sweep is not None:
        why = _sweep_resolution_problem(settings.sweep, params) or _sweep_machine_problem(
            settings.sweep, params
        )
        if why:
            raise CaseError([f"{source}: sweep: {why}"])
    try:
        problem = Problem.from_periods(
            params,
            initial,
            periods=periods,
            samples_per_period=settings.time.samples_per_period,
            name=settings.case.name,
        )
    except ValueError as exc:  # e.g. a time span that overflows
        raise CaseError([f"{source}: time: cannot build the time grid: {exc}"]) from None
    if init.stator is not None:
        problem = _with_stator_start(problem, init.stator, scale, source)
    return Case(settings=settings, problem=problem, scale=scale, path=path)


def _with_stator_start(
    problem: Problem, start: list[float], scale: units.PhysicalScale | None, source: str
) -> Problem:
    """``problem`` with the stator's start from [initial] stator (converted with
    [physical]); CaseError without a [stator] or with a value out of the model's domain."""
    if problem.params.stator is None:
        raise CaseError([f"{source}: initial.stator: needs a [stator] (a stator with its own "
                         "mass)"])  # fmt: skip
    state = tuple(start) if scale is None else units.nondimensional_state(*start, scale)
    for name, value in zip(("u", "v", "u'", "v'"), state, strict=True):
        why = _state_problem(value)
        if why:
            raise CaseError([f"{source}: initial.stator: {name} {why}"])
    return dataclasses.replace(problem, stator_initial=state)


def paper_machine_problem(case: Case, what: str, why: str) -> str | None:
    """Why ``what`` (a field, an analysis of the paper's machine alone, for ``why``) cannot
    take the case's general machine, naming what makes it general; None on the paper's."""
    p = case.params
    if p.is_paper_machine:
        return None
    return (
        f"{case.source}: {what} holds on the paper's machine only ({why}); model: "
        f"{'; '.join(p.machine_lines())} makes this machine general (docs/machines.md)"
    )


def _check_machine(settings: CaseFile, values: dict[str, Any], source: str) -> None:
    """The general machine's checks that need the whole machine: its converted values
    (with [physical]), the methods that run it (the registry's ``GENERAL_MACHINE``), and
    a driven rotor on it (not built)."""
    where = "model" if settings.model is not None else "physical: converts to"
    try:  # the machine alone: its speed (eta, perhaps from [speed]) plays no part here
        machine = ModelParams(**{**values, "eta": 1.0})
    except (TypeError, ValueError) as exc:
        raise CaseError([f"{source}: {where}: {str(exc).removeprefix('ModelParams: ')}"]) from None
    if machine.is_paper_machine:
        return
    if settings.speed is not None and settings.speed.driven:
        raise CaseError(
            [
                f"{source}: speed.profile: a driven rotor runs on the paper's machine only (the "
                "drive's equations have no offset, static load, anisotropic support or moving "
                "stator)"
            ]
        )
    if settings.speed is not None and machine.stator is not None:
        raise CaseError(
            [
                f"{source}: speed: a stator with its own mass runs at a constant speed only "
                "(leave out [speed], or [stator])"
            ]
        )
    features = [registry.GENERAL_MACHINE]
    if machine.stator is not None:  # the more particular refusal first
        features.insert(0, registry.MOVING_STATOR)
    lists = [("solver.methods", settings.solver.methods)]
    if settings.compare is not None and settings.compare.methods is not None:
        lists.append(("compare.methods", settings.compare.methods))
    for name, methods in lists:
        for method in methods:
            for feature in features:
                why = registry.unsupported(method, feature)
                if why:
                    raise CaseError([f"{source}: {name}: {why}"])


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


def _state_problem(value: float) -> str | None:
    """Why a start-state value lies outside the model's domain, or None."""
    if not math.isfinite(value):
        return "must be finite"
    if abs(value) > model.MAX_MAGNITUDE:
        return (
            f"must be at most {model.MAX_MAGNITUDE:g} in size (the model's domain, docs/cases.md)"
        )
    return None


def load_case(path: str | Path) -> Case:
    """Read, validate and assemble a case file. Raises CaseError (TypeError if ``path``
    is not a path)."""
    if not isinstance(path, str | os.PathLike):
        raise TypeError(f"load_case(): path must be a str or a path, got {type(path).__name__}")
    if "\0" in str(path):
        raise ValueError("load_case(): path holds a NUL byte (\\0), which no file name may hold")
    raw = read_case_file(path)
    return assemble_case(validate_case(raw, str(path)), path)


def load_case_text(text: str, source: str = "<case>") -> Case:
    """Like ``load_case`` for TOML text in memory (e.g. the sample of ``rubcli init``)."""
    return assemble_case(validate_case(parse_case_text(text, source), source), None, source)


def _format_error(source: str, error: dict[str, Any]) -> str:
    """One pydantic error as ``source: dotted.field: message``."""
    loc = error["loc"]
    field = ""
    for part in loc:
        field += f"[{part}]" if isinstance(part, int) else (f".{part}" if field else str(part))
    kind = error["type"]
    if kind == "missing":
        if len(loc) == 1 and loc[0] in _TABLES:
            message = f"missing table [{loc[0]}]"
        else:
            message = "missing required key"
    elif kind == "string_pattern_mismatch" and loc == ("case", "name"):
        message = (
            "must start with an ASCII letter or digit and hold only ASCII letters, digits, "
            f"'.', '_' and '-' (it names the default output dir; got "
            f"{_short_repr(error['input'])})"
        )
    elif kind == "extra_forbidden":
        message = "unknown key (not part of the case-file schema; see docs/cases.md)"
    else:
        message = error["msg"]
        if "input" in error and not isinstance(error["input"], dict | list):
            message += f" (got {_short_repr(error['input'])})"
    return f"{source}: {field or '(file)'}: {message}"

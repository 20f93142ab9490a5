"""The whole case file: its tables, the rules between them, and validating a parsed
case against it (errors as ``source: dotted.field: message``)."""

from __future__ import annotations

from typing import Any

from pydantic import Field, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from rubcli.case.base import (
    MAX_CASE_MEMORY_BYTES,
    RUN_BYTES_PER_SAMPLE,
    CaseError,
    _gib,
    _Section,
)
from rubcli.case.chart import ChartSection
from rubcli.case.compare import AnalysisSection, CompareSection
from rubcli.case.ensemble import EnsembleSection
from rubcli.case.forces_map import ForcesMapSection
from rubcli.case.machine import ModelSection, PhysicalSection, StatorSection
from rubcli.case.orbits import OrbitsSection
from rubcli.case.run import CaseSection, InitialSection, OutputSection, SolverSection, TimeSection
from rubcli.case.speed import SpeedSection
from rubcli.case.sweep import (
    SWEEP_MIN_SAMPLES,
    SWEEP_POINTS_IN_MEMORY,
    SweepSection,
    sweep_memory,
)
from rubcli.problem import MAX_OUTPUT_SAMPLES
from rubcli.solvers import registry


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


_MODEL_XOR_PHYSICAL = "give exactly one of [model] (nondimensional) and [physical] (SI units)"
_TABLES = frozenset(CaseFile.model_fields)


def _short_repr(value: object, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (a 5 MB value is not echoed whole)."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f"{text[: limit - 25]}... ({len(text)} characters)"


# What a case with [rotor] (a machine given as matrices, rubcli.case.rotor) runs with.
MATRICES_CASE_COMMANDS = (
    "a machine given as matrices runs with `rubcli validate`, `rubcli run` and `rubcli "
    "compare` (the other commands take the Jeffcott rotor's [model] or [physical])"
)


def validate_case(raw: dict[str, Any], source: str = "<case>") -> CaseFile:
    """Step 2: validate a parsed case against the schema. Raises CaseError."""
    if "rotor" in raw:  # a machine given as matrices: rubcli.case.rotor
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

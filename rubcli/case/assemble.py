"""A validated case assembled: defaults filled, physical units converted once
(``rubcli.units``) and the nondimensional ``Problem`` built."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import model, units
from rubcli.case.base import (
    MAX_CASE_MEMORY_BYTES,
    RUN_BYTES_PER_SAMPLE,
    CaseError,
    _gib,
    _state_problem,
)
from rubcli.case.casefile import CaseFile, validate_case
from rubcli.case.machine import machine_values
from rubcli.case.sweep import _sweep_machine_problem, _sweep_resolution_problem
from rubcli.model import ModelParams
from rubcli.problem import MAX_OUTPUT_SAMPLES, Problem, resolution_problem
from rubcli.solvers import registry


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

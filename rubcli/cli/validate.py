"""``rubcli validate CASE [--json]``: check a case file and show what it resolves to.

Exit 0 if valid, 2 with one line per problem if not. ``--json`` prints only
``{"valid": true, "case": ...}`` (the case as report.json echoes it) or
``{"valid": false, "problems": [...]}`` on stdout, with the same exit codes.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from rubcli import io
from rubcli.case import Case, CaseError, load_case, paper_machine_problem
from rubcli.cli import console
from rubcli.cli.common import EXIT_INVALID, JsonOption, emit
from rubcli.problem import Problem

__all__ = ["EXIT_INVALID", "command", "load_or_exit", "summary_lines"]


def load_or_exit(path: Path) -> Case:
    """Load a case; on a CaseError print one line per problem and exit with code 2."""
    try:
        return load_case(path)
    except CaseError as exc:
        console.error_lines(f"invalid case file {path}", exc.problems)
        raise typer.Exit(EXIT_INVALID) from None


def paper_machine_or_exit(case: Case, what: str, why: str) -> None:
    """Exit 2 if the case's machine is general, where ``what`` holds on the paper's machine
    only, for ``why`` (``case.paper_machine_problem``)."""
    problem = paper_machine_problem(case, what, why)
    if problem is not None:
        console.error(problem)
        raise typer.Exit(EXIT_INVALID)


def _time_line(problem: Problem) -> str:
    """The span and the samples (for a changing speed, the profile and its revolutions)."""
    end, n = problem.t_span[1], problem.t_eval.size
    if problem.drive is not None:
        return f"speed     {problem.drive.text()}: tau 0 .. {end:.6g}, {n} samples"
    if problem.speed is None:
        return f"time      {problem.periods:g} periods = tau 0 .. {end:.6g}, {n} samples"
    turns = (problem.speed.phase(end, 0.0) - problem.speed.phase(0.0, 0.0)) / (2.0 * math.pi)
    return f"speed     {problem.speed.text()}: tau 0 .. {end:.6g}, {turns:.0f} turns, {n} samples"


def _stator_lines(p, problem: Problem) -> list[str]:
    """A moving stator: its values, its own frequencies and its start."""
    fx, fy = p.stator.natural_frequencies()
    start = "at rest"
    if any(problem.stator_initial):
        start = "at u={:.6g} v={:.6g} u'={:.6g} v'={:.6g}".format(*problem.stator_initial)
    ring = p.stator.text().removeprefix("stator ")
    return [f"stator    {ring}; own frequencies {fx:.4g}, {fy:.4g} (x omega); starts {start}"]


def summary_lines(case: Case) -> list[str]:
    """What a case resolves to, in a few lines (the nondimensional problem it defines)."""
    p, problem = case.params, case.problem
    nu = "" if p.damping is not None else f"nu={p.nu:.6g} "  # (a damping matrix: machine)
    lines = [
        f"case      {case.name}"
        + (
            f": {console.shorten(case.settings.case.description)}"
            if case.settings.case.description
            else ""
        ),
        f"model     {nu}eta={p.eta:.6g} e={p.e:.6g} K={p.K:.6g} mu={p.mu:.6g} Rp={p.Rp:.6g} "
        f"phi0={p.phi0:.6g}",
        *([f"machine   {p.machine_lines()[0]}"] if p.machine_dict() else []),
        *(_stator_lines(p, problem) if p.stator is not None else []),
        "initial   x={:.6g} y={:.6g} vx={:.6g} vy={:.6g}".format(*problem.initial),
        _time_line(problem),
        f"methods   {', '.join(case.methods)}",
        f"output    {case.output_dir}",
    ]
    if case.scale is not None:
        s = case.scale
        lines.insert(
            2,
            f"scale     omega={s.omega:.6g} rad/s, clearance={s.clearance:.6g} m, "
            f"force unit k_r*clearance={s.force:.6g} N",
        )
    return lines


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    json: JsonOption = False,
) -> None:
    """Validate a case file; exit 0 if valid, 2 with one line per problem if not."""
    from rubcli.cli import rotor

    matrices_case = rotor.rotor_case_or_none(case_file, json)
    if matrices_case is not None:
        rotor.validate(matrices_case, case_file, json)
        return
    if json:
        try:
            case = load_case(case_file)
        except CaseError as exc:
            envelope = io.report_envelope("validate", {"case_file": str(case_file)})
            emit({**envelope, "valid": False, "problems": exc.problems}, json)
            raise typer.Exit(EXIT_INVALID) from None
        envelope = io.report_envelope("validate", {"case_file": str(case_file)}, case.to_dict())
        emit({**envelope, "valid": True, "summary": summary_lines(case)}, json)
        return
    case = load_or_exit(case_file)
    for line in summary_lines(case):
        console.info(line)
    console.success(f"{case_file}: valid")

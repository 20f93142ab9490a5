"""``rubcli orbits CASE [--out DIR] [--overlay sweep.nc] [--quick]``: continue a periodic orbit.

Output dir: ``--out DIR``, else ``orbits/`` inside the case's output dir.

Reads the case's ``[orbits]`` table (docs/orbits.md), finds the starting periodic orbit by
shooting (from ``[initial]``, from the end of a transient, or from the exact synchronous
rub), continues it in one parameter by pseudo-arclength in both directions, detects and
locates folds, period doublings, Neimark-Sacker points, grazing and stick onset, and writes

- ``branch.csv`` and ``branch.nc``: one row per orbit (parameter, k, state on the section,
  max/min z, contact and stick fractions, multipliers, stability, bifurcation label);
  located bifurcation points are rows with their label, in branch order;
- ``branch.png`` (max z against the parameter, stable solid, unstable dashed, bifurcations
  marked; over the sweep's stroboscopic z with ``--overlay``) and ``multipliers.png``;
- ``report.json``: the case, the settings, why each direction stopped, the bifurcations.

``--quick`` (for CI) caps each direction at 12 points and loosens the integration to 1e-10.

``[orbits] max_wall_time_s`` (default 3600 s; ``--max-wall-time S``) bounds the whole
run, the transient included: what is computed by then is written. Where no progress bar
shows (stderr not a terminal), a ``progress:`` line goes to stderr every 10 s.

Exit codes: 0 done (a direction that stopped early says why in the report); 2 invalid
input (nothing written); 1 no starting orbit (only report.json, with the reason), or the
wall-time budget ran out (the orbits computed are written, the report says so).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rubcli.analysis.orbits import continuation as cn
from rubcli.cli import console, progress, tables
from rubcli.cli.common import (
    ForceOption,
    JsonOption,
    WaitOption,
    check_max_wall_time,
    command_dir,
    emit,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit
from rubcli.studies import orbits as study

if TYPE_CHECKING:
    from rubcli.analysis.orbits.curves import Curve

EXIT_FAILED = 1


def summary_lines(branch: cn.Branch) -> list[list[str]]:
    """The console's table of bifurcations, in increasing order of the parameter (the
    branch lists them in the order continuation met them: one direction, then the other)."""
    rows = []
    for b in sorted(branch.bifurcations, key=lambda b: b.parameter):
        mods = ", ".join(f"{abs(m):.6f}" for m in b.point.multipliers)
        rows.append([b.kind, f"{b.parameter:.10g}", "yes" if b.located else "no",
                     f"{b.point.max_z:.6g}", mods, b.note])  # fmt: skip
    return rows


def curve_line(curve: Curve, report: dict) -> list[str]:
    """The console's row for one continued curve."""
    distance = report["max_distance_to_closed_form"]
    ends = curve.message if curve.status != "ok" else "; ".join(curve.stops.values())
    shown = "-" if distance is None else f"{distance:.2g}"
    start = f"{curve.names[0]} = {curve.start.parameter:.10g}"
    return [curve.kind, start, str(len(curve.points)), shown, ends]


# ------------------------------------------------------------------------ command


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", metavar="DIR", help="Output dir (default: <case output dir>/orbits)."
        ),
    ] = None,
    overlay: Annotated[
        Path | None,
        typer.Option("--overlay", help="A sweep.nc of the same machine to draw the branch over."),
    ] = None,
    overlay_var: Annotated[
        str | None,
        typer.Option("--overlay-var", help="The stroboscopic variable of the sweep.nc to draw."),
    ] = None,
    quick: Annotated[
        bool, typer.Option("--quick", help="CI mode: 12 points per direction, tolerance 1e-10.")
    ] = False,
    max_wall_time: Annotated[
        float | None,
        typer.Option(
            "--max-wall-time",
            metavar="S",
            help="Wall-time budget in seconds instead of [orbits] max_wall_time_s.",
        ),
    ] = None,  # fmt: skip
    json: JsonOption = False,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Periodic orbits, Floquet multipliers and continuation in one parameter (orbits table)."""
    case = load_or_exit(case_file)
    check_max_wall_time(max_wall_time)
    if case.settings.orbits is not None and case.settings.orbits.kind == "whirl":
        from rubcli.cli import whirls

        if overlay is not None:
            console.error(
                f'{case_file}: --overlay: draws periodic-orbit branches, not kind = "whirl"'
            )
            raise typer.Exit(EXIT_INVALID)
        target = command_dir(case, "orbits", out)
        return whirls.run(case_file, case, target, force, wait, quick, json, max_wall_time)
    problems = study.check_case(case)
    overlay_data = None
    if not problems and overlay is not None:
        loaded = study.load_overlay(overlay, case.settings.orbits.parameter, overlay_var)
        if isinstance(loaded, list):
            problems = loaded
        else:
            overlay_data = loaded
    if problems:
        console.error_lines(f"cannot continue orbits of {case_file}", problems)
        raise typer.Exit(EXIT_INVALID)
    target = command_dir(case, "orbits", out)
    plan = prepare_output(target, force, wait, study.files_for(case))  # before any work
    with console.machine_readable(json):
        _orbits(case_file, case, target, plan, overlay, overlay_data, quick, max_wall_time, json)


def _orbits(case_file, case, target, plan, overlay, overlay_data, quick, max_wall_time, json):
    """The study, its files and what the console shows, once the inputs are checked."""
    t0 = time.perf_counter()
    budget = study.settings_from_case(case, quick, max_wall_time).max_wall_time_s
    state = {"phase": "the starting orbit", "done": 0}

    def status() -> str:
        return (f"orbits: {state['phase']}, {state['done']} orbits, "
                f"{time.perf_counter() - t0:.0f} s of the {budget:g} s budget")  # fmt: skip

    def advanced(phase: str, done: int, total: int) -> None:
        state.update(phase=phase, done=done)
        update(done / total)

    bar = f"orbits continued in {case.settings.orbits.parameter}"
    with progress.progress_lines(status), progress.progress_bar(bar, total=1.0) as update:
        result = study.continue_orbits(case, quick=quick, max_wall_time_s=max_wall_time,
                                       overlay=overlay_data, progress=advanced)  # fmt: skip
    command_line = {"case_file": str(case_file), "out": str(target), "quick": quick,
                    "overlay": str(overlay) if overlay is not None else None}  # fmt: skip
    report = result.write(target, plan, command_line)
    report_stale(plan)
    emit(report, json)
    branch, wall = result.branch, result.wall_time_s
    if not result.ok:
        console.error(f"{case_file}: {branch.message}; report.json written to {target}")
        raise typer.Exit(EXIT_FAILED)
    console.info(
        f"{len(branch.points)} orbits in {wall:.1f} s; "
        + "; ".join(f"{k}: {v}" for k, v in branch.stops.items())
    )
    if branch.budget_exhausted:
        console.error(
            f"{case_file}: stopped by the wall-time budget ({budget:g} s): "
            f"the {len(branch.points)} orbits computed are written to {target} "
            "(--max-wall-time or [orbits] max_wall_time_s for more)"
        )
        raise typer.Exit(EXIT_FAILED)
    if branch.bifurcations:
        tables.table(
            f"bifurcations along {branch.parameter}",
            ["kind", branch.parameter, "located", "max z", "|multipliers|", "note"],
            summary_lines(branch),
        )
    else:
        console.info("no bifurcation detected on the branch")
    if case.settings.orbits.second_parameter:
        tables.table(
            f"bifurcations continued in {case.settings.orbits.second_parameter}",
            ["kind", "from", "points", "|distance| to closed form", "ends"],
            [curve_line(c, report) for c, report in zip(result.curves,
                                                          report["curves"], strict=True)],
        )  # fmt: skip
    console.success(f"wrote {', '.join(report['files'])} to {target}")

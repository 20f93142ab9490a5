"""``rubcli chart CASE [--out DIR] [--quick] [--overlay sweep.nc] [--max-wall-time S]``: the
stability chart of a parameter plane.

Runs the case's ``[chart]`` table (``rubcli.analysis.charts.stability``; docs/charts.md): on the
isotropic machine the synchronous motions are known in closed form, so each point of the
plane is put in its region (free whirl, synchronous rub, both, or neither) and the curves
that bound the regions are located without an integration. Writes

- ``chart.png``: the regions and the curves (with ``--overlay``, beside them what each
  point of a ``rubcli sweep`` over the same plane settled on: free whirl, synchronous rub,
  partial rub, dry whip or dry whirl, under the same curves);
- ``curve.csv``: every located curve point: the two parameters and the curve's kind
  (``free_grazing``, ``rub_fold``, ``rub_stability``);
- ``chart.nc``: the regions on the grid and each curve's function;
- ``report.json``: the case, the plane, the share of each region, the points per curve.

``[chart] max_wall_time_s`` (default 3600 s; ``--max-wall-time S``) bounds the whole
chart, checked at every grid line and by each continuation check.

Exit codes: 0 done; 1 the wall-time budget ran out (nothing written); 2 invalid input
(nothing written).
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Annotated

import typer

from rubcli.cli import console, progress, tables
from rubcli.cli.common import (
    ForceOption,
    JsonOption,
    WaitOption,
    budget_spent,
    check_max_wall_time,
    command_dir,
    emit,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit, paper_machine_or_exit

OutOption = Annotated[
    Path | None, typer.Option("--out", "-o", help="Output dir (default: <case dir>/chart).")
]
QuickOption = Annotated[bool, typer.Option("--quick", help="CI mode: a 41 x 21 grid.")]


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: OutOption = None,
    quick: QuickOption = False,
    overlay: Annotated[
        Path | None,
        typer.Option("--overlay", help="A sweep.nc over the same plane, drawn beside it."),
    ] = None,
    max_wall_time: Annotated[
        float | None,
        typer.Option(
            "--max-wall-time",
            metavar="S",
            help="Wall-time budget in seconds instead of [chart] max_wall_time_s.",
        ),
    ] = None,  # fmt: skip
    json: JsonOption = False,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Regions of the synchronous motions in a parameter plane (the case's chart table)."""
    case = load_or_exit(case_file)
    c = case.settings.chart
    if c is None:
        console.error(f"{case.source}: chart: missing table [chart] (docs/charts.md)")
        raise typer.Exit(EXIT_INVALID)
    check_max_wall_time(max_wall_time)
    from rubcli.analysis.orbits.periodic import WallTimeBudgetError
    from rubcli.studies import chart as study  # (scipy: loaded by this command only)

    paper_machine_or_exit(case, "chart", study.PAPER_MACHINE_ONLY)

    sweep = None
    if overlay is not None:
        sweep = study.load_sweep_map(overlay, c, case.params)
        if isinstance(sweep, list):
            console.error_lines(f"cannot chart {case_file}", sweep)
            raise typer.Exit(EXIT_INVALID)
    target = command_dir(case, "chart", out)
    plan = prepare_output(target, force, wait, study.FILES)
    with console.machine_readable(json):
        checks = min(c.check_points, study.QUICK_CHECK_POINTS) if quick else c.check_points
        with (
            console.notice_if_slow(f"charting {c.nx} x {c.ny} points in ({c.x}, {c.y})"),
            progress.progress_bar("continuation check", total=checks)
            if checks
            else contextlib.nullcontext(None) as update,
        ):
            try:
                result = study.chart_of(case, quick=quick, progress=update, sweep=sweep,
                                        max_wall_time_s=max_wall_time)  # fmt: skip
            except WallTimeBudgetError:
                budget = c.max_wall_time_s if max_wall_time is None else max_wall_time
                raise budget_spent(case_file, budget, "[chart] max_wall_time_s") from None
        command_line = {"case_file": str(case_file), "out": str(target), "quick": quick,
                        "overlay": str(overlay) if overlay is not None else None,
                        "max_wall_time": max_wall_time}  # fmt: skip
        report = result.write(target, plan, command_line)
        report_stale(plan)
        emit(report, json)
        rows = [[name, f"{share:.1%}"] for name, share in report["region_fractions"].items()]
        tables.table(f"regions of ({c.x}, {c.y})", ["region", "share of the plane"], rows)
        for kind, found in report["continuation_check"]["by_kind"].items():
            if found["points"]:
                console.info(f"{kind}: {found['points']} points located by continuation, "
                             f"within {found['max_distance']:.1e} of the closed form")  # fmt: skip
        overlaid = report["sweep_overlay"]
        if overlaid is not None:
            console.info(
                f"sweep ({overlaid['direction']}, {overlaid['points']} points): "
                f"{overlaid['contradictions']} on a synchronous motion where the closed form "
                "says it is not stable"
            )
        console.success(f"wrote {', '.join(report['files'])} to {target}")

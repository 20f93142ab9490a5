"""``rubcli chart CASE [--out DIR] [--quick]``: the stability chart of a parameter plane.

Runs the case's ``[chart]`` table (``rubcli.analysis.charts``; docs/charts.md): on the
isotropic machine the synchronous motions are known in closed form, so each point of the
plane is put in its region (free whirl, synchronous rub, both, or neither) and the curves
that bound the regions are located without an integration. Writes

- ``chart.png``: the regions and the curves;
- ``curve.csv``: every located curve point: the two parameters and the curve's kind
  (``free_grazing``, ``rub_fold``, ``rub_stability``);
- ``chart.nc``: the regions on the grid and each curve's function;
- ``report.json``: the case, the plane, the share of each region, the points per curve.

Exit codes: 0 done; 2 invalid input (nothing written).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from rubcli import io
from rubcli.cli import console
from rubcli.cli.common import (
    ForceOption,
    JsonOption,
    WaitOption,
    command_dir,
    emit,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit

QUICK_GRID = (41, 21)  # --quick: at most this many grid values of x and y
EXPECTED_FILES = ("chart.png", "curve.csv", "chart.nc", "report.json")
OutOption = Annotated[
    Path | None, typer.Option("--out", help="Output dir (default: <case dir>/chart).")
]
QuickOption = Annotated[bool, typer.Option("--quick", help="CI mode: a 41 x 21 grid.")]


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: OutOption = None,
    quick: QuickOption = False,
    json: JsonOption = False,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Regions of the synchronous motions in a parameter plane ([chart] table)."""
    case = load_or_exit(case_file)
    c = case.settings.chart
    if c is None:
        console.error(f"{case.source}: chart: missing table [chart] (docs/charts.md)")
        raise typer.Exit(EXIT_INVALID)
    nx, ny = (min(c.nx, QUICK_GRID[0]), min(c.ny, QUICK_GRID[1])) if quick else (c.nx, c.ny)
    from rubcli.analysis import charts as ch  # (scipy: loaded by this command only)

    target = command_dir(case, "chart", out)
    plan = prepare_output(target, force, wait, EXPECTED_FILES)
    with console.machine_readable(json):
        started = time.perf_counter()
        with console.notice_if_slow(f"charting {nx} x {ny} points in ({c.x}, {c.y})"):
            chart = ch.closed_form_chart(
                case.params, c.x, (c.x_min, c.x_max), c.y, (c.y_min, c.y_max), nx=nx, ny=ny
            )
        fixed = {k: v for k, v in case.params.as_dict().items() if k not in (c.x, c.y)}
        report = {
            **io.report_envelope("chart", {"case_file": str(case_file), "out": str(target),
                                           "quick": quick}, case.to_dict()),
            "wall_time_s": time.perf_counter() - started,
            "plane": {"x": c.x, "x_range": [c.x_min, c.x_max], "nx": nx,
                      "y": c.y, "y_range": [c.y_min, c.y_max], "ny": ny},
            "fixed": fixed,
            "region_fractions": chart.region_fractions(),
            "curve_points": {k: len(chart.curves[k]) for k in ch.CURVE_KINDS},
        }  # fmt: skip
        with io.staged_output_dir(target, plan) as staged:
            io.write_rows_csv(staged.path("curve.csv"), (c.x, c.y, "kind"), chart.curve_rows())
            io.write_netcdf(ch.chart_dataset(chart, case.params), staged.path("chart.nc"))
            from rubcli.plotting.chart import chart_figure

            held = ", ".join(f"{k} = {v:g}" for k, v in fixed.items() if k != "phi0")
            title = f"{case.name}: synchronous motions in ({c.x}, {c.y}); {held}"
            here = (getattr(case.params, c.x), getattr(case.params, c.y))
            io.save_figure(chart_figure(chart, title, here), staged.path("chart.png"))
            report["files"] = sorted(f.name for f in staged.staging.iterdir()) + ["report.json"]
            staged.write_report(report)
        report_stale(plan)
        emit(report, json)
        rows = [[name, f"{share:.1%}"] for name, share in report["region_fractions"].items()]
        console.table(f"regions of ({c.x}, {c.y})", ["region", "share of the plane"], rows)
        console.success(f"wrote {', '.join(report['files'])} to {target}")

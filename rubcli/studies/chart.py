"""The stability chart of a case's parameter plane (``rubcli chart``), as a library study:
``chart_of(case)`` returns a ``ChartResult``, whose ``write(directory)`` writes
``chart.png``, ``curve.csv``, ``chart.nc`` and ``report.json`` in one atomic commit
(``rubcli.io``). The plane is the case's ``[chart]`` table (docs/charts.md)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rubcli import io
from rubcli.analysis import charts as ch
from rubcli.case import Case, ChartSection

FILES = ("chart.png", "curve.csv", "chart.nc", "report.json")
QUICK_GRID = (41, 21)  # quick: at most this many grid values of x and y


@dataclass
class ChartResult:
    """A chart with what produced it; ``write`` puts it in a directory."""

    case: Case
    table: ChartSection
    chart: ch.Chart
    wall_time_s: float
    quick: bool = False

    @property
    def fixed(self) -> dict[str, float]:
        """The parameters held at the case's values."""
        c = self.table
        return {k: v for k, v in self.case.params.as_dict().items() if k not in (c.x, c.y)}

    def report(self, command_line: dict[str, Any]) -> dict[str, Any]:
        c, chart = self.table, self.chart
        return {
            **io.report_envelope("chart", command_line, self.case.to_dict()),
            "wall_time_s": self.wall_time_s,
            "plane": {"x": c.x, "x_range": [c.x_min, c.x_max], "nx": int(chart.x.size),
                      "x_spacing": c.x_spacing, "y": c.y, "y_range": [c.y_min, c.y_max],
                      "ny": int(chart.y.size), "y_spacing": c.y_spacing},
            "fixed": self.fixed,
            "region_fractions": chart.region_fractions(),
            "curve_points": {k: len(chart.curves[k]) for k in ch.CURVE_KINDS},
        }  # fmt: skip

    def write(
        self, directory: str | Path, plan: io.OutputPlan | None = None,
        command_line: dict[str, Any] | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Write the outputs into ``directory`` as one commit (``plan``: the dir as the
        caller opened and checked it; without one it is opened here); returns the report."""
        c, chart, case = self.table, self.chart, self.case
        report = self.report(command_line or {"out": str(directory)})
        with io.staged_output_dir(directory, plan) as staged:
            io.write_rows_csv(staged.path("curve.csv"), (c.x, c.y, "kind"), chart.curve_rows())
            io.write_netcdf(ch.chart_dataset(chart, case.params), staged.path("chart.nc"))
            from rubcli.plotting.chart import chart_figure

            held = ", ".join(f"{k} = {v:g}" for k, v in self.fixed.items() if k != "phi0")
            title = f"{case.name}: synchronous motions in ({c.x}, {c.y}); {held}"
            here = (getattr(case.params, c.x), getattr(case.params, c.y))
            io.save_figure(chart_figure(chart, title, here), staged.path("chart.png"))
            report["files"] = sorted(f.name for f in staged.staging.iterdir()) + ["report.json"]
            staged.write_report(report)
        return report


def chart_of(case: Case, *, quick: bool = False) -> ChartResult:
    """The regions and closed-form curves of the case's ``[chart]`` plane (``quick``: a
    grid of at most 41 x 21); ValueError if the case has no ``[chart]`` table."""
    c = case.settings.chart
    if c is None:
        raise ValueError(f"{case.source}: chart: missing table [chart] (docs/charts.md)")
    nx, ny = (min(c.nx, QUICK_GRID[0]), min(c.ny, QUICK_GRID[1])) if quick else (c.nx, c.ny)
    started = time.perf_counter()
    chart = ch.closed_form_chart(
        case.params, c.x, (c.x_min, c.x_max), c.y, (c.y_min, c.y_max), nx=nx, ny=ny,
        x_spacing=c.x_spacing, y_spacing=c.y_spacing,
    )  # fmt: skip
    return ChartResult(case, c, chart, time.perf_counter() - started, quick)

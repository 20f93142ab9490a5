"""The stability chart of a case's parameter plane (``rubcli chart``), as a library study:
``chart_of(case)`` returns a ``ChartResult``, whose ``write(directory)`` writes
``chart.png``, ``curve.csv``, ``chart.nc`` and ``report.json`` in one atomic commit
(``rubcli.io``). The plane is the case's ``[chart]`` table (docs/charts.md)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import io
from rubcli.analysis import charts as ch
from rubcli.case import Case, ChartSection

FILES = ("chart.png", "curve.csv", "chart.nc", "report.json")
QUICK_GRID = (41, 21)  # quick: at most this many grid values of x and y
QUICK_CHECK_POINTS = 2  # quick: at most this many values of x checked by continuation
CSV_COLUMNS_TAIL = ("kind", "source", "distance_to_closed_form")


@dataclass
class ChartResult:
    """A chart with what produced it; ``write`` puts it in a directory."""

    case: Case
    table: ChartSection
    chart: ch.Chart
    wall_time_s: float
    quick: bool = False
    continued: list[ch.ContinuedPoint] = field(default_factory=list)

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
            "continuation_check": self.check_summary(),
        }  # fmt: skip

    def check_summary(self) -> dict[str, Any]:
        """The points located by continuation and their largest distance in y from the
        closed-form curve, by kind (None: no point of that kind)."""
        by_kind = {}
        for kind in ch.CURVE_KINDS:
            found = [p.deviation for p in self.continued if p.kind == kind]
            worst = float(np.nanmax(found)) if found else None
            by_kind[kind] = {"points": len(found), "max_distance": worst}
        n = self.table.check_points
        return {"x_values": min(n, QUICK_CHECK_POINTS) if self.quick else n, "by_kind": by_kind}

    def curve_rows(self) -> list[tuple]:
        """curve.csv: the closed-form points, then the points located by continuation with
        their distance in y from the closed form."""
        rows: list[tuple] = [(x, y, kind, "closed form", None) for x, y, kind in
                             self.chart.curve_rows()]  # fmt: skip
        rows += [(p.x, p.y, p.kind, "continuation", p.deviation) for p in self.continued]
        return rows

    def write(
        self, directory: str | Path, plan: io.OutputPlan | None = None,
        command_line: dict[str, Any] | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Write the outputs into ``directory`` as one commit (``plan``: the dir as the
        caller opened and checked it; without one it is opened here); returns the report."""
        c, chart, case = self.table, self.chart, self.case
        report = self.report(command_line or {"out": str(directory)})
        with io.staged_output_dir(directory, plan) as staged:
            io.write_rows_csv(staged.path("curve.csv"), (c.x, c.y, *CSV_COLUMNS_TAIL),
                              self.curve_rows(), nonfinite="")  # fmt: skip
            io.write_netcdf(ch.chart_dataset(chart, case.params), staged.path("chart.nc"))
            from rubcli.plotting.chart import chart_figure

            held = ", ".join(f"{k} = {v:g}" for k, v in self.fixed.items() if k != "phi0")
            title = f"{case.name}: synchronous motions in ({c.x}, {c.y}); {held}"
            here = (getattr(case.params, c.x), getattr(case.params, c.y))
            figure = chart_figure(chart, title, here, self.continued)
            io.save_figure(figure, staged.path("chart.png"))
            report["files"] = sorted(f.name for f in staged.staging.iterdir()) + ["report.json"]
            staged.write_report(report)
        return report


def chart_of(
    case: Case, *, quick: bool = False, progress: Callable[[int], None] | None = None
) -> ChartResult:
    """The regions and closed-form curves of the case's ``[chart]`` plane, checked by
    continuation at ``check_points`` values of x (``quick``: a grid of at most 41 x 21,
    at most 2 values checked; ``progress(n)``: values of x checked so far); ValueError if
    the case has no ``[chart]`` table."""
    c = case.settings.chart
    if c is None:
        raise ValueError(f"{case.source}: chart: missing table [chart] (docs/charts.md)")
    nx, ny = (min(c.nx, QUICK_GRID[0]), min(c.ny, QUICK_GRID[1])) if quick else (c.nx, c.ny)
    started = time.perf_counter()
    chart = ch.closed_form_chart(
        case.params, c.x, (c.x_min, c.x_max), c.y, (c.y_min, c.y_max), nx=nx, ny=ny,
        x_spacing=c.x_spacing, y_spacing=c.y_spacing,
    )  # fmt: skip
    n = min(c.check_points, QUICK_CHECK_POINTS) if quick else c.check_points
    continued = ch.continued_points(case.params, chart, n, progress)
    return ChartResult(case, c, chart, time.perf_counter() - started, quick, continued)

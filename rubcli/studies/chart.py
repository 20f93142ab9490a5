"""The stability chart of a case's parameter plane (``rubcli chart``), as a library study:
``chart_of(case)`` returns a ``ChartResult``, whose ``write(directory)`` writes
``chart.png``, ``curve.csv``, ``chart.nc`` and ``report.json`` in one atomic commit
(``rubcli.io``). The plane is the case's ``[chart]`` table (docs/charts.md)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rubcli import io
from rubcli.analysis.charts import stability as ch
from rubcli.analysis.charts.stability import SWEEP_REGIMES, SweepMap
from rubcli.case import Case, ChartSection, paper_machine_problem

if TYPE_CHECKING:
    from rubcli.model import ModelParams

FILES = ("chart.png", "curve.csv", "chart.nc", "report.json")
QUICK_GRID = (41, 21)  # quick: at most this many grid values of x and y
QUICK_CHECK_POINTS = 2  # quick: at most this many values of x checked by continuation
# Why a chart holds on the paper's machine alone (a general machine is refused).
PAPER_MACHINE_ONLY = ("its regions are the closed forms of the synchronous motions, on a "
                      "concentric rigid stator and an isotropic support without load")  # fmt: skip
CSV_COLUMNS_TAIL = ("kind", "source", "distance_to_closed_form")


def contradictions(table: dict[str, dict[str, int]]) -> int:
    """Sweep points on a synchronous motion where the closed forms say it is not stable:
    a free whirl outside the regions with a stable free whirl, a synchronous rub outside
    those with a stable rub. (Other attractors may coexist with a stable synchronous motion:
    they are not contradictions.)"""
    free = {ch.REGIONS[ch.FREE], ch.REGIONS[ch.BOTH]}
    rub = {ch.REGIONS[ch.RUB], ch.REGIONS[ch.BOTH]}
    out = 0
    for region, row in table.items():
        out += row.get("free whirl", 0) if region not in free else 0
        out += row.get("synchronous rub", 0) if region not in rub else 0
    return out


def load_sweep_map(path: Path, table: ChartSection, params: ModelParams) -> SweepMap | list[str]:
    """The sweep.nc at ``path`` as a SweepMap over the chart's plane, or its problems: it
    must sweep the chart's two parameters (any order) with the chart's other parameters
    held at the case's values. Of a run-up and run-down, the run-up is shown."""
    from rubcli.studies.sweep import open_overlay, other_machine

    ds = open_overlay(path)
    if isinstance(ds, list):
        return ds
    with ds:
        needed = ("contact_fraction", "stick_fraction", "whirl_order", "status",
                  "response_class", "response_period")  # fmt: skip
        missing = [n for n in (table.x, table.y, *needed) if n not in ds.variables]
        if missing:
            return [f"{path}: --overlay: not a sweep over ({table.x}, {table.y}): "
                    f"no {', '.join(missing)}"]  # fmt: skip
        differ = other_machine(ds, params, (table.x, table.y))
        if differ:
            return [f"{path}: --overlay: another machine: {', '.join(differ)}"]
        extra = [d for d in ds["contact_fraction"].dims if d not in ("direction", table.x, table.y)]
        if extra:
            also = ", ".join(map(str, extra))
            return [f"{path}: --overlay: the sweep also varies {also}: only a sweep over "
                    f"({table.x}, {table.y}) alone can be drawn in the plane"]  # fmt: skip
        directions = [str(d) for d in ds["direction"].values]
        direction = "up" if "up" in directions else directions[0]
        one = ds.sel(direction=direction).transpose(table.y, table.x, ...)
        contact = np.asarray(one["contact_fraction"].values, dtype=float)
        stick = np.asarray(one["stick_fraction"].values, dtype=float)
        order = np.asarray(one["whirl_order"].values, dtype=float)
        ok = np.asarray(one["status"].values) == 0
        kind = np.asarray(one["response_class"].values, dtype=float)
        period = np.asarray(one["response_period"].values, dtype=float)
        x = np.asarray(one[table.x].values, dtype=float)
        y = np.asarray(one[table.y].values, dtype=float)
    from rubcli.analysis.ensembles.ensemble import regime_of
    from rubcli.analysis.response.classification import CONVERGING, KINDS, PERIODIC

    # a forward whirl in contact all round is the synchronous rub only when it repeats
    # every forcing period (or converges to such an orbit); else it is modulated (a torus)
    synchronous = np.isin(kind, [KINDS.index(PERIODIC), KINDS.index(CONVERGING)]) & (period == 1)
    regimes = np.full(contact.shape, SWEEP_REGIMES.index("no result"), dtype=int)
    for index in np.ndindex(contact.shape):
        values = (contact[index], stick[index], order[index])
        if ok[index] and all(math.isfinite(v) for v in values):
            name = regime_of(*values)
            if name == "synchronous rub" and not synchronous[index]:
                name = "modulated full rub"
            regimes[index] = SWEEP_REGIMES.index(name)
    return SweepMap(Path(path), direction, x, y, regimes, (table.x, table.y))


@dataclass
class ChartResult:
    """A chart with what produced it; ``write`` puts it in a directory."""

    case: Case
    table: ChartSection
    chart: ch.Chart
    wall_time_s: float
    quick: bool = False
    continued: list[ch.ContinuedPoint] = field(default_factory=list)
    sweep: SweepMap | None = None  # drawn beside the regions (--overlay)

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
            "sweep_overlay": self.sweep_summary(),
        }  # fmt: skip

    def sweep_summary(self) -> dict[str, Any] | None:
        """The overlaid sweep: its file, direction, and how its points' regimes fall in the
        closed-form regions (None without one)."""
        if self.sweep is None:
            return None
        table = self.sweep.cross_table(self.case.params)
        return {"file": str(self.sweep.path), "direction": self.sweep.direction,
                "points": int(self.sweep.regimes.size), "by_region": table,
                "contradictions": contradictions(table)}  # fmt: skip

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
            figure = chart_figure(chart, title, here, self.continued, self.sweep)
            io.save_figure(figure, staged.path("chart.png"))
            report["files"] = staged.names() + ["report.json"]
            staged.write_report(report)
        return report


def chart_of(
    case: Case, *, quick: bool = False, progress: Callable[[int], None] | None = None,
    sweep: SweepMap | None = None, max_wall_time_s: float | None = None,
) -> ChartResult:  # fmt: skip
    """The regions and closed-form curves of the case's ``[chart]`` plane, checked by
    continuation at ``check_points`` values of x (``quick``: a grid of at most 41 x 21,
    at most 2 values checked; ``progress(n)``: values of x checked so far; ``sweep``: a
    sweep of the plane, ``load_sweep_map``, drawn beside the regions); ValueError if the
    case has no ``[chart]`` table or its machine is not the paper's. The whole chart is
    bounded by ``[chart] max_wall_time_s`` (``max_wall_time_s``: a budget instead of the
    table's):
    ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` once it is spent."""
    c = case.settings.chart
    if c is None:
        raise ValueError(f"{case.source}: chart: missing table [chart] (docs/charts.md)")
    general = paper_machine_problem(case, "chart", PAPER_MACHINE_ONLY)
    if general is not None:
        raise ValueError(general)
    nx, ny = (min(c.nx, QUICK_GRID[0]), min(c.ny, QUICK_GRID[1])) if quick else (c.nx, c.ny)
    started = time.perf_counter()
    deadline = started + (c.max_wall_time_s if max_wall_time_s is None else max_wall_time_s)
    chart = ch.closed_form_chart(
        case.params, c.x, (c.x_min, c.x_max), c.y, (c.y_min, c.y_max), nx=nx, ny=ny,
        x_spacing=c.x_spacing, y_spacing=c.y_spacing, deadline=deadline,
    )  # fmt: skip
    n = min(c.check_points, QUICK_CHECK_POINTS) if quick else c.check_points
    continued = ch.continued_points(case.params, chart, n, progress, deadline)
    wall = time.perf_counter() - started
    return ChartResult(case, c, chart, wall, quick, continued, sweep)

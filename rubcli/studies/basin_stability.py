"""Basin stability along a parameter (``rubcli ensemble`` with ``[ensemble] parameter``), as
a library study: ``basin_stability_of(case)`` returns a ``BasinStabilityResult``, whose
``write(directory)`` writes ``basin_stability.csv``, ``basin_stability.png`` and
``report.json`` in one atomic commit (``rubcli.io``). The numerics are
``rubcli.analysis.ensembles.basin_stability``; the table is the case's ``[ensemble]``
(docs/cases.md)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import io
from rubcli.analysis.ensembles import basin_stability as bs
from rubcli.analysis.ensembles import ensemble as en
from rubcli.case import Case
from rubcli.solvers import wall_time_deadline
from rubcli.studies import ensemble as en_study

FILES = ("basin_stability.csv", "basin_stability.png", "report.json")
CSV_COLUMNS_TAIL = ("attractor", "count", "runs", "fraction", "ci_low", "ci_high")
# --quick: a CI run of a few seconds: the first, middle and last values, few short runs,
# the minimal perturbation along the 8 axes only, to a coarser bracket
QUICK = {"runs": 12, "periods": 300, "record_periods": 100, "lyapunov_periods": 50,
         "perturbation_directions": 0}  # fmt: skip
QUICK_VALUES = 3
QUICK_PERTURBATION_RTOL = 0.1
BOTH_GRID = 2001  # parameter values at which the closed-form regions are evaluated


def settings_of(case: Case, quick: bool = False) -> tuple[dict, list[str]]:
    """The settings from the case's ``[ensemble]`` (defaults filled, ``quick`` caps
    applied), or the problems with them (each naming the file and the field)."""
    src, e = case.source, case.settings.ensemble
    if e is None:
        return {}, [f"{src}: ensemble: missing table [ensemble] (docs/reproduction.md)"]
    if e.parameter is None:
        return {}, [f"{src}: ensemble.parameter: missing (what is the basin stability along?)"]
    s = e.model_dump()
    s["values"] = list(e.parameter_values())
    s["periods"] = s["periods"] or int(round(case.problem.periods))
    s["methods"] = s["methods"] or case.methods[:1]
    s["rtols"] = s["rtols"] or [case.settings.solver.rtol]
    if quick:
        s.update({k: min(s[k], v) for k, v in QUICK.items()})
        values = s["values"]
        if len(values) > QUICK_VALUES:
            s["values"] = [values[0], values[len(values) // 2], values[-1]]
        s["perturbation_rtol"] = max(s["perturbation_rtol"], QUICK_PERTURBATION_RTOL)
    for key in ("start", "stop", "num"):
        s.pop(key)
    if not s["record_periods"] < s["periods"]:
        return s, [f"{src}: ensemble.record_periods: {s['record_periods']} must be below "
                   f"the periods run ({s['periods']})"]  # fmt: skip
    return s, []


def both_spans(case: Case, parameter: str, values: list[float]) -> list[tuple[float, float]]:
    """The ranges of ``parameter`` within the values where the closed forms give both the
    free whirl and a stable synchronous rub (``analysis.charts.stability``, region "both"),
    each edge between two grid values located by bisection to 1e-9 of the range."""
    import dataclasses

    from rubcli.analysis.charts import stability as ch

    def both(v: float) -> bool:
        return ch.region(dataclasses.replace(case.params, **{parameter: float(v)})) == ch.BOTH

    def edge(outside: float, inside: float) -> float:
        while abs(inside - outside) > 1e-9 * span:
            middle = 0.5 * (outside + inside)
            outside, inside = (middle, inside) if not both(middle) else (outside, middle)
        return inside

    grid = np.linspace(min(values), max(values), BOTH_GRID)
    span = float(grid[-1] - grid[0])
    flags = [both(v) for v in grid]
    spans, k = [], 0
    while k < grid.size:
        if not flags[k]:
            k += 1
            continue
        j = k
        while j + 1 < grid.size and flags[j + 1]:
            j += 1
        lo = edge(grid[k - 1], grid[k]) if k > 0 else grid[k]
        hi = edge(grid[j + 1], grid[j]) if j + 1 < grid.size else grid[j]
        spans.append((float(lo), float(hi)))
        k = j + 1
    return spans


@dataclass
class BasinStabilityResult:
    """A basin stability along a parameter with what produced it; ``write`` puts it in a
    directory."""

    case: Case
    settings: dict
    basin: bs.BasinStability
    wall_time_s: float
    quick: bool = False

    def report(self, command_line: dict[str, Any]) -> dict[str, Any]:
        return {
            **io.report_envelope("ensemble", command_line, self.case.to_dict()),
            "mode": "basin_stability",
            "wall_time_s": self.wall_time_s,
            "starts": self.starts_description(),
            **self.basin.to_dict(),
        }

    def starts_description(self) -> str:
        s = self.settings
        if s["starts"] == "box":
            sides = ", ".join(f"{k} in [{lo:g}, {hi:g}]" for k, (lo, hi) in
                              ((k, v) for k, v in self.case.settings.ensemble.box().items()
                               if v is not None))  # fmt: skip
            return f"{s['runs']} starts uniform over {sides} (seed {s['seed']})"
        return f"the case's start and {s['runs'] - 1} within {s['spread']:g} of it"

    def write(
        self, directory: str | Path, plan: io.OutputPlan | None = None,
        command_line: dict[str, Any] | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Write the outputs into ``directory`` as one commit (``plan``: the dir as the
        caller opened and checked it; without one it is opened here); returns the report."""
        basin, case = self.basin, self.case
        report = self.report(command_line or {"out": str(directory)})
        with io.staged_output_dir(directory, plan) as staged:
            io.write_rows_csv(staged.path("basin_stability.csv"),
                              (basin.parameter, *CSV_COLUMNS_TAIL), basin.rows(),
                              nonfinite="")  # fmt: skip
            from rubcli.plotting.basin_stability import basin_stability_figure

            held = ", ".join(f"{k} = {v:g}" for k, v in case.params.as_dict().items()
                             if k not in (basin.parameter, "phi0"))  # fmt: skip
            periods = self.settings["periods"]
            title = f"{case.name}: {held}\n{self.starts_description()}, {periods} periods each"
            spans = both_spans(case, basin.parameter, basin.values)
            io.save_figure(basin_stability_figure(basin, title, spans),
                           staged.path("basin_stability.png"))  # fmt: skip
            report["files"] = staged.names() + ["report.json"]
            staged.write_report(report)
        return report


def basin_stability_of(
    case: Case,
    *,
    quick: bool = False,
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    max_wall_time_s: float | None = None,
) -> BasinStabilityResult:
    """The basin stability along the case's ``[ensemble] parameter`` (``quick``: the first,
    middle and last values, at most 12 runs of 300 periods each, the minimal perturbation
    along the axes only); ``progress(done, total)``. ValueError if the table cannot be
    run (its message names the file and the field).

    The whole, the minimal perturbations too, is bounded by ``[ensemble] max_wall_time_s``
    (``max_wall_time_s``: a budget instead of the table's; None in both: no budget but
    each run's): checked after every run and every direction, each solve getting at most
    the time left; ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` once it is spent
    (TypeError or ValueError naming ``max_wall_time_s`` for a budget that is not a
    number > 0)."""
    s, problems = settings_of(case, quick)
    if problems:
        raise ValueError("\n".join(problems))
    deadline = wall_time_deadline("basin_stability_of()", en_study.budget_of(case, max_wall_time_s))
    started = time.perf_counter()
    e = case.settings.ensemble
    start = case.problem.initial
    starts = en.box_starts(start, e.box(), s["runs"], s["seed"]) if s["starts"] == "box" else None
    perturbation = (
        bs.PerturbationSettings(s["perturbation_directions"], s["perturbation_max"],
                                s["perturbation_rtol"], s["seed"])
        if s["minimal_perturbation"] else None
    )  # fmt: skip
    basin = bs.basin_stability(
        case.params, s["parameter"], s["values"], start, starts, perturbation=perturbation,
        workers=workers, progress=progress, settings=s, runs=s["runs"], spread=s["spread"],
        seed=s["seed"], methods=s["methods"], rtols=s["rtols"], options=case.solver_options,
        periods=s["periods"], samples_per_period=case.settings.time.samples_per_period,
        record_periods=s["record_periods"], lyapunov=s["lyapunov"],
        lyapunov_periods=s["lyapunov_periods"], settle_tolerance=s["settle_tolerance"],
        deadline=deadline,
    )  # fmt: skip
    return BasinStabilityResult(case, s, basin, time.perf_counter() - started, quick)

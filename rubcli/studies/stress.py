"""The built-in suite of extreme cases (``rubcli stress``), as a library study:
``run_stress(cases, methods)`` runs every case with every method within its budget and
returns a ``StressResult``, whose ``write(directory)`` writes ``stress.csv``,
``stress.md`` and ``report.json`` in one atomic commit (``rubcli.io``). The cases and the
checks of each run are ``rubcli.analysis.accuracy.stress``'s (docs/stability.md).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rubcli import __version__, io
from rubcli.analysis.accuracy import stress

FILES = ("stress.csv", "stress.md", io.REPORT_NAME)


def _cell(value: object) -> object:
    """stress.csv keeps flags as 1/0."""
    return int(value) if isinstance(value, bool) else value


def write_csv(path: Path, runs: list[stress.StressRun]) -> None:
    rows = [[_cell(v) for v in run.as_row().values()] for run in runs]
    io.write_rows_csv(path, stress.RUN_COLUMNS, rows, nonfinite="")


def short_number(value: float | None, fmt: str = ".2g") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return format(value, fmt)


def markdown_text(
    runs: list[stress.StressRun], cases: list[stress.StressCase], quick: bool, command: str
) -> str:
    """stress.md: the cases, then one table row per run."""
    mode = "quick" if quick else "full"
    lines = [
        f"# rubcli stress ({mode})",
        "",
        f"`{command}`, rubcli {__version__}, "
        f"{dt.datetime.now(dt.UTC).isoformat(timespec='seconds')}.",
        "",
        "Error: max |w - w_ref| (clearances) over the samples the run shares with its "
        "reference. Energy residual: |ΔE - (W_in - D_damp - D_fric)| / throughput; it is "
        "informative only above its quadrature floor (docs/stability.md).",
        "",
        "## Cases",
        "",
        "| case | periods | samples/period | what |",
        "|---|---|---|---|",
    ]
    for case in cases:
        periods = case.quick_periods if quick else case.periods
        lines.append(f"| {case.name} | {periods:g} | {case.samples_per_period} | "
                     f"{case.description} |")  # fmt: skip
    lines += [
        "",
        "## Runs",
        "",
        "| case | method | status | wall s | periods | steps | events | reference | error "
        "| energy res. | quad. floor | max pen. | NaN | warning / message |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        message = (r.warning if r.status == "success" else r.message).replace("|", "/")
        if r.warning and r.status == "success":
            message = f"**WARNING: {message}**"
        lines.append(
            f"| {r.case} | {r.method} | {r.status} | {r.wall_time_s:.2f} | "
            f"{r.periods:.4g}/{r.target_periods:g} | {r.n_steps if r.n_steps is not None else '-'}"
            f" | {r.n_events} | {r.reference or '-'} | {short_number(r.error)} | "
            f"{short_number(r.energy_residual)} | {short_number(r.energy_quadrature_error)} | "
            f"{short_number(r.max_penetration, '.3g')} | {'yes' if r.nan else 'no'} | {message} |"
        )
    return "\n".join(lines) + "\n"


@dataclass
class StressResult:
    """The runs of the suite with what produced them; ``write`` puts them in a directory."""

    runs: list[stress.StressRun]
    cases: list[stress.StressCase]
    quick: bool

    @property
    def success(self) -> bool:
        """Every run ended cleanly (no solver exception, no non-finite state)."""
        return all(stress.clean(r) for r in self.runs)

    def write(
        self, directory: str | Path, plan: io.OutputPlan | None = None,
        command_line: dict[str, Any] | None = None, command: str = "rubcli stress",
    ) -> dict[str, Any]:  # fmt: skip
        """Write the outputs into ``directory`` as one commit (``plan``: the dir as the
        caller opened and checked it; without one it is opened here); returns the report.
        ``command``: the command line stress.md names."""
        report = {
            **io.report_envelope("stress", command_line or {"quick": self.quick}),
            "quick": self.quick,
            "success": self.success,
            "runs": [dataclasses.asdict(r) for r in self.runs],
            "files": list(FILES),
        }
        with io.staged_output_dir(directory, plan) as staged:
            write_csv(staged.path("stress.csv"), self.runs)
            text = markdown_text(self.runs, self.cases, self.quick, command)
            io.write_text(staged.path("stress.md"), text)
            staged.write_report(report)
        return report


def run_stress(
    cases: list[stress.StressCase] | None = None,
    methods: list[str] | None = None,
    *,
    quick: bool = False,
    on_run: Callable[[stress.StressRun], None] | None = None,
    max_wall_time_s: float | None = None,
) -> StressResult:
    """Every case (default: all of ``stress.stress_cases()``) with every method (default:
    all registered), ``on_run(run)`` after each; ``quick``: short horizons and budgets.

    ``max_wall_time_s`` (None: no budget but each run's) bounds the whole suite: checked
    after every run, each solve getting at most the time left;
    ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` once it is spent (TypeError or
    ValueError naming ``max_wall_time_s`` for a budget that is not a number > 0)."""
    from rubcli.analysis.orbits.periodic import check_deadline
    from rubcli.solvers import METHODS, wall_time_budget, wall_time_deadline

    deadline = wall_time_deadline("run_stress()", max_wall_time_s)
    cases = stress.stress_cases() if cases is None else cases
    methods = list(METHODS) if methods is None else methods

    def after(run: stress.StressRun) -> None:
        if on_run is not None:
            on_run(run)
        check_deadline(deadline)

    with wall_time_budget(deadline):
        runs = stress.run_suite(cases, methods, quick=quick, on_run=after)
    check_deadline(deadline)  # (a reference the budget cut short)
    return StressResult(runs, cases, quick)

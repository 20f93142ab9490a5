"""``rubcli ensemble CASE [--out DIR] [--workers N] [--quick] [--max-wall-time S]``: a fragile
outcome in numbers.

Runs the case's ``[ensemble]`` table (``rubcli.studies.ensemble``; docs/reproduction.md):
the case from a cloud of starts (or a box of them, ``starts = "box"``) at every setting of
a tolerance ladder, the end of each run classified and named, and writes

- ``ensemble.csv``: one row per run: method, rtol, start offset, attractor, regime, class,
  settled, time to reach the attractor (forcing periods), contact and stick fractions,
  whirl order, max z, Lyapunov exponent and error, contraction rate, rotation number;
- ``ensemble.png``: the fraction of runs on each attractor and the survival of the
  transient;
- ``report.json``: the case, the settings, the fractions with their intervals, the
  lifetime of the transient (mean, interval, median, per attractor), failed runs.

With ``[ensemble] parameter`` it runs the basin stability along that parameter instead
(``rubcli.studies.basin_stability``; docs/charts.md): the same starts at every value, the
attractors followed from value to value, and writes ``basin_stability.csv`` (per value and
attractor: count, runs, fraction, 95 % interval), ``basin_stability.png`` and
``report.json`` (with the minimal perturbation off the free whirl, where asked).

``[ensemble] max_wall_time_s`` (default none; ``--max-wall-time S``) bounds the whole
command, the minimal perturbations too: checked after every run, each solve getting at
most the time left.

Exit codes: 0 done; 1 every run failed, or the wall-time budget ran out (nothing
written); 2 invalid input (nothing written).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from rubcli.cli import console, progress, tables
from rubcli.cli.common import (
    ForceOption,
    JsonOption,
    WaitOption,
    budget_spent,
    check_max_wall_time,
    check_memory,
    command_dir,
    emit,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit

if TYPE_CHECKING:
    from rubcli.case import Case

OutOption = Annotated[
    Path | None, typer.Option("--out", "-o", help="Output dir (default: <case dir>/ensemble).")
]
WorkersOption = Annotated[
    int | None, typer.Option("--workers", "-w", min=1, help="Local processes (default: all cores).")
]
QuickOption = Annotated[
    bool,
    typer.Option("--quick", help="CI mode: 4 runs of 300 periods (along a parameter: 12 runs "
                 "at 3 values)."),
]  # fmt: skip
MaxWallTimeOption = Annotated[
    float | None,
    typer.Option("--max-wall-time", metavar="S",
                 help="Wall-time budget in seconds instead of [ensemble] max_wall_time_s."),
]  # fmt: skip


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: OutOption = None,
    workers: WorkersOption = None,
    quick: QuickOption = False,
    max_wall_time: MaxWallTimeOption = None,
    json: JsonOption = False,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Attractor fractions and escape times over a cloud of starts (the ensemble table)."""
    check_max_wall_time(max_wall_time)
    case = load_or_exit(case_file)
    e = case.settings.ensemble
    if e is not None and e.parameter is not None:
        _basin_stability(case_file, case, out, workers, quick, json, force, wait, max_wall_time)
        return
    from rubcli.studies import ensemble as study

    s, workers = _checked(case_file, *study.settings_of(case, quick), workers)
    _check_run_memory(case_file, case, s)
    target = command_dir(case, "ensemble", out)
    plan = prepare_output(target, force, wait, study.FILES)
    with console.machine_readable(json):
        runs = study.run_count(s)
        with (progress.progress_bar(f"ensemble of {runs} runs", total=runs) as update,
              _budget(case_file, study.budget_of(case, max_wall_time))):  # fmt: skip
            found = study.ensemble_of(case, quick=quick, workers=workers, progress=update,
                                      max_wall_time_s=max_wall_time)  # fmt: skip
        command_line = {"case_file": str(case_file), "out": str(target), "quick": quick,
                        "workers": workers, "max_wall_time": max_wall_time}  # fmt: skip
        report = found.write(target, plan, command_line)
        report_stale(plan)
        emit(report, json)
        result = found.result
        if not result.good:
            console.error(f"{case_file}: every run failed; see {target}/report.json")
            raise typer.Exit(1)
        rows = [[name, str(o["runs"]),
                 f"{o['fraction']:.2f} [{o['lower']:.2f}, {o['upper']:.2f}]"]
                for name, o in result.outcomes().items()]  # fmt: skip
        tables.table("where the runs end", ["attractor", "runs", "fraction [95 %]"], rows)
        life = result.lifetimes()["mean_lifetime"]
        if life["mean"]:
            console.info(f"mean lifetime of the transient: {life['mean']:.0f} forcing periods "
                         f"[{life['lower']:.0f}, {life['upper']:.0f}] (95 %)")  # fmt: skip
        console.success(f"wrote {', '.join(report['files'])} to {target}")


def _basin_stability(case_file, case, out, workers, quick, json, force, wait,
                     max_wall_time) -> None:  # fmt: skip
    """``[ensemble] parameter``: the basin stability along it (rubcli.studies.basin_stability)."""
    from rubcli.studies import basin_stability as study
    from rubcli.studies.ensemble import budget_of

    s, workers = _checked(case_file, *study.settings_of(case, quick), workers)
    _check_run_memory(case_file, case, s)
    target = command_dir(case, "ensemble", out)
    plan = prepare_output(target, force, wait, study.FILES)
    with console.machine_readable(json):
        n = len(s["values"])
        bar = f"basin stability: {n} values of {s['parameter']}"
        with (progress.progress_bar(bar, total=1.0) as update,
              _budget(case_file, budget_of(case, max_wall_time))):  # fmt: skip
            result = study.basin_stability_of(
                case, quick=quick, workers=workers, progress=lambda done, n: update(done / n),
                max_wall_time_s=max_wall_time,
            )  # fmt: skip
        command_line = {"case_file": str(case_file), "out": str(target), "quick": quick,
                        "workers": workers, "max_wall_time": max_wall_time}  # fmt: skip
        report = result.write(target, plan, command_line)
        report_stale(plan)
        emit(report, json)
        basin = result.basin
        if not any(basin.good_runs(i) for i in range(n)):
            console.error(f"{case_file}: every run failed; see {target}/report.json")
            raise typer.Exit(1)
        labels = basin.labels
        rows = []
        for i, value in enumerate(basin.values):
            f = basin.fractions(i)
            rows.append([f"{value:g}", str(basin.good_runs(i))]
                        + [f"{f[k]['fraction']:.2f} [{f[k]['ci_low']:.2f}, {f[k]['ci_high']:.2f}]"
                           for k in labels] + [str(basin.failed_runs(i))])  # fmt: skip
        tables.table(f"where the runs end along {basin.parameter} (fraction [95 %])",
                     [basin.parameter, "runs", *labels, "failed"], rows)  # fmt: skip
        for p in basin.perturbations:
            if p.found:
                d = ", ".join(f"{v:.2f}" for v in p.direction)
                console.info(f"{basin.parameter} = {p.value:g}: minimal perturbation <= "
                             f"{p.size:.3g} along ({d}) onto {p.reached}")  # fmt: skip
            else:
                why = "not found" if p.computable else "not computable"
                console.info(f"{basin.parameter} = {p.value:g}: minimal perturbation {why}: "
                             f"{p.reason}")  # fmt: skip
        console.success(f"wrote {', '.join(report['files'])} to {target}")


@contextlib.contextmanager
def _budget(case_file: Path, budget: float | None) -> Iterator[None]:
    """Exit 1 with one message if the wall-time budget ran out within."""
    from rubcli.analysis.orbits.periodic import WallTimeBudgetError

    try:
        yield
    except WallTimeBudgetError:
        raise budget_spent(case_file, budget, "[ensemble] max_wall_time_s") from None


def _check_run_memory(case_file: Path, case: Case, settings: dict) -> None:
    """Exit 2 if one run's samples will not fit in a process (each process, a worker or
    this one, holds one run at a time)."""
    samples = settings["periods"] * case.settings.time.samples_per_period + 1
    check_memory(case_file, samples, 1, fields="ensemble.periods (default time.periods)")


def _checked(
    case_file: Path, settings: Any, problems: list[str], workers: int | None
) -> tuple[Any, int]:
    """The settings and the number of workers, or exit 2 with the problems (the table's,
    or more workers than cores)."""
    from rubcli.analysis.sweep import check_workers

    if problems:
        console.error_lines(f"cannot run the ensemble of {case_file}", problems)
        raise typer.Exit(EXIT_INVALID)
    try:
        return settings, check_workers(workers)  # no more processes than cores
    except ValueError as exc:
        console.error(f"--{exc}")
        raise typer.Exit(EXIT_INVALID) from None

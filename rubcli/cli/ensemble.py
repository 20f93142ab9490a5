"""``rubcli ensemble CASE [--out DIR] [--workers N] [--quick]``: a fragile outcome in numbers.

Runs the case's ``[ensemble]`` table (``rubcli.analysis.ensemble``; docs/reproduction.md):
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

Exit codes: 0 done; 1 every run failed; 2 invalid input (nothing written).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from rubcli import io
from rubcli.analysis import ensemble as en
from rubcli.cli import console, progress
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

if TYPE_CHECKING:
    from rubcli.case import Case

QUICK = {"runs": 4, "periods": 300, "record_periods": 100, "lyapunov_periods": 50}
COLUMNS = ("run", "method", "rtol", "start_offset", "attractor", "regime", "kind", "settled",
           "settle_period", "contact_fraction", "stick_fraction", "whirl_order", "z_max",
           "lyapunov", "lyapunov_stderr", "contraction_rate", "rotation_number", "ok",
           "message")  # fmt: skip


def settings_of(case: Case, quick: bool) -> tuple[dict, list[str]]:
    """The ensemble's settings from the case (and --quick), or the problems with it."""
    src, e = case.source, case.settings.ensemble
    if e is None:
        return {}, [f"{src}: ensemble: missing table [ensemble] (docs/reproduction.md)"]
    s = e.model_dump()
    s["periods"] = s["periods"] or int(round(case.problem.periods))
    s["methods"] = s["methods"] or case.methods[:1]
    s["rtols"] = s["rtols"] or [case.settings.solver.rtol]
    if quick:
        s.update({k: min(s[k], v) for k, v in QUICK.items()})
    if not s["record_periods"] < s["periods"]:
        return s, [f"{src}: ensemble.record_periods: {s['record_periods']} must be below "
                   f"the periods run ({s['periods']})"]  # fmt: skip
    return s, []


OutOption = Annotated[
    Path | None, typer.Option("--out", "-o", help="Output dir (default: <case dir>/ensemble).")
]
WorkersOption = Annotated[
    int | None, typer.Option("--workers", "-w", min=1, help="Local processes (default: all cores).")
]
EXPECTED_FILES = ("ensemble.csv", "ensemble.png", "report.json")
QuickOption = Annotated[
    bool,
    typer.Option("--quick", help="CI mode: 4 runs of 300 periods (along a parameter: 12 runs "
                 "at 3 values)."),
]  # fmt: skip


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: OutOption = None,
    workers: WorkersOption = None,
    quick: QuickOption = False,
    json: JsonOption = False,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Attractor fractions and escape times over a cloud of starts (the ensemble table)."""
    case = load_or_exit(case_file)
    e = case.settings.ensemble
    if e is not None and e.parameter is not None:
        _basin_stability(case_file, case, out, workers, quick, json, force, wait)
        return
    s, workers = _checked(case_file, *settings_of(case, quick), workers)
    target = command_dir(case, "ensemble", out)
    plan = prepare_output(target, force, wait, EXPECTED_FILES)
    with console.machine_readable(json):
        started = time.perf_counter()
        starts = (en.box_starts(case.problem.initial, e.box(), s["runs"], s["seed"])
                  if s["starts"] == "box" else None)  # fmt: skip
        tasks = en.member_tasks(
            case.params, case.problem.initial, runs=s["runs"], spread=s["spread"],
            seed=s["seed"], methods=s["methods"], rtols=s["rtols"],
            options=case.solver_options, periods=s["periods"],
            samples_per_period=case.settings.time.samples_per_period,
            record_periods=s["record_periods"], lyapunov=s["lyapunov"],
            lyapunov_periods=s["lyapunov_periods"], settle_tolerance=s["settle_tolerance"],
            starts=starts,
        )  # fmt: skip
        with progress.progress_bar(f"ensemble of {len(tasks)} runs", total=len(tasks)) as update:
            result = en.run_ensemble(tasks, workers=min(workers, len(tasks)), progress=update,
                                     settings=s)  # fmt: skip
        report = {
            **io.report_envelope("ensemble", {"case_file": str(case_file), "out": str(target),
                                              "quick": quick, "workers": workers}, case.to_dict()),
            "wall_time_s": time.perf_counter() - started,
            **result.to_dict(),
            "members": [m.to_dict() for m in result.members],
        }  # fmt: skip
        with io.staged_output_dir(target, plan) as staged:
            rows = [[m.index, m.method, m.rtol, m.offset, m.attractor, m.regime, m.kind,
                     m.settled, m.settle_period, m.contact_fraction, m.stick_fraction,
                     m.whirl_order, m.z_max, m.lyapunov, m.lyapunov_stderr,
                     m.contraction_rate, m.rotation_number, m.ok, m.message]
                    for m in result.members]  # fmt: skip
            io.write_rows_csv(staged.path("ensemble.csv"), COLUMNS, rows, nonfinite="")
            if result.good:
                from rubcli.plotting.ensemble import ensemble_figure

                p = case.params
                where = (
                    f"starts within {s['spread']:g}"
                    if starts is None
                    else "starts in a box: "
                    + ", ".join(f"{k} in [{v[0]:g}, {v[1]:g}]" for k, v in e.box().items() if v)
                )
                title = (f"{case.name}: {len(tasks)} runs of {s['periods']} periods, mu = "
                         f"{p.mu:g}, eta = {p.eta:g}, e = {p.e:g}, {where}")  # fmt: skip
                io.save_figure(ensemble_figure(result, title), staged.path("ensemble.png"))
            report["files"] = sorted(f.name for f in staged.staging.iterdir()) + ["report.json"]
            staged.write_report(report)
        report_stale(plan)
        emit(report, json)
        if not result.good:
            console.error(f"{case_file}: every run failed; see {target}/report.json")
            raise typer.Exit(1)
        rows = [[name, str(o["runs"]),
                 f"{o['fraction']:.2f} [{o['lower']:.2f}, {o['upper']:.2f}]"]
                for name, o in result.outcomes().items()]  # fmt: skip
        console.table("where the runs end", ["attractor", "runs", "fraction [95 %]"], rows)
        life = result.lifetimes()["mean_lifetime"]
        if life["mean"]:
            console.info(f"mean lifetime of the transient: {life['mean']:.0f} forcing periods "
                         f"[{life['lower']:.0f}, {life['upper']:.0f}] (95 %)")  # fmt: skip
        console.success(f"wrote {', '.join(report['files'])} to {target}")


def _basin_stability(case_file, case, out, workers, quick, json, force, wait) -> None:
    """``[ensemble] parameter``: the basin stability along it (rubcli.studies.basin_stability)."""
    from rubcli.studies import basin_stability as study

    s, workers = _checked(case_file, *study.settings_of(case, quick), workers)
    target = command_dir(case, "ensemble", out)
    plan = prepare_output(target, force, wait, study.FILES)
    with console.machine_readable(json):
        n = len(s["values"])
        bar = f"basin stability: {n} values of {s['parameter']}"
        with progress.progress_bar(bar, total=1.0) as update:
            result = study.basin_stability_of(
                case, quick=quick, workers=workers, progress=lambda done, n: update(done / n)
            )
        command_line = {"case_file": str(case_file), "out": str(target), "quick": quick,
                        "workers": workers}  # fmt: skip
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
        console.table(f"where the runs end along {basin.parameter} (fraction [95 %])",
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

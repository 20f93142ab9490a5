"""``rubcli compare CASE [--out DIR] [--quick] [--max-wall-time S]``: reference, error
against run time, orbits.

What it does, in order (docs/compare.md):

1. **Reference** for the work-precision problem (``[compare] horizon_periods``, default
   the case's ``[time] periods``): exact where the case has one, otherwise DOP853 at 1e-12
   checked against LSODA at 1e-12, with its predictability horizon
   (``rubcli.analysis.accuracy.reference``).
2. **Work-precision** (unless ``[compare] work_precision = false``): each method of
   ``[compare] methods`` (default ``[solver] methods``) over its ladder, timed (median of
   ``repeats``; start-up apart) and measured against the reference
   (``rubcli.analysis.accuracy.work_precision``). Writes ``work_precision.csv``,
   ``work_precision.png`` and ``error_growth.png``.
3. **Orbits**: for the case's mu, or for each value of ``[compare] mu`` (the paper's
   Figure 3 is ``mu = [0, 0.01, ..., 0.05]``), each method at the case's ``[solver]``
   settings over ``[time] periods``, with its error against a reference of that mu and
   the largest difference between the methods. Writes ``orbits.png`` (one panel per mu:
   transient faded, the last periods bold, keyphasor dots), ``spectrum.png`` (the full
   spectrum of x + i y over the steady span, per mu; its dominant line in report.json)
   (both at a constant speed only: with ``[speed]`` their keyphasor and orders have no
   one period) and, with a mu list, ``sweep.csv``. The synchronous full annular rub of each mu is
   reported with its stability (``rubcli.analysis.orbits.synchronous``).
4. **Response** (only with ``[analysis] response = true``): the class of each method's
   steady response from the stroboscopic section after ``transient_periods``, backed by
   the largest Lyapunov exponent; ``poincare.png``.

``report.md`` and ``report.json`` summarise everything (``--json``: the report on stdout
only). The study is ``rubcli.studies.compare`` (on ``rubcli.analysis.accuracy.work_precision``
and ``panels``); this module parses, calls and prints. ``--quick`` (for CI) shortens the
ladders (rtol 1e-3, 1e-6, 1e-9; steps_per_period 25, 100, 400), runs each setting once,
caps the work-precision horizon at 5 periods, the orbit runs at 150 periods (a transient
longer than the run is cut to 2/3 of it) and the Lyapunov run at 30 periods.

``[compare] total_wall_time_s`` (default none; ``--max-wall-time S``) bounds the whole
command beside each solve's ``[compare] max_wall_time_s``: checked after the ladders and
after each orbit panel, every solve getting at most the time left.

Exit codes: 0 done (failed settings are results, listed in the report); 2 invalid input or
unusable output dir (checked before anything is computed, ``rubcli.io.open_output_dir``);
1 if no reference could be built, or the wall-time budget ran out (nothing written);
128 + N when stopped by signal N.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from rubcli import io
from rubcli.analysis.accuracy.reference import ReferenceError
from rubcli.case import Case, CompareSection
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
    machine_readable,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit
from rubcli.studies import compare as study

EXIT_FAILED = 1
QUICK_HELP = f"For CI: {study.QUICK_TEXT}."


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", metavar="DIR", help="Output dir (default: <case output dir>/compare)."
        ),
    ] = None,  # fmt: skip
    quick: Annotated[bool, typer.Option("--quick", help=QUICK_HELP)] = False,
    max_wall_time: Annotated[
        float | None,
        typer.Option(
            "--max-wall-time",
            metavar="S",
            help="Wall-time budget of the whole command in seconds instead of [compare] "
            "total_wall_time_s.",
        ),
    ] = None,
    force: ForceOption = False,
    wait: WaitOption = False,
    json: JsonOption = False,
) -> None:
    """Reference solution, error against run time per method, orbits and response classes."""
    check_max_wall_time(max_wall_time)
    from rubcli.cli import rotor

    rotor_case = rotor.rotor_case_or_none(case_file)
    if rotor_case is not None:
        if quick:
            console.error(f"{case_file}: --quick: a machine given as matrices runs its own ladder")
            raise typer.Exit(EXIT_INVALID)
        rotor.compare(rotor_case, case_file, out, max_wall_time, force, wait, json)
        return
    case = load_or_exit(case_file)
    cfg = case.settings.compare or CompareSection()
    from rubcli import solvers

    methods = list(cfg.methods or case.methods)
    unavailable = [m for m in methods if m not in solvers.METHODS]
    if unavailable:
        console.error(f"{case_file}: methods not available: {', '.join(unavailable)}")
        raise typer.Exit(EXIT_INVALID)
    check_memory(case_file, *study.samples_in_memory(case, cfg, quick))
    target = command_dir(case, "compare", out)
    plan = prepare_output(target, force, wait, study.expected_files(case, cfg))
    command_line = {"case_file": str(case_file), "out": str(out) if out else None,
                    "quick": quick, "max_wall_time": max_wall_time}  # fmt: skip
    with machine_readable(json):
        report = _compare(case, cfg, methods, quick, target, plan, command_line)
    emit(report, json)


def _compare(
    case: Case,
    cfg: CompareSection,
    methods: list[str],
    quick: bool,
    target: Path,
    plan: io.OutputPlan,
    command_line: dict[str, Any],
) -> dict[str, Any]:
    console.info(f"{case.name}: compare {', '.join(methods)}" + (" (quick)" if quick else ""))
    from rubcli.analysis.orbits.periodic import WallTimeBudgetError

    max_wall_time = command_line["max_wall_time"]
    try:
        result = study.compare_case(case, quick=quick, progress_bar=progress.progress_bar,
                                    max_wall_time_s=max_wall_time)  # fmt: skip
    except ReferenceError as exc:
        console.error(f"no reference solution: {exc}")
        raise typer.Exit(EXIT_FAILED) from None
    except WallTimeBudgetError:
        budget = cfg.total_wall_time_s if max_wall_time is None else max_wall_time
        raise budget_spent(
            command_line["case_file"], budget, "[compare] total_wall_time_s"
        ) from None
    report = result.write(target, plan, command_line)
    report_stale(plan)
    wp, panels, files = result.wp, result.panels, report["files"]
    from rubcli.plotting import compare as plots

    if wp is not None:
        tables.table(
            f"{case.name}: work-precision ({wp.problem.periods:.4g} periods)",
            [
                "method",
                "setting",
                "wall s",
                "error max",
                "error final",
                "steps",
                "f evals",
                "status",
            ],  # fmt: skip
            plots.table_rows(wp.rows),
        )
        for t, row in wp.cheapest().items():
            text = "-" if row is None else f"{row.method} {row.setting_name} = {row.label}"
            console.info(f"cheapest for error <= {t:g}: {text}")
    for panel in panels:
        for run in panel.runs:
            if run.response is not None:
                r = run.response.response
                console.info(f"mu = {panel.mu:g} {run.method}: {r.kind}"
                             + (f", period {r.period}" if r.period else "")
                             + f" ({r.message})")  # fmt: skip
            if not run.solution.success:
                console.warning(f"mu = {panel.mu:g} {run.method}: {run.solution.message}")
    console.info(f"wrote {len(files)} files to {target}: {', '.join(files)}")
    return report

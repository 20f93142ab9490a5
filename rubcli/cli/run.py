"""``rubcli run CASE [--method NAME]... [--out DIR] [--periods P] [--max-wall-time S]
[--force] [--json]``.

Each method of the case (or of ``--method``) is solved and only the products the case asks
for are written into the output dir (``rubcli.studies.run``, whose docstring lists them).
A case whose machine is given as matrices (``[rotor] matrices``) runs through
``rubcli.cli.rotor``.

The output dir is locked and checked before anything is solved, and all files are
committed as a whole at the end (``rubcli.io.open_output_dir``; docs/cases.md, "Output
dirs").

``[solver] total_wall_time_s`` (default none; ``--max-wall-time S``) bounds the whole
run beside each method's ``[solver] max_wall_time_s``: checked between the methods, each
solve getting at most the time left.

Exit codes: 0 success; 2 invalid input or unusable output dir (nothing is solved or
written); 1 if any method failed (its failure is in report.json; the outputs of the run
are still written), or the run's wall-time budget ran out (nothing written); 3 if every
method finished but one or more failed a plausibility check (``status: warning`` in
report.json: e.g. a tolerance so loose that the orbit ends deep inside the stator): the
files are written, but the result must not be trusted; 74 the outputs could not be
written (nothing of this run is); 75 the output dir is in use (``--wait`` waits); 128 + N
when stopped by signal N.
"""

from __future__ import annotations

import gc
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from rubcli import io
from rubcli.analysis.runs.checks import WARNING
from rubcli.case import KNOWN_METHODS, Case, CaseError
from rubcli.cli import console, progress, tables
from rubcli.cli.common import (
    ForceOption,
    JsonOption,
    WaitOption,
    budget_spent,
    check_max_wall_time,
    check_memory,
    emit,
    machine_readable,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit
from rubcli.studies import run as study
from rubcli.studies import run_summary as summary

if TYPE_CHECKING:
    from rubcli.plotting.transient import SteadyStates

EXIT_FAILED = 1
EXIT_WARNING = 3


def _check_methods(names: list[str] | None) -> list[str] | None:
    """--method values: known names, repeated ones dropped (first kept)."""
    if not names:
        return None
    unknown = [n for n in names if n not in KNOWN_METHODS]
    if unknown:
        console.error(
            f"--method: unknown method {', '.join(repr(n) for n in unknown)}; "
            f"choose from {', '.join(KNOWN_METHODS)}"
        )
        raise typer.Exit(EXIT_INVALID)
    return list(dict.fromkeys(names))


def _apply_overrides(
    case: Case, methods: list[str] | None, out: Path | None, periods: float | None
) -> Case:
    if periods is not None and not (math.isfinite(periods) and periods > 0):
        console.error(f"--periods: must be a finite number > 0 (got {periods!r})")
        raise typer.Exit(EXIT_INVALID)
    try:
        return case.with_overrides(methods=methods, periods=periods, output_dir=out)
    except CaseError as exc:
        console.error_lines("invalid command-line override", exc.problems)
        raise typer.Exit(EXIT_INVALID) from None


# A start-up longer than this is numba compiling (a warm cache loads in 0.2-0.5 s): say so.
START_UP_NOTICE_S = 2.0
COMPILING_NOTICE = (
    "compiling the numba kernels (the first run on a machine, or after an update: about a "
    "minute on an idle 2-core machine, longer on a busy one); later runs load them in about "
    "a second"
)


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    method: Annotated[
        list[str] | None,
        typer.Option(
            "--method",
            "-m",
            metavar="NAME",
            help=f"Method to run instead of the case's (repeatable): {', '.join(KNOWN_METHODS)}.",
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", metavar="DIR", help="Output dir instead of the case's (output.dir)."
        ),
    ] = None,
    periods: Annotated[
        float | None,
        typer.Option(
            "--periods",
            metavar="P",
            help="Duration in forcing periods instead of the case's time.periods (quick checks).",
        ),
    ] = None,
    overlay: Annotated[
        Path | None,
        typer.Option(
            "--overlay",
            metavar="SWEEP_NC",
            help="A case with [speed]: draw the steady states of a `rubcli sweep` over eta "
            "of the same machine (its sweep.nc) under the Bode plot.",
        ),
    ] = None,
    max_wall_time: Annotated[
        float | None,
        typer.Option(
            "--max-wall-time",
            metavar="S",
            help="Wall-time budget of the whole run in seconds instead of [solver] "
            "total_wall_time_s.",
        ),
    ] = None,
    force: ForceOption = False,
    wait: WaitOption = False,
    json: JsonOption = False,
) -> None:
    """Solve a case with each of its methods and write CSVs, plots and report.json."""
    check_max_wall_time(max_wall_time)
    from rubcli.cli import rotor

    matrices_case = rotor.rotor_case_or_none(case_file)
    if matrices_case is not None:
        rotor.run(matrices_case, case_file, method, out, periods, max_wall_time, force, wait, json)
        return
    case = load_or_exit(case_file)
    case = _apply_overrides(case, _check_methods(method), out, periods)
    target = case.output_dir

    from rubcli import solvers

    unavailable = [m for m in case.methods if m not in solvers.METHODS]
    if unavailable:
        console.error(f"{case_file}: solver.methods: not available: {', '.join(unavailable)}")
        raise typer.Exit(EXIT_INVALID)
    steady = _steady_or_exit(case, overlay)
    check_memory(case_file, case.problem.t_eval.size, len(case.methods))
    plan = prepare_output(target, force, wait, study.expected_files(case))

    with machine_readable(json):
        report = _run(case, case_file, method, out, periods, plan, steady, max_wall_time)
    emit(report, json)
    entries = report["methods"]
    failed = {n: e for n, e in entries.items() if e["status"] not in ("success", WARNING)}
    for name, entry in failed.items():
        console.error(f"method {name} {entry['status']}: {entry['message']}")
    warned = {n: e for n, e in entries.items() if e["status"] == WARNING}
    for name, entry in warned.items():
        console.warning(f"method {name}: do not trust this result: {'; '.join(entry['warnings'])}")
    if failed:
        raise typer.Exit(EXIT_FAILED)
    if warned:
        raise typer.Exit(EXIT_WARNING)


def _run(
    case: Case, case_file: Path, method: list[str] | None, out: Path | None,
    periods: float | None, plan: io.OutputPlan, steady: SteadyStates | None = None,
    max_wall_time: float | None = None,
) -> dict[str, Any]:  # fmt: skip
    console.info(
        f"{case.name}: {summary.span_text(case.problem)}, methods {', '.join(case.methods)}"
    )
    command_line = {"case_file": str(case_file), "methods": method or None,
                    "out": str(out) if out is not None else None, "periods": periods,
                    "max_wall_time": max_wall_time}  # fmt: skip
    # Solved first, every method alone (its timing its own), then written
    # (``RunResult.write``). What the imports made lives as long as the process: frozen
    # out of the cyclic collector's passes, and not unfrozen (the last collection at exit
    # would walk it all).
    gc.freeze()
    from rubcli import solvers
    from rubcli.analysis.orbits.periodic import WallTimeBudgetError

    budget = case.settings.solver.total_wall_time_s if max_wall_time is None else max_wall_time
    deadline = None if budget is None else time.perf_counter() + budget  # the warm-up's too
    try:
        with (console.notice_if_slow(COMPILING_NOTICE, START_UP_NOTICE_S),
              solvers.wall_time_budget(deadline)):  # fmt: skip
            startup = study.start_up(case)
        if startup > 0.05:
            console.info(f"start-up (compiled kernels loaded or compiled): {startup:.2f} s")
        left = None if deadline is None else max(deadline - time.perf_counter(),
                                                 solvers.LAST_SOLVE_S)  # fmt: skip
        result = study.run_case(case, progress_bar=progress.progress_bar,
                                on_error=console.exception, startup_s=startup,
                                max_wall_time_s=left)  # fmt: skip
    except WallTimeBudgetError:
        raise budget_spent(case_file, budget, "[solver] total_wall_time_s") from None
    report = result.write(case.output_dir, plan, command_line, progress.progress_bar, steady)
    entries = report["methods"]
    report_stale(plan)

    tables.table(f"{case.name}: results", list(summary.COLUMNS), summary.summary_rows(entries),
                 caption=summary.CAPTION)  # fmt: skip
    for name, entry in entries.items():
        if entry.get("transient") is not None:
            console.info(summary.transient_line(name, entry["transient"]))
    files = report["files"]
    console.info(f"wrote {len(files)} files to {case.output_dir}: {', '.join(files)}")
    return report


def _steady_or_exit(case: Case, overlay: Path | None) -> SteadyStates | None:
    """The steady states of ``--overlay`` (None without it); exit 2 naming the problem."""
    if overlay is None:
        return None
    from rubcli.studies.transient import load_steady

    steady = load_steady(overlay, case)
    if isinstance(steady, list):
        console.error_lines("cannot overlay the sweep", steady)
        raise typer.Exit(EXIT_INVALID)
    return steady

"""``rubcli stress [--out DIR] [--quick] [--max-wall-time S]``: the built-in suite of
extreme cases.

Runs every case of ``rubcli.analysis.accuracy.stress.stress_cases`` with every method (or the
``--case`` / ``--method`` subsets), each within its budget, and writes into ``DIR``
(default ``out/stress``, or ``out/stress-quick`` with ``--quick``):

- ``stress.csv``: one row per run: case, method, status, message, wall time, periods
  reached, steps, events, reference used, error against it, energy residual and its
  quadrature floor, max penetration, whether any state was not finite, stick fraction;
- ``stress.md``: the same as a readable table, with the cases described;
- ``report.json``: the common report envelope, the runs as records, ``files`` (the
  manifest of the output dir).

``--json`` prints the report on stdout only. ``--quick`` shortens every horizon and
budget (about a minute in all: the test suite runs it). Exit 0 when every run ended
cleanly (``success``, or ``failed`` with a reason such as an exhausted budget, and no
non-finite state); 1 if a solver raised or produced a non-finite state, or the
suite's wall-time budget ran out (``--max-wall-time S``, default none: checked after
every run, each solve getting at most the time left; nothing written); 2 on invalid
options or an unusable output dir. Warnings (a success whose energy balance or exact
error says the orbit is wrong) are findings, shown in the table and in stress.md; they
do not change the exit code. Files are staged and moved in at the end.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rubcli import io
from rubcli.analysis.accuracy import stress
from rubcli.cli import console, progress, tables
from rubcli.cli.common import (
    ForceOption,
    JsonOption,
    WaitOption,
    check_max_wall_time,
    emit,
    machine_readable,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID
from rubcli.studies import stress as study
from rubcli.studies.stress import short_number

EXIT_FAILED = 1


def command(
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", metavar="DIR", help="Output dir (default out/stress)."),
    ] = None,
    quick: Annotated[
        bool, typer.Option("--quick", help="Short horizons and small budgets (~1 minute).")
    ] = False,
    case: Annotated[
        list[str] | None,
        typer.Option("--case", metavar="NAME", help="Run only this case (repeatable)."),
    ] = None,
    method: Annotated[
        list[str] | None,
        typer.Option("--method", "-m", metavar="NAME", help="Run only this method (repeatable)."),
    ] = None,
    max_wall_time: Annotated[
        float | None,
        typer.Option(
            "--max-wall-time",
            metavar="S",
            help="Wall-time budget of the whole suite in seconds (default none).",
        ),
    ] = None,  # fmt: skip
    force: ForceOption = False,
    wait: WaitOption = False,
    json: JsonOption = False,
) -> None:
    """Run the built-in suite of extreme cases with every method; write stress.csv and .md."""
    from rubcli.solvers import METHODS

    check_max_wall_time(max_wall_time)

    cases = stress.stress_cases()
    names = [c.name for c in cases]
    if case:
        unknown = [n for n in case if n not in names]
        if unknown:
            console.error(f"--case: unknown case {', '.join(unknown)}; choose from "
                          f"{', '.join(names)}")  # fmt: skip
            raise typer.Exit(EXIT_INVALID)
        cases = [c for c in cases if c.name in case]
    methods = list(METHODS)
    if method:
        unknown = [m for m in method if m not in METHODS]
        if unknown:
            console.error(f"--method: unknown method {', '.join(unknown)}; choose from "
                          f"{', '.join(METHODS)}")  # fmt: skip
            raise typer.Exit(EXIT_INVALID)
        methods = list(dict.fromkeys(method))
    target = out if out is not None else Path("out/stress-quick" if quick else "out/stress")
    plan = prepare_output(target, force, wait, study.FILES)
    with machine_readable(json):
        runs, report = _stress(cases, methods, quick, target, plan, case, method, max_wall_time)
    emit(report, json)
    bad = [r for r in runs if not stress.clean(r)]
    for r in bad:
        console.error(f"{r.case} / {r.method}: {r.status}: {r.message}"
                      + (" (non-finite state)" if r.nan else ""))  # fmt: skip
    if bad:
        raise typer.Exit(EXIT_FAILED)


def _stress(
    cases: list[stress.StressCase],
    methods: list[str],
    quick: bool,
    target: Path,
    plan: io.OutputPlan,
    case: list[str] | None,
    method: list[str] | None,
    max_wall_time: float | None = None,
) -> tuple[list[stress.StressRun], dict]:
    from rubcli.analysis.orbits.periodic import WallTimeBudgetError

    console.info(
        f"stress ({'quick' if quick else 'full'}): {len(cases)} cases x {len(methods)} methods"
    )
    done = [0]
    total = len(cases) * len(stress.method_variants(methods))
    with progress.progress_bar("stress  ", total=total) as update:

        def on_run(run: stress.StressRun) -> None:
            done[0] += 1
            update(done[0])
            console.info(
                f"{run.case:>20} {run.method:<24} {run.status:<8} {run.wall_time_s:8.2f} s"
                + ("" if run.status == "success" else f"  {run.message}")
            )

        try:
            result = study.run_stress(cases, methods, quick=quick, on_run=on_run,
                                      max_wall_time_s=max_wall_time)  # fmt: skip
        except WallTimeBudgetError:
            console.error(f"stress: stopped by the wall-time budget ({max_wall_time:g} s) "
                          f"after {done[0]} of {total} runs: nothing written "
                          "(--max-wall-time for more)")  # fmt: skip
            raise typer.Exit(EXIT_FAILED) from None

    parts = ["rubcli stress"] + (["--quick"] if quick else [])
    parts += [f"--case {c}" for c in case or []] + [f"--method {m}" for m in method or []]
    parts += [f"--max-wall-time {max_wall_time:g}"] if max_wall_time is not None else []
    command_line = {"quick": quick, "cases": case or None, "methods": method or None,
                    "max_wall_time": max_wall_time}  # fmt: skip
    report = result.write(target, plan, command_line, " ".join(parts))
    report_stale(plan)
    runs = result.runs
    rows = [
        [r.case, r.method, r.status, f"{r.wall_time_s:.2f}", short_number(r.error),
         short_number(r.energy_residual), "yes" if r.nan else "no", r.warning]
        for r in runs
    ]  # fmt: skip
    tables.table(
        "stress",
        ["case", "method", "status", "wall s", "error", "energy res.", "NaN", "warning"],
        rows,
    )
    console.info(f"wrote {', '.join(report['files'])} to {target}")
    return runs, report

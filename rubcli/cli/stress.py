"""``rubcli stress [--out DIR] [--quick]``: the built-in suite of extreme cases.

Runs every case of ``rubcli.analysis.stress.stress_cases`` with every method (or the
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
non-finite state); 1 if a solver raised or produced a non-finite state; 2 on invalid
options or an unusable output dir. Warnings (a success whose energy balance or exact
error says the orbit is wrong) are findings, shown in the table and in stress.md; they
do not change the exit code. Files are staged and moved in at the end.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
from pathlib import Path
from typing import Annotated

import typer

from rubcli import __version__, io
from rubcli.analysis import stress
from rubcli.cli import console
from rubcli.cli.common import (
    ForceOption,
    JsonOption,
    WaitOption,
    emit,
    machine_readable,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID

EXIT_FAILED = 1


def _cell(value: object) -> object:
    """stress.csv keeps flags as 1/0."""
    return int(value) if isinstance(value, bool) else value


def write_csv(path: Path, runs: list[stress.StressRun]) -> None:
    rows = [[_cell(v) for v in run.as_row().values()] for run in runs]
    io.write_rows_csv(path, stress.RUN_COLUMNS, rows, nonfinite="")


def _short(value: float | None, fmt: str = ".2g") -> str:
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
            f" | {r.n_events} | {r.reference or '-'} | {_short(r.error)} | "
            f"{_short(r.energy_residual)} | {_short(r.energy_quadrature_error)} | "
            f"{_short(r.max_penetration, '.3g')} | {'yes' if r.nan else 'no'} | {message} |"
        )
    return "\n".join(lines) + "\n"


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
    force: ForceOption = False,
    wait: WaitOption = False,
    json: JsonOption = False,
) -> None:
    """Run the built-in suite of extreme cases with every method; write stress.csv and .md."""
    from rubcli.solvers import METHODS

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
    plan = prepare_output(target, force, wait, ("stress.csv", "stress.md", io.REPORT_NAME))
    with machine_readable(json):
        runs, report = _stress(cases, methods, quick, target, plan, case, method)
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
) -> tuple[list[stress.StressRun], dict]:
    console.info(
        f"stress ({'quick' if quick else 'full'}): {len(cases)} cases x {len(methods)} methods"
    )
    done = [0]
    total = len(cases) * len(stress.method_variants(methods))
    with console.progress_bar("stress  ", total=total) as update:

        def on_run(run: stress.StressRun) -> None:
            done[0] += 1
            update(done[0])
            console.info(
                f"{run.case:>20} {run.method:<24} {run.status:<8} {run.wall_time_s:8.2f} s"
                + ("" if run.status == "success" else f"  {run.message}")
            )

        runs = stress.run_suite(cases, methods, quick=quick, on_run=on_run)

    parts = ["rubcli stress"] + (["--quick"] if quick else [])
    parts += [f"--case {c}" for c in case or []] + [f"--method {m}" for m in method or []]
    files = ["stress.csv", "stress.md", io.REPORT_NAME]
    command_line = {"quick": quick, "cases": case or None, "methods": method or None}
    report = {
        **io.report_envelope("stress", command_line),
        "quick": quick,
        "success": all(stress.clean(r) for r in runs),
        "runs": [dataclasses.asdict(r) for r in runs],
        "files": files,
    }
    with io.staged_output_dir(target, plan) as staged:
        write_csv(staged.path("stress.csv"), runs)
        io.write_text(staged.path("stress.md"), markdown_text(runs, cases, quick, " ".join(parts)))
        staged.write_report(report)
    report_stale(plan)

    rows = [
        [r.case, r.method, r.status, f"{r.wall_time_s:.2f}", _short(r.error),
         _short(r.energy_residual), "yes" if r.nan else "no", r.warning]
        for r in runs
    ]  # fmt: skip
    console.table(
        "stress",
        ["case", "method", "status", "wall s", "error", "energy res.", "NaN", "warning"],
        rows,
    )
    console.info(f"wrote {', '.join(files)} to {target}")
    return runs, report

"""``rubcli run CASE [--method NAME]... [--out DIR] [--periods P] [--force] [--json]``.

Each method of the case (or of ``--method``) is solved with ``rubcli.solvers.solve``; then
only the products the case asks for are written into the output dir:

- ``<method>.csv`` per method if ``[output] csv`` (streamed in blocks: any length fits);
- ``orbit.png`` and/or ``time.png`` per ``[output] plots``;
- ``energy.png`` if ``[output] plots`` lists ``energy`` (the energy balance, never by default);
- ``spectrum.png`` if ``[output] plots`` lists ``spectrum`` (the full spectrum of x + i y);
- ``poincare.png`` and the response classes with ``[analysis] response = true``;
- ``report.json`` always: the case echoed, and per method its status, message, wall time,
  step/evaluation counts, contact switches, contact fraction, max penetration, the time
  spent in each regime (from the located switch times), the energy balance with its
  ``energy_residual`` (``rubcli.analysis.energy``, docs/stability.md), its plausibility
  ``warnings`` (``rubcli.analysis.checks``) and the dominant line of the full spectrum
  over the steady span (``spectrum``: order, direction). Its ``files`` list is the run's
  manifest.

The output dir is locked and checked before anything is solved
(``rubcli.io.open_output_dir``): writable, and either new, empty or written by rubcli
(else ``--force``); a file of the user's named like one of this run's outputs is refused;
the files of a previous run that this run does not write are removed, and named. All
files are staged and committed as a whole at the end (docs/cases.md, "Output dirs").

Exit codes: 0 success; 2 invalid input or unusable output dir (nothing is solved or
written); 1 if any method failed (its failure is in report.json; the outputs of the run
are still written); 3 if every method finished but one or more failed a plausibility
check (``status: warning`` in report.json: e.g. a tolerance so loose that the orbit ends
deep inside the stator): the files are written, but the result must not be trusted;
74 the outputs could not be written (nothing of this run is); 75 the output dir is in use
(``--wait`` waits); 128 + N when stopped by signal N.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import math
import time
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from rubcli import io
from rubcli.analysis import panels
from rubcli.analysis.checks import WARNING, method_summary
from rubcli.case import KNOWN_METHODS, Case, CaseError
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
from rubcli.cli.validate import EXIT_INVALID, load_or_exit
from rubcli.solution import Solution

EXIT_FAILED = 1
EXIT_WARNING = 3
ERROR = "error"  # status of a method whose solver raised an exception


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


def start_up(case: Case) -> float:
    """Run every method over the first 1/20 forcing period, untimed by the report.

    A process pays numba's compilation (first run on a machine) or cache load (about
    0.3-0.5 s) at its first compiled call; without this, that one-off cost would be
    charged to whichever method runs first. The warm-up has budgets of its own
    (``solvers.warm_up_options``: 2000 steps, 2 s past compiling), never the run's: a
    stiff case once spent a whole 5e6-step budget here before its timed run spent it
    again. Returns the seconds it took.
    """
    from rubcli import solvers
    from rubcli.analysis.reference import truncate_problem

    t0 = case.problem.t_span[0]
    short = truncate_problem(case.problem, t0 + case.params.period / 20.0)
    start = time.perf_counter()
    for name in case.methods:
        with contextlib.suppress(Exception):  # the timed run reports any failure
            solvers.solve(short, name, **solvers.warm_up_options(case.options_for(name)))
        io.checkpoint()  # a termination signal is never taken for a solver's failure
    return time.perf_counter() - start


def solve_method(case: Case, name: str) -> tuple[Solution | None, dict[str, Any] | None]:
    """Solve the case with one method behind a progress bar: ``(solution, None)``, or
    ``(None, entry)`` if the solver raised (status ``error``, its traceback printed: the
    other methods still run and the run exits 1)."""
    from rubcli import solvers

    t0, t1 = case.problem.t_span
    start = time.perf_counter()
    with console.progress_bar(f"{name:<8}", total=t1 - t0) as update:
        try:
            solution = solvers.solve(
                case.problem,
                name,
                **case.options_for(name),
                progress=lambda tau: update(tau - t0),
            )
        except Exception as exc:  # noqa: BLE001 - reported with its traceback, run exits 1
            io.checkpoint()  # a termination signal is never taken for a solver's failure
            console.exception(exc)
            entry = {
                "status": ERROR,
                "message": f"{type(exc).__name__}: {exc}",
                "wall_time_s": time.perf_counter() - start,
                "settings": case.options_for(name),
            }
            return None, entry
    return solution, None


def method_entry(
    case: Case, solution: Solution, balances: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The report entry of a solution. When the case plots ``energy`` and ``balances`` is
    given, the energy balance is computed once here, for the entry, and kept in
    ``balances[method]`` for energy.png."""
    balance = None
    if balances is not None and "energy" in case.settings.output.plots:
        balance = _balance_or_none(solution)
        if balance is not None:
            balances[solution.method] = balance
    return method_summary(solution, balance)


def _balance_or_none(solution: Solution):
    """The energy balance with its series (None if a state is not finite)."""
    from rubcli.analysis.energy import energy_balance

    if not np.all(np.isfinite(solution.states)):
        return None
    with np.errstate(all="ignore"):
        return energy_balance(solution)


def response_settings(case: Case) -> panels.ResponseSettings | None:
    """The case's ``[analysis]`` as response settings (None unless ``response = true``)."""
    analysis = case.settings.analysis
    if analysis is None or not analysis.response:
        return None
    return panels.ResponseSettings(**analysis.model_dump(exclude={"response"}))


def import_plotting_in_background(case: Case, background: io.Background) -> None:
    """Import the plotting modules (matplotlib's figure and Agg canvas, about 0.3 s) in the
    background thread, first, if the case draws any figure: the main thread meanwhile
    computes the report entries, whose compiled energy balance releases the GIL; when it
    reaches the figures the import is done (or it waits for it at the import lock)."""
    if case.settings.output.plots:
        background.submit(_import_plotting)


def _import_plotting() -> None:
    importlib.import_module("rubcli.plotting.run")
    gc.freeze()  # matplotlib's modules, as the other imports (``_run``)


def write_csvs_in_background(
    case: Case, solutions: list[Solution], staged: io.StagedOutput, background: io.Background
) -> None:
    """Hand each solution's CSV (if the case writes CSV) to the background thread
    (``io.Background``). Called once every method is solved: a method's timing is never
    shared with the writer. The main thread meanwhile computes the report entries (the
    compiled energy balance) and draws the figures; the CSV formatter and the energy
    kernel release the GIL, so on two cores they run side by side."""
    if not case.settings.output.csv:
        return
    for solution in solutions:
        name = f"{solution.method}.csv"
        blocks = io.shared_solution_blocks(solution, case.scale)  # the main thread helps
        background.submit(io.write_solution_csv, staged.path(name), solution, case.scale,
                          blocks=blocks, progress=(f"{name:<12}", float(solution.t.size)),
                          helper=blocks.work)  # fmt: skip


def write_outputs(
    case: Case,
    solutions: list[Solution],
    entries: dict[str, dict[str, Any]],
    command_line: dict[str, Any],
    staged: io.StagedOutput,
    background: io.Background,
    balances: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Write the requested figures and report.json into the staged output dir, the CSVs
    having been handed to ``background`` (``write_csvs_in_background``); waits for them;
    return the report. ``balances``: energy balances already computed, by method."""
    from rubcli.plotting import run as plots

    output = case.settings.output
    files: list[str] = []
    if output.csv:
        for solution in solutions:
            name = f"{solution.method}.csv"
            entries[solution.method]["files"] = [name]
            files.append(name)
    title = plots.parameters_title(case.name, case.params)
    failures = {n: e["message"] for n, e in entries.items() if e["status"] == ERROR}
    transient = case.settings.analysis.transient_periods if case.settings.analysis else None
    spectra = _spectra(case, solutions, entries, transient)
    for plot in output.plots:
        if plot == "energy":
            figure = _energy_figure(solutions, title, case.scale, balances)
        elif plot == "spectrum":
            figure = _spectrum_figure(spectra, failures, title, case.scale)
        elif plot == "orbit":
            figure = plots.orbit_figure(
                solutions, title, scale=case.scale, transient_periods=transient,
                failures=failures,
            )  # fmt: skip
        else:
            figure = plots.time_figure(solutions, title, scale=case.scale, failures=failures,
                                       transient_periods=transient)  # fmt: skip
        io.save_figure(figure, staged.path(f"{plot}.png"))
        files.append(f"{plot}.png")
    response = None
    settings = response_settings(case)
    if settings is not None and solutions:
        results = panels.run_responses(solutions, settings, progress=console.progress_bar)
        for result in results:
            entries[result.method]["response"] = result.to_dict()
        response = panels.response_summary(results)
        io.save_figure(_poincare_figure(case, results), staged.path("poincare.png"))
        files.append("poincare.png")
    background.wait(console.progress_bar)  # the CSVs, before the report names them
    files.append(io.REPORT_NAME)
    report = {
        **io.report_envelope("run", command_line, case.to_dict()),
        "success": all(e["status"] == "success" for e in entries.values()),
        "methods": entries,
        "response": response,
        "files": files,
    }
    staged.write_report(report)
    return report


def _poincare_figure(case: Case, results: list[panels.MethodResponse]):
    from rubcli.plotting.compare import poincare_figure
    from rubcli.plotting.run import parameters_title

    sections = [(r.method, r.section, r.response) for r in results if r.section is not None]
    return poincare_figure(sections, parameters_title(case.name, case.params))


def _energy_figure(solutions: list[Solution], title: str, scale=None, balances=None):
    """energy.png: the energy balance of every method (``plots = ["energy"]``), reusing
    the balances computed for the report (``balances``, by method) where there are."""
    from rubcli.analysis.energy import energy_balance
    from rubcli.plotting.energy import energy_figure

    balances = balances or {}
    drawn = [balances[s.method] if s.method in balances else energy_balance(s) for s in solutions]
    return energy_figure(solutions, drawn, title, scale=scale)


def _spectra(case: Case, solutions: list[Solution], entries: dict, transient: float | None):
    """Full spectrum of each solution over its steady span (``analysis.spectrum``).

    Adds ``entries[method]["spectrum"]`` (dominant whirl order, direction, amplitude; rad/s
    for a [physical] case; null for a failed run) and returns the figure's panels.
    """
    from rubcli.analysis.spectrum import steady_spectrum

    omega_scale = None if case.scale is None else case.scale.omega
    panels = []
    for sol in solutions:
        spectrum = steady_spectrum(sol, transient)
        summary = None if spectrum is None else spectrum.to_dict(omega_scale)
        entries[sol.method]["spectrum"] = summary
        note = "" if spectrum is not None else f"{sol.status}: {sol.message}"
        panels.append((sol.method, spectrum, note))
    return panels


def _spectrum_figure(panels, failures: dict[str, str], title: str, scale=None):
    """spectrum.png (``plots = [..., "spectrum"]``): one panel per method."""
    from rubcli.plotting.spectrum import spectrum_figure

    panels = panels + [(name, None, f"error: {why}") for name, why in failures.items()]
    return spectrum_figure(panels, title, scale=scale)


def _summary_rows(entries: dict[str, dict[str, Any]]) -> list[list[str]]:
    rows = []
    for name, e in entries.items():
        stats = e.get("stats", {})
        steps = stats.get("nsteps")
        fraction = e.get("contact_fraction")
        penetration = e.get("max_penetration")
        residual = e.get("energy_residual")
        rows.append(
            [
                name,
                e["status"],
                f"{e['wall_time_s']:.3f}",
                "-" if steps is None else str(steps),
                str(e.get("n_contact_switches", "-")),
                "-" if fraction is None else f"{100 * fraction:.1f}%",
                "-" if penetration is None else f"{penetration:.4g}",
                "-" if residual is None else f"{residual:.2g}",
            ]
        )
    return rows


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
    force: ForceOption = False,
    wait: WaitOption = False,
    json: JsonOption = False,
) -> None:
    """Solve a case with each of its methods and write CSVs, plots and report.json."""
    case = load_or_exit(case_file)
    case = _apply_overrides(case, _check_methods(method), out, periods)
    target = case.output_dir

    from rubcli import solvers

    unavailable = [m for m in case.methods if m not in solvers.METHODS]
    if unavailable:
        console.error(f"{case_file}: solver.methods: not available: {', '.join(unavailable)}")
        raise typer.Exit(EXIT_INVALID)
    plan = prepare_output(target, force, wait, expected_files(case))

    with machine_readable(json):
        report = _run(case, case_file, method, out, periods, plan)
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


def expected_files(case: Case) -> tuple[str, ...]:
    """The files a run of ``case`` writes (``write_outputs``)."""
    output = case.settings.output
    names = [f"{m}.csv" for m in case.methods] if output.csv else []
    names += [f"{plot}.png" for plot in output.plots]
    if response_settings(case) is not None:
        names.append("poincare.png")
    return (*names, io.REPORT_NAME)


def _run(
    case: Case,
    case_file: Path,
    method: list[str] | None,
    out: Path | None,
    periods: float | None,
    plan: io.OutputPlan,
) -> dict[str, Any]:
    problem = case.problem
    console.info(
        f"{case.name}: {problem.periods:g} periods (tau 0 .. {problem.t_span[1]:.6g}), "
        f"methods {', '.join(case.methods)}"
    )
    solutions: list[Solution] = []
    entries: dict[str, dict[str, Any]] = {}
    command_line = {
        "case_file": str(case_file),
        "methods": method or None,
        "out": str(out) if out is not None else None,
        "periods": periods,
    }
    # Solved first, every method alone (its timing is its own); then the plotting modules
    # are imported and the CSVs written in the background while the report entries are
    # computed and the figures drawn.
    # What the imports made lives as long as the process: out of the cyclic collector's
    # full passes (they would walk numba's and the modules' objects again and again).
    # Not unfrozen afterwards: the interpreter's last collection at exit would then walk
    # them all (0.15-0.3 s measured); a caller that goes on in this process only keeps
    # the few garbage cycles made before the run.
    gc.freeze()
    with io.staged_output_dir(case.output_dir, plan) as staged, io.Background() as background:
        with console.notice_if_slow(COMPILING_NOTICE, START_UP_NOTICE_S):
            startup = start_up(case)
        if startup > 0.05:
            console.info(f"start-up (compiled kernels loaded or compiled): {startup:.2f} s")
        for name in case.methods:
            solution, failure = solve_method(case, name)
            entries[name] = failure if solution is None else {}  # (the report's order)
            if solution is not None:
                solutions.append(solution)
        import_plotting_in_background(case, background)
        write_csvs_in_background(case, solutions, staged, background)
        balances: dict[str, Any] = {}
        for solution in solutions:
            entries[solution.method] = method_entry(case, solution, balances)
            entries[solution.method]["startup_s"] = startup
        report = write_outputs(case, solutions, entries, command_line, staged, background, balances)
    report_stale(plan)

    console.table(
        f"{case.name}: results",
        ["method", "status", "wall s", "steps", "events", "contact", "max pen", "E resid"],
        _summary_rows(entries),
        caption="events: located switches; contact: share of time in contact; max pen: "
        "largest penetration (clearances); E resid: energy-balance residual (report.json)",
    )
    files = report["files"]
    console.info(f"wrote {len(files)} files to {case.output_dir}: {', '.join(files)}")
    return report

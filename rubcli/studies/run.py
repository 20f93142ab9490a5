"""A case solved with each of its methods (``rubcli run``), as a library study:
``run_case(case)`` returns a ``RunResult`` (the solutions, the methods that raised),
whose ``entries()`` are the report's per-method summaries and whose
``write(directory)`` writes the products the case asks for (CSVs, figures, the response
section) with ``report.json`` in one atomic commit (``rubcli.io``).

The products, each only where the case asks for it:

- ``<method>.csv`` per method if ``[output] csv`` (streamed in blocks: any length fits);
- ``orbit.png`` and/or ``time.png`` per ``[output] plots``;
- ``energy.png`` if ``[output] plots`` lists ``energy`` (the energy balance, never by default);
- ``spectrum.png`` if ``[output] plots`` lists ``spectrum`` (the full spectrum of x + i y);
- ``poincare.png`` and the response classes with ``[analysis] response = true``;
- ``report.json`` always: the case echoed, and per method its status, message, wall time,
  step/evaluation counts, contact switches, contact fraction, max penetration, the time
  spent in each regime (from the located switch times), the energy balance with its
  ``energy_residual`` (``rubcli.analysis.energy.balance``, docs/stability.md), its plausibility
  ``warnings`` (``rubcli.analysis.runs.checks``) and the dominant line of the full spectrum
  over the steady span (``spectrum``: order, direction). Its ``files`` list is the run's
  manifest.

Timing: every method is solved alone, after a warm-up (``start_up``) that pays numba's
compilation or cache load; writing then runs the CSV formatter in a background thread
while the report entries (the compiled energy balance) and the figures are computed.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rubcli import io
from rubcli.analysis.response import panels
from rubcli.analysis.response.panels import ProgressFactory, no_progress
from rubcli.analysis.runs.checks import method_summary
from rubcli.case import Case
from rubcli.solution import Solution
from rubcli.studies.compare import response_settings

if TYPE_CHECKING:
    from rubcli.plotting.transient import SteadyStates

ERROR = "error"  # status of a method whose solver raised an exception


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
    from rubcli.analysis.accuracy.reference import truncate_problem

    t0 = case.problem.t_span[0]
    short = truncate_problem(case.problem, t0 + case.params.period / 20.0)
    start = time.perf_counter()
    for name in case.methods:
        with contextlib.suppress(Exception):  # the timed run reports any failure
            solvers.solve(short, name, **solvers.warm_up_options(case.options_for(name)))
        io.checkpoint()  # a termination signal is never taken for a solver's failure
    return time.perf_counter() - start


def solve_method(
    case: Case,
    name: str,
    progress_bar: ProgressFactory = no_progress,
    on_error: Callable[[BaseException], None] | None = None,
) -> tuple[Solution | None, dict[str, Any] | None]:
    """Solve the case with one method: ``(solution, None)``, or ``(None, entry)`` if the
    solver raised (status ``error``; ``on_error(exc)`` is called, the other methods still
    run)."""
    from rubcli import solvers

    t0, t1 = case.problem.t_span
    start = time.perf_counter()
    with progress_bar(f"{name:<8}", t1 - t0) as update:
        try:
            solution = solvers.solve(
                case.problem,
                name,
                **case.options_for(name),
                progress=lambda tau: update(tau - t0),
            )
        except MemoryError:  # not the method's failure: the run cannot go on
            raise
        except Exception as exc:  # noqa: BLE001 - reported to on_error, the run goes on
            io.checkpoint()  # a termination signal is never taken for a solver's failure
            if on_error is not None:
                on_error(exc)
            entry = {
                "status": ERROR,
                "message": f"{type(exc).__name__}: {exc}",
                "wall_time_s": time.perf_counter() - start,
                "settings": case.options_for(name),
            }
            return None, entry
    return solution, None


@dataclass
class RunResult:
    """The solutions of a case's methods; ``entries`` summarises them, ``write`` puts the
    case's products in a directory."""

    case: Case
    solutions: list[Solution]
    failures: dict[str, dict[str, Any]]  # the report entries of the methods that raised
    startup_s: float
    _entries: dict[str, dict[str, Any]] | None = field(default=None, repr=False)
    _balances: dict[str, Any] = field(default_factory=dict, repr=False)

    def entries(self) -> dict[str, dict[str, Any]]:
        """The report entry of every method, in the case's order (computed once: the
        energy balance of a case that plots it is kept for energy.png)."""
        if self._entries is None:
            solved = {s.method: s for s in self.solutions}
            entries = {}
            for name in self.case.methods:
                if name in solved:
                    entries[name] = method_entry(self.case, solved[name], self._balances)
                    entries[name]["startup_s"] = self.startup_s
                else:
                    entries[name] = self.failures[name]
            self._entries = entries
        return self._entries

    def write(
        self, directory: str | Path, plan: io.OutputPlan | None = None,
        command_line: dict[str, Any] | None = None, progress_bar: ProgressFactory = no_progress,
        steady: SteadyStates | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Write the case's products into ``directory`` as one commit (``plan``: the dir
        as the caller opened and checked it; without one it is opened here); returns the
        report. ``steady``: a sweep's steady states under the Bode plot of a run whose
        speed changes (``studies.transient.load_steady``)."""
        case = self.case
        command_line = command_line or {"out": str(directory)}
        with io.staged_output_dir(directory, plan) as staged, io.Background() as background:
            import_plotting_in_background(case, background)
            write_csvs_in_background(case, self.solutions, staged, background)
            entries = self.entries()  # meanwhile: the compiled energy balance
            return write_outputs(case, self.solutions, entries, command_line, staged,
                                 background, self._balances, progress_bar, steady)  # fmt: skip


def run_case(
    case: Case,
    *,
    progress_bar: ProgressFactory = no_progress,
    on_error: Callable[[BaseException], None] | None = None,
    startup_s: float | None = None,
    max_wall_time_s: float | None = None,
) -> RunResult:
    """Solve the case with each of its methods, each alone and timed, after the warm-up
    (``start_up``; ``startup_s``: its seconds, if the caller ran it). ``progress_bar`` as
    ``rubcli.cli.progress.progress_bar``; ``on_error(exc)`` for a solver that raised.

    The whole is bounded by ``[solver] total_wall_time_s`` (``max_wall_time_s``: a budget
    instead of the table's; None in both: no budget but each method's): checked between
    the methods, each solve getting at most the time left;
    ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` once it is spent (TypeError or
    ValueError naming ``max_wall_time_s`` for a budget that is not a number > 0)."""
    from rubcli.analysis.orbits.periodic import check_deadline
    from rubcli.solvers import wall_time_budget, wall_time_deadline

    if max_wall_time_s is None:
        max_wall_time_s = case.settings.solver.total_wall_time_s
    deadline = wall_time_deadline("run_case()", max_wall_time_s)
    solutions, failures = [], {}
    with wall_time_budget(deadline):
        if startup_s is None:
            startup_s = start_up(case)
        for name in case.methods:
            check_deadline(deadline)
            solution, failure = solve_method(case, name, progress_bar, on_error)
            if solution is None:
                failures[name] = failure
            else:
                solutions.append(solution)
    check_deadline(deadline)  # (a solve the budget cut short is no result of the method)
    return RunResult(case, solutions, failures, startup_s)


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
    from rubcli.analysis.energy.balance import energy_balance

    if not np.all(np.isfinite(solution.states)) or solution.stator_states is not None:
        return None  # (a moving stator's balance: analysis.energy.two_body, no figure)
    with np.errstate(all="ignore"):
        return energy_balance(solution)


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
    progress_bar: ProgressFactory = no_progress,
    steady: SteadyStates | None = None,
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
    title = plots.parameters_title(case.name, case.params, speed=case.speed_text())
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
    if case.problem.changes_speed:
        files += _transient_outputs(case, solutions, entries, staged, steady)
    response = None
    settings = response_settings(case.settings.analysis)
    if settings is not None and solutions:
        results = panels.run_responses(solutions, settings, progress=progress_bar)
        for result in results:
            entries[result.method]["response"] = result.to_dict()
        response = panels.response_summary(results)
        io.save_figure(_poincare_figure(case, results), staged.path("poincare.png"))
        files.append("poincare.png")
    background.wait(progress_bar)  # the CSVs, before the report names them
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


def _transient_outputs(
    case: Case, solutions: list[Solution], entries: dict, staged: io.StagedOutput,
    steady: SteadyStates | None = None,
) -> list[str]:  # fmt: skip
    """A run whose speed changes: each method's order tracking in its report entry
    (``transient``), and the figures (``studies.transient.FIGURES``) of the first
    method that has them. Returns the files written."""
    from rubcli.studies import transient

    drawn: list[str] = []
    for solution in solutions:
        result = transient.analyse(case, solution)
        if isinstance(result, str):
            entries[solution.method]["transient"] = {"note": result}
            continue
        entries[solution.method]["transient"] = result.to_dict()
        if drawn:
            continue
        for name, figure in transient.figures(case, solution, result, steady).items():
            io.save_figure(figure, staged.path(f"{name}.png"))
            drawn.append(f"{name}.png")
        entries[solution.method]["transient"]["figures"] = list(drawn)
    return drawn


def _poincare_figure(case: Case, results: list[panels.MethodResponse]):
    from rubcli.plotting.compare import poincare_figure
    from rubcli.plotting.run import parameters_title

    sections = [(r.method, r.section, r.response) for r in results if r.section is not None]
    return poincare_figure(sections, parameters_title(case.name, case.params))


def _energy_figure(solutions: list[Solution], title: str, scale=None, balances=None):
    """energy.png: the energy balance of every method (``plots = ["energy"]``), reusing
    the balances computed for the report (``balances``, by method) where there are."""
    from rubcli.analysis.energy.balance import energy_balance
    from rubcli.plotting.energy import energy_figure

    balances = balances or {}
    drawn = [balances[s.method] if s.method in balances else energy_balance(s) for s in solutions]
    return energy_figure(solutions, drawn, title, scale=scale)


def _spectra(case: Case, solutions: list[Solution], entries: dict, transient: float | None):
    """Full spectrum of each solution over its steady span (``analysis.response.spectrum``).

    Adds ``entries[method]["spectrum"]`` (dominant whirl order, direction, amplitude; rad/s
    for a [physical] case; null for a failed run) and returns the figure's panels.
    """
    from rubcli.analysis.response.spectrum import steady_spectrum

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


def expected_files(case: Case) -> tuple[str, ...]:
    """The files a run of ``case`` writes (``write_outputs``)."""
    output = case.settings.output
    names = [f"{m}.csv" for m in case.methods] if output.csv else []
    names += [f"{plot}.png" for plot in output.plots]
    if case.problem.changes_speed:
        from rubcli.studies.transient import DRIVE_FIGURES, FIGURES

        names += [f"{name}.png" for name in FIGURES]
        if case.problem.drive is not None:
            names += [f"{name}.png" for name in DRIVE_FIGURES]
    if response_settings(case.settings.analysis) is not None:
        names.append("poincare.png")
    return (*names, io.REPORT_NAME)

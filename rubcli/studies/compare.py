"""Reference, error against run time and orbits of a case (``rubcli compare``), as a
library study: ``compare_case(case)`` returns a ``CompareResult``, whose
``write(directory)`` writes its files, ``report.md`` and ``report.json`` in one atomic
commit (``rubcli.io``). The steps (docs/compare.md): the reference, the work-precision
ladders (``rubcli.analysis.accuracy.work_precision``), the orbit panels of each mu with their
references and response classes (``rubcli.analysis.response.panels``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import io
from rubcli.analysis.accuracy import work_precision as wpm
from rubcli.analysis.accuracy.reference import Reference, ReferenceError
from rubcli.analysis.response import panels as panel_study
from rubcli.analysis.response.panels import (
    OrbitPanel,
    ProgressFactory,
    no_progress,
    response_settings,
)
from rubcli.case import AnalysisSection, Case, CompareSection
from rubcli.problem import Problem
from rubcli.solvers.registry import SPECS, STEPS_PER_PERIOD

QUICK_HORIZON_PERIODS = 5.0
QUICK_LYAPUNOV_PERIODS = panel_study.QUICK_LYAPUNOV_PERIODS
QUICK_ORBIT_PERIODS = 150.0
# what --quick does, in its help and in report.md, from the numbers it uses
QUICK_TEXT = (
    f"short ladders run once, work-precision over at most {QUICK_HORIZON_PERIODS:g} forcing "
    f"periods, each orbit over at most {QUICK_ORBIT_PERIODS:g} and its Lyapunov run over at "
    f"most {QUICK_LYAPUNOV_PERIODS:g}"
)
CSV_COLUMNS = (
    "method", "setting", "wall_time_s", "error_max", "error_final", "setting_name",
    "wall_time_min_s", "repeats", "nsteps", "nfev", "njev", "n_events", "status",
)  # fmt: skip


# ------------------------------------------------------------------------- helpers


def case_periods(case: Case) -> float:
    """The case's span in periods: ``[time] periods``, or for a speed that changes the
    revolutions of the unbalance over the profile's span (a driven rotor's counted at its
    start speed)."""
    if not case.problem.changes_speed:
        return case.settings.time.periods
    return case.problem.periods


def samples_in_memory(case: Case, cfg: CompareSection, quick: bool) -> tuple[int, int]:
    """The output samples of the longest span ``compare_case`` holds and how many solutions
    over it are held at once: the orbit panel's runs (one per method, beside their
    reference) over the case's span, or the work-precision reference and one ladder solve
    over its horizon (the case's sampling over either)."""
    periods = case_periods(case)
    orbit = min(periods, QUICK_ORBIT_PERIODS) if quick else periods
    spans = [(orbit, len(case.methods) + 1)]
    if cfg.work_precision:
        horizon = cfg.horizon_periods or periods
        spans.append((min(horizon, QUICK_HORIZON_PERIODS) if quick else horizon, 2))
    per_period = (case.problem.t_eval.size - 1) / periods
    span, held = max(spans, key=lambda s: s[0] * s[1])
    return math.ceil(span * per_period) + 1, held


def _problem(case: Case, periods: float, mu: float | None = None) -> Problem:
    params = case.params if mu is None else dataclasses.replace(case.params, mu=float(mu))
    if case.problem.speed is not None:  # the first ``periods`` revolutions of the profile
        from rubcli.analysis.accuracy.reference import truncate_problem

        t = case.problem.t_eval
        turns = (case.problem.speed.phase(t, 0.0) - case.problem.speed.phase(t[0], 0.0)) / (
            2.0 * math.pi
        )
        whole = dataclasses.replace(case.problem, params=params)
        return truncate_problem(whole, float(np.interp(periods, turns, t)))
    if case.problem.drive is not None:  # periods at the start speed
        from rubcli.analysis.accuracy.reference import truncate_problem

        whole = dataclasses.replace(case.problem, params=params)
        return truncate_problem(whole, periods * params.period)
    problem = Problem.from_periods(
        params,
        case.problem.initial,
        periods=periods,
        samples_per_period=case.settings.time.samples_per_period,
        name=case.name,
    )  # (a moving stator's start kept)
    return dataclasses.replace(problem, stator_initial=case.problem.stator_initial)


def _fmt(value: float | None, spec: str = ".3g") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return format(value, spec)


# ------------------------------------------------------------------ work-precision


def work_precision(
    case: Case, cfg: CompareSection, quick: bool, threshold: float,
    progress_bar: ProgressFactory = no_progress,
) -> wpm.WorkPrecision:  # fmt: skip
    """Reference and work-precision table of the case (step 1 and 2)."""
    periods = cfg.horizon_periods or case_periods(case)
    if quick:
        periods = min(periods, QUICK_HORIZON_PERIODS)
    problem = _problem(case, periods)
    reference = panel_study.reference_with_progress(problem, threshold, "reference", progress_bar)
    methods = list(cfg.methods or case.methods)
    if quick:
        rtols, steps, repeats = wpm.QUICK_RTOLS, wpm.QUICK_STEPS_PER_PERIOD, 1
    else:
        rtols = tuple(cfg.rtols or wpm.DEFAULT_RTOLS)
        steps = tuple(cfg.steps_per_period or wpm.DEFAULT_STEPS_PER_PERIOD)
        repeats = cfg.repeats
    settings = wpm.ladder(methods, rtols, steps, cfg.atol_factor)
    index = {id(s): i for i, s in enumerate(settings)}
    span = max(reference.trusted_until - problem.t_span[0], 1e-300)
    with progress_bar("work-precision ladder  ", float(len(settings))) as update:
        result = wpm.run_work_precision(
            problem,
            reference,
            settings,
            repeats=repeats,
            max_wall_time_s=cfg.max_wall_time_s,
            progress=lambda s, tau: update(index[id(s)] + (tau - problem.t_span[0]) / span),
        )
    return result


def write_work_precision_csv(path: Path, result: wpm.WorkPrecision) -> None:
    rows = []
    for row in result.rows:
        rec = row.record()
        rows.append([rec.get(name) for name in CSV_COLUMNS])
    io.write_rows_csv(path, CSV_COLUMNS, rows, nonfinite="nan")


# ------------------------------------------------------------------------ orbits


def orbit_panel(
    case: Case,
    mu: float | None,
    methods: list[str],
    threshold: float,
    analysis: AnalysisSection | None,
    quick: bool,
    reference: Reference | None = None,
    progress_bar: ProgressFactory = no_progress,
) -> OrbitPanel:
    """One mu (``rubcli.analysis.response.panels.orbit_panel`` on the case's problem of that mu)."""
    periods = case_periods(case)
    if quick:
        periods = min(periods, QUICK_ORBIT_PERIODS)
    return panel_study.orbit_panel(
        _problem(case, periods, mu),
        methods,
        case.solver_options,
        threshold=threshold,
        response=response_settings(analysis),
        quick=quick,
        reference=reference,
        progress=progress_bar,
        transient_periods=steady_transient(analysis, periods),
        omega_scale=None if case.scale is None else case.scale.omega,
    )


def steady_transient(analysis: AnalysisSection | None, periods: float) -> float | None:
    """Start of the steady span of the orbit plots and spectra, in forcing periods.

    ``[analysis] transient_periods`` when shorter than the run, 2/3 of the run when not
    (as the response classes); None (half the run) without it.
    """
    transient = None if analysis is None else analysis.transient_periods
    if transient is not None and transient >= periods:
        transient = 2.0 * periods / 3.0
    return transient


def _spectrum_panels(panels: list[OrbitPanel]) -> list[tuple]:
    """spectrum.png: per mu, the full spectrum of every method that has one, overlaid."""
    out = []
    for p in panels:
        found = [(run.method, run.spectrum) for run in p.runs if run.spectrum is not None]
        if found:
            out.append((f"mu = {p.mu:g}", found, ""))
        else:
            out.append((f"mu = {p.mu:g}", None, "no method succeeded over two periods"))
    return out


SWEEP_COLUMNS = (
    "mu", "method", "status", "wall_time_s", "error_max", "error_final", "error_until_tau",
    "response_kind", "response_period", "lyapunov", "lyapunov_stderr", "sync_rub_r",
    "sync_rub_stable", "sync_rub_growth_rate",
)  # fmt: skip


def write_sweep_csv(path: Path, panels: list[OrbitPanel]) -> None:
    rows = []
    for panel in panels:
        rub = panel.synchronous_rubs[-1] if panel.synchronous_rubs else {}
        for run in panel.runs:
            e = run.to_dict()
            r = e.get("response") or {}
            rows.append([
                panel.mu, run.method, e["status"], e["wall_time_s"], e["error_max"],
                e["error_final"], e["error_until_tau"], r.get("kind"), r.get("period"),
                r.get("lyapunov"), r.get("lyapunov_stderr"), rub.get("r"), rub.get("stable"),
                rub.get("growth_rate"),
            ])  # fmt: skip
    io.write_rows_csv(path, SWEEP_COLUMNS, rows, nonfinite="")


# ------------------------------------------------------------------------ report


def report_markdown(case: Case, wp: wpm.WorkPrecision | None, panels: list[OrbitPanel],
                    quick: bool, targets: tuple[float, ...] = wpm.TARGETS) -> str:  # fmt: skip
    """The human-readable summary (report.md)."""
    from rubcli.plotting.compare import table_rows

    p = case.params
    out = [f"# rubcli compare: {case.name}", ""]
    out.append(
        f"Parameters: nu = {p.nu:g}, eta = {p.eta:g}, e = {p.e:g}, K = {p.K:g}, mu = {p.mu:g}, "
        f"Rp = {p.Rp:g}, phi0 = {p.phi0:g}; initial state {case.problem.initial}."
        + (f" Quick mode: {QUICK_TEXT}." if quick else "")
    )
    out.append("")
    if wp is not None:
        ref = wp.reference
        out += ["## Reference", "", ref.description + ".", ""]
        out.append(
            f"Estimated error of the reference: max {ref.error_estimate:.2g}, at the end of the "
            f"trusted span {ref.error_estimate_final:.2g} (clearances). Trusted up to tau = "
            f"{ref.trusted_until:.6g} ({(ref.trusted_until - ref.problem.t_span[0]) / p.period:.4g}"
            f" forcing periods) of {ref.problem.t_span[1]:.6g}"
            + (" (finite predictability horizon)." if ref.horizon_limited else ".")
        )
        for note in ref.notes:
            out.append(f"- {note}")
        out += ["", "## Work-precision", ""]
        out.append(
            f"Over {wp.problem.periods:.4g} forcing periods; wall time is the median of up to "
            f"{wp.repeats} runs (runs over {wpm.REPEAT_BELOW_S:g} s are not repeated). Start-up "
            "(a warm-up solve per method, excluded from the table): "
            + ", ".join(f"{m} {s * 1e3:.1f} ms" for m, s in wp.startup_s.items())
            + "."
        )
        out += ["", "| method | setting | wall time (s) | error max | error final | steps | "
                "f evals | status |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for cells in table_rows(wp.rows):
            out.append("| " + " | ".join(cells) + " |")
        if wp.skipped:
            out += ["", "Skipped after a failure or budget stop: " + ", ".join(wp.skipped) + "."]
        out += ["", "### Cheapest method for a target error", ""]
        out += [
            "| target (max error) | cheapest | wall time (s) | error max |",
            "|---|---|---|---|",
        ]
        for target, row in wp.cheapest(targets).items():
            if row is None:
                why = (
                    "not resolvable (below 10x the reference error)"
                    if target < wpm.RESOLUTION_FACTOR * ref.error_estimate
                    else "none reached it"
                )
                out.append(f"| {target:g} | {why} | - | - |")
            else:
                out.append(
                    f"| {target:g} | {row.method} at {row.setting_name} = {row.label} | "
                    f"{row.wall_time_s:.4g} | {row.error_max:.3g} |"
                )
        for method in (m for m in wp.methods if SPECS[m].knob == STEPS_PER_PERIOD):
            order = wpm.observed_order(wp.rows_of(method))
            if order is not None:
                out += ["", f"Observed order of `{method}` in its step (fit of log error_max "
                        f"vs log step over the ladder): {order:.2f}."]  # fmt: skip
        out.append("")
    if panels:
        out += ["## Orbits" + (" per mu" if len(panels) > 1 else ""), ""]
        out.append(
            f"Each method at the case's [solver] settings over {_orbit_periods(panels)} "
            "forcing periods; errors against the reference of that mu within its trusted span."
        )
        out += ["", "| mu | method | status | error max | response | period | Lyapunov | "
                "synchronous rub r (stable?) |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for panel in panels:
            rub = panel.synchronous_rubs[-1] if panel.synchronous_rubs else None
            rub_text = "none" if rub is None else (
                f"{rub['r']:.6g} ({'stable' if rub['stable'] else 'unstable'}, "
                f"growth {rub['growth_rate']:.2g})"
            )  # fmt: skip
            for name, e in panel.to_dict()["methods"].items():
                r = e.get("response") or {}
                lyap = r.get("lyapunov")
                lyap_text = "-" if lyap is None else f"{lyap:.3g} +- {r['lyapunov_stderr']:.1g}"
                status = (
                    e["status"] if e["status"] == "success" else f"{e['status']}: {e['message']}"
                )
                out.append(
                    f"| {panel.mu:g} | {name} | {status} | {_fmt(e['error_max'])} | "
                    f"{r.get('kind', '-')} | {r.get('period') or '-'} | {lyap_text} | {rub_text} |"
                )
        out.append("")
        for panel in panels:
            ref = panel.reference
            start = ref.problem.t_span[0]
            out.append(
                f"- mu = {panel.mu:g}: reference {ref.kind}, estimated error "
                f"{ref.error_estimate:.2g}, trusted for "
                f"{(ref.trusted_until - start) / ref.problem.params.period:.4g} of "
                f"{ref.problem.periods:.4g} periods"
            )
        for panel in panels:
            for a in panel.agreements:
                out.append(
                    f"- mu = {panel.mu:g}: {a.pair}: max |difference| {a.max_difference:.3g}"
                    + (
                        f", first above 1e-2 at tau = {a.first_tau_above:.6g}"
                        if a.first_tau_above is not None
                        else ""
                    )  # fmt: skip
                )
        out.append("")
    return "\n".join(out)


def _orbit_periods(panels: list[OrbitPanel]) -> str:
    """The span the orbit runs covered, as solved (``--quick`` caps the case's)."""
    spans = sorted({f"{p.problem.periods:g}" for p in panels}, key=float)
    return " to ".join(spans) if len(spans) <= 2 else ", ".join(spans)


def expected_files(case: Case, cfg: CompareSection) -> tuple[str, ...]:
    """The files ``rubcli compare`` writes for ``case`` (``poincare.png`` with responses)."""
    names = ["work_precision.csv", "work_precision.png", "error_growth.png"]
    names = names if cfg.work_precision else []
    if not case.problem.changes_speed:  # both count periods of one speed
        names += ["orbits.png", "spectrum.png"]
    names += ["sweep.csv"] if cfg.mu is not None else []
    if response_settings(case.settings.analysis) is not None:
        names.append("poincare.png")
    return (*names, "report.md", io.REPORT_NAME)


@dataclass
class CompareResult:
    """The reference, the work-precision table and the orbit panels of a case; ``write``
    puts them in a directory."""

    case: Case
    cfg: CompareSection
    quick: bool
    wp: wpm.WorkPrecision | None
    panels: list[OrbitPanel]
    wall_time_s: float

    def write(
        self, directory: str | Path, plan: io.OutputPlan | None = None,
        command_line: dict[str, Any] | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Write the files into ``directory`` as one commit (``plan``: the dir as the caller
        opened and checked it; without one it is opened here); returns the report."""
        from rubcli.plotting import compare as plots
        from rubcli.plotting.run import parameters_title
        from rubcli.plotting.spectrum import spectrum_figure

        case, wp, panels, analysis = self.case, self.wp, self.panels, self.case.settings.analysis
        speed = case.speed_text()
        title = parameters_title(case.name, case.params, speed=speed)
        files: list[str] = []
        with io.staged_output_dir(directory, plan) as staged:
            if wp is not None:
                write_work_precision_csv(staged.path("work_precision.csv"), wp)
                io.save_figure(
                    plots.work_precision_figure(wp, title), staged.path("work_precision.png")
                )
                io.save_figure(
                    plots.error_growth_figure(wp, title), staged.path("error_growth.png")
                )
                files += ["work_precision.csv", "work_precision.png", "error_growth.png"]
            orbit_panels = [
                {"title": f"mu = {p.mu:g}", "solutions": p.solutions, "note": p.note(),
                 "transient_periods": steady_transient(analysis, p.problem.periods)}
                for p in panels
            ]  # fmt: skip
            sweep_title = parameters_title(case.name, case.params, vary_mu=len(panels) > 1,
                                           speed=speed)  # fmt: skip
            if speed is None:  # the keyphasor and the orders count periods of one speed
                io.save_figure(
                    plots.orbits_figure(orbit_panels, sweep_title), staged.path("orbits.png")
                )
                spectra = spectrum_figure(_spectrum_panels(panels), sweep_title,
                                          scale=case.scale)  # fmt: skip
                io.save_figure(spectra, staged.path("spectrum.png"))
                files += ["orbits.png", "spectrum.png"]
            if self.cfg.mu is not None:
                write_sweep_csv(staged.path("sweep.csv"), panels)
                files.append("sweep.csv")
            sections = [
                (f"{r.method}, mu = {p.mu:g}", r.section, r.response)
                for p in panels
                for r in p.responses
                if r.section is not None
            ]
            if sections:
                io.save_figure(
                    plots.poincare_figure(sections, sweep_title), staged.path("poincare.png")
                )
                files.append("poincare.png")
            text = report_markdown(case, wp, panels, self.quick)
            io.write_text(staged.path("report.md"), text)
            files += ["report.md", io.REPORT_NAME]
            report = {
                **io.report_envelope(
                    "compare", command_line or {"out": str(directory)}, case.to_dict()
                ),  # fmt: skip
                "quick": self.quick,
                "reference": None if wp is None else wp.reference.to_dict(),
                "work_precision": None if wp is None else _work_precision_json(wp),
                "orbits": [p.to_dict() for p in panels],
                "response": panel_study.panels_response_summary(panels),
                "wall_time_s": self.wall_time_s,
                "files": files,
            }
            staged.write_report(report)
        return report


def compare_case(
    case: Case, *, quick: bool = False, progress_bar: ProgressFactory = no_progress,
    max_wall_time_s: float | None = None,
) -> CompareResult:  # fmt: skip
    """The reference and work-precision ladders (unless ``[compare] work_precision =
    false``), then the orbit panel of each mu; ``quick``: the CI settings (``QUICK_TEXT``).
    Raises ``rubcli.analysis.accuracy.reference.ReferenceError`` if no reference can be built.

    The whole is bounded by ``[compare] total_wall_time_s`` (``max_wall_time_s``: a budget
    instead of the table's; None in both: no budget but each solve's ``[compare]
    max_wall_time_s``): checked after the ladders and after each panel, every solve
    getting at most the time left; ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` once it
    is spent (TypeError or ValueError naming ``max_wall_time_s`` for a budget that is not
    a number > 0)."""
    from rubcli.analysis.orbits.periodic import check_deadline
    from rubcli.solvers import wall_time_budget, wall_time_deadline

    started = time.perf_counter()
    cfg = case.settings.compare or CompareSection()
    budget = cfg.total_wall_time_s if max_wall_time_s is None else max_wall_time_s
    deadline = wall_time_deadline("compare_case()", budget)
    try:
        with wall_time_budget(deadline):
            wp, panels = _compare(case, cfg, quick, progress_bar, deadline)
    except ReferenceError:
        check_deadline(deadline)  # a reference the budget cut short: the budget's stop
        raise
    check_deadline(deadline)
    return CompareResult(case, cfg, quick, wp, panels, time.perf_counter() - started)


def _compare(
    case: Case, cfg: CompareSection, quick: bool, progress_bar: ProgressFactory,
    deadline: float | None,
) -> tuple[wpm.WorkPrecision | None, list[OrbitPanel]]:  # fmt: skip
    from rubcli.analysis.orbits.periodic import check_deadline

    threshold = cfg.reference_threshold
    analysis = case.settings.analysis
    wp = work_precision(case, cfg, quick, threshold, progress_bar) if cfg.work_precision else None
    mus = cfg.mu if cfg.mu is not None else [None]
    orbit_periods = case_periods(case)
    if quick:
        orbit_periods = min(orbit_periods, QUICK_ORBIT_PERIODS)
    same = (
        wp is not None and cfg.mu is None
        and math.isclose(wp.reference.problem.periods, orbit_periods)
    )  # fmt: skip
    panels = []
    for mu in mus:
        check_deadline(deadline)
        panels.append(orbit_panel(case, mu, list(case.methods), threshold, analysis, quick,
                                  reference=wp.reference if same else None,
                                  progress_bar=progress_bar))  # fmt: skip
    return wp, panels


def _work_precision_json(wp: wpm.WorkPrecision) -> dict[str, Any]:
    return {
        "periods": wp.problem.periods,
        "repeats": wp.repeats,
        "startup_s": wp.startup_s,
        "skipped": wp.skipped,
        "rows": [r.record() for r in wp.rows],
        "cheapest": {
            f"{t:g}": None
            if r is None
            else {
                "method": r.method,
                "setting_name": r.setting_name,
                "setting": r.setting,
                "wall_time_s": r.wall_time_s,
                "error_max": r.error_max,
            }
            for t, r in wp.cheapest().items()
        },
        "observed_order_analytic": wpm.observed_order(wp.rows_of("analytic")),
    }

"""Orbit panels (one per mu) and response runs: the domain work of `compare` and `run`.

- ``response_of(solution, settings)``: the class of a solution's steady response
  (``analysis.response.classification.classify_solution`` after the transient) and its stroboscopic
  section; ``run_responses`` does it for several solutions, ``response_summary`` gives
  the top-level ``response`` of a report.
- ``orbit_panel(problem, methods, options, ...)``: each method at the given settings over
  the problem, its error against a reference of that mu, the largest difference between
  the methods (``Agreement``) and the synchronous full annular rubs with their stability.
  The Figure 3 composite of `rubcli compare` is one panel per mu.

Results are typed (dataclasses); ``to_dict()`` gives the report.json form. Long steps
report progress through a *progress factory*: a callable ``(label, total)`` returning a
context manager that yields ``update(done)`` (``rubcli.cli.progress.progress_bar`` is one;
the default shows nothing). Nothing here prints or writes files.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rubcli.analysis.accuracy.reference import Reference, position_errors, reference_solution
from rubcli.analysis.orbits.synchronous import synchronous_rubs
from rubcli.analysis.response import classification as rsp
from rubcli.analysis.response.spectrum import FullSpectrum, steady_spectrum
from rubcli.problem import Problem
from rubcli.solution import Solution

ProgressFactory = Callable[[str, float], AbstractContextManager[Callable[[float], None]]]
QUICK_LYAPUNOV_PERIODS = 30
AGREEMENT_LEVEL = 1e-2  # first_tau_above_1e-2 of an Agreement


def no_progress(label: str, total: float) -> AbstractContextManager[Callable[[float], None]]:
    """A progress factory that shows nothing."""
    return contextlib.nullcontext(lambda done: None)


# ------------------------------------------------------------------------- response


@dataclass(frozen=True)
class ResponseSettings:
    """How to classify a response (the keys of a case's ``[analysis]`` table)."""

    transient_periods: float | None = None  # None: half the run
    lyapunov: bool = True
    lyapunov_periods: int = 100
    rel_tol: float = 1e-4
    max_period: int = 16


@dataclass
class MethodResponse:
    """The response class of one solution and its stroboscopic section (None if empty)."""

    method: str
    response: rsp.Response
    section: rsp.PoincareSection | None
    transient_periods: float

    def to_dict(self) -> dict[str, Any]:
        return self.response.to_dict()


def response_of(
    solution: Solution, settings: ResponseSettings, *, quick: bool = False
) -> MethodResponse:
    """Classify ``solution``'s steady response.

    The transient is ``settings.transient_periods``, half the run if None, and 2/3 of the
    run if it is not shorter than the run. ``quick`` caps the Lyapunov run at
    ``QUICK_LYAPUNOV_PERIODS``.
    """
    periods = solution.problem.periods
    transient = settings.transient_periods
    if transient is None or transient >= periods:
        transient = 0.5 * periods if transient is None else 2.0 * periods / 3.0
    lyap_periods = settings.lyapunov_periods
    if quick:
        lyap_periods = min(lyap_periods, QUICK_LYAPUNOV_PERIODS)
    result = rsp.classify_solution(
        solution,
        transient_periods=transient,
        lyapunov=settings.lyapunov,
        lyapunov_periods=lyap_periods,
        rel_tol=settings.rel_tol,
        max_period=settings.max_period,
    )
    section = rsp.section_from_solution(solution, transient) if solution.t.size > 1 else None
    return MethodResponse(solution.method, result, section, transient)


def run_responses(
    solutions: Iterable[Solution],
    settings: ResponseSettings,
    *,
    quick: bool = False,
    progress: ProgressFactory = no_progress,
) -> list[MethodResponse]:
    """``response_of`` for each solution, one progress step each."""
    results = []
    for solution in solutions:
        with progress(f"response {solution.method:<13}", 1.0) as update:
            results.append(response_of(solution, settings, quick=quick))
            update(1.0)
    return results


def response_summary(responses: Sequence[MethodResponse]) -> dict[str, Any] | None:
    """The top-level ``response`` of a report: the first method's class, and every one's."""
    if not responses:
        return None
    by_method = {r.method: r.to_dict() for r in responses}
    first = by_method[responses[0].method]
    return {"method": responses[0].method, "kind": first["kind"], "label": first["label"],
            "period": first["period"], "lyapunov": first["lyapunov"],
            "evidence": first["evidence"], "by_method": by_method}  # fmt: skip


# --------------------------------------------------------------------------- panels


@dataclass
class MethodRun:
    """One method on one panel: the solution and its error against the panel's reference."""

    solution: Solution
    error_max: float | None
    error_final: float | None
    error_until_tau: float | None
    response: MethodResponse | None = None
    spectrum: FullSpectrum | None = None  # full spectrum over the steady span
    omega_scale: float | None = None  # rad/s per rad/tau ([physical] case)

    @property
    def method(self) -> str:
        return self.solution.method

    def to_dict(self) -> dict[str, Any]:
        sol = self.solution
        entry: dict[str, Any] = {
            "status": sol.status,
            "message": sol.message,
            "wall_time_s": sol.wall_time_s,
            "stats": dict(sol.stats),
            "tau_end": float(sol.t[-1]) if sol.t.size else None,
            "error_max": self.error_max,
            "error_final": self.error_final,
            "error_until_tau": self.error_until_tau,
        }
        entry["spectrum"] = (
            None if self.spectrum is None else self.spectrum.to_dict(self.omega_scale)
        )
        if self.response is not None:
            entry["response"] = self.response.to_dict()
        return entry


@dataclass(frozen=True)
class Agreement:
    """The largest |w_a - w_b| of two methods over their common samples."""

    first: str
    second: str
    max_difference: float
    until_tau: float | None
    first_tau_above: float | None  # first sample where the difference exceeds 1e-2

    @property
    def pair(self) -> str:
        return f"{self.first} vs {self.second}"

    def to_dict(self) -> dict[str, Any]:
        return {
            "max_difference": self.max_difference,
            "until_tau": self.until_tau,
            "first_tau_above_1e-2": self.first_tau_above,
        }


def agreement(a: Solution, b: Solution, level: float = AGREEMENT_LEVEL) -> Agreement:
    n = min(a.t.size, b.t.size)
    diff = np.abs(a.w[:n] - b.w[:n]) if n else np.array([np.nan])
    above = np.nonzero(diff > level)[0] if n else np.array([], dtype=int)
    return Agreement(
        first=a.method,
        second=b.method,
        max_difference=float(np.max(diff)),
        until_tau=float(a.t[n - 1]) if n else None,
        first_tau_above=float(a.t[above[0]]) if above.size else None,
    )


@dataclass
class OrbitPanel:
    """One mu: every method's run, their agreement and the synchronous rubs."""

    problem: Problem
    reference: Reference
    runs: list[MethodRun]
    agreements: list[Agreement]
    synchronous_rubs: list[dict[str, Any]] = field(default_factory=list)

    @property
    def mu(self) -> float:
        return self.problem.params.mu

    @property
    def solutions(self) -> list[Solution]:
        return [run.solution for run in self.runs]

    @property
    def responses(self) -> list[MethodResponse]:
        return [run.response for run in self.runs if run.response is not None]

    def note(self) -> str:
        """One line for the panel's title: the response classes (the orbit figure states
        the distance between the methods itself)."""
        parts = []
        for run in self.runs:
            if run.response is not None:
                r = run.response.response
                parts.append(f"{run.method}: {r.kind}" + (f" p{r.period}" if r.period else ""))
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return {
            "mu": self.mu,
            "periods": self.problem.periods,
            "reference": self.reference.to_dict(),
            "methods": {run.method: run.to_dict() for run in self.runs},
            "agreement": {a.pair: a.to_dict() for a in self.agreements},
            "synchronous_rubs": self.synchronous_rubs,
        }


def reference_with_progress(
    problem: Problem, threshold: float, label: str, progress: ProgressFactory = no_progress
) -> Reference:
    """``reference_solution`` with one progress bar over its two runs (reference, check)."""
    t0, t1 = problem.t_span
    with progress(f"{label:<22}", 2.0 * (t1 - t0)) as update:
        offsets = {"reference": 0.0, "reference check": t1 - t0}
        return reference_solution(
            problem,
            threshold=threshold,
            progress=lambda which, tau: update(offsets[which] + tau - t0),
        )


def solve_with_progress(
    problem: Problem,
    method: str,
    options: dict[str, Any],
    label: str,
    progress: ProgressFactory = no_progress,
) -> Solution:
    """``solvers.solve`` with a progress bar over tau; ``options`` filtered per method."""
    from rubcli.solvers import options_for, solve

    t0, t1 = problem.t_span
    with progress(f"{label:<22}", t1 - t0) as update:
        return solve(
            problem, method, **options_for(method, options), progress=lambda tau: update(tau - t0)
        )


def orbit_panel(
    problem: Problem,
    methods: Sequence[str],
    options: dict[str, Any],
    *,
    threshold: float,
    response: ResponseSettings | None = None,
    quick: bool = False,
    reference: Reference | None = None,
    progress: ProgressFactory = no_progress,
    transient_periods: float | None = None,
    omega_scale: float | None = None,
) -> OrbitPanel:
    """Each method on ``problem`` at ``options``, errors against ``reference`` (built at
    ``threshold`` if None), its full spectrum over the steady span (after
    ``transient_periods``: ``spectrum.default_transient``), the agreement of every pair,
    the response class of each method if ``response`` is given, and the synchronous rubs
    of the problem's parameters."""
    mu = problem.params.mu
    if reference is None:
        reference = reference_with_progress(problem, threshold, f"reference mu={mu:g}", progress)
    runs = []
    for name in methods:
        sol = solve_with_progress(problem, name, options, f"{name} mu={mu:g}", progress)
        err = position_errors(sol.t, sol.states, reference)
        run = MethodRun(
            solution=sol,
            error_max=float(err.max()) if err.size else None,
            error_final=float(err[-1]) if err.size else None,
            error_until_tau=float(reference.t[err.size - 1]) if err.size else None,
            spectrum=steady_spectrum(sol, transient_periods),
            omega_scale=omega_scale,
        )
        if response is not None:
            run.response = response_of(sol, response, quick=quick)
        runs.append(run)
    solutions = [run.solution for run in runs]
    agreements = [
        agreement(solutions[i], solutions[j])
        for i in range(len(solutions))
        for j in range(i + 1, len(solutions))
    ]
    rubs = [r.to_dict() for r in synchronous_rubs(problem.params)]
    return OrbitPanel(problem, reference, runs, agreements, rubs)


def panels_response_summary(panels: Sequence[OrbitPanel]) -> dict[str, Any] | None:
    """Top-level ``response`` of a compare report: the first panel's methods."""
    return response_summary(panels[0].responses) if panels else None


def response_settings(analysis: Any) -> ResponseSettings | None:
    """A case's ``[analysis]`` table (``rubcli.case.AnalysisSection``, or None) as response
    settings (None unless ``response = true``). Typed ``Any``: the analysis layer does not
    import the case schema, which sits above it."""
    if analysis is None or not analysis.response:
        return None
    return ResponseSettings(**analysis.model_dump(exclude={"response"}))

"""The reference solution of a Problem, and an honest statement of how good it is.

Three kinds, tried in this order (``reference_solution``):

1. **Free flight, exact**: the start is inside the clearance and the closed-form free
   flight (``model.free_flight``, notes section 5) never reaches ``z = 1`` over the time
   span. This is checked on a grid of spacing ``h`` no coarser than 1/400 of the forcing
   and natural periods, with the margin ``max |v| h / 2`` so that a touch between grid
   points cannot be missed.
2. **Synchronous full annular rub, exact**: the start lies on the orbit
   ``w = A exp(i eta tau)`` of ``model.synchronous_rub`` (relative 1e-12) with forward
   slip. The orbit is exact whether or not it is stable; its stability
   (``analysis.orbits.synchronous``) is reported beside it, since numerical solutions of an
   unstable orbit depart from it at the rate of the unstable eigenvalue.
3. **Numerical** otherwise: DOP853 at rtol = atol = 1e-12 with event restarts
   (``rubcli.solvers.solve``; run as ``dop853-jit``, which takes scipy's DOP853 steps
   in compiled code, tests/test_dop853_jit.py), checked against LSODA at
   rtol = atol = 1e-12 (Adams / BDF multistep from ODEPACK: a different method family,
   so its errors are independent). The estimated error of the reference is the
   difference between the two,
   ``|w_ref - w_check|``: it measures the error of the less accurate of the two, so it
   is an upper estimate of the reference error when the reference is the better one
   (DOP853 is, at equal tolerance, in the tests). Radau at 1e-12 would be a third
   independent choice but is ~100x slower here.

The exact kinds carry a round-off estimate ``eps * max|w| * (1 + eta * tau_end)`` (the
phase ``eta tau`` is rounded to ``eps * eta * tau``).

**Predictability horizon.** Two tight solutions of a chaotic (or otherwise sensitive)
case separate exponentially. The reference is trusted up to the last sample before
``|w_ref - w_check|`` first exceeds ``threshold`` (default 1e-6 clearances):
``trusted_until``. Errors of other methods must be computed only up to it
(``work_precision`` truncates the problem there). If a reference solver fails part way
(e.g. the rotor sticks, which the scipy methods do not model) the trusted span ends
where it stopped.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from rubcli import model
from rubcli.analysis.orbits.synchronous import SynchronousRub, started_on_synchronous_rub
from rubcli.problem import Problem

if TYPE_CHECKING:
    from rubcli.solution import Solution

EXACT_FREE_FLIGHT = "exact-free-flight"
EXACT_SYNCHRONOUS_RUB = "exact-synchronous-rub"
NUMERICAL = "numerical"

REFERENCE_METHOD = "dop853-jit"  # scipy's DOP853 step for step, compiled
REFERENCE_OPTIONS = {"rtol": 1e-12, "atol": 1e-12}
CHECK_METHOD = "lsoda"
CHECK_OPTIONS = {"rtol": 1e-12, "atol": 1e-12}
THRESHOLD = 1e-6  # predictability horizon: trusted while the two references differ less
GRID_FRACTION = 1.0 / 400.0  # free-flight check grid: this fraction of the fastest period
EPS = np.finfo(float).eps


class ReferenceError(RuntimeError):
    """No usable reference: the reference solver failed before the second sample."""


@dataclass
class Reference:
    """A reference solution at the problem's samples and what is known of its error."""

    kind: str  # EXACT_FREE_FLIGHT, EXACT_SYNCHRONOUS_RUB or NUMERICAL
    description: str
    problem: Problem
    t: np.ndarray  # sample times (a prefix of problem.t_eval)
    states: np.ndarray  # (n, 4)
    error_estimate: float  # max estimated position error over the trusted span
    error_estimate_final: float  # estimated position error at trusted_until
    trusted_until: float  # tau up to which the reference is trusted
    threshold: float
    deviation: np.ndarray | None = field(default=None, repr=False)  # |w_ref - w_check|
    method: str | None = None
    options: dict = field(default_factory=dict)
    check_method: str | None = None
    check_options: dict = field(default_factory=dict)
    wall_time_s: float = 0.0
    check_wall_time_s: float = 0.0
    synchronous: SynchronousRub | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def exact(self) -> bool:
        return self.kind != NUMERICAL

    @property
    def w(self) -> np.ndarray:
        return self.states[:, 0] + 1j * self.states[:, 1]

    @property
    def n_trusted(self) -> int:
        """Number of samples up to and including ``trusted_until``."""
        return int(np.searchsorted(self.t, self.trusted_until, side="right"))

    @property
    def horizon_limited(self) -> bool:
        """True when the trusted span ends before the problem's end."""
        return self.trusted_until < float(self.problem.t_eval[-1])

    def to_dict(self) -> dict:
        period = self.problem.params.period
        t0 = float(self.problem.t_eval[0])
        return {
            "kind": self.kind,
            "exact": self.exact,
            "description": self.description,
            "error_estimate": self.error_estimate,
            "error_estimate_final": self.error_estimate_final,
            "trusted_until_tau": self.trusted_until,
            "trusted_until_periods": (self.trusted_until - t0) / period,
            "problem_end_tau": float(self.problem.t_eval[-1]),
            "horizon_limited": self.horizon_limited,
            "threshold": self.threshold,
            "method": self.method,
            "options": self.options,
            "check_method": self.check_method,
            "check_options": self.check_options,
            "wall_time_s": self.wall_time_s,
            "check_wall_time_s": self.check_wall_time_s,
            "synchronous_rub": None if self.synchronous is None else self.synchronous.to_dict(),
            "notes": list(self.notes),
        }


# ------------------------------------------------------------------------ exact cases


def free_flight_stays_free(problem: Problem) -> bool:
    """True if the closed-form free flight from the start never reaches z = 1 (see above)."""
    params = problem.params
    s0 = np.asarray(problem.initial, dtype=float)
    if math.hypot(s0[0], s0[1]) >= 1.0:
        return False
    t0, t1 = problem.t_span
    beta = math.sqrt(abs(1.0 - params.nu**2)) or 1.0
    fastest = max(params.eta, beta, 1.0)
    h = GRID_FRACTION * 2.0 * math.pi / fastest
    n = max(2, int(math.ceil((t1 - t0) / h)) + 1)
    chunk = 200_000
    for start in range(0, n, chunk):
        grid = t0 + (t1 - t0) * np.arange(start, min(n, start + chunk + 1)) / (n - 1)
        S = model.free_flight(grid, t0, s0, params)
        z = np.hypot(S[0], S[1])
        speed = np.hypot(S[2], S[3])
        step = (t1 - t0) / (n - 1)
        if np.max(z + speed * step / 2.0) >= 1.0:
            return False
    return True


def _roundoff(states: np.ndarray, params: model.ModelParams, t_end: float) -> float:
    size = float(np.max(np.hypot(states[:, 0], states[:, 1])))
    return EPS * size * (1.0 + params.eta * abs(t_end))


def exact_reference(problem: Problem) -> Reference | None:
    """The exact reference of the problem if it has one (free flight, synchronous rub; at a
    constant speed on the paper's machine only: their closed forms are its)."""
    if problem.changes_speed or not problem.params.is_paper_machine:
        return None
    params = problem.params
    t = problem.t_eval
    t_end = float(t[-1])
    if free_flight_stays_free(problem):
        states = model.free_flight(t, float(t[0]), problem.initial, params).T
        err = _roundoff(states, params, t_end)
        return Reference(
            kind=EXACT_FREE_FLIGHT,
            description="exact: closed-form free flight (notes section 5); the orbit stays "
            "inside the clearance over the whole span (checked with a margin)",
            problem=problem, t=t.copy(), states=states, error_estimate=err,
            error_estimate_final=err, trusted_until=t_end, threshold=THRESHOLD,
        )  # fmt: skip
    rub = started_on_synchronous_rub(params, problem.initial, float(t[0]))
    if rub is not None:
        states = model.synchronous_rub(t, params, rub.r).T
        err = _roundoff(states, params, t_end)
        stability = (
            "stable (all rotating-frame eigenvalues have negative real part, largest "
            f"{rub.growth_rate:.3g})"
            if rub.stable
            else f"UNSTABLE (growth rate {rub.growth_rate:.3g} per unit tau): numerical "
            "solutions depart from it exponentially, which is a property of the orbit"
        )
        return Reference(
            kind=EXACT_SYNCHRONOUS_RUB,
            description=f"exact: synchronous forward full annular rub, r = {rub.r:.12g} "
            f"(notes section 5), started on the orbit; the orbit is {stability}",
            problem=problem, t=t.copy(), states=states, error_estimate=err,
            error_estimate_final=err, trusted_until=t_end, threshold=THRESHOLD,
            synchronous=rub,
        )  # fmt: skip
    return None


# -------------------------------------------------------------------------- numerical


def trusted_span(t: np.ndarray, deviation: np.ndarray, threshold: float) -> int:
    """Number of leading samples whose deviation stays within ``threshold`` (at least 1)."""
    over = np.nonzero(~(deviation <= threshold))[0]
    return int(deviation.size if over.size == 0 else max(1, over[0]))


def numerical_reference(
    problem: Problem,
    *,
    threshold: float = THRESHOLD,
    method: str = REFERENCE_METHOD,
    options: dict | None = None,
    check_method: str = CHECK_METHOD,
    check_options: dict | None = None,
    progress: Callable[[str, float], None] | None = None,
    max_wall_time_s: float = 3600.0,
) -> Reference:
    """A tight numerical reference with its error estimated against a second solution.

    ``progress(label, tau)`` is called while the two solutions run.
    """
    from rubcli.solvers import solve

    options = dict(REFERENCE_OPTIONS if options is None else options)
    check_options = dict(CHECK_OPTIONS if check_options is None else check_options)

    def run(name: str, opts: dict, label: str) -> Solution:
        cb = None if progress is None else (lambda tau: progress(label, tau))
        return solve(problem, name, max_wall_time_s=max_wall_time_s, progress=cb, **opts)

    ref = run(method, options, "reference")
    if ref.t.size < 2:
        raise ReferenceError(f"reference solver {method} failed at the start: {ref.message}")
    check = run(check_method, check_options, "reference check")
    notes = []
    n = min(ref.t.size, check.t.size)
    if not ref.success:
        notes.append(f"reference {method} stopped early: {ref.message}")
    if not check.success:
        notes.append(f"check {check_method} stopped early: {check.message}")
    if n < 2:
        raise ReferenceError(f"check solver {check_method} failed at the start: {check.message}")
    deviation = np.abs(ref.w[:n] - check.w[:n])
    n_trusted = trusted_span(ref.t[:n], deviation, threshold)
    trusted_until = float(ref.t[n_trusted - 1])
    if n_trusted < n:
        notes.append(
            f"the two references separate beyond {threshold:g} at tau = {ref.t[n_trusted]:.6g}:"
            " a finite horizon of predictability; errors are computed only up to "
            f"tau = {trusted_until:.6g}"
        )
    elif n < problem.t_eval.size:
        notes.append(
            f"trusted span ends where a reference solver stopped (tau = {ref.t[n - 1]:.6g})"
        )
    description = (
        f"numerical: {method} at rtol = {options.get('rtol'):g}, atol = {options.get('atol'):g} "
        f"with event restarts; error estimated by the difference to {check_method} at "
        f"rtol = {check_options.get('rtol'):g}, atol = {check_options.get('atol'):g} "
        "(an independent method family; the difference bounds the error of the less "
        "accurate of the two)"
    )
    return Reference(
        kind=NUMERICAL,
        description=description,
        problem=problem,
        t=ref.t[:n].copy(),
        states=ref.states[:n].copy(),
        error_estimate=float(np.max(deviation[:n_trusted])),
        error_estimate_final=float(deviation[n_trusted - 1]),
        trusted_until=trusted_until,
        threshold=threshold,
        deviation=deviation,
        method=method,
        options=options,
        check_method=check_method,
        check_options=check_options,
        wall_time_s=ref.wall_time_s,
        check_wall_time_s=check.wall_time_s,
        notes=notes,
    )


def reference_solution(
    problem: Problem,
    *,
    threshold: float = THRESHOLD,
    progress: Callable[[str, float], None] | None = None,
    **numerical_options: Any,
) -> Reference:
    """The exact reference where the problem has one, otherwise ``numerical_reference``."""
    exact = exact_reference(problem)
    if exact is not None:
        exact.threshold = threshold
        return exact
    return numerical_reference(problem, threshold=threshold, progress=progress, **numerical_options)


def truncate_problem(problem: Problem, tau_end: float) -> Problem:
    """The same problem with the samples after ``tau_end`` dropped (at least two kept)."""
    keep = int(max(2, np.searchsorted(problem.t_eval, tau_end, side="right")))
    if keep >= problem.t_eval.size:
        return problem
    return replace(problem, t_eval=problem.t_eval[:keep].copy())


def position_errors(t: np.ndarray, states: np.ndarray, reference: Reference) -> np.ndarray:
    """``|w - w_ref|`` at the common samples within the trusted span.

    ``t`` must be a prefix of the same sample grid (it is when both come from one
    Problem); fewer samples than the reference (a failed run) give a shorter array.
    """
    n = min(len(t), reference.n_trusted)
    if n and not np.allclose(t[:n], reference.t[:n], rtol=0.0, atol=1e-9 * max(1.0, t[n - 1])):
        raise ValueError("solution and reference are not sampled at the same times")
    w = states[:n, 0] + 1j * states[:n, 1]
    return np.abs(w - reference.w[:n])

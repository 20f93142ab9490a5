"""Work-precision: error against run time for each method over a ladder of settings.

For every method and setting the problem is solved ``repeats`` times with
``rubcli.solvers.solve``; the reported wall time is the median. Before a method's
ladder, one warm-up solve over a short span (one forcing period) absorbs one-off
start-up (first calls into scipy, caches, any compilation); its time is reported apart
as ``startup_s`` and is not in any row. A run that takes longer than
``repeat_below_s`` is not repeated (its single time is reported, ``repeats = 1``).

The errors are against a ``Reference`` (``analysis.accuracy.reference``) on the same samples and
only over its trusted span: ``error_max = max_k |w_k - w_ref,k|`` and
``error_final = |w - w_ref|`` at the last trusted sample. The problem is truncated to the
trusted span before it is solved, so time and error cover the same interval.

A setting that fails is recorded with its status and message. If it failed on the run
budget (``max_wall_time_s``, ``max_steps``), the tighter settings of that method are
skipped (they would cost more), and noted; after any other failure (a loose step that
diverged, say) the ladder goes on.

Settings: scipy methods take ``rtol`` with ``atol = rtol * atol_factor``; ``analytic``
and ``analytic-polar`` take ``steps_per_period``. ``cheapest_for(rows, target)`` picks
the fastest successful row whose ``error_max`` is at most the target (``None`` if none
reaches it, or if the target is below what the reference can resolve).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from rubcli.analysis.accuracy.reference import Reference, position_errors, truncate_problem
from rubcli.problem import Problem
from rubcli.solvers.registry import SPECS, STEPS_PER_PERIOD

DEFAULT_RTOLS = tuple(10.0**-k for k in range(3, 12))  # 1e-3 ... 1e-11
DEFAULT_STEPS_PER_PERIOD = (25, 50, 100, 200, 400, 800, 1600, 3200, 6400)
QUICK_RTOLS = (1e-3, 1e-6, 1e-9)
QUICK_STEPS_PER_PERIOD = (25, 100, 400)
ATOL_FACTOR = 1e-2
TARGETS = (1e-3, 1e-6, 1e-9)
REPEAT_BELOW_S = 5.0
RESOLUTION_FACTOR = 10.0  # a target below this many times the reference error is unresolved


@dataclass(frozen=True)
class Setting:
    """One method at one setting: ``name`` is 'rtol' or 'steps_per_period'."""

    method: str
    name: str
    value: float
    options: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return f"{self.value:g}" if self.name == "rtol" else f"{int(self.value)}"


def ladder(
    methods: Sequence[str],
    rtols: Sequence[float] = DEFAULT_RTOLS,
    steps_per_period: Sequence[int] = DEFAULT_STEPS_PER_PERIOD,
    atol_factor: float = ATOL_FACTOR,
) -> list[Setting]:
    """The settings for each method, loosest first (so a budget stop skips the dearest)."""
    out = []
    for method in methods:
        if SPECS[method].knob == STEPS_PER_PERIOD:  # the analytic methods: fixed steps
            for n in sorted(steps_per_period):
                out.append(
                    Setting(method, "steps_per_period", int(n), {"steps_per_period": int(n)})
                )
        else:
            for rtol in sorted(rtols, reverse=True):
                opts = {"rtol": float(rtol), "atol": float(rtol) * atol_factor}
                out.append(Setting(method, "rtol", float(rtol), opts))
    return out


@dataclass
class Row:
    """One (method, setting) of the work-precision table."""

    method: str
    setting_name: str
    setting: float
    wall_time_s: float  # median over the repeats
    wall_time_min_s: float
    repeats: int
    error_max: float
    error_final: float
    nsteps: int | None
    nfev: int | None
    njev: int | None
    n_events: int
    status: str
    message: str
    options: dict = field(default_factory=dict)
    errors: np.ndarray | None = field(default=None, repr=False)  # |w - w_ref| per sample
    t: np.ndarray | None = field(default=None, repr=False)

    @property
    def label(self) -> str:
        return f"{self.setting:g}" if self.setting_name == "rtol" else f"{int(self.setting)}"

    @property
    def success(self) -> bool:
        return self.status == "success"

    def record(self) -> dict:
        """The row without its arrays (for CSV and JSON)."""
        out = asdict(self)
        out.pop("errors")
        out.pop("t")
        return out


@dataclass
class WorkPrecision:
    """The table and what it was measured against."""

    rows: list[Row]
    reference: Reference
    problem: Problem  # the (possibly truncated) problem every method solved
    startup_s: dict[str, float]
    skipped: list[str]
    repeats: int

    def rows_of(self, method: str) -> list[Row]:
        return [r for r in self.rows if r.method == method]

    @property
    def methods(self) -> list[str]:
        return list(dict.fromkeys(r.method for r in self.rows))

    def cheapest(self, targets: Sequence[float] = TARGETS) -> dict[float, Row | None]:
        return {t: cheapest_for(self.rows, t, self.reference) for t in targets}


def cheapest_for(
    rows: Sequence[Row], target: float, reference: Reference | None = None
) -> Row | None:
    """The fastest successful row with ``error_max <= target``, or None.

    None also when the target is below ``RESOLUTION_FACTOR`` times the reference's own
    estimated error: such a claim could not be checked.
    """
    if reference is not None and target < RESOLUTION_FACTOR * reference.error_estimate:
        return None
    ok = [r for r in rows if r.success and math.isfinite(r.error_max) and r.error_max <= target]
    return min(ok, key=lambda r: r.wall_time_s) if ok else None


def measure(
    problem: Problem,
    reference: Reference,
    setting: Setting,
    *,
    repeats: int = 3,
    repeat_below_s: float = REPEAT_BELOW_S,
    max_wall_time_s: float = 600.0,
    progress: Callable[[float], None] | None = None,
) -> Row:
    """Solve ``problem`` at one setting ``repeats`` times; the row of its time and errors."""
    from rubcli.solvers import solve

    times = []
    solution = None
    for i in range(max(1, repeats)):
        try:
            solution = solve(
                problem,
                setting.method,
                max_wall_time_s=max_wall_time_s,
                progress=progress if i == 0 else None,
                **setting.options,
            )
        except Exception as exc:  # a method that raises is a failed row, not a dead ladder
            return _error_row(setting, exc)
        times.append(solution.wall_time_s)
        if not solution.success or solution.wall_time_s > repeat_below_s:
            break
    assert solution is not None
    errors = position_errors(solution.t, solution.states, reference)
    complete = solution.success and errors.size == reference.n_trusted
    stats = solution.stats
    return Row(
        method=setting.method,
        setting_name=setting.name,
        setting=setting.value,
        wall_time_s=float(statistics.median(times)),
        wall_time_min_s=float(min(times)),
        repeats=len(times),
        error_max=float(np.max(errors)) if complete else math.nan,
        error_final=float(errors[-1]) if complete else math.nan,
        nsteps=stats.get("nsteps"),
        nfev=stats.get("nfev"),
        njev=stats.get("njev"),
        n_events=len(solution.events),
        status=solution.status,
        message=solution.message,
        options=dict(setting.options),
        errors=errors,
        t=solution.t[: errors.size].copy(),
    )


def _error_row(setting: Setting, exc: Exception) -> Row:
    return Row(
        method=setting.method,
        setting_name=setting.name,
        setting=setting.value,
        wall_time_s=math.nan,
        wall_time_min_s=math.nan,
        repeats=0,
        error_max=math.nan,
        error_final=math.nan,
        nsteps=None,
        nfev=None,
        njev=None,
        n_events=0,
        status="error",
        message=f"{type(exc).__name__}: {exc}",
        options=dict(setting.options),
    )


def warm_up(problem: Problem, method: str, options: dict) -> float:
    """One solve over the first forcing period, with the warm-up's own budgets
    (``solvers.warm_up_options``); returns its wall time (start-up cost)."""
    from rubcli.solvers import solve, warm_up_options

    period_end = float(problem.t_eval[0]) + problem.params.period
    short = truncate_problem(problem, period_end)
    try:
        return solve(short, method, **warm_up_options(options)).wall_time_s
    except Exception:  # the ladder's own rows record the failure
        return math.nan


def run_work_precision(
    problem: Problem,
    reference: Reference,
    settings: Sequence[Setting],
    *,
    repeats: int = 3,
    repeat_below_s: float = REPEAT_BELOW_S,
    max_wall_time_s: float = 600.0,
    progress: Callable[[Setting, float], None] | None = None,
) -> WorkPrecision:
    """Measure every setting (see the module docstring).

    ``progress(setting, tau)`` is called while each setting runs (first repeat only).
    """
    solved = truncate_problem(problem, reference.trusted_until)
    rows: list[Row] = []
    startup: dict[str, float] = {}
    skipped: list[str] = []
    stopped: set[str] = set()
    for setting in settings:
        if setting.method in stopped:
            skipped.append(f"{setting.method} {setting.name} = {setting.label}")
            continue
        if setting.method not in startup:
            startup[setting.method] = warm_up(solved, setting.method, setting.options)
        cb = None if progress is None else (lambda tau, s=setting: progress(s, tau))
        row = measure(
            solved,
            reference,
            setting,
            repeats=repeats,
            repeat_below_s=repeat_below_s,
            max_wall_time_s=max_wall_time_s,
            progress=cb,
        )
        rows.append(row)
        if not row.success and "budget" in row.message:
            stopped.add(setting.method)  # tighter settings would cost more still
    return WorkPrecision(rows, reference, solved, startup, skipped, repeats)


def observed_order(rows: Sequence[Row]) -> float | None:
    """Slope of log(error_max) against log(step) for an analytic ladder (None if < 2 points).

    The step is the forcing period over ``steps_per_period``; points at the reference's
    resolution floor should be left out by the caller.
    """
    pts = [
        (math.log(1.0 / r.setting), math.log(r.error_max))
        for r in rows
        if r.setting_name == "steps_per_period" and r.success and r.error_max > 0
    ]
    if len(pts) < 2:
        return None
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])

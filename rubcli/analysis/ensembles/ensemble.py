"""Ensembles of runs where one run's outcome is fragile: attractor fractions and escape times.

A chaotic transient decides which attractor a run reaches, and when, by digits that
round-off and tolerances change (docs/reproduction.md, mu = 0.04). One run is then one
draw; the statements that hold are statistical. ``run_ensemble`` solves the case from a
cloud of starts (the case's own and ``runs - 1`` others at a distance ``spread`` in a
random direction) at every setting of a ladder (methods x rtols), and for each run:

- classifies the last ``record_periods`` (``analysis.response.classification``, with its
  evidence) and names the attractor by its contact regime: *free whirl* (no contact), *dry whip*
  (rolling, stick > 99 % of the window), *dry whirl* (backward whirl in permanent
  contact), *synchronous rub* (forward, permanent contact), *partial rub* otherwise. A
  window whose last quarter is in another regime is cut to that quarter; a run whose
  last 20 periods still differ is *changing regime*. A run is *settled* when its class
  is regular (periodic, converging, quasi-periodic) and its regime is not changing;
- measures the **time to reach** that attractor: the last forcing period at which the
  stroboscopic section was farther than ``settle_tolerance`` from the section points of
  the final window (distances in units of the final window's extent, per coordinate).

The summary gives the fraction of runs on each attractor with its 95 % Wilson interval
(E. B. Wilson, J. Am. Stat. Assoc. 22 (1927) 209), and the lifetime of the transient:
a run that settled is an escape at its time to reach; one that did not (chaotic or
undecided at the end) is censored at the run's length. For a memoryless escape (the
usual law of a chaotic transient: an exponential distribution) the maximum-likelihood
mean lifetime is the total time at risk over the number of escapes, ``T / d``, with the
exact two-sided interval ``[2T / chi2(1 - a/2; 2d + 2), 2T / chi2(a/2; 2d)]`` for
time-censored data (B. Epstein, Technometrics 2 (1960) 83; W. Q. Meeker, L. A. Escobar,
Statistical Methods for Reliability Data, Wiley 1998, sec. 7.6); escapes to one
attractor alone give its own mean time, ``T / d_k`` (competing risks). The Kaplan-Meier
estimate of the survival (E. L. Kaplan, P. Meier, J. Am. Stat. Assoc. 53 (1958) 457)
gives the median without assuming a law.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor
from dataclasses import asdict, dataclass, field
from typing import TypeVar

import numpy as np

from rubcli import model
from rubcli.analysis.orbits.periodic import check_deadline
from rubcli.analysis.response import classification as rsp
from rubcli.analysis.runs.processes import local_pool
from rubcli.analysis.sweep.attractors import normalised
from rubcli.model import ModelParams
from rubcli.problem import Problem

REGULAR = (rsp.PERIODIC, rsp.CONVERGING, rsp.QUASI_PERIODIC)
MIN_TAIL_PERIODS = 20  # a window whose last quarter (>= this) is in another regime is cut
CHANGING = "changing regime"  # the last MIN_TAIL_PERIODS differ from the window analysed
CONFIDENCE = 0.95


@dataclass(frozen=True)
class MemberTask:
    """One run of the ensemble (small, picklable)."""

    index: int
    params: ModelParams
    start: tuple[float, float, float, float]
    offset: float  # distance of the start from the case's start
    method: str
    options: dict
    periods: int
    samples_per_period: int
    record_periods: int
    lyapunov: bool
    lyapunov_periods: int
    settle_tolerance: float
    # the command's deadline (``time.perf_counter()``, the machine's monotonic clock, the
    # same in a worker process): the run's solves get at most the time left
    deadline: float | None = None


@dataclass
class MemberResult:
    index: int
    method: str
    rtol: float | None
    offset: float
    ok: bool
    message: str
    attractor: str = ""  # e.g. "dry whip, quasi-periodic"
    regime: str = ""
    kind: str = ""
    settled: bool = False
    settle_period: float = math.nan  # last period away from the final attractor
    contact_fraction: float = math.nan
    stick_fraction: float = math.nan
    whirl_order: float = math.nan
    z_max: float = math.nan
    lyapunov: float = math.nan
    lyapunov_stderr: float = math.nan
    contraction_rate: float = math.nan
    rotation_number: float = math.nan
    # the final window's stroboscopic section as (x, y, vx / eta, vy / eta): the mean of
    # its points and the length of their extent (the attractor's place and size)
    section_centre: tuple[float, float, float, float] | None = None
    section_size: float = math.nan

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and math.isnan(v) else v)
                for k, v in asdict(self).items()}  # fmt: skip


def regime_of(contact: float, stick: float, order: float) -> str:
    """The rub regime of a window from its contact and stick fractions and dominant whirl."""
    if contact < 1e-3:
        return "free whirl"
    if stick > 0.99:
        return "dry whip"
    if contact > 0.999:
        return "dry whirl" if order < 0.0 else "synchronous rub"
    return "partial rub"


def settle_period(sections: np.ndarray, final: np.ndarray, weights: np.ndarray,
                  tolerance: float) -> float:  # fmt: skip
    """The last index of ``sections`` farther than ``tolerance`` from every point of
    ``final`` (distances of ``(s - f) / weights``); 0 if none ever was."""
    scaled_final = final / weights
    far = []
    for k, point in enumerate(sections / weights):
        if np.min(np.linalg.norm(scaled_final - point, axis=1)) > tolerance:
            far.append(k)
    return float(far[-1] + 1) if far else 0.0


def run_member(task: MemberTask) -> MemberResult:
    """Solve one run and analyse its end; a failure is a result, never raised. Its solves
    end by ``task.deadline`` (a run cut short fails as on its own budget)."""
    from rubcli.solvers import wall_time_budget

    with wall_time_budget(task.deadline):
        return _member(task)


def _member(task: MemberTask) -> MemberResult:
    from rubcli.solvers import solve

    rtol = task.options.get("rtol")
    base = MemberResult(task.index, task.method, rtol, task.offset, False, "")
    spp = task.samples_per_period
    problem = Problem.from_periods(task.params, task.start, task.periods, spp)
    try:
        sol = solve(problem, task.method, **task.options)
    except Exception as exc:  # one failed run never stops the ensemble
        base.message = f"{type(exc).__name__}: {exc}"
        return base
    if not sol.success:
        base.message = sol.message
        return base
    states = np.asarray(sol.states)
    record = task.record_periods
    regime = _regime(sol, task, record)
    tail = max(MIN_TAIL_PERIODS, record // 4)
    if _regime(sol, task, tail) != regime:  # the window holds a change: analyse its end
        record = tail
        regime = _regime(sol, task, record)
    if _regime(sol, task, MIN_TAIL_PERIODS) != regime:  # still changing at the very end
        regime = CHANGING
    window = slice((task.periods - record) * spp, None)
    response = rsp.classify_solution(
        sol,
        transient_periods=task.periods - record,
        lyapunov=task.lyapunov,
        lyapunov_periods=task.lyapunov_periods,
        lyapunov_method="dop853-jit",
    )
    regimes = sol.regimes[window]
    sections = states[::spp]
    final = sections[-record - 1 :]
    spread = np.ptp(states[window], axis=0)
    weights = np.where(spread > 0.0, spread, 1.0)
    settled = response.kind in REGULAR and regime != CHANGING
    evidence = response.evidence()
    section = normalised(final, task.params.eta)
    return MemberResult(
        task.index, task.method, rtol, task.offset, True, response.message,
        attractor=f"{regime}, {response.kind}", regime=regime, kind=response.kind,
        settled=settled,
        settle_period=settle_period(sections, final, weights, task.settle_tolerance)
        if settled else math.nan,
        contact_fraction=float(np.mean(regimes != model.FREE)),
        stick_fraction=float(np.mean(regimes == model.STICK)),
        whirl_order=_order(sol, task, record), z_max=float(np.max(sol.z[window])),
        lyapunov=evidence["lyapunov"], lyapunov_stderr=evidence["lyapunov_stderr"],
        contraction_rate=evidence["contraction_rate"],
        rotation_number=evidence["rotation_number"],
        section_centre=tuple(float(v) for v in section.mean(axis=0)),
        section_size=float(np.linalg.norm(np.ptp(section, axis=0))),
    )  # fmt: skip


def _order(sol, task: MemberTask, periods: int) -> float:
    from rubcli.analysis.response.spectrum import full_spectrum

    window = slice((task.periods - periods) * task.samples_per_period, None)
    return full_spectrum(sol.t[window][:-1], sol.w[window][:-1], task.params.eta).dominant_order


def _regime(sol, task: MemberTask, periods: int) -> str:
    """The regime of the last ``periods`` of a run."""
    regimes = sol.regimes[(task.periods - periods) * task.samples_per_period :]
    contact = float(np.mean(regimes != model.FREE))
    stick = float(np.mean(regimes == model.STICK))
    return regime_of(contact, stick, _order(sol, task, periods))


# ------------------------------------------------------------------------ statistics


def wilson_interval(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson's score interval for a proportion k / n."""
    from statistics import NormalDist

    if n == 0:
        return (0.0, 1.0)
    z = NormalDist().inv_cdf(0.5 + confidence / 2.0)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def exponential_mean(total_time: float, events: int, confidence: float = CONFIDENCE) -> dict:
    """MLE of an exponential mean from time-censored data and its exact interval."""
    from scipy.special import chdtri  # chdtri(df, y): the chi-square quantile of 1 - y

    alpha = 1.0 - confidence
    if events == 0:
        lower = 2.0 * total_time / float(chdtri(2, alpha / 2.0))
        return {"mean": None, "lower": lower, "upper": None, "events": 0,
                "time_at_risk": total_time}  # fmt: skip
    return {
        "mean": total_time / events,
        "lower": 2.0 * total_time / float(chdtri(2 * events + 2, alpha / 2.0)),
        "upper": 2.0 * total_time / float(chdtri(2 * events, 1.0 - alpha / 2.0)),
        "events": events,
        "time_at_risk": total_time,
    }


def kaplan_meier(times: Sequence[float], observed: Sequence[bool]) -> list[tuple[float, float]]:
    """(time, survival just after it) at each escape time."""
    order = np.argsort(times, kind="stable")
    t = np.asarray(times, dtype=float)[order]
    e = np.asarray(observed, dtype=bool)[order]
    at_risk, surv, out = t.size, 1.0, []
    for value in np.unique(t):
        here = t == value
        d = int(np.sum(e & here))
        if d:
            surv *= 1.0 - d / at_risk
            out.append((float(value), surv))
        at_risk -= int(np.sum(here))
    return out


@dataclass
class EnsembleResult:
    members: list[MemberResult]
    periods: int
    period_tau: float  # forcing period in tau
    settings: dict = field(default_factory=dict)

    @property
    def good(self) -> list[MemberResult]:
        return [m for m in self.members if m.ok]

    def outcomes(self) -> dict[str, dict]:
        good = self.good
        counts = Counter(m.attractor for m in good)
        out = {}
        for name, k in counts.most_common():
            lo, hi = wilson_interval(k, len(good))
            out[name] = {"runs": k, "fraction": k / len(good), "lower": lo, "upper": hi}
        return out

    def lifetimes(self) -> dict:
        """Escape-time statistics of the transient, in forcing periods and tau."""
        good = self.good
        times = [m.settle_period if m.settled else float(self.periods) for m in good]
        escaped = [m.settled for m in good]
        total = float(sum(times))
        all_exits = exponential_mean(total, sum(escaped))
        by_attractor = {
            name: exponential_mean(total, sum(1 for m in good if m.settled and m.attractor == name))
            for name in sorted({m.attractor for m in good if m.settled})
        }
        curve = kaplan_meier(times, escaped)
        median = next((t for t, s in curve if s <= 0.5), None)
        return {
            "unit": "forcing periods",
            "period_tau": self.period_tau,
            "runs": len(good),
            "escaped": int(sum(escaped)),
            "censored": int(len(good) - sum(escaped)),
            "escape_periods": sorted(m.settle_period for m in good if m.settled),
            "mean_lifetime": all_exits,
            "mean_time_to": by_attractor,
            "median_lifetime": median,
            "kaplan_meier": curve,
            "confidence": CONFIDENCE,
        }

    def by_setting(self) -> dict[str, dict[str, int]]:
        """Runs on each attractor for each (method, rtol) of the ladder."""
        out: dict[str, Counter] = {}
        for m in self.good:
            key = m.method + ("" if m.rtol is None else f" rtol={m.rtol:g}")
            out.setdefault(key, Counter())[m.attractor] += 1
        return {k: dict(v.most_common()) for k, v in out.items()}

    def to_dict(self) -> dict:
        return {
            "settings": self.settings,
            "runs": len(self.members),
            "by_setting": self.by_setting(),
            "failed": [m.to_dict() for m in self.members if not m.ok],
            "outcomes": self.outcomes(),
            "lifetime": self.lifetimes(),
        }


STATE = ("x", "y", "vx", "vy")


def box_starts(
    start: Sequence[float], box: dict[str, tuple[float, float] | None], runs: int, seed: int
) -> np.ndarray:
    """``runs`` starts drawn uniformly (seeded) over a box of the state space, ``(runs, 4)``.

    ``box`` maps each of x, y, vx, vy to its ``(lo, hi)``, or to None to hold it at
    ``start``. Four uniforms are drawn per start whichever sides are given, so a side's
    draws do not change when another side is added or removed."""
    uniform = np.random.default_rng(seed).random((runs, 4))
    out = np.tile(np.asarray(start, dtype=float), (runs, 1))
    for k, name in enumerate(STATE):
        side = box.get(name)
        if side is not None:
            lo, hi = side
            out[:, k] = lo + (hi - lo) * uniform[:, k]
    return out


def member_tasks(
    params: ModelParams,
    start: Sequence[float],
    *,
    runs: int,
    spread: float,
    seed: int,
    methods: Sequence[str],
    rtols: Sequence[float | None],
    options: dict,
    periods: int,
    samples_per_period: int,
    record_periods: int,
    lyapunov: bool,
    lyapunov_periods: int,
    settle_tolerance: float,
    starts: np.ndarray | None = None,
    deadline: float | None = None,
) -> list[MemberTask]:
    """The runs: ``runs`` starts (the first the case's own) at every (method, rtol);
    ``starts`` (an array ``(n, 4)``) replaces that cloud by these starts (``runs`` and
    ``spread`` unused), each with its distance from ``start`` as its offset; ``deadline``:
    the command's (``MemberTask.deadline``)."""
    from rubcli.solvers import options_for

    base = np.asarray(start, dtype=float)
    if starts is not None:
        drawn = np.asarray(starts, dtype=float)
        offsets = np.linalg.norm(drawn - base, axis=1)
        cloud = [
            (tuple(float(v) for v in s), float(d)) for s, d in zip(drawn, offsets, strict=True)
        ]
    else:
        rng = np.random.default_rng(seed)
        cloud = [(tuple(base), 0.0)]
        for _ in range(runs - 1):
            direction = rng.normal(size=4)
            offset = base + spread * direction / np.linalg.norm(direction)
            cloud.append((tuple(float(v) for v in offset), spread))
    tasks = []
    for method in methods:
        for rtol in rtols:
            opts = dict(options)
            if rtol is not None:
                opts["rtol"], opts["atol"] = rtol, rtol * 1e-2
            opts = options_for(method, opts)
            for s, offset in cloud:
                tasks.append(MemberTask(len(tasks), params, s, offset, method, opts, periods,
                                        samples_per_period, record_periods, lyapunov,
                                        lyapunov_periods, settle_tolerance,
                                        deadline))  # fmt: skip
    return tasks


T = TypeVar("T")


def within_deadline(pool: Executor, results: Iterator[T], deadline: float | None) -> Iterator[T]:
    """The results of ``pool.map``, then WallTimeBudgetError after one once ``deadline`` has
    passed, the tasks not started cancelled (those running end by the deadline too)."""
    for result in results:
        yield result
        if deadline is not None and time.perf_counter() > deadline:
            pool.shutdown(wait=False, cancel_futures=True)
            check_deadline(deadline)


def _warm_up(tasks: list[MemberTask]) -> None:
    from rubcli.solvers import solve

    for method in {t.method for t in tasks}:
        task = next(t for t in tasks if t.method == method)
        solve(Problem.from_periods(task.params, task.start, 2, 8), method, **task.options)


def run_ensemble(
    tasks: list[MemberTask],
    *,
    workers: int = 1,
    progress: Callable[[int], None] | None = None,
    settings: dict | None = None,
) -> EnsembleResult:
    """Every task, in this process (``workers = 1``) or on a local process pool.
    ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` after a run once the tasks' deadline
    has passed (the runs not started are dropped)."""
    results: list[MemberResult] = []
    deadline = tasks[0].deadline if tasks else None
    if workers <= 1:
        for task in tasks:
            results.append(run_member(task))
            if progress is not None:
                progress(len(results))
            check_deadline(deadline)
    else:
        _warm_up(tasks)  # compile or load the kernels once, before the workers fork
        with local_pool(workers) as pool:
            for result in within_deadline(pool, pool.map(run_member, tasks), deadline):
                results.append(result)
                if progress is not None:
                    progress(len(results))
    params = tasks[0].params if tasks else None
    return EnsembleResult(results, tasks[0].periods if tasks else 0,
                          params.period if params else math.nan, settings or {})  # fmt: skip

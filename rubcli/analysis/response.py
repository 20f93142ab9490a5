"""Classification of the steady response: Poincare section, period, Lyapunov exponent.

The rotor is forced with period ``T = 2 pi / eta``. Its steady response is read from
the *stroboscopic Poincare section*: one state per forcing period, after a transient.

- **periodic** with period ``p`` (in forcing periods): the section repeats itself every
  ``p`` points, ``|P[k+p] - P[k]| <= rel_tol * scale`` over the second half of the
  section, where ``scale`` is the size of the orbit (not of the section, which is a
  single point for a period-1 orbit). The smallest such ``p`` is reported.
- **quasi-periodic**: not periodic, and either the largest Lyapunov exponent is zero
  within its uncertainty (a torus attractor), or, when no exponent is available, the
  section passes the weighted Birkhoff average test (Das, Saiki, Sander and Yorke,
  "Quantitative quasiperiodicity", Nonlinearity 30 (2017) 4111): time averages along a
  quasi-periodic orbit converge faster than any power of N with the smooth weight
  ``exp(-1/(t (1 - t)))``, on a chaotic one only like ``N^(-1/2)``.
- **chaotic**: the largest Lyapunov exponent is positive beyond its uncertainty (or,
  without an exponent, the Birkhoff test fails; the result then says it is unconfirmed).
- **unbounded**: non-finite states, states beyond ``bound``, or a section that keeps
  growing (its size in the last quarter exceeds ``growth_factor`` times the first).

A negative exponent on a section that has not settled within tolerance means an
attracting periodic orbit that is still being approached: reported as periodic, with a
message saying so.

The largest Lyapunov exponent is estimated with two nearby trajectories and periodic
renormalisation (G. Benettin, L. Galgani, J.-M. Strelcyn, Phys. Rev. A 14 (1976) 2338;
the algorithm as in J. C. Sprott, Chaos and Time-Series Analysis, Oxford 2003, sec. 5.6).
It is written over a *propagator* ``propagate(t, s, dt) -> s(t + dt)``, so the same code
runs on the Lorenz system in the tests and on the rotor through ``rubcli.solvers.solve``.
For the rotor this is the natural choice: its right-hand side is piecewise smooth, and a
variational (tangent) equation would need saltation matrices at every contact switch,
whereas two trajectories that each locate their own switches handle them exactly. Its
accuracy: the statistical error of a finite-time average (reported as ``stderr`` from
block means, roughly ``1/T``), plus a bias from the integration error, which is kept
well below the separation ``d0`` by the solver tolerances (defaults: dop853, rtol 1e-10).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

PERIODIC = "periodic"
QUASI_PERIODIC = "quasi-periodic"
CHAOTIC = "chaotic"
UNBOUNDED = "unbounded"
UNDETERMINED = "undetermined"
KINDS = (PERIODIC, QUASI_PERIODIC, CHAOTIC, UNBOUNDED, UNDETERMINED)

# Defaults of the classifier, named so that reports can quote them.
REL_TOL = 1e-4  # periodicity: return distance relative to the orbit size
MAX_PERIOD = 16  # longest period (in forcing periods) that is looked for
BOUND = 1e6  # a state beyond this norm is taken as diverged
GROWTH_FACTOR = 100.0  # section size growth (last quarter / first quarter) = unbounded
REGULAR_DIGITS = 5.0  # Birkhoff test: digits of agreement that count as regular
LYAPUNOV_FLOOR = 1e-3  # |lambda| below this (per unit time) counts as zero
LYAPUNOV_SIGMAS = 3.0  # ... and below this many standard errors
MIN_SECTION_POINTS = 8


# --------------------------------------------------------------------------- section


@dataclass(frozen=True)
class PoincareSection:
    """Stroboscopic section: the states at ``t0 + k T`` for k >= transient_periods."""

    tau: np.ndarray  # times of the section points
    points: np.ndarray  # shape (m, d)
    period: float  # forcing period T
    transient_periods: float

    def __len__(self) -> int:
        return int(self.points.shape[0])


def stroboscopic_section(
    t: np.ndarray,
    states: np.ndarray,
    period: float,
    *,
    t0: float | None = None,
    transient_periods: float = 0.0,
    phase: float = 0.0,
) -> PoincareSection:
    """One state per forcing period from sampled arrays.

    The section times are ``t0 + phase + k * period`` for ``k >= transient_periods``
    within ``[t[0], t[-1]]``. A sample that lies within ``1e-9 * period`` of a section
    time is taken as it is; otherwise the states are interpolated by a cubic spline
    (error O(h^4) in the sample spacing h). ``t0`` defaults to ``t[0]``.
    """
    t = np.asarray(t, dtype=float)
    states = np.asarray(states, dtype=float)
    if states.ndim == 1:
        states = states[:, None]
    if t.ndim != 1 or states.shape[0] != t.size or t.size < 2:
        raise ValueError("t must be 1-D and match the first axis of states (>= 2 samples)")
    if not period > 0.0:
        raise ValueError("period must be positive")
    start = float(t[0]) if t0 is None else float(t0)
    k_first = max(0, math.ceil(transient_periods - 1e-9))
    slack = 1e-9 * period
    k_last = math.floor((t[-1] + slack - start - phase) / period)
    ks = np.arange(k_first, k_last + 1)
    times = start + phase + ks * period
    times = times[(times >= t[0] - slack) & (times <= t[-1] + slack)]
    if times.size == 0:
        return PoincareSection(times, np.empty((0, states.shape[1])), period, transient_periods)
    idx = np.clip(np.searchsorted(t, times), 0, t.size - 1)
    idx_prev = np.clip(idx - 1, 0, t.size - 1)
    nearest = np.where(np.abs(t[idx] - times) <= np.abs(t[idx_prev] - times), idx, idx_prev)
    exact = np.abs(t[nearest] - times) <= slack
    points = np.empty((times.size, states.shape[1]))
    points[exact] = states[nearest[exact]]
    if not np.all(exact):
        finite = np.all(np.isfinite(states), axis=1)
        from scipy.interpolate import (
            CubicSpline,
        )  # on use: `rubcli run` needs no scipy interpolator

        spline = CubicSpline(t[finite], states[finite], axis=0)
        points[~exact] = spline(times[~exact])
    return PoincareSection(times, points, period, transient_periods)


def section_from_solution(solution, transient_periods: float = 0.0) -> PoincareSection:
    """Stroboscopic section of a ``Solution`` at the forcing period of its problem."""
    problem = solution.problem
    return stroboscopic_section(
        solution.t,
        solution.states,
        problem.params.period,
        t0=float(problem.t_eval[0]),
        transient_periods=transient_periods,
    )


# --------------------------------------------------------------------------- tests


def return_distances(points: np.ndarray, scale: float, max_period: int = MAX_PERIOD) -> dict:
    """``{p: max_k |P[k+p] - P[k]| / scale}`` over the second half of the section."""
    points = np.asarray(points, dtype=float)
    n = points.shape[0]
    first = n // 2
    out = {}
    for p in range(1, max_period + 1):
        if n - first - p < max(2, p):
            break
        diff = points[first + p :] - points[first : n - p]
        out[p] = float(np.max(np.linalg.norm(diff, axis=1)) / scale)
    return out


def _birkhoff_weights(n: int) -> np.ndarray:
    s = (np.arange(n) + 0.5) / n
    w = np.exp(-1.0 / (s * (1.0 - s)))
    return w / w.sum()


def weighted_birkhoff_digits(values: np.ndarray) -> float:
    """Digits of agreement between weighted Birkhoff averages of two halves of a series.

    ``-log10 |WB(first half) - WB(second half)| / spread``: large (>= 5 or so) for a
    periodic or quasi-periodic orbit, small (~1-3) for a chaotic one (Das et al. 2017).
    ``values`` may be (n,) or (n, d); the smallest over the columns is returned.
    """
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        values = values[:, None]
    half = values.shape[0] // 2
    if half < 4:
        return float("nan")
    w = _birkhoff_weights(half)
    digits = []
    for column in values.T:
        spread = float(np.ptp(column))
        if spread == 0.0:
            digits.append(16.0)
            continue
        a = float(w @ column[:half])
        b = float(w @ column[half : 2 * half])
        diff = abs(a - b) / spread
        digits.append(16.0 if diff == 0.0 else min(16.0, -math.log10(diff)))
    return float(min(digits))


# --------------------------------------------------------------------------- Lyapunov

Propagator = Callable[[float, np.ndarray, float], np.ndarray]


@dataclass(frozen=True)
class LyapunovEstimate:
    """Largest Lyapunov exponent (per unit of time) by Benettin's two-trajectory method."""

    exponent: float
    stderr: float  # standard error from block means of the local stretching rates
    interval: float  # time between renormalisations
    n_intervals: int
    d0: float  # separation after each renormalisation (in the scaled norm)
    running: np.ndarray = field(repr=False)  # running mean after each interval
    method: str = "Benettin two-trajectory renormalisation"

    def to_dict(self) -> dict:
        return {
            "exponent": self.exponent,
            "stderr": self.stderr,
            "interval": self.interval,
            "n_intervals": self.n_intervals,
            "d0": self.d0,
            "time": self.interval * self.n_intervals,
            "method": self.method,
        }


def largest_lyapunov(
    propagate: Propagator,
    t0: float,
    s0: Sequence[float],
    *,
    interval: float,
    n_intervals: int,
    d0: float = 1e-8,
    transient_intervals: int = 0,
    scale: Sequence[float] | float | None = None,
    direction: Sequence[float] | None = None,
    n_blocks: int = 10,
) -> LyapunovEstimate:
    """Largest Lyapunov exponent of the flow behind ``propagate`` (Benettin et al. 1976).

    A fiducial trajectory from ``s0`` and a companion at distance ``d0`` are propagated
    over ``interval``; the companion is then pulled back to distance ``d0`` along the
    current separation. The exponent is the mean of ``ln(d / d0) / interval``. Distances
    are measured in the norm of ``s / scale`` (componentwise), so that positions and
    velocities of different sizes weigh alike. The first ``transient_intervals`` are run
    (renormalising, to align the separation with the most unstable direction) but not
    averaged. Raises ``FloatingPointError`` if a state becomes non-finite.
    """
    if n_intervals < 1 or not interval > 0.0 or not d0 > 0.0:
        raise ValueError("need n_intervals >= 1, interval > 0 and d0 > 0")
    state = np.asarray(s0, dtype=float).copy()
    dim = state.size
    weights = np.ones(dim) if scale is None else np.broadcast_to(np.asarray(scale, float), dim)
    if direction is None:
        direction = np.ones(dim)
    unit = np.asarray(direction, dtype=float)
    unit = unit / np.linalg.norm(unit)  # unit vector in the scaled coordinates s / scale
    companion = state + d0 * unit * weights
    t = float(t0)
    logs = []
    for i in range(transient_intervals + n_intervals):
        new_state = np.asarray(propagate(t, state, interval), dtype=float)
        new_companion = np.asarray(propagate(t, companion, interval), dtype=float)
        if not (np.all(np.isfinite(new_state)) and np.all(np.isfinite(new_companion))):
            raise FloatingPointError(f"non-finite state at t = {t + interval:g}")
        sep = (new_companion - new_state) / weights
        d = float(np.linalg.norm(sep))
        if d == 0.0:
            raise FloatingPointError("trajectories coincided; increase d0")
        if i >= transient_intervals:
            logs.append(math.log(d / d0))
        companion = new_state + (new_companion - new_state) * (d0 / d)
        state = new_state
        t += interval
    rates = np.asarray(logs) / interval
    running = np.cumsum(rates) / np.arange(1, rates.size + 1)
    blocks = np.array_split(rates, min(n_blocks, rates.size))
    means = np.array([b.mean() for b in blocks])
    stderr = float(means.std(ddof=1) / math.sqrt(means.size)) if means.size > 1 else math.inf
    return LyapunovEstimate(
        exponent=float(rates.mean()),
        stderr=stderr,
        interval=float(interval),
        n_intervals=int(n_intervals),
        d0=float(d0),
        running=running,
    )


def propagator_from_rhs(
    fun: Callable[[float, np.ndarray], np.ndarray],
    method: str = "DOP853",
    rtol: float = 1e-10,
    atol: float = 1e-12,
) -> Propagator:
    """A propagator for a smooth ``ds/dt = fun(t, s)`` by ``scipy.integrate.solve_ivp``."""

    def propagate(t: float, s: np.ndarray, dt: float) -> np.ndarray:
        from scipy.integrate import solve_ivp

        sol = solve_ivp(fun, (t, t + dt), s, method=method, rtol=rtol, atol=atol)
        if not sol.success:
            raise FloatingPointError(sol.message)
        return sol.y[:, -1]

    return propagate


def rotor_propagator(params, method: str = "dop853", **options) -> Propagator:
    """A propagator for the rotor: each call solves a Problem with ``rubcli.solvers.solve``.

    The solver locates its own contact switches and slip reversals, so the piecewise
    right-hand side is handled exactly as in a normal run. Raises ``RuntimeError`` if
    the solver fails (the message says why).
    """
    from rubcli.problem import Problem
    from rubcli.solvers import solve

    def propagate(t: float, s: np.ndarray, dt: float) -> np.ndarray:
        problem = Problem(params=params, initial=tuple(s), t_eval=np.array([t, t + dt]))
        solution = solve(problem, method, **options)
        if not solution.success or solution.t.size < 2:
            raise RuntimeError(f"{method} failed in the Lyapunov run: {solution.message}")
        return solution.states[-1]

    return propagate


# --------------------------------------------------------------------------- classifier


@dataclass(frozen=True)
class Response:
    """The class of a steady response and the evidence for it."""

    kind: str  # one of KINDS
    period: int | None  # in forcing periods, for a periodic response
    lyapunov: LyapunovEstimate | None
    n_points: int  # section points used
    scale: float  # orbit size the tolerance is relative to
    rel_tol: float
    return_distances: dict = field(default_factory=dict)
    birkhoff_digits: float | None = None
    message: str = ""

    def to_dict(self) -> dict:
        lyap = self.lyapunov
        return {
            "kind": self.kind,
            "period": self.period,
            "lyapunov": None if lyap is None else lyap.exponent,
            "lyapunov_stderr": None if lyap is None else lyap.stderr,
            "lyapunov_details": None if lyap is None else lyap.to_dict(),
            "n_section_points": self.n_points,
            "scale": self.scale,
            "rel_tol": self.rel_tol,
            "return_distances": {str(k): v for k, v in self.return_distances.items()},
            "birkhoff_digits": self.birkhoff_digits,
            "message": self.message,
        }


def _lyapunov_sign(lyap: LyapunovEstimate, floor: float, sigmas: float) -> int:
    """+1 positive, -1 negative, 0 zero within max(floor, sigmas * stderr)."""
    margin = max(floor, sigmas * lyap.stderr)
    if lyap.exponent > margin:
        return 1
    if lyap.exponent < -margin:
        return -1
    return 0


def classify_section(
    points: np.ndarray,
    *,
    scale: float | None = None,
    rel_tol: float = REL_TOL,
    max_period: int = MAX_PERIOD,
    lyapunov: LyapunovEstimate | Callable[[], LyapunovEstimate] | None = None,
    bound: float = BOUND,
    growth_factor: float = GROWTH_FACTOR,
    regular_digits: float = REGULAR_DIGITS,
    lyapunov_floor: float = LYAPUNOV_FLOOR,
    lyapunov_sigmas: float = LYAPUNOV_SIGMAS,
) -> Response:
    """Classify the section points (module docstring gives the rules).

    ``scale`` is the orbit size (default: the largest of the section's extent and the
    norm of its mean; pass the extent of the whole trajectory when it is known, since a
    period-1 section is a single point). ``lyapunov`` is an estimate, or a callable
    that computes one: it is called only when the section is not periodic.
    """
    points = np.asarray(points, dtype=float)
    if points.ndim == 1:
        points = points[:, None]
    n = points.shape[0]
    if not np.all(np.isfinite(points)):
        return Response(UNBOUNDED, None, None, n, math.nan, rel_tol, message="non-finite states")
    norms = np.linalg.norm(points, axis=1) if n else np.zeros(0)
    if n and norms.max() > bound:
        return Response(
            UNBOUNDED,
            None,
            None,
            n,
            math.nan,
            rel_tol,
            message=f"state norm {norms.max():.3g} exceeds the bound {bound:g}",
        )
    if n < MIN_SECTION_POINTS:
        return Response(
            UNDETERMINED,
            None,
            None,
            n,
            math.nan,
            rel_tol,
            message=f"only {n} section points (need {MIN_SECTION_POINTS}): run longer",
        )
    if scale is None:
        extent = float(np.max(np.ptp(points, axis=0)))
        scale = max(extent, float(np.linalg.norm(points.mean(axis=0))))
    scale = max(float(scale), np.finfo(float).tiny)
    quarter = max(1, n // 4)
    spread_first = float(np.max(np.ptp(points[:quarter], axis=0))) + float(np.max(norms[:quarter]))
    spread_last = float(np.max(np.ptp(points[-quarter:], axis=0))) + float(np.max(norms[-quarter:]))
    if spread_last > growth_factor * spread_first:
        return Response(
            UNBOUNDED,
            None,
            None,
            n,
            scale,
            rel_tol,
            message=f"the section grows by {spread_last / spread_first:.3g}x over the run",
        )
    distances = return_distances(points, scale, max_period)
    for p, d in distances.items():
        if d <= rel_tol:
            return Response(
                PERIODIC,
                p,
                None,
                n,
                scale,
                rel_tol,
                distances,
                message=f"section repeats every {p} forcing period(s) within {d:.2g} x scale",
            )
    digits = weighted_birkhoff_digits(points / scale)
    lyap = lyapunov() if callable(lyapunov) else lyapunov
    if lyap is not None:
        sign = _lyapunov_sign(lyap, lyapunov_floor, lyapunov_sigmas)
        text = f"largest Lyapunov exponent {lyap.exponent:.4g} +- {lyap.stderr:.2g}"
        if sign > 0:
            return Response(
                CHAOTIC,
                None,
                lyap,
                n,
                scale,
                rel_tol,
                distances,
                digits,
                message=f"{text}: positive",
            )
        if sign < 0:
            best = min(distances, key=distances.get) if distances else None
            return Response(
                PERIODIC,
                best,
                lyap,
                n,
                scale,
                rel_tol,
                distances,
                digits,
                message=f"{text}: negative, an attracting periodic orbit still being "
                f"approached (section not settled within {rel_tol:g}; "
                f"closest return every {best} period(s)); run longer to confirm",
            )
        return Response(
            QUASI_PERIODIC,
            None,
            lyap,
            n,
            scale,
            rel_tol,
            distances,
            digits,
            message=f"{text}: zero within its uncertainty (a torus)",
        )
    if digits >= regular_digits:
        return Response(
            QUASI_PERIODIC,
            None,
            None,
            n,
            scale,
            rel_tol,
            distances,
            digits,
            message=f"not periodic up to {max_period}; weighted Birkhoff averages agree to "
            f"{digits:.1f} digits (regular); no Lyapunov exponent computed",
        )
    return Response(
        CHAOTIC,
        None,
        None,
        n,
        scale,
        rel_tol,
        distances,
        digits,
        message=f"not periodic up to {max_period}; weighted Birkhoff averages agree to only "
        f"{digits:.1f} digits (irregular); unconfirmed: no Lyapunov exponent computed",
    )


def classify_solution(
    solution,
    *,
    transient_periods: float,
    lyapunov: bool = True,
    lyapunov_periods: int = 200,
    lyapunov_method: str = "dop853",
    lyapunov_options: dict | None = None,
    **classify_options,
) -> Response:
    """Classify the steady response of a rotor ``Solution``.

    The section starts after ``transient_periods``; the tolerance is relative to the
    extent of the trajectory after the transient. If the section is not periodic and
    ``lyapunov`` is true, the largest exponent is estimated from the end of the run over
    ``lyapunov_periods`` forcing periods (renormalising once per period) with
    ``rotor_propagator(lyapunov_method, **lyapunov_options)``.
    """
    problem = solution.problem
    period = problem.params.period
    states = np.asarray(solution.states, dtype=float)
    if states.size and not np.all(np.isfinite(states)):
        return Response(
            UNBOUNDED,
            None,
            None,
            0,
            math.nan,
            REL_TOL,
            message=f"non-finite states ({solution.message})",
        )
    if not solution.success:
        if "non-finite" in solution.message:
            return Response(UNBOUNDED, None, None, 0, math.nan, REL_TOL, message=solution.message)
        return Response(
            UNDETERMINED,
            None,
            None,
            0,
            math.nan,
            REL_TOL,
            message=f"{solution.method} did not finish: {solution.message}",
        )
    section = section_from_solution(solution, transient_periods)
    after = solution.t >= float(problem.t_eval[0]) + transient_periods * period
    tail = states[after] if np.any(after) else states
    scale = float(np.max(np.ptp(tail, axis=0))) if tail.shape[0] > 1 else None
    if scale is not None:
        scale = max(scale, float(np.max(np.linalg.norm(tail, axis=1))) * 1e-3)

    failures: list[str] = []

    def compute_lyapunov() -> LyapunovEstimate | None:
        options = {"rtol": 1e-10, "atol": 1e-12}
        options.update(lyapunov_options or {})
        propagate = rotor_propagator(problem.params, lyapunov_method, **options)
        spread = np.ptp(tail, axis=0)
        weights = np.where(spread > 0, spread, 1.0)
        try:
            return largest_lyapunov(
                propagate,
                float(solution.t[-1]),
                states[-1],
                interval=period,
                n_intervals=lyapunov_periods,
                d0=1e-7,
                transient_intervals=min(10, lyapunov_periods // 10),
                scale=weights,
            )
        except (RuntimeError, FloatingPointError) as exc:
            failures.append(f"Lyapunov estimate failed: {exc}")
            return None

    response = classify_section(
        section.points,
        scale=scale,
        lyapunov=compute_lyapunov if lyapunov else None,
        **classify_options,
    )
    if failures:
        response = replace(response, message=f"{response.message}; {'; '.join(failures)}")
    return response

"""Classification of the steady response from the stroboscopic section, with its evidence.

The rotor is forced with period ``T = 2 pi / eta``. Its steady response is read from
the *stroboscopic Poincare section*: one state per forcing period, after a transient.
Each class comes with the numbers that decided it (``Response.evidence``), and the
tests run in this order:

1. **unbounded**: non-finite states, states beyond ``bound``, or a section that keeps
   growing (its size in the last quarter exceeds ``growth_factor`` times the first).
2. **periodic, period p**: the section repeats itself every ``p`` points,
   ``|P[k+p] - P[k]| <= rel_tol * scale`` over the second half of the section, where
   ``scale`` is the size of the orbit (not of the section, which is a single point for a
   period-1 orbit); for p > 1 the return distance must also be below ``rel_tol`` of the
   distance between the cycle's own points, so that a small section turning by about
   360/p degrees a period is not taken for a p-cycle. The smallest such p is reported,
   with the contraction still measured on it, if any.
3. **the section map's linear regime** (``analysis.response.section_map.linear_fit``): for
   p = 1 ... ``max_period`` the steps of the section are fitted by ``d_{k+p} = A d_k``;
   where the fit is linear (relative residual <= ``LINEAR_TOL``) and its leading
   multiplier has the same modulus in both halves of the record, the modulus decides:
   below 1, **converging to period p**, with its contraction rate per forcing period,
   rotation and the periods it needs to settle; above 1, **undecided** (the motion is
   leaving an unstable period-p orbit: the record ends before it reaches an attractor);
   1 within its error, a closed curve turned by the map: **quasi-periodic** (a small
   torus), with its rotation number, unless a positive exponent contradicts it (then
   undecided). A negative exponent does not: an attracting orbit would contract the
   section, which the fit measures directly; such an estimate has not yet turned to the
   torus's neutral direction (slow when the next exponent is close to zero, as on the dry
   whip, where it is -nu).
4. otherwise the **largest Lyapunov exponent** (when computed) and the **refined
   frequencies** of the section (``analysis.response.section_map.section_frequencies``: NAFF,
   Laskar 1993, on each half of the record) decide:
   - **chaotic**: the exponent is positive beyond ``LYAPUNOV_SIGMAS`` standard errors
     and beyond ``LYAPUNOV_FLOOR``;
   - **converging** (period not identified): negative beyond the same margin;
   - **quasi-periodic**: the dominant frequency of the two halves agrees to
     ``FREQUENCY_TOL`` of the Fourier resolution, and the exponent (if computed) is zero:
     within ``LYAPUNOV_ZERO_SIGMAS`` standard errors (or ``LYAPUNOV_FLOOR``), with an
     error small enough to exclude growth of ``LYAPUNOV_RESOLUTION`` per forcing period
     at ``LYAPUNOV_SIGMAS`` standard errors;
   - **undecided: record too short** otherwise: an exponent between zero and positive
     (0.009 +- 0.004 per tau is neither), an error too large to tell, frequencies that
     drift, or, without an exponent, an irregular section (chaos is never claimed
     without a positive exponent).

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
from typing import TYPE_CHECKING, Any

import numpy as np

from rubcli.analysis.response.section_map import (
    LINEAR_TOL,
    MARGINAL_RATE,
    Frequencies,
    LinearFit,
    linear_fit,
    section_frequencies,
)

if TYPE_CHECKING:
    from rubcli.model import ModelParams
    from rubcli.solution import Solution

PERIODIC = "periodic"
QUASI_PERIODIC = "quasi-periodic"
CHAOTIC = "chaotic"
UNBOUNDED = "unbounded"
UNDECIDED = "undecided"
CONVERGING = "converging"
KINDS = (PERIODIC, QUASI_PERIODIC, CHAOTIC, UNBOUNDED, UNDECIDED, CONVERGING)  # code = index
RECORD_TOO_SHORT = "record too short"

# Defaults of the classifier, named so that reports can quote them.
REL_TOL = 1e-4  # periodicity: return distance relative to the orbit size
MAX_PERIOD = 16  # longest period (in forcing periods) that is looked for
BOUND = 1e6  # a state beyond this norm is taken as diverged
GROWTH_FACTOR = 100.0  # section size growth (last quarter / first quarter) = unbounded
LYAPUNOV_FLOOR = 1e-3  # |lambda| (per unit time) below this is never called non-zero
LYAPUNOV_SIGMAS = 3.0  # positive or negative: beyond this many standard errors
LYAPUNOV_ZERO_SIGMAS = 2.0  # zero: within this many standard errors (or the floor) ...
LYAPUNOV_RESOLUTION = 0.1  # ... and LYAPUNOV_SIGMAS errors below this per interval
FREQUENCY_TOL = 0.2  # quasi-periodic: the halves' frequencies agree to this / resolution
NOISE_FLOOR = 1e-7  # a settled section smaller than this x scale has no contraction to fit
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


def section_from_solution(solution: Solution, transient_periods: float = 0.0) -> PoincareSection:
    """Stroboscopic section of a ``Solution`` at the forcing period of its problem."""
    problem = solution.problem
    return stroboscopic_section(
        solution.t,
        solution.states,
        problem.params.period,
        t0=float(problem.t_eval[0]),
        transient_periods=transient_periods,
    )


# --------------------------------------------------------------------------- returns


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


def rotor_propagator(params: ModelParams, method: str = "dop853", **options: Any) -> Propagator:
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
    """The class of a steady response, the evidence that decided it, and its label."""

    kind: str  # one of KINDS
    period: int | None  # forcing periods: of a periodic response, or of the orbit approached
    lyapunov: LyapunovEstimate | None
    n_points: int  # section points used
    scale: float  # orbit size the tolerance is relative to
    rel_tol: float
    return_distances: dict = field(default_factory=dict)
    message: str = ""
    contraction: LinearFit | None = None  # the section map's linear fit, when it decided
    frequencies: Frequencies | None = None  # refined frequencies of the section
    reason: str = ""  # why an undecided response is undecided

    @property
    def label(self) -> str:
        """The class in words: "converging to period 1", "undecided: record too short"."""
        if self.kind == PERIODIC:
            return f"periodic, period {self.period}"
        if self.kind == CONVERGING:
            return "converging" + (f" to period {self.period}" if self.period else "")
        if self.kind == QUASI_PERIODIC:
            return "quasi-periodic (torus)"
        if self.kind == UNDECIDED and self.reason:
            return f"undecided: {self.reason}"
        return self.kind

    def evidence(self) -> dict[str, float]:
        """The numbers behind the label, NaN where not measured (sweep columns)."""
        fit, freq, lyap = self.contraction, self.frequencies, self.lyapunov
        return {
            "contraction_rate": math.nan if fit is None else fit.rate,
            "contraction_rate_stderr": math.nan if fit is None else fit.rate_stderr,
            "rotation_number": _rotation_number(fit, freq),
            "frequency_diffusion": math.nan if freq is None else freq.diffusion,
            "lyapunov": math.nan if lyap is None else lyap.exponent,
            "lyapunov_stderr": math.nan if lyap is None else lyap.stderr,
            "lyapunov_time": math.nan if lyap is None else lyap.interval * lyap.n_intervals,
        }

    def to_dict(self) -> dict:
        lyap = self.lyapunov
        evidence = {k: (None if isinstance(v, float) and math.isnan(v) else v)
                    for k, v in self.evidence().items()}  # fmt: skip
        if lyap is not None:
            evidence["lyapunov_significance"] = (
                lyap.exponent / lyap.stderr if lyap.stderr > 0 else None
            )
        return {
            "kind": self.kind,
            "label": self.label,
            "period": self.period,
            "reason": self.reason or None,
            "evidence": evidence,
            "lyapunov": None if lyap is None else lyap.exponent,
            "lyapunov_stderr": None if lyap is None else lyap.stderr,
            "lyapunov_details": None if lyap is None else lyap.to_dict(),
            "contraction": None if self.contraction is None else self.contraction.to_dict(),
            "frequencies": None if self.frequencies is None else self.frequencies.to_dict(),
            "n_section_points": self.n_points,
            "scale": self.scale,
            "rel_tol": self.rel_tol,
            "return_distances": {str(k): v for k, v in self.return_distances.items()},
            "message": self.message,
        }


def _rotation_number(fit: LinearFit | None, freq: Frequencies | None) -> float:
    """Rotation per forcing period: the period-1 linear fit's where it decided, else the
    dominant NAFF line (a p-th iterate's rotation is known only modulo 1/p)."""
    if fit is not None and (fit.period == 1 or freq is None):
        return fit.rotation
    return math.nan if freq is None else freq.rotation_number


def lyapunov_verdict(
    lyap: LyapunovEstimate,
    floor: float = LYAPUNOV_FLOOR,
    sigmas: float = LYAPUNOV_SIGMAS,
    zero_sigmas: float = LYAPUNOV_ZERO_SIGMAS,
    resolution: float = LYAPUNOV_RESOLUTION,
) -> str:
    """ "positive", "negative", "zero" or "unresolved" (module docstring gives the rules)."""
    x, err = lyap.exponent, lyap.stderr
    if x > floor and x > sigmas * err:
        return "positive"
    if x < -floor and x < -sigmas * err:
        return "negative"
    if not sigmas * err * lyap.interval <= resolution:
        return "unresolved"
    if abs(x) <= max(floor, zero_sigmas * err):
        return "zero"
    return "unresolved"


def _lyapunov_text(lyap: LyapunovEstimate) -> str:
    t = lyap.exponent / lyap.stderr if lyap.stderr > 0 else math.inf
    return (
        f"largest Lyapunov exponent {lyap.exponent:.3g} +- {lyap.stderr:.2g} per unit time "
        f"({t:+.1f} standard errors, over {lyap.n_intervals} intervals)"
    )


def _settled_period(points, distances: dict, rel_tol: float, scale: float) -> int | None:
    """The smallest p whose return distance is below ``rel_tol`` of the orbit size and,
    for p > 1, of the distance between the cycle's own points (a slowly turning section
    that nearly closes after p periods is not a p-cycle)."""
    for p, d in distances.items():
        if d > rel_tol:
            continue
        if p == 1:
            return 1
        last = points[-p:]
        gaps = np.linalg.norm(last[:, None, :] - last[None, :, :], axis=2)
        separation = float(np.min(gaps[np.triu_indices(p, 1)])) / scale
        if d <= rel_tol * separation:
            return p
    return None


def classify_section(
    points: np.ndarray,
    *,
    scale: float | None = None,
    rel_tol: float = REL_TOL,
    max_period: int = MAX_PERIOD,
    lyapunov: LyapunovEstimate | Callable[[], LyapunovEstimate | None] | None = None,
    bound: float = BOUND,
    growth_factor: float = GROWTH_FACTOR,
    lyapunov_floor: float = LYAPUNOV_FLOOR,
    lyapunov_sigmas: float = LYAPUNOV_SIGMAS,
) -> Response:
    """Classify the section points (module docstring gives the rules).

    ``scale`` is the orbit size (default: the largest of the section's extent and the
    norm of its mean; pass the extent of the whole trajectory when it is known, since a
    period-1 section is a single point). ``lyapunov`` is an estimate, or a callable
    that computes one: it is called only when the section map is not in a linear regime
    that decides by itself.
    """
    points = np.asarray(points, dtype=float)
    if points.ndim == 1:
        points = points[:, None]
    n = points.shape[0]

    def response(
        kind: str, period: int | None = None, message: str = "", **evidence: Any
    ) -> Response:
        return Response(kind, period, evidence.pop("lyap", None), n, scale_, rel_tol,
                        distances, message, **evidence)  # fmt: skip

    scale_, distances = math.nan, {}
    if not np.all(np.isfinite(points)):
        return response(UNBOUNDED, message="non-finite states")
    norms = np.linalg.norm(points, axis=1) if n else np.zeros(0)
    if n and norms.max() > bound:
        return response(
            UNBOUNDED, message=f"state norm {norms.max():.3g} exceeds the bound {bound:g}"
        )
    if n < MIN_SECTION_POINTS:
        return response(
            UNDECIDED,
            message=f"only {n} section points (need {MIN_SECTION_POINTS}): run longer",
            reason=RECORD_TOO_SHORT,
        )
    if scale is None:
        extent = float(np.max(np.ptp(points, axis=0)))
        scale = max(extent, float(np.linalg.norm(points.mean(axis=0))))
    scale_ = max(float(scale), np.finfo(float).tiny)
    quarter = max(1, n // 4)
    spread_first = float(np.max(np.ptp(points[:quarter], axis=0))) + float(np.max(norms[:quarter]))
    spread_last = float(np.max(np.ptp(points[-quarter:], axis=0))) + float(np.max(norms[-quarter:]))
    if spread_last > growth_factor * spread_first:
        return response(
            UNBOUNDED,
            message=f"the section grows by {spread_last / spread_first:.3g}x over the run",
        )
    distances = return_distances(points, scale_, max_period)
    spread = np.ptp(points, axis=0)
    scaled = points / np.where(spread > 1e-12 * scale_, spread, scale_)
    settled = _settled_period(points, distances, rel_tol, scale_)
    if settled is not None:
        text = f"section repeats every {settled} forcing period(s) within " \
               f"{distances[settled]:.2g} x scale"  # fmt: skip
        fit = None
        if float(np.max(spread)) > NOISE_FLOOR * scale_:
            fit = linear_fit(scaled, settled)
            if fit is None or not (fit.residual <= LINEAR_TOL and fit.significant
                                   and fit.constant):  # fmt: skip
                fit = None
        if fit is not None and fit.log_rate > 0.0:
            return response(
                UNDECIDED, settled,
                f"{text}, but leaving that orbit: the section map is linear (residual "
                f"{fit.residual:.1g}) with a growing mode, {fit.rate:.6g} +- "
                f"{fit.rate_stderr:.1g} per forcing period; the record ends before the "
                "motion reaches its attractor",
                contraction=fit, reason=RECORD_TOO_SHORT,
            )  # fmt: skip
        if fit is not None:
            text += f"; still contracting by {fit.rate:.6g} per period"
        return response(PERIODIC, settled, text, contraction=fit)

    freq = section_frequencies(points)
    marginal = None
    for p in range(1, max_period + 1):
        fit = linear_fit(scaled, p)
        if fit is None or fit.residual > LINEAR_TOL:
            continue
        rate = f"{fit.rate:.6g} +- {fit.rate_stderr:.1g} per forcing period"
        turn = f"turning {abs(fit.rotation) * 360.0:.2f} deg per period"
        if fit.significant and fit.constant and fit.log_rate < 0.0:
            q = fit.resolved_period()
            return response(CONVERGING, q, _converging_text(fit, q, rate, turn, rel_tol, scale_),
                            contraction=fit, frequencies=freq)  # fmt: skip
        if fit.significant and fit.constant and fit.log_rate > 0.0:
            return response(
                UNDECIDED, p,
                f"leaving a period-{p} orbit: the section map is linear (residual "
                f"{fit.residual:.1g}) with a growing mode, {rate}, {turn}; the record ends "
                "before the motion reaches its attractor",
                contraction=fit, frequencies=freq, reason=RECORD_TOO_SHORT,
            )  # fmt: skip
        if not fit.significant and fit.log_rate_spread <= 10.0 * MARGINAL_RATE:
            marginal = fit
            break

    lyap = lyapunov() if callable(lyapunov) else lyapunov
    verdict = None if lyap is None else lyapunov_verdict(lyap, lyapunov_floor, lyapunov_sigmas)
    lyap_text = "no Lyapunov exponent computed" if lyap is None else _lyapunov_text(lyap)
    regular = freq is not None and freq.diffusion <= FREQUENCY_TOL * freq.resolution
    freq_text = "" if freq is None else (
        f"section frequency {freq.rotation_number:.6f} cycles per period, drifting "
        f"{freq.diffusion:.1g} between the halves (resolution {freq.resolution:.2g})"
    )  # fmt: skip
    if marginal is not None:
        text = (
            f"the section map is close to a rotation of a closed curve (linear fit residual "
            f"{marginal.residual:.1g}): modulus "
            f"{marginal.rate:.6g} +- {marginal.rate_stderr:.1g} per period (1 within error), "
            f"rotation number {_rotation_number(marginal, freq):.6f}; {lyap_text}"
        )
        if verdict in (None, "zero"):
            return response(QUASI_PERIODIC, None, text, lyap=lyap,
                            contraction=marginal, frequencies=freq)  # fmt: skip
        if lyap.exponent < 0.0:
            # An attracting orbit would contract the section, which the fit measures
            # directly and finds neutral: the exponent has not yet turned to the neutral
            # direction along the torus (slow where the next exponent is close to 0).
            return response(
                QUASI_PERIODIC, None,
                f"{text}: below zero, but the section does not contract, so the estimate "
                "has not converged to the torus's zero exponent",
                lyap=lyap, contraction=marginal, frequencies=freq,
            )  # fmt: skip
        return response(UNDECIDED, None, f"{text}: conflicting evidence", lyap=lyap,
                        contraction=marginal, frequencies=freq,
                        reason="conflicting evidence")  # fmt: skip
    nonlinear = f"no linear regime of the section map up to period {max_period}"
    if verdict == "positive":
        return response(CHAOTIC, None, f"{lyap_text}: positive; {freq_text}", lyap=lyap,
                        frequencies=freq)  # fmt: skip
    if verdict == "negative":
        return response(
            CONVERGING, None,
            f"{lyap_text}: negative, an attracting orbit still being approached; {nonlinear}, "
            "so its period is not identified yet",
            lyap=lyap, frequencies=freq,
        )  # fmt: skip
    if regular and verdict in (None, "zero"):
        tail = "zero within its error" if verdict else "quasi-periodicity rests on the frequencies"
        return response(QUASI_PERIODIC, None, f"{freq_text}; {lyap_text}: {tail}", lyap=lyap,
                        frequencies=freq)  # fmt: skip
    if verdict == "unresolved":
        why = (f"{lyap_text}: neither zero nor positive at this record length; "
               "a longer Lyapunov record decides")  # fmt: skip
    elif verdict == "zero":
        why = f"{lyap_text}: zero within its error, but the {freq_text}"
    else:
        why = f"irregular section ({freq_text}); chaos needs a positive exponent: {lyap_text}"
    return response(UNDECIDED, None, why, lyap=lyap, frequencies=freq, reason=RECORD_TOO_SHORT)


def _converging_text(
    fit: LinearFit, period: int, rate: str, turn: str, rel_tol: float, scale: float
) -> str:
    text = (
        f"converging to a period-{period} orbit: the section map is linear (residual "
        f"{fit.residual:.1g}) and contracts by {rate}, {turn}"
    )
    if period != fit.period:
        text += f" (fitted as its {fit.period // period}-th iterate, whose limits coincide)"
    remaining = fit.remaining / scale
    if math.isfinite(remaining) and remaining > rel_tol:
        settle = math.log(rel_tol / remaining) / fit.log_rate
        text += f"; {remaining:.2g} x scale from it, within {rel_tol:g} in ~{settle:.0f} periods"
    return text


def classify_solution(
    solution: Solution,
    *,
    transient_periods: float,
    lyapunov: bool = True,
    lyapunov_periods: int = 200,
    lyapunov_method: str = "dop853",
    lyapunov_options: dict | None = None,
    **classify_options: Any,
) -> Response:
    """Classify the steady response of a rotor ``Solution``.

    The section starts after ``transient_periods``; the tolerance is relative to the
    extent of the trajectory after the transient. If the section map does not decide in
    its linear regime and ``lyapunov`` is true, the largest exponent is estimated from
    the end of the run over ``lyapunov_periods`` forcing periods (renormalising once per
    period) with ``rotor_propagator(lyapunov_method, **lyapunov_options)``; not with a
    stator with its own mass, whose state that propagator does not carry (the section's
    evidence alone decides).
    """
    problem = solution.problem
    period = problem.params.period
    lyapunov = lyapunov and solution.stator_states is None
    states = np.asarray(solution.states, dtype=float)
    if states.size and not np.all(np.isfinite(states)):
        return Response(
            UNBOUNDED, None, None, 0, math.nan, REL_TOL,
            message=f"non-finite states ({solution.message})",
        )  # fmt: skip
    if not solution.success:
        if "non-finite" in solution.message:
            return Response(UNBOUNDED, None, None, 0, math.nan, REL_TOL, message=solution.message)
        return Response(
            UNDECIDED, None, None, 0, math.nan, REL_TOL,
            message=f"{solution.method} did not finish: {solution.message}",
            reason="the solver did not finish",
        )  # fmt: skip
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

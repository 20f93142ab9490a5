"""Periodic orbits of the forced, nonsmooth rotor: the stroboscopic map, its monodromy
matrix through contact and stick, and shooting (docs/orbits.md).

The stroboscopic map ``P^k(x0; p)`` is the state after k forcing periods ``T = 2 pi / eta``
started from ``x0`` at ``tau = 0``. It is integrated through the solvers' driver, by
``dop853-jit`` at tight tolerances in the variational mode of ``solvers.variational``:
the rotor's flow with its variational equation ``Phi' = J Phi``, multiplied at each
event by the saltation matrix (and where stick ends by the Jacobian of the projection
onto the rolling constraint). The events are the solvers' own (the extended systems'
event search and rules). In stick the rank of ``Phi`` drops: a zero multiplier is
expected there. The largest and smallest z of a flow are refined from its samples to
where z turns (``extreme_z``): grazing is located on them.

Shooting solves ``P^k(x0) - x0 = 0`` by Newton with ``Phi - I``.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import operator
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rubcli import model
from rubcli.analysis.energy.regimes import time_in_regimes
from rubcli.analysis.orbits.bounds import ORBITS_BOUNDS, ORBITS_WALL_TIME_S
from rubcli.model import ModelParams
from rubcli.solvers import events as ev

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

    from rubcli.solvers.variational import Flow

# Integration tolerances of the map (relative and absolute): tight, so the monodromy
# matrix and the located bifurcations are accurate to ~1e-9.
RTOL = 1e-12
ATOL = 1e-12
# A period with more switch events than this is a failure (a chattering contact).
MAX_EVENTS_PER_PERIOD = 400
# The samples a flow's extremes of z are first read on (``sample_grid``), and the
# refinement of the extreme sample: Newton's iterations at most, and the step below
# which it stops (relative to max(1, tau)): the time of the turn is then off by about the
# step's square times the contact's frequency, and z, flat there, by that error's square
# (about 1e-14).
SAMPLES_PER_PERIOD = 64
SAMPLES_PER_CONTACT_PERIOD = 16
EXTREME_ITERATIONS = 12
EXTREME_STEP = 1e-4
PARAMETERS = ("eta", "mu", "K", "e", "nu", "Rp")
# A long flow without a map's variational equations (a transient) is integrated in pieces
# of at most this many forcing periods: the samples of one piece are kept (for the
# extremes of z), so its memory is bounded whatever its length.
TRANSIENT_CHUNK_PERIODS = 16
# A stator with its own mass (``two_body_flow``): the samples a period its flow's extremes
# of z are first read on (the ring's own oscillation resolved too).
TWO_BODY_SAMPLES = 200


class OrbitError(RuntimeError):
    """The map could not be evaluated (chatter, a failed integration)."""


class WallTimeBudgetError(Exception):
    """The wall-time budget of an orbits run is spent. Not an OrbitError: nothing retries
    it (a corrector would halve its step and try again); the callers stop with it."""


def check_deadline(deadline: float | None) -> None:
    """WallTimeBudgetError once ``time.perf_counter()`` has passed ``deadline`` (None: never)."""
    if deadline is not None and time.perf_counter() > deadline:
        raise WallTimeBudgetError("wall-time budget exhausted")


@dataclass
class FlowResult:
    """The state after the flow from ``tau0`` to ``tau1`` and what happened on the way."""

    state: np.ndarray  # (4,)
    monodromy: np.ndarray | None  # (4, 4) d state / d initial state, or None
    events: list[tuple[float, str, int, int]]  # (tau, kind, regime before, regime after)
    max_z: float
    min_z: float
    contact_time: float
    stick_time: float
    duration: float
    nfev: int = 0

    @property
    def contact_fraction(self) -> float:
        return self.contact_time / self.duration if self.duration > 0 else 0.0

    @property
    def stick_fraction(self) -> float:
        return self.stick_time / self.duration if self.duration > 0 else 0.0

    @property
    def contact_phases(self) -> int:
        """Contact entries on the way (0 for an orbit always in contact or always free)."""
        return sum(1 for e in self.events if e[1] == ev.KIND_NAMES[ev.ENTRY])


def with_parameter(params: ModelParams, name: str, value: float) -> ModelParams:
    """``params`` with one of PARAMETERS set to ``value``; OrbitError if ``value`` lies
    outside the model's domain (a continuation step past ``eta = 0`` or ``mu = 0``)."""
    if name not in PARAMETERS:
        raise ValueError(f"unknown continuation parameter {name!r}; one of {PARAMETERS}")
    try:
        return dataclasses.replace(params, **{name: float(value)})
    except ValueError as exc:
        raise OrbitError(f"{name} = {value:.6g} leaves the model's domain ({exc})") from None


# ------------------------------------------------------------- the API's arguments

ROTOR_STATE = ("x", "y", "vx", "vy")
TWO_BODY_STATE = (*ROTOR_STATE, "u", "v", "u'", "v'")
_BOUNDS = (("gt", operator.gt, ">"), ("ge", operator.ge, ">="), ("lt", operator.lt, "<"),
           ("le", operator.le, "<="))  # fmt: skip


def orbits_setting(
    owner: str, name: str, value: object, key: str, integer: bool = False
) -> float | int:
    """``value`` of the argument ``name`` of ``owner``, checked as the [orbits] table's
    ``key`` is in a case file: an int (``integer``) or a finite real number, within the
    bounds of ``orbit_bounds.ORBITS_BOUNDS`` (the one source of them, the case schema's
    too); a TypeError or ValueError naming ``owner: name``."""
    if integer:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise TypeError(f"{owner}: {name} must be an int, got {type(value).__name__}")
        value = int(value)
    else:
        value = model.real_number(owner, name, value)
        if not math.isfinite(value):
            raise ValueError(f"{owner}: {name} must be finite (got {value!r})")
    bounds = ORBITS_BOUNDS[key]
    for attr, holds, word in _BOUNDS:
        limit = bounds.get(attr)
        if limit is not None and not holds(value, limit):
            raise ValueError(
                f"{owner}: {name} must be {word} {limit:g} (got {value!r}), as [orbits] "
                f"{key} in a case file"
            )
    return value


def orbits_budget(owner: str, max_wall_time_s: object) -> float:
    """The wall-time budget ``max_wall_time_s`` checked as [orbits] max_wall_time_s (None:
    that key's default)."""
    if max_wall_time_s is None:
        return ORBITS_WALL_TIME_S
    return orbits_setting(owner, "max_wall_time_s", max_wall_time_s, "max_wall_time_s")


def section_state(owner: str, name: str, value: object, params: object) -> np.ndarray:
    """``value`` checked as a state on the section of ``params`` (a ModelParams): the
    rotor's four entries, with a stator of its own mass the ring's four too."""
    from rubcli.problem import state_values

    if not isinstance(params, ModelParams):
        raise TypeError(f"{owner}: params must be a ModelParams, got {type(params).__name__}")
    names = ROTOR_STATE if params.stator is None else TWO_BODY_STATE
    return np.array(state_values(owner, name, value, names))


def check_deadline_value(owner: str, deadline: object) -> float | None:
    """``deadline`` checked: None or a finite ``time.perf_counter()`` value."""
    if deadline is None:
        return None
    value = model.real_number(owner, "deadline", deadline)
    if not math.isfinite(value):
        raise ValueError(f"{owner}: deadline must be finite (got {value!r})")
    return value


# ------------------------------------------------------------------------- the flow


def sample_grid(params: ModelParams, tau0: float, tau1: float) -> np.ndarray:
    """The samples a flow is read on for its extremes of z: ``SAMPLES_PER_PERIOD`` a
    forcing period, and ``SAMPLES_PER_CONTACT_PERIOD`` a period of the contact's
    oscillation (of circular frequency ``sqrt(1 + K)``), whichever is closer."""
    h = min(params.period / SAMPLES_PER_PERIOD,
            2.0 * math.pi / (SAMPLES_PER_CONTACT_PERIOD * math.sqrt(1.0 + params.K)))  # fmt: skip
    n = max(2, math.ceil((tau1 - tau0) / h)) + 1
    return np.linspace(tau0, tau1, n)


def flow(
    params: ModelParams,
    s0: ArrayLike,
    tau0: float,
    tau1: float,
    *,
    variational: bool = True,
    rtol: float = RTOL,
    atol: float = ATOL,
    max_events: int | None = None,
    locked: int | None = None,
    deadline: float | None = None,
) -> FlowResult:
    """Integrate the nonsmooth flow from (tau0, s0) to tau1, with the monodromy matrix.

    Returns the final state, ``Phi = d s(tau1) / d s0`` (if ``variational``), the switch
    events, the largest and smallest z (``extreme_z``), and the time spent in contact
    and in stick. Raises OrbitError on chatter or a failed integration, and
    WallTimeBudgetError once ``time.perf_counter()`` passes ``deadline``.

    ``locked``: integrate in this one regime without any switch (the smooth extension of
    a free or a slipping flow across the surfaces), used to locate grazing from the side
    where the branch is smooth.
    """
    if not tau1 > tau0:
        raise OrbitError(f"empty time span tau = {tau0:.9g} .. {tau1:.9g}")
    if params.stator is not None:
        return two_body_flow(params, s0, tau0, tau1, variational=variational, rtol=rtol,
                             atol=atol, locked=locked, deadline=deadline)  # fmt: skip
    # on use: the extended loop's event search imports scipy, which `rubcli run` of a
    # compiled method does without (analysis modules import this one)
    from rubcli.solvers.variational import N_ROTOR, rotor_flow

    s = np.asarray(s0, dtype=float).copy()
    regime = model.regime_of_state(s, params, tau0) if locked is None else int(locked)
    if regime == model.STICK:
        s = model.project_to_rolling(s, params)
    limit = _event_limit(params, tau0, tau1, max_events)
    run = _runner(rotor_flow, params, locked, rtol, atol, limit, deadline)
    main = run(s, sample_grid(params, tau0, tau1), np.eye(4) if variational else None)

    def acceleration(t: float, state: np.ndarray, regime: int) -> tuple[float, float]:
        f = model.rhs(t, state, params, regime)
        return f[2], f[3]

    def flow_to(start: np.ndarray, t_eval: np.ndarray) -> tuple[np.ndarray, int, int]:
        out = run(start, t_eval, None)
        return out.solution.states[-1], int(out.solution.regimes[-1]), out.nfev

    sol = main.solution
    phi = main.end[N_ROTOR:].reshape(4, 4) if variational else None
    return _flow_result(main, main.end[:4], phi, sol.states, acceleration, flow_to, tau0, tau1)


def _event_limit(params: ModelParams, tau0: float, tau1: float, given: int | None) -> int:
    """A flow's event budget: ``given``, or ``MAX_EVENTS_PER_PERIOD`` a period."""
    periods = max(1.0, (tau1 - tau0) / params.period)
    return given if given is not None else int(MAX_EVENTS_PER_PERIOD * periods) + 10


def _runner(
    flow_of: Callable[..., Flow], params: ModelParams, locked: int | None, rtol: float,
    atol: float, limit: int, deadline: float | None,
) -> Callable[[np.ndarray, np.ndarray, np.ndarray | None], Flow]:  # fmt: skip
    """``run(start, t_eval, phi)``: the flow ``flow_of`` (``solvers.variational``) with
    the deadline's time left as its budget; OrbitError if it fails, WallTimeBudgetError
    past ``deadline``."""

    def run(start: np.ndarray, t_eval: np.ndarray, phi: np.ndarray | None) -> Flow:
        check_deadline(deadline)
        budget = math.inf if deadline is None else max(deadline - time.perf_counter(), 0.0)
        out = flow_of(params, start, t_eval, phi=phi, locked=locked, rtol=rtol, atol=atol,
                      max_events=limit, max_wall_time_s=budget)  # fmt: skip
        if not out.solution.success:
            check_deadline(deadline)
            raise OrbitError(f"integration failed: {out.solution.message}")
        return out

    return run


def _flow_result(
    main: Flow, state: np.ndarray, monodromy: np.ndarray | None, section: np.ndarray,
    acceleration: Callable[[float, np.ndarray, int], tuple[float, float]],
    flow_to: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, int, int]], tau0: float,
    tau1: float,
) -> FlowResult:  # fmt: skip
    """The FlowResult of a flow's run ``main``: its end ``state`` and ``monodromy``, its
    extremes of z refined from its samples (``section``: the section's states there;
    ``extreme_z``), its events and its time in contact and in stick."""
    sol, nfev = main.solution, main.nfev
    extremes = []
    for sign in (1.0, -1.0):
        z, more = extreme_z(sol.t, section, sol.regimes, sign, acceleration, flow_to)
        extremes.append(z)
        nfev += more
    regimes = time_in_regimes(sol)
    return FlowResult(
        state=np.array(state),
        monodromy=None if monodromy is None else np.array(monodromy),
        events=[(e.tau, e.kind, e.regime_before, e.regime_after) for e in sol.events],
        max_z=extremes[0],
        min_z=extremes[1],
        contact_time=float(sum(v for k, v in regimes.items() if k != "free")),
        stick_time=float(regimes["stick"]),
        duration=float(tau1 - tau0),
        nfev=nfev,
    )


def extreme_z(
    t: np.ndarray, S: np.ndarray, regimes: np.ndarray, sign: float,
    acceleration: Callable[[float, np.ndarray, int], tuple[float, float]],
    flow_to: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, int, int]],
) -> tuple[float, int]:  # fmt: skip
    """The largest z of a flow's samples (``sign`` +1; -1: the smallest) refined to where
    z turns, ``g = x vx + y vy = 0``, by Newton's method on g (``g' = |v|^2 + x ax + y
    ay``) safeguarded by bisection in the samples' bracket, each iterate's state from a
    short flow ``flow_to(start, [t_j, t]) -> (state at t, its regime, evaluations)``
    from the sample t_j before it. ``S`` holds
    the section's states at the samples ``t`` (n, m), the rotor's (x, y, vx, vy) first,
    ``regimes`` their regimes; ``acceleration(t, state, regime)`` is the rotor's (ax,
    ay). At the span's ends, or where g does not change sign around the sample (no turn
    between them), the sample's z. Returns (z, evaluations spent)."""
    z = np.hypot(S[:, 0], S[:, 1])
    i = int(np.argmax(sign * z))
    best, nfev = float(z[i]), 0
    if i == 0 or i == t.size - 1:
        return best, nfev
    lo, hi = float(t[i - 1]), float(t[i + 1])
    if not sign * _radial(S[i - 1]) > 0.0 > sign * _radial(S[i + 1]):
        return best, nfev
    tk, sk, regime = float(t[i]), S[i], int(regimes[i])
    for _ in range(EXTREME_ITERATIONS):
        ax, ay = acceleration(tk, sk, regime)
        g = _radial(sk)
        if sign * g > 0.0:
            lo = max(lo, tk)
        elif sign * g < 0.0:
            hi = min(hi, tk)
        else:
            break
        rate = sk[2] ** 2 + sk[3] ** 2 + sk[0] * ax + sk[1] * ay
        t_next = tk - g / rate if rate != 0.0 else math.nan
        if not lo < t_next < hi:
            t_next = 0.5 * (lo + hi)
        j = int(np.searchsorted(t, t_next, side="right")) - 1
        if t[j] == t_next:  # an iterate exactly on a sample: its state, not an empty flow
            sk, regime, spent = S[j], int(regimes[j]), 0
        else:
            sk, regime, spent = flow_to(S[j], np.array([t[j], t_next]))
        nfev += spent
        step, tk = abs(t_next - tk), t_next
        zk = math.hypot(sk[0], sk[1])
        best = max(best, zk) if sign > 0.0 else min(best, zk)
        if step <= EXTREME_STEP * max(1.0, abs(tk)):
            break
    return best, nfev


def _radial(s: np.ndarray) -> float:
    """g = x vx + y vy = z z': z turns where it changes sign."""
    return float(s[0] * s[2] + s[1] * s[3])


def two_body_flow(
    params: ModelParams,
    s0: ArrayLike,
    tau0: float,
    tau1: float,
    *,
    variational: bool = True,
    rtol: float = RTOL,
    atol: float = ATOL,
    locked: int | None = None,
    deadline: float | None = None,
) -> FlowResult:
    """``flow`` of a stator with its own mass: the state on the section is the rotor's
    four entries and the ring's, ``(x, y, vx, vy, u, v, u', v')``. Integrated by
    ``dop853-jit`` in the extended event loop, its monodromy matrix in the variational
    mode of ``solvers.variational`` (through the two bodies' saltation matrices); its
    extremes of z refined (``extreme_z``) from ``TWO_BODY_SAMPLES`` samples a period.
    Raises OrbitError on a failed flow or a grazing switch, WallTimeBudgetError past
    ``deadline``."""
    from rubcli.solvers.compiled.two_body import N_SECTION, SECTION, two_body_rhs
    from rubcli.solvers.variational import two_body_flow as run_flow
    from rubcli.stator import N_STATES

    s = np.asarray(s0, dtype=float).copy()
    if s.shape != (N_SECTION,):
        raise OrbitError(f"a two-body state has {N_SECTION} entries (got {s.shape})")
    run = _runner(run_flow, params, locked, rtol, atol, _event_limit(params, tau0, tau1, None),
                  deadline)  # fmt: skip
    n = max(2, int(math.ceil(TWO_BODY_SAMPLES * (tau1 - tau0) / params.period))) + 1
    main = run(s, np.linspace(tau0, tau1, n), np.eye(N_SECTION) if variational else None)
    pars, stator = np.array(model.params_vector(params)), params.stator.record()
    on_section = list(SECTION)

    def acceleration(t: float, q: np.ndarray, regime: int) -> tuple[float, float]:
        full = np.empty(N_STATES)
        full[on_section] = q
        full[4], full[5] = params.phi0 + params.eta * t, params.eta
        f = two_body_rhs(full, pars, stator, regime)
        return f[2], f[3]

    def flow_to(start: np.ndarray, t_eval: np.ndarray) -> tuple[np.ndarray, int, int]:
        out = run(start, t_eval, None)
        return out.end[on_section], int(out.solution.regimes[-1]), out.nfev

    sol = main.solution
    section = np.hstack((sol.states, sol.stator_states))
    phi = main.end[N_STATES:].reshape(N_SECTION, N_SECTION) if variational else None
    return _flow_result(main, main.end[on_section], phi, section, acceleration, flow_to, tau0,
                        tau1)  # fmt: skip


# ------------------------------------------------------------------------ the map


def stroboscopic_map(
    params: ModelParams,
    s0: ArrayLike,
    k: int = 1,
    *,
    variational: bool = True,
    rtol: float = RTOL,
    atol: float = ATOL,
    locked: int | None = None,
    deadline: float | None = None,
) -> FlowResult:
    """P^k(s0): the flow over k forcing periods from tau = 0 (with its monodromy matrix)."""
    T = k * params.period
    return flow(params, s0, 0.0, T, variational=variational, rtol=rtol, atol=atol, locked=locked,
                deadline=deadline)  # fmt: skip


def floquet_multipliers(monodromy: np.ndarray) -> np.ndarray:
    """Eigenvalues of the monodromy matrix, largest modulus first."""
    lam = np.linalg.eigvals(monodromy)
    return lam[np.argsort(-np.abs(lam), kind="stable")]


@dataclass
class PeriodicOrbit:
    """A fixed point of P^k and its stability."""

    params: ModelParams
    state: np.ndarray  # on the section tau = 0 (mod kT)
    k: int
    monodromy: np.ndarray = field(repr=False)
    multipliers: np.ndarray
    flow: FlowResult = field(repr=False)
    newton_iterations: int = 0
    residual: float = 0.0

    @property
    def stable(self) -> bool:
        return bool(np.max(np.abs(self.multipliers)) < 1.0)


@dataclass
class NewtonError(Exception):
    """Shooting did not converge: why, and the last iterate."""

    reason: str
    state: np.ndarray
    residual: float

    def __str__(self) -> str:
        return self.reason


def residual_scale(state: np.ndarray) -> float:
    return max(1.0, float(np.max(np.abs(state))))


def shoot(
    params: ModelParams,
    guess: ArrayLike,
    k: int = 1,
    *,
    tol: float = 1e-10,
    max_iter: int = 12,
    rtol: float = RTOL,
    atol: float = ATOL,
    deadline: float | None = None,
    max_wall_time_s: float | None = None,
) -> PeriodicOrbit:
    """Newton on G(x0) = P^k(x0) - x0 with the Jacobian Phi - I.

    Converged when ``|G|_inf <= tol * max(1, |x0|_inf)``. Raises NewtonError with the
    reason (no convergence within ``max_iter``, a singular Jacobian, a failed map), and
    WallTimeBudgetError once ``max_wall_time_s`` seconds have passed (default: [orbits]
    max_wall_time_s's, 3600) or past ``deadline`` (a ``time.perf_counter()`` value).

    The arguments are checked as a case file's [orbits] table (``k`` as ``period``,
    ``tol`` as ``newton_tol``, ``max_iter`` as ``max_newton``, ``rtol``, ``atol``): a
    TypeError or ValueError naming the argument; ``guess`` holds the section's state
    (``x, y, vx, vy``, with a stator of its own mass the ring's ``u, v, u', v'`` too).
    """
    owner = "shoot()"
    x = section_state(owner, "guess", guess, params)
    k = orbits_setting(owner, "k", k, "period", integer=True)
    tol = orbits_setting(owner, "tol", tol, "newton_tol")
    max_iter = orbits_setting(owner, "max_iter", max_iter, "max_newton", integer=True)
    rtol = orbits_setting(owner, "rtol", rtol, "rtol")
    atol = orbits_setting(owner, "atol", atol, "atol")
    budget = time.perf_counter() + orbits_budget(owner, max_wall_time_s)
    deadline = check_deadline_value(owner, deadline)
    deadline = budget if deadline is None else min(deadline, budget)
    res = math.inf
    for it in range(max_iter + 1):
        try:
            fl = stroboscopic_map(params, x, k, rtol=rtol, atol=atol, deadline=deadline)
        except OrbitError as exc:
            raise NewtonError(f"map failed at Newton iteration {it}: {exc}", x, res) from None
        G = fl.state - x
        res = float(np.max(np.abs(G)))
        if not math.isfinite(res):
            raise NewtonError(f"non-finite residual at Newton iteration {it}", x, res)
        if res <= tol * residual_scale(x):
            return PeriodicOrbit(
                params, x, k, fl.monodromy, floquet_multipliers(fl.monodromy), fl, it, res
            )
        if it == max_iter:
            break
        try:
            dx = np.linalg.solve(fl.monodromy - np.eye(x.size), -G)
        except np.linalg.LinAlgError:
            raise NewtonError(f"singular Phi - I at Newton iteration {it}", x, res) from None
        x = x + dx
    raise NewtonError(
        f"Newton did not converge in {max_iter} iterations (residual {res:.3g})", x, res
    )


def transient_state(
    params: ModelParams, s0: ArrayLike, periods: int, deadline: float | None = None
) -> np.ndarray:
    """The state after ``periods`` forcing periods from s0 (a starting guess for shooting),
    integrated in pieces of ``TRANSIENT_CHUNK_PERIODS`` (bounded memory); WallTimeBudgetError
    past ``deadline``."""
    s = np.asarray(s0, dtype=float).copy()
    done = 0
    while done < periods:
        n = min(TRANSIENT_CHUNK_PERIODS, periods - done)
        tau0, tau1 = done * params.period, (done + n) * params.period
        s = flow(params, s, tau0, tau1, variational=False, rtol=1e-10, atol=1e-12,
                 deadline=deadline).state  # fmt: skip
        done += n
    return s


def free_multipliers(params: ModelParams, k: int = 1) -> np.ndarray:
    """Closed-form multipliers of the free (never touching) Jeffcott rotor over k periods.

    The free rotor x'' + 2 nu x' + x = forcing has the eigenvalues -nu +- i beta
    (beta^2 = 1 - nu^2), each twice (x and y); the multipliers are exp(lambda k T).
    """
    T = k * params.period
    beta = np.sqrt(complex(1.0 - params.nu**2))
    lam = np.array([-params.nu + 1j * beta, -params.nu - 1j * beta] * 2)
    out = np.exp(lam * T)
    return out[np.argsort(-np.abs(out), kind="stable")]

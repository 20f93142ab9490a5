"""Periodic orbits of the forced, nonsmooth rotor: the stroboscopic map, its monodromy
matrix through contact and stick, and shooting (docs/orbits.md).

The stroboscopic map ``P^k(x0; p)`` is the state after k forcing periods ``T = 2 pi / eta``
started from ``x0`` at ``tau = 0``. It is integrated here one smooth segment at a time
(regime-locked ``model.rhs``, scipy DOP853 at tight tolerances, terminal events at every
switch: contact entry/exit, slip reversal, stick exit), together with the variational
equation ``Phi' = J Phi`` of the same segment (``model.rhs_jacobian``; in stick the
Jacobian of the rolling flow, which ignores the slip component of the state). At each event
``Phi`` is multiplied by the saltation matrix

    S = I + (f+ - f-) grad(h)^T / (grad(h)^T f- + dh/dtau)

(``saltation_matrix``), and by the Jacobian of the projection onto the rolling constraint
where stick ends (the state is projected there, as the solvers do: ``events.apply_event``).
At contact entry and exit ``f+ = f-`` (the contact force vanishes at ``z = 1``), so
``S = I``; at a slip reversal and at stick entry the friction force jumps and ``S`` is not
the identity. In stick the rank of ``Phi`` drops: a zero multiplier is expected there.

Shooting solves ``P^k(x0) - x0 = 0`` by Newton with ``Phi - I``. The regime switches
themselves come from ``rubcli.solvers.events`` (which regime follows an event), so this
module and the solvers share one set of switching rules.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import events as ev

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from rubcli.solution import Solution

# Integration tolerances of the map (relative and absolute): tight, so the monodromy
# matrix and the located bifurcations are accurate to ~1e-9.
RTOL = 1e-12
ATOL = 1e-12
# A period with more switch events than this is a failure (a chattering contact).
MAX_EVENTS_PER_PERIOD = 400
# Events closer than this to a segment's start are the restart surface itself, not a crossing.
RESTART_GAP = 1e-11
PARAMETERS = ("eta", "mu", "K", "e", "nu", "Rp")
# A long flow without a map's variational equations (a transient) is integrated in pieces
# of at most this many forcing periods: the dense output of one piece is kept (for the
# extremes of z), and 1e5 periods in one piece once held 3 GB.
TRANSIENT_CHUNK_PERIODS = 16
# A stator with its own mass (``two_body_flow``): the samples a period on which its flow's
# extremes of z are read.
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


# ----------------------------------------------------------------- switching surfaces


def _slip_gradient(s: np.ndarray) -> np.ndarray:
    """grad of v_r = Rp eta + (x vy - y vx) / z in (x, y, vx, vy)."""
    x, y, vx, vy = s
    z = math.hypot(x, y)
    w = x * vy - y * vx
    return np.array([vy / z - w * x / z**3, -vx / z - w * y / z**3, -y / z, x / z])


def _stick_margin(tau: float, s: np.ndarray, params: ModelParams, sign: float) -> float:
    """``events.stick_margin``: stick ends where it rises through zero."""
    pars = model.params_vector(params)
    return float(ev.stick_margin(tau, s[0], s[1], s[2], s[3], pars, sign))


def _numerical_gradient(fun, tau: float, s: np.ndarray) -> tuple[np.ndarray, float]:
    """Central differences of a scalar fun(tau, s): (grad in s, d/dtau)."""
    grad = np.zeros(4)
    for j in range(4):
        h = 1e-7 * max(1.0, abs(s[j]))
        sp, sm = s.copy(), s.copy()
        sp[j] += h
        sm[j] -= h
        grad[j] = (fun(tau, sp) - fun(tau, sm)) / (2.0 * h)
    h = 1e-7 * max(1.0, abs(tau))
    return grad, (fun(tau + h, s) - fun(tau - h, s)) / (2.0 * h)


def surface_gradient(
    kind: int, tau: float, s: np.ndarray, params: ModelParams, regime: int
) -> tuple[np.ndarray, float]:
    """(grad h, dh/dtau) of the surface an event of ``kind`` (an ``events`` code) crosses."""
    if kind in (ev.ENTRY, ev.EXIT):
        return np.array([2.0 * s[0], 2.0 * s[1], 0.0, 0.0]), 0.0
    if kind in (ev.REVERSAL, ev.STICK_ENTRY):
        return _slip_gradient(s), 0.0
    # stick exit: h = sign T - L, the sign the needed friction leaves the cone on
    needed = float(model.stick_friction(tau, s[0], s[1], s[2], s[3], params))
    sign = 1.0 if needed > 0.0 else -1.0
    return _numerical_gradient(lambda t, q: _stick_margin(t, q, params, sign), tau, s)


def saltation_matrix(
    tau: float,
    s: np.ndarray,
    params: ModelParams,
    regime_before: int,
    regime_after: int,
    grad: np.ndarray,
    dh_dtau: float = 0.0,
) -> np.ndarray:
    """S = I + (f+ - f-) grad(h)^T / (grad(h)^T f- + dh/dtau) at a transversal crossing.

    Raises OrbitError at a grazing crossing (the denominator vanishes): grazing is a
    bifurcation of its own and is detected on the branch, not divided by.
    """
    f_minus = model.rhs(tau, s, params, regime_before)
    f_plus = model.rhs(tau, s, params, regime_after)
    rate = float(grad @ f_minus) + dh_dtau
    jump = f_plus - f_minus
    if not np.any(jump):
        return np.eye(4)
    scale = float(np.linalg.norm(grad) * np.linalg.norm(f_minus)) + abs(dh_dtau)
    if abs(rate) <= 1e-13 * max(scale, 1e-300):
        raise OrbitError(f"grazing switch at tau = {tau:.9g}: the saltation matrix is singular")
    return np.eye(4) + np.outer(jump, grad) / rate


def rolling_projection_jacobian(s: np.ndarray, params: ModelParams) -> np.ndarray:
    """Jacobian of ``model.project_to_rolling`` at s (central differences)."""
    jac = np.zeros((4, 4))
    for j in range(4):
        h = 1e-7 * max(1.0, abs(s[j]))
        sp, sm = s.copy(), s.copy()
        sp[j] += h
        sm[j] -= h
        jac[:, j] = (
            model.project_to_rolling(sp, params) - model.project_to_rolling(sm, params)
        ) / (2.0 * h)
    return jac


# ------------------------------------------------------------------------- the flow


def _event_functions(params: ModelParams, regime: int) -> list:
    """solve_ivp event functions of a regime, each tagged with its kind: the event
    functions of ``events`` (``surface_value``, ``slip_value``, ``stick_margin``) on the
    flow's first four entries."""

    def entry(t: float, Y: np.ndarray) -> float:
        return float(ev.surface_value(Y))

    def exit_(t: float, Y: np.ndarray) -> float:
        return float(ev.surface_value(Y))

    entry.terminal, entry.direction, entry.kind = True, 1.0, ev.ENTRY
    exit_.terminal, exit_.direction, exit_.kind = True, -1.0, ev.EXIT
    if regime == model.FREE:
        return [entry]
    out = [exit_]
    if params.mu > 0.0 and regime in (model.SLIP_POSITIVE, model.SLIP_NEGATIVE):

        def reversal(t: float, Y: np.ndarray) -> float:
            return float(ev.slip_value(Y, params, t))

        reversal.terminal, reversal.kind = True, ev.REVERSAL
        reversal.direction = -1.0 if regime == model.SLIP_POSITIVE else 1.0
        out.append(reversal)
    if regime == model.STICK:
        for sign in (1.0, -1.0):

            def margin(t: float, Y: np.ndarray, sign: float = sign) -> float:
                return _stick_margin(t, Y[:4], params, sign)

            margin.terminal, margin.direction, margin.kind = True, 1.0, ev.STICK_EXIT
            out.append(margin)
    return out


def _start_regime(tau: float, s: np.ndarray, params: ModelParams) -> int:
    """The regime a state starts in (contact by z, slip direction by v_r, Filippov at 0)."""
    return model.regime_of_state(s, params, tau)


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
    events, the largest and smallest z (refined on the dense output), and the time spent
    in contact and in stick. Raises OrbitError on chatter or a failed integration, and
    WallTimeBudgetError once ``time.perf_counter()`` passes ``deadline`` (checked at every
    evaluation of the right-hand side).

    ``locked``: integrate in this one regime without any switch (the smooth extension of
    a free or a slipping flow across the surfaces), used to locate grazing from the side
    where the branch is smooth.
    """
    if not tau1 > tau0:
        raise OrbitError(f"empty time span tau = {tau0:.9g} .. {tau1:.9g}")
    if params.stator is not None:
        return two_body_flow(params, s0, tau0, tau1, variational=variational, rtol=rtol,
                             atol=atol, locked=locked, deadline=deadline)  # fmt: skip
    s = np.asarray(s0, dtype=float).copy()
    regime = _start_regime(tau0, s, params) if locked is None else int(locked)
    if regime == model.STICK:
        s = model.project_to_rolling(s, params)
    phi = np.eye(4)
    tau = float(tau0)
    periods = max(1.0, (tau1 - tau0) / params.period)
    limit = max_events if max_events is not None else int(MAX_EVENTS_PER_PERIOD * periods) + 10
    args = model.params_vector(params)
    found: list[tuple[float, str, int, int]] = []
    contact_time = stick_time = 0.0
    best_max = (-math.inf, None, None)  # (z, dense sol, (ta, tb))
    best_min = (math.inf, None, None)
    nfev = 0
    last_kind = ev.NO_EVENT

    while tau < tau1:
        reg = regime

        check_deadline(deadline)
        if variational:

            def fun(t: float, Y: np.ndarray, reg: int = reg) -> np.ndarray:
                check_deadline(deadline)
                f = model.rhs_record(t, Y[0], Y[1], Y[2], Y[3], args, reg)
                J = model.rhs_jacobian_record(t, Y[0], Y[1], Y[2], Y[3], args, reg)
                out = np.empty(20)
                out[:4] = f
                out[4:] = (J @ Y[4:].reshape(4, 4)).ravel()
                return out

            Y0 = np.concatenate([s, phi.ravel()])
        else:

            def fun(t: float, Y: np.ndarray, reg: int = reg) -> np.ndarray:
                check_deadline(deadline)
                return np.array(model.rhs_record(t, Y[0], Y[1], Y[2], Y[3], args, reg))

            Y0 = s.copy()
        evs = _event_functions(params, reg) if locked is None else []
        from scipy.integrate import solve_ivp  # on use: `rubcli run` needs no scipy integrator

        sol = solve_ivp(
            fun, (tau, tau1), Y0, method="DOP853", rtol=rtol, atol=atol, events=evs,
            dense_output=True,
        )  # fmt: skip
        nfev += sol.nfev
        if sol.status == -1:
            raise OrbitError(f"integration failed at tau = {tau:.9g}: {sol.message}")
        t_end = float(sol.t[-1])
        # extremes of z on this segment, refined later on the dense output
        z = np.hypot(sol.y[0], sol.y[1])
        i_max, i_min = int(np.argmax(z)), int(np.argmin(z))
        if z[i_max] > best_max[0]:
            best_max = (float(z[i_max]), sol.sol, _bracket(sol.t, i_max))
        if z[i_min] < best_min[0]:
            best_min = (float(z[i_min]), sol.sol, _bracket(sol.t, i_min))
        if reg != model.FREE:
            contact_time += t_end - tau
        if reg == model.STICK:
            stick_time += t_end - tau
        if sol.status == 0:
            s = sol.y[:4, -1].copy()
            if variational:
                phi = sol.y[4:, -1].reshape(4, 4).copy()
            tau = float(tau1)
            break
        # a terminal event: which one
        idx = next(i for i, te in enumerate(sol.t_events) if te.size)
        kind = evs[idx].kind
        t_ev = float(sol.t_events[idx][0])
        Y_ev = sol.y_events[idx][0]
        s_ev = Y_ev[:4].copy()
        if variational:
            phi = Y_ev[4:].reshape(4, 4).copy()
        s_new, new_regime, kind, _ = ev.apply_event(t_ev, kind, s_ev, reg, params)
        if variational:
            grad, dh_dt = surface_gradient(kind, t_ev, s_ev, params, reg)
            if kind == ev.STICK_EXIT:
                # the rolling flow ignored the slip part of the state; the state is
                # projected here, and so is its variation
                phi = rolling_projection_jacobian(s_ev, params) @ phi
            phi = saltation_matrix(t_ev, s_new, params, reg, new_regime, grad, dh_dt) @ phi
        found.append((t_ev, ev.KIND_NAMES[kind], reg, new_regime))
        if len(found) > limit:
            raise OrbitError(
                f"more than {limit} switch events in {periods:.3g} periods (chattering contact)"
            )
        if t_ev - tau <= RESTART_GAP and kind == last_kind and new_regime == reg:
            raise OrbitError(f"switch storm at tau = {t_ev:.9g} ({ev.KIND_NAMES[kind]})")
        s, regime, tau, last_kind = s_new, new_regime, t_ev, kind

    max_z = _refine_extreme(best_max, +1.0)
    min_z = _refine_extreme(best_min, -1.0)
    return FlowResult(
        state=s,
        monodromy=phi if variational else None,
        events=found,
        max_z=max_z,
        min_z=min_z,
        contact_time=contact_time,
        stick_time=stick_time,
        duration=float(tau1 - tau0),
        nfev=nfev,
    )


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
    ``dop853-jit`` in the extended event loop (``solvers.two_body``); its extremes of z
    read on ``TWO_BODY_SAMPLES`` samples a period; its monodromy matrix through the
    switches by saltation matrices, each smooth segment's Jacobian by central differences
    of its locked flow (``analysis.two_body_monodromy``). Raises OrbitError on a failed
    flow or a grazing switch, WallTimeBudgetError past ``deadline``."""
    from rubcli.analysis import two_body_monodromy
    from rubcli.analysis.regimes import time_in_regimes
    from rubcli.solvers.two_body import two_body_flow as run

    s = np.asarray(s0, dtype=float).copy()
    if s.shape != (8,):
        raise OrbitError(f"a two-body state has 8 entries (got {s.shape})")
    n = max(2, int(math.ceil(TWO_BODY_SAMPLES * (tau1 - tau0) / params.period))) + 1
    grid = np.linspace(tau0, tau1, n)

    def end(start: np.ndarray, t_eval: np.ndarray, regime: int | None) -> Solution:
        check_deadline(deadline)
        budget = None if deadline is None else max(deadline - time.perf_counter(), 0.0)
        problem = Problem(params, tuple(start[:4]), t_eval, stator_initial=tuple(start[4:]))
        sol = run(problem, rtol, atol, locked=regime, max_wall_time_s=budget)
        if not sol.success:
            check_deadline(deadline)
            raise OrbitError(f"integration failed: {sol.message}")
        return sol

    def segment(start: np.ndarray, ta: float, tb: float, regime: int) -> tuple[np.ndarray, int]:
        other = end(start, np.array([ta, tb]), regime)
        ends = np.concatenate((other.states[-1], other.stator_states[-1]))
        return ends, int(other.stats.get("nfev", 0))

    sol = end(s, grid, locked)
    state = np.concatenate((sol.states[-1], sol.stator_states[-1]))
    nfev = int(sol.stats.get("nfev", 0))
    phi = None
    if variational:
        try:
            phi, more = two_body_monodromy.monodromy(segment, sol, s, tau0, tau1)
        except two_body_monodromy.GrazingSwitchError as exc:
            raise OrbitError(f"{exc} in the flow from tau = {tau0:.9g}") from None
        nfev += more
    regimes = time_in_regimes(sol)
    events = [(e.tau, e.kind, e.regime_before, e.regime_after) for e in sol.events]
    z = sol.z
    return FlowResult(
        state=state,
        monodromy=phi,
        events=events,
        max_z=float(np.max(z)),
        min_z=float(np.min(z)),
        contact_time=float(sum(v for k, v in regimes.items() if k != "free")),
        stick_time=float(regimes["stick"]),
        duration=float(tau1 - tau0),
        nfev=nfev,
    )


def _bracket(t: np.ndarray, i: int) -> tuple[float, float]:
    return float(t[max(i - 1, 0)]), float(t[min(i + 1, t.size - 1)])


def _refine_extreme(best, sign: float) -> float:
    """The extreme of z on the dense output near the best step point (golden/Brent)."""
    value, dense, (ta, tb) = best
    if dense is None or tb <= ta:
        return value

    def neg(t: float) -> float:
        y = dense(t)
        return -sign * math.hypot(y[0], y[1])

    from scipy.optimize import minimize_scalar

    res = minimize_scalar(neg, bounds=(ta, tb), method="bounded", options={"xatol": 1e-12})
    return max(value, -res.fun) if sign > 0 else min(value, res.fun)


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
) -> PeriodicOrbit:
    """Newton on G(x0) = P^k(x0) - x0 with the Jacobian Phi - I.

    Converged when ``|G|_inf <= tol * max(1, |x0|_inf)``. Raises NewtonError with the
    reason (no convergence within ``max_iter``, a singular Jacobian, a failed map), and
    WallTimeBudgetError past ``deadline``.
    """
    x = np.asarray(guess, dtype=float).copy()
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

"""Whirls of the symmetric machine: circular orbits of unknown rate, their stability and
their continuation (``[orbits] kind = "whirl"``, docs/orbits.md).

Without unbalance (``e = 0``) the rotor and the stator are rotationally symmetric, and a
whirl ``w = r exp(i W tau)`` at constant radius ``r > 1`` and rate ``W`` (negative:
backward) is a *relative equilibrium*: an equilibrium ``u = r`` of the equation in the
frame turning with it, ``u = w exp(-i W tau)``,

    u'' + 2 (nu + i W) u' + (1 - W^2 + 2 i nu W) u + K (1 - 1/|u|)(1 + i mu_c) u = 0.

It is not a fixed point of any iterate of the forcing-period map, so shooting does not
find it; here it is algebraic. With ``s = 1 - 1/r`` (0 at the clearance, 1 at infinity)
and the slip velocity ``v_r = Rp eta + r W`` of the rotor's surface on the stator:

- radial balance (every whirl): ``W^2 - 1 - K s = 0``;
- **slip** (``v_r`` of sign ``sigma``, friction ``mu_c = sigma mu``): the tangential
  balance ``2 nu W + sigma mu K s = 0``. The friction drives the whirl against ``v_r``:
  with ``Rp eta > 0`` only ``sigma = +1``, ``W < 0`` is consistent, the *dry whirl*,
  ``s = (K + sqrt(K^2 + 4 a)) / (2 a)``, ``a = (mu K / 2 nu)^2``, whatever eta and Rp;
- **rolling** (``v_r = 0``, the dry whip): ``W + Rp eta (1 - s) = 0``, i.e.
  ``(1 + K) r^2 - K r - (Rp eta)^2 = 0`` (``model.rolling_whirl_radius``). It needs the
  friction coefficient ``mu_eq = -2 nu W / (K s)`` and holds while ``|mu_eq| <= mu``.

Where a slip branch reaches ``v_r = 0`` its friction is exactly ``mu`` and it meets the
rolling branch at the edge of the friction cone: the two are born (or die) together there,
a nonsmooth fold of the two branches when the parameter turns back (reported as such).

**Stability.** A slip whirl: the eigenvalues of the 4x4 Jacobian of the equation above in
``(Re u, Im u, Re u', Im u')`` (``synchronous.rotating_frame_jacobian`` with ``eta``
replaced by ``W``, ``E = 0``); one is zero, the turn of the whole whirl (the symmetry),
and the others decide. A rolling whirl moves on the constraint ``v_r = 0``: its radial
motion ``r'' = (Rp eta)^2 / r - 2 nu r' - r - K (r - 1)`` has the eigenvalues
``-nu +- sqrt(nu^2 - c)``, ``c = (Rp eta / r)^2 + 1 + K``; the turn is neutral (0), and a
slip off the constraint returns to it in finite time while the needed friction is inside
the cone (reported as the transverse eigenvalue ``-inf``, multiplier 0). The multipliers
over one forcing period ``T = 2 pi / eta`` are ``exp(lambda T)``.

**Continuation.** Pseudo-arclength in ``X = (s, W, q)``, ``q = p / (p_max - p_min)``, on
the two equations of the current mode, Newton on the bordered 3x3 system; the step grows
after easy corrections and halves after failed ones. Between consecutive points: the
mode's validity (``sigma v_r > 0`` in slip, ``mu - |mu_eq| >= 0`` rolling) is located on
its zero by Brent's method and the branch continues in the other mode from that point;
``s`` reaching 0 (the whirl leaves contact) or 1 (the radius grows without bound) ends
it; a fold (the tangent's parameter component changes sign, ``det dF/d(s, W) = 0``) and a
change of the number of unstable eigenvalues (a Hopf pair or a real root through 0) are
located by Brent's method on their test functions.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from rubcli import model
from rubcli.analysis.orbits.periodic import WallTimeBudgetError, check_deadline
from rubcli.analysis.orbits.synchronous import rotating_frame_jacobian
from rubcli.model import ModelParams

SLIP_POSITIVE, SLIP_NEGATIVE, ROLLING = model.SLIP_POSITIVE, model.SLIP_NEGATIVE, model.STICK
MODE_NAMES = {SLIP_POSITIVE: "slip+", SLIP_NEGATIVE: "slip-", ROLLING: "rolling"}
PARAMETERS = ("eta", "mu", "K", "nu", "Rp")  # e stays 0: the machine must stay symmetric
NONSMOOTH_FOLD, SLIP_ROLL, FOLD, HOPF, REAL_CROSSING, GRAZING, INFINITY = (
    "nonsmooth_fold",
    "slip_roll_transition",
    "fold",
    "hopf",
    "real_eigenvalue_crossing",
    "grazing",
    "radius_unbounded",
)
EIGEN_TOL = 1e-9  # |eigenvalue| below this (x the largest) is the neutral turn
S_EDGE = 1e-9  # s this close to 0 or 1 ends a branch (contact lost, radius unbounded)
XTOL = 1e-13  # Brent on the segment fraction
BUDGET_STOP = "wall-time budget exhausted"  # a direction's stop when the budget ran out


class WhirlError(ValueError):
    """Parameters for which whirls are not defined (the machine is not symmetric)."""


def check_symmetric(params: ModelParams) -> None:
    if params.e != 0.0:
        raise WhirlError(
            f"whirls of constant radius need a symmetric machine: e = 0 (got e = {params.e:g})"
        )


# ------------------------------------------------------------------------ equations


def residual(mode: int, s: float, w: float, p: ModelParams) -> np.ndarray:
    """The two equations of a whirl of this mode at ``(s, W)`` (module docstring)."""
    radial = w * w - 1.0 - p.K * s
    if mode == ROLLING:
        return np.array([radial, w + p.Rp * p.eta * (1.0 - s)])
    return np.array([radial, 2.0 * p.nu * w + float(mode) * p.mu * p.K * s])


def jacobian(mode: int, s: float, w: float, p: ModelParams) -> np.ndarray:
    """d(residual)/d(s, W)."""
    if mode == ROLLING:
        return np.array([[-p.K, 2.0 * w], [-p.Rp * p.eta, 1.0]])
    return np.array([[-p.K, 2.0 * w], [float(mode) * p.mu * p.K, 2.0 * p.nu]])


def validity(mode: int, s: float, w: float, p: ModelParams) -> float:
    """Positive while the mode holds: ``sigma v_r`` in slip, ``mu - |mu_eq|`` rolling."""
    if mode == ROLLING:
        return p.mu - abs(needed_friction(s, w, p))
    return float(mode) * (p.Rp * p.eta + w / (1.0 - s))


def needed_friction(s: float, w: float, p: ModelParams) -> float:
    """mu_eq = -2 nu W / (K s): the friction coefficient that holds a rolling whirl."""
    return -2.0 * p.nu * w / (p.K * s) if s > 0.0 else math.inf


# ------------------------------------------------------------------------ one whirl


@dataclass(frozen=True)
class Whirl:
    """One whirl: mode, radius, rate and its stability in the co-rotating frame."""

    params: ModelParams
    mode: int  # SLIP_POSITIVE, SLIP_NEGATIVE or ROLLING
    s: float  # 1 - 1/r
    rate: float  # W, rad per unit tau (negative: backward whirl)
    eigenvalues: np.ndarray = field(repr=False)  # co-rotating frame (4; -inf transverse)

    @property
    def radius(self) -> float:
        return 1.0 / (1.0 - self.s)

    @property
    def order(self) -> float:
        """Whirl rate in orders of the running speed, W / eta."""
        return self.rate / self.params.eta

    @property
    def slip_velocity(self) -> float:
        return self.params.Rp * self.params.eta + self.radius * self.rate

    @property
    def friction_needed(self) -> float:
        """The friction coefficient the whirl uses: mu_eq rolling, sigma mu slipping."""
        if self.mode == ROLLING:
            return needed_friction(self.s, self.rate, self.params)
        return float(self.mode) * self.params.mu

    @property
    def nontrivial(self) -> np.ndarray:
        """The eigenvalues without the neutral turn (the one nearest 0)."""
        eig = self.eigenvalues
        finite = np.isfinite(eig)
        turn = int(np.argmin(np.where(finite, np.abs(eig), np.inf)))
        return np.delete(eig, turn)

    @property
    def growth_rate(self) -> float:
        """Largest real part of the nontrivial eigenvalues (negative: stable)."""
        eig = self.nontrivial
        return float(np.max(eig[np.isfinite(eig)].real))

    @property
    def n_unstable(self) -> int:
        eig = self.nontrivial
        scale = max(1.0, float(np.max(np.abs(eig[np.isfinite(eig)]))))
        return int(np.sum(np.isfinite(eig) & (eig.real > EIGEN_TOL * scale)))

    @property
    def stable(self) -> bool:
        return self.n_unstable == 0 and self.growth_rate < 0.0

    @property
    def state(self) -> np.ndarray:
        """The state at tau = 0 with the whirl on the x axis: (r, 0, 0, r W)."""
        return np.array([self.radius, 0.0, 0.0, self.radius * self.rate])

    def multipliers(self) -> np.ndarray:
        """exp(lambda T) over one forcing period T = 2 pi / eta (the transverse: 0)."""
        eig = self.eigenvalues
        out = np.zeros(eig.size, dtype=complex)
        finite = np.isfinite(eig)
        with np.errstate(under="ignore"):
            out[finite] = np.exp(eig[finite] * self.params.period)
        return out

    def to_dict(self) -> dict:
        return {
            "mode": MODE_NAMES[self.mode],
            "radius": self.radius,
            "whirl_rate": self.rate,
            "whirl_order": self.order,
            "slip_velocity": self.slip_velocity,
            "friction_needed": self.friction_needed,
            "stable": self.stable,
            "n_unstable": self.n_unstable,
            "growth_rate": self.growth_rate,
            "eigenvalues": [[float(v.real), float(v.imag)] for v in self.eigenvalues],
        }


def eigenvalues(mode: int, s: float, w: float, p: ModelParams) -> np.ndarray:
    """Co-rotating-frame eigenvalues (module docstring), largest real part first."""
    r = 1.0 / (1.0 - s)
    if mode == ROLLING:
        c = (p.Rp * p.eta / r) ** 2 + 1.0 + p.K
        root = np.sqrt(complex(p.nu * p.nu - c))
        eig = np.array([-p.nu + root, -p.nu - root, 0.0, -np.inf], dtype=complex)
    else:
        jac = rotating_frame_jacobian(complex(r, 0.0), p, float(mode) * p.mu, rate=w)
        eig = np.linalg.eigvals(jac).astype(complex)
    order = np.argsort(-np.where(np.isfinite(eig.real), eig.real, -np.inf), kind="stable")
    return eig[order]


def make_whirl(mode: int, s: float, w: float, p: ModelParams) -> Whirl:
    return Whirl(p, mode, float(s), float(w), eigenvalues(mode, s, w, p))


def whirls(params: ModelParams) -> list[Whirl]:
    """Every whirl of these parameters in contact (closed forms of the module docstring):
    slipping in either direction and rolling, each only where its mode holds."""
    check_symmetric(params)
    p, out = params, []
    if p.nu > 0.0 and p.mu > 0.0:
        a = (p.mu * p.K / (2.0 * p.nu)) ** 2
        s = (p.K + math.sqrt(p.K * p.K + 4.0 * a)) / (2.0 * a)
        for mode in (SLIP_POSITIVE, SLIP_NEGATIVE):
            w = -float(mode) * p.mu * p.K * s / (2.0 * p.nu)
            if 0.0 < s < 1.0 and validity(mode, s, w, p) > 0.0:
                out.append(make_whirl(mode, s, w, p))
    spin = p.Rp * p.eta
    r = model.rolling_whirl_radius(p)
    if r > 1.0 and spin > 0.0:
        s, w = 1.0 - 1.0 / r, -spin / r
        if validity(ROLLING, s, w, p) >= 0.0:
            out.append(make_whirl(ROLLING, s, w, p))
    return out


# ------------------------------------------------------------------------ continuation


@dataclass(frozen=True)
class WhirlSettings:
    """What to continue and how (the [orbits] table with kind = "whirl")."""

    parameter: str
    p_min: float
    p_max: float
    step: float
    min_step: float
    max_step: float
    max_points: int = 200  # per direction of each branch
    directions: tuple[int, ...] = (1, -1)
    newton_tol: float = 1e-12
    max_newton: int = 20
    locate: bool = True
    max_wall_time_s: float | None = None  # the run's wall-time budget (None: unbounded)

    @property
    def scale(self) -> float:
        return self.p_max - self.p_min


@dataclass
class WhirlPoint:
    """A whirl on a branch, with the parameter value and how it was found."""

    whirl: Whirl
    value: float  # the continued parameter
    branch: int
    label: str = ""  # the event of a located point
    newton_iterations: int = 0


@dataclass
class WhirlEvent:
    kind: str
    value: float
    point: WhirlPoint
    located: bool
    note: str

    def to_dict(self) -> dict:
        return {"kind": self.kind, "value": self.value, "located": self.located,
                "note": self.note, "whirl": self.point.whirl.to_dict()}  # fmt: skip


@dataclass
class WhirlBranch:
    """One branch, in order along the arclength (the start somewhere inside)."""

    index: int
    start: Whirl
    points: list[WhirlPoint] = field(default_factory=list)
    events: list[WhirlEvent] = field(default_factory=list)
    stops: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "branch": self.index,
            "start": self.start.to_dict(),
            "points": len(self.points),
            "events": [e.to_dict() for e in self.events],
            "stops": self.stops,
        }


@dataclass
class WhirlContinuation:
    parameter: str
    settings: WhirlSettings
    start_whirls: list[Whirl]
    branches: list[WhirlBranch]
    status: str = "ok"
    message: str = ""
    budget_exhausted: bool = False  # the wall-time budget cut the run short

    @property
    def events(self) -> list[WhirlEvent]:
        return [e for b in self.branches for e in b.events]

    def rows(self) -> list[WhirlPoint]:
        return [pt for b in self.branches for pt in b.points]

    def to_dict(self) -> dict:
        return {
            "parameter": self.parameter,
            "status": self.status,
            "message": self.message,
            "wall_time_budget_exhausted": self.budget_exhausted,
            "start_whirls": [w.to_dict() for w in self.start_whirls],
            "branches": [b.to_dict() for b in self.branches],
            "events": [e.to_dict() for e in self.events],
        }


class _Tracer:
    """Pseudo-arclength on one branch (module docstring)."""

    def __init__(self, base: ModelParams, settings: WhirlSettings, deadline: float | None = None):
        self.base, self.st = base, settings
        self.deadline = deadline  # time.perf_counter() past which WallTimeBudgetError

    def params(self, q: float) -> ModelParams:
        return replace(self.base, **{self.st.parameter: q * self.st.scale})

    def f(self, mode: int, x: np.ndarray) -> np.ndarray:
        return residual(mode, x[0], x[1], self.params(x[2]))

    def full_jacobian(self, mode: int, x: np.ndarray) -> np.ndarray:
        jac = np.zeros((2, 3))
        jac[:, :2] = jacobian(mode, x[0], x[1], self.params(x[2]))
        h = 1e-7 * max(1.0, abs(x[2]))
        up, down = x.copy(), x.copy()
        up[2] += h
        down[2] -= h
        jac[:, 2] = (self.f(mode, up) - self.f(mode, down)) / (2.0 * h)
        return jac

    def tangent(self, mode: int, x: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
        _, _, vt = np.linalg.svd(self.full_jacobian(mode, x))
        t = vt[-1]
        if previous is not None and float(t @ previous) < 0.0:
            t = -t
        return t

    def correct(
        self, mode: int, guess: np.ndarray, normal: np.ndarray, anchor: np.ndarray
    ) -> tuple[np.ndarray, int] | None:
        """Newton on F = 0 and normal . (X - anchor) = 0."""
        x = guess.copy()
        for it in range(1, self.st.max_newton + 1):
            check_deadline(self.deadline)
            rhs = np.concatenate([self.f(mode, x), [float(normal @ (x - anchor))]])
            jac = np.vstack([self.full_jacobian(mode, x), normal])
            try:
                dx = np.linalg.solve(jac, -rhs)
            except np.linalg.LinAlgError:
                return None
            x = x + dx
            if not np.all(np.isfinite(x)):
                return None
            small = np.max(np.abs(dx)) <= self.st.newton_tol * max(1.0, float(np.max(np.abs(x))))
            if small and np.max(np.abs(self.f(mode, x))) <= 1e3 * self.st.newton_tol:
                return x, it
        return None

    def at_value(self, mode: int, guess: np.ndarray, q: float) -> tuple[np.ndarray, int] | None:
        """The point of this mode at the parameter q (Newton with q fixed)."""
        return self.correct(mode, np.array([guess[0], guess[1], q]), np.array([0.0, 0.0, 1.0]),
                            np.array([0.0, 0.0, q]))  # fmt: skip

    def on_segment(
        self, mode: int, a: np.ndarray, b: np.ndarray, theta: float
    ) -> tuple[np.ndarray, int] | None:
        """The point of the branch on the hyperplane through a + theta (b - a), normal b - a."""
        anchor = a + theta * (b - a)
        return self.correct(mode, anchor, b - a, anchor)

    def locate(
        self, mode: int, a: np.ndarray, b: np.ndarray, fn: Callable[[np.ndarray], float]
    ) -> np.ndarray | None:
        """The root of fn between the branch points a (fn < 0 or > 0) and b (other sign)."""
        from scipy.optimize import brentq

        def g(theta: float) -> float:
            hit = self.on_segment(mode, a, b, theta)
            if hit is None:
                raise ArithmeticError
            return fn(hit[0])

        try:
            fa, fb = fn(a), fn(b)
            if fa == 0.0:
                return a
            if fb == 0.0:
                return b
            theta = brentq(g, 0.0, 1.0, xtol=XTOL)
        except (ArithmeticError, ValueError):
            return None
        hit = self.on_segment(mode, a, b, theta)
        return None if hit is None else hit[0]


def _det(tracer: _Tracer, mode: int, x: np.ndarray) -> float:
    return float(np.linalg.det(jacobian(mode, x[0], x[1], tracer.params(x[2]))))


def continue_whirls(
    params: ModelParams,
    settings: WhirlSettings,
    progress: Callable[[int], None] | None = None,
    deadline: float | None = None,
) -> WhirlContinuation:
    """Every whirl of ``params`` continued in ``settings.parameter`` both ways; a start
    whirl already on an earlier branch (reached through a slip-roll point) is not traced
    again.

    The run ends by ``deadline`` (a ``time.perf_counter()`` value; default: now plus
    ``settings.max_wall_time_s``), checked at every corrector iteration: the points traced
    by then are kept, the direction under way says so in its stops, the directions not
    begun are not traced, and ``budget_exhausted`` is set."""
    check_symmetric(params)
    if settings.parameter not in PARAMETERS:
        raise WhirlError(f"whirls are continued in one of {', '.join(PARAMETERS)}")
    starts = whirls(params)
    out = WhirlContinuation(settings.parameter, settings, starts, [])
    if not starts:
        out.status = "failed"
        out.message = (f"no whirl in contact at {settings.parameter} = "
                       f"{getattr(params, settings.parameter):g}")  # fmt: skip
        return out
    if deadline is None and settings.max_wall_time_s is not None:
        deadline = time.perf_counter() + settings.max_wall_time_s
    tracer = _Tracer(params, settings, deadline)
    done = 0
    for start in starts:
        if out.budget_exhausted:
            break
        q0 = getattr(params, settings.parameter) / settings.scale
        if any(_covers(b, start, q0, tracer) for b in out.branches):
            continue
        branch = WhirlBranch(len(out.branches), start)
        halves = []
        for direction in settings.directions:
            if out.budget_exhausted:
                break
            pts, events, stop = _trace(tracer, start, direction, branch.index)
            out.budget_exhausted = stop.startswith(BUDGET_STOP)
            halves.append((direction, pts, events))
            branch.stops["up" if direction > 0 else "down"] = stop
            done += len(pts)
            if progress is not None:
                progress(done)
        first = WhirlPoint(start, getattr(params, settings.parameter), branch.index)
        ordered: list[WhirlPoint] = []
        for direction, pts, _ in halves:
            if direction < 0:
                ordered = list(reversed(pts)) + ordered
        ordered.append(first)
        for direction, pts, _ in halves:
            if direction > 0:
                ordered += pts
        branch.points = ordered
        branch.events = [e for _, _, events in halves for e in events]
        out.branches.append(branch)
    return out


def _covers(branch: WhirlBranch, whirl: Whirl, q0: float, tracer: _Tracer) -> bool:
    """Whether ``branch`` passes through ``whirl`` (same mode, same s and W at q0)."""
    pts = branch.points
    for a, b in zip(pts[:-1], pts[1:], strict=False):
        if a.whirl.mode != whirl.mode or b.whirl.mode != whirl.mode:
            continue
        qa, qb = a.value / tracer.st.scale, b.value / tracer.st.scale
        if (qa - q0) * (qb - q0) > 0.0 or qa == qb:
            continue
        t = (q0 - qa) / (qb - qa)
        s = a.whirl.s + t * (b.whirl.s - a.whirl.s)
        w = a.whirl.rate + t * (b.whirl.rate - a.whirl.rate)
        if abs(s - whirl.s) <= 1e-3 * max(1e-3, whirl.s) and abs(w - whirl.rate) <= 1e-3 * max(
            1.0, abs(whirl.rate)
        ):
            return True
    return False


def _trace(tracer: _Tracer, start: Whirl, direction: int, index: int):
    """Continue from ``start`` with the parameter moving by ``direction`` at first: the
    points, the events and why it stopped (the points traced when the budget ran out kept)."""
    points: list[WhirlPoint] = []
    events: list[WhirlEvent] = []
    try:
        stop = _walk(tracer, start, direction, index, points, events)
    except WallTimeBudgetError:
        budget = tracer.st.max_wall_time_s
        stop = BUDGET_STOP + (f" (max_wall_time_s = {budget:g})" if budget is not None else "")
    return points, events, stop


def _walk(tracer: _Tracer, start: Whirl, direction: int, index: int,
          points: list[WhirlPoint], events: list[WhirlEvent]) -> str:  # fmt: skip
    """``_trace``'s loop: appends to ``points`` and ``events``, returns why it stopped."""
    st = tracer.st
    scale = st.scale
    mode = start.mode
    x = np.array([start.s, start.rate, getattr(start.params, st.parameter) / scale])
    t = tracer.tangent(mode, x, None)
    if t[2] * direction < 0.0:
        t = -t
    step = st.step / scale
    previous = start
    lo, hi = st.p_min / scale, st.p_max / scale

    def point(x: np.ndarray, label: str = "", iterations: int = 0) -> WhirlPoint:
        return WhirlPoint(make_whirl(mode, x[0], x[1], tracer.params(x[2])), x[2] * scale,
                          index, label, iterations)  # fmt: skip

    def event(kind: str, x: np.ndarray, note: str, located: bool = True) -> WhirlPoint:
        pt = point(x, kind)
        points.append(pt)
        events.append(WhirlEvent(kind, pt.value, pt, located, note))
        return pt

    while len(points) < st.max_points:
        predicted = x + step * t
        hit = tracer.correct(mode, predicted, t, predicted)
        if hit is None:
            step *= 0.5
            if step < st.min_step / scale:
                return f"corrector failed at the minimum step near " \
                                       f"{st.parameter} = {x[2] * scale:.8g}"  # fmt: skip
            continue
        y, iterations = hit
        # the window
        if not lo <= y[2] <= hi:
            bound = hi if y[2] > hi else lo
            fixed = tracer.at_value(mode, y, bound)
            if fixed is not None and _valid(tracer, mode, fixed[0]):
                points.append(point(fixed[0], "", fixed[1]))
            return f"reached {st.parameter} = {bound * scale:g}"
        # the edges of s: contact lost, radius unbounded
        if not 0.0 < y[1 - 1] < 1.0:
            edge = 0.0 if y[0] <= 0.0 else 1.0
            root = tracer.locate(mode, x, y, lambda z, e=edge: z[0] - e) if st.locate else None
            kind, what = (GRAZING, "the whirl leaves contact (r = 1)") if edge == 0.0 else (
                INFINITY, "the whirl radius grows without bound")  # fmt: skip
            if root is not None:
                event(kind, root, what)
            return f"{what} at {st.parameter} = {y[2] * scale:.8g}"
        # the mode's own validity
        if validity(mode, y[0], y[1], tracer.params(y[2])) < 0.0:
            root = tracer.locate(
                mode, x, y, lambda z, m=mode: validity(m, z[0], z[1], tracer.params(z[2]))
            )
            if root is None:
                where = f"{st.parameter} = {y[2] * scale:.8g}"
                return f"could not locate where the {MODE_NAMES[mode]} " \
                                       f"whirl ends near {where}"  # fmt: skip
            new_mode = _other_mode(mode, root, tracer)
            new_t = tracer.tangent(new_mode, root, None)
            probe = root + 1e-6 * new_t
            if validity(new_mode, probe[0], probe[1], tracer.params(probe[2])) < 0.0:
                new_t = -new_t
            turned = (new_t[2] * t[2]) < 0.0
            kind = NONSMOOTH_FOLD if turned else SLIP_ROLL
            note = (f"{MODE_NAMES[mode]} whirl meets the {MODE_NAMES[new_mode]} whirl at "
                    f"v_r = 0, friction needed = mu: "
                    + ("the parameter turns back (both whirls born or lost here)" if turned
                       else "the branch goes on in the other mode"))  # fmt: skip
            event(kind, root, note)
            mode, x, t = new_mode, root, new_t
            previous = points[-1].whirl
            continue
        new_t = tracer.tangent(mode, y, t)
        whirl = make_whirl(mode, y[0], y[1], tracer.params(y[2]))
        # fold: the parameter turns on a smooth branch
        if st.locate and new_t[2] * t[2] < 0.0:
            root = tracer.locate(mode, x, y, lambda z, m=mode: _det(tracer, m, z))
            if root is not None:
                event(FOLD, root, "the parameter turns back on a smooth branch")
        # stability changes
        if whirl.n_unstable != previous.n_unstable and st.locate:
            kind, fn = _stability_test(previous, whirl, tracer, mode)
            root = tracer.locate(mode, x, y, fn)
            if root is not None:
                event(kind, root, f"unstable eigenvalues {previous.n_unstable} -> "
                                  f"{whirl.n_unstable}")  # fmt: skip
        points.append(WhirlPoint(whirl, y[2] * scale, index, "", iterations))
        previous, x, t = whirl, y, new_t
        if iterations <= 3:
            step = min(step * 1.5, st.max_step / scale)
        elif iterations >= 8:
            step = max(step * 0.6, st.min_step / scale)
    return f"point budget ({st.max_points}) spent"


def _valid(tracer: _Tracer, mode: int, x: np.ndarray) -> bool:
    return 0.0 < x[0] < 1.0 and validity(mode, x[0], x[1], tracer.params(x[2])) >= 0.0


def _other_mode(mode: int, x: np.ndarray, tracer: _Tracer) -> int:
    """The mode that takes over where ``mode`` ends: rolling after slip; after rolling,
    slip in the direction the needed friction points."""
    if mode != ROLLING:
        return ROLLING
    mu_eq = needed_friction(x[0], x[1], tracer.params(x[2]))
    return SLIP_POSITIVE if mu_eq > 0.0 else SLIP_NEGATIVE


def _stability_test(before: Whirl, after: Whirl, tracer: _Tracer, mode: int):
    """The kind of a change of stability and a test function for it: the real part of
    the eigenvalue that crosses (a complex pair: Hopf; a real root: through zero)."""
    crossing = after if after.n_unstable > before.n_unstable else before
    eig = crossing.nontrivial
    eig = eig[np.isfinite(eig)]
    lead = eig[np.argmax(eig.real)]
    complex_pair = abs(lead.imag) > 1e-9 * max(1.0, abs(lead))

    def fn(z: np.ndarray) -> float:
        w = make_whirl(mode, z[0], z[1], tracer.params(z[2]))
        e = w.nontrivial
        e = e[np.isfinite(e)]
        if complex_pair:
            e = e[np.abs(e.imag) > 1e-9 * max(1.0, float(np.max(np.abs(e))))]
        else:
            e = e[np.abs(e.imag) <= 1e-9 * max(1.0, float(np.max(np.abs(e))))]
        return float(np.max(e.real)) if e.size else -math.inf

    return (HOPF if complex_pair else REAL_CROSSING), fn

"""Bifurcations continued in a second parameter: curves of folds, period doublings,
Neimark-Sacker points and grazings (docs/orbits.md, "Two parameters").

A bifurcation located on a branch in ``p1`` is a solution of

    P^k(x0; p1, p2) - x0 = 0,    T(x0; p1, p2) = 0

with ``T`` its test function (``continuation.CONTINUOUS_TESTS``: ``det(Phi - I)`` for a
fold, ``det(Phi + I)`` for a period doubling, the bialternate product for a
Neimark-Sacker point, ``max z - 1`` of the free flow for a grazing). These are five
equations in the six unknowns ``Z = (x0, q1, q2)``, ``q_i = p_i / (max_i - min_i)``: a
curve in the plane of the two parameters, followed by pseudo-arclength continuation
(predictor along the null vector of the 5 x 6 Jacobian, corrector Newton with the
arclength condition). The Jacobian is ``[Phi - I, dP/dq1, dP/dq2]`` above ``grad T``:
``Phi`` from the variational equations (``analysis.orbits.periodic``), the rest by differences of
the map (central for ``dP/dq``, forward with relative step 1e-6 for ``grad T``; for a
grazing, whose ``max z`` has a kink in the start of a trajectory, ``T`` is differenced
along the family of orbits in the parameters alone).

A curve stops at either parameter's bound (the point on the bound is added), when it
closes on its start, when a Neimark-Sacker pair turns real (beyond it the test function
marks a neutral saddle, not a bifurcation), or when the corrector fails at the smallest
step; every stop is reported with its reason.
"""

from __future__ import annotations

import contextlib
import math
import numbers
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rubcli import model
from rubcli.analysis.orbits import continuation as cn
from rubcli.analysis.orbits import periodic as ob
from rubcli.model import ModelParams

# The kinds of point a curve follows (the nonsmooth folds at a grazing follow its curve).
CURVE_KINDS = (cn.FOLD, cn.FLIP, cn.NEIMARK_SACKER, cn.GRAZING)
# The closed-form curve (analysis.charts.stability) each kind lies on for synchronous orbits (k = 1)
# of the isotropic machine: the free whirl's grazing; the full annular rub's fold and its
# stability boundary.
CLOSED_FORMS = {cn.GRAZING: "free_grazing", cn.FOLD: "rub_fold",
                cn.NEIMARK_SACKER: "rub_stability"}  # fmt: skip
FD_STEP = 1e-6  # relative step of the differences of the map and the test function
STEP_TOL = 1e-9  # a Newton step this small (relative to |Z|) ends the correction
GRAZING_NEAR = 1e-2  # a curve's orbit this close to max z = 1 is said to graze
EASY_ITERATIONS = 4  # a correction in at most this many grows the step; twice as many: shrinks


@dataclass(frozen=True, kw_only=True)
class CurveSettings:
    """The plane and the steps of a curve (the [orbits] table's second parameter), by
    keyword. ``step`` is the first arclength step in fractions of the windows; the step
    stays within ``[step / 1000, 5 step]``. Checked on construction: a ValueError naming
    the field."""

    parameter: str
    p_min: float
    p_max: float
    second: str
    s_min: float
    s_max: float
    step: float = 0.02
    max_points: int = 100  # per direction
    k: int = 1
    newton_tol: float = 1e-10
    max_newton: int = 10
    rtol: float = ob.RTOL
    atol: float = ob.ATOL

    def __post_init__(self) -> None:
        problem = self._problem()
        if problem:
            raise ValueError(f"CurveSettings: {problem}")

    def _problem(self) -> str | None:
        for name in ("parameter", "second"):
            if getattr(self, name) not in ob.PARAMETERS:
                return f"{name} must be one of {', '.join(ob.PARAMETERS)}"
        if self.parameter == self.second:
            return f"parameter and second are both {self.parameter!r}"
        for name in ("p_min", "p_max", "s_min", "s_max", "step", "newton_tol", "rtol", "atol"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                return f"{name} must be a real number (got {value!r})"
            if not math.isfinite(value):
                return f"{name} must be finite (got {value!r})"
        if not (self.p_min < self.p_max and self.s_min < self.s_max):
            return "each window must have min below max"
        if not 0.0 < self.step <= 0.5:
            return f"step must lie in (0, 0.5] (got {self.step!r})"
        for name in ("max_points", "k", "max_newton"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
                return f"{name} must be an int >= 1 (got {value!r})"
        return None

    @property
    def scales(self) -> tuple[float, float]:
        return self.p_max - self.p_min, self.s_max - self.s_min


@dataclass
class CurvePoint:
    """One point of a curve: both parameter values, the orbit, its multipliers."""

    values: tuple[float, float]  # (p1, p2)
    state: np.ndarray
    multipliers: np.ndarray
    max_z: float
    contact_fraction: float
    test_value: float
    newton_iterations: int

    def to_dict(self) -> dict:
        return {
            "values": [float(v) for v in self.values],
            "state": [float(v) for v in self.state],
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "max_z": self.max_z,
            "contact_fraction": self.contact_fraction,
            "test_value": self.test_value,
        }


@dataclass
class Curve:
    """A bifurcation continued in two parameters: its points in curve order (the start
    at ``start_index``) and why each direction stopped."""

    kind: str
    names: tuple[str, str]
    start: cn.Bifurcation
    points: list[CurvePoint]
    start_index: int
    stops: dict[str, str] = field(default_factory=dict)
    status: str = "ok"
    message: str = ""
    budget_exhausted: bool = False

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "parameters": list(self.names),
            "start": {"parameter": self.start.parameter, "kind": self.start.kind},
            "status": self.status,
            "message": self.message,
            "stops": self.stops,
            "points": len(self.points),
            "start_index": self.start_index,
            "budget_exhausted": self.budget_exhausted,
        }


class _CurveError(Exception):
    """A corrector on the curve that did not converge."""


class _System:
    """H(Z) = (P^k(x0) - x0, T) and its Jacobian, in scaled unknowns Z = (x0, q1, q2)."""

    def __init__(self, params: ModelParams, kind: str, s: CurveSettings, deadline):
        self.params, self.kind, self.s, self.deadline = params, kind, s, deadline
        self.locked = model.FREE if kind == cn.GRAZING else None
        self.scales = np.array(s.scales)
        self.names = (s.parameter, s.second)

    def params_at(self, Z: np.ndarray) -> ModelParams:
        p = self.params
        for name, q, scale in zip(self.names, Z[-2:], self.scales, strict=True):
            try:
                p = ob.with_parameter(p, name, float(q * scale))
            except ob.OrbitError as exc:
                raise _CurveError(str(exc)) from None
        return p

    def flow(self, Z: np.ndarray, variational: bool) -> ob.FlowResult:
        try:
            return ob.stroboscopic_map(
                self.params_at(Z), Z[:-2], self.s.k, variational=variational, rtol=self.s.rtol,
                atol=self.s.atol, locked=self.locked, deadline=self.deadline,
            )  # fmt: skip
        except ob.OrbitError as exc:
            raise _CurveError(str(exc)) from None

    def test(self, fl: ob.FlowResult) -> float:
        if self.kind == cn.GRAZING:
            return fl.max_z - 1.0
        multipliers = ob.floquet_multipliers(fl.monodromy)
        return {
            cn.FOLD: cn.fold_test,
            cn.FLIP: cn.flip_test,
            cn.NEIMARK_SACKER: cn.neimark_sacker_test,
        }[self.kind](multipliers)

    def evaluate(self, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray, ob.FlowResult]:
        """H(Z), its (n + 1) x (n + 2) Jacobian, and the flow at Z (n states: the rotor's
        four, with a moving stator eight)."""
        n = Z.size - 2
        fl = self.flow(Z, True)
        T = self.test(fl)
        H = np.concatenate([fl.state - Z[:n], [T]])
        J = np.zeros((n + 1, n + 2))
        J[:n, :n] = fl.monodromy - np.eye(n)
        for j in (n, n + 1):  # dP/dq: central differences of the map
            h = FD_STEP * max(1.0, abs(Z[j]))
            plus, minus = Z.copy(), Z.copy()
            plus[j] += h
            minus[j] -= h
            J[:n, j] = (self.flow(plus, False).state - self.flow(minus, False).state) / (2 * h)
        if self.kind == cn.GRAZING:
            # max z of a trajectory has a kink in its start (any start off a circular orbit
            # reaches farther): T is differenced along the orbit family instead, the orbit
            # at each shifted parameter from one Newton step (exact for the linear free flow)
            step_matrix = fl.monodromy - np.eye(n)
            for j in (n, n + 1):
                h = FD_STEP * max(1.0, abs(Z[j]))
                shifted = Z.copy()
                shifted[j] += h
                shifted[:n] -= np.linalg.solve(step_matrix, self.flow(shifted, False).state - Z[:n])
                J[n, j] = (self.test(self.flow(shifted, False)) - T) / h
            return H, J, fl
        for j in range(n + 2):  # grad T: forward differences
            h = FD_STEP * max(1.0, abs(Z[j]))
            shifted = Z.copy()
            shifted[j] += h
            J[n, j] = (self.test(self.flow(shifted, True)) - T) / h
        return H, J, fl

    def point(self, Z: np.ndarray, fl: ob.FlowResult, H: np.ndarray, iterations: int) -> CurvePoint:
        multipliers = ob.floquet_multipliers(fl.monodromy)
        values = (float(Z[-2] * self.scales[0]), float(Z[-1] * self.scales[1]))
        return CurvePoint(values, Z[:-2].copy(), multipliers, fl.max_z, fl.contact_fraction,
                          float(H[-1]), iterations)  # fmt: skip

    def correct(
        self, Z_pred: np.ndarray, normal: np.ndarray
    ) -> tuple[np.ndarray, CurvePoint, np.ndarray]:
        """Newton on H = 0, normal . (Z - Z_pred) = 0: (Z, point, Jacobian at Z)."""
        Z = Z_pred.copy()
        step = math.inf
        for it in range(self.s.max_newton + 1):
            H, J, fl = self.evaluate(Z)
            small = float(np.max(np.abs(H[:-1]))) <= self.s.newton_tol * ob.residual_scale(Z[:-2])
            if small and step <= STEP_TOL * max(1.0, float(np.linalg.norm(Z))):
                return Z, self.point(Z, fl, H, it), J
            if it == self.s.max_newton:
                break
            A = np.vstack([J, normal])
            rhs = np.concatenate([-H, [-float(normal @ (Z - Z_pred))]])
            try:
                dZ = np.linalg.solve(A, rhs)
            except np.linalg.LinAlgError:
                raise _CurveError("singular Jacobian of the curve's system") from None
            Z = Z + dZ
            step = float(np.linalg.norm(dZ))
        raise _CurveError(f"no convergence in {self.s.max_newton} iterations")


def _tangent(J: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    t = np.linalg.svd(J)[2][-1]
    if previous is not None and float(t @ previous) < 0.0:
        t = -t
    return t


def continue_curve(
    params: ModelParams,
    start: cn.Bifurcation,
    settings: CurveSettings,
    deadline: float | None = None,
    progress: Callable[[int], None] | None = None,
) -> Curve:
    """Continue the located bifurcation ``start`` (of a branch in ``settings.parameter``,
    with every other parameter as in ``params``) in the plane of ``settings.parameter`` and
    ``settings.second``, both ways from it. ``deadline``: a ``time.perf_counter()`` value
    past which the curve stops with what it has (``ob.WallTimeBudgetError`` is not raised).
    ``progress(n)``: points so far."""
    s = settings
    names = (s.parameter, s.second)
    curve = Curve(start.kind, names, start, [], 0)
    if start.kind not in CURVE_KINDS:
        curve.status, curve.message = "failed", f"a {start.kind} point is not continued"
        return curve
    system = _System(params, start.kind, s, deadline)
    scales = np.array(s.scales)
    p2 = float(getattr(params, s.second))
    Z0 = np.concatenate([start.point.state, [start.parameter / scales[0], p2 / scales[1]]])
    fixed_second = np.zeros(6)
    fixed_second[5] = 1.0
    try:
        Z0, first, J0 = system.correct(Z0, fixed_second)
    except _CurveError as exc:
        curve.status, curve.message = "failed", f"the starting point: {exc}"
        return curve
    except ob.WallTimeBudgetError:
        curve.status, curve.message = "failed", "the starting point: wall-time budget exhausted"
        curve.budget_exhausted = True
        return curve
    arms = {}
    done = [1]
    t0 = _tangent(J0, None)
    for direction, name in ((1, "forward"), (-1, "backward")):
        arm: list[CurvePoint] = []
        try:
            reason = _one_way(system, Z0, direction * t0, arm, done, progress)
        except ob.WallTimeBudgetError:
            reason = "wall-time budget exhausted"
            curve.budget_exhausted = True
        arms[direction] = arm
        curve.stops[name] = reason
    curve.points = [*reversed(arms[-1]), first, *arms[1]]
    curve.start_index = len(arms[-1])
    return curve


def _one_way(system: _System, Z0, t0, out: list, done: list, progress) -> str:
    s = system.s
    ds = s.step
    ds_min, ds_max = s.step / 1000.0, 5.0 * s.step
    lower = np.array([s.p_min, s.s_min]) / system.scales
    upper = np.array([s.p_max, s.s_max]) / system.scales
    Z, t = Z0, t0
    while True:
        if len(out) >= s.max_points:
            return f"point budget used ({s.max_points} points)"
        try:
            Z_new, pt, J = system.correct(Z + ds * t, t)
        except _CurveError as exc:
            if ds / 2.0 < ds_min:
                return _stalled(system, Z, out[-1] if out else None, exc)
            ds /= 2.0
            continue
        q = Z_new[-2:]
        outside = np.flatnonzero((q < lower) | (q > upper))
        if outside.size:
            return _to_bound(system, Z, Z_new, int(outside[0]), lower, upper, out)
        if system.kind == cn.NEIMARK_SACKER and cn._unit_pair(pt.multipliers) is None:
            return "the critical pair turned real (a neutral saddle beyond, not a bifurcation)"
        out.append(pt)
        done[0] += 1
        if progress is not None:
            progress(done[0])
        if len(out) > 3 and np.linalg.norm(Z_new - Z0) < 0.5 * ds:
            return "closed: the curve came back to its start"
        if pt.newton_iterations <= EASY_ITERATIONS:
            ds = min(ds * 1.5, ds_max)
        elif pt.newton_iterations > 2 * EASY_ITERATIONS:
            ds = max(ds * 0.6, ds_min)
        Z, t = Z_new, _tangent(J, t)


def _stalled(system: _System, Z: np.ndarray, last: CurvePoint | None, exc) -> str:
    """Why a curve stops where the corrector fails at the smallest step: where, and the
    orbit's distance from the stator's edge when it is near (a curve of a rub's fold or
    stability boundary ends where that orbit grazes)."""
    where = ", ".join(f"{n} = {q * sc:.6g}" for n, q, sc in
                      zip(system.names, Z[-2:], system.scales, strict=True))  # fmt: skip
    text = f"no point beyond {where} at the minimum step"
    if last is not None and abs(last.max_z - 1.0) < GRAZING_NEAR:
        text += f" (max z = {last.max_z:.6g}: the orbit grazes the stator there)"
    return f"{text}; last correction: {exc}"


def _to_bound(system: _System, Z_a, Z_b, i: int, lower, upper, out: list) -> str:
    """The point where parameter ``i`` reaches its bound between Z_a and Z_b (appended if
    found), and the reason the curve stops."""
    at = Z_a.size - 2 + i  # the parameter's entry
    q_a, q_b = Z_a[at], Z_b[at]
    bound = lower[i] if q_b < lower[i] else upper[i]
    which = "lower" if bound == lower[i] else "upper"
    theta = (bound - q_a) / (q_b - q_a)
    guess = Z_a + theta * (Z_b - Z_a)
    guess[at] = bound
    normal = np.zeros(Z_a.size)
    normal[at] = 1.0
    with contextlib.suppress(_CurveError):  # without it the curve ends at its last point
        out.append(system.correct(guess, normal)[1])
    name = system.names[i]
    return f"reached the {which} bound {name} = {bound * system.scales[i]:.6g}"


def continue_curves(
    params: ModelParams,
    branch: cn.Branch,
    settings: CurveSettings,
    deadline: float | None = None,
    progress: Callable[[int], None] | None = None,
) -> list[Curve]:
    """Every located fold, period doubling, Neimark-Sacker point and grazing of
    ``branch`` (a nonsmooth fold at a grazing follows that grazing's curve; a point found
    twice is continued once) continued in ``settings.second``."""
    starts: list[cn.Bifurcation] = []
    for bif in branch.bifurcations:
        if bif.kind not in CURVE_KINDS or not bif.located or bif.nonsmooth:
            continue
        scale = max(1.0, abs(bif.parameter))
        if any(b.kind == bif.kind and abs(b.parameter - bif.parameter) <= 1e-9 * scale
               for b in starts):  # fmt: skip
            continue
        starts.append(bif)
    curves: list[Curve] = []
    for bif in starts:
        on = _on_curve(bif, float(getattr(params, settings.second)), curves, settings)
        if on is not None:
            curve = Curve(bif.kind, (settings.parameter, settings.second), bif, [], 0)
            curve.status = "same curve"
            curve.message = f"lies on the curve continued from {on.start.parameter:.10g}"
        elif deadline is not None and time.perf_counter() > deadline:
            curve = Curve(bif.kind, (settings.parameter, settings.second), bif, [], 0)
            curve.status, curve.message = "failed", "wall-time budget exhausted"
            curve.budget_exhausted = True
        else:
            curve = continue_curve(params, bif, settings, deadline, progress)
        curves.append(curve)
    return curves


def _on_curve(bif: cn.Bifurcation, second: float, curves: list[Curve], s: CurveSettings):
    """The curve already continued that passes through ``bif`` (at ``second``), or None:
    one of the same kind with a segment between two of its points within a tenth of that
    segment's length of it (in fractions of the windows: the chord's distance from the
    curve it cuts is far smaller where the steps follow the curve)."""
    scales = np.array(s.scales)
    here = np.array([bif.parameter, second]) / scales
    for curve in curves:
        if curve.kind != bif.kind or len(curve.points) < 2:
            continue
        path = np.array([pt.values for pt in curve.points]) / scales
        for a, b in zip(path[:-1], path[1:], strict=True):
            if _segment_distance(here, a, b) <= 0.1 * float(np.linalg.norm(b - a)):
                return curve
    return None


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    t = 0.0 if not d.any() else float(np.clip((p - a) @ d / (d @ d), 0.0, 1.0))
    return float(np.linalg.norm(p - a - t * d))

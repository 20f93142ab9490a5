"""Pseudo-arclength continuation of periodic orbits and bifurcation detection (docs/orbits.md).

Unknowns ``X = (x0, q)``: the state on the section and the continued parameter scaled as
``q = p / scale`` (``scale`` the width of the parameter window, so a step weighs state and
parameter alike). A branch point solves ``G(x0, p) = P^k(x0; p) - x0 = 0`` and the
pseudo-arclength condition ``t . (X - X_pred) = 0`` by Newton with the bordered Jacobian
``[[Phi - I, dP/dq], [t^T]]``; ``Phi`` comes from the variational equations through every
switch (``rubcli.analysis.orbits.periodic``), ``dP/dq`` from central differences of the map. Steps
grow after easy corrections and halve after failed ones, within ``[min_step, max_step]``.

Between two consecutive points the test functions are compared:

- fold (a multiplier through +1): ``det(Phi - I) = prod(lambda - 1)`` changes sign;
- period doubling (through -1): ``det(Phi + I)`` changes sign;
- Neimark-Sacker (a complex pair through the unit circle): the bialternate product
  ``prod_{i<j} (lambda_i lambda_j - 1)`` changes sign and the pair at the located point is
  complex (a real pair with product 1 is a neutral saddle, not reported);
- grazing: ``max z - 1`` changes sign (the orbit touches the stator from inside), or the
  number of contact phases per period changes (a phase shrinks to zero length);
- stick onset: the time spent rolling without slip becomes positive (or zero).

Each detected point is located on the segment between its two neighbours (a corrected
point on the hyperplane through ``X_a + theta (X_b - X_a)`` orthogonal to ``X_b - X_a``):
by Brent's method on the continuous test functions, by bisection on the counts.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rubcli import model
from rubcli.analysis.orbits import periodic as ob
from rubcli.analysis.orbits.bounds import MIN_ORBIT_STEP_FRACTION
from rubcli.model import ModelParams

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

FOLD, FLIP, NEIMARK_SACKER, GRAZING, STICK_ONSET = (
    "fold",
    "period_doubling",
    "neimark_sacker",
    "grazing",
    "stick_onset",
)
KINDS = (FOLD, FLIP, NEIMARK_SACKER, GRAZING, STICK_ONSET)
# A located Neimark-Sacker pair must be this far from the real axis (else: neutral saddle).
COMPLEX_PAIR_TOL = 1e-6
# Bisection on a count stops at this fraction of the segment.
BISECTION_TOL = 1e-7
# A bifurcation bracketed this tightly (relative, in the parameter) counts as located.
LOCATED_WIDTH = 1e-6
# The smallest Brent tolerance on the segment fraction of a located bifurcation: a few
# doubles of the fraction (its relative tolerance is 1e-14 anyway).
MIN_LOCATE_XTOL = 1e-15
# Step halvings of the damped Newton corrector.
MAX_HALVINGS = 4
# The parameter offsets (scaled, relative) tried past a corner of the branch.
CORNER_FIRST_OFFSET = 1e-6
CORNER_LAST_OFFSET = 1e-3
# Only a branch whose last orbit is this close to grazing (|max z - 1|) is tried past a
# corner; elsewhere a corrector failing at the smallest step ends the direction at once.
CORNER_BAND = 0.05


@dataclass(frozen=True, kw_only=True)
class ContinuationSettings:
    """What to continue and how (the [orbits] table, nondimensional), by keyword::

        ContinuationSettings(parameter="mu", p_min=0.0, p_max=0.06, step=0.002)

    ``min_step`` defaults to step / 1000 and ``max_step`` to 5 step, as in a case file.
    Every field is checked on construction as the [orbits] key it stands for
    (``orbits.orbits_setting``: ``k`` is ``period``, ``p_min``/``p_max`` ``min``/``max``
    in the parameter's domain): a TypeError or ValueError naming it."""

    parameter: str
    p_min: float
    p_max: float
    step: float  # first step, parameter units
    min_step: float | None = None
    max_step: float | None = None
    max_points: int = 200  # per direction
    directions: tuple[int, ...] = (1, -1)
    k: int = 1
    newton_tol: float = 1e-10
    max_newton: int = 10
    rtol: float = ob.RTOL
    atol: float = ob.ATOL
    locate: bool = True
    locate_xtol: float = 1e-12  # Brent tolerance on the segment fraction
    max_wall_time_s: float | None = None  # the run's wall-time budget (None: [orbits]'s, 3600 s)

    def __post_init__(self) -> None:
        owner = "ContinuationSettings"
        if not isinstance(self.parameter, str) or self.parameter not in ob.PARAMETERS:
            raise ValueError(
                f"{owner}: parameter {self.parameter!r} is not one of {', '.join(ob.PARAMETERS)}"
            )
        for name in ("p_min", "p_max"):
            value = model.real_number(owner, name, getattr(self, name))
            why = model.parameter_problem(self.parameter, value)
            if why:
                raise ValueError(f"{owner}: {name}: {self.parameter} {why} (got {value!r})")
            object.__setattr__(self, name, value)
        if not self.p_min < self.p_max:
            raise ValueError(
                f"{owner}: p_min must be below p_max (got {self.p_min!r} >= {self.p_max!r})"
            )
        step = ob.orbits_setting(owner, "step", self.step, "step")
        if self.min_step is None:
            object.__setattr__(self, "min_step", step / 1000.0)
        if self.max_step is None:
            object.__setattr__(self, "max_step", 5.0 * step)
        keys = {"step": "step", "min_step": "min_step", "max_step": "max_step",
                "max_points": "max_points", "k": "period", "newton_tol": "newton_tol",
                "max_newton": "max_newton", "rtol": "rtol", "atol": "atol"}  # fmt: skip
        for name, key in keys.items():
            integer = name in ("max_points", "k", "max_newton")
            value = ob.orbits_setting(owner, name, getattr(self, name), key, integer)
            object.__setattr__(self, name, value)
        budget = ob.orbits_budget(owner, self.max_wall_time_s)
        object.__setattr__(self, "max_wall_time_s", budget)
        self._check_steps(owner)
        if (
            not isinstance(self.directions, tuple | list)
            or not self.directions
            or any(isinstance(d, bool) or d not in (1, -1) for d in self.directions)
        ):
            raise ValueError(f"{owner}: directions must hold 1 and/or -1 (got {self.directions!r})")
        object.__setattr__(self, "directions", tuple(int(d) for d in self.directions))
        if not isinstance(self.locate, bool):
            raise TypeError(
                f"{owner}: locate must be True or False, got {type(self.locate).__name__}"
            )
        xtol = model.real_number(owner, "locate_xtol", self.locate_xtol)
        if not (math.isfinite(xtol) and MIN_LOCATE_XTOL <= xtol < 1.0):
            raise ValueError(
                f"{owner}: locate_xtol must satisfy {MIN_LOCATE_XTOL:g} <= locate_xtol < 1 "
                f"(a fraction of the segment; got {xtol!r})"
            )
        object.__setattr__(self, "locate_xtol", xtol)

    def _check_steps(self, owner: str) -> None:
        """The steps against the window, as [orbits]: ``min_step <= step <= max_step``,
        ``step`` within the window, ``min_step`` a resolvable fraction of it."""
        width = self.p_max - self.p_min
        if not self.min_step <= self.step <= self.max_step:
            raise ValueError(
                f"{owner}: steps must satisfy 0 < min_step <= step <= max_step (got "
                f"{self.min_step!r}, {self.step!r}, {self.max_step!r})"
            )
        if self.step > width:
            raise ValueError(
                f"{owner}: step {self.step!r} is wider than the window p_max - p_min = {width:g}"
            )
        if self.min_step < MIN_ORBIT_STEP_FRACTION * width:
            raise ValueError(
                f"{owner}: min_step {self.min_step:g} is below {MIN_ORBIT_STEP_FRACTION:g} of "
                f"the window p_max - p_min = {width:g}: so small a step does not move the "
                "parameter by a resolvable amount"
            )

    @property
    def scale(self) -> float:
        return self.p_max - self.p_min


@dataclass
class BranchPoint:
    """One periodic orbit on the branch."""

    parameter: float
    state: np.ndarray
    k: int
    multipliers: np.ndarray
    max_z: float
    min_z: float
    contact_fraction: float
    stick_fraction: float
    contact_phases: int
    newton_iterations: int
    label: str = ""  # a bifurcation kind for located points
    monodromy: np.ndarray | None = field(default=None, repr=False)

    @property
    def stable(self) -> bool:
        return bool(np.max(np.abs(self.multipliers)) < 1.0)

    @property
    def n_unstable(self) -> int:
        return int(np.sum(np.abs(self.multipliers) > 1.0))

    def to_dict(self) -> dict:
        return {
            "parameter": self.parameter,
            "state": [float(v) for v in self.state],
            "k": self.k,
            "max_z": self.max_z,
            "min_z": self.min_z,
            "contact_fraction": self.contact_fraction,
            "stick_fraction": self.stick_fraction,
            "contact_phases": self.contact_phases,
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "multiplier_moduli": [float(abs(m)) for m in self.multipliers],
            "stable": self.stable,
            "label": self.label,
        }


@dataclass
class Bifurcation:
    """A detected (and, if ``located``, located) bifurcation between two branch points."""

    kind: str
    point: BranchPoint
    between: tuple[int, int]  # indices of the neighbours in Branch.points
    located: bool
    test_value: float
    note: str = ""
    nonsmooth: bool = False  # at a grazing point, where Phi jumps (not a smooth crossing)

    @property
    def parameter(self) -> float:
        return self.point.parameter

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "parameter": self.parameter,
            "located": self.located,
            "test_value": self.test_value,
            "between_points": list(self.between),
            "note": self.note,
            "nonsmooth": self.nonsmooth,
            "point": self.point.to_dict(),
        }


@dataclass
class Branch:
    """A continued branch: points in branch order, bifurcations, why each direction stopped."""

    parameter: str
    settings: ContinuationSettings
    points: list[BranchPoint]
    bifurcations: list[Bifurcation]
    stops: dict[str, str]  # direction ("forward"/"backward") -> reason
    start_index: int
    status: str = "ok"  # "ok" or "failed" (no starting orbit)
    message: str = ""
    budget_exhausted: bool = False  # the wall-time budget cut the run short

    def rows(self) -> list[BranchPoint]:
        """Branch points with the located bifurcation points inserted in branch order."""
        extra: dict[int, list[BranchPoint]] = {}
        for bif in self.bifurcations:
            if bif.located:
                extra.setdefault(bif.between[0], []).append(bif.point)
        rows: list[BranchPoint] = []
        for i, pt in enumerate(self.points):
            rows.append(pt)
            inserted = extra.get(i, [])
            if inserted and i + 1 < len(self.points):
                up = self.points[i + 1].parameter >= pt.parameter
                inserted = sorted(inserted, key=lambda q: q.parameter, reverse=not up)
            rows.extend(inserted)
        return rows

    def to_dict(self) -> dict:
        return {
            "parameter": self.parameter,
            "status": self.status,
            "message": self.message,
            "n_points": len(self.points),
            "start_index": self.start_index,
            "stops": self.stops,
            "wall_time_budget_exhausted": self.budget_exhausted,
            "bifurcations": [b.to_dict() for b in self.bifurcations],
        }


# ----------------------------------------------------------------- test functions


def fold_test(multipliers: np.ndarray) -> float:
    """det(Phi - I) from the multipliers."""
    return float(np.real(np.prod(multipliers - 1.0)))


def flip_test(multipliers: np.ndarray) -> float:
    """det(Phi + I) from the multipliers."""
    return float(np.real(np.prod(multipliers + 1.0)))


def neimark_sacker_test(multipliers: np.ndarray) -> float:
    """prod_{i<j} (lambda_i lambda_j - 1): the bialternate-product test function."""
    lam = np.asarray(multipliers)
    out = 1.0 + 0j
    for i in range(lam.size):
        for j in range(i + 1, lam.size):
            out *= lam[i] * lam[j] - 1.0
    return float(out.real)


def grazing_test(point: BranchPoint) -> float:
    """max z - 1: negative while the orbit stays inside the clearance."""
    return point.max_z - 1.0


CONTINUOUS_TESTS: dict[str, Callable[[BranchPoint], float]] = {
    FOLD: lambda pt: fold_test(pt.multipliers),
    FLIP: lambda pt: flip_test(pt.multipliers),
    NEIMARK_SACKER: lambda pt: neimark_sacker_test(pt.multipliers),
    GRAZING: grazing_test,
}


def _has_stick(point: BranchPoint) -> bool:
    return point.stick_fraction > 0.0


# ------------------------------------------------------------------- the corrector


class CorrectorError(Exception):
    """A corrector (Newton on the branch) that did not converge."""


def _deflated(G: np.ndarray, X: np.ndarray, avoid: np.ndarray | None) -> float:
    """The residual Newton reduces: max |G|, deflated away from ``avoid`` (``correct``)."""
    res = float(np.max(np.abs(G)))
    if avoid is None:
        return res
    d = X[:-1] - avoid
    return res * (1.0 + 1.0 / max(float(d @ d), 1e-300))


class _Problem:
    """G(X) and its Jacobian for one parameter, in scaled coordinates X = (x0, q)."""

    def __init__(
        self,
        params: ModelParams,
        settings: ContinuationSettings,
        locked: int | None = None,
        deadline: float | None = None,
    ):
        self.params = params
        self.s = settings
        self.locked = locked  # a regime to integrate in without switches (grazing location)
        self.deadline = deadline  # time.perf_counter() past which WallTimeBudgetError
        self.evaluations = 0
        self.last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def params_at(self, q: float) -> ModelParams:
        return ob.with_parameter(self.params, self.s.parameter, q * self.s.scale)

    def evaluate(
        self, X: np.ndarray, derivative: bool = True
    ) -> tuple[ob.FlowResult, np.ndarray, np.ndarray | None]:
        """(flow result, G, dP/dq or None) at X."""
        p = self.params_at(X[-1])
        fl = ob.stroboscopic_map(
            p, X[:-1], self.s.k, rtol=self.s.rtol, atol=self.s.atol, locked=self.locked,
            deadline=self.deadline,
        )  # fmt: skip
        self.evaluations += 1
        dPdq = self.derivative(X) if derivative else None
        return fl, fl.state - X[:-1], dPdq

    def derivative(self, X: np.ndarray) -> np.ndarray:
        """dP/dq at X by central differences of the map; one-sided where one side lies
        outside the model's domain (at mu = 0, the bound of a window starting there)."""
        q = X[-1]
        h = 1e-6 * max(1.0, abs(q))
        sides = []
        for step in (h, -h):
            try:
                sides.append((q + step, self.params_at(q + step)))
            except ob.OrbitError:
                sides.append((q, self.params_at(q)))
        (q_plus, p_plus), (q_minus, p_minus) = sides
        plus, minus = (
            ob.stroboscopic_map(
                p, X[:-1], self.s.k, variational=False, rtol=self.s.rtol, atol=self.s.atol,
                locked=self.locked, deadline=self.deadline,
            ).state
            for p in (p_plus, p_minus)
        )  # fmt: skip
        return (plus - minus) / (q_plus - q_minus)

    def point(self, X: np.ndarray, fl: ob.FlowResult, iterations: int) -> BranchPoint:
        return BranchPoint(
            parameter=float(X[-1] * self.s.scale),
            state=X[:-1].copy(),
            k=self.s.k,
            multipliers=ob.floquet_multipliers(fl.monodromy),
            max_z=fl.max_z,
            min_z=fl.min_z,
            contact_fraction=fl.contact_fraction,
            stick_fraction=fl.stick_fraction,
            contact_phases=fl.contact_phases,
            newton_iterations=iterations,
            monodromy=fl.monodromy,
        )

    def correct(
        self, X_pred: np.ndarray, normal: np.ndarray, avoid: np.ndarray | None = None
    ) -> tuple[np.ndarray, BranchPoint]:
        """Newton on G = 0, normal . (X - X_pred) = 0 from X_pred.

        A step that does not reduce the residual is halved (up to ``MAX_HALVINGS`` times):
        the map is only piecewise smooth where an orbit grazes, and full Newton steps can
        cycle across the kink there. ``avoid``: a known orbit (state) that Newton must not
        return to: deflation, Newton on ``(1 + 1/|x - avoid|^2) G`` (P. E. Farrell, A.
        Birkisson, S. W. Funke, SIAM J. Sci. Comput. 37 (2015) A2026), which keeps the
        other roots and removes that one; where the deflated iteration stalls (the orbit
        sought lies past a kink of the map), plain Newton goes on from where it stopped.
        """
        X = X_pred.copy()
        fl, G = self._residual(X)
        dPdq = self._dPdq(X)
        for it in range(self.s.max_newton + 1):
            if float(np.max(np.abs(G))) <= self.s.newton_tol * ob.residual_scale(X[:-1]):
                self.last = (X.copy(), fl.monodromy, dPdq)  # reused by tangent()
                return X, self.point(X, fl, it)
            if it == self.s.max_newton:
                break
            n = X.size - 1  # the state's size: the rotor's four, with a moving stator eight
            A = np.zeros((n + 1, n + 1))
            A[:n, :n] = fl.monodromy - np.eye(n)
            A[:n, n] = dPdq
            A[n] = normal
            rhs = np.concatenate([-G, [-float(normal @ (X - X_pred))]])
            if avoid is not None:
                d = X[:n] - avoid
                dd = max(float(d @ d), 1e-300)
                m = 1.0 + 1.0 / dd
                A[:n] *= m
                A[:n, :n] += np.outer(G, -2.0 * d / dd**2)
                rhs[:n] *= m
            try:
                dX = np.linalg.solve(A, rhs)
            except np.linalg.LinAlgError:
                raise CorrectorError("singular bordered Jacobian") from None
            res = _deflated(G, X, avoid)
            lam = 1.0
            for halving in range(MAX_HALVINGS + 1):
                X_new = X + lam * dX
                fl_new, G_new = self._residual(X_new)
                if _deflated(G_new, X_new, avoid) < res or halving == MAX_HALVINGS:
                    break
                lam /= 2.0
            X, fl, G = X_new, fl_new, G_new
            dPdq = self._dPdq(X)
        if avoid is not None:  # deflation brought X near another root: plain Newton there
            return self.correct(X, normal)
        res = float(np.max(np.abs(G)))
        raise CorrectorError(f"no convergence in {self.s.max_newton} iterations ({res:.3g})")

    def _residual(self, X: np.ndarray):
        try:
            fl, G, _ = self.evaluate(X, derivative=False)
        except ob.OrbitError as exc:
            raise CorrectorError(str(exc)) from None
        if not np.all(np.isfinite(G)):
            raise CorrectorError("non-finite residual")
        return fl, G

    def _dPdq(self, X: np.ndarray) -> np.ndarray:
        try:
            return self.derivative(X)
        except ob.OrbitError as exc:
            raise CorrectorError(str(exc)) from None

    def tangent(self, X: np.ndarray, previous: np.ndarray | None, direction: int) -> np.ndarray:
        """Unit tangent of the branch at a solution X, oriented along ``previous``/direction."""
        last = self.last
        if last is not None and np.array_equal(last[0], X):
            monodromy, dPdq = last[1], last[2]
        else:
            fl, _, dPdq = self.evaluate(X)
            monodromy = fl.monodromy
        n = X.size - 1
        J = np.zeros((n, n + 1))
        J[:, :n] = monodromy - np.eye(n)
        J[:, n] = dPdq
        t = np.linalg.svd(J)[2][-1]
        if previous is not None:
            sign = np.sign(t @ previous)
        else:
            sign = np.sign(t[-1]) * direction if t[-1] != 0.0 else direction
        return t * (sign if sign != 0.0 else 1.0)


# --------------------------------------------------------------------- continuation


def deadline_of(settings: ContinuationSettings, start: float | None = None) -> float:
    """The ``time.perf_counter()`` at which ``settings.max_wall_time_s`` runs out, counted
    from ``start`` (default: now)."""
    return (time.perf_counter() if start is None else start) + settings.max_wall_time_s


def continue_branch(
    params: ModelParams,
    start_state: ArrayLike,
    settings: ContinuationSettings,
    progress: Callable[[int], None] | None = None,
    deadline: float | None = None,
) -> Branch:
    """Continue the periodic orbit through ``start_state`` in ``settings.parameter``.

    ``params`` holds the starting value of the parameter, which must lie within the bounds.
    A starting orbit that cannot be found gives a Branch with status "failed" and the
    reason; a direction that stops early keeps its points and says why in ``stops``.
    ``progress(n)`` is called with the number of points computed so far.

    The run ends by ``deadline`` (a ``time.perf_counter()`` value; default: now plus
    ``settings.max_wall_time_s``): what is computed by then is kept, the direction under
    way stops with the reason, bifurcations not yet located are reported unlocated, and
    ``budget_exhausted`` is set.

    A TypeError or ValueError names a bad argument: ``params`` not a ModelParams, its
    value of the parameter outside ``[p_min, p_max]``, ``start_state`` not the section's
    state (``orbits.section_state``), ``settings`` not a ContinuationSettings, ``progress``
    neither callable nor None.
    """
    owner = "continue_branch()"
    start_state = ob.section_state(owner, "start_state", start_state, params)
    if not isinstance(settings, ContinuationSettings):
        raise TypeError(
            f"{owner}: settings must be a ContinuationSettings (made by keyword), got "
            f"{type(settings).__name__}"
        )
    if progress is not None and not callable(progress):
        raise TypeError(
            f"{owner}: progress must be a callable of the points so far (or None), got "
            f"{type(progress).__name__}"
        )
    s = settings
    value = getattr(params, s.parameter)
    if not s.p_min <= value <= s.p_max:
        raise ValueError(
            f"{owner}: params.{s.parameter} = {value!r} lies outside the window [p_min, "
            f"p_max] = [{s.p_min!r}, {s.p_max!r}]: the start must lie in it"
        )
    deadline = ob.check_deadline_value(owner, deadline)
    if deadline is None:
        deadline = deadline_of(s)
    prob = _Problem(params, s, deadline=deadline)
    p0 = float(getattr(params, s.parameter))
    budget = f"wall-time budget exhausted (max_wall_time_s = {s.max_wall_time_s:g})"
    try:
        orbit = ob.shoot(
            params, start_state, s.k, tol=s.newton_tol, max_iter=s.max_newton,
            rtol=s.rtol, atol=s.atol, deadline=deadline, max_wall_time_s=s.max_wall_time_s,
        )  # fmt: skip
    except ob.NewtonError as exc:
        return Branch(s.parameter, s, [], [], {}, 0, "failed", f"no starting orbit: {exc}")
    except ob.WallTimeBudgetError:
        return Branch(s.parameter, s, [], [], {}, 0, "failed", f"no starting orbit: {budget}",
                      budget_exhausted=True)  # fmt: skip
    X0 = np.concatenate([orbit.state, [p0 / s.scale]])
    first = prob.point(X0, orbit.flow, orbit.newton_iterations)
    done = [1]
    arms: dict[int, list[tuple[np.ndarray, BranchPoint]]] = {}
    stops: dict[str, str] = {}
    exhausted = False
    for direction in s.directions:
        name = "forward" if direction > 0 else "backward"
        arm: list[tuple[np.ndarray, BranchPoint]] = []
        try:
            reason = _one_direction(prob, (X0, first), direction, done, progress, arm)
        except ob.WallTimeBudgetError:
            reason, exhausted = budget, True
        arms[direction] = arm
        stops[name] = reason
    backward = arms.get(-1, [])
    forward = arms.get(1, [])
    ordered = [*reversed(backward), (X0, first), *forward]
    Xs = [X for X, _ in ordered]
    points = [pt for _, pt in ordered]
    try:
        bifurcations = detect(prob, Xs, points, locate=s.locate)
    except ob.WallTimeBudgetError:
        exhausted = True
        bifurcations = detect(prob, Xs, points, locate=False)
        for bif in bifurcations:
            bif.note = f"not located: {budget}"
    return Branch(s.parameter, s, points, bifurcations, stops, len(backward),
                  budget_exhausted=exhausted)  # fmt: skip


def _one_direction(prob: _Problem, start, direction, done, progress, out) -> str:
    """Continue from ``start`` (X0, its point) in ``direction``, appending (X, point) to
    ``out``; returns why it stopped (WallTimeBudgetError passes through, ``out`` keeping
    the points so far)."""
    X0, first = start
    s = prob.s
    ds = s.step / s.scale
    ds_min, ds_max = s.min_step / s.scale, s.max_step / s.scale
    q_min, q_max = s.p_min / s.scale, s.p_max / s.scale
    X = X0
    try:
        t = prob.tangent(X, None, direction)
    except ob.OrbitError as exc:
        return f"tangent failed at the start: {exc}"
    while True:
        if len(out) >= s.max_points:
            return f"point budget used ({s.max_points} points)"
        X_pred = X + ds * t
        try:
            X_new, pt = prob.correct(X_pred, t)
        except CorrectorError as exc:
            if ds / 2.0 >= ds_min:
                ds /= 2.0
                continue
            last = out[-1][1] if out else first
            near = abs(last.max_z - 1.0) < CORNER_BAND  # a corner lies at a grazing
            crossed = _cross_corner(prob, X, last, t) if near else None
            if crossed is None:
                return f"corrector failed at the minimum step: {exc}"
            X_new, pt = crossed
            t = _away_from_corner(prob, X, last, X_new, pt, ds_min)
            ds = s.step / s.scale
        q = X_new[-1]
        if q > q_max or q < q_min:
            bound = q_max if q > q_max else q_min
            end = _at_bound(prob, X, X_new, bound)
            if end is not None:
                out.append(end)
                done[0] += 1
                if progress:
                    progress(done[0])
            which = "upper" if bound == q_max else "lower"
            return f"reached the {which} bound {s.parameter} = {bound * s.scale:.6g}"
        try:
            t_new = prob.tangent(X_new, t, direction)
        except ob.OrbitError as exc:
            out.append((X_new, pt))
            return f"tangent failed: {exc}"
        out.append((X_new, pt))
        done[0] += 1
        if progress:
            progress(done[0])
        if pt.newton_iterations <= 2:
            ds = min(ds * 1.5, ds_max)
        elif pt.newton_iterations >= 5:
            ds = max(ds * 0.6, ds_min)
        X, t = X_new, t_new


def _cross_corner(prob: _Problem, X, last: BranchPoint, t):
    """The branch past a corner, where the tangent of one smooth piece leads nowhere.

    Where an orbit grazes the stator (or a contact phase appears or vanishes), the map is
    only piecewise smooth: the branch on the other side may leave at a sharp angle (a stiff
    stator saturates the amplitude) or turn back (a nonsmooth fold), and the predictor
    along the old tangent finds nothing however short the step. Here orbits are corrected
    at fixed parameter offsets ``h`` past the last point, onward and back, over a doubling
    ladder from ``CORNER_FIRST_OFFSET`` to ``CORNER_LAST_OFFSET`` (relative, scaled).
    Newton starts from the last state, from the orbit of the other side's flow extended
    smoothly (free flight leaving contact, contact locked in slip entering it) and, where
    it returns to the last piece, deflated away from that orbit. The first that lies on
    another piece (the other side of ``max z = 1``, or another number of contact phases)
    and within ``sqrt(h)`` of the last point (a branch leaves a grazing like a square root
    at most: a farther orbit is another branch) is returned with its point, or None.
    """
    onward = 1.0 if t[-1] >= 0.0 else -1.0
    normal = np.zeros(X.size)
    normal[-1] = 1.0
    # the smooth extensions of the flows on the other side: leaving contact, the free
    # flow; entering it, the contact flow locked in slip either way (a full rub's orbit)
    locked = (model.FREE,) if last.max_z > 1.0 else (model.SLIP_POSITIVE, model.SLIP_NEGATIVE)
    extensions = [_Problem(prob.params, prob.s, locked=r, deadline=prob.deadline) for r in locked]
    unit = max(1.0, abs(X[-1]))
    h = CORNER_FIRST_OFFSET * unit
    while h <= CORNER_LAST_OFFSET * unit:
        for side in (onward, -onward):
            guess = X.copy()
            guess[-1] = X[-1] + side * h
            same = None  # the orbit of the last piece at this value, once found
            for way in ("direct", *extensions, "deflated"):
                try:
                    if way == "direct":
                        X_new, pt = prob.correct(guess, normal)
                    elif way != "deflated":  # from the orbit of a smooth extension
                        X_new, pt = prob.correct(way.correct(guess, normal)[0], normal)
                    elif same is not None:
                        X_new, pt = prob.correct(guess, normal, avoid=same[:-1])
                    else:
                        continue
                except CorrectorError:
                    continue
                other_piece = (pt.max_z - 1.0) * (last.max_z - 1.0) < 0.0 or (
                    pt.contact_phases != last.contact_phases
                )
                if not other_piece:
                    same = X_new
                elif np.linalg.norm(X_new - X) <= math.sqrt(h):
                    return X_new, pt
        h *= 2.0
    return None


def _away_from_corner(prob: _Problem, X, last: BranchPoint, X_new, pt: BranchPoint, ds: float):
    """The direction along the new piece that leaves the corner: past a grazing, the one
    in which ``|max z - 1|`` grows (a probe step of ``ds``; a probe that finds no orbit
    points into the corner); elsewhere, the one along the chord from the last point."""
    chord = (X_new - X) / float(np.linalg.norm(X_new - X))
    t = prob.tangent(X_new, chord, 1)
    if (pt.max_z - 1.0) * (last.max_z - 1.0) >= 0.0:
        return t
    try:
        _, probe = prob.correct(X_new + ds * t, t)
    except CorrectorError:
        return -t
    return t if abs(probe.max_z - 1.0) > abs(pt.max_z - 1.0) else -t


def _at_bound(prob: _Problem, X_a, X_b, bound: float):
    """The branch point with q = bound between X_a and X_b (Newton with q fixed), or None."""
    if abs(bound - X_a[-1]) <= 1e-12 * max(1.0, abs(bound)):
        return None  # the last point is on the bound already
    theta = (bound - X_a[-1]) / (X_b[-1] - X_a[-1])
    guess = X_a + theta * (X_b - X_a)
    normal = np.zeros(X_a.size)
    normal[-1] = 1.0
    guess[-1] = bound
    try:
        return prob.correct(guess, normal)
    except CorrectorError:
        return None


# -------------------------------------------------------------------- detection


def detect(
    prob: _Problem, Xs: list[np.ndarray], points: list[BranchPoint], locate: bool = True
) -> list[Bifurcation]:
    """Bifurcations between consecutive points, each located if ``locate``.

    Where the orbit grazes between two points, ``Phi`` jumps (the flow on one side has no
    contact phase): a sign change of the fold or flip test function in that segment is a
    nonsmooth (discontinuous) bifurcation at the grazing point, reported there.
    """
    found: list[Bifurcation] = []
    for i in range(len(points) - 1):
        a, b = points[i], points[i + 1]
        graze = None
        if (a.max_z - 1.0) * (b.max_z - 1.0) < 0.0:
            graze = _locate_grazing(prob, Xs, points, i, locate)
        elif a.contact_phases != b.contact_phases:
            graze = _locate_count(prob, Xs, points, i, GRAZING, _phases, locate)
        if graze is not None:
            found.append(graze)
        for kind in (FOLD, FLIP, NEIMARK_SACKER):
            test = CONTINUOUS_TESTS[kind]
            ta, tb = test(a), test(b)
            if ta == 0.0 or tb == 0.0 or (ta > 0.0) == (tb > 0.0):
                continue
            if kind == NEIMARK_SACKER and a.n_unstable == b.n_unstable:
                continue  # no pair crossed the circle: a neutral saddle or a jump of Phi
            if graze is not None:
                note = (
                    f"at the grazing point: Phi jumps there and {a.n_unstable} -> "
                    f"{b.n_unstable} multipliers lie outside the unit circle (nonsmooth {kind})"
                )
                found.append(Bifurcation(kind, _labelled(graze.point, kind), (i, i + 1),
                                         graze.located, test(graze.point), note,
                                         nonsmooth=True))  # fmt: skip
                continue
            found.extend(_locate_continuous(prob, Xs, points, i, kind, test, locate))
        if _has_stick(a) != _has_stick(b):
            found.append(_locate_count(prob, Xs, points, i, STICK_ONSET, _has_stick, locate))
    return found


def _locate_grazing(prob: _Problem, Xs, points, i, locate) -> Bifurcation:
    """Grazing between points i and i+1 (one of them free), located on the smooth side.

    The free orbit is continued with contact switched off (its smooth extension:
    ``locked`` free flow, corrected at fixed parameter values), and the root of its
    ``max z - 1`` in the parameter is where it touches the stator: Brent's method, on a
    bracket widened past the other point where the branch turns back at the corner (a
    nonsmooth fold: both points on one side of the grazing value). The orbit found there
    is on both pieces (the contact force vanishes at z = 1). The bracket grows from the
    free point in the direction in which the free orbit's max z grows. Newton on the switching map
    itself cycles near a grazing orbit; if the smooth side cannot be corrected, bisection
    on "touches or not" along the segment is used instead.
    """
    if not locate:
        return _locate_continuous(prob, Xs, points, i, GRAZING, grazing_test, False)[0]
    between = (i, i + 1)
    free = i if points[i].max_z < 1.0 else i + 1
    other = 2 * i + 1 - free
    side = _Problem(prob.params, prob.s, locked=model.FREE, deadline=prob.deadline)
    normal = np.zeros(Xs[free].size)
    normal[-1] = 1.0
    cache: dict[float, BranchPoint] = {}

    def g(q: float) -> float:
        if q not in cache:
            guess = Xs[free].copy()
            guess[-1] = q
            cache[q] = side.correct(guess, normal)[1]
        return grazing_test(cache[q])

    q_free, q_other = float(Xs[free][-1]), float(Xs[other][-1])
    try:
        g_free = g(q_free)
        span = q_other - q_free
        if span == 0.0:
            span = CORNER_FIRST_OFFSET * max(1.0, abs(q_free))
        if g(q_free + span) < g_free:  # max z of the free orbit grows the other way
            span = -span
        far = q_free + span
        for _ in range(20):  # widen past the other point (a corner that turns back)
            if (g(far) > 0.0) != (g_free > 0.0):
                break
            span *= 2.0
            far = q_free + span
        else:
            raise CorrectorError("no parameter value with max z > 1 on the smooth side")
        from scipy.optimize import brentq

        xtol = prob.s.locate_xtol * max(1.0, abs(q_free))
        q = brentq(g, min(q_free, far), max(q_free, far), xtol=xtol, rtol=1e-14, maxiter=80)
    except (CorrectorError, ValueError, RuntimeError) as exc:
        return _locate_count(prob, Xs, points, i, GRAZING, _touches, locate, f"{exc}; ")
    return Bifurcation(GRAZING, _labelled(cache[q], GRAZING), between, True, g(q))


def _touches(point: BranchPoint) -> bool:
    return point.max_z > 1.0


def _phases(point: BranchPoint) -> int:
    return point.contact_phases


def _on_segment(prob: _Problem, Xa, Xb, theta: float) -> BranchPoint:
    d = Xb - Xa
    X_pred = Xa + theta * d
    _, pt = prob.correct(X_pred, d / float(np.linalg.norm(d)))
    return pt


def _locate_continuous(prob, Xs, points, i, kind, test, locate, cache=None) -> list[Bifurcation]:
    """Brent's method on ``test`` along the segment i -> i+1 (``cache``: known ends)."""
    cache = dict(cache) if cache is not None else {0.0: points[i], 1.0: points[i + 1]}
    a, b = cache[0.0], cache[1.0]
    between = (i, i + 1)
    if not locate or (test(a) > 0.0) == (test(b) > 0.0):
        mid = a if abs(test(a)) < abs(test(b)) else b
        note = "" if not locate else "no sign change of the test function on the smooth side"
        return [Bifurcation(kind, _labelled(mid, kind), between, False, test(mid), note)]

    def g(theta: float) -> float:
        if theta not in cache:
            cache[theta] = _on_segment(prob, Xs[i], Xs[i + 1], theta)
        return test(cache[theta])

    try:
        from scipy.optimize import brentq

        theta = brentq(g, 0.0, 1.0, xtol=prob.s.locate_xtol, rtol=1e-14, maxiter=60)
    except (CorrectorError, ValueError, RuntimeError) as exc:
        # the corrector fails close to a nonsmooth point (a corner of the branch at a
        # grazing): keep the tightest bracket found and report its better end
        lo, hi = _bracket(cache, test, test(a))
        pl, ph = cache[lo], cache[hi]
        best = pl if abs(test(pl)) <= abs(test(ph)) else ph
        width = abs(ph.parameter - pl.parameter)
        note = f"bracketed to {width:.2g} in {prob.s.parameter} (corrector: {exc})"
        located = width <= LOCATED_WIDTH * max(1.0, abs(best.parameter))
        return [Bifurcation(kind, _labelled(best, kind), between, located, test(best), note)]
    pt = cache[theta]
    note = ""
    if kind == NEIMARK_SACKER:
        pair = _unit_pair(pt.multipliers)
        if pair is None:
            return []  # a neutral saddle (real pair with product 1), not a bifurcation
        note = f"critical pair {pair.real:.6g} +- {abs(pair.imag):.6g}i"
        note += f", angle {math.degrees(abs(math.atan2(pair.imag, pair.real))):.4g} deg"
    elif kind in (FOLD, FLIP) and a.n_unstable == b.n_unstable:
        note = "test function changes sign without a change of stability (a jump of Phi)"
    return [Bifurcation(kind, _labelled(pt, kind), between, True, test(pt), note)]


def _bracket(cache: dict[float, BranchPoint], test, value_a: float) -> tuple[float, float]:
    """The tightest [lo, hi] among evaluated fractions with the sign change inside."""
    side_a = [t for t, pt in cache.items() if (test(pt) > 0.0) == (value_a > 0.0)]
    lo = max(side_a)
    hi = min(t for t, pt in cache.items() if t > lo and (test(pt) > 0.0) != (value_a > 0.0))
    return lo, hi


def _unit_pair(multipliers: np.ndarray) -> complex | None:
    """The complex multiplier nearest the unit circle, if it is truly complex."""
    lam = np.asarray(multipliers)
    complex_ones = lam[np.abs(lam.imag) > COMPLEX_PAIR_TOL]
    if complex_ones.size == 0:
        return None
    return complex(complex_ones[np.argmin(np.abs(np.abs(complex_ones) - 1.0))])


def _locate_count(prob, Xs, points, i, kind, predicate, locate, why="") -> Bifurcation:
    a, b = points[i], points[i + 1]
    between = (i, i + 1)
    if not locate:
        return Bifurcation(kind, _labelled(b, kind), between, False, 0.0)
    lo, hi, pa = 0.0, 1.0, predicate(a)
    best = b
    try:
        while hi - lo > BISECTION_TOL:
            mid = 0.5 * (lo + hi)
            pt = _on_segment(prob, Xs[i], Xs[i + 1], mid)
            if predicate(pt) == pa:
                lo = mid
            else:
                hi, best = mid, pt
    except CorrectorError as exc:
        note = f"{why}not located: {exc}"
        return Bifurcation(kind, _labelled(best, kind), between, False, 0.0, note)
    note = f"{why}located by bisection to {BISECTION_TOL:g} of the segment"
    return Bifurcation(kind, _labelled(best, kind), between, True, 0.0, note)


def _labelled(point: BranchPoint, kind: str) -> BranchPoint:
    out = BranchPoint(**{**point.__dict__})
    out.label = kind
    return out

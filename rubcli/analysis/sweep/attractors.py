"""Attractor recognition for independent starts: learn the attractors, then stop early.

A basin grid integrates every start for its whole budget although most starts reach a
known attractor long before. Here a start is stopped as soon as its trajectory is
recognised on an attractor already learned, and the attractor and the time are recorded.

**Method** (matching in the stroboscopic section, in the spirit of Attractors.jl's
``AttractorsViaRecurrences``, with the cell grid replaced by the distance to learned
points). The section is the state at the end of every forcing period, normalised as
``(x, y, vx / eta, vy / eta)`` (clearances; a synchronous orbit of radius r has velocity
eta r, so both halves weigh alike). An attractor is *learned* from a trajectory that ran
to its budget: the cloud of its last section points. Its *radius* is the larger of the
user's ``tolerance`` and the largest nearest-neighbour distance within the cloud, so a
closed curve (a torus, the dry whip) sampled by finitely many points is covered between
its samples, while a fixed point or a period-p orbit keeps the tolerance. A trajectory is
*recognised* on attractor A when ``consecutive`` successive section points each lie
within A's radius of A's cloud; its convergence time is the first period of that run.
A state beyond ``escape_radius`` is recognised at once as divergence.

**Failure modes**, and what is done about them:

- an attractor not learned yet: nothing matches, the trajectory runs to its budget and
  the caller learns the attractor from its tail (``AttractorSet.learn``), so it is known
  to every later start;
- a long chaotic transient: it runs to the budget and is reported *not recognised*
  (``UNRECOGNISED``) with the periods integrated, never guessed;
- a transient that shadows a learned attractor for ``consecutive`` periods and then
  leaves it is mislabelled: raise ``consecutive`` (the cost grows by as many periods);
- two attractors closer than a radius are one for this method: lower ``tolerance``.

Nothing here imports the case loader; the solver is called through ``rubcli.solvers``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

UNRECOGNISED = -1  # ran to its budget without being recognised
DIVERGED = -2  # left the escape radius
FAILED = -3  # the solver failed
SAME_ATTRACTOR_SHARE = 0.9  # a learned cloud this much inside a known attractor is that one
PERIODIC_MAX = 32  # at most this many distinct section clusters make a periodic orbit


def normalised(states: np.ndarray, eta: float) -> np.ndarray:
    """Section states ``(n, 4)`` as ``(x, y, vx / eta, vy / eta)``."""
    out = np.array(states, dtype=float, ndmin=2)
    out[:, 2:] /= eta
    return out


def _nearest(cloud: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance of every point to the nearest point of ``cloud`` (brute force, in blocks)."""
    out = np.empty(len(points))
    for i in range(0, len(points), 256):
        block = points[i : i + 256]
        d2 = ((block[:, None, :] - cloud[None, :, :]) ** 2).sum(axis=-1)
        out[i : i + 256] = np.sqrt(d2.min(axis=1))
    return out


def clusters(cloud: np.ndarray, tolerance: float) -> list[np.ndarray]:
    """The cloud split greedily into groups of points within ``tolerance`` of a seed."""
    left = np.arange(len(cloud))
    groups = []
    while left.size:
        seed = cloud[left[0]]
        near = np.linalg.norm(cloud[left] - seed, axis=1) <= tolerance
        groups.append(cloud[left[near]])
        left = left[~near]
    return groups


def describe(cloud: np.ndarray, tolerance: float) -> dict:
    """Descriptors of a learned attractor: its kind, period, radial range and centre.

    A cloud that falls into at most ``PERIODIC_MAX`` groups, each within the tolerance,
    is a period-p orbit of the stroboscopic map (p groups; p = 1 a fixed point);
    otherwise it fills a curve or a set (a torus, the dry whip, a chaotic set), which the
    section alone does not tell apart.
    """
    z = np.hypot(cloud[:, 0], cloud[:, 1])
    groups = clusters(cloud, tolerance)
    periodic = len(groups) <= PERIODIC_MAX and len(groups) < len(cloud)
    return {
        "kind": (
            "fixed point"
            if periodic and len(groups) == 1
            else f"period-{len(groups)} orbit"
            if periodic
            else "torus or chaotic set"
        ),
        "period": len(groups) if periodic else 0,
        "z_min": float(z.min()),
        "z_max": float(z.max()),
        "x_mean": float(cloud[:, 0].mean()),
        "y_mean": float(cloud[:, 1].mean()),
        "points": int(len(cloud)),
    }


@dataclass
class Attractor:
    """A learned attractor: its label, section cloud (normalised), radius, descriptors."""

    label: int
    cloud: np.ndarray
    radius: float
    descriptor: dict

    def contains(self, points: np.ndarray) -> np.ndarray:
        return _nearest(self.cloud, points) <= self.radius


@dataclass
class AttractorSet:
    """The attractors learned so far, and the recognition settings."""

    tolerance: float = 1e-2
    consecutive: int = 10
    escape_radius: float = 1e3
    attractors: list[Attractor] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance) and self.tolerance > 0):
            raise ValueError(f"tolerance must be finite and > 0 (got {self.tolerance!r})")
        if int(self.consecutive) != self.consecutive or self.consecutive < 1:
            raise ValueError(f"consecutive must be an integer >= 1 (got {self.consecutive!r})")
        if not (math.isfinite(self.escape_radius) and self.escape_radius > 0):
            raise ValueError(f"escape_radius must be finite and > 0 (got {self.escape_radius!r})")

    def match(self, point: np.ndarray) -> int | None:
        """The label of the learned attractor ``point`` lies on (the nearest), or None."""
        best, best_gap = None, math.inf
        for attractor in self.attractors:
            gap = float(_nearest(attractor.cloud, point[None, :])[0]) / attractor.radius
            if gap <= 1.0 and gap < best_gap:
                best, best_gap = attractor.label, gap
        return best

    def learn(self, cloud: np.ndarray) -> int:
        """The label of the attractor whose tail ``cloud`` is (normalised section points):
        a known one if at least ``SAME_ATTRACTOR_SHARE`` of the cloud lies on it, else a
        new one, learned from this cloud."""
        cloud = np.asarray(cloud, dtype=float)
        for attractor in self.attractors:
            if attractor.contains(cloud).mean() >= SAME_ATTRACTOR_SHARE:
                return attractor.label
        radius = self.tolerance
        if len(cloud) > 1:
            d = np.sqrt(((cloud[:, None, :] - cloud[None, :, :]) ** 2).sum(axis=-1))
            np.fill_diagonal(d, np.inf)
            radius = max(radius, float(d.min(axis=1).max()))
        label = len(self.attractors)
        self.attractors.append(Attractor(label, cloud, radius, describe(cloud, self.tolerance)))
        return label


@dataclass
class Recogniser:
    """Feeds section points one period at a time; says when a run of ``consecutive``
    points on one attractor is complete."""

    attractors: AttractorSet
    label: int | None = None
    run: int = 0
    run_start: int = 0  # the period (1-based) of the run's first point

    def feed(self, point: np.ndarray, period: int) -> int | None:
        """The recognised label once the run is long enough, else None."""
        if not np.all(np.isfinite(point)) or np.linalg.norm(point) > self.attractors.escape_radius:
            self.label, self.run_start = DIVERGED, period
            return DIVERGED
        label = self.attractors.match(point)
        if label is None:
            self.label, self.run = None, 0
            return None
        if label != self.label:
            self.label, self.run, self.run_start = label, 0, period
        self.run += 1
        return label if self.run >= self.attractors.consecutive else None


@dataclass
class StartResult:
    """Where one start went: the attractor (or a code), when, and at what cost."""

    label: int  # an attractor's label, or UNRECOGNISED, DIVERGED, FAILED
    recognised: bool  # stopped early on a learned attractor (or divergence)
    convergence_period: int  # first period of the recognising run (0 if none)
    periods: int  # forcing periods integrated
    final_state: tuple[float, float, float, float]
    tail: np.ndarray  # the last section points (normalised), to learn from
    message: str = ""


def run_start(
    params,
    start,
    attractors: AttractorSet,
    *,
    budget_periods: int,
    method: str,
    options: dict,
    check_every: int = 10,
    tail_periods: int = 100,
) -> StartResult:
    """Integrate from ``start`` in blocks of ``check_every`` periods until recognised or
    ``budget_periods`` are spent; the tail (last ``tail_periods`` section points) is kept
    for learning when the budget is spent."""
    from rubcli.problem import Problem
    from rubcli.solvers import solve

    recogniser = Recogniser(attractors)
    state = tuple(float(v) for v in start)
    done = 0
    tail: list[np.ndarray] = []
    while done < budget_periods:
        n = min(check_every, budget_periods - done)
        sol = solve(
            Problem.from_periods(params, state, n, 1, name="basin-start"), method, **options
        )
        if not sol.success:
            return StartResult(FAILED, False, 0, done, state, np.empty((0, 4)), sol.message)
        section = normalised(np.asarray(sol.states)[1:], params.eta)
        for k, point in enumerate(section):
            label = recogniser.feed(point, done + k + 1)
            if label is not None:
                final = tuple(float(v) for v in np.asarray(sol.states)[k + 1])
                return StartResult(
                    label, True, recogniser.run_start, done + k + 1, final,  # type: ignore[arg-type]
                    section[: k + 1],
                )  # fmt: skip
        tail.append(section)
        state = tuple(float(v) for v in np.asarray(sol.states)[-1])
        done += n
    cloud = np.concatenate(tail)[-tail_periods:] if tail else np.empty((0, 4))
    return StartResult(UNRECOGNISED, False, 0, done, state, cloud)  # type: ignore[arg-type]

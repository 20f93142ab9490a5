"""Attractor recognition for independent starts: learn the attractors, then stop early.

A basin grid integrates every start for its whole budget although most starts reach a
known attractor long before. Here a start is stopped as soon as its trajectory is
recognised, and the attractor and the time are recorded (``basins`` runs the grid).

**Method** (in the spirit of Attractors.jl's ``AttractorsViaRecurrences``). The section
is the state at the end of every forcing period, normalised as ``(x, y, vx / eta,
vy / eta)`` (clearances; a synchronous orbit of radius r has velocity eta r, so both
halves weigh alike). An attractor is *learned* from a trajectory that ran to its budget:
the cloud of its last section points, once it has ``settled`` (each half of the tail
near the other). Its *radius* is the larger of the user's ``tolerance`` and the largest
nearest-neighbour gap within the cloud, so a closed curve (a torus, the dry whip) sampled
by finitely many points is covered between its samples, while a fixed point or a
period-p orbit keeps the tolerance. A trajectory is *recognised* on attractor A when
``consecutive`` successive section points each lie within A's radius of A's cloud (its
convergence time is the first period of that run), or, with a ``CellMap``, when
``basin_hits`` successive points fall into *basin cells* that earlier trajectories
crossed on their way to A. A state beyond ``escape_radius`` has diverged.
``recognise_kernel.scan`` is the compiled form of ``Recogniser.feed_block``.

The failure modes are listed in docs/sweeps.md ("Basins at full resolution").
Nothing here imports the case loader or a solver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

UNRECOGNISED = -1  # ran to its budget without being recognised
DIVERGED = -2  # left the escape radius
FAILED = -3  # the solver failed
SAME_ATTRACTOR_SHARE = 0.75  # a learned cloud this much near a known attractor is that one
# A new tail within this many radii of a known cloud is that attractor sampled again: a
# torus or a chaotic set sampled by a hundred points leaves gaps a new sampling falls in.
SAME_FACTOR = 3.0
PERIODIC_MAX = 32  # at most this many distinct section clusters make a periodic orbit


@dataclass(frozen=True)
class Recognition:
    """The settings of attractor recognition (``[sweep.recognition]``)."""

    tolerance: float = 0.01  # distance in the normalised section that counts as "on"
    consecutive: int = 10  # periods in a row on a learned attractor
    basin_cell: float = 0.05  # side of a basin cell (0: no basin cells)
    basin_hits: int = 3  # periods in a row in cells of one attractor
    check_every: int = 5  # periods between looks at a trajectory
    seed_points: int = 64  # starts run to the budget first, to learn from
    escape_radius: float = 1e3  # a section point beyond this has diverged

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def normalised(states: np.ndarray, eta: float) -> np.ndarray:
    """Section states ``(n, 4)`` as ``(x, y, vx / eta, vy / eta)``."""
    out = np.array(states, dtype=float, ndmin=2)
    out[:, 2:] /= eta
    return out


def nearest(cloud: np.ndarray, points: np.ndarray) -> np.ndarray:
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
        return nearest(self.cloud, points) <= self.radius


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
        return self.match_block(np.asarray(point, dtype=float)[None, :])[0]

    def match_block(self, points: np.ndarray) -> list[int | None]:
        """``match`` for every row of ``points`` (one array operation per attractor)."""
        best = [None] * len(points)
        best_gap = np.full(len(points), np.inf)
        for attractor in self.attractors:
            gap = nearest(attractor.cloud, points) / attractor.radius
            better = (gap <= 1.0) & (gap < best_gap)
            best_gap = np.where(better, gap, best_gap)
            for i in np.flatnonzero(better).tolist():
                best[i] = attractor.label
        return best

    def learn(self, cloud: np.ndarray) -> int:
        """The label of the attractor whose tail ``cloud`` is (normalised section points):
        a known one if at least ``SAME_ATTRACTOR_SHARE`` of the cloud lies within
        ``SAME_FACTOR`` radii of it, else a new one, learned from this cloud (check
        ``settled`` first: a tail still in its transient is no attractor)."""
        cloud = np.asarray(cloud, dtype=float)
        for attractor in self.attractors:
            near = nearest(attractor.cloud, cloud) <= SAME_FACTOR * attractor.radius
            if near.mean() >= SAME_ATTRACTOR_SHARE:
                return attractor.label
        label = len(self.attractors)
        radius = cloud_radius(cloud, self.tolerance)
        self.attractors.append(Attractor(label, cloud, radius, describe(cloud, self.tolerance)))
        return label

    def settled(self, cloud: np.ndarray) -> bool:
        """Whether a tail has settled on its attractor: each half of it lies (a share of
        ``SAME_ATTRACTOR_SHARE``) within ``SAME_FACTOR`` radii of the other half. A tail
        that drifts (a transient from a partial rub into dry whip, a slow spiral) is not."""
        cloud = np.asarray(cloud, dtype=float)
        if len(cloud) < 4:
            return True
        first, second = cloud[: len(cloud) // 2], cloud[len(cloud) // 2 :]
        for a, b in ((first, second), (second, first)):
            reach = SAME_FACTOR * cloud_radius(a, self.tolerance)
            if (nearest(a, b) <= reach).mean() < SAME_ATTRACTOR_SHARE:
                return False
        return True


def cloud_radius(cloud: np.ndarray, tolerance: float) -> float:
    """The tolerance, or the largest nearest-neighbour gap within the cloud if larger."""
    if len(cloud) < 2:
        return tolerance
    d = np.sqrt(((cloud[:, None, :] - cloud[None, :, :]) ** 2).sum(axis=-1))
    np.fill_diagonal(d, np.inf)
    return max(tolerance, float(d.min(axis=1).max()))


AMBIGUOUS = -1  # a cell visited on the way to two different attractors
CELL_BITS = 15  # bits per cell index in a packed key (4 x 15 bits in an int64)
MAX_CELLS = 2_000_000  # cells kept at most (about 28 MB); later cells are not added


@dataclass
class CellMap:
    """Basin cells: cells of the normalised stroboscopic section (a grid of side
    ``size``) that trajectories visited on their way to a learned attractor, each with
    that attractor's label (``AMBIGUOUS`` when visited on the way to two) and the periods
    that were left, from the cell, to the attractor. Keys are the four cell indices
    packed into an int64, sorted."""

    size: float
    keys: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    labels: np.ndarray = field(default_factory=lambda: np.empty(0, np.int16))
    remaining: np.ndarray = field(default_factory=lambda: np.empty(0, np.int32))

    def pack(self, points: np.ndarray) -> np.ndarray:
        """Each point's cell key; -1 for a point outside the packable range."""
        half = 1 << (CELL_BITS - 1)
        with np.errstate(invalid="ignore", over="ignore"):
            index = np.floor(np.asarray(points, dtype=float) / self.size) + half
        valid = np.all(np.isfinite(index) & (index >= 0) & (index < 2 * half), axis=1)
        index = np.where(valid[:, None], index, 0).astype(np.int64)
        keys = index[:, 0]
        for j in range(1, 4):
            keys = (keys << CELL_BITS) | index[:, j]
        return np.where(valid, keys, -1)

    def lookup(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each point's cell label (AMBIGUOUS when none is known) and periods left."""
        keys = self.pack(points)
        if self.keys.size == 0:
            return np.full(len(keys), AMBIGUOUS, np.int16), np.zeros(len(keys), np.int32)
        at = np.clip(np.searchsorted(self.keys, keys), 0, self.keys.size - 1)
        hit = (self.keys[at] == keys) & (keys >= 0)
        return np.where(hit, self.labels[at], AMBIGUOUS), np.where(hit, self.remaining[at], 0)

    def merged(self, keys: np.ndarray, labels: np.ndarray, remaining: np.ndarray) -> CellMap:
        """This map with new visits (in order: an earlier visit's periods left are kept;
        a cell reached on the way to two attractors becomes AMBIGUOUS for good)."""
        room = max(0, MAX_CELLS - self.keys.size)
        keep = keys >= 0
        keys, labels, remaining = keys[keep], labels[keep], remaining[keep]
        if keys.size == 0:
            return self
        all_keys = np.concatenate([self.keys, keys])
        all_labels = np.concatenate([self.labels, labels.astype(np.int16)])
        all_left = np.concatenate([self.remaining, remaining.astype(np.int32)])
        order = np.argsort(all_keys, kind="stable")  # known cells first, then visit order
        k, lab, left = all_keys[order], all_labels[order], all_left[order]
        first = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
        lo = np.minimum.reduceat(lab, first)
        hi = np.maximum.reduceat(lab, first)
        new_keys = k[first]
        is_new = ~np.isin(new_keys, self.keys, assume_unique=True)
        if is_new.sum() > room:  # keep the known cells and the first new ones by key
            allowed = np.flatnonzero(is_new)[room:]
            is_kept = np.ones(new_keys.size, bool)
            is_kept[allowed] = False
        else:
            is_kept = np.ones(new_keys.size, bool)
        agree = lo == hi  # an ambiguous cell foretells no time either
        return CellMap(
            self.size,
            new_keys[is_kept],
            np.where(agree, lo, AMBIGUOUS).astype(np.int16)[is_kept],
            np.where(agree, left[first], 0).astype(np.int32)[is_kept],
        )


@dataclass
class Recogniser:
    """Feeds section points in blocks; says when a start is recognised: ``consecutive``
    points in a row on one learned attractor, or (with ``cells``) ``basin_hits`` points
    in a row in basin cells of one attractor."""

    attractors: AttractorSet
    cells: CellMap | None = None
    basin_hits: int = 3
    label: int | None = None
    run: int = 0
    run_start: int = 0  # the period (1-based) of the run's first point
    basin_label: int = AMBIGUOUS
    basin_run: int = 0
    basin_eta: int = 0  # the convergence period the basin run's first cell foretells
    how: str = ""  # "attractor", "basin" or "diverged" once recognised
    convergence: int = 0  # the period the start reached its attractor (foretold by a cell)

    def feed(self, point: np.ndarray, period: int) -> int | None:
        """The recognised label once the run is long enough, else None."""
        found = self.feed_block(np.asarray(point, dtype=float)[None, :], period)
        return None if found is None else found[0]

    def feed_block(self, points: np.ndarray, first_period: int) -> tuple[int, int] | None:
        """Feed consecutive section points (the first at period ``first_period``); at the
        first that completes a recognition, ``(label, its index in points)``."""
        escape = self.attractors.escape_radius
        finite = np.all(np.isfinite(points), axis=1)
        clean = np.where(finite[:, None], points, 0.0)
        labels = self.attractors.match_block(clean)
        norms = np.linalg.norm(clean, axis=1)
        if self.cells is not None:
            cell_labels, cell_left = self.cells.lookup(clean)
        for i, label in enumerate(labels):
            period = first_period + i
            if not finite[i] or norms[i] > escape:
                self.label, self.run_start = DIVERGED, period
                self.how, self.convergence = "diverged", period
                return DIVERGED, i
            if label is None:
                self.label, self.run = None, 0
            else:
                if label != self.label:
                    self.label, self.run, self.run_start = label, 0, period
                self.run += 1
                if self.run >= self.attractors.consecutive:
                    self.how, self.convergence = "attractor", self.run_start
                    return label, i
            if self.cells is None:
                continue
            cell = int(cell_labels[i])
            if cell == AMBIGUOUS:
                self.basin_label, self.basin_run = AMBIGUOUS, 0
                continue
            if cell != self.basin_label:
                self.basin_label, self.basin_run = cell, 0
                self.basin_eta = period + int(cell_left[i])
            self.basin_run += 1
            if self.basin_run >= self.basin_hits:
                self.how, self.convergence = "basin", self.basin_eta
                return cell, i
        return None

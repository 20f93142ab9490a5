"""One machine as data: a linear structure, unbalances, contact stations and a speed.

    M v' + (C + Omega G) v + K q = f_static + f_unbalance(t) + sum_s W_s F_s

(``docs/composed-machine.md``). Every field is checked once, here, on construction: a TypeError or
ValueError naming the owner and the field. The system built from a machine
(``rubcli.system``) trusts it.

- ``Structure``: the matrices ``M`` (symmetric positive definite), ``C``, ``K``, ``G``
  (any; ``G`` is scaled by the spin speed), a static force, and ``dof_per_node`` (the
  coordinates per node, a node's lateral ``x, y`` first: ROSS's order); optionally a
  ``SpeedTable``: bearings' and seals' coefficients that change with the speed, added to
  ``K`` and ``C`` on their coordinates at the current speed; and ``node_xy``, each node's
  ``x, y`` where nodes differ in their coordinates (a ROSS support node has 3).
- ``Unbalance`` at a pair of coordinates: ``m e (Omega^2 cos p + Omega' sin p)`` on the
  first, ``m e (Omega^2 sin p - Omega' cos p)`` on the second, ``p = phase + integral
  Omega``.
- ``Station``: a rotor point (a coordinate pair) and a stator, rigid (``stator = None``,
  its centre at ``offset``) or a coordinate pair of the structure (then ``offset`` is the
  rest offset of the pair); its ``clearance``, contact law, friction coefficient and the
  rotor's surface ``radius`` there (the slip ``v_r = radius Omega + d' . t``).
- ``Speed``: the spin speed ``Omega`` as knots ``(t, Omega)`` of a piecewise-linear
  profile (one knot: a constant speed), held before the first and after the last knot.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rubcli.machine.contact import ContactLaw
from rubcli.model import MAX_MAGNITUDE, real_number

# A structure is kept dense (its inverse mass matrix too): beyond this many coordinates
# its matrices take more memory than a run should (8 n^2 bytes each); reduce the model.
MAX_COORDINATES = 2000
# M must be symmetric to this relative tolerance (it is then symmetrised).
SYMMETRY_RTOL = 1e-9


def _kind(value: object) -> str:
    return type(value).__name__


def _finite(owner: str, name: str, value: object) -> float:
    number = real_number(owner, name, value)
    if not (math.isfinite(number) and abs(number) <= MAX_MAGNITUDE):
        raise ValueError(f"{owner}: {name} must be finite (got {number!r})")
    return number


def _index(owner: str, name: str, value: object, size: int) -> int:
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{owner}: {name} must be an int, got {_kind(value)}")
    if not 0 <= value < size:
        raise ValueError(f"{owner}: {name} = {value} is not a coordinate (0 to {size - 1})")
    return int(value)


def _pair(owner: str, name: str, value: object) -> tuple[float, float]:
    if isinstance(value, str | bytes | dict) or not isinstance(value, Sequence | np.ndarray):
        raise TypeError(f"{owner}: {name} must be a pair [x, y] of numbers, got {_kind(value)}")
    if len(value) != 2:
        raise ValueError(f"{owner}: {name} must hold 2 numbers, got {len(value)}")
    return (_finite(owner, f"{name}[0]", value[0]), _finite(owner, f"{name}[1]", value[1]))


def _matrix(owner: str, name: str, value: object, n: int | None) -> np.ndarray:
    """``value`` as a finite float (n, n) matrix (n None: any square size)."""
    try:
        if isinstance(value, str | bytes | dict):
            raise TypeError
        matrix = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{owner}: {name} must be a square matrix of numbers") from None
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
        raise ValueError(f"{owner}: {name} must be a square matrix (got shape {matrix.shape})")
    if n is not None and matrix.shape != (n, n):
        raise ValueError(f"{owner}: {name} must be {n} x {n} as M (got shape {matrix.shape})")
    if not np.all(np.isfinite(matrix)) or np.max(np.abs(matrix), initial=0.0) > MAX_MAGNITUDE:
        raise ValueError(f"{owner}: {name} must be finite (it holds nan, inf or a huge entry)")
    return matrix


@dataclass(frozen=True, eq=False)
class SpeedTable:
    """Stiffness and damping that change with the spin speed (bearings, seals): at speed
    ``Omega`` the blocks ``K(Omega)``, ``C(Omega)`` on ``coordinates``, linear between
    the tabulated ``speeds`` (rad/s, increasing) and held beyond them, are added to the
    structure's ``K`` and ``C``. Their force ``-K(Omega) q_b - C(Omega) q_b'`` is counted
    in the work ``W`` (a stiffness that changes with time stores no energy of its own)."""

    coordinates: tuple[int, ...]
    speeds: np.ndarray = field(repr=False)  # (k,)
    K: np.ndarray = field(repr=False)  # (k, m, m)
    C: np.ndarray = field(repr=False)  # (k, m, m)

    def __post_init__(self) -> None:
        owner = "structure: speed table"
        coords = tuple(int(c) for c in self.coordinates)
        if not coords or len(set(coords)) != len(coords):
            raise ValueError(f"{owner}: coordinates must be distinct and at least one")
        m = len(coords)
        speeds = np.array(self.speeds, dtype=float).reshape(-1)
        if speeds.size < 1 or not np.all(np.isfinite(speeds)) or np.any(np.diff(speeds) <= 0):
            raise ValueError(f"{owner}: speeds must be finite and increase")
        for name in ("K", "C"):
            block = np.array(getattr(self, name), dtype=float)
            if block.shape != (speeds.size, m, m):
                raise ValueError(
                    f"{owner}: {name} must be {speeds.size} x {m} x {m} (a block a speed), "
                    f"got shape {block.shape}"
                )
            if not np.all(np.isfinite(block)) or np.max(np.abs(block)) > MAX_MAGNITUDE:
                raise ValueError(f"{owner}: {name} must be finite")
            block.setflags(write=False)
            object.__setattr__(self, name, block)
        speeds.setflags(write=False)
        object.__setattr__(self, "coordinates", coords)
        object.__setattr__(self, "speeds", speeds)

    def at(self, omega: float) -> tuple[np.ndarray, np.ndarray]:
        """The blocks ``(K, C)`` at speed ``omega`` (interpolated as the kernel does)."""
        w = self.speeds
        if omega <= w[0] or w.size == 1:
            return self.K[0].copy(), self.C[0].copy()
        if omega >= w[-1]:
            return self.K[-1].copy(), self.C[-1].copy()
        k = int(np.searchsorted(w, omega, side="right")) - 1
        s = (omega - w[k]) / (w[k + 1] - w[k])
        return (1 - s) * self.K[k] + s * self.K[k + 1], (1 - s) * self.C[k] + s * self.C[k + 1]


@dataclass(frozen=True, eq=False)
class Structure:
    """The linear structure: ``M`` (symmetric positive definite), ``C``, ``K``, ``G``
    (None: zero), a static force (None: zero), ``dof_per_node`` coordinates a node."""

    M: np.ndarray = field(repr=False)
    K: np.ndarray = field(repr=False)
    C: np.ndarray | None = field(default=None, repr=False)
    G: np.ndarray | None = field(default=None, repr=False)
    static: np.ndarray | None = field(default=None, repr=False)
    dof_per_node: int = 2
    speed_table: SpeedTable | None = None
    # each node's (x, y) coordinates where the nodes are not all alike (a ROSS rotor's
    # support nodes have fewer coordinates than its shaft's); None: dof_per_node a node
    node_xy: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        owner = "structure"
        M = _matrix(owner, "M", self.M, None)
        n = M.shape[0]
        if n < 2:
            raise ValueError(f"{owner}: M must be at least 2 x 2 (a node's x and y)")
        if n > MAX_COORDINATES:
            raise ValueError(
                f"{owner}: M has {n} coordinates, more than {MAX_COORDINATES} (its dense "
                "matrices would not fit a run's memory): reduce the model"
            )
        scale = max(np.max(np.abs(M)), 1e-300)
        if np.max(np.abs(M - M.T)) > SYMMETRY_RTOL * scale:
            raise ValueError(f"{owner}: M must be symmetric (M - M^T is not 0)")
        M = 0.5 * (M + M.T)
        try:
            np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            raise ValueError(f"{owner}: M must be positive definite (a mass matrix)") from None
        matrices = {"M": M, "K": _matrix(owner, "K", self.K, n)}
        for name in ("C", "G"):
            value = getattr(self, name)
            matrices[name] = np.zeros((n, n)) if value is None else _matrix(owner, name, value, n)
        for name, matrix in matrices.items():
            matrix.setflags(write=False)
            object.__setattr__(self, name, matrix)
        if self.static is None:
            static = np.zeros(n)
        else:
            try:
                static = np.array(self.static, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise TypeError(f"{owner}: static must be a vector of {n} numbers") from None
            if static.shape != (n,) or not np.all(np.isfinite(static)):
                raise ValueError(f"{owner}: static must be {n} finite numbers (one a coordinate)")
        static.setflags(write=False)
        object.__setattr__(self, "static", static)
        per_node = self.dof_per_node
        if isinstance(per_node, bool) or not isinstance(per_node, numbers.Integral):
            raise TypeError(f"{owner}: dof_per_node must be an int, got {_kind(per_node)}")
        if self.node_xy is not None:
            xy = np.array(self.node_xy, dtype=np.int64)
            if xy.ndim != 2 or xy.shape[1] != 2 or xy.shape[0] < 1:
                raise ValueError(f"{owner}: node_xy must be a pair of coordinates a node")
            if np.any(xy < 0) or np.any(xy >= n) or np.unique(xy).size != xy.size:
                raise ValueError(f"{owner}: node_xy must name distinct coordinates 0 to {n - 1}")
            xy.setflags(write=False)
            object.__setattr__(self, "node_xy", xy)
        elif not (per_node >= 2 and n % per_node == 0):
            raise ValueError(
                f"{owner}: dof_per_node = {per_node} must be >= 2 and divide the {n} coordinates"
            )
        table = self.speed_table
        if table is not None:
            if not isinstance(table, SpeedTable):
                raise TypeError(f"{owner}: speed_table must be a SpeedTable, got {_kind(table)}")
            if not all(0 <= c < n for c in table.coordinates):
                raise ValueError(
                    f"{owner}: the speed table names a coordinate outside 0 to {n - 1}"
                )

    def at_speed(self, omega: float) -> tuple[np.ndarray, np.ndarray]:
        """``(K, C)`` at spin speed ``omega``: the matrices with the speed table's blocks
        there added (the matrices themselves without a table)."""
        K, C = np.array(self.K), np.array(self.C)
        if self.speed_table is not None:
            b = np.array(self.speed_table.coordinates)
            Kb, Cb = self.speed_table.at(omega)
            K[np.ix_(b, b)] += Kb
            C[np.ix_(b, b)] += Cb
        return K, C

    @property
    def size(self) -> int:
        """The number of coordinates n."""
        return self.M.shape[0]

    @property
    def nodes(self) -> int:
        if self.node_xy is not None:
            return int(self.node_xy.shape[0])
        return self.size // self.dof_per_node

    def lateral(self, node: int) -> tuple[int, int]:
        """The coordinates (x, y) of ``node``; ValueError if there is no such node."""
        if isinstance(node, bool) or not isinstance(node, numbers.Integral):
            raise TypeError(f"structure: node must be an int, got {_kind(node)}")
        if not 0 <= node < self.nodes:
            raise ValueError(f"structure: node {node} does not exist (0 to {self.nodes - 1})")
        if self.node_xy is not None:
            return (int(self.node_xy[node, 0]), int(self.node_xy[node, 1]))
        return (self.dof_per_node * int(node), self.dof_per_node * int(node) + 1)

    def lateral_pairs(self) -> np.ndarray:
        """(nodes, 2): every node's x and y coordinates."""
        return np.array([self.lateral(k) for k in range(self.nodes)], dtype=np.int64)


@dataclass(frozen=True)
class Unbalance:
    """An unbalance ``magnitude`` (m e) at ``coordinates`` (x, y), at ``phase`` (rad)."""

    coordinates: tuple[int, int]
    magnitude: float
    phase: float = 0.0


@dataclass(frozen=True)
class Station:
    """A contact station (module docstring). ``stator`` None: a rigid stator centred at
    ``offset``; else the stator's coordinate pair."""

    rotor: tuple[int, int]
    clearance: float
    law: ContactLaw
    mu: float = 0.0
    radius: float = 0.0
    stator: tuple[int, int] | None = None
    offset: tuple[float, float] = (0.0, 0.0)
    name: str = ""


@dataclass(frozen=True)
class Speed:
    """The spin speed: knots ``times`` (increasing) and ``values`` (> 0) of a
    piecewise-linear profile; one knot is a constant speed."""

    times: tuple[float, ...]
    values: tuple[float, ...]

    @classmethod
    def constant(cls, value: float) -> Speed:
        return cls((0.0,), (value,))

    def __post_init__(self) -> None:
        owner = "speed"
        times = tuple(_finite(owner, f"times[{i}]", t) for i, t in enumerate(self.times))
        values = tuple(_finite(owner, f"values[{i}]", v) for i, v in enumerate(self.values))
        if len(times) != len(values) or not times:
            raise ValueError(f"{owner}: times and values must have the same length >= 1")
        if any(not b > a for a, b in zip(times, times[1:], strict=False)):
            raise ValueError(f"{owner}: times must increase")
        if any(not v > 0.0 for v in values):
            raise ValueError(f"{owner}: every value must be > 0 (the rotor spins one way)")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)

    @property
    def is_constant(self) -> bool:
        return len(self.values) == 1 or len(set(self.values)) == 1

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(Omega, angle)`` at the times ``t``: the speed and the spin angle
        ``integral_0^t Omega``, as the system reads them (``kernels.speed_at``)."""
        t = np.asarray(t, dtype=float)
        knots = self.knots()
        k = np.clip(np.searchsorted(knots[:, 0], t, side="right") - 1, 0, len(knots) - 1)
        dt = t - knots[k, 0]
        inside = (t > knots[0, 0]) & (k < len(knots) - 1)
        nxt = np.minimum(k + 1, len(knots) - 1)
        span = np.where(inside, knots[nxt, 0] - knots[k, 0], 1.0)
        rate = np.where(inside, (knots[nxt, 1] - knots[k, 1]) / span, 0.0)
        return knots[k, 1] + rate * dt, knots[k, 2] + knots[k, 1] * dt + 0.5 * rate * dt * dt

    def knots(self) -> np.ndarray:
        """(k, 3): each knot's time, speed and the spin angle integral_0^t Omega there."""
        t = np.array(self.times)
        w = np.array(self.values)
        angle = np.empty_like(t)
        angle[0] = w[0] * t[0]
        angle[1:] = angle[0] + np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))
        return np.column_stack([t, w, angle])


@dataclass(frozen=True, eq=False)
class Machine:
    """A structure, its unbalances, its contact stations and its speed, checked together:
    every coordinate a station or an unbalance names exists, and no station's rotor and
    stator share a coordinate."""

    structure: Structure
    stations: tuple[Station, ...]
    speed: Speed
    unbalances: tuple[Unbalance, ...] = ()
    name: str = "machine"

    def __post_init__(self) -> None:
        if not isinstance(self.structure, Structure):
            raise TypeError(f"machine: structure must be a Structure, got {_kind(self.structure)}")
        if not isinstance(self.speed, Speed):
            raise TypeError(f"machine: speed must be a Speed, got {_kind(self.speed)}")
        n = self.structure.size
        unbalances = tuple(self.unbalances)
        for k, unbalance in enumerate(unbalances):
            owner = f"machine: unbalance {k}"
            if not isinstance(unbalance, Unbalance):
                raise TypeError(f"{owner} must be an Unbalance, got {_kind(unbalance)}")
            coords = _coordinates(owner, "coordinates", unbalance.coordinates, n)
            object.__setattr__(unbalance, "coordinates", coords)
            magnitude = _finite(owner, "magnitude", unbalance.magnitude)
            if magnitude < 0.0:
                raise ValueError(f"{owner}: magnitude must be >= 0 (got {magnitude!r})")
            object.__setattr__(unbalance, "magnitude", magnitude)
            object.__setattr__(unbalance, "phase", _finite(owner, "phase", unbalance.phase))
        stations = tuple(self.stations)
        if not stations:
            raise ValueError("machine: at least one contact station is needed")
        for k, station in enumerate(stations):
            _check_station(f"machine: station {station.name or k}", station, n)
        object.__setattr__(self, "stations", stations)
        object.__setattr__(self, "unbalances", unbalances)

    @property
    def size(self) -> int:
        """The structure's coordinate count n (the state is 2 n: positions, velocities)."""
        return self.structure.size


def _coordinates(owner: str, name: str, value: object, n: int) -> tuple[int, int]:
    if isinstance(value, str | bytes | dict) or not isinstance(value, Sequence | np.ndarray):
        raise TypeError(f"{owner}: {name} must be a pair of coordinate indices")
    if len(value) != 2:
        raise ValueError(f"{owner}: {name} must hold 2 coordinate indices, got {len(value)}")
    pair = (_index(owner, f"{name}[0]", value[0], n), _index(owner, f"{name}[1]", value[1], n))
    if pair[0] == pair[1]:
        raise ValueError(f"{owner}: {name} must be two different coordinates (got {pair})")
    return pair


def _check_station(owner: str, station: object, n: int) -> None:
    if not isinstance(station, Station):
        raise TypeError(f"{owner} must be a Station, got {_kind(station)}")
    rotor = _coordinates(owner, "rotor", station.rotor, n)
    stator = None
    if station.stator is not None:
        stator = _coordinates(owner, "stator", station.stator, n)
        if set(rotor) & set(stator):
            raise ValueError(f"{owner}: rotor {rotor} and stator {stator} share a coordinate")
    if not isinstance(station.law, ContactLaw):
        raise TypeError(f"{owner}: law must be a ContactLaw, got {_kind(station.law)}")
    clearance = _finite(owner, "clearance", station.clearance)
    if not clearance > 0.0:
        raise ValueError(f"{owner}: clearance must be > 0 (got {clearance!r})")
    mu = _finite(owner, "mu", station.mu)
    radius = _finite(owner, "radius", station.radius)
    for name, value in (("mu", mu), ("radius", radius)):
        if value < 0.0:
            raise ValueError(f"{owner}: {name} must be >= 0 (got {value!r})")
    values = {
        "rotor": rotor,
        "stator": stator,
        "clearance": clearance,
        "mu": mu,
        "radius": radius,
        "offset": _pair(owner, "offset", station.offset),
    }
    for name, value in values.items():
        object.__setattr__(station, name, value)

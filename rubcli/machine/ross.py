"""A structure from a ROSS rotor (``ross-rotordynamics``, the optional extra ``ross``).

ROSS assembles a finite-element rotor (Timoshenko shaft elements, disks, bearings and
seals) into ``M(speed)``, ``K(speed)``, ``C(speed)`` (bearing and seal coefficients at
that speed, Rayleigh damping) and ``G()``, with 6 coordinates a node in the order
``x, y, z, alpha, beta, theta``. rubcli takes these matrices as ROSS gives them, at the
running speed (coefficients evaluated at the synchronous frequency, as ROSS's
``run_unbalance_response`` and ``save_mat`` do), cross-coupled terms kept; in a run-up,
the coefficients that change with the speed at the current speed (``ross_structure``'s
``speed_range``: ROSS's interpolant tabulated finely, ``SpeedTable``).

The axial ``z`` and torsional ``theta`` coordinates of ROSS's beam are not coupled to
the lateral ones in these linear matrices, and nothing rubcli applies (unbalances,
contact forces, lateral gravity) acts on them, so from rest they stay at rest: they are
dropped when every coupling entry is exactly zero (``lateral_coordinates``), leaving 4
coordinates a node, ``x, y, alpha, beta``, node ``k``'s ``x, y`` at ``4 k, 4 k + 1``.
Support nodes (a bearing's ``n_link``: a pedestal, a ring), which ROSS numbers after the
shaft's with 3 coordinates each (``x, y, z``), keep their ``x, y`` after the shaft's
coordinates (the structure's ``node_xy`` maps every node). This
is exact (no reduction): it removes the axial and torsional modes, the stiffest of the
model, and with them the rigid-body modes a rotor without axial supports has. Where a
coupling is not zero (an axial force, a bearing's cross term into ``z``) all 6 stay.

Versions (``pyproject.toml``): ROSS 3.x on Python 3.13 and newer; ROSS 2.3 (with
``plotly < 6``) on Python 3.11 and 3.12. ROSS 3 reads files written by 2.3; ROSS 2.3
cannot read a file written by ROSS 3 (it has ``default_damping_ratio``), which
``load_ross_rotor`` says.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rubcli.machine.contact import ContactLaw
from rubcli.machine.linear import with_gravity
from rubcli.machine.machine import (
    MAX_COORDINATES,
    Machine,
    Speed,
    SpeedTable,
    Station,
    Structure,
    Unbalance,
)

ROSS_DOF_PER_NODE = 6
SUPPORT_DOF_PER_NODE = 3  # a support node's x, y, z (ROSS numbers them after the shaft's)
LATERAL = (0, 1, 3, 4)  # x, y, alpha, beta of each node's 6
ROSS_MISSING = 'needs ROSS (ross-rotordynamics): pip install -e ".[ross]"'


class RossError(ValueError):
    """A ROSS rotor that cannot be used: ROSS missing, its file unreadable, its model
    outside what rubcli runs; the message says which and why."""


@contextmanager
def _quiet_descriptors():
    """Standard output and error sent to /dev/null at the descriptor level: ROSS's
    import prints (from Python and from a C library) about optional thermodynamic
    libraries, which would corrupt a command's JSON output."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, null):
            os.close(fd)


def import_ross() -> Any:
    """The ``ross`` module, imported quietly; RossError if it is not installed or
    does not import."""
    if sys.modules.get("ross") is not None:
        return sys.modules["ross"]
    try:
        with _quiet_descriptors():
            import ross
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] == "ross":
            raise RossError(ROSS_MISSING) from None
        raise RossError(f"ROSS does not import: {exc} ({ROSS_MISSING})") from None
    except Exception as exc:  # noqa: BLE001 (an optional library's failure is reported)
        raise RossError(f"ROSS does not import: {type(exc).__name__}: {exc}") from None
    return ross


def load_ross_rotor(path: str | Path) -> Any:
    """A ``ross.Rotor`` from its file (checked before by the case's reader,
    ``rubcli.case.rotor.check_ross_file``); RossError with ROSS's own message if ROSS
    cannot build it."""
    path = Path(path)
    ross = import_ross()
    try:
        with _quiet_descriptors():
            return ross.Rotor.load(str(path))
    except TypeError as exc:
        if "default_damping_ratio" in str(exc):
            raise RossError(
                f"{path}: written by ROSS 3, which this ROSS ({ross.__version__}, for Python "
                "3.11-3.12) cannot read: run rubcli on Python 3.13+ (ROSS 3), or export the "
                "matrices there (rubcli export-matrices) and use [rotor] matrices"
            ) from None
        raise RossError(f"{path}: ROSS cannot build this rotor: {exc}") from None
    except Exception as exc:  # noqa: BLE001 (ROSS's own errors name the problem)
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise RossError(
            f"{path}: ROSS cannot build this rotor: {type(exc).__name__}: {first}"
        ) from None


def _is_ross_rotor(rotor: object) -> bool:
    return all(hasattr(rotor, name) for name in ("M", "K", "C", "G", "shaft_elements", "ndof"))


def ross_matrices(rotor: Any, speed: float) -> dict[str, np.ndarray]:
    """ROSS's ``M, K, C, G`` of ``rotor`` at ``speed`` (rad/s; coefficients at the
    synchronous frequency), as dense float arrays with 6 coordinates a node."""
    if not _is_ross_rotor(rotor):
        raise TypeError(f"rotor must be a ross.Rotor, got {type(rotor).__name__}")
    speed = float(speed)
    if not (np.isfinite(speed) and speed >= 0.0):
        raise ValueError(f"speed must be a finite number >= 0 rad/s (got {speed!r})")
    try:
        with _quiet_descriptors():
            out = {
                "M": rotor.M(speed),
                "K": rotor.K(speed),
                "C": rotor.C(speed),
                "G": rotor.G(),
            }
    except Exception as exc:  # noqa: BLE001 (ROSS's own errors name the problem)
        raise RossError(f"ROSS cannot assemble the matrices at {speed:g} rad/s: {exc}") from None
    out = {k: np.array(v, dtype=float) for k, v in out.items()}
    if rotor.number_dof != ROSS_DOF_PER_NODE:
        raise RossError(
            f"the rotor has {rotor.number_dof} coordinates a node; rubcli reads ROSS's "
            f"{ROSS_DOF_PER_NODE} (x, y, z, alpha, beta, theta)"
        )
    return out


def support_nodes(rotor: Any) -> int:
    """The rotor's support nodes: ROSS numbers them after the shaft's, 3 coordinates
    each (``x, y, z``: a bearing's ``n_link``, a point mass on it), after the shaft
    nodes' 6; RossError if its coordinates do not add up so."""
    shaft = len(rotor.nodes)
    rest = int(rotor.ndof) - ROSS_DOF_PER_NODE * shaft
    if rest < 0 or rest % SUPPORT_DOF_PER_NODE:
        raise RossError(
            f"the rotor has {rotor.ndof} coordinates, not {ROSS_DOF_PER_NODE} a shaft node "
            f"and {SUPPORT_DOF_PER_NODE} a support node"
        )
    return rest // SUPPORT_DOF_PER_NODE


def lateral_coordinates(
    matrices: dict[str, np.ndarray], shaft_nodes: int | None = None
) -> tuple[np.ndarray, int, np.ndarray | None]:
    """The coordinates kept, the count a shaft node, and each node's ``x, y`` among the
    kept ones where there are support nodes (None: none). Kept: ``x, y, alpha, beta`` of
    every shaft node (4) and ``x, y`` of every support node when no matrix couples them
    to the ``z, theta`` (module docstring), else every coordinate. ``shaft_nodes``: the
    shaft's nodes (None: every coordinate a shaft node's)."""
    n = matrices["M"].shape[0]
    shaft = n // ROSS_DOF_PER_NODE if shaft_nodes is None else int(shaft_nodes)
    base = ROSS_DOF_PER_NODE * shaft
    supports = (n - base) // SUPPORT_DOF_PER_NODE
    support_xy = [(base + SUPPORT_DOF_PER_NODE * i, base + SUPPORT_DOF_PER_NODE * i + 1)
                  for i in range(supports)]  # fmt: skip
    lateral = np.array(
        [ROSS_DOF_PER_NODE * k + j for k in range(shaft) for j in LATERAL]
        + [c for pair in support_xy for c in pair],
        dtype=np.int64,
    )
    other = np.setdiff1d(np.arange(n), lateral)
    coupled = any(
        np.any(m[np.ix_(lateral, other)] != 0.0) or np.any(m[np.ix_(other, lateral)] != 0.0)
        for m in matrices.values()
    )
    keep = np.arange(n) if coupled else lateral
    per_node = ROSS_DOF_PER_NODE if coupled else len(LATERAL)
    if not supports:
        return keep, per_node, None
    where = {int(c): k for k, c in enumerate(keep)}
    xy = [(ROSS_DOF_PER_NODE * k, ROSS_DOF_PER_NODE * k + 1) for k in range(shaft)] + support_xy
    return keep, per_node, np.array([(where[x], where[y]) for x, y in xy], dtype=np.int64)


def outer_radii(rotor: Any) -> np.ndarray:
    """The shaft's outer radius at each node (m): the larger of the elements meeting
    there (``odl / 2`` of the element starting at it, ``odr / 2`` of one ending at it)."""
    radii = np.zeros(len(rotor.nodes))
    for element in rotor.shaft_elements:
        left, right = int(element.n_l), int(element.n_r)
        radii[left] = max(radii[left], float(element.odl) / 2.0)
        radii[right] = max(radii[right], float(element.odr) / 2.0)
    return radii


def shaft_layout(rotor: Any) -> dict[str, np.ndarray]:
    """The shaft's layout for its view, as a matrices file holds it: ``node_position``
    (m along the axis, one a node of the structure: nan for a node off the shaft, as a
    bearing's support node that ROSS numbers after the shaft's), ``outer_radius``
    (``outer_radii``), ``disk_nodes``, ``bearing_nodes`` (the bearings on the shaft that
    carry a load: not a link of zero coefficients to a support node)."""
    positions = np.full(len(rotor.nodes) + support_nodes(rotor), np.nan)
    on_shaft = [float(x) for x in rotor.nodes_pos]
    positions[: len(on_shaft)] = on_shaft
    with _quiet_descriptors():  # a bearing of zero coefficients (a link to a ring) is none
        bearings = sorted({
            int(b.n) for b in rotor.bearing_elements
            if int(b.n) < len(on_shaft) and (np.any(b.K(0.0) != 0.0) or np.any(b.C(0.0) != 0.0))
        })  # fmt: skip
    return {
        "node_position": positions,
        "outer_radius": outer_radii(rotor),
        "disk_nodes": np.array(sorted(int(d.n) for d in rotor.disk_elements), dtype=np.int64),
        "bearing_nodes": np.array(bearings, dtype=np.int64),
    }


def _bearing_blocks(
    rotor: Any, speeds: np.ndarray, only: list[int] | None = None
) -> tuple[list[int], list[int], np.ndarray, np.ndarray]:
    """The bearings and seals (their indices in ``rotor.bearing_elements``) whose
    coefficients change over ``speeds`` (rad/s), or those of ``only``; their coordinates
    (ROSS's numbering) and their summed ``K``, ``C`` blocks at each speed as ROSS
    evaluates them (``BearingElement.K(frequency)``, ``.C(frequency)``)."""
    chosen = []
    with _quiet_descriptors():
        for k, element in enumerate(rotor.bearing_elements):
            if only is not None and k not in only:
                continue
            dofs = [int(d) for d in element.dof_global_index.values()]
            K = np.array([np.asarray(element.K(w), dtype=float) for w in speeds])
            C = np.array([np.asarray(element.C(w), dtype=float) for w in speeds])
            if only is not None or np.ptp(K, axis=0).any() or np.ptp(C, axis=0).any():
                chosen.append((k, dofs, K, C))
    coordinates = sorted({d for _, dofs, _, _ in chosen for d in dofs})
    where = {d: k for k, d in enumerate(coordinates)}
    K = np.zeros((speeds.size, len(coordinates), len(coordinates)))
    C = np.zeros_like(K)
    for _, dofs, Kb, Cb in chosen:
        at = np.array([where[d] for d in dofs])
        K[:, at[:, None], at[None, :]] += Kb
        C[:, at[:, None], at[None, :]] += Cb
    return [k for k, _, _, _ in chosen], coordinates, K, C


# A run-up's bearings: ROSS's interpolant of each coefficient (a spline through its
# table) tabulated at speeds across the run's range, finer until linear interpolation
# between them is within this share of the largest coefficient of ROSS's own at the
# midpoints (at most MAX_TABLE_SPEEDS speeds).
TABLE_RTOL = 1e-6
MAX_TABLE_SPEEDS = 4097


def ross_speed_table(
    rotor: Any, low: float, high: float
) -> tuple[list[int], list[int], np.ndarray, np.ndarray, np.ndarray, float]:
    """The bearings and seals of ``rotor`` whose coefficients change between ``low`` and
    ``high`` (rad/s; their indices, empty: none change), their coordinates (ROSS's
    numbering), the tabulated speeds, the ``K`` and ``C`` blocks there, and the table's
    largest error against ROSS's interpolant at the midpoints, a share of the largest
    coefficient."""
    count = 17
    changing = _bearing_blocks(rotor, np.linspace(low, high, count))[0]
    if not changing:
        return [], [], np.array([low]), np.zeros((1, 0, 0)), np.zeros((1, 0, 0)), 0.0
    while True:
        speeds = np.linspace(low, high, count)
        _, coordinates, K, C = _bearing_blocks(rotor, speeds, changing)
        mid = 0.5 * (speeds[1:] + speeds[:-1])
        _, _, Km, Cm = _bearing_blocks(rotor, mid, changing)
        error = 0.0
        for table, midpoint in ((K, Km), (C, Cm)):
            scale = max(float(np.max(np.abs(table))), 1e-300)
            gap = np.max(np.abs(0.5 * (table[1:] + table[:-1]) - midpoint))
            error = max(error, float(gap) / scale)
        if error <= TABLE_RTOL or count >= MAX_TABLE_SPEEDS:
            return changing, coordinates, speeds, K, C, error
        count = 2 * count - 1


def ross_structure(
    rotor: Any,
    speed: float,
    gravity: tuple[float, float] | None = None,
    speed_range: tuple[float, float] | None = None,
) -> Structure:
    """The structure of a ROSS rotor at ``speed`` (rad/s): its matrices, the lateral
    coordinates only where that is exact (module docstring), and the static force of
    ``gravity`` (m/s^2 along x and y: ``M a`` with ``a`` the acceleration on every node's
    x and y, the consistent load of the weight).

    With ``speed_range`` (rad/s, a run-up's lowest and highest speed): the bearings and
    seals whose coefficients change over it become the structure's ``SpeedTable``
    (``ross_speed_table``: ROSS's interpolant, tabulated), the matrices hold the rest.
    RossError if a bearing's mass coefficients change with the speed (not supported)."""
    matrices = ross_matrices(rotor, speed)
    table = None
    if speed_range is not None:
        low, high = (float(v) for v in speed_range)
        if high > low:
            with _quiet_descriptors():
                changing_mass = np.any(rotor.M(low) != rotor.M(high))
            if changing_mass:
                raise RossError(
                    "a bearing's mass coefficients change with the speed, which a run-up does "
                    "not support: give them constant"
                )
            changing, *table = ross_speed_table(rotor, low, high)
            if changing:
                b = np.array(table[0])
                _, _, Kb, Cb = _bearing_blocks(rotor, np.array([float(speed)]), changing)
                matrices["K"][np.ix_(b, b)] -= Kb[0]
                matrices["C"][np.ix_(b, b)] -= Cb[0]
            else:
                table = None
    together = dict(matrices)
    if table is not None:  # a coordinate coupled at any tabulated speed is kept
        b = np.array(table[0])
        for name, blocks in (("K", table[2]), ("C", table[3])):
            extra = np.zeros_like(matrices[name])
            extra[np.ix_(b, b)] = np.max(np.abs(blocks), axis=0)
            together[f"{name}_table"] = extra
    support_nodes(rotor)  # the coordinates add up (RossError if not)
    keep, per_node, node_xy = lateral_coordinates(together, len(rotor.nodes))
    if keep.size > MAX_COORDINATES:
        raise RossError(
            f"the rotor has {keep.size} coordinates, more than {MAX_COORDINATES}: reduce the model"
        )
    sub = {k: np.ascontiguousarray(v[np.ix_(keep, keep)]) for k, v in matrices.items()}
    speed_table = None
    if table is not None:
        coordinates, speeds, K, C, _ = table
        inside = [k for k, c in enumerate(coordinates) if c in set(keep.tolist())]
        position = {int(c): k for k, c in enumerate(keep)}
        sel = np.array(inside)
        speed_table = SpeedTable(
            tuple(position[coordinates[k]] for k in inside),
            speeds,
            K[:, sel[:, None], sel[None, :]],
            C[:, sel[:, None], sel[None, :]],
        )
    try:
        structure = Structure(
            M=sub["M"], K=sub["K"], C=sub["C"], G=sub["G"], dof_per_node=per_node,
            speed_table=speed_table, node_xy=node_xy,
        )  # fmt: skip
    except ValueError as exc:
        raise RossError(f"ROSS's matrices: {str(exc).removeprefix('structure: ')}") from None
    return with_gravity(structure, gravity)


def export_matrices(rotor: Any, speed: float, path: str | Path) -> dict[str, np.ndarray]:
    """Write the matrices of ``rotor`` at ``speed`` (rad/s) to an ``.npz`` a matrices
    case reads without ROSS (``[rotor] matrices``): ``M, K, C, G``, ``number_dof``, the
    shaft's layout (``shaft_layout``: ``outer_radius`` is also a station's default radius)
    and ``speed_rpm`` (the speed the bearings' coefficients are taken at), lateral
    coordinates only where exact; written atomically. Returns the arrays written."""
    from rubcli.io.files import atomic_path

    structure = ross_structure(rotor, speed)
    arrays = {
        "M": np.asarray(structure.M),
        "K": np.asarray(structure.K),
        "C": np.asarray(structure.C),
        "G": np.asarray(structure.G),
        "number_dof": np.array(structure.dof_per_node),
        **({} if structure.node_xy is None else {"node_xy": np.asarray(structure.node_xy)}),
        **shaft_layout(rotor),
        "speed_rpm": np.array(float(speed) * 60.0 / (2.0 * np.pi)),  # the bearings' speed
    }
    with atomic_path(Path(path)) as tmp, open(tmp, "wb") as handle:
        np.savez(handle, **arrays)
    return arrays


@dataclass(frozen=True)
class NodeStation:
    """A contact station given at nodes of a finite-element rotor (SI): the rotor's node,
    the clearance (m), the contact law, the friction coefficient, the surface radius (m;
    None: the shaft's outer radius at the node), the stator's centre (m) or the node of
    the structure that is the stator, and a name."""

    node: int
    clearance: float
    law: ContactLaw
    mu: float = 0.0
    radius: float | None = None
    offset: tuple[float, float] = (0.0, 0.0)
    stator_node: int | None = None
    name: str | None = None


def ross_machine(
    rotor: Any,
    speed: float | Speed,
    stations: Sequence[NodeStation],
    unbalances: Sequence[tuple[int, float, float]] = (),
    gravity: tuple[float, float] | None = None,
) -> Machine:
    """The machine of a ``ross.Rotor`` at the constant ``speed`` (rad/s) or on a
    ``Speed`` profile (a run-up: the bearings follow the speed, ``ross_structure``'s
    ``speed_range``), with contact ``stations`` and ``unbalances`` ``(node, magnitude kg
    m, phase rad)`` at nodes (ROSS's convention) and ``gravity`` (m/s^2 along x, y) as the
    static load."""
    profile = speed if isinstance(speed, Speed) else Speed.constant(float(speed))
    values = profile.values
    span = None if profile.is_constant else (min(values), max(values))
    structure = ross_structure(rotor, values[0], gravity, span)
    radii = outer_radii(rotor)
    built = []
    for k, s in enumerate(stations):
        if not isinstance(s, NodeStation):
            raise TypeError(f"stations[{k}] must be a NodeStation, got {type(s).__name__}")
        radius = s.radius
        if radius is None:
            if not 0 <= s.node < radii.size:
                raise ValueError(f"stations[{k}].node: node {s.node} does not exist")
            radius = float(radii[s.node])
        stator = None if s.stator_node is None else structure.lateral(s.stator_node)
        built.append(
            Station(
                structure.lateral(s.node),
                s.clearance,
                s.law,
                s.mu,
                radius,
                stator,
                s.offset,
                s.name or f"station{k}",
            )  # fmt: skip
        )
    loads = []
    for k, unbalance in enumerate(unbalances):
        if len(unbalance) != 3:
            raise ValueError(f"unbalances[{k}] must be (node, magnitude, phase)")
        node, magnitude, phase = unbalance
        loads.append(Unbalance(structure.lateral(node), magnitude, phase))
    return Machine(structure, tuple(built), profile, tuple(loads))

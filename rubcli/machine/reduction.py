"""A machine reduced to its stations' coordinates and a few modes (Craig-Bampton).

The coordinates a station or an unbalance reads (its rotor's and stator's ``x, y``) and
any asked for (``keep``: a probe's) stay physical; the rest (the interior) is spanned by

- the constraint modes ``Psi = -K_ii^-1 K_ib``: the interior's static response to each
  kept coordinate moved alone, so that the reduced model is statically exact for any
  force at the kept coordinates (a contact force, an unbalance);
- the lowest ``modes`` fixed-interface modes (``K_ii`` symmetric part, ``M_ii``; the kept
  coordinates held at 0), which carry the dynamics of the rest up to their frequency;
- where the static force loads the interior (gravity), its static deflection with the
  kept coordinates held, made M-orthogonal to the modes: the weight's sag is then exact.

Coefficients that change with the speed (``SpeedTable``: bearings in a run-up) sit on
kept coordinates, so the interior's matrices, and with them the basis, do not depend on
the speed: the reduction is the same at every speed, and the table acts on the kept
coordinates unchanged.

``q = T p``: the first ``len(kept)`` reduced coordinates are the kept ones themselves, the
others modal. The reduced matrices are ``T^T X T`` for X in M, C, K, G (a Galerkin
projection: symmetry, definiteness of M and the skew gyroscopic part are kept).

Why Craig-Bampton rather than truncating the free modes: the stations' coordinates stay
physical, so every event function and contact force reads them directly, and the static
correction is built in, where modal truncation loses the local flexibility at a contact
(the force there excites every mode) unless a residual flexibility is added by hand.
With every interior mode kept, T is square and the reduced model is the full one.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from rubcli.machine.machine import Machine, Structure


@dataclass(frozen=True, eq=False)
class Reduction:
    """``q = basis @ p``: the full coordinates from the reduced ones; ``kept[k]`` is the
    full coordinate that reduced coordinate k is (k < len(kept)); ``modes`` the
    fixed-interface modes, ``static_vectors`` the static correction's (0 or 1)."""

    basis: np.ndarray
    kept: tuple[int, ...]
    modes: int
    static_vectors: int

    def reduced_index(self, coordinate: int) -> int:
        """The reduced coordinate that is the full ``coordinate``; ValueError if it is
        not kept."""
        try:
            return self.kept.index(int(coordinate))
        except ValueError:
            raise ValueError(f"reduction: coordinate {coordinate} is not kept") from None

    def full_positions(self, q: np.ndarray) -> np.ndarray:
        """The full coordinates (..., n) of reduced positions or velocities (..., r)."""
        return np.asarray(q) @ self.basis.T


def kept_coordinates(machine: Machine, keep: tuple[int, ...] = ()) -> tuple[int, ...]:
    """The coordinates a reduction of ``machine`` keeps physical, in order, once: each
    station's rotor and stator pair, each unbalance's pair, the speed table's coordinates
    (bearings whose coefficients change with the speed), then ``keep``."""
    found: list[int] = []
    pairs = [s.rotor for s in machine.stations]
    pairs += [s.stator for s in machine.stations if s.stator is not None]
    pairs += [u.coordinates for u in machine.unbalances]
    table = machine.structure.speed_table
    pairs += [table.coordinates] if table is not None else []
    for coordinate in [c for pair in pairs for c in pair] + [int(c) for c in keep]:
        if coordinate not in found:
            found.append(coordinate)
    return tuple(found)


def craig_bampton(
    structure: Structure, kept: tuple[int, ...], modes: int
) -> tuple[Structure, Reduction]:
    """The structure reduced to the coordinates ``kept`` and ``modes`` fixed-interface
    modes (module docstring); ValueError if ``modes`` is out of range or the structure
    with the kept coordinates held is not supported (``K_ii`` singular)."""
    n = structure.size
    b = np.array(kept, dtype=np.int64)
    interior = np.setdiff1d(np.arange(n), b)
    if isinstance(modes, bool) or not isinstance(modes, int | np.integer) or modes < 1:
        raise ValueError(f"reduction: modes must be an int >= 1 (got {modes!r})")
    if modes > interior.size:
        raise ValueError(
            f"reduction: modes = {modes} is more than the {interior.size} coordinates besides "
            f"the {b.size} kept ones"
        )
    M, K = structure.M, structure.K
    Mii = M[np.ix_(interior, interior)]
    Kii = K[np.ix_(interior, interior)]
    with warnings.catch_warnings():  # a singular K_ii is refused below, by name
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        lu = scipy.linalg.lu_factor(Kii, check_finite=False)
    if np.min(np.abs(np.diag(lu[0]))) <= 1e-13 * np.max(np.abs(np.diag(lu[0]))):
        raise ValueError(
            "reduction: the structure with its stations' coordinates held is not supported "
            "(its interior stiffness is singular): give the full model (modes = 0)"
        )
    psi = -scipy.linalg.lu_solve(lu, K[np.ix_(interior, b)], check_finite=False)
    _, phi = scipy.linalg.eigh(0.5 * (Kii + Kii.T), Mii, subset_by_index=[0, modes - 1])
    vectors = [phi]
    static_i = structure.static[interior]
    if modes < interior.size and np.any(static_i != 0.0):
        sag = scipy.linalg.lu_solve(lu, static_i, check_finite=False)
        size = float(np.sqrt(sag @ Mii @ sag))
        rest = sag - phi @ (phi.T @ (Mii @ sag))
        left = float(np.sqrt(max(rest @ Mii @ rest, 0.0)))
        if left > 1e-9 * size:
            vectors.append((rest / left)[:, None])
    phi = np.hstack(vectors)
    T = np.zeros((n, b.size + phi.shape[1]))
    T[b, np.arange(b.size)] = 1.0
    T[np.ix_(interior, np.arange(b.size))] = psi
    T[interior, b.size :] = phi
    table = structure.speed_table
    if table is not None:
        missing = sorted(set(table.coordinates) - set(int(c) for c in b))
        if missing:
            raise ValueError(f"reduction: the speed table's coordinates {missing} must be kept")
        table = dataclasses.replace(
            table, coordinates=tuple(int(np.flatnonzero(b == c)[0]) for c in table.coordinates)
        )
    reduced = Structure(
        M=T.T @ M @ T,
        K=T.T @ K @ T,
        C=T.T @ structure.C @ T,
        G=T.T @ structure.G @ T,
        static=T.T @ structure.static,
        dof_per_node=T.shape[1],  # a reduced structure has no nodes: Reduction maps them
        speed_table=table,
    )
    reduction = Reduction(T, tuple(int(c) for c in b), modes, phi.shape[1] - modes)
    return reduced, reduction


def reduce_machine(
    machine: Machine, modes: int, keep: tuple[int, ...] = ()
) -> tuple[Machine, Reduction]:
    """``machine`` on its Craig-Bampton reduction (``craig_bampton``): its stations and
    unbalances at the same (kept) coordinates, renumbered, and ``keep`` kept too."""
    kept = kept_coordinates(machine, keep)
    structure, reduction = craig_bampton(machine.structure, kept, modes)

    def pair(coordinates: tuple[int, int]) -> tuple[int, int]:
        return (reduction.reduced_index(coordinates[0]), reduction.reduced_index(coordinates[1]))

    stations = tuple(
        dataclasses.replace(
            s, rotor=pair(s.rotor), stator=None if s.stator is None else pair(s.stator)
        )
        for s in machine.stations
    )
    unbalances = tuple(
        dataclasses.replace(u, coordinates=pair(u.coordinates)) for u in machine.unbalances
    )
    reduced = Machine(structure, stations, machine.speed, unbalances, machine.name)
    return reduced, reduction

"""The structure's linear answers, without contact: its eigenvalues at a speed and its
steady response to the unbalances at a constant speed.

With ``M q'' + (C + Omega G) q' + K q = f + F(t)`` and the unbalance force of ROSS's
convention at a constant speed, ``F_x = m e Omega^2 cos(Omega t + p)``, ``F_y = m e
Omega^2 sin(Omega t + p)`` (``Unbalance``), the force is ``Re(F e^{i Omega t})`` with
``F_x = m e Omega^2 e^{i p}``, ``F_y = -i m e Omega^2 e^{i p}``, and the steady state is
``q = q_s + Re(Q e^{i Omega t})``: ``K q_s = f`` and ``(K - Omega^2 M + i Omega (C +
Omega G)) Q = F``, the equation ROSS's ``run_unbalance_response`` solves. Bearings whose
coefficients change with the speed (``SpeedTable``) are taken at the speed asked.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from rubcli.machine.machine import Machine, Structure


def gravity_load(M: np.ndarray, pairs: np.ndarray, gravity: tuple[float, float]) -> np.ndarray:
    """The static force of ``gravity`` (m/s^2 along x, y) on a structure of mass matrix
    ``M``: ``M a``, ``a`` the acceleration on every node's x and y (``pairs``, (nodes, 2):
    their coordinates), the consistent load of the weight."""
    acceleration = np.zeros(M.shape[0])
    pairs = np.asarray(pairs, dtype=np.int64)
    acceleration[pairs[:, 0]], acceleration[pairs[:, 1]] = (float(g) for g in gravity)
    return M @ acceleration


def with_gravity(structure: Structure, gravity: Sequence[float] | None) -> Structure:
    """``structure`` with the static force of ``gravity`` (m/s^2 along x, y; None: the
    structure as it is) on every node (``gravity_load``)."""
    if gravity is None:
        return structure
    load = gravity_load(structure.M, structure.lateral_pairs(), tuple(gravity))
    return dataclasses.replace(structure, static=load)


def unbalance_amplitudes(machine: Machine, speed: float) -> np.ndarray:
    """The complex force amplitudes ``F`` (N) of the unbalances at ``speed`` (rad/s)."""
    force = np.zeros(machine.size, dtype=complex)
    for unbalance in machine.unbalances:
        ix, iy = unbalance.coordinates
        phasor = unbalance.magnitude * speed**2 * np.exp(1j * unbalance.phase)
        force[ix] += phasor
        force[iy] += -1j * phasor
    return force


def steady_response(machine: Machine, speed: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The free (no contact) steady state at a constant speed: the static deflection
    ``q_s`` (zero where the structure carries no static force) and the complex
    amplitudes ``Q`` of the unbalance response (module docstring). ``speed`` (rad/s)
    defaults to the machine's, which must then be constant."""
    if speed is None:
        if len(machine.speed.values) != 1:
            raise ValueError("steady_response: the machine's speed is not constant; give speed")
        speed = float(machine.speed.values[0])
    st = machine.structure
    K, C = st.at_speed(speed)  # bearings whose coefficients change: at this speed
    dynamic = K - speed**2 * st.M + 1j * speed * (C + speed * st.G)
    amplitudes = np.linalg.solve(dynamic, unbalance_amplitudes(machine, speed))
    static = np.zeros(machine.size)
    if np.any(st.static != 0.0):
        static = np.linalg.solve(K, st.static)
    return static, amplitudes


def eigenvalues(structure: Structure, speed: float) -> np.ndarray:
    """The eigenvalues of the free structure at ``speed`` (rad/s), ``lambda`` of ``q =
    Re(phi e^{lambda t})``, sorted by the damped frequency ``|Im lambda|`` (each pair of
    complex conjugates once, with ``Im lambda >= 0``)."""
    n = structure.size
    K, C = structure.at_speed(speed)
    Minv = np.linalg.inv(structure.M)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -Minv @ K
    A[n:, n:] = -Minv @ (C + speed * structure.G)
    values = np.linalg.eigvals(A)
    values = values[values.imag >= 0.0]
    return values[np.argsort(values.imag)]

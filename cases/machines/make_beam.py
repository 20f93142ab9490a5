"""Writes beam.npz beside this script: the matrices of a small finite-element rotor (SI).

A steel shaft (1 m long, 40 mm across) of five Euler-Bernoulli beam elements, six nodes
of four coordinates each in the order ``x, y, alpha, beta`` (a node's lateral ``x, y``
first, as ROSS orders them; ``alpha`` the rotation about x, ``beta`` about y); a disk
of 10 kg at node 2 (its polar and diametral inertia; the polar one gives the gyroscopic
matrix ``G``); isotropic bearings at nodes 0 and 5 (2e7 N/m, 2e3 N s/m); stiffness-
proportional damping 2e-5 K and mass-proportional damping 20 M beside them (about 3 % of
critical on the first mode). Run ``python cases/machines/make_beam.py`` to
regenerate it (the tests check that the file holds what this script makes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

LENGTH, DIAMETER = 1.0, 0.04  # m
DENSITY, YOUNG = 7850.0, 2.1e11  # kg/m^3, Pa
ELEMENTS = 5
DISK_NODE, DISK_MASS, DISK_IP, DISK_ID = 2, 10.0, 0.05, 0.03  # kg, kg m^2
BEARING_NODES, BEARING_K, BEARING_C = (0, 5), 2e7, 2e3
RAYLEIGH_BETA = 2e-5  # s
RAYLEIGH_ALPHA = 20.0  # 1/s
DOF = 4


def beam_matrices() -> dict[str, np.ndarray]:
    nodes = ELEMENTS + 1
    n = DOF * nodes
    M, K, C, G = (np.zeros((n, n)) for _ in range(4))
    L = LENGTH / ELEMENTS
    area = np.pi * DIAMETER**2 / 4.0
    EI = YOUNG * np.pi * DIAMETER**4 / 64.0
    k = (
        EI
        / L**3
        * np.array(
            [
                [12, 6 * L, -12, 6 * L],
                [6 * L, 4 * L * L, -6 * L, 2 * L * L],
                [-12, -6 * L, 12, -6 * L],
                [6 * L, 2 * L * L, -6 * L, 4 * L * L],
            ]
        )
    )
    m = (
        DENSITY
        * area
        * L
        / 420.0
        * np.array(
            [
                [156, 22 * L, 54, -13 * L],
                [22 * L, 4 * L * L, 13 * L, -3 * L * L],
                [54, 13 * L, 156, -22 * L],
                [-13 * L, -3 * L * L, -22 * L, 4 * L * L],
            ]
        )
    )
    for e in range(ELEMENTS):
        a, b = DOF * e, DOF * (e + 1)
        for plane in ((0, 3), (1, 2)):  # x with beta, y with alpha
            idx = [a + plane[0], a + plane[1], b + plane[0], b + plane[1]]
            flip = 1.0 if plane == (0, 3) else -1.0  # alpha turns against the y plane's slope
            sign = np.array([1.0, flip, 1.0, flip])
            K[np.ix_(idx, idx)] += k * np.outer(sign, sign)
            M[np.ix_(idx, idx)] += m * np.outer(sign, sign)
    d = DOF * DISK_NODE
    M[d, d] += DISK_MASS
    M[d + 1, d + 1] += DISK_MASS
    M[d + 2, d + 2] += DISK_ID
    M[d + 3, d + 3] += DISK_ID
    G[d + 2, d + 3] += DISK_IP
    G[d + 3, d + 2] -= DISK_IP
    C += RAYLEIGH_BETA * K + RAYLEIGH_ALPHA * M
    for node in BEARING_NODES:
        for i in (DOF * node, DOF * node + 1):
            K[i, i] += BEARING_K
            C[i, i] += BEARING_C
    return {"M": M, "K": K, "C": C, "G": G, "number_dof": np.array(DOF)}


if __name__ == "__main__":
    np.savez(Path(__file__).with_name("beam.npz"), **beam_matrices())

"""The two linearised contact propagators of the analytic methods, compiled.

A step's data live in the preallocated arrays of ``workspace``: "prepare" fills them
at (tau0, s0) as the Python propagators' ``__init__`` (``analytic.LinearisedContact``,
``analytic.PolarLinearisedContact``) do, "evaluate" writes the Cartesian state and its
time derivative at tau0 + dt as their ``states`` and ``derivatives`` do.
"""

from __future__ import annotations

import cmath
import math

import numpy as np

from rubcli.model import (
    P_E,
    P_ETA,
    P_K,
    P_NU,
    P_PHI0,
    cartesian_entries,
    free_flight_record,
    linearised_contact_record,
    polar_entries,
    polar_jacobian_arrays,
    polar_rhs_entries,
)
from rubcli.solvers.compiled.jit import (
    jit,
)
from rubcli.solvers.compiled.linalg import (
    _eig_small,
    _eig_warm,
    _lu_factor,
    _lu_solve,
    _norm1,
    _residual_ok,
)


@jit
def _phi12(z):
    """phi1(z) = (e^z - 1)/z, phi2(z) = (e^z - 1 - z)/z^2, series near 0 (as analytic._phi12)."""
    if z.real * z.real + z.imag * z.imag < 1e-6:  # |z| < 1e-3
        z2 = z * z
        z3 = z2 * z
        return 1 + z / 2 + z2 / 6 + z3 / 24, 0.5 + z / 6 + z2 / 24 + z3 / 120
    inv = 1.0 / z
    em1 = cmath.exp(z) - 1
    return em1 * inv, (em1 - z) * inv * inv


def workspace() -> tuple[np.ndarray, ...]:
    """(lam, V, LU, coef, piv, real, M, B, Q, H, Z, scale, x, P, dP, Vinv): a step's
    arrays, allocated in Python (by the stepper, once a run) for the compiled loops."""
    return (
        np.empty(4, dtype=np.complex128),  # lam: eigenvalues
        np.empty((4, 4), dtype=np.complex128),  # V: unit eigenvectors
        np.empty((4, 4), dtype=np.complex128),  # LU: LU factors
        np.empty((2, 4), dtype=np.complex128),  # coef: eigen-coefficients
        np.empty(4, dtype=np.int64),  # piv: LU pivots
        np.empty(12),  # real: p0, f0, f_tau (polar); s_c, b (Cartesian)
        np.empty((4, 4)),  # M: the system matrix J (polar) or A (Cartesian)
        np.empty((4, 4)),  # B: eigensolver work (balanced matrix)
        np.empty((4, 4)),  # Q: eigensolver work
        np.empty((4, 4), dtype=np.complex128),  # H: eigensolver work (Schur form)
        np.empty((4, 4), dtype=np.complex128),  # Z: eigensolver work (Schur vectors)
        np.empty(4),  # scale: balancing
        np.empty(4, dtype=np.complex128),  # x: complex vector work
        np.empty(4),  # P: polar state work
        np.empty(4),  # dP: its derivative
        np.empty((4, 4), dtype=np.complex128),  # Vinv: the inverse of V
    )


@jit
def _eigenbasis(ws, warm):
    """Eigen-decomposition of ``M`` into ``lam``, ``V`` and ``Vinv``; returns cond(V).

    The condition number is ``||V||_1 ||V^-1||_1`` measured with ``_norm1``, so between
    cond1(V) and 2 cond1(V), and cond2(V) <= 4 cond1(V) (inf when V is exactly singular
    or M is not finite). With ``warm`` (``lam`` holds the previous step's eigenvalues)
    ``_eig_warm`` is tried first, else (or if it fails) the QR-based ``_eig_small``;
    either is accepted only if its residual in the balanced coordinates is small; if
    neither is, cond = inf hands the step to the Python propagator (LAPACK's eig, or
    its expm fallback). ``Vinv`` comes from the left eigenvectors (warm) or from the LU
    factors of V.
    """
    lam, V, LU, _, piv, _, M, B, Q, H, Z, scale, x, _, _, Vinv = ws
    for i in range(4):
        for j in range(4):
            if not math.isfinite(M[i, j]):
                return np.inf
    if warm:
        for i in range(4):
            x[i] = lam[i]
        warm = _eig_warm(M, lam, V, Vinv, x, B, scale) and _residual_ok(M, lam, V, scale)
    if not warm and not (
        _eig_small(M, lam, V, B, Q, H, Z, scale, x) and _residual_ok(M, lam, V, scale)
    ):
        return np.inf  # the step goes to Python (LAPACK's eig, or its expm fallback)
    if not warm:
        LU[:, :] = V
        if not _lu_factor(LU, piv):
            return np.inf
        for j in range(4):
            for i in range(4):
                x[i] = 0.0
            x[j] = 1.0
            _lu_solve(LU, piv, x)
            for i in range(4):
                Vinv[i, j] = x[i]
    return _norm1(V) * _norm1(Vinv)


@jit
def _omega_max(lam, eta):
    """max(|Im lam|, eta, 1): the fastest angular frequency of the step (scan spacing)."""
    m = 0.0
    for i in range(lam.shape[0]):
        m = max(m, abs(lam[i].imag))
    return max(m, eta, 1.0)


@jit
def _prepare_polar(tau0, s0, pars, mu_c, ws, warm):
    """PolarLinearisedContact.__init__ at (tau0, s0): returns (cond1(V), omega_max).

    ``real`` holds p0 (0:4), f0 (4:8), f_tau (8:12); ``M`` is J; ``coef`` the
    eigen-coefficients of f0 and f_tau.
    """
    lam, _, _, coef, _, real, M, _, _, _, _, _, _, _, _, Vinv = ws
    nu, eta, E, phi0, K = pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0], pars[P_K]
    r, theta, u, omega = polar_entries(s0[0], s0[1], s0[2], s0[3])
    f0 = polar_rhs_entries(tau0, r, theta, u, omega, nu, eta, E, phi0, K, mu_c)
    J, f_tau = polar_jacobian_arrays(tau0, r, theta, u, omega, nu, eta, E, phi0, K, mu_c)
    M[:, :] = J
    real[0] = r
    real[1] = theta
    real[2] = u
    real[3] = omega
    for i in range(4):
        real[4 + i] = f0[i]
        real[8 + i] = f_tau[i]
    cond = _eigenbasis(ws, warm)
    if not cond < np.inf:
        return cond, 1.0
    for i in range(4):
        c0 = 0j
        c1 = 0j
        for j in range(4):
            c0 += Vinv[i, j] * f0[j]
            c1 += Vinv[i, j] * f_tau[j]
        coef[0, i] = c0
        coef[1, i] = c1
    return cond, _omega_max(lam, eta)


@jit
def _evaluate_polar(dt, ws, out, dout):
    """PolarLinearisedContact.states and .derivatives at tau0 + dt, in Cartesian form."""
    lam, V, _, coef, _, real, M, _, _, _, _, _, w, P, dP, _ = ws
    if dt == 0.0:
        for i in range(4):
            P[i] = real[i]  # p0 + Re(V @ 0), exactly
    else:
        for i in range(4):
            phi1, phi2 = _phi12(lam[i] * dt)
            w[i] = dt * phi1 * coef[0, i] + dt * dt * phi2 * coef[1, i]
        for i in range(4):
            acc = 0j
            for j in range(4):
                acc += V[i, j] * w[j]
            P[i] = real[i] + acc.real
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += M[i, j] * (P[j] - real[j])
        dP[i] = real[4 + i] + acc + real[8 + i] * dt
    r, theta, u, omega = P[0], P[1], P[2], P[3]
    x, y, vx, vy = cartesian_entries(r, theta, u, omega)
    out[0] = x
    out[1] = y
    out[2] = vx
    out[3] = vy
    c = x / r  # cos(theta), sin(theta) to round-off (the rates serve the event check)
    sn = y / r
    u_dot = dP[2]
    omega_dot = dP[3]
    dout[0] = vx
    dout[1] = vy
    dout[2] = u_dot * c - 2 * u * omega * sn - r * omega_dot * sn - r * omega * omega * c
    dout[3] = u_dot * sn + 2 * u * omega * c + r * omega_dot * c - r * omega * omega * sn


@jit
def _prepare_cartesian(tau0, s0, pars, mu_c, ws, warm):
    """LinearisedContact.__init__ at (tau0, s0): returns (cond1(V), omega_max)."""
    A, b = linearised_contact_record(s0[0], s0[1], pars, mu_c)
    return _prepare_system(tau0, s0, pars, A, b, ws, warm)


@jit
def prepare_free_flight(
    tau0: float, s0: np.ndarray, pars: np.ndarray, ws: tuple, warm: bool
) -> tuple[float, float]:
    """analytic.LinearFreeFlight.__init__ at (tau0, s0), the general machine's exact free
    flight (``model.free_flight_record``): returns (cond1(V), omega_max); evaluated by
    ``_evaluate`` (Cartesian) as a contact step is."""
    A, b = free_flight_record(pars)
    return _prepare_system(tau0, s0, pars, A, b, ws, warm)


@jit
def _prepare_system(tau0, s0, pars, A, b, ws, warm):
    """The closed form of ``s' = A s + b + (0, 0, E cos, E sin)(eta tau + phi0)`` from
    (tau0, s0) (``analytic.LinearisedContact._solve``): returns (cond1(V), omega_max).

    ``real`` holds s_c (0:4) and b (4:8); ``M`` is A; ``coef[0]`` the eigen-coefficients
    c of d0, ``coef[1]`` the harmonic amplitude S_hat.
    """
    lam, _, LU, coef, piv, real, M, _, _, _, _, _, x, _, _, Vinv = ws
    eta, E, phi0 = pars[P_ETA], pars[P_E], pars[P_PHI0]
    M[:, :] = A
    for i in range(4):
        for j in range(4):
            LU[i, j] = A[i, j]
    if not _lu_factor(LU, piv):
        return np.inf, 1.0
    for i in range(4):
        x[i] = -b[i]
    _lu_solve(LU, piv, x)  # s_c = A^-1 (-b)
    for i in range(4):
        real[i] = x[i].real
        real[4 + i] = b[i]
    for i in range(4):
        for j in range(4):
            LU[i, j] = -A[i, j]
        LU[i, i] += 1j * eta
    if not _lu_factor(LU, piv):
        return np.inf, 1.0
    coef[1, 0] = 0.0
    coef[1, 1] = 0.0
    coef[1, 2] = E
    coef[1, 3] = -1j * E
    _lu_solve(LU, piv, coef[1])  # S_hat = (i eta - A)^-1 (0, 0, E, -i E)
    cond = _eigenbasis(ws, warm)
    if not cond < np.inf:
        return cond, 1.0
    rot = cmath.exp(1j * (eta * tau0 + phi0))
    for i in range(4):
        x[i] = s0[i] - real[i] - (coef[1, i] * rot).real  # d0
    for i in range(4):
        c = 0j
        for j in range(4):
            c += Vinv[i, j] * x[j]
        coef[0, i] = c
    return cond, _omega_max(lam, eta)


@jit
def _evaluate_cartesian(dt, tau, pars, ws, out, dout):
    """LinearisedContact.states and .derivatives at tau = tau0 + dt."""
    lam, V, _, coef, _, real, M, _, _, _, _, _, e, _, _, _ = ws
    eta, E, phi0 = pars[P_ETA], pars[P_E], pars[P_PHI0]
    phase = eta * tau + phi0
    rot = cmath.exp(1j * phase)
    for j in range(4):
        e[j] = coef[0, j] * cmath.exp(lam[j] * dt)
    for i in range(4):
        acc = 0j
        for j in range(4):
            acc += V[i, j] * e[j]
        out[i] = real[i] + (coef[1, i] * rot).real + acc.real
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += M[i, j] * out[j]
        dout[i] = acc + real[4 + i]
    dout[2] += E * math.cos(phase)
    dout[3] += E * math.sin(phase)


@jit
def _prepare(polar, tau0, s0, pars, mu_c, ws, warm):
    if polar:
        return _prepare_polar(tau0, s0, pars, mu_c, ws, warm)
    return _prepare_cartesian(tau0, s0, pars, mu_c, ws, warm)


@jit
def _evaluate(polar, tau0, t, pars, ws, out, dout):
    if polar:
        _evaluate_polar(t - tau0, ws, out, dout)
    else:
        _evaluate_cartesian(t - tau0, t, pars, ws, out, dout)

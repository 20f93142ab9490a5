"""scipy's DOP853 step, compiled: tableau, step, error norm, dense output, initial step.

Each function is scipy.integrate.DOP853's algorithm with scipy's coefficients (vendored
in ``dop853_coefficients.py``): the same stages, the 5th/3rd-order error blend, the
7th-order dense output and Hairer's initial step, so that for the same rtol/atol the
compiled loop takes scipy's steps.
"""

from __future__ import annotations

import math

import numpy as np

from rubcli.solvers import dop853_coefficients as _dop
from rubcli.solvers.compiled.jit import (
    jit,
)
from rubcli.solvers.compiled.rhs import (
    _rhs_into,
)

# scipy's DOP853 tableau (vendored: dop853_coefficients.py, Hairer's coefficients):
# stages 0-11 and the solution weights, the embedded 5th- and 3rd-order error weights,
# and the three extra stages and the D matrix of the 7th-order dense output.
DOP_A = np.ascontiguousarray(_dop.A, dtype=float)  # (16, 16)


DOP_B = np.ascontiguousarray(_dop.B, dtype=float)  # (12,)
DOP_C = np.ascontiguousarray(_dop.C, dtype=float)  # (16,)
DOP_E3 = np.ascontiguousarray(_dop.E3, dtype=float)  # (13,)
DOP_E5 = np.ascontiguousarray(_dop.E5, dtype=float)  # (13,)
DOP_D = np.ascontiguousarray(_dop.D, dtype=float)  # (4, 16)
DOP_STAGES = _dop.N_STAGES  # 12
DOP_ERROR_EXPONENT = -1.0 / 8.0  # scipy: -1 / (error_estimator_order + 1), order 7
DOP_SAFETY, DOP_MIN_FACTOR, DOP_MAX_FACTOR = 0.9, 0.2, 10.0  # scipy.integrate._ivp.rk
DOP_SCAN_POINTS = 4  # scipy_ivp.SCAN_POINTS: the event scan grid of a step


@jit
def _rms_norm(v):
    total = 0.0
    for i in range(v.shape[0]):
        total += v[i] * v[i]
    return math.sqrt(total / v.shape[0])


@jit
def dop853_initial_step(
    t0: float, y0: np.ndarray, f0: np.ndarray, t_bound: float, pars: np.ndarray, regime: int,
    rtol: float, atol: float,
) -> float:  # fmt: skip
    """scipy's ``select_initial_step`` (Hairer, Norsett, Wanner II.4) for DOP853 (order 7)."""
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0
    scaled = np.empty(4)
    for i in range(4):
        scaled[i] = y0[i] / (atol + abs(y0[i]) * rtol)
    d0 = _rms_norm(scaled)
    for i in range(4):
        scaled[i] = f0[i] / (atol + abs(y0[i]) * rtol)
    d1 = _rms_norm(scaled)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, interval)
    y1 = np.empty(4)
    for i in range(4):
        y1[i] = y0[i] + h0 * f0[i]
    f1 = np.empty(4)
    _rhs_into(t0 + h0, y1, pars, regime, f1)
    for i in range(4):
        scaled[i] = (f1[i] - f0[i]) / (atol + abs(y0[i]) * rtol)
    d2 = _rms_norm(scaled) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1, interval)


@jit
def _dop853_try(t, y, h, pars, regime, Kst, y_new, tmp):
    """One DOP853 step of length h from (t, y) with Kst[0] = f(t, y): y_new, Kst[1:13]."""
    for s in range(1, DOP_STAGES):
        for i in range(4):
            acc = 0.0
            for j in range(s):
                acc += DOP_A[s, j] * Kst[j, i]
            tmp[i] = y[i] + h * acc
        _rhs_into(t + DOP_C[s] * h, tmp, pars, regime, Kst[s])
    for i in range(4):
        acc = 0.0
        for j in range(DOP_STAGES):
            acc += DOP_B[j] * Kst[j, i]
        y_new[i] = y[i] + h * acc
    _rhs_into(t + h, y_new, pars, regime, Kst[DOP_STAGES])


@jit
def _dop853_error_norm(Kst, h, y, y_new, rtol, atol):
    """scipy's DOP853._estimate_error_norm (the 5th/3rd-order blend)."""
    e5 = 0.0
    e3 = 0.0
    for i in range(4):
        scale = atol + max(abs(y[i]), abs(y_new[i])) * rtol
        a5 = 0.0
        a3 = 0.0
        for j in range(DOP_STAGES + 1):
            a5 += DOP_E5[j] * Kst[j, i]
            a3 += DOP_E3[j] * Kst[j, i]
        e5 += (a5 / scale) ** 2
        e3 += (a3 / scale) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * 4.0)


@jit
def _dop853_dense_coefficients(t_old, h, y_old, y_new, pars, regime, Kst, F, tmp):
    """The 7th-order dense output of an accepted step (scipy's Dop853DenseOutput F)."""
    for s in range(DOP_STAGES + 1, Kst.shape[0]):
        for i in range(4):
            acc = 0.0
            for j in range(s):
                acc += DOP_A[s, j] * Kst[j, i]
            tmp[i] = y_old[i] + h * acc
        _rhs_into(t_old + DOP_C[s] * h, tmp, pars, regime, Kst[s])
    for i in range(4):
        delta = y_new[i] - y_old[i]
        F[0, i] = delta
        F[1, i] = h * Kst[0, i] - delta
        F[2, i] = 2.0 * delta - h * (Kst[DOP_STAGES, i] + Kst[0, i])
        for r in range(4):
            acc = 0.0
            for j in range(Kst.shape[0]):
                acc += DOP_D[r, j] * Kst[j, i]
            F[3 + r, i] = h * acc


@jit
def _dop853_dense_at(t, t_old, h, y_old, F, out):
    x = (t - t_old) / h
    for i in range(4):
        acc = 0.0
        for n in range(F.shape[0]):
            acc += F[F.shape[0] - 1 - n, i]
            acc *= x if n % 2 == 0 else 1.0 - x
        out[i] = acc + y_old[i]


@jit
def dop853_dense_point(
    t: float, t_old: float, h: float, y_old: np.ndarray, F: np.ndarray
) -> np.ndarray:
    """The dense output at one time t: the state (4,)."""
    out = np.empty(4)
    _dop853_dense_at(t, t_old, h, y_old, F, out)
    return out


@jit
def dop853_dense(
    t: np.ndarray, t_old: float, h: float, y_old: np.ndarray, F: np.ndarray
) -> np.ndarray:
    """The dense output at the times t (n,): states (4, n), as scipy's Dop853DenseOutput."""
    out = np.empty((4, t.shape[0]))
    row = np.empty(4)
    for k in range(t.shape[0]):
        _dop853_dense_at(t[k], t_old, h, y_old, F, row)
        for i in range(4):
            out[i, k] = row[i]
    return out

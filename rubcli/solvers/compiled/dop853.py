"""scipy's DOP853 step, compiled: tableau, step, error norm, dense output, initial step.

Each function is scipy.integrate.DOP853's algorithm with scipy's coefficients (vendored
in ``dop853_coefficients.py``): the same stages, the 5th/3rd-order error blend, the
7th-order dense output and Hairer's initial step, so that for the same rtol/atol the
compiled loops take scipy's steps. The steps are built per right-hand side
(``dop853_step``): the rotor's four states (``rhs._rhs_into``, ``dop853-jit``) and the
extended systems' (``extended_loop.dop853_loop``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from rubcli.solvers import dop853_coefficients as _dop
from rubcli.solvers.compiled.jit import (
    jit,
    jit_loop,
)
from rubcli.solvers.compiled.rhs import (
    _rhs_into,
    _rhs_paper_into,
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


def dop853_step(
    rhs_into: Callable[..., None], n_states: int, counted: bool = True
) -> tuple[Callable[..., float], Callable[..., tuple], Callable[..., int]]:
    """scipy's DOP853 on the right-hand side ``rhs_into(t, y, ctx, regime, out)`` of
    ``n_states`` states, compiled: ``(initial_step, accepted_step, dense_coefficients)``.

    The right-hand side is a closure constant (as in ``events.event_search``), so the
    three functions are compiled once per right-hand side and stay cachable; the state
    count is a compile-time constant, so the four-state loops compile as when it was
    written out; ``n_states = 0`` takes the state's size at run time (the composed
    machine's system, ``rubcli.system``). ``counted = False`` compiles the step, its
    attempt, error norm and dense output without numba's reference counting (they
    allocate nothing): a system whose context is a tuple of many arrays then does not
    count references to each of them at every stage."""
    N = n_states
    step_jit = jit if counted else jit_loop

    def initial_step(
        t0: float, y0: np.ndarray, f0: np.ndarray, t_bound: float, ctx: Any, regime: int,
        rtol: float, atol: float,
    ) -> float:  # fmt: skip
        """scipy's ``select_initial_step`` (Hairer, Norsett, Wanner II.4), order 7."""
        n = N if N > 0 else y0.shape[0]
        interval = abs(t_bound - t0)
        if interval == 0.0:
            return 0.0
        scaled = np.empty(n)
        for i in range(n):
            scaled[i] = y0[i] / (atol + abs(y0[i]) * rtol)
        d0 = _rms_norm(scaled)
        for i in range(n):
            scaled[i] = f0[i] / (atol + abs(y0[i]) * rtol)
        d1 = _rms_norm(scaled)
        h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
        h0 = min(h0, interval)
        y1 = np.empty(n)
        for i in range(n):
            y1[i] = y0[i] + h0 * f0[i]
        f1 = np.empty(n)
        rhs_into(t0 + h0, y1, ctx, regime, f1)
        for i in range(n):
            scaled[i] = (f1[i] - f0[i]) / (atol + abs(y0[i]) * rtol)
        d2 = _rms_norm(scaled) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
        return min(100.0 * h0, h1, interval)

    # The stages are written out in ``attempt`` and ``dense_coefficients``, not called
    # through one function: a stage as a call (even inlined in numba's IR) made the paper
    # machine's dop853-jit about 15 % slower per step.
    def attempt(
        t: float, y: np.ndarray, h: float, ctx: Any, regime: int, Kst: np.ndarray,
        y_new: np.ndarray, tmp: np.ndarray,
    ) -> None:  # fmt: skip
        """One step of length h from (t, y) with Kst[0] = f(t, y): y_new, Kst[1:13]."""
        n = N if N > 0 else y.shape[0]
        for s in range(1, DOP_STAGES):
            for i in range(n):
                acc = 0.0
                for j in range(s):
                    acc += DOP_A[s, j] * Kst[j, i]
                tmp[i] = y[i] + h * acc
            rhs_into(t + DOP_C[s] * h, tmp, ctx, regime, Kst[s])
        for i in range(n):
            acc = 0.0
            for j in range(DOP_STAGES):
                acc += DOP_B[j] * Kst[j, i]
            y_new[i] = y[i] + h * acc
        rhs_into(t + h, y_new, ctx, regime, Kst[DOP_STAGES])

    def error_norm(
        Kst: np.ndarray, h: float, y: np.ndarray, y_new: np.ndarray, rtol: float, atol: float
    ) -> float:
        """scipy's DOP853._estimate_error_norm (the 5th/3rd-order blend)."""
        n = N if N > 0 else y.shape[0]
        e5 = 0.0
        e3 = 0.0
        for i in range(n):
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
        return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)

    def accepted_step(
        tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, ctx: Any,
        regime: int, rtol: float, atol: float, Kst: np.ndarray, y_new: np.ndarray,
        tmp: np.ndarray,
    ) -> tuple[float, float, float, int]:  # fmt: skip
        """scipy's step loop from (tau, y), f = f(tau, y), proposed |h| ``h_abs``: tries
        and rejects until a step is accepted. Returns ``(t_new, h, h_abs, nfev)``: the
        accepted step to t_new, of length h, in y_new with the stages in Kst, and the
        next proposal; h = 0 if the step fell below scipy's minimum (10 ulp of tau)."""
        n = N if N > 0 else y.shape[0]
        min_step = 10.0 * abs(np.nextafter(tau, np.inf) - tau)
        h_abs = max(h_abs, min_step)
        rejected = False
        nfev = 0
        while True:
            if h_abs < min_step:
                return tau, 0.0, h_abs, nfev
            t_new = min(tau + h_abs, t_end)
            h = t_new - tau
            h_abs = abs(h)
            for i in range(n):
                Kst[0, i] = f[i]
            attempt(tau, y, h, ctx, regime, Kst, y_new, tmp)
            nfev += DOP_STAGES
            error = error_norm(Kst, h, y, y_new, rtol, atol)
            if error < 1.0:
                if error == 0.0:
                    factor = DOP_MAX_FACTOR
                else:
                    factor = min(DOP_MAX_FACTOR, DOP_SAFETY * error**DOP_ERROR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                return t_new, h, h_abs * factor, nfev
            if not math.isfinite(error):
                h_abs *= DOP_MIN_FACTOR
            else:
                h_abs *= max(DOP_MIN_FACTOR, DOP_SAFETY * error**DOP_ERROR_EXPONENT)
            rejected = True

    def dense_coefficients(
        t_old: float, h: float, y_old: np.ndarray, y_new: np.ndarray, ctx: Any, regime: int,
        Kst: np.ndarray, F: np.ndarray, tmp: np.ndarray,
    ) -> int:  # fmt: skip
        """The 7th-order dense output of an accepted step (scipy's Dop853DenseOutput F);
        returns the evaluations of the right-hand side it took."""
        n = N if N > 0 else y_old.shape[0]
        for s in range(DOP_STAGES + 1, Kst.shape[0]):
            for i in range(n):
                acc = 0.0
                for j in range(s):
                    acc += DOP_A[s, j] * Kst[j, i]
                tmp[i] = y_old[i] + h * acc
            rhs_into(t_old + DOP_C[s] * h, tmp, ctx, regime, Kst[s])
        for i in range(n):
            delta = y_new[i] - y_old[i]
            F[0, i] = delta
            F[1, i] = h * Kst[0, i] - delta
            F[2, i] = 2.0 * delta - h * (Kst[DOP_STAGES, i] + Kst[0, i])
            for r in range(4):
                acc = 0.0
                for j in range(Kst.shape[0]):
                    acc += DOP_D[r, j] * Kst[j, i]
                F[3 + r, i] = h * acc
        return Kst.shape[0] - DOP_STAGES - 1

    attempt = step_jit(attempt)
    error_norm = step_jit(error_norm)
    return jit(initial_step), step_jit(accepted_step), step_jit(dense_coefficients)


# the rotor's four states (``dop853-jit``; ctx = the parameter record): any machine, and
# the paper's machine at a constant speed without a branch in the stages
dop853_initial_step, _dop853_accepted_step, _dop853_dense_coefficients = dop853_step(_rhs_into, 4)
_, _paper_accepted_step, _paper_dense_coefficients = dop853_step(_rhs_paper_into, 4)


@jit
def _dop853_dense_at(t, t_old, h, y_old, F, out):
    x = (t - t_old) / h
    for i in range(y_old.shape[0]):
        acc = 0.0
        for n in range(F.shape[0]):
            acc += F[F.shape[0] - 1 - n, i]
            acc *= x if n % 2 == 0 else 1.0 - x
        out[i] = acc + y_old[i]


@jit
def dop853_dense_point(
    t: float, t_old: float, h: float, y_old: np.ndarray, F: np.ndarray
) -> np.ndarray:
    """The dense output at one time t: the state (4,) or (6,), as y_old."""
    out = np.empty(y_old.shape[0])
    _dop853_dense_at(t, t_old, h, y_old, F, out)
    return out


@jit
def dop853_dense(
    t: np.ndarray, t_old: float, h: float, y_old: np.ndarray, F: np.ndarray
) -> np.ndarray:
    """The dense output at the times t (n,): states (4 or 6, n), as scipy's
    Dop853DenseOutput."""
    m = y_old.shape[0]
    out = np.empty((m, t.shape[0]))
    row = np.empty(m)
    for k in range(t.shape[0]):
        _dop853_dense_at(t[k], t_old, h, y_old, F, row)
        for i in range(m):
            out[i, k] = row[i]
    return out

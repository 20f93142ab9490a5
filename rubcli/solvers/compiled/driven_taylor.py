"""``taylor`` on the driven rotor (``rubcli.drive``): the six states' Taylor series, the
step, and the step loop with the drive's event pre-check.

The series follow ``drive.driven_rhs_entries`` (and, in stick, ``rolling_projection``
and ``stick_torque_value``) operation by operation, each operation by its recurrence
(Moore 1966; Jorba & Zou 2005): products by Cauchy sums, quotients by the division rule
(``_divide``: ``b_0 c_k = a_k - sum_{j>=1} b_j c_{k-j}``), ``z = sqrt(q)`` by
``2 z_0 z_k = q_k - sum_{j=1}^{k-1} z_j z_{k-j}``, and ``(cos p, sin p)`` with
``p' = w`` by ``k c_k = -sum_j s_j w_{k-1-j}``, ``k s_k = sum_j c_j w_{k-1-j}``. The
motor's torque is a line in the speed (``motor_line``): the linear characteristic, or
the piece of a table the speed is in; a step ends where the speed reaches the piece's
end, so that no series carries a table's corner.

The order, the step (the last two terms below the state tolerance; the phase, which
grows without bound, is left out of the state's scale) and the scan grid (eight
intervals a period of the fastest frequency, the spin's from the larger end speed) are
``taylor``'s rules. The step runs in the extended systems' one loop
(``extended_loop.step_loop``), which locates the events on the step's polynomial with
the one event search, as for ``dop853-jit``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rubcli.drive import D_INERTIA, motor_line
from rubcli.model import FREE, P_ECC, P_K, P_MU, P_NU, P_RP, STICK, friction_sign
from rubcli.solvers.compiled.drive import N_STATES, drive_into, drive_project
from rubcli.solvers.compiled.event_loop import STOP_NONE, no_restart
from rubcli.solvers.compiled.extended_loop import keep_nothing, step_loop
from rubcli.solvers.compiled.jit import STOP_PYTHON, STOP_SMALL_STEP, jit, jit_inline
from rubcli.solvers.compiled.taylor import (
    MAX_ORDER,
    MAX_SCAN,
    RECIPROCALS,
    STEP_SAFETY_EXPONENT,
    _cauchy,
    scan_intervals,
)

SERIES_ROWS = 40  # work rows of the series (the stick's intermediate quantities)
TABLE_GRID = 32  # points a step's speed is checked at against the motor table's corners


@jit
def _divide(out, a, b, k):
    """Order k of out = a / b (orders below k filled)."""
    acc = a[k]
    for j in range(1, k + 1):
        acc -= b[j] * out[k - j]
    out[k] = acc / b[0]


@jit
def _root(out, q, k):
    """Order k of out = sqrt(q) (orders below k filled)."""
    if k == 0:
        out[0] = math.sqrt(q[0])
        return
    acc = q[k]
    for j in range(1, k):
        acc -= out[j] * out[k - j]
    out[k] = acc / (2.0 * out[0])


@jit
def _phase_terms(c, s, dp, k):
    """Order k of (cos p, sin p) with p' = dp (orders below k of all three filled)."""
    if k == 0:
        return
    cc = 0.0
    ss = 0.0
    for j in range(k):
        cc += s[j] * dp[k - 1 - j]
        ss += c[j] * dp[k - 1 - j]
    c[k] = -cc * RECIPROCALS[k]
    s[k] = ss * RECIPROCALS[k]


@jit
def driven_series(
    s0: np.ndarray, pars: np.ndarray, drive: np.ndarray, regime: int, order: int,
    C: np.ndarray, R: np.ndarray, torque: float, slope: float,
) -> None:  # fmt: skip
    """The Taylor coefficients C[:, 0..order] (rows x, y, vx, vy, p, w) of the driven
    rotor's regime-locked solution through ``s0``, the motor's torque less drag the line
    ``torque + slope w`` (``motor_line``); ``R`` (SERIES_ROWS, MAX_ORDER + 1) is work
    space (module docstring)."""
    nu, K, Rp, e = pars[P_NU], pars[P_K], pars[P_RP], pars[P_ECC]
    j = drive[D_INERTIA]
    je = j - e * e
    mu_c = pars[P_MU] * friction_sign(regime) if regime != FREE and regime != STICK else 0.0
    x, y, vx, vy, p, w = C[0], C[1], C[2], C[3], C[4], C[5]
    for i in range(N_STATES):
        C[i, 0] = s0[i]
    c, sn, fx, fy, q, z, nx, ny = R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7]
    normal, T, pdd, w2 = R[8], R[9], R[10], R[11]
    c[0], sn[0] = math.cos(p[0]), math.sin(p[0])
    stick = regime == STICK
    contact = regime != FREE
    # stick: the velocities projected onto the rolling constraint (rolling_projection)
    ht, hr, up, ux, uy, vr, den, scale = R[12], R[13], R[14], R[15], R[16], R[17], R[18], R[19]
    vxd, vyd, wd = R[20], R[21], R[22]
    zd, rt, thd, A, B, num, dd = R[23], R[24], R[25], R[26], R[27], R[28], R[29]
    f0x, f0y = R[30], R[31]  # the force without the rolling friction (stick_torque_value)
    for k in range(order):
        one = 1.0 if k == 0 else 0.0
        if contact:
            acc = 0.0
            for m in range(k + 1):
                acc += x[m] * x[k - m] + y[m] * y[k - m]
            q[k] = acc
            _root(z, q, k)
            _divide(nx, x, z, k)
            _divide(ny, y, z, k)
            normal[k] = K * (z[k] - one)
        if stick:
            _phase_terms(c, sn, wd, k)
            # h = (-ny, nx): t . h and r . h of the unbalance's directions
            ht[k] = _cauchy(ny, sn, k) + _cauchy(nx, c, k)
            hr[k] = -_cauchy(ny, c, k) + _cauchy(nx, sn, k)
            up[k] = (Rp * one - e * ht[k]) / je
            ux[k] = -ny[k] + e * _cauchy(up, sn, k)
            uy[k] = nx[k] - e * _cauchy(up, c, k)
            vr[k] = Rp * w[k] - _cauchy(ny, vx, k) + _cauchy(nx, vy, k)
            den[k] = -_cauchy(ny, ux, k) + _cauchy(nx, uy, k) + Rp * up[k]
            _divide(scale, vr, den, k)
            vxd[k] = vx[k] - _cauchy(scale, ux, k)
            vyd[k] = vy[k] - _cauchy(scale, uy, k)
            wd[k] = w[k] - _cauchy(scale, up, k)
            # stick_torque_value on the projected state
            f0x[k] = -x[k] - 2.0 * nu * vxd[k] - _cauchy(normal, nx, k)
            f0y[k] = -y[k] - 2.0 * nu * vyd[k] - _cauchy(normal, ny, k)
            zd[k] = _cauchy(nx, vxd, k) + _cauchy(ny, vyd, k)
            rt[k] = _cauchy(nx, vyd, k) - _cauchy(ny, vxd, k)
            _divide(thd, rt, z, k)
            w2[k] = _cauchy(wd, wd, k)
            A[k] = (
                -_cauchy(ny, f0x, k) + _cauchy(nx, f0y, k) + e * _cauchy(w2, hr, k)
                - _cauchy(thd, zd, k)
            )  # fmt: skip
            B[k] = Rp * one - e * ht[k]
            tf = -_cauchy(sn, f0x, k) + _cauchy(c, f0y, k)
            num[k] = torque * one + slope * wd[k] - e * tf - _cauchy(B, A, k)
            dd[k] = je * one + _cauchy(B, B, k)
            _divide(pdd, num, dd, k)
            T[k] = A[k] + _cauchy(B, pdd, k)
            # the rolling friction T along -theta-hat: fx += T y / z, fy -= T x / z
            fx[k] = f0x[k] + _cauchy(T, ny, k)
            fy[k] = f0y[k] - _cauchy(T, nx, k)
            dx, dy, dp = vxd[k], vyd[k], wd[k]
        else:
            _phase_terms(c, sn, w, k)
            fx[k] = -x[k] - 2.0 * nu * vx[k]
            fy[k] = -y[k] - 2.0 * nu * vy[k]
            if contact:
                T[k] = mu_c * normal[k]
                fx[k] -= _cauchy(normal, nx, k) - _cauchy(T, ny, k)
                fy[k] -= _cauchy(normal, ny, k) + _cauchy(T, nx, k)
            else:
                T[k] = 0.0
            tf = -_cauchy(sn, fx, k) + _cauchy(c, fy, k)
            pdd[k] = (torque * one + slope * w[k] - Rp * T[k] - e * tf) / je
            w2[k] = _cauchy(w, w, k)
            dx, dy, dp = vx[k], vy[k], w[k]
        ax = fx[k] + e * _cauchy(w2, c, k) + e * _cauchy(pdd, sn, k)
        ay = fy[k] + e * _cauchy(w2, sn, k) - e * _cauchy(pdd, c, k)
        inv = RECIPROCALS[k + 1]
        C[0, k + 1] = dx * inv
        C[1, k + 1] = dy * inv
        C[2, k + 1] = ax * inv
        C[3, k + 1] = ay * inv
        C[4, k + 1] = dp * inv
        C[5, k + 1] = pdd[k] * inv


@jit
def _speed_at(C, order, s):
    """The speed's polynomial (row 5) at s from the step's start (Horner)."""
    v = C[5, order]
    for k in range(order - 1, -1, -1):
        v = v * s + C[5, k]
    return v


@jit
def _leaves_at(C, order, h, low, high, grid_points):
    """The first s in (0, h] where the speed's polynomial leaves [low, high] (on a grid
    of ``grid_points`` intervals, then by bisection to round-off), or h if it stays
    (at once where the polynomial's spread, sum_k |w_k| h^k, keeps it inside)."""
    spread = 0.0
    p = 1.0
    for k in range(1, order + 1):
        p *= h
        spread += abs(C[5, k]) * p
    if low < C[5, 0] - spread and C[5, 0] + spread < high:
        return h
    previous = 0.0
    for m in range(1, grid_points + 1):
        s = h * m / grid_points
        w = _speed_at(C, order, s)
        if w < low or w > high:
            a, b = previous, s
            for _ in range(200):
                mid = 0.5 * (a + b)
                if mid <= a or mid >= b:
                    break
                wm = _speed_at(C, order, mid)
                if wm < low or wm > high:
                    b = mid
                else:
                    a = mid
            return b
        previous = s
    return h


@jit
def extended_step_size(C: np.ndarray, order: int, rtol: float, atol: float) -> float:
    """``taylor.step_size`` for an extended system's states (the rows of C): the last
    two terms below the state tolerance max(atol, rtol |s_0|), the phase (entry 4) left
    out of |s_0| (it grows without bound)."""
    scale = 0.0
    for i in range(C.shape[0]):
        if i != 4:
            scale = max(scale, abs(C[i, 0]))
    eps = max(atol, rtol * scale)
    h = math.inf
    for k in (order - 1, order):
        norm = 0.0
        for i in range(C.shape[0]):
            norm = max(norm, abs(C[i, k]))
        if norm > 0.0:
            h = min(h, (eps / norm) ** RECIPROCALS[k])
    return h * math.exp(-STEP_SAFETY_EXPONENT * RECIPROCALS[order - 1])


@jit
def polynomial_at(t: float, dense: Any, row: np.ndarray) -> None:
    """A Taylor step's polynomial at t (Horner), dense = (t0, C, order): every row of C."""
    t0, C, order = dense
    dt = t - t0
    for i in range(C.shape[0]):
        v = C[i, order]
        for k in range(order - 1, -1, -1):
            v = v * dt + C[i, k]
        row[i] = v


@jit
def polynomial_values(t: np.ndarray, t0: float, C: np.ndarray, order: int) -> np.ndarray:
    """A Taylor step's polynomial at the times t (n,): states (rows of C, n)."""
    out = np.empty((C.shape[0], t.shape[0]))
    row = np.empty(C.shape[0])
    for m in range(t.shape[0]):
        polynomial_at(t[m], (t0, C, order), row)
        for i in range(C.shape[0]):
            out[i, m] = row[i]
    return out


@jit_inline
def _step(tau, y, t_end, ctx, regime, m, c, y_new):
    """``extended_loop.step_loop``'s step: the series from the motor's line at the
    speed (the piece below on a table's corner while slowing), ``taylor``'s step size,
    cut where the speed reaches a corner of the table, and the end state."""
    C, R = m[0], m[1]
    order, rtol, atol = c[0], c[1], c[2]
    pars, drive, table_speed, table_torque = ctx[0], ctx[1], ctx[2], ctx[3]
    torque, slope, low, high = motor_line(y[5], True, drive, table_speed, table_torque)
    driven_series(y, pars, drive, regime, order, C, R, torque, slope)
    if y[5] == low and C[5, 1] < 0.0:  # on a table's corner, slowing: the piece below
        torque, slope, low, high = motor_line(y[5], False, drive, table_speed, table_torque)
        driven_series(y, pars, drive, regime, order, C, R, torque, slope)
    h = extended_step_size(C, order, rtol, atol)
    t_new = min(tau + h, t_end)
    h = t_new - tau
    if table_speed.shape[0] > 0:  # the step ends where the speed reaches a corner
        cut = _leaves_at(C, order, h, low, high, TABLE_GRID)
        if cut < h:
            h = cut
            t_new = tau + h
    if not (h >= 10.0 * abs(np.nextafter(tau, np.inf) - tau)):
        return t_new, STOP_SMALL_STEP if math.isfinite(h) else STOP_PYTHON, c
    polynomial_at(t_new, (tau, C, order), y_new)
    return t_new, STOP_NONE, (order, rtol, atol, h)


@jit_inline
def _intervals(tau, t_new, y, y_new, ctx, regime, m, c):
    """``taylor``'s scan intervals of the step taken (``c[3]``: its length, cut at a
    table's corner), the spin's from the larger end speed, into ``info[0]`` (for
    Python's dense output of the step the loop stops in)."""
    n = scan_intervals(c[3], regime, ctx[0], y, max(abs(y[5]), abs(y_new[5])))
    m[2][0] = n
    return n


@jit_inline
def _dense(tau, y, m, c):
    """The step's polynomial: (its start, the coefficients, the order)."""
    return tau, m[0], c[0]


_loop = step_loop(_step, _intervals, keep_nothing, no_restart, _dense, polynomial_at, drive_into,
                  drive_project, N_STATES, MAX_SCAN)  # fmt: skip


@jit
def advance_driven_taylor(
    tau: float, y: np.ndarray, t_end: float,
    ctx: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], regime: int, order: int,
    rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    band: float, found: np.ndarray, C: np.ndarray, info: np.ndarray, events: tuple,
    applies: bool,
) -> tuple[float, float, int, int, int, int, int, bool]:  # fmt: skip
    """Taylor steps of the driven rotor with their events (``extended_loop.step_loop``:
    applied in the loop and recorded in ``events``, or with ``applies`` False returned
    at in ``found``). A step handed to Python (reason EVENT) leaves its coefficients in
    ``C`` and its scan intervals in ``info[0]``. Returns ``(tau, t_new, k, steps,
    reason, regime, n_events, at_event)``."""
    m = (C, np.zeros((SERIES_ROWS, MAX_ORDER + 1)), info)
    tau, t_new, k, steps, reason, regime, n_events, at_event, _ = _loop(
        tau, y, t_end, ctx, regime, t_eval, out_states, out_regimes, k, max_steps,
        starts, band, found, np.empty(N_STATES), events, applies, m, (order, rtol, atol, 0.0),
    )  # fmt: skip
    return tau, t_new, k, steps, reason, regime, n_events, at_event

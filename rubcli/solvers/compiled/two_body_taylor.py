"""``taylor`` on the stator with its own mass (``rubcli.stator``): the ten states' Taylor
series, the step, and the extended systems' step loop.

The series follow ``stator.two_body_entries`` (and, in stick, ``two_body_projection``)
operation by operation, each by its recurrence (Moore 1966; Jorba & Zou 2005), as
``driven_taylor``'s: products by Cauchy sums, quotients by the division rule, ``z =
sqrt(q)``, and ``(cos p, sin p)`` with ``p' = w`` (the constant speed, a state). The
order, the step (the last two terms below the state tolerance; the phase left out of
the state's scale) and the scan grid are ``taylor``'s rules, the grid's frequency bound
with the ring's own frequency and the contact's on the ring added. The step runs in the
extended systems' one loop (``extended_loop.step_loop``), which locates the events on
the step's polynomial with the one event search.
"""

from __future__ import annotations

import math

import numpy as np

from rubcli.model import (
    FREE,
    P_DXX,
    P_DXY,
    P_DYX,
    P_DYY,
    P_ECC,
    P_GX,
    P_GY,
    P_K,
    P_MU,
    P_NU,
    P_RP,
    P_SXX,
    P_SXY,
    P_SYX,
    P_SYY,
    STICK,
    friction_sign,
)
from rubcli.solvers.compiled.driven_taylor import (
    _divide,
    _phase_terms,
    _root,
    extended_step_size,
    polynomial_at,
)
from rubcli.solvers.compiled.event_loop import STOP_NONE, no_restart
from rubcli.solvers.compiled.extended_loop import keep_nothing, step_loop
from rubcli.solvers.compiled.jit import (
    STOP_PYTHON,
    STOP_SMALL_STEP,
    jit,
    jit_inline,
)
from rubcli.solvers.compiled.taylor import (
    MAX_ORDER,
    MAX_SCAN,
    RECIPROCALS,
    _cauchy,
    scan_intervals,
)
from rubcli.solvers.compiled.two_body import two_body_into, two_body_project
from rubcli.stator import N_STATES, S_INV_MASS, S_KX, S_KY, S_NX, S_NY

SERIES_ROWS = 32  # work rows of the series


@jit
def two_body_series(
    s0: np.ndarray, pars: np.ndarray, st: np.ndarray, regime: int, order: int, C: np.ndarray,
    R: np.ndarray,
) -> None:  # fmt: skip
    """The Taylor coefficients C[:, 0..order] (rows x, y, vx, vy, p, w, u, v, u', v') of
    the two bodies' regime-locked solution through ``s0``; ``R`` (SERIES_ROWS, MAX_ORDER
    + 1) is work space (module docstring)."""
    nu, K, Rp, e = pars[P_NU], pars[P_K], pars[P_RP], pars[P_ECC]
    sxx, sxy, syx, syy = 1.0 + pars[P_SXX], pars[P_SXY], pars[P_SYX], 1.0 + pars[P_SYY]
    dxx, dxy, dyx, dyy = nu + pars[P_DXX], pars[P_DXY], pars[P_DYX], nu + pars[P_DYY]
    gx, gy = pars[P_GX], pars[P_GY]
    m_inv = st[S_INV_MASS]
    share = m_inv / (1.0 + m_inv)
    mu_c = pars[P_MU] * friction_sign(regime) if regime != FREE and regime != STICK else 0.0
    x, y, vx, vy, w = C[0], C[1], C[2], C[3], C[5]
    u, v, up, vp = C[6], C[7], C[8], C[9]
    for i in range(N_STATES):
        C[i, 0] = s0[i]
    c, sn, q, z, nx, ny, normal, T = R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7]
    w2, vxd, vyd, upd, vpd, change = R[8], R[9], R[10], R[11], R[12], R[13]
    ax0, ay0, bx0, by0, relt, dn, prod, pz = R[14], R[15], R[16], R[17], R[18], R[19], R[20], R[21]
    fx, fy = R[22], R[23]
    c[0], sn[0] = math.cos(C[4, 0]), math.sin(C[4, 0])
    stick = regime == STICK
    contact = regime != FREE
    for k in range(order):
        one = 1.0 if k == 0 else 0.0
        _phase_terms(c, sn, w, k)
        if contact:
            acc = 0.0
            for m in range(k + 1):
                acc += x[m] * x[k - m] + y[m] * y[k - m]
            q[k] = acc
            _root(z, q, k)
            _divide(nx, x, z, k)
            _divide(ny, y, z, k)
            normal[k] = K * (z[k] - one)
        if stick:  # the velocities projected onto v_r = 0 (two_body_projection)
            change[k] = -Rp * w[k] + _cauchy(ny, vx, k) - _cauchy(nx, vy, k)
            vxd[k] = vx[k] - _cauchy(change, ny, k)
            vyd[k] = vy[k] + _cauchy(change, nx, k)
            upd[k] = up[k] + share * _cauchy(change, ny, k)
            vpd[k] = vp[k] - share * _cauchy(change, nx, k)
        else:
            vxd[k], vyd[k], upd[k], vpd[k] = vx[k], vy[k], up[k], vp[k]
        w2[k] = _cauchy(w, w, k)
        wx, wy = x[k] + u[k], y[k] + v[k]  # the rotor from the support, less the offset
        wvx, wvy = vxd[k] + upd[k], vyd[k] + vpd[k]
        ax0[k] = (e * _cauchy(w2, c, k) + gx * one - (sxx * wx + sxy * wy)
                  - 2.0 * (dxx * wvx + dxy * wvy))  # fmt: skip
        ay0[k] = (e * _cauchy(w2, sn, k) + gy * one - (syx * wx + syy * wy)
                  - 2.0 * (dyx * wvx + dyy * wvy))  # fmt: skip
        bx0[k] = -(st[S_KX] * u[k] + 2.0 * st[S_NX] * upd[k]) * m_inv
        by0[k] = -(st[S_KY] * v[k] + 2.0 * st[S_NY] * vpd[k]) * m_inv
        ax, ay, bx, by = ax0[k], ay0[k], bx0[k], by0[k]
        if contact:
            if stick:
                relt[k] = -_cauchy(ny, ax0, k) + _cauchy(nx, ay0, k) + _cauchy(ny, bx0, k)
                relt[k] -= _cauchy(nx, by0, k)
                dn[k] = _cauchy(vxd, nx, k) + _cauchy(vyd, ny, k)
                prod[k] = -Rp * _cauchy(w, dn, k)  # (d' . t)(d' . n), d' . t = -Rp w
                _divide(pz, prod, z, k)
                T[k] = (relt[k] - pz[k]) / (1.0 + m_inv)
            else:
                T[k] = mu_c * normal[k]
            fx[k] = -_cauchy(normal, nx, k) + _cauchy(T, ny, k)
            fy[k] = -_cauchy(normal, ny, k) - _cauchy(T, nx, k)
            ax += fx[k]
            ay += fy[k]
            bx -= fx[k] * m_inv
            by -= fy[k] * m_inv
        inv = RECIPROCALS[k + 1]
        C[0, k + 1] = vxd[k] * inv
        C[1, k + 1] = vyd[k] * inv
        C[2, k + 1] = (ax - bx) * inv
        C[3, k + 1] = (ay - by) * inv
        C[4, k + 1] = w[k] * inv
        C[5, k + 1] = 0.0
        C[6, k + 1] = upd[k] * inv
        C[7, k + 1] = vpd[k] * inv
        C[8, k + 1] = bx * inv
        C[9, k + 1] = by * inv


@jit_inline
def _step(tau, y, t_end, ctx, regime, m, c, y_new):
    """``extended_loop.step_loop``'s step: the two bodies' series, ``taylor``'s step
    size and the end state."""
    C, R = m[0], m[1]
    order, rtol, atol, ring = c
    two_body_series(y, ctx[0], ctx[1], regime, order, C, R)
    h = extended_step_size(C, order, rtol, atol)
    t_new = min(tau + h, t_end)
    h = t_new - tau
    if not (h >= 10.0 * abs(np.nextafter(tau, np.inf) - tau)):
        return t_new, STOP_SMALL_STEP if math.isfinite(h) else STOP_PYTHON, c
    polynomial_at(t_new, (tau, C, order), y_new)
    return t_new, STOP_NONE, c


@jit_inline
def _intervals(tau, t_new, y, y_new, ctx, regime, m, c):
    """``taylor``'s scan intervals with the ring's own frequency and the contact's on
    it added to the spin, into ``info[0]`` (for Python's dense output of the step the
    loop stops in)."""
    n = scan_intervals(t_new - tau, regime, ctx[0], y, abs(y[5]) + c[3])
    m[2][0] = n
    return n


@jit_inline
def _dense(tau, y, m, c):
    """The step's polynomial: (its start, the coefficients, the order)."""
    return tau, m[0], c[0]


_loop = step_loop(_step, _intervals, keep_nothing, no_restart, _dense, polynomial_at, two_body_into,
                  two_body_project, N_STATES, MAX_SCAN)  # fmt: skip


@jit
def advance_two_body_taylor(
    tau: float, y: np.ndarray, t_end: float, ctx: tuple[np.ndarray, np.ndarray], regime: int,
    order: int, rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    band: float, found: np.ndarray, C: np.ndarray, info: np.ndarray, events: tuple,
    applies: bool,
) -> tuple[float, float, int, int, int, int, int, bool]:  # fmt: skip
    """Taylor steps of the two bodies with their events (``extended_loop.step_loop``:
    applied in the loop and recorded in ``events``, or with ``applies`` False returned
    at in ``found``). A step handed to Python (reason EVENT) leaves its coefficients in
    ``C`` and its scan intervals in ``info[0]``. Returns ``(tau, t_new, k, steps,
    reason, regime, n_events, at_event)``."""
    pars, st = ctx[0], ctx[1]
    # the scan grid's frequency bound: the spin, and the ring's own and the contact's on it
    m_inv = st[S_INV_MASS]
    ring = math.sqrt(max(st[S_KX], st[S_KY]) * m_inv) + math.sqrt(pars[P_K] * m_inv)
    m = (C, np.zeros((SERIES_ROWS, MAX_ORDER + 1)), info)
    tau, t_new, k, steps, reason, regime, n_events, at_event, _ = _loop(
        tau, y, t_end, ctx, regime, t_eval, out_states, out_regimes, k, max_steps,
        starts, band, found, np.empty(N_STATES), events, applies, m, (order, rtol, atol, ring),
    )  # fmt: skip
    return tau, t_new, k, steps, reason, regime, n_events, at_event

"""The composed machine's system, compiled: its right-hand side, station forces, stick
forces, projection onto rolling, energy rate and event functions, written once for every
machine (``docs/composed-machine.md``, "What is then written once").

The state is ``y = (q, v, W)``: the structure's ``n`` coordinates, their velocities, and
the work ``W`` done on the structure by everything but its conservative forces (so that
``E(t) - E(0) - W(t)`` is the energy balance's residual, ``rubcli.system.energy``).
Regimes per station (``model.FREE``, ``SLIP_POSITIVE``, ``SLIP_NEGATIVE``, ``STICK``) are
part of the context ``ctx`` (``SystemArrays.context``), so a DOP853 step sees the system
through ``rhs_into(t, y, ctx, regime, out)`` as every compiled system of rubcli does.

At a station, ``d = q[rotor] - q[stator] - offset`` (a rigid stator: ``q[stator] = 0``),
``z = |d|``, ``n = d / z``, ``t = J n``, ``d' = a n + b t``; penetration ``delta = z -
clearance``; slip ``v_r = radius Omega + b``; the force on the rotor point ``-F_N n - F_T
t`` (its reaction on the stator point), ``F_N`` the contact law's (``machine.contact``),
``F_T = mu sign(v_r) F_N`` while slipping. Stations in stick hold ``v_r = 0``: their
tangential forces ``T`` solve the small system of mobilities
``sum_s m_rs T_s = radius_r Omega' + g_r . a_free - a_r b_r / z_r``, ``m_rs = g_r^T M^-1
g_s`` with ``g_s = W_s t_s``, and the velocities are held on the rolling constraint by
the least change of kinetic energy, ``v + M^-1 sum_s g_s lambda_s`` with ``m lambda =
-v_r`` (the same mobilities).
"""

from __future__ import annotations

import math

import numpy as np
from numba.extending import register_jitable

from rubcli.cached_jit import njit
from rubcli.machine import contact
from rubcli.model import FREE, SLIP_POSITIVE, STICK, STICK_EXIT_MARGIN
from rubcli.solvers.compiled.jit import jit_loop as jit

# the small helpers, inlined into their callers in numba's IR (no call, no arrays passed)
inline = njit(nogil=True, _nrt=False, inline="always")

for _core in (contact.elastic_force, contact.normal_force, contact.stored_energy):
    register_jitable(_core)

# columns of a station's parameters (``SystemArrays.station_parameters``)
S_CX, S_CY, S_CLEARANCE, S_MU, S_RADIUS, S_LAW = 0, 1, 2, 3, 4, 5
# columns of a station's geometry (``_geometry``)
G_Z, G_NX, G_NY, G_TX, G_TY, G_A, G_B = 0, 1, 2, 3, 4, 5, 6
GEOMETRY_SIZE = 7
# columns of a station's values (``evaluate``'s ``vals``)
V_PENETRATION, V_SLIP, V_NORMAL, V_TANGENTIAL = 0, 1, 2, 3
VALUES_SIZE = 4
# rows of the work buffer before the stick stations' mobility vectors
W_VELOCITY, W_ACCELERATION = 0, 1
WORK_ROWS = 2
# positions in the context tuple (``SystemArrays.context``)
C_PARAMETERS, C_REGIMES, C_VALUES = 10, 12, 19
# the structure's flags (``SystemArrays.flags``): G apart from C (a speed that changes);
# G not skew (it then does work); K not symmetric (cross-coupling)
F_GYROSCOPIC, F_GYROSCOPIC_WORK, F_CROSS_COUPLED = 0, 1, 2
# evaluate's status
OK, SINGULAR = 0, 1


@inline
def speed_at(knots: np.ndarray, t: float) -> tuple[float, float, float]:
    """``(Omega, Omega', angle)`` at t of the piecewise-linear profile ``knots`` (rows
    time, speed, angle integral_0^t Omega at the knot), held outside its knots."""
    last = knots.shape[0] - 1
    if t <= knots[0, 0] or last == 0:
        return knots[0, 1], 0.0, knots[0, 2] + knots[0, 1] * (t - knots[0, 0])
    if t >= knots[last, 0]:
        return knots[last, 1], 0.0, knots[last, 2] + knots[last, 1] * (t - knots[last, 0])
    k = 0
    while knots[k + 1, 0] < t:
        k += 1
    dt = t - knots[k, 0]
    rate = (knots[k + 1, 1] - knots[k, 1]) / (knots[k + 1, 0] - knots[k, 0])
    return knots[k, 1] + rate * dt, rate, knots[k, 2] + knots[k, 1] * dt + 0.5 * rate * dt * dt


@inline
def _table_at(tw, tK, tC, omega, Kw, Cw):
    """The speed table's blocks at ``omega`` into ``Kw``, ``Cw``: linear between its
    speeds ``tw``, held beyond them (``machine.SpeedTable``)."""
    last = tw.shape[0] - 1
    k, s = 0, 0.0
    if last > 0 and omega > tw[0]:
        if omega >= tw[last]:
            k = last
        else:
            while tw[k + 1] <= omega:
                k += 1
            s = (omega - tw[k]) / (tw[k + 1] - tw[k])
    m = Kw.shape[0]
    for a in range(m):
        for c in range(m):
            if s > 0.0:
                Kw[a, c] = (1.0 - s) * tK[k, a, c] + s * tK[k + 1, a, c]
                Cw[a, c] = (1.0 - s) * tC[k, a, c] + s * tC[k + 1, a, c]
            else:
                Kw[a, c] = tK[k, a, c]
                Cw[a, c] = tC[k, a, c]


@inline
def _geometry(q, v, idx, par, s, geo):
    """Station s's relative position and velocity (``G_*`` columns of ``geo[s]``)."""
    dx = q[idx[s, 0]] - par[s, S_CX]
    dy = q[idx[s, 1]] - par[s, S_CY]
    wx = v[idx[s, 0]]
    wy = v[idx[s, 1]]
    if idx[s, 2] >= 0:
        dx -= q[idx[s, 2]]
        dy -= q[idx[s, 3]]
        wx -= v[idx[s, 2]]
        wy -= v[idx[s, 3]]
    z = math.hypot(dx, dy)
    if z > 0.0:
        nx, ny = dx / z, dy / z
    else:
        nx, ny = 1.0, 0.0
    geo[s, G_Z] = z
    geo[s, G_NX] = nx
    geo[s, G_NY] = ny
    geo[s, G_TX] = -ny
    geo[s, G_TY] = nx
    geo[s, G_A] = wx * nx + wy * ny
    geo[s, G_B] = -wx * ny + wy * nx


@inline
def _add_plane(vec, Minv, idx, s, fx, fy, into):
    """``into += Minv W_s (fx, fy)`` (``Minv`` None-like when ``vec`` is False: the
    plane force added to the coordinates themselves)."""
    ix, iy, jx, jy = idx[s, 0], idx[s, 1], idx[s, 2], idx[s, 3]
    n = into.shape[0]
    if vec:
        for i in range(n):
            acc = Minv[i, ix] * fx + Minv[i, iy] * fy
            if jx >= 0:
                acc -= Minv[i, jx] * fx + Minv[i, jy] * fy
            into[i] += acc
    else:
        into[ix] += fx
        into[iy] += fy
        if jx >= 0:
            into[jx] -= fx
            into[jy] -= fy


@inline
def _tangential_of(vec, idx, s, geo):
    """``g_s . vec = t_s . (W_s^T vec)``: the tangential part of station s's relative
    component of ``vec``."""
    ix, iy, jx, jy = idx[s, 0], idx[s, 1], idx[s, 2], idx[s, 3]
    wx, wy = vec[ix], vec[iy]
    if jx >= 0:
        wx -= vec[jx]
        wy -= vec[jy]
    return geo[s, G_TX] * wx + geo[s, G_TY] * wy


@inline
def _solve_small(A, b, k):
    """Solves ``A[:k, :k] x = b[:k]`` in place (x in b) by Gaussian elimination with
    partial pivoting; False if A is singular to working precision."""
    for c in range(k):
        p = c
        for r in range(c + 1, k):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if not abs(A[p, c]) > 0.0:
            return False
        if p != c:
            for j in range(k):
                A[c, j], A[p, j] = A[p, j], A[c, j]
            b[c], b[p] = b[p], b[c]
        for r in range(c + 1, k):
            factor = A[r, c] / A[c, c]
            for j in range(c, k):
                A[r, j] -= factor * A[c, j]
            b[r] -= factor * b[c]
    for c in range(k - 1, -1, -1):
        acc = b[c]
        for j in range(c + 1, k):
            acc -= A[c, j] * b[j]
        b[c] = acc / A[c, c]
    return True


@inline
def _stick_mobilities(Minv, idx, geo, regimes, work, stuck, mob):
    """The stick stations (into ``stuck``, their count returned), their mobility vectors
    ``M^-1 g_s`` (work rows from ``WORK_ROWS``) and mobilities ``mob``."""
    k = 0
    for s in range(regimes.shape[0]):
        if regimes[s] == STICK:
            stuck[k] = s
            k += 1
    for a in range(k):
        h = work[WORK_ROWS + a]
        h[:] = 0.0
        s = stuck[a]
        _add_plane(True, Minv, idx, s, geo[s, G_TX], geo[s, G_TY], h)
    for a in range(k):
        for c in range(k):
            mob[a, c] = _tangential_of(work[WORK_ROWS + c], idx, stuck[a], geo)
    return k


@jit
def evaluate(t: float, y: np.ndarray, ctx: tuple, out: np.ndarray, vals: np.ndarray) -> int:
    """The derivative of ``y = (q, v, W)`` into ``out`` and each station's penetration,
    slip, normal and tangential force into ``vals`` (``V_*``); returns ``OK`` or
    ``SINGULAR`` (the stick stations' mobilities are singular)."""
    (Minv, MinvK, MinvC, MinvG, Dsym, Gsym, Kanti, facc, unb, idx, par, knots, regimes, work,
     geo, mob, lhs, rhs, stuck, _, flags, tidx, tw, tK, tC, tKw, tCw, tf) = ctx  # fmt: skip
    n = Minv.shape[0]
    S = idx.shape[0]
    omega, omega_rate, angle = speed_at(knots, t)
    q = y[:n]
    v = work[W_VELOCITY]
    for i in range(n):
        v[i] = y[n + i]
    for s in range(S):
        _geometry(q, v, idx, par, s, geo)
    k = _stick_mobilities(Minv, idx, geo, regimes, work, stuck, mob)
    if k > 0:  # the velocities onto rolling: m lambda = -v_r
        for a in range(k):
            s = stuck[a]
            rhs[a] = -(par[s, S_RADIUS] * omega + geo[s, G_B])
            for c in range(k):
                lhs[a, c] = mob[a, c]
        if not _solve_small(lhs, rhs, k):
            return SINGULAR
        for a in range(k):
            h = work[WORK_ROWS + a]
            for i in range(n):
                v[i] += rhs[a] * h[i]
        for s in range(S):
            _geometry(q, v, idx, par, s, geo)
    # the linear structure and the unbalances (their forces on two coordinates each)
    acc = work[W_ACCELERATION]
    power = 0.0
    for i in range(n):
        a_i = facc[i]
        for j in range(n):
            a_i -= MinvK[i, j] * q[j] + MinvC[i, j] * v[j]
        acc[i] = a_i
    if flags[F_GYROSCOPIC]:  # a speed that changes: Omega G apart from C
        for i in range(n):
            a_i = 0.0
            for j in range(n):
                a_i += MinvG[i, j] * v[j]
            acc[i] -= omega * a_i
    if tidx.shape[0] > 0:  # the speed table's force -K(Omega) q_b - C(Omega) v_b, and its power
        _table_at(tw, tK, tC, omega, tKw, tCw)
        m_b = tidx.shape[0]
        for a in range(m_b):
            f_a = 0.0
            for c in range(m_b):
                f_a -= tKw[a, c] * q[tidx[c]] + tCw[a, c] * v[tidx[c]]
            tf[a] = f_a
            power += v[tidx[a]] * f_a
        for i in range(n):
            a_i = 0.0
            for a in range(m_b):
                a_i += Minv[i, tidx[a]] * tf[a]
            acc[i] += a_i
    for u in range(unb.shape[0]):
        p = unb[u, 3] + angle
        c, sn = math.cos(p), math.sin(p)
        scale = unb[u, 2]
        ix, iy = int(unb[u, 0]), int(unb[u, 1])
        fx = scale * (omega * omega * c + omega_rate * sn)
        fy = scale * (omega * omega * sn - omega_rate * c)
        for i in range(n):
            acc[i] += Minv[i, ix] * fx + Minv[i, iy] * fy
        power += v[ix] * fx + v[iy] * fy
    # the power of the damping (C's symmetric part, and G's if it is not skew) and of
    # the cross-coupling (K's antisymmetric part)
    for i in range(n):
        p_i = 0.0
        for j in range(n):
            p_i += Dsym[i, j] * v[j]
        if flags[F_GYROSCOPIC_WORK]:
            for j in range(n):
                p_i += omega * Gsym[i, j] * v[j]
        if flags[F_CROSS_COUPLED]:
            for j in range(n):
                p_i += Kanti[i, j] * q[j]
        power -= v[i] * p_i
    # the stations' normal forces and slip friction
    for s in range(S):
        pen = geo[s, G_Z] - par[s, S_CLEARANCE]
        slip = par[s, S_RADIUS] * omega + geo[s, G_B]
        vals[s, V_PENETRATION] = pen
        vals[s, V_SLIP] = slip
        vals[s, V_NORMAL] = 0.0
        vals[s, V_TANGENTIAL] = 0.0
        if regimes[s] == FREE:
            continue
        # in contact from delta = 0 on: a segment that starts on the surface (an entry)
        # has its damping force c z' from its first instant, not from the next one (a
        # jump at a step's start defeats radau's error estimate, which uses f there)
        normal = contact.normal_force(par, s, S_LAW, pen, geo[s, G_A]) if pen >= 0.0 else 0.0
        tangential = 0.0
        if regimes[s] != STICK:
            tangential = par[s, S_MU] * normal * (1.0 if regimes[s] == SLIP_POSITIVE else -1.0)
        fx = -normal * geo[s, G_NX] - tangential * geo[s, G_TX]
        fy = -normal * geo[s, G_NY] - tangential * geo[s, G_TY]
        _add_plane(True, Minv, idx, s, fx, fy, acc)
        elastic = contact.elastic_force(par, s, S_LAW, pen) if pen > 0.0 else 0.0
        power -= (normal - elastic) * geo[s, G_A] + tangential * geo[s, G_B]
        vals[s, V_NORMAL] = normal
        vals[s, V_TANGENTIAL] = tangential
    if k > 0:  # the stick forces: m T = radius Omega' + g . a - a b / z
        for a in range(k):
            s = stuck[a]
            rhs[a] = (
                par[s, S_RADIUS] * omega_rate
                + _tangential_of(acc, idx, s, geo)
                - geo[s, G_A] * geo[s, G_B] / geo[s, G_Z]
            )
            for c in range(k):
                lhs[a, c] = mob[a, c]
        if not _solve_small(lhs, rhs, k):
            return SINGULAR
        for a in range(k):
            s = stuck[a]
            h = work[WORK_ROWS + a]
            for i in range(n):
                acc[i] -= rhs[a] * h[i]
            power -= rhs[a] * geo[s, G_B]
            vals[s, V_TANGENTIAL] = rhs[a]
    for i in range(n):
        out[i] = v[i]
        out[n + i] = acc[i]
    out[2 * n] = power
    return OK


@jit
def rhs_into(t: float, y: np.ndarray, ctx: tuple, regime: int, out: np.ndarray) -> None:
    """``evaluate`` as DOP853's steps take a right-hand side (the station values into
    the context's last buffer; ``regime`` unused: the regimes are in ``ctx``). A singular
    stick system gives nan, which the step control rejects."""
    if evaluate(t, y, ctx, out, ctx[C_VALUES]) != OK:
        out[:] = np.nan


@jit
def event_functions(
    t: float, y: np.ndarray, ctx: tuple, out: np.ndarray, vals: np.ndarray, g: np.ndarray
) -> int:
    """Each station's two event functions into ``g`` (S, 2), positive while its regime
    holds: free ``clearance - z`` and 1; slipping ``z - clearance`` and ``sign v_r``
    (1 without friction); in stick ``z - clearance`` and the friction cone's margin
    ``mu F_N (1 + STICK_EXIT_MARGIN) - |T|``. Returns ``evaluate``'s status."""
    status = evaluate(t, y, ctx, out, vals)
    regimes = ctx[C_REGIMES]
    par = ctx[C_PARAMETERS]
    for s in range(regimes.shape[0]):
        r = regimes[s]
        pen = vals[s, V_PENETRATION]
        if r == FREE:
            g[s, 0] = -pen
            g[s, 1] = 1.0
        elif r == STICK:
            g[s, 0] = pen
            g[s, 1] = par[s, S_MU] * vals[s, V_NORMAL] * (1.0 + STICK_EXIT_MARGIN) - abs(
                vals[s, V_TANGENTIAL]
            )
        else:
            g[s, 0] = pen
            if par[s, S_MU] > 0.0:
                g[s, 1] = vals[s, V_SLIP] * (1.0 if r == SLIP_POSITIVE else -1.0)
            else:
                g[s, 1] = 1.0
    return status


@inline
def _difference_column(t, y, ctx, scale, j, jac, shifted, f_plus, f_minus):
    """Column j of the Jacobian by a central difference, step ``1e-6 max(|y_j|,
    scale[j])`` (``shifted`` holds y on entry and on return)."""
    m = y.shape[0]
    h = 1e-6 * max(abs(y[j]), scale[j])
    shifted[j] = y[j] + h
    rhs_into(t, shifted, ctx, 0, f_plus)
    shifted[j] = y[j] - h
    rhs_into(t, shifted, ctx, 0, f_minus)
    shifted[j] = y[j]
    for i in range(m):
        jac[i, j] = (f_plus[i] - f_minus[i]) / (2.0 * h)


@jit
def jacobian_into(
    t: float, y: np.ndarray, ctx: tuple, scale: np.ndarray, jac: np.ndarray,
    shifted: np.ndarray, f_plus: np.ndarray, f_minus: np.ndarray,
) -> None:  # fmt: skip
    """The right-hand side's Jacobian (m, m) into ``jac``, for the implicit methods.

    With no station in stick, a state that no station reads enters the derivative only
    through the linear structure, so its column is exact from the matrices (``q' = v``,
    ``v' = -M^-1 K q - M^-1 (C + Omega G) v``); the columns of the stations' coordinates
    are central differences (step ``1e-6 max(|y_j|, scale[j])``, ``scale``: a typical
    size of each state). A station in stick couples every state (its force holds the
    rolling constraint against the whole free acceleration): then every column is a
    difference. The work ``W`` is a state nothing depends on: its column is 0, and so is
    its row outside the differenced columns (Newton's iterate of W then follows the
    others' exactly, which is all an implicit step needs of it)."""
    (Minv, MinvK, MinvC, MinvG, _, _, _, _, _, idx, _, knots, regimes, _, _, _, _, _, _,
     _, flags, tidx, tw, tK, tC, tKw, tCw, _) = ctx  # fmt: skip
    m = y.shape[0]
    n = Minv.shape[0]
    for i in range(m):
        shifted[i] = y[i]
    jac[:, :] = 0.0
    stuck = False
    for s in range(regimes.shape[0]):
        if regimes[s] == STICK:
            stuck = True
    if stuck:
        for j in range(m - 1):
            _difference_column(t, y, ctx, scale, j, jac, shifted, f_plus, f_minus)
        return
    omega = speed_at(knots, t)[0]
    gyro = omega if flags[F_GYROSCOPIC] else 0.0
    for i in range(n):
        jac[i, n + i] = 1.0
        for j in range(n):
            jac[n + i, j] = -MinvK[i, j]
            jac[n + i, n + j] = -MinvC[i, j] - gyro * MinvG[i, j]
    m_b = tidx.shape[0]
    if m_b > 0:  # the speed table's blocks at this speed
        _table_at(tw, tK, tC, omega, tKw, tCw)
        for i in range(n):
            for c in range(m_b):
                kc, cc = 0.0, 0.0
                for a in range(m_b):
                    kc += Minv[i, tidx[a]] * tKw[a, c]
                    cc += Minv[i, tidx[a]] * tCw[a, c]
                jac[n + i, tidx[c]] -= kc
                jac[n + i, n + tidx[c]] -= cc
    for s in range(idx.shape[0]):
        for c in range(4):
            j = idx[s, c]
            if j >= 0:
                _difference_column(t, y, ctx, scale, j, jac, shifted, f_plus, f_minus)
                _difference_column(t, y, ctx, scale, n + j, jac, shifted, f_plus, f_minus)

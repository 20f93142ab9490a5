"""The compiled one-pass core of the energy balance (``analysis.energy.balance``).

``balance_pass`` walks the nodes of every smooth piece (``analysis.energy.regimes.piece_bounds``)
over the solution's own arrays, without copying them, and computes, node by node, what
``energy._interval_integrals`` and ``energy._coarse_estimate`` compute on whole arrays:
the powers, their central-difference rates along the motion, the corrected trapezoid
integrals and the every-other-node estimate of the quadrature error. The totals need
no memory that grows with the samples; the cumulative series are written only when
output arrays are given (the energy figure). The arithmetic is that of the numpy path,
operation by operation, so the two agree to round-off (tests/test_energy.py checks
1e-12 relative); the physics comes from the model's compilable cores
(``model.stick_friction_value``, ``model.friction_sign``).
"""

from __future__ import annotations

import numpy as np

from rubcli import model
from rubcli.cached_jit import njit
from rubcli.model import (
    N_PARAMS,
    P_DXX,
    P_DXY,
    P_DYX,
    P_DYY,
    P_E,
    P_ETA,
    P_K,
    P_MU,
    P_NU,
    P_PHI0,
    P_RP,
    P_SXX,
    P_SXY,
    P_SYX,
    P_SYY,
)

jit = njit(nogil=True)  # runs beside the CSV thread (io.Background)
# The per-node helpers are inlined in numba's IR: called, each would count references to
# every array it is handed (atomic increments and decrements, most of a node's cost).
jit_inline = njit(nogil=True, inline="always")

_stick_friction = jit(model.stick_friction_record)
_friction_sign = jit(model.friction_sign)
_support_extra = jit(model.support_extra)
_is_general = jit(model.is_general_record)

FREE, STICK = model.FREE, model.STICK
# Columns, as energy.W_IN ... energy.W_ABS_CROSS
_IN, _DAMP, _FRIC, _SLIP, _SPIN, _ABS_IN, _ABS_FRIC, _CROSS, _ABS_CROSS = range(9)
N_TERMS = 9
# After the model's parameter record, ``pv`` carries energy.DERIVATIVE_STEP and
# SMALL_SHIFT, then the general machine's offset c and load g (its potential and the
# cross-coupling's power are taken at the rotor's position w = d + c)
_DERIVATIVE_STEP, _SMALL_SHIFT = N_PARAMS, N_PARAMS + 1
_CX, _CY, _GX, _GY = N_PARAMS + 2, N_PARAMS + 3, N_PARAMS + 4, N_PARAMS + 5


@jit_inline
def _support_potential(x, y, pv):
    """``energy.support_potential`` of one state from ``pv``."""
    wx, wy = x + pv[_CX], y + pv[_CY]
    sxx, syy = 1.0 + pv[P_SXX], 1.0 + pv[P_SYY]
    quadratic = sxx * wx * wx + (pv[P_SXY] + pv[P_SYX]) * wx * wy + syy * wy * wy
    return 0.5 * quadratic - (pv[_GX] * wx + pv[_GY] * wy)


@jit_inline
def _general_powers(x, y, vx, vy, pv, out):
    """The general machine's damping power 2 w'^T D w' and the cross-coupling's
    (``energy.cross_coupling_power``) into out."""
    dxx, dyy = pv[P_NU] + pv[P_DXX], pv[P_NU] + pv[P_DYY]
    out[_DAMP] = 2.0 * (dxx * vx * vx + (pv[P_DXY] + pv[P_DYX]) * vx * vy + dyy * vy * vy)
    q = 0.5 * (pv[P_SXY] - pv[P_SYX])
    cross = q * (vy * (x + pv[_CX]) - vx * (y + pv[_CY]))
    out[_CROSS] = cross
    out[_ABS_CROSS] = abs(cross)


@jit_inline
def _node(k, n, p, t, states, start_tau, start_state, end_tau, end_state, lo, out):
    """Node k of piece p (of n nodes) into out[0:5] = tau, x, y, vx, vy."""
    if k == 0:
        out[0] = start_tau[p]
        for i in range(4):
            out[1 + i] = start_state[p, i]
    elif k == n - 1:
        out[0] = end_tau[p]
        for i in range(4):
            out[1 + i] = end_state[p, i]
    else:
        j = lo[p] + k - 1
        out[0] = t[j]
        for i in range(4):
            out[1 + i] = states[j, i]


@jit_inline
def _powers_at(c, s, tau, x, y, vx, vy, z, pv, general, regime, out):
    """``energy.powers`` of one state into out[0:N_TERMS], given c, s = cos, sin(eta tau +
    phi0) and z = hypot(x, y) (used in contact only)."""
    nu, eta, E, K, mu, Rp = pv[P_NU], pv[P_ETA], pv[P_E], pv[P_K], pv[P_MU], pv[P_RP]
    p_in = E * (c * vx + s * vy)
    out[_IN] = p_in
    out[_ABS_IN] = abs(p_in)
    if general:
        _general_powers(x, y, vx, vy, pv, out)
    else:
        out[_DAMP] = 2.0 * nu * (vx * vx + vy * vy)
        out[_CROSS] = 0.0
        out[_ABS_CROSS] = 0.0
    if regime == FREE:
        out[_FRIC] = 0.0
        out[_SLIP] = 0.0
        out[_SPIN] = 0.0
        out[_ABS_FRIC] = 0.0
        return
    if regime == STICK:
        T = _stick_friction(tau, x, y, vx, vy, pv)
    else:
        T = _friction_sign(regime) * mu * K * (z - 1.0)
    whirl = (x * vy - y * vx) / z
    v_r = Rp * eta + ((x * vy - y * vx) / z if z > 0.0 else 0.0)
    out[_FRIC] = -T * whirl
    out[_SLIP] = T * v_r
    out[_SPIN] = T * Rp * eta
    out[_ABS_FRIC] = abs(T * whirl)


@jit_inline
def _shifted_powers(c, s, tau, x, y, vx, vy, pv, regime, out):
    """``energy.powers`` of one state (a node's shifted along the motion) into
    out[0:N_TERMS], given the cos and sin of its phase."""
    z = np.hypot(x, y) if regime != FREE else 0.0
    _powers_at(c, s, tau, x, y, vx, vy, z, pv, _is_general(pv), regime, out)


@jit_inline
def _accelerations(c, s, tau, x, y, vx, vy, z, pv, general, regime):
    """``energy.accelerations`` of one state: (ax, ay), given c, s = cos, sin(eta tau +
    phi0) and z = hypot(x, y)."""
    nu, E, K, mu = pv[P_NU], pv[P_E], pv[P_K], pv[P_MU]
    ax = E * c - 2.0 * nu * vx - x
    ay = E * s - 2.0 * nu * vy - y
    if general:  # the stick friction below holds its tangential part
        ex, ey = _support_extra(x, y, vx, vy, pv)
        ax += ex
        ay += ey
    if regime == STICK:
        normal = K * (z - 1.0) if z > 1.0 else 0.0
        tangential = _stick_friction(tau, x, y, vx, vy, pv)
        ax = ax - (normal * x - tangential * y) / z
        ay = ay - (normal * y + tangential * x) / z
    elif regime != FREE:
        mu_c = mu * _friction_sign(regime)
        factor = 1.0 - 1.0 / z if z > 1.0 else 0.0
        ax = ax + -K * factor * (x - mu_c * y)
        ay = ay + -K * factor * (y + mu_c * x)
    return ax, ay


@jit_inline
def _power_and_rate(node, spacing, pv, regime, P, dP, shifted):
    """Powers P at a node and their rates dP (central differences along the motion);
    returns z = hypot(x, y) at the node. The phase's cos and sin and z are computed once
    for the powers and the accelerations (the same values the two would compute)."""
    eta = pv[P_ETA]
    general = _is_general(pv)
    tau, x, y, vx, vy = node[0], node[1], node[2], node[3], node[4]
    phase = eta * tau + pv[P_PHI0]
    c = np.cos(phase)
    s = np.sin(phase)
    z = np.hypot(x, y)
    _powers_at(c, s, tau, x, y, vx, vy, z, pv, general, regime, P)
    ax, ay = _accelerations(c, s, tau, x, y, vx, vy, z, pv, general, regime)
    delta = pv[_DERIVATIVE_STEP] * spacing
    a = eta * delta  # the phase at tau +- delta: the node's rotated by +-a (energy.shift_rotation)
    if abs(a) < pv[_SMALL_SHIFT]:
        ca = 1.0 - 0.5 * a * a
        sa = a * (1.0 - a * a / 6.0)
    else:
        ca = np.cos(a)
        sa = np.sin(a)
    _shifted_powers(c * ca - s * sa, s * ca + c * sa, tau + delta, x + delta * vx,
                    y + delta * vy, vx + delta * ax, vy + delta * ay, pv, regime,
                    shifted)  # fmt: skip
    for i in range(N_TERMS):
        dP[i] = shifted[i]
    _shifted_powers(c * ca + s * sa, s * ca - c * sa, tau - delta, x - delta * vx,
                    y - delta * vy, vx - delta * ax, vy - delta * ay, pv, regime,
                    shifted)  # fmt: skip
    for i in range(N_TERMS):
        dP[i] = (dP[i] - shifted[i]) / (2.0 * delta)
    dP[_ABS_IN] = 0.0
    dP[_ABS_FRIC] = 0.0
    dP[_ABS_CROSS] = 0.0
    return z


@jit
def _piece_pass(p, n, t, states, bounds, pv, regime, fine, coarse, cum_out, energy_out, offset,
                running):  # fmt: skip
    """Piece p (of n >= 2 nodes) in one walk over its nodes: the corrected-trapezoid
    integrals on every node (``fine``) and on every other node and the last (``coarse``,
    with the same nodal powers and rates), and the mechanical energy at each node. With
    ``cum_out`` and ``energy_out`` of nonzero length the cumulative integrals (plus
    ``running``, the sums of the pieces before) and the energies are stored from row
    ``offset`` on. Returns the energy at the first and last node and its largest
    magnitude."""
    start_tau, start_state, end_tau, end_state, lo = bounds
    K = pv[P_K]
    general = _is_general(pv)
    prev = np.empty(5)
    cur = np.empty(5)
    nxt = np.empty(5)
    P_prev, dP_prev = np.empty(N_TERMS), np.empty(N_TERMS)
    P_kept, dP_kept = np.empty(N_TERMS), np.empty(N_TERMS)
    P, dP, shifted = np.empty(N_TERMS), np.empty(N_TERMS), np.empty(N_TERMS)
    for i in range(N_TERMS):
        fine[i] = 0.0
        coarse[i] = 0.0
    store = cum_out.shape[0] > 0
    tau_kept = 0.0
    energy_first = 0.0
    energy_last = 0.0
    energy_max = 0.0
    _node(0, n, p, t, states, start_tau, start_state, end_tau, end_state, lo, cur)
    _node(1, n, p, t, states, start_tau, start_state, end_tau, end_state, lo, nxt)
    for k in range(n):
        h_prev = cur[0] - prev[0] if k > 0 else np.inf
        h_next = nxt[0] - cur[0] if k < n - 1 else np.inf
        z = _power_and_rate(cur, min(h_next, h_prev), pv, regime, P, dP, shifted)
        if k > 0:
            h = h_prev
            for i in range(N_TERMS):
                fine[i] += 0.5 * h * (P_prev[i] + P[i]) + (h * h / 12.0) * (dP_prev[i] - dP[i])
        if k % 2 == 0 or k == n - 1:  # a node of the coarse rule
            if k > 0:
                h = cur[0] - tau_kept
                for i in range(N_TERMS):
                    coarse[i] += 0.5 * h * (P_kept[i] + P[i]) + (h * h / 12.0) * (
                        dP_kept[i] - dP[i]
                    )
            tau_kept = cur[0]
            for i in range(N_TERMS):
                P_kept[i] = P[i]
                dP_kept[i] = dP[i]
        if n == 2 and k == 1:  # no interior node: the coarse rule is the plain trapezoid
            span = end_tau[p] - start_tau[p]
            for i in range(N_TERMS):
                coarse[i] = 0.5 * (P_prev[i] + P[i]) * span
        vx, vy = cur[3], cur[4]
        kinetic = 0.5 * (vx * vx + vy * vy)
        spring = _support_potential(cur[1], cur[2], pv) if general else 0.5 * z * z
        stator = 0.5 * K * (z - 1.0) ** 2 if regime != FREE else 0.0
        energy = kinetic + spring + stator
        if k == 0:
            energy_first = energy
        energy_last = energy
        energy_max = max(energy_max, abs(energy))
        if store:
            energy_out[offset + k, 0] = kinetic
            energy_out[offset + k, 1] = spring
            energy_out[offset + k, 2] = stator
            for i in range(N_TERMS):
                cum_out[offset + k, i] = fine[i] + running[i]
        for i in range(N_TERMS):
            P_prev[i] = P[i]
            dP_prev[i] = dP[i]
        for i in range(5):
            prev[i] = cur[i]
            cur[i] = nxt[i]
        if k + 2 < n:
            _node(k + 2, n, p, t, states, start_tau, start_state, end_tau, end_state, lo, nxt)
    return energy_first, energy_last, energy_max


@jit
def balance_pass(
    t: np.ndarray, states: np.ndarray, regimes: np.ndarray, start_tau: np.ndarray,
    start_state: np.ndarray, end_tau: np.ndarray, end_state: np.ndarray, lo: np.ndarray,
    hi: np.ndarray, pv: np.ndarray, cum_out: np.ndarray, energy_out: np.ndarray,
) -> tuple[np.ndarray, float, float, float, float]:  # fmt: skip
    """The energy balance over every piece in one pass. ``pv``: the model's parameter
    vector (``model.params_vector``) followed by the derivative step and the small-shift
    limit of the power rates (``energy.DERIVATIVE_STEP``, ``energy.SMALL_SHIFT``).

    Returns ``(running, quad_sum, energy_first, energy_last, energy_max_abs)``: the
    integrals of the N_TERMS power columns over the whole span, the summed |W - D + F| of the
    per-piece quadrature-error estimates, and the mechanical energy at the first and last
    node and its largest magnitude. With ``cum_out`` of shape (nodes, N_TERMS) and
    ``energy_out`` of shape (nodes, 3) (else shape (0, ...)) the cumulative integrals and
    the kinetic, rotor-spring and stator energies at every node are written too.
    """
    bounds = (start_tau, start_state, end_tau, end_state, lo)
    running = np.zeros(N_TERMS)
    fine = np.zeros(N_TERMS)
    coarse = np.zeros(N_TERMS)
    quad_sum = 0.0
    energy_first = 0.0
    energy_last = 0.0
    energy_max = 0.0
    # an int64, not the literal 0: with a literal numba would compile _piece_pass twice,
    # once for Literal[int](0) while inferring the loop's types and once for int64
    offset = np.int64(0)
    for p in range(regimes.size):
        n = hi[p] - lo[p] + 2
        first, last, largest = _piece_pass(p, n, t, states, bounds, pv, regimes[p], fine, coarse,
                                           cum_out, energy_out, offset, running)  # fmt: skip
        divisor = 15.0 if n >= 3 else 1.0  # Richardson (order 4), or against the trapezoid
        for i in range(N_TERMS):
            coarse[i] = abs(fine[i] - coarse[i]) / divisor
        quad_sum += abs(coarse[_IN] - coarse[_DAMP] + coarse[_FRIC] + coarse[_CROSS])
        if p == 0:
            energy_first = first
        energy_last = last
        energy_max = max(energy_max, largest)
        for i in range(N_TERMS):
            running[i] += fine[i]
        offset += n
    return running, quad_sum, energy_first, energy_last, energy_max

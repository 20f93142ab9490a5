"""A stator with its own mass: the snubber ring on its own supports (two bodies).

``../shared/docs/general-machine.md``: the stator (ring) centre moves by ``s = (u, v)``
from its rest position, with mass ratio ``m_s = M_s / m``, support stiffness ratios
``k_s = (k_sx, k_sy)`` and damping ``n_s = (n_sx, n_sy)`` along its own axes::

    m_s s'' + 2 diag(n_s) s' + diag(k_s) s = -F

with ``F`` the contact force on the rotor. The state keeps the rotor's four entries
relative to the stator's centre, ``d = w - s - c`` (so the contact, the slip ``v_r =
Rp eta + d' . t`` and the events are those of the rigid stator), and adds the unbalance's
phase and speed and the stator's four::

    (x, y, vx, vy, p, w, u, v, u', v')

At a constant speed ``p' = w`` and ``w' = 0``: the phase is a state so that the system
is autonomous, as the driven rotor's (``rubcli.drive``), and runs in the same event
loop (``solvers.extended``). The rotor's acceleration is ``w'' = f_u + g - 2 D w' - S w
+ F`` at ``w = d + s + c``, and ``d'' = w'' - s''``.

In stick the rub force is the multiplier ``T`` (positive opposing positive slip; the
force on the rotor is ``-T t``, on the stator ``T t``) that holds ``v_r' = 0``::

    T = ((A_w - A_s) . t - (d' . t)(d' . n) / z) / (1 + 1/m_s)

with ``A_w``, ``A_s`` the two accelerations without any tangential force. A projection
onto ``v_r = 0`` (stick's start, its samples) moves the two bodies' velocities along the
kinetic energy's metric: an impulse ``lambda t`` on the rotor and ``-lambda t`` on the
stator (``two_body_projection``).

Energy ``|w'|^2/2 + w^T S_sym w/2 - g . w + m_s |s'|^2/2 + s^T diag(k_s) s/2 + K (z-1)^2/2``
(``w`` from the support's centre); its rate is the unbalance's power, less the
damping's (rotor and stator), plus the cross-coupling's ``-w'^T S_anti w``, less the
friction's on the relative motion ``T d' . t`` (``analysis.energy.two_body``).
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
    S_INV_MASS,
    S_KX,
    S_KY,
    S_NX,
    S_NY,
    STICK,
    friction_sign,
)

# The stator's data (``model.Stator``, which ``ModelParams.stator`` holds), with its equations
from rubcli.model import STATOR_RECORD as STATOR_RECORD
from rubcli.model import Stator as Stator

N_STATES = 10  # x, y, vx, vy (relative), p, w, u, v, u', v'


# ------------------------------------------------------------------ compilable cores


def two_body_projection(
    x: float, y: float, vx: float, vy: float, up: float, vp: float, spin: float, m_inv: float
) -> tuple[float, float, float, float]:
    """The velocities ``(vx, vy, u', v')`` with ``v_r = 0`` exactly, moved along the
    kinetic energy's metric: an impulse ``lambda t`` on the rotor, ``-lambda t`` on the
    stator, so ``d'`` moves by ``lambda (1 + 1/m_s) t`` and ``s'`` by ``-lambda t / m_s``
    (compilable core)."""
    z = math.hypot(x, y)
    tx, ty = -y / z, x / z
    change = -spin - (tx * vx + ty * vy)  # the change of d' . t
    share = m_inv / (1.0 + m_inv)  # of it, the stator's (with the opposite sign)
    return vx + change * tx, vy + change * ty, up - share * change * tx, vp - share * change * ty


def two_body_entries(s: np.ndarray, pars: np.ndarray, st: np.ndarray, regime: int,
                     out: np.ndarray) -> float:  # fmt: skip
    """The ten derivatives into ``out`` in ``regime``; returns the rub's tangential force
    ``T`` (module docstring; compilable core). In stick the velocities are first
    projected onto the rolling constraint (as the stick samples are reported), so that
    drift in v_r is not fed back."""
    x, y, vx, vy, p, w = s[0], s[1], s[2], s[3], s[4], s[5]
    u, v, up, vp = s[6], s[7], s[8], s[9]
    m_inv = st[S_INV_MASS]
    if regime == STICK:
        vx, vy, up, vp = two_body_projection(x, y, vx, vy, up, vp, pars[P_RP] * w, m_inv)
    nu = pars[P_NU]
    sxx, sxy = 1.0 + pars[P_SXX], pars[P_SXY]
    syx, syy = pars[P_SYX], 1.0 + pars[P_SYY]
    dxx, dxy = nu + pars[P_DXX], pars[P_DXY]
    dyx, dyy = pars[P_DYX], nu + pars[P_DYY]
    # the rotor from the support's centre, less the offset (g - S c is the record's g)
    wx, wy, wvx, wvy = x + u, y + v, vx + up, vy + vp
    unbalance = pars[P_ECC] * w * w
    ax = unbalance * math.cos(p) + pars[P_GX] - (sxx * wx + sxy * wy)
    ax -= 2.0 * (dxx * wvx + dxy * wvy)
    ay = unbalance * math.sin(p) + pars[P_GY] - (syx * wx + syy * wy)
    ay -= 2.0 * (dyx * wvx + dyy * wvy)
    bx = -(st[S_KX] * u + 2.0 * st[S_NX] * up) * m_inv
    by = -(st[S_KY] * v + 2.0 * st[S_NY] * vp) * m_inv
    T = 0.0
    if regime != FREE:
        z = math.hypot(x, y)
        nx, ny = x / z, y / z
        normal = pars[P_K] * (z - 1.0)
        if regime == STICK:
            relative_t = -(ax - bx) * ny + (ay - by) * nx
            T = (relative_t - (-vx * ny + vy * nx) * (vx * nx + vy * ny) / z) / (1.0 + m_inv)
        else:
            T = pars[P_MU] * friction_sign(regime) * normal
        fx = -normal * nx + T * ny  # F = -N n - T t, t = (-n_y, n_x)
        fy = -normal * ny - T * nx
        ax += fx
        ay += fy
        bx -= fx * m_inv
        by -= fy * m_inv
    out[0], out[1], out[2], out[3] = vx, vy, ax - bx, ay - by
    out[4], out[5] = w, 0.0
    out[6], out[7], out[8], out[9] = up, vp, bx, by
    return T

"""The rotor at a constant speed as a system of ``extended_loop`` (``solvers.variational``):
its six states ``(x, y, vx, vy, p, w)`` (the phase and the constant speed beside the
rotor's four), and the same with its variational matrix ``Phi = d (x, y, vx, vy) / d
start`` (4 x 4, row by row) after them, ``Phi' = J Phi`` with J the Jacobian of the
regime's right-hand side (``model.rhs_jacobian_record``). The right-hand side is
``model.rhs_record``'s at ``tau = (p - phi0) / eta``, so any machine at a constant speed."""

from __future__ import annotations

import math

import numpy as np

from rubcli.model import (
    FREE,
    P_ETA,
    P_K,
    P_MU,
    P_PHI0,
    P_RP,
    STICK,
    friction_sign,
    rhs_jacobian_record,
    rhs_record,
    rolling_velocity,
    stick_friction_record,
)
from rubcli.solvers.compiled.extended_loop import dop853_loop
from rubcli.solvers.compiled.jit import jit

N_ROTOR = 6  # x, y, vx, vy, the phase p and the speed w
N_VARIATIONAL = N_ROTOR + 16  # and Phi, row by row


@jit
def _rotor_into(row: np.ndarray, pars: np.ndarray, regime: int, out: np.ndarray) -> float:
    """The six derivatives into ``out``; returns the rub's tangential force T (positive
    opposing positive slip; in stick the friction that holds the rolling, from the
    velocity projected onto it, as ``model.rhs_entries`` takes it)."""
    eta = pars[P_ETA]
    tau = (row[4] - pars[P_PHI0]) / eta
    x, y, vx, vy = row[0], row[1], row[2], row[3]
    dx, dy, ax, ay = rhs_record(tau, x, y, vx, vy, pars, regime)
    out[0], out[1], out[2], out[3] = dx, dy, ax, ay
    out[4], out[5] = row[5], 0.0
    if regime == FREE:
        return 0.0
    if regime == STICK:
        rx, ry = rolling_velocity(x, y, vx, vy, pars[P_RP] * row[5])
        return stick_friction_record(tau, x, y, rx, ry, pars)
    return friction_sign(regime) * pars[P_MU] * pars[P_K] * (math.hypot(x, y) - 1.0)


@jit
def _variational_into(row: np.ndarray, pars: np.ndarray, regime: int, out: np.ndarray) -> float:
    """``_rotor_into`` and ``Phi' = J Phi`` into ``out[6:]``."""
    T = _rotor_into(row, pars, regime, out)
    tau = (row[4] - pars[P_PHI0]) / pars[P_ETA]
    J = rhs_jacobian_record(tau, row[0], row[1], row[2], row[3], pars, regime)
    for i in range(4):
        for j in range(4):
            total = 0.0
            for m in range(4):
                total += J[i, m] * row[N_ROTOR + 4 * m + j]
            out[N_ROTOR + 4 * i + j] = total
    return T


@jit
def rotor_into(row: np.ndarray, ctx: tuple, regime: int, out: np.ndarray) -> float:
    """``_rotor_into`` as ``extended_loop``'s system; ctx = (pars,)."""
    return _rotor_into(row, ctx[0], regime, out)


@jit
def variational_into(row: np.ndarray, ctx: tuple, regime: int, out: np.ndarray) -> float:
    """``_variational_into`` as ``extended_loop``'s system; ctx = (pars,)."""
    return _variational_into(row, ctx[0], regime, out)


@jit
def rotor_project(row: np.ndarray, ctx: tuple) -> None:
    """The velocity projected onto the rolling constraint in place (``Phi`` is the
    caller's: ``solvers.variational``)."""
    row[2], row[3] = rolling_velocity(row[0], row[1], row[2], row[3], ctx[0][P_RP] * row[5])


@jit
def rotor_rhs(s: np.ndarray, pars: np.ndarray, regime: int) -> np.ndarray:
    """The six derivatives at one state."""
    out = np.empty(N_ROTOR)
    _rotor_into(s, pars, regime, out)
    return out


@jit
def variational_rhs(s: np.ndarray, pars: np.ndarray, regime: int) -> np.ndarray:
    """The six derivatives and Phi's at one state."""
    out = np.empty(N_VARIATIONAL)
    _variational_into(s, pars, regime, out)
    return out


@jit
def rotor_columns(S: np.ndarray, pars: np.ndarray, regime: int) -> tuple[np.ndarray, np.ndarray]:
    """For the states in the columns of S (6 or 22 rows, n): the six derivatives and the
    rub's tangential force T, what the event search reads (Phi's rows are left 0)."""
    n = S.shape[1]
    dS = np.zeros((S.shape[0], n))
    T = np.empty(n)
    row = np.empty(N_ROTOR)
    out = np.empty(N_ROTOR)
    for k in range(n):
        for i in range(N_ROTOR):
            row[i] = S[i, k]
        T[k] = _rotor_into(row, pars, regime, out)
        for i in range(N_ROTOR):
            dS[i, k] = out[i]
    return dS, T


# orbits' flows apply their own events (Phi jumps at each): the loops return at each
_rotor_initial, _rotor_advance = dop853_loop(rotor_into, rotor_project, N_ROTOR,
                                             loop_applies=False)  # fmt: skip
# (the events read the rotor's six states: the search evaluates their right-hand side alone)
_variational_initial, _variational_advance = dop853_loop(
    variational_into, rotor_project, N_VARIATIONAL, rotor_into, loop_applies=False
)


# The loops' entry points at module level, so that numba's cache loads them (as
# ``compiled.drive``'s).
@jit
def rotor_initial_step(
    t0: float, y0: np.ndarray, f0: np.ndarray, t_bound: float, ctx: tuple, regime: int,
    rtol: float, atol: float,
) -> float:  # fmt: skip
    """The rotor's loop's initial step (``extended_loop.dop853_loop``)."""
    return _rotor_initial(t0, y0, f0, t_bound, ctx, regime, rtol, atol)


@jit
def advance_rotor(
    tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, ctx: tuple,
    regime: int, rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    band: float, found: np.ndarray, y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray,
    events: tuple, applies: bool,
) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
    """The rotor's loop's steps with their events (``dop853_loop``'s advance)."""
    return _rotor_advance(
        tau, y, f, h_abs, t_end, ctx, regime, rtol, atol, t_eval, out_states, out_regimes, k,
        max_steps, starts, band, found, y_new, f_new, F, events, applies,
    )  # fmt: skip


@jit
def variational_initial_step(
    t0: float, y0: np.ndarray, f0: np.ndarray, t_bound: float, ctx: tuple, regime: int,
    rtol: float, atol: float,
) -> float:  # fmt: skip
    """The variational loop's initial step (``extended_loop.dop853_loop``)."""
    return _variational_initial(t0, y0, f0, t_bound, ctx, regime, rtol, atol)


@jit
def advance_variational(
    tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, ctx: tuple,
    regime: int, rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    band: float, found: np.ndarray, y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray,
    events: tuple, applies: bool,
) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
    """The variational loop's steps with their events (``dop853_loop``'s advance)."""
    return _variational_advance(
        tau, y, f, h_abs, t_end, ctx, regime, rtol, atol, t_eval, out_states, out_regimes, k,
        max_steps, starts, band, found, y_new, f_new, F, events, applies,
    )  # fmt: skip

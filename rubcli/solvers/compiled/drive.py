"""The driven rotor compiled (``rubcli.drive``): its right-hand side at one state, or at
the columns of a step's scan grid with the rub's tangential force beside (the events),
and its DOP853 loop (``extended_loop``, with the drive as the system)."""

from __future__ import annotations

import numpy as np

from rubcli.drive import D_INERTIA, driven_rhs_entries, rolling_projection, shaft_torque_value
from rubcli.model import P_ECC, P_K, P_MU, P_NU, P_RP, STICK
from rubcli.solvers.compiled.extended_loop import dop853_loop
from rubcli.solvers.compiled.jit import jit

N_STATES = 6  # x, y, vx, vy, the phase p and the speed w


@jit
def _driven_into(s, pars, drive, table_speed, table_torque, regime, out):
    """The six derivatives into ``out``; returns the rub's tangential force T. In stick
    the velocities are first projected onto the rolling constraint (as the stick samples
    are reported), so that drift in v_r is not fed back."""
    nu, K, mu, Rp, e = pars[P_NU], pars[P_K], pars[P_MU], pars[P_RP], pars[P_ECC]
    j = drive[D_INERTIA]
    x, y, vx, vy, p, w = s[0], s[1], s[2], s[3], s[4], s[5]
    if regime == STICK:
        vx, vy, w = rolling_projection(x, y, vx, vy, p, w, e, Rp, j)
    Q0 = shaft_torque_value(w, drive, table_speed, table_torque)
    dx, dy, ax, ay, dp, dw, T = driven_rhs_entries(x, y, vx, vy, p, w, nu, K, mu, Rp, e, j, Q0,
                                                   regime)  # fmt: skip
    out[0], out[1], out[2], out[3], out[4], out[5] = dx, dy, ax, ay, dp, dw
    return T


@jit
def driven_rhs(
    s: np.ndarray, pars: np.ndarray, drive: np.ndarray, table_speed: np.ndarray,
    table_torque: np.ndarray, regime: int,
) -> np.ndarray:  # fmt: skip
    """The driven rotor's six derivatives at one state (``pars`` = params_vector)."""
    out = np.empty(6)
    _driven_into(s, pars, drive, table_speed, table_torque, regime, out)
    return out


@jit
def driven_columns(
    S: np.ndarray, pars: np.ndarray, drive: np.ndarray, table_speed: np.ndarray,
    table_torque: np.ndarray, regime: int,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """For the states in the columns of S (6, n): their derivatives and the rub's
    tangential force T (positive opposing positive slip; 0 in free flight)."""
    n = S.shape[1]
    dS = np.empty((6, n))
    T = np.empty(n)
    row = np.empty(6)
    out = np.empty(6)
    for k in range(n):
        for i in range(6):
            row[i] = S[i, k]
        T[k] = _driven_into(row, pars, drive, table_speed, table_torque, regime, out)
        for i in range(6):
            dS[i, k] = out[i]
    return dS, T


@jit
def drive_into(row: np.ndarray, ctx: tuple, regime: int, out: np.ndarray) -> float:
    """``_driven_into`` as ``extended_loop``'s system; ctx = (pars, drive, table_speed,
    table_torque)."""
    return _driven_into(row, ctx[0], ctx[1], ctx[2], ctx[3], regime, out)


@jit
def drive_project(row: np.ndarray, ctx: tuple) -> None:
    """``rolling_projection`` of ``row`` in place, as ``extended_loop``'s system."""
    e, Rp, j = ctx[0][P_ECC], ctx[0][P_RP], ctx[1][D_INERTIA]
    row[2], row[3], row[5] = rolling_projection(
        row[0], row[1], row[2], row[3], row[4], row[5], e, Rp, j
    )


_initial_step, _advance = dop853_loop(drive_into, drive_project, N_STATES)


# The loop's entry points at module level: numba caches a function by its code, and a
# closure also by its cells, which hold dispatchers that differ in every process; so the
# factory's closures would compile anew in each one, while these load from the cache
# with the closures compiled into them.
@jit
def driven_initial_step(
    t0: float, y0: np.ndarray, f0: np.ndarray, t_bound: float, ctx: tuple, regime: int,
    rtol: float, atol: float,
) -> float:  # fmt: skip
    """The loop's initial step (``extended_loop.dop853_loop``)."""
    return _initial_step(t0, y0, f0, t_bound, ctx, regime, rtol, atol)


@jit
def advance_driven(
    tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, ctx: tuple,
    regime: int, rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    band: float, found: np.ndarray, y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray,
    events: tuple, applies: bool,
) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
    """The loop's steps with their events (``extended_loop.dop853_loop``'s advance)."""
    return _advance(
        tau, y, f, h_abs, t_end, ctx, regime, rtol, atol, t_eval, out_states, out_regimes, k,
        max_steps, starts, band, found, y_new, f_new, F, events, applies,
    )  # fmt: skip

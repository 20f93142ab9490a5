"""The stator with its own mass compiled (``rubcli.stator``): its right-hand side at one
state, or at the columns of a step's scan grid with the rub's tangential force beside
(the events), and its DOP853 loop (``extended_loop``, with the two bodies as the
system)."""

from __future__ import annotations

import numpy as np

from rubcli.model import P_RP
from rubcli.solvers.compiled.extended_loop import dop853_loop
from rubcli.solvers.compiled.jit import jit
from rubcli.stator import N_STATES, S_INV_MASS, two_body_entries, two_body_projection


@jit
def two_body_into(row: np.ndarray, ctx: tuple, regime: int, out: np.ndarray) -> float:
    """``stator.two_body_entries`` as ``extended_loop``'s system; ctx = (pars, stator)."""
    return two_body_entries(row, ctx[0], ctx[1], regime, out)


@jit
def two_body_project(row: np.ndarray, ctx: tuple) -> None:
    """``stator.two_body_projection`` of ``row`` in place, as ``extended_loop``'s system."""
    spin = ctx[0][P_RP] * row[5]
    row[2], row[3], row[8], row[9] = two_body_projection(
        row[0], row[1], row[2], row[3], row[8], row[9], spin, ctx[1][S_INV_MASS]
    )


@jit
def two_body_rhs(s: np.ndarray, pars: np.ndarray, stator: np.ndarray, regime: int) -> np.ndarray:
    """The ten derivatives at one state."""
    out = np.empty(N_STATES)
    two_body_entries(s, pars, stator, regime, out)
    return out


@jit
def two_body_columns(
    S: np.ndarray, pars: np.ndarray, stator: np.ndarray, regime: int
) -> tuple[np.ndarray, np.ndarray]:
    """For the states in the columns of S (10, n): their derivatives and the rub's
    tangential force T (positive opposing positive slip; 0 in free flight)."""
    n = S.shape[1]
    dS = np.empty((N_STATES, n))
    T = np.empty(n)
    row = np.empty(N_STATES)
    out = np.empty(N_STATES)
    for k in range(n):
        for i in range(N_STATES):
            row[i] = S[i, k]
        T[k] = two_body_entries(row, pars, stator, regime, out)
        for i in range(N_STATES):
            dS[i, k] = out[i]
    return dS, T


_initial_step, _advance = dop853_loop(two_body_into, two_body_project, N_STATES)


# The loop's entry points at module level, so that numba's cache loads them (as
# ``compiled.drive``'s).
@jit
def two_body_initial_step(
    t0: float, y0: np.ndarray, f0: np.ndarray, t_bound: float, ctx: tuple, regime: int,
    rtol: float, atol: float,
) -> float:  # fmt: skip
    """The loop's initial step (``extended_loop.dop853_loop``)."""
    return _initial_step(t0, y0, f0, t_bound, ctx, regime, rtol, atol)


@jit
def advance_two_body(
    tau: float, y: np.ndarray, f: np.ndarray, h_abs: float, t_end: float, ctx: tuple,
    regime: int, rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, hand_first: bool, y_new: np.ndarray,
    f_new: np.ndarray, F: np.ndarray,
) -> tuple[float, float, float, int, int, int, int]:  # fmt: skip
    """The loop's steps up to a pending one (``extended_loop.dop853_loop``'s advance)."""
    return _advance(tau, y, f, h_abs, t_end, ctx, regime, rtol, atol, t_eval, out_states,
                    out_regimes, k, max_steps, hand_first, y_new, f_new, F)  # fmt: skip

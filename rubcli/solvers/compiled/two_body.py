"""The stator with its own mass compiled (``rubcli.stator``): its right-hand side at one
state, or at the columns of a step's scan grid with the rub's tangential force beside
(the events), and its DOP853 loop (``extended_loop``, with the two bodies as the
system); and the same with the variational matrix of the section's eight states after
the ten (``solvers.variational``): ``Phi' = J Phi``, J by central differences of the
right-hand side."""

from __future__ import annotations

import numpy as np

from rubcli.model import P_RP
from rubcli.solvers.compiled.extended_loop import dop853_loop
from rubcli.solvers.compiled.jit import jit
from rubcli.stator import N_STATES, S_INV_MASS, two_body_entries, two_body_projection

# the section's entries of the ten states (the phase and the speed are not perturbed)
SECTION = (0, 1, 2, 3, 6, 7, 8, 9)
N_SECTION = len(SECTION)
N_VARIATIONAL = N_STATES + N_SECTION * N_SECTION  # the ten, then Phi row by row
# the central differences' step of J, relative to 1 + |q_j|: the cube root of the
# round-off, where their truncation and rounding errors (each ~4e-11 of J) balance
JACOBIAN_STEP = 6e-6


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
    """For the states in the columns of S (10 rows, or 10 and Phi's: n columns): the ten
    derivatives and the rub's tangential force T (positive opposing positive slip; 0 in
    free flight), what the event search reads (Phi's rows are left 0)."""
    n = S.shape[1]
    dS = np.zeros((S.shape[0], n))
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


@jit
def two_body_variational_into(row: np.ndarray, ctx: tuple, regime: int, out: np.ndarray) -> float:
    """``two_body_into`` and ``Phi' = J Phi`` into ``out[10:]``, J (8 x 8) by central
    differences of the regime's right-hand side in the section's states."""
    pars, stator = ctx[0], ctx[1]
    T = two_body_entries(row, pars, stator, regime, out)
    up, down = np.empty(N_STATES), np.empty(N_STATES)
    f_up, f_down = np.empty(N_STATES), np.empty(N_STATES)
    J = np.empty((N_SECTION, N_SECTION))
    for col in range(N_SECTION):
        j = SECTION[col]
        for i in range(N_STATES):
            up[i] = row[i]
            down[i] = row[i]
        h = JACOBIAN_STEP * (1.0 + abs(row[j]))
        up[j] = row[j] + h
        down[j] = row[j] - h
        two_body_entries(up, pars, stator, regime, f_up)
        two_body_entries(down, pars, stator, regime, f_down)
        width = up[j] - down[j]  # the step as represented
        for r in range(N_SECTION):
            J[r, col] = (f_up[SECTION[r]] - f_down[SECTION[r]]) / width
    for i in range(N_SECTION):
        for j in range(N_SECTION):
            total = 0.0
            for m in range(N_SECTION):
                total += J[i, m] * row[N_STATES + N_SECTION * m + j]
            out[N_STATES + N_SECTION * i + j] = total
    return T


_initial_step, _advance = dop853_loop(two_body_into, two_body_project, N_STATES)
# (the events read the ten states: the search evaluates their right-hand side alone)
# (the variational flow applies its own events, Phi jumping at each: the loop returns)
_variational_initial, _variational_advance = dop853_loop(
    two_body_variational_into,
    two_body_project,
    N_VARIATIONAL,
    two_body_into,
    loop_applies=False,
)


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
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    band: float, found: np.ndarray, y_new: np.ndarray, f_new: np.ndarray, F: np.ndarray,
    events: tuple, applies: bool,
) -> tuple[float, float, float, int, int, int, int, int, int, bool]:  # fmt: skip
    """The loop's steps with their events (``extended_loop.dop853_loop``'s advance)."""
    return _advance(
        tau, y, f, h_abs, t_end, ctx, regime, rtol, atol, t_eval, out_states, out_regimes, k,
        max_steps, starts, band, found, y_new, f_new, F, events, applies,
    )  # fmt: skip


@jit
def two_body_variational_rhs(
    s: np.ndarray, pars: np.ndarray, stator: np.ndarray, regime: int
) -> np.ndarray:
    """The ten derivatives and Phi's at one state."""
    out = np.empty(N_VARIATIONAL)
    two_body_variational_into(s, (pars, stator), regime, out)
    return out


@jit
def two_body_variational_initial_step(
    t0: float, y0: np.ndarray, f0: np.ndarray, t_bound: float, ctx: tuple, regime: int,
    rtol: float, atol: float,
) -> float:  # fmt: skip
    """The variational loop's initial step (``extended_loop.dop853_loop``)."""
    return _variational_initial(t0, y0, f0, t_bound, ctx, regime, rtol, atol)


@jit
def advance_two_body_variational(
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

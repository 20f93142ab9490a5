"""The analytic methods' free flight and stick propagators, compiled, with their ``ev``
functions for the event search (``events.event_search``).

- Free flight: the closed form of ``model.free_flight`` (eq. 7-8 with the corrections),
  the same definition (``model.free_flight_value``, a compilable core): ``_free_prepare``
  stores the homogeneous part's start (tau0, w0 - w_p(tau0), v0 - v_p(tau0)) in a
  5-array, ``_free_at`` evaluates the state at any tau.
- Stick: one classical RK4 step of the rolling law (``model.rhs_entries`` in
  ``STICK``) with cubic Hermite dense output: ``stick_prepare`` stores (s0, s1, f0,
  f1) and (tau0, h); ``stick_at`` evaluates the cubic. These are the one
  definition of the stick step: plain functions registered with ``register_jitable``,
  which ``analytic.StickStep`` (the Python path) calls as Python and the loop calls
  compiled, so the two paths are the same arithmetic, bitwise.
- The contact steps' ``ev`` (``contact_ev``) wraps ``propagators._evaluate``.

Every ``ev(t, deriv, ctx, row, drow)`` fills ``row`` with the state at ``t`` and, when
``deriv``, ``drow`` with its time derivative (what the Python propagators'
``derivatives`` return): the segment of the event search (``events.event_search``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from numba.extending import register_jitable

from rubcli.model import (
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
    STICK,
    free_flight_value,
    free_steady_value,
    is_paper_record,
    rhs_entries,
    rhs_record,
)
from rubcli.solvers.compiled.jit import jit
from rubcli.solvers.compiled.propagators import _evaluate

if TYPE_CHECKING:
    import numpy as np


@jit
def free_omega_max(pars: np.ndarray) -> float:
    """``analytic.FreeFlight.omega_max``: max(eta, sqrt|1 - nu^2|, 1)."""
    nu, eta = pars[P_NU], pars[P_ETA]
    return max(eta, math.sqrt(abs(1.0 - nu * nu)), 1.0)


@jit
def _free_prepare(tau0, s0, pars, ff):
    """The free flight from (tau0, s0): ff = (tau0, Re d0, Im d0, Re dv0, Im dv0)."""
    wp0, vp0 = free_steady_value(tau0, pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0])
    d0 = complex(s0[0], s0[1]) - wp0
    dv0 = complex(s0[2], s0[3]) - vp0
    ff[0] = tau0
    ff[1] = d0.real
    ff[2] = d0.imag
    ff[3] = dv0.real
    ff[4] = dv0.imag


@jit
def _free_at(t, ff, pars, row):
    """``model.free_flight`` at a scalar time t, into row."""
    d0 = complex(ff[1], ff[2])
    dv0 = complex(ff[3], ff[4])
    w, v = free_flight_value(t, ff[0], d0, dv0, pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0])
    row[0] = w.real
    row[1] = w.imag
    row[2] = v.real
    row[3] = v.imag


@jit
def free_ev(
    t: float, deriv: bool, ctx: tuple[np.ndarray, np.ndarray], row: np.ndarray, drow: np.ndarray
) -> None:
    """ev of the free flight: ctx = (ff, pars); drow as ``FreeFlight.derivatives``."""
    ff, pars = ctx
    _free_at(t, ff, pars, row)
    if deriv:
        nu, eta, E, phi0 = pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0]
        phase = eta * t + phi0
        drow[0] = row[2]
        drow[1] = row[3]
        drow[2] = E * math.cos(phase) - 2.0 * nu * row[2] - row[0]
        drow[3] = E * math.sin(phase) - 2.0 * nu * row[3] - row[1]


@register_jitable
def _paper_stick_f(t, x, y, vx, vy, pars):
    """The rolling law on the paper's machine at a constant speed."""
    return rhs_entries(t, x, y, vx, vy, pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0],
                       pars[P_K], pars[P_MU], pars[P_RP], STICK)  # fmt: skip


@register_jitable
def _general_stick_f(t, x, y, vx, vy, pars):
    """The rolling law of any machine and speed."""
    return rhs_record(t, x, y, vx, vy, pars, STICK)


@register_jitable
def stick_omega_max(pars: np.ndarray | tuple[float, ...]) -> float:
    """``analytic.StickStep.omega_max``: max(eta, 1, sqrt(1 + K + s)), s a bound on the
    general machine's added stiffness (the sum of |S - I|'s entries; 0 on the paper's)."""
    extra = abs(pars[P_SXX]) + abs(pars[P_SXY]) + abs(pars[P_SYX]) + abs(pars[P_SYY])
    return max(pars[P_ETA], 1.0, math.sqrt(1.0 + pars[P_K] + extra))


@register_jitable
def stick_prepare(
    tau0: float, s0: np.ndarray, h: float, pars: np.ndarray | tuple[float, ...], st: np.ndarray,
    meta: np.ndarray,
) -> None:  # fmt: skip
    """``StickStep(tau0, s0, h)``: st rows (s0, s1, f0, f1), meta = (tau0, h). The
    paper's machine at a constant speed has its own step, without the general machine's
    terms (a branch to them in every evaluation cost the paper's stick step about 30 %)."""
    if is_paper_record(pars):
        _paper_stick_rk4(tau0, s0, h, pars, st, meta)
    else:
        _general_stick_rk4(tau0, s0, h, pars, st, meta)


def _stick_rk4(f: Callable[..., tuple]) -> Callable[..., None]:
    """``stick_prepare``'s RK4 step on the rolling law ``f`` (compilable core)."""

    def rk4(
        tau0: float, s0: np.ndarray, h: float, pars: np.ndarray | tuple[float, ...],
        st: np.ndarray, meta: np.ndarray,
    ) -> None:  # fmt: skip
        x, y, vx, vy = s0[0], s0[1], s0[2], s0[3]
        k1 = f(tau0, x, y, vx, vy, pars)
        h2 = h / 2
        k2 = f(tau0 + h2, x + h2 * k1[0], y + h2 * k1[1], vx + h2 * k1[2], vy + h2 * k1[3], pars)
        k3 = f(tau0 + h2, x + h2 * k2[0], y + h2 * k2[1], vx + h2 * k2[2], vy + h2 * k2[3], pars)
        k4 = f(tau0 + h, x + h * k3[0], y + h * k3[1], vx + h * k3[2], vy + h * k3[3], pars)
        h6 = h / 6
        for j in range(4):
            st[0, j] = s0[j]
            st[1, j] = s0[j] + h6 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j])
            st[2, j] = k1[j]
        f1 = f(tau0 + h, st[1, 0], st[1, 1], st[1, 2], st[1, 3], pars)
        for j in range(4):
            st[3, j] = f1[j]
        meta[0] = tau0
        meta[1] = h

    return register_jitable(rk4)


_paper_stick_rk4 = _stick_rk4(_paper_stick_f)
_general_stick_rk4 = _stick_rk4(_general_stick_f)


@register_jitable
def _hermite(t, meta):
    u = (t - meta[0]) / meta[1]
    u2 = u * u
    u3 = u2 * u
    return 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2


@register_jitable
def stick_at(t: float, st: np.ndarray, meta: np.ndarray, row: np.ndarray) -> None:
    """``StickStep.states`` at a scalar time (the order of its scalar expression)."""
    h = meta[1]
    h00, h10, h01, h11 = _hermite(t, meta)
    for j in range(4):
        row[j] = h00 * st[0, j] + h10 * h * st[2, j] + h01 * st[1, j] + h11 * h * st[3, j]


@jit
def stick_ev(
    t: float,
    deriv: bool,
    ctx: tuple[np.ndarray, np.ndarray, np.ndarray],
    row: np.ndarray,
    drow: np.ndarray,
) -> None:
    """ev of a stick step: ctx = (st, meta, pars); drow = the rolling law's rhs there."""
    st, meta, pars = ctx
    stick_at(t, st, meta, row)
    if deriv:
        f = rhs_record(t, row[0], row[1], row[2], row[3], pars, STICK)
        for j in range(4):
            drow[j] = f[j]


@jit
def contact_ev(
    t: float,
    deriv: bool,
    ctx: tuple[bool, float, np.ndarray, tuple[np.ndarray, ...]],
    row: np.ndarray,
    drow: np.ndarray,
) -> None:
    """ev of a linearised contact step: ctx = (polar, tau0, pars, ws) (``_evaluate``)."""
    polar, tau0, pars, ws = ctx
    _evaluate(polar, tau0, t, pars, ws, row, drow)

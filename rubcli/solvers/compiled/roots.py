"""Events located on a DOP853 step's dense output, compiled.

The pre-check of a step (may it hold an event?), the dense output as a segment of the
shared event search (``_dop853_ev`` for ``events.locate``, the one definition of the
event functions, the crossing rules and the Brent iteration, which the Python paths
run too), and the application of an event (``events.switch_regime``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from numba.extending import register_jitable

from rubcli import model
from rubcli.model import (
    P_E,
    P_ETA,
    P_K,
    P_MU,
    P_NU,
    P_PHI0,
    P_RATE,
    P_RP,
    STICK_EXIT_MARGIN,
    rolling_velocity,
    stick_friction_value,
)
from rubcli.solvers.compiled.dop853 import DOP_SCAN_POINTS, _dop853_dense_at
from rubcli.solvers.compiled.jit import jit, jit_inline
from rubcli.solvers.compiled.precheck import (
    _may_cross_relative,
    _slip_may_cross,
    _surface_may_cross,
)
from rubcli.solvers.compiled.rhs import _rhs_into, _rhs_paper_into
from rubcli.solvers.events import (
    event_search,
    run_time,
    spin_at,
    stick_margin,
    switch_regime,
)

if TYPE_CHECKING:
    import numpy as np

FREE_REGIME, STICK_REGIME = model.FREE, model.STICK


def dop853_precheck(rhs_into: Callable[..., None],
                    stick_may_exit: Callable[..., bool]) -> Callable[..., bool]:  # fmt: skip
    """The event pre-check of one accepted DOP853 step, its slip rates from
    ``rhs_into`` and its stick exit from ``stick_may_exit`` (``_rhs_into`` and
    ``stick_margin``: any machine; ``_rhs_paper_into`` and ``_paper_margin``: the paper's
    machine at a constant speed), compiled."""

    def may_have_event(
        t_old: float, h: float, y_old: np.ndarray, F: np.ndarray, pars: np.ndarray,
        regime: int, grid: np.ndarray, S: np.ndarray, dS: np.ndarray, hv: np.ndarray,
        hd: np.ndarray, row: np.ndarray, starts: tuple[bool, bool, bool],
    ) -> bool:  # fmt: skip
        """The event pre-check of one accepted step on scipy_ivp's scan grid.

        Conservative, like the analytic loop's (``precheck``): False only if
        ``events.earliest_event`` surely finds no event in the step (contact entry in free
        flight; contact exit and slip reversal in slip; contact exit and stick exit in
        stick). ``starts`` = (on the contact surface, on the slip surface, slip start
        immediate), as ``events.start_flags`` gives them. Fills ``grid`` (``np.linspace``
        of the step, element for element, as Python builds it) and the dense states ``S``
        on it.
        """
        n = DOP_SCAN_POINTS
        step = h / n
        for k in range(n):
            grid[k] = k * step + t_old
        grid[n] = t_old + h
        for k in range(n + 1):
            _dop853_dense_at(grid[k], t_old, h, y_old, F, row)
            for i in range(4):
                S[k, i] = row[i]
        direction = 1.0 if regime == FREE_REGIME else -1.0
        if _surface_may_cross(grid, S, n, direction, 1.0, hv, hd, starts[0]):
            return True
        if regime == STICK_REGIME:
            return stick_may_exit(grid, S, n, t_old, h, y_old, F, pars, hv, hd, row)
        if regime == FREE_REGIME or pars[P_MU] == 0.0:
            return False
        for k in range(n + 1):
            rhs_into(grid[k], S[k], pars, regime, row)
            for i in range(4):
                dS[k, i] = row[i]
        spin, spin_rate = spin_at(grid[0], pars), pars[P_RP] * pars[P_RATE]
        return _slip_may_cross(grid, S, dS, n, float(regime), spin, spin_rate, 1.0, hv, hd, starts)

    return jit(may_have_event)


def _stick_may_exit_with(margin: Callable[..., float]) -> Callable[..., bool]:
    """The stick-exit pre-check on the margin ``margin(t, x, y, vx, vy, pars, sign)``
    (``events.stick_margin``, or ``_paper_margin``), compilable."""

    def stick_may_exit(
        grid: np.ndarray, S: np.ndarray, n: int, t_old: float, h: float, y_old: np.ndarray,
        F: np.ndarray, pars: np.ndarray, hv: np.ndarray, hd: np.ndarray, row: np.ndarray,
    ) -> bool:  # fmt: skip
        """The pre-check of the stick exit (``earliest_event`` in stick): the margin on the
        grid for each side of the friction cone, its rate by the same central differences."""
        d = 1e-6 * max(1.0, grid[n] - grid[0])
        for sign in (1.0, -1.0):
            for i in range(n + 1):
                hv[i] = margin(grid[i], S[i, 0], S[i, 1], S[i, 2], S[i, 3], pars, sign)
                _dop853_dense_at(grid[i] + d, t_old, h, y_old, F, row)
                up = margin(grid[i] + d, row[0], row[1], row[2], row[3], pars, sign)
                _dop853_dense_at(grid[i] - d, t_old, h, y_old, F, row)
                down = margin(grid[i] - d, row[0], row[1], row[2], row[3], pars, sign)
                hd[i] = (up - down) / (2.0 * d)
            if _may_cross_relative(grid, hv, hd, n):
                return True
        return False

    return register_jitable(stick_may_exit)


@register_jitable
def _paper_margin(t, x, y, vx, vy, pars, sign):
    """``events.stick_margin`` on the paper's machine at a constant speed."""
    T = stick_friction_value(t, x, y, vx, vy, pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0])
    limit = pars[P_MU] * pars[P_K] * (math.hypot(x, y) - 1.0)
    return sign * T - limit * (1.0 + STICK_EXIT_MARGIN)


_dop853_may_have_event = dop853_precheck(_rhs_into, _stick_may_exit_with(stick_margin))
_paper_may_have_event = dop853_precheck(_rhs_paper_into, _stick_may_exit_with(_paper_margin))


@jit
def _dop853_ev(t, deriv, ctx, row, drow):
    """The step's dense output as a segment of ``events.locate``: the state at t and,
    with ``deriv``, the regime's right-hand side there (as the Python path's)."""
    t_old, h, y_old, F, pars, regime = ctx
    _dop853_dense_at(t, t_old, h, y_old, F, row)
    if deriv:
        _rhs_into(t, row, pars, regime, drow)


_locate_dense, _ = event_search(_dop853_ev, compile=jit)


@jit
def _dop853_locate(t_old, h, y_old, F, pars, regime, grid, hv, hd, row, drow, starts, band):
    """The event search's ``locate`` on one step's dense output (scan grid ``grid[:DOP_SCAN_POINTS +
    1]``): (tau, kind) of the earliest event, or (NaN, NO_EVENT)."""
    ctx = (t_old, h, y_old, F, pars, regime)
    # the grid size through run_time: a literal would compile the search's scan twice (for
    # Literal[int](DOP_SCAN_POINTS) and for the refinement's int64)
    n = run_time(DOP_SCAN_POINTS)
    return _locate_dense(ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow)


@jit
def _apply_event(kind, t, s, regime, pars):
    """``events.switch_regime`` on a kernel state: (new regime, kind as recorded); ``s``
    is projected onto the rolling constraint in place when stick begins or ends."""
    new, recorded, project = switch_regime(kind, t, s[0], s[1], s[2], s[3], regime, pars)
    if project:
        s[2], s[3] = rolling_velocity(s[0], s[1], s[2], s[3], spin_at(t, pars))
    return new, recorded


@jit
def apply_and_record(
    kind: int, t: float, s: np.ndarray, regime: int, pars: np.ndarray, events_tau: np.ndarray,
    events_kind: np.ndarray, events_state: np.ndarray, events_regimes: np.ndarray, n_events: int,
    y: np.ndarray,
) -> tuple[int, int]:  # fmt: skip
    """A compiled loop's event: ``_apply_event`` on the state ``s`` at t (in place),
    recorded as entry ``n_events`` of the loop's event buffers, and copied into the
    loop's state ``y``, from which the next segment starts. Returns (new regime, kind
    as recorded)."""
    new_regime, recorded = _apply_event(kind, t, s, regime, pars)
    events_tau[n_events] = t
    events_kind[n_events] = recorded
    events_regimes[n_events, 0] = regime
    events_regimes[n_events, 1] = new_regime
    for i in range(4):
        events_state[n_events, i] = s[i]
        y[i] = s[i]
    return new_regime, recorded


@jit_inline
def rotor_project(t: float, row: np.ndarray, pars: np.ndarray) -> None:
    """The event loop's projection of a sample in stick onto the rolling constraint
    (the rotor's: ``ctx`` is the parameter record)."""
    row[2], row[3] = rolling_velocity(row[0], row[1], row[2], row[3], spin_at(t, pars))


@jit_inline
def rotor_apply(
    kind: int, t: float, s: np.ndarray, regime: int, pars: np.ndarray, m: tuple,
    events_tau: np.ndarray, events_kind: np.ndarray, events_state: np.ndarray,
    events_regimes: np.ndarray, n_events: int, y: np.ndarray,
) -> tuple[int, int]:  # fmt: skip
    """The event loop's event on the rotor: ``apply_and_record``."""
    return apply_and_record(kind, t, s, regime, pars, events_tau, events_kind, events_state,
                            events_regimes, n_events, y)  # fmt: skip

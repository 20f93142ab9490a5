"""The conservative event pre-check of a step, compiled.

False only if ``events.first_crossing`` surely finds no crossing of an event function
on the step's scan grid (values within a margin of the level, or an interior maximum the
rise bound cannot keep below it): a step the kernels take without Python is a step in
which the Python event code finds no event. The margins cover the round-off by which
the compiled and the Python propagators can differ.
"""

from __future__ import annotations

from rubcli.model import (
    slip_velocity_rate,
    slip_velocity_value,
)
from rubcli.solvers.compiled.jit import (
    EPS,
    jit,
)

EVENT_MARGIN = 1e-9  # relative margin of the event pre-check (plus eps * cond(V) terms)


@jit
def _may_cross(grid, hv, hd, n, margin_v, margin_d, on_surface, immediate):
    """False only if h surely stays below 0 on (grid[0], grid[n]] (events.first_crossing).

    A conservative form of ``first_crossing``: True at a grid value within ``margin_v``
    of the level, or in an interval whose end rates allow an interior maximum (within
    ``margin_d``) that the rise bound ``2 * length * max|rate|`` cannot keep below the
    level. A segment that starts on this surface (``on_surface``, the event that began
    it) counts as starting just below it, and with ``immediate`` a start rate that is
    not clearly negative may be a zero-duration phase: True.
    """
    if on_surface:
        if immediate and hd[0] >= -margin_d:
            return True
        hv[0] = -abs(hv[0])
    elif hv[0] >= -margin_v:
        return True
    for i in range(n):
        if hv[i + 1] >= -margin_v:
            return True
        if hd[i] > -margin_d and hd[i + 1] < margin_d:
            rise = 2.0 * (grid[i + 1] - grid[i]) * max(abs(hd[i]), abs(hd[i + 1]))
            if max(hv[i], hv[i + 1]) + rise > -margin_v:
                return True
    return False


@jit
def _step_may_have_event(grid, S, dS, n, sign, check_slip, spin, cond, hv, hd, starts):
    """Whether ``events.earliest_event`` might find an event of a slip step on this grid.

    Contact exit: h = -(z^2 - 1) with rate -2 (x vx + y vy); slip reversal (mu > 0):
    h = -sign v_r with rate -sign dv_r/dtau (``events.slip_rate``). The margins are
    relative (``EVENT_MARGIN``) plus the round-off an eigenbasis of condition ``cond``
    allows, so that the compiled and the Python propagators cannot disagree.
    ``starts`` = (on the contact surface, on the slip surface, slip start immediate):
    the segment begins at the event that started it (``earliest_event``'s last_kind).
    """
    if _surface_may_cross(grid, S, n, -1.0, cond, hv, hd, starts[0]):
        return True
    return check_slip and _slip_may_cross(grid, S, dS, n, sign, spin, cond, hv, hd, starts)


@jit
def _surface_may_cross(grid, S, n, direction, cond, hv, hd, on_surface):
    """The pre-check for h = direction * (z^2 - 1): +1 contact entry, -1 contact exit."""
    rel = EVENT_MARGIN + 64.0 * EPS * cond
    rate_scale = 0.0
    for i in range(n + 1):
        x, y, vx, vy = S[i, 0], S[i, 1], S[i, 2], S[i, 3]
        hv[i] = direction * (x * x + y * y - 1.0)
        hd[i] = direction * 2.0 * (x * vx + y * vy)
        rate_scale = max(rate_scale, abs(hd[i]))
    return _may_cross(grid, hv, hd, n, 2.0 * rel, rel * (1.0 + rate_scale), on_surface, True)


@jit
def _slip_may_cross(grid, S, dS, n, sign, spin, cond, hv, hd, starts):
    """The pre-check for the slip reversal h = -sign v_r (mu > 0)."""
    rel = EVENT_MARGIN + 64.0 * EPS * cond
    rate_scale = 0.0
    for i in range(n + 1):
        x, y, vx, vy = S[i, 0], S[i, 1], S[i, 2], S[i, 3]
        hv[i] = -sign * slip_velocity_value(x, y, vx, vy, spin)
        hd[i] = -sign * slip_velocity_rate(x, y, vx, vy, dS[i, 2], dS[i, 3])
        rate_scale = max(rate_scale, abs(hd[i]))
    margin_v = rel * (1.0 + abs(spin))
    return _may_cross(grid, hv, hd, n, margin_v, rel * (1.0 + rate_scale), starts[1], starts[2])

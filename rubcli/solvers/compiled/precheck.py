"""The conservative event pre-check of a step, compiled.

False only if ``events.first_crossing`` surely finds no crossing of an event function
on the step's scan grid (values within a margin of the level, or an interior maximum the
rise bound cannot keep below it): a step the kernels take without Python is a step in
which the Python event code finds no event. The margins cover the round-off by which
the compiled and the Python propagators can differ.

A polar linearised step is first offered to ``polar_step_clear``, which bounds r and
r theta' over the whole step from the closed form's modes, with no grid: where it clears
the step, the scan grid (1/16 of the fastest period, so some 1,000 evaluations a step on
a stiff stator) is not evaluated at all.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from rubcli.model import (
    slip_velocity_rate,
    slip_velocity_value,
)
from rubcli.solvers.compiled.jit import (
    EPS,
    jit,
)
from rubcli.solvers.events import run_time

if TYPE_CHECKING:
    import numpy as np

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
def _may_cross_relative(grid, hv, hd, n):
    """``_may_cross`` of a function that does not start on its surface (a side of the
    friction cone in stick), its margins ``EVENT_MARGIN`` relative to the function's own
    scale: 1 plus its largest |value| and |rate| on the grid."""
    value_scale = 0.0
    rate_scale = 0.0
    for i in range(n + 1):
        value_scale = max(value_scale, abs(hv[i]))
        rate_scale = max(rate_scale, abs(hd[i]))
    margin_v = EVENT_MARGIN * (1.0 + value_scale)
    margin_d = EVENT_MARGIN * (1.0 + rate_scale)
    return _may_cross(grid, hv, hd, n, margin_v, margin_d, run_time(False), run_time(True))


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
    return check_slip and _slip_may_cross(grid, S, dS, n, sign, spin, 0.0, cond, hv, hd, starts)


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
    immediate = run_time(True)
    return _may_cross(grid, hv, hd, n, 2.0 * rel, rel * (1.0 + rate_scale), on_surface, immediate)


@jit
def _slip_may_cross(grid, S, dS, n, sign, spin, spin_rate, cond, hv, hd, starts):
    """The pre-check for the slip reversal h = -sign v_r (mu > 0); the surface speed is
    ``spin`` at grid[0] and changes at ``spin_rate`` (Rp eta', 0 at constant speed)."""
    rel = EVENT_MARGIN + 64.0 * EPS * cond
    rate_scale = 0.0
    spin_scale = abs(spin)
    for i in range(n + 1):
        x, y, vx, vy = S[i, 0], S[i, 1], S[i, 2], S[i, 3]
        spin_i = spin + spin_rate * (grid[i] - grid[0])
        hv[i] = -sign * slip_velocity_value(x, y, vx, vy, spin_i)
        hd[i] = -sign * (slip_velocity_rate(x, y, vx, vy, dS[i, 2], dS[i, 3]) + spin_rate)
        rate_scale = max(rate_scale, abs(hd[i]))
        spin_scale = max(spin_scale, abs(spin_i))
    margin_v = rel * (1.0 + spin_scale)
    return _may_cross(grid, hv, hd, n, margin_v, rel * (1.0 + rate_scale), starts[1], starts[2])


# relative rounding allowed for in the oscillation form's cancelling terms (~45 ulp)
ROUNDING = 1e-14


@jit
def _component_range(i, lam, V, coef, h):
    """(lo, hi) bounding component i of Re(V w(s)) for s in [0, h], where w_j(s) =
    s phi1(lam_j s) c0_j + s^2 phi2(lam_j s) c1_j is the polar step's closed form
    (``propagators._evaluate_polar``: P(s) = p0 + Re(V w(s)), c0 = ``coef[0]``, c1 =
    ``coef[1]``).

    Each mode's term lies in two intervals, and in their intersection: by the integrals
    |s phi1(lam s)| <= h g and |s^2 phi2(lam s)| <= h^2 g / 2 (g = max(1, e^{Re lam h})),
    and, written w = e^{lam s} d - d - s c1 / lam with d = c0 / lam + c1 / lam^2, by its
    constant and linear parts exactly and its oscillation by |V_ij d| g. The second is
    the tight one for a mode faster than the step (a ringing contact mode counts with its
    amplitude, not with its rate times the step), the first for a slow one, where the
    second's terms cancel and its rounding (widened by ROUNDING) makes it the wider one.
    Non-finite data give an infinite or NaN range (no clearance).
    """
    lo = 0.0
    hi = 0.0
    for j in range(lam.shape[0]):
        lj = lam[j]
        g = max(1.0, math.exp(lj.real * h))
        v = V[i, j]
        spread = abs(v) * (abs(coef[0, j]) * h + 0.5 * abs(coef[1, j]) * h * h) * g
        lo_j, hi_j = -spread, spread
        if lj != 0.0:
            d = coef[0, j] / lj + coef[1, j] / (lj * lj)
            const = -(v * d).real
            drift = -(v * coef[1, j] / lj).real * h
            # the rounding of const +- amplitude, which cancel for a slow mode (|d| huge)
            slack = ROUNDING * (abs(v * d) + abs(drift))
            amplitude = abs(v * d) * g + slack
            lo_j = max(lo_j, const + min(0.0, drift) - amplitude)
            hi_j = min(hi_j, const + max(0.0, drift) + amplitude)
        lo += lo_j
        hi += hi_j
    return lo, hi


@jit
def polar_step_clear(
    ws: tuple[np.ndarray, ...], h: float, cond: float, sign: float, check_slip: bool, spin: float
) -> bool:
    """True if the polar linearised step prepared in ``ws`` (``propagators._prepare_polar``)
    surely holds no event on [0, h]: r stays above 1 (no contact exit) and, with
    friction (``check_slip``), sign v_r = sign (Rp eta + r theta') above 0 (no slip
    reversal), each by the pre-check's relative margin, on the bounds of r and theta'
    from ``_component_range`` (v_r by interval arithmetic). It holds for every point of
    the step, so for every point of the scan grid ``_step_may_have_event`` would test.

    Not for a step that starts on an event surface (the caller's ``starts``): there the
    event function starts at zero and no margin can clear it.
    """
    lam, V, coef, real = ws[0], ws[1], ws[3], ws[5]
    rel = EVENT_MARGIN + 64.0 * EPS * cond
    r0, w0 = real[0], real[3]
    lo_r, hi_r = _component_range(run_time(0), lam, V, coef, h)
    if not r0 + lo_r - 1.0 > 2.0 * rel * r0:
        return False
    if not check_slip:
        return True
    lo_w, hi_w = _component_range(run_time(3), lam, V, coef, h)
    a, b = r0 + lo_r, r0 + hi_r
    c, d = w0 + lo_w, w0 + hi_w
    low = spin + min(min(a * c, a * d), min(b * c, b * d))
    high = spin + max(max(a * c, a * d), max(b * c, b * d))
    margin = rel * (1.0 + abs(spin) + abs(spin + r0 * w0))
    return low > margin if sign > 0.0 else high < -margin

"""Event functions and root location shared by the solvers.

Two non-smoothnesses end a segment: the contact surface ``z = 1`` (model notes 1) and,
in contact with friction, the slip reversal ``v_r = 0``. Each solver integrates one
regime at a time and stops at the first event, so no step straddles a kink.

A crossing is sought with a *direction*: we look for ``h = direction * g`` going from
negative to non-negative. The segment's start may lie on the surface (it is the event
that began the segment); the start is then treated as being on the near side, and a
crossing *at* the start is reported only when the state moves the wrong way
(``h' >= 0``), which is how a zero-duration (grazing) contact or an inconsistent slip
direction shows itself.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from rubcli import model

# A free orbit whose largest penetration stays below this many clearances is taken as
# a grazing touch that does not enter contact (the force there is below K * 1e-12).
GRAZING_TOLERANCE = 1e-12
# Root location tolerance in tau.
XTOL = 1e-14
RTOL = 4.0 * np.finfo(float).eps


def surface_value(S: np.ndarray) -> np.ndarray:
    """g = z^2 - 1 for states S of shape (4, n) or (4,)."""
    return S[0] ** 2 + S[1] ** 2 - 1.0


def surface_rate(S: np.ndarray) -> np.ndarray:
    """dg/dtau = 2 (x vx + y vy)."""
    return 2.0 * (S[0] * S[2] + S[1] * S[3])


def slip_value(S: np.ndarray, params: model.ModelParams) -> np.ndarray:
    return model.slip_velocity(S[0], S[1], S[2], S[3], params.Rp, params.eta)


def slip_rate(S: np.ndarray, dS: np.ndarray) -> np.ndarray:
    """d v_r / dtau from states S and their derivatives dS (both shape (4, n))."""
    x, y, vx, vy = S
    ax, ay = dS[2], dS[3]
    z = np.hypot(x, y)
    whirl = x * vy - y * vx
    zdot = (x * vx + y * vy) / z
    return (x * ay - y * ax) / z - whirl * zdot / (z * z)


def first_crossing(
    h: Callable[[float], float],
    grid: np.ndarray,
    hv: np.ndarray,
    hd: np.ndarray,
    dh: Callable[[float], float],
    start_on_surface: bool,
    tolerance: float = 0.0,
    start_tolerance: float = 1e-12,
) -> float | None:
    """First time in (grid[0], grid[-1]] where h goes from < 0 to >= 0, or None.

    ``hv`` and ``hd`` are h and dh/dtau on ``grid``; ``h`` and ``dh`` evaluate them at
    any time of the segment. The grid must be fine enough that h has at most one
    extremum per interval (callers use 1/16 of the fastest period or less).

    A sign change between grid points is located by Brent's method. An interior
    maximum of h between two negative values (a dip across the surface and back inside
    one interval) is found as the root of dh; it counts only if h there exceeds
    ``tolerance`` (a grazing touch below it is ignored). With ``start_on_surface`` the
    value at grid[0] is taken as 0 from below: if dh >= 0 there, the crossing is at
    the start itself; otherwise a return to the surface inside the first interval
    counts only if h comes back above ``start_tolerance`` (round-off right after the
    restart is not a crossing).
    """
    n = len(grid) - 1
    if start_on_surface:
        if hd[0] >= 0.0:
            return float(grid[0])
        hv = np.array(hv, dtype=float)
        hv[0] = -max(abs(hv[0]), np.finfo(float).tiny)  # strictly below: -0.0 >= 0.0
        if 0.0 <= hv[1] <= start_tolerance:
            hv[1] = -np.finfo(float).tiny
    for i in range(n):
        a, b = float(grid[i]), float(grid[i + 1])
        ha = hv[i]
        if ha >= 0.0:
            # Only possible at i == 0 without start_on_surface: already across.
            return a
        if hv[i + 1] >= 0.0:
            if i == 0 and start_on_surface:
                # h leaves the surface downwards, then comes back: find the minimum.
                if hd[1] > 0.0 and dh(a) < 0.0:
                    a = brentq(dh, a, b, xtol=XTOL, rtol=RTOL)
                if h(a) >= 0.0:
                    return a
            return brentq(h, a, b, xtol=XTOL, rtol=RTOL)
        if hd[i] > 0.0 and hd[i + 1] < 0.0:
            tm = brentq(dh, a, b, xtol=XTOL, rtol=RTOL)
            if h(tm) > tolerance:
                return brentq(h, a, tm, xtol=XTOL, rtol=RTOL)
    return None


def scan_spacing(omega_max: float, fraction: float = 1.0 / 16.0) -> float:
    """Grid spacing for event scans: ``fraction`` of the fastest period."""
    return fraction * 2.0 * math.pi / max(omega_max, 1e-300)


def entry_regime(s: np.ndarray, params: model.ModelParams) -> int:
    """The slip direction a contact starts in: sign of v_r at the entry state."""
    if params.mu == 0.0:
        return model.SLIP_POSITIVE
    v_r = model.slip_velocity(s[0], s[1], s[2], s[3], params.Rp, params.eta)
    return model.SLIP_POSITIVE if v_r >= 0.0 else model.SLIP_NEGATIVE


def reversal_undone(state: np.ndarray, tau: float, new_regime: int, params) -> bool:
    """True when, slipping in the new direction, v_r would go straight back through zero.

    That is the signature of stick (rolling, notes section 4): neither slip direction is
    consistent, and a plain sign() would chatter.
    """
    d = model.rhs(tau, state, params, new_regime)
    rate = float(slip_rate(np.asarray(state)[:, None], d[:, None])[0])
    return float(new_regime) * rate < 0.0


class StormGuard:
    """Counts switch events at one instant; too many is a switch storm (a clean failure)."""

    LIMIT = 20

    def __init__(self) -> None:
        self.tau: float | None = None
        self.count = 0

    def storm(self, tau: float) -> bool:
        if self.tau is not None and abs(tau - self.tau) <= 1e-12 * max(1.0, abs(tau)):
            self.count += 1
        else:
            self.tau, self.count = tau, 1
        return self.count > self.LIMIT

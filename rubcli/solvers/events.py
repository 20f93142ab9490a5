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
# The band of the position-level surface g relative to the slip band (earliest_event).
SURFACE_BAND = 1.0
# A scan finer than this many points in one step means the linearised step carries a
# frequency the step cannot resolve (a diverged linearisation): the run fails cleanly.
MAX_SCAN_POINTS = 100_000
# The level a stick margin must reach to end stick (first_crossing's start_tolerance).
STICK_EXIT_LEVEL = 1e-12
# Sub-intervals of a first interval in which a segment left its surface and came back.
REFINE_POINTS = 32
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
    return model.slip_velocity_rate(S[0], S[1], S[2], S[3], dS[2], dS[3])


def first_crossing(
    h: Callable[[float], float],
    grid: np.ndarray,
    hv: np.ndarray,
    hd: np.ndarray,
    dh: Callable[[float], float],
    start_on_surface: bool,
    tolerance: float = 0.0,
    start_tolerance: float = 1e-12,
    immediate: bool = True,
    refine: bool = True,
) -> float | None:
    """First time in (grid[0], grid[-1]] where h goes from < 0 to >= 0, or None.

    ``hv`` and ``hd`` are h and dh/dtau on ``grid``; ``h`` and ``dh`` evaluate them at
    any time of the segment. The grid must be fine enough that h has at most one
    extremum per interval (callers use 1/16 of the fastest period or less).

    A sign change between grid points is located by Brent's method. An interior
    maximum of h between two negative values (a dip across the surface and back inside
    one interval) is found as the root of dh; it counts only if h there exceeds
    ``tolerance`` (a grazing touch below it is ignored).

    With ``start_on_surface`` the segment begins on this very surface (the event that
    started it): if dh >= 0 there the crossing is at the start itself (a zero-duration
    phase; ``immediate=False`` skips this for phases that begin with dh = 0 by
    construction, such as leaving stick).

    A crossing must clear ``start_tolerance`` (the noise band of h: round-off for a
    closed form, the tolerance of an adaptive solver's dense output), so noise around
    the surface, after a restart or anywhere, is not a crossing; the crossing is then
    located between the last point truly below zero and the first beyond the band.

    A segment that starts on the surface is never bracketed from its start, where h is
    zero only to round-off and could read as a zero-duration phase: if it leaves the
    surface and comes back before any grid point is truly below zero (a coarse step at
    a loose tolerance, with the return inside the band at the first grid point), the
    return is sought past the minimum of h in the first interval; if h is beyond the
    band at the first grid point and still falling there (it turned twice within that
    interval), on a finer grid of ``REFINE_POINTS`` sub-intervals (``refine``).
    """
    n = len(grid) - 1
    hv = np.array(hv, dtype=float)
    level = start_tolerance
    if start_on_surface:
        if immediate and hd[0] >= 0.0:
            return float(grid[0])
        hv[0] = -max(abs(hv[0]), np.finfo(float).tiny)  # strictly below: -0.0 >= 0.0
    below = 0  # the last grid point where h was truly below zero (not in the band)
    for i in range(n):
        a, b = float(grid[i]), float(grid[i + 1])
        if hv[i + 1] >= level:
            if start_on_surface and below == 0 and hd[1] > 0.0:
                # h left the surface downwards and came back before any grid point was
                # truly below zero: search past its minimum in the first interval
                a = _extremum(dh, float(grid[0]), float(grid[1])) or float(grid[0])
            elif i == 0 and start_on_surface and refine:
                sub = np.linspace(a, b, REFINE_POINTS + 1)
                sv = np.array([h(t) for t in sub])
                sd = np.array([dh(t) for t in sub])
                return first_crossing(
                    h, sub, sv, sd, dh, True, tolerance, start_tolerance, False, False
                )
            elif below < i:
                a = float(grid[below])  # h sat in the restart band: bracket from below
            return _root(h, a, b)
        if hv[i + 1] < 0.0:
            below = i + 1
        if hd[i] > 0.0 and hd[i + 1] < 0.0:
            # h can rise at most ~ rate * length above its end values within one
            # interval (factor 2 for safety): skip maxima that cannot reach the level.
            rise = 2.0 * (b - a) * max(hd[i], -hd[i + 1])
            if max(hv[i], hv[i + 1]) + rise <= max(tolerance, level):
                continue
            tm = _extremum(dh, a, b)
            if tm is not None and h(tm) > max(tolerance, level):
                return _root(h, a, tm)
    return None


def _root(h: Callable[[float], float], a: float, b: float) -> float:
    """Root of h in [a, b] where h(b) >= 0; ``a`` itself if h(a) is not below zero there.

    The grid values that chose [a, b] and the pointwise h can differ by round-off at a
    restart point; then the crossing is at ``a``.
    """
    if h(a) >= 0.0:
        return a
    if h(b) < 0.0:
        return b
    return brentq(h, a, b, xtol=XTOL, rtol=RTOL)


def _extremum(dh: Callable[[float], float], a: float, b: float) -> float | None:
    """Root of dh in [a, b] if dh brackets one there (a noisy rate may not)."""
    da, db = dh(a), dh(b)
    if da == 0.0:
        return a
    if da * db > 0.0:
        return None
    return brentq(dh, a, b, xtol=XTOL, rtol=RTOL)


def scan_spacing(omega_max: float, fraction: float = 1.0 / 16.0) -> float:
    """Grid spacing for event scans: ``fraction`` of the fastest period."""
    return fraction * 2.0 * math.pi / max(omega_max, 1e-300)


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

    def message(self) -> str:
        """The failure message of the storm just detected."""
        return f"switch storm at tau = {self.tau:.6g}: {self.count} events at one instant"


# Event kinds: one code each (what compiled code passes around), and the name a
# SwitchEvent carries (``KIND_NAMES[code]``). NO_EVENT: a segment not begun by an event.
ENTRY, EXIT, REVERSAL, STICK_ENTRY, STICK_EXIT = 0, 1, 2, 3, 4
NO_EVENT = -1
KIND_NAMES = ("contact_entry", "contact_exit", "slip_reversal", "stick_entry", "stick_exit")


def start_flags(last_kind: int) -> tuple[bool, bool, bool]:
    """(on the contact surface, on the slip surface, slip start immediate) of a segment
    begun by the event ``last_kind`` (``NO_EVENT`` if none): the segment starts on that
    event's surface (contact entry/exit: z = 1; slip reversal, stick exit: v_r = 0), and
    after a stick exit the slip leaves v_r = 0 with zero rate (compilable core)."""
    return (
        last_kind in (ENTRY, EXIT),
        last_kind in (REVERSAL, STICK_EXIT),
        last_kind != STICK_EXIT,
    )


def switch_regime(kind, tau, x, y, vx, vy, regime, nu, eta, E, phi0, K, mu, Rp):
    """The switch at a located event of ``kind`` (compilable core).

    Returns ``(new regime, kind as recorded, project)``: contact exit -> free; contact
    entry -> the sign of v_r; stick exit -> the slip the needed friction points to;
    slip reversal -> Filippov's rule (``model.zero_slip_regime_value``), recorded as a
    stick entry when it ends in stick. ``project``: the state must be projected onto the
    rolling constraint (stick begins or ends in contact).
    """
    if kind == EXIT:
        new = model.FREE
    elif kind == ENTRY:
        new = model.entry_regime_value(x, y, vx, vy, mu, Rp * eta)
    elif kind == STICK_EXIT:
        needed = model.stick_friction_value(tau, x, y, vx, vy, nu, eta, E, phi0)
        new = model.SLIP_POSITIVE if needed > 0.0 else model.SLIP_NEGATIVE
    else:  # slip reversal
        new = model.zero_slip_regime_value(tau, x, y, vx, vy, nu, eta, E, phi0, K, mu)
    recorded = STICK_ENTRY if new == model.STICK else kind
    stick = regime == model.STICK or new == model.STICK
    return new, recorded, stick and regime != model.FREE and new != model.FREE


def earliest_event(states, derivatives, grid, regime, params, last_kind, restart_band=1e-12):
    """Earliest event of ``regime`` in (grid[0], grid[-1]]: (tau, kind) or None.

    ``states(t)`` gives the segment's state at a scalar or array time (shape (4,) or
    (4, n)); ``derivatives(t, S)`` its time derivative. ``last_kind`` is the event that
    started the segment (``NO_EVENT`` otherwise): the segment then starts on that event's
    surface. Events by regime: free -> contact entry; slip -> contact exit, slip
    reversal (v_r = 0, if mu > 0); stick -> contact exit, stick exit (|T| = mu F_N).

    ``restart_band``: a slip reversal must clear this band (times 1 + Rp eta) in v_r.
    A closed form gives v_r to round-off (1e-12); an adaptive solver's dense output gives
    the velocity-level v_r only to its tolerance, so scipy methods pass rtol. The
    position-level surface g = z^2 - 1 gets the same band: a solver at tolerance rtol
    cannot tell a contact whose penetration is below ~rtol from none (an orbit riding the
    clearance wanders across z = 1 by that much), so such a touch is not a contact.
    """
    S = states(grid)
    on_surface, on_slip, immediate = start_flags(last_kind)

    def surface(sign):
        def h(t):
            return sign * float(surface_value(states(t)))

        def dh(t):
            return sign * float(surface_rate(states(t)))

        return h, sign * surface_value(S), sign * surface_rate(S), dh

    found = []
    if regime == model.FREE:
        h, hv, hd, dh = surface(+1.0)
        tau = first_crossing(
            h, grid, hv, hd, dh, on_surface, GRAZING_TOLERANCE, SURFACE_BAND * restart_band
        )
        return None if tau is None else (tau, ENTRY)

    h, hv, hd, dh = surface(-1.0)
    tau = first_crossing(h, grid, hv, hd, dh, on_surface, 0.0, SURFACE_BAND * restart_band)
    if tau is not None:
        found.append((tau, EXIT))
    if params.mu > 0.0 and regime in (model.SLIP_POSITIVE, model.SLIP_NEGATIVE):
        sign = float(regime)
        dS = derivatives(grid, S)

        def hv_fn(t):
            return -sign * float(slip_value(states(t), params))

        def dhv_fn(t):
            s = states(t)
            return -sign * float(slip_rate(s[:, None], derivatives(t, s[:, None]))[0])

        scale = 1.0 + abs(params.Rp * params.eta)
        tau = first_crossing(
            hv_fn,
            grid,
            -sign * slip_value(S, params),
            -sign * slip_rate(S, dS),
            dhv_fn,
            on_slip,
            0.0,
            restart_band * scale,
            immediate=immediate,
        )
        if tau is not None:
            found.append((tau, REVERSAL))
    if regime == model.STICK:
        for sign in (+1.0, -1.0):
            # h = sign * T - mu K (z - 1): crosses 0 upwards when the needed friction
            # leaves the friction cone on that side.
            def hs(t, sign=sign):
                s = states(t)
                return _stick_margin(t, s, params, sign)

            def dhs(t, sign=sign):
                d = 1e-6 * max(1.0, grid[-1] - grid[0])
                return (hs(t + d) - hs(t - d)) / (2 * d)

            values = _stick_margin(grid, S, params, sign)
            d = 1e-6 * max(1.0, grid[-1] - grid[0])
            rates = (
                _stick_margin(grid + d, states(grid + d), params, sign)
                - _stick_margin(grid - d, states(grid - d), params, sign)
            ) / (2 * d)
            tau = first_crossing(hs, grid, values, rates, dhs, False, 0.0, STICK_EXIT_LEVEL)
            if tau is not None:
                found.append((tau, STICK_EXIT))
    return min(found, key=lambda item: item[0]) if found else None


def _stick_margin(t, S, params, sign):
    """sign * T - L (1 + STICK_EXIT_MARGIN): stick ends where this rises through 0."""
    T = model.stick_friction(t, S[0], S[1], S[2], S[3], params)
    limit = params.mu * params.K * (np.hypot(S[0], S[1]) - 1.0)
    return sign * T - limit * (1.0 + model.STICK_EXIT_MARGIN)


def initial_kind(s, regime: int, params) -> int:
    """The event surface an initial state lies on, if any (so it is not re-detected)."""
    if abs(math.hypot(s[0], s[1]) - 1.0) <= 1e-14:
        return ENTRY if regime != model.FREE else EXIT
    if regime in (model.SLIP_POSITIVE, model.SLIP_NEGATIVE) and params.mu > 0.0:
        v_r = model.slip_velocity(s[0], s[1], s[2], s[3], params.Rp, params.eta)
        if abs(v_r) <= 1e-12 * (1.0 + abs(params.Rp * params.eta)):
            return STICK_EXIT
    return NO_EVENT


def apply_event(tau: float, kind: int, state, regime: int, params):
    """The switch at a located event (``switch_regime``), applied to a Python state.

    Returns ``(state, new_regime, recorded kind, SwitchEvent)``; the state is projected
    onto the rolling constraint when stick begins or ends in contact.
    """
    from rubcli.solution import SwitchEvent

    state = np.asarray(state, dtype=float)
    new_regime, recorded, project = switch_regime(
        kind, tau, state[0], state[1], state[2], state[3], regime, *model.params_vector(params)
    )
    if project:
        state = model.project_to_rolling(state, params)
    event = SwitchEvent(tau, KIND_NAMES[recorded], tuple(state), regime, new_regime)
    return state, new_regime, recorded, event

"""Events located on a DOP853 step's dense output, compiled.

A transcription of ``events.earliest_event`` for the compiled DOP853 (the Python event
code stays the definition; ``compiled_events=False`` runs it instead, and
tests/test_dop853_jit.py holds the two to the same events): the pre-check of a step,
the event functions (contact surface, slip, stick margin), scipy's Brent iteration,
``first_crossing``'s decisions, the earliest event of a step and its application
(``events.switch_regime``).
"""

from __future__ import annotations

import math

import numpy as np

from rubcli import model
from rubcli.model import (
    rolling_velocity,
    slip_velocity_rate,
    slip_velocity_value,
    stick_friction_value,
)
from rubcli.solvers.compiled.dop853 import (
    DOP_SCAN_POINTS,
    _dop853_dense_at,
)
from rubcli.solvers.compiled.jit import (
    jit,
)
from rubcli.solvers.compiled.precheck import (
    EVENT_MARGIN,
    _may_cross,
    _slip_may_cross,
    _surface_may_cross,
)
from rubcli.solvers.compiled.rhs import (
    _rhs_into,
)
from rubcli.solvers.events import (
    ENTRY,
    EXIT,
    GRAZING_TOLERANCE,
    REFINE_POINTS,
    REVERSAL,
    RTOL,
    STICK_EXIT,
    STICK_EXIT_LEVEL,
    SURFACE_BAND,
    XTOL,
    switch_regime,
)

FREE_REGIME, STICK_REGIME = model.FREE, model.STICK
STICK_EXIT_MARGIN = model.STICK_EXIT_MARGIN
SLIP_POSITIVE_REGIME, SLIP_NEGATIVE_REGIME = model.SLIP_POSITIVE, model.SLIP_NEGATIVE
BRENT_XTOL, BRENT_RTOL = XTOL, RTOL  # events' root tolerances
TINY = np.finfo(float).tiny


# Event functions of events.earliest_event: the surface z = 1, the slip v_r = 0, and the
# stick margin (the needed friction against the friction cone).
FN_SURFACE, FN_SLIP, FN_STICK = 0, 1, 2


@jit
def _dop853_may_have_event(t_old, h, y_old, F, pars, regime, grid, S, dS, hv, hd, row, starts):
    """The event pre-check of one accepted step on scipy_ivp's scan grid.

    Conservative, like ``advance_contact``'s: False only if ``events.earliest_event``
    surely finds no event in the step (contact entry in free flight; contact exit and
    slip reversal in slip; contact exit and stick exit in stick). ``starts`` = (on the
    contact surface, on the slip surface, slip start immediate), as in
    ``advance_contact``. Fills ``grid`` (``np.linspace`` of the step, element for
    element, as Python builds it) and the dense states ``S`` on it.
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
        return _stick_may_exit(grid, S, n, t_old, h, y_old, F, pars, hv, hd, row)
    if regime == FREE_REGIME or pars[5] == 0.0:
        return False
    for k in range(n + 1):
        _rhs_into(grid[k], S[k], pars, regime, row)
        for i in range(4):
            dS[k, i] = row[i]
    spin = pars[6] * pars[1]
    return _slip_may_cross(grid, S, dS, n, float(regime), spin, 1.0, hv, hd, starts)


@jit
def _stick_margin_at(t, s, pars, sign):
    """``events._stick_margin``: sign T - mu K (z - 1) (1 + STICK_EXIT_MARGIN)."""
    T = stick_friction_value(t, s[0], s[1], s[2], s[3], pars[0], pars[1], pars[2], pars[3])
    limit = pars[5] * pars[4] * (math.hypot(s[0], s[1]) - 1.0)
    return sign * T - limit * (1.0 + STICK_EXIT_MARGIN)


@jit
def _stick_may_exit(grid, S, n, t_old, h, y_old, F, pars, hv, hd, row):
    """The pre-check of the stick exit (``earliest_event`` in stick): the margin on the
    grid for each side of the friction cone, its rate by the same central differences."""
    d = 1e-6 * max(1.0, grid[n] - grid[0])
    for sign in (1.0, -1.0):
        value_scale = 0.0
        rate_scale = 0.0
        for i in range(n + 1):
            hv[i] = _stick_margin_at(grid[i], S[i], pars, sign)
            _dop853_dense_at(grid[i] + d, t_old, h, y_old, F, row)
            up = _stick_margin_at(grid[i] + d, row, pars, sign)
            _dop853_dense_at(grid[i] - d, t_old, h, y_old, F, row)
            down = _stick_margin_at(grid[i] - d, row, pars, sign)
            hd[i] = (up - down) / (2.0 * d)
            value_scale = max(value_scale, abs(hv[i]))
            rate_scale = max(rate_scale, abs(hd[i]))
        margin_v = EVENT_MARGIN * (1.0 + value_scale)
        if _may_cross(grid, hv, hd, n, margin_v, EVENT_MARGIN * (1.0 + rate_scale), False, True):
            return True
    return False


@jit
def _event_fn(t, fn, sign, deriv, t_old, h, y_old, F, pars, regime, d, row, drow):
    """An event function of ``events.earliest_event`` (or its rate) on the dense output,
    evaluated as the Python code evaluates it:

    - FN_SURFACE: ``sign (z^2 - 1)``, rate ``sign 2 (x vx + y vy)``;
    - FN_SLIP: ``-sign v_r``, rate ``-sign dv_r/dtau`` with the regime's right-hand side;
    - FN_STICK: ``_stick_margin`` for side ``sign``, rate by central differences of
      half-width ``d``.
    """
    if fn == FN_STICK:
        if not deriv:
            _dop853_dense_at(t, t_old, h, y_old, F, row)
            return _stick_margin_at(t, row, pars, sign)
        _dop853_dense_at(t + d, t_old, h, y_old, F, row)
        up = _stick_margin_at(t + d, row, pars, sign)
        _dop853_dense_at(t - d, t_old, h, y_old, F, row)
        down = _stick_margin_at(t - d, row, pars, sign)
        return (up - down) / (2.0 * d)
    _dop853_dense_at(t, t_old, h, y_old, F, row)
    x, y, vx, vy = row[0], row[1], row[2], row[3]
    if fn == FN_SURFACE:
        if deriv:
            return sign * (2.0 * (x * vx + y * vy))
        return sign * (x**2 + y**2 - 1.0)
    if deriv:
        _rhs_into(t, row, pars, regime, drow)
        return -sign * slip_velocity_rate(x, y, vx, vy, drow[2], drow[3])
    return -sign * slip_velocity_value(x, y, vx, vy, pars[6] * pars[1])


@jit
def _brentq(a, b, fa, fb, fn, sign, deriv, t_old, h, y_old, F, pars, regime, d, row, drow):
    """scipy's ``brentq`` (scipy/optimize/Zeros/brentq.c: Brent's method with its
    extrapolation formula) on ``_event_fn``, with ``events.XTOL`` and ``events.RTOL``;
    ``fa``, ``fb``: the function at a and b, of opposite signs."""
    xpre, xcur, fpre, fcur = a, b, fa, fb
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    for _ in range(100):
        if fpre != 0.0 and fcur != 0.0 and ((fpre < 0.0) != (fcur < 0.0)):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = (BRENT_XTOL + BRENT_RTOL * abs(xcur)) / 2.0
        sbis = (xblk - xcur) / 2.0
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:  # interpolate
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:  # extrapolate
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry  # good short step
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = _event_fn(xcur, fn, sign, deriv, t_old, h, y_old, F, pars, regime, d, row, drow)
    return xcur


@jit
def _root(a, b, fn, sign, t_old, h, y_old, F, pars, regime, d, row, drow):
    """``events._root``: root of h in [a, b] where h(b) >= 0."""
    fa = _event_fn(a, fn, sign, False, t_old, h, y_old, F, pars, regime, d, row, drow)
    if fa >= 0.0:
        return a
    fb = _event_fn(b, fn, sign, False, t_old, h, y_old, F, pars, regime, d, row, drow)
    if fb < 0.0:
        return b
    return _brentq(a, b, fa, fb, fn, sign, False, t_old, h, y_old, F, pars, regime, d, row, drow)


@jit
def _extremum(a, b, fn, sign, t_old, h, y_old, F, pars, regime, d, row, drow):
    """``events._extremum``: root of the rate in [a, b] if it brackets one, else NaN."""
    da = _event_fn(a, fn, sign, True, t_old, h, y_old, F, pars, regime, d, row, drow)
    db = _event_fn(b, fn, sign, True, t_old, h, y_old, F, pars, regime, d, row, drow)
    if da == 0.0:
        return a
    if da * db > 0.0:
        return math.nan
    return _brentq(a, b, da, db, fn, sign, True, t_old, h, y_old, F, pars, regime, d, row, drow)


@jit
def _first_crossing(
    fn, sign, grid, hv, hd, n, on_surface, tolerance, level, immediate,
    t_old, h, y_old, F, pars, regime, d, row, drow,
):  # fmt: skip
    """``events.first_crossing`` for one event function on a step's dense output: the
    crossing time, or NaN. The grid values ``hv``, ``hd`` are filled here as Python
    computes them; then the same decisions in the same order, with the same root
    finder (and the same refinement of a first interval), so it returns what the
    Python code returns."""
    for i in range(n + 1):
        hv[i] = _event_fn(grid[i], fn, sign, False, t_old, h, y_old, F, pars, regime, d, row, drow)
        hd[i] = _event_fn(grid[i], fn, sign, True, t_old, h, y_old, F, pars, regime, d, row, drow)
    t, a, b = _crossing_scan(
        fn, sign, grid, hv, hd, n, on_surface, tolerance, level, immediate, True,
        t_old, h, y_old, F, pars, regime, d, row, drow,
    )  # fmt: skip
    if not math.isnan(a):  # events.first_crossing's refinement of the first interval
        m = REFINE_POINTS
        sub, sv, sd = np.empty(m + 1), np.empty(m + 1), np.empty(m + 1)
        step = (b - a) / m  # np.linspace(a, b, m + 1)
        for k in range(m):
            sub[k] = k * step + a
        sub[m] = b
        for k in range(m + 1):
            sv[k] = _event_fn(
                sub[k], fn, sign, False, t_old, h, y_old, F, pars, regime, d, row, drow
            )
            sd[k] = _event_fn(
                sub[k], fn, sign, True, t_old, h, y_old, F, pars, regime, d, row, drow
            )
        t, a, b = _crossing_scan(
            fn, sign, sub, sv, sd, m, True, tolerance, level, False, False,
            t_old, h, y_old, F, pars, regime, d, row, drow,
        )  # fmt: skip
    return t


@jit
def _crossing_scan(
    fn, sign, grid, hv, hd, n, on_surface, tolerance, level, immediate, refine,
    t_old, h, y_old, F, pars, regime, d, row, drow,
):  # fmt: skip
    """The loop of ``events.first_crossing`` on filled grid values: ``(t, NaN, NaN)``
    (t the crossing or NaN), or ``(NaN, a, b)`` when the first interval [a, b] must be
    refined (``refine``)."""
    if on_surface:
        if immediate and hd[0] >= 0.0:
            return grid[0], math.nan, math.nan
        hv[0] = -max(abs(hv[0]), TINY)
    below = 0
    for i in range(n):
        a, b = grid[i], grid[i + 1]
        if hv[i + 1] >= level:
            if on_surface and below == 0 and hd[1] > 0.0:
                tm = _extremum(
                    grid[0], grid[1], fn, sign, t_old, h, y_old, F, pars, regime, d, row, drow
                )
                # Python: _extremum(...) or grid[0]
                a = tm if not math.isnan(tm) and tm != 0.0 else grid[0]
            elif i == 0 and on_surface and refine:
                return math.nan, a, b
            elif below < i:
                a = grid[below]
            t = _root(a, b, fn, sign, t_old, h, y_old, F, pars, regime, d, row, drow)
            return t, math.nan, math.nan
        if hv[i + 1] < 0.0:
            below = i + 1
        if hd[i] > 0.0 and hd[i + 1] < 0.0:
            rise = 2.0 * (b - a) * max(hd[i], -hd[i + 1])
            if max(hv[i], hv[i + 1]) + rise <= max(tolerance, level):
                continue
            tm = _extremum(a, b, fn, sign, t_old, h, y_old, F, pars, regime, d, row, drow)
            if math.isnan(tm):
                continue
            peak = _event_fn(tm, fn, sign, False, t_old, h, y_old, F, pars, regime, d, row, drow)
            if peak > max(tolerance, level):
                t = _root(a, tm, fn, sign, t_old, h, y_old, F, pars, regime, d, row, drow)
                return t, math.nan, math.nan
    return math.nan, math.nan, math.nan


@jit
def _dop853_locate(t_old, h, y_old, F, pars, regime, grid, hv, hd, row, drow, starts, band):
    """``events.earliest_event`` on one step: (tau, kind) of the earliest event, or
    (NaN, -1). ``band`` is the restart band; the same candidates in the same order, the
    first of equal times kept (Python's ``min``)."""
    n = DOP_SCAN_POINTS
    d = 1e-6 * max(1.0, grid[n] - grid[0])
    if regime == FREE_REGIME:
        t = _first_crossing(
            FN_SURFACE, 1.0, grid, hv, hd, n, starts[0], GRAZING_TOLERANCE,
            SURFACE_BAND * band, True, t_old, h, y_old, F, pars, regime, d, row, drow,
        )  # fmt: skip
        return (t, ENTRY) if not math.isnan(t) else (t, -1)
    best, kind = math.nan, -1
    t = _first_crossing(
        FN_SURFACE, -1.0, grid, hv, hd, n, starts[0], 0.0, SURFACE_BAND * band, True,
        t_old, h, y_old, F, pars, regime, d, row, drow,
    )  # fmt: skip
    if not math.isnan(t):
        best, kind = t, EXIT
    if pars[5] > 0.0 and regime != STICK_REGIME:
        level = band * (1.0 + abs(pars[6] * pars[1]))
        t = _first_crossing(
            FN_SLIP, float(regime), grid, hv, hd, n, starts[1], 0.0, level, starts[2],
            t_old, h, y_old, F, pars, regime, d, row, drow,
        )  # fmt: skip
        if not math.isnan(t) and (math.isnan(best) or t < best):
            best, kind = t, REVERSAL
    if regime == STICK_REGIME:
        for sign in (1.0, -1.0):
            t = _first_crossing(
                FN_STICK, sign, grid, hv, hd, n, False, 0.0, STICK_EXIT_LEVEL, True,
                t_old, h, y_old, F, pars, regime, d, row, drow,
            )  # fmt: skip
            if not math.isnan(t) and (math.isnan(best) or t < best):
                best, kind = t, STICK_EXIT
    return best, kind


@jit
def _apply_event(kind, t, s, regime, pars):
    """``events.switch_regime`` on a kernel state: (new regime, kind as recorded); ``s``
    is projected onto the rolling constraint in place when stick begins or ends."""
    new, recorded, project = switch_regime(
        kind, t, s[0], s[1], s[2], s[3], regime,
        pars[0], pars[1], pars[2], pars[3], pars[4], pars[5], pars[6],
    )  # fmt: skip
    if project:
        s[2], s[3] = rolling_velocity(s[0], s[1], s[2], s[3], pars[6] * pars[1])
    return new, recorded

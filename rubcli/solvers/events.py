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
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from rubcli import model
from rubcli.model import P_ETA, P_K, P_MU, P_RATE, P_RP, P_TAU0
from rubcli.solution import KIND_NAMES, SwitchEvent

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike

    from rubcli.model import FloatOrArray

_T = TypeVar("_T")  # run_time's and compile_time's value: what goes in comes out

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
# A zero-duration phase needs the rate at the start and at this fraction of the first
# interval later to be >= 0: a start rate that is zero to round-off (a tangential start,
# as at an exit located at the apex of a graze) is decided by where h goes next.
LOOK_AHEAD = 1e-6
# The entry of an extended system's state that holds the unbalance's speed w (its surface
# speed is Rp w: ``solvers.extended``).
SPEED = 5
# Root location tolerance in tau.
XTOL = 1e-14
RTOL = 4.0 * np.finfo(float).eps


def surface_value(S: np.ndarray) -> np.ndarray:
    """g = z^2 - 1 for states S of shape (4, n) or (4,)."""
    return S[0] ** 2 + S[1] ** 2 - 1.0


def surface_rate(S: np.ndarray) -> np.ndarray:
    """dg/dtau = 2 (x vx + y vy)."""
    return 2.0 * (S[0] * S[2] + S[1] * S[3])


def slip_value(S: np.ndarray, params: model.ModelParams, t: FloatOrArray) -> np.ndarray:
    """v_r of states S (shape (4, n)) at the times t."""
    return model.slip_velocity(S[0], S[1], S[2], S[3], params.Rp, params.speed(t))


def slip_rate(S: np.ndarray, dS: np.ndarray, params: model.ModelParams) -> np.ndarray:
    """d v_r / dtau from states S and their derivatives dS (both shape (4, n)); the
    surface speed's rate Rp eta' while the speed changes."""
    out = model.slip_velocity_rate(S[0], S[1], S[2], S[3], dS[2], dS[3])
    return out + params.Rp * params.rate if params.rate != 0.0 else out


def spin_at(t: float, pars: np.ndarray) -> float:
    """Rp eta(t) from a parameter record (compilable core)."""
    rate = pars[P_RATE]
    if rate == 0.0:  # a constant speed (the event search's hot path)
        return pars[P_RP] * pars[P_ETA]
    return pars[P_RP] * (pars[P_ETA] + rate * (t - pars[P_TAU0]))


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
) -> float | None:
    """First time in (grid[0], grid[-1]] where a scalar h goes from < 0 to >= 0, or None.

    ``crossing`` for a given function: ``hv`` and ``hd`` are h and dh/dtau on ``grid``;
    ``h`` and ``dh`` evaluate them at any time of the segment (``FN_GIVEN``).
    """
    n = len(grid) - 1
    values, rates = np.array(hv, dtype=float), np.array(hd, dtype=float)
    tau = _python_crossing(
        _GivenFunction(h, dh), FN_GIVEN, 1.0, np.asarray(grid, dtype=float), values, rates, n,
        start_on_surface, tolerance, start_tolerance, immediate, None, 0.0, np.zeros(4),
        np.zeros(4),
    )  # fmt: skip
    return None if math.isnan(tau) else float(tau)


def scan_spacing(omega_max: float, fraction: float = 1.0 / 16.0) -> float:
    """Grid spacing for event scans: ``fraction`` of the fastest period."""
    return fraction * 2.0 * math.pi / max(omega_max, 1e-300)


class StormGuard:
    """Counts switch events at one instant; too many is a switch storm (a clean failure)."""

    LIMIT = 20
    INSTANT = 1e-12  # events within INSTANT * max(1, |tau|) of each other are one instant

    def __init__(self) -> None:
        self.tau: float | None = None
        self.count = 0

    def storm(self, tau: float) -> bool:
        if self.tau is not None and abs(tau - self.tau) <= self.INSTANT * max(1.0, abs(tau)):
            self.count += 1
        else:
            self.tau, self.count = tau, 1
        return self.count > self.LIMIT

    def message(self) -> str:
        """The failure message of the storm just detected."""
        return f"switch storm at tau = {self.tau:.6g}: {self.count} events at one instant"


# Event kinds: one code each (what compiled code passes around), and the name a
# SwitchEvent carries (``KIND_NAMES[code]``, defined with the records in rubcli.solution).
# NO_EVENT: a segment not begun by an event.
ENTRY, EXIT, REVERSAL, STICK_ENTRY, STICK_EXIT = 0, 1, 2, 3, 4
NO_EVENT = -1


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


def switch_rule(
    kind: int, x: float, y: float, vx: float, vy: float, regime: int, mu: float,
    spin: float, needed: float, limit: float,
) -> tuple[int, int, bool]:  # fmt: skip
    """The switch at a located event of ``kind`` on any system (compilable core): the
    rotor's state relative to the stator, the surface speed ``spin`` there and, for a
    stick exit or a slip reversal, the friction ``needed`` to hold v_r = 0 (the system's
    stick law) and the cone's ``limit`` mu K (z - 1).

    Returns ``(new regime, kind as recorded, project)``: contact exit -> free; contact
    entry -> the sign of v_r; stick exit -> the slip the needed friction points to;
    slip reversal -> Filippov's rule (``model.filippov_regime``), recorded as a stick
    entry when it ends in stick. ``project``: the state must be projected onto the
    rolling constraint (stick begins or ends in contact).
    """
    if kind == EXIT:
        new = model.FREE
    elif kind == ENTRY:
        new = model.entry_regime_value(x, y, vx, vy, mu, spin)
    elif kind == STICK_EXIT:
        new = model.SLIP_POSITIVE if needed > 0.0 else model.SLIP_NEGATIVE
    else:  # slip reversal
        new = model.filippov_regime(needed, limit)
    recorded = STICK_ENTRY if new == model.STICK else kind
    stick = regime == model.STICK or new == model.STICK
    return new, recorded, stick and regime != model.FREE and new != model.FREE


def switch_regime(
    kind: int, tau: float, x: float, y: float, vx: float, vy: float, regime: int,
    pars: np.ndarray | tuple[float, ...],
) -> tuple[int, int, bool]:  # fmt: skip
    """``switch_rule`` on the rotor (compilable core): the needed friction from the
    machine's stick law (``model.stick_friction_record``), evaluated only where the rule
    reads it."""
    needed = limit = 0.0
    if kind != EXIT and kind != ENTRY:
        needed = model.stick_friction_record(tau, x, y, vx, vy, pars)
        limit = pars[P_MU] * pars[P_K] * (math.hypot(x, y) - 1.0)
    spin = spin_at(tau, pars)
    return switch_rule(kind, x, y, vx, vy, regime, pars[P_MU], spin, needed, limit)


# ---------------------------------------------------------------------------------------
# The event search (``event_search``): one definition, run as Python by the Python paths
# and compiled by numba for each compiled loop's kind of segment.
# ---------------------------------------------------------------------------------------

# The event functions h (a crossing is h going from < 0 to >= 0):
# FN_SURFACE: sign (z^2 - 1), rate sign 2 (x vx + y vy);
# FN_SLIP: -sign v_r, rate -sign dv_r/dtau (with the segment's derivative);
# FN_STICK: the stick margin of side sign (``stick_margin``), rate by central differences
# of half-width d;
# FN_GIVEN: the segment's ev writes h itself into row[0] (and dh into drow[0]).
FN_SURFACE, FN_SLIP, FN_STICK, FN_GIVEN = 0, 1, 2, 3
TINY = np.finfo(float).tiny
BRENT_ITERATIONS = 100


def linspace_into(grid: np.ndarray, a: float, b: float, n: int) -> None:
    """``np.linspace(a, b, n + 1)`` into ``grid[:n + 1]``, element for element (numpy's
    ``k * step + a`` with the exact end point): the scan grids of the compiled loops are
    the Python paths' (compilable core)."""
    step = (b - a) / n
    for k in range(n):
        grid[k] = k * step + a
    grid[n] = b


def stick_margin(
    t: FloatOrArray,
    x: FloatOrArray,
    y: FloatOrArray,
    vx: FloatOrArray,
    vy: FloatOrArray,
    pars: np.ndarray,
    sign: float,
) -> FloatOrArray:
    """sign T - mu K (z - 1) (1 + STICK_EXIT_MARGIN): stick ends on side ``sign`` where
    this rises through 0 (the needed friction leaves the friction cone); scalars or
    arrays (compilable core)."""
    T = model.stick_friction_record(t, x, y, vx, vy, pars)
    limit = pars[P_MU] * pars[P_K] * (np.hypot(x, y) - 1.0)
    return sign * T - limit * (1.0 + model.STICK_EXIT_MARGIN)


def run_time(value: _T) -> _T:
    """``value`` itself. Compiled code passes a constant (an event-function kind, a flag,
    a grid size) through it to another compiled function: numba compiles a callee once
    for every distinct constant argument it is handed (and once more for each constant
    a variable holds before type inference settles on its type), and this hands it a
    run-time value instead (``jit.COMPILABLE_CORES`` registers it: compiled, it returns
    a plain int or bool). The start-up of ``rubcli run`` with numba's cache empty went
    from 93 to 40 s with ``analytic``, 24 to 14 s with ``dop853-jit`` and 55 to 43 s
    with ``taylor`` (whose kinds stay constants: ``compile_time``;
    benchmarks/compile_time.md), with the same numbers and, within 1-2 %, the same run
    times: a branch on a run-time flag costs nothing next to the segment it selects."""
    return value


def compile_time(value: _T) -> _T:
    """``value`` itself, compiled as a plain jitted function: a constant stays a constant
    (numba compiles the callee for it, and folds the branches on it). ``event_search``
    passes the event-function kinds through it instead of ``run_time`` for ``taylor``,
    whose search inlines the pointwise evaluation: there the folded branches are 5 % of
    an event-dense run (the paper's case with mu = 0.03), worth the 13 s of a first
    compile that the three specialisations of the crossing search cost."""
    return value


def event_search(
    ev: Callable[..., None],
    fill: Callable[..., None] | None = None,
    compile: Callable[[Callable[..., Any]], Callable[..., Any]] | None = None,
    compile_inline: Callable[[Callable[..., Any]], Callable[..., Any]] | None = None,
    margin: Callable[..., float] | None = None,
) -> tuple[Callable[..., tuple[float, int]], Callable[..., float]]:
    """The event search over one kind of segment: ``(locate, crossing)``.

    ``ev(t, deriv, ctx, row, drow)`` evaluates the segment: it writes the state at t into
    row[:4] and, if ``deriv``, its tau-derivative into drow[:4] (a scipy dense output, a
    DOP853 or Taylor step's polynomial, a closed-form propagator); ``ctx`` is whatever
    it needs. ``fill(ctx, fn, sign, grid, n, pars, d, row, drow, hv, hd)`` writes an
    event function and its rate on a scan grid (default: ``fill_values``, point by
    point; the Python paths fill vectorised). ``pars`` is ``model.params_vector``.

    One definition for every path: the Python paths run these functions as they are
    (``compile=None``); a compiled loop builds its own search with ``compile=jit``, and
    numba compiles the same functions with ``ev`` fixed (a closure constant, so no
    function object is passed at run time and the kernels stay cachable).
    ``compile_inline`` (default ``compile``) compiles the one function each pointwise
    evaluation goes through (``event_value``: Brent's iterations, the bracket ends, the
    look-ahead), so that it can be inlined into its callers in numba IR: a call passes
    every array argument exploded and reference-counted, which costs more than
    evaluating a Taylor polynomial (``taylor`` inlines it and its ``ev``: 9 % of the
    event-dense mu = 0.03 run; for the other loops it saves nothing measurable). With
    ``compile_inline`` the event-function kinds are compile-time constants as well
    (``compile_time``); otherwise they, and the search's flags, are run-time values
    (``run_time``), so that each function is compiled once.

    ``margin`` makes it the search of a system with states beyond the rotor's four
    (``solvers.extended``): ``ev`` writes the system's whole state into ``row`` (and its
    derivative into ``drow``), the surface speed is ``Rp`` times the state's speed
    ``row[SPEED]`` (its rate ``Rp drow[SPEED]``), and ``margin(ctx, t, pars, sign, row)``
    is the stick margin of side ``sign`` at the state in ``row`` (the system's stick
    friction). Without it, the rotor's: the speed from the record (``spin_at``), the
    margin ``stick_margin``.

    The search itself does not check for non-finite values (a NaN compares false and
    ends no scan): the Python segments raise ValueError when asked for a non-finite
    state (a diverged closed form; the analytic methods end the run cleanly on it, as
    scipy's ``brentq`` made them do before), the compiled loops fail their own finite
    check of the next state.
    """

    def stick_value(
        ctx: Any, t: float, sign: float, deriv: bool, pars: np.ndarray, d: float,
        row: np.ndarray, drow: np.ndarray,
    ) -> float:  # fmt: skip
        """The stick margin of side ``sign`` at t, or (``deriv``) its rate by central
        differences of half-width d."""
        if not deriv:
            ev(t, run_time(False), ctx, row, drow)
            return margin_at(ctx, t, pars, sign, row)
        ev(t + d, run_time(False), ctx, row, drow)
        up = margin_at(ctx, t + d, pars, sign, row)
        ev(t - d, run_time(False), ctx, row, drow)
        down = margin_at(ctx, t - d, pars, sign, row)
        return (up - down) / (2.0 * d)

    def margin_at(ctx: Any, t: float, pars: np.ndarray, sign: float, row: np.ndarray) -> float:
        """The stick margin of side ``sign`` at the state in ``row`` at t."""
        if system:
            return margin(ctx, t, pars, sign, row)
        return stick_margin(t, row[0], row[1], row[2], row[3], pars, sign)

    def slip_at(t: float, pars: np.ndarray, row: np.ndarray, drow: np.ndarray,
                deriv: bool) -> float:  # fmt: skip
        """v_r at the state in ``row`` at t, or (``deriv``) its rate from ``drow``."""
        x, y, vx, vy = row[0], row[1], row[2], row[3]
        if not deriv:
            spin = pars[P_RP] * row[SPEED] if system else spin_at(t, pars)
            return model.slip_velocity_value(x, y, vx, vy, spin)
        rate = model.slip_velocity_rate(x, y, vx, vy, drow[2], drow[3])
        if system:
            rate += pars[P_RP] * drow[SPEED]
        elif pars[P_RATE] != 0.0:
            rate += pars[P_RP] * pars[P_RATE]
        return rate

    def event_value(
        ctx: Any, t: float, fn: int, sign: float, deriv: bool, pars: np.ndarray, d: float,
        row: np.ndarray, drow: np.ndarray,
    ) -> float:  # fmt: skip
        """The event function ``fn`` (or its rate, ``deriv``) of the segment at t."""
        if fn == FN_STICK:
            return stick_value(ctx, t, sign, deriv, pars, d, row, drow)
        ev(t, deriv and fn != FN_SURFACE, ctx, row, drow)
        if fn == FN_GIVEN:
            return drow[0] if deriv else row[0]
        x, y, vx, vy = row[0], row[1], row[2], row[3]
        if fn == FN_SURFACE:
            if deriv:
                return sign * (2.0 * (x * vx + y * vy))
            return sign * (x**2 + y**2 - 1.0)
        return -sign * slip_at(t, pars, row, drow, deriv)

    def event_values(
        ctx: Any, t: float, fn: int, sign: float, pars: np.ndarray, d: float, row: np.ndarray,
        drow: np.ndarray,
    ) -> tuple[float, float]:  # fmt: skip
        """``event_value`` and its rate at t from one evaluation of the segment (three
        for the stick margin's central differences): the same numbers."""
        if fn == FN_STICK:
            value = stick_value(ctx, t, sign, run_time(False), pars, d, row, drow)
            return value, stick_value(ctx, t, sign, run_time(True), pars, d, row, drow)
        ev(t, fn != FN_SURFACE, ctx, row, drow)
        if fn == FN_GIVEN:
            return row[0], drow[0]
        x, y, vx, vy = row[0], row[1], row[2], row[3]
        if fn == FN_SURFACE:
            return sign * (x**2 + y**2 - 1.0), sign * (2.0 * (x * vx + y * vy))
        yes, no = run_time(True), run_time(False)
        return -sign * slip_at(t, pars, row, drow, no), -sign * slip_at(t, pars, row, drow, yes)

    def fill_values(
        ctx: Any, fn: int, sign: float, grid: np.ndarray, n: int, pars: np.ndarray, d: float,
        row: np.ndarray, drow: np.ndarray, hv: np.ndarray, hd: np.ndarray,
    ) -> None:  # fmt: skip
        """The event function and its rate on ``grid[:n + 1]``, point by point."""
        for i in range(n + 1):
            hv[i], hd[i] = event_values(ctx, grid[i], fn, sign, pars, d, row, drow)

    def brentq(
        ctx: Any, a: float, b: float, fa: float, fb: float, fn: int, sign: float, deriv: bool,
        pars: np.ndarray, d: float, row: np.ndarray, drow: np.ndarray,
    ) -> float:  # fmt: skip
        """Root of the event function (or of its rate) in [a, b], fa and fb of opposite
        signs: scipy's ``brentq`` (scipy/optimize/Zeros/brentq.c, Brent's method with its
        extrapolation formula) transcribed, with ``XTOL`` and ``RTOL``."""
        xpre, xcur, fpre, fcur = a, b, fa, fb
        if fpre == 0.0:
            return xpre
        if fcur == 0.0:
            return xcur
        xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
        for _ in range(BRENT_ITERATIONS):
            if fpre != 0.0 and fcur != 0.0 and ((fpre < 0.0) != (fcur < 0.0)):
                xblk, fblk = xpre, fpre
                spre = scur = xcur - xpre
            if abs(fblk) < abs(fcur):
                xpre, xcur, xblk = xcur, xblk, xcur
                fpre, fcur, fblk = fcur, fblk, fcur
            delta = (XTOL + RTOL * abs(xcur)) / 2.0
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
            fcur = event_value(ctx, xcur, fn, sign, deriv, pars, d, row, drow)
        return xcur

    def _root(ctx, a, b, fn, sign, pars, d, row, drow):
        """Root of h in [a, b] where h(b) >= 0; ``a`` itself if h(a) is not below zero there
        (the grid values that chose [a, b] and the pointwise h can differ by round-off at a
        restart point; then the crossing is at ``a``)."""
        no = run_time(False)
        fa = event_value(ctx, a, fn, sign, no, pars, d, row, drow)
        if fa >= 0.0:
            return a
        fb = event_value(ctx, b, fn, sign, no, pars, d, row, drow)
        if fb < 0.0:
            return b
        return brentq(ctx, a, b, fa, fb, fn, sign, no, pars, d, row, drow)

    def _extremum(ctx, a, b, fn, sign, pars, d, row, drow):
        """Root of dh in [a, b] if dh brackets one there (a noisy rate may not), else NaN."""
        yes = run_time(True)
        da = event_value(ctx, a, fn, sign, yes, pars, d, row, drow)
        db = event_value(ctx, b, fn, sign, yes, pars, d, row, drow)
        if da == 0.0:
            return a
        if da * db > 0.0:
            return math.nan
        return brentq(ctx, a, b, da, db, fn, sign, yes, pars, d, row, drow)

    def crossing(
        ctx: Any, fn: int, sign: float, grid: np.ndarray, hv: np.ndarray, hd: np.ndarray, n: int,
        on_surface: bool, tolerance: float, level: float, immediate: bool, pars: np.ndarray,
        d: float, row: np.ndarray, drow: np.ndarray,
    ) -> float:  # fmt: skip
        """First time in (grid[0], grid[n]] where the event function goes from < 0 to >= 0,
        or NaN; ``hv`` and ``hd`` hold it and its rate on the grid (``hv[0]`` is changed).

        The grid must be fine enough that h has at most one extremum per interval (callers
        use 1/8 of the fastest period or less). A sign change between grid points is located
        by Brent's method. An interior maximum of h between two negative values (a dip
        across the surface and back inside one interval) is found as the root of dh; it
        counts only if h there exceeds ``tolerance`` (a grazing touch below it is ignored).

        With ``on_surface`` the segment begins on this very surface (the event that started
        it): if dh >= 0 there, and still a moment later (``LOOK_AHEAD``), the crossing is at
        the start itself (a zero-duration phase; ``immediate=False`` skips this for phases
        that begin with dh = 0 by construction, such as leaving stick). The second reading
        matters at a tangential start, where dh is zero to round-off and its sign means
        nothing: at an exit located at the apex of a graze, both the free and the contact
        segment read dh >= 0 and would hand over to each other at that instant for ever (a
        switch storm); the rate a moment later says which side the orbit really goes to.

        A crossing must clear ``level`` (the noise band of h: round-off for a closed form,
        the tolerance of an adaptive solver's dense output), so noise around the surface,
        after a restart or anywhere, is not a crossing; the crossing is then located between
        the last point truly below zero and the first beyond the band.

        A segment that starts on the surface is never bracketed from its start, where h is
        zero only to round-off and could read as a zero-duration phase: if it leaves the
        surface and comes back before any grid point is truly below zero (a coarse step at
        a loose tolerance, with the return inside the band at the first grid point), the
        return is sought past the minimum of h in the first interval; if h is beyond the
        band at the first grid point and still falling there (it turned twice within that
        interval), on a finer grid of ``REFINE_POINTS`` sub-intervals.
        """
        yes, no = run_time(True), run_time(False)
        t, a, b = _crossing_scan(
            ctx, fn, sign, grid, hv, hd, n, on_surface, tolerance, level, immediate, yes,
            pars, d, row, drow,
        )  # fmt: skip
        if math.isnan(a):
            return t
        m = run_time(REFINE_POINTS)
        sub, sv, sd = np.empty(m + 1), np.empty(m + 1), np.empty(m + 1)
        linspace_into(sub, a, b, m)
        fill_values(ctx, fn, sign, sub, m, pars, d, row, drow, sv, sd)
        t, a, b = _crossing_scan(
            ctx, fn, sign, sub, sv, sd, m, yes, tolerance, level, no, no, pars, d, row, drow,
        )  # fmt: skip
        return t

    def _crossing_scan(
        ctx, fn, sign, grid, hv, hd, n, on_surface, tolerance, level, immediate, refine,
        pars, d, row, drow,
    ):  # fmt: skip
        """The scan of ``crossing``: ``(t, NaN, NaN)`` (t the crossing or NaN), or
        ``(NaN, a, b)`` when the first interval [a, b] must be refined (``refine``)."""
        if on_surface:
            if immediate and hd[0] >= 0.0:
                ahead = grid[0] + LOOK_AHEAD * (grid[1] - grid[0])
                if event_value(ctx, ahead, fn, sign, run_time(True), pars, d, row, drow) >= 0.0:
                    return grid[0], math.nan, math.nan
            hv[0] = -max(abs(hv[0]), TINY)  # strictly below: -0.0 >= 0.0
        below = 0  # the last grid point where h was truly below zero (not in the band)
        for i in range(n):
            a, b = grid[i], grid[i + 1]
            if hv[i + 1] >= level:
                if on_surface and below == 0 and hd[1] > 0.0:
                    # h left the surface downwards and came back before any grid point was
                    # truly below zero: search past its minimum in the first interval
                    tm = _extremum(ctx, grid[0], grid[1], fn, sign, pars, d, row, drow)
                    a = tm if not math.isnan(tm) and tm != 0.0 else grid[0]
                elif i == 0 and on_surface and refine:
                    return math.nan, a, b
                elif below < i:
                    a = grid[below]  # h sat in the restart band: bracket from below
                return _root(ctx, a, b, fn, sign, pars, d, row, drow), math.nan, math.nan
            if hv[i + 1] < 0.0:
                below = i + 1
            if hd[i] > 0.0 and hd[i + 1] < 0.0:
                # h can rise at most ~ rate * length above its end values within one
                # interval (factor 2 for safety): skip maxima that cannot reach the level.
                rise = 2.0 * (b - a) * max(hd[i], -hd[i + 1])
                if max(hv[i], hv[i + 1]) + rise <= max(tolerance, level):
                    continue
                tm = _extremum(ctx, a, b, fn, sign, pars, d, row, drow)
                if math.isnan(tm):
                    continue
                if event_value(ctx, tm, fn, sign, run_time(False), pars, d, row, drow) > max(
                    tolerance, level
                ):
                    return _root(ctx, a, tm, fn, sign, pars, d, row, drow), math.nan, math.nan
        return math.nan, math.nan, math.nan

    def locate(
        ctx: Any, regime: int, pars: np.ndarray, grid: np.ndarray, n: int,
        starts: tuple[bool, bool, bool], band: float, hv: np.ndarray, hd: np.ndarray,
        row: np.ndarray, drow: np.ndarray,
    ) -> tuple[float, int]:  # fmt: skip
        """Earliest event of ``regime`` in (grid[0], grid[n]]: ``(tau, kind)``, or
        ``(NaN, NO_EVENT)``; the first of equal times in the order below is kept.

        Events by regime: free -> contact entry; slip -> contact exit, slip reversal
        (v_r = 0, if mu > 0); stick -> contact exit, stick exit (|T| = mu F_N). ``starts`` =
        ``start_flags`` of the event that began the segment. ``band`` (the restart band): a
        slip reversal must clear it times 1 + Rp eta in v_r, the position-level surface
        g = z^2 - 1 times ``SURFACE_BAND``. A closed form gives v_r to round-off (1e-12); an
        adaptive solver's dense output gives it only to its tolerance, so scipy methods pass
        rtol; a solver at tolerance rtol cannot tell a contact whose penetration is below
        ~rtol from none (an orbit riding the clearance wanders across z = 1 by that much),
        so such a touch is not a contact.
        """
        d = 1e-6 * max(1.0, grid[n] - grid[0])
        surface, slip, stick = fn_value(FN_SURFACE), fn_value(FN_SLIP), fn_value(FN_STICK)
        yes, no = run_time(True), run_time(False)
        if regime == model.FREE:
            fill(ctx, surface, 1.0, grid, n, pars, d, row, drow, hv, hd)
            t = crossing(
                ctx, surface, 1.0, grid, hv, hd, n, starts[0], GRAZING_TOLERANCE,
                SURFACE_BAND * band, yes, pars, d, row, drow,
            )  # fmt: skip
            return (t, ENTRY) if not math.isnan(t) else (t, NO_EVENT)
        best, kind = math.nan, NO_EVENT
        fill(ctx, surface, -1.0, grid, n, pars, d, row, drow, hv, hd)
        t = crossing(
            ctx, surface, -1.0, grid, hv, hd, n, starts[0], 0.0, SURFACE_BAND * band, yes,
            pars, d, row, drow,
        )  # fmt: skip
        if not math.isnan(t):
            best, kind = t, EXIT
        if pars[P_MU] > 0.0 and regime != model.STICK:
            sign = float(regime)
            if system:
                ev(grid[0], no, ctx, row, drow)
                level = band * (1.0 + abs(pars[P_RP] * row[SPEED]))
            else:
                level = band * (1.0 + abs(spin_at(grid[0], pars)))
            fill(ctx, slip, sign, grid, n, pars, d, row, drow, hv, hd)
            t = crossing(
                ctx, slip, sign, grid, hv, hd, n, starts[1], 0.0, level, starts[2], pars,
                d, row, drow,
            )  # fmt: skip
            if not math.isnan(t) and (math.isnan(best) or t < best):
                best, kind = t, REVERSAL
        if regime == model.STICK:
            for sign in (1.0, -1.0):
                fill(ctx, stick, sign, grid, n, pars, d, row, drow, hv, hd)
                t = crossing(
                    ctx, stick, sign, grid, hv, hd, n, no, 0.0, STICK_EXIT_LEVEL, yes,
                    pars, d, row, drow,
                )  # fmt: skip
                if not math.isnan(t) and (math.isnan(best) or t < best):
                    best, kind = t, STICK_EXIT
        return best, kind

    system = margin is not None  # a closure constant: the compiled search folds it
    fn_value = run_time  # the event-function kinds as run-time values (see compile_time)
    if compile is not None:
        if compile_inline is not None:
            fn_value = compile(compile_time)
        margin_at = compile(margin_at)
        slip_at = compile(slip_at)
        stick_value = compile(stick_value)
        event_value = (compile_inline or compile)(event_value)
        event_values = compile(event_values)
        fill_values = compile(fill_values)
        brentq = compile(brentq)
        _root = compile(_root)
        _extremum = compile(_extremum)
        crossing = compile(crossing)
        _crossing_scan = compile(_crossing_scan)
        locate = compile(locate)
    if fill is None:
        fill = fill_values
    return locate, crossing


def earliest_event(
    states: Callable[[FloatOrArray], np.ndarray],
    derivatives: Callable[[FloatOrArray, np.ndarray], np.ndarray],
    grid: ArrayLike,
    regime: int,
    params: model.ModelParams,
    last_kind: int,
    restart_band: float = 1e-12,
) -> tuple[float, int] | None:
    """Earliest event of ``regime`` in (grid[0], grid[-1]]: (tau, kind) or None.

    The event search on a Python segment: ``states(t)`` gives its state at a scalar or
    array time (shape (4,) or (4, n)), ``derivatives(t, S)`` its time derivative; the
    scan grid is filled vectorised (``_PythonSegment.fill``). ``last_kind`` is the event
    that started the segment (``NO_EVENT`` otherwise). Raises ValueError if the search
    meets a non-finite state.
    """
    grid = np.asarray(grid, dtype=float)
    n = len(grid) - 1
    segment = _PythonSegment(states, derivatives, grid, params)
    tau, kind = _python_locate(
        segment, regime, segment.pars, grid, n, start_flags(last_kind), restart_band,
        np.empty(n + 1), np.empty(n + 1), np.empty(4), np.empty(4),
    )  # fmt: skip
    return None if kind == NO_EVENT else (float(tau), kind)


class _PythonSegment:
    """A segment given by Python callables: ``ev`` at one time, ``fill`` on the whole
    grid at once (one vectorised call of ``states`` and ``derivatives``)."""

    def __init__(self, states, derivatives, grid, params):
        self.states, self.derivatives, self.grid, self.params = states, derivatives, grid, params
        self.pars = np.array(model.params_vector(params))
        self.S = states(grid)
        self.dS = None

    def ev(self, t: float, deriv: bool, row: np.ndarray, drow: np.ndarray) -> None:
        s = self.states(t)
        row[:] = s
        if deriv:
            drow[:] = self.derivatives(t, s[:, None])[:, 0]
        if not (np.all(np.isfinite(row)) and (not deriv or np.all(np.isfinite(drow)))):
            raise ValueError(f"the segment is not finite at tau = {t!r}")

    def fill(
        self, fn: int, sign: float, grid: np.ndarray, n: int, pars: np.ndarray, d: float,
        row: np.ndarray, drow: np.ndarray, hv: np.ndarray, hd: np.ndarray,
    ) -> None:  # fmt: skip
        S = self.S
        if fn == FN_SURFACE:
            hv[:] = sign * surface_value(S)
            hd[:] = sign * surface_rate(S)
        elif fn == FN_SLIP:
            if self.dS is None:
                self.dS = self.derivatives(grid, S)
            hv[:] = -sign * slip_value(S, self.params, grid)
            hd[:] = -sign * slip_rate(S, self.dS, self.params)
        else:
            hv[:] = stick_margin(grid, *S, pars, sign)
            up, down = grid + d, grid - d
            hd[:] = (
                stick_margin(up, *self.states(up), pars, sign)
                - stick_margin(down, *self.states(down), pars, sign)
            ) / (2 * d)


class _GivenFunction:
    """``first_crossing``'s h and dh as a segment (``FN_GIVEN``)."""

    def __init__(self, h, dh):
        self.h, self.dh = h, dh

    def ev(self, t: float, deriv: bool, row: np.ndarray, drow: np.ndarray) -> None:
        row[0] = self.h(t)
        if deriv:
            drow[0] = self.dh(t)
        if not (math.isfinite(row[0]) and (not deriv or math.isfinite(drow[0]))):
            raise ValueError(f"the event function is not finite at tau = {t!r}")


def _python_ev(t, deriv, segment, row, drow):
    segment.ev(t, deriv, row, drow)


def _python_fill(segment, fn, sign, grid, n, pars, d, row, drow, hv, hd):
    segment.fill(fn, sign, grid, n, pars, d, row, drow, hv, hd)


# The event search of the Python paths (the same functions the kernels compile)
_python_locate, _python_crossing = event_search(_python_ev, _python_fill)


class _SystemSegment(_PythonSegment):
    """A segment of a system with states beyond the rotor's four (``earliest_system_event``):
    ``columns(S) -> (dS, T)`` its derivatives and its stick friction at the states in the
    columns of S."""

    def __init__(self, states, columns, grid, pars):
        self.states, self.columns, self.grid, self.pars = states, columns, grid, pars
        self.derivatives = lambda t, S: columns(S)[0]  # autonomous: the time is a state
        self.S = states(grid)
        self.dS = None

    def margin(self, S: np.ndarray, pars: np.ndarray, sign: float) -> np.ndarray:
        """The stick margin of side ``sign`` at the states in the columns of S."""
        T = self.columns(np.atleast_2d(S.T).T)[1]
        limit = pars[P_MU] * pars[P_K] * (np.hypot(S[0], S[1]) - 1.0)
        return sign * T - limit * (1.0 + model.STICK_EXIT_MARGIN)

    def fill(
        self, fn: int, sign: float, grid: np.ndarray, n: int, pars: np.ndarray, d: float,
        row: np.ndarray, drow: np.ndarray, hv: np.ndarray, hd: np.ndarray,
    ) -> None:  # fmt: skip
        S = self.S
        if fn == FN_SURFACE:  # the rotor's, on the system's first four states
            super().fill(fn, sign, grid, n, pars, d, row, drow, hv, hd)
        elif fn == FN_SLIP:
            if self.dS is None:
                self.dS = self.columns(S)[0]
            dS, Rp = self.dS, pars[P_RP]
            hv[:] = -sign * model.slip_velocity(S[0], S[1], S[2], S[3], Rp, S[SPEED])
            rate = model.slip_velocity_rate(S[0], S[1], S[2], S[3], dS[2], dS[3])
            hd[:] = -sign * (rate + Rp * dS[SPEED])
        else:
            hv[:] = self.margin(S, pars, sign)
            up, down = self.states(grid + d), self.states(grid - d)
            hd[:] = (self.margin(up, pars, sign) - self.margin(down, pars, sign)) / (2 * d)


def _python_margin(segment, t, pars, sign, row):
    return float(segment.margin(row, pars, sign)[0])


_system_locate = event_search(_python_ev, _python_fill, margin=_python_margin)[0]


def earliest_system_event(
    states: Callable[[FloatOrArray], np.ndarray],
    columns: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    grid: ArrayLike,
    regime: int,
    pars: np.ndarray,
    last_kind: int,
    restart_band: float,
) -> tuple[float, int] | None:
    """``earliest_event`` of a system with states beyond the rotor's four
    (``solvers.extended``): ``states(t)`` its whole state at a time or times, ``columns(S)
    -> (dS, T)`` its derivatives and stick friction at the states in the columns of S,
    ``pars`` the parameter record; the surface speed is ``Rp`` times the state's speed
    (``event_search`` with ``margin``)."""
    grid = np.asarray(grid, dtype=float)
    n = len(grid) - 1
    segment = _SystemSegment(states, columns, grid, pars)
    size = segment.S.shape[0]
    tau, kind = _system_locate(
        segment, regime, pars, grid, n, start_flags(last_kind), restart_band,
        np.empty(n + 1), np.empty(n + 1), np.empty(size), np.empty(size),
    )  # fmt: skip
    return None if kind == NO_EVENT else (float(tau), kind)


def initial_kind(
    s: Sequence[float] | np.ndarray, regime: int, params: model.ModelParams, tau: float = 0.0
) -> int:
    """The event surface an initial state at ``tau`` lies on, if any (so it is not
    re-detected)."""
    if abs(math.hypot(s[0], s[1]) - 1.0) <= 1e-14:
        return ENTRY if regime != model.FREE else EXIT
    if regime in (model.SLIP_POSITIVE, model.SLIP_NEGATIVE) and params.mu > 0.0:
        spin = params.spin(tau)
        v_r = model.slip_velocity(s[0], s[1], s[2], s[3], params.Rp, params.speed(tau))
        if abs(v_r) <= 1e-12 * (1.0 + abs(spin)):
            return STICK_EXIT
    return NO_EVENT


def apply_event(
    tau: float, kind: int, state: ArrayLike, regime: int, params: model.ModelParams
) -> tuple[np.ndarray, int, int, SwitchEvent]:
    """The switch at a located event (``switch_regime``), applied to a Python state.

    Returns ``(state, new_regime, recorded kind, SwitchEvent)``; the state is projected
    onto the rolling constraint when stick begins or ends in contact.
    """
    state = np.asarray(state, dtype=float)
    new_regime, recorded, project = switch_regime(
        kind, tau, state[0], state[1], state[2], state[3], regime, model.params_vector(params)
    )
    if project:
        state = model.project_to_rolling(state, params, tau)
    event = SwitchEvent(tau, KIND_NAMES[recorded], tuple(state), regime, new_regime)
    return state, new_regime, recorded, event

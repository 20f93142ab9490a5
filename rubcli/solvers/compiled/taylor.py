"""Compiled (numba) kernels of the ``taylor`` method: Taylor-series steps of the rub
equations, their event location on the Taylor polynomial, and the step loop.

The series
----------
The regime-locked right-hand side (``model.rhs_entries``) is built from products, one
square root and one division, plus the forcing ``E exp(i (eta tau + phi0))``, so its
Taylor coefficients follow from the state's by the classical recurrences (automatic
differentiation, Moore 1966; Jorba & Zou 2005, section 3). With ``a_k`` the normalised
coefficient of order k (``a(tau0 + s) = sum a_k s^k``) and ``(a b)_k = sum_j a_j b_{k-j}``:

- forcing: ``F_k = F_{k-1} i eta / k`` with ``F_0 = exp(i (eta tau0 + phi0))``;
- ``q = x^2 + y^2``; ``z = sqrt(q)``: ``z_k = (q_k - sum_{j=1}^{k-1} z_j z_{k-j}) / (2 z_0)``
  (both sums symmetric: half of each is summed);
- slip: ``P = w / z`` (w = x + i y) by the division rule, ``P_k = (w_k - sum_{j=1}^{k}
  z_j P_{k-j}) / z_0``, and ``a = E F - 2 nu v - w - K (w - P) (1 + i mu_c)``; per order
  k about 3.5 k multiply-adds (q, z and P in two passes over j);
- stick: the rolling law of ``model.rhs_entries`` term by term with ``u = 1 / z`` by the
  power rule (``k q_0 u_k = sum_{j=1}^{k} (j / 2 - k) q_j u_{k-j}``): the velocity
  projected onto ``r theta' = -Rp eta``, the needed friction ``stick_friction_value`` on
  it, the normal force ``K (z - 1) / z`` and the tangential force ``T / z``;
- ``x_{k+1} = vx_k / (k + 1)``, ``vx_{k+1} = ax_k / (k + 1)`` (and the same for y).

A step of order N costs O(N^2) operations and no right-hand-side calls: about 0.15 us
for the slip series at N = 13 (AMD EPYC, Zen 4), 0.28 us a whole step with the step
size, the pre-check and the dense output. The free and slip series are compiled with
FMA contraction (``jit_fused``: each a * b + c rounded once where the host has FMA),
every other kernel as plain IEEE arithmetic.

Reference counts. numba counts the references of every array a compiled function
takes, with atomic operations, in any function that also calls another (a leaf's
counts are pruned). They were a fifth of a run's time under ``perf``; so the step loop
calls the free and slip series (leaves, indexing C and W directly, no row views)
itself, its O(N) pre-check ``step_clear`` is inlined into it, and ``locate`` gets the
step's polynomial as one flat array (``fill_context``) and fills its scan grid in one
call (``_taylor_fill``).

Order and step (Jorba & Zou 2005, section 3.2.2; heyoka's rule)
---------------------------------------------------------------
The order is fixed for a run by the tolerance: ``N = ceil(-0.5 ln(rtol)) + 6`` (13 at
1e-6, 18 at 1e-10, 21 at 1e-13): Jorba and Zou's slope (their ``ceil(-ln(rtol) / 2) +
1`` minimises the operation count of the recurrences alone) with a larger offset, since
each step also carries the step size, the pre-check and the loop overheads. Measured at
equal final error (the cheapest setting of a half-decade tolerance ladder reaching it,
CPU time): against the former ``ceil(-0.9 ln(rtol)) + 3`` (16, 24, 30) it is 1.3x
faster on the paper's case with friction (mu = 0.03, 941 switches: a lower order is more
accurate at a given tolerance there) and the same within noise at mu = 0; offsets 5 and
7 were no better. With the state tolerance ``eps = max(atol, rtol |s_0|_inf)`` the step
is ``h = exp(-0.7 / (N - 1)) min((eps / |a_{N-1}|)^(1/(N-1)), (eps / |a_N|)^(1/N))``, so
that the last terms of the series are below eps; steps are never rejected. The step's
Taylor polynomial is its dense output (samples and events).

Events
------
Each step's event functions (``events.earliest_event``: the surface ``z^2 - 1``, the
slip ``v_r`` with friction, the stick margin) are located on the step's polynomial by
the event search of every method (``events.event_search``, compiled here with the
polynomial as its segment: the same grid logic, scipy's Brent iteration), and applied
by ``roots._apply_event`` (Filippov's rule, the projection onto rolling).
Most steps are cleared without a scan (``step_clear``, then ``step_events``):

- the surface: its Taylor series ``q - 1`` differs from ``z^2 - 1`` of the state
  polynomials (what ``locate`` evaluates) by the product terms above order N, bounded
  (``_product_tail_bound``, or more loosely in one pass). With ``|H(s) - H_0| <= sum_k
  |H_k| s^k``, a step whose bound stays below zero by the margin holds no event of it;
  failing that, the series is evaluated on 4, then 16 sub-intervals and bounded between
  them by its second derivative (``_surface_clear_quick``, ``_stays_below``);
- a step that starts on the surface (the first of a segment begun by a contact entry or
  exit) by ``H(s) = H_0 + s G(s)``: a clearly negative start rate and G below zero on
  the step keep H within round-off of zero, below the restart band the scan needs;
- the slip: first an O(N) bound of ``v_r = Rp eta + (x vy - y vx) / hypot(x, y)`` on the
  state polynomials themselves (``_slip_clear``: the spread of each polynomial bounds
  that of v_r); failing that, the series ``v_r = Rp eta + P_x vy - P_y vx``, whose terms
  beyond order N a margin of 100 state tolerances covers. A step whose slip is cleared
  this way is scanned for the surface alone (``locate`` is handed mu = 0).

Every stick step and every step that starts on the slip surface (after a slip reversal
or a stick exit) is scanned. The scan grid has ``max(4, ceil(8 h omega / 2 pi))``
intervals, omega a bound on the fastest frequency (1 + eta in free flight, sqrt(1 + K) +
1 + eta + |theta'| in contact): the extrema of an event function are half a period of it
apart, so it turns at most once per interval, as the crossing search requires.
"""

from __future__ import annotations

import math

import numpy as np

from rubcli.model import (
    N_PARAMS,
    P_DXX,
    P_DXY,
    P_DYX,
    P_DYY,
    P_E,
    P_ECC,
    P_ETA,
    P_GX,
    P_GY,
    P_K,
    P_MU,
    P_NU,
    P_PHI0,
    P_RATE,
    P_RP,
    P_SXX,
    P_SXY,
    P_SYX,
    P_SYY,
    P_TAU0,
    add_support_extra,
    is_general_record,
    rhs_entries,
    slip_velocity_rate,
    slip_velocity_value,
)
from rubcli.solvers.compiled.event_loop import (
    LOOP_APPLIES,
    PYTHON_LOCATES,
    SCAN_NONE,
    STOP_NONE,
    event_loop,
    no_restart,
)
from rubcli.solvers.compiled.jit import (
    STOP_PYTHON,
    STOP_SMALL_STEP,
    jit,
    jit_fused,
    jit_inline,
)
from rubcli.solvers.compiled.roots import FREE_REGIME, STICK_REGIME, rotor_apply, rotor_project
from rubcli.solvers.events import (
    FN_STICK,
    FN_SURFACE,
    SURFACE_BAND,
    event_search,
    linspace_into,
    spin_at,
    stick_margin,
)

MAX_ORDER = 30
MIN_ORDER = 4
ORDER_FACTOR = 0.5  # N = ceil(-0.5 ln(rtol)) + 6 (Jorba & Zou's rule: 0.5 and + 1)
ORDER_OFFSET = 6
WORK_ROWS = 34
# rows of the work space holding a speed profile's unbalance force (x, y) and exp(i p)
FORCE_X, FORCE_Y, PHASE_C, PHASE_S = 27, 28, 29, 30
# the general machine's force beyond the paper's (model.support_extra) in stick, and
# x e_y - y e_x, whose quotient by z the rolling friction takes up
EXTRA_X, EXTRA_Y, EXTRA_CROSS = 31, 32, 33
WORK_COLS = 2 * MAX_ORDER + 1  # the surface's polynomial has degree 2N
STEP_SAFETY_EXPONENT = 0.7  # h *= exp(-0.7 / (N - 1)) (heyoka)
PRECHECK_MARGIN = 1e-9  # relative margin of the series bound (plus the state tolerance)
SCAN_PER_PERIOD = 8  # scan intervals per period of the fastest frequency
MIN_SCAN = 4
PRECHECK_GRID = 16  # intervals of the pre-check's second, finer bound
MAX_SCAN = 4096
START_ROUNDOFF = 1e-13  # relative round-off of H near the start of a step on the surface
SCAN_SURFACE, SCAN_ALL = 1, 2  # step_events: what locate must scan (or SCAN_NONE)
# 1 / k for the recurrences (a constant table: no division on the series' chain)
RECIPROCALS = np.array([0.0] + [1.0 / k for k in range(1, MAX_ORDER + 2)])


def taylor_order(rtol: float) -> int:
    """The order for a tolerance: ceil(-0.5 ln(rtol)) + 6, within [MIN_ORDER, MAX_ORDER]
    (module docstring)."""
    order = math.ceil(-ORDER_FACTOR * math.log(rtol)) + ORDER_OFFSET
    return int(min(MAX_ORDER, max(MIN_ORDER, order)))


@jit
def _cauchy(a, b, k):
    """(a b)_k = sum_{j=0}^{k} a_j b_{k-j}."""
    acc = 0.0
    for j in range(k + 1):
        acc += a[j] * b[k - j]
    return acc


@jit
def _inverse_radius_terms(x, y, q, u, k):
    """Order k of q = x^2 + y^2 and u = q^(-1/2) = 1 / z (orders below k filled).

    q_k by the symmetric Cauchy sum; u by the power rule for q^alpha, alpha = -1/2:
    k q_0 u_k = sum_{j=1}^{k} (alpha j - (k - j)) q_j u_{k-j}.
    """
    acc = 0.0
    for j in range((k + 1) // 2):
        acc += x[j] * x[k - j] + y[j] * y[k - j]
    acc *= 2.0
    if k % 2 == 0:
        m = k // 2
        acc += x[m] * x[m] + y[m] * y[m]
    q[k] = acc
    if k == 0:
        u[0] = 1.0 / math.sqrt(q[0])
        return
    acc = 0.0
    for j in range(1, k + 1):
        acc += (-0.5 * j - (k - j)) * q[j] * u[k - j]
    u[k] = acc / (k * q[0])


@jit
def _forcing(eta, phi0, t0):
    """exp(i (eta t0 + phi0)): (cos, sin) of the forcing phase at the step's start."""
    phase = eta * t0 + phi0
    return math.cos(phase), math.sin(phase)


@jit
def _profile_forcing(t0, pars, order, W):
    """On a leg of a speed profile (rate = eta' != 0): the unbalance force's series
    f = fx + i fy = e (w^2 - i rate) exp(i p) (``model.unbalance_value``) into
    W[FORCE_X], W[FORCE_Y], orders 0..order-1. With w = w0 + rate s the speed and
    c = exp(i p), c' = i w c: (k + 1) c_{k+1} = i (w0 c_k + rate c_{k-1}), and
    f_k = e ((w0^2 - i rate) c_k + 2 w0 rate c_{k-1} + rate^2 c_{k-2})."""
    eta, rate, e = pars[P_ETA], pars[P_RATE], pars[P_ECC]
    d = t0 - pars[P_TAU0]
    w0 = eta + rate * d
    phase = eta * t0 + pars[P_PHI0] + 0.5 * rate * d * d
    cr, ci, fx, fy = W[PHASE_C], W[PHASE_S], W[FORCE_X], W[FORCE_Y]
    cr[0], ci[0] = math.cos(phase), math.sin(phase)
    for k in range(order - 1):
        ar, ai = w0 * cr[k], w0 * ci[k]
        if k >= 1:
            ar += rate * cr[k - 1]
            ai += rate * ci[k - 1]
        inv = RECIPROCALS[k + 1]
        cr[k + 1], ci[k + 1] = -ai * inv, ar * inv
    w2, cross, r2 = w0 * w0, 2.0 * w0 * rate, rate * rate
    for k in range(order):
        gx = w2 * cr[k] + rate * ci[k]
        gy = w2 * ci[k] - rate * cr[k]
        if k >= 1:
            gx += cross * cr[k - 1]
            gy += cross * ci[k - 1]
        if k >= 2:
            gx += r2 * cr[k - 2]
            gy += r2 * ci[k - 2]
        fx[k], fy[k] = e * gx, e * gy


@jit_inline
def taylor_coefficients(
    t0: float, s: np.ndarray, pars: np.ndarray, regime: int, order: int, C: np.ndarray,
    W: np.ndarray,
) -> None:  # fmt: skip
    """The Taylor coefficients C[:, 0..order] (rows x, y, vx, vy; columns the orders)
    of the regime-locked solution through ``s`` at ``t0``; ``W`` (WORK_ROWS,
    WORK_COLS) is work space, left holding the series of q = z^2 (row 0) up to
    ``order`` in every regime, of P = w / z (rows 4, 5) in slip (to ``order`` with
    friction, ``order - 1`` without) and of u = 1 / z (row 2) in stick, and on a leg of
    a speed profile the unbalance force's (``_profile_forcing``). Inlined into the event
    loop's step (``_step``), which runs without reference counting: called, it would
    count the references of its arrays, and of the series' it calls, on every step."""
    for i in range(4):
        C[i, 0] = s[i]
    fr, fi = _forcing(pars[P_ETA], pars[P_PHI0], t0)
    if pars[P_RATE] != 0.0:
        _profile_forcing(t0, pars, order, W)
    if regime == STICK_REGIME:
        _stick_coefficients(t0, fr, fi, pars, order, C, W)
        _inverse_radius_terms(C[0], C[1], W[0], W[2], order)
        return
    if regime == FREE_REGIME:
        _free_coefficients(fr, fi, pars, order, C, W)
    else:
        _slip_coefficients(fr, fi, pars, float(regime), order, C, W)


# Reversed copies (xr[M - j] = x_j) turn every Cauchy sum into a forward dot product,
# sum_j a_j b_{k-j} = sum_j a_j br[M - k + j], contiguous in j; the sums of one order
# (q, u and the contact force) share one pass over j.


@jit
def _extra_term(pars, k, x, y, vx, vy):
    """Order k of the series of ``model.support_extra`` from order k of the position and
    velocity: it is linear, and its constant force enters at order 0 only."""
    ex = -(pars[P_SXX] * x + pars[P_SXY] * y) - 2.0 * (pars[P_DXX] * vx + pars[P_DXY] * vy)
    ey = -(pars[P_SYX] * x + pars[P_SYY] * y) - 2.0 * (pars[P_DYX] * vx + pars[P_DYY] * vy)
    if k == 0:
        ex += pars[P_GX]
        ey += pars[P_GY]
    return ex, ey


@jit_fused
def _free_coefficients(fr, fi, pars, order, C, W):
    """``taylor_coefficients`` in free flight, with the series of q = x^2 + y^2 (W[0],
    for the pre-check)."""
    nu2, eta = 2.0 * pars[P_NU], pars[P_ETA]
    # on a leg of a speed profile the force's series is W's (_profile_forcing), read into
    # (fr, fi) with E = 1; at a constant speed E (fr, fi) is the rotating forcing
    profile = pars[P_RATE] != 0.0
    E = 1.0 if profile else pars[P_E]
    general = is_general_record(pars)
    M = MAX_ORDER
    x0, y0 = C[0, 0], C[1, 0]
    W[23, M], W[24, M] = x0, y0
    W[0, 0] = x0 * x0 + y0 * y0
    for k in range(order):
        if profile:
            fr, fi = W[FORCE_X, k], W[FORCE_Y, k]
        ax = E * fr - nu2 * C[2, k] - C[0, k]
        ay = E * fi - nu2 * C[3, k] - C[1, k]
        if general:
            ex, ey = _extra_term(pars, k, C[0, k], C[1, k], C[2, k], C[3, k])
            ax += ex
            ay += ey
        inv = RECIPROCALS[k + 1]
        rotate = eta * inv
        fr, fi = -fi * rotate, fr * rotate
        xm = C[2, k] * inv
        ym = C[3, k] * inv
        C[0, k + 1] = xm
        C[1, k + 1] = ym
        C[2, k + 1] = ax * inv
        C[3, k + 1] = ay * inv
        m = k + 1
        off = M - m
        W[23, off], W[24, off] = xm, ym
        sq = 0.0
        for j in range(1, m):
            sq += C[0, j] * W[23, off + j] + C[1, j] * W[24, off + j]
        W[0, m] = sq + 2.0 * (x0 * xm + y0 * ym)


@jit_fused
def _slip_coefficients(fr, fi, pars, sign, order, C, W):
    """``taylor_coefficients`` in slip (``sign`` the regime, +1 or -1), with the series
    of q = x^2 + y^2 (W[0]), z = sqrt(q) (W[3]) and P = w / z (W[4], W[5]).

    The contact force is K (w - P) (1 + i mu_c). Per order m: q_m and z_m by their
    symmetric sums (z^2 = q: 2 z_0 z_m = q_m - sum_{j=1}^{m-1} z_j z_{m-j}), then P_m by
    the division rule (z P = w: z_0 P_m = w_m - sum_{j=1}^{m} z_j P_{m-j}); 3.5 m
    multiply-adds an order, against 6 m for q, u = q^(-1/2) and u w. The accelerations
    need P up to order N - 1; z_N and P_N are for the slip pre-check alone, so without
    friction they are left out (the top order is the costliest: 6-7 % of the series at
    N = 13 and 18)."""
    nu2, eta, K = 2.0 * pars[P_NU], pars[P_ETA], pars[P_K]
    profile = pars[P_RATE] != 0.0  # the force's series is W's, as in _free_coefficients
    E = 1.0 if profile else pars[P_E]
    mu_c = pars[P_MU] * sign
    M = MAX_ORDER
    x0, y0 = C[0, 0], C[1, 0]
    W[23, M], W[24, M] = x0, y0
    q0 = x0 * x0 + y0 * y0
    W[0, 0] = q0
    z0 = math.sqrt(q0)
    W[3, 0] = z0
    W[25, M] = z0
    inv_z0 = 1.0 / z0
    p0x, p0y = x0 * inv_z0, y0 * inv_z0
    W[4, 0], W[5, 0] = p0x, p0y
    W[26, M], W[22, M] = p0x, p0y
    gx, gy = x0 - p0x, y0 - p0y  # w - P, order 0
    general = is_general_record(pars)
    for k in range(order):
        if profile:
            fr, fi = W[FORCE_X, k], W[FORCE_Y, k]
        ax = E * fr - nu2 * C[2, k] - C[0, k] - K * (gx - mu_c * gy)
        ay = E * fi - nu2 * C[3, k] - C[1, k] - K * (gy + mu_c * gx)
        if general:
            ex, ey = _extra_term(pars, k, C[0, k], C[1, k], C[2, k], C[3, k])
            ax += ex
            ay += ey
        inv = RECIPROCALS[k + 1]
        rotate = eta * inv
        fr, fi = -fi * rotate, fr * rotate
        xm = C[2, k] * inv
        ym = C[3, k] * inv
        C[0, k + 1] = xm
        C[1, k + 1] = ym
        C[2, k + 1] = ax * inv
        C[3, k + 1] = ay * inv
        m = k + 1
        off = M - m
        W[23, off], W[24, off] = xm, ym
        # the loops add their newest terms (those of order m - 1, computed last) last
        sq = 0.0
        sz = 0.0
        for j in range((m + 1) // 2 - 1, 0, -1):
            sq += C[0, j] * W[23, off + j] + C[1, j] * W[24, off + j]
            sz += W[3, j] * W[25, off + j]
        sq *= 2.0
        sz *= 2.0
        if m % 2 == 0:
            c = m // 2
            sq += C[0, c] * C[0, c] + C[1, c] * C[1, c]
            sz += W[3, c] * W[3, c]
        qm = sq + 2.0 * (x0 * xm + y0 * ym)
        W[0, m] = qm
        if m == order and mu_c == 0.0:
            break  # z_N and P_N: only the slip pre-check reads them (_may_have_event)
        zm = (qm - sz) * (0.5 * inv_z0)
        W[3, m] = zm
        W[25, off] = zm
        sx = 0.0
        sy = 0.0
        for j in range(2, m - 1):
            sx += W[3, j] * W[26, off + j]
            sy += W[3, j] * W[22, off + j]
        if m >= 3:  # z_{m-1} P_1
            sx += W[3, m - 1] * W[26, off + m - 1]
            sy += W[3, m - 1] * W[22, off + m - 1]
        if m >= 2:  # z_1 P_{m-1}
            sx += W[3, 1] * W[26, off + 1]
            sy += W[3, 1] * W[22, off + 1]
        pxm = (xm - sx - zm * p0x) * inv_z0
        pym = (ym - sy - zm * p0y) * inv_z0
        W[4, m], W[5, m] = pxm, pym
        W[26, off], W[22, off] = pxm, pym
        gx = xm - pxm
        gy = ym - pym


@jit
def _stick_coefficients(t0, fr, fi, pars, order, C, W):
    """``taylor_coefficients`` in stick: the rolling law of ``model.rhs_entries`` (the
    velocity projected onto r theta' = -Rp eta, the needed friction T on it, the normal
    force K (z - 1) / z and the tangential force T / z), term by term. On a leg of a
    speed profile the force is W's series (``_profile_forcing``), the surface speed
    Rp eta(t0 + s) a line, and T holds r theta' = -Rp eta with its rate (+ Rp rate,
    ``model.stick_friction_value``)."""
    nu, eta, E, K, Rp = pars[P_NU], pars[P_ETA], pars[P_E], pars[P_K], pars[P_RP]
    rate = pars[P_RATE]
    profile = rate != 0.0
    scale = 1.0 if profile else E  # the force is scale (fc, fs)
    x, y, vx, vy = C[0], C[1], C[2], C[3]
    q, u, fac, fc, fs = W[0], W[2], W[3], W[4], W[5]
    d, rad, a1, a2, vxp, vyp = W[8], W[9], W[10], W[11], W[12], W[13]
    sr1, sinrel, d2, rdot, w2, rtd, thd, T, tf = (
        W[14], W[15], W[16], W[17], W[18], W[19], W[20], W[21], W[22]
    )  # fmt: skip
    ex, ey, cross = W[EXTRA_X], W[EXTRA_Y], W[EXTRA_CROSS]
    general = is_general_record(pars)
    spin = spin_at(t0, pars)
    spin_rate = Rp * rate
    for k in range(order):
        if profile:
            fc[k], fs[k] = W[FORCE_X, k], W[FORCE_Y, k]
        else:
            fc[k], fs[k] = fr, fi
            fr, fi = -fi * eta / (k + 1), fr * eta / (k + 1)
        _inverse_radius_terms(x, y, q, u, k)
        fac[k] = K * ((1.0 if k == 0 else 0.0) - u[k])
        d[k] = _cauchy(x, vx, k) + _cauchy(y, vy, k)
        rad[k] = _cauchy(d, u, k)
        a1[k] = _cauchy(rad, x, k) + spin * y[k]
        a2[k] = _cauchy(rad, y, k) - spin * x[k]
        if profile and k >= 1:
            a1[k] += spin_rate * y[k - 1]
            a2[k] -= spin_rate * x[k - 1]
        vxp[k] = _cauchy(a1, u, k)
        vyp[k] = _cauchy(a2, u, k)
        sr1[k] = _cauchy(fs, x, k) - _cauchy(fc, y, k)
        sinrel[k] = _cauchy(sr1, u, k)
        d2[k] = _cauchy(x, vxp, k) + _cauchy(y, vyp, k)
        rdot[k] = _cauchy(d2, u, k)
        w2[k] = _cauchy(x, vyp, k) - _cauchy(y, vxp, k)
        rtd[k] = _cauchy(w2, u, k)
        thd[k] = _cauchy(rtd, u, k)
        T[k] = scale * sinrel[k] - _cauchy(rdot, thd, k) - 2.0 * nu * rtd[k]
        if k == 0:
            T[0] += spin_rate
        if general:  # the friction also holds the extra force's tangential part
            ex[k], ey[k] = _extra_term(pars, k, x[k], y[k], vxp[k], vyp[k])
            cross[k] = _cauchy(ey, x, k) - _cauchy(ex, y, k)
            T[k] += _cauchy(cross, u, k)
        tf[k] = _cauchy(T, u, k)
        ax = scale * fc[k] - 2.0 * nu * vxp[k] - x[k] - _cauchy(fac, x, k) + _cauchy(tf, y, k)
        ay = scale * fs[k] - 2.0 * nu * vyp[k] - y[k] - _cauchy(fac, y, k) - _cauchy(tf, x, k)
        if general:
            ax += ex[k]
            ay += ey[k]
        C[0, k + 1] = vxp[k] / (k + 1)
        C[1, k + 1] = vyp[k] / (k + 1)
        C[2, k + 1] = ax / (k + 1)
        C[3, k + 1] = ay / (k + 1)


@jit
def step_size(C: np.ndarray, order: int, rtol: float, atol: float) -> float:
    """Jorba & Zou's step (heyoka's safety factor): the last two terms below the state
    tolerance max(atol, rtol |s_0|_inf)."""
    scale = max(max(abs(C[0, 0]), abs(C[1, 0])), max(abs(C[2, 0]), abs(C[3, 0])))
    eps = max(atol, rtol * scale)
    # h = min_k (eps / |a_k|)^(1/k) exp(-0.7 / (N - 1)), as one exponential; the parts
    # that do not wait for the last coefficients first, 1 / k from the table: the step
    # size is on the chain from one step to the next
    log_eps = math.log(eps)
    r1, r2 = RECIPROCALS[order - 1], RECIPROCALS[order]
    safety = STEP_SAFETY_EXPONENT * r1
    base1, base2 = log_eps * r1 - safety, log_eps * r2 - safety
    exponent = math.inf
    k = order - 1
    norm = max(max(abs(C[0, k]), abs(C[1, k])), max(abs(C[2, k]), abs(C[3, k])))
    if norm > 0.0:
        exponent = base1 - math.log(norm) * r1
    norm = max(max(abs(C[0, order]), abs(C[1, order])), max(abs(C[2, order]), abs(C[3, order])))
    if norm > 0.0:
        exponent = min(exponent, base2 - math.log(norm) * r2)
    return math.exp(exponent), eps


@jit
def dense_at(t: float, t0: float, C: np.ndarray, order: int, out: np.ndarray) -> None:
    """The step's Taylor polynomial at t, into out (4,): by Estrin's scheme (pairs
    a_{k-1} + a_k dt, then Horner in dt^2), half the dependent operations of Horner's,
    since the step's end state is on the chain from one step to the next; the four rows'
    chains side by side. (``TaylorDense`` repeats these operations; the event search's
    evaluations, ``_taylor_ev`` and ``_taylor_fill``, are Horner's: they differ by
    round-off.)"""
    dt = t - t0
    d2 = dt * dt
    if order % 2 == 1:
        k = order - 1
        v0, v1 = C[0, k] + C[0, order] * dt, C[1, k] + C[1, order] * dt
        v2, v3 = C[2, k] + C[2, order] * dt, C[3, k] + C[3, order] * dt
        k -= 1
    else:
        v0, v1, v2, v3 = C[0, order], C[1, order], C[2, order], C[3, order]
        k = order - 1
    while k >= 1:
        v0 = v0 * d2 + (C[0, k - 1] + C[0, k] * dt)
        v1 = v1 * d2 + (C[1, k - 1] + C[1, k] * dt)
        v2 = v2 * d2 + (C[2, k - 1] + C[2, k] * dt)
        v3 = v3 * d2 + (C[3, k - 1] + C[3, k] * dt)
        k -= 2
    out[0], out[1], out[2], out[3] = v0, v1, v2, v3


@jit
def dense(t: np.ndarray, t0: float, C: np.ndarray, order: int) -> np.ndarray:
    """``dense_at`` at the times t (n,): states (4, n)."""
    out = np.empty((4, t.shape[0]))
    row = np.empty(4)
    for j in range(t.shape[0]):
        dense_at(t[j], t0, C, order, row)
        for i in range(4):
            out[i, j] = row[i]
    return out


@jit
def _series_bound(H, order, h):
    """sum_{k>=1} |H_k| h^k, a bound of |H(s) - H_0| on [0, h]."""
    acc = 0.0
    p = 1.0
    for k in range(1, order + 1):
        p *= h
        acc += abs(H[k]) * p
    return acc


@jit
def _poly_at(H, order, s):
    """sum_k H_k s^k (Horner)."""
    v = H[order]
    for k in range(order - 1, -1, -1):
        v = v * s + H[k]
    return v


@jit
def _stays_below(H, order, h, margin):
    """True if the polynomial H (its series) stays below -margin on [0, h]: first by
    |H(s) - H_0| <= sum_{k>=1} |H_k| h^k; failing that, on 4 and then PRECHECK_GRID
    intervals of length delta, by the chord bound max H <= max(H_a, H_b) + M2 delta^2 / 8
    with M2 = sum_k k (k - 1) |H_k| h^(k-2) a bound of |H''| on the step."""
    spread = _series_bound(H, order, h)
    if H[0] + spread + margin < 0.0:
        return True
    if H[0] >= -margin:
        return False
    m2 = 0.0
    p = 1.0
    for k in range(2, order + 1):
        m2 += k * (k - 1) * abs(H[k]) * p
        p *= h
    # first on 4 intervals, the four values by Horner chains side by side
    delta = 0.25 * h
    rise = m2 * delta * delta / 8.0
    s1, s2, s3, s4 = delta, 2.0 * delta, 3.0 * delta, h
    v1 = v2 = v3 = v4 = H[order]
    for k in range(order - 1, -1, -1):
        v1 = v1 * s1 + H[k]
        v2 = v2 * s2 + H[k]
        v3 = v3 * s3 + H[k]
        v4 = v4 * s4 + H[k]
    top = max(max(H[0], v1), max(v2, max(v3, v4)))
    if top + rise + margin < 0.0:
        return True
    delta = h / PRECHECK_GRID
    rise = m2 * delta * delta / 8.0
    left = H[0]
    for j in range(1, PRECHECK_GRID + 1):
        right = _poly_at(H, order, j * delta)
        if max(left, right) + rise + margin >= 0.0:
            return False
        left = right
    return True


@jit
def _product_tail_bound(C, order, h, W):
    """Bound on [0, h] of the terms of degree above N of x(s)^2 + y(s)^2, x and y the
    polynomials of degree N (C[0], C[1]): for each, sum_{i+j>N} A_i A_j = sum_{i=1}^{N}
    A_i R_{N-i+1}, with A_i = |a_i| h^i and R_m = sum_{j>=m} A_j (work rows W[11], W[12]
    for x, W[14], W[15] for y; both in one pass)."""
    Ax, Rx, Ay, Ry = W[11], W[12], W[14], W[15]
    p = 1.0
    for i in range(order + 1):
        Ax[i] = abs(C[0, i]) * p
        Ay[i] = abs(C[1, i]) * p
        p *= h
    Rx[order + 1] = 0.0
    Ry[order + 1] = 0.0
    for m in range(order, -1, -1):
        Rx[m] = Rx[m + 1] + Ax[m]
        Ry[m] = Ry[m + 1] + Ay[m]
    acc = 0.0
    for i in range(1, order + 1):
        acc += Ax[i] * Rx[order - i + 1] + Ay[i] * Ry[order - i + 1]
    return acc


@jit
def _surface_may_cross(C, order, h, regime, W):
    """False if the surface's series stays below zero by a margin on [0, h]."""
    # The surface's series q - 1 (W[0]), against x(s)^2 + y(s)^2 - 1 of the state
    # polynomials that locate evaluates: they differ by the product terms of degree
    # above N, bounded by _product_tail_bound; the margin adds round-off.
    if _surface_clear_quick(C, order, h, regime, W):
        return False
    q, H = W[0], W[10]
    direction = 1.0 if regime == FREE_REGIME else -1.0
    for k in range(order + 1):
        H[k] = direction * q[k]
    H[0] -= direction
    tail = _product_tail_bound(C, order, h, W)
    margin = PRECHECK_MARGIN * (1.0 + abs(H[0]) + _series_bound(H, order, h)) + tail
    return not _stays_below(H, order, h, margin)


@jit_inline
def _surface_clear_quick(C, order, h, regime, W):
    """``_surface_may_cross``'s tests in two passes: H_0 + sum_k |H_k| h^k plus the
    margin below zero, or else the chord bound on 4 intervals (``_stays_below``), with
    the product tail bounded by 2 (sum_{i>N/2} A_i) (sum_j A_j) (a pair i + j > N has
    one index above N/2), above ``_product_tail_bound``'s. True only where the full
    test clears the step too; False leaves the decision to it. (The chord bound's
    second-derivative sum is taken in a pass of its own: the first test clears some 97 %
    of the steps of a persistent contact, and with that sum in its pass the pre-check
    cost 2-3 % more of a whole run.)"""
    direction = 1.0 if regime == FREE_REGIME else -1.0
    h0 = direction * (W[0, 0] - 1.0)
    half = order // 2
    sb = 0.0
    ax = abs(C[0, 0])
    ay = abs(C[1, 0])
    p = 1.0
    for k in range(1, half + 1):
        p *= h
        a = abs(W[0, k]) * p
        sb += a
        ax += abs(C[0, k]) * p
        ay += abs(C[1, k]) * p
    hx = 0.0
    hy = 0.0
    for k in range(half + 1, order + 1):
        p *= h
        a = abs(W[0, k]) * p
        sb += a
        hx += abs(C[0, k]) * p
        hy += abs(C[1, k]) * p
    tail = 2.0 * (hx * (ax + hx) + hy * (ay + hy))
    margin = PRECHECK_MARGIN * (1.0 + abs(h0) + sb) + tail
    if h0 + sb + margin < 0.0:
        return True
    if h0 >= -margin:
        return False
    # the chord bound on 4 intervals of h / 4: rise = M2 (h / 4)^2 / 8, M2 = m2 / h^2
    m2 = 0.0  # sum_k k (k - 1) |H_k| h^k
    p = 1.0
    for k in range(1, order + 1):
        p *= h
        m2 += k * (k - 1) * (abs(W[0, k]) * p)
    rise = m2 / 128.0
    s1, s2, s3 = 0.25 * h, 0.5 * h, 0.75 * h
    v1 = v2 = v3 = v4 = W[0, order]
    for k in range(order - 1, -1, -1):
        v1 = v1 * s1 + W[0, k]
        v2 = v2 * s2 + W[0, k]
        v3 = v3 * s3 + W[0, k]
        v4 = v4 * h + W[0, k]
    top = direction * (max(max(v1, v2), max(v3, v4)) - 1.0)
    if direction < 0.0:
        top = direction * (min(min(v1, v2), min(v3, v4)) - 1.0)
    return max(h0, top) + rise + margin < 0.0


@jit
def _may_have_event(C, order, h, regime, pars, W, eps, spin):
    """False if no event function of the regime can reach zero in [t0, t0 + h]: the
    surface's series (and the slip's) stays below zero by a margin (``_stays_below``);
    ``spin`` is Rp eta at t0 (a line on a leg of a speed profile)."""
    if _surface_may_cross(C, order, h, regime, W):
        return True
    if regime == FREE_REGIME or pars[P_MU] == 0.0:
        return False
    H = W[10]
    # v_r = Rp eta + P_x vy - P_y vx, P = w / z (W[4], W[5]): its series; the margin
    # covers the terms beyond order N, by which it differs from v_r of the state
    # polynomials
    vx, vy = C[2], C[3]
    px, py = W[4], W[5]
    sign = float(regime)
    for k in range(order + 1):
        H[k] = -sign * (_cauchy(px, vy, k) - _cauchy(py, vx, k))
    H[0] -= sign * spin
    H[1] -= sign * pars[P_RP] * pars[P_RATE]
    scale = 1.0 + abs(spin) + abs(H[0])
    margin = PRECHECK_MARGIN * scale + 100.0 * eps * scale
    return not _stays_below(H, order, h, margin)


@jit
def _surface_start_may_cross(C, order, h, regime, W, level):
    """The surface pre-check of a step that starts on the surface (the contact entry
    or exit that began the segment), where H = direction (q - 1) is zero to round-off:
    ``events.first_crossing`` finds no crossing if the start rate (its ``hd[0]``) is
    clearly negative and H stays below its ``level`` (the restart band) on (0, h].
    With H(s) = H_0 + s G(s), G_k = H_{k+1}: G below -(tail / h + margin) on [0, h]
    keeps the state polynomials' H below |H_0| + round-off, the product terms of degree
    above N included (they grow at least like s^(N+1), so below s tail / h)."""
    q, H, G = W[0], W[10], W[13]
    direction = 1.0 if regime == FREE_REGIME else -1.0
    rate = direction * 2.0 * (C[0, 0] * C[2, 0] + C[1, 0] * C[3, 0])  # locate's hd[0]
    if rate >= -PRECHECK_MARGIN * (1.0 + abs(rate)):
        return True
    for k in range(order + 1):
        H[k] = direction * q[k]
    H[0] -= direction
    if abs(H[0]) + START_ROUNDOFF * (1.0 + abs(q[0]) + _series_bound(H, order, h)) > 0.5 * level:
        return True
    for k in range(order):
        G[k] = H[k + 1]
    tail = _product_tail_bound(C, order, h, W)
    margin = tail / h + PRECHECK_MARGIN * (1.0 + abs(G[0]) + _series_bound(G, order - 1, h))
    return not _stays_below(G, order - 1, h, margin)


@jit_inline
def _slip_clear(C, order, h, regime, pars, spin):
    """True if the slip velocity of the state polynomials (what ``locate`` evaluates:
    v_r = Rp eta + (x vy - y vx) / hypot(x, y), Rp eta = ``spin`` at the step's start
    and moving by |Rp eta'| h at most over it) surely keeps its sign on [0, h]: with
    D_a = sum_{k>=1} |a_k| h^k the spread of each polynomial, P = x vy - y vx moves by
    at most dP = |x_0| D_vy + |vy_0| D_x + D_x D_vy + (the same for y vx), z by at most
    dz = hypot(D_x, D_y), so P / z by at most dP / (z_0 - dz) + |P_0| dz / (z_0 (z_0 -
    dz)). O(N), against the O(N^2) series of v_r (``_may_have_event``)."""
    d0 = d1 = d2 = d3 = 0.0
    p = 1.0
    for k in range(1, order + 1):
        p *= h
        d0 += abs(C[0, k]) * p
        d1 += abs(C[1, k]) * p
        d2 += abs(C[2, k]) * p
        d3 += abs(C[3, k]) * p
    x, y, vx, vy = C[0, 0], C[1, 0], C[2, 0], C[3, 0]
    # sqrt rather than hypot (a libm call, a sixth of this test's time): within 2 ulp,
    # far inside the margin; a z that large (or not finite) is left to the full test
    z = math.sqrt(x * x + y * y)
    dz = math.sqrt(d0 * d0 + d1 * d1)
    if not (dz < 0.5 * z and z < 1e150):
        return False
    whirl = x * vy - y * vx
    dp = abs(x) * d3 + abs(vy) * d0 + d0 * d3 + abs(y) * d2 + abs(vx) * d1 + d1 * d2
    spread = dp / (z - dz) + abs(whirl) * dz / (z * (z - dz))
    spread += abs(pars[P_RP] * pars[P_RATE]) * h
    v_r = spin + whirl / z
    scale = 1.0 + abs(spin) + abs(v_r) + spread
    return float(regime) * v_r - spread > PRECHECK_MARGIN * scale


@jit_inline
def step_clear(
    C: np.ndarray,
    order: int,
    h: float,
    regime: int,
    pars: np.ndarray,
    W: np.ndarray,
    starts: tuple[bool, bool, bool],
    spin: float,
) -> bool:
    """True where ``step_events`` would return SCAN_NONE by its O(N) tests alone (a step
    that does not start on an event surface, the slip cleared by ``_slip_clear``, the
    surface by ``_surface_clear_quick``): most steps; False leaves the step to
    ``step_events``. Inlined, with both tests, into the step loop (numba IR): a call
    taking the step's arrays reference-counts each of them (atomic operations) on every
    step."""
    clear = not (regime == STICK_REGIME or starts[0] or starts[1])
    if clear and regime != FREE_REGIME and pars[P_MU] > 0.0:
        clear = _slip_clear(C, order, h, regime, pars, spin)
    if clear:
        clear = _surface_clear_quick(C, order, h, regime, W)
    return clear


@jit
def step_events(
    C: np.ndarray,
    order: int,
    h: float,
    regime: int,
    pars: np.ndarray,
    W: np.ndarray,
    eps: float,
    starts: tuple[bool, bool, bool],
    band: float,
    spin: float,
) -> int:
    """Which event functions ``locate`` must scan on a step: SCAN_NONE (none can reach
    its level: the step is clear), SCAN_SURFACE (the slip reversal surely cannot occur)
    or SCAN_ALL. Stick steps and steps that start on the slip surface are always
    scanned; a step that starts on the contact surface by ``_surface_start_may_cross``;
    every other by ``_may_have_event``, its slip part first by the O(N) ``_slip_clear``.
    ``spin`` is Rp eta at the step's start."""
    if regime == STICK_REGIME or starts[1]:
        return SCAN_ALL
    slip = regime != FREE_REGIME and pars[P_MU] > 0.0
    slip_clear = (not slip) or _slip_clear(C, order, h, regime, pars, spin)
    if starts[0]:
        surface = _surface_start_may_cross(C, order, h, regime, W, SURFACE_BAND * band)
        if slip_clear:
            return SCAN_SURFACE if surface else SCAN_NONE
        return SCAN_ALL
    if slip_clear:
        return SCAN_SURFACE if _surface_may_cross(C, order, h, regime, W) else SCAN_NONE
    return SCAN_ALL if _may_have_event(C, order, h, regime, pars, W, eps, spin) else SCAN_NONE


@jit
def scan_points(h: float, regime: int, pars: np.ndarray, s: np.ndarray, t0: float) -> int:
    """Intervals of the event scan of a step of length h from t0 (module docstring; on
    a leg of a speed profile eta is its larger end's)."""
    eta = pars[P_ETA]
    if pars[P_RATE] != 0.0:
        d = t0 - pars[P_TAU0]
        eta = max(abs(eta + pars[P_RATE] * d), abs(eta + pars[P_RATE] * (d + h)))
    return scan_intervals(h, regime, pars, s, eta)


@jit
def scan_intervals(h: float, regime: int, pars: np.ndarray, s: np.ndarray, eta: float) -> int:
    """``max(4, ceil(8 h omega / 2 pi))`` (at most MAX_SCAN), omega the fastest frequency's
    bound from the speed ``eta`` (its largest magnitude over the step) and the state s."""
    omega = 1.0 + abs(eta)
    if regime != FREE_REGIME:
        r2 = s[0] * s[0] + s[1] * s[1]
        theta_dot = abs(s[0] * s[3] - s[1] * s[2]) / r2 if r2 > 0.0 else 0.0
        omega += math.sqrt(1.0 + pars[P_K]) + theta_dot
    n = int(math.ceil(SCAN_PER_PERIOD * h * omega / (2.0 * math.pi)))
    return min(MAX_SCAN, max(MIN_SCAN, n))


# ------------------------------------------------------- events.locate on the polynomial


CTX_T0, CTX_ORDER, CTX_REGIME, CTX_PARS = 0, 1, 2, 3  # the flat segment (_taylor_ev)
CTX_COEFFICIENTS = CTX_PARS + N_PARAMS  # C[i, k] at CTX_COEFFICIENTS + 4 k + i
CTX_SIZE = CTX_COEFFICIENTS + 4 * (MAX_ORDER + 1)


@jit
def fill_context(
    ctx: np.ndarray, t0: float, C: np.ndarray, order: int, pars: np.ndarray, regime: int
) -> None:
    """The step's polynomial as ``events.locate``'s segment: one flat float64 array
    (t0, order, regime, the parameter record, C by orders), so that the search passes one
    array through its calls instead of a tuple holding two (fewer reference counts: a
    located step costs about 2/3 of the time)."""
    ctx[CTX_T0] = t0
    ctx[CTX_ORDER] = order
    ctx[CTX_REGIME] = regime
    for i in range(N_PARAMS):
        ctx[CTX_PARS + i] = pars[i]
    for k in range(order + 1):
        base = CTX_COEFFICIENTS + 4 * k
        for i in range(4):
            ctx[base + i] = C[i, k]


@jit_inline
def _taylor_ev(t, deriv, ctx, row, drow):
    """The step's polynomial (``fill_context``) as a segment of ``events.locate``: the
    state at t (Horner chains; ``dense_at``'s Estrin scheme differs by round-off) and,
    with ``deriv``, the regime's right-hand side there (as the Python path's)."""
    order = int(ctx[CTX_ORDER])
    dt = t - ctx[CTX_T0]
    base = CTX_COEFFICIENTS + 4 * order
    v0, v1, v2, v3 = ctx[base], ctx[base + 1], ctx[base + 2], ctx[base + 3]
    for _ in range(order):
        base -= 4
        v0 = v0 * dt + ctx[base]
        v1 = v1 * dt + ctx[base + 1]
        v2 = v2 * dt + ctx[base + 2]
        v3 = v3 * dt + ctx[base + 3]
    row[0], row[1], row[2], row[3] = v0, v1, v2, v3
    if deriv:
        p = CTX_PARS
        regime = int(ctx[CTX_REGIME])
        vx, vy, ax, ay = rhs_entries(
            t, v0, v1, v2, v3, ctx[p + P_NU], ctx[p + P_ETA], ctx[p + P_E], ctx[p + P_PHI0],
            ctx[p + P_K], ctx[p + P_MU], ctx[p + P_RP], regime,
            ctx[p + P_ECC], ctx[p + P_RATE], ctx[p + P_TAU0],
        )  # fmt: skip
        ax, ay = add_support_extra(v0, v1, vx, vy, ax, ay, ctx[p : p + N_PARAMS], regime)
        drow[0], drow[1], drow[2], drow[3] = vx, vy, ax, ay


@jit
def _taylor_fill(ctx, fn, sign, grid, n, pars, d, row, drow, hv, hd):
    """``event_search``'s ``fill`` on the step's polynomial: the event function and its
    rate on ``grid[:n + 1]`` by the same operations as the search's pointwise
    ``event_values`` (the same numbers), in one call: the polynomial's Horner chains
    (``_taylor_ev``'s) inline, not one call of the segment per grid point."""
    order = int(ctx[CTX_ORDER])
    t0 = ctx[CTX_T0]
    p = CTX_PARS
    regime = int(ctx[CTX_REGIME])
    for i in range(n + 1):
        t = grid[i]
        if fn == FN_STICK:
            _taylor_ev(t, False, ctx, row, drow)
            hv[i] = stick_margin(t, row[0], row[1], row[2], row[3], pars, sign)
            _taylor_ev(t + d, False, ctx, row, drow)
            up = stick_margin(t + d, row[0], row[1], row[2], row[3], pars, sign)
            _taylor_ev(t - d, False, ctx, row, drow)
            down = stick_margin(t - d, row[0], row[1], row[2], row[3], pars, sign)
            hd[i] = (up - down) / (2.0 * d)
            continue
        dt = t - t0
        base = CTX_COEFFICIENTS + 4 * order
        x, y, vx, vy = ctx[base], ctx[base + 1], ctx[base + 2], ctx[base + 3]
        for _ in range(order):
            base -= 4
            x = x * dt + ctx[base]
            y = y * dt + ctx[base + 1]
            vx = vx * dt + ctx[base + 2]
            vy = vy * dt + ctx[base + 3]
        if fn == FN_SURFACE:
            hv[i] = sign * (x**2 + y**2 - 1.0)
            hd[i] = sign * (2.0 * (x * vx + y * vy))
        else:  # FN_SLIP (FN_GIVEN is no taylor segment's)
            vxl, vyl, ax, ay = rhs_entries(
                t, x, y, vx, vy, ctx[p + P_NU], ctx[p + P_ETA], ctx[p + P_E], ctx[p + P_PHI0],
                ctx[p + P_K], ctx[p + P_MU], ctx[p + P_RP], regime, ctx[p + P_ECC],
                ctx[p + P_RATE], ctx[p + P_TAU0],
            )  # fmt: skip
            ax, ay = add_support_extra(x, y, vxl, vyl, ax, ay, pars, regime)
            hv[i] = -sign * slip_velocity_value(x, y, vx, vy, spin_at(t, pars))
            hd[i] = -sign * (slip_velocity_rate(x, y, vx, vy, ax, ay) + pars[P_RP] * pars[P_RATE])


_locate_polynomial, _ = event_search(
    _taylor_ev, _taylor_fill, compile=jit, compile_inline=jit_inline
)


@jit
def locate_in(
    ctx: np.ndarray,
    pars: np.ndarray,
    regime: int,
    grid: np.ndarray,
    n: int,
    hv: np.ndarray,
    hd: np.ndarray,
    row: np.ndarray,
    drow: np.ndarray,
    starts: tuple[bool, bool, bool],
    band: float,
) -> tuple[float, int]:
    """``events.locate`` on the step's polynomial held in ``ctx`` (``fill_context``)."""
    return _locate_polynomial(ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow)


@jit
def locate(
    t0: float,
    C: np.ndarray,
    order: int,
    pars: np.ndarray,
    regime: int,
    grid: np.ndarray,
    n: int,
    hv: np.ndarray,
    hd: np.ndarray,
    row: np.ndarray,
    drow: np.ndarray,
    starts: tuple[bool, bool, bool],
    band: float,
) -> tuple[float, int]:
    """``events.locate`` on one step's polynomial (scan grid ``grid[:n + 1]``): (tau,
    kind) of the earliest event, or (NaN, NO_EVENT)."""
    ctx = np.empty(CTX_SIZE)
    fill_context(ctx, t0, C, order, pars, regime)
    return locate_in(ctx, pars, regime, grid, n, hv, hd, row, drow, starts, band)


# ------------------------------------------------------------------------ the step loop


@jit_inline
def _step(
    tau: float, y: np.ndarray, t_end: float, pars: np.ndarray, regime: int, m: tuple,
    c: tuple, y_new: np.ndarray,
) -> tuple:  # fmt: skip
    """The event loop's step: the step's coefficients (``taylor_coefficients``) and size
    (``step_size``, cut at t_end). ``m = (C, W, grid, hv, hd, ctx, pars_surface, info,
    drow, row)``, ``c = (order, rtol, atol, eps)``."""
    C, W = m[0], m[1]
    order, rtol, atol, _ = c
    taylor_coefficients(tau, y, pars, regime, order, C, W)
    h, eps = step_size(C, order, rtol, atol)
    t_new = min(tau + h, t_end)
    h = t_new - tau
    if not (h >= 10.0 * abs(np.nextafter(tau, np.inf) - tau)):
        return t_new, STOP_SMALL_STEP if math.isfinite(h) else STOP_PYTHON, c
    dense_at(t_new, tau, C, order, y_new)
    return t_new, STOP_NONE, (order, rtol, atol, eps)


@jit_inline
def _precheck(
    tau: float, t_new: float, y: np.ndarray, y_new: np.ndarray, pars: np.ndarray,
    regime: int, m: tuple, c: tuple, starts: tuple[bool, bool, bool], band: float,
) -> int:  # fmt: skip
    """The event loop's pre-check: ``step_clear``, then ``step_events``; where a scan is
    needed, its intervals into ``info[0]`` (for ``_locate``, or for Python)."""
    C, W, info = m[0], m[1], m[7]
    order, eps = c[0], c[3]
    h = t_new - tau
    spin = spin_at(tau, pars)
    scan = SCAN_NONE
    if not step_clear(C, order, h, regime, pars, W, starts, spin):
        scan = step_events(C, order, h, regime, pars, W, eps, starts, band, spin)
    if scan != SCAN_NONE:
        info[0] = scan_points(h, regime, pars, y, tau)
    return scan


@jit_inline
def _locate(
    tau: float, t_new: float, y: np.ndarray, pars: np.ndarray, regime: int, m: tuple,
    c: tuple, scan: int, starts: tuple[bool, bool, bool], band: float,
) -> tuple[float, int]:  # fmt: skip
    """The event loop's search: ``locate_in`` on the step's polynomial, on the grid of
    ``info[0]`` intervals; where the slip reversal cannot occur (SCAN_SURFACE) it is
    handed the parameters with mu = 0 (it reads mu only to decide whether to scan the
    slip)."""
    C, grid, hv, hd, ctx, pars_surface, info, drow, row = (
        m[0], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9]
    )  # fmt: skip
    n = info[0]
    linspace_into(grid, tau, t_new, n)
    scan_pars = pars if scan == SCAN_ALL else pars_surface
    fill_context(ctx, tau, C, c[0], scan_pars, regime)
    return locate_in(ctx, scan_pars, regime, grid, n, hv, hd, row, drow, starts, band)


@jit_inline
def _state_at(
    t: float, tau: float, t_new: float, y: np.ndarray, m: tuple, c: tuple, row: np.ndarray
) -> None:
    dense_at(t, tau, m[0], c[0], row)


@jit_inline
def _commit(y: np.ndarray, y_new: np.ndarray, regime: int, m: tuple) -> None:
    for i in range(4):
        y[i] = y_new[i]


_loop = event_loop(4, _step, _precheck, _locate, _state_at, rotor_project, _commit, no_restart,
                   rotor_apply)  # fmt: skip


@jit
def advance_taylor(
    tau: float, y: np.ndarray, t_end: float, pars: np.ndarray, regime: int, order: int,
    rtol: float, atol: float, t_eval: np.ndarray, out_states: np.ndarray,
    out_regimes: np.ndarray, k: int, max_steps: int, starts: tuple[bool, bool, bool],
    C: np.ndarray, band: float, events_tau: np.ndarray, events_kind: np.ndarray,
    events_state: np.ndarray, events_regimes: np.ndarray, compiled_events: bool,
    info: np.ndarray,
) -> tuple[float, float, int, int, int, int, int, bool]:  # fmt: skip
    """Taylor steps of order ``order`` with their events, from ``(tau, y)``: the one
    event loop (``event_loop``) on the parts above.

    Like ``dop853_loop.advance_dop853``: each step's coefficients and size; the step goes
    through the event pre-check (stick steps and steps that start on the slip surface
    always scan). A clear step is committed and fills the samples it covers (projected
    in stick). Otherwise, with ``compiled_events``, ``locate`` finds the earliest event
    on the scan grid, the samples up to it are filled, the event is applied and recorded
    in ``events_*``, and a new segment starts; without, the step is returned uncommitted
    (reason EVENT) with ``C`` holding its coefficients and ``info[0]`` the scan
    intervals, for the Python event code.

    ``starts``: (on the contact surface, on the slip surface, slip start immediate) of
    the current segment, as ``events.start_flags``. Returns ``(tau, t_new, k, steps,
    reason, regime, n_events, at_event)``; reasons as ``advance_dop853``'s.
    """
    pars_surface = pars.copy()
    pars_surface[P_MU] = 0.0
    m = (
        C, np.zeros((WORK_ROWS, WORK_COLS)), np.empty(MAX_SCAN + 1), np.empty(MAX_SCAN + 1),
        np.empty(MAX_SCAN + 1), np.empty(CTX_SIZE), pars_surface, info, np.empty(4),
        np.empty(4),
    )  # fmt: skip
    tau, t_new, k, steps, reason, regime, n_events, at_event, _ = _loop(
        tau, y, np.empty(4), t_end, pars, regime, t_eval, out_states, out_regimes, k,
        max_steps, starts, band, np.empty(2), events_tau, events_kind, events_state,
        events_regimes, LOOP_APPLIES if compiled_events else PYTHON_LOCATES, np.empty(4),
        m, (order, rtol, atol, 0.0),
    )  # fmt: skip
    return tau, t_new, k, steps, reason, regime, n_events, at_event

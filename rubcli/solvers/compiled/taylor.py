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
- ``q = x^2 + y^2``; ``z = sqrt(q)``: ``z_k = (q_k - sum_{j=1}^{k-1} z_j z_{k-j}) / (2 z_0)``;
- ``u = 1 / z``: ``u_k = -(sum_{j=1}^{k} z_j u_{k-j}) / z_0``; the force factor
  ``K (1 - 1/z)`` has coefficients ``K (delta_k0 - u_k)``;
- slip: ``a = E F - 2 nu v - w - K (1 - u) (w + i mu_c w)`` (w = x + i y);
- stick: the rolling law of ``model.rhs_entries`` term by term: the velocity projected
  onto ``r theta' = -Rp eta``, the needed friction ``stick_friction_value`` on it, the
  normal force ``K (z - 1) / z`` and the tangential force ``T / z``;
- ``x_{k+1} = vx_k / (k + 1)``, ``vx_{k+1} = ax_k / (k + 1)`` (and the same for y).

A step of order N costs O(N^2) operations and no right-hand-side calls.

Order and step (Jorba & Zou 2005, section 3.2.2; heyoka's rule)
---------------------------------------------------------------
The order is fixed for a run by the tolerance: ``N = ceil(-0.9 ln(rtol)) + 3`` (16 at
1e-6, 24 at 1e-10, 30 at 1e-13). Jorba and Zou's rule ``ceil(-ln(rtol) / 2) + 1`` (8,
13, 16) minimises the operation count of the recurrences alone; measured here, higher
orders pay (fewer, longer steps; each step also carries the event pre-check, the
samples and the loop overheads of short recurrences). On the paper's case (K = 17.6,
mu = 0, 100 periods, CPU time, minimum of 5) orders 10 / 13 / 16 / 20 / 24 / 28 took
1.83 / 1.34 / 1.22 / 1.20 / 1.30 / 1.51 ms at rtol 1e-6 and 4.86 / 2.89 / 2.26 / 1.92 /
1.93 / 2.07 ms at rtol 1e-10, at about the same error (``benchmarks/peers.py`` measures
the method as registered). With the state tolerance ``eps = max(atol, rtol |s_0|_inf)``
the step is ``h = exp(-0.7 / (N - 1)) min((eps / |a_{N-1}|)^(1/(N-1)),
(eps / |a_N|)^(1/N))``, so that the last terms of the series are below eps; steps are
never rejected. The step's Taylor polynomial is its dense output (samples and events).

Events
------
Each step's event functions (``events.earliest_event``: the surface ``z^2 - 1``, the
slip ``v_r`` with friction, the stick margin) are located on the step's polynomial by
the event search of every method (``events.event_search``, compiled here with the
polynomial as its segment: the same grid logic, scipy's Brent iteration), and applied
by ``roots._apply_event`` (Filippov's rule, the projection onto rolling).
Most steps are cleared without a scan. The surface and the slip have Taylor series of
their own (``q - 1`` above; ``v_r = Rp eta + (x vy - y vx) u``). They differ from the
event functions of the state polynomials (what ``locate`` evaluates) by terms above
order N: for the surface these are bounded exactly (``_product_tail_bound``), for the
slip a margin of 100 state tolerances covers them. With ``|H(s) - H_0| <= sum_k |H_k|
s^k``, a step whose bound stays below zero by the margin holds no event of it; failing
that, the series is evaluated on 16 sub-intervals and bounded between them by its
second derivative (``_stays_below``). The first step of every segment and every stick
step are scanned. The scan grid has ``max(4, ceil(8 h omega / 2 pi))`` intervals, omega
a bound on the fastest frequency (1 + eta in free flight, sqrt(1 + K) + 1 + eta +
|theta'| in contact): the extrema of an event function are half a period of it apart,
so it turns at most once per interval, as the crossing search requires.
"""

from __future__ import annotations

import math

import numpy as np

from rubcli.model import rolling_velocity
from rubcli.solvers.compiled.jit import (
    STOP_END,
    STOP_EVENT,
    STOP_FULL,
    STOP_LIMIT,
    STOP_PYTHON,
    STOP_SMALL_STEP,
    jit,
    jit_fast,
)
from rubcli.solvers.compiled.rhs import _rhs_into
from rubcli.solvers.compiled.roots import FREE_REGIME, STICK_REGIME, _apply_event
from rubcli.solvers.events import event_search, start_flags

# ``jit_fast`` (compiled/jit.py) for the series and the pre-check bound only: they are
# computed here only, never again in Python, so the compiled and the Python event paths
# still see the same coefficients; the dense output and the event functions, which both
# paths evaluate, use plain ``jit``.
fast = jit_fast

MAX_ORDER = 30
MIN_ORDER = 4
ORDER_FACTOR = 0.9  # N = ceil(-0.9 ln(rtol)) + 3 (Jorba & Zou's rule: 0.5 and + 1)
ORDER_OFFSET = 3
WORK_ROWS = 27
WORK_COLS = 2 * MAX_ORDER + 1  # the surface's polynomial has degree 2N
STEP_SAFETY_EXPONENT = 0.7  # h *= exp(-0.7 / (N - 1)) (heyoka)
PRECHECK_MARGIN = 1e-9  # relative margin of the series bound (plus the state tolerance)
SCAN_PER_PERIOD = 8  # scan intervals per period of the fastest frequency
MIN_SCAN = 4
PRECHECK_GRID = 16  # intervals of the pre-check's second, finer bound
MAX_SCAN = 4096


def taylor_order(rtol: float) -> int:
    """The order for a tolerance: ceil(-0.9 ln(rtol)) + 3, within [MIN_ORDER, MAX_ORDER]
    (module docstring)."""
    order = math.ceil(-ORDER_FACTOR * math.log(rtol)) + ORDER_OFFSET
    return int(min(MAX_ORDER, max(MIN_ORDER, order)))


@fast
def _cauchy(a, b, k):
    """(a b)_k = sum_{j=0}^{k} a_j b_{k-j}."""
    acc = 0.0
    for j in range(k + 1):
        acc += a[j] * b[k - j]
    return acc


@fast
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


@fast
def taylor_coefficients(t0, s, pars, regime, order, C, W):
    """The Taylor coefficients C[:, 0..order] (rows x, y, vx, vy; columns the orders)
    of the regime-locked solution through ``s`` at ``t0``; ``W`` (WORK_ROWS,
    WORK_COLS) is work space, left holding the series of q = z^2 (row 0) up to
    ``order`` in every regime and of u = 1 / z (row 2) in contact."""
    nu, eta, E, phi0, K, mu = pars[0], pars[1], pars[2], pars[3], pars[4], pars[5]
    x, y, vx, vy = C[0], C[1], C[2], C[3]
    q, u = W[0], W[2]
    for i in range(4):
        C[i, 0] = s[i]
    phase = eta * t0 + phi0
    fr, fi = math.cos(phase), math.sin(phase)
    contact = regime != FREE_REGIME
    if regime == STICK_REGIME:
        _stick_coefficients(fr, fi, pars, order, C, W)
        _inverse_radius_terms(x, y, q, u, order)
        return
    mu_c = mu * float(regime) if contact else 0.0
    nu2 = 2.0 * nu
    # Reversed copies (xr[M - j] = x_j) turn every Cauchy sum into a forward dot
    # product, sum_j a_j b_{k-j} = sum_j a_j br[M - k + j], which vectorises.
    M = MAX_ORDER
    xr, yr, ur, jq = W[23], W[24], W[25], W[26]
    xr[M], yr[M] = s[0], s[1]
    for k in range(order):
        ax = E * fr - nu2 * vx[k] - x[k]
        ay = E * fi - nu2 * vy[k] - y[k]
        fr, fi = -fi * eta / (k + 1), fr * eta / (k + 1)
        if contact:
            # q = x^2 + y^2 and u = q^(-1/2) (``_inverse_radius_terms``, written out:
            # k q_0 u_k = sum_{j=1}^{k} (j / 2 - k) q_j u_{k-j})
            off = M - k
            acc = 0.0
            for j in range(k + 1):
                acc += x[j] * xr[off + j] + y[j] * yr[off + j]
            q[k] = acc
            jq[k] = k * acc
            if k == 0:
                u[0] = 1.0 / math.sqrt(acc)
            else:
                acc1 = 0.0
                acc2 = 0.0
                for j in range(1, k + 1):
                    acc1 += jq[j] * ur[off + j]
                    acc2 += q[j] * ur[off + j]
                u[k] = (0.5 * acc1 - k * acc2) / (k * q[0])
            ur[off] = u[k]
            # K (1 - u) (x - mu_c y, y + mu_c x): sum_j K (delta_j0 - u_j) (x, y)_{k-j}
            gx = 0.0
            gy = 0.0
            for j in range(k + 1):
                gx += u[j] * xr[off + j]
                gy += u[j] * yr[off + j]
            gx = x[k] - gx
            gy = y[k] - gy
            ax -= K * (gx - mu_c * gy)
            ay -= K * (gy + mu_c * gx)
        inv = 1.0 / (k + 1)
        C[0, k + 1] = vx[k] * inv
        C[1, k + 1] = vy[k] * inv
        C[2, k + 1] = ax * inv
        C[3, k + 1] = ay * inv
        xr[M - k - 1] = C[0, k + 1]
        yr[M - k - 1] = C[1, k + 1]
    if contact:
        _inverse_radius_terms(x, y, q, u, order)
    else:
        for k in range(order + 1):
            acc = 0.0
            off = M - k
            for j in range(k + 1):
                acc += x[j] * xr[off + j] + y[j] * yr[off + j]
            q[k] = acc


@fast
def _stick_coefficients(fr, fi, pars, order, C, W):
    """``taylor_coefficients`` in stick: the rolling law of ``model.rhs_entries`` (the
    velocity projected onto r theta' = -Rp eta, the needed friction T on it, the normal
    force K (z - 1) / z and the tangential force T / z), term by term."""
    nu, eta, E, K, Rp = pars[0], pars[1], pars[2], pars[4], pars[6]
    x, y, vx, vy = C[0], C[1], C[2], C[3]
    q, u, fac, fc, fs = W[0], W[2], W[3], W[4], W[5]
    d, rad, a1, a2, vxp, vyp = W[8], W[9], W[10], W[11], W[12], W[13]
    sr1, sinrel, d2, rdot, w2, rtd, thd, T, tf = (
        W[14], W[15], W[16], W[17], W[18], W[19], W[20], W[21], W[22]
    )  # fmt: skip
    spin = Rp * eta
    for k in range(order):
        fc[k], fs[k] = fr, fi
        fr, fi = -fi * eta / (k + 1), fr * eta / (k + 1)
        _inverse_radius_terms(x, y, q, u, k)
        fac[k] = K * ((1.0 if k == 0 else 0.0) - u[k])
        d[k] = _cauchy(x, vx, k) + _cauchy(y, vy, k)
        rad[k] = _cauchy(d, u, k)
        a1[k] = _cauchy(rad, x, k) + spin * y[k]
        a2[k] = _cauchy(rad, y, k) - spin * x[k]
        vxp[k] = _cauchy(a1, u, k)
        vyp[k] = _cauchy(a2, u, k)
        sr1[k] = _cauchy(fs, x, k) - _cauchy(fc, y, k)
        sinrel[k] = _cauchy(sr1, u, k)
        d2[k] = _cauchy(x, vxp, k) + _cauchy(y, vyp, k)
        rdot[k] = _cauchy(d2, u, k)
        w2[k] = _cauchy(x, vyp, k) - _cauchy(y, vxp, k)
        rtd[k] = _cauchy(w2, u, k)
        thd[k] = _cauchy(rtd, u, k)
        T[k] = E * sinrel[k] - _cauchy(rdot, thd, k) - 2.0 * nu * rtd[k]
        tf[k] = _cauchy(T, u, k)
        ax = E * fc[k] - 2.0 * nu * vxp[k] - x[k] - _cauchy(fac, x, k) + _cauchy(tf, y, k)
        ay = E * fs[k] - 2.0 * nu * vyp[k] - y[k] - _cauchy(fac, y, k) - _cauchy(tf, x, k)
        C[0, k + 1] = vxp[k] / (k + 1)
        C[1, k + 1] = vyp[k] / (k + 1)
        C[2, k + 1] = ax / (k + 1)
        C[3, k + 1] = ay / (k + 1)


@jit
def step_size(C, order, rtol, atol):
    """Jorba & Zou's step (heyoka's safety factor): the last two terms below the state
    tolerance max(atol, rtol |s_0|_inf)."""
    scale = 0.0
    for i in range(4):
        scale = max(scale, abs(C[i, 0]))
    eps = max(atol, rtol * scale)
    h = math.inf
    for k in (order - 1, order):
        norm = 0.0
        for i in range(4):
            norm = max(norm, abs(C[i, k]))
        if norm > 0.0:
            h = min(h, (eps / norm) ** (1.0 / k))
    return h * math.exp(-STEP_SAFETY_EXPONENT / (order - 1)), eps


@jit
def dense_at(t, t0, C, order, out):
    """The step's Taylor polynomial at t (Horner), into out (4,)."""
    dt = t - t0
    for i in range(4):
        v = C[i, order]
        for k in range(order - 1, -1, -1):
            v = v * dt + C[i, k]
        out[i] = v


@jit
def dense(t, t0, C, order):
    """``dense_at`` at the times t (n,): states (4, n)."""
    out = np.empty((4, t.shape[0]))
    row = np.empty(4)
    for j in range(t.shape[0]):
        dense_at(t[j], t0, C, order, row)
        for i in range(4):
            out[i, j] = row[i]
    return out


@fast
def _series_bound(H, order, h):
    """sum_{k>=1} |H_k| h^k, a bound of |H(s) - H_0| on [0, h]."""
    acc = 0.0
    p = 1.0
    for k in range(1, order + 1):
        p *= h
        acc += abs(H[k]) * p
    return acc


@fast
def _poly_at(H, order, s):
    """sum_k H_k s^k (Horner)."""
    v = H[order]
    for k in range(order - 1, -1, -1):
        v = v * s + H[k]
    return v


@fast
def _stays_below(H, order, h, margin):
    """True if the polynomial H (its series) stays below -margin on [0, h]: first by
    |H(s) - H_0| <= sum_{k>=1} |H_k| h^k; failing that, on PRECHECK_GRID intervals of
    length delta, by the chord bound max H <= max(H_a, H_b) + M2 delta^2 / 8 with M2 =
    sum_k k (k - 1) |H_k| h^(k-2) a bound of |H''| on the step."""
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
    delta = h / PRECHECK_GRID
    rise = m2 * delta * delta / 8.0
    left = H[0]
    for j in range(1, PRECHECK_GRID + 1):
        right = _poly_at(H, order, j * delta)
        if max(left, right) + rise + margin >= 0.0:
            return False
        left = right
    return True


@fast
def _product_tail_bound(a, order, h, A, R):
    """Bound on [0, h] of the terms of degree above N of a(s)^2, a the polynomial of
    degree N: sum_{i+j>N} A_i A_j = sum_{i=1}^{N} A_i R_{N-i+1}, with A_i = |a_i| h^i and
    R_m = sum_{j>=m} A_j."""
    p = 1.0
    for i in range(order + 1):
        A[i] = abs(a[i]) * p
        p *= h
    R[order + 1] = 0.0
    for m in range(order, -1, -1):
        R[m] = R[m + 1] + A[m]
    acc = 0.0
    for i in range(1, order + 1):
        acc += A[i] * R[order - i + 1]
    return acc


@fast
def _may_have_event(C, order, h, regime, pars, W, eps):
    """False if no event function of the regime can reach zero in [t0, t0 + h]: the
    surface's series (and the slip's) stays below zero by a margin (``_stays_below``)."""
    # The surface's series q - 1 (W[0]), against x(s)^2 + y(s)^2 - 1 of the state
    # polynomials that locate evaluates: they differ by the product terms of degree
    # above N, bounded by _product_tail_bound; the margin adds round-off.
    x, y, q, H = C[0], C[1], W[0], W[10]
    direction = 1.0 if regime == FREE_REGIME else -1.0
    for k in range(order + 1):
        H[k] = direction * q[k]
    H[0] -= direction
    tail = _product_tail_bound(x, order, h, W[11], W[12])
    tail += _product_tail_bound(y, order, h, W[11], W[12])
    margin = PRECHECK_MARGIN * (1.0 + abs(H[0]) + _series_bound(H, order, h)) + tail
    if not _stays_below(H, order, h, margin):
        return True
    if regime == FREE_REGIME or pars[5] == 0.0:
        return False
    # v_r = Rp eta + (x vy - y vx) u: its series (u is W[2]); the margin covers the
    # terms beyond order N, by which it differs from v_r of the state polynomials
    vx, vy = C[2], C[3]
    wv, u = W[8], W[2]
    sign = float(regime)
    for k in range(order + 1):
        wv[k] = _cauchy(x, vy, k) - _cauchy(y, vx, k)
    for k in range(order + 1):
        H[k] = -sign * _cauchy(wv, u, k)
    spin = pars[6] * pars[1]
    H[0] -= sign * spin
    scale = 1.0 + abs(spin) + abs(H[0])
    margin = PRECHECK_MARGIN * scale + 100.0 * eps * scale
    return not _stays_below(H, order, h, margin)


@jit
def scan_points(h, regime, pars, s):
    """Intervals of the event scan of a step of length h (module docstring)."""
    eta = pars[1]
    omega = 1.0 + abs(eta)
    if regime != FREE_REGIME:
        r2 = s[0] * s[0] + s[1] * s[1]
        theta_dot = abs(s[0] * s[3] - s[1] * s[2]) / r2 if r2 > 0.0 else 0.0
        omega += math.sqrt(1.0 + pars[4]) + theta_dot
    n = int(math.ceil(SCAN_PER_PERIOD * h * omega / (2.0 * math.pi)))
    return min(MAX_SCAN, max(MIN_SCAN, n))


# ------------------------------------------------------- events.locate on the polynomial


@jit
def _taylor_ev(t, deriv, ctx, row, drow):
    """The step's polynomial as a segment of ``events.locate``: the state at t and, with
    ``deriv``, the regime's right-hand side there (as the Python path's)."""
    t0, C, order, pars, regime = ctx
    dense_at(t, t0, C, order, row)
    if deriv:
        _rhs_into(t, row, pars, regime, drow)


_locate_polynomial, _ = event_search(_taylor_ev, compile=jit)


@jit
def locate(t0, C, order, pars, regime, grid, n, hv, hd, row, drow, starts, band):
    """``events.locate`` on one step's polynomial (scan grid ``grid[:n + 1]``): (tau,
    kind) of the earliest event, or (NaN, NO_EVENT)."""
    ctx = (t0, C, order, pars, regime)
    return _locate_polynomial(ctx, regime, pars, grid, n, starts, band, hv, hd, row, drow)


# ------------------------------------------------------------------------ the step loop


@jit
def advance_taylor(
    tau, y, t_end, pars, regime, order, rtol, atol, t_eval, out_states, out_regimes, k,
    max_steps, starts, C, band, events_tau, events_kind, events_state, events_regimes,
    compiled_events, info,
):  # fmt: skip
    """Taylor steps of order ``order`` with their events, from ``(tau, y)``.

    Like ``dop853_loop.advance_dop853``: each step's coefficients (``taylor_coefficients``)
    and step (``step_size``, cut at t_end); the step goes through the event pre-check
    (``_may_have_event``; the first step of a segment and stick steps always scan). A
    clear step is committed and fills the samples it covers (projected in stick).
    Otherwise, with ``compiled_events``, ``locate`` finds the earliest event on the
    scan grid, the samples up to it are filled, the event is applied
    (``roots._apply_event``), recorded in ``events_*``, and a new segment starts;
    without, the step is returned uncommitted (reason EVENT) with ``C`` holding its
    coefficients and ``info[0]`` the scan intervals, for the Python event code.

    ``starts``: (on the contact surface, on the slip surface, slip start immediate) of
    the current segment, as ``events.start_flags``. Returns ``(tau, t_new, k, steps,
    reason, regime, n_events, at_event)``; reasons as ``advance_dop853``'s.
    """
    W = np.zeros((WORK_ROWS, WORK_COLS))
    row = np.empty(4)
    drow = np.empty(4)
    y_new = np.empty(4)
    grid = np.empty(MAX_SCAN + 1)
    hv = np.empty(MAX_SCAN + 1)
    hd = np.empty(MAX_SCAN + 1)
    n_out = t_eval.shape[0]
    capacity = events_tau.shape[0]
    steps = 0
    n_events = 0
    while True:
        at_event = starts[0] or starts[1]
        if tau >= t_end:
            return tau, tau, k, steps, STOP_END, regime, n_events, at_event
        if steps >= max_steps:
            return tau, tau, k, steps, STOP_LIMIT, regime, n_events, at_event
        taylor_coefficients(tau, y, pars, regime, order, C, W)
        h, eps = step_size(C, order, rtol, atol)
        t_new = min(tau + h, t_end)
        h = t_new - tau
        if not (h >= 10.0 * abs(np.nextafter(tau, np.inf) - tau)):
            reason = STOP_SMALL_STEP if math.isfinite(h) else STOP_PYTHON
            return tau, t_new, k, steps, reason, regime, n_events, at_event
        dense_at(t_new, tau, C, order, y_new)
        finite = True
        for i in range(4):
            finite = finite and math.isfinite(y_new[i])
        if not finite:
            return tau, t_new, k, steps, STOP_PYTHON, regime, n_events, at_event
        kind = -1
        t_stop = t_new
        if at_event or regime == STICK_REGIME or _may_have_event(C, order, h, regime, pars, W, eps):
            n = scan_points(h, regime, pars, y)
            info[0] = n
            if not compiled_events:
                return tau, t_new, k, steps, STOP_EVENT, regime, n_events, at_event
            step = h / n  # np.linspace(tau, t_new, n + 1), element for element
            for j in range(n):
                grid[j] = j * step + tau
            grid[n] = t_new
            t_ev, kind = locate(
                tau, C, order, pars, regime, grid, n, hv, hd, row, drow, starts, band
            )
            if kind >= 0:
                t_stop = t_ev
        while k < n_out and t_eval[k] <= t_stop:
            dense_at(t_eval[k], tau, C, order, row)
            if regime == STICK_REGIME:
                row[2], row[3] = rolling_velocity(row[0], row[1], row[2], row[3], pars[6] * pars[1])
            for i in range(4):
                out_states[k, i] = row[i]
            out_regimes[k] = regime
            k += 1
        steps += 1
        if kind < 0:
            for i in range(4):
                y[i] = y_new[i]
            tau = t_new
            starts = (False, False, True)
            continue
        dense_at(t_stop, tau, C, order, row)
        new_regime, kind = _apply_event(kind, t_stop, row, regime, pars)
        events_tau[n_events] = t_stop
        events_kind[n_events] = kind
        events_regimes[n_events, 0] = regime
        events_regimes[n_events, 1] = new_regime
        for i in range(4):
            events_state[n_events, i] = row[i]
            y[i] = row[i]
        n_events += 1
        tau, regime = t_stop, new_regime
        starts = start_flags(kind)
        if n_events == capacity:
            return tau, tau, k, steps, STOP_FULL, regime, n_events, True

"""Compiled (numba) kernels: the event-free bulk of the analytic contact steps, and the
right-hand sides given to scipy.

What is compiled, and what is not
---------------------------------
``advance_contact`` advances *consecutive fixed-length contact steps in one slip regime*
(slip+ or slip-) from ``(tau, state)`` with the Cartesian (``analytic``) or the polar
(``analytic-polar``) linearisation, exactly as the Python propagators
``LinearisedContact`` and ``PolarLinearisedContact`` in ``analytic.py`` do, and fills the
output samples that fall in each step from the step's closed form. It hands control back
to Python *before* any step that might contain an event, so that every event is located,
and every regime change decided, by the tested Python code (``events.earliest_event``):

- on the step's scan grid (the spacing rule of ``analytic.py``: a fraction of the
  fastest period ``2 pi / omega_max``) the surface function ``-(z^2 - 1)`` or, with
  friction, the slip function ``-sign * v_r`` comes within a margin of zero, or an
  interior extremum might reach it (the rise bound of ``events.first_crossing``, with
  margins); the margins cover the round-off by which the compiled and the Python
  propagators differ, so a step the kernel takes is a step in which Python finds no
  event;
- the eigenbasis is not clearly well conditioned (the Python propagator then decides
  between its eigen-decomposition and its ``expm`` fallback), the compiled eigensolver
  does not pass its own checks, the linear system is exactly singular, or the step's
  states are not finite (Python then fails cleanly);
- the step budget it was given is used up, or ``t_end`` is reached.

``advance_contact_adaptive`` does the same for *adaptive steps* (``analytic_tol``): the
step doubling and step-size control of analytic.py's Python loop, pair of half steps by
pair, each half checked and sampled as one fixed step and counted as one step. A pair
is taken whole or handed back to Python untouched (with the step size it started
from), so Python's adaptive loop takes the pairs near events exactly as it would have.

A step that starts at an event (the segment's first) is checked as ``first_crossing``
checks it: it starts just below that surface, and a start rate that might be a
zero-duration phase goes to Python. Stick and free flight stay in Python. The physics
(contact Jacobian, linearised system, polar right-hand side and Jacobian, the
regime-locked right-hand side) is not written here: it is ``model.py``'s compilable
cores, registered with numba below, so both paths run one definition.

Caching: every kernel is compiled with ``cache=True``; the first call on a machine
compiles (seconds), later processes load the machine code from ``__pycache__``. numba
does not notice that a *called* function in another file changed, so ``ensure_fresh``
(run once per process before the first kernel call) evaluates the registered model cores
through a cached probe and recompiles every kernel if the probe disagrees with Python.
"""

from __future__ import annotations

import cmath
import math
import warnings

import numba
import numpy as np
from numba.extending import register_jitable
from scipy.integrate._ivp import dop853_coefficients as _dop

from rubcli import model
from rubcli.model import (
    cartesian_entries,
    friction_sign,
    linearised_contact_arrays,
    polar_entries,
    polar_jacobian_arrays,
    polar_rhs_entries,
    rhs_entries,
    rhs_jacobian_array,
    rolling_velocity,
    slip_velocity_rate,
    stick_friction_value,
)

# The model's compilable cores, registered so that compiled code calls the same functions.
COMPILABLE_CORES = (
    model.friction_sign,
    model.force_jacobian_entries,
    model.linearised_contact_arrays,
    model.stick_friction_value,
    model.rolling_velocity,
    model.rhs_entries,
    model.rhs_jacobian_array,
    model.slip_velocity_rate,
    model.polar_entries,
    model.cartesian_entries,
    model.polar_rhs_entries,
    model.polar_jacobian_arrays,
)
for _core in COMPILABLE_CORES:
    register_jitable(_core)

# Why advance_contact stopped.
STOP_END = 0  # reached t_end
STOP_EVENT = 1  # the next step may contain an event: Python takes it
from rubcli.solvers.events import (  # noqa: E402
    GRAZING_TOLERANCE,
    LOOK_AHEAD,
    MAX_SCAN_POINTS,
    REFINE_POINTS,
    RTOL,
    STICK_EXIT_LEVEL,
    SURFACE_BAND,
    XTOL,
)

STOP_PYTHON = 2  # the next step needs Python (conditioning, singular system, non-finite)
STOP_LIMIT = 3  # the step limit it was given is reached
STOP_REASONS = {
    STOP_END: "end",
    STOP_EVENT: "event",
    STOP_PYTHON: "python",
    STOP_LIMIT: "limit",
    4: "small step",
    5: "event buffer full",
}

EPS = np.finfo(float).eps
EVENT_MARGIN = 1e-9  # relative margin of the event pre-check (plus eps * cond(V) terms)
EIG_RESIDUAL_TOL = 1e3 * EPS  # backward error accepted from the hand-written eigensolver
WARM_NEWTON_ITERATIONS = 6  # Newton steps allowed per eigenvalue from the previous step's

jit = numba.njit(cache=True)
jit_inline = numba.njit(cache=True, inline="always")  # inlined in numba IR


# --------------------------------------------------------------- small linear algebra


@jit
def _abs1(z):
    return abs(z.real) + abs(z.imag)


@jit
def _lu_factor(M, piv):
    """In-place LU with partial pivoting (as LAPACK getrf; pivots by |re| + |im|).

    The unit lower factor is stored below the diagonal, U above it, and the diagonal
    holds the *reciprocals* of U's pivots (so that ``_lu_solve`` multiplies). Returns
    False when a pivot is exactly zero (LAPACK's "singular" condition).
    """
    n = M.shape[0]
    for j in range(n):
        p = j
        best = _abs1(M[j, j])
        for i in range(j + 1, n):
            a = _abs1(M[i, j])
            if a > best:
                best = a
                p = i
        piv[j] = p
        if best == 0.0:
            return False
        if p != j:
            for c in range(n):
                tmp = M[j, c]
                M[j, c] = M[p, c]
                M[p, c] = tmp
        inv = 1.0 / M[j, j]
        M[j, j] = inv
        for i in range(j + 1, n):
            M[i, j] *= inv
        for i in range(j + 1, n):
            f = M[i, j]
            for c in range(j + 1, n):
                M[i, c] -= f * M[j, c]
    return True


@jit
def _lu_solve(LU, piv, b):
    """Solve in place with the factors of ``_lu_factor``."""
    n = LU.shape[0]
    for j in range(n):
        p = piv[j]
        if p != j:
            tmp = b[j]
            b[j] = b[p]
            b[p] = tmp
    for i in range(n):
        acc = b[i]
        for c in range(i):
            acc -= LU[i, c] * b[c]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for c in range(i + 1, n):
            acc -= LU[i, c] * b[c]
        b[i] = acc * LU[i, i]


@jit
def _givens(x, y):
    """(c, s): c real, s complex, with [[c, s], [-conj(s), c]] @ [x, y] = [r, 0]."""
    ay2 = y.real * y.real + y.imag * y.imag
    if ay2 == 0.0:
        return 1.0, 0j
    ax2 = x.real * x.real + x.imag * x.imag
    if ax2 == 0.0:
        return 0.0, 1.0 + 0j
    ax = math.sqrt(ax2)
    norm = math.sqrt(ax2 + ay2)
    inv = 1.0 / (ax * norm)
    return ax / norm, complex(
        (x.real * y.real + x.imag * y.imag) * inv, (x.imag * y.real - x.real * y.imag) * inv
    )


@jit
def _rotate(H, Z, k, c, s, col_start, row_stop):
    """H <- G H G^H on rows/columns k, k+1 (G = [[c, s], [-conj(s), c]]); Z <- Z G^H."""
    n = H.shape[0]
    sr = s.real
    si = s.imag
    for j in range(col_start, n):
        a = H[k, j]
        b = H[k + 1, j]
        H[k, j] = complex(
            c * a.real + sr * b.real - si * b.imag, c * a.imag + sr * b.imag + si * b.real
        )
        H[k + 1, j] = complex(
            c * b.real - sr * a.real - si * a.imag, c * b.imag - sr * a.imag + si * a.real
        )
    for i in range(row_stop):
        a = H[i, k]
        b = H[i, k + 1]
        H[i, k] = complex(
            c * a.real + sr * b.real + si * b.imag, c * a.imag + sr * b.imag - si * b.real
        )
        H[i, k + 1] = complex(
            c * b.real - sr * a.real + si * a.imag, c * b.imag - sr * a.imag - si * a.real
        )
    for i in range(n):
        a = Z[i, k]
        b = Z[i, k + 1]
        Z[i, k] = complex(
            c * a.real + sr * b.real + si * b.imag, c * a.imag + sr * b.imag - si * b.real
        )
        Z[i, k + 1] = complex(
            c * b.real - sr * a.real + si * a.imag, c * b.imag - sr * a.imag - si * a.real
        )


@jit
def _rotate_real(B, Q, k, c, s, col_start):
    """Real Givens similarity on rows/columns k, k+1: B <- G B G^T, Q <- Q G^T."""
    n = B.shape[0]
    for j in range(col_start, n):
        a = B[k, j]
        b = B[k + 1, j]
        B[k, j] = c * a + s * b
        B[k + 1, j] = c * b - s * a
    for i in range(n):
        a = B[i, k]
        b = B[i, k + 1]
        B[i, k] = c * a + s * b
        B[i, k + 1] = c * b - s * a
    for i in range(n):
        a = Q[i, k]
        b = Q[i, k + 1]
        Q[i, k] = c * a + s * b
        Q[i, k + 1] = c * b - s * a


@jit
def _balance(B, scale):
    """Balance B in place by powers of 2 (LAPACK gebal's scaling, no permutations).

    On return B holds D^-1 B D with D = diag(scale).
    """
    n = B.shape[0]
    for i in range(n):
        scale[i] = 1.0
    converged = False
    while not converged:
        converged = True
        for i in range(n):
            c = 0.0
            r = 0.0
            for j in range(n):
                if j != i:
                    c += B[j, i] * B[j, i]
                    r += B[i, j] * B[i, j]
            if c == 0.0 or r == 0.0:
                continue
            c = math.sqrt(c)
            r = math.sqrt(r)
            g = r / 2.0
            f = 1.0
            s = c + r
            while c < g:
                f *= 2.0
                c *= 2.0
                r /= 2.0
                g /= 2.0
            g = c / 2.0
            while g >= r:
                f /= 2.0
                c /= 2.0
                g /= 2.0
                r *= 2.0
            if c + r >= 0.95 * s:
                continue
            scale[i] *= f
            converged = False
            inv = 1.0 / f
            for j in range(n):
                B[i, j] *= inv
                B[j, i] *= f


@jit
def _eig_small(M, lam, V, B, Q, H, Z, scale, x):
    """Eigenvalues and unit eigenvectors of a small real matrix; False if it failed.

    Balancing by powers of 2 (LAPACK gebal's scaling), Hessenberg form by real Givens
    rotations, complex single-shift QR with Wilkinson shifts (exceptional shifts every
    10 iterations) to the Schur form, eigenvectors by back substitution (with ztrevc's
    perturbation of tiny divisors) and back-transformation. About 1.5 us for 4x4,
    against about 9 us for LAPACK's zgeev through numba. ``scale`` returns the balancing.
    """
    n = M.shape[0]
    for i in range(n):
        for j in range(n):
            B[i, j] = M[i, j]
            Q[i, j] = 1.0 if i == j else 0.0
    _balance(B, scale)
    # Hessenberg by real Givens rotations
    for j in range(n - 2):
        for i in range(n - 1, j + 1, -1):
            b = B[i, j]
            if b != 0.0:
                a = B[i - 1, j]
                norm = math.hypot(a, b)
                _rotate_real(B, Q, i - 1, a / norm, b / norm, j)
                B[i, j] = 0.0
    hnorm = 0.0
    for i in range(n):
        for j in range(n):
            H[i, j] = B[i, j]
            Z[i, j] = Q[i, j]
            hnorm = max(hnorm, abs(B[i, j]))
    # complex single-shift QR (Wilkinson shifts, exceptional shifts every 10 iterations)
    hi = n - 1
    its = 0
    total = 0
    while hi > 0:
        lo = hi
        while lo > 0:
            tst = _abs1(H[lo - 1, lo - 1]) + _abs1(H[lo, lo])
            if tst == 0.0:
                tst = hnorm
            if _abs1(H[lo, lo - 1]) <= EPS * tst:
                H[lo, lo - 1] = 0.0
                break
            lo -= 1
        if lo == hi:
            hi -= 1
            its = 0
            continue
        its += 1
        total += 1
        if total > 30 * n:
            return False
        a = H[hi - 1, hi - 1]
        b = H[hi - 1, hi]
        cc = H[hi, hi - 1]
        d = H[hi, hi]
        if its % 10 == 0:
            mu = d + 0.75 * _abs1(cc)
        else:
            p = 0.5 * (a - d)
            disc = np.sqrt(p * p + b * cc)
            den = p + disc
            den2 = p - disc
            if _abs1(den2) > _abs1(den):
                den = den2
            mu = d if den == 0 else d - b * cc / den
        xx = H[lo, lo] - mu
        yy = H[lo + 1, lo]
        for k in range(lo, hi):
            if k > lo:
                xx = H[k, k - 1]
                yy = H[k + 1, k - 1]
            c, s = _givens(xx, yy)
            _rotate(H, Z, k, c, s, max(lo, k - 1), min(k + 2, hi) + 1)
            if k > lo:
                H[k + 1, k - 1] = 0.0
    for k in range(n):
        lam[k] = H[k, k]
    # eigenvectors of the triangular factor, back-transformed and unit-normalised
    for k in range(n):
        smin = max(EPS * _abs1(H[k, k]), 1e-290)
        x[k] = 1.0
        for i in range(k - 1, -1, -1):
            acc = 0j
            for j in range(i + 1, k + 1):
                acc += H[i, j] * x[j]
            den = H[i, i] - H[k, k]
            if _abs1(den) < smin:
                den = smin
            x[i] = -acc / den
        norm = 0.0
        for i in range(n):
            acc = 0j
            for j in range(k + 1):
                acc += Z[i, j] * x[j]
            acc *= scale[i]
            V[i, k] = acc
            norm += acc.real * acc.real + acc.imag * acc.imag
        if not (norm > 0.0 and norm < np.inf):
            return False
        inv_norm = 1.0 / math.sqrt(norm)
        for i in range(n):
            V[i, k] *= inv_norm
    return True


@jit
def _second_order_blocks(M):
    """True if M = [[0, I], [P, C]] exactly (both linearised systems have this form)."""
    return (
        M[0, 0] == 0.0
        and M[0, 1] == 0.0
        and M[1, 0] == 0.0
        and M[1, 1] == 0.0
        and M[0, 2] == 1.0
        and M[0, 3] == 0.0
        and M[1, 2] == 0.0
        and M[1, 3] == 1.0
    )


@jit
def _eig_warm(M, lam, V, Vinv, lam0, B, scale):
    """Eigenpairs of M = [[0, I], [P, C]] refined from nearby eigenvalues ``lam0``.

    In a run of steps the system matrix moves little from one step to the next, so the
    previous step's eigenvalues start Newton's method on the characteristic quartic
    det(l^2 I - l C - P) = 0 (evaluated in factored form); the eigenvectors are [w; l w]
    with w spanning the null space of the 2x2 matrix N = l^2 I - l C - P, and the rows
    of V^-1 are the left eigenvectors [(l I - C^T) y; y], y^T N = 0, each divided by its
    product with the right one (distinct eigenvalues). Returns False
    (the caller then uses ``_eig_small``) if an iteration does not converge, two
    eigenvalues come out (nearly) equal, or a null space is not clear-cut. ``B`` and
    ``scale`` return the balancing for the residual check. About 0.4 us for 4x4.
    """
    if not _second_order_blocks(M):
        return False
    p00, p01, p10, p11 = M[2, 0], M[2, 1], M[3, 0], M[3, 1]
    c00, c01, c10, c11 = M[2, 2], M[2, 3], M[3, 2], M[3, 3]
    radius = 0.0
    for k in range(4):
        radius = max(radius, _abs1(lam0[k]))
    for k in range(4):
        x = lam0[k]
        converged = False
        for _ in range(WARM_NEWTON_ITERATIONS):
            a = x * x - c00 * x - p00
            d = x * x - c11 * x - p11
            b = c01 * x + p01
            c = c10 * x + p10
            df = (2.0 * x - c00) * d + a * (2.0 * x - c11) - c01 * c - b * c10
            if df == 0.0:
                return False
            step = (a * d - b * c) / df
            x = x - step
            if _abs1(step) <= 8.0 * EPS * max(_abs1(x), 1e-3 * radius):
                converged = True
                break
        if not converged:
            return False
        lam[k] = x
    for i in range(4):
        for j in range(i + 1, 4):
            gap = _abs1(lam[i] - lam[j])
            if gap <= 1e-8 * max(_abs1(lam[i]), _abs1(lam[j]), 1e-3 * radius):
                return False
    size = abs(c00) + abs(c01) + abs(c10) + abs(c11)
    rest = abs(p00) + abs(p01) + abs(p10) + abs(p11)
    for k in range(4):
        x = lam[k]
        n00 = x * x - c00 * x - p00
        n01 = -(c01 * x) - p01
        n10 = -(c10 * x) - p10
        n11 = x * x - c11 * x - p11
        r0 = _abs1(n00) + _abs1(n01)
        r1 = _abs1(n10) + _abs1(n11)
        if r0 >= r1:
            w0, w1, row = -n01, n00, r0
        else:
            w0, w1, row = -n11, n10, r1
        c0 = _abs1(n00) + _abs1(n10)
        c1 = _abs1(n01) + _abs1(n11)
        if c0 >= c1:
            y0, y1, col = -n10, n00, c0
        else:
            y0, y1, col = -n11, n01, c1
        if not min(row, col) > 1e-8 * (_abs1(x * x) + _abs1(x) * size + rest):
            return False
        u0 = x * y0 - (c00 * y0 + c10 * y1)
        u1 = x * y1 - (c01 * y0 + c11 * y1)
        v2 = x * w0
        v3 = x * w1
        norm2 = (
            w0.real * w0.real
            + w0.imag * w0.imag
            + w1.real * w1.real
            + w1.imag * w1.imag
            + v2.real * v2.real
            + v2.imag * v2.imag
            + v3.real * v3.real
            + v3.imag * v3.imag
        )
        inv = 1.0 / math.sqrt(norm2)
        V[0, k] = w0 * inv
        V[1, k] = w1 * inv
        V[2, k] = v2 * inv
        V[3, k] = v3 * inv
        dot = u0 * V[0, k] + u1 * V[1, k] + y0 * V[2, k] + y1 * V[3, k]
        if dot == 0.0:
            return False
        inv_dot = 1.0 / dot
        Vinv[k, 0] = u0 * inv_dot
        Vinv[k, 1] = u1 * inv_dot
        Vinv[k, 2] = y0 * inv_dot
        Vinv[k, 3] = y1 * inv_dot
    for i in range(4):
        for j in range(4):
            B[i, j] = M[i, j]
    _balance(B, scale)
    return True


@jit
def _residual_ok(M, lam, V, scale):
    """|(M v - lam v)_i| / scale_i <= tol ||D^-1 M D||_1 max_i |v_i / scale_i| per eigenpair."""
    n = M.shape[0]
    bnorm = 0.0
    for j in range(n):
        col = 0.0
        for i in range(n):
            col += abs(M[i, j]) * scale[j] / scale[i]
        bnorm = max(bnorm, col)
    for k in range(n):
        vmax = 0.0
        rmax = 0.0
        for i in range(n):
            acc = -lam[k] * V[i, k]
            for j in range(n):
                acc += M[i, j] * V[j, k]
            rmax = max(rmax, _abs1(acc) / scale[i])
            vmax = max(vmax, _abs1(V[i, k]) / scale[i])
        if not rmax <= EIG_RESIDUAL_TOL * bnorm * vmax:
            return False
    return True


@jit
def _norm1(M):
    """The 1-norm with |re| + |im| for the modulus: between ||M||_1 and sqrt(2) ||M||_1."""
    best = 0.0
    for j in range(M.shape[1]):
        s = 0.0
        for i in range(M.shape[0]):
            s += _abs1(M[i, j])
        best = max(best, s)
    return best


@jit
def _phi12(z):
    """phi1(z) = (e^z - 1)/z, phi2(z) = (e^z - 1 - z)/z^2, series near 0 (as analytic._phi12)."""
    if z.real * z.real + z.imag * z.imag < 1e-6:  # |z| < 1e-3
        z2 = z * z
        z3 = z2 * z
        return 1 + z / 2 + z2 / 6 + z3 / 24, 0.5 + z / 6 + z2 / 24 + z3 / 120
    inv = 1.0 / z
    em1 = cmath.exp(z) - 1
    return em1 * inv, (em1 - z) * inv * inv


# --------------------------------------------------------------- the two propagators
#
# A step's data live in the preallocated arrays of ``_workspace``: "prepare" fills them at
# (tau0, s0) as the Python propagator's __init__ does, "evaluate" writes the Cartesian
# state and its time derivative at tau0 + dt as its ``states`` and ``derivatives`` do.


@jit
def _workspace():
    """(lam, V, LU, coef, piv, real, M, B, Q, H, Z, scale, x, P, dP, Vinv): a step's arrays."""
    return (
        np.empty(4, dtype=np.complex128),  # lam: eigenvalues
        np.empty((4, 4), dtype=np.complex128),  # V: unit eigenvectors
        np.empty((4, 4), dtype=np.complex128),  # LU: LU factors
        np.empty((2, 4), dtype=np.complex128),  # coef: eigen-coefficients
        np.empty(4, dtype=np.int64),  # piv: LU pivots
        np.empty(12),  # real: p0, f0, f_tau (polar); s_c, b (Cartesian)
        np.empty((4, 4)),  # M: the system matrix J (polar) or A (Cartesian)
        np.empty((4, 4)),  # B: eigensolver work (balanced matrix)
        np.empty((4, 4)),  # Q: eigensolver work
        np.empty((4, 4), dtype=np.complex128),  # H: eigensolver work (Schur form)
        np.empty((4, 4), dtype=np.complex128),  # Z: eigensolver work (Schur vectors)
        np.empty(4),  # scale: balancing
        np.empty(4, dtype=np.complex128),  # x: complex vector work
        np.empty(4),  # P: polar state work
        np.empty(4),  # dP: its derivative
        np.empty((4, 4), dtype=np.complex128),  # Vinv: the inverse of V
    )


@jit
def _eigenbasis(ws, warm):
    """Eigen-decomposition of ``M`` into ``lam``, ``V`` and ``Vinv``; returns cond(V).

    The condition number is ``||V||_1 ||V^-1||_1`` measured with ``_norm1``, so between
    cond1(V) and 2 cond1(V), and cond2(V) <= 4 cond1(V) (inf when V is exactly singular
    or M is not finite). With ``warm`` (``lam`` holds the previous step's eigenvalues)
    ``_eig_warm`` is tried first, else (or if it fails) the QR-based ``_eig_small``;
    either is accepted only if its residual in the balanced coordinates is small; if
    neither is, cond = inf hands the step to the Python propagator (LAPACK's eig, or
    its expm fallback). ``Vinv`` comes from the left eigenvectors (warm) or from the LU
    factors of V.
    """
    lam, V, LU, _, piv, _, M, B, Q, H, Z, scale, x, _, _, Vinv = ws
    for i in range(4):
        for j in range(4):
            if not math.isfinite(M[i, j]):
                return np.inf
    if warm:
        for i in range(4):
            x[i] = lam[i]
        warm = _eig_warm(M, lam, V, Vinv, x, B, scale) and _residual_ok(M, lam, V, scale)
    if not warm and not (
        _eig_small(M, lam, V, B, Q, H, Z, scale, x) and _residual_ok(M, lam, V, scale)
    ):
        return np.inf  # the step goes to Python (LAPACK's eig, or its expm fallback)
    if not warm:
        LU[:, :] = V
        if not _lu_factor(LU, piv):
            return np.inf
        for j in range(4):
            for i in range(4):
                x[i] = 0.0
            x[j] = 1.0
            _lu_solve(LU, piv, x)
            for i in range(4):
                Vinv[i, j] = x[i]
    return _norm1(V) * _norm1(Vinv)


@jit
def _omega_max(lam, eta):
    """max(|Im lam|, eta, 1): the fastest angular frequency of the step (scan spacing)."""
    m = 0.0
    for i in range(lam.shape[0]):
        m = max(m, abs(lam[i].imag))
    return max(m, eta, 1.0)


@jit
def _prepare_polar(tau0, s0, pars, mu_c, ws, warm):
    """PolarLinearisedContact.__init__ at (tau0, s0): returns (cond1(V), omega_max).

    ``real`` holds p0 (0:4), f0 (4:8), f_tau (8:12); ``M`` is J; ``coef`` the
    eigen-coefficients of f0 and f_tau.
    """
    lam, _, _, coef, _, real, M, _, _, _, _, _, _, _, _, Vinv = ws
    nu, eta, E, phi0, K = pars[0], pars[1], pars[2], pars[3], pars[4]
    r, theta, u, omega = polar_entries(s0[0], s0[1], s0[2], s0[3])
    f0 = polar_rhs_entries(tau0, r, theta, u, omega, nu, eta, E, phi0, K, mu_c)
    J, f_tau = polar_jacobian_arrays(tau0, r, theta, u, omega, nu, eta, E, phi0, K, mu_c)
    M[:, :] = J
    real[0] = r
    real[1] = theta
    real[2] = u
    real[3] = omega
    for i in range(4):
        real[4 + i] = f0[i]
        real[8 + i] = f_tau[i]
    cond = _eigenbasis(ws, warm)
    if not cond < np.inf:
        return cond, 1.0
    for i in range(4):
        c0 = 0j
        c1 = 0j
        for j in range(4):
            c0 += Vinv[i, j] * f0[j]
            c1 += Vinv[i, j] * f_tau[j]
        coef[0, i] = c0
        coef[1, i] = c1
    return cond, _omega_max(lam, eta)


@jit
def _evaluate_polar(dt, ws, out, dout):
    """PolarLinearisedContact.states and .derivatives at tau0 + dt, in Cartesian form."""
    lam, V, _, coef, _, real, M, _, _, _, _, _, w, P, dP, _ = ws
    if dt == 0.0:
        for i in range(4):
            P[i] = real[i]  # p0 + Re(V @ 0), exactly
    else:
        for i in range(4):
            phi1, phi2 = _phi12(lam[i] * dt)
            w[i] = dt * phi1 * coef[0, i] + dt * dt * phi2 * coef[1, i]
        for i in range(4):
            acc = 0j
            for j in range(4):
                acc += V[i, j] * w[j]
            P[i] = real[i] + acc.real
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += M[i, j] * (P[j] - real[j])
        dP[i] = real[4 + i] + acc + real[8 + i] * dt
    r, theta, u, omega = P[0], P[1], P[2], P[3]
    x, y, vx, vy = cartesian_entries(r, theta, u, omega)
    out[0] = x
    out[1] = y
    out[2] = vx
    out[3] = vy
    c = x / r  # cos(theta), sin(theta) to round-off (the rates serve the event check)
    sn = y / r
    u_dot = dP[2]
    omega_dot = dP[3]
    dout[0] = vx
    dout[1] = vy
    dout[2] = u_dot * c - 2 * u * omega * sn - r * omega_dot * sn - r * omega * omega * c
    dout[3] = u_dot * sn + 2 * u * omega * c + r * omega_dot * c - r * omega * omega * sn


@jit
def _prepare_cartesian(tau0, s0, pars, mu_c, ws, warm):
    """LinearisedContact.__init__ at (tau0, s0): returns (cond1(V), omega_max).

    ``real`` holds s_c (0:4) and b (4:8); ``M`` is A; ``coef[0]`` the eigen-coefficients
    c of d0, ``coef[1]`` the harmonic amplitude S_hat.
    """
    lam, _, LU, coef, piv, real, M, _, _, _, _, _, x, _, _, Vinv = ws
    nu, eta, E, phi0, K = pars[0], pars[1], pars[2], pars[3], pars[4]
    A, b = linearised_contact_arrays(s0[0], s0[1], K, nu, mu_c)
    M[:, :] = A
    for i in range(4):
        for j in range(4):
            LU[i, j] = A[i, j]
    if not _lu_factor(LU, piv):
        return np.inf, 1.0
    for i in range(4):
        x[i] = -b[i]
    _lu_solve(LU, piv, x)  # s_c = A^-1 (-b)
    for i in range(4):
        real[i] = x[i].real
        real[4 + i] = b[i]
    for i in range(4):
        for j in range(4):
            LU[i, j] = -A[i, j]
        LU[i, i] += 1j * eta
    if not _lu_factor(LU, piv):
        return np.inf, 1.0
    coef[1, 0] = 0.0
    coef[1, 1] = 0.0
    coef[1, 2] = E
    coef[1, 3] = -1j * E
    _lu_solve(LU, piv, coef[1])  # S_hat = (i eta - A)^-1 (0, 0, E, -i E)
    cond = _eigenbasis(ws, warm)
    if not cond < np.inf:
        return cond, 1.0
    rot = cmath.exp(1j * (eta * tau0 + phi0))
    for i in range(4):
        x[i] = s0[i] - real[i] - (coef[1, i] * rot).real  # d0
    for i in range(4):
        c = 0j
        for j in range(4):
            c += Vinv[i, j] * x[j]
        coef[0, i] = c
    return cond, _omega_max(lam, eta)


@jit
def _evaluate_cartesian(dt, tau, pars, ws, out, dout):
    """LinearisedContact.states and .derivatives at tau = tau0 + dt."""
    lam, V, _, coef, _, real, M, _, _, _, _, _, e, _, _, _ = ws
    eta, E, phi0 = pars[1], pars[2], pars[3]
    phase = eta * tau + phi0
    rot = cmath.exp(1j * phase)
    for j in range(4):
        e[j] = coef[0, j] * cmath.exp(lam[j] * dt)
    for i in range(4):
        acc = 0j
        for j in range(4):
            acc += V[i, j] * e[j]
        out[i] = real[i] + (coef[1, i] * rot).real + acc.real
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += M[i, j] * out[j]
        dout[i] = acc + real[4 + i]
    dout[2] += E * math.cos(phase)
    dout[3] += E * math.sin(phase)


@jit
def _prepare(polar, tau0, s0, pars, mu_c, ws, warm):
    if polar:
        return _prepare_polar(tau0, s0, pars, mu_c, ws, warm)
    return _prepare_cartesian(tau0, s0, pars, mu_c, ws, warm)


@jit
def _evaluate(polar, tau0, t, pars, ws, out, dout):
    if polar:
        _evaluate_polar(t - tau0, ws, out, dout)
    else:
        _evaluate_cartesian(t - tau0, t, pars, ws, out, dout)


# --------------------------------------------------------------- the event pre-check


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
        z = math.hypot(x, y)
        whirl = x * vy - y * vx
        hv[i] = -sign * (spin + whirl / z)
        hd[i] = -sign * slip_velocity_rate(x, y, vx, vy, dS[i, 2], dS[i, 3])
        rate_scale = max(rate_scale, abs(hd[i]))
    margin_v = rel * (1.0 + abs(spin))
    return _may_cross(grid, hv, hd, n, margin_v, rel * (1.0 + rate_scale), starts[1], starts[2])


# --------------------------------------------------------------- the bulk steppers

STEP_CLEAR = -1  # _check_step: no event can occur in the step, the kernel may take it


@jit
def _scan_buffers(size):
    """(grid, S, dS, hv, hd) of a scan grid of ``size`` points."""
    return (
        np.empty(size),
        np.empty((size, 4)),
        np.empty((size, 4)),
        np.empty(size),
        np.empty(size),
    )


@jit
def _scan_points(tau, tb, omega_max, scan_fraction):
    """Intervals of the step's scan grid (analytic.py's ``search``), -1 beyond MAX_SCAN_POINTS."""
    spacing = scan_fraction * 2.0 * math.pi / max(omega_max, 1e-300)
    if (tb - tau) / spacing > MAX_SCAN_POINTS:
        return -1
    return max(1, math.ceil((tb - tau) / spacing))


@jit_inline
def _check_step(polar, tau, tb, n, ws, cond, pars, event_args, scan, end, work):
    """The event pre-check of one prepared contact step [tau, tb] (propagator in ``ws``).

    The lines of ``advance_contact``'s step (kept inline there: this call, with the
    workspace, costs its fixed steps ~10% more): the step is evaluated on its scan grid
    of ``n`` intervals (``np.linspace(tau, tb, n + 1)``, ``n`` from ``_scan_points``)
    and ``_step_may_have_event`` decides. ``event_args`` = (sign, check_slip, spin,
    starts); ``scan`` = (grid, S, dS, hv, hd) of at least n + 1 points
    (``_scan_buffers``); ``end`` receives the state at tb (the grid's last point);
    ``work`` = (out, dout). Returns ``STEP_CLEAR`` if no event can occur, ``STOP_EVENT``
    if one might, ``STOP_PYTHON`` if a state is not finite (Python fails the run).
    """
    sign, check_slip, spin, starts = event_args
    grid, S, dS, hv, hd = scan
    out, dout = work
    delta = (tb - tau) / n  # np.linspace(tau, tb, n + 1)
    for i in range(n):
        grid[i] = i * delta + tau
    grid[n] = tb
    finite = True
    for i in range(n + 1):
        _evaluate(polar, tau, grid[i], pars, ws, out, dout)
        for j in range(4):
            S[i, j] = out[j]
            dS[i, j] = dout[j]
            finite = finite and math.isfinite(out[j]) and math.isfinite(dout[j])
    if not finite:
        return STOP_PYTHON
    for j in range(4):
        end[j] = S[n, j]
    if _step_may_have_event(grid, S, dS, n, sign, check_slip, spin, cond, hv, hd, starts):
        return STOP_EVENT
    return STEP_CLEAR


@jit_inline
def _fill_samples(polar, tau, tb, pars, ws, t_eval, out_states, k, work):
    """Write the samples of ``t_eval[k:]`` in (.., tb] from the step prepared at tau
    (as ``advance_contact`` does); returns the new k. ``work`` = (out, dout)."""
    out, dout = work
    while k < t_eval.shape[0] and t_eval[k] <= tb:
        _evaluate(polar, tau, t_eval[k], pars, ws, out, dout)
        for j in range(4):
            out_states[k, j] = out[j]
        k += 1
    return k


@jit
def _event_args(regime, pars, starts):
    """(sign, check_slip, spin, starts) of a slip regime, for ``_check_step``."""
    eta, mu, Rp = pars[1], pars[5], pars[6]
    return float(regime), mu > 0.0, Rp * eta, starts


@jit
def advance_contact(
    polar,
    tau,
    state,
    h,
    t_end,
    regime,
    pars,
    t_eval,
    out_states,
    k,
    max_steps,
    scan_fraction,
    cond_limit,
    starts,
):
    """Fixed contact steps of length h in one slip regime while no event can occur.

    ``polar`` selects the linearisation (``PolarLinearisedContact`` or
    ``LinearisedContact``); ``pars`` is ``model.params_vector``; each step is
    ``[tau, min(t_end, tau + h)]`` and ``out_states[k:]`` receives the samples of
    ``t_eval[k:]`` that it covers. ``scan_fraction`` and ``cond_limit`` are analytic.py's
    ``CONTACT_SCAN_FRACTION`` and ``EIGVEC_COND_LIMIT``. At most ``max_steps`` steps.
    ``starts`` = (on the contact surface, on the slip surface, slip start immediate)
    says whether the first step starts at an event (as ``earliest_event``'s last_kind).

    Returns ``(tau, state, k, steps, reason)`` (reason: a ``STOP_*`` code); the step
    from ``(tau, state)`` has not been taken.
    """
    eta, mu, Rp = pars[1], pars[5], pars[6]
    mu_c = mu * friction_sign(regime)
    check_slip = mu > 0.0
    sign = float(regime)
    spin = Rp * eta
    s = state.copy()
    n_out = t_eval.shape[0]
    ws = _workspace()
    out = np.empty(4)
    dout = np.empty(4)
    size = 2
    grid = np.empty(size)
    S = np.empty((size, 4))
    dS = np.empty((size, 4))
    hv = np.empty(size)
    hd = np.empty(size)
    steps = 0
    while True:
        if tau >= t_end:
            return tau, s, k, steps, STOP_END
        if steps >= max_steps:
            return tau, s, k, steps, STOP_LIMIT
        tb = min(t_end, tau + h)
        # from the second step on, the previous eigenvalues start the eigensolver
        cond, omega_max = _prepare(polar, tau, s, pars, mu_c, ws, steps > 0)
        # Python uses the eigenbasis while cond2(V) <= cond_limit, and cond2 <= 4 cond1:
        # proceed only where Python surely uses it too.
        if not 8.0 * cond <= cond_limit:
            return tau, s, k, steps, STOP_PYTHON
        spacing = scan_fraction * 2.0 * math.pi / max(omega_max, 1e-300)
        if (tb - tau) / spacing > MAX_SCAN_POINTS:
            return tau, s, k, steps, STOP_PYTHON  # Python fails the run cleanly
        n = max(1, math.ceil((tb - tau) / spacing))
        if size < n + 1:
            size = n + 1
            grid = np.empty(size)
            S = np.empty((size, 4))
            dS = np.empty((size, 4))
            hv = np.empty(size)
            hd = np.empty(size)
        delta = (tb - tau) / n  # np.linspace(tau, tb, n + 1)
        for i in range(n):
            grid[i] = i * delta + tau
        grid[n] = tb
        finite = True
        for i in range(n + 1):
            _evaluate(polar, tau, grid[i], pars, ws, out, dout)
            for j in range(4):
                S[i, j] = out[j]
                dS[i, j] = dout[j]
                finite = finite and math.isfinite(out[j]) and math.isfinite(dout[j])
        if not finite:
            return tau, s, k, steps, STOP_PYTHON
        if steps > 0:
            starts = (False, False, False)
        if _step_may_have_event(grid, S, dS, n, sign, check_slip, spin, cond, hv, hd, starts):
            return tau, s, k, steps, STOP_EVENT
        while k < n_out and t_eval[k] <= tb:
            _evaluate(polar, tau, t_eval[k], pars, ws, out, dout)
            for j in range(4):
                out_states[k, j] = out[j]
            k += 1
        for j in range(4):
            s[j] = S[n, j]
        tau = tb
        steps += 1


@jit
def advance_contact_adaptive(
    polar,
    tau,
    state,
    h,
    t_end,
    regime,
    pars,
    t_eval,
    out_states,
    k,
    max_steps,
    scan_fraction,
    cond_limit,
    starts,
    control,
):
    """Adaptive (step-doubling) contact steps in one slip regime while no event can occur.

    The step control of analytic.py's Python loop (``_doubling_error`` and the loop in
    ``solve_piecewise``), pair of half steps by pair: from (tau, s) a step of
    ``step = min(h, h_max, t_end - tau)`` is compared with two of ``step / 2``,
    ``err = max(|full - second| / (1 + |s|)) * 4/3``; the proposed next step is
    ``step * min(max_factor, max(min_factor, safety * (tol / err)^(1/3)))``, and the step
    is rejected (and retried with that step) unless ``err <= tol`` or
    ``step <= min_step``. An accepted pair is taken as its two half steps, each checked
    for events and sampled as ``advance_contact`` checks and samples one step, each
    counted as one step. ``control`` = (tol, safety, min_factor, max_factor, h_max,
    min_step); the other arguments are ``advance_contact``'s.

    A pair is committed whole or not at all: if either half might hold an event, needs
    Python (conditioning, scan size, non-finite states), or the pair does not fit in
    ``max_steps``, the kernel returns *before* the pair, with the ``h`` it started the
    pair with, so Python's own adaptive loop recomputes that pair (its rejections
    included) exactly as it would have without the kernel.

    Returns ``(tau, state, k, steps, rejected, h, reason)``: ``rejected`` counts the
    rejected tries of the committed pairs only, ``h`` is the controller's proposed next
    step; with ``steps == 0`` and a limit too small for a pair the reason is
    ``STOP_PYTHON``, else ``STOP_LIMIT``.
    """
    tol, safety, min_factor, max_factor, h_max, min_step = control
    mu_c = pars[5] * friction_sign(regime)
    first_args = _event_args(regime, pars, starts)
    later_args = _event_args(regime, pars, (False, False, False))
    s = state.copy()
    ws1 = _workspace()  # the full step and the first half: one propagator, at (tau, s)
    ws2 = _workspace()  # the second half, at (tau + step / 2, mid)
    full = np.empty(4)
    mid = np.empty(4)
    end = np.empty(4)
    dout = np.empty(4)
    work = (np.empty(4), dout)
    grid, S, dS, hv, hd = _scan_buffers(2)
    steps = 0
    rejected = 0
    while True:
        if tau >= t_end:
            return tau, s, k, steps, rejected, h, STOP_END
        if steps + 2 > max_steps:
            return tau, s, k, steps, rejected, h, STOP_LIMIT if steps > 0 else STOP_PYTHON
        if steps > 0:  # start the eigensolver from the last mid-point's eigenvalues
            for i in range(4):
                ws1[0][i] = ws2[0][i]
        cond1, omega1 = _prepare(polar, tau, s, pars, mu_c, ws1, steps > 0)
        if not 8.0 * cond1 <= cond_limit:  # as in advance_contact
            return tau, s, k, steps, rejected, h, STOP_PYTHON
        h_next = h
        tries = 0
        while True:
            step = min(h_next, h_max, t_end - tau)
            t_mid = tau + step / 2
            t_next = tau + step
            _evaluate(polar, tau, t_next, pars, ws1, full, dout)
            _evaluate(polar, tau, t_mid, pars, ws1, mid, dout)
            for i in range(4):
                ws2[0][i] = ws1[0][i]
            cond2, omega2 = _prepare(polar, t_mid, mid, pars, mu_c, ws2, True)
            if not 8.0 * cond2 <= cond_limit:
                return tau, s, k, steps, rejected, h, STOP_PYTHON
            _evaluate(polar, t_mid, t_next, pars, ws2, end, dout)
            largest = 0.0
            for j in range(4):
                d = abs(full[j] - end[j]) / (1.0 + abs(s[j]))
                if not d <= largest:  # (a NaN propagates, as in np.max)
                    largest = d
            err = largest * 4.0 / 3.0
            if not math.isfinite(err):
                return tau, s, k, steps, rejected, h, STOP_PYTHON
            factor = safety * (tol / max(err, 1e-300)) ** (1 / 3)
            h_next = step * min(max_factor, max(min_factor, factor))
            if err <= tol or step <= min_step:
                break
            tries += 1
        # both halves are checked before either is taken (Python may redo the pair)
        n1 = _scan_points(tau, t_mid, omega1, scan_fraction)
        n2 = _scan_points(t_mid, t_next, omega2, scan_fraction)
        if n1 < 0 or n2 < 0:
            return tau, s, k, steps, rejected, h, STOP_PYTHON  # Python fails the run cleanly
        if grid.shape[0] < max(n1, n2) + 1:
            grid, S, dS, hv, hd = _scan_buffers(max(n1, n2) + 1)
        scan = (grid, S, dS, hv, hd)
        args = first_args if steps == 0 else later_args
        code = _check_step(polar, tau, t_mid, n1, ws1, cond1, pars, args, scan, mid, work)
        if code != STEP_CLEAR:
            return tau, s, k, steps, rejected, h, code
        code = _check_step(polar, t_mid, t_next, n2, ws2, cond2, pars, later_args, scan, end, work)
        if code != STEP_CLEAR:
            return tau, s, k, steps, rejected, h, code
        k = _fill_samples(polar, tau, t_mid, pars, ws1, t_eval, out_states, k, work)
        k = _fill_samples(polar, t_mid, t_next, pars, ws2, t_eval, out_states, k, work)
        for j in range(4):
            s[j] = end[j]
        tau = t_next
        h = h_next
        steps += 2
        rejected += tries


# --------------------------------------------------------------- DOP853, compiled

# scipy's own DOP853 tableau (Hairer's coefficients, as scipy.integrate.DOP853 uses them):
# stages 0-11 and the solution weights, the embedded 5th- and 3rd-order error weights,
# and the three extra stages and the D matrix of the 7th-order dense output.
DOP_A = np.ascontiguousarray(_dop.A, dtype=float)  # (16, 16)
DOP_B = np.ascontiguousarray(_dop.B, dtype=float)  # (12,)
DOP_C = np.ascontiguousarray(_dop.C, dtype=float)  # (16,)
DOP_E3 = np.ascontiguousarray(_dop.E3, dtype=float)  # (13,)
DOP_E5 = np.ascontiguousarray(_dop.E5, dtype=float)  # (13,)
DOP_D = np.ascontiguousarray(_dop.D, dtype=float)  # (4, 16)
DOP_STAGES = _dop.N_STAGES  # 12
DOP_ERROR_EXPONENT = -1.0 / 8.0  # scipy: -1 / (error_estimator_order + 1), order 7
DOP_SAFETY, DOP_MIN_FACTOR, DOP_MAX_FACTOR = 0.9, 0.2, 10.0  # scipy.integrate._ivp.rk
DOP_SCAN_POINTS = 4  # scipy_ivp.SCAN_POINTS: the event scan grid of a step
STOP_SMALL_STEP = 4  # the step size fell below scipy's minimum (10 ulp of tau)
STOP_FULL = 5  # the kernel's event buffers are full
FREE_REGIME, STICK_REGIME = model.FREE, model.STICK
STICK_EXIT_MARGIN = model.STICK_EXIT_MARGIN
SLIP_POSITIVE_REGIME, SLIP_NEGATIVE_REGIME = model.SLIP_POSITIVE, model.SLIP_NEGATIVE
BRENT_XTOL, BRENT_RTOL = XTOL, RTOL  # events' root tolerances
TINY = np.finfo(float).tiny


@jit
def _rhs_into(t, y, pars, regime, out):
    vx, vy, ax, ay = rhs_entries(
        t,
        y[0],
        y[1],
        y[2],
        y[3],
        pars[0],
        pars[1],
        pars[2],
        pars[3],
        pars[4],
        pars[5],
        pars[6],
        regime,
    )
    out[0], out[1], out[2], out[3] = vx, vy, ax, ay


@jit
def _rms_norm(v):
    total = 0.0
    for i in range(v.shape[0]):
        total += v[i] * v[i]
    return math.sqrt(total / v.shape[0])


@jit
def dop853_initial_step(t0, y0, f0, t_bound, pars, regime, rtol, atol):
    """scipy's ``select_initial_step`` (Hairer, Norsett, Wanner II.4) for DOP853 (order 7)."""
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0
    scaled = np.empty(4)
    for i in range(4):
        scaled[i] = y0[i] / (atol + abs(y0[i]) * rtol)
    d0 = _rms_norm(scaled)
    for i in range(4):
        scaled[i] = f0[i] / (atol + abs(y0[i]) * rtol)
    d1 = _rms_norm(scaled)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, interval)
    y1 = np.empty(4)
    for i in range(4):
        y1[i] = y0[i] + h0 * f0[i]
    f1 = np.empty(4)
    _rhs_into(t0 + h0, y1, pars, regime, f1)
    for i in range(4):
        scaled[i] = (f1[i] - f0[i]) / (atol + abs(y0[i]) * rtol)
    d2 = _rms_norm(scaled) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1, interval)


@jit
def _dop853_try(t, y, h, pars, regime, Kst, y_new, tmp):
    """One DOP853 step of length h from (t, y) with Kst[0] = f(t, y): y_new, Kst[1:13]."""
    for s in range(1, DOP_STAGES):
        for i in range(4):
            acc = 0.0
            for j in range(s):
                acc += DOP_A[s, j] * Kst[j, i]
            tmp[i] = y[i] + h * acc
        _rhs_into(t + DOP_C[s] * h, tmp, pars, regime, Kst[s])
    for i in range(4):
        acc = 0.0
        for j in range(DOP_STAGES):
            acc += DOP_B[j] * Kst[j, i]
        y_new[i] = y[i] + h * acc
    _rhs_into(t + h, y_new, pars, regime, Kst[DOP_STAGES])


@jit
def _dop853_error_norm(Kst, h, y, y_new, rtol, atol):
    """scipy's DOP853._estimate_error_norm (the 5th/3rd-order blend)."""
    e5 = 0.0
    e3 = 0.0
    for i in range(4):
        scale = atol + max(abs(y[i]), abs(y_new[i])) * rtol
        a5 = 0.0
        a3 = 0.0
        for j in range(DOP_STAGES + 1):
            a5 += DOP_E5[j] * Kst[j, i]
            a3 += DOP_E3[j] * Kst[j, i]
        e5 += (a5 / scale) ** 2
        e3 += (a3 / scale) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * 4.0)


@jit
def _dop853_dense_coefficients(t_old, h, y_old, y_new, pars, regime, Kst, F, tmp):
    """The 7th-order dense output of an accepted step (scipy's Dop853DenseOutput F)."""
    for s in range(DOP_STAGES + 1, Kst.shape[0]):
        for i in range(4):
            acc = 0.0
            for j in range(s):
                acc += DOP_A[s, j] * Kst[j, i]
            tmp[i] = y_old[i] + h * acc
        _rhs_into(t_old + DOP_C[s] * h, tmp, pars, regime, Kst[s])
    for i in range(4):
        delta = y_new[i] - y_old[i]
        F[0, i] = delta
        F[1, i] = h * Kst[0, i] - delta
        F[2, i] = 2.0 * delta - h * (Kst[DOP_STAGES, i] + Kst[0, i])
        for r in range(4):
            acc = 0.0
            for j in range(Kst.shape[0]):
                acc += DOP_D[r, j] * Kst[j, i]
            F[3 + r, i] = h * acc


@jit
def _dop853_dense_at(t, t_old, h, y_old, F, out):
    x = (t - t_old) / h
    for i in range(4):
        acc = 0.0
        for n in range(F.shape[0]):
            acc += F[F.shape[0] - 1 - n, i]
            acc *= x if n % 2 == 0 else 1.0 - x
        out[i] = acc + y_old[i]


@jit
def dop853_dense_point(t, t_old, h, y_old, F):
    """The dense output at one time t: the state (4,)."""
    out = np.empty(4)
    _dop853_dense_at(t, t_old, h, y_old, F, out)
    return out


@jit
def dop853_dense(t, t_old, h, y_old, F):
    """The dense output at the times t (n,): states (4, n), as scipy's Dop853DenseOutput."""
    out = np.empty((4, t.shape[0]))
    row = np.empty(4)
    for k in range(t.shape[0]):
        _dop853_dense_at(t[k], t_old, h, y_old, F, row)
        for i in range(4):
            out[i, k] = row[i]
    return out


# Event kinds the kernel applies: events.ENTRY, EXIT, REVERSAL, STICK_ENTRY, STICK_EXIT.
KIND_ENTRY, KIND_EXIT, KIND_REVERSAL, KIND_STICK_ENTRY, KIND_STICK_EXIT = 0, 1, 2, 3, 4
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
    return -sign * (pars[6] * pars[1] + (x * vy - y * vx) / math.hypot(x, y))


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
            ahead = grid[0] + LOOK_AHEAD * (grid[1] - grid[0])  # events._ahead
            rate = _event_fn(ahead, fn, sign, True, t_old, h, y_old, F, pars, regime, d, row, drow)
            if rate >= 0.0:
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
        return (t, KIND_ENTRY) if not math.isnan(t) else (t, -1)
    best, kind = math.nan, -1
    t = _first_crossing(
        FN_SURFACE, -1.0, grid, hv, hd, n, starts[0], 0.0, SURFACE_BAND * band, True,
        t_old, h, y_old, F, pars, regime, d, row, drow,
    )  # fmt: skip
    if not math.isnan(t):
        best, kind = t, KIND_EXIT
    if pars[5] > 0.0 and regime != STICK_REGIME:
        level = band * (1.0 + abs(pars[6] * pars[1]))
        t = _first_crossing(
            FN_SLIP, float(regime), grid, hv, hd, n, starts[1], 0.0, level, starts[2],
            t_old, h, y_old, F, pars, regime, d, row, drow,
        )  # fmt: skip
        if not math.isnan(t) and (math.isnan(best) or t < best):
            best, kind = t, KIND_REVERSAL
    if regime == STICK_REGIME:
        for sign in (1.0, -1.0):
            t = _first_crossing(
                FN_STICK, sign, grid, hv, hd, n, False, 0.0, STICK_EXIT_LEVEL, True,
                t_old, h, y_old, F, pars, regime, d, row, drow,
            )  # fmt: skip
            if not math.isnan(t) and (math.isnan(best) or t < best):
                best, kind = t, KIND_STICK_EXIT
    return best, kind


@jit
def _apply_event(kind, t, s, regime, pars):
    """``events.apply_event``: (new regime, kind as recorded); ``s`` is projected onto
    the rolling constraint in place when stick begins or ends in contact."""
    if kind == KIND_EXIT:
        new = FREE_REGIME
    elif kind == KIND_ENTRY:
        new = SLIP_POSITIVE_REGIME
        if pars[5] != 0.0:
            v_r = pars[6] * pars[1] + ((s[0] * s[3] - s[1] * s[2]) / math.hypot(s[0], s[1]))
            new = SLIP_POSITIVE_REGIME if v_r >= 0.0 else SLIP_NEGATIVE_REGIME
    else:
        needed = stick_friction_value(t, s[0], s[1], s[2], s[3], pars[0], pars[1], pars[2], pars[3])
        if kind == KIND_STICK_EXIT:
            new = SLIP_POSITIVE_REGIME if needed > 0.0 else SLIP_NEGATIVE_REGIME
        else:  # slip reversal: model.regime_at_zero_slip (Filippov)
            limit = pars[5] * pars[4] * (math.hypot(s[0], s[1]) - 1.0)
            if needed > limit:
                new = SLIP_POSITIVE_REGIME
            elif needed < -limit:
                new = SLIP_NEGATIVE_REGIME
            else:
                new = STICK_REGIME
    if new == STICK_REGIME:
        kind = KIND_STICK_ENTRY
    stick = regime == STICK_REGIME or new == STICK_REGIME
    if stick and regime != FREE_REGIME and new != FREE_REGIME:
        s[2], s[3] = rolling_velocity(s[0], s[1], s[2], s[3], pars[6] * pars[1])
    return new, kind


@jit
def _start_flags(kind):
    """``events.start_flags`` of the event kind that begins a segment."""
    return (
        kind in (KIND_ENTRY, KIND_EXIT),
        kind in (KIND_REVERSAL, KIND_STICK_EXIT),
        kind != KIND_STICK_EXIT,
    )


@jit
def advance_dop853(
    tau, y, f, h_abs, t_end, pars, regime, rtol, atol, t_eval, out_states, out_regimes, k,
    max_steps, starts, y_new, f_new, F, band, events_tau, events_kind, events_state,
    events_regimes, compiled_events,
):  # fmt: skip
    """Adaptive DOP853 steps with their events (scipy's algorithm, the scipy methods' events).

    Each step is scipy's DOP853 step exactly: the same tableau, error norm, step-size
    rule (safety 0.9, factors 0.2-10, no growth right after a rejection) and minimum
    step. After each accepted step its dense output goes through the conservative event
    pre-check (which treats the first step against the event that began the segment,
    ``starts``, as ``earliest_event`` does). A step where no event is possible is
    committed, and the samples ``t_eval[k:]`` it covers go to ``out_states`` and
    ``out_regimes`` (projected in stick). Otherwise:

    - with ``compiled_events``: the kernel runs ``events.earliest_event`` itself
      (``_dop853_locate``: a transcription of ``first_crossing`` for each event function
      of the regime, ``band`` the restart band) and, at an event, ``events.apply_event``
      (``_apply_event``), records it in ``events_*`` and starts the next segment as the
      Python driver would (new f, scipy's initial step);
    - without: the step is *not* committed; it is returned for Python, with ``y_new``,
      ``f_new`` and the dense coefficients ``F`` filled.

    ``y`` and ``f`` hold the last committed state. Returns ``(tau, t_new, h_abs, k,
    steps, nfev, reason, regime, n_events, at_event)``: reason END, LIMIT (``max_steps``
    steps), EVENT (a pending step from ``tau`` to ``t_new``), FULL (the event buffers
    are full; the state is at the last event, its segment not yet started), PYTHON (a
    non-finite state) or SMALL_STEP; ``at_event``: ``tau`` is the last event's time.
    """
    Kst = np.empty((DOP_A.shape[0], 4))
    tmp = np.empty(4)
    row = np.empty(4)
    drow = np.empty(4)
    n = DOP_SCAN_POINTS
    grid = np.empty(n + 1)
    S = np.empty((n + 1, 4))
    dS = np.empty((n + 1, 4))
    hv = np.empty(n + 1)
    hd = np.empty(n + 1)
    n_out = t_eval.shape[0]
    capacity = events_tau.shape[0]
    steps = 0
    nfev = 0
    n_events = 0
    while True:
        at_event = starts[0] or starts[1]
        if tau >= t_end:
            return tau, tau, h_abs, k, steps, nfev, STOP_END, regime, n_events, at_event
        if steps >= max_steps:
            return tau, tau, h_abs, k, steps, nfev, STOP_LIMIT, regime, n_events, at_event
        min_step = 10.0 * abs(np.nextafter(tau, np.inf) - tau)
        h_abs = max(h_abs, min_step)
        rejected = False
        while True:
            if h_abs < min_step:
                return (
                    tau, tau, h_abs, k, steps, nfev, STOP_SMALL_STEP, regime, n_events,
                    at_event,
                )  # fmt: skip
            t_new = min(tau + h_abs, t_end)
            h = t_new - tau
            h_abs = abs(h)
            for i in range(4):
                Kst[0, i] = f[i]
            _dop853_try(tau, y, h, pars, regime, Kst, y_new, tmp)
            nfev += DOP_STAGES
            error = _dop853_error_norm(Kst, h, y, y_new, rtol, atol)
            if error < 1.0:
                if error == 0.0:
                    factor = DOP_MAX_FACTOR
                else:
                    factor = min(DOP_MAX_FACTOR, DOP_SAFETY * error**DOP_ERROR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            if not math.isfinite(error):
                h_abs *= DOP_MIN_FACTOR
            else:
                h_abs *= max(DOP_MIN_FACTOR, DOP_SAFETY * error**DOP_ERROR_EXPONENT)
            rejected = True
        for i in range(4):
            f_new[i] = Kst[DOP_STAGES, i]
        _dop853_dense_coefficients(tau, h, y, y_new, pars, regime, Kst, F, tmp)
        nfev += Kst.shape[0] - DOP_STAGES - 1
        finite = True
        for i in range(4):
            finite = finite and math.isfinite(y_new[i])
        if not finite:
            return tau, t_new, h_abs, k, steps, nfev, STOP_PYTHON, regime, n_events, at_event
        kind = -1
        t_stop = t_new
        if _dop853_may_have_event(tau, h, y, F, pars, regime, grid, S, dS, hv, hd, row, starts):
            if not compiled_events:
                return tau, t_new, h_abs, k, steps, nfev, STOP_EVENT, regime, n_events, at_event
            t_ev, kind = _dop853_locate(
                tau, h, y, F, pars, regime, grid, hv, hd, row, drow, starts, band
            )
            if kind >= 0:
                t_stop = t_ev
        while k < n_out and t_eval[k] <= t_stop:
            _dop853_dense_at(t_eval[k], tau, h, y, F, row)
            if regime == STICK_REGIME:  # samples in stick are reported projected
                row[2], row[3] = rolling_velocity(row[0], row[1], row[2], row[3], pars[6] * pars[1])
            for i in range(4):
                out_states[k, i] = row[i]
            out_regimes[k] = regime
            k += 1
        steps += 1
        if kind < 0:
            for i in range(4):
                y[i] = y_new[i]
                f[i] = f_new[i]
            tau = t_new
            starts = (False, False, True)
            continue
        # the event: events.apply_event, then a new segment as the driver starts one
        _dop853_dense_at(t_stop, tau, h, y, F, row)
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
        starts = _start_flags(kind)
        if n_events == capacity:
            return tau, tau, h_abs, k, steps, nfev, STOP_FULL, regime, n_events, True
        _rhs_into(tau, y, pars, regime, f)
        h_abs = dop853_initial_step(tau, y, f, t_end, pars, regime, rtol, atol)
        nfev += 2


# --------------------------------------------------------------- right-hand sides


@jit
def rhs(t, s, pars, regime):
    """``model.rhs`` compiled: the regime-locked right-hand side (pars = params_vector)."""
    out = np.empty(4)
    vx, vy, ax, ay = rhs_entries(
        t,
        s[0],
        s[1],
        s[2],
        s[3],
        pars[0],
        pars[1],
        pars[2],
        pars[3],
        pars[4],
        pars[5],
        pars[6],
        regime,
    )
    out[0], out[1], out[2], out[3] = vx, vy, ax, ay
    return out


@jit
def rhs_columns(t, S, pars, regime):
    """``rhs`` for the states in the columns of S (4, n) at the times t (n,)."""
    out = np.empty_like(S)
    for k in range(S.shape[1]):
        out[:, k] = rhs(t[k], np.ascontiguousarray(S[:, k]), pars, regime)
    return out


@jit
def rhs_jacobian(t, s, pars, regime):
    """``model.rhs_jacobian`` compiled."""
    return rhs_jacobian_array(
        t,
        s[0],
        s[1],
        s[2],
        s[3],
        pars[0],
        pars[1],
        pars[2],
        pars[3],
        pars[4],
        pars[5],
        pars[6],
        regime,
    )


# --------------------------------------------------------------- freshness of the cache


def _probe_values(x):
    """The registered model cores evaluated at one point (see ``ensure_fresh``).

    A plain function, run as it is by the interpreter and compiled as ``_probe``.
    """
    nu, eta, E, phi0, K, mu, Rp = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
    tau, px, py, vx, vy = x[7], x[8], x[9], x[10], x[11]
    out = np.empty(81)
    n = 0
    for regime in (0, 1, -1, 2):
        for v in rhs_entries(tau, px, py, vx, vy, nu, eta, E, phi0, K, mu, Rp, regime):
            out[n] = v
            n += 1
    for v in rhs_jacobian_array(tau, px, py, vx, vy, nu, eta, E, phi0, K, mu, Rp, 1).ravel():
        out[n] = v
        n += 1
    A, b = linearised_contact_arrays(px, py, K, nu, mu)
    for v in A.ravel():
        out[n] = v
        n += 1
    for v in b:
        out[n] = v
        n += 1
    out[n] = slip_velocity_rate(px, py, vx, vy, 0.3, -0.2)
    n += 1
    r, theta, u, omega = polar_entries(px, py, vx, vy)
    for v in cartesian_entries(r, theta, u, omega):
        out[n] = v
        n += 1
    for v in polar_rhs_entries(tau, r, theta, u, omega, nu, eta, E, phi0, K, mu):
        out[n] = v
        n += 1
    J, f_tau = polar_jacobian_arrays(tau, r, theta, u, omega, nu, eta, E, phi0, K, mu)
    for v in J.ravel():
        out[n] = v
        n += 1
    for v in f_tau:
        out[n] = v
        n += 1
    return out[:n]


_probe = jit(_probe_values)
# nu, eta, E, phi0, K, mu, Rp, tau, x, y, vx, vy: a contact state with friction
PROBE_POINT = np.array([0.013, 0.71, 2.9, 0.37, 123.0, 0.07, 3.1, 1.3, 1.05, -0.42, 0.61, 1.7])
PROBE_RTOL = 1e-12  # the two evaluations differ by round-off (libm vs CPython's hypot)
_usable: bool | None = None


def _probe_agrees() -> bool:
    compiled = _probe(PROBE_POINT)
    expected = _probe_values(PROBE_POINT)
    return bool(np.allclose(compiled, expected, rtol=PROBE_RTOL, atol=PROBE_RTOL))


def ensure_fresh() -> bool:
    """Make sure the cached kernels run model.py's current cores; True if they do.

    numba invalidates a cached function when its own file changes, not when a function
    it calls in another file (model.py's cores) does. Once per process, the probe
    (cached like the kernels) is compared with the interpreter's evaluation of the same
    cores; if they disagree, every kernel's cache is flushed and the probe compared
    again. Should they still disagree (a core that numba compiles differently), the
    kernels are not used: False, with a warning, and the callers run pure Python.
    """
    global _usable
    if _usable is None:
        usable = _probe_agrees()
        if not usable:
            for dispatcher in _CACHED:
                dispatcher.recompile()  # flushes its cache; compiled afresh on next call
            usable = _probe_agrees()
        if not usable:
            warnings.warn(
                "rubcli: the compiled kernels disagree with model.py; using the pure-Python "
                "path (please report this)",
                RuntimeWarning,
                stacklevel=2,
            )
        _usable = usable
    return _usable


_CACHED = [
    value
    for value in list(globals().values())
    if isinstance(value, numba.core.dispatcher.Dispatcher)
]

"""Small dense linear algebra for the 4x4 linearised contact systems, compiled.

LU with partial pivoting, and an eigensolver (balancing, Hessenberg form by Givens
rotations, complex single-shift QR, eigenvectors by back substitution) that takes about
1.5 us for a 4x4 matrix against about 9 us for LAPACK's zgeev through numba; a warm
start that refines the previous step's eigenvalues by Newton on the characteristic
quartic (about 0.4 us); and the residual check that decides whether a result is
trusted (else the step goes to the Python propagator and LAPACK).
"""

from __future__ import annotations

import math

import numpy as np

from rubcli.solvers.compiled.jit import (
    EPS,
    jit,
)

EIG_RESIDUAL_TOL = 1e3 * EPS  # backward error accepted from the hand-written eigensolver
WARM_NEWTON_ITERATIONS = 6  # Newton steps allowed per eigenvalue from the previous step's


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

    On return B holds D^-1 B D with D = diag(scale). A row or column whose norm
    overflows (entries beyond 1e154) is left unscaled: its scaling loop would not end.
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
            if c == 0.0 or r == 0.0 or not (c < np.inf and r < np.inf):
                continue  # (an overflowing norm would never balance: leave the row)
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

"""Evidence read from a stroboscopic section: linear contraction and refined frequencies.

Two measurements that ``analysis.response.classification`` uses to decide what a section is.

**Contraction (``linear_fit``).** Near a periodic orbit of period p the p-th iterate of
the stroboscopic map is linear to first order, so the steps ``d_k = P[k+p] - P[k]`` of
each residue class ``k mod p`` obey ``d_{k+p} = A d_k``. ``A`` is fitted by least squares
(dynamic mode decomposition: P. J. Schmid, "Dynamic mode decomposition of numerical and
experimental data", J. Fluid Mech. 656 (2010) 5-28; the steps instead of the states
remove the unknown fixed point, as in Prony's method). Its eigenvalues are the
multipliers of the orbit that the section still shows, to the accuracy of the fit; the
leading one gives the rate per forcing period, ``|lambda|^(1/p)``, and the rotation
per forcing period, ``arg(lambda) / (2 pi p)``. The fit is repeated on each half of the
record: a converging (or departing) section in the linear regime has the same rate in
both halves, a section that is still nonlinear (approaching a torus, chaotic, a large
torus) does not, or fits badly (relative residual above the tolerance). Eigenvalues
that differ between the halves (noise directions) are not used.

**Frequencies (``refined_frequencies``).** The numerical analysis of fundamental
frequencies (NAFF) of J. Laskar, "Frequency analysis for multi-dimensional systems.
Global dynamics and diffusion", Physica D 67 (1993) 257-281 (and J. Laskar, C.
Froeschle, A. Celletti, Physica D 56 (1992) 253-269): the complex signal
``z_k = x_k + i y_k`` of the section, multiplied by a Hann window, has its Fourier
amplitude maximised over a continuous frequency (not an FFT bin); the line is subtracted
and the next one sought. On a quasi-periodic section the frequencies of the two halves of
the record agree to far below the resolution 1 / N (the error falls like a power of N);
on a chaotic one they wander (Laskar's frequency diffusion). Frequencies are in cycles
per forcing period in (-1/2, 1/2]: the section samples the motion once per period, so a
whirl at ``omega`` rad per tau shows at ``omega T / (2 pi)`` modulo 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LINEAR_TOL = 0.05  # relative residual of the linear fit below which the map is linear
RATE_CONSTANCY = 0.25  # the two halves' ln(rate) may differ by this fraction of ln(rate)
DECAY_AGREEMENT = 0.5  # observed step decay within this fraction of the fitted one (+ 0.1)
LIMIT_AGREEMENT = 0.25  # limits closer than this x the distance still to go coincide
MARGINAL_RATE = 1e-4  # |ln rate| per period below which a linear section is a circle
MIN_PAIRS_PER_RANK = 2  # least-squares pairs per fitted dimension


# --------------------------------------------------------------------------- linear fit


@dataclass(frozen=True)
class LinearFit:
    """The linear fit of the p-th iterate of the section map (module docstring)."""

    period: int  # p, forcing periods
    multiplier: complex  # leading multiplier of the p-th iterate (full record)
    log_rate: float  # ln |multiplier| / p: per forcing period (< 0 converging)
    log_rate_halves: tuple[float, float]  # the same from each half of the record
    rotation: float  # arg(multiplier) / (2 pi p): cycles per forcing period
    residual: float  # largest relative residual of the three fits
    rank: int  # dimensions fitted
    pairs: int  # least-squares pairs (d_k, d_{k+p}) of the full fit of one class
    remaining: float  # distance of the last point from the extrapolated limit (absolute)
    limit: np.ndarray  # extrapolated limit of the last residue class
    limits: tuple[np.ndarray, ...]  # extrapolated limits of all p residue classes
    remainings: tuple[float, ...]  # and the distance of each class's last point from it
    observed_log_rate: float  # ln(RMS step, last quarter / first quarter) per period
    observed_span: float  # forcing periods between the two quarters' centres

    @property
    def rate(self) -> float:
        """Contraction factor per forcing period, exp(log_rate): < 1 converging."""
        return math.exp(self.log_rate)

    @property
    def log_rate_spread(self) -> float:
        """|ln rate(first half) - ln rate(second half)| per forcing period."""
        a, b = self.log_rate_halves
        return abs(a - b)

    @property
    def log_rate_error(self) -> float:
        """Standard error of ln(rate) per period from the fit's residual: a relative
        residual r over m pairs moves an eigenvalue by about r / sqrt(m)."""
        return self.residual / math.sqrt(max(self.pairs, 1)) / self.period

    @property
    def uncertainty(self) -> float:
        """Uncertainty of ln(rate) per period: the halves' spread or the fit's error."""
        return max(self.log_rate_spread, self.log_rate_error)

    @property
    def rate_stderr(self) -> float:
        """The uncertainty as a rate per forcing period."""
        return self.rate * self.uncertainty

    @property
    def significant(self) -> bool:
        """ln(rate) differs from 0 by more than three uncertainties (and MARGINAL_RATE)."""
        return abs(self.log_rate) > max(MARGINAL_RATE, 3.0 * self.uncertainty)

    @property
    def constant(self) -> bool:
        """The rate is the same in both halves of the record (a linear regime), and the
        steps of the section shrink or grow over the record as the fitted rate says.
        The halves may differ by RATE_CONSTANCY of the rate plus three of their own
        errors (each half has half the pairs)."""
        halves_error = 2.0 * self.log_rate_error  # sqrt(2) for half the pairs, sqrt(2) for two
        spread_ok = self.log_rate_spread <= RATE_CONSTANCY * abs(self.log_rate) + 3 * halves_error
        observed = abs(self.observed_log_rate - self.log_rate)
        allowed = DECAY_AGREEMENT * abs(self.log_rate) + 0.1 / max(self.observed_span, 1.0)
        return spread_ok and observed <= allowed

    def resolved_period(self) -> int:
        """The period of the orbit approached: p, or its smallest divisor q whose residue
        classes converge to the same points (within LIMIT_AGREEMENT of the distance still
        to go: the extrapolation cannot separate closer limits)."""
        p = self.period
        if p == 1 or not self.limits:
            return p
        limits = np.asarray(self.limits)
        tol = LIMIT_AGREEMENT * max(self.remainings)
        if not math.isfinite(tol):
            return p
        for q in range(1, p):
            if p % q == 0 and all(
                np.linalg.norm(limits[j] - limits[(j + q) % p]) <= tol for j in range(p)
            ):
                return q
        return p

    def to_dict(self) -> dict:
        return {
            "period": self.period,
            "contraction_rate": self.rate,
            "contraction_rate_stderr": self.rate_stderr,
            "log_rate_per_period": self.log_rate,
            "log_rate_halves": list(self.log_rate_halves),
            "observed_log_rate": self.observed_log_rate,
            "multiplier": [self.multiplier.real, self.multiplier.imag],
            "rotation_per_period": self.rotation,
            "residual": self.residual,
            "rank": self.rank,
            "pairs": self.pairs,
            "method": "linear fit of the section's steps, d_{k+p} = A d_k (DMD, Schmid 2010)",
        }


def _fit(steps: np.ndarray, max_rank: int) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """Least-squares ``d_{k+1} = A d_k`` in the leading singular directions of the steps.

    Returns (eigenvalues, relative residual, basis U, reduced matrix A_r).
    """
    y0, y1 = steps[:-1].T, steps[1:].T
    u, s, vt = np.linalg.svd(y0, full_matrices=False)
    if s.size == 0 or s[0] == 0.0:
        return np.zeros(0, complex), math.inf, u[:, :0], np.zeros((0, 0))
    keep = int(np.sum(s > 1e-12 * s[0]))
    rank = max(1, min(keep, max_rank))
    u, s, vt = u[:, :rank], s[:rank], vt[:rank]
    reduced = u.T @ y1 @ vt.T / s
    fitted = u @ reduced @ (u.T @ y0)
    norm = float(np.linalg.norm(y1))
    residual = float(np.linalg.norm(y1 - fitted)) / norm if norm > 0.0 else math.inf
    return np.linalg.eigvals(reduced), residual, u, reduced


def _limit(points: np.ndarray, steps: np.ndarray, fit) -> tuple[np.ndarray, float]:
    """Where a residue class converges, x_n + A (I - A)^-1 d_{n-1} in the fitted subspace,
    and its distance from the last point (NaN, and the last point, if it does not)."""
    eig, _, basis, reduced = fit
    if eig.size == 0 or np.max(np.abs(eig)) >= 1.0:
        return points[-1].copy(), math.nan
    try:
        shift = reduced @ np.linalg.solve(np.eye(reduced.shape[0]) - reduced, basis.T @ steps[-1])
    except np.linalg.LinAlgError:
        return points[-1].copy(), math.nan
    return points[-1] + basis @ shift, float(np.linalg.norm(basis @ shift))


def _leading(full: np.ndarray, halves: list[np.ndarray], tol: float) -> int | None:
    """Index of the largest-modulus eigenvalue of ``full`` found again in both halves."""
    for i in np.argsort(-np.abs(full)):
        if all(h.size and np.min(np.abs(h - full[i])) <= tol for h in halves):
            return int(i)
    return None


def linear_fit(points: np.ndarray, period: int = 1) -> LinearFit | None:
    """Fit the p-th iterate of the section map linearly (module docstring).

    ``points`` (n, d) should be scaled so that its coordinates weigh alike. Returns None
    when the record is too short for the fit (and its two halves) at this period, or
    when no eigenvalue is found again in both halves.
    """
    points = np.asarray(points, dtype=float)
    n, dim = points.shape
    classes = [points[j::period] for j in range(period)]
    shortest = min(c.shape[0] for c in classes)
    # each half of each class (half - 2 pairs) needs MIN_PAIRS_PER_RANK pairs per fitted
    # dimension: twice as many equations as unknowns in the fit
    rank = min(dim, (shortest // 2 - 2) // MIN_PAIRS_PER_RANK)
    if rank < 1:
        return None
    fits = []
    for c in classes:
        steps = np.diff(c, axis=0)
        half = c.shape[0] // 2
        full = _fit(steps, rank)
        first = _fit(np.diff(c[: half + 1], axis=0), rank)
        second = _fit(np.diff(c[half:], axis=0), rank)
        fits.append((c, steps, full, first, second))
    # the first class (the one with the last point) carries the estimate; the others
    # must agree with it, as the multipliers of a cycle are the same at each of its points
    residual = max(max(f[2][1], f[3][1], f[4][1]) for f in fits)
    if not math.isfinite(residual):
        return None
    tol = max(10.0 * residual, 1e-9)
    last = (n - 1) % period
    c, steps, full, first, second = fits[last]
    lead = _leading(full[0], [first[0], second[0]] + [f[2][0] for f in fits], tol)
    if lead is None:
        return None
    lam = complex(full[0][lead])
    modulus = abs(lam)
    if modulus == 0.0:
        return None

    def log_of(eig: np.ndarray) -> float:
        nearest = eig[np.argmin(np.abs(eig - lam))]
        return math.log(max(abs(nearest), 1e-300)) / period

    limits = tuple(_limit(f[0], f[1], f[2]) for f in fits)
    limit, remaining = limits[last]
    sizes = np.linalg.norm(steps, axis=1)
    quarter = max(1, sizes.size // 4)
    first_rms = float(np.sqrt(np.mean(sizes[:quarter] ** 2)))
    last_rms = float(np.sqrt(np.mean(sizes[-quarter:] ** 2)))
    span = float((sizes.size - quarter) * period)
    observed = math.log(last_rms / first_rms) / span if first_rms > 0 and last_rms > 0 else math.nan
    return LinearFit(
        period=period,
        multiplier=lam,
        log_rate=math.log(modulus) / period,
        log_rate_halves=(log_of(first[0]), log_of(second[0])),
        rotation=math.atan2(lam.imag, lam.real) / (2.0 * math.pi * period),
        residual=residual,
        rank=int(full[2].shape[1]),
        pairs=int(steps.shape[0] - 1),
        remaining=remaining,
        limit=limit,
        limits=tuple(point for point, _ in limits),
        remainings=tuple(distance for _, distance in limits),
        observed_log_rate=observed,
        observed_span=span,
    )


# --------------------------------------------------------------------------- frequencies


@dataclass(frozen=True)
class Frequencies:
    """Refined frequencies of the section (NAFF) and their drift between halves."""

    lines: tuple[tuple[float, float], ...]  # (frequency, amplitude), strongest first
    halves: tuple[float, float]  # the dominant line's frequency in each half
    n_points: int

    @property
    def rotation_number(self) -> float:
        """Frequency of the dominant line, cycles per forcing period in (-1/2, 1/2]."""
        return self.lines[0][0] if self.lines else math.nan

    @property
    def diffusion(self) -> float:
        """|f(first half) - f(second half)| of the dominant line (Laskar's diffusion)."""
        return abs(_wrap(self.halves[0] - self.halves[1]))

    @property
    def resolution(self) -> float:
        """1 / (points of a half): the Fourier resolution the diffusion is measured against."""
        return 1.0 / max(1, self.n_points // 2)

    def to_dict(self) -> dict:
        return {
            "rotation_number": self.rotation_number,
            "lines": [{"frequency": f, "amplitude": a} for f, a in self.lines],
            "halves": list(self.halves),
            "diffusion": self.diffusion,
            "resolution": self.resolution,
            "unit": "cycles per forcing period",
            "method": "NAFF (Laskar 1993): Hann-windowed amplitude maximised in frequency",
        }


def _wrap(f: float) -> float:
    """A frequency in cycles per sample, folded into (-1/2, 1/2]."""
    return -((0.5 - f) % 1.0 - 0.5)


def _amplitude(z: np.ndarray, window: np.ndarray, f: float) -> complex:
    k = np.arange(z.size)
    return complex(np.sum(window * z * np.exp(-2j * math.pi * f * k)) / np.sum(window))


def refined_frequencies(signal: np.ndarray, lines: int = 3) -> tuple[tuple[float, float], ...]:
    """The ``lines`` strongest frequencies of a (complex) series by NAFF (Laskar 1993).

    The mean is removed first. Each frequency is the maximum of the Hann-windowed Fourier
    amplitude, bracketed on a 16x zero-padded FFT and refined by a bounded scalar search
    to 1e-13; its line is then subtracted. Returns ``(frequency, amplitude)`` pairs.
    """
    from scipy.optimize import minimize_scalar

    z = np.asarray(signal, dtype=complex)
    z = z - z.mean()
    n = z.size
    if n < 4:
        return ()
    window = 1.0 - np.cos(2.0 * math.pi * np.arange(n) / (n - 1))
    pad = 16 * n
    grid = np.fft.fftfreq(pad)
    scale = float(np.max(np.abs(z)))
    out = []
    k = np.arange(n)
    for _ in range(lines):
        if scale == 0.0 or float(np.max(np.abs(z))) <= 1e-13 * scale:
            break
        spectrum = np.abs(np.fft.fft(window * z, pad))
        f0 = float(grid[int(np.argmax(spectrum))])
        h = 2.0 / pad
        best = minimize_scalar(
            lambda f, z=z: -abs(_amplitude(z, window, f)),
            bounds=(f0 - h, f0 + h),
            method="bounded",
            options={"xatol": 1e-13},
        )
        f = float(best.x)
        a = _amplitude(z, window, f)
        out.append((_wrap(f), abs(a)))
        z = z - a * np.exp(2j * math.pi * f * k)
    return tuple(out)


def section_frequencies(points: np.ndarray, lines: int = 3) -> Frequencies | None:
    """NAFF of the section's ``x + i y`` (its first coordinate alone if it has one) over
    the whole record and over each half; None below 16 points."""
    points = np.asarray(points, dtype=float)
    n = points.shape[0]
    if n < 16:
        return None
    z = points[:, 0] + 1j * points[:, 1] if points.shape[1] > 1 else points[:, 0].astype(complex)
    whole = refined_frequencies(z, lines)
    if not whole:
        return None
    half = n // 2
    dominant = whole[0][0]

    def matched(part: np.ndarray) -> float:
        found = refined_frequencies(part, lines)
        if not found:
            return math.nan
        strong = [f for f, a in found if a >= 0.5 * found[0][1]]  # lines of similar weight
        return min(strong, key=lambda f: abs(_wrap(f - dominant)))

    return Frequencies(whole, (matched(z[:half]), matched(z[half : 2 * half])), n)

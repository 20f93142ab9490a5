"""Full spectrum of the whirl: the FFT of the complex position w = x + i y.

Rotordynamics practice (A. Muszynska, *Rotordynamics*, 2005, ch. on full spectrum; see
docs/sweeps.md) reads the orbit of a rotor through the spectrum of the *complex* signal
``w(tau) = x + i y``: a component ``A exp(i omega tau)`` with ``omega > 0`` is a forward
whirl (in the sense of the spin), with ``omega < 0`` a backward one. A half spectrum of x
alone cannot tell them apart; the full spectrum is how a forward synchronous rub
(``+1X``) is told from a backward dry whip (a large negative component, not locked to
the running speed).

Frequencies are reported in rad per unit tau (``omega``) and as orders of the running
speed (``order = omega / eta``, "1X", "-0.3X"); the physical frequency in rad/s is
``omega * scale.omega`` for a ``[physical]`` case (``units.PhysicalScale``).

Method: the samples must be uniform in time (a Problem's ``t_eval`` is); the mean is
kept (the 0X line is a static offset), a Hann window limits leakage, the amplitudes are
divided by the window's coherent gain so that a pure whirl of radius ``A`` on a bin
shows amplitude ``A``, and the dominant peak is refined from its bin and the larger
neighbour by Grandke's Hann interpolation (exact for a lone line between bins). The
resolution is ``2 pi / T`` for a record of length ``T``: record whole forcing periods,
and many of them, to separate close lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from rubcli.solution import Solution

FORWARD = "forward"
BACKWARD = "backward"
STATIC = "static"  # the dominant line is the 0X offset (no whirl)


@dataclass(frozen=True)
class FullSpectrum:
    """Amplitudes of the whirl components of ``w = x + i y`` against frequency."""

    omega: np.ndarray = field(repr=False)  # rad per unit tau, ascending, negative = backward
    amplitude: np.ndarray = field(repr=False)  # whirl radius of each line (clearances)
    eta: float  # running speed (rad per unit tau): orders are omega / eta
    resolution: float  # bin spacing in omega
    dominant_omega: float  # refined frequency of the largest line, 0X excluded if any whirl
    dominant_amplitude: float
    direction: str  # FORWARD, BACKWARD or STATIC
    static_offset: float  # amplitude of the 0X line (the static offset of the orbit)

    @property
    def order(self) -> np.ndarray:
        """Frequencies as multiples of the running speed (1X = synchronous forward)."""
        return self.omega / self.eta

    @property
    def dominant_order(self) -> float:
        return self.dominant_omega / self.eta

    def to_dict(self, omega_scale: float | None = None) -> dict:
        """Summary for report.json; ``omega_scale`` (rad/s per rad/tau) adds rad/s."""
        out = {
            "dominant_order": self.dominant_order,
            "dominant_omega": self.dominant_omega,
            "dominant_amplitude": self.dominant_amplitude,
            "direction": self.direction,
            "static_offset": self.static_offset,
            "resolution_order": self.resolution / self.eta,
        }
        if omega_scale is not None:
            out["dominant_omega_rad_s"] = self.dominant_omega * omega_scale
        return out


def hann(n: int) -> np.ndarray:
    """The periodic Hann window of length n (its coherent gain is 1/2)."""
    return 0.5 - 0.5 * np.cos(2.0 * math.pi * np.arange(n) / n)


def full_spectrum(t: ArrayLike, w: ArrayLike, eta: float, *, floor: float = 1e-12) -> FullSpectrum:
    """The full spectrum of the complex signal ``w`` sampled at uniform times ``t``.

    ``eta`` is the running speed (orders are ``omega / eta``). The dominant line is the
    largest one away from 0X (more than one bin from it); if every such line is below
    ``floor`` times the static offset (no whirl at all), the direction is ``static``.
    Raises ValueError for fewer than 8 samples or non-uniform or non-finite input.
    """
    t = np.asarray(t, dtype=float)
    w = np.asarray(w, dtype=complex)
    n = t.size
    if n < 8 or w.shape != t.shape:
        raise ValueError("need at least 8 samples of w, one per time")
    dt = (t[-1] - t[0]) / (n - 1)
    if not dt > 0.0 or not np.allclose(np.diff(t), dt, rtol=1e-6, atol=0.0):
        raise ValueError("the samples must be uniform in time")
    if not np.all(np.isfinite(w)):
        raise ValueError("the signal is not finite")
    window = hann(n)
    coefficients = np.fft.fftshift(np.fft.fft(w * window)) / (0.5 * n)
    omega = np.fft.fftshift(np.fft.fftfreq(n, d=dt)) * 2.0 * math.pi
    amplitude = np.abs(coefficients)
    resolution = 2.0 * math.pi / (n * dt)
    zero = int(np.argmin(np.abs(omega)))
    static = float(amplitude[zero])
    away = np.abs(np.arange(n) - zero) > 1  # the 0X line and its Hann neighbours
    if not np.any(away):
        raise ValueError("too few samples to resolve any whirl")
    masked = np.where(away, amplitude, -1.0)
    peak = int(np.argmax(masked))
    if amplitude[peak] <= floor * max(static, np.finfo(float).tiny):
        return FullSpectrum(omega, amplitude, float(eta), resolution, 0.0, static, STATIC, static)
    offset, height = _refine_peak(amplitude, peak)
    dominant = float(omega[peak] + offset * resolution)
    direction = FORWARD if dominant > 0.0 else BACKWARD
    return FullSpectrum(
        omega, amplitude, float(eta), resolution, dominant, height, direction, static
    )


def _refine_peak(amplitude: np.ndarray, peak: int) -> tuple[float, float]:
    """(offset in bins, amplitude) of a line from its bin and the larger neighbour.

    Grandke's interpolation for the Hann window (IEEE Trans. Instrum. Meas. 32 (1983)
    350): with ``a`` the ratio of the larger neighbour to the peak bin, the line lies
    ``d = (2 a - 1) / (a + 1)`` bins towards that neighbour, and the window's response
    there, ``sinc(d) / (1 - d^2)``, restores its amplitude. Exact for a lone line; a peak
    at the edge of the array, or one beside a larger bin (not a local maximum), is
    returned unrefined.
    """
    b = float(amplitude[peak])
    if peak == 0 or peak == amplitude.size - 1 or b <= 0.0:
        return 0.0, b
    left, right = float(amplitude[peak - 1]), float(amplitude[peak + 1])
    if max(left, right) > b:
        # not a local maximum: the larger neighbour belongs to another line (the 0X one,
        # excluded from the search), so the two-bin interpolation does not apply (and
        # its offset would reach 1, where the window response formula divides by zero)
        return 0.0, b
    side = 1.0 if right >= left else -1.0
    ratio = max(left, right) / b
    offset = min(1.0, max(0.0, (2.0 * ratio - 1.0) / (ratio + 1.0)))
    if offset == 0.0:
        return 0.0, b
    response = math.sin(math.pi * offset) / (math.pi * offset) / (1.0 - offset * offset)
    return side * offset, b / response


def solution_spectrum(solution: Solution, transient_periods: float = 0.0) -> FullSpectrum:
    """The full spectrum of a Solution's whirl after ``transient_periods`` forcing periods.

    The record is cut to a whole number of forcing periods (so the 1X line falls on a
    bin); at least one period must remain.
    """
    problem = solution.problem
    period = problem.params.period
    t0 = float(problem.t_eval[0]) + transient_periods * period
    t = np.asarray(solution.t, dtype=float)
    whole = math.floor((t[-1] - t0) / period + 1e-9) if t.size else 0
    if whole < 1:
        raise ValueError("less than one forcing period after the transient")
    keep = (t >= t0 - 1e-9 * period) & (t < t0 + whole * period - 1e-9 * period)
    return full_spectrum(t[keep], solution.w[keep], problem.params.eta)


def default_transient(recorded_periods: float, transient_periods: float | None = None) -> float:
    """Forcing periods taken as transient in a record of ``recorded_periods``.

    ``transient_periods`` when given and shorter than the record; otherwise the first
    half of the record, rounded down to whole periods (the figures' keyphasor dots and
    the report's spectrum use the same rule).
    """
    if transient_periods is None or transient_periods >= recorded_periods:
        return float(math.floor(recorded_periods / 2.0))
    return float(transient_periods)


def steady_spectrum(
    solution: Solution, transient_periods: float | None = None
) -> FullSpectrum | None:
    """The full spectrum of a successful Solution over its steady span, or None.

    The steady span follows ``default_transient``; None for a failed run, a record of
    less than two forcing periods or a non-finite one (nothing trustworthy to analyse), and
    for a speed that changes (its orders have no one speed; ``order_tracking.order_cascade``).
    """
    if not solution.success or solution.t.size < 8 or solution.problem.changes_speed:
        return None
    period = solution.problem.params.period
    recorded = float(solution.t[-1] - solution.t[0]) / period
    if recorded < 2.0 - 1e-9:
        return None
    try:
        return solution_spectrum(solution, default_transient(recorded, transient_periods))
    except ValueError:
        return None

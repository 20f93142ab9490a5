"""Order tracking of a run whose speed changes: the 1X vector per revolution, the envelope,
the rub, and a phase-resampled full-spectrum cascade (docs/transient.md).

Inputs are plain arrays sampled at uniform times ``tau``: the position ``x``, ``y``, the
unbalance phase ``phase(tau)`` (the exact integral of the speed, strictly increasing) and
the speed ``eta(tau)``; optionally the regime codes of ``model.REGIME_NAMES`` (0 free,
nonzero in contact). Without regime codes, contact means ``z > 1``.

**Revolutions.** Revolution ``k`` holds the samples whose phase lies in
``[phase[0] + 2 pi k, phase[0] + 2 pi (k + 1))``. Only complete revolutions are tracked:
the samples after the last whole turn (less than one revolution) are left out of the
per-revolution table, though they count in the rub events and the time in each regime.
Each revolution needs at least ``MIN_SAMPLES_PER_REVOLUTION`` samples.

**Order tracking.** Per revolution, a least-squares fit of its samples to
``w = C + A_f exp(i phase) + A_b exp(-i phase)`` (``w = x + i y``): ``A_f`` is the forward
1X vector, ``A_b`` the backward one, ``C`` the static offset. Since ``exp(+-i phase)``
span the same space as ``cos phase`` and ``sin phase``, the same fit is the fit of x alone
and of y alone to ``c + a cos(phase) + b sin(phase)``: it is computed once as a real
least-squares problem with two right-hand sides. The speed of a revolution is the mean of
``eta`` over its samples (for a linear ramp, the speed at its middle time).

**Probe convention.** A probe at angle ``theta`` (x: 0, y: 90 degrees) reads
``R cos(phase - theta - lag)``: ``R`` is its 1X amplitude and ``lag`` the angle by which
its 1X peak follows the instant the unbalance points at the probe. A forward circular
whirl ``A_f exp(i phase)`` gives both probes ``R = |A_f|`` and ``lag = -arg A_f``: for the
free whirl 0 degrees well below the critical speed, 90 at it, towards 180 above. The lag
lies in [-90, 270) degrees, so that the lag of a single mode (0 to 180) never wraps.

**Changing speed.** The fit assumes constant 1X vectors over a revolution. For a linear
ramp ``eta' = a`` and a 1X vector ``A(eta)`` that follows the speed slowly, its error
against ``A`` at the revolution's mean speed is, to leading order in
``epsilon = a / eta^2`` (the relative speed change per radian of phase),

    delta A_f = epsilon^2 (pi^2/6 eta^2 A'' + 5/4 eta A')      (' = d/d eta)

(derived in docs/transient.md: the linear change of ``A`` over the window only leaks
into ``C`` and ``A_b``), plus a term of order ``epsilon eta A' / n`` for ``n`` samples per
revolution from the window not spanning exactly one turn. Both are checked in
tests/test_order_tracking.py.

**Cascade.** ``order_cascade`` resamples ``w`` uniformly in phase (a cubic spline in the
phase variable), so that a component locked to the speed (1X, 2X, 1/2X) stays on its
order bin however the speed changes; windows of whole revolutions, Hann-windowed,
amplitudes divided by the coherent gain (a pure whirl of radius ``A`` on a bin shows
``A``), orders from ``-M/2`` to ``M/2`` for ``M`` samples per revolution. A component at a
fixed *frequency* (the free whirl at 1) is spread over the orders its window sweeps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline

from rubcli.analysis.response.spectrum import hann
from rubcli.model import FREE, REGIME_NAMES

MIN_SAMPLES_PER_REVOLUTION = 8  # the fit has three unknowns; fewer samples are a sampling error
REVOLUTIONS_PER_WINDOW = 8  # cascade: order resolution 1/8, Hann main lobe +-1/4 order
SAMPLES_PER_REVOLUTION = 64  # cascade: orders from -32 to 32
WINDOW_OVERLAP = 0.5  # cascade: consecutive windows share half their revolutions
CONTACT = "contact"  # regime name when contact comes from z > 1 (no regime codes given)


@dataclass(frozen=True)
class Revolutions:
    """Per-revolution order tracking of a run: one entry per complete revolution."""

    start: np.ndarray = field(repr=False)  # index of each revolution's first sample
    stop: np.ndarray = field(repr=False)  # one past its last sample
    tau: np.ndarray = field(repr=False)  # mean time of its samples
    eta: np.ndarray = field(repr=False)  # mean speed over its samples
    offset: np.ndarray = field(repr=False)  # C: static offset of w (complex)
    forward: np.ndarray = field(repr=False)  # A_f: forward 1X vector (complex)
    backward: np.ndarray = field(repr=False)  # A_b: backward 1X vector (complex)
    x_amplitude: np.ndarray = field(repr=False)  # probe x: 1X amplitude
    x_lag_deg: np.ndarray = field(repr=False)  # probe x: 1X phase lag (degrees)
    y_amplitude: np.ndarray = field(repr=False)
    y_lag_deg: np.ndarray = field(repr=False)
    x_peak_to_peak: np.ndarray = field(repr=False)  # max - min of x over the revolution
    y_peak_to_peak: np.ndarray = field(repr=False)
    z_max: np.ndarray = field(repr=False)  # largest radius over the revolution
    contact_fraction: np.ndarray = field(repr=False)  # share of its samples in contact

    def __len__(self) -> int:
        return int(self.start.size)


@dataclass(frozen=True)
class RubEvents:
    """When the rotor touches the stator: every on/off transition and the episodes."""

    transition_tau: np.ndarray = field(repr=False)  # midway between the two samples
    transition_eta: np.ndarray = field(repr=False)  # speed there (mean of the two samples)
    transition_on: np.ndarray = field(repr=False)  # True: contact starts; False: it ends
    contact_at_start: bool
    contact_at_end: bool
    onset_tau: float | None  # first contact: first on-transition, or tau[0] if touching
    onset_eta: float | None
    end_tau: float | None  # last off-transition; None when still touching at the end
    end_eta: float | None


@dataclass(frozen=True)
class TransientSummary:
    """The numbers of report.json for a transient run (speeds as eta = Omega/omega)."""

    revolutions: int
    peak_forward_amplitude: float  # largest |A_f|
    peak_forward_eta: float
    peak_x_amplitude: float  # largest probe-x 1X amplitude
    peak_x_eta: float
    peak_z: float  # largest radius over any tracked revolution
    peak_z_eta: float
    rub_onset_eta: float | None
    rub_end_eta: float | None
    rub_transitions: int
    time_in_regime: dict[str, float]  # tau spent in each regime (names of REGIME_NAMES)

    def to_dict(self, rpm_per_eta: float | None = None) -> dict:
        """report.json entries; ``rpm_per_eta`` (a physical case) adds each speed in rpm."""
        out = {
            "method": "order tracking: least squares per revolution on the unbalance phase",
            "revolutions": self.revolutions,
            "peak_1x_forward_amplitude": self.peak_forward_amplitude,
            "peak_1x_forward_eta": self.peak_forward_eta,
            "peak_1x_x_amplitude": self.peak_x_amplitude,
            "peak_1x_x_eta": self.peak_x_eta,
            "peak_z": self.peak_z,
            "peak_z_eta": self.peak_z_eta,
            "rub_onset_eta": self.rub_onset_eta,
            "rub_end_eta": self.rub_end_eta,
            "rub_transitions": self.rub_transitions,
            "time_in_regime": dict(self.time_in_regime),
        }
        if rpm_per_eta is not None:
            for key in [k for k in out if k.endswith("_eta")]:
                value = out[key]
                out[key[:-3] + "rpm"] = None if value is None else value * rpm_per_eta
        return out


@dataclass(frozen=True)
class OrderCascade:
    """Short-time full spectra of ``w = x + i y`` in orders of the running speed."""

    order: np.ndarray = field(repr=False)  # ascending; negative = backward whirl
    eta: np.ndarray = field(repr=False)  # mean speed of each window (time average)
    tau: np.ndarray = field(repr=False)  # middle time of each window
    amplitude: np.ndarray = field(repr=False)  # (n_windows, n_orders), whirl radius
    revolutions_per_window: int


def rpm_per_eta(omega_rad_s: float) -> float:
    """rpm of a speed ratio of 1 for a rotor of natural frequency ``omega_rad_s``."""
    return omega_rad_s * 60.0 / (2.0 * math.pi)


def _checked(tau, *signals) -> tuple[np.ndarray, ...]:
    tau = np.asarray(tau, dtype=float)
    if tau.ndim != 1 or tau.size < MIN_SAMPLES_PER_REVOLUTION:
        raise ValueError("need a 1-D record of at least 8 samples")
    dt = (tau[-1] - tau[0]) / (tau.size - 1)
    if not dt > 0.0 or not np.allclose(np.diff(tau), dt, rtol=1e-6, atol=0.0):
        raise ValueError("the samples must be uniform in time")
    out = [tau]
    for s in signals:
        a = np.asarray(s, dtype=float)
        if a.shape != tau.shape or not np.all(np.isfinite(a)):
            raise ValueError("every signal needs one finite value per time")
        out.append(a)
    return tuple(out)


def revolution_bounds(phase: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(start, stop) sample indices of each complete revolution of ``phase``."""
    phase = np.asarray(phase, dtype=float)
    if np.any(np.diff(phase) <= 0.0):
        raise ValueError("the phase must increase strictly (a positive speed)")
    turns = (phase - phase[0]) / (2.0 * math.pi)
    complete = int(math.floor(turns[-1] * (1.0 + 1e-14)))
    edges = np.searchsorted(turns, np.arange(complete + 1) * (1.0 - 1e-14), side="left")
    return edges[:-1], edges[1:]


def contact_mask(x: ArrayLike, y: ArrayLike, regimes: ArrayLike | None = None) -> np.ndarray:
    """Samples in contact: a nonzero regime code, or ``z > 1`` without codes."""
    if regimes is not None:
        return np.asarray(regimes) != FREE
    return np.hypot(x, y) > 1.0


def order_track(
    tau: ArrayLike, x: ArrayLike, y: ArrayLike, phase: ArrayLike, eta: ArrayLike,
    regimes: ArrayLike | None = None,
) -> Revolutions:  # fmt: skip
    """Order tracking per revolution (module docstring): 1X vectors, probe amplitude and
    lag, envelope and contact fraction. ValueError for non-uniform times, a phase that
    does not increase, less than one revolution or fewer than 8 samples in one."""
    tau, x, y, phase, eta = _checked(tau, x, y, phase, eta)
    start, stop = revolution_bounds(phase)
    if start.size == 0:
        raise ValueError("the record holds less than one revolution")
    counts = stop - start
    if counts.min() < MIN_SAMPLES_PER_REVOLUTION:
        raise ValueError(
            f"a revolution holds {counts.min()} samples, fewer than "
            f"{MIN_SAMPLES_PER_REVOLUTION}: sample the run finer"
        )
    n = int(stop[-1])
    c, s = np.cos(phase[:n]), np.sin(phase[:n])
    basis = (np.ones(n), c, s)

    def sums(values: np.ndarray) -> np.ndarray:
        return np.add.reduceat(values, start)

    gram = np.empty((start.size, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            gram[:, i, j] = gram[:, j, i] = sums(basis[i] * basis[j])
    rhs = np.empty((start.size, 3, 2))
    for i in range(3):
        rhs[:, i, 0] = sums(basis[i] * x[:n])
        rhs[:, i, 1] = sums(basis[i] * y[:n])
    coef = np.linalg.solve(gram, rhs)  # (rev, [1, cos, sin], [x, y])
    p = coef[:, 1, 0] + 1j * coef[:, 1, 1]  # w = C + P cos + Q sin
    q = coef[:, 2, 0] + 1j * coef[:, 2, 1]
    contact = contact_mask(x[:n], y[:n], None if regimes is None else np.asarray(regimes)[:n])
    return Revolutions(
        start=start,
        stop=stop,
        tau=sums(tau[:n]) / counts,
        eta=sums(eta[:n]) / counts,
        offset=coef[:, 0, 0] + 1j * coef[:, 0, 1],
        forward=0.5 * (p - 1j * q),
        backward=0.5 * (p + 1j * q),
        x_amplitude=np.hypot(coef[:, 1, 0], coef[:, 2, 0]),
        x_lag_deg=probe_lag_deg(coef[:, 1, 0], coef[:, 2, 0], 0.0),
        y_amplitude=np.hypot(coef[:, 1, 1], coef[:, 2, 1]),
        y_lag_deg=probe_lag_deg(coef[:, 1, 1], coef[:, 2, 1], 90.0),
        x_peak_to_peak=np.maximum.reduceat(x[:n], start) - np.minimum.reduceat(x[:n], start),
        y_peak_to_peak=np.maximum.reduceat(y[:n], start) - np.minimum.reduceat(y[:n], start),
        z_max=np.maximum.reduceat(np.hypot(x[:n], y[:n]), start),
        contact_fraction=sums(contact.astype(float)) / counts,
    )


def probe_lag_deg(a: ArrayLike, b: ArrayLike, probe_angle_deg: float) -> np.ndarray:
    """Phase lag (degrees, in [-90, 270)) of a probe at ``probe_angle_deg`` reading
    ``a cos p + b sin p = R cos(p - probe_angle - lag)``."""
    lag = np.degrees(np.arctan2(b, a)) - probe_angle_deg
    return np.mod(lag + 90.0, 360.0) - 90.0


def rub_events(
    tau: ArrayLike, x: ArrayLike, y: ArrayLike, eta: ArrayLike, regimes: ArrayLike | None = None
) -> RubEvents:
    """Every change between free flight and contact over the whole record, and the onset
    (first contact) and end (last release) of the rub with the speed there."""
    tau, x, y, eta = _checked(tau, x, y, eta)
    contact = contact_mask(x, y, regimes)
    change = np.flatnonzero(contact[1:] != contact[:-1]) + 1
    t = 0.5 * (tau[change - 1] + tau[change])
    v = 0.5 * (eta[change - 1] + eta[change])
    on = contact[change]
    at_start, at_end = bool(contact[0]), bool(contact[-1])
    onset_tau = onset_eta = end_tau = end_eta = None
    if at_start:
        onset_tau, onset_eta = float(tau[0]), float(eta[0])
    elif on.any():
        first = int(np.argmax(on))
        onset_tau, onset_eta = float(t[first]), float(v[first])
    if not at_end and (~on).any():
        last = int(np.flatnonzero(~on)[-1])
        end_tau, end_eta = float(t[last]), float(v[last])
    return RubEvents(t, v, on, at_start, at_end, onset_tau, onset_eta, end_tau, end_eta)


def time_in_regimes(tau: ArrayLike, regimes: ArrayLike) -> dict[str, float]:
    """Time spent in each regime: the interval from each sample to the next counts for
    the sample's regime (so the times add up to the record's length). Keys are the names
    of ``model.REGIME_NAMES`` (an unknown code by its number), zeros included."""
    tau = np.asarray(tau, dtype=float)
    codes = np.asarray(regimes)
    if codes.shape != tau.shape:
        raise ValueError("need one regime code per time")
    dt = np.diff(tau)
    out = {name: 0.0 for name in REGIME_NAMES.values()}
    for code in np.unique(codes[:-1]):
        name = REGIME_NAMES.get(int(code), str(int(code)))
        out[name] = float(dt[codes[:-1] == code].sum())
    return out


def summarize(
    revolutions: Revolutions, events: RubEvents, time_in_regime: dict[str, float]
) -> TransientSummary:
    """The summary of report.json from the order tracking and the rub events."""
    fwd = np.abs(revolutions.forward)
    k_f = int(np.argmax(fwd))
    k_x = int(np.argmax(revolutions.x_amplitude))
    k_z = int(np.argmax(revolutions.z_max))
    return TransientSummary(
        revolutions=len(revolutions),
        peak_forward_amplitude=float(fwd[k_f]),
        peak_forward_eta=float(revolutions.eta[k_f]),
        peak_x_amplitude=float(revolutions.x_amplitude[k_x]),
        peak_x_eta=float(revolutions.eta[k_x]),
        peak_z=float(revolutions.z_max[k_z]),
        peak_z_eta=float(revolutions.eta[k_z]),
        rub_onset_eta=events.onset_eta,
        rub_end_eta=events.end_eta,
        rub_transitions=int(events.transition_on.size),
        time_in_regime=time_in_regime,
    )


def analyse_transient(
    tau: ArrayLike, x: ArrayLike, y: ArrayLike, phase: ArrayLike, eta: ArrayLike,
    regimes: ArrayLike | None = None,
) -> tuple[Revolutions, RubEvents, TransientSummary]:  # fmt: skip
    """``(Revolutions, RubEvents, TransientSummary)`` of a run; without regime codes the
    time is split into ``free`` and ``contact`` by ``z > 1``."""
    revolutions = order_track(tau, x, y, phase, eta, regimes)
    events = rub_events(tau, x, y, eta, regimes)
    if regimes is None:
        contact = contact_mask(np.asarray(x), np.asarray(y))
        times = time_in_regimes(tau, contact.astype(int))
        times = {"free": times["free"], CONTACT: times["slip+"]}
    else:
        times = time_in_regimes(tau, regimes)
    return revolutions, events, summarize(revolutions, events, times)


def order_cascade(
    tau: ArrayLike,
    x: ArrayLike,
    y: ArrayLike,
    phase: ArrayLike,
    *,
    revolutions_per_window: int = REVOLUTIONS_PER_WINDOW,
    samples_per_revolution: int = SAMPLES_PER_REVOLUTION,
    overlap: float = WINDOW_OVERLAP,
) -> OrderCascade:
    """Short-time full spectra of ``w = x + i y`` resampled uniformly in phase (module
    docstring). Windows of ``revolutions_per_window`` whole revolutions from the first
    sample, consecutive ones ``overlap`` apart (a share of the window); a trailing part
    shorter than a window is left out. ValueError when not one window fits."""
    tau, x, y, phase = _checked(tau, x, y, phase)
    if np.any(np.diff(phase) <= 0.0):
        raise ValueError("the phase must increase strictly (a positive speed)")
    m, n_rev = int(samples_per_revolution), int(revolutions_per_window)
    if m < 8 or n_rev < 1 or not 0.0 <= overlap < 1.0:
        raise ValueError("need 8 or more samples and 1 or more revolutions per window")
    step = 2.0 * math.pi / m
    count = int(math.floor((phase[-1] - phase[0]) / step * (1.0 + 1e-14))) + 1
    grid = phase[0] + step * np.arange(count)
    w = CubicSpline(phase, x + 1j * y)(grid)
    size = n_rev * m
    hop = max(1, int(round((1.0 - overlap) * n_rev)) * m)
    starts = np.arange(0, count - size, hop)  # each window's end point on the grid
    if starts.size == 0:
        raise ValueError(f"the record holds fewer than {n_rev} revolutions")
    window = hann(size)
    blocks = w[starts[:, None] + np.arange(size)]
    spectra = np.fft.fftshift(np.fft.fft(blocks * window, axis=1), axes=1) / (0.5 * size)
    order = np.fft.fftshift(np.fft.fftfreq(size, d=1.0 / m))
    t0 = np.interp(grid[starts], phase, tau)
    t1 = np.interp(grid[starts] + n_rev * 2.0 * math.pi, phase, tau)
    return OrderCascade(
        order=order,
        eta=n_rev * 2.0 * math.pi / (t1 - t0),
        tau=0.5 * (t0 + t1),
        amplitude=np.abs(spectra),
        revolutions_per_window=n_rev,
    )

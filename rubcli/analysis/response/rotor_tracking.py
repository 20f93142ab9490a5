"""A rotor's run-up, tracked per revolution (``studies.rotor_runup`` computes it): each
probe's 1X and the linear response's beside, each station's largest distance and contact,
each probe node's full-spectrum cascade and the lowest natural frequencies, SI and rpm;
and report.json's ``runup`` entry (``RotorRunup.to_dict``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rubcli.analysis.response.order_tracking import OrderCascade


@dataclass(frozen=True)
class ProbeTrack:
    """One probe's 1X per revolution: amplitude (m), lag (degrees), peak to peak (m); its
    linear 1X amplitude and lag at ``RotorRunup.linear_rpm``."""

    name: str
    node: int
    angle: float  # rad
    amplitude: np.ndarray = field(repr=False)
    lag_deg: np.ndarray = field(repr=False)
    peak_to_peak: np.ndarray = field(repr=False)
    linear_amplitude: np.ndarray = field(repr=False)
    linear_lag_deg: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class StationTrack:
    """One station's largest distance per revolution (clearances), its share of each
    revolution in contact and its rub's onset and end (rpm; None: none)."""

    name: str
    node: int
    largest: np.ndarray = field(repr=False)
    contact_share: np.ndarray = field(repr=False)
    onset_rpm: float | None
    end_rpm: float | None


@dataclass(frozen=True)
class RotorRunup:
    """A run-up's tracking: per revolution its mean time (s) and speed (rpm), the probes'
    and stations' tracks; the linear response's speeds; each probe node's cascade; the
    lowest natural frequencies (Hz) at ``mode_rpm``."""

    t: np.ndarray = field(repr=False)
    rpm: np.ndarray = field(repr=False)
    probes: tuple[ProbeTrack, ...]
    stations: tuple[StationTrack, ...]
    linear_rpm: np.ndarray = field(repr=False)
    cascades: tuple[tuple[str, OrderCascade], ...]  # (the probes at a node, cascade)
    mode_rpm: np.ndarray = field(repr=False)
    mode_hz: np.ndarray = field(repr=False)  # (speeds, modes) the lowest damped frequencies

    def to_dict(self) -> dict[str, Any]:
        """report.json's ``runup`` entry."""
        probes = {}
        for track in self.probes:
            k = int(np.argmax(track.amplitude))
            j = int(np.argmax(track.linear_amplitude))
            probes[track.name] = {
                "peak_1x_m": float(track.amplitude[k]),
                "peak_1x_rpm": float(self.rpm[k]),
                "largest_peak_to_peak_m": float(np.max(track.peak_to_peak)),
                "linear_peak_1x_m": float(track.linear_amplitude[j]),
                "linear_critical_rpm": float(self.linear_rpm[j]),
            }
        stations = {
            s.name: {
                "largest_clearances": float(np.max(s.largest)),
                "largest_rpm": float(self.rpm[int(np.argmax(s.largest))]),
                "rub_onset_rpm": s.onset_rpm,
                "rub_end_rpm": s.end_rpm,
                "revolutions_in_contact": int(np.count_nonzero(s.contact_share > 0.0)),
            }
            for s in self.stations
        }
        return {
            "method": "order tracking per revolution on the spin angle; the linear response "
            "without contact at each speed beside",
            "revolutions": int(self.rpm.size),
            "probes": probes,
            "stations": stations,
        }

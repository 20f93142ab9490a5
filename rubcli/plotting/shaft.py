"""The shaft view of a finite-element rotor (SI): where it rubs along its axis.

Above, the shaft's outline (its outer radius at each node, mm) with its disks, bearings,
contact stations and probes marked; below, on the same axial positions, the deflection
envelope: each node's largest radial deflection over the whole run (a wide faint band)
and over its last quarter (the steady part, a strong line on it), in micrometres, with
each station's clearance marked at its node, so a reader sees which stations the
envelope reaches."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

MICRO = 1e6
MILLI = 1e3


@dataclass(frozen=True)
class Marked:
    """A named node on the shaft (a station with its clearance in m, or a probe)."""

    name: str
    node: int
    clearance: float | None = None


def shaft_figure(
    title: str,
    positions: np.ndarray,
    radii: np.ndarray,
    disks: Sequence[int],
    bearings: Sequence[int],
    stations: Sequence[Marked],
    probes: Sequence[Marked],
    envelope_all: np.ndarray,
    envelope_last: np.ndarray,
) -> Figure:
    """The shaft view (module docstring); positions (nan: a node off the shaft, not
    drawn), radii and envelopes a node, m."""
    fig = Figure(figsize=(10.0, 6.4), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(title)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(1.0, 2.0))
    shaft = np.isfinite(positions)
    stations = [m for m in stations if shaft[m.node]]
    probes = [m for m in probes if shaft[m.node]]
    x = positions  # indexed by node; the lines below run over the shaft's nodes only
    r = np.where(shaft, radii, np.nan) * MILLI
    top.fill_between(x[shaft], -r[shaft], r[shaft], color="0.8", label="shaft (outer radius)")
    top.plot(x[shaft], r[shaft], color="0.4", linewidth=0.8)
    top.plot(x[shaft], -r[shaft], color="0.4", linewidth=0.8)
    reach = max(float(np.max(r[shaft], initial=0.0)), 1e-3)
    if disks:
        top.plot(x[list(disks)], np.zeros(len(disks)), linestyle="none", marker="s",
                 markersize=11, color="0.25", label="disk")  # fmt: skip
    if bearings:
        top.plot(x[list(bearings)], np.full(len(bearings), -1.35 * reach), linestyle="none",
                 marker="^", markersize=10, color="tab:brown", label="bearing")  # fmt: skip
    for k, station in enumerate(stations):
        top.axvline(x[station.node], color="tab:red", linewidth=1.2,
                    label="contact station" if k == 0 else None)  # fmt: skip
        top.annotate(station.name, (x[station.node], 1.45 * reach), ha="center",
                     fontsize=8, color="tab:red")  # fmt: skip
    for k, probe in enumerate(probes):
        top.plot([x[probe.node]], [1.2 * reach], linestyle="none", marker="D", markersize=6,
                 color="tab:green", label="probe" if k == 0 else None)  # fmt: skip
    top.set_ylim(-1.7 * reach, 1.8 * reach)
    top.set_ylabel("radius (mm)")
    top.set_title("the rotor: shaft, disks, bearings, stations and probes", fontsize="medium")
    top.grid(True, linewidth=0.3)
    top.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)

    # the whole run as a wide band behind: it shows where the last quarter reaches it too
    bottom.plot(x[shaft], envelope_all[shaft] * MICRO, color="tab:blue", alpha=0.25,
                linewidth=7.0, solid_capstyle="round", label="whole run (wide band)")  # fmt: skip
    bottom.plot(x[shaft], envelope_last[shaft] * MICRO, color="tab:blue", linewidth=1.6,
                marker="o", markersize=3, label="last quarter of the run")  # fmt: skip
    for k, station in enumerate(stations):
        c = station.clearance * MICRO
        length = float(np.max(x[shaft]) - np.min(x[shaft]))
        span = 0.015 * (length if length > 0.0 else 1.0)
        bottom.plot([x[station.node] - span, x[station.node] + span], [c, c], color="tab:red",
                    linewidth=2.5, label="clearance at a station" if k == 0 else None)  # fmt: skip
        bottom.annotate(station.name, (x[station.node], c), xytext=(0, 5), ha="center",
                        textcoords="offset points", fontsize=8, color="tab:red")  # fmt: skip
    for probe in probes:
        bottom.axvline(x[probe.node], color="tab:green", linewidth=0.8, linestyle=":")
    bottom.set_ylim(0.0, None)
    bottom.set_xlabel("axial position (m)")
    bottom.set_ylabel("largest radial deflection (µm)")
    bottom.set_title("deflection envelope (probes dotted)", fontsize="medium")
    bottom.grid(True, linewidth=0.3)
    bottom.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    return fig

"""The shaft view of a finite-element rotor (SI): where it rubs along its axis.

Above, the shaft's outline (its outer radius at each node, mm) with its disks, bearings,
contact stations and probes marked; below, on the same axial positions, the deflection
envelope: each node's largest radial deflection over the whole run (a wide faint band)
and over its last quarter (the steady part, a strong line on it), in micrometres, with
each station's clearance marked at its node, so a reader sees which stations the
envelope reaches. ``shapes_figure``: the deflected shape at chosen instants."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

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


def shapes_figure(
    title: str,
    positions: np.ndarray,
    times: Sequence[float],
    shapes: np.ndarray,
    stations: Sequence[Marked],
    offsets: Sequence[tuple[float, float]],
) -> Figure:
    """The deflected shape at chosen instants: each node's x (upper panel) and y (lower)
    deflection (µm) along the shaft at each time of ``times``, ``shapes`` (instants,
    nodes, 2) in m; each station's wall, its stator's centre plus and minus its
    clearance, marked at its node (``offsets``: the centres, m)."""
    fig = Figure(figsize=(10.0, 6.8), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(f"{title}\nevery node's x and y at the sample nearest each instant")
    axes = fig.subplots(2, 1, sharex=True, sharey=True)
    shaft = np.isfinite(positions)
    x = positions[shaft]
    colours = [f"C{k % 10}" for k in range(len(times))]
    for j, (ax, name) in enumerate(zip(axes, ("x", "y"), strict=True)):
        for k, t in enumerate(times):
            ax.plot(x, MICRO * shapes[k, shaft, j], color=colours[k], marker="o", markersize=2.5,
                    linewidth=1.4, label=f"t = {t:.6g} s")  # fmt: skip
        ax.axhline(0.0, color="0.6", linewidth=0.8, zorder=1)
        for station, centre in zip(stations, offsets, strict=True):
            if not shaft[station.node]:
                continue
            at = positions[station.node]
            for side in (-1.0, 1.0):
                wall = MICRO * (centre[j] + side * station.clearance)
                ax.plot([at], [wall], marker="_", markersize=18, markeredgewidth=2.0,
                        color="0.1", linestyle="none", zorder=4)  # fmt: skip
            ax.annotate(station.name, (at, MICRO * (centre[j] + station.clearance)),
                        xytext=(0, 6), textcoords="offset points", ha="center",
                        fontsize="small", color="0.1")  # fmt: skip
        ax.set_ylabel(f"deflection {name} (µm)")
        ax.grid(True, alpha=0.3)
    axes[1].set_xlabel("axial position (m)")
    handles, labels = axes[0].get_legend_handles_labels()
    handles.append(Line2D([], [], marker="_", markersize=14, markeredgewidth=2.0,
                          color="0.1", linestyle="none"))  # fmt: skip
    labels.append("station's wall: its stator's centre +- clearance")
    fig.legend(handles, labels, loc="outside lower center", ncols=min(4, len(labels)),
               fontsize="small")  # fmt: skip
    return fig

"""The orbit at each contact station of a machine given as matrices (SI): the rotor
point's position relative to the stator's centre, in micrometres, inside its clearance
circle; the start faint, the last revolutions (the steady state, if the run reached one)
drawn strong, the samples in contact marked. One panel per station, on one scale each
(its own clearance), so a reader sees at a glance where and how deep it rubs; then one
per probe: its node's orbit about the bearing line, with the probe's direction."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

MICRO = 1e6
LAST_SHARE = 0.25  # the last quarter of the run is drawn as its steady part


@dataclass(frozen=True)
class StationOrbit:
    """One station's relative orbit (k, 2) in m, its clearance (m), which samples are in
    contact (k,), and its label; a probe's: its node's orbit, no clearance and no
    contact, and its ``direction`` (rad)."""

    label: str
    relative: np.ndarray
    clearance: float | None
    contact: np.ndarray | None
    direction: float | None = None


def station_orbits_figure(
    title: str, orbits: Sequence[StationOrbit], t: np.ndarray, revolutions: float
) -> Figure:
    """The orbit of every station, side by side."""
    count = len(orbits)
    fig = Figure(figsize=(4.8 * count + 0.6, 6.0), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(title)
    last = max(1, int(round(LAST_SHARE * t.size)))
    start_s = float(t[-last]) if t.size else 0.0
    last_revolutions = revolutions * LAST_SHARE
    handles: dict[str, object] = {}
    # the probes' panels on one scale, so that their orbits compare at a glance
    probe_size = max(
        (1.05 * MICRO * float(np.max(np.hypot(*o.relative.T), initial=0.0))
         for o in orbits if o.clearance is None), default=0.0,
    )  # fmt: skip
    for i, orbit in enumerate(orbits):
        ax = fig.add_subplot(1, count, i + 1)
        xy = orbit.relative * MICRO
        size = 1.05 * float(np.max(np.hypot(xy[:, 0], xy[:, 1]), initial=0.0))
        if orbit.clearance is None:
            size = probe_size
        if orbit.clearance is not None:
            c = orbit.clearance * MICRO
            circle = np.linspace(0.0, 2.0 * np.pi, 361)
            ax.plot(c * np.cos(circle), c * np.sin(circle), color="0.3", linestyle="--",
                    linewidth=1.0, label="clearance circle")  # fmt: skip
            size = max(size, 1.15 * c)
        if orbit.direction is not None:
            d = np.array([np.cos(orbit.direction), np.sin(orbit.direction)]) * size
            ax.plot([-d[0], d[0]], [-d[1], d[1]], color="tab:green", linewidth=1.0,
                    label="probe direction")  # fmt: skip
        ax.plot(xy[:-last, 0], xy[:-last, 1], color="tab:blue", alpha=0.25, linewidth=0.6,
                label=f"start (t < {start_s:.3g} s)")  # fmt: skip
        ax.plot(xy[-last:, 0], xy[-last:, 1], color="tab:blue", linewidth=1.2,
                label=f"last {last_revolutions:.3g} revolutions")  # fmt: skip
        ax.set_xlim(-size, size)
        ax.set_ylim(-size, size)
        ax.set_aspect("equal")
        if orbit.contact is not None:
            touching = np.zeros(len(xy), dtype=bool)
            touching[-last:] = orbit.contact[-last:]
            share = float(np.mean(orbit.contact[-last:]))
            ax.plot(xy[touching, 0], xy[touching, 1], linestyle="none", marker="o",
                    markersize=2.0, color="tab:red", label="in contact")  # fmt: skip
            ax.set_title(f"{orbit.label}\nclearance {c:.4g} µm; in contact {100 * share:.3g} % "
                         f"of the last {last_revolutions:.3g} revolutions",
                         fontsize="medium")  # fmt: skip
            ax.set_xlabel("x relative to the stator's centre (µm)")
            ax.set_ylabel("y relative to the stator's centre (µm)")
        else:
            along = xy[-last:] @ np.array([np.cos(orbit.direction), np.sin(orbit.direction)])
            ax.set_title(f"{orbit.label}\n{np.ptp(along):.4g} µm peak to peak along it over the "
                         f"last {last_revolutions:.3g} revolutions", fontsize="medium")  # fmt: skip
            ax.set_xlabel("x relative to the bearing line (µm)")
            ax.set_ylabel("y relative to the bearing line (µm)")
        ax.grid(True, linewidth=0.3)
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    # every entry of every panel once: four in a row where the panels are wide enough
    fig.legend(list(handles.values()), list(handles), loc="outside lower center",
               ncol=min(len(handles), 4 if count > 1 else 2))  # fmt: skip
    return fig


@dataclass(frozen=True)
class Trace:
    """A signal against time for the time traces: its label, values (k,) in m, and,
    for a station, its clearance (m) and which samples are in contact."""

    label: str
    values: np.ndarray
    clearance: float | None = None
    contact: np.ndarray | None = None


def traces_figure(title: str, t: np.ndarray, stations: Sequence[Trace],
                  probes: Sequence[Trace]) -> Figure:  # fmt: skip
    """Time traces: each station's distance from its stator's centre with its clearance
    (samples in contact marked), then each probe's reading; micrometres against seconds,
    one shared time axis."""
    rows = 1 + (1 if probes else 0)
    fig = Figure(figsize=(10.0, 3.2 * rows + 0.8), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(title)
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    ax = axes[0]
    # red marks contact: the signals take the other colours of the cycle
    colors = [f"C{c}" for c in (0, 1, 2, 4, 5, 6, 8, 9)]
    for k, trace in enumerate(stations):
        color = colors[k % len(colors)]
        ax.plot(t, trace.values * MICRO, color=color, linewidth=0.9, label=trace.label)
        ax.axhline(trace.clearance * MICRO, color=color, linestyle="--", linewidth=1.0,
                   label=f"{trace.label}: clearance")  # fmt: skip
        touching = trace.contact
        ax.plot(t[touching], trace.values[touching] * MICRO, linestyle="none", marker="o",
                markersize=2.0, color="tab:red",
                label="in contact" if k == 0 else None)  # fmt: skip
    ax.set_ylabel("distance from the stator's centre (µm)")
    ax.set_title("contact stations", fontsize="medium")
    if probes:
        bottom = axes[1]
        for k, trace in enumerate(probes):
            bottom.plot(t, trace.values * MICRO, color=colors[(k + len(stations)) % len(colors)],
                        linewidth=0.9, label=trace.label)  # fmt: skip
        bottom.set_ylabel("probe reading (µm)")
        bottom.set_title("probes", fontsize="medium")
    for a in axes:
        a.grid(True, linewidth=0.3)
        a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1].set_xlabel("time (s)")
    return fig

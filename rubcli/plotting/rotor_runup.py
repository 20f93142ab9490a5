"""Figures of a rotor case's run-up or coast-down (``studies.rotor_runup``), speed in rpm
on the x-axis, lengths in micrometres:

- ``bode_figure`` (bode.png): each probe's 1X amplitude and phase lag per revolution
  over its linear response without contact, each station's largest distance from its
  stator's centre (in clearances) and its share of each revolution in contact; the
  revolutions in contact shaded, the linear critical speed marked;
- ``polar_figure`` (polar.png): each probe's 1X vector, one panel a probe on one scale,
  round speeds labelled;
- ``cascade_figure`` (cascade.png): the full spectrum of each probe's node against
  speed, the orders 1X, 2X, 1/2X, -1X and the lowest natural frequencies marked.

Agg canvas, no pyplot; save with ``rubcli.io.save_figure``.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from rubcli.analysis.response.rotor_tracking import RotorRunup
from rubcli.plotting import display
from rubcli.plotting.cascade import CMAP, DYNAMIC_RANGE_DB, LARGE, SMALL, cascade_points
from rubcli.plotting.run import _new_figure
from rubcli.plotting.transient import ORDER_LINES, RUB_SHADE, TRACKING_NOTE, polar_labels

MICRO = 1e6
RPM_LABEL = "speed (rpm)"
COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink")
MAX_ORDER = 4.0  # the cascade's order axis: +- this


def _colour(k: int) -> str:
    return COLOURS[k % len(COLOURS)]


def _contact_spans(runup: RotorRunup) -> list[tuple[float, float]]:
    """Speed spans of consecutive revolutions with contact at any station."""
    if not runup.stations:
        return []
    touching = np.any([s.contact_share > 0.0 for s in runup.stations], axis=0)
    rpm = runup.rpm
    spans, start = [], None
    half = 0.5 * float(np.median(np.abs(np.diff(rpm)))) if rpm.size > 1 else 0.0
    for k, on in enumerate(touching):
        if on and start is None:
            start = k
        if start is not None and (not on or k == touching.size - 1):
            stop = k if on else k - 1
            lo, hi = sorted((float(rpm[start]), float(rpm[stop])))
            spans.append((lo - half, hi + half))
            start = None
    return spans


def _critical(runup: RotorRunup) -> float | None:
    if not runup.probes:
        return None
    track = runup.probes[0]
    return float(runup.linear_rpm[int(np.argmax(track.linear_amplitude))])


def _mark(ax, runup: RotorRunup) -> None:
    for lo, hi in _contact_spans(runup):
        ax.axvspan(lo, hi, **RUB_SHADE)
    critical = _critical(runup)
    if critical is not None:
        ax.axvline(critical, color="0.35", ls=":", lw=1.0, zorder=1)


def bode_figure(title: str, runup: RotorRunup) -> Figure:
    """The Bode plot (module docstring)."""
    fig = _new_figure(12.5, 8.6)
    (amp, dist), (lag, share) = fig.subplots(2, 2, sharex=True)
    for k, track in enumerate(runup.probes):
        colour = _colour(k)
        label = f"{track.name} (node {track.node}, "
        label += f"{math.degrees(track.angle):.4g} deg)"
        amp.plot(runup.rpm, MICRO * track.amplitude, color=colour, lw=1.5, label=label, zorder=3)
        amp.plot(runup.linear_rpm, MICRO * track.linear_amplitude, color=colour, lw=0.9,
                 ls="--", zorder=2)  # fmt: skip
        lag.plot(runup.rpm, track.lag_deg, color=colour, lw=1.5, zorder=3)
        lag.plot(runup.linear_rpm, track.linear_lag_deg, color=colour, lw=0.9, ls="--", zorder=2)
    top = max((float(np.max(t.amplitude)) for t in runup.probes), default=0.0)
    amp.set_ylim(0.0, 1.15 * MICRO * top if top > 0 else 1.0)  # the linear peak may be far above
    amp.set_ylabel("1X amplitude (µm)")
    amp.set_title("probe 1X amplitude (linear response dashed, clipped)", fontsize="medium")
    lag.set_ylim(-90.0, 270.0)
    lag.set_yticks(np.arange(-90.0, 271.0, 45.0))
    lag.set_ylabel("1X phase lag (degrees)")
    lag.set_title("probe 1X phase lag behind the unbalance", fontsize="medium")
    for k, station in enumerate(runup.stations):
        colour = _colour(len(runup.probes) + k)
        label = f"station {station.name} (node {station.node})"
        dist.plot(runup.rpm, station.largest, color=colour, lw=1.5, label=label)
        share.plot(runup.rpm, station.contact_share, color=colour, lw=1.5)
    dist.axhline(1.0, label="clearance", **display.CLEARANCE_STYLE)
    largest = max((float(np.max(s.largest)) for s in runup.stations), default=1.0)
    dist.set_ylim(0.0, 1.08 * max(1.0, largest))
    dist.set_ylabel("distance from the stator's centre (clearances)")
    dist.set_title("largest distance per revolution at each station", fontsize="medium")
    share.set_ylim(-0.03, 1.03)
    share.set_ylabel("share of the revolution (-)")
    share.set_title("time in contact per revolution", fontsize="medium")
    for ax in (amp, dist, lag, share):
        _mark(ax, runup)
        ax.grid(True, alpha=0.3)
    for ax in (lag, share):
        ax.set_xlabel(RPM_LABEL)
    handles, labels = [], []
    for ax in (amp, dist):
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.append(h)
            labels.append(lab)
    handles.append(Line2D([], [], color="0.3", lw=0.9, ls="--"))
    labels.append("linear response, no contact (steady at each speed)")
    critical = _critical(runup)
    if critical is not None:
        handles.append(Line2D([], [], color="0.35", ls=":", lw=1.0))
        labels.append(
            f"critical speed of the linear response at {runup.probes[0].name}: {critical:.0f} rpm"
        )
    if _contact_spans(runup):
        handles.append(Patch(**{k: v for k, v in RUB_SHADE.items() if k != "zorder"}))
        labels.append("revolutions in contact")
    fig.legend(handles, labels, loc="outside lower center", ncols=3, fontsize="small")
    fig.suptitle(f"{title}: Bode plot\n{TRACKING_NOTE}", fontsize="medium")
    return fig


def polar_figure(title: str, runup: RotorRunup) -> Figure:
    """The polar plot (module docstring): ``A e^{-i lag}``, in phase with the unbalance
    along +Re; a lag draws clockwise."""
    count = max(1, len(runup.probes))
    rpm = runup.rpm
    norm = Normalize(float(rpm.min()), float(rpm.max()) if rpm.max() > rpm.min() else rpm.min() + 1)
    vectors = [MICRO * t.amplitude * np.exp(-1j * np.radians(t.lag_deg)) for t in runup.probes]
    reach = max((float(np.max(np.abs(v))) for v in vectors), default=1.0) or 1.0
    # one box for every panel: the origin and every probe's curve, with a margin
    every = np.concatenate([[0.0], *vectors])
    pad = 0.12 * reach
    box_x = (float(every.real.min()) - pad, float(every.real.max()) + pad)
    box_y = (float(every.imag.min()) - pad, float(every.imag.max()) + pad)
    ratio = (box_y[1] - box_y[0]) / (box_x[1] - box_x[0])
    fig = _new_figure(4.6 * count + 1.4, max(3.6, 4.2 * min(ratio, 1.6) + 1.8))
    axes = np.atleast_1d(fig.subplots(1, count))
    line = None
    for ax, track, vector in zip(axes, runup.probes, vectors, strict=False):
        points = np.column_stack((vector.real, vector.imag))
        segments = np.stack((points[:-1], points[1:]), axis=1)
        line = LineCollection(segments, cmap="viridis", norm=norm, linewidths=1.8, zorder=3)
        line.set_array(0.5 * (rpm[:-1] + rpm[1:]))
        ax.add_collection(line)
        ax.plot([0.0], [0.0], "+", color="0.3", ms=10, zorder=2)
        for k, tick in polar_labels(vector, rpm, 2.0 * reach):
            ax.plot(vector.real[k], vector.imag[k], "o", color="k", ms=3.5, zorder=4)
            left = vector.real[k] < 0.0
            ax.annotate(f"{tick:.0f} rpm", (vector.real[k], vector.imag[k]),
                        xytext=(-5 if left else 5, 4), textcoords="offset points",
                        ha="right" if left else "left", fontsize="x-small", zorder=5)  # fmt: skip
        ax.set_xlim(*box_x)
        ax.set_ylim(*box_y)
        ax.set_aspect("equal")
        ax.axhline(0.0, color="0.85", lw=0.8, zorder=1)
        ax.axvline(0.0, color="0.85", lw=0.8, zorder=1)
        ax.set_title(f"{track.name} (node {track.node}, "
                     f"{math.degrees(track.angle):.4g} deg)", fontsize="medium")  # fmt: skip
        ax.set_xlabel("in phase with the unbalance (µm)")
        ax.set_ylabel("90 degrees ahead of it (µm)")
        ax.grid(True, alpha=0.3)
    if line is not None:
        fig.colorbar(line, ax=list(axes), label=RPM_LABEL, shrink=0.8)
    fig.suptitle(f"{title}: polar plot of the probes' 1X\n{TRACKING_NOTE}", fontsize="medium")
    return fig


def cascade_figure(title: str, runup: RotorRunup) -> Figure:
    """The full-spectrum cascades (module docstring), one panel a probe's node, on one
    colour scale (dB of the largest line of all)."""
    count = max(1, len(runup.cascades))
    fig = _new_figure(6.2 * count + 1.2, 6.6)
    axes = np.atleast_1d(fig.subplots(1, count, sharey=True))
    reference = max((float(np.max(c.amplitude)) for _, c in runup.cascades), default=0.0)
    norm = Normalize(-DYNAMIC_RANGE_DB, 0.0)
    artist = None
    for ax, (label, cascade) in zip(axes, runup.cascades, strict=False):
        inside = np.abs(cascade.order) <= MAX_ORDER
        speed = cascade.eta * 60.0 / (2.0 * math.pi)  # rad/s -> rpm
        orders, speeds, db = cascade_points(cascade.order[inside], speed,
                                            cascade.amplitude[:, inside], reference,
                                            DYNAMIC_RANGE_DB)  # fmt: skip
        ax.axhspan(-MAX_ORDER, 0.0, color="0.95", zorder=0)
        if orders.size:
            shares = np.clip((db + DYNAMIC_RANGE_DB) / DYNAMIC_RANGE_DB, 0.0, 1.0)
            rank = np.argsort(db)
            sizes = (SMALL + (LARGE - SMALL) * shares) ** 2
            artist = ax.scatter(speeds[rank], orders[rank], s=sizes[rank], c=db[rank],
                                cmap=CMAP, norm=norm, linewidths=0, zorder=4)  # fmt: skip
        for value, name in ORDER_LINES.items():
            ax.axhline(value, color="0.45", ls=":", lw=0.9, zorder=2)
            ax.annotate(name, (1.0, value), xycoords=("axes fraction", "data"), xytext=(4, 0),
                        textcoords="offset points", va="center", fontsize="small",
                        color="0.3")  # fmt: skip
        for j in range(runup.mode_hz.shape[1]):
            order = runup.mode_hz[:, j] * 60.0 / runup.mode_rpm
            for sign in (1.0, -1.0):
                keep = np.abs(order) <= MAX_ORDER
                ax.plot(runup.mode_rpm[keep], sign * order[keep], color="tab:red", ls="--",
                        lw=1.0, zorder=3)  # fmt: skip
        ax.set_ylim(-MAX_ORDER, MAX_ORDER)
        ax.set_xlim(float(runup.rpm.min()), float(runup.rpm.max()))
        ax.set_xlabel(RPM_LABEL)
        ax.set_title(label, fontsize="medium")
        ax.grid(True, alpha=0.25)
    axes[0].set_ylabel("whirl order (multiples of the speed; < 0 backward, shaded)")
    if not runup.cascades:
        axes[0].text(0.5, 0.5, "fewer revolutions than a cascade window", ha="center",
                     va="center", transform=axes[0].transAxes)  # fmt: skip
    if artist is not None:
        fig.colorbar(artist, ax=list(axes), pad=0.02,
                     label=f"level, dB of the largest line ({MICRO * reference:.3g} µm);"
                     f"\nlines below -{DYNAMIC_RANGE_DB:g} dB not drawn")  # fmt: skip
    handles = [
        Line2D([], [], color="tab:red", ls="--", lw=1.0,
               label=f"the {runup.mode_hz.shape[1]} lowest natural frequencies (linear, no "
               "contact) as orders +-f / speed"),
        Line2D([], [], color="0.45", ls=":", lw=0.9, label="orders 1X, 2X, 1/2X, -1X"),
    ]  # fmt: skip
    fig.legend(handles=handles, loc="outside lower center", ncols=2, fontsize="small")
    windows = runup.cascades[0][1].revolutions_per_window if runup.cascades else 0
    fig.suptitle(f"{title}: full-spectrum cascade of x + i y at the probes' nodes\n"
                 f"resampled in the spin angle; windows of {windows} revolutions, Hann",
                 fontsize="medium")  # fmt: skip
    return fig

"""Figures of a run whose speed changes, speed on the x-axis (docs/transient.md):

- ``bode_figure`` (bode.png): 1X amplitude and phase lag per revolution, beside the
  peak-to-peak envelope, the largest radius and the contact fraction, rub marked;
- ``polar_figure`` (polar.png): the forward and backward 1X vectors, speeds labelled;
- ``cascade_figure`` (cascade.png): the phase-resampled full spectrum against speed, the
  orders 1X, 2X, 1/2X, -1X, the free whirl and the dry-whip line marked;
- ``orbit_snapshots_figure`` (orbits.png): one revolution of the orbit at a few speeds.

They only draw what ``rubcli.analysis.response.order_tracking`` computed (Agg canvas, no pyplot;
save with ``rubcli.io.save_figure``). Speeds are ``eta = Omega / omega``, or rpm when
``speed_unit="rpm"`` with ``rpm_per_eta`` (``order_tracking.rpm_per_eta``); lengths are
in clearances.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from numpy.typing import ArrayLike

from rubcli import model
from rubcli.analysis.response.order_tracking import OrderCascade, Revolutions, RubEvents
from rubcli.plotting import display
from rubcli.plotting.cascade import CMAP, DYNAMIC_RANGE_DB, LARGE, SMALL, cascade_points
from rubcli.plotting.run import _new_figure

ETA_LABEL = "speed eta = Omega / omega (-)"
RPM_LABEL = "speed (rpm)"
TRACKING_NOTE = "1X by order tracking: least squares over each revolution on the unbalance phase"
RUB_COLOUR = "tab:red"
RUB_SHADE = {"color": "tab:red", "alpha": 0.08, "linewidth": 0, "zorder": 0}
PROBE_STYLES = {  # x and y coincide for a circular whirl: a thick light line under a thin one
    "x": {"color": "tab:blue", "linewidth": 2.6, "alpha": 0.5, "zorder": 2},
    "y": {"color": "tab:orange", "linewidth": 1.0, "linestyle": (0, (4, 2)), "zorder": 3},
}
ORDER_LINES = {1.0: "1X", 2.0: "2X", 0.5: "1/2X", -1.0: "-1X"}
MIN_ORDER_RANGE = 2.5  # cascade: the order axis spans at least +-this
LINE_LEVEL_DB = -40.0  # cascade: lines within this of the largest set the order range
POLAR_LABELS = 8  # polar: about this many speeds labelled along each curve


@dataclass(frozen=True)
class SpeedAxis:
    """How speeds are shown: ``factor * eta`` under ``label``."""

    factor: float
    label: str
    unit: str  # "eta" or "rpm", for titles

    def __call__(self, eta):
        return np.asarray(eta, dtype=float) * self.factor

    def text(self, eta: float) -> str:
        value = float(eta) * self.factor
        return f"{value:.0f} rpm" if self.unit == "rpm" else f"eta = {value:.3g}"


def speed_axis(speed_unit: str = "eta", rpm_per_eta: float | None = None) -> SpeedAxis:
    """The speed axis: ``"eta"`` (nondimensional) or ``"rpm"`` (needs ``rpm_per_eta``)."""
    if speed_unit == "eta":
        return SpeedAxis(1.0, ETA_LABEL, "eta")
    if speed_unit == "rpm":
        if rpm_per_eta is None or not rpm_per_eta > 0:
            raise ValueError("speed_unit='rpm' needs rpm_per_eta > 0")
        return SpeedAxis(float(rpm_per_eta), RPM_LABEL, "rpm")
    raise ValueError(f"speed_unit must be 'eta' or 'rpm', not {speed_unit!r}")


def contact_spans(revolutions: Revolutions) -> list[tuple[float, float]]:
    """(first, last) speed of each run of consecutive revolutions with some contact."""
    touching = revolutions.contact_fraction > 0.0
    edges = np.flatnonzero(np.diff(np.concatenate(([0], touching.astype(int), [0]))))
    return [(float(revolutions.eta[a]), float(revolutions.eta[b - 1]))
            for a, b in zip(edges[::2], edges[1::2], strict=True)]  # fmt: skip


def _mark_rub(ax, revolutions: Revolutions, events: RubEvents | None, speed: SpeedAxis) -> None:
    for a, b in contact_spans(revolutions):
        lo, hi = sorted((float(speed(a)), float(speed(b))))
        ax.axvspan(lo, hi, **RUB_SHADE)
    if events is None:
        return
    if events.onset_eta is not None:
        ax.axvline(float(speed(events.onset_eta)), color=RUB_COLOUR, ls="--", lw=1.0, zorder=1)
    if events.end_eta is not None:
        ax.axvline(float(speed(events.end_eta)), color=RUB_COLOUR, ls=":", lw=1.2, zorder=1)


def _rub_handles(revolutions: Revolutions, events: RubEvents | None, speed: SpeedAxis):
    handles = []
    if contact_spans(revolutions):
        handles.append(Patch(label="revolutions with contact", **RUB_SHADE | {"alpha": 0.2}))
    if events is not None and events.onset_eta is not None:
        handles.append(Line2D([], [], color=RUB_COLOUR, ls="--", lw=1.0,
                              label=f"rub onset ({speed.text(events.onset_eta)})"))  # fmt: skip
    if events is not None and events.end_eta is not None:
        handles.append(Line2D([], [], color=RUB_COLOUR, ls=":", lw=1.2,
                              label=f"rub ends ({speed.text(events.end_eta)})"))  # fmt: skip
    elif events is not None and events.contact_at_end:
        handles.append(Line2D([], [], color="none", label="still rubbing at the end of the run"))
    return handles


def broken_at_wraps(
    s: ArrayLike, lag_deg: ArrayLike, jump: float = 180.0
) -> tuple[np.ndarray, np.ndarray]:
    """``(s, lag)`` with a NaN between consecutive points whose lag jumps by more than
    ``jump`` degrees (a wrap of the [-90, 270) range), so no line crosses the panel."""
    s, lag = np.asarray(s, dtype=float), np.asarray(lag_deg, dtype=float)
    cut = np.flatnonzero(np.abs(np.diff(lag)) > jump) + 1
    return np.insert(s, cut, np.nan), np.insert(lag, cut, np.nan)


@dataclass(frozen=True)
class SteadyStates:
    """Steady states of the same machine at constant speeds (a ``rubcli sweep`` over eta),
    drawn under the Bode plot: per direction of the sweep, the speeds, the 1X whirl
    radius of the recorded periods and their largest radius."""

    eta: np.ndarray
    forward_1x: dict[str, np.ndarray]  # by direction ("up", "down")
    z_max: dict[str, np.ndarray]
    source: str


STEADY_MARKERS = {"up": "^", "down": "v"}


def _draw_steady(full, zmax, steady: SteadyStates, speed: SpeedAxis) -> None:
    for direction, marker in STEADY_MARKERS.items():
        if direction not in steady.z_max:
            continue
        style = {"ls": "none", "marker": marker, "ms": 4.5, "mfc": "none", "color": "0.35",
                 "zorder": 2}  # fmt: skip
        label = f"steady state, sweep {direction} ({steady.source})"
        full.plot(speed(steady.eta), steady.forward_1x[direction], label=label, **style)
        zmax.plot(speed(steady.eta), steady.z_max[direction], label=label, **style)


def bode_figure(
    revolutions: Revolutions,
    events: RubEvents | None = None,
    *,
    title: str = "",
    speed_unit: str = "eta",
    rpm_per_eta: float | None = None,
    steady: SteadyStates | None = None,
) -> Figure:
    """The Bode plot of a transient run, one point per revolution against its mean speed.

    Left: the forward and backward 1X amplitudes of ``x + i y``; the 1X amplitude of the
    x and y probes; their phase lag (probe convention of ``order_tracking``). Right: the
    peak-to-peak displacement of x and y; the largest radius with the clearance; the
    share of each revolution in contact. The revolutions with contact are shaded, the rub
    onset and end marked on every panel; one legend below the panels. ``steady``: the
    steady states at constant speed under the 1X and largest-radius panels (open
    triangles: up, down), so that the delay of a jump with acceleration shows.
    """
    speed = speed_axis(speed_unit, rpm_per_eta)
    s = speed(revolutions.eta)
    fig = _new_figure(12.0, 9.6)
    axes = fig.subplots(3, 2, sharex=True)
    (full, pp), (probe, zmax), (lag, contact) = axes
    full.plot(s, np.abs(revolutions.forward), color="tab:green", lw=1.4, label="forward 1X |A_f|")
    full.plot(s, np.abs(revolutions.backward), color="tab:purple", lw=1.4,
              label="backward 1X |A_b|")  # fmt: skip
    full.set_ylabel("1X of x + i y (clearances)")
    full.set_title("full-spectrum 1X (whirl radius)", fontsize="medium")
    for name in ("x", "y"):
        style = PROBE_STYLES[name]
        probe.plot(s, getattr(revolutions, f"{name}_amplitude"), label=f"probe {name}", **style)
        lag.plot(*broken_at_wraps(s, getattr(revolutions, f"{name}_lag_deg")), **style)
        pp.plot(s, getattr(revolutions, f"{name}_peak_to_peak"), **style)
    probe.set_ylabel("1X amplitude (clearances)")
    probe.set_title("probe 1X amplitude", fontsize="medium")
    lag.set_ylabel("1X phase lag (degrees)")
    lag.set_title("probe 1X phase lag behind the unbalance", fontsize="medium")
    lag.set_ylim(-90.0, 270.0)
    lag.set_yticks(np.arange(-90.0, 271.0, 45.0))
    pp.set_ylabel("peak-to-peak (clearances)")
    pp.set_title("peak-to-peak displacement per revolution", fontsize="medium")
    zmax.plot(s, revolutions.z_max, color="k", lw=1.2, label="largest z per revolution")
    zmax.axhline(1.0, label="clearance (z = 1)", **display.CLEARANCE_STYLE)
    zmax.set_ylabel("z (clearances)")
    zmax.set_title("largest radius per revolution", fontsize="medium")
    zmax.set_ylim(bottom=0.0, top=1.08 * max(1.0, float(np.max(revolutions.z_max))))
    contact.plot(s, revolutions.contact_fraction, color=RUB_COLOUR, lw=1.2,
                 label="contact fraction")  # fmt: skip
    if steady is not None:
        _draw_steady(full, zmax, steady, speed)
        top = max(float(np.max(revolutions.z_max)), *(float(np.nanmax(v)) for v in
                  steady.z_max.values()))  # fmt: skip
        zmax.set_ylim(bottom=0.0, top=1.08 * max(1.0, top))
    contact.set_ylim(-0.03, 1.03)
    contact.set_ylabel("share of the revolution (-)")
    contact.set_title("time in contact per revolution", fontsize="medium")
    for ax in axes.ravel():
        _mark_rub(ax, revolutions, events, speed)
        ax.grid(True, alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel(speed.label)
    handles, labels = [], []
    for ax in (full, probe, zmax, contact):
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:  # the steady states are in two panels
                handles.append(h)
                labels.append(lab)
    for h in _rub_handles(revolutions, events, speed):
        handles.append(h)
        labels.append(h.get_label())
    fig.legend(handles, labels, loc="outside lower center", ncols=4, fontsize="small")
    fig.suptitle(_title(title, "Bode plot", TRACKING_NOTE), fontsize="medium")
    return fig


def _title(title: str, what: str, note: str) -> str:
    head = f"{title}: {what}" if title else what
    return f"{head}\n{note}"


def polar_labels(
    points: np.ndarray, speeds: np.ndarray, span: float, count: int = POLAR_LABELS
) -> list[tuple[int, float]]:
    """``(index, round speed)`` of the points to label: about ``count`` round speeds
    along the curve, each at the revolution nearest it in speed, skipping any point closer
    than 10 % of ``span`` to one already labelled."""
    if speeds.size == 0:
        return []
    ticks = MaxNLocator(nbins=count, steps=[1, 2, 2.5, 5, 10]).tick_values(
        float(speeds.min()), float(speeds.max())
    )
    chosen: list[tuple[int, float]] = []
    lo, hi = float(speeds.min()), float(speeds.max())
    for tick in ticks:
        if not lo <= tick <= hi:
            continue
        k = int(np.argmin(np.abs(speeds - tick)))
        if all(abs(points[k] - points[j]) > 0.1 * span for j, _ in chosen):
            chosen.append((k, float(tick)))
    return chosen


def polar_figure(
    revolutions: Revolutions,
    *,
    title: str = "",
    speed_unit: str = "eta",
    rpm_per_eta: float | None = None,
) -> Figure:
    """The 1X vectors in the complex plane as the speed changes: the forward ``A_f`` and
    the backward ``A_b`` of ``x + i y``, relative to the unbalance (along +Re), each
    curve coloured by speed with round speeds labelled. A lag behind the unbalance draws
    clockwise from +Re (the free whirl: -90 degrees at the critical speed)."""
    speed = speed_axis(speed_unit, rpm_per_eta)
    s = speed(revolutions.eta)
    fig = _new_figure(12.0, 6.4)
    axes = fig.subplots(1, 2)
    norm = Normalize(float(s.min()), float(s.max()) if s.max() > s.min() else float(s.min()) + 1)
    line = None
    for ax, vector, name in (
        (axes[0], revolutions.forward, "forward 1X A_f"),
        (axes[1], revolutions.backward, "backward 1X A_b"),
    ):
        points = np.column_stack((vector.real, vector.imag))
        segments = np.stack((points[:-1], points[1:]), axis=1)
        line = LineCollection(segments, cmap="viridis", norm=norm, linewidths=1.8, zorder=3)
        line.set_array(0.5 * (s[:-1] + s[1:]))
        ax.add_collection(line)
        reach = float(np.max(np.abs(vector), initial=0.0))
        span = 2.0 * reach if reach > 0 else 1.0
        ax.plot([0.0], [0.0], "+", color="0.3", ms=10, zorder=2)
        for k, tick in polar_labels(vector, s, span):
            ax.plot(vector.real[k], vector.imag[k], "o", color="k", ms=3.5, zorder=4)
            left = vector.real[k] < 0.0  # the text away from the centre, on either side
            ax.annotate(speed.text(tick / speed.factor), (vector.real[k], vector.imag[k]),
                        xytext=(-5 if left else 5, 4), textcoords="offset points",
                        ha="right" if left else "left", fontsize="x-small", zorder=5)  # fmt: skip
        limit = 1.15 * reach if reach > 0 else 1.0
        ax.set_xlim(-limit, limit)
        ax.set_ylim(-limit, limit)
        ax.set_aspect("equal")
        ax.axhline(0.0, color="0.85", lw=0.8, zorder=1)
        ax.axvline(0.0, color="0.85", lw=0.8, zorder=1)
        ax.set_title(name, fontsize="medium")
        ax.set_xlabel("Re: in phase with the unbalance (clearances)")
        ax.set_ylabel("Im: 90 degrees ahead of it (clearances)")
        ax.grid(True, alpha=0.3)
    fig.colorbar(line, ax=list(axes), label=speed.label, shrink=0.8)
    fig.suptitle(_title(title, "polar plot of the 1X vectors", TRACKING_NOTE), fontsize="medium")
    return fig


def order_limit(cascade: OrderCascade, reference: float) -> float:
    """Half-width of the cascade's order axis: every line within ``LINE_LEVEL_DB`` of the
    largest, with some room, at least ``MIN_ORDER_RANGE``, at most the Nyquist order."""
    nyquist = float(np.max(np.abs(cascade.order)))
    strong = cascade.amplitude >= reference * 10.0 ** (LINE_LEVEL_DB / 20.0)
    orders = np.abs(np.broadcast_to(cascade.order, cascade.amplitude.shape)[strong])
    wanted = max(MIN_ORDER_RANGE, 1.15 * float(np.max(orders, initial=0.0)))
    return min(wanted, nyquist)


def dry_whip_order(params: model.ModelParams, eta: ArrayLike) -> np.ndarray:
    """Order of the rolling backward whirl (dry whip, ``model.rolling_whirl_radius``):
    whirl rate ``-Rp eta / r`` over the speed ``eta``, i.e. ``-Rp / r(eta)``."""
    eta = np.atleast_1d(np.asarray(eta, dtype=float))
    radii = [model.rolling_whirl_radius(dataclasses.replace(params, eta=float(v))) for v in eta]
    return -params.Rp / np.asarray(radii)


def cascade_figure(
    cascade: OrderCascade,
    *,
    params: model.ModelParams | None = None,
    title: str = "",
    speed_unit: str = "eta",
    rpm_per_eta: float | None = None,
    max_order: float | None = None,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
) -> Figure:
    """The full-spectrum cascade against speed: each window's spectral lines
    (``plotting.cascade``: markers coloured and sized by level in dB of the largest line,
    nothing below ``dynamic_range_db``), order on the y-axis, backward orders shaded.
    Marked: 1X, 2X, 1/2X, -1X; the free whirl at the natural frequency (orders +-1/eta);
    with ``params`` (Rp > 0) the dry-whip line ``-Rp / r(eta)`` where inside the range.
    ``max_order``: half-width of the order axis (default: from the lines drawn)."""
    speed = speed_axis(speed_unit, rpm_per_eta)
    amp = cascade.amplitude
    reference = float(np.max(amp)) if amp.size else 0.0
    limit = float(max_order) if max_order is not None else order_limit(cascade, reference)
    inside = np.abs(cascade.order) <= limit
    line_order, line_eta, line_db = cascade_points(
        cascade.order[inside], cascade.eta, amp[:, inside], reference, dynamic_range_db
    )
    fig = _new_figure(11.0, 7.0)
    ax = fig.add_subplot()
    ax.axhspan(-limit, 0.0, color="0.95", zorder=0)
    sx = speed(cascade.eta)
    pad = 0.5 * float(np.min(np.diff(sx), initial=0.0) if sx.size > 1 else 0.0) or 0.05
    left, right = float(sx.min()) - abs(pad), float(sx.max()) + abs(pad)
    artist = None
    if line_order.size:
        share = np.clip((line_db + dynamic_range_db) / dynamic_range_db, 0.0, 1.0)
        sizes = (SMALL + (LARGE - SMALL) * share) ** 2
        rank = np.argsort(line_db)  # strongest drawn last, on top
        artist = ax.scatter(speed(line_eta[rank]), line_order[rank], s=sizes[rank],
                            c=line_db[rank],
                            cmap=CMAP, norm=Normalize(-dynamic_range_db, 0.0), linewidths=0,
                            zorder=4)  # fmt: skip
    for value, name in ORDER_LINES.items():
        if abs(value) <= limit:
            ax.axhline(value, color="0.45", ls=":", lw=0.9, zorder=2)
            ax.annotate(name, (1.0, value), xycoords=("axes fraction", "data"),
                        xytext=(4, 0), textcoords="offset points", va="center",
                        fontsize="small", color="0.3")  # fmt: skip
    grid = np.linspace(float(cascade.eta.min()), float(cascade.eta.max()), 200)
    handles = []
    free = 1.0 / grid
    for sign in (1.0, -1.0):
        keep = free <= limit
        ax.plot(speed(grid[keep]), sign * free[keep], color="tab:red", ls="--", lw=1.1, zorder=3)
    handles.append(Line2D([], [], color="tab:red", ls="--", lw=1.1,
                          label="free whirl at the natural frequency: order +-1/eta"))  # fmt: skip
    # the rolling whirl's closed form is the paper machine's (concentric, isotropic)
    if params is not None and params.Rp > 0 and params.is_paper_machine:
        whip = dry_whip_order(params, grid)
        keep = np.abs(whip) <= limit
        if keep.any():
            ax.plot(speed(grid[keep]), whip[keep], color="tab:brown", ls="-.", lw=1.3, zorder=3)
            handles.append(Line2D([], [], color="tab:brown", ls="-.", lw=1.3,
                                  label="dry whip (rolling): order -Rp / r(eta)"))  # fmt: skip
        else:
            handles.append(
                Line2D(
                    [],
                    [],
                    color="none",
                    label=(
                        f"dry whip at order {whip.max():.3g} to {whip.min():.3g}: outside the axis"
                    ),
                )
            )
    handles.append(Line2D([], [], color="0.45", ls=":", lw=0.9, label="orders 1X, 2X, 1/2X, -1X"))
    ax.set_xlim(left, right)
    ax.set_ylim(-limit, limit)
    ax.set_xlabel(speed.label)
    ax.set_ylabel("whirl order (multiples of the speed; < 0 backward, shaded)")
    ax.grid(True, alpha=0.25)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.1), ncols=2,
              fontsize="small", frameon=False)  # fmt: skip
    if artist is not None:
        fig.colorbar(artist, ax=ax, pad=0.06, label=(
            f"level of each line of x + i y, dB of the largest ({reference:.3g} clearances)"
            f"\nlines below -{dynamic_range_db:g} dB are not drawn"))  # fmt: skip
    note = (f"order spectrum resampled uniformly in the unbalance phase; windows of "
            f"{cascade.revolutions_per_window} revolutions, Hann")  # fmt: skip
    fig.suptitle(_title(title, "full-spectrum cascade", note), fontsize="medium")
    return fig


def snapshot_revolutions(
    revolutions: Revolutions, speeds: Sequence[float] | None = None
) -> list[tuple[int, str]]:
    """``(revolution index, reason)`` of each orbit snapshot, in time order.

    Given ``speeds`` (eta): the revolution whose mean speed is nearest each (the first one
    on a tie). Otherwise: the peak forward 1X (resonance), the first revolution with
    contact (rub onset) and the largest radius; one revolution picked twice is shown once
    with both reasons."""
    if speeds is not None:
        picks = [(int(np.argmin(np.abs(revolutions.eta - v))), "requested") for v in speeds]
    else:
        picks = [(int(np.argmax(np.abs(revolutions.forward))), "peak 1X (resonance)")]
        touching = np.flatnonzero(revolutions.contact_fraction > 0.0)
        if touching.size:
            picks.append((int(touching[0]), "rub onset"))
        picks.append((int(np.argmax(revolutions.z_max)), "largest z"))
    merged: dict[int, list[str]] = {}
    for index, reason in picks:
        if reason not in merged.setdefault(index, []):
            merged[index].append(reason)
    return [(k, ", ".join(merged[k])) for k in sorted(merged)]


def orbit_snapshots_figure(
    tau: ArrayLike,
    x: ArrayLike,
    y: ArrayLike,
    revolutions: Revolutions,
    *,
    speeds: Sequence[float] | None = None,
    title: str = "",
    speed_unit: str = "eta",
    rpm_per_eta: float | None = None,
) -> Figure:
    """One revolution of the orbit at each snapshot (``snapshot_revolutions``), with the
    clearance circle z = 1 and a dot where the revolution starts (the unbalance at its
    starting phase); equal aspect, the same axes in every panel."""
    speed = speed_axis(speed_unit, rpm_per_eta)
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    picks = snapshot_revolutions(revolutions, speeds)
    columns = min(len(picks), 4)
    rows = math.ceil(len(picks) / columns)
    fig = _new_figure(3.4 * columns + 0.4, 3.7 * rows + 1.0)
    axes = np.atleast_1d(fig.subplots(rows, columns, sharex=True, sharey=True)).ravel()
    reach = 1.0
    circle = np.linspace(0.0, 2.0 * math.pi, 361)
    for ax, (k, reason) in zip(axes, picks, strict=False):
        a, b = int(revolutions.start[k]), min(int(revolutions.stop[k]) + 1, x.size)
        ax.plot(np.cos(circle), np.sin(circle), label="clearance (z = 1)",
                **display.CLEARANCE_STYLE)  # fmt: skip
        ax.plot(x[a:b], y[a:b], color="tab:blue", lw=1.4, zorder=3, label="orbit")
        ax.plot(x[a], y[a], "o", color="k", ms=4, zorder=4, label="start of the revolution")
        reach = max(reach, float(np.max(np.hypot(x[a:b], y[a:b]))))
        contact = revolutions.contact_fraction[k]
        heading = f"{speed.text(revolutions.eta[k])}: {reason}"
        ax.set_title(
            f"{heading}\ncontact {100 * contact:.0f} % of the revolution", fontsize="small"
        )
        ax.set_aspect("equal")
        ax.grid(True, alpha=0.3)
    for ax in axes[len(picks) :]:
        ax.set_axis_off()
    limit = display.MARGIN * reach
    for ax in axes[: len(picks)]:
        ax.set_xlim(-limit, limit)
        ax.set_ylim(-limit, limit)
    for i, ax in enumerate(axes[: len(picks)]):
        if i + columns >= len(picks):  # no panel below: this one carries the x-axis
            ax.xaxis.set_tick_params(labelbottom=True)
    fig.supxlabel("x (clearances)", fontsize="medium")
    for ax in axes[::columns]:
        ax.set_ylabel("y (clearances)")
    # the key in the title: a legend below or above the equal-aspect panels met their
    # labels or the title (constrained layout does not reserve its room there)
    key = "one revolution each, same axes; dashed circle: the clearance z = 1; dot: its start"
    fig.suptitle(_title(title, "orbit snapshots", key),
                 fontsize="medium")  # fmt: skip
    return fig

"""Figures of a run: the orbits of every method overlaid, and x, y, z against time.

Figures are built on matplotlib's Agg canvas directly (``Figure`` + ``FigureCanvasAgg``),
without pyplot, so making them never opens a window nor changes a global backend. Save
them with ``rubcli.io.save_figure``. These functions only draw solutions; they never solve.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from rubcli import units
from rubcli.model import ModelParams
from rubcli.solution import Solution

LINE_STYLES = ("-", "--", ":", "-.")
TIME_LABEL = "tau = omega t"
ZOOM_PERIODS = 3.0  # time.png: the last this many forcing periods, zoomed
ZOOM_POINTS_PER_PERIOD = 200  # ... drawn between the samples at this many points per period


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _label(solution: Solution) -> str:
    return solution.method if solution.success else f"{solution.method} (failed)"


BAND_ALPHA = 0.25  # the fill of a time trace's min/max band (``time_figure``)


def _line_style(index: int) -> dict:
    """Overlaid methods that agree stay visible: the first is a thick light line, the
    second a thin solid line drawn on top of it (inside it where they agree), a third and
    later ones thin dashed or dotted lines on top of those (``orbit.OVERLAY_DASHES``)."""
    from rubcli.plotting.orbit import OVERLAY_DASHES

    if index == 0:
        return {"linestyle": "-", "linewidth": 2.4, "alpha": 0.55, "zorder": 2}
    dashes = OVERLAY_DASHES[index % len(OVERLAY_DASHES)]
    return {"linestyle": dashes, "linewidth": 1.1 if index == 1 else 0.9, "zorder": 2 + index}


def parameters_title(
    name: str, params: ModelParams, vary_mu: bool = False, speed: str | None = None
) -> str:
    """A figure title: the case name and its nondimensional parameters.

    ``vary_mu``: the figure's panels differ in mu (a sweep), so mu is not one value.
    ``speed``: the speed changes (``SpeedProfile.text``), so eta is not one value.
    """
    p = params
    mu = "mu: see each panel" if vary_mu else f"mu={p.mu:g}"
    eta = speed if speed is not None else f"eta={p.eta:g}"
    nu = "" if p.damping is not None else f"nu={p.nu:g}, "
    title = f"{name}\n{nu}{eta}, e={p.e:g}, K={p.K:g}, {mu}, Rp={p.Rp:g}, phi0={p.phi0:g}"
    return "\n".join([title, *p.machine_lines()])


def orbit_figure(
    solutions: Sequence[Solution],
    title: str,
    *,
    scale: units.PhysicalScale | None = None,
    transient_periods: float | None = None,
    failures: Mapping[str, str] | None = None,
) -> Figure:
    """Orbits (y against x) of every solution overlaid, with the clearance circle.

    Drawn by ``plotting.orbit.draw_orbits``: transient faint, the last periods bold (or
    faint where they do not retrace one curve), keyphasor dots over the steady span (after
    ``transient_periods``, default half the run), failed methods clipped and labelled.
    With two or more successful methods a difference panel below shows how far each is
    from the first against time (``plotting.difference``): two orbits that agree to a
    fraction of a line width cannot both be seen, their distance can. ``failures`` are
    methods that produced no solution at all (name: reason); when nothing succeeded the
    figure says so in place of a blank plot. Axes in clearances, or in metres when
    ``scale`` is given.
    """
    from rubcli.plotting.difference import comparable, draw_difference
    from rubcli.plotting.orbit import draw_orbits, legend_handles

    two = len(comparable(solutions)) >= 2
    fig = _new_figure(6.8, 10.2 if two else 7.6)
    if two:
        ax, diff = fig.subplots(2, 1, height_ratios=(3.2, 1.0))
    else:
        ax, diff = fig.add_subplot(), None
    unit = 1.0 if scale is None else scale.clearance
    unit_name = "clearances" if scale is None else "m"
    drawing = draw_orbits(ax, solutions, unit=unit, transient_periods=transient_periods)
    if scale is None:
        ax.set_xlabel("x / clearance")
        ax.set_ylabel("y / clearance")
    else:
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    handles, text = legend_handles(drawing, _bold_periods(solutions), unit_name)
    method_handles, _ = ax.get_legend_handles_labels()
    if diff is not None:
        steady = drawing.steady_from.get(drawing.first or "")
        draw_difference(diff, solutions, colors=drawing.colors, unit=unit, scale=scale,
                        steady_from=steady)  # fmt: skip
        diff.set_xlabel(TIME_LABEL if scale is None else "t (s)")
        diff.set_title(_difference_title(drawing.first) + "; shaded: transient",
                       fontsize="small")  # fmt: skip
    fig.legend(handles=method_handles + handles, loc="outside lower center", ncols=2,
               fontsize="small", title=text or None, title_fontsize="small")  # fmt: skip
    message = failure_message(solutions, failures)
    if message:
        _message_box(ax, message)
    fig.suptitle(title, fontsize="medium")
    return fig


def _bold_periods(solutions: Sequence[Solution]) -> float:
    from rubcli.plotting import display

    spans = [display.recorded_periods(s) for s in solutions if s.success]
    return min([display.BOLD_PERIODS, *spans]) if spans else display.BOLD_PERIODS


def failure_message(
    solutions: Sequence[Solution], failures: Mapping[str, str] | None = None
) -> str | None:
    """The text a figure shows in place of data when no method succeeded (else None)."""
    if any(s.success for s in solutions):
        return None
    lines = [f"{s.method}: {s.status}: {s.message}" for s in solutions]
    lines += [f"{name}: {why}" for name, why in (failures or {}).items()]
    if not lines:
        lines = ["no method was run"]
    short = [line if len(line) <= 90 else line[:87] + "..." for line in lines]
    head = "Every method failed (any partial trace is drawn up to its failure):"
    return head + "\n" + "\n".join(short)


def _message_box(ax, message: str) -> None:
    ax.text(0.5, 0.5, message, transform=ax.transAxes, ha="center", va="center",
            fontsize="small", color="darkred", wrap=True, zorder=20,
            bbox={"boxstyle": "round", "facecolor": "white", "edgecolor": "darkred",
                  "alpha": 0.9})  # fmt: skip


def time_figure(
    solutions: Sequence[Solution],
    title: str,
    *,
    scale: units.PhysicalScale | None = None,
    failures: Mapping[str, str] | None = None,
    zoom_periods: float = ZOOM_PERIODS,
    transient_periods: float | None = None,
) -> Figure:
    """x, y and z against time: the whole run on the left, the last ``zoom_periods``
    forcing periods on the right (where each oscillation is resolved), the clearance
    marked on z; with two or more successful methods a bottom row shows their distance
    from the first (``plotting.difference``), over the whole run and in the zoom, the
    transient (before ``transient_periods``, default half the run) shaded.

    A long trace is drawn as the band between its min and max over each of
    ``display.ENVELOPE_BINS`` groups of samples (what a screen can show): filled lightly,
    its edges in the method's line style, so a long run costs little memory and drawing
    time. The zoom draws every trace between its samples by ``display.hermite``. The first
    method is a thick light line, the others thin lines on top, so methods that agree
    both stay visible. The legend sits beside the axes, never over the data; the y limits
    come from the successful methods (a diverged one is clipped) and are shared by the
    whole run and its zoom. Time in tau and positions in clearances, or seconds and metres
    when ``scale`` is given.
    """
    from rubcli.plotting import display
    from rubcli.plotting.difference import comparable, draw_difference
    from rubcli.plotting.orbit import COLORS

    two = len(comparable(solutions)) >= 2
    rows = 4 if two else 3
    fig = _new_figure(12.0, 2.4 * rows + 0.9)
    axes = fig.subplots(rows, 2, width_ratios=(2.4, 1.0), sharex="col")
    for row in range(3):
        axes[row, 1].sharey(axes[row, 0])
    unit = 1.0 if scale is None else scale.clearance
    seconds = (lambda tau: tau) if scale is None else (lambda tau: units.seconds(tau, scale))
    window = _zoom_window(solutions, zoom_periods)
    limits = [[np.inf, -np.inf] for _ in range(3)]
    for index, solution in enumerate(solutions):
        n = display.finite_length(solution)
        t = seconds(solution.t[:n])
        style = {**_line_style(index), "color": COLORS[index % len(COLORS)]}
        label = _label(solution)
        zoom = _zoom_traces(solution, n, window)
        for k, values in enumerate((solution.x, solution.y, solution.z)):
            ax = axes[k, 0]
            band = display.envelope_band(t, values[:n])  # (reduced first, then scaled)
            if band is None:
                ve = unit * values[:n]
                ax.plot(t, ve, label=label, **style)
            else:  # the min/max band: filled, its edges in the method's line style
                steps, lo, hi = band[0], unit * band[1], unit * band[2]
                (edge,) = ax.plot(steps, hi, drawstyle="steps-post", label=label, **style)
                ax.plot(steps, lo, drawstyle="steps-post", **style)
                ax.fill_between(steps, lo, hi, step="post", color=edge.get_color(),
                                alpha=BAND_ALPHA, linewidth=0)  # fmt: skip
                ve = np.concatenate((lo, hi))
            if zoom is not None:
                axes[k, 1].plot(seconds(zoom[0]), unit * zoom[1][k], **style)
            if solution.success and ve.size:
                limits[k] = [min(limits[k][0], ve.min()), max(limits[k][1], ve.max())]
    for ax in axes[2, :]:
        ax.axhline(unit, label="clearance" if ax is axes[2, 0] else None,
                   **display.CLEARANCE_STYLE)  # fmt: skip
    limits[2] = [min(limits[2][0], unit), max(limits[2][1], unit)]
    for k, (lo, hi) in enumerate(limits):
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            pad = 0.05 * (hi - lo)
            axes[k, 0].set_ylim(lo - pad, hi + pad)
    # with an offset stator the positions are the rotor's relative to the stator's centre
    machine = solutions[0].problem.params if solutions else None
    offset = machine is not None and (machine.offset != (0.0, 0.0) or machine.stator is not None)
    names = ("x rel. stator", "y rel. stator", "z") if offset else ("x", "y", "z")
    for k, name in enumerate(names):
        axes[k, 0].set_ylabel(f"{name} / clearance" if scale is None else f"{name} (m)")
        for ax in axes[k]:
            ax.grid(True, alpha=0.3)
    if window is not None:
        a, b = seconds(window[0]), seconds(window[1])
        for k in range(rows):
            axes[k, 0].axvspan(a, b, color="gold", alpha=0.25, zorder=0,
                               label="zoomed on the right" if k == 0 else None)  # fmt: skip
        axes[k, 1].set_xlim(a, b)
        axes[0, 1].set_title(f"the last {_periods_text(window, solutions)} forcing periods",
                             fontsize="medium")  # fmt: skip
    else:
        for k in range(rows):
            axes[k, 1].set_axis_off()
    if two:
        good = comparable(solutions)
        colors = {s.method: COLORS[i % len(COLORS)] for i, s in enumerate(solutions)}
        steady = display.steady_start(good[0], transient_periods)
        draw_difference(axes[3, 0], solutions, colors=colors, unit=unit, scale=scale,
                        steady_from=steady)  # fmt: skip
        if window is not None:
            draw_difference(axes[3, 1], solutions, colors=colors, unit=unit, scale=scale,
                            window=window)  # fmt: skip
            axes[3, 1].set_ylabel("")
            (a0, a1), (b0, b1) = axes[3, 0].get_ylim(), axes[3, 1].get_ylim()
            axes[3, 1].sharey(axes[3, 0])  # one distance axis for the run and its zoom
            axes[3, 0].set_ylim(min(a0, b0), max(a1, b1))
        axes[3, 0].set_title(_difference_title(good[0].method), fontsize="small", loc="left")
    time_label = TIME_LABEL if scale is None else "t (s)"
    for ax in axes[-1]:
        ax.set_xlabel(time_label)
    handles, labels = [], []
    for ax in (axes[0, 0], axes[2, 0], axes[-1, 0]):
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="outside right upper", fontsize="small")
    message = failure_message(solutions, failures)
    if message:
        _message_box(axes[1, 0], message)
    fig.suptitle(title, fontsize="medium")
    return fig


def _difference_title(first: str | None) -> str:
    return f"distance from {first}, in each method's colour (log scale)"


def _zoom_window(solutions: Sequence[Solution], periods: float) -> tuple[float, float] | None:
    """tau of the zoom: the last ``periods`` forcing periods the successful methods share
    (the last common ones of the failed ones when none succeeded); None when the record
    is too short for a zoom to show more than the whole run."""
    from rubcli.plotting import display

    good = [s for s in solutions if s.success and display.finite_length(s) >= 2]
    drawn = good or [s for s in solutions if display.finite_length(s) >= 2]
    if not drawn:
        return None
    end = min(float(s.t[display.finite_length(s) - 1]) for s in drawn)
    start = max(float(s.t[0]) for s in drawn)
    period = drawn[0].problem.params.period
    if end - start <= 2.0 * periods * period:
        return None
    return end - periods * period, end


def _zoom_traces(solution: Solution, n: int, window):
    """``(tau, (x, y, z))`` of the zoom, between the samples by ``display.hermite``."""
    from rubcli.plotting import display

    if window is None or n < 2:
        return None
    t = solution.t[:n]
    a, b = max(window[0], float(t[0])), min(window[1], float(t[-1]))
    if b <= a:
        return None
    period = solution.problem.params.period
    m = int(max(2, np.ceil((b - a) / period * ZOOM_POINTS_PER_PERIOD)))
    tq = np.linspace(a, b, m + 1)
    xy = display.hermite(t, solution.states[:n], tq)
    return tq, (xy[:, 0], xy[:, 1], np.hypot(xy[:, 0], xy[:, 1]))


def _periods_text(window, solutions) -> str:
    period = next(s.problem.params.period for s in solutions)
    return f"{(window[1] - window[0]) / period:g}"

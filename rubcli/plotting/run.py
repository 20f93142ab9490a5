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


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _label(solution: Solution) -> str:
    return solution.method if solution.success else f"{solution.method} (failed)"


BAND_ALPHA = 0.25  # the fill of a time trace's min/max band (``time_figure``)


def _line_style(index: int) -> dict:
    """Overlaid methods that agree stay visible: dashes differ and later lines are thinner."""
    return {
        "linestyle": LINE_STYLES[index % len(LINE_STYLES)],
        "linewidth": max(0.5, 1.3 - 0.2 * index),
    }


def parameters_title(name: str, params: ModelParams, vary_mu: bool = False) -> str:
    """A figure title: the case name and its nondimensional parameters.

    ``vary_mu``: the figure's panels differ in mu (a sweep), so mu is not one value.
    """
    p = params
    mu = "mu: see each panel" if vary_mu else f"mu={p.mu:g}"
    return (
        f"{name}\nnu={p.nu:g}, eta={p.eta:g}, e={p.e:g}, K={p.K:g}, "
        f"{mu}, Rp={p.Rp:g}, phi0={p.phi0:g}"
    )


def orbit_figure(
    solutions: Sequence[Solution],
    title: str,
    *,
    scale: units.PhysicalScale | None = None,
    transient_periods: float | None = None,
    failures: Mapping[str, str] | None = None,
) -> Figure:
    """Orbits (y against x) of every solution overlaid, with the clearance circle.

    Drawn by ``plotting.orbit.draw_orbits``: transient faded, the last periods bold,
    keyphasor dots over the steady span (after ``transient_periods``, default half the
    run), failed methods clipped and labelled. ``failures`` are methods that produced no
    solution at all (name: reason); when nothing succeeded the figure says so in place
    of a blank plot. Axes in clearances, or in metres when ``scale`` is given.
    """
    from rubcli.plotting.orbit import draw_orbits, legend_handles

    fig = _new_figure(6.6, 7.6)
    ax = fig.add_subplot()
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
) -> Figure:
    """x, y and z against time, three stacked axes, the clearance marked on z.

    A long trace is drawn as the band between its min and max over each of
    ``display.ENVELOPE_BINS`` groups of samples (what a screen can show): filled lightly,
    its edges in the method's line style, so an overlaid method stays visible and a long
    run costs little memory and drawing time. The legend sits beside the axes, never
    over the data; the y limits come from the successful methods (a diverged one is
    clipped). Time in tau and positions in clearances, or seconds and metres when
    ``scale`` is given.
    """
    from rubcli.plotting import display

    fig = _new_figure(10.0, 7.5)
    axes = fig.subplots(3, 1, sharex=True)
    unit = 1.0 if scale is None else scale.clearance
    limits = [[np.inf, -np.inf] for _ in axes]
    for index, solution in enumerate(solutions):
        n = display.finite_length(solution)
        t = solution.t[:n] if scale is None else units.seconds(solution.t[:n], scale)
        style = _line_style(index)
        label = _label(solution)
        for k, (ax, values) in enumerate(
            zip(axes, (solution.x, solution.y, solution.z), strict=True)
        ):
            band = display.envelope_band(t, values[:n])  # (reduced first, then scaled)
            if band is None:
                ve = unit * values[:n]
                ax.plot(t, ve, label=label, **style)
            else:  # the min/max band: filled, its edges in the method's line style
                steps, lo, hi = band[0], unit * band[1], unit * band[2]
                (edge,) = ax.plot(steps, hi, drawstyle="steps-post", label=label, **style)
                ax.plot(steps, lo, drawstyle="steps-post", color=edge.get_color(), **style)
                ax.fill_between(steps, lo, hi, step="post", color=edge.get_color(),
                                alpha=BAND_ALPHA, linewidth=0)  # fmt: skip
                ve = np.concatenate((lo, hi))
            if solution.success and ve.size:
                limits[k] = [min(limits[k][0], ve.min()), max(limits[k][1], ve.max())]
    axes[2].axhline(unit, label="clearance", **display.CLEARANCE_STYLE)
    limits[2] = [min(limits[2][0], unit), max(limits[2][1], unit)]
    for ax, (lo, hi) in zip(axes, limits, strict=True):
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            pad = 0.05 * (hi - lo)
            ax.set_ylim(lo - pad, hi + pad)
    names = ("x", "y", "z")
    for ax, name in zip(axes, names, strict=True):
        ax.set_ylabel(f"{name} / clearance" if scale is None else f"{name} (m)")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("tau = omega t" if scale is None else "t (s)")
    handles, labels = axes[2].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize="small")
    message = failure_message(solutions, failures)
    if message:
        _message_box(axes[1], message)
    axes[0].set_title(title, fontsize="medium")
    return fig

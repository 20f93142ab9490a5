"""Orbits as an engineer reads them: the steady state bold, the transient faded.

``draw_orbits`` draws the orbits (y against x) of several solutions of one problem into
one matplotlib axes, used by ``rubcli run`` (orbit.png) and by the Figure 3 composite of
``rubcli compare`` (orbits.png):

- the transient (from the start to the last ``BOLD_PERIODS`` forcing periods) of the
  first successful method thin and faded, the start marked with a star; a long
  transient is drawn as whole periods (``display.period_subset``), so a long run never
  draws a million points;
- the last ``BOLD_PERIODS`` periods bold, interpolated at 720 points per period from the
  samples and their velocities (``display.hermite``), so that a whirl looks round;
- keyphasor dots: one per forcing period over the steady span (after the transient,
  ``display.steady_start``), the stroboscopic section: one dot for a period-one orbit, a
  closed curve for a quasi-periodic one;
- overlaid methods: the first successful method thick, each other one a thin dashed line
  of a contrasting colour (its bold span only) with thin cross keyphasor markers, so
  both stay visible when they agree; their largest distance from the first method is
  returned (and stated by the callers);
- failed methods: a dotted line up to where they failed, labelled with the tau of the
  failure and marked with a cross; they never set the axes (``display.orbit_radius``), so
  a diverged trace is clipped at the axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rubcli.plotting import display
from rubcli.solution import Solution

COLORS = ("C0", "C3", "C2", "C1", "C4", "C5", "C6", "C8")
CROSSES = ("x", "+", "1", "2", "3", "4")  # thin markers: the dot under them stays visible


@dataclass
class OrbitDrawing:
    """What ``draw_orbits`` drew, for captions, legends and tests."""

    radius: float  # half-width of the axes (clearances, times the unit)
    steady_from: dict[str, float] = field(default_factory=dict)  # tau of the steady span
    bold_from: dict[str, float] = field(default_factory=dict)  # tau of the bold span
    keyphasor: dict[str, int] = field(default_factory=dict)  # dots drawn per method
    distance_steady: dict[str, float | None] = field(default_factory=dict)  # vs the first
    distance_all: dict[str, float | None] = field(default_factory=dict)
    first: str | None = None  # the method others are measured against
    failed: dict[str, float | None] = field(default_factory=dict)  # tau of the last sample
    points: int = 0  # points drawn in all (bounded for long runs)


def draw_orbits(
    ax,
    solutions: Sequence[Solution],
    *,
    unit: float = 1.0,
    transient_periods: float | None = None,
    bold_periods: float = display.BOLD_PERIODS,
    label_methods: bool = True,
) -> OrbitDrawing:
    """Draw the orbits of ``solutions`` (one problem) into ``ax``; see the module doc.

    ``unit`` scales clearances to the axes' unit (metres for a physical case).
    ``transient_periods`` fixes the start of the steady span (default: half the record).
    """
    circle = np.linspace(0.0, 2.0 * np.pi, 721)
    ax.plot(
        unit * np.cos(circle), unit * np.sin(circle), label="clearance", **display.CLEARANCE_STYLE
    )
    radius = unit * display.orbit_radius(solutions)
    drawing = OrbitDrawing(radius=radius)
    good = [s for s in solutions if s.success and display.finite_length(s) >= 2]
    first = good[0] if good else None
    drawing.first = None if first is None else first.method
    for index, sol in enumerate(solutions):
        color = COLORS[index % len(COLORS)]
        n = display.finite_length(sol)
        label = sol.method if label_methods else None
        if n == 0:
            continue
        if not sol.success or n < 2:
            drawing.failed[sol.method] = float(sol.t[n - 1])
            pts = display.period_subset(sol, float(sol.t[n - 1]))
            drawing.points += pts.shape[0]
            ax.plot(unit * pts[:, 0], unit * pts[:, 1], color=color, ls=":", lw=1.0, alpha=0.9,
                    label=f"{sol.method}: failed at tau = {sol.t[n - 1]:.6g}" if label_methods
                    else None)  # fmt: skip
            ax.plot(unit * sol.x[n - 1], unit * sol.y[n - 1], "X", color=color, ms=8, mec="k")
            continue
        main = sol is first
        period = sol.problem.params.period
        t_end = float(sol.t[n - 1])
        steady = display.steady_start(sol, transient_periods)
        bold = max(float(sol.t[0]), t_end - bold_periods * period)
        drawing.steady_from[sol.method] = steady
        drawing.bold_from[sol.method] = bold
        faded = display.period_subset(sol, bold) if main else np.empty((0, 2))
        fine = display.fine_orbit(sol, bold)
        drawing.points += faded.shape[0] + fine.shape[0]
        if main:  # the others' transients would only blur it; their distance is stated
            ax.plot(unit * faded[:, 0], unit * faded[:, 1], color=color, lw=0.5, alpha=0.3)
            ax.plot(unit * fine[:, 0], unit * fine[:, 1], color=color, lw=2.2, zorder=3,
                    label=label)  # fmt: skip
        else:  # thin and dashed: the bold line shows between the dashes
            ax.plot(unit * fine[:, 0], unit * fine[:, 1], color=color, lw=1.0, zorder=4,
                    ls=(0, (4, 2)), label=label)  # fmt: skip
        if main:  # every method starts from the same state
            ax.plot(unit * sol.x[0], unit * sol.y[0], "*", color=color, ms=11, mec="k", mew=0.6,
                    zorder=6)  # fmt: skip
        dots = display.keyphasor(sol, transient_periods)
        drawing.keyphasor[sol.method] = int(dots.shape[0])
        drawing.points += dots.shape[0]
        if main:
            ax.plot(unit * dots[:, 0], unit * dots[:, 1], "o", color="k", ms=5, mfc=color,
                    mew=0.8, zorder=7)  # fmt: skip
        else:
            marker = CROSSES[index % len(CROSSES)]
            ax.plot(unit * dots[:, 0], unit * dots[:, 1], marker, color=color, ms=7, mew=1.2,
                    zorder=8)  # fmt: skip
            near = display.distance(first, sol, steady)
            drawing.distance_steady[sol.method] = _scaled(near, unit)
            drawing.distance_all[sol.method] = _scaled(display.distance(first, sol), unit)
    ax.set_xlim(-radius, radius)
    ax.set_ylim(-radius, radius)
    ax.set_aspect("equal", adjustable="box")
    ax.grid(True, alpha=0.3)
    return drawing


def _scaled(value: float | None, unit: float) -> float | None:
    return None if value is None else unit * value


def legend_handles(drawing: OrbitDrawing, periods: float, unit_name: str) -> tuple[list, str]:
    """Proxy legend entries for the styles (faded, start, keyphasor) and a caption text.

    The caption states the distance between the methods, in ``unit_name``.
    """
    from matplotlib.lines import Line2D

    handles = [
        Line2D([], [], color="0.5", lw=0.5, alpha=0.5, label="transient (faded)"),
        Line2D([], [], color="0.3", lw=2.0, label=f"last {periods:g} forcing periods (bold)"),
        Line2D([], [], ls="", marker="*", color="0.6", mec="k", ms=11, label="start"),
        Line2D([], [], ls="", marker="o", color="k", mfc="0.6", ms=5,
               label="keyphasor: 1 dot per forcing period (steady span)"),
    ]  # fmt: skip
    if drawing.first is None:  # nothing succeeded: no bold span, start or dots were drawn
        handles = []
    return handles, distance_text(drawing, unit_name)


def distance_text(drawing: OrbitDrawing, unit_name: str) -> str:
    """``max |w_b - w_a|`` of each method b against the first a, steady span and whole."""
    parts = []
    for name, steady in drawing.distance_steady.items():
        whole = drawing.distance_all.get(name)
        if steady is None and whole is None:
            parts.append(f"{name} vs {drawing.first}: not sampled alike")
            continue
        parts.append(
            f"max |Δw| {name} vs {drawing.first}: {_g(steady)} steady, {_g(whole)} whole run"
            f" ({unit_name})"
        )
    return "\n".join(parts)


def _g(value: float | None) -> str:
    return "-" if value is None else f"{value:.2g}"

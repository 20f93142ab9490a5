"""Orbits as an engineer reads them: the steady state visible, the transient faint.

``draw_orbits`` draws the orbits (y against x) of several solutions of one problem into
one matplotlib axes, used by ``rubcli run`` (orbit.png) and by the Figure 3 composite of
``rubcli compare`` (orbits.png):

- the transient (from the start to the last ``BOLD_PERIODS`` forcing periods) of the
  first successful method thin and faint, the start marked with a star; a long
  transient is drawn as whole periods (``display.period_subset``), so a long run never
  draws a million points;
- the last ``BOLD_PERIODS`` periods, interpolated at 720 points per period from the
  samples and their velocities (``display.hermite``), so that a whirl looks round. When
  they retrace one closed curve (``display.settled``: a periodic orbit) they are bold;
  when they fill a band (a torus, chaos, a transient still changing shape) only the last
  ``UNSETTLED_PERIODS`` are drawn, translucent, and the keyphasor points
  carry the structure;
- keyphasor dots: one per forcing period over the steady span (after the transient,
  ``display.steady_start``), the stroboscopic section: one dot for a period-one orbit, a
  closed curve for a quasi-periodic one. Older dots are lighter, so the dots a slow
  transient leaves behind do not blur the last ones;
- overlaid methods: the first successful method a thick line with large dots; each
  other one a thin solid line of a contrasting colour drawn on top, with small dots:
  where they agree, the thin line runs inside the thick one and each small dot sits in
  a large one, so both stay visible. Their largest distance from the first method is
  returned (and stated by the callers; ``display.difference`` gives it against time);
- failed methods: a dotted line up to where they failed, labelled with the tau of the
  failure and marked with a cross; they never set the axes (``display.orbit_radius``), so
  a diverged trace is clipped at the axes.

``legend_handles`` gives legend entries in the colours and markers actually drawn.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.colors import to_rgba

from rubcli.plotting import display
from rubcli.solution import Solution

if TYPE_CHECKING:
    from matplotlib.axes import Axes

COLORS = ("C0", "C3", "C2", "C1", "C4", "C5", "C6", "C8")
FIRST_LINE = 2.6  # the first method's bold orbit (points)
OTHER_LINE = 1.0  # every other method, drawn on top of it
# an orbit that does not settle: translucent, the first method wide and light, the
# others thin on top (as for a settled orbit) ...
FAINT_FIRST_LINE, FAINT_FIRST_ALPHA = 2.2, 0.35
FAINT_LINE, FAINT_ALPHA = 0.9, 0.8
UNSETTLED_PERIODS = 3.0  # ... over its last this many forcing periods only
TRANSIENT_LINE, TRANSIENT_ALPHA = 0.4, 0.25
# the second method solid, a third and later ones dashed or dotted: drawn on top of each
# other where they agree, each still shows through the gaps of the next
OVERLAY_DASHES = ("-", "-", (0, (5, 3)), (0, (1.5, 2)), (0, (6, 2, 1.5, 2)))
FIRST_DOT, OTHER_DOT = 6.5, 3.2  # keyphasor marker sizes (points)
OLDEST_DOT_ALPHA = 0.25  # the first keyphasor dot of the steady span; the last is opaque


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
    colors: dict[str, str] = field(default_factory=dict)  # each method's colour
    settled: dict[str, bool] = field(default_factory=dict)  # bold (True) or faint last periods
    artists: dict[str, dict[str, object]] = field(default_factory=dict)  # per method, by role


def draw_orbits(
    ax: Axes,
    solutions: Sequence[Solution],
    *,
    unit: float = 1.0,
    transient_periods: float | None = None,
    bold_periods: float = display.BOLD_PERIODS,
    label_methods: bool = True,
    radius: float | None = None,
) -> OrbitDrawing:
    """Draw the orbits of ``solutions`` (one problem) into ``ax``; see the module doc.

    ``unit`` scales clearances to the axes' unit (metres for a physical case).
    ``transient_periods`` fixes the start of the steady span (default: half the record).
    ``radius`` sets the half-width of the axes (in the axes' unit), e.g. one shared by
    several panels; default ``display.orbit_radius``.
    """
    # the states are relative to the stator's centre; drawn where the rotor is, about its
    # support's centre, with the clearance circle about the stator's (its offset); a
    # moving stator's at its rest position, its centre's path beside
    cx, cy = solutions[0].problem.params.offset if solutions else (0.0, 0.0)
    moving = bool(solutions) and solutions[0].stator_states is not None
    if moving:
        paths = {s.method: s.stator_states[:, :2] for s in solutions}
        solutions = [rotor_view(s) for s in solutions]
    if radius is None:  # the orbits, the clearance and the support's centre
        radius = unit * _radius_about_support(solutions, cx, cy)

    def at(x: np.ndarray | float, y: np.ndarray | float) -> tuple:
        return unit * (x + cx), unit * (y + cy)

    circle = np.linspace(0.0, 2.0 * np.pi, 721)
    ax.plot(*at(np.cos(circle), np.sin(circle)),
            label="clearance (stator at rest)" if moving else "clearance",
            **display.CLEARANCE_STYLE)  # fmt: skip
    if cx != 0.0 or cy != 0.0:
        # a ring about the start's star (a rotor at rest on its support starts there)
        ax.plot(0.0, 0.0, "o", ms=17, mfc="none", mec="0.2", mew=1.3, ls="none",
                label="support centre", zorder=5)  # fmt: skip
    drawing = OrbitDrawing(radius=radius)
    good = [s for s in solutions if s.success and display.finite_length(s) >= 2]
    first = good[0] if good else None
    drawing.first = None if first is None else first.method
    for index, sol in enumerate(solutions):
        color = COLORS[index % len(COLORS)]
        drawing.colors[sol.method] = color
        n = display.finite_length(sol)
        label = sol.method if label_methods else None
        if n == 0:
            continue
        if not sol.success or n < 2:
            drawing.failed[sol.method] = float(sol.t[n - 1])
            pts = display.period_subset(sol, float(sol.t[n - 1]))
            drawing.points += pts.shape[0]
            ax.plot(*at(pts[:, 0], pts[:, 1]), color=color, ls=":", lw=1.0, alpha=0.9,
                    label=f"{sol.method}: failed at tau = {sol.t[n - 1]:.6g}" if label_methods
                    else None)  # fmt: skip
            ax.plot(*at(sol.x[n - 1], sol.y[n - 1]), "X", color=color, ms=8, mec="k")
            continue
        main = sol is first
        artists = drawing.artists.setdefault(sol.method, {})
        period = sol.problem.params.period
        t_end = float(sol.t[n - 1])
        steady = display.steady_start(sol, transient_periods)
        bold = max(float(sol.t[0]), t_end - bold_periods * period)
        drawing.steady_from[sol.method] = steady
        drawing.bold_from[sol.method] = bold
        calm = display.settled(sol, bold)
        if not calm:  # fewer loops: a band of ten is a tangle even when faint
            bold = max(float(sol.t[0]), t_end - min(bold_periods, UNSETTLED_PERIODS) * period)
        drawing.settled[sol.method] = calm
        drawing.bold_from[sol.method] = bold
        faded = display.period_subset(sol, bold) if main else np.empty((0, 2))
        fine = display.fine_orbit(sol, bold)
        drawing.points += faded.shape[0] + fine.shape[0]
        if main:  # the others' transients would only blur it; their distance is stated
            (artists["transient"],) = ax.plot(
                *at(faded[:, 0], faded[:, 1]), color=color, lw=TRANSIENT_LINE,
                alpha=transient_alpha((bold - float(sol.t[0])) / period), zorder=2,
            )  # fmt: skip
        if calm:
            width, alpha = (FIRST_LINE, 1.0) if main else (OTHER_LINE, 1.0)
        else:
            width, alpha = (
                (FAINT_FIRST_LINE, FAINT_FIRST_ALPHA) if main else (FAINT_LINE, FAINT_ALPHA)
            )
        (artists["orbit"],) = ax.plot(
            *at(fine[:, 0], fine[:, 1]), color=color, lw=width, alpha=alpha,
            zorder=3 if main else 3 + index, ls=OVERLAY_DASHES[index % len(OVERLAY_DASHES)]
            if not main else "-", label=label,
        )  # fmt: skip
        if main:  # every method starts from the same state
            ax.plot(*at(sol.x[0], sol.y[0]), "*", color=color, ms=11, mec="k", mew=0.6,
                    zorder=6)  # fmt: skip
        dots = display.keyphasor(sol, transient_periods)
        drawing.keyphasor[sol.method] = int(dots.shape[0])
        drawing.points += dots.shape[0]
        artists["keyphasor"] = _keyphasor(ax, np.column_stack(at(dots[:, 0], dots[:, 1])), color,
                                          main)  # fmt: skip
        if not main:
            near = display.distance(first, sol, steady)
            drawing.distance_steady[sol.method] = _scaled(near, unit)
            drawing.distance_all[sol.method] = _scaled(display.distance(first, sol), unit)
    if moving and first is not None:
        n = display.finite_length(first)
        start = drawing.bold_from[first.method]
        last = first.t[:n] >= start
        path = paths[first.method][:n][last]
        periods = (float(first.t[n - 1]) - start) / first.problem.params.period
        ax.plot(*at(path[:, 0], path[:, 1]), color="0.25", lw=1.4, zorder=4,
                label=f"stator centre, last {periods:.3g} periods")  # fmt: skip
    ax.set_xlim(unit * cx - radius, unit * cx + radius)
    ax.set_ylim(unit * cy - radius, unit * cy + radius)
    ax.set_aspect("equal", adjustable="box")
    ax.grid(True, alpha=0.3)
    return drawing


def axes_radius(solutions: Sequence[Solution]) -> float:
    """The half-width (clearances) of the axes ``draw_orbits`` gives these solutions,
    about the stator's centre: the orbits as drawn (with a moving stator, the rotor's own
    motion), the clearance and the support's centre."""
    if not solutions:
        return display.orbit_radius([])
    cx, cy = solutions[0].problem.params.offset
    if solutions[0].stator_states is not None:
        solutions = [rotor_view(s) for s in solutions]
    return _radius_about_support(solutions, cx, cy)


def _radius_about_support(solutions: Sequence[Solution], cx: float, cy: float) -> float:
    """``axes_radius`` of solutions already in the rotor's own motion."""
    return max(display.orbit_radius(solutions), display.MARGIN * math.hypot(cx, cy))


def rotor_view(solution: Solution) -> Solution:
    """A moving stator's solution with the rotor's own motion as its states (relative
    plus the stator's displacement and velocity): what the orbit plot draws about the
    support's centre."""
    return replace(solution, states=solution.states + solution.stator_states,
                   stator_states=None)  # fmt: skip


def transient_alpha(periods: float) -> float:
    """Opacity of a faint transient of ``periods`` forcing periods: ``TRANSIENT_ALPHA`` up
    to 20 periods, less for longer ones (as 1/sqrt), so that hundreds of faint loops do
    not add up to a solid disc under the steady orbit."""
    return TRANSIENT_ALPHA * min(1.0, math.sqrt(20.0 / max(periods, 1e-9)))


def _keyphasor(ax, dots: np.ndarray, color: str, main: bool):
    """Keyphasor dots in the method's colour, the oldest lightest (``OLDEST_DOT_ALPHA``)."""
    n = dots.shape[0]
    alpha = np.linspace(OLDEST_DOT_ALPHA, 1.0, n) if n > 1 else np.ones(n)
    face = np.array([to_rgba(color, a) for a in alpha]).reshape(n, 4)
    if main:  # large, with a dark edge
        edge = np.array([to_rgba("k", a) for a in alpha]).reshape(n, 4)
        return ax.scatter(dots[:, 0], dots[:, 1], s=FIRST_DOT**2, c=face, edgecolors=edge,
                          linewidths=0.7, zorder=7)  # fmt: skip
    # small, with a white rim: visible inside a large dot of the first method
    return ax.scatter(dots[:, 0], dots[:, 1], s=OTHER_DOT**2, c=face, edgecolors="white",
                      linewidths=0.5, zorder=8)  # fmt: skip


def _scaled(value: float | None, unit: float) -> float | None:
    return None if value is None else unit * value


def legend_handles(
    drawing: OrbitDrawing | Sequence[OrbitDrawing], periods: float, unit_name: str
) -> tuple[list, str]:
    """Legend entries for the styles drawn (transient, last periods, start, keyphasor dots
    of each method, in its colour and marker) and a caption text.

    ``drawing`` may be the drawings of several panels (one legend for all). The caption
    states the distance between the methods, in ``unit_name`` (of a single drawing).
    """
    from matplotlib.lines import Line2D

    drawings = [drawing] if isinstance(drawing, OrbitDrawing) else list(drawing)
    text = distance_text(drawings[0], unit_name) if len(drawings) == 1 else ""
    drawn = [d for d in drawings if d.first is not None]
    if not drawn:  # nothing succeeded: no bold span, start or dots were drawn
        return [], text
    first = drawn[0].first
    color = drawn[0].colors[first]
    states = [calm for d in drawn for calm in d.settled.values()]
    calm, faint = all(states), not any(states)
    thin = min(periods, UNSETTLED_PERIODS)
    if calm:
        last = f"last {periods:g} forcing periods (bold)"
    elif faint:
        last = f"last {thin:g} forcing periods (light: the loops do not retrace one curve)"
    else:
        last = (f"last {periods:g} forcing periods bold (the last {thin:g}, light, where the "
                "loops do not retrace one curve)")  # fmt: skip
    handles = [
        Line2D([], [], color=color, lw=TRANSIENT_LINE + 0.4, alpha=TRANSIENT_ALPHA + 0.2,
               label=f"transient of {first} (faint)"),
        Line2D([], [], color=color, lw=FIRST_LINE if calm else FAINT_FIRST_LINE,
               alpha=1.0 if calm else FAINT_FIRST_ALPHA, label=last),
        Line2D([], [], ls="", marker="*", color=color, mec="k", ms=11, label="start"),
    ]  # fmt: skip
    counts: dict[str, list[int]] = {}
    colors: dict[str, str] = {}
    for d in drawn:
        for name, n in d.keyphasor.items():
            counts.setdefault(name, []).append(n)
            colors.setdefault(name, d.colors[name])
    for name, ns in counts.items():
        main = name == first
        many = f"{ns[0]}; " if len(drawings) == 1 else ""
        handles.append(
            Line2D([], [], ls="", marker="o", color=colors[name], mec="k" if main else "white",
                   ms=FIRST_DOT if main else OTHER_DOT + 1,
                   label=f"{name}: keyphasor, 1 dot per forcing period ({many}older lighter)")
        )  # fmt: skip
    return handles, text


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

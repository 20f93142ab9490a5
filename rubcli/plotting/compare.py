"""Figures of `rubcli compare`: work-precision, orbits (Figure 3 panels), error growth, Poincare.

Built on the Agg canvas without pyplot (as ``plotting.run``); save with
``rubcli.io.save_figure``. These functions draw analyses; they never solve.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from rubcli.analysis.accuracy.work_precision import Row, WorkPrecision
from rubcli.analysis.response.classification import PoincareSection, Response
from rubcli.plotting import display
from rubcli.plotting.display import CLEARANCE_STYLE
from rubcli.plotting.run import _line_style, _new_figure, failure_message

MARKERS = ("o", "s", "^", "v", "D", "P")


def _clearance(ax) -> None:
    circle = np.linspace(0.0, 2.0 * np.pi, 721)
    ax.plot(np.cos(circle), np.sin(circle), label="clearance", **CLEARANCE_STYLE)


def work_precision_figure(wp: WorkPrecision, title: str) -> Figure:
    """Max position error against median wall time, log-log, one line per method."""
    fig = _new_figure(9.0, 5.5)
    ax = fig.add_subplot()
    for index, method in enumerate(wp.methods):
        rows = [r for r in wp.rows_of(method) if r.success and r.error_max > 0]
        if not rows:
            continue
        times = [r.wall_time_s for r in rows]
        errors = [r.error_max for r in rows]
        (line,) = ax.loglog(times, errors, marker=MARKERS[index % len(MARKERS)], label=method)
        for r in rows:
            ax.annotate(
                r.label, (r.wall_time_s, r.error_max), textcoords="offset points",
                xytext=(4, 3), fontsize="x-small", color=line.get_color(),
            )  # fmt: skip
    ref = wp.reference
    if ref.error_estimate > 0:
        ax.axhline(ref.error_estimate, color="0.4", linestyle=":", linewidth=1.0,
                   label=f"reference error estimate ({ref.error_estimate:.1g})")  # fmt: skip
    ax.set_xlabel("wall time per solve (s, median of repeats)")
    ax.set_ylabel("max over samples of |w - w_ref| (clearances)")
    ax.grid(True, which="both", alpha=0.3)
    # beside the axes: inside, it would hide the fastest method's tightest settings
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    span = wp.problem.periods
    ax.set_title(
        f"{title}\nwork-precision over {span:.4g} forcing periods; labels: rtol or "
        "steps_per_period",
        fontsize="medium",
    )
    return fig


def error_growth_figure(wp: WorkPrecision, title: str) -> Figure:
    """|w - w_ref| against tau for each method at the middle setting of its ladder."""
    fig = _new_figure(7.5, 4.8)
    ax = fig.add_subplot()
    for index, method in enumerate(wp.methods):
        rows = [r for r in wp.rows_of(method) if r.errors is not None and r.errors.size]
        if not rows:
            continue
        row = rows[len(rows) // 2]
        err = np.where(row.errors > 0, row.errors, np.nan)
        ax.semilogy(row.t, err, label=f"{method} ({row.setting_name} = {row.label})",
                    **_line_style(index))  # fmt: skip
    ref = wp.reference
    if ref.deviation is not None:
        n = ref.n_trusted
        dev = np.where(ref.deviation[:n] > 0, ref.deviation[:n], np.nan)
        ax.semilogy(ref.t[:n], dev, color="0.3", linewidth=0.8,
                    label="reference error estimate")  # fmt: skip
    ax.set_xlabel("tau")
    ax.set_ylabel("|w - w_ref| (clearances)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title(f"{title}\nerror growth at the middle setting of each ladder", fontsize="medium")
    return fig


SCALE_RATIO = 2.5  # orbits.png: panels within this ratio of sizes share one scale


def shared_radii(radii: Sequence[float], ratio: float = SCALE_RATIO) -> list[float]:
    """The half-width of each panel's axes, shared: one scale for all the panels whose
    orbits are within ``ratio`` of the smallest one, and one (the largest) for the others.

    A single scale for orbits of 1.2 and 9 clearances (a rub and a dry whip) would shrink
    the rubs to a few pixels; one per panel makes sizes incomparable. Two scales, each
    shared, keep both readable and every size comparable within its group.
    """
    if not radii:
        return []
    small = min(radii)
    near = [r for r in radii if r <= ratio * small]
    far = [r for r in radii if r > ratio * small]
    r_near, r_far = max(near), max(far, default=0.0)
    return [r_near if r <= ratio * small else r_far for r in radii]


def orbits_figure(panels: Sequence[dict], title: str) -> Figure:
    """Orbits of several methods overlaid, one panel per case (a 2x3 grid for Figure 3).

    Each panel is ``{"title": str, "solutions": [Solution, ...], "note": str}`` and may
    give ``"transient_periods"`` (the start of the steady span of its keyphasor dots).
    Drawn as ``plotting.orbit.draw_orbits``: the transient faint, the last periods bold
    (thin where they do not retrace one curve), keyphasor dots; the distance between the
    methods is stated in each panel's title. The panels share their axes
    (``shared_radii``): a panel drawn at the larger of two scales says so in its title and
    shows the frame of the others as a dotted square.
    """
    from rubcli.plotting.orbit import axes_radius, distance_text, draw_orbits, legend_handles

    n = len(panels)
    cols = 3 if n > 4 else max(1, n) if n <= 2 else 2
    rows = math.ceil(n / cols)
    fig = _new_figure(max(6.8, 4.4 * cols), 4.7 * rows + 1.8)
    method_handles: dict[str, object] = {}
    drawings = []
    bold = display.BOLD_PERIODS
    radii = shared_radii([axes_radius(p["solutions"]) for p in panels])
    small = min(radii, default=1.0)
    for k, panel in enumerate(panels):
        ax = fig.add_subplot(rows, cols, k + 1)
        solutions = panel["solutions"]
        drawing = draw_orbits(ax, solutions, transient_periods=panel.get("transient_periods"),
                              radius=radii[k])  # fmt: skip
        drawings.append(drawing)
        spans = [display.recorded_periods(s) for s in solutions if s.success]
        bold = min([bold, *spans])
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            method_handles.setdefault(label, handle)
        ax.set_xlabel("x / clearance")
        ax.set_ylabel("y / clearance")
        lines = [panel["title"]]
        if panel.get("note"):
            lines.append(panel["note"])
        distance = distance_text(drawing, "clearances").replace(" (clearances)", "")
        if distance:
            lines.append(distance.replace("max |Δw| ", "max|Δw| "))
        if radii[k] > small:
            ax.add_patch(Rectangle((-small, -small), 2 * small, 2 * small, fill=False,
                                   ls=":", lw=1.0, ec="0.4", zorder=1))  # fmt: skip
            lines.append(f"axes {radii[k] / small:.1f}x wider; dotted: the other panels' frame")
        if failure_message(solutions):
            lines.append("every method failed")
        ax.set_title(f"({chr(ord('a') + k)}) " + "\n".join(lines), fontsize="small")
    if drawings:
        styles, _ = legend_handles(drawings, bold, "clearances")
        fig.legend(handles=list(method_handles.values()) + styles, loc="outside lower center",
                   ncols=3 if cols > 1 else 2, fontsize="small")  # fmt: skip
    fig.suptitle(title, fontsize="medium")
    return fig


def poincare_figure(
    sections: Sequence[tuple[str, PoincareSection, Response]], title: str
) -> Figure:
    """Stroboscopic sections (x, y) of each method, titled with its response class and
    the number of points; the panels share their axes as in ``orbits_figure``
    (``shared_radii``), and nothing but the data is drawn inside them."""
    n = max(1, len(sections))
    cols = min(3, n)
    rows = math.ceil(n / cols)
    fig = _new_figure(max(6.4, 4.2 * cols), 4.2 * rows + 0.9)
    sizes = []
    for _, section, _ in sections:
        pts = section.points
        r = float(np.max(np.hypot(pts[:, 0], pts[:, 1]))) if pts.shape[0] else 0.0
        sizes.append(display.MARGIN * max(1.0, r if math.isfinite(r) else 1.0))
    radii = shared_radii(sizes)
    small = min(radii, default=1.0)
    for k, (label, section, response) in enumerate(sections):
        ax = fig.add_subplot(rows, cols, k + 1)
        _clearance(ax)
        pts = section.points
        if pts.shape[0]:
            ax.plot(pts[:, 0], pts[:, 1], ".", ms=3)
        ax.set_xlim(-radii[k], radii[k])
        ax.set_ylim(-radii[k], radii[k])
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x / clearance")
        ax.set_ylabel("y / clearance")
        ax.grid(True, alpha=0.3)
        kind = response.kind
        if response.period:
            kind += f", period {response.period}"
        if response.lyapunov is not None:
            kind += f", lambda = {response.lyapunov.exponent:.3g}"
        head = f"{label}: {kind}\n{pts.shape[0]} section points"
        if radii[k] > small:
            ax.add_patch(Rectangle((-small, -small), 2 * small, 2 * small, fill=False,
                                   ls=":", lw=1.0, ec="0.4", zorder=1))  # fmt: skip
            head += f"; axes {radii[k] / small:.1f}x wider (dotted: the others' frame)"
        ax.set_title(head, fontsize="small")
    fig.suptitle(f"{title}\nstroboscopic Poincare section (one point per forcing period); "
                 "dashed: the clearance", fontsize="medium")  # fmt: skip
    return fig


def table_rows(rows: Sequence[Row]) -> list[list[str]]:
    """Rows for a text table (console or markdown)."""
    out = []
    for r in rows:
        out.append(
            [
                r.method,
                f"{r.setting_name} = {r.label}",
                f"{r.wall_time_s:.4g}",
                f"{r.error_max:.3g}",
                f"{r.error_final:.3g}",
                "-" if r.nsteps is None else str(r.nsteps),
                "-" if r.nfev is None else str(r.nfev),
                r.status,
            ]
        )
    return out

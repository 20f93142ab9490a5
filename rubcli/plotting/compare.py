"""Figures of `rubcli compare`: work-precision, orbits (Figure 3 panels), error growth, Poincare.

Built on the Agg canvas without pyplot (as ``plotting.run``); save with
``rubcli.io.save_figure``. These functions draw analyses; they never solve.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from rubcli.analysis.response import PoincareSection, Response
from rubcli.analysis.work_precision import Row, WorkPrecision
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


def orbits_figure(panels: Sequence[dict], title: str) -> Figure:
    """Orbits of several methods overlaid, one panel per case (a 2x3 grid for Figure 3).

    Each panel is ``{"title": str, "solutions": [Solution, ...], "note": str}`` and may
    give ``"transient_periods"`` (the start of the steady span of its keyphasor dots).
    Drawn as ``plotting.orbit.draw_orbits``: the transient faded, the last periods bold,
    keyphasor dots; the distance between the methods is stated in each panel's title.
    """
    from rubcli.plotting.orbit import distance_text, draw_orbits, legend_handles

    n = len(panels)
    cols = 3 if n > 4 else max(1, n) if n <= 2 else 2
    rows = math.ceil(n / cols)
    fig = _new_figure(max(6.4, 4.4 * cols), 4.6 * rows + 1.6)
    method_handles: dict[str, object] = {}
    drawing = None
    bold = display.BOLD_PERIODS
    for k, panel in enumerate(panels):
        ax = fig.add_subplot(rows, cols, k + 1)
        solutions = panel["solutions"]
        drawing = draw_orbits(ax, solutions, transient_periods=panel.get("transient_periods"))
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
        message = failure_message(solutions)
        if message:
            lines.append("every method failed")
        ax.set_title(f"({chr(ord('a') + k)}) " + "\n".join(lines), fontsize="small")
    if drawing is not None:
        styles, _ = legend_handles(drawing, bold, "clearances")
        fig.legend(handles=list(method_handles.values()) + styles, loc="outside lower center",
                   ncols=4, fontsize="small")  # fmt: skip
    fig.suptitle(title, fontsize="medium")
    return fig


def poincare_figure(
    sections: Sequence[tuple[str, PoincareSection, Response]], title: str
) -> Figure:
    """Stroboscopic sections (x, y) of each method, titled with its response class."""
    n = max(1, len(sections))
    cols = min(3, n)
    rows = math.ceil(n / cols)
    fig = _new_figure(max(6.4, 4.2 * cols), 4.2 * rows + 0.9)
    for k, (label, section, response) in enumerate(sections):
        ax = fig.add_subplot(rows, cols, k + 1)
        _clearance(ax)
        pts = section.points
        if pts.shape[0]:
            ax.plot(pts[:, 0], pts[:, 1], ".", ms=3, label=f"{pts.shape[0]} section points")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x / clearance")
        ax.set_ylabel("y / clearance")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="x-small")
        kind = response.kind
        if response.period:
            kind += f", period {response.period}"
        if response.lyapunov is not None:
            kind += f", lambda = {response.lyapunov.exponent:.3g}"
        ax.set_title(f"{label}: {kind}", fontsize="small")
    fig.suptitle(f"{title}\nstroboscopic Poincare section (one point per forcing period)",
                 fontsize="medium")  # fmt: skip
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

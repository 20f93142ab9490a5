"""Figure of continued whirls: radius and whirl rate against the parameter.

Two panels sharing the parameter axis: the whirl radius (clearances, log scale: a slip
whirl hugs the clearance while the rolling whirl is many clearances out) and the whirl
rate in orders of the running speed (negative: backward). Slip parts are drawn in one
colour, rolling parts in another; stable solid, unstable dashed; every located event is
numbered, marked on both panels and listed with its value in the legend. It only draws.
"""

from __future__ import annotations

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import NullFormatter, ScalarFormatter

from rubcli.analysis.orbits.whirls import MODE_NAMES, WhirlContinuation

MODE_COLOURS = {"rolling": "tab:purple", "slip+": "tab:red", "slip-": "tab:orange"}
EVENT_MARKERS = {"nonsmooth_fold": "s", "slip_roll_transition": "D", "fold": "s",
                 "hopf": "*", "real_eigenvalue_crossing": "P", "grazing": "v",
                 "radius_unbounded": "^"}  # fmt: skip
AXIS_LABELS = {
    "eta": "speed ratio eta = Omega/omega (-)",
    "mu": "friction coefficient mu (-)",
    "K": "stiffness ratio K (-)",
    "nu": "damping ratio nu (-)",
    "Rp": "rotor radius Rp (clearances)",
}


def whirl_figure(result: WhirlContinuation, title: str) -> Figure:
    fig = Figure(figsize=(8.0, 7.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax_r, ax_w = fig.subplots(2, 1, sharex=True)
    for branch in result.branches:
        for colour, style, run in _runs(branch.points):
            xs = [p.value for p in run]
            ax_r.plot(xs, [p.whirl.radius for p in run], style, color=colour, lw=1.6)
            ax_w.plot(xs, [p.whirl.order for p in run], style, color=colour, lw=1.6)
    handles = [
        Line2D([], [], color=MODE_COLOURS["slip+"], lw=1.6, label="slipping (dry whirl)"),
        Line2D([], [], color=MODE_COLOURS["rolling"], lw=1.6, label="rolling (dry whip)"),
        Line2D([], [], color="0.3", ls="-", label="stable"),
        Line2D([], [], color="0.3", ls="--", label="unstable (a saddle)"),
    ]
    if any(MODE_NAMES[p.whirl.mode] == "slip-" for p in result.rows()):
        handles.insert(1, Line2D([], [], color=MODE_COLOURS["slip-"], lw=1.6,
                                 label="slipping, v_r < 0"))  # fmt: skip
    for n, event in enumerate(result.events, start=1):
        w = event.point.whirl
        marker = EVENT_MARKERS.get(event.kind, "o")
        for ax, y in ((ax_r, w.radius), (ax_w, w.order)):
            ax.plot(event.value, y, marker, color="k", ms=8, mfc="none", mew=1.4)
            ax.annotate(str(n), (event.value, y), xytext=(6, 6), textcoords="offset points")
        label = f"{n}: {event.kind.replace('_', ' ')} at {result.parameter} = {event.value:.8g}"
        handles.append(Line2D([], [], marker=marker, color="k", ls="", mfc="none", label=label))
    for start in result.start_whirls:
        value = getattr(start.params, result.parameter)
        ax_r.plot(value, start.radius, "o", color="k", ms=4)
        ax_w.plot(value, start.order, "o", color="k", ms=4)
    handles.append(Line2D([], [], marker="o", color="k", ls="", ms=4, label="the case's whirls"))
    ax_r.axhline(1.0, color="0.5", lw=0.8, ls=":")
    ax_r.set_yscale("log")
    ax_r.yaxis.set_major_formatter(ScalarFormatter())
    ax_r.yaxis.set_minor_formatter(NullFormatter())
    ax_r.set_ylabel("whirl radius r (clearances, log)")
    ax_w.axhline(0.0, color="0.5", lw=0.8, ls=":")
    ax_w.set_ylabel("whirl rate W / eta (orders; < 0 backward)")
    ax_w.set_xlabel(AXIS_LABELS.get(result.parameter, result.parameter))
    for ax in (ax_r, ax_w):
        ax.grid(True, alpha=0.3)
    handles.append(Line2D([], [], color="0.5", lw=0.8, ls=":", label="clearance r = 1"))
    ax_r.legend(handles=handles, fontsize="small", loc="best")
    fig.suptitle(title, fontsize="medium")
    return fig


def _runs(points):
    """Consecutive points drawn as one line while mode and stability stay the same (so
    that dashes run on); a located event point ends one run and starts the next."""
    runs, current, key = [], [], None
    for a, b in zip(points[:-1], points[1:], strict=False):
        ref = b if a.label else a  # a segment takes its non-event end's mode and stability
        k = (MODE_COLOURS[MODE_NAMES[ref.whirl.mode]], "-" if ref.whirl.stable else "--")
        if k != key and current:
            runs.append((*key, current))
            current = [a]
        elif not current:
            current = [a]
        key = k
        current.append(b)
    if current:
        runs.append((*key, current))
    return runs

"""Figure of a stability chart: regions of the synchronous motions in a parameter plane.

The regions (``analysis.charts.stability``: free whirl only, synchronous rub only, both, neither)
fill the plane as an image in four fixed colours; the closed-form curves that bound them
(the free whirl's grazing, the rub's fold, the rub's stability boundary) are drawn as the
zero level of each curve's function on the chart's grid, one colour and dash per kind.
It only draws.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from rubcli.analysis.charts import stability as ch

if TYPE_CHECKING:
    from collections.abc import Sequence


REGION_COLOURS = {
    ch.NEITHER: "#d9d9d9",
    ch.FREE: "#a6cee3",
    ch.RUB: "#fdbf6f",
    ch.BOTH: "#b2df8a",
}
SWEEP_COLOURS = {  # the synchronous motions in their regions' colours
    "free whirl": REGION_COLOURS[ch.FREE],
    "synchronous rub": REGION_COLOURS[ch.RUB],
    "modulated full rub": "#ff7f00",
    "partial rub": "#fb9a99",
    "dry whip": "#cab2d6",
    "dry whirl": "#ffff99",
    "no result": "#ffffff",
}
CURVE_STYLES = {  # kind: (colour, line style)
    ch.FREE_GRAZING: ("#1f4e9c", "-"),
    ch.RUB_FOLD: ("#b30000", "--"),
    ch.RUB_STABILITY: ("#000000", ":"),
}
CURVE_LABELS = {
    ch.FREE_GRAZING: "grazing of the free whirl (|W| = 1)",
    ch.RUB_FOLD: "fold of the synchronous rub",
    ch.RUB_STABILITY: "stability boundary of the rub (Neimark-Sacker)",
}
SYMBOLS = {"eta": "eta = Omega / omega", "mu": "mu (friction)", "e": "e (unbalance / clearance)",
           "nu": "nu (damping ratio)", "K": "K (stator / rotor stiffness)",
           "Rp": "Rp (rotor radius / clearance)", "phi0": "phi0 (rad)"}  # fmt: skip


def _label(name: str) -> str:
    return SYMBOLS.get(name, name)


def chart_figure(
    chart: ch.Chart, title: str, here: tuple[float, float] | None = None,
    continued: Sequence[ch.ContinuedPoint] = (), sweep: ch.SweepMap | None = None,
) -> Figure:  # fmt: skip
    """The chart's regions and closed-form curves; ``here``: the case's own (x, y), marked
    where it lies in the plane; ``continued``: the points located by continuation
    (``charts.ContinuedPoint``), drawn on the curves as open markers; ``sweep``: a sweep
    of the plane (``analysis.charts.SweepMap``), what each of its points settled on drawn
    in a second panel under the same curves, on the same axes."""
    fig = Figure(figsize=(16.0, 6.8) if sweep is not None else (10.0, 6.5),
                 layout="constrained")  # fmt: skip
    FigureCanvasAgg(fig)
    if sweep is None:
        ax, right = fig.subplots(), None
    else:
        ax, right = fig.subplots(1, 2, sharex=True, sharey=True)
    codes = sorted(REGION_COLOURS)
    cmap = ListedColormap([REGION_COLOURS[c] for c in codes])
    norm = BoundaryNorm(np.arange(len(codes) + 1) - 0.5, cmap.N)
    ax.pcolormesh(chart.x, chart.y, chart.regions, cmap=cmap, norm=norm, shading="nearest",
                  rasterized=True)  # fmt: skip
    present = set(np.unique(chart.regions).tolist())
    handles: list = [
        Patch(color=REGION_COLOURS[c], label=ch.REGIONS[c]) for c in codes if c in present
    ]
    handles += _curves(ax, chart)
    if right is not None:
        handles += _sweep_panel(right, sweep)
        _curves(right, chart)
    for kind in ch.CURVE_KINDS:
        points = [p for p in continued if p.kind == kind]
        if not points:
            continue
        colour = CURVE_STYLES[kind][0]
        ax.plot([p.x for p in points], [p.y for p in points], linestyle="none", marker="o",
                markersize=8, markerfacecolor="white", markeredgecolor=colour,
                markeredgewidth=1.8, zorder=5)  # fmt: skip
        worst = max(p.deviation for p in points)
        handles.append(Line2D([], [], linestyle="none", marker="o", markerfacecolor="white",
                              markeredgecolor=colour, markeredgewidth=1.8,
                              label=f"located by continuation ({len(points)}; within "
                              f"{worst:.0e} of the line)"))  # fmt: skip
    if (
        here is not None
        and chart.x[0] <= here[0] <= chart.x[-1]
        and (chart.y[0] <= here[1] <= chart.y[-1])
    ):
        ax.plot(*here, marker="*", markersize=14, color="white", markeredgecolor="black",
                linestyle="none", clip_on=False)  # fmt: skip
        handles.append(Line2D([], [], marker="*", markersize=12, color="white",
                              markeredgecolor="black", linestyle="none",
                              label=f"the case: {chart.x_name} = {here[0]:g}, "
                              f"{chart.y_name} = {here[1]:g}"))  # fmt: skip
    if chart.log_x:
        ax.set_xscale("log")
    if chart.log_y:
        ax.set_yscale("log")
    ax.set_xlim(chart.x[0], chart.x[-1])
    ax.set_ylim(chart.y[0], chart.y[-1])
    ax.set_xlabel(_label(chart.x_name))
    ax.set_ylabel(_label(chart.y_name))
    if right is None:
        ax.set_title(title, fontsize="medium")
    else:
        fig.suptitle(title, fontsize="medium")
        ax.set_title("closed form: where each synchronous motion is stable", fontsize="medium")
        right.set_xlabel(_label(chart.x_name))
        right.set_title(f"simulated: what each point of the sweep settled on ({sweep.direction}"
                        f", {sweep.regimes.size} points)", fontsize="medium")  # fmt: skip
    fig.legend(handles=handles, loc="outside lower center", ncols=3 if right is not None else 2,
               fontsize="small", frameon=False)  # fmt: skip
    return fig


def _curves(ax, chart: ch.Chart) -> list:
    """The closed-form curves as the zero level of each curve's function; their handles."""
    handles = []
    for kind in ch.CURVE_KINDS:
        colour, style = CURVE_STYLES[kind]
        field = np.ma.masked_invalid(chart.fields.get(kind, np.full(chart.regions.shape, np.nan)))
        if not chart.curves.get(kind) or field.count() == 0:
            continue
        ax.contour(chart.x, chart.y, field, levels=[0.0], colors=[colour],
                   linestyles=[style], linewidths=1.8)  # fmt: skip
        handles.append(Line2D([], [], color=colour, linestyle=style, linewidth=1.8,
                              label=CURVE_LABELS[kind]))  # fmt: skip
    return handles


def _sweep_panel(ax, sweep) -> list:
    """The sweep's regimes as cells around its points; their handles."""
    colours = [SWEEP_COLOURS[name] for name in sweep.labels]
    cmap = ListedColormap(colours)
    norm = BoundaryNorm(np.arange(len(colours) + 1) - 0.5, cmap.N)
    ax.pcolormesh(sweep.x, sweep.y, sweep.regimes, cmap=cmap, norm=norm, shading="nearest",
                  rasterized=True)  # fmt: skip
    present = set(np.unique(sweep.regimes).tolist())
    return [Patch(facecolor=SWEEP_COLOURS[name], edgecolor="0.5", label=f"simulated: {name}")
            for i, name in enumerate(sweep.labels) if i in present]  # fmt: skip

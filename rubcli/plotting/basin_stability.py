"""Figure of a basin stability along a parameter: the share of starts on each attractor,
and the minimal perturbation off the free whirl.

Top: the fraction of the starts that end on each attractor against the parameter, each
with its 95 % Wilson band; the spans where the closed forms give both the free whirl and
a stable synchronous rub are shaded. Each series has its own colour, line style and
marker, the markers drawn smaller from one series to the next, so that series which
coincide (all at 0 where neither exists) all stay visible. Bottom (when computed): the
minimal perturbation found, its bracket as an error bar, and where it was not computable
or not found. It only draws.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from rubcli.analysis.ensembles.basin_stability import FREE_WHIRL, UNDECIDED, BasinStability
from rubcli.plotting.chart import SYMBOLS

COLOURS = {FREE_WHIRL: "#1f77b4", "synchronous rub": "#d62728", "dry whip": "#2ca02c",
           "dry whirl": "#9467bd", "partial rub": "#ff7f0e", UNDECIDED: "#7f7f7f"}  # fmt: skip
SPARE_COLOURS = ("#8c564b", "#e377c2", "#17becf", "#bcbd22", "#393b79", "#637939")
STYLES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "D", "v", "P", "X")
BOTH_COLOUR = "#b2df8a"  # the chart's colour of "both" (plotting.chart)


def _colours(labels: Sequence[str]) -> dict[str, str]:
    out, spare = {}, iter(SPARE_COLOURS * 4)
    used: set[str] = set()
    for label in labels:
        base = next((k for k in COLOURS if label == k or label.startswith(k + " ")), None)
        colour = COLOURS[base] if base is not None else next(spare)
        while colour in used:  # a second attractor of one regime: another colour
            colour = next(spare)
        used.add(colour)
        out[label] = colour
    return out


def basin_stability_figure(
    result: BasinStability, title: str, both_spans: Sequence[tuple[float, float]] = ()
) -> Figure:
    """The figure; ``both_spans``: (lo, hi) ranges of the parameter where the closed forms
    give both synchronous motions stable (shaded)."""
    perturbation = bool(result.perturbations)
    fig = Figure(figsize=(10.0, 8.5 if perturbation else 5.8), layout="constrained")
    FigureCanvasAgg(fig)
    if perturbation:
        ax, ax_p = fig.subplots(2, 1, sharex=True, height_ratios=(1.6, 1.0))
    else:
        ax, ax_p = fig.subplots(), None
    values = np.array(result.values)
    order = np.argsort(values)
    labels = result.labels
    colours = _colours(labels)
    handles: list = []
    for axes in (ax, ax_p):
        for lo, hi in both_spans if axes is not None else ():
            axes.axvspan(lo, hi, color=BOTH_COLOUR, alpha=0.3, lw=0, zorder=0)
    if both_spans:
        where = ", ".join(f"{lo:.3f} to {hi:.3f}" for lo, hi in both_spans)
        both = f"free whirl and synchronous rub both stable ({result.parameter} {where})"
        handles.append(Patch(color=BOTH_COLOUR, alpha=0.5, label=both))
    for k, label in enumerate(labels):
        f = [result.fractions(i)[label] for i in order]
        frac = np.array([x["fraction"] for x in f])
        lo = np.array([x["ci_low"] for x in f])
        hi = np.array([x["ci_high"] for x in f])
        colour, style, marker = colours[label], STYLES[k % len(STYLES)], MARKERS[k % len(MARKERS)]
        ax.fill_between(values[order], lo, hi, color=colour, alpha=0.18, lw=0, zorder=1)
        size = max(9.0 - 1.6 * k, 3.5)
        ax.plot(
            values[order],
            frac,
            linestyle=style,
            marker=marker,
            color=colour,
            lw=1.8,
            markersize=size,
            markerfacecolor="white" if k % 2 == 0 else colour,
            markeredgewidth=1.5,
            zorder=3 + k,
            clip_on=False,
        )  # (markers on 0 and 1 whole)
        handles.append(Line2D([], [], linestyle=style, marker=marker, color=colour, lw=1.8,
                              markersize=size, markeredgewidth=1.5,
                              markerfacecolor="white" if k % 2 == 0 else colour,
                              label=label))  # fmt: skip
    handles.append(Patch(color="0.5", alpha=0.25, label="95 % Wilson interval"))
    ax.set_ylim(0.0, 1.0)
    ax.set_ylabel("fraction of starts on the attractor")
    ax.grid(True, alpha=0.3)
    runs = sorted({result.good_runs(i) for i in range(len(values))})
    failed = sum(result.failed_runs(i) for i in range(len(values)))
    left_out = f"; {failed} failed runs left out" if failed else ""
    ax.set_title(f"basin stability: share of the {'/'.join(map(str, runs))} runs at each value "
                 f"that end on each attractor{left_out}", fontsize="medium")  # fmt: skip
    if ax_p is not None:
        handles += _perturbation_panel(ax_p, result)
    (ax_p if ax_p is not None else ax).set_xlabel(
        f"{SYMBOLS.get(result.parameter, result.parameter)} (nondimensional)"
    )
    span = float(np.ptp(values)) or 1.0
    ax.set_xlim(values.min() - 0.03 * span, values.max() + 0.03 * span)
    fig.suptitle(title, fontsize="medium")
    fig.legend(handles=handles, loc="outside lower center", ncols=2, fontsize="small",
               frameon=False)  # fmt: skip
    return fig


def _perturbation_panel(ax, result: BasinStability) -> list:
    """Draw the minimal perturbation at each value; returns the legend's handles."""
    found = [p for p in result.perturbations if p.found]
    handles: list = []
    if found:
        v = np.array([p.value for p in found])
        size = np.array([p.size for p in found])
        lower = np.array([p.lower for p in found])
        ax.errorbar(v, size, yerr=[size - lower, np.zeros_like(size)], fmt="o-", color="k",
                    ms=6, capsize=3, lw=1.4)  # fmt: skip
        handles.append(Line2D([], [], marker="o", color="k", lw=1.4,
                              label="minimal perturbation (an upper bound; bar: its "
                              "bracket)"))  # fmt: skip
    top = max([p.size for p in found] + [0.0])
    missing = [p for p in result.perturbations if p.computable and not p.found]
    limit = result.settings.get("perturbation_max", math.nan)
    if missing:
        y = limit if math.isfinite(limit) else top
        ax.plot([p.value for p in missing], [y] * len(missing), "^", color="tab:orange",
                ms=8, linestyle="none")  # fmt: skip
        none = f"none found up to {limit:g} (every direction returned)"
        handles.append(Line2D([], [], marker="^", color="tab:orange", linestyle="none",
                              label=none))  # fmt: skip
        top = max(top, y)
    absent = [p for p in result.perturbations if not p.computable]
    if absent:
        ax.plot([p.value for p in absent], [0.0] * len(absent), "x", color="0.35", ms=8,
                mew=2, linestyle="none", clip_on=False)  # fmt: skip
        for p in absent:  # why, in short: "no free whirl", "no rub"
            ax.annotate(p.reason.split(":")[0], (p.value, 0.0), xytext=(0, 8),
                        textcoords="offset points", rotation=90, ha="center", va="bottom",
                        fontsize="x-small", color="0.35")  # fmt: skip
        handles.append(Line2D([], [], marker="x", color="0.35", mew=2, linestyle="none",
                              label="minimal perturbation not computable there"))  # fmt: skip
    ax.set_ylim(0.0, 1.12 * top if top > 0 else 1.0)
    ax.set_ylabel("minimal perturbation\n|d(x, y, vx, vy)| (clearances)")
    n = max((p.directions_tried for p in result.perturbations), default=0)
    ax.set_title(f"smallest perturbation of the free whirl that ends off it, over {n} "
                 "directions", fontsize="medium")  # fmt: skip
    ax.grid(True, alpha=0.3)
    return handles

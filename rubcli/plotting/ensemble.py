"""Figure of an ensemble: where the runs end, and how long the transient lasts.

Left: the fraction of runs on each attractor with its 95 % Wilson interval. Right: the
Kaplan-Meier survival of the transient (runs not yet on a regular attractor) against
forcing periods, with the exponential law of the fitted mean lifetime and its 95 % band,
and each escape marked by the attractor it reached. It only draws.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from rubcli.analysis.ensembles.ensemble import EnsembleResult


def ensemble_figure(result: EnsembleResult, title: str) -> Figure:
    fig = Figure(figsize=(12.0, 5.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax_f, ax_s = fig.subplots(1, 2, width_ratios=(1.0, 1.3))
    outcomes = result.outcomes()
    names = list(outcomes)
    y = np.arange(len(names))
    frac = np.array([outcomes[n]["fraction"] for n in names])
    lo = frac - np.array([outcomes[n]["lower"] for n in names])
    hi = np.array([outcomes[n]["upper"] for n in names]) - frac
    colours = [f"C{i}" for i in range(len(names))]
    ax_f.barh(y, frac, xerr=[lo, hi], color=colours, capsize=4)
    for k, n in zip(y, names, strict=True):
        ax_f.annotate(f"{outcomes[n]['runs']}", (frac[k], k), xytext=(4, -12),
                      textcoords="offset points", fontsize="small")  # fmt: skip
    ax_f.set_yticks(y, names)
    ax_f.invert_yaxis()
    ax_f.set_xlim(0.0, 1.0)
    ax_f.set_xlabel("fraction of runs (bar: 95 % Wilson interval; number: runs)")
    ax_f.set_title(f"where {len(result.good)} runs end", fontsize="medium")
    ax_f.grid(True, axis="x", alpha=0.3)

    life = result.lifetimes()
    curve = life["kaplan_meier"]
    t = [0.0] + [c[0] for c in curve] + [float(result.periods)]
    s = [1.0] + [c[1] for c in curve] + [curve[-1][1] if curve else 1.0]
    ax_s.step(t, s, where="post", color="k", lw=1.6, label="Kaplan-Meier: runs still in transient")
    mean = life["mean_lifetime"]
    grid = np.linspace(0.0, result.periods, 200)
    if mean["mean"]:
        ax_s.plot(grid, np.exp(-grid / mean["mean"]), "--", color="tab:gray",
                  label=f"exp(-t / {mean['mean']:.0f}): mean lifetime, 95 % band")  # fmt: skip
        ax_s.fill_between(grid, np.exp(-grid / mean["lower"]), np.exp(-grid / mean["upper"]),
                          color="tab:gray", alpha=0.2)  # fmt: skip
    colour_of = dict(zip(names, colours, strict=True))
    for m in result.good:
        if m.settled:
            surv = next((c[1] for c in curve if c[0] == m.settle_period), None)
            if surv is not None:
                ax_s.plot(m.settle_period, surv, "o", color=colour_of[m.attractor], ms=5)
    ax_s.set_ylim(0.0, 1.02)
    ax_s.set_xlim(0.0, result.periods)
    ax_s.set_xlabel(f"forcing periods (T = {result.period_tau:.4g} tau)")
    ax_s.set_ylabel("fraction of runs not yet on a regular attractor")
    ax_s.set_title(f"lifetime of the transient: {life['escaped']} escaped, "
                   f"{life['censored']} still in it at {result.periods} periods",
                   fontsize="medium")  # fmt: skip
    ax_s.grid(True, alpha=0.3)
    ax_s.plot([], [], "o", color="0.4", ms=5, label="an escape (colour: the attractor reached)")
    # below the axes: inside, it would cover the curve's start and the escapes near 1
    ax_s.legend(fontsize="small", loc="upper center", bbox_to_anchor=(0.5, -0.12), ncols=2)
    fig.suptitle(title, fontsize="medium")
    return fig

"""The energy-balance figure of a run (``plots = ["energy"]``): terms and residual vs tau.

One row per method: on the left the change of mechanical energy and the cumulative work
and dissipation terms (``rubcli.analysis.energy.balance``); on the right the residual of the
balance relative to the throughput, on a log scale from a decade below the estimated
quadrature floor (drawn), so the part of the residual that carries information is readable.
Draws given balances only; it never solves.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from rubcli import units
from rubcli.analysis.energy.balance import EnergyBalance
from rubcli.plotting import display
from rubcli.plotting.run import _message_box, _new_figure
from rubcli.solution import Solution

RESIDUAL_BOTTOM = 1e-18  # the residual axis never reaches below this (relative)
SPIN_HEADROOM = 1.8  # the spin-drive axis spans this many times its curve's range


def residual_limits(relative: np.ndarray, quadrature_error: float) -> tuple[float, float]:
    """(bottom, top) of the log residual axis: a decade below the quadrature floor or
    the residual's 5th percentile (whichever is lower), and above its largest value.

    Exact zeros (the first node) would otherwise pull a log axis down to 1e-308 and
    squash everything readable into its top decade; they are drawn at the bottom.
    """
    positive = relative[np.isfinite(relative) & (relative > 0.0)]
    low = [float(np.percentile(positive, 5.0))] if positive.size else []
    if quadrature_error > 0.0:
        low.append(quadrature_error)
    bottom = max(RESIDUAL_BOTTOM, 0.1 * min(low)) if low else RESIDUAL_BOTTOM
    high = [bottom * 10.0, quadrature_error]
    if positive.size:
        high.append(float(np.max(positive)))
    return bottom, 3.0 * max(high)


def energy_figure(
    solutions: Sequence[Solution],
    balances: Sequence[EnergyBalance],
    title: str,
    *,
    scale: units.PhysicalScale | None = None,
) -> Figure:
    """Energy terms and the relative residual against tau, one row per solution.

    Energies in units of k_r c^2 (c the clearance), or joules when ``scale`` is given;
    time in tau, or seconds. The residual panel is logarithmic from a decade below its
    quadrature floor (drawn, with the band below it shaded: a residual there says
    nothing about the solver). Long series are drawn as min/max envelopes; legends sit
    beside the axes.
    """
    rows = max(1, len(solutions))
    fig = _new_figure(12.0, 2.7 * rows + 0.9)
    axes = np.atleast_2d(fig.subplots(rows, 2, sharex=True, squeeze=False))
    joule = None if scale is None else scale.k_r * scale.clearance**2
    unit_name = "k_r c²" if scale is None else "J"
    if not solutions:
        _message_box(axes[0, 0], "Every method failed; no solution to balance.")
    for row, (solution, balance) in enumerate(zip(solutions, balances, strict=True)):
        terms, resid = axes[row]
        label = solution.method if solution.success else f"{solution.method} (failed)"
        if balance.tau.size == 0:
            _message_box(terms, f"{label}: no samples")
            continue
        tau = balance.tau if scale is None else units.seconds(balance.tau, scale)
        k = 1.0 if joule is None else joule
        delta = balance.energy - balance.energy[0]
        series = [
            (delta, {"color": "k", "lw": 1.4, "label": "ΔE (kinetic + springs)"}),
            (balance.work_unbalance, {"lw": 1.0, "label": "W_in unbalance"}),
            (balance.damping, {"lw": 1.0, "label": "D_damp"}),
            (balance.friction, {"lw": 1.0, "label": "D_fric (on translation)"}),
        ]
        for values, style in series:
            terms.plot(*display.envelope(tau, k * values), **style)
        terms.set_ylabel(f"{label}\nenergy ({unit_name})")
        terms.grid(True, alpha=0.3)
        anchor = (1.01, 1.0)
        if np.any(balance.spin_drive != 0.0):
            # the work of the spin on the contact is not in the balance and can be 10-100x
            # its terms: on its own axis, so that it does not flatten them
            spin = terms.twinx()
            spin.plot(*display.envelope(tau, k * balance.spin_drive), color="tab:red", lw=1.2,
                      ls=":", label="spin drive T Rp eta (right axis)")  # fmt: skip
            # Both axes autoscale and the spin drive grows like W_in: its own range would lay
            # it on W_in's curve. Its axis reaches to SPIN_HEADROOM times its extent, so it
            # runs through the middle of the panel instead.
            low, high = spin.get_ylim()
            spin.set_ylim(low, low + SPIN_HEADROOM * (high - low))
            spin.set_ylabel(f"spin drive ({unit_name})", color="tab:red", fontsize="small")
            spin.tick_params(axis="y", colors="tab:red", labelsize="small")
            handles, labels = terms.get_legend_handles_labels()
            more, more_labels = spin.get_legend_handles_labels()
            terms.legend(handles + more, labels + more_labels, loc="upper left",
                         bbox_to_anchor=(1.16, 1.0), fontsize="x-small")  # fmt: skip
        else:
            terms.legend(loc="upper left", bbox_to_anchor=anchor, fontsize="x-small")
        norm = balance.throughput if balance.throughput > 0 else 1.0
        relative = np.abs(balance.residual) / norm
        bottom, top = residual_limits(relative, balance.quadrature_error)
        te, re = display.envelope(tau, np.maximum(relative, bottom))
        resid.semilogy(te, re, lw=1.0, label="|residual| / throughput")
        if balance.quadrature_error > 0:
            resid.axhspan(bottom, balance.quadrature_error, color="0.9", zorder=0)
            floor = "quadrature floor (estimate);\nbelow it: no information"
            resid.axhline(balance.quadrature_error, color="0.3", ls="--", lw=1.0, label=floor)
        resid.set_ylim(bottom, top)
        resid.set_ylabel("relative residual")
        resid.grid(True, which="major", alpha=0.3)
        resid.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="x-small")
        resid.set_title(f"energy_residual = {balance.relative_residual:.3g}", fontsize="small")
    xlabel = "tau = omega t" if scale is None else "t (s)"
    axes[-1, 0].set_xlabel(xlabel)
    axes[-1, 1].set_xlabel(xlabel)
    fig.suptitle(title, fontsize="medium")
    return fig

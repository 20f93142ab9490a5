"""The energy-balance figure of a run (``plots = ["energy"]``): terms and residual vs tau.

One row per method: on the left the change of mechanical energy and the cumulative work
and dissipation terms (``rubcli.analysis.energy``); on the right the residual of the
balance relative to the throughput, on a log scale, with the estimated quadrature floor.
Draws given balances only; it never solves.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from rubcli.analysis.energy import EnergyBalance
from rubcli.plotting.run import _new_figure
from rubcli.solution import Solution


def energy_figure(
    solutions: Sequence[Solution], balances: Sequence[EnergyBalance], title: str
) -> Figure:
    """Energy terms and the relative residual against tau, one row per solution."""
    rows = max(1, len(solutions))
    fig = _new_figure(11.0, 2.6 * rows + 0.8)
    axes = np.atleast_2d(fig.subplots(rows, 2, sharex=True, squeeze=False))
    for row, (solution, balance) in enumerate(zip(solutions, balances, strict=True)):
        terms, resid = axes[row]
        label = solution.method if solution.success else f"{solution.method} (failed)"
        if balance.tau.size == 0:
            terms.text(0.5, 0.5, "no samples", ha="center", transform=terms.transAxes)
            continue
        tau = balance.tau
        delta = balance.energy - balance.energy[0]
        terms.plot(tau, delta, color="k", lw=1.4, label="ΔE (kinetic + springs)")
        terms.plot(tau, balance.work_unbalance, lw=1.0, label="W_in unbalance")
        terms.plot(tau, balance.damping, lw=1.0, label="D_damp")
        terms.plot(tau, balance.friction, lw=1.0, label="D_fric (on translation)")
        if np.any(balance.spin_drive != 0.0):
            terms.plot(tau, balance.spin_drive, lw=0.8, ls=":", label="spin drive T Rp eta")
        terms.set_ylabel(f"{label}\nenergy")
        terms.grid(True, alpha=0.3)
        terms.legend(loc="upper left", fontsize="x-small")
        scale = balance.throughput if balance.throughput > 0 else 1.0
        relative = np.abs(balance.residual) / scale
        floor = np.finfo(float).tiny
        resid.semilogy(tau, np.maximum(relative, floor), lw=1.0, label="|residual| / throughput")
        if balance.quadrature_error > 0:
            resid.axhline(
                balance.quadrature_error, color="0.4", ls="--", lw=0.8, label="quadrature estimate"
            )
        resid.set_ylabel("relative residual")
        resid.grid(True, which="both", alpha=0.3)
        resid.legend(loc="lower right", fontsize="x-small")
        resid.set_title(f"energy_residual = {balance.relative_residual:.3g}", fontsize="small")
    axes[-1, 0].set_xlabel("tau = omega t")
    axes[-1, 1].set_xlabel("tau = omega t")
    fig.suptitle(title, fontsize="medium")
    return fig

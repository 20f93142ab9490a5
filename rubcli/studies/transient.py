"""The products of a run whose speed changes (``rubcli run`` on a case with [speed]):
order tracking per revolution, the rub's onset and end, the full-spectrum cascade
(``analysis.order_tracking``), and the figures engineers read from a run-up or a
coast-down (``plotting.transient``): bode.png, polar.png, cascade.png, orbits.png.
Speeds are drawn in rpm for a [physical] case.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rubcli.analysis import order_tracking as ot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from rubcli.case import Case
    from rubcli.solution import Solution

FIGURES = ("bode", "polar", "cascade", "orbits")


@dataclass(frozen=True)
class Transient:
    """One solution's order tracking, rub events, summary and cascade."""

    method: str
    revolutions: ot.Revolutions
    events: ot.RubEvents
    summary: ot.TransientSummary
    cascade: ot.OrderCascade | None  # None: too few revolutions for one window
    rpm_per_eta: float | None  # a [physical] case: rpm of eta = 1

    def to_dict(self) -> dict[str, Any]:
        """report.json's ``transient`` entry."""
        return self.summary.to_dict(self.rpm_per_eta)


def analyse(case: Case, solution: Solution) -> Transient | str:
    """The transient products of ``solution``, or why there are none (a run that failed
    before a revolution, a record without a whole revolution)."""
    n = solution.t.size
    if n < 2 or not np.all(np.isfinite(solution.states)):
        return f"{solution.method}: no transient analysis ({solution.status}: {solution.message})"
    tau, x, y = solution.t, solution.x, solution.y
    phase, eta = solution.phase, solution.speed
    try:
        revolutions, events, summary = ot.analyse_transient(tau, x, y, phase, eta, solution.regimes)
    except ValueError as exc:
        return f"{solution.method}: no transient analysis ({exc})"
    if len(revolutions) == 0:
        return f"{solution.method}: no transient analysis (not one whole revolution)"
    try:
        cascade = ot.order_cascade(tau, x, y, phase)
    except ValueError:
        cascade = None
    rpm = ot.rpm_per_eta(case.scale.omega) if case.scale is not None else None
    return Transient(solution.method, revolutions, events, summary, cascade, rpm)


def figures(case: Case, solution: Solution, transient: Transient) -> dict[str, Figure]:
    """The transient figures by name (``FIGURES``; cascade.png only when a window fits)."""
    from rubcli.plotting import transient as plots
    from rubcli.plotting.run import parameters_title

    units = {"speed_unit": "rpm" if transient.rpm_per_eta else "eta",
             "rpm_per_eta": transient.rpm_per_eta}  # fmt: skip
    speed_text = case.problem.speed.text() if case.problem.speed is not None else None
    title = f"{parameters_title(case.name, case.params, speed=speed_text)} ({solution.method})"
    out = {
        "bode": plots.bode_figure(transient.revolutions, transient.events, title=title, **units),
        "polar": plots.polar_figure(transient.revolutions, title=title, **units),
    }
    if transient.cascade is not None:
        out["cascade"] = plots.cascade_figure(
            transient.cascade, params=case.params, title=title, **units
        )
    speed = case.settings.speed
    snapshots = speed.snapshot_etas(case.scale) if speed is not None else None
    out["orbits"] = plots.orbit_snapshots_figure(
        solution.t, solution.x, solution.y, transient.revolutions, speeds=snapshots,
        title=title, **units,
    )  # fmt: skip
    return out

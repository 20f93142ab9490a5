"""The products of a run whose speed changes (``rubcli run`` on a case with [speed]):
order tracking per revolution, the rub's onset and end, the full-spectrum cascade
(``analysis.response.order_tracking``), and the figures engineers read from a run-up or a
coast-down (``plotting.transient``): bode.png, polar.png, cascade.png, orbits.png.
Speeds are drawn in rpm for a [physical] case.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rubcli.analysis.energy.drive_torques import DriveTorques, drive_summary, revolution_means
from rubcli.analysis.response import order_tracking as ot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from rubcli.case import Case
    from rubcli.plotting.transient import SteadyStates
    from rubcli.solution import Solution

FIGURES = ("bode", "polar", "cascade", "orbits")
DRIVE_FIGURES = ("drive",)  # a driven rotor's, besides


@dataclass(frozen=True)
class Transient:
    """One solution's order tracking, rub events, summary and cascade."""

    method: str
    revolutions: ot.Revolutions
    events: ot.RubEvents
    summary: ot.TransientSummary
    cascade: ot.OrderCascade | None  # None: too few revolutions for one window
    rpm_per_eta: float | None  # a [physical] case: rpm of eta = 1
    torques: DriveTorques | None = None  # a driven rotor's
    drive: dict[str, Any] | None = None  # a driven rotor's summary (``drive_summary``)

    def to_dict(self) -> dict[str, Any]:
        """report.json's ``transient`` entry (a driven rotor's with its ``drive``)."""
        out = self.summary.to_dict(self.rpm_per_eta)
        if self.drive is not None:
            out["drive"] = dict(self.drive)
            if self.rpm_per_eta:  # a [physical] case: the speeds in rpm beside
                for key in ("start_speed", "final_speed", "max_speed", "min_speed",
                            "motor_free_speed"):  # fmt: skip
                    out["drive"][f"{key}_rpm"] = self.drive[key] * self.rpm_per_eta
        return out


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
    torques = drive = None
    if case.problem.drive is not None:
        torques = revolution_means(solution)
        drive = drive_summary(solution, torques)
    return Transient(solution.method, revolutions, events, summary, cascade, rpm, torques, drive)


def figures(
    case: Case, solution: Solution, transient: Transient, steady: SteadyStates | None = None
) -> dict[str, Figure]:
    """The transient figures by name (``FIGURES``; cascade.png only when a window fits);
    ``steady``: a sweep's steady states under the Bode plot (``load_steady``)."""
    from rubcli.plotting import transient as plots
    from rubcli.plotting.run import parameters_title

    units = {"speed_unit": "rpm" if transient.rpm_per_eta else "eta",
             "rpm_per_eta": transient.rpm_per_eta}  # fmt: skip
    speed_text = case.speed_text()
    title = f"{parameters_title(case.name, case.params, speed=speed_text)} ({solution.method})"
    out = {
        "bode": plots.bode_figure(
            transient.revolutions, transient.events, title=title, steady=steady, **units
        ),
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
    if transient.torques is not None:
        out["drive"] = _drive_figure(case, transient, title)
    return out


def _drive_figure(case: Case, transient: Transient, title: str) -> Figure:
    """drive.png, in seconds and N m for a [physical] case."""
    from rubcli.plotting.drive import drive_figure
    from rubcli.plotting.transient import speed_axis

    scale = case.scale
    speed = speed_axis("rpm" if transient.rpm_per_eta else "eta", transient.rpm_per_eta)
    units = {}
    if scale is not None:
        units = {"time_factor": 1.0 / scale.omega, "time_label": "time t (s)",
                 "torque_factor": scale.k_r * scale.clearance**2,
                 "torque_label": "torque (N m)"}  # fmt: skip
    drive = case.problem.drive
    return drive_figure(transient.torques, speed=speed, free_speed=drive.free_speed(),
                        title=title, **units)  # fmt: skip


def load_steady(path: Path, case: Case) -> SteadyStates | list[str]:
    """The steady states of a ``rubcli sweep`` over eta of the same machine (``--overlay``),
    or the problems that keep it from being drawn under this run's Bode plot."""
    from rubcli.plotting.transient import SteadyStates
    from rubcli.studies.sweep import open_overlay, other_machine

    if not case.problem.changes_speed:
        return [f"{case.source}: --overlay draws under a run-up's Bode plot: the case has no "
                "[speed]"]  # fmt: skip
    ds = open_overlay(path)
    if isinstance(ds, list):
        return ds
    with ds:
        missing = [n for n in ("eta", "z_max", "direction") if n not in ds.variables]
        if missing:
            return [f"{path}: --overlay: not a rubcli sweep over eta: no {', '.join(missing)}"]
        if "spectrum" not in ds.variables:
            return [f"{path}: --overlay: the sweep has no spectrum, so no 1X to draw: run it "
                    "with [sweep] spectrum = true"]  # fmt: skip
        extra = [d for d in ds["z_max"].dims if d not in ("direction", "eta")]
        if extra:
            return [f"{path}: --overlay: the sweep also varies {', '.join(map(str, extra))}: "
                    "only a sweep over eta alone is a branch under the Bode plot"]  # fmt: skip
        differ = other_machine(ds, case.params, ("eta", "phi0"))
        if differ:
            return [f"{path}: --overlay: another machine: {', '.join(differ)}"]
        one_x = ds["spectrum"].sel(order=1.0, method="nearest")
        if not math.isclose(float(one_x["order"]), 1.0, abs_tol=1e-9):
            return [f"{path}: --overlay: the sweep's spectrum has no order 1 line"]
        directions = [str(d) for d in ds["direction"].values]
        return SteadyStates(
            eta=np.asarray(ds["eta"].values, dtype=float),
            forward_1x={d: np.asarray(one_x.sel(direction=d).values, float) for d in directions},
            z_max={d: np.asarray(ds["z_max"].sel(direction=d).values, float) for d in directions},
            source=Path(path).name,
        )

"""The terminal summary of a run (``rubcli run`` prints it): the span of the run, the
table of its methods' results and the line of a run whose speed changes."""

from __future__ import annotations

import math
from typing import Any

from rubcli.problem import Problem

COLUMNS = ("method", "status", "wall s", "steps", "events", "contact", "max pen", "E resid")
CAPTION = (
    "events: located switches; contact: share of time in contact; max pen: largest "
    "penetration (clearances); E resid: energy-balance residual (report.json)"
)


def span_text(problem: Problem) -> str:
    """What the run covers: its periods, its speed profile or its drive, and tau."""
    if problem.drive is not None:
        return f"{problem.drive.text()}, tau 0 .. {problem.t_span[1]:.6g}"
    if problem.speed is None:
        return f"{problem.periods:g} periods (tau 0 .. {problem.t_span[1]:.6g})"
    turns = problem.speed.phase(problem.t_span[1], 0.0) - problem.speed.phase(0.0, 0.0)
    revolutions = turns / (2.0 * math.pi)
    return f"{problem.speed.text()}, tau 0 .. {problem.t_span[1]:.6g} ({revolutions:.0f} turns)"


def summary_rows(entries: dict[str, dict[str, Any]]) -> list[list[str]]:
    """One row of ``COLUMNS`` per method of the report's entries."""
    rows = []
    for name, e in entries.items():
        stats = e.get("stats", {})
        steps = stats.get("nsteps")
        fraction = e.get("contact_fraction")
        penetration = e.get("max_penetration")
        residual = e.get("energy_residual")
        rows.append(
            [
                name,
                e["status"],
                f"{e['wall_time_s']:.3f}",
                "-" if steps is None else str(steps),
                str(e.get("n_contact_switches", "-")),
                "-" if fraction is None else f"{100 * fraction:.1f}%",
                "-" if penetration is None else f"{penetration:.4g}",
                "-" if residual is None else f"{residual:.2g}",
            ]
        )
    return rows


def transient_line(method: str, transient: dict) -> str:
    """One line of a run whose speed changes: the 1X peak and the rub's speeds."""
    if "note" in transient:
        return transient["note"]
    rpm = "peak_1x_forward_rpm" in transient
    unit, key = ("rpm", "rpm") if rpm else ("", "eta")

    def speed(name: str) -> str:
        value = transient.get(f"{name}_{key}")
        if value is None:
            return "-"
        return f"{value:.0f} {unit}".strip() if rpm else f"eta {value:.4g}"

    end = speed("rub_end") if transient.get("rub_end_eta") is not None else "still rubbing"
    if transient.get("rub_onset_eta") is None:
        rub = "no rub"
    else:
        rub = f"rub from {speed('rub_onset')} to {end}, {transient['rub_transitions']} rub starts"
    line = (
        f"{method}: peak 1X {transient['peak_1x_forward_amplitude']:.4g} clearances at "
        f"{speed('peak_1x_forward')}; {rub} over {transient['revolutions']} revolutions"
    )
    drive = transient.get("drive")
    if drive is not None:  # a driven rotor: where its speed went
        captured = ", captured" if drive["captured"] else ""
        if rpm:
            went = f"{drive['start_speed_rpm']:.0f} to {drive['final_speed_rpm']:.0f} rpm"
        else:
            went = f"eta {drive['start_speed']:.4g} to {drive['final_speed']:.4g}"
        line += f"; speed {went}{captured}"
    return line

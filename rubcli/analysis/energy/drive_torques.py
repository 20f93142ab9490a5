"""The torques on a driven rotor's spin (``rubcli.drive``), sample by sample and as
means over each revolution, and the summary report.json gives of a driven run.

The drive's equation ``j p'' = Q0(w) - Rp T - e t . w''`` splits the torque on the spin
into the motor's less drag ``Q0``, the rub's ``-Rp T`` (the tangential force's moment
about the geometric centre) and the unbalance's reaction ``-e t . w''`` (the vibration
the drive keeps up); their sum is the inertia's ``j p''``. The accelerations come from
the equations at each sample (``compiled.drive.driven_columns``), so the balance holds
to round-off at every sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rubcli import model
from rubcli.solution import Solution


@dataclass(frozen=True)
class DriveTorques:
    """Per-revolution means (``tau`` the revolution's middle) beside the samples'
    speed; torques nondimensional (over ``k_r gamma^2``)."""

    tau: np.ndarray
    motor: np.ndarray
    rub: np.ndarray
    vibration: np.ndarray
    inertia: np.ndarray
    radius: np.ndarray  # the revolution's largest radius
    contact: np.ndarray  # the revolution's share of samples in contact
    tau_samples: np.ndarray
    speed_samples: np.ndarray


def sample_torques(solution: Solution) -> dict[str, np.ndarray]:
    """The torques on the spin at every sample: motor (less drag), rub, vibration (the
    unbalance's reaction) and inertia (``j p''``, their sum)."""
    from rubcli.solvers.driven import sample_derivatives

    problem = solution.problem
    motor = problem.drive.shaft_torque(solution.speed)
    dS, rub_force = sample_derivatives(solution)
    inertia = problem.drive.inertia * dS[5]
    rub = -problem.params.Rp * rub_force
    return {"motor": motor, "rub": rub, "vibration": inertia - motor - rub, "inertia": inertia}


def revolution_means(solution: Solution) -> DriveTorques:
    """The torques, the largest radius and the contact share over each whole revolution
    of the unbalance."""
    torques = sample_torques(solution)
    turn = np.floor((solution.phase - solution.phase[0]) / (2.0 * np.pi)).astype(int)
    whole = turn < turn[-1] if turn[-1] > 0 else np.ones(turn.size, bool)
    index = turn[whole]
    counts = np.bincount(index)
    keep = counts > 0

    def mean(values: np.ndarray) -> np.ndarray:
        return (np.bincount(index, weights=values[whole]) / np.maximum(counts, 1))[keep]

    radius = np.zeros(counts.size)
    np.maximum.at(radius, index, solution.z[whole])
    return DriveTorques(
        tau=mean(solution.t),
        motor=mean(torques["motor"]),
        rub=mean(torques["rub"]),
        vibration=mean(torques["vibration"]),
        inertia=mean(torques["inertia"]),
        radius=radius[keep],
        contact=mean((solution.regimes != model.FREE).astype(float)),
        tau_samples=solution.t,
        speed_samples=solution.speed,
    )


def drive_summary(solution: Solution, torques: DriveTorques) -> dict[str, Any]:
    """report.json's ``drive`` entry: the speed reached and its largest, the mean
    torques over the last revolution, and whether the drive ended captured: its speed
    steady (changing by at most 1 % over the last tenth of the run) more than 5 % below
    the speed the motor holds without the rotor's load (``Drive.free_speed``)."""
    w, t = solution.speed, solution.t
    drive = solution.problem.drive
    last = t >= t[0] + 0.9 * (t[-1] - t[0])
    change = float(np.ptp(w[last])) if np.any(last) else 0.0
    top = drive.free_speed()
    final = float(w[-1])
    out = {
        "start_speed": float(w[0]),
        "final_speed": final,
        "max_speed": float(np.max(w)),
        "min_speed": float(np.min(w)),
        "motor_free_speed": top,
        "captured": bool(change <= 0.01 * final and final < 0.95 * top),
    }
    if torques.tau.size:
        out["last_revolution_torques"] = {
            "motor": float(torques.motor[-1]),
            "rub": float(torques.rub[-1]),
            "vibration": float(torques.vibration[-1]),
            "inertia": float(torques.inertia[-1]),
        }
    return out

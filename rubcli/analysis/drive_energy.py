"""The energy balance of a driven rotor (``rubcli.drive``): the check of a run's
quality when the speed is a state.

With the energy ``E = |v|^2 / 2 + e w t . v + j w^2 / 2 + |w|^2 / 2 + K (z - 1)^2 / 2``
(``drive.energy_value``; ``v`` the rotor's velocity, ``w`` its speed), the equations
give exactly::

    d/dtau E = T_m(w) w - c_b w^2 - 2 nu |v|^2 - T v_r

the motor's power, the bearing drag's, the damping's and the rub's (``T`` the rub's
tangential force, positive opposing positive slip; ``v_r`` the slip velocity; zero in
stick, where the rotor rolls). Every power is continuous in time (the rub's vanishes at
every switch: ``z = 1`` or ``v_r = 0`` there), so the works are integrated over the
samples by the trapezoid rule. ``energy_residual = |Delta E - (W_motor - D_drag -
D_damp - D_rub)| / throughput`` with the throughput the sum of the works' magnitudes
plus the largest energy stored; ``energy_quadrature_error`` estimates the rule's own
share (the rule on every other sample against every sample, over 3, order 2): a residual
says something about the solver only above it.
"""

from __future__ import annotations

import numpy as np

from rubcli import model
from rubcli.drive import energy_value
from rubcli.solution import Solution


def drive_powers(solution: Solution) -> dict[str, np.ndarray]:
    """The powers at the samples: motor, drag, damping and rub (dissipations positive)."""
    p, drive = solution.problem.params, solution.problem.drive
    w = solution.speed
    rub = solution.friction_force * solution.slip_velocity
    rub = np.where(solution.regimes == model.STICK, 0.0, rub)
    return {
        "motor": drive.motor_torque(w) * w,
        "drag": drive.drag * w * w,
        "damping": 2.0 * p.nu * (solution.vx**2 + solution.vy**2),
        "rub": rub,
    }


def drive_energy(solution: Solution) -> np.ndarray:
    """The driven rotor's energy at the samples (``drive.energy_value``)."""
    p, drive = solution.problem.params, solution.problem.drive
    x, y, vx, vy = solution.states.T
    return energy_value(x, y, vx, vy, solution.phase, solution.speed, p.K, p.e, drive.inertia)


def _trapezoid(t: np.ndarray, P: np.ndarray) -> float:
    return float(np.sum(0.5 * (P[1:] + P[:-1]) * np.diff(t))) if t.size > 1 else 0.0


def drive_energy_summary(solution: Solution) -> dict[str, float]:
    """The balance's totals over the run, for report.json (module docstring)."""
    t = solution.t
    if t.size < 3:
        return {"energy_residual": 0.0, "energy_quadrature_error": 0.0}
    energy = drive_energy(solution)
    powers = drive_powers(solution)
    works = {name: _trapezoid(t, P) for name, P in powers.items()}
    net = works["motor"] - works["drag"] - works["damping"] - works["rub"]
    coarse = {name: _trapezoid(t[::2], P[::2]) for name, P in powers.items()}
    if (t.size - 1) % 2:  # the last interval, left out of every other sample
        for name, P in powers.items():
            coarse[name] += _trapezoid(t[-2:], P[-2:])
    coarse_net = coarse["motor"] - coarse["drag"] - coarse["damping"] - coarse["rub"]
    throughput = sum(_trapezoid(t, np.abs(P)) for P in powers.values()) + float(np.max(energy))
    change = float(energy[-1] - energy[0])
    return {
        "energy_residual": abs(change - net) / throughput,
        "energy_quadrature_error": abs(net - coarse_net) / 3.0 / throughput,
        "energy_change": change,
        "motor_work": works["motor"],
        "drag_dissipation": works["drag"],
        "damping_dissipation": works["damping"],
        "rub_dissipation": works["rub"],
        "energy_throughput": throughput,
    }

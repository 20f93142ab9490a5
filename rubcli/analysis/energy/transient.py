"""The energy balance of a run whose speed changes: the check of its quality.

**A prescribed speed** (``rubcli.speed``). The rotor's energy ``E = |v|^2 / 2 + |w|^2 / 2
+ K (z - 1)^2 / 2`` changes by the unbalance's power, with the tangential term of a
changing speed (``model.unbalance_value``), the damping's and the friction's on the
translation::

    d/dtau E = f_u(tau) . v - 2 nu |v|^2 - T r theta'

(``analysis.energy.balance``'s balance with ``E (cos p, sin p)`` replaced by ``f_u``; the motor
holding the prescribed speed supplies ``T Rp eta(tau)`` of the friction's power, reported
as ``spin_drive_work``, and the contact dissipates ``T v_r``). The powers are integrated
piece by piece between the located events (``analysis.energy.regimes.solution_pieces``: a
slip reversal flips the friction), on each leg of the profile with that leg's line of
speed, by the trapezoid rule (``profile_energy_summary``).

**A driven rotor** (``rubcli.drive``), the speed a state.

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
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers.rub import friction_force, slip_velocity


def drive_powers(solution: Solution) -> dict[str, np.ndarray]:
    """The powers at the samples: motor, drag, damping and rub (dissipations positive)."""
    p, drive = solution.problem.params, solution.problem.drive
    w = solution.speed
    rub = friction_force(solution) * slip_velocity(solution)
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


def _coarse(t: np.ndarray, P: np.ndarray) -> float:
    """The trapezoid rule on every other node (the last interval kept whole)."""
    out = _trapezoid(t[::2], P[::2])
    if (t.size - 1) % 2:
        out += _trapezoid(t[-2:], P[-2:])
    return out


def profile_powers(
    problem: Problem, tau: np.ndarray, states: np.ndarray, regime: int
) -> np.ndarray:
    """``analysis.energy.balance.powers`` at the nodes ``tau`` (states (n, 4)) of one piece in
    ``regime``, each node on its leg of the profile: array (n, ``energy.N_TERMS``)."""
    from rubcli.analysis.energy.balance import N_TERMS, powers

    legs = problem.legs()
    starts = np.array([start for start, _ in legs])
    leg_of = np.clip(np.searchsorted(starts, tau, side="right") - 1, 0, len(legs) - 1)
    out = np.empty((tau.size, N_TERMS))
    for i, (_, params) in enumerate(legs):
        on = leg_of == i
        if np.any(on):
            out[on] = powers(tau[on], states[on], params, regime)
    return out


def profile_energy_summary(solution: Solution) -> dict[str, float]:
    """A prescribed speed's balance over the run, for report.json (module docstring):
    the keys of ``analysis.energy.balance``'s summary."""
    from rubcli.analysis.energy import balance as en
    from rubcli.analysis.energy.regimes import solution_pieces

    if solution.t.size < 3:
        return {"energy_residual": 0.0, "energy_quadrature_error": 0.0}
    fine, coarse = np.zeros(en.N_TERMS), np.zeros(en.N_TERMS)
    for piece in solution_pieces(solution):
        P = profile_powers(solution.problem, piece.tau, piece.states, piece.regime)
        fine += [_trapezoid(piece.tau, P[:, i]) for i in range(en.N_TERMS)]
        coarse += [_coarse(piece.tau, P[:, i]) for i in range(en.N_TERMS)]
    params = solution.problem.params
    energy = sum(en.mechanical_energy(solution.states, params, solution.regimes))
    throughput = (fine[en.W_ABS_IN] + fine[en.W_DAMP] + fine[en.W_ABS_FRIC]
                  + fine[en.W_ABS_CROSS] + float(np.max(energy)))  # fmt: skip
    change = float(energy[-1] - energy[0])

    def net(works: np.ndarray) -> float:
        return works[en.W_IN] - works[en.W_DAMP] + works[en.W_FRIC] + works[en.W_CROSS]

    return {
        "energy_residual": abs(change - net(fine)) / throughput,
        "energy_quadrature_error": abs(net(fine) - net(coarse)) / 3.0 / throughput,
        "energy_change": change,
        "work_unbalance": fine[en.W_IN],
        "damping_dissipation": fine[en.W_DAMP],
        "friction_dissipation": -fine[en.W_FRIC],
        "contact_dissipation": fine[en.W_SLIP],
        "spin_drive_work": fine[en.W_SPIN],
        **({"cross_coupling_work": fine[en.W_CROSS]} if fine[en.W_CROSS] != 0.0 else {}),
        "energy_throughput": throughput,
    }


def speed_energy_summary(solution: Solution) -> dict[str, float]:
    """The balance of a run whose speed changes: a driven rotor's or a profile's."""
    if solution.problem.drive is not None:
        return drive_energy_summary(solution)
    return profile_energy_summary(solution)


def drive_energy_summary(solution: Solution) -> dict[str, float]:
    """The balance's totals over the run, for report.json (module docstring)."""
    t = solution.t
    if t.size < 3:
        return {"energy_residual": 0.0, "energy_quadrature_error": 0.0}
    energy = drive_energy(solution)
    powers = drive_powers(solution)
    works = {name: _trapezoid(t, P) for name, P in powers.items()}
    net = works["motor"] - works["drag"] - works["damping"] - works["rub"]
    coarse = {name: _coarse(t, P) for name, P in powers.items()}
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

"""The rub at a solution's samples: the slip velocity, the normal force and the friction.

A ``Solution`` holds what a run found (times, states, regimes, events); the forces at
its samples are asked here of the system that ran: the rotor's own equations
(``rubcli.model``), a speed profile's legs, the driven rotor's (``solvers.driven``) or
the two bodies' (``solvers.two_body``). Those two are imported on first use, so that
writing a solution's CSV loads no compiled kernel it does not run.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rubcli import model

if TYPE_CHECKING:
    from rubcli.solution import Solution


def slip_velocity(solution: Solution) -> np.ndarray:
    """v_r at each sample (``model.slip_velocity``), at the sample's own speed when the
    speed changes (a speed profile, a driven rotor)."""
    problem = solution.problem
    p = problem.params
    constant = problem.speed is None and solution.drive_states is None
    eta = p.eta if constant else solution.speed
    return model.slip_velocity(solution.x, solution.y, solution.vx, solution.vy, p.Rp, eta)


def normal_force(solution: Solution) -> np.ndarray:
    """K (z - 1) in contact regimes, 0 in free flight (nondimensional)."""
    return np.where(solution.contact == 1, solution.problem.params.K * (solution.z - 1.0), 0.0)


def friction_force(solution: Solution) -> np.ndarray:
    """Signed tangential force (positive opposes positive slip): mu_c K (z - 1) when
    slipping, the rolling friction in stick, 0 in free flight (model.tangential_force;
    a driven rotor's from its own equations, ``rubcli.drive``; a stator with its own
    mass's from the two bodies', ``rubcli.stator``)."""
    problem = solution.problem
    if problem.drive is not None:
        from rubcli.solvers.driven import rub_force

        return rub_force(solution)
    if solution.stator_states is not None:
        from rubcli.solvers.two_body import sample_derivatives

        return sample_derivatives(solution)[1]
    t, x, y, vx, vy = solution.t, solution.x, solution.y, solution.vx, solution.vy
    if problem.speed is None:
        return model.tangential_force(t, x, y, vx, vy, problem.params, solution.regimes)
    out = np.zeros(t.size)  # leg by leg: each leg's line of speed
    legs = problem.legs()
    for i, (start, params) in enumerate(legs):
        end = legs[i + 1][0] if i + 1 < len(legs) else np.inf
        on = (t >= start) & (t < end) if i else t < end
        if np.any(on):
            out[on] = model.tangential_force(t[on], x[on], y[on], vx[on], vy[on], params,
                                             solution.regimes[on])  # fmt: skip
    return out

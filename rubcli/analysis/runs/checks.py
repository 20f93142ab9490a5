"""What a run's report says about one method, and whether its "success" can be trusted.

``method_summary(solution)`` is the report.json entry of one method of `rubcli run`
(status, counts, contact, penetration, time in each regime, energy balance) with its
plausibility ``warnings``: a solver can finish "successfully" at a tolerance so loose that
the orbit is nonsense (``rtol = 0.999999, atol = 1e300`` ends 1e19 clearances deep in
the stator). Three checks that need no reference decide it:

1. **Non-finite states**: any NaN or infinity among the samples.
2. **Energy balance**: the residual of the energy balance (``analysis.energy.balance``) above
   ``ENERGY_RESIDUAL_LIMIT`` (1e-2 of the energy throughput) *and* above
   ``QUADRATURE_FACTOR`` times its own quadrature floor (below the floor the residual
   says nothing, docs/stability.md).
3. **Penetration**: the largest penetration ``z - 1`` above a generous static bound
   (``penetration_bound``): ``BOUND_FACTOR`` (10) times the largest of the penetration
   at which the initial energy would be all elastic, the rolling-whirl penetration (dry
   whip, ``model.rolling_whirl_radius``) and the static penetration under the unbalance
   force amplified by the damped resonance factor ``1/(2 nu)``. Without damping there is
   no such bound and the check is skipped.

A method with warnings gets ``"status": "warning"`` in the report (its solver status is
kept in ``solver_status``); see ``rubcli run``'s exit codes.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import SUCCESS, Solution

WARNING = "warning"
ENERGY_RESIDUAL_LIMIT = 1e-2
QUADRATURE_FACTOR = 10.0
BOUND_FACTOR = 10.0


def _elastic_penetration(energy: float, K: float) -> float:
    """The penetration p at which 1/2 (1 + p)^2 + 1/2 K p^2 equals ``energy`` (0 if the
    energy does not reach the clearance)."""
    if energy <= 0.5:
        return 0.0
    # (1 + K) p^2 + 2 p + 1 - 2 E = 0
    a, b, c = 1.0 + K, 2.0, 1.0 - 2.0 * energy
    return (-b + math.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)


def penetration_bound(problem: Problem) -> float | None:
    """A generous static bound on the penetration of a correct orbit (None: no bound,
    i.e. no damping). See the module docstring."""
    p = problem.params
    if not p.nu > 0:
        return None
    if problem.speed is not None:  # at the profile's highest speed (e eta^2 grows with it)
        p = replace(p, eta=max(problem.speed.eta))
    if problem.drive is not None:  # a driven rotor's speed is bounded by its run only
        return None
    x, y, vx, vy = problem.initial
    z0 = math.hypot(x, y)
    energy = 0.5 * (vx * vx + vy * vy) + 0.5 * z0 * z0 + 0.5 * p.K * max(0.0, z0 - 1.0) ** 2
    initial = _elastic_penetration(energy, p.K)
    rolling = model.rolling_whirl_radius(p) - 1.0 if p.Rp > 0 else 0.0
    force = p.e * p.eta * p.eta / (2.0 * p.nu)  # unbalance force times the resonance factor
    forced = max(0.0, (force - 1.0) / (1.0 + p.K))
    return BOUND_FACTOR * max(initial, rolling, forced, 1.0 / (1.0 + p.K))


def plausibility_warnings(
    solution: Solution, energy: dict[str, Any] | None, penetration: float | None = None
) -> list[str]:
    """Why a run that reports success should not be trusted (empty if nothing is wrong).

    ``energy`` is ``EnergyBalance.summary()`` (None if it could not be computed);
    ``penetration`` the solution's ``max_penetration()`` if already computed.
    """
    if solution.status != SUCCESS:
        return []
    reasons = []
    if not bool(np.all(np.isfinite(solution.states))):
        reasons.append("non-finite state (NaN or infinity) among the samples")
        return reasons
    if energy is not None:
        residual = energy.get("energy_residual")
        floor = energy.get("energy_quadrature_error") or 0.0
        if (
            residual is not None
            and not residual <= ENERGY_RESIDUAL_LIMIT
            and not residual <= QUADRATURE_FACTOR * floor
        ):
            reasons.append(
                f"energy balance off by {residual:.3g} of the throughput (limit "
                f"{ENERGY_RESIDUAL_LIMIT:g}, quadrature floor {floor:.2g})"
            )
    bound = penetration_bound(solution.problem)
    if penetration is None:
        penetration = solution.max_penetration()
    if bound is not None and not penetration <= bound:
        reasons.append(
            f"max penetration {penetration:.3g} clearances beyond the static bound {bound:.3g}"
        )
    return reasons


def method_summary(solution: Solution, balance: Any = None) -> dict[str, Any]:
    """The report.json entry of one method, with its plausibility warnings.

    ``time_in_regime`` comes from the located switch times (``analysis.energy.regimes``);
    ``energy_residual`` and ``energy`` from the energy balance (``analysis.energy.balance``):
    ``balance`` if given (an ``EnergyBalance`` or ``EnergyTotals`` of this solution,
    computed once for the energy figure too), else its totals (``energy_totals``: one
    compiled pass, no per-sample arrays).
    """
    from rubcli.analysis.energy.balance import energy_totals
    from rubcli.analysis.energy.regimes import time_in_regimes

    t_end = float(solution.t[-1]) if solution.t.size else None
    finite = bool(np.all(np.isfinite(solution.states)))
    with np.errstate(all="ignore"):
        if not finite:
            energy = None
        elif solution.problem.changes_speed:
            from rubcli.analysis.energy.transient import speed_energy_summary

            energy = speed_energy_summary(solution)
        elif solution.stator_states is not None:
            from rubcli.analysis.energy.two_body import two_body_energy_summary

            energy = two_body_energy_summary(solution)
        elif balance is not None:
            energy = balance.summary()
        else:
            energy = energy_totals(solution).summary()
        penetration = solution.max_penetration()
    warnings = plausibility_warnings(solution, energy, penetration)
    return {
        "status": WARNING if warnings else solution.status,
        "solver_status": solution.status,
        "message": solution.message,
        "warnings": warnings,
        "wall_time_s": solution.wall_time_s,
        "stats": dict(solution.stats),
        "n_contact_switches": solution.n_contact_switches,
        "n_events": len(solution.events),
        "contact_fraction": solution.contact_fraction(),
        "max_penetration": penetration,
        "penetration_bound": penetration_bound(solution.problem),
        "time_in_regime": time_in_regimes(solution),
        "energy_residual": None if energy is None else energy["energy_residual"],
        "energy": energy,
        "n_samples": int(solution.t.size),
        "tau_end": t_end,
        "settings": dict(solution.settings),
    }

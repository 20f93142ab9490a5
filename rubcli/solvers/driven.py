"""The driven rotor (``rubcli.drive``) in the event loop of ``solvers.extended``.

The state has six entries, ``(x, y, vx, vy, p, w)``; the drive's rules at an event are
the extended systems': Filippov's rule at a slip reversal with the stick friction of the
coupled system (``drive.stick_torque_value``), and stick begun and ended with the
velocities projected onto the rolling constraint along the kinetic energy's metric
(``drive.rolling_projection``), the rotor's and the drive's together.

The scipy methods, ``dop853-jit`` and ``taylor`` (its series in
``compiled.driven_taylor``) run it through ``extended.solve_extended``.
"""

from __future__ import annotations

import numpy as np

from rubcli import model
from rubcli.drive import D_INERTIA, rolling_projection, shaft_torque_value, stick_torque_value
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers.compiled.drive import (
    _driven_into,
    advance_driven,
    driven_columns,
    driven_initial_step,
    driven_rhs,
)
from rubcli.solvers.compiled.driven_taylor import advance_driven_taylor
from rubcli.solvers.extended import (
    ExtendedRun,
    System,
    solve_extended,
)
from rubcli.solvers.registry import DRIVEN, SPECS, ToleranceOptions


class DrivenRun(ExtendedRun):
    """An extended run whose state is the driven rotor's six entries (module docstring)."""

    def __init__(self, problem: Problem, method: str, **budget) -> None:
        drive = problem.drive
        self.system = DRIVEN_SYSTEM
        self.drive = drive.record()
        self.table = drive.table()
        pars = np.array(model.params_vector(problem.params))
        state = np.array([*problem.initial, problem.params.phi0, drive.start])
        super().__init__(problem, method, (pars, self.drive, *self.table), state, **budget)

    def stick_friction(self, s: np.ndarray) -> float:
        """The friction T that holds v_r = 0 at the state ``s`` (``stick_torque_value``)."""
        p = self.params
        x, y, vx, vy, phase, w = s
        j = self.drive[D_INERTIA]
        Q0 = shaft_torque_value(w, self.drive, *self.table)
        return stick_torque_value(x, y, vx, vy, phase, w, p.nu, p.K, p.e, p.Rp, j, Q0)[0]

    def project(self, s: np.ndarray) -> np.ndarray:
        """The state with v_r = 0 exactly (``drive.rolling_projection``)."""
        p = self.params
        out = np.array(s, dtype=float)
        out[2], out[3], out[5] = rolling_projection(*s, p.e, p.Rp, self.drive[D_INERTIA])
        return out

    def solution(self, settings: dict) -> Solution:
        solution = super().solution(settings)
        k = solution.t.size
        solution.states = np.ascontiguousarray(self.states[:k, :4])
        solution.drive_states = np.ascontiguousarray(self.states[:k, 4:])
        return solution


def _python_rhs(s, pars, drive, table_speed, table_torque, regime) -> np.ndarray:
    """``compiled.drive.driven_rhs`` run by the interpreter (``compiled=False``)."""
    out = np.empty(6)
    _driven_into.py_func(s, pars, drive, table_speed, table_torque, regime, out)
    return out


def _python_columns(S, pars, drive, table_speed, table_torque, regime):
    """``compiled.drive.driven_columns`` run by the interpreter."""
    dS, T, out = np.empty_like(S), np.empty(S.shape[1]), np.empty(6)
    for k in range(S.shape[1]):
        T[k] = _driven_into.py_func(S[:, k], pars, drive, table_speed, table_torque, regime, out)
        dS[:, k] = out
    return dS, T


def sample_derivatives(solution: Solution) -> tuple[np.ndarray, np.ndarray]:
    """A driven run's equations at its samples, each in its regime: the derivatives of
    the six states (6, n) and the rub's tangential force (n,) (positive opposing
    positive slip; the stick multiplier in stick; 0 in free flight)."""
    problem = solution.problem
    pars = np.array(model.params_vector(problem.params))
    drive = problem.drive.record()
    ts, tt = problem.drive.table()
    S = np.vstack([solution.states.T, solution.drive_states.T])
    dS, T = np.empty_like(S), np.zeros(solution.t.size)
    for regime in (model.FREE, model.SLIP_POSITIVE, model.SLIP_NEGATIVE, model.STICK):
        on = solution.regimes == regime
        if np.any(on):
            dS[:, on], T[on] = driven_columns(np.ascontiguousarray(S[:, on]), pars, drive, ts,
                                              tt, regime)  # fmt: skip
    return dS, T


def rub_force(solution: Solution) -> np.ndarray:
    """The rub's tangential force at a driven run's samples (``sample_derivatives``)."""
    return sample_derivatives(solution)[1]


DRIVEN_SYSTEM = System(
    size=6, rhs=driven_rhs, columns=driven_columns, python_rhs=_python_rhs,
    python_columns=_python_columns, loop=(driven_initial_step, advance_driven),
    taylor=advance_driven_taylor,
)  # fmt: skip


def solve_driven(problem: Problem, options: ToleranceOptions, name: str) -> Solution:
    """A driven rotor by the method ``name``: a scipy method, ``dop853-jit`` or
    ``taylor`` (module docstring). The compiled loops always locate and apply the events
    compiled (``compiled_events`` changes nothing here); ``dop853-jit`` with ``compiled=False``
    (or its kernels unusable) is scipy's ``dop853`` under its name, and ``taylor`` has no
    pure-Python path, as at a constant speed."""
    if DRIVEN not in SPECS[name].features:
        raise ValueError(f"{name} does not run a driven rotor")
    o = options
    run = DrivenRun(
        problem, name, max_steps=o.max_steps, max_wall_time_s=o.max_wall_time_s,
        progress=o.progress,
    )  # fmt: skip
    return solve_extended(run, name, o.rtol, o.atol, o.compiled)

"""scipy's integrators (rk45 = the paper's ODE45, dop853, radau, bdf, lsoda) with event restarts.

Each regime (free, slip+, slip-) is integrated with its own smooth right-hand side
(``model.rhs`` with the regime locked). After every accepted step the events of the
regime are checked on the step's dense output (contact entry ``z = 1`` from inside;
contact exit ``z = 1`` from outside and the slip reversal ``v_r = 0`` in contact); the
first one is located by Brent's method, the segment ends there and a new solver starts
in the new regime from the located state. No step straddles a non-smoothness.

The step loop is driven here (not by ``solve_ivp``) so that the run budget
(``max_steps``, ``max_wall_time_s``) is honoured inside a segment and progress can be
reported. Samples are taken from each step's dense output (order 4 for rk45, 7 for
dop853, the collocation polynomial for radau, the BDF/LSODA interpolants).

Stick (rolling, model notes 4) is a regime of its own: when v_r reaches 0 and the
friction needed to hold it there is within mu F_N, the segment continues with the
rolling law (``model.rhs`` with ``model.STICK``) until the needed friction leaves the
friction cone (slip restarts in the direction it points) or contact ends. Implicit
methods get a finite-difference Jacobian in stick.

With ``compiled=True`` (the default) the right-hand side, its Jacobian and the column
derivatives of the event scan are numba kernels (``kernels.rhs``) compiled from the
same ``model.rhs_entries``; scipy's own per-step Python work is unchanged, so this
buys only the share of the time spent in the right-hand side (benchmarks/floor.md).

Limits: an event is missed if its function changes sign twice within one scan
interval of an accepted step (``SCAN_POINTS`` per step; a dip resolved by the dense
output is caught).
"""

from __future__ import annotations

from functools import partial

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers import driver
from rubcli.solvers.events import (
    NO_EVENT,
    earliest_event,
)
from rubcli.solvers.registry import SPECS, ToleranceOptions, register
from rubcli.solvers.shared import (
    SCAN_POINTS,
    SCIPY_CLASSES,
    OdeSolverStepper,
    fill_samples,
    rhs_functions,
)


class ScipyStepper(OdeSolverStepper):
    """One of scipy's ``OdeSolver`` classes as a driver stepper on the rotor's four states.

    One ``advance`` is one accepted scipy step: a solver is started at each segment
    (the regime-locked right-hand side), the step's dense output is scanned for the
    regime's events, the samples up to the step's end (or the event) are filled, and a
    located event is applied, which ends the segment.
    """

    def _start_segment(self, run: driver.Run) -> None:
        fun, jac, self.derivatives = rhs_functions(run.params, run.regime, self.compiled)
        options = {"rtol": self.rtol, "atol": self.atol}
        if SPECS[self.name].implicit and run.regime != model.STICK:
            options["jac"] = jac
        self.solver = self.cls(fun, run.tau, run.state, run.t_end, **options)
        run.stats["n_segments"] += 1

    def advance(self, run: driver.Run) -> None:
        if not self.step(run):
            return
        solver = self.solver
        dense = solver.dense_output()
        grid = np.linspace(solver.t_old, solver.t, SCAN_POINTS + 1)
        event = earliest_event(
            dense, self.derivatives, grid, run.regime, run.params, run.last_kind,
            self.restart_band,
        )  # fmt: skip
        run.last_kind = NO_EVENT
        t_stop = event[0] if event else solver.t
        run.k = fill_samples(
            dense, run.t_eval, run.k, t_stop, run.regime, run.params, run.states, run.regimes
        )
        self.finish(run, dense, event)


def solve_scipy(problem: Problem, options: ToleranceOptions, name: str) -> Solution:
    o = options
    run = driver.Run(
        problem, name, max_steps=o.max_steps, max_wall_time_s=o.max_wall_time_s,
        progress=o.progress,
    )  # fmt: skip
    return driver.integrate(run, ScipyStepper(run, name, o.rtol, o.atol, o.compiled))


def _register(name: str) -> None:
    register(name)(partial(solve_scipy, name=name))


for _name in SCIPY_CLASSES:
    _register(_name)

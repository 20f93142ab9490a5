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

from collections.abc import Callable
from functools import partial

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers import compiled as kernels
from rubcli.solvers import driver, register
from rubcli.solvers.events import (
    NO_EVENT,
    earliest_event,
)
from rubcli.solvers.registry import SPECS, ToleranceOptions
from rubcli.solvers.shared import RESTART_BAND_FLOOR, SCAN_POINTS, fill_samples, rhs_functions

# The class of ``scipy.integrate`` for each method: scipy is imported when a scipy
# method runs, not with the registry (a `rubcli run` of a compiled method never loads it).
SCIPY_CLASSES = {
    "rk45": "RK45",
    "dop853": "DOP853",
    "radau": "Radau",
    "bdf": "BDF",
    "lsoda": "LSODA",
}


class ScipyStepper:
    """One of scipy's ``OdeSolver`` classes as a driver stepper (``driver.integrate``).

    One ``advance`` is one accepted scipy step: a solver is started at each segment
    (the regime-locked right-hand side), the step's dense output is scanned for the
    regime's events, the samples up to the step's end (or the event) are filled, and a
    located event is applied, which ends the segment.
    """

    def __init__(self, run: driver.Run, name: str, rtol: float, atol: float, compiled: bool):
        self.name, self.rtol, self.atol = name, rtol, atol
        from scipy import integrate

        self.cls = getattr(integrate, SCIPY_CLASSES[name])
        # Right after a restart the dense output is consistent with the located state only
        # to the solver's tolerance, not to round-off: a new crossing must clear that band.
        self.restart_band = max(RESTART_BAND_FLOOR, rtol)
        self.compiled = compiled and kernels.ensure_fresh()
        self.solver = None  # the segment's scipy solver (None: a segment is to start)
        run.stats.update(nfev=0, njev=0, nlu=0, n_segments=0)
        self.settings = {
            "rtol": rtol,
            "atol": atol,
            "max_steps": run.max_steps,
            "max_wall_time_s": run.max_wall_time_s,
            "compiled": self.compiled,
        }

    def _start_segment(self, run: driver.Run) -> None:
        fun, jac, self.derivatives = rhs_functions(run.params, run.regime, self.compiled)
        options = {"rtol": self.rtol, "atol": self.atol}
        if SPECS[self.name].implicit and run.regime != model.STICK:
            options["jac"] = jac
        self.solver = self.cls(fun, run.tau, run.state, run.t_end, **options)
        run.stats["n_segments"] += 1

    def _end_segment(self, run: driver.Run) -> None:
        solver, self.solver = self.solver, None
        run.stats["nfev"] += int(solver.nfev)
        run.stats["njev"] += int(getattr(solver, "njev", 0) or 0)
        run.stats["nlu"] += int(getattr(solver, "nlu", 0) or 0)

    def new_leg(self, run: driver.Run) -> None:
        """A new leg of the speed profile: the next segment starts with its parameters."""
        if self.solver is not None:
            self._end_segment(run)

    def step(self, run: driver.Run) -> bool:
        """One accepted step of the segment's solver (started first if need be); False,
        with the run failed, if the solver failed or left the finite numbers."""
        if self.solver is None:
            self._start_segment(run)
        solver = self.solver
        msg = solver.step()
        run.stats["nsteps"] += 1
        if solver.status == "failed":
            self._end_segment(run)
            run.fail(f"{self.name} failed at tau = {solver.t:.6g}: {msg}")
            return False
        if not np.all(np.isfinite(solver.y)):
            self._end_segment(run)
            run.fail(f"non-finite state at tau = {solver.t:.6g}")
            return False
        return True

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

    def finish(
        self, run: driver.Run, dense: Callable[[float], np.ndarray], event: tuple[float, int] | None
    ) -> None:
        """End the step (its samples filled): the run moves to its end, or to the event
        located in it, which is applied and ends the segment."""
        solver = self.solver
        if event is None:
            run.tau, run.state = solver.t, solver.y
            if solver.status == "finished":
                self._end_segment(run)
            return
        self._end_segment(run)
        run.switch(event[0], event[1], dense(event[0]))


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

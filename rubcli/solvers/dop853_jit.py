"""``dop853-jit``: scipy's DOP853, step for step, with its step loop compiled.

The method is ``scipy.integrate.DOP853`` (Hairer's 8(5,3) pair with the 7th-order dense
output) with scipy's own tableau, error norm, step-size rule, minimum step and initial
step, so for the same ``rtol``/``atol`` it takes the same steps as ``dop853`` and its
results agree with it to round-off (tests/test_dop853_jit.py). What differs is where the
time goes: scipy spends some 100 us of Python per step; here consecutive steps run in a
numba kernel (``kernels.advance_dop853``) at about 1 us each.

Events follow the scipy methods' rules (``scipy_ivp``): one regime at a time, the events
of the regime sought on each step's dense output on the same scan grid, located by
Brent's method, and applied by the same rule. After each accepted step the kernel runs a
conservative pre-check of the events ``events.earliest_event`` could find in it; if one
is possible it runs the event search itself (``events.event_search`` compiled on the
dense output: the crossing of each event function of the regime, the contact surface,
the slip reversal, the two sides of the friction cone in stick; scipy's Brent
iteration) and ``apply_event``'s rule
(Filippov's rule at v_r = 0, the projection onto the rolling constraint), records the
event and starts the next segment as this driver would. ``compiled_events=False`` hands
every step that might hold an event to the Python event code instead: the tests check
that both give the same events, steps and states (``tests/test_dop853_jit.py``), and
that both agree with scipy's ``dop853``. So the Python event code stays the definition,
and an event costs microseconds instead of scipy's ~1 ms.

Limits are those of ``dop853``: an explicit method, so on stiff stators (large K) its
step in contact is bounded by stability, about 3 / sqrt(K), whatever the tolerance.
"""

from __future__ import annotations

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers import compiled as kernels
from rubcli.solvers import driver
from rubcli.solvers.events import (
    NO_EVENT,
    start_flags,
)
from rubcli.solvers.registry import CompiledOptions, ToleranceOptions, register, registered
from rubcli.solvers.shared import (
    EVENT_BUFFER,
    RESTART_BAND_FLOOR,
    SCAN_POINTS,
    Dop853Dense,
    kernel_failure,
    locate_in_python,
)

CHUNK_STEPS = 2000  # committed steps per kernel call: budget and progress checks between


class Dop853Stepper:
    """The compiled DOP853 as a driver stepper (``driver.integrate``).

    One ``advance`` is one call of ``kernels.advance_dop853`` (or
    ``advance_paper_dop853``): up to ``CHUNK_STEPS`` steps with the events it locates and
    applies itself (recorded here, with the storm guard), or, with ``compiled_events=False``
    (or a step the kernel hands back), the pending step's events located by the Python
    event code.
    """

    def __init__(self, run: driver.Run, rtol: float, atol: float, compiled_events: bool):
        self._set_pars(run)
        self.restart_band = max(RESTART_BAND_FLOOR, rtol)
        # scipy raises a too small rtol to 100 eps (with a warning); so do we, silently
        self.rtol, self.atol = max(rtol, 100 * np.finfo(float).eps), atol
        self.compiled_events = compiled_events
        self.y_new, self.f_new, self.F, self.f = (
            np.empty(4),
            np.empty(4),
            np.empty((7, 4)),
            np.empty(4),
        )
        self.ev_tau = np.empty(EVENT_BUFFER)
        self.ev_kind = np.empty(EVENT_BUFFER, dtype=np.int64)
        self.ev_state = np.empty((EVENT_BUFFER, 4))
        self.ev_regimes = np.empty((EVENT_BUFFER, 2), dtype=np.int64)
        self.new_segment, self.at_event = True, run.last_kind != NO_EVENT
        self.h_abs = 0.0
        run.stats.update(nfev=0, n_segments=0, python_steps=0)
        self.settings = {
            "rtol": self.rtol,
            "atol": atol,
            "max_steps": run.max_steps,
            "max_wall_time_s": run.max_wall_time_s,
            "compiled": True,
            "compiled_events": compiled_events,
        }

    def _set_pars(self, run: driver.Run) -> None:
        """The record of the run's parameters and the loop that runs them: the paper's
        machine at a constant speed has its own (``kernels.advance_paper_dop853``)."""
        self.pars = np.array(model.params_vector(run.params))
        paper = model.is_paper_record(self.pars)
        self.kernel = kernels.advance_paper_dop853 if paper else kernels.advance_dop853

    def new_leg(self, run: driver.Run) -> None:
        """A new leg of the speed profile: its parameters, and a new segment."""
        self._set_pars(run)
        self.new_segment = True

    def advance(self, run: driver.Run) -> None:
        stats, pars = run.stats, self.pars
        if self.new_segment:  # as scipy starts a solver: f and the initial step
            run.state = np.ascontiguousarray(run.state, dtype=float)
            self.f[:] = kernels.rhs(run.tau, run.state, pars, run.regime)
            self.h_abs = kernels.dop853_initial_step(
                run.tau, run.state, self.f, run.t_end, pars, run.regime, self.rtol, self.atol
            )
            stats["nfev"] += 2
            stats["n_segments"] += 1
            self.new_segment = False
        starts = start_flags(run.last_kind if self.at_event else NO_EVENT)
        chunk = max(1, min(CHUNK_STEPS, run.steps_left))
        tau0, state0 = run.tau, run.state
        tau, t_new, self.h_abs, run.k, steps, nfev, reason, run.regime, n_ev, self.at_event = (
            self.kernel(
                tau0, state0, self.f, self.h_abs, run.t_end, pars, run.regime, self.rtol,
                self.atol, run.t_eval, run.states, run.regimes, run.k, chunk, starts,
                self.y_new, self.f_new, self.F, self.restart_band, self.ev_tau, self.ev_kind,
                self.ev_state, self.ev_regimes, self.compiled_events,
            )
        )  # fmt: skip
        run.tau = tau  # the kernel updated the state in place
        stats["nsteps"] += steps
        stats["nfev"] += nfev
        # segments the kernel started (with a full buffer the last one starts here)
        stats["n_segments"] += n_ev - (reason == kernels.STOP_FULL)
        events = (self.ev_tau, self.ev_kind, self.ev_state, self.ev_regimes)
        if not driver.record_kernel_events(run, n_ev, *events):
            return
        failure = kernel_failure(reason, "dop853-jit", tau, t_new)
        if failure:
            run.fail(failure)
        elif reason == kernels.STOP_FULL:
            self.new_segment = True
        elif reason == kernels.STOP_EVENT:
            self._python_event_step(run, t_new)

    def _python_event_step(self, run: driver.Run, t_new: float) -> None:
        """The pending step [tau, t_new]: the shared event code decides."""
        dense = Dop853Dense(run.tau, t_new, run.state, self.F)
        last_kind = run.last_kind if self.at_event else NO_EVENT
        event = locate_in_python(run, dense, t_new, SCAN_POINTS, last_kind, self.restart_band)
        if event is None:
            run.tau, self.at_event = t_new, False
            run.state[:], self.f[:] = self.y_new, self.f_new
        elif run.switch(event[0], event[1], dense(event[0])):
            self.at_event, self.new_segment = True, True


def solve_dop853_jit(problem: Problem, options: CompiledOptions) -> Solution:
    """scipy's DOP853 in a compiled step loop; ``compiled_events=False`` hands every
    possible event to the Python event code (a check of the compiled one)."""
    o = options
    if not (o.compiled and kernels.ensure_fresh()):
        # the same algorithm, run by scipy (kernels unusable or compiled=False)
        scipy_options = {f: getattr(o, f) for f in ToleranceOptions.names()}
        sol = registered("scipy")["dop853"](
            problem, ToleranceOptions(**{**scipy_options, "compiled": False})
        )
        sol.method = "dop853-jit"
        return sol
    run = driver.Run(
        problem, "dop853-jit", max_steps=o.max_steps, max_wall_time_s=o.max_wall_time_s,
        progress=o.progress,
    )  # fmt: skip
    return driver.integrate(run, Dop853Stepper(run, o.rtol, o.atol, o.compiled_events))


register("dop853-jit")(solve_dop853_jit)

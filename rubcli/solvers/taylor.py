"""``taylor``: an adaptive Taylor-series integrator of the rub equations, compiled.

Scheme: Taylor's method of order N = ceil(-ln(rtol) / 2) + 6 (13 at rtol 1e-6, 18 at
1e-10), its coefficients computed by the automatic-differentiation recurrences of the
regime-locked right-hand side (``taylor_kernels.taylor_coefficients``: forcing, z =
sqrt(x^2 + y^2), w / z, the products of the contact law and of the rolling law), the step
by Jorba and Zou's rule (the last two terms below max(atol, rtol |s|)), no rejected steps.
It is the approach of heyoka (Biscani and Izzo 2021), written for this one system, with
the events of the other methods located on each step's Taylor polynomial.

Its order is N; its local error per step is about the tolerance, and its dense output
(the polynomial) carries the same accuracy between steps, so samples and events come at
no extra cost. The step is limited by the radius of convergence of the series, about
1 / omega for the fastest frequency omega: on stiff stators (large K, omega ~ sqrt(K)) it
takes many steps like every explicit method.

Events follow the scipy methods' rules (``scipy_ivp``, ``dop853_jit``): one regime at a
time, the events of the regime found on each step's polynomial by the shared event
search (``events.event_search``, compiled) on a scan grid and applied by
``events.apply_event``'s rule (Filippov at v_r = 0, rolling in stick); see
``taylor_kernels``. ``compiled_events=False`` hands every step that might hold an event
to the Python event code
(``events.earliest_event`` on the step's polynomial, ``events.apply_event``): the tests
check that both give the same events and states. ``compiled=False`` is the same as
``compiled_events=False`` (the series themselves are always compiled).
"""

from __future__ import annotations

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers import compiled as kernels
from rubcli.solvers import driver
from rubcli.solvers.compiled import taylor as taylor_kernels
from rubcli.solvers.events import NO_EVENT, start_flags
from rubcli.solvers.registry import CompiledOptions, register
from rubcli.solvers.shared import RESTART_BAND_FLOOR, kernel_failure, locate_in_python

# steps per kernel call, with budget and progress checks between: 20,000 steps are 5-20
# ms (0.25-1 us a step); a call costs ~20 us of dispatch (2,000 cost 1.3 % at mu = 0.03)
CHUNK_STEPS = 20_000
# events the kernel may apply before it returns to flush them (the other compiled
# loops': shared.EVENT_BUFFER, 256); a kernel call costs ~20 us of dispatch, so a run
# with an event every 3 steps returns only every 4096 events (and CHUNK_STEPS steps)
EVENT_BUFFER = 4096


class TaylorDense:
    """A step's Taylor polynomial: the state at a scalar time (4,) or at times (4, n), by
    the operations of the kernel's ``dense_at`` (Estrin's scheme): the same numbers."""

    def __init__(self, t0: float, C: np.ndarray, order: int):
        self.t0, self.C, self.order = t0, C[:, : order + 1].copy(), order

    def __call__(self, t):
        dt = np.asarray(t, dtype=float) - self.t0
        if dt.ndim == 0:
            dt, C = float(dt), self.C
        else:
            dt, C = dt.ravel(), self.C[:, :, None]  # rows (4, order + 1, 1): out (4, n)
        order, d2 = self.order, dt * dt
        if order % 2 == 1:
            v, k = C[:, order - 1] + C[:, order] * dt, order - 2
        else:
            v, k = C[:, order], order - 1
        while k >= 1:
            v = v * d2 + (C[:, k - 1] + C[:, k] * dt)
            k -= 2
        return v


class TaylorStepper:
    """The compiled Taylor method as a driver stepper (``driver.integrate``).

    One ``advance`` is one call of ``taylor_kernels.advance_taylor``: up to
    ``CHUNK_STEPS`` steps with the events it locates and applies itself (recorded here,
    with the storm guard), or, with ``compiled_events=False`` (or a step the kernel hands
    back), the pending step's events located by the Python event code on its polynomial.
    """

    def __init__(self, run: driver.Run, rtol: float, atol: float, compiled_events: bool):
        self.pars = np.array(model.params_vector(run.params))
        self.restart_band = max(RESTART_BAND_FLOOR, rtol)
        self.rtol, self.atol = max(rtol, 100 * np.finfo(float).eps), atol
        self.order = taylor_kernels.taylor_order(self.rtol)
        self.compiled_events = compiled_events
        self.C = np.zeros((4, taylor_kernels.MAX_ORDER + 1))
        self.info = np.zeros(1, dtype=np.int64)
        self.ev_tau = np.empty(EVENT_BUFFER)
        self.ev_kind = np.empty(EVENT_BUFFER, dtype=np.int64)
        self.ev_state = np.empty((EVENT_BUFFER, 4))
        self.ev_regimes = np.empty((EVENT_BUFFER, 2), dtype=np.int64)
        self.at_event = run.last_kind != NO_EVENT
        run.state = np.ascontiguousarray(run.state, dtype=float)
        run.stats.update(nfev=0, n_segments=1, python_steps=0, order=self.order)
        self.settings = {
            "rtol": self.rtol,
            "atol": atol,
            "order": self.order,
            "max_steps": run.max_steps,
            "max_wall_time_s": run.max_wall_time_s,
            "compiled": True,
            "compiled_events": compiled_events,
        }

    def new_leg(self, run: driver.Run) -> None:
        """A new leg of the speed profile: its parameters (each step's series starts from
        its own state, so nothing else carries over)."""
        self.pars = np.array(model.params_vector(run.params))

    def advance(self, run: driver.Run) -> None:
        stats = run.stats
        starts = start_flags(run.last_kind if self.at_event else NO_EVENT)
        chunk = max(1, min(CHUNK_STEPS, run.steps_left))
        tau, t_new, run.k, steps, reason, run.regime, n_ev, self.at_event = (
            taylor_kernels.advance_taylor(
                run.tau, run.state, run.t_end, self.pars, run.regime, self.order, self.rtol,
                self.atol, run.t_eval, run.states, run.regimes, run.k, chunk, starts, self.C,
                self.restart_band, self.ev_tau, self.ev_kind, self.ev_state, self.ev_regimes,
                self.compiled_events, self.info,
            )
        )  # fmt: skip
        run.tau = tau  # the kernel updated the state in place
        stats["nsteps"] += steps
        stats["nfev"] = stats["nsteps"]  # one series expansion per step
        stats["n_segments"] += n_ev
        if not driver.record_kernel_events(
            run, n_ev, self.ev_tau, self.ev_kind, self.ev_state, self.ev_regimes
        ):
            return
        failure = kernel_failure(reason, "taylor", tau, t_new)
        if failure:
            run.fail(failure)
        elif reason == kernels.STOP_EVENT:
            self._python_event_step(run, t_new)

    def _python_event_step(self, run: driver.Run, t_new: float) -> None:
        """The pending step [tau, t_new]: the shared event code decides."""
        dense = TaylorDense(run.tau, self.C, self.order)
        last_kind = run.last_kind if self.at_event else NO_EVENT
        intervals = int(self.info[0])
        event = locate_in_python(run, dense, t_new, intervals, last_kind, self.restart_band)
        run.stats["nfev"] = run.stats["nsteps"]
        if event is None:
            run.tau, self.at_event = t_new, False
            run.state[:] = dense(t_new)
            return
        run.stats["n_segments"] += 1
        if run.switch(event[0], event[1], dense(event[0])):
            run.state = np.array(run.state, dtype=float)
            self.at_event = True


def solve_taylor(problem: Problem, options: CompiledOptions) -> Solution:
    """Adaptive Taylor series (order from rtol, ``taylor_kernels.taylor_order``) with
    located events. There is no pure-Python path: ``compiled=False`` only hands every
    possible event to the Python event code (as ``compiled_events=False``)."""
    o = options
    kernels.ensure_fresh()
    run = driver.Run(
        problem, "taylor", max_steps=o.max_steps, max_wall_time_s=o.max_wall_time_s,
        progress=o.progress,
    )  # fmt: skip
    stepper = TaylorStepper(run, o.rtol, o.atol, bool(o.compiled_events and o.compiled))
    return driver.integrate(run, stepper)


register("taylor")(solve_taylor)

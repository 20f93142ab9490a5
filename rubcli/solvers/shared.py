"""What the method families share: the regime's right-hand side for Python code, the
samples of a step's dense output, the Python event search of a compiled loop's pending
step, a compiled DOP853 step's dense output, and scipy's solvers stepping a run segment
by segment (``OdeSolverStepper``, for the rotor's states and a system's). The families
(``analytic``, ``scipy_ivp``, ``dop853_jit``, ``taylor``, ``driven``) import these from
here, never from each other."""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from rubcli import model
from rubcli.solvers import compiled as kernels
from rubcli.solvers import driver
from rubcli.solvers.events import earliest_event

if TYPE_CHECKING:
    from collections.abc import Callable

    from rubcli.model import FloatOrArray

# The restart band of an event (the band around the surface in which the segment that
# an event began does not see it again) is max(RESTART_BAND_FLOOR, rtol).
RESTART_BAND_FLOOR = 1e-12
SCAN_POINTS = 4  # sub-intervals per step in which events are scanned on the dense output
# events a compiled loop may apply before it returns for its stepper to record them
EVENT_BUFFER = 256


def _column_derivatives(fun):
    """derivatives(t, S) for states S of shape (4, n) from a rhs of one state."""

    def derivatives(t: FloatOrArray, S: np.ndarray) -> np.ndarray:
        t = np.broadcast_to(np.asarray(t, dtype=float), (S.shape[1],))
        return np.array([fun(t[k], S[:, k]) for k in range(S.shape[1])]).T

    return derivatives


def fill_samples(
    dense: Callable[[float], np.ndarray], t_eval: np.ndarray, k: int, t_stop: float,
    regime: int, params: model.ModelParams, out_states: np.ndarray, out_regimes: np.ndarray,
) -> int:  # fmt: skip
    """Samples ``t_eval[k:]`` up to ``t_stop`` from a step's dense output (projected onto
    the rolling constraint in stick); returns the next sample to fill."""
    while k < t_eval.size and t_eval[k] <= t_stop:
        sample = dense(t_eval[k])
        if regime == model.STICK:
            sample = model.project_to_rolling(sample, params, t_eval[k])
        out_states[k], out_regimes[k] = sample, regime
        k += 1
    return k


def _rhs_fun(t, s, params, regime):
    return model.rhs(t, s, params, regime)


def _jac_fun(t, s, params, regime):
    return model.rhs_jacobian(t, s, params, regime)


def rhs_functions(
    params: model.ModelParams, regime: int, compiled: bool
) -> tuple[
    Callable[[float, np.ndarray], np.ndarray],
    Callable[[float, np.ndarray], np.ndarray],
    Callable[[FloatOrArray, np.ndarray], np.ndarray],
]:
    """(fun, jac, derivatives) of one regime: compiled kernels or model.py in Python."""
    if not compiled:
        fun = partial(_rhs_fun, params=params, regime=regime)
        return fun, partial(_jac_fun, params=params, regime=regime), _column_derivatives(fun)
    pars = np.array(model.params_vector(params))
    rhs, jacobian, columns = kernels.rhs, kernels.rhs_jacobian, kernels.rhs_columns

    def fun(t: float, s: np.ndarray) -> np.ndarray:
        return rhs(t, s, pars, regime)

    def jac(t: float, s: np.ndarray) -> np.ndarray:
        return jacobian(t, s, pars, regime)

    def derivatives(t: FloatOrArray, S: np.ndarray) -> np.ndarray:
        t = np.broadcast_to(np.asarray(t, dtype=float), (S.shape[1],))
        return columns(np.ascontiguousarray(t), np.ascontiguousarray(S, dtype=float), pars, regime)

    return fun, jac, derivatives


def locate_in_python(
    run: driver.Run,
    dense: Callable[[FloatOrArray], np.ndarray],
    t_new: float,
    intervals: int,
    last_kind: int,
    band: float,
) -> tuple[float, int] | None:
    """A compiled loop's pending step [run.tau, t_new] with its dense output ``dense``:
    the Python event code (``events.earliest_event`` on ``intervals`` scan intervals)
    finds its earliest event, and its samples up to that event (or t_new) are filled.
    Returns the event ``(tau, kind)`` or None; the caller moves the run on."""
    run.stats["nsteps"] += 1
    run.stats["python_steps"] += 1
    grid = np.linspace(run.tau, t_new, intervals + 1)
    derivatives = rhs_functions(run.params, run.regime, True)[2]
    event = earliest_event(dense, derivatives, grid, run.regime, run.params, last_kind, band)
    t_stop = event[0] if event else t_new
    run.k = fill_samples(
        dense, run.t_eval, run.k, t_stop, run.regime, run.params, run.states, run.regimes
    )
    return event


# why a compiled loop's step fell below its minimum, as each method words it (scipy's
# DOP853 message for dop853-jit)
SMALL_STEP_WHY = {
    "dop853-jit": "required step size is less than spacing between numbers",
    "taylor": "the step fell below 10 ulp of tau",
}


def kernel_failure(reason: int, method: str, tau: float, t_new: float) -> str | None:
    """The run's failure message for a compiled loop's stop ``reason`` (a step below the
    minimum at ``tau``, a non-finite state at ``t_new``), or None if it is no failure."""
    if reason == kernels.STOP_SMALL_STEP:
        return f"{method} failed at tau = {tau:.6g}: {SMALL_STEP_WHY[method]}"
    if reason == kernels.STOP_PYTHON:
        return f"non-finite state at tau = {t_new:.6g}"
    return None


class Dop853Dense:
    """The dense output of one step (scipy's ``Dop853DenseOutput``), from a compiled
    loop's F (four states or the driven rotor's six)."""

    def __init__(self, t_old: float, t_new: float, y_old: np.ndarray, F: np.ndarray):
        self.t_old, self.h = t_old, t_new - t_old
        self.y_old, self.F = y_old.copy(), F.copy()

    def __call__(self, t):
        if isinstance(t, np.ndarray) and t.ndim == 1:
            return kernels.dop853_dense(t.astype(float), self.t_old, self.h, self.y_old, self.F)
        return kernels.dop853_dense_point(float(t), self.t_old, self.h, self.y_old, self.F)


# The class of ``scipy.integrate`` for each method: scipy is imported when a scipy
# method runs, not with the registry (a `rubcli run` of a compiled method never loads it).
SCIPY_CLASSES = {
    "rk45": "RK45",
    "dop853": "DOP853",
    "radau": "Radau",
    "bdf": "BDF",
    "lsoda": "LSODA",
}


class OdeSolverStepper:
    """One of scipy's ``OdeSolver`` classes stepping a run segment by segment, for the
    driver (``driver.integrate``): the solver of each segment, its counts, its failures,
    and the end of a step at its end or at an event. A subclass starts a segment
    (``_start_segment``: ``self.solver`` on the regime-locked right-hand side) and takes
    a step with its events (``advance``): the rotor's four states (``scipy_ivp``) or a
    system's (``extended``).
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

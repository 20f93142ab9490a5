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

import time
from functools import partial

import numpy as np
from scipy import integrate

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import FAILED, SUCCESS, Solution, SwitchEvent
from rubcli.solvers import kernels, register
from rubcli.solvers.events import (
    NO_EVENT,
    StormGuard,
    apply_event,
    earliest_event,
    initial_kind,
)

SCIPY_CLASSES = {
    "rk45": integrate.RK45,
    "dop853": integrate.DOP853,
    "radau": integrate.Radau,
    "bdf": integrate.BDF,
    "lsoda": integrate.LSODA,
}
IMPLICIT = {"radau", "bdf", "lsoda"}
RESTART_BAND_FLOOR = 1e-12
SCAN_POINTS = 4  # sub-intervals per step in which events are scanned on the dense output


class Budget:
    def __init__(self, max_steps: int, max_wall_time_s: float):
        self.max_steps = max_steps
        self.max_wall_time_s = max_wall_time_s
        self.start = time.perf_counter()

    def exceeded(self, steps: int) -> str | None:
        if steps >= self.max_steps:
            return f"step budget exhausted (max_steps = {self.max_steps})"
        if time.perf_counter() - self.start > self.max_wall_time_s:
            return f"wall-time budget exhausted (max_wall_time_s = {self.max_wall_time_s:g})"
        return None


def _column_derivatives(fun):
    """derivatives(t, S) for states S of shape (4, n) from a rhs of one state."""

    def derivatives(t, S):
        t = np.broadcast_to(np.asarray(t, dtype=float), (S.shape[1],))
        return np.array([fun(t[k], S[:, k]) for k in range(S.shape[1])]).T

    return derivatives


def solve_scipy(
    problem: Problem,
    name: str,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    max_steps: int = 5_000_000,
    max_wall_time_s: float = 600.0,
    progress=None,
    compiled: bool = True,
) -> Solution:
    params = problem.params
    t_eval = problem.t_eval
    t_end = float(t_eval[-1])
    cls = SCIPY_CLASSES[name]
    budget = Budget(max_steps, max_wall_time_s)
    # Right after a restart the dense output is consistent with the located state only
    # to the solver's tolerance, not to round-off: a new crossing must clear that band.
    restart_band = max(RESTART_BAND_FLOOR, rtol)

    out_states = np.empty((t_eval.size, 4))
    out_regimes = np.empty(t_eval.size, dtype=int)
    state = np.array(problem.initial, dtype=float)
    tau = float(t_eval[0])
    regime = model.regime_of_state(state, params)
    out_states[0], out_regimes[0] = state, regime
    k = 1  # next sample to fill
    events: list[SwitchEvent] = []
    stats = {"nsteps": 0, "nfev": 0, "njev": 0, "nlu": 0, "n_segments": 0}
    status, message = SUCCESS, "reached the end of the time span"
    last_kind = initial_kind(state, regime, params)
    storms = StormGuard()
    next_progress = tau

    compiled = compiled and kernels.ensure_fresh()
    while tau < t_end:
        fun, jac, derivatives = _rhs_functions(params, regime, compiled)
        options = {"rtol": rtol, "atol": atol}
        if name in IMPLICIT and regime != model.STICK:
            options["jac"] = jac
        solver = cls(fun, tau, state, t_end, **options)
        stats["n_segments"] += 1
        event = None
        while True:
            msg = solver.step()
            stats["nsteps"] += 1
            if solver.status == "failed":
                status, message = FAILED, f"{name} failed at tau = {solver.t:.6g}: {msg}"
                break
            if not np.all(np.isfinite(solver.y)):
                status, message = FAILED, f"non-finite state at tau = {solver.t:.6g}"
                break
            dense = solver.dense_output()
            grid = np.linspace(solver.t_old, solver.t, SCAN_POINTS + 1)
            event = earliest_event(
                dense, derivatives, grid, regime, params, last_kind, restart_band
            )
            last_kind = NO_EVENT
            t_stop = event[0] if event else solver.t
            k = fill_samples(dense, t_eval, k, t_stop, regime, params, out_states, out_regimes)
            if event is not None or solver.status == "finished":
                break
            reason = budget.exceeded(stats["nsteps"])
            if reason:
                status, message = FAILED, f"{reason} at tau = {solver.t:.6g}"
                break
            if progress is not None and solver.t >= next_progress:
                progress(solver.t)
                next_progress = solver.t + 0.01 * (t_end - t_eval[0])
        stats["nfev"] += int(solver.nfev)
        stats["njev"] += int(getattr(solver, "njev", 0) or 0)
        stats["nlu"] += int(getattr(solver, "nlu", 0) or 0)
        if status == FAILED or event is None:
            break
        t_ev = event[0]
        state, regime, kind, switch = apply_event(t_ev, event[1], dense(t_ev), regime, params)
        events.append(switch)
        if storms.storm(t_ev):
            status = FAILED
            message = storms.message()
            break
        tau, last_kind = t_ev, kind

    if status == SUCCESS and progress is not None:
        progress(t_end)
    return Solution.from_samples(
        problem,
        name,
        k,
        out_states,
        out_regimes,
        events=events,
        stats=stats,
        settings={
            "rtol": rtol,
            "atol": atol,
            "max_steps": max_steps,
            "max_wall_time_s": max_wall_time_s,
            "compiled": compiled,
        },
        status=status,
        message=message,
    )


def fill_samples(dense, t_eval, k, t_stop, regime, params, out_states, out_regimes) -> int:
    """Samples ``t_eval[k:]`` up to ``t_stop`` from a step's dense output (projected onto
    the rolling constraint in stick); returns the next sample to fill."""
    while k < t_eval.size and t_eval[k] <= t_stop:
        sample = dense(t_eval[k])
        if regime == model.STICK:
            sample = model.project_to_rolling(sample, params)
        out_states[k], out_regimes[k] = sample, regime
        k += 1
    return k


def _rhs_fun(t, s, params, regime):
    return model.rhs(t, s, params, regime)


def _jac_fun(t, s, params, regime):
    return model.rhs_jacobian(t, s, params, regime)


def _rhs_functions(params: model.ModelParams, regime: int, compiled: bool):
    """(fun, jac, derivatives) of one regime: compiled kernels or model.py in Python."""
    if not compiled:
        fun = partial(_rhs_fun, params=params, regime=regime)
        return fun, partial(_jac_fun, params=params, regime=regime), _column_derivatives(fun)
    pars = np.array(model.params_vector(params))
    rhs, jacobian, columns = kernels.rhs, kernels.rhs_jacobian, kernels.rhs_columns

    def fun(t, s):
        return rhs(t, s, pars, regime)

    def jac(t, s):
        return jacobian(t, s, pars, regime)

    def derivatives(t, S):
        t = np.broadcast_to(np.asarray(t, dtype=float), (S.shape[1],))
        return columns(np.ascontiguousarray(t), np.ascontiguousarray(S, dtype=float), pars, regime)

    return fun, jac, derivatives


def _register(name: str) -> None:
    register(name)(partial(solve_scipy, name=name))


for _name in SCIPY_CLASSES:
    _register(_name)

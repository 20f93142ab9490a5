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

Limits: an event is missed if its function changes sign twice within one accepted step
(a grazing dip shorter than a step); the scan inside each step (``SCAN_POINTS``) catches
a dip that is resolved by the dense output. Set-valued friction (stick, ``v_r = 0``
held) is not modelled: a slip reversal that is immediately undone ends the run with a
clear message instead of chattering.
"""

from __future__ import annotations

import time
from functools import partial

import numpy as np
from scipy import integrate

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import FAILED, SUCCESS, Solution, SwitchEvent
from rubcli.solvers import register
from rubcli.solvers.events import (
    GRAZING_TOLERANCE,
    StormGuard,
    entry_regime,
    first_crossing,
    reversal_undone,
    slip_rate,
    slip_value,
    surface_rate,
    surface_value,
)

SCIPY_CLASSES = {
    "rk45": integrate.RK45,
    "dop853": integrate.DOP853,
    "radau": integrate.Radau,
    "bdf": integrate.BDF,
    "lsoda": integrate.LSODA,
}
IMPLICIT = {"radau", "bdf", "lsoda"}
SCAN_POINTS = 4  # sub-intervals per step in which events are scanned on the dense output


class _Budget:
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


def _locate_event(dense, t_old, t_new, params, regime, deriv, start_on_surface, start_on_slip):
    """Earliest event of ``regime`` in (t_old, t_new] on the dense output, or None.

    Returns (tau, kind, new_regime).
    """
    grid = np.linspace(t_old, t_new, SCAN_POINTS + 1)
    S = dense(grid)
    dS = np.array([deriv(t, S[:, k]) for k, t in enumerate(grid)]).T
    found = []
    if regime == model.FREE:
        # entry: g = z^2 - 1 from < 0 to >= 0
        def h(t):
            return float(surface_value(dense(t)))

        def dh(t):
            return float(surface_rate(dense(t)))

        tau = first_crossing(
            h,
            grid,
            surface_value(S),
            surface_rate(S),
            dh,
            start_on_surface,
            GRAZING_TOLERANCE,
        )
        if tau is not None:
            found.append((tau, "contact_entry", None))
    else:
        # exit: -g from < 0 to >= 0
        def h(t):
            return -float(surface_value(dense(t)))

        def dh(t):
            return -float(surface_rate(dense(t)))

        tau = first_crossing(
            h, grid, -surface_value(S), -surface_rate(S), dh, start_on_surface, 0.0
        )
        if tau is not None:
            found.append((tau, "contact_exit", model.FREE))
        if params.mu > 0.0:
            sign = float(regime)

            def hv(t):
                return -sign * float(slip_value(dense(t), params))

            def dhv(t):
                s = dense(t)
                return -sign * float(slip_rate(s[:, None], deriv(t, s)[:, None])[0])

            tau = first_crossing(
                hv,
                grid,
                -sign * slip_value(S, params),
                -sign * slip_rate(S, dS),
                dhv,
                start_on_slip,
                0.0,
            )
            if tau is not None:
                found.append((tau, "slip_reversal", -regime))
    if not found:
        return None
    return min(found, key=lambda item: item[0])


def solve_scipy(
    problem: Problem,
    name: str,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    max_steps: int = 5_000_000,
    max_wall_time_s: float = 600.0,
    progress=None,
    **_ignored,
) -> Solution:
    params = problem.params
    t_eval = problem.t_eval
    t_end = float(t_eval[-1])
    cls = SCIPY_CLASSES[name]
    budget = _Budget(max_steps, max_wall_time_s)

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
    start_on_surface = start_on_slip = False
    storms = StormGuard()
    next_progress = tau

    while tau < t_end:
        fun = partial(_rhs_fun, params=params, regime=regime)
        options = {"rtol": rtol, "atol": atol}
        if name in IMPLICIT:
            options["jac"] = partial(_jac_fun, params=params, regime=regime)
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
            t_old, t_new = solver.t_old, solver.t
            dense = solver.dense_output()
            event = _locate_event(
                dense, t_old, t_new, params, regime, fun, start_on_surface, start_on_slip
            )
            start_on_surface = start_on_slip = False
            t_stop = event[0] if event else t_new
            while k < t_eval.size and t_eval[k] <= t_stop:
                out_states[k], out_regimes[k] = dense(t_eval[k]), regime
                k += 1
            if event is not None:
                break
            if solver.status == "finished":
                break
            reason = budget.exceeded(stats["nsteps"])
            if reason:
                status, message = FAILED, f"{reason} at tau = {t_new:.6g}"
                break
            if progress is not None and t_new >= next_progress:
                progress(t_new)
                next_progress = t_new + 0.01 * (t_end - t_eval[0])
        stats["nfev"] += int(solver.nfev)
        stats["njev"] += int(getattr(solver, "njev", 0) or 0)
        stats["nlu"] += int(getattr(solver, "nlu", 0) or 0)
        if status == FAILED:
            break
        if event is None:
            tau = t_end
            break
        t_ev, kind, new_regime = event
        state = np.asarray(dense(t_ev), dtype=float)
        if new_regime is None:
            new_regime = entry_regime(state, params)
        events.append(SwitchEvent(t_ev, kind, tuple(state), regime, new_regime))
        if storms.storm(t_ev):
            status = FAILED
            message = f"switch storm at tau = {t_ev:.6g}: {storms.count} events at one instant"
            break
        if kind == "slip_reversal" and reversal_undone(state, t_ev, new_regime, params):
            status = FAILED
            message = (
                f"slip reversal at tau = {t_ev:.6g} is immediately undone: the rotor sticks "
                f"(rolls) on the stator, which this method does not model"
            )
            break
        start_on_surface = kind in ("contact_entry", "contact_exit")
        start_on_slip = kind == "slip_reversal"
        tau, regime = t_ev, new_regime

    if status == SUCCESS and progress is not None:
        progress(t_end)
    return Solution(
        problem=problem,
        method=name,
        t=t_eval[:k].copy(),
        states=out_states[:k].copy(),
        regimes=out_regimes[:k].copy(),
        events=events,
        stats=stats,
        settings={
            "rtol": rtol,
            "atol": atol,
            "max_steps": max_steps,
            "max_wall_time_s": max_wall_time_s,
        },
        status=status,
        message=message,
    )


def _rhs_fun(t, s, params, regime):
    return model.rhs(t, s, params, regime)


def _jac_fun(t, s, params, regime):
    return model.rhs_jacobian(t, s, params, regime)


def _register(name: str) -> None:
    register(name)(partial(solve_scipy, name=name))


for _name in SCIPY_CLASSES:
    _register(_name)

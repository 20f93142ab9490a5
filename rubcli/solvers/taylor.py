"""``taylor``: an adaptive Taylor-series integrator of the rub equations, compiled.

Scheme: Taylor's method of order N = ceil(-ln(rtol) / 2) + 1 (8 at rtol 1e-6, 13 at
1e-10), its coefficients computed by the automatic-differentiation recurrences of the
regime-locked right-hand side (``taylor_kernels.taylor_coefficients``: forcing, z =
sqrt(x^2 + y^2), 1/z, the products of the contact law and of the rolling law), the step
by Jorba and Zou's rule (the last two terms below max(atol, rtol |s|)), no rejected steps.
It is the approach of heyoka (Biscani and Izzo 2021), written for this one system, with
the events of the other methods located on each step's Taylor polynomial.

Its order is N; its local error per step is about the tolerance, and its dense output
(the polynomial) carries the same accuracy between steps, so samples and events come at
no extra cost. The step is limited by the radius of convergence of the series, about
1 / omega for the fastest frequency omega: on stiff stators (large K, omega ~ sqrt(K)) it
takes many steps like every explicit method.

Events follow the scipy methods' rules (``scipy_ivp``, ``dop853_jit``): one regime at a
time, the events of the regime found on each step's polynomial by a transcription of
``events.first_crossing`` on a scan grid and applied by ``events.apply_event``'s rule
(Filippov at v_r = 0, rolling in stick); see ``taylor_kernels``. ``compiled_events=False``
hands every step that might hold an event to the Python event code
(``events.earliest_event`` on the step's polynomial, ``events.apply_event``): the tests
check that both give the same events and states. ``compiled=False`` is the same as
``compiled_events=False`` (the series themselves are always compiled).
"""

from __future__ import annotations

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import FAILED, SUCCESS, Solution, SwitchEvent
from rubcli.solvers import kernels, register, taylor_kernels
from rubcli.solvers.dop853_jit import EVENT_BUFFER, KERNEL_KINDS
from rubcli.solvers.events import (
    StormGuard,
    apply_event,
    earliest_event,
    initial_kind,
    start_flags,
)
from rubcli.solvers.scipy_ivp import RESTART_BAND_FLOOR, Budget, _rhs_functions, fill_samples

CHUNK_STEPS = 2000  # steps per kernel call: budget and progress checks between


class TaylorDense:
    """A step's Taylor polynomial: the state at a scalar time (4,) or at times (4, n)."""

    def __init__(self, t0: float, C: np.ndarray, order: int):
        self.t0, self.C, self.order = t0, C[:, : order + 1].copy(), order

    def __call__(self, t):
        dt = np.asarray(t, dtype=float) - self.t0
        if dt.ndim == 0:
            dt = float(dt)
            v = self.C[:, self.order].copy()
            for k in range(self.order - 1, -1, -1):
                v = v * dt + self.C[:, k]
            return v
        out = np.empty((4, dt.size))
        for i in range(4):
            v = np.full(dt.shape, self.C[i, self.order])
            for k in range(self.order - 1, -1, -1):
                v = v * dt + self.C[i, k]
            out[i] = v
        return out


def solve_taylor(
    problem: Problem,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    max_steps: int = 5_000_000,
    max_wall_time_s: float = 600.0,
    progress=None,
    compiled: bool = True,
    compiled_events: bool = True,
    **_ignored,
) -> Solution:
    """Adaptive Taylor series of order ceil(-ln(rtol)/2) + 1 with located events."""
    kernels.ensure_fresh()
    compiled_events = bool(compiled_events and compiled)
    params = problem.params
    pars = np.array(model.params_vector(params))
    t_eval = problem.t_eval
    t_end = float(t_eval[-1])
    budget = Budget(max_steps, max_wall_time_s)
    restart_band = max(RESTART_BAND_FLOOR, rtol)
    rtol = max(rtol, 100 * np.finfo(float).eps)
    order = taylor_kernels.taylor_order(rtol)

    out_states = np.empty((t_eval.size, 4))
    out_regimes = np.empty(t_eval.size, dtype=int)
    state = np.array(problem.initial, dtype=float)
    tau = float(t_eval[0])
    regime = model.regime_of_state(state, params)
    out_states[0], out_regimes[0] = state, regime
    k = 1
    events: list[SwitchEvent] = []
    stats = {"nsteps": 0, "nfev": 0, "n_segments": 1, "python_steps": 0, "order": order}
    status, message = SUCCESS, "reached the end of the time span"
    last_kind = initial_kind(state, regime, params)
    storms = StormGuard()
    next_progress = tau
    C = np.zeros((4, taylor_kernels.MAX_ORDER + 1))
    info = np.zeros(1, dtype=np.int64)
    ev_tau, ev_kind = np.empty(EVENT_BUFFER), np.empty(EVENT_BUFFER, dtype=np.int64)
    ev_state, ev_regimes = np.empty((EVENT_BUFFER, 4)), np.empty((EVENT_BUFFER, 2), dtype=np.int64)
    at_event = last_kind is not None

    while True:
        starts = start_flags(last_kind) if at_event else start_flags(None)
        chunk = max(1, min(CHUNK_STEPS, max_steps - stats["nsteps"]))
        tau, t_new, k, steps, reason, regime, n_ev, at_event = taylor_kernels.advance_taylor(
            tau, state, t_end, pars, regime, order, rtol, atol, t_eval, out_states,
            out_regimes, k, chunk, starts, C, restart_band, ev_tau, ev_kind, ev_state,
            ev_regimes, compiled_events, info,
        )  # fmt: skip
        stats["nsteps"] += steps
        stats["n_segments"] += n_ev
        taus, kinds = ev_tau[:n_ev].tolist(), ev_kind[:n_ev].tolist()
        ev_states, ev_regs = ev_state[:n_ev].tolist(), ev_regimes[:n_ev].tolist()
        for i in range(n_ev):
            t_ev, kind = taus[i], KERNEL_KINDS[kinds[i]]
            before, after = ev_regs[i]
            events.append(SwitchEvent(t_ev, kind, tuple(ev_states[i]), before, after))
            last_kind = kind
            if storms.storm(t_ev):
                status, message = FAILED, storms.message()
                k = int(np.searchsorted(t_eval, t_ev, side="right"))
                break
        if status == FAILED or reason == kernels.STOP_END:
            break
        if reason == kernels.STOP_SMALL_STEP:
            status = FAILED
            message = f"taylor failed at tau = {tau:.6g}: the step fell below 10 ulp of tau"
            break
        if reason == kernels.STOP_PYTHON:
            status, message = FAILED, f"non-finite state at tau = {t_new:.6g}"
            break
        if reason == kernels.STOP_EVENT:
            # the pending step [tau, t_new]: the shared event code decides
            stats["nsteps"] += 1
            stats["python_steps"] += 1
            dense = TaylorDense(tau, C, order)
            grid = np.linspace(tau, t_new, int(info[0]) + 1)
            derivatives = _rhs_functions(params, regime, True)[2]
            event = earliest_event(
                dense, derivatives, grid, regime, params, last_kind if at_event else None,
                restart_band,
            )  # fmt: skip
            t_stop = event[0] if event else t_new
            k = fill_samples(dense, t_eval, k, t_stop, regime, params, out_states, out_regimes)
            if event is None:
                tau, at_event = t_new, False
                state[:] = dense(t_new)
            else:
                t_ev = event[0]
                state, regime, switch = apply_event(t_ev, event[1], dense(t_ev), regime, params)
                state = np.array(state, dtype=float)
                events.append(switch)
                stats["n_segments"] += 1
                if storms.storm(t_ev):
                    status, message = FAILED, storms.message()
                    break
                tau, last_kind, at_event = t_ev, switch.kind, True
                if tau >= t_end:
                    break
        over = budget.exceeded(stats["nsteps"])
        if over:
            status, message = FAILED, f"{over} at tau = {tau:.6g}"
            break
        if progress is not None and tau >= next_progress:
            progress(tau)
            next_progress = tau + 0.01 * (t_end - t_eval[0])

    stats["nfev"] = stats["nsteps"]  # one series expansion per step
    if status == SUCCESS and progress is not None:
        progress(t_end)
    return Solution.from_samples(
        problem,
        "taylor",
        k,
        out_states,
        out_regimes,
        events=events,
        stats=stats,
        settings={
            "rtol": rtol,
            "atol": atol,
            "order": order,
            "max_steps": max_steps,
            "max_wall_time_s": max_wall_time_s,
            "compiled": True,
            "compiled_events": compiled_events,
        },
        status=status,
        message=message,
    )


register("taylor")(solve_taylor)

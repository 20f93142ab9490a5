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
is possible it runs a compiled transcription of ``earliest_event`` (``first_crossing``
for each event function of the regime: the contact surface, the slip reversal, the two
sides of the friction cone in stick; scipy's Brent iteration) and of ``apply_event``
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
from rubcli.solution import FAILED, SUCCESS, Solution, SwitchEvent
from rubcli.solvers import kernels, register
from rubcli.solvers.events import (
    KIND_NAMES,
    NO_EVENT,
    StormGuard,
    apply_event,
    earliest_event,
    initial_kind,
    start_flags,
)
from rubcli.solvers.scipy_ivp import (
    RESTART_BAND_FLOOR,
    SCAN_POINTS,
    Budget,
    _rhs_functions,
    fill_samples,
    solve_scipy,
)

CHUNK_STEPS = 2000  # committed steps per kernel call: budget and progress checks between
EVENT_BUFFER = 256  # events the kernel may apply before it returns to flush them


class Dop853Dense:
    """The dense output of one step (scipy's ``Dop853DenseOutput``), from the kernel's F."""

    def __init__(self, t_old: float, t_new: float, y_old: np.ndarray, F: np.ndarray):
        self.t_old, self.h = t_old, t_new - t_old
        self.y_old, self.F = y_old.copy(), F.copy()

    def __call__(self, t):
        if isinstance(t, np.ndarray) and t.ndim == 1:
            return kernels.dop853_dense(t.astype(float), self.t_old, self.h, self.y_old, self.F)
        return kernels.dop853_dense_point(float(t), self.t_old, self.h, self.y_old, self.F)


def solve_dop853_jit(
    problem: Problem,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    max_steps: int = 5_000_000,
    max_wall_time_s: float = 600.0,
    progress=None,
    compiled: bool = True,
    compiled_events: bool = True,
) -> Solution:
    """scipy's DOP853 in a compiled step loop; ``compiled_events=False`` hands every
    possible event to the Python event code (a check of the compiled one)."""
    if not (compiled and kernels.ensure_fresh()):
        # the same algorithm, run by scipy (kernels unusable or compiled=False)
        sol = solve_scipy(
            problem, "dop853", rtol, atol, max_steps, max_wall_time_s, progress, compiled=False
        )
        sol.method = "dop853-jit"
        return sol
    params = problem.params
    pars = np.array(model.params_vector(params))
    t_eval = problem.t_eval
    t_end = float(t_eval[-1])
    budget = Budget(max_steps, max_wall_time_s)
    restart_band = max(RESTART_BAND_FLOOR, rtol)
    # scipy raises a too small rtol to 100 eps (with a warning); so do we, silently
    rtol = max(rtol, 100 * np.finfo(float).eps)

    out_states = np.empty((t_eval.size, 4))
    out_regimes = np.empty(t_eval.size, dtype=int)
    state = np.array(problem.initial, dtype=float)
    tau = float(t_eval[0])
    regime = model.regime_of_state(state, params)
    out_states[0], out_regimes[0] = state, regime
    k = 1
    events: list[SwitchEvent] = []
    stats = {"nsteps": 0, "nfev": 0, "n_segments": 0, "python_steps": 0}
    status, message = SUCCESS, "reached the end of the time span"
    last_kind = initial_kind(state, regime, params)
    storms = StormGuard()
    next_progress = tau
    y_new, f_new, F = np.empty(4), np.empty(4), np.empty((7, 4))
    f = np.empty(4)
    ev_tau, ev_kind = np.empty(EVENT_BUFFER), np.empty(EVENT_BUFFER, dtype=np.int64)
    ev_state, ev_regimes = np.empty((EVENT_BUFFER, 4)), np.empty((EVENT_BUFFER, 2), dtype=np.int64)
    new_segment, at_event = True, last_kind != NO_EVENT

    while True:
        if new_segment:  # as scipy starts a solver: f and the initial step
            f[:] = kernels.rhs(tau, state, pars, regime)
            h_abs = kernels.dop853_initial_step(tau, state, f, t_end, pars, regime, rtol, atol)
            stats["nfev"] += 2
            stats["n_segments"] += 1
            new_segment = False
        starts = start_flags(last_kind if at_event else NO_EVENT)
        chunk = max(1, min(CHUNK_STEPS, max_steps - stats["nsteps"]))
        tau, t_new, h_abs, k, steps, nfev, reason, regime, n_ev, at_event = (
            kernels.advance_dop853(
                tau, state, f, h_abs, t_end, pars, regime, rtol, atol, t_eval, out_states,
                out_regimes, k, chunk, starts, y_new, f_new, F, restart_band, ev_tau, ev_kind,
                ev_state, ev_regimes, compiled_events,
            )
        )  # fmt: skip
        stats["nsteps"] += steps
        stats["nfev"] += nfev
        # segments the kernel started (with a full buffer the last one starts here)
        stats["n_segments"] += n_ev - (reason == kernels.STOP_FULL)
        for i in range(n_ev):  # the events the kernel located and applied
            t_ev, last_kind = float(ev_tau[i]), int(ev_kind[i])
            before, after = int(ev_regimes[i, 0]), int(ev_regimes[i, 1])
            state_i = tuple(map(float, ev_state[i]))
            events.append(SwitchEvent(t_ev, KIND_NAMES[last_kind], state_i, before, after))
            if storms.storm(t_ev):
                status, message = FAILED, storms.message()
                k = int(np.searchsorted(t_eval, t_ev, side="right"))
                break
        if status == FAILED:
            break
        if reason == kernels.STOP_END:
            break
        if reason == kernels.STOP_SMALL_STEP:
            status = FAILED
            message = (
                f"dop853-jit failed at tau = {tau:.6g}: "
                "required step size is less than spacing between numbers"
            )
            break
        if reason == kernels.STOP_PYTHON:
            status, message = FAILED, f"non-finite state at tau = {t_new:.6g}"
            break
        if reason == kernels.STOP_FULL:
            new_segment = True
        elif reason == kernels.STOP_EVENT:
            # the pending step [tau, t_new]: the shared event code decides
            stats["nsteps"] += 1
            stats["python_steps"] += 1
            dense = Dop853Dense(tau, t_new, state, F)
            grid = np.linspace(tau, t_new, SCAN_POINTS + 1)
            derivatives = _rhs_functions(params, regime, True)[2]
            event = earliest_event(
                dense, derivatives, grid, regime, params, last_kind if at_event else NO_EVENT,
                restart_band,
            )  # fmt: skip
            t_stop = event[0] if event else t_new
            k = fill_samples(dense, t_eval, k, t_stop, regime, params, out_states, out_regimes)
            if event is None:
                tau, at_event = t_new, False
                state[:], f[:] = y_new, f_new
            else:
                t_ev = event[0]
                state, regime, kind, switch = apply_event(
                    t_ev, event[1], dense(t_ev), regime, params
                )
                events.append(switch)
                if storms.storm(t_ev):
                    status, message = FAILED, storms.message()
                    break
                tau, last_kind, at_event, new_segment = t_ev, kind, True, True
                if tau >= t_end:
                    break
        over = budget.exceeded(stats["nsteps"])
        if over:
            status, message = FAILED, f"{over} at tau = {tau:.6g}"
            break
        if progress is not None and tau >= next_progress:
            progress(tau)
            next_progress = tau + 0.01 * (t_end - t_eval[0])

    if status == SUCCESS and progress is not None:
        progress(t_end)
    return Solution.from_samples(
        problem,
        "dop853-jit",
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
            "compiled": True,
            "compiled_events": compiled_events,
        },
        status=status,
        message=message,
    )


register("dop853-jit")(solve_dop853_jit)

"""A run of a composed machine: the event loop around a stepper, for every method.

Each step (``dop853-jit``: many steps in the compiled ``advance``; scipy's methods: one
``OdeSolver.step`` each) is scanned at its quarters for an event function leaving its
regime (``kernels.event_functions``); the earliest crossing of the first scan interval
that has one is located by Brent's method on the step's dense output, the samples up to
it are written, and the switch rule applied:

- contact entry (``z`` reaches the clearance): slip in the sign of ``v_r`` (stick if
  ``v_r = 0`` and the cone holds it); contact exit: free;
- ``v_r`` reaching 0 while slipping: stick if the stick force the station needs lies in
  the friction cone (Filippov's rule; the velocities are then moved onto the rolling
  constraint), else slip the other way;
- the cone left in stick: slip in the direction the needed force points.

The run then starts a new segment at the event. Limits, stated: two crossings of one
event function inside one scan interval (a quarter step) are not seen; the scan is
conservative only as far as the step's error control resolves the event functions.
Budgets: ``max_steps``, ``max_events``, ``max_wall_time_s``; an event storm (more than
``STORM_EVENTS`` events without time moving on) fails the run with a message.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK45, Radau
from scipy.optimize import brentq

from rubcli.machine import Machine
from rubcli.model import FREE, SLIP_NEGATIVE, SLIP_POSITIVE, STICK
from rubcli.system import advance as adv
from rubcli.system.analytic import (
    GROW,
    SAFETY,
    SHRINK,
    STEPS_PER_PERIOD,
    AnalyticError,
    Dense,
    FreeFlow,
    Piece,
)
from rubcli.system.arrays import SystemArrays
from rubcli.system.kernels import (
    OK,
    S_MU,
    V_NORMAL,
    V_SLIP,
    V_TANGENTIAL,
    W_VELOCITY,
    evaluate,
    event_functions,
    jacobian_into,
    rhs_into,
)
from rubcli.system.solution import (
    ENTRY,
    EXIT,
    FAILED,
    REVERSAL,
    STICK_ENTRY,
    STICK_EXIT,
    SUCCESS,
    MachineSolution,
    StationEvents,
)

SCIPY_METHODS = {"rk45": RK45, "dop853": DOP853, "radau": Radau, "bdf": BDF, "lsoda": LSODA}
METHODS = ("dop853-jit", "analytic", *SCIPY_METHODS)
IMPLICIT = ("radau", "bdf", "lsoda")
STORM_EVENTS = 200  # events in a row at one instant: a storm
CHUNK_STEPS = 20_000  # dop853-jit's steps between two checks of the wall-time budget


class _RunError(Exception):
    pass


def simulate(
    machine: Machine,
    t_eval: np.ndarray,
    initial: np.ndarray | None = None,
    method: str = "dop853-jit",
    rtol: float = 1e-9,
    atol: float = 1e-12,
    max_steps: int = 10_000_000,
    max_events: int = 1_000_000,
    max_wall_time_s: float | None = None,
) -> MachineSolution:
    """Runs ``machine`` from ``initial`` (``(q, v)``, 2 n numbers; None: at rest at 0)
    over the sample times ``t_eval`` with ``method`` (``METHODS``)."""
    if not isinstance(machine, Machine):
        raise TypeError(f"simulate: machine must be a Machine, got {type(machine).__name__}")
    if method not in METHODS:
        raise ValueError(f"simulate: unknown method {method!r}; choose from {', '.join(METHODS)}")
    if method == "analytic" and not machine.speed.is_constant:
        raise ValueError(
            "simulate: analytic needs a constant speed (its free flight is the closed form "
            "of a structure that does not change); a speed that changes runs by dop853-jit "
            "or radau"
        )
    n = machine.size
    t_eval = np.asarray(t_eval, dtype=float)
    if t_eval.ndim != 1 or t_eval.size < 2 or not np.all(np.diff(t_eval) > 0):
        raise ValueError("simulate: t_eval must be at least 2 increasing times")
    if not np.all(np.isfinite(t_eval)):
        raise ValueError("simulate: t_eval must be finite")
    for name, value in (("max_steps", max_steps), ("max_events", max_events)):
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise ValueError(f"simulate: {name} must be an int > 0 (got {value!r})")
    if max_wall_time_s is not None and not (
        isinstance(max_wall_time_s, int | float) and math.isfinite(max_wall_time_s)
        and max_wall_time_s > 0
    ):  # fmt: skip
        raise ValueError(
            f"simulate: max_wall_time_s must be a finite number > 0 (got {max_wall_time_s!r})"
        )
    for name, value in (("rtol", rtol), ("atol", atol)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"simulate: {name} must be a finite number > 0 (got {value!r})")
    y0 = np.zeros(2 * n + 1)
    if initial is not None:
        start = np.asarray(initial, dtype=float).reshape(-1)
        if start.shape != (2 * n,) or not np.all(np.isfinite(start)):
            raise ValueError(f"simulate: initial must be {2 * n} finite numbers (q, v)")
        y0[: 2 * n] = start
    run = _Run(SystemArrays.of(machine), t_eval, method, rtol, atol)
    started = time.perf_counter()
    deadline = None if max_wall_time_s is None else started + float(max_wall_time_s)
    status, message = SUCCESS, ""
    try:
        run.go(y0, max_steps, max_events, deadline)
    except _RunError as failure:
        status, message = FAILED, str(failure)
    k = run.k
    events = run.event_columns()
    return MachineSolution(
        machine=machine,
        method=method,
        t=t_eval[:k].copy(),
        states=run.samples[:k, : 2 * n].copy(),
        work=run.samples[:k, 2 * n].copy(),
        regimes=run.sample_regimes[:k].copy(),
        events=events,
        stats={"steps": run.steps, "nfev": run.nfev, "events": len(events)},
        settings={"rtol": rtol, "atol": atol},
        status=status,
        message=message,
        wall_time_s=time.perf_counter() - started,
    )


class _Run:
    """The state of one run: buffers, regimes, samples, events."""

    def __init__(self, arrays: SystemArrays, t_eval: np.ndarray, method: str, rtol, atol):
        self.arrays = arrays
        self.t_eval = t_eval
        self.method = method
        self.rtol, self.atol = float(rtol), float(atol)
        S = arrays.indices.shape[0]
        m = arrays.size
        self.n = arrays.Minv.shape[0]
        self.regimes = np.zeros(S, dtype=np.int64)
        self.ctx = arrays.context(self.regimes)
        self.samples = np.zeros((t_eval.size, m))
        self.sample_regimes = np.zeros((t_eval.size, S), dtype=np.int8)
        self.k = 0
        self.steps = 0
        self.nfev = 0
        self.events: list[tuple] = []
        self.out = np.empty(m)
        self.vals = np.empty((S, 4))
        self.g = np.empty((S, 2))
        self.g_prev = np.ones((S, 2))
        self.point = np.empty(m)
        # analytic: the free flight (built at the first segment) and a context with every
        # station free, whose right-hand side is the structure's alone
        self.flow: FreeFlow | None = None
        self.ctx_free = arrays.context(np.zeros(S, dtype=np.int64))
        self._free_out = np.empty(m)

    # -- the system at one state ---------------------------------------------------------
    def _evaluate(self, t: float, y: np.ndarray) -> None:
        if evaluate(t, y, self.ctx, self.out, self.vals) != OK:
            raise _RunError(f"the stick stations' mobilities are singular at t = {t:.9g}")

    def _g(self, t: float, y: np.ndarray) -> np.ndarray:
        if event_functions(t, y, self.ctx, self.out, self.vals, self.g) != OK:
            raise _RunError(f"the stick stations' mobilities are singular at t = {t:.9g}")
        return self.g

    # -- the loop -----------------------------------------------------------------------
    def go(self, y0: np.ndarray, max_steps: int, max_events: int, deadline: float | None) -> None:
        t = float(self.t_eval[0])
        t_end = float(self.t_eval[-1])
        y = y0.copy()
        self._initial_regimes(t, y)
        self.samples[0] = y
        self.sample_regimes[0] = self.regimes
        self.k = 1
        storm = 0
        while t < t_end:
            if deadline is not None and time.perf_counter() > deadline:
                raise _RunError(f"the wall-time budget ran out at t = {t:.9g}")
            found = self._segment(t, y, t_end, max_steps, deadline)
            if found is None:
                break
            t_ev, y_ev, station, which, dense = found
            self._samples_until(t_ev, dense)
            y = y_ev
            storm = storm + 1 if self.events and t_ev - self.events[-1][0] <= _instant(t_ev) else 0
            if storm > STORM_EVENTS:
                raise _RunError(
                    f"an event storm at t = {t_ev:.9g}: more than {STORM_EVENTS} events at one "
                    f"instant at station {station}"
                )
            self._switch(t_ev, y, station, which)
            if len(self.events) > max_events:
                raise _RunError(f"more than max_events = {max_events} events by t = {t_ev:.9g}")
            t = t_ev
        # samples at t_end (a run that ends exactly on an event)
        while self.k < self.t_eval.size and self.t_eval[self.k] <= t:
            self.samples[self.k] = y
            self.sample_regimes[self.k] = self.regimes
            self.k += 1

    def _segment(self, t, y, t_end, max_steps, deadline):
        """Steps from (t, y) in the current regimes to the next event (its time, state,
        station, function and the dense output around it) or the end (None)."""
        self.g_prev[:] = 1.0
        if self.method == "dop853-jit":
            return self._segment_jit(t, y, t_end, max_steps, deadline)
        if self.method == "analytic":
            return self._segment_analytic(t, y, t_end, max_steps, deadline)
        return self._segment_scipy(t, y, t_end, max_steps, deadline)

    def _segment_jit(self, t, y, t_end, max_steps, deadline):
        y = y.copy()
        m = y.size
        f = np.empty(m)
        h_abs = adv.first_step(t, y, f, t_end, self.ctx, self.rtol, self.atol)
        Kst = np.empty((16, m))
        y_new, tmp, F = np.empty(m), np.empty(m), np.empty((7, m))
        while True:
            chunk = min(CHUNK_STEPS, max_steps - self.steps)
            if chunk <= 0:
                raise _RunError(f"more than max_steps = {max_steps} steps by t = {t:.9g}")
            stop, t, h_abs, self.k, steps, nfev, t_old, h, j = adv.advance(
                t, y, f, h_abs, t_end, self.ctx, self.rtol, self.atol, self.t_eval, self.k,
                self.samples, self.sample_regimes, chunk, Kst, y_new, tmp, F, self.g_prev,
                self.g, self.vals, self.out, self.point,
            )  # fmt: skip
            self.steps += steps
            self.nfev += nfev
            if stop == adv.END:
                return None
            if stop == adv.SMALL_STEP:
                raise _RunError(f"the step size fell below the minimum at t = {t:.9g}")
            if stop == adv.SINGULAR_STICK:
                raise _RunError(f"the stick stations' mobilities are singular at t = {t:.9g}")
            if stop == adv.EVENT:
                y_old, coeffs = y.copy(), F.copy()

                def dense(
                    tau: float, t_old: float = t_old, h: float = h, y_old: np.ndarray = y_old,
                    coeffs: np.ndarray = coeffs,
                ) -> np.ndarray:  # fmt: skip
                    out = np.empty(m)
                    adv.dense_point(tau, t_old, h, y_old, coeffs, out)
                    return out

                root, s, i = adv.locate(
                    t_old, h, j, y_old, coeffs, self.ctx, self.g_prev, self.out, self.vals,
                    self.g, self.point,
                )  # fmt: skip
                return root, self.point.copy(), s, i, dense
            if deadline is not None and time.perf_counter() > deadline:
                raise _RunError(f"the wall-time budget ran out at t = {t:.9g}")

    def _segment_scipy(self, t, y, t_end, max_steps, deadline):
        m = y.size
        ctx = self.ctx

        def fun(tau: float, state: np.ndarray) -> np.ndarray:
            out = np.empty(m)
            rhs_into(tau, np.ascontiguousarray(state, dtype=float), ctx, 0, out)
            return out

        options = {}
        if self.method in IMPLICIT:
            scale = self._state_scale()
            buffers = [np.empty((m, m)), np.empty(m), np.empty(m), np.empty(m)]

            def jac(tau: float, state: np.ndarray) -> np.ndarray:
                state = np.ascontiguousarray(state, dtype=float)
                jacobian_into(tau, state, ctx, scale, *buffers)
                return buffers[0].copy()

            options["jac"] = jac
        solver = SCIPY_METHODS[self.method](
            fun, t, y.copy(), t_end, rtol=self.rtol, atol=self.atol, **options
        )
        nfev_before = self.nfev  # a solver counts its own segment's evaluations
        while True:
            if self.steps >= max_steps:
                raise _RunError(f"more than max_steps = {max_steps} steps by t = {solver.t:.9g}")
            if deadline is not None and time.perf_counter() > deadline:
                raise _RunError(f"the wall-time budget ran out at t = {solver.t:.9g}")
            message = solver.step()
            self.steps += 1
            if solver.status == "failed":
                raise _RunError(f"{self.method} failed at t = {solver.t:.9g}: {message}")
            t_old, t_new = solver.t_old, solver.t
            dense = solver.dense_output()
            h = t_new - t_old
            for j in range(1, adv.SCAN_POINTS + 1):
                tj = t_new if j == adv.SCAN_POINTS else t_old + h * j / adv.SCAN_POINTS
                yj = solver.y if j == adv.SCAN_POINTS else dense(tj)
                g = self._g(tj, np.ascontiguousarray(yj))
                if np.any((self.g_prev > 0.0) & (g <= 0.0)):
                    self.nfev = nfev_before + solver.nfev
                    return self._locate(t_old, h, j, dense)
                self.g_prev[:] = g
            self._samples_until(t_new, dense)
            self.nfev = nfev_before + solver.nfev
            if solver.status == "finished":
                return None

    def _segment_analytic(self, t, y, t_end, max_steps, deadline):
        """Closed-form steps (``system.analytic``): one piece a free step, two half
        pieces a contact step (step doubling), each scanned at its quarters."""
        if self.flow is None:
            try:
                self.flow = FreeFlow(self.arrays, self.ctx_free, t)
            except AnalyticError as failure:
                raise _RunError(f"analytic cannot run this machine: {failure}") from None
        flow = self.flow
        y = y.copy()
        h_contact = None
        rho = flow.omega
        while t < t_end:
            if self.steps >= max_steps:
                raise _RunError(f"more than max_steps = {max_steps} steps by t = {t:.9g}")
            if deadline is not None and time.perf_counter() > deadline:
                raise _RunError(f"the wall-time budget ran out at t = {t:.9g}")
            w0 = flow.modal(y)
            if not np.any(self.regimes != FREE):
                rho = flow.fastest_rate(t, w0, self.rtol)
                h_res = min(2.0 * math.pi / (rho * STEPS_PER_PERIOD), t_end - t)
                pieces = [Piece(flow, t, y, w0, h_res)]
            else:
                pieces, h_contact, rho = self._contact_step(t, y, w0, t_end, h_contact, rho)
            self.steps += 1
            dense = Dense(pieces, self.ctx)
            for piece in pieces:
                scan = piece.t0 + piece.h * np.arange(1, adv.SCAN_POINTS + 1) / adv.SCAN_POINTS
                scan[-1] = piece.t1
                for j, (tj, yj) in enumerate(zip(scan, piece.states(scan), strict=True), 1):
                    g = self._g(tj, yj)
                    if np.any((self.g_prev > 0.0) & (g <= 0.0)):
                        return self._locate(piece.t0, piece.h, j, dense, dense.state)
                    self.g_prev[:] = g
                self._samples_until(piece.t1, dense)
            last = pieces[-1]
            t = last.t1
            y = dense(t)
            if np.any(self.regimes == STICK):  # the velocities back onto rolling
                self._evaluate(t, y)
                y[self.n : 2 * self.n] = self.ctx[13][W_VELOCITY]
        return None

    def _station_acceleration(self, t: float, y: np.ndarray) -> np.ndarray:
        """The stations' share of the acceleration: the system's minus the free one's."""
        n = self.n
        rhs_into(t, y, self.ctx, 0, self.out)
        rhs_into(t, y, self.ctx_free, 0, self._free_out)
        self.nfev += 2
        return self.out[n : 2 * n] - self._free_out[n : 2 * n]

    def _expansion(self, t: float, y: np.ndarray, rho: float) -> tuple[np.ndarray, np.ndarray]:
        """The stations' acceleration at (t, y) and its rate along the flow: a one-sided
        second-order difference (ahead only: a contact's start is its surface) over
        1e-5 of the fastest motion's period, so that neither its truncation nor its
        rounding shows at the step's order."""
        a0 = self._station_acceleration(t, y)
        rhs_into(t, y, self.ctx, 0, self.out)
        self.nfev += 1
        rate = self.out.copy()
        delta = 1e-5 * 2.0 * math.pi / rho
        a1 = self._station_acceleration(t + delta, y + delta * rate)
        a2 = self._station_acceleration(t + 2.0 * delta, y + 2.0 * delta * rate)
        return a0, (4.0 * a1 - 3.0 * a0 - a2) / (2.0 * delta)

    def _contact_step(self, t, y, w0, t_end, h_contact, rho):
        """A contact step: the station forces linear in time about (t, y) (the predictor),
        then the cubic through their values and rates at both ends (the corrector, kept);
        the difference between it and the quadratic through the start's value and rate
        and the end's value, ``O(h^4)``, and the cubic's defect at the step's middle are
        held to rtol/atol on the mechanical states.
        Returns the piece, the next step's length and the resolution's rate."""
        flow = self.flow
        a0, r0 = self._expansion(t, y, rho)
        rho = flow.fastest_rate(t, w0, self.rtol, flow.modal_forces(a0, r0))
        h_res = min(2.0 * math.pi / (rho * STEPS_PER_PERIOD), t_end - t)
        h = h_res if h_contact is None else min(h_contact, h_res)
        m2 = 2 * self.n
        while True:
            t1 = t + h
            predictor = Piece(flow, t, y, w0, h, flow.modal_forces(a0, r0))
            guess = predictor.state(t1)
            a1, r1 = self._expansion(t1, guess, rho)
            jump = a1 - a0 - r0 * h
            c2 = (3.0 * jump - h * (r1 - r0)) / h**2
            c3 = (h * (r1 - r0) - 2.0 * jump) / h**3
            piece = Piece(flow, t, y, w0, h, flow.modal_forces(a0, r0, c2, c3))
            end = piece.state(t1)
            lower = Piece(flow, t, y, w0, h, flow.modal_forces(a0, r0, jump / h**2))
            other = lower.state(t1)
            # the cubic's defect at the step's middle (a kink inside, which the ends do
            # not see: a force that stops pulling), as the state error it would make
            middle = t + 0.5 * h
            cubic = a0 + 0.5 * h * (r0 + 0.5 * h * (c2 + 0.5 * h * c3))
            defect = self._station_acceleration(middle, piece.state(middle)) - cubic
            scale = self.atol + self.rtol * np.maximum(np.abs(y[:m2]), np.abs(end[:m2]))
            error = np.maximum(
                np.abs(other[:m2] - end[:m2]),
                np.concatenate([0.125 * h * h * np.abs(defect), 0.5 * h * np.abs(defect)]),
            )
            err = float(np.sqrt(np.mean((error / scale) ** 2)))
            if not math.isfinite(err):
                err = math.inf
            factor = GROW if err == 0.0 else min(GROW, max(SHRINK, SAFETY * err**-0.25))
            if err <= 1.0:
                return [piece], h * factor, rho
            h *= factor
            if h <= 16.0 * math.ulp(max(abs(t), 1.0)):
                raise _RunError(f"the step size fell below the minimum at t = {t:.9g}")

    def _state_scale(self) -> np.ndarray:
        """A typical size of each state, for the Jacobian's differences: the smallest
        clearance for positions, it times the fastest spin speed for velocities."""
        clearance = float(np.min(self.arrays.parameters[:, 2]))
        speed = float(np.max(self.arrays.knots[:, 1]))
        return np.concatenate(
            [np.full(self.n, clearance), np.full(self.n, clearance * max(speed, 1.0)), [1.0]]
        )

    def _locate(
        self, t_old: float, h: float, j: int, dense: Callable, state: Callable | None = None
    ):
        """The earliest event in the scan interval j of the step (t_old, h); ``state``: the
        dense output without the work, for the search (default ``dense``)."""
        state = dense if state is None else state
        ta = t_old + h * (j - 1) / adv.SCAN_POINTS
        tb = t_old + h * j / adv.SCAN_POINTS if j < adv.SCAN_POINTS else t_old + h
        gb = self._g(tb, state(tb)).copy()
        ga = self._g(ta, state(ta)).copy()
        best = None
        for s, i in zip(*np.nonzero((self.g_prev > 0.0) & (gb <= 0.0)), strict=True):
            if ga[s, i] <= 0.0:  # on or past the surface at the segment's start
                root = ta
            else:

                def value(tau: float, s: int = s, i: int = i) -> float:
                    return self._g(tau, state(tau))[s, i]

                root = brentq(value, ta, tb, xtol=4.0 * math.ulp(max(abs(ta), abs(tb), 1.0)))
                # the root strictly beyond the surface, so the switch starts outside it
                while value(root) >= 0.0 and root < tb:
                    root = min(tb, np.nextafter(root, math.inf))
            if best is None or root < best[0]:
                best = (root, int(s), int(i))
        root, s, i = best
        return root, dense(root), s, i, dense

    def _samples_until(self, t_to: float, dense: Callable) -> None:
        while self.k < self.t_eval.size and self.t_eval[self.k] <= t_to:
            self.samples[self.k] = dense(self.t_eval[self.k])
            self.sample_regimes[self.k] = self.regimes
            self.k += 1

    # -- regimes ------------------------------------------------------------------------
    def _initial_regimes(self, t: float, y: np.ndarray) -> None:
        self.regimes[:] = FREE
        self._evaluate(t, y)
        for s in np.nonzero(self.vals[:, 0] > 0.0)[0]:
            self._enter(t, y, int(s))

    def _enter(self, t: float, y: np.ndarray, s: int) -> int:
        """Station s comes into contact: slip in the sign of v_r (stick at v_r = 0 if the
        cone holds it); returns the event kind."""
        self.regimes[s] = SLIP_POSITIVE
        self._evaluate(t, y)
        slip = self.vals[s, V_SLIP]
        if slip == 0.0 and self.arrays.parameters[s, S_MU] > 0.0 and self._try_stick(t, y, s):
            return STICK_ENTRY
        self.regimes[s] = SLIP_POSITIVE if slip >= 0.0 else SLIP_NEGATIVE
        return ENTRY

    def _try_stick(self, t: float, y: np.ndarray, s: int) -> bool:
        """Stick at s if its needed force lies in the cone (the velocities then moved onto
        rolling, in y); else the regime the needed force points to."""
        self.regimes[s] = STICK
        self._evaluate(t, y)
        needed = self.vals[s, V_TANGENTIAL]
        mu = self.arrays.parameters[s, S_MU]
        if abs(needed) <= mu * self.vals[s, V_NORMAL]:
            y[self.n : 2 * self.n] = self.ctx[13][W_VELOCITY]
            return True
        self.regimes[s] = SLIP_POSITIVE if needed > 0.0 else SLIP_NEGATIVE
        return False

    def _switch(self, t: float, y: np.ndarray, s: int, which: int) -> None:
        before = int(self.regimes[s])
        if which == 0:
            if before == FREE:
                kind = self._enter(t, y, s)
            else:
                self.regimes[s] = FREE
                kind = EXIT
        elif before == STICK:
            self._evaluate(t, y)
            self.regimes[s] = SLIP_POSITIVE if self.vals[s, V_TANGENTIAL] > 0.0 else SLIP_NEGATIVE
            kind = STICK_EXIT
        else:
            kind = STICK_ENTRY if self._try_stick(t, y, s) else REVERSAL
            if kind == REVERSAL and self.regimes[s] == before:
                self.regimes[s] = -before
        self.events.append((t, s, kind, before, int(self.regimes[s]), y[: 2 * self.n].copy()))

    def event_columns(self) -> StationEvents:
        m = 2 * self.n
        if not self.events:
            empty = np.empty(0)
            return StationEvents(
                empty, empty.astype(np.int64), empty.astype(np.int8), empty.astype(np.int8),
                empty.astype(np.int8), np.empty((0, m)),
            )  # fmt: skip
        t, s, kind, before, after, state = zip(*self.events, strict=True)
        return StationEvents(
            np.array(t), np.array(s, dtype=np.int64), np.array(kind, dtype=np.int8),
            np.array(before, dtype=np.int8), np.array(after, dtype=np.int8), np.array(state),
        )  # fmt: skip


def _instant(t: float) -> float:
    return 64.0 * math.ulp(max(abs(t), 1.0))

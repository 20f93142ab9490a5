"""The paper's piecewise analytical method on the stator with its own mass
(``rubcli.stator``): ``analytic`` on the two bodies.

At a constant speed the two bodies' eight mechanical states ``q = (x, y, vx, vy, u, v,
u', v')`` (the rotor relative to the stator's centre, the stator's displacement) obey
``q' = A q + b + Re(F exp(i p))`` with ``p = w tau + phi0`` the unbalance's phase,
except for the contact force ``F_c(d) = -K f(d)``, ``f = (1 - 1/z)(x - mu_c y, y + mu_c
x)``, the paper's force (``model.force_jacobian``), which acts on the rotor and, with the
opposite sign, on the stator::

    w'' = f_u + g - S w - 2 D w' + F_c,   m_s s'' = -K_s s - 2 N_s s' - F_c,   d'' = w'' - s''

with ``w = d + s`` (``g`` the record's ``g - S c``). So the method is the paper's
(``solvers.analytic``), in eight states:

- **Free flight** (z < 1): ``F_c = 0``, the two bodies are linear and the closed form
  (``analytic.LinearFlow``, an eigen-decomposition with constant and harmonic particular
  solutions) is exact for all time. One propagator serves the whole flight; the flight
  is scanned in steps of ``FREE_STEP_INTERVALS`` scan intervals of 1/32 of its fastest
  period.
- **Slip** (z > 1): each step of ``h = period / steps_per_period`` expands ``F_c`` to
  first order about the step's start, ``F_c(d) = F_c(d0) - K J (d - d0)``, and solves the
  resulting linear system exactly. Global order 2, as on the rigid stator.
- **Stick**: the rolling law of the two bodies (``stator.two_body_entries`` in stick) by
  classical RK4 steps of ``h`` with cubic Hermite dense output, the state projected onto
  the rolling constraint at each step's end, as the rigid stator's ``StickStep``.

Each step's closed form is the dense output of ``extended.ExtendedStepper``'s event
search (the events and their rules are the other methods'), scanned at 1/16 of the step
linearisation's fastest period. With ``analytic_tol`` the contact steps are chosen by step
doubling (``solvers.control``) on the eight states. The propagators are numpy (no compiled
loop); the stick steps' right-hand side is the compiled one unless ``compiled=False``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rubcli import model
from rubcli.solution import Solution
from rubcli.solvers import control, driver
from rubcli.solvers.analytic import (
    CONTACT_SCAN_FRACTION,
    FREE_SCAN_FRACTION,
    RESTART_BAND,
    LinearFlow,
    step_settings,
)
from rubcli.solvers.events import MAX_SCAN_POINTS, scan_spacing
from rubcli.solvers.extended import SPEED, Dense, ExtendedRun, ExtendedStepper
from rubcli.solvers.registry import StepOptions
from rubcli.stator import S_INV_MASS, S_KX, S_KY, S_NX, S_NY

MECHANICAL = np.array([0, 1, 2, 3, 6, 7, 8, 9])  # the eight mechanical entries of a state
PHASE = 4  # the state's entry of the unbalance's phase
FREE_STEP_INTERVALS = 64  # scan intervals per free-flight step (two fastest periods)


def two_body_system(
    s0: np.ndarray, pars: np.ndarray, stator: np.ndarray, regime: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, b, F)`` of the two bodies' eight states in ``regime`` (FREE or a slip),
    the contact force linearised about ``s0`` in slip (module docstring): ``F`` is the
    complex amplitude of the unbalance's forcing, ``e w^2`` on the rotor's rows."""
    m_inv = stator[S_INV_MASS]
    S = np.array([[1.0 + pars[model.P_SXX], pars[model.P_SXY]],
                  [pars[model.P_SYX], 1.0 + pars[model.P_SYY]]])  # fmt: skip
    D = np.array([[pars[model.P_NU] + pars[model.P_DXX], pars[model.P_DXY]],
                  [pars[model.P_DYX], pars[model.P_NU] + pars[model.P_DYY]]])  # fmt: skip
    Ks = np.diag([stator[S_KX], stator[S_KY]])
    Ns = np.diag([stator[S_NX], stator[S_NY]])
    g = np.array([pars[model.P_GX], pars[model.P_GY]])
    # the contact force F_c = Fd d + Fc (zero in free flight)
    Fd, Fc = np.zeros((2, 2)), np.zeros(2)
    if regime != model.FREE:
        mu_c = pars[model.P_MU] * model.friction_sign(regime)
        x0, y0 = float(s0[0]), float(s0[1])
        J = model.force_jacobian(x0, y0, mu_c)
        factor = 1.0 - 1.0 / math.hypot(x0, y0)
        f0 = factor * np.array([x0 - mu_c * y0, y0 + mu_c * x0])
        K = pars[model.P_K]
        Fd, Fc = -K * J, -K * (f0 - J @ np.array([x0, y0]))
    I2 = np.eye(2)
    A = np.zeros((8, 8))
    A[0:2, 2:4] = I2
    A[4:6, 6:8] = I2
    # d'' = w'' - s'', s'' = (-K_s s - 2 N_s s' - F_c) / m_s
    A[2:4, 0:2] = -S + (1.0 + m_inv) * Fd
    A[2:4, 2:4] = -2.0 * D
    A[2:4, 4:6] = -S + m_inv * Ks
    A[2:4, 6:8] = -2.0 * D + 2.0 * m_inv * Ns
    A[6:8, 0:2] = -m_inv * Fd
    A[6:8, 4:6] = -m_inv * Ks
    A[6:8, 6:8] = -2.0 * m_inv * Ns
    b = np.zeros(8)
    b[2:4] = g + (1.0 + m_inv) * Fc
    b[6:8] = -m_inv * Fc
    E = pars[model.P_ECC] * s0[SPEED] ** 2
    F = np.zeros(8, dtype=complex)
    F[2], F[3] = E, -1j * E
    return A, b, F


class TwoBodyFlow(LinearFlow):
    """The closed form of a free flight or a linearised slip step from (tau0, s0): the
    ten states at a time (10,) or at times (10, n), the phase and the speed put back
    beside the eight mechanical states."""

    def __init__(self, tau0: float, s0: np.ndarray, pars: np.ndarray, stator: np.ndarray,
                 regime: int) -> None:  # fmt: skip
        A, b, F = two_body_system(s0, pars, stator, regime)
        self.p0, self.w = float(s0[PHASE]), float(s0[SPEED])
        self._solve(tau0, s0[MECHANICAL], A, b, F, self.w, self.p0 - self.w * tau0)

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        q = self.states(t)
        t = np.asarray(t, dtype=float)
        out = np.empty((10,) + t.shape)
        out[MECHANICAL] = q
        out[PHASE] = self.p0 + self.w * (t - self.tau0)
        out[SPEED] = self.w
        return out


class StickRK4:
    """One classical RK4 step of the two bodies' rolling law from (tau0, s0) over h, with
    cubic Hermite dense output; ``omega_max`` the fastest frequency of the bodies in
    contact without friction at s0 (its scan spacing)."""

    def __init__(self, tau0: float, s0: np.ndarray, h: float,
                 rhs: Callable[[np.ndarray], np.ndarray], pars: np.ndarray,
                 stator: np.ndarray) -> None:  # fmt: skip
        k1 = rhs(s0)
        k2 = rhs(s0 + 0.5 * h * k1)
        k3 = rhs(s0 + 0.5 * h * k2)
        k4 = rhs(s0 + h * k3)
        self.tau0, self.h = tau0, h
        self.s0, self.f0 = np.array(s0, dtype=float), k1
        self.s1 = s0 + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        self.f1 = rhs(self.s1)
        frictionless = np.array(pars, dtype=float)
        frictionless[model.P_MU] = 0.0
        lam = np.linalg.eigvals(two_body_system(s0, frictionless, stator, model.SLIP_POSITIVE)[0])
        self.omega_max = max(float(np.max(np.abs(lam.imag))), float(s0[SPEED]), 1.0)
        self.use_expm = False  # (no eigenbasis: the expm fallbacks count slip steps only)

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        u = (np.asarray(t, dtype=float) - self.tau0) / self.h
        h00 = (1.0 + 2.0 * u) * (1.0 - u) ** 2
        h10 = u * (1.0 - u) ** 2
        h01 = u * u * (3.0 - 2.0 * u)
        h11 = u * u * (u - 1.0)
        if u.ndim:
            h00, h10, h01, h11 = (c[None, :] for c in (h00, h10, h01, h11))
            s0, s1, f0, f1 = (a[:, None] for a in (self.s0, self.s1, self.f0, self.f1))
        else:
            s0, s1, f0, f1 = self.s0, self.s1, self.f0, self.f1
        return h00 * s0 + h01 * s1 + self.h * (h10 * f0 + h11 * f1)


class TwoBodyAnalyticStepper(ExtendedStepper):
    """``analytic`` on the two bodies as a driver stepper (module docstring): one
    ``advance`` is one step (a free-flight scan step, a slip step or a stick step), its
    closed form handed to ``ExtendedStepper.close_step`` (events, samples, switches)."""

    restart_band = RESTART_BAND

    def __init__(self, run: ExtendedRun, steps_per_period: int, analytic_tol: float | None,
                 compiled: bool) -> None:  # fmt: skip
        params = run.params
        self.name, self.analytic_tol = run.method, analytic_tol
        self.h = params.period / steps_per_period
        self.h_max = params.period * control.MAX_STEP_FRACTION
        self.min_step = control.MIN_STEP_FRACTION * params.period
        # the accepted half steps still to be walked (adaptive)
        self.pending: list[tuple[TwoBodyFlow | StickRK4, float]] = []
        self.free: TwoBodyFlow | None = None  # the free flight in progress
        self.t_new = run.tau
        system = run.system
        self.rhs = system.rhs if compiled else system.python_rhs
        self.column_function = system.columns if compiled else system.python_columns
        run.stats.update(
            n_free_segments=0, n_contact_steps=0, n_stick_steps=0, n_rejected_steps=0,
            n_expm_fallbacks=0,
        )  # fmt: skip
        self.settings = step_settings(run, steps_per_period, analytic_tol, compiled)

    def _step(self, run: ExtendedRun, tau: float, state: np.ndarray,
              h: float) -> TwoBodyFlow | StickRK4:  # fmt: skip
        """The propagator of one contact step of length h from (tau, state)."""
        pars, stator = run.ctx
        if run.regime == model.STICK:
            ctx = run.ctx

            def rhs(s: np.ndarray) -> np.ndarray:
                return self.rhs(np.ascontiguousarray(s), *ctx, model.STICK)

            return StickRK4(tau, state, h, rhs, pars, stator)
        return TwoBodyFlow(tau, state, pars, stator, run.regime)

    def _contact(self, run: ExtendedRun) -> tuple[TwoBodyFlow | StickRK4, float]:
        """One contact step: (propagator, its end), fixed or the next accepted adaptive
        half step (step doubling on the eight mechanical states)."""
        tau = run.tau
        if self.analytic_tol is None:
            tb = min(run.t_end, tau + self.h)
            return self._step(run, tau, run.state, tb - tau), tb
        if not self.pending:

            def pair(step: float) -> tuple[float, TwoBodyFlow | StickRK4, TwoBodyFlow | StickRK4]:
                full = self._step(run, tau, run.state, step)
                first = self._step(run, tau, run.state, step / 2)
                mid = first(tau + step / 2)
                if run.regime == model.STICK:
                    mid = run.project(mid)
                second = self._step(run, tau + step / 2, mid, step / 2)
                change = np.abs(full(tau + step) - second(tau + step))[MECHANICAL]
                err = float(np.max(change / (1.0 + np.abs(run.state[MECHANICAL])))) * 4.0 / 3.0
                return err, first, second

            first, second, step, self.h, rejected = control.accepted_pair(
                pair, self.h, self.h_max, run.t_end - tau, self.analytic_tol, self.min_step
            )
            run.stats["n_rejected_steps"] += rejected
            self.pending.extend([(first, tau + step / 2), (second, tau + step)])
        return self.pending.pop(0)

    def advance(self, run: ExtendedRun) -> None:
        regime, ctx, columns = run.regime, run.ctx, self.column_function
        self.columns = lambda S: columns(np.ascontiguousarray(S), *ctx, regime)
        tau = run.tau
        try:
            if regime == model.FREE:
                if self.free is None:
                    self.pending.clear()
                    self.free = TwoBodyFlow(tau, run.state, *ctx, model.FREE)
                    run.stats["n_free_segments"] += 1
                prop = self.free
                spacing = scan_spacing(prop.omega_max, FREE_SCAN_FRACTION)
                tb = min(run.t_end, tau + FREE_STEP_INTERVALS * spacing)
            else:
                prop, tb = self._contact(run)
                spacing = scan_spacing(prop.omega_max, CONTACT_SCAN_FRACTION)
                key = "n_stick_steps" if regime == model.STICK else "n_contact_steps"
                run.stats[key] += 1
                run.stats["n_expm_fallbacks"] += int(prop.use_expm)
        except np.linalg.LinAlgError as exc:
            run.fail(f"linearised contact system singular at tau = {tau:.6g}: {exc}")
            return
        intervals = max(1, math.ceil((tb - tau) / spacing - 1e-9))
        if intervals > MAX_SCAN_POINTS:
            run.fail(
                f"the linearised step at tau = {tau:.6g} has a frequency of "
                f"{prop.omega_max:.3g} per tau, which a step of {tb - tau:.3g} cannot resolve "
                "(the linearisation has diverged; try a smaller step)"
            )
            return
        self.intervals = intervals
        self.t_new = tb
        run.stats["nsteps"] += 1
        try:
            self.close_step(run, prop, tau, tb, float(run.state[SPEED]))
        except ValueError:  # brentq met a NaN: the closed form overflowed
            run.fail(
                f"the event search in the linearised step at tau = {tau:.6g} met a non-finite "
                "state (the linearisation has diverged; try a smaller step)"
            )

    def finish(self, run: ExtendedRun, dense: Dense, event: tuple[float, int] | None) -> None:
        if event is None:
            state = dense(self.t_new)
            run.tau = self.t_new
            run.state = run.project(state) if run.regime == model.STICK else state
            return
        self.pending.clear()
        self.free = None
        run.switch(event[0], event[1], dense(event[0]))

    def _end_segment(self, run: ExtendedRun) -> None:
        self.free = None


def solve_two_body_analytic(run: ExtendedRun, options: StepOptions) -> Solution:
    """``analytic`` on a two-body run (module docstring)."""
    stepper = TwoBodyAnalyticStepper(run, options.steps_per_period, options.analytic_tol,
                                     options.compiled)  # fmt: skip
    return driver.integrate(run, stepper)

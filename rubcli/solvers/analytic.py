"""The paper's piecewise analytical method (model notes, section 3), with its corrections.

- **Free flight** (z < 1): the closed form of eq. (7-8) (``model.free_flight``), exact for
  all time. No steps are taken inside it; the contact entry is sought on the closed form
  by a vectorised scan (1/32 of the fastest period, ``events.earliest_event``) followed
  by Brent's method, so an entry is located to ~1e-14 in tau and a brief touch inside a
  scan interval is found through the extremum of ``z``.
- **Contact** (z > 1): every step of length ``h = period / steps_per_period`` expands the
  contact force to first order about the current point (eq. 9-14, with the stiffness
  matrix of correction 2) and solves the resulting linear 4x4 system exactly: constant
  and harmonic particular solutions plus the homogeneous part from the full
  eigen-decomposition of the system matrix (correction 5: no assumption that modes decay
  at rate nu; complex or growing modes are kept). The expansion point moves every step.
  Contact exit and slip reversal are located on the step's closed form by the same
  scan-and-Brent procedure, so a step that leaves and re-enters is not missed.
- **Friction direction** follows ``sign(v_r)``; a reversal ends the step and the next
  step uses the new sign.

Order: the linearisation error in the force is O(delta^2) with delta ~ h, so the local
error is O(h^4) in position and O(h^3) in velocity, and the global error is O(h^2).
The error grows with K (the curvature of the force scales with K): on stiff stators the
step must shrink like 1/sqrt(K) for a fixed accuracy (docs/solvers.md).

Stick (rolling, notes section 4) has no closed form in the paper: when v_r reaches 0
and the needed friction is within mu F_N, the rolling law is integrated by RK4 steps
(``StickStep``) until it leaves the friction cone or contact ends.

Compiled (``compiled=True``, the default). Fixed steps run in the one compiled event
loop (``kernels.advance_piecewise``, compiled/piecewise_loop.py): free flight, slip and stick
steps, the event search (``events.event_search``) and the switches, with the same propagators
(compiled/propagators.py, compiled/piecewise.py) and the same scan grids as the Python
code below; it hands back to the Python step only what it cannot do (an ill-conditioned
eigenbasis: LAPACK or the ``expm`` fallback; a diverged linearisation: the failure
message). Adaptive steps (``analytic_tol``): runs of slip steps in which no event can
occur are taken by ``kernels.advance_contact_adaptive`` (the step doubling and control
below, pair of half steps by pair, in the same loop); events, stick steps and free
flights run in Python.
The paths agree to round-off (tests/test_kernels.py, tests/test_piecewise_loop.py).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers import compiled as kernels
from rubcli.solvers import control, driver
from rubcli.solvers.compiled import piecewise
from rubcli.solvers.events import (
    MAX_SCAN_POINTS,
    NO_EVENT,
    earliest_event,
    scan_spacing,
    start_flags,
)
from rubcli.solvers.registry import StepOptions, register
from rubcli.solvers.shared import EVENT_BUFFER

if TYPE_CHECKING:
    from rubcli.model import FloatOrArray


def _expm(M: np.ndarray) -> np.ndarray:
    """scipy.linalg.expm, imported on first use (the eigenvector fallback only)."""
    import scipy.linalg

    return scipy.linalg.expm(M)


FREE_SCAN_FRACTION = 1.0 / 32.0  # scan spacing in free flight, fraction of fastest period
CONTACT_SCAN_FRACTION = 1.0 / 16.0  # scan spacing inside a contact step
FREE_SCAN_CHUNK = 512  # scan intervals evaluated at once in free flight, at most
# the first chunk of a free flight, doubled chunk by chunk up to FREE_SCAN_CHUNK: most free
# flights between impacts end within a period, and each chunk is evaluated whole
FREE_FIRST_CHUNK = 16
EIGVEC_COND_LIMIT = 1e10  # above this the eigenbasis is not trusted: use expm
KERNEL_CHUNK_STEPS = 4096  # compiled steps per call between wall-time and progress checks
# the compiled loops' first scan buffers: a free flight's largest chunk and its end
# points; a step with a finer grid has the loop return for larger ones
KERNEL_SCAN_POINTS = FREE_SCAN_CHUNK + 2
RESTART_BAND = 1e-12  # the event search's restart band (earliest_event's default)


class FreeFlight:
    """The closed-form free flight from (tau0, s0): eq. (7-8)."""

    def __init__(self, tau0: float, s0: np.ndarray, params: model.ModelParams):
        self.tau0, self.s0, self.params = tau0, np.asarray(s0, dtype=float), params
        beta = math.sqrt(abs(1.0 - params.nu**2))
        self.omega_max = max(params.eta, beta, 1.0)

    def states(self, t: FloatOrArray) -> np.ndarray:
        return model.free_flight(t, self.tau0, self.s0, self.params)

    def derivatives(self, t: FloatOrArray, S: np.ndarray) -> np.ndarray:
        p = self.params
        phase = p.eta * np.asarray(t) + p.phi0
        ax = p.E * np.cos(phase) - 2.0 * p.nu * S[2] - S[0]
        ay = p.E * np.sin(phase) - 2.0 * p.nu * S[3] - S[1]
        return np.array([S[2], S[3], ax, ay])


class LinearFlow:
    """Exact solution of a linear system with constant coefficients, constant and
    harmonic forcing, from (tau0, s0)::

        s' = A s + b + Re(F exp(i (eta t + phi0)))

    ``s(t) = s_c + Re(S_hat exp(i(eta t + phi0))) + exp(A (t - tau0)) d0`` where
    ``A s_c + b = 0``, ``(i eta - A) S_hat = F`` and ``d0`` matches s0. The homogeneous
    part comes from the full eigen-decomposition of A (correction 5: complex or growing
    modes are kept), or from ``expm`` where the eigenbasis is ill-conditioned. Any state
    size: the rotor's four (``LinearisedContact``) or the two bodies' eight
    (``solvers.two_body_analytic``)."""

    def _solve(self, tau0: float, s0: np.ndarray, A: np.ndarray, b: np.ndarray,
               forcing: np.ndarray, eta: float, phi0: float) -> None:  # fmt: skip
        self.tau0, self.eta, self.phi0 = tau0, eta, phi0
        self.A, self.b = A, b
        self.s_c = np.linalg.solve(A, -b)
        self.S_hat = np.linalg.solve(1j * eta * np.eye(A.shape[0]) - A, forcing)
        self.d0 = np.asarray(s0, dtype=float) - self.s_c - self._harmonic(tau0)
        lam, V = np.linalg.eig(A)
        self.lam = lam
        self.use_expm = np.linalg.cond(V) > EIGVEC_COND_LIMIT
        if not self.use_expm:
            self.V = V
            self.c = np.linalg.solve(V, self.d0.astype(complex))
        self.omega_max = max(float(np.max(np.abs(lam.imag))), eta, 1.0)

    def _harmonic(self, t):
        phase = self.eta * np.asarray(t, dtype=float) + self.phi0
        if np.ndim(phase) == 0:
            return np.real(self.S_hat * np.exp(1j * phase))
        return np.real(self.S_hat[:, None] * np.exp(1j * phase)[None, :])

    def states(self, t: FloatOrArray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        dt = t - self.tau0
        if self.use_expm:
            if dt.ndim == 0:
                hom = _expm(self.A * float(dt)) @ self.d0
            else:
                hom = np.array([_expm(self.A * d) @ self.d0 for d in dt]).T
        elif dt.ndim == 0:
            hom = np.real(self.V @ (self.c * np.exp(self.lam * float(dt))))
        else:
            hom = np.real(self.V @ (self.c[:, None] * np.exp(np.outer(self.lam, dt))))
        s_c = self.s_c if dt.ndim == 0 else self.s_c[:, None]
        return s_c + self._harmonic(t) + hom


class LinearisedContact(LinearFlow):
    """Exact solution of the contact equation linearised about (tau0, s0) (eq. 13-18
    corrected): ``LinearFlow`` with the unbalance's forcing ``F = (0, 0, E, -i E)``."""

    def __init__(self, tau0: float, s0: np.ndarray, params: model.ModelParams, mu_c: float):
        self._start(tau0, s0, params, *model.linearised_contact_system(s0, params, mu_c))

    def _start(
        self, tau0: float, s0: np.ndarray, params: model.ModelParams, A: np.ndarray, b: np.ndarray
    ) -> None:
        self.params = params
        forcing = np.array([0.0, 0.0, params.E, -1j * params.E])
        self._solve(tau0, s0, A, b, forcing, params.eta, params.phi0)

    def derivatives(self, t: FloatOrArray, S: np.ndarray) -> np.ndarray:
        p = self.params
        phase = p.eta * np.asarray(t, dtype=float) + p.phi0
        out = self.A @ S + (self.b if S.ndim == 1 else self.b[:, None])
        out[2] = out[2] + p.E * np.cos(phase)
        out[3] = out[3] + p.E * np.sin(phase)
        return out


class LinearFreeFlight(LinearisedContact):
    """The free flight of the general machine (``model.free_flight_system``): linear with
    constant coefficients, harmonic and constant forcing, so the same closed form is
    exact. On the paper's machine ``FreeFlight`` (eq. 7-8) is used."""

    def __init__(self, tau0: float, s0: np.ndarray, params: model.ModelParams):
        self._start(tau0, s0, params, *model.free_flight_system(params))


def _phi12(z: np.ndarray):
    """phi1(z) = (e^z - 1)/z and phi2(z) = (e^z - 1 - z)/z^2, with series near z = 0."""
    small = np.abs(z) < 1e-3
    zs = np.where(small, 1.0, z)
    ez = np.exp(z)
    phi1 = np.where(small, 1 + z / 2 + z * z / 6 + z**3 / 24, (ez - 1) / zs)
    phi2 = np.where(small, 0.5 + z / 6 + z * z / 24 + z**3 / 120, (ez - 1 - z) / (zs * zs))
    return phi1, phi2


class PolarLinearisedContact:
    """Local linearisation of the polar contact equations about (tau0, s0), solved exactly.

    With p = (r, theta, r', theta') the contact law is linear in r - 1 (model notes 1), so
    the stiff term K (r - 1) is integrated exactly whatever K is; what is linearised
    (r theta'^2, the forcing's dependence on theta, mu_c K (r - 1)/r, and the explicit
    time dependence) does not scale with the stiffness in the radial equation. The
    affine system p' = f0 + J (p - p0) + f_tau (t - tau0) has the solution
    ``p - p0 = t phi1(J t) f0 + t^2 phi2(J t) f_tau``, evaluated through the
    eigen-decomposition of J (J may be singular: theta is cyclic without unbalance),
    or through the exponential of the augmented 6x6 matrix when the eigenbasis is
    ill-conditioned. Global order 2, like the Cartesian linearisation.
    """

    def __init__(self, tau0: float, s0: np.ndarray, params: model.ModelParams, mu_c: float):
        self.tau0, self.params, self.mu_c = tau0, params, mu_c
        self.p0 = model.to_polar(np.asarray(s0, dtype=float))
        self.f0 = model.polar_rhs(tau0, self.p0, params, mu_c)
        self.J, self.f_tau = model.polar_jacobian(tau0, self.p0, params, mu_c)
        lam, V = np.linalg.eig(self.J)
        self.lam = lam
        self.use_expm = np.linalg.cond(V) > EIGVEC_COND_LIMIT
        if not self.use_expm:
            self.V = V
            self.c0 = np.linalg.solve(V, self.f0.astype(complex))
            self.c1 = np.linalg.solve(V, self.f_tau.astype(complex))
        self.omega_max = max(float(np.max(np.abs(lam.imag))), params.eta, 1.0)

    def polar_states(self, t: FloatOrArray) -> np.ndarray:
        dt = np.atleast_1d(np.asarray(t, dtype=float) - self.tau0)
        if self.use_expm:
            M = np.zeros((6, 6))
            M[:4, :4], M[:4, 4], M[:4, 5], M[4, 5] = self.J, self.f_tau, self.f0, 1.0
            e5 = np.zeros(6)
            e5[5] = 1.0
            y = np.array([(_expm(M * d) @ e5)[:4] for d in dt]).T
        else:
            z = np.outer(self.lam, dt)
            phi1, phi2 = _phi12(z)
            y = np.real(self.V @ (dt * phi1 * self.c0[:, None] + dt * dt * phi2 * self.c1[:, None]))
        out = self.p0[:, None] + y
        return out[:, 0] if np.ndim(t) == 0 else out

    def states(self, t: FloatOrArray) -> np.ndarray:
        return model.from_polar(self.polar_states(t))

    def derivatives(self, t: FloatOrArray, S: np.ndarray) -> np.ndarray:
        """Time derivative of the linearised solution, in Cartesian form."""
        t = np.asarray(t, dtype=float)
        P = self.polar_states(t)
        if P.ndim == 1:
            P, t = P[:, None], np.atleast_1d(t)
        dP = (
            self.f0[:, None]
            + self.J @ (P - self.p0[:, None])
            + self.f_tau[:, None] * (t - self.tau0)
        )
        r, theta, u, omega = P
        u_dot, omega_dot = dP[2], dP[3]
        c, sn = np.cos(theta), np.sin(theta)
        ax = u_dot * c - 2 * u * omega * sn - r * omega_dot * sn - r * omega * omega * c
        ay = u_dot * sn + 2 * u * omega * c + r * omega_dot * c - r * omega * omega * sn
        out = np.array([u * c - r * omega * sn, u * sn + r * omega * c, ax, ay])
        return out[:, 0] if np.ndim(S) == 1 else out


class StickStep:
    """One classical RK4 step of the rolling law with cubic Hermite dense output.

    The paper has no stick regime; rolling phases (notes section 4) are integrated
    with RK4 on ``model.rhs(..., STICK)`` at the method's step (local error O(h^5)).
    The arithmetic is ``compiled/piecewise.py``'s (``stick_prepare``, ``stick_at``:
    plain functions registered with numba), run here as Python, so the compiled loop
    takes the same steps bitwise.
    """

    def __init__(self, tau0: float, s0: np.ndarray, h: float, params: model.ModelParams):
        self.tau0, self.h, self.params = tau0, h, params
        self.pars = model.params_vector(params)
        self.st, self.meta = np.empty((4, 4)), np.empty(2)
        piecewise.stick_prepare(
            float(tau0), np.asarray(s0, dtype=float), float(h), self.pars, self.st, self.meta
        )
        self.s0, self.s1, self.f0, self.f1 = self.st
        self.omega_max = piecewise.stick_omega_max(self.pars)

    def states(self, t: FloatOrArray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if t.ndim == 0:
            out = np.empty(4)
            piecewise.stick_at(float(t), self.st, self.meta, out)
            return out
        out = np.empty((4, t.size))
        row = np.empty(4)
        for i, ti in enumerate(t.tolist()):
            piecewise.stick_at(ti, self.st, self.meta, row)
            out[:, i] = row
        return out

    def derivatives(self, t: FloatOrArray, S: np.ndarray) -> np.ndarray:
        t = np.broadcast_to(np.asarray(t, dtype=float), (S.shape[1],))
        return np.array(
            [model.rhs(t[j], S[:, j], self.params, model.STICK) for j in range(S.shape[1])]
        ).T


class _UnresolvedError(Exception):
    """A step whose event scan would need more than MAX_SCAN_POINTS points."""


CONTACT_PROPAGATORS = {"cartesian": LinearisedContact, "polar": PolarLinearisedContact}
# Adaptive steps (step doubling): local error ~ h^3, so h scales with (tol/err)^(1/3).


def _contact_step(linearisation: str, tau: float, state, h: float, params, regime: int):
    """The propagator of one contact step of length h (raises LinAlgError if singular)."""
    if regime == model.STICK:
        return StickStep(tau, state, h, params)
    mu_c = params.mu * model.friction_sign(regime)
    return CONTACT_PROPAGATORS[linearisation](tau, state, params, mu_c)


def _doubling_error(linearisation, tau, state, h, params, regime):
    """Step-doubling estimate: (error, first half-step propagator, second half-step's).

    One step of h is compared with two of h/2; the difference (max norm of the state,
    relative to 1 + |state|) estimates the local error of the half steps (x 4/3).
    """
    full = _contact_step(linearisation, tau, state, h, params, regime)
    first = _contact_step(linearisation, tau, state, h / 2, params, regime)
    mid = first.states(tau + h / 2)
    if regime == model.STICK:
        mid = model.project_to_rolling(mid, params)
    second = _contact_step(linearisation, tau + h / 2, mid, h / 2, params, regime)
    error = control.doubling_error(full.states(tau + h), second.states(tau + h), state)
    return error, first, second


def step_settings(run: driver.Run, steps_per_period: int, analytic_tol: float | None,
                  compiled: bool) -> dict:  # fmt: skip
    """The settings an analytic stepper reports (``Solution.settings``)."""
    return {
        "steps_per_period": steps_per_period,
        "analytic_tol": analytic_tol,
        "max_steps": run.max_steps,
        "max_wall_time_s": run.max_wall_time_s,
        "compiled": compiled,
    }


class PiecewiseStepper:
    """The piecewise method as a driver stepper (``driver.integrate``).

    One ``advance`` is, at fixed steps, a call of the compiled loop
    (``kernels.advance_piecewise``: every regime and its events); else, or for a step
    the loop leaves to Python, one step of the method: a whole free flight up to its
    next event (scanned chunk by chunk on the closed form), a compiled run of
    event-free adaptive slip steps (``kernels.advance_contact_adaptive``), or one
    contact step in Python (fixed, or the next accepted half step of the adaptive
    control) with its events. ``linearisation`` is 'cartesian' (``analytic``) or 'polar'
    (``analytic-polar``).
    """

    def __init__(
        self,
        run: driver.Run,
        linearisation: str,
        steps_per_period: int,
        analytic_tol: float | None,
        compiled: bool,
    ):
        params = run.params
        self.linearisation, self.analytic_tol = linearisation, analytic_tol
        self.h = params.period / steps_per_period
        self.h_max = params.period * control.MAX_STEP_FRACTION
        self.min_step = control.MIN_STEP_FRACTION * params.period
        self.pending = []  # accepted half-step propagators still to be walked (adaptive)
        run.stats.update(
            n_free_segments=0, n_contact_steps=0, n_stick_steps=0, n_rejected_steps=0,
            n_expm_fallbacks=0, n_compiled_steps=0,
        )  # fmt: skip
        self.use_kernel = compiled and kernels.ensure_fresh()
        if self.use_kernel:
            self.pars = np.array(model.params_vector(params))
            self.t_eval_c = np.ascontiguousarray(run.t_eval, dtype=float)
            self.control = (
                float(analytic_tol) if analytic_tol is not None else 0.0,
                control.SAFETY, control.MIN_FACTOR, control.MAX_FACTOR, self.h_max, self.min_step,
            )  # fmt: skip
        # fixed steps: the compiled loop takes every regime, its events included;
        # adaptive steps: the kernel takes the event-free slip steps
        self.use_loop = self.use_kernel and analytic_tol is None
        self.adaptive_kernel = self.use_kernel and analytic_tol is not None
        self.python_next = False  # the loop handed the next step to Python
        self.scan_size = KERNEL_SCAN_POINTS  # the compiled loops' scan buffers (points)
        self._allocate()
        if self.use_loop:
            self.free = np.empty(6)  # the free flight in progress (advance_piecewise's ff)
            self.free_active = False
            self.events = (
                np.empty(EVENT_BUFFER), np.empty(EVENT_BUFFER, dtype=np.int64),
                np.empty((EVENT_BUFFER, 4)), np.empty((EVENT_BUFFER, 2), dtype=np.int64),
            )  # fmt: skip
        self.settings = step_settings(run, steps_per_period, analytic_tol, self.use_kernel)

    def _fill(self, run: driver.Run, prop, t_stop: float) -> None:
        """The samples of the propagator's span up to ``t_stop``."""
        j = int(np.searchsorted(run.t_eval, t_stop, side="right"))
        if j > run.k:
            samples = prop.states(run.t_eval[run.k : j])
            if run.regime == model.STICK:
                samples = model.project_to_rolling(samples, run.params)
            run.states[run.k : j] = samples.T
            run.regimes[run.k : j] = run.regime
            run.k = j

    def _search(self, run: driver.Run, prop, ta: float, tb: float, fraction: float):
        """The earliest event of the propagator in (ta, tb] on its scan grid."""
        spacing = scan_spacing(prop.omega_max, fraction)
        if (tb - ta) / spacing > MAX_SCAN_POINTS:
            raise _UnresolvedError(
                f"the linearised step at tau = {ta:.6g} has a frequency of "
                f"{prop.omega_max:.3g} per tau, which a step of {tb - ta:.3g} cannot resolve "
                f"(the linearisation has diverged; try a smaller step)"
            )
        grid = np.linspace(ta, tb, max(1, math.ceil((tb - ta) / spacing)) + 1)
        try:
            return earliest_event(
                prop.states, prop.derivatives, grid, run.regime, run.params, run.last_kind
            )
        except ValueError:  # brentq met a NaN: the closed form overflowed
            # (a NaN only past the step's first event is harmless and never reached)
            raise _UnresolvedError(
                f"the event search in the linearised step at tau = {ta:.6g} met a non-finite "
                "state (the linearisation has diverged; try a smaller step)"
            ) from None

    def _free_flight(self, run: driver.Run):
        """No steps in free flight: scan the closed form chunk by chunk for the entry."""
        self.pending.clear()
        flight = FreeFlight if run.params.is_paper_machine else LinearFreeFlight
        prop = flight(run.tau, run.state, run.params)
        run.stats["n_free_segments"] += 1
        spacing = scan_spacing(prop.omega_max, FREE_SCAN_FRACTION)
        intervals = float(FREE_FIRST_CHUNK)
        event, tb = None, run.tau
        while tb < run.t_end and event is None:
            ta, tb = tb, min(run.t_end, tb + intervals * spacing)
            intervals = min(2.0 * intervals, FREE_SCAN_CHUNK)
            event = self._search(run, prop, ta, tb, FREE_SCAN_FRACTION)
            run.last_kind = NO_EVENT
            self._fill(run, prop, event[0] if event else tb)
            if run.elapsed() > run.max_wall_time_s:
                break
        return prop, tb, event

    def _compiled_slip_steps(self, run: driver.Run) -> bool:
        """Event-free adaptive slip steps in the kernel (``advance_contact_adaptive``);
        True if it took this advance's steps (False: a possible event or a step it
        leaves to Python is next)."""
        pairs = min(KERNEL_CHUNK_STEPS, run.steps_left) // 2
        if pairs == 0:  # the budget has no room for a pair: Python's half step
            return False
        state = np.array(run.state, dtype=float)
        # h comes back as the controller's next step (unchanged if no pair was taken);
        # the rejections of the pairs it took
        tau, k, taken, rejected, self.h, reason, need = kernels.advance_contact_adaptive(
            self.linearisation == "polar", run.tau, state, self.h, run.t_end, run.regime,
            self.pars, self.t_eval_c, run.states, run.regimes, run.k, pairs,
            CONTACT_SCAN_FRACTION, EIGVEC_COND_LIMIT, start_flags(run.last_kind),
            self.control, self.work,
        )  # fmt: skip
        run.stats["n_rejected_steps"] += rejected
        run.tau, run.state, run.k = tau, state, k
        if taken:
            run.last_kind = NO_EVENT
        run.stats["nsteps"] += taken
        run.stats["n_contact_steps"] += taken
        run.stats["n_compiled_steps"] += taken
        if reason == kernels.STOP_GROW:  # the next advance calls it with larger buffers
            self._grow(need)
        # at a possible event (or a step the kernel leaves to Python) the Python step is
        # taken from where the kernel stopped
        return reason not in (kernels.STOP_EVENT, kernels.STOP_PYTHON)

    def _grow(self, need: int) -> None:
        """Scan buffers of at least ``need`` points for the compiled loops' next call."""
        self.scan_size = max(need, 2 * self.scan_size)
        self._allocate()

    def _allocate(self) -> None:
        """The work arrays of the compiled loop this run calls, allocated once a run
        (again for larger scan buffers)."""
        if self.use_loop:
            self.work = kernels.piecewise_work(self.scan_size)
        elif self.adaptive_kernel:
            self.work = kernels.adaptive_work(self.scan_size)

    def _contact_step(self, run: driver.Run):
        """One contact step in Python (fixed, or the next accepted adaptive half step)."""
        params, tau = run.params, run.tau
        if self.analytic_tol is None:
            tb = min(run.t_end, tau + self.h)
            prop = _contact_step(self.linearisation, tau, run.state, tb - tau, params, run.regime)
        else:
            if not self.pending:

                def pair(step: float) -> tuple[float, object, object]:
                    return _doubling_error(self.linearisation, tau, run.state, step, params,
                                           run.regime)  # fmt: skip

                first, second, step, self.h, rejected = control.accepted_pair(
                    pair, self.h, self.h_max, run.t_end - tau, self.analytic_tol, self.min_step
                )
                run.stats["n_rejected_steps"] += rejected
                self.pending.extend([(first, tau + step / 2), (second, tau + step)])
            prop, tb = self.pending.pop(0)
        if run.regime == model.STICK:
            run.stats["n_stick_steps"] += 1
        else:
            run.stats["n_contact_steps"] += 1
            run.stats["n_expm_fallbacks"] += int(prop.use_expm)
        event = self._search(run, prop, tau, tb, CONTACT_SCAN_FRACTION)
        run.last_kind = NO_EVENT
        self._fill(run, prop, event[0] if event else tb)
        return prop, tb, event

    def _compiled_loop(self, run: driver.Run) -> None:
        """Up to ``KERNEL_CHUNK_STEPS`` steps (and free-flight scan chunks) in the
        compiled loop, ``kernels.advance_piecewise``, with the events it applies."""
        counts = np.zeros(kernels.N_COUNTS, dtype=np.int64)
        state = np.array(run.state, dtype=float)
        fractions = (
            FREE_SCAN_FRACTION, CONTACT_SCAN_FRACTION, float(FREE_FIRST_CHUNK),
            float(FREE_SCAN_CHUNK),
        )  # fmt: skip
        tau, k, regime, n_ev, at_event, reason, need = kernels.advance_piecewise(
            self.linearisation == "polar", run.tau, state, self.h, run.t_end, run.regime,
            start_flags(run.last_kind), self.pars, self.t_eval_c, run.states, run.regimes,
            run.k, min(KERNEL_CHUNK_STEPS, run.steps_left), fractions, EIGVEC_COND_LIMIT,
            RESTART_BAND, self.free, self.free_active, self.work, *self.events, counts,
        )  # fmt: skip
        stats = run.stats
        for key, i in kernels.PIECEWISE_COUNTS.items():
            stats[key] += int(counts[i])
        run.tau, run.state, run.regime, run.k = tau, state, regime, k
        # a free flight the loop began goes on in the next call (not one left to Python,
        # nor one whose event filled the buffers: the loop has not begun it)
        python = reason in (kernels.STOP_PYTHON, kernels.STOP_EVENT)
        self.free_active = regime == model.FREE and not python and reason != kernels.STOP_FULL
        if not driver.record_kernel_events(run, n_ev, *self.events):
            return
        if not at_event:  # a step was taken since the last event
            run.last_kind = NO_EVENT
        if reason == kernels.STOP_GROW:
            self._grow(need)
        # a step the loop leaves to Python (conditioning, scan size, a non-finite
        # state): the Python step below is taken next, from where the loop stopped
        self.python_next = python

    def advance(self, run: driver.Run) -> None:
        if self.use_loop:
            if not self.python_next:
                self._compiled_loop(run)
                return
            self.python_next = self.free_active = False
        try:
            if run.regime == model.FREE:
                prop, tb, event = self._free_flight(run)
            else:
                slip = run.regime in (model.SLIP_POSITIVE, model.SLIP_NEGATIVE)
                # the adaptive kernel's slip steps, between pairs of half steps (`pending`
                # empty); a fixed step is here only where the compiled loop left it
                kernel = self.adaptive_kernel and slip and not self.pending
                if kernel and self._compiled_slip_steps(run):
                    return  # the kernel advanced tau, the state, the samples, the counts
                try:
                    prop, tb, event = self._contact_step(run)
                except np.linalg.LinAlgError as exc:
                    run.fail(f"linearised contact system singular at tau = {run.tau:.6g}: {exc}")
                    return
        except _UnresolvedError as exc:
            run.fail(str(exc))
            return
        run.stats["nsteps"] += 1
        if event is None:
            run.tau = tb
            run.state = prop.states(tb)
        else:
            self.pending.clear()
            run.switch(event[0], event[1], prop.states(event[0]))


def solve_piecewise(
    problem: Problem, method: str, linearisation: str, options: StepOptions
) -> Solution:
    """The piecewise method with a given contact linearisation ('cartesian' or 'polar').

    Fixed steps of ``period / steps_per_period`` in contact, or, with ``analytic_tol``,
    adaptive steps chosen by step doubling so that the estimated local error per step
    stays below the tolerance (``steps_per_period`` then sets the first step).
    With ``compiled`` fixed steps run in the compiled loop
    (``kernels.advance_piecewise``), and the event-free adaptive slip steps in
    ``kernels.advance_contact_adaptive`` (the same step doubling and control as
    ``PiecewiseStepper``); ``compiled=False`` is the pure-Python path.
    """
    o = options
    run = driver.Run(
        problem, method, max_steps=o.max_steps, max_wall_time_s=o.max_wall_time_s,
        progress=o.progress,
    )  # fmt: skip
    stepper = PiecewiseStepper(run, linearisation, o.steps_per_period, o.analytic_tol, o.compiled)
    return driver.integrate(run, stepper)


@register("analytic")
def solve_analytic(problem: Problem, options: StepOptions) -> Solution:
    """The paper's method: Cartesian Taylor linearisation of the contact force (eq. 9-14)."""
    return solve_piecewise(problem, "analytic", "cartesian", options)


@register("analytic-polar")
def solve_analytic_polar(problem: Problem, options: StepOptions) -> Solution:
    """The paper's idea with the contact phase linearised in polar coordinates."""
    return solve_piecewise(problem, "analytic-polar", "polar", options)

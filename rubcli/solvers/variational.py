"""The flows ``analysis.orbits.periodic`` integrates for its stroboscopic map, monodromy matrix
and shooting (docs/orbits.md): the rotor at a constant speed, and the two bodies of a
stator with its own mass, in the event loop of ``solvers.extended``, with or without
their variational equations.

The state is the rotor's four entries and the unbalance's phase and constant speed,
``(x, y, vx, vy, p, w)``; in the variational mode the matrix ``Phi = d (x, y, vx, vy) /
d start`` follows (``compiled.variational``: ``Phi' = J Phi`` with J the Jacobian of the
regime's right-hand side; in stick the Jacobian of the rolling flow, which ignores the
slip component of the state). ``dop853-jit`` integrates it in the extended systems'
compiled loop, with their event search and their rules at an event
(``ExtendedRun.switch``). At each event ``Phi`` is multiplied by the saltation matrix

    S = I + (f+ - f-) grad(h)^T / (grad(h)^T f- + dh/dtau)

(``saltation_matrix``), and where stick ends first by the Jacobian of the projection
onto the rolling constraint (the state is projected there, as the solvers do). At
contact entry and exit ``f+ = f-`` (the contact force vanishes at ``z = 1``), so ``S =
I``; at a slip reversal and at stick entry the friction force jumps and ``S`` is not the
identity. A grazing crossing has no saltation matrix (``GrazingSwitchError``: the run
fails with it).

The two bodies' state is their ten entries ``(x, y, vx, vy, p, w, u, v, u', v')``
(``solvers.two_body``), and in the variational mode the matrix of the section's eight
(all but the phase and the speed) after them (``compiled.two_body``; J by central
differences of the right-hand side). At each event ``Phi`` is multiplied by their
saltation matrix (``two_body_saltation``, in the ten states, where the system is
autonomous: the phase's row of the jump is 0) and, where stick begins or ends, by the
Jacobian of the two bodies' projection onto the rolling constraint.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers import compiled as kernels
from rubcli.solvers import driver
from rubcli.solvers import events as ev
from rubcli.solvers.compiled.two_body import (
    N_SECTION,
    SECTION,
    advance_two_body_variational,
    two_body_columns,
    two_body_rhs,
    two_body_variational_initial_step,
    two_body_variational_rhs,
)
from rubcli.solvers.compiled.variational import (
    N_ROTOR,
    N_VARIATIONAL,
    advance_rotor,
    advance_variational,
    rotor_columns,
    rotor_initial_step,
    rotor_rhs,
    variational_initial_step,
    variational_rhs,
)
from rubcli.solvers.extended import ExtendedJitStepper, ExtendedRun, System
from rubcli.solvers.two_body import TwoBodyRun
from rubcli.stator import N_STATES, S_INV_MASS, two_body_projection

# A flow's step budget (its wall time is the caller's).
FLOW_MAX_STEPS = 10_000_000
GRADIENT_STEP = 1e-7  # the two bodies' event gradients and projection: central differences


class GrazingSwitchError(ArithmeticError):
    """An event whose surface the flow crosses tangentially: no saltation matrix."""


# ----------------------------------------------------------------- the switches' jumps


def _slip_gradient(s: np.ndarray) -> np.ndarray:
    """grad of v_r = Rp eta + (x vy - y vx) / z in (x, y, vx, vy)."""
    x, y, vx, vy = s
    z = math.hypot(x, y)
    w = x * vy - y * vx
    return np.array([vy / z - w * x / z**3, -vx / z - w * y / z**3, -y / z, x / z])


def _numerical_gradient(
    fun: Callable[[float, np.ndarray], float], tau: float, s: np.ndarray
) -> tuple[np.ndarray, float]:
    """Central differences of a scalar fun(tau, s): (grad in s, d/dtau)."""
    grad = np.zeros(4)
    for j in range(4):
        h = 1e-7 * max(1.0, abs(s[j]))
        sp, sm = s.copy(), s.copy()
        sp[j] += h
        sm[j] -= h
        grad[j] = (fun(tau, sp) - fun(tau, sm)) / (2.0 * h)
    h = 1e-7 * max(1.0, abs(tau))
    return grad, (fun(tau + h, s) - fun(tau - h, s)) / (2.0 * h)


def surface_gradient(
    kind: int, tau: float, s: np.ndarray, params: ModelParams, regime: int
) -> tuple[np.ndarray, float]:
    """(grad h, dh/dtau) of the surface an event of ``kind`` (an ``events`` code) crosses."""
    if kind in (ev.ENTRY, ev.EXIT):
        return np.array([2.0 * s[0], 2.0 * s[1], 0.0, 0.0]), 0.0
    if kind in (ev.REVERSAL, ev.STICK_ENTRY):
        return _slip_gradient(s), 0.0
    # stick exit: h = sign T - L, the sign the needed friction leaves the cone on
    needed = float(model.stick_friction(tau, s[0], s[1], s[2], s[3], params))
    sign = 1.0 if needed > 0.0 else -1.0
    pars = model.params_vector(params)

    def margin(t: float, q: np.ndarray) -> float:
        return float(ev.stick_margin(t, q[0], q[1], q[2], q[3], pars, sign))

    return _numerical_gradient(margin, tau, s)


def saltation_matrix(
    tau: float,
    s: np.ndarray,
    params: ModelParams,
    regime_before: int,
    regime_after: int,
    grad: np.ndarray,
    dh_dtau: float = 0.0,
) -> np.ndarray:
    """S = I + (f+ - f-) grad(h)^T / (grad(h)^T f- + dh/dtau) at a transversal crossing.

    Raises GrazingSwitchError at a grazing crossing (the denominator vanishes): grazing is
    a bifurcation of its own and is detected on the branch, not divided by.
    """
    f_minus = model.rhs(tau, s, params, regime_before)
    f_plus = model.rhs(tau, s, params, regime_after)
    rate = float(grad @ f_minus) + dh_dtau
    jump = f_plus - f_minus
    if not np.any(jump):
        return np.eye(4)
    scale = float(np.linalg.norm(grad) * np.linalg.norm(f_minus)) + abs(dh_dtau)
    if abs(rate) <= 1e-13 * max(scale, 1e-300):
        raise GrazingSwitchError(
            f"grazing switch at tau = {tau:.9g}: the saltation matrix is singular"
        )
    return np.eye(4) + np.outer(jump, grad) / rate


def rolling_projection_jacobian(s: np.ndarray, params: ModelParams) -> np.ndarray:
    """Jacobian of ``model.project_to_rolling`` at s (central differences)."""
    jac = np.zeros((4, 4))
    for j in range(4):
        h = 1e-7 * max(1.0, abs(s[j]))
        sp, sm = s.copy(), s.copy()
        sp[j] += h
        sm[j] -= h
        jac[:, j] = (
            model.project_to_rolling(sp, params) - model.project_to_rolling(sm, params)
        ) / (2.0 * h)
    return jac


def _two_body_records(params: ModelParams) -> tuple[np.ndarray, np.ndarray]:
    return np.array(model.params_vector(params)), params.stator.record()


def _two_body_event_function(
    before: int, after: int, params: ModelParams
) -> Callable[[np.ndarray], float]:
    """The event function h(ten states) whose rising zero switched ``before`` into
    ``after``: the clearance ``z^2 - 1`` at contact entry and exit, the slip velocity
    ``v_r`` at a reversal or stick entry, the stick margin ``s T - mu K (z - 1)`` at
    stick exit."""
    pars, stator = _two_body_records(params)
    if model.FREE in (before, after):
        return lambda s: s[0] ** 2 + s[1] ** 2 - 1.0
    if before == model.STICK:
        side = 1.0 if after == model.SLIP_POSITIVE else -1.0
        limit = params.mu * params.K

        def margin(s: np.ndarray) -> float:
            T = two_body_columns(np.ascontiguousarray(s[:, None]), pars, stator, model.STICK)[1]
            return side * float(T[0]) - limit * (math.hypot(s[0], s[1]) - 1.0)

        return margin
    return lambda s: float(model.slip_velocity(s[0], s[1], s[2], s[3], params.Rp, s[5]))


def _section_gradient(h: Callable[[np.ndarray], float], s: np.ndarray) -> np.ndarray:
    """grad h in the ten states, by central differences in the section's eight (0 in the
    phase and the speed)."""
    grad = np.zeros(s.size)
    for j in SECTION:
        step = GRADIENT_STEP * (1.0 + abs(s[j]))
        up, down = s.copy(), s.copy()
        up[j] += step
        down[j] -= step
        grad[j] = (h(up) - h(down)) / (2.0 * step)
    return grad


def two_body_saltation(s: np.ndarray, before: int, after: int, params: ModelParams) -> np.ndarray:
    """The two bodies' saltation matrix (8, 8) on the section at the event state ``s``
    (ten states) switching ``before`` into ``after``; GrazingSwitchError where the
    crossing is tangential."""
    pars, stator = _two_body_records(params)
    f_minus = two_body_rhs(s, pars, stator, before)
    f_plus = two_body_rhs(s, pars, stator, after)
    jump = f_plus - f_minus
    if not np.any(jump[list(SECTION)]):
        return np.eye(N_SECTION)
    grad = _section_gradient(_two_body_event_function(before, after, params), s)
    rate = float(grad @ f_minus)
    scale = float(np.linalg.norm(grad) * np.linalg.norm(f_minus))
    if abs(rate) <= 1e-13 * max(scale, 1e-300):
        raise GrazingSwitchError("the saltation matrix is singular (a grazing switch)")
    full = np.eye(N_STATES) + np.outer(jump, grad) / rate
    return full[np.ix_(SECTION, SECTION)]


def two_body_projection_jacobian(s: np.ndarray, params: ModelParams) -> np.ndarray:
    """The Jacobian (8, 8) of the two bodies' projection onto the rolling constraint at
    ``s`` (ten states), by central differences."""
    m_inv = params.stator.record()[S_INV_MASS]

    def project(state: np.ndarray) -> np.ndarray:
        out = state.copy()
        spin = params.Rp * state[5]
        out[2], out[3], out[8], out[9] = two_body_projection(
            state[0], state[1], state[2], state[3], state[8], state[9], spin, m_inv
        )
        return out[list(SECTION)]

    jac = np.zeros((N_SECTION, N_SECTION))
    for col, j in enumerate(SECTION):
        step = GRADIENT_STEP * (1.0 + abs(s[j]))
        up, down = s.copy(), s.copy()
        up[j] += step
        down[j] -= step
        jac[:, col] = (project(up) - project(down)) / (2.0 * step)
    return jac


# --------------------------------------------------------------------------- the run

ROTOR_SYSTEM = System(
    size=N_ROTOR, rhs=rotor_rhs, columns=rotor_columns, python_rhs=rotor_rhs,
    python_columns=rotor_columns, loop=(rotor_initial_step, advance_rotor), taylor=None,
)  # fmt: skip
# the event search reads the rotor's six entries only: the columns leave Phi's rows 0
VARIATIONAL_SYSTEM = System(
    size=N_VARIATIONAL, rhs=variational_rhs, columns=rotor_columns,
    python_rhs=variational_rhs, python_columns=rotor_columns,
    loop=(variational_initial_step, advance_variational), taylor=None,
)  # fmt: skip


TWO_BODY_VARIATIONAL_SYSTEM = System(
    size=N_STATES + N_SECTION * N_SECTION, rhs=two_body_variational_rhs,
    columns=two_body_columns, python_rhs=two_body_variational_rhs,
    python_columns=two_body_columns,
    loop=(two_body_variational_initial_step, advance_two_body_variational), taylor=None,
)  # fmt: skip


def _chattering(run: ExtendedRun, switched: bool, max_events: int) -> bool:
    """Whether a switch just applied makes more than ``max_events`` events (and the run
    then failed: a chattering contact)."""
    if switched and run.recorder.n > max_events:
        run.fail(f"more than {max_events} switch events (a chattering contact)")
        return True
    return False


class RotorFlowRun(ExtendedRun):
    """An extended run of the rotor at a constant speed (module docstring), in the
    variational mode when ``phi`` is given: Phi then starts there and jumps at every
    event. More than ``max_events`` events fail the run (a chattering contact)."""

    loop_applies_events = False  # ``switch`` moves Phi and counts the events

    def __init__(
        self, problem: Problem, phi: np.ndarray | None, locked: int | None, max_events: int,
        max_wall_time_s: float,
    ) -> None:  # fmt: skip
        p = problem.params
        self.system = ROTOR_SYSTEM if phi is None else VARIATIONAL_SYSTEM
        self.max_events = max_events
        phase = p.phi0 + p.eta * float(problem.t_eval[0])
        state = [*problem.initial, phase, p.eta]
        if phi is not None:
            state += list(np.asarray(phi, dtype=float).ravel())
        pars = np.array(model.params_vector(p))
        super().__init__(problem, "dop853-jit", (pars,), np.array(state), locked=locked,
                         max_steps=FLOW_MAX_STEPS, max_wall_time_s=max_wall_time_s)  # fmt: skip

    def project(self, s: np.ndarray) -> np.ndarray:
        """The state with v_r = 0 exactly (``model.rolling_velocity``); Phi unchanged
        (``switch`` multiplies it by the projection's Jacobian where stick ends)."""
        out = np.array(s, dtype=float)
        out[2], out[3] = model.rolling_velocity(s[0], s[1], s[2], s[3], self.params.Rp * s[5])
        return out

    def switch(self, tau: float, kind: int, state: np.ndarray) -> bool:
        """``ExtendedRun.switch``, and in the variational mode Phi through the event's
        saltation matrix (module docstring)."""
        before, s_event = self.regime, np.array(state[:4], dtype=float)
        switched = super().switch(tau, kind, state)
        if self.system is VARIATIONAL_SYSTEM:
            p, recorded = self.params, self.last_kind
            phi = self.state[N_ROTOR:].reshape(4, 4)
            grad, dh_dtau = surface_gradient(recorded, tau, s_event, p, before)
            if recorded == ev.STICK_EXIT:
                phi = rolling_projection_jacobian(s_event, p) @ phi
            jump = saltation_matrix(tau, self.state[:4], p, before, self.regime, grad, dh_dtau)
            self.state[N_ROTOR:] = (jump @ phi).ravel()
        return switched and not _chattering(self, switched, self.max_events)

    def solution(self, settings: dict) -> Solution:
        solution = super().solution(settings)
        solution.states = np.ascontiguousarray(self.states[: solution.t.size, :4])
        return solution


class TwoBodyFlowRun(TwoBodyRun):
    """A run of the two bodies (``solvers.two_body``) as a flow: in the variational mode
    when ``phi`` (8 x 8) is given, Phi jumping at every event (module docstring); more
    than ``max_events`` events fail it."""

    loop_applies_events = False  # ``switch`` moves Phi and counts the events

    def __init__(
        self, problem: Problem, phi: np.ndarray | None, locked: int | None, max_events: int,
        max_wall_time_s: float,
    ) -> None:  # fmt: skip
        if phi is not None:
            self.system = TWO_BODY_VARIATIONAL_SYSTEM
        self.max_events = max_events
        super().__init__(problem, "dop853-jit", extra=phi, locked=locked,
                         max_steps=FLOW_MAX_STEPS, max_wall_time_s=max_wall_time_s)  # fmt: skip

    def switch(self, tau: float, kind: int, state: np.ndarray) -> bool:
        """``TwoBodyRun.switch``, and in the variational mode Phi through the event's
        saltation matrix and, where stick begins or ends, the projection's Jacobian, both
        at the state after the event."""
        before = self.regime
        switched = super().switch(tau, kind, state)
        if self.system is TWO_BODY_VARIATIONAL_SYSTEM:
            s, after, p = self.state[:N_STATES], self.regime, self.params
            phi = two_body_saltation(s, before, after, p) @ self.state[N_STATES:].reshape(
                N_SECTION, N_SECTION
            )
            if model.STICK in (before, after) and model.FREE not in (before, after):
                phi = two_body_projection_jacobian(s, p) @ phi
            self.state[N_STATES:] = phi.ravel()
        return switched and not _chattering(self, switched, self.max_events)


@dataclass
class Flow:
    """A flow's run: its Solution (the rotor's samples and events; the stator's beside
    for the two bodies), the full state at its last sample (after the rotor's and the
    stator's, in the variational mode Phi) and the right-hand side evaluations spent."""

    solution: Solution
    end: np.ndarray
    nfev: int


def _flow(run: ExtendedRun, rtol: float, atol: float) -> Flow:
    kernels.ensure_fresh()
    sol = driver.integrate(run, ExtendedJitStepper(run, rtol, atol))
    end = np.array(run.states[sol.t.size - 1])
    return Flow(sol, end, int(run.stats.get("nfev", 0)))


def rotor_flow(
    params: ModelParams,
    start: np.ndarray,
    t_eval: np.ndarray,
    *,
    phi: np.ndarray | None = None,
    locked: int | None = None,
    rtol: float,
    atol: float,
    max_events: int,
    max_wall_time_s: float = math.inf,
) -> Flow:
    """``dop853-jit``'s run of the rotor at a constant speed from ``start`` (x, y, vx, vy)
    at ``t_eval[0]``, sampled at ``t_eval``; with ``phi`` (4 x 4) in the variational mode;
    in one regime without events when ``locked`` (the smooth extension of a flow across
    its surfaces)."""
    problem = Problem(params, tuple(start), t_eval)
    return _flow(RotorFlowRun(problem, phi, locked, max_events, max_wall_time_s), rtol, atol)


def two_body_flow(
    params: ModelParams,
    start: np.ndarray,
    t_eval: np.ndarray,
    *,
    phi: np.ndarray | None = None,
    locked: int | None = None,
    rtol: float,
    atol: float,
    max_events: int,
    max_wall_time_s: float = math.inf,
) -> Flow:
    """``rotor_flow`` of the two bodies: ``start`` their eight entries on the section
    ``(x, y, vx, vy, u, v, u', v')``, ``phi`` (8 x 8)."""
    problem = Problem(params, tuple(start[:4]), t_eval, stator_initial=tuple(start[4:]))
    return _flow(TwoBodyFlowRun(problem, phi, locked, max_events, max_wall_time_s), rtol, atol)

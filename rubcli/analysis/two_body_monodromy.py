"""The monodromy matrix of a stator with its own mass through its switches, by saltation
matrices (docs/orbits.md, docs/machines.md).

On the section the state is the two bodies' eight entries ``q = (x, y, vx, vy, u, v, u',
v')``; the phase ``p = eta tau + phi0`` and the speed are not perturbed. A flow from
``tau0`` to ``tau1`` with events at ``t_1 < ... < t_n`` is smooth between them, so its
Jacobian is the product

    Phi = Phi_n  P_n S_n  Phi_{n-1}  ...  P_1 S_1  Phi_0

- ``Phi_i``: the Jacobian of segment i, the flow locked in its regime from the state
  after its starting event to the next, by central differences (a smooth flow: no
  event moves under the perturbation);
- ``S_i = I + (f+ - f-) grad(h)^T / (grad(h)^T f-)``: the saltation matrix of the event
  surface ``h = 0`` (``rubcli.stator.two_body_entries`` for ``f-`` and ``f+``, in the ten
  states, where the system is autonomous; the phase's row of the jump is 0, so the
  phase stays unperturbed): the clearance ``z^2 - 1`` at contact entry and exit (``f+ =
  f-`` there: the contact force vanishes at ``z = 1``, ``S = I``), the slip velocity
  ``v_r`` at a reversal or stick entry, the stick margin ``s T - mu K (z - 1)`` at stick
  exit;
- ``P_i``: the Jacobian of the projection onto the rolling constraint where the run
  projects (stick entry and exit, ``stator.two_body_projection``), else I.

A grazing event (``grad(h)^T f- = 0``) has no saltation matrix: OrbitError, as on the
rigid stator (``solvers.variational.saltation_matrix``). The gradients and the projection's Jacobian
are central differences of closed-form functions (step ``GRADIENT_STEP`` (1 + |q_j|)).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rubcli import model
from rubcli.model import ModelParams
from rubcli.solution import Solution
from rubcli.solvers.compiled.two_body import two_body_columns, two_body_rhs
from rubcli.solvers.variational import GrazingSwitchError
from rubcli.stator import S_INV_MASS, two_body_projection

MECHANICAL = np.array([0, 1, 2, 3, 6, 7, 8, 9])  # the section's entries of the ten states
GRADIENT_STEP = 1e-7  # central differences of the event functions and the projection
# a segment's central differences, relative to 1 + |q_j|: the flow's own error at rtol
# 1e-12 is then 1e-7 of a column, the differences' truncation 1e-10
FD_STEP = 1e-5

# a segment's locked flow: (start (8,), tau_a, tau_b, regime) -> end (8,), evaluations
SegmentFlow = Callable[[np.ndarray, float, float, int], tuple[np.ndarray, int]]


def full_state(q: np.ndarray, tau: float, params: ModelParams) -> np.ndarray:
    """The ten states of the section's eight at tau (phase and speed of the constant
    speed)."""
    out = np.empty(10)
    out[MECHANICAL] = q
    out[4], out[5] = params.phi0 + params.eta * tau, params.eta
    return out


def _records(params: ModelParams) -> tuple[np.ndarray, np.ndarray]:
    return np.array(model.params_vector(params)), params.stator.record()


def _event_function(before: int, after: int, params: ModelParams) -> Callable[[np.ndarray], float]:
    """The event function h(ten states) whose rising zero switched ``before`` into
    ``after`` (module docstring)."""
    pars, stator = _records(params)
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


def _gradient(h: Callable[[np.ndarray], float], s: np.ndarray) -> np.ndarray:
    grad = np.zeros(s.size)
    for j in MECHANICAL:
        step = GRADIENT_STEP * (1.0 + abs(s[j]))
        up, down = s.copy(), s.copy()
        up[j] += step
        down[j] -= step
        grad[j] = (h(up) - h(down)) / (2.0 * step)
    return grad


def saltation(s: np.ndarray, before: int, after: int, params: ModelParams) -> np.ndarray:
    """The saltation matrix (8, 8) on the section at the event state ``s`` (ten states)
    switching ``before`` into ``after``; GrazingSwitchError where the crossing is
    tangential."""
    pars, stator = _records(params)
    f_minus = two_body_rhs(s, pars, stator, before)
    f_plus = two_body_rhs(s, pars, stator, after)
    jump = f_plus - f_minus
    if not np.any(jump[MECHANICAL]):
        return np.eye(8)
    grad = _gradient(_event_function(before, after, params), s)
    rate = float(grad @ f_minus)
    scale = float(np.linalg.norm(grad) * np.linalg.norm(f_minus))
    if abs(rate) <= 1e-13 * max(scale, 1e-300):
        raise GrazingSwitchError("the saltation matrix is singular (a grazing switch)")
    full = np.eye(10) + np.outer(jump, grad) / rate
    return full[np.ix_(MECHANICAL, MECHANICAL)]


def projection_jacobian(s: np.ndarray, params: ModelParams) -> np.ndarray:
    """The Jacobian (8, 8) of the projection onto the rolling constraint at ``s``."""
    m_inv = params.stator.record()[S_INV_MASS]

    def project(state: np.ndarray) -> np.ndarray:
        out = state.copy()
        spin = params.Rp * state[5]
        out[2], out[3], out[8], out[9] = two_body_projection(
            state[0], state[1], state[2], state[3], state[8], state[9], spin, m_inv
        )
        return out[MECHANICAL]

    jac = np.zeros((8, 8))
    for col, j in enumerate(MECHANICAL):
        step = GRADIENT_STEP * (1.0 + abs(s[j]))
        up, down = s.copy(), s.copy()
        up[j] += step
        down[j] -= step
        jac[:, col] = (project(up) - project(down)) / (2.0 * step)
    return jac


def segment_jacobian(flow: SegmentFlow, q: np.ndarray, ta: float, tb: float,
                     regime: int) -> tuple[np.ndarray, int]:  # fmt: skip
    """The Jacobian (8, 8) of the flow locked in ``regime`` from (ta, q) to tb, by
    central differences; and the evaluations it took."""
    jac, nfev = np.empty((8, 8)), 0
    for j in range(8):
        step = FD_STEP * (1.0 + abs(q[j]))
        sides = []
        for sign in (1.0, -1.0):
            moved = q.copy()
            moved[j] += sign * step
            end, n = flow(moved, ta, tb, regime)
            sides.append(end)
            nfev += n
        jac[:, j] = (sides[0] - sides[1]) / (2.0 * step)
    return jac, nfev


def monodromy(flow: SegmentFlow, solution: Solution, q0: np.ndarray, tau0: float,
              tau1: float) -> tuple[np.ndarray, int]:  # fmt: skip
    """The flow's Jacobian (8, 8) from (tau0, q0) to tau1 through the switches of its run
    ``solution`` (module docstring), and the evaluations it took."""
    params = solution.problem.params
    phi, nfev = np.eye(8), 0
    start, ta, regime = np.asarray(q0, dtype=float), float(tau0), int(solution.regimes[0])
    stators = solution.stator_events
    for i, event in enumerate(solution.events):
        if event.tau > ta:
            jac, n = segment_jacobian(flow, start, ta, event.tau, regime)
            phi, nfev = jac @ phi, nfev + n
        after = np.concatenate((event.state, stators[i]))
        s = full_state(after, event.tau, params)
        before_regime, after_regime = event.regime_before, event.regime_after
        phi = saltation(s, before_regime, after_regime, params) @ phi
        projects = model.STICK in (before_regime, after_regime) and model.FREE not in (
            before_regime, after_regime)  # fmt: skip
        if projects:
            phi = projection_jacobian(s, params) @ phi
        start, ta, regime = after, float(event.tau), after_regime
    if tau1 > ta:
        jac, n = segment_jacobian(flow, start, ta, tau1, regime)
        phi, nfev = jac @ phi, nfev + n
    return phi, nfev

"""The stator with its own mass (``rubcli.stator``) in the event loop of
``solvers.extended``.

The state has ten entries, ``(x, y, vx, vy, p, w, u, v, u', v')``: the rotor relative to
the stator's centre, the unbalance's phase and (constant) speed, the stator's
displacement from its rest position and velocity (``Problem.stator_initial``). Its
stick friction is the two bodies' (``stator.two_body_entries`` in stick), and stick
begins and ends with the two bodies' velocities projected onto the rolling constraint
(``stator.two_body_projection``). The scipy methods and ``dop853-jit`` run it
(``extended.solve_extended``), ``taylor`` (its series in ``compiled.two_body_taylor``)
and ``analytic`` (``solvers.two_body_analytic``).
"""

from __future__ import annotations

import numpy as np

from rubcli import model
from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers.compiled.two_body import (
    advance_two_body,
    two_body_columns,
    two_body_initial_step,
    two_body_rhs,
)
from rubcli.solvers.compiled.two_body_taylor import (
    advance_two_body_taylor,
)
from rubcli.solvers.extended import (
    ExtendedRun,
    System,
    solve_extended,
)
from rubcli.solvers.registry import MOVING_STATOR, SPECS, Options, StepOptions
from rubcli.stator import N_STATES, S_INV_MASS, two_body_entries, two_body_projection


def _python_rhs(s, pars, stator, regime) -> np.ndarray:
    """``compiled.two_body.two_body_rhs`` run by the interpreter (``compiled=False``)."""
    out = np.empty(N_STATES)
    two_body_entries(s, pars, stator, regime, out)
    return out


def _python_columns(S, pars, stator, regime):
    """``compiled.two_body.two_body_columns`` run by the interpreter."""
    dS, T, out = np.empty_like(S), np.empty(S.shape[1]), np.empty(N_STATES)
    for k in range(S.shape[1]):
        T[k] = two_body_entries(S[:, k], pars, stator, regime, out)
        dS[:, k] = out
    return dS, T


TWO_BODY_SYSTEM = System(
    size=N_STATES, rhs=two_body_rhs, columns=two_body_columns, python_rhs=_python_rhs,
    python_columns=_python_columns, loop=(two_body_initial_step, advance_two_body),
    taylor=advance_two_body_taylor,
)  # fmt: skip


class TwoBodyRun(ExtendedRun):
    """An extended run whose state is the two bodies' ten entries (module docstring)."""

    system = TWO_BODY_SYSTEM

    def __init__(self, problem: Problem, method: str, extra: np.ndarray | None = None,
                 **options) -> None:  # fmt: skip
        """``extra``: states after the ten, for a system with more (``solvers.variational``)."""
        p = problem.params
        self.stator = p.stator.record()
        pars = np.array(model.params_vector(p))
        phase = p.phi0 + p.eta * float(problem.t_eval[0])
        state = [*problem.initial, phase, p.eta, *problem.stator_initial]
        if extra is not None:
            state += list(np.ravel(extra))
        super().__init__(problem, method, (pars, self.stator), np.array(state), **options)
        self.event_stators: list[np.ndarray] = []  # the stator's states at each event

    def switch(self, tau: float, kind: int, state: np.ndarray) -> bool:
        """``ExtendedRun.switch``, the stator's states at the event kept beside."""
        switched = super().switch(tau, kind, state)
        self.event_stators.append(np.array(self.state[6:N_STATES]))
        return switched

    def record_events(
        self, n: int, taus: np.ndarray, kinds: np.ndarray, states: np.ndarray,
        regimes: np.ndarray,
    ) -> bool:  # fmt: skip
        """``ExtendedRun.record_events``, the stator's states at the events recorded kept
        beside."""
        before = self.recorder.n
        recorded = super().record_events(n, taus, kinds, states, regimes)
        self.event_stators += [np.array(s[6:N_STATES]) for s in states[: self.recorder.n - before]]
        return recorded

    def project(self, s: np.ndarray) -> np.ndarray:
        """The state with v_r = 0 exactly (``stator.two_body_projection``)."""
        out = np.array(s, dtype=float)
        spin = self.params.Rp * s[5]
        out[2], out[3], out[8], out[9] = two_body_projection(
            s[0], s[1], s[2], s[3], s[8], s[9], spin, self.stator[S_INV_MASS]
        )
        return out

    def solution(self, settings: dict) -> Solution:
        solution = super().solution(settings)
        k = solution.t.size
        solution.states = np.ascontiguousarray(self.states[:k, :4])
        solution.stator_states = np.ascontiguousarray(self.states[:k, 6:N_STATES])
        solution.stator_events = np.array(self.event_stators).reshape(-1, 4)
        return solution


def full_states(solution: Solution) -> np.ndarray:
    """A two-body run's ten states at its samples, (10, n): the phase and speed of the
    constant speed put back beside the rotor's and the stator's."""
    p = solution.problem.params
    return np.vstack([solution.states.T, p.eta * solution.t + p.phi0,
                      np.full(solution.t.size, p.eta), solution.stator_states.T])  # fmt: skip


def sample_derivatives(solution: Solution) -> tuple[np.ndarray, np.ndarray]:
    """A two-body run's equations at its samples, each in its regime: the derivatives of
    the ten states (10, n) and the rub's tangential force (n,) (positive opposing
    positive slip; the stick multiplier in stick; 0 in free flight)."""
    params = solution.problem.params
    pars = np.array(model.params_vector(params))
    stator = params.stator.record()
    S = full_states(solution)
    dS, T = np.empty_like(S), np.zeros(solution.t.size)
    for regime in (model.FREE, model.SLIP_POSITIVE, model.SLIP_NEGATIVE, model.STICK):
        on = solution.regimes == regime
        if np.any(on):
            dS[:, on], T[on] = two_body_columns(np.ascontiguousarray(S[:, on]), pars, stator,
                                                regime)  # fmt: skip
    return dS, T


def solve_two_body(problem: Problem, options: Options, name: str) -> Solution:
    """A stator with its own mass by the method ``name``: a scipy method, ``dop853-jit``,
    ``taylor`` (module docstring; the compiled loops always locate and apply the events
    compiled, so ``compiled_events`` changes nothing here) or
    ``analytic`` (``solvers.two_body_analytic``)."""
    if MOVING_STATOR not in SPECS[name].features:
        raise ValueError(f"{name} does not run a stator with its own mass")
    o = options
    run = TwoBodyRun(
        problem, name, max_steps=o.max_steps, max_wall_time_s=o.max_wall_time_s,
        progress=o.progress,
    )  # fmt: skip
    if isinstance(o, StepOptions):
        from rubcli.solvers.two_body_analytic import solve_two_body_analytic

        return solve_two_body_analytic(run, o)
    return solve_extended(run, name, o.rtol, o.atol, o.compiled)

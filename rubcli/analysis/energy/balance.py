"""Energy balance of a solution: a reference-free check of its quality.

Multiplying the equation of motion (model notes 1) by the velocity ``v = w'`` gives,
exactly, for every regime (``'`` = d/dtau)::

    d/dtau [ 1/2 |v|^2 + 1/2 z^2 + 1/2 K (z - 1)^2 [in contact] ]
        = E (cos(eta tau + phi0) vx + sin(eta tau + phi0) vy)      power of the unbalance
          - 2 nu |v|^2                                            damping
          - T r theta'                                            friction on the translation

so, with ``E_mech`` the bracket, over any span::

    Delta E_mech = W_in - D_damp - D_fric,    W_in = int P_in,  D_damp = int 2 nu |v|^2,
                                              D_fric = int T r theta' dtau.

``T`` is the signed tangential contact force (``model.tangential_force``: ``mu_c K (z-1)``
when slipping, the rolling force ``model.stick_friction`` in stick; positive opposes
positive slip) and ``r theta' = (x vy - y vx) / z`` the whirl speed. The normal force
``K (z - 1)`` does no net work: its power is the rate of the stator's elastic energy.

**Friction and the motor.** The energy friction dissipates at the contact is
``T v_r >= 0`` (zero in stick), with the slip ``v_r = Rp eta + r theta'``. Since
``T r theta' = T v_r - T Rp eta``, the friction's effect on the translation is the
contact dissipation minus ``T Rp eta``: the share of the friction power that the spin
drive supplies (the rotor is driven at constant speed ``eta``, so the motor provides
whatever torque the friction takes). ``D_fric`` can therefore be negative: in a backward
whirl (dry whip) the spinning surface pumps energy into the whirl. Both shares are
reported (``contact_dissipation``, ``spin_drive``).

**Quadrature.** The integrals are taken piece by piece between the solution's located
events (``analysis.energy.regimes.solution_pieces``), so the kinks of the contact force at a
switch never fall inside a quadrature interval. On each interval between two nodes
(samples, or event states) the state is the cubic Hermite interpolant of the positions
(from positions and velocities) and of the velocities (from velocities and
accelerations, the accelerations from the equation of motion in the piece's regime);
each power is integrated as its own cubic Hermite interpolant, from its values and its
rates at the nodes (the corrected trapezoid rule ``h/2 (P_k + P_k+1) + h^2/12 (P'_k -
P'_k+1)``; the rates are central differences along the motion). The rule is of order 4
in the node spacing ``h`` and needs no minimum number of nodes, so a contact shorter
than the output spacing (two event states, no sample) still gets its friction work.

**Residual.** ``energy_residual = |Delta E_mech - (W_in - D_damp - D_fric)| / throughput``
with ``throughput = int |P_in| + D_damp + int |T r theta'| + max E_mech``, the energy that
flowed through the system plus the largest energy stored (so a conservative motion with
no input still has a scale). An exact solution has a residual at quadrature level
(``O((omega h)^4)`` with ``omega`` the fastest frequency of the motion); a numerical
solution adds its own violation of the balance, which grows with its error.
``quadrature_error`` estimates the quadrature's own share (same normalisation): the
difference between the rule on every node and on every other node of each piece (with
the same nodal powers and rates), divided by 15 (Richardson, order 4); for a piece with
no interior sample, the difference from the trapezoid rule. **A residual is informative
only when it is well above the quadrature error**: when the output samples do not
resolve the motion (a stiff stator's contact oscillates with frequency ``~ sqrt(K)``;
raise ``samples_per_period``), both are large and the residual says nothing about the
solver.

**Cost.** ``energy_balance`` and ``energy_totals`` run in one compiled pass over the
nodes (``analysis.energy.kernel``), with the arithmetic of the whole-array numpy path
``energy_balance_numpy`` (kept as the tests' reference); ``energy_totals``, all a report
needs, keeps no per-sample array.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rubcli import model
from rubcli.analysis.energy.regimes import Piece, solution_pieces
from rubcli.solution import Solution

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from rubcli.model import FloatOrArray

DERIVATIVE_STEP = 1e-5  # central-difference step of the power rates, times the node spacing
RICHARDSON_FACTOR = 15.0  # 2^4 - 1: order-4 rule on h and 2h
SMALL_SHIFT = 1e-4  # phase shifts below this: cos and sin by their Taylor series

# Columns of the power array: unbalance, damping, friction on the translation
# (-T r theta'), contact dissipation (T v_r), spin drive (T Rp eta), |P_in|, |T r theta'|,
# and on the general machine the cross-coupled stiffness's work on the rotor
# (-w'^T S_anti w) and its magnitude (also analysis.energy.transient's columns).
W_IN, W_DAMP, W_FRIC, W_SLIP, W_SPIN, W_ABS_IN, W_ABS_FRIC, W_CROSS, W_ABS_CROSS = range(9)
N_TERMS = 9


@dataclass(frozen=True)
class EnergyBalance:
    """The terms of the energy balance at the nodes of a solution (cumulative from the start).

    ``tau`` are the nodes (samples and event times, in order); each series has the same
    length. ``work_unbalance``, ``damping``, ``friction`` (= D_fric), ``contact_dissipation``
    and ``spin_drive`` are integrals from the start to each node. ``residual`` is
    ``(E_mech - E_mech[0]) - (W_in - D_damp - D_fric)`` at each node.
    """

    tau: np.ndarray
    kinetic: np.ndarray
    rotor_spring: np.ndarray
    stator: np.ndarray
    work_unbalance: np.ndarray
    damping: np.ndarray
    friction: np.ndarray
    contact_dissipation: np.ndarray
    spin_drive: np.ndarray
    throughput: float
    quadrature_error: float  # relative to throughput (see module docstring)
    n_pieces: int = 0
    # the general machine's cross-coupled stiffness's work on the rotor (None: 0)
    cross_coupling: np.ndarray | None = None

    @property
    def energy(self) -> np.ndarray:
        """Mechanical energy: kinetic + rotor spring + stator."""
        return self.kinetic + self.rotor_spring + self.stator

    @property
    def residual(self) -> np.ndarray:
        delta = self.energy - self.energy[0]
        cross = 0.0 if self.cross_coupling is None else self.cross_coupling
        return delta - (self.work_unbalance - self.damping - self.friction + cross)

    @property
    def relative_residual(self) -> float:
        """``energy_residual``: |final residual| / throughput (0 for an empty solution)."""
        if self.tau.size == 0:
            return 0.0
        final = abs(float(self.residual[-1]))
        if self.throughput > 0.0:
            return final / self.throughput
        return 0.0 if final == 0.0 else float("inf")

    def summary(self) -> dict[str, float]:
        """Totals over the span, for reports."""
        if self.tau.size == 0:
            return {"energy_residual": 0.0, "energy_quadrature_error": 0.0}
        return {
            "energy_residual": self.relative_residual,
            "energy_quadrature_error": self.quadrature_error,
            "energy_change": float(self.energy[-1] - self.energy[0]),
            "work_unbalance": float(self.work_unbalance[-1]),
            "damping_dissipation": float(self.damping[-1]),
            "friction_dissipation": float(self.friction[-1]),
            "contact_dissipation": float(self.contact_dissipation[-1]),
            "spin_drive_work": float(self.spin_drive[-1]),
            **_cross_entry(0.0 if self.cross_coupling is None else self.cross_coupling[-1]),
            "energy_throughput": self.throughput,
        }


def _cross_entry(work: float) -> dict[str, float]:
    """The cross-coupling's work for a report, where there is any (general machine)."""
    return {"cross_coupling_work": float(work)} if work != 0.0 else {}


# ----------------------------------------------------------------------- pointwise terms


def mechanical_energy(
    states: ArrayLike, params: model.ModelParams, regime: int | np.ndarray
) -> tuple:
    """Kinetic 1/2 |v|^2, rotor spring 1/2 z^2, stator 1/2 K (z-1)^2 in contact (else 0).

    On the general machine the rotor spring is the support's and the load's potential,
    ``1/2 w^T S_sym w - g . w`` at the rotor's position ``w = d + c``.
    ``states`` has shape (n, 4) (or (4,)); ``regime`` is a code or an array of codes.
    """
    S = np.atleast_2d(np.asarray(states, dtype=float))
    x, y, vx, vy = S.T
    z = np.hypot(x, y)
    in_contact = np.asarray(regime) != model.FREE
    kinetic = 0.5 * (vx * vx + vy * vy)
    spring = 0.5 * z * z if params.is_paper_machine else support_potential(x, y, params)
    stator = np.where(in_contact, 0.5 * params.K * (z - 1.0) ** 2, 0.0)
    return kinetic, spring, np.broadcast_to(stator, z.shape).astype(float)


def accelerations(
    tau: FloatOrArray, states: ArrayLike, params: model.ModelParams, regime: int
) -> np.ndarray:
    """d(vx, vy)/dtau of states (shape (n, 4)) in one regime, vectorised.

    The contact force is the model's: ``model.contact_force`` when slipping; in stick the
    normal force ``model.normal_force`` along ``-r_hat`` and the rolling friction
    ``model.tangential_force`` along ``-theta_hat`` (what ``model.rhs`` applies).
    """
    S = np.atleast_2d(np.asarray(states, dtype=float))
    tau = np.asarray(tau, dtype=float)
    x, y, vx, vy = S.T
    phase = params.eta * tau + params.phi0
    ax = params.E * np.cos(phase) - 2.0 * params.nu * vx - x
    ay = params.E * np.sin(phase) - 2.0 * params.nu * vy - y
    if not params.is_paper_machine:  # the stick friction below holds its tangential part
        ex, ey = model.support_extra(x, y, vx, vy, model.params_vector(params))
        ax, ay = ax + ex, ay + ey
    if regime == model.STICK:
        z = np.hypot(x, y)
        normal = model.normal_force(x, y, params.K)
        tangential = model.tangential_force(tau, x, y, vx, vy, params, regime)
        ax = ax - (normal * x - tangential * y) / z
        ay = ay - (normal * y + tangential * x) / z
    elif regime != model.FREE:
        fx, fy = model.contact_force(x, y, params.K, params.mu * model.friction_sign(regime))
        ax, ay = ax + fx, ay + fy
    return np.column_stack((ax, ay))


def powers(
    tau: FloatOrArray,
    states: ArrayLike,
    params: model.ModelParams,
    regime: int,
    phase: tuple[FloatOrArray, FloatOrArray] | None = None,
) -> np.ndarray:
    """Power terms at states (shape (n, 4)) in one regime: array (n, N_TERMS).

    Columns: unbalance P_in, damping 2 nu |v|^2, friction on the translation -T r theta',
    contact dissipation T v_r, spin drive T Rp eta, |P_in|, |T r theta'|. ``phase``:
    (cos, sin) of ``eta tau + phi0`` if already known. On a leg of a speed profile
    (``params.rate``) the unbalance carries its tangential term (``model.unbalance_value``)
    and the spin is the leg's ``eta(tau)``.
    """
    S = np.atleast_2d(np.asarray(states, dtype=float))
    tau = np.asarray(tau, dtype=float)
    x, y, vx, vy = S.T
    eta = params.eta
    if params.rate != 0.0:
        p = params
        fx, fy = model.unbalance_value(tau, p.eta, p.E, p.phi0, p.e, p.rate, p.tau0)
        p_in = fx * vx + fy * vy
        eta = p.speed(tau)
    else:
        if phase is None:
            angle = params.eta * tau + params.phi0
            phase = (np.cos(angle), np.sin(angle))
        p_in = params.E * (phase[0] * vx + phase[1] * vy)
    out = np.zeros((S.shape[0], N_TERMS))
    if params.is_paper_machine:
        p_damp = 2.0 * params.nu * (vx * vx + vy * vy)
    else:  # 2 w'^T D w' (the antisymmetric part does no work), the cross-coupling's work
        (dxx, dxy), (dyx, dyy) = params.damping_matrix
        p_damp = 2.0 * (dxx * vx * vx + (dxy + dyx) * vx * vy + dyy * vy * vy)
        out[:, W_CROSS] = cross_coupling_power(x, y, vx, vy, params)
        out[:, W_ABS_CROSS] = np.abs(out[:, W_CROSS])
    out[:, W_IN], out[:, W_DAMP], out[:, W_ABS_IN] = p_in, p_damp, np.abs(p_in)
    if regime != model.FREE:
        T = model.tangential_force(tau, x, y, vx, vy, params, regime)
        z = np.hypot(x, y)
        whirl = (x * vy - y * vx) / z  # r theta'
        v_r = model.slip_velocity(x, y, vx, vy, params.Rp, eta)
        out[:, W_FRIC] = -T * whirl
        out[:, W_SLIP] = T * v_r
        out[:, W_SPIN] = T * params.Rp * eta
        out[:, W_ABS_FRIC] = np.abs(T * whirl)
    return out


def support_potential(x: FloatOrArray, y: FloatOrArray, params: model.ModelParams) -> FloatOrArray:
    """``1/2 w^T S_sym w - g . w`` at the rotor's position ``w = (x, y) + c``: the
    general machine's support and load potential (the paper's ``1/2 z^2``)."""
    (sxx, sxy), (syx, syy) = params.stiffness
    wx, wy = x + params.offset[0], y + params.offset[1]
    quadratic = sxx * wx * wx + (sxy + syx) * wx * wy + syy * wy * wy
    return 0.5 * quadratic - (params.load[0] * wx + params.load[1] * wy)


def cross_coupling_power(
    x: FloatOrArray, y: FloatOrArray, vx: FloatOrArray, vy: FloatOrArray,
    params: model.ModelParams,
) -> FloatOrArray:  # fmt: skip
    """The cross-coupled stiffness's power on the rotor, ``-w'^T S_anti w`` with
    ``S_anti = q [[0, 1], [-1, 0]]``, ``q = (k_xy - k_yx) / 2``: positive in a forward
    whirl when q > 0 (it feeds the whirl; docs/machines.md)."""
    (_, sxy), (syx, _) = params.stiffness
    q = 0.5 * (sxy - syx)
    wx, wy = x + params.offset[0], y + params.offset[1]
    return q * (vy * wx - vx * wy)


# ---------------------------------------------------------------------------- quadrature


def _node_powers_and_rates(tau: np.ndarray, states: np.ndarray, params, regime: int):
    """The powers ``P`` at the nodes and their rates ``P'`` (both shape (n, N_TERMS)): central
    differences of the powers along the motion, ``s +- delta (v, a)``, with the
    accelerations of the piece's regime; ``delta`` is 1e-5 of the local node spacing.
    The absolute-value columns (scales only) get no rate."""
    h = np.diff(tau)
    P = powers(tau, states, params, regime)
    rate = np.column_stack((states[:, 2:], accelerations(tau, states, params, regime)))
    spacing = np.minimum(np.append(h, np.inf), np.insert(h, 0, np.inf))
    delta = (DERIVATIVE_STEP * spacing)[:, None]
    angle = params.eta * tau + params.phi0
    c, s = np.cos(angle), np.sin(angle)
    ca, sa = shift_rotation(params.eta * delta[:, 0])
    ahead, behind = (c * ca - s * sa, s * ca + c * sa), (c * ca + s * sa, s * ca - c * sa)
    forward = powers(tau + delta[:, 0], states + delta * rate, params, regime, ahead)
    backward = powers(tau - delta[:, 0], states - delta * rate, params, regime, behind)
    dP = (forward - backward) / (2.0 * delta)
    dP[:, [W_ABS_IN, W_ABS_FRIC, W_ABS_CROSS]] = 0.0
    return P, dP


def shift_rotation(a: FloatOrArray) -> tuple[np.ndarray, np.ndarray]:
    """(cos a, sin a) for the phase shift ``a = eta delta`` of the central differences:
    the phase at ``tau +- delta`` is the node's rotated by ``+-a`` (exact to round-off,
    where ``eta (tau +- delta) + phi0`` would lose ``|eta tau| eps`` of ``a`` late in a
    long run), by the Taylor series when ``a < 1e-4`` (its next terms are below 1e-17)."""
    small = np.abs(a) < SMALL_SHIFT
    ca = np.where(small, 1.0 - 0.5 * a * a, np.cos(a))
    sa = np.where(small, a * (1.0 - a * a / 6.0), np.sin(a))
    return ca, sa


def _corrected_trapezoid(tau: np.ndarray, P: np.ndarray, dP: np.ndarray) -> np.ndarray:
    """Integrals over each interval [tau_k, tau_k+1] (shape (n - 1, N_TERMS)) of the cubic
    Hermite interpolant of each power: ``h/2 (P_k + P_k+1) + h^2/12 (P'_k - P'_k+1)``
    (for the absolute-value columns, whose rates are zero, the plain trapezoid rule)."""
    h = np.diff(tau)
    return 0.5 * h[:, None] * (P[:-1] + P[1:]) + (h * h / 12.0)[:, None] * (dP[:-1] - dP[1:])


def _coarse_estimate(piece: Piece, fine: np.ndarray, P: np.ndarray, dP: np.ndarray) -> np.ndarray:
    """Estimated quadrature error of a piece's integrals (N_TERMS columns), see module docstring:
    the rule on every other node (and the last), with the same nodal powers and rates."""
    n = piece.tau.size
    if n >= 3:
        keep = np.arange(0, n, 2)
        if keep[-1] != n - 1:
            keep = np.append(keep, n - 1)
        coarse = _corrected_trapezoid(piece.tau[keep], P[keep], dP[keep])
        return np.abs(fine.sum(axis=0) - coarse.sum(axis=0)) / RICHARDSON_FACTOR
    trapezoid = 0.5 * (P[0] + P[1]) * (piece.tau[1] - piece.tau[0])
    return np.abs(fine.sum(axis=0) - trapezoid)


def _balance_combination(integrals: np.ndarray) -> np.ndarray:
    """W_in - D_damp - D_fric + W_cross from integral columns (D_fric = -int P_fric)."""
    return (
        integrals[..., W_IN]
        - integrals[..., W_DAMP]
        + integrals[..., W_FRIC]
        + integrals[..., W_CROSS]
    )


def _kernel_inputs(solution: Solution):
    from rubcli.analysis.energy.regimes import piece_bounds
    from rubcli.solvers.compiled import ensure_fresh

    ensure_fresh()  # the kernel's cached copy follows model.py's record

    b = piece_bounds(solution)
    t = np.ascontiguousarray(solution.t, dtype=float)
    states = np.ascontiguousarray(solution.states, dtype=float)
    params = solution.problem.params
    pv = np.array([*model.params_vector(params), DERIVATIVE_STEP, SMALL_SHIFT, *params.offset,
                   *params.load])  # fmt: skip
    return b, (t, states, b.regime, b.start_tau, b.start_state, b.end_tau, b.end_state,
               b.lo, b.hi, pv)  # fmt: skip


def _pass(solution: Solution, cum: np.ndarray, energies: np.ndarray):
    from rubcli.analysis.energy.kernel import balance_pass

    bounds, args = _kernel_inputs(solution)
    running, quad_sum, first, last, largest = balance_pass(*args, cum, energies)
    throughput = float(
        running[W_ABS_IN] + running[W_DAMP] + running[W_ABS_FRIC] + running[W_ABS_CROSS] + largest
    )
    quad = quad_sum / throughput if throughput > 0.0 else 0.0
    return running, float(first), float(last), throughput, float(quad), bounds.size


@dataclass(frozen=True)
class EnergyTotals:
    """The totals of the energy balance over the span, without the series (bounded memory:
    ``energy_totals``). ``summary()`` equals ``EnergyBalance.summary()`` of the same run."""

    energy_first: float
    energy_last: float
    work_unbalance: float
    damping: float
    friction: float
    contact_dissipation: float
    spin_drive: float
    throughput: float
    quadrature_error: float
    n_pieces: int = 0
    cross_coupling: float = 0.0

    @property
    def relative_residual(self) -> float:
        if self.n_pieces == 0:
            return 0.0
        delta = self.energy_last - self.energy_first
        gained = self.work_unbalance - self.damping - self.friction + self.cross_coupling
        final = abs(delta - gained)
        if self.throughput > 0.0:
            return final / self.throughput
        return 0.0 if final == 0.0 else float("inf")

    def summary(self) -> dict[str, float]:
        """Totals over the span, for reports (``EnergyBalance.summary``)."""
        if self.n_pieces == 0:
            return {"energy_residual": 0.0, "energy_quadrature_error": 0.0}
        return {
            "energy_residual": self.relative_residual,
            "energy_quadrature_error": self.quadrature_error,
            "energy_change": self.energy_last - self.energy_first,
            "work_unbalance": self.work_unbalance,
            "damping_dissipation": self.damping,
            "friction_dissipation": self.friction,
            "contact_dissipation": self.contact_dissipation,
            "spin_drive_work": self.spin_drive,
            **_cross_entry(self.cross_coupling),
            "energy_throughput": self.throughput,
        }


def energy_totals(solution: Solution) -> EnergyTotals:
    """The totals of the energy balance, in one compiled pass over the samples that keeps
    no per-sample array (a 10-million-sample run needs no more memory than its solution)."""
    if solution.t.size == 0:
        return EnergyTotals(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    running, first, last, throughput, quad, n_pieces = _pass(
        solution, np.zeros((0, N_TERMS)), np.zeros((0, 3))
    )
    return EnergyTotals(
        energy_first=first,
        energy_last=last,
        work_unbalance=float(running[W_IN]),
        damping=float(running[W_DAMP]),
        friction=float(-running[W_FRIC]),
        contact_dissipation=float(running[W_SLIP]),
        spin_drive=float(running[W_SPIN]),
        throughput=throughput,
        quadrature_error=quad,
        n_pieces=n_pieces,
        cross_coupling=float(running[W_CROSS]),
    )


def energy_balance(solution: Solution) -> EnergyBalance:
    """The energy balance of a solution, integrated piecewise between its events.

    One compiled pass (``analysis.energy.kernel``); the series take 10 floats per node.
    For the totals alone, ``energy_totals`` keeps none.
    """
    if solution.t.size == 0:
        empty = np.zeros(0)
        return EnergyBalance(
            empty, empty, empty, empty, empty, empty, empty, empty, empty, 0.0, 0.0
        )
    bounds, args = _kernel_inputs(solution)
    nodes = bounds.n_nodes
    cum = np.empty((nodes, N_TERMS))
    energies = np.empty((nodes, 3))
    from rubcli.analysis.energy.kernel import balance_pass

    running, quad_sum, _, _, largest = balance_pass(*args, cum, energies)
    throughput = float(
        running[W_ABS_IN] + running[W_DAMP] + running[W_ABS_FRIC] + running[W_ABS_CROSS] + largest
    )
    tau = np.empty(nodes)
    offset = 0
    t = args[0]
    for p in range(bounds.size):
        lo, hi = int(bounds.lo[p]), int(bounds.hi[p])
        n = hi - lo + 2
        tau[offset] = bounds.start_tau[p]
        tau[offset + 1 : offset + n - 1] = t[lo:hi]
        tau[offset + n - 1] = bounds.end_tau[p]
        offset += n
    return _balance(
        tau, energies[:, 0], energies[:, 1], energies[:, 2], cum, throughput, quad_sum,
        bounds.size,
    )  # fmt: skip


def energy_balance_numpy(solution: Solution) -> EnergyBalance:
    """``energy_balance`` computed on whole arrays with numpy, piece by piece (the Python
    path: the reference the compiled one-pass core is tested against; it holds several
    arrays of (samples, N_TERMS) at once)."""
    params = solution.problem.params
    pieces = solution_pieces(solution)
    taus, states, regimes, cumulative = [], [], [], []
    running = np.zeros(N_TERMS)
    quad_error = 0.0
    for piece in pieces:
        P, dP = _node_powers_and_rates(piece.tau, piece.states, params, piece.regime)
        fine = _corrected_trapezoid(piece.tau, P, dP)
        quad_error += abs(float(_balance_combination(_coarse_estimate(piece, fine, P, dP))))
        sums = running + np.vstack((np.zeros(N_TERMS), np.cumsum(fine, axis=0)))
        taus.append(piece.tau)
        states.append(piece.states)
        regimes.append(np.full(piece.tau.size, piece.regime))
        cumulative.append(sums)
        running = sums[-1]
    if not pieces:
        empty = np.zeros(0)
        return EnergyBalance(
            empty, empty, empty, empty, empty, empty, empty, empty, empty, 0.0, 0.0
        )
    tau = np.concatenate(taus)
    S = np.vstack(states)
    cum = np.vstack(cumulative)
    kinetic, spring, stator = mechanical_energy(S, params, np.concatenate(regimes))
    energy = kinetic + spring + stator
    throughput = float(
        running[W_ABS_IN]
        + running[W_DAMP]
        + running[W_ABS_FRIC]
        + running[W_ABS_CROSS]
        + np.max(np.abs(energy))
    )
    return _balance(tau, kinetic, spring, stator, cum, throughput, quad_error, len(pieces))


def _balance(tau, kinetic, spring, stator, cum, throughput, quad_sum, n_pieces) -> EnergyBalance:
    """The balance from the mechanical energies at the nodes and the cumulative integrals
    of the power columns (``cum``, columns ``W_IN`` ... ``W_ABS_FRIC``): both paths'."""
    return EnergyBalance(
        tau=tau,
        kinetic=kinetic,
        rotor_spring=spring,
        stator=stator,
        work_unbalance=cum[:, W_IN],
        damping=cum[:, W_DAMP],
        friction=-cum[:, W_FRIC],
        contact_dissipation=cum[:, W_SLIP],
        spin_drive=cum[:, W_SPIN],
        throughput=throughput,
        quadrature_error=quad_sum / throughput if throughput > 0.0 else 0.0,
        n_pieces=n_pieces,
        cross_coupling=cum[:, W_CROSS],
    )


def energy_residual(solution: Solution) -> float:
    """``energy_residual`` of a solution: |Delta E - (W_in - D_damp - D_fric)| / throughput."""
    return energy_balance(solution).relative_residual

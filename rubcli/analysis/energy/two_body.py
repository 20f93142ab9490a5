"""The energy balance of a stator with its own mass (``rubcli.stator``).

With ``w = d + s + c`` the rotor's position from its support's centre, the energy::

    E = |w'|^2/2 + w^T S_sym w/2 - g . w + m_s |s'|^2/2 + s^T diag(k_s) s/2 + K (z - 1)^2/2

(the last term in contact) changes by the unbalance's power ``f_u . w'``, the damping's
``-2 w'^T D_sym w' - 2 s'^T diag(n_s) s'``, the cross-coupling's ``-w'^T S_anti w`` and
the friction's on the relative motion, ``-T d' . t``: the rub's tangential force ``-T t``
on the rotor and ``T t`` on the stator. Split as ``-T v_r`` (the contact's dissipation)
plus ``T Rp eta`` (what the spin, held at its speed, supplies to the rubbing surfaces);
zero in free flight, ``d' . t = -Rp eta`` in stick.

The friction's power jumps at a slip reversal and where stick begins or ends, so every
power is integrated piece by piece between the located events (each event's full state
is the run's, ``Solution.stator_events``), by the rule of ``analysis.energy.balance``: the cubic
Hermite interpolant of each power between two nodes, ``h/2 (P_k + P_k+1) + h^2/12 (P'_k
- P'_k+1)``, order 4. A power is a function of the state alone (the phase is a state),
so its rate is its derivative along the flow, a central difference of step ``RATE_STEP``
along the state's derivative. The rule's own share is estimated by the rule on every
other node of each piece (over 15): ``energy_quadrature_error``. ``energy_residual =
|Delta E - W| / throughput`` with the throughput the sum of the works' magnitudes plus
the largest energy stored.
"""

from __future__ import annotations

import numpy as np

from rubcli import model
from rubcli.solution import Solution

TERMS = ("unbalance", "damping", "cross_coupling", "friction", "contact", "spin")
RATE_STEP = 1e-5  # of the powers' central differences along the flow, in tau
RICHARDSON = 15.0  # an order-4 rule's error is its change on halving the nodes over 15


def _machine(params: model.ModelParams):
    S = np.array(params.stiffness)
    D = np.array(params.damping_matrix)
    return S, D, np.array(params.offset), np.array(params.load)


def energy_at(params: model.ModelParams, states: np.ndarray) -> np.ndarray:
    """The two bodies' energy at the ten states in the columns of ``states`` (10, n)."""
    S, _, c, g = _machine(params)
    st = params.stator
    x, y, vx, vy, _, _, u, v, up, vp = states
    wx, wy = x + u + c[0], y + v + c[1]
    wvx, wvy = vx + up, vy + vp
    sym = 0.5 * (S + S.T)
    z = np.hypot(x, y)
    contact = np.where(z > 1.0, 0.5 * params.K * (z - 1.0) ** 2, 0.0)
    rotor = (
        0.5 * (wvx**2 + wvy**2)
        + 0.5 * (sym[0, 0] * wx * wx + 2.0 * sym[0, 1] * wx * wy + sym[1, 1] * wy * wy)
        - (g[0] * wx + g[1] * wy)
    )
    (kx, ky) = st.stiffness
    ring = 0.5 * st.mass * (up**2 + vp**2) + 0.5 * (kx * u * u + ky * v * v)
    return rotor + ring + contact


def powers_at(params: model.ModelParams, states: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The powers (``TERMS``, rows) at the ten states in the columns of ``states`` (10, n),
    with the rub's tangential force T (n,): unbalance, damping (dissipated, positive),
    cross-coupling, friction (on the relative motion), and its parts contact (``T v_r``,
    dissipated) and spin (``T Rp eta``)."""
    S, D, c, _ = _machine(params)
    st = params.stator
    x, y, vx, vy, p, w, u, v, up, vp = states
    wx, wy = x + u + c[0], y + v + c[1]
    wvx, wvy = vx + up, vy + vp
    f = params.e * w * w
    unbalance = f * (np.cos(p) * wvx + np.sin(p) * wvy)
    sym = 0.5 * (D + D.T)
    damping = 2.0 * (sym[0, 0] * wvx**2 + 2.0 * sym[0, 1] * wvx * wvy + sym[1, 1] * wvy**2)
    damping = damping + 2.0 * (st.damping[0] * up**2 + st.damping[1] * vp**2)
    q = 0.5 * (S[0, 1] - S[1, 0])  # S_anti = q [[0, 1], [-1, 0]]
    cross = -(wvx * q * wy - wvy * q * wx)
    z = np.hypot(x, y)
    whirl = np.where(z > 0.0, (x * vy - y * vx) / np.where(z > 0.0, z, 1.0), 0.0)
    spin = T * params.Rp * w
    contact = T * (params.Rp * w + whirl)
    return np.vstack([unbalance, damping, cross, -T * whirl, contact, spin])


def _hermite(t: np.ndarray, P: np.ndarray, dP: np.ndarray) -> np.ndarray:
    """The integrals of the powers P (rows) over the nodes t by the cubic Hermite rule."""
    h = np.diff(t)
    return np.sum(0.5 * h * (P[:, :-1] + P[:, 1:]) + h * h / 12.0 * (dP[:, :-1] - dP[:, 1:]),
                  axis=1)  # fmt: skip


def _coarse(t: np.ndarray, P: np.ndarray, dP: np.ndarray) -> np.ndarray:
    """The rule on every other node (and the last)."""
    keep = np.arange(0, t.size, 2)
    if keep[-1] != t.size - 1:
        keep = np.append(keep, t.size - 1)
    return _hermite(t[keep], P[:, keep], dP[:, keep])


def pieces(solution: Solution) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """The run's smooth pieces ``(regime, tau, states (10, n))``, each from an event (or
    the first sample) through the samples inside it to the next event (or the last
    sample), with the events' full states."""
    from rubcli.solvers.two_body import full_states

    p = solution.problem.params
    t = solution.t
    if t.size == 0:
        return []
    S = full_states(solution)
    events = solution.events.until(float(t[-1]))
    m = len(events)
    E = np.vstack([events.state.T, p.eta * events.tau + p.phi0, np.full(m, p.eta),
                   solution.stator_events[:m].T])  # fmt: skip
    starts = np.concatenate((t[:1], events.tau))
    ends = np.concatenate((events.tau, t[-1:]))
    first = np.hstack([S[:, :1], E])
    last = np.hstack([E, S[:, -1:]])
    regimes = np.concatenate((solution.regimes[:1], events.regime_after))
    out = []
    for i in range(m + 1):
        if not ends[i] > starts[i]:
            continue
        lo = int(np.searchsorted(t, starts[i], side="right"))
        hi = int(np.searchsorted(t, ends[i], side="left"))
        tau = np.concatenate(([starts[i]], t[lo:hi], [ends[i]]))
        states = np.hstack([first[:, i : i + 1], S[:, lo:hi], last[:, i : i + 1]])
        out.append((int(regimes[i]), tau, states))
    return out


def two_body_energy_summary(solution: Solution) -> dict[str, float]:
    """The balance's totals over the run, for report.json (module docstring)."""
    from rubcli.solvers.compiled.two_body import two_body_columns

    params = solution.problem.params
    if solution.t.size < 3:
        return {"energy_residual": 0.0, "energy_quadrature_error": 0.0}
    pars = np.array(model.params_vector(params))
    record = params.stator.record()

    def powers(S: np.ndarray, regime: int) -> tuple[np.ndarray, np.ndarray]:
        dS, T = two_body_columns(np.ascontiguousarray(S), pars, record, regime)
        return powers_at(params, S, T), dS

    fine, coarse, magnitude = np.zeros(len(TERMS)), np.zeros(len(TERMS)), np.zeros(len(TERMS))
    for regime, tau, states in pieces(solution):
        P, dS = powers(states, regime)
        ahead, behind = powers(states + RATE_STEP * dS, regime)[0], powers(
            states - RATE_STEP * dS, regime)[0]  # fmt: skip
        dP = (ahead - behind) / (2.0 * RATE_STEP)
        fine += _hermite(tau, P, dP)
        coarse += _coarse(tau, P, dP)
        magnitude += _hermite(tau, np.abs(P), np.zeros_like(P))
    energy = energy_at(params, _full(solution))
    change = float(energy[-1] - energy[0])

    def net(works: np.ndarray) -> float:
        return float(works[0] - works[1] + works[2] + works[3])

    throughput = float(np.sum(magnitude[:4]) + np.max(np.abs(energy)))
    names = dict(zip(TERMS, fine.tolist(), strict=True))
    return {
        "energy_residual": abs(change - net(fine)) / throughput,
        "energy_quadrature_error": abs(net(fine) - net(coarse)) / RICHARDSON / throughput,
        "energy_change": change,
        "work_unbalance": names["unbalance"],
        "damping_dissipation": names["damping"],
        "friction_dissipation": -names["friction"],
        "contact_dissipation": names["contact"],
        "spin_drive_work": names["spin"],
        **({"cross_coupling_work": names["cross_coupling"]} if names["cross_coupling"] else {}),
        "energy_throughput": throughput,
    }


def _full(solution: Solution) -> np.ndarray:
    from rubcli.solvers.two_body import full_states

    return full_states(solution)

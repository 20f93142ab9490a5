"""What a run's samples mean: each station's penetration, slip and forces, and the energy
balance, asked of the system (``kernels.evaluate``), not written again."""

from __future__ import annotations

import numpy as np

from rubcli.machine.contact import stored_energy
from rubcli.solvers.compiled.jit import jit
from rubcli.system.arrays import SystemArrays
from rubcli.system.kernels import C_REGIMES, VALUES_SIZE, evaluate
from rubcli.system.solution import MachineSolution


@jit
def _series(t, states, work, sample_regimes, ctx, values, y, out):
    regimes = ctx[C_REGIMES]
    m = states.shape[1]
    for k in range(t.shape[0]):
        for s in range(regimes.shape[0]):
            regimes[s] = sample_regimes[k, s]
        for i in range(m):
            y[i] = states[k, i]
        y[m] = work[k]
        evaluate(t[k], y, ctx, out, values[k])


def station_series(solution: MachineSolution) -> np.ndarray:
    """(k, S, 4): at each sample and station the penetration ``z - clearance``, the slip
    ``v_r``, the normal force and the tangential force (``kernels.V_*``)."""
    arrays = SystemArrays.of(solution.machine)
    S = arrays.indices.shape[0]
    ctx = arrays.context(np.zeros(S, dtype=np.int64))
    values = np.zeros((solution.t.size, S, VALUES_SIZE))
    y = np.empty(arrays.size)
    out = np.empty(arrays.size)
    states = np.ascontiguousarray(solution.states)
    regimes = np.ascontiguousarray(solution.regimes)
    _series(solution.t, states, np.ascontiguousarray(solution.work), regimes, ctx, values, y, out)
    return values


def energy(solution: MachineSolution, penetration: np.ndarray | None = None) -> np.ndarray:
    """The mechanical energy ``v^T M v / 2 + q^T K_sym q / 2 - f_static . q`` plus each
    station's stored contact energy, at each sample (k,)."""
    machine = solution.machine
    st = machine.structure
    n = st.size
    q, v = solution.states[:, :n], solution.states[:, n:]
    K_sym = 0.5 * (st.K + st.K.T)
    E = 0.5 * np.einsum("ki,ij,kj->k", v, st.M, v) + 0.5 * np.einsum("ki,ij,kj->k", q, K_sym, q)
    E -= q @ st.static
    if penetration is None:
        penetration = station_series(solution)[:, :, 0]
    for s, station in enumerate(machine.stations):
        E += _stored_energy(station.law.record()[None, :], np.ascontiguousarray(penetration[:, s]))
    return E


@jit
def _stored_energy(law: np.ndarray, penetration: np.ndarray) -> np.ndarray:
    """The law's stored energy at each penetration (``contact.stored_energy``)."""
    out = np.empty(penetration.shape[0])
    for k in range(penetration.shape[0]):
        out[k] = stored_energy(law, 0, 0, penetration[k])
    return out


def energy_residual(solution: MachineSolution) -> np.ndarray:
    """``E(t) - E(t0) - W(t)`` at each sample: the energy balance's residual (the work
    ``W`` of the unbalance, the damping, the cross-coupling, contact damping and
    friction integrated with the run, ``kernels.evaluate``)."""
    E = energy(solution)
    return E - E[0] - (solution.work - solution.work[0])

"""The regime-locked right-hand side (``model.rhs_record``) compiled: for scipy's
solvers (one state, a column of states, the Jacobian) and for the compiled DOP853.
"""

from __future__ import annotations

import numpy as np

from rubcli.model import (
    P_E,
    P_ETA,
    P_K,
    P_MU,
    P_NU,
    P_PHI0,
    P_RP,
    is_paper_record,
    rhs_entries,
    rhs_jacobian_record,
    rhs_record,
)
from rubcli.solvers.compiled.jit import (
    jit,
)


@jit
def _rhs_paper_into(t, y, pars, regime, out):
    """The paper's machine at a constant speed: ``model.rhs_entries`` with rate = 0
    folded in and nothing added. The record is unpacked here, not through
    ``model.rhs_record``: one call level less in DOP853's stages, which LLVM then inlines
    whole. (``dop853-jit``'s loop on the paper's machine is built on it: the general
    machine's terms behind a branch in the stages cost the paper's case about 10 %.)"""
    nu, eta, E, phi0 = pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0]
    K, mu, Rp = pars[P_K], pars[P_MU], pars[P_RP]
    vx, vy, ax, ay = rhs_entries(t, y[0], y[1], y[2], y[3], nu, eta, E, phi0, K, mu, Rp, regime)
    out[0], out[1], out[2], out[3] = vx, vy, ax, ay


@jit
def _rhs_into(t, y, pars, regime, out):
    """Any machine and speed: ``_rhs_paper_into`` on the paper's machine at a constant
    speed, else ``model.rhs_record``."""
    if is_paper_record(pars):
        _rhs_paper_into(t, y, pars, regime, out)
    else:
        vx, vy, ax, ay = rhs_record(t, y[0], y[1], y[2], y[3], pars, regime)
        out[0], out[1], out[2], out[3] = vx, vy, ax, ay


@jit
def rhs(t: float, s: np.ndarray, pars: np.ndarray, regime: int) -> np.ndarray:
    """``model.rhs`` compiled: the regime-locked right-hand side (pars = params_vector)."""
    out = np.empty(4)
    _rhs_into(t, s, pars, regime, out)
    return out


@jit
def rhs_columns(t: np.ndarray, S: np.ndarray, pars: np.ndarray, regime: int) -> np.ndarray:
    """``rhs`` for the states in the columns of S (4, n) at the times t (n,)."""
    out = np.empty_like(S)
    for k in range(S.shape[1]):
        out[:, k] = rhs(t[k], np.ascontiguousarray(S[:, k]), pars, regime)
    return out


@jit
def rhs_jacobian(t: float, s: np.ndarray, pars: np.ndarray, regime: int) -> np.ndarray:
    """``model.rhs_jacobian`` compiled."""
    return rhs_jacobian_record(t, s[0], s[1], s[2], s[3], pars, regime)

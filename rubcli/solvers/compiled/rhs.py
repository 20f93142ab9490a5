"""The regime-locked right-hand side (``model.rhs_entries``) compiled: for scipy's
solvers (one state, a column of states, the Jacobian) and for the compiled DOP853.
"""

from __future__ import annotations

import numpy as np

from rubcli.model import rhs_jacobian_record, rhs_record
from rubcli.solvers.compiled.jit import (
    jit,
)


@jit
def _rhs_into(t, y, pars, regime, out):
    vx, vy, ax, ay = rhs_record(t, y[0], y[1], y[2], y[3], pars, regime)
    out[0], out[1], out[2], out[3] = vx, vy, ax, ay


@jit
def rhs(t, s, pars, regime):
    """``model.rhs`` compiled: the regime-locked right-hand side (pars = params_vector)."""
    out = np.empty(4)
    _rhs_into(t, s, pars, regime, out)
    return out


@jit
def rhs_columns(t, S, pars, regime):
    """``rhs`` for the states in the columns of S (4, n) at the times t (n,)."""
    out = np.empty_like(S)
    for k in range(S.shape[1]):
        out[:, k] = rhs(t[k], np.ascontiguousarray(S[:, k]), pars, regime)
    return out


@jit
def rhs_jacobian(t, s, pars, regime):
    """``model.rhs_jacobian`` compiled."""
    return rhs_jacobian_record(t, s[0], s[1], s[2], s[3], pars, regime)

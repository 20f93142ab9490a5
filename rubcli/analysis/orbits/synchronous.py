"""Existence and stability of the synchronous forward full annular rub (notes section 5).

On the synchronous rub the rotor whirls forward in permanent contact, ``w = A exp(i eta
tau)`` with ``|A| = r > 1`` (``model.synchronous_rub``). In the frame rotating with the
forcing, ``u = w exp(-i eta tau)``, the orbit is an equilibrium ``u* = A`` of the
autonomous equation (slip positive, ``mu_c = +mu``)

    u'' + 2 (nu + i eta) u' + (1 - eta^2 + 2 i nu eta) u + K (1 - 1/|u|)(1 + i mu) u
        = E exp(i phi0),

because the contact force commutes with rotations. Its stability is that of the
equilibrium: the eigenvalues of the 4x4 Jacobian in the real variables
``(Re u, Im u, Re u', Im u')``. A root with positive real part means the orbit is
unstable (for ``mu > 0`` this is the friction-induced instability of the notes,
correction 5); the orbit is then exact but not observed in a simulation that starts
anywhere else. The Jacobian of the contact force is ``model.force_jacobian``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rubcli import model
from rubcli.model import ModelParams

if TYPE_CHECKING:
    from numpy.typing import ArrayLike


def _complex_matrix(c: complex) -> np.ndarray:
    """The real 2x2 matrix of multiplication by the complex number c."""
    return np.array([[c.real, -c.imag], [c.imag, c.real]])


def rotating_frame_jacobian(
    u: complex, params: ModelParams, mu_c: float, rate: float | None = None
) -> np.ndarray:
    """Jacobian of the contact equation at the point u in the frame rotating at ``rate``
    (default the running speed ``params.eta``; a whirl of its own rate passes that, of
    either sign) (module docstring)."""
    eta = params.eta if rate is None else rate
    nu = params.nu
    stiffness = _complex_matrix(complex(1.0 - eta**2, 2.0 * nu * eta))
    stiffness = stiffness + params.K * model.force_jacobian(u.real, u.imag, mu_c)
    jac = np.zeros((4, 4))
    jac[0, 2] = jac[1, 3] = 1.0
    jac[2:, :2] = -stiffness
    jac[2:, 2:] = -_complex_matrix(complex(2.0 * nu, 2.0 * eta))
    return jac


@dataclass(frozen=True)
class SynchronousRub:
    """One synchronous full annular rub and its stability."""

    r: float  # whirl radius, clearances
    amplitude: complex  # A in w = A exp(i eta tau)
    forward_slip: bool  # v_r = (Rp + r) eta > 0, so mu_c = +mu holds on it
    eigenvalues: np.ndarray = field(repr=False)  # rotating-frame linearisation
    growth_rate: float = 0.0  # largest real part of the eigenvalues

    @property
    def stable(self) -> bool:
        return self.growth_rate < 0.0

    def to_dict(self) -> dict:
        return {
            "r": self.r,
            "amplitude": [self.amplitude.real, self.amplitude.imag],
            "forward_slip": self.forward_slip,
            "stable": self.stable,
            "growth_rate": self.growth_rate,
            "eigenvalues": [[float(v.real), float(v.imag)] for v in self.eigenvalues],
        }


def synchronous_rubs(params: ModelParams) -> list[SynchronousRub]:
    """Every synchronous forward rub of these parameters (r > 1), with its stability. The
    closed form is the paper machine's (a concentric stator, an isotropic support, no
    load): on the general machine there is none, and the list is empty."""
    if not params.is_paper_machine:
        return []
    out = []
    for r in model.synchronous_rub_radii(params):
        amplitude = model.synchronous_rub_amplitude(r, params)
        forward = model.synchronous_rub_is_forward(r, params)
        eig = np.linalg.eigvals(rotating_frame_jacobian(amplitude, params, params.mu))
        out.append(SynchronousRub(r, amplitude, forward, eig, float(np.max(eig.real))))
    return out


def started_on_synchronous_rub(
    params: ModelParams, initial: ArrayLike, tau0: float = 0.0, rel_tol: float = 1e-12
) -> SynchronousRub | None:
    """The synchronous rub whose state at ``tau0`` is ``initial`` (within rel_tol), or None."""
    state = np.asarray(initial, dtype=float)
    for rub in synchronous_rubs(params):
        if not rub.forward_slip:
            continue
        exact = model.synchronous_rub(np.array([tau0]), params, rub.r)[:, 0]
        if np.max(np.abs(state - exact)) <= rel_tol * max(1.0, float(np.max(np.abs(exact)))):
            return rub
    return None

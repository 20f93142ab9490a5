"""``analytic`` on a composed machine: the structure's free flight exact, the station
forces expanded about each step's start.

At a constant speed ``Omega`` a machine with every station free is linear,
``y' = A y + b + Re(F exp(i Omega t))`` on its ``2 n`` mechanical states (the structure,
its bearings' coefficients at that speed, gyroscopic terms, static force, unbalances).
``FreeFlow`` takes ``A``, ``b`` and ``F`` from the one system itself (``kernels.rhs_into``
with every station free: its columns, and its forcing at three instants, checked at a
fourth), so no equation of motion is written again here, and decomposes
``A = V diag(lambda) V^-1`` once a run. Every step is then a closed form in the modal
coordinates ``w = V^-1 y``:

    w(s) = e^{lambda s} w0 + s phi_1(lambda s) (b^ + c0^) + s^2 phi_2(lambda s) c1^
           + sum_+- e^{+-i Omega (t0 + s)} s phi_1((lambda -+ i Omega) s) F^_+-

with ``phi_k`` the exponential integrator's functions, ``F^_+ = V^-1 F / 2``,
``F^_- = V^-1 conj(F) / 2``, and ``c0 + c1 s`` the station forces (their acceleration,
contact, friction and stick, ``N = rhs - rhs with every station free``) expanded to
first order in time along the flow about the step's start (``c1`` a forward difference
along ``y'``). Free flight (``c = 0``) is exact for all time, whatever the structure's
stiffest mode: no stability limit, so a finite-element model's stiff modes cost nothing
but their resolution while they are excited. In contact the force's expansion leaves a
local error ``O(h^3)``: global order 2, as the paper's method (whose expansion is in the
state, which needs an eigen-decomposition every step; this one needs none, a step costs
``O(n^2)``). The contact steps are chosen by step doubling to ``rtol``/``atol`` on the
mechanical states (the two half steps kept); stations in stick have their velocities put
back onto rolling at each step's end (``evaluate``'s projection).

Resolution: each step is at most 1/8 of the period ``2 pi / rho`` of the fastest motion
still present, ``rho`` the largest of ``Omega`` and the ``|lambda|`` of the modes whose
free amplitudes at the stations (their homogeneous part, in clearances, velocities over
``clearance Omega``) add up to more than ``rtol`` from the fastest down; the event scan
is at each step's quarters (1/32 of that period), as the other methods'. So a touch the
scan may miss is shallower than ``rtol`` clearances plus what a quarter step hides of
the resolved motion. The work ``W`` is a quadrature of the system's own power along the
closed form from the step's start: 8-point Gauss-Legendre, bisected until two halves
agree with their whole to rounding (the power has a kink where a damped contact force
stops pulling).
"""

from __future__ import annotations

import cmath
import math

import numpy as np

from rubcli.cached_jit import njit
from rubcli.solvers.compiled.jit import jit
from rubcli.system.arrays import SystemArrays
from rubcli.system.kernels import rhs_into

inline = njit(nogil=True, _nrt=False, inline="always")

STEPS_PER_PERIOD = 8  # steps per period of the fastest motion present (scan: 4 a step)
SERIES_RADIUS = 1.0  # |z| below which phi_k is summed as its series
SERIES_TERMS = 18
CONDITION_LIMIT = 1e12  # the eigenbasis' condition number beyond which a run is refused
FORCING_RTOL = 1e-9  # the forcing's check: one harmonic at the speed and a constant
SAFETY, GROW, SHRINK = 0.9, 4.0, 0.2  # step doubling's control
GAUSS_NODES, GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(8)
WORK_RTOL, WORK_DEPTH = 1e-12, 30  # the work's quadrature: halves that agree; bisections


class AnalyticError(Exception):
    """A machine or a state ``analytic`` cannot run, with the reason."""


INVERSE_FACTORIALS = np.array([1.0 / math.factorial(k) for k in range(SERIES_TERMS + 5)])


@inline
def _phis(z: complex) -> tuple[complex, complex, complex, complex, complex]:
    """``e^z`` and ``phi_1..phi_4(z)``, ``phi_{k+1} = (phi_k - 1/k!) / z``; summed as
    ``sum_j z^j / (j + k)!`` where ``|z| < SERIES_RADIUS`` (the recurrence cancels)."""
    e = cmath.exp(z)
    if abs(z) < SERIES_RADIUS:
        p1 = INVERSE_FACTORIALS[SERIES_TERMS + 1] + 0j
        p2 = INVERSE_FACTORIALS[SERIES_TERMS + 2] + 0j
        p3 = INVERSE_FACTORIALS[SERIES_TERMS + 3] + 0j
        p4 = INVERSE_FACTORIALS[SERIES_TERMS + 4] + 0j
        for j in range(SERIES_TERMS - 1, -1, -1):
            p1 = p1 * z + INVERSE_FACTORIALS[j + 1]
            p2 = p2 * z + INVERSE_FACTORIALS[j + 2]
            p3 = p3 * z + INVERSE_FACTORIALS[j + 3]
            p4 = p4 * z + INVERSE_FACTORIALS[j + 4]
        return e, p1, p2, p3, p4
    p1 = (e - 1.0) / z
    p2 = (p1 - 1.0) / z
    p3 = (p2 - 0.5) / z
    return e, p1, p2, p3, (p3 - 1.0 / 6.0) / z


@jit
def modal_states(
    lam: np.ndarray, w0: np.ndarray, c: np.ndarray, f_plus: np.ndarray, f_minus: np.ndarray,
    omega: float, t0: float, taus: np.ndarray, out: np.ndarray,
) -> None:  # fmt: skip
    """The change of the modal coordinates from ``w0`` at each of ``taus`` (rows of
    ``out``) of a step from ``t0`` whose station forces are ``sum_k c[k] s^k`` (module
    docstring's closed form; ``e^z - 1 = z phi_1(z)``, so the change is exact to
    rounding at ``s`` small and 0 at ``s = 0``)."""
    for k in range(taus.shape[0]):
        s = taus[k] - t0
        turn = cmath.exp(1j * omega * taus[k])
        for j in range(lam.shape[0]):
            p1, p2, p3, p4 = _phis(lam[j] * s)[1:]
            value = s * (
                p1 * (lam[j] * w0[j] + c[0, j])
                + s * (p2 * c[1, j] + s * (2.0 * p3 * c[2, j] + 6.0 * s * p4 * c[3, j]))
            )
            if omega > 0.0:
                hp = _phis((lam[j] - 1j * omega) * s)[1]
                hm = _phis((lam[j] + 1j * omega) * s)[1]
                value += s * (turn * hp * f_plus[j] + hm * f_minus[j] / turn)
            out[k, j] = value


class FreeFlow:
    """The machine's free flight at its constant speed: ``A``, ``b``, ``F`` read from the
    system, ``A``'s eigen-decomposition, the forcing in modal coordinates, and which
    modes move the stations (module docstring)."""

    def __init__(self, arrays: SystemArrays, ctx_free: tuple, t0: float):
        n = arrays.Minv.shape[0]
        self.n = n
        size = 2 * n + 1
        self.omega = float(arrays.knots[0, 1])
        y = np.zeros(size)
        out = np.empty(size)

        def forcing(t: float) -> np.ndarray:
            rhs_into(t, y, ctx_free, 0, out)
            return out[: 2 * n].copy()

        g0 = forcing(t0)
        A = np.empty((2 * n, 2 * n))
        for j in range(2 * n):
            y[j] = 1.0
            rhs_into(t0, y, ctx_free, 0, out)
            A[:, j] = out[: 2 * n] - g0
            y[j] = 0.0
        w = self.omega
        r0, r_half, r_quarter = forcing(0.0), forcing(math.pi / w), forcing(0.5 * math.pi / w)
        b = 0.5 * (r0 + r_half)
        F = 0.5 * (r0 - r_half) + 1j * (b - r_quarter)
        t_check = 0.37 * 2.0 * math.pi / w
        expected = b + (F * np.exp(1j * w * t_check)).real
        scale = float(np.max(np.abs(b)) + np.max(np.abs(F))) or 1.0
        if np.max(np.abs(forcing(t_check) - expected)) > FORCING_RTOL * scale:
            raise AnalyticError(
                "the free structure's forcing is not a constant and one harmonic at the speed"
            )
        lam, V = np.linalg.eig(A)
        condition = np.linalg.cond(V)
        if not math.isfinite(condition) or condition > CONDITION_LIMIT:
            raise AnalyticError(
                f"the free structure's eigenbasis is ill-conditioned (condition number "
                f"{condition:.3g}): its modes are (nearly) defective"
            )
        Vinv = np.linalg.inv(V)
        self.A, self.lam, self.V, self.Vinv = A, lam, V, Vinv
        self.Vinv_acc = np.ascontiguousarray(Vinv[:, n:])
        self.b_hat = Vinv @ b
        self.f_plus = Vinv @ (0.5 * F)
        self.f_minus = Vinv @ (0.5 * np.conj(F))
        # the steady (particular) modal response, for the modes' free amplitudes
        self._steady_b = _safe_divide(-self.b_hat, lam)
        self._steady_p = _safe_divide(self.f_plus, 1j * w - lam)
        self._steady_m = _safe_divide(self.f_minus, -1j * w - lam)
        # each mode's size at the stations' coordinates, in clearances
        clearance = arrays.parameters[:, 2]
        rows, scales = [], []
        for s in range(arrays.indices.shape[0]):
            for c in arrays.indices[s]:
                if c >= 0:
                    rows += [c, n + c]
                    scales += [clearance[s], clearance[s] * max(w, 1.0)]
        self._station_modes = np.abs(V[rows, :]) / np.array(scales)[:, None]
        self._speed = np.abs(lam)
        self._order = np.argsort(-self._speed)

    def modal(self, y: np.ndarray) -> np.ndarray:
        return self.Vinv @ y[: 2 * self.n]

    def modal_forces(self, *accelerations: np.ndarray) -> np.ndarray:
        """(k, 2 n): the modal coordinates of the coefficients ``a_k`` of ``sum_k a_k s^k``,
        accelerations of the ``n`` coordinates."""
        return np.array(accelerations) @ self.Vinv_acc.T

    def fastest_rate(
        self, t: float, w: np.ndarray, tol: float, forces: np.ndarray | None = None
    ) -> float:
        """``rho``: the largest of the speed and the ``|lambda|`` of the fastest mode that,
        with every faster one, moves the stations by more than ``tol`` clearances, apart
        from its steady response to the forcing and to the station forces ``forces``
        (modal ``c0 + c1 s``: ``-c0 / lambda - c1 / lambda^2``, so a stiff mode that
        follows a contact force quasi-statically is not a motion to resolve)."""
        e = np.exp(1j * self.omega * t)
        free = w - self._steady_b - self._steady_p * e - self._steady_m / e
        if forces is not None:
            free += _safe_divide(forces[0], self.lam)
            free += _safe_divide(forces[1], self.lam**2)
        size = np.max(self._station_modes * np.abs(free)[None, :], axis=0)
        cumulative = np.cumsum(size[self._order])
        above = np.nonzero(cumulative > tol)[0]
        fastest = self._speed[self._order[above[0]]] if above.size else 0.0
        return max(self.omega, float(fastest))


def _safe_divide(a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``a / d``, 0 where ``d`` vanishes (a rigid or resonant mode: no steady part)."""
    small = np.abs(d) <= 1e-12 * max(float(np.max(np.abs(d))), 1.0)
    return np.where(small, 0.0, a / np.where(small, 1.0, d))


class Piece:
    """One closed-form step: from ``(t0, y0)`` (``y0`` with its work) over ``h``, with the
    station forces' expansion ``c0 + c1 s`` in modal coordinates (``None``: free)."""

    def __init__(self, flow: FreeFlow, t0: float, y0: np.ndarray, w0: np.ndarray, h: float,
                 forces: np.ndarray | None = None):  # fmt: skip
        self.flow, self.t0, self.y0, self.w0, self.h = flow, t0, y0, w0, h
        self.c = np.zeros((4, flow.lam.size), dtype=complex)
        if forces is not None:
            self.c[: forces.shape[0]] = forces
        self.c[0] += flow.b_hat
        self.t1 = t0 + h

    def states(self, taus: np.ndarray) -> np.ndarray:
        """(k, 2 n + 1): the state at each of ``taus``, with the start's work (for the
        event scan; ``Dense`` adds the work)."""
        f = self.flow
        taus = np.asarray(taus, dtype=float)
        modal = np.empty((taus.size, f.lam.size), dtype=complex)
        modal_states(f.lam, self.w0, self.c, f.f_plus, f.f_minus, f.omega, self.t0, taus, modal)
        out = np.empty((taus.size, self.y0.size))
        out[:, :-1] = self.y0[:-1] + (modal @ f.V.T).real
        out[:, -1] = self.y0[-1]
        return out

    def state(self, tau: float) -> np.ndarray:
        return self.states(np.array([tau]))[0]


class Dense:
    """The dense output of a step's pieces, with the work by quadrature of the system's
    power (``ctx``: the run's regimes) from each piece's start."""

    def __init__(self, pieces: list[Piece], ctx: tuple):
        self.pieces = pieces
        self.ctx = ctx
        self._out = np.empty(pieces[0].y0.size)

    def _piece(self, tau: float) -> Piece:
        for p in self.pieces:
            if tau <= p.t1:
                return p
        return self.pieces[-1]

    def state(self, tau: float) -> np.ndarray:
        return self._piece(tau).state(tau)

    def _gauss(self, piece: Piece, a: float, b: float) -> tuple[float, float]:
        """The power's integral over (a, b) and that of its size (the rounding's scale)."""
        nodes = a + 0.5 * (b - a) * (GAUSS_NODES + 1.0)
        total, size = 0.0, 0.0
        for ti, yi, weight in zip(nodes, piece.states(nodes), GAUSS_WEIGHTS, strict=True):
            rhs_into(ti, yi, self.ctx, 0, self._out)
            total += weight * self._out[-1]
            size += weight * abs(self._out[-1])
        return 0.5 * (b - a) * total, 0.5 * (b - a) * size

    def _integral(
        self, piece: Piece, a: float, b: float, whole: float, depth: int, before: float
    ) -> float:
        """The power's integral over (a, b), bisected while two halves disagree with the
        whole beyond rounding and the disagreement keeps falling (a kink inside: a
        contact force that stops pulling; ``before``: the parent's disagreement)."""
        m = 0.5 * (a + b)
        (left, left_size), (right, right_size) = self._gauss(piece, a, m), self._gauss(piece, m, b)
        halves = left + right
        change = abs(halves - whole)
        if (depth >= WORK_DEPTH or change <= WORK_RTOL * (left_size + right_size)
                or change > 0.5 * before):  # fmt: skip
            return halves
        return self._integral(piece, a, m, left, depth + 1, change) + self._integral(
            piece, m, b, right, depth + 1, change
        )

    def work(self, piece: Piece, tau: float) -> float:
        if tau <= piece.t0:
            return float(piece.y0[-1])
        whole = self._gauss(piece, piece.t0, tau)[0]
        return float(piece.y0[-1]) + self._integral(piece, piece.t0, tau, whole, 0, math.inf)

    def __call__(self, tau: float) -> np.ndarray:
        piece = self._piece(tau)
        y = piece.state(tau)
        y[-1] = self.work(piece, tau)
        return y

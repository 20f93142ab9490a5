"""Contact-force maps, the error of the first-order Taylor expansion, and contact eigenvalues.

Three analyses of the contact law (paper section 3.1 and Figure 2; model notes 2.5, 2.8):

``force_map``
    Figure 2 as the paper made it: on a square grid, the exact contact force, its
    first-order Taylor expansion evaluated *at its own expansion point*, and their
    difference. At its own point the expansion is exact by construction, so the
    difference is round-off (notes 2.8); the paper's "< 1e-10" says nothing about the
    expansion's accuracy.

``taylor_error``
    The error that matters for the analytic solver: the expansion about ``p0`` evaluated
    at ``p0 + delta d`` for a unit direction ``d``, as the rotor moves away from the point
    over one step. Maximum over a band of expansion points; see ``taylor_error`` for the
    exact definition of the radial, tangential and worst-case directions.

``eigen_map``
    Eigenvalues of the 4x4 first-order system of the linearised contact equation at each
    contact point of a grid, friction in the forward-spin direction (``mu_c = +mu``).

Sign convention (that of ``rubcli.model``): forces are the force of the stator on the
rotor, ``F = -K f``, nondimensional, in units of ``k_r * clearance``; positions are in
clearances. A rotor pressed outwards along +x feels ``F_x < 0``; with ``mu_c > 0`` the
friction force on a rotor at ``(x, 0)``, ``x > 1``, is ``F_y < 0`` (it opposes forward
whirl/spin slip).

The physics is called, never rewritten: the exact force is ``model.contact_force`` (which
takes arrays), the expansion is ``model.taylor_force`` (array-valued in the evaluation
point, scalar in the expansion point, so it is called once per expansion point), and the
linearised system is ``model.linearised_contact_system``. The only closed form here is the
eigenvalue formula of a damped system with a scalar damping matrix, checked against
``numpy.linalg.eigvals`` in the tests.

Limits: the expansion error is measured only where the displaced point is still in
contact (z > 1); crossing the clearance circle is a switching event located by root
finding, not a truncation error of the expansion, and it is not measured here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rubcli.model import ModelParams, contact_force, linearised_contact_system, taylor_force

if TYPE_CHECKING:
    from collections.abc import Iterator

    from numpy.typing import ArrayLike

    from rubcli.model import FloatOrArray

DIRECTIONS: tuple[str, ...] = ("radial", "tangential", "worst")
DEFAULT_DELTAS: tuple[float, ...] = tuple(float(d) for d in np.logspace(-6.0, -1.0, 11))
DEFAULT_K_VALUES: tuple[float, ...] = (17.6, 1.76e3, 1.76e5, 1.75e6)

# Sampling of the band of expansion points and of the directions (taylor_error).
BAND_RADII = 48  # radii z0 in (1, extent], clustered towards z0 = 1 where the error peaks
BAND_POLAR_ANGLES = 8  # polar positions of the expansion points (the error is rotation invariant)
DIRECTION_ANGLES = 360  # directions sampled for the worst case, every 1 degree
SMALLEST_PENETRATION = 1e-6  # z0 - 1 of the innermost expansion point, as a fraction of extent - 1
# Errors below ROUND_OFF_FACTOR * eps * K * extent are round-off and are left out of slope fits.
ROUND_OFF_FACTOR = 100.0

# Leading-order worst-case coefficients of the Taylor error at z0 -> 1 (see taylor_error):
# |error| ~ K sqrt(1 + mu^2) C delta^2 / z0^2.
TANGENTIAL_COEFFICIENT = 0.5
WORST_COEFFICIENT = 1.0 / math.sqrt(3.0)


def grid_axis(extent: float, resolution: int) -> np.ndarray:
    """Coordinates ``linspace(-extent, extent, resolution)`` of one axis of the square grid."""
    if not (math.isfinite(extent) and extent > 0.0):
        raise ValueError(f"extent must be a positive finite number, got {extent!r}")
    if int(resolution) < 2:
        raise ValueError(f"resolution must be at least 2, got {resolution!r}")
    return np.linspace(-extent, extent, int(resolution))


def _contact_points(extent: float, resolution: int):
    """Grid axes, the meshgrid (indexed [iy, ix]) and the mask of contact points (z > 1)."""
    axis = grid_axis(extent, resolution)
    X, Y = np.meshgrid(axis, axis, indexing="xy")
    in_contact = np.hypot(X, Y) > 1.0
    return axis, X, Y, in_contact


# --------------------------------------------------------------------------- Figure 2


@dataclass(frozen=True)
class ForceMap:
    """Exact and own-point Taylor forces on a square grid; arrays indexed ``[iy, ix]``."""

    x: np.ndarray  # (n,) grid abscissae, clearances
    y: np.ndarray  # (n,) grid ordinates, clearances
    Fx_exact: np.ndarray
    Fy_exact: np.ndarray
    Fx_taylor: np.ndarray
    Fy_taylor: np.ndarray
    K: float
    mu_c: float

    @property
    def Fx_diff(self) -> np.ndarray:
        """Exact minus Taylor, x component."""
        return self.Fx_exact - self.Fx_taylor

    @property
    def Fy_diff(self) -> np.ndarray:
        """Exact minus Taylor, y component."""
        return self.Fy_exact - self.Fy_taylor

    @property
    def max_abs_diff(self) -> float:
        """Largest |exact - Taylor| of either component over the grid."""
        return float(max(np.max(np.abs(self.Fx_diff)), np.max(np.abs(self.Fy_diff))))

    @property
    def max_abs_force(self) -> float:
        """Largest |F| of either exact component over the grid (the scale of round-off)."""
        return float(max(np.max(np.abs(self.Fx_exact)), np.max(np.abs(self.Fy_exact))))


def force_map(K: float, mu_c: float, extent: float, resolution: int) -> ForceMap:
    """The paper's Figure 2: exact force, Taylor expansion at its own point, on a grid.

    At each contact point ``p0`` (z > 1) the expansion about ``p0`` (paper eq. 9-14, in
    ``model.taylor_force``) is evaluated at ``p0`` itself, as in the paper ("the origin of
    the Taylor approximation is updated at each location"). Inside the clearance the
    contact law gives zero and the expansion, which the method uses only in contact, is
    set to zero too. The difference is round-off: a few ulps of ``K * z``.
    """
    axis, X, Y, in_contact = _contact_points(extent, resolution)
    Fx_exact, Fy_exact = contact_force(X, Y, K, mu_c)
    Fx_taylor = np.zeros_like(X)
    Fy_taylor = np.zeros_like(Y)
    for iy, ix in zip(*np.nonzero(in_contact), strict=True):
        x0, y0 = float(X[iy, ix]), float(Y[iy, ix])
        Fx_taylor[iy, ix], Fy_taylor[iy, ix] = taylor_force(x0, y0, x0, y0, K, mu_c)
    return ForceMap(
        x=axis,
        y=axis.copy(),
        Fx_exact=np.asarray(Fx_exact, dtype=float),
        Fy_exact=np.asarray(Fy_exact, dtype=float),
        Fx_taylor=Fx_taylor,
        Fy_taylor=Fy_taylor,
        K=float(K),
        mu_c=float(mu_c),
    )


# --------------------------------------------------------------------- Taylor error


@dataclass(frozen=True)
class TaylorError:
    """Maximum force error of the expansion at distance delta; ``max_abs_error[k, d, j]``.

    Indices: ``k`` over ``K_values``, ``d`` over ``directions``, ``j`` over ``deltas``.
    The error is the Euclidean norm ``|F_exact(p0 + delta d) - F_taylor(p0; p0 + delta d)|``
    in units of ``k_r * clearance``, maximised over the expansion points of the band (and
    for ``"worst"`` over the directions as well). NaN where no displaced point was in
    contact.
    """

    K_values: np.ndarray
    deltas: np.ndarray
    directions: tuple[str, ...]
    max_abs_error: np.ndarray
    mu_c: float
    extent: float
    band_radii: np.ndarray  # the expansion radii z0 sampled

    def rows(self) -> Iterator[tuple[float, float, str, float]]:
        """``(K, delta, direction, max_abs_error)`` tuples in the order K, direction, delta."""
        for k, K in enumerate(self.K_values):
            for d, direction in enumerate(self.directions):
                for j, delta in enumerate(self.deltas):
                    yield float(K), float(delta), direction, float(self.max_abs_error[k, d, j])

    def round_off_floor(self, K: float) -> float:
        """Errors below this are round-off of forces of size ``K * extent``."""
        return ROUND_OFF_FACTOR * np.finfo(float).eps * K * self.extent

    def slope(self, K: float, direction: str) -> float | None:
        """Fitted log-log slope of the error against delta (None when all is round-off)."""
        matches = np.flatnonzero(self.K_values == K)
        if matches.size == 0:
            raise ValueError(f"K = {K!r} is not among the computed K values")
        k = int(matches[0])
        d = self.directions.index(direction)
        return fit_loglog_slope(self.deltas, self.max_abs_error[k, d], self.round_off_floor(K))

    def slopes(self) -> dict[str, dict[str, float | None]]:
        """``{direction: {K as text: slope}}`` for every K and direction."""
        return {
            direction: {repr(float(K)): self.slope(K, direction) for K in self.K_values}
            for direction in self.directions
        }


def fit_loglog_slope(deltas: ArrayLike, errors: ArrayLike, floor: float = 0.0) -> float | None:
    """Least-squares slope of log(error) against log(delta), over errors above ``floor``.

    Returns None when fewer than three points are above the floor: the error is round-off
    (as it is along the radial direction, where the contact force is linear).
    """
    deltas = np.asarray(deltas, dtype=float)
    errors = np.asarray(errors, dtype=float)
    keep = np.isfinite(errors) & (errors > floor) & (deltas > 0.0)
    if np.count_nonzero(keep) < 3:
        return None
    slope, _ = np.polyfit(np.log(deltas[keep]), np.log(errors[keep]), 1)
    return float(slope)


def band_radii(extent: float, n: int = BAND_RADII) -> np.ndarray:
    """Expansion radii in ``(1, extent]``, geometrically clustered towards the circle.

    ``z0 - 1 = (extent - 1) * geomspace(SMALLEST_PENETRATION, 1, n)``: the error of the
    expansion grows as the expansion point approaches the clearance circle (as 1/z0^2),
    so the band's supremum is approached at its inner edge.
    """
    if not extent > 1.0:
        raise ValueError(f"the band of contact points needs extent > 1, got {extent!r}")
    return 1.0 + (extent - 1.0) * np.geomspace(SMALLEST_PENETRATION, 1.0, n)


def taylor_error(
    K_values: ArrayLike,
    deltas: ArrayLike,
    mu_c: float,
    extent: float,
    *,
    n_radii: int = BAND_RADII,
    n_polar: int = BAND_POLAR_ANGLES,
    n_angles: int = DIRECTION_ANGLES,
) -> TaylorError:
    """Error of the first-order expansion at a distance delta from its point.

    Expansion points ``p0 = z0 (cos t, sin t)``: ``z0`` from ``band_radii(extent)``,
    ``t`` at ``n_polar`` equally spaced angles (offset from the axes). From each ``p0``
    the expansion is evaluated at ``p0 + delta (cos a u + sin a v)``, ``u`` the outward
    radial unit vector, ``v`` the tangential one, for ``n_angles`` directions ``a``.

    - ``radial``: ``a = 0`` (outwards). Along a ray in contact the force ``-K(z - 1) R u``
      is linear in z, so the expansion is exact there and the error is round-off.
    - ``tangential``: ``a = pi/2``. Exactly ``K sqrt(1+mu_c^2) (sqrt(1 + (delta/z0)^2) - 1)``.
    - ``worst``: the largest error over all sampled directions, i.e. over every direction
      of motion. At leading order the error is ``K sqrt(1+mu_c^2) delta^2 |sin a|
      sqrt(cos^2 a + sin^2 a / 4) / z0^2``, largest at ``cos^2 a = 1/3`` (about 54.7 deg
      from the radial), where it is ``delta^2/sqrt(3)`` against ``delta^2/2`` tangentially.

    Each value is the maximum over the band of expansion points of the Euclidean norm of
    the force error, counting only displaced points that are still in contact (z > 1).
    "Worst case" is thus: the worst expansion point in the band, moving in the worst
    direction, by exactly delta, without leaving contact. ``n_angles`` must be a multiple
    of 4 so that the radial and tangential directions are among the sampled ones.
    """
    if n_angles % 4 != 0:
        raise ValueError("n_angles must be a multiple of 4")
    K_values = np.atleast_1d(np.asarray(K_values, dtype=float))
    deltas = np.atleast_1d(np.asarray(deltas, dtype=float))
    if np.any(~np.isfinite(K_values)) or np.any(K_values <= 0.0):
        raise ValueError("K values must be positive and finite")
    if np.any(~np.isfinite(deltas)) or np.any(deltas <= 0.0):
        raise ValueError("deltas must be positive and finite")

    radii = band_radii(extent, n_radii)
    polar = (np.arange(n_polar) + 0.5) * (2.0 * math.pi / n_polar)
    angles = np.arange(n_angles) * (2.0 * math.pi / n_angles)
    i_radial, i_tangential = 0, n_angles // 4
    # Displacements relative to the local frame, shape (n_deltas, n_angles).
    d_u = deltas[:, None] * np.cos(angles)[None, :]
    d_v = deltas[:, None] * np.sin(angles)[None, :]
    d_v[:, i_radial] = 0.0  # exact zeros: the radial direction has no tangential part
    d_u[:, i_tangential] = 0.0

    worst = np.full((K_values.size, len(DIRECTIONS), deltas.size), np.nan)
    for k, K in enumerate(K_values):
        for z0 in radii:
            for t in polar:
                c, s = math.cos(t), math.sin(t)
                x0, y0 = z0 * c, z0 * s
                # u = (c, s), v = (-s, c)
                xd = x0 + d_u * c - d_v * s
                yd = y0 + d_u * s + d_v * c
                Fx, Fy = contact_force(xd, yd, K, mu_c)
                Tx, Ty = taylor_force(x0, y0, xd, yd, K, mu_c)
                err = np.hypot(Fx - Tx, Fy - Ty)
                err[np.hypot(xd, yd) <= 1.0] = np.nan
                for d, column in ((0, err[:, i_radial]), (1, err[:, i_tangential])):
                    worst[k, d] = np.fmax(worst[k, d], column)
                all_directions = np.max(_nan_to_neg(err), axis=1)
                all_directions[np.isneginf(all_directions)] = np.nan
                worst[k, 2] = np.fmax(worst[k, 2], all_directions)
    return TaylorError(
        K_values=K_values,
        deltas=deltas,
        directions=DIRECTIONS,
        max_abs_error=worst,
        mu_c=float(mu_c),
        extent=float(extent),
        band_radii=radii,
    )


def _nan_to_neg(values: np.ndarray) -> np.ndarray:
    """NaN -> -inf, so that a row max ignores them without a RuntimeWarning."""
    return np.where(np.isnan(values), -np.inf, values)


def taylor_error_bound(
    K: float, mu: float, delta: FloatOrArray, z0: float = 1.0, direction: str = "worst"
) -> FloatOrArray:
    """Leading-order maximum force error of the expansion at distance delta (see taylor_error).

    ``K sqrt(1 + mu^2) C delta^2 / z0^2`` with ``C = 1/2`` tangentially and ``1/sqrt(3)``
    in the worst direction; zero radially. Valid for ``delta << z0``.
    """
    coefficient = {"radial": 0.0, "tangential": TANGENTIAL_COEFFICIENT, "worst": WORST_COEFFICIENT}
    if direction not in coefficient:
        raise ValueError(f"unknown direction {direction!r}; choose from {', '.join(DIRECTIONS)}")
    delta = np.asarray(delta, dtype=float)
    out = K * math.sqrt(1.0 + mu * mu) * coefficient[direction] * delta**2 / z0**2
    return out if np.ndim(out) else float(out)


def taylor_step_bound(
    K: float, mu: float, tolerance: float, speed: float, z0: float = 1.0, direction: str = "worst"
) -> float:
    """Largest step h (in tau) that keeps the expansion's force error below ``tolerance``.

    Over a step of length h with the expansion point at the start of the step, the rotor
    moves by ``delta ~ speed * h``; ``taylor_error_bound(delta) <= tolerance`` gives
    ``h <= sqrt(tolerance z0^2 / (K sqrt(1 + mu^2) C)) / speed``: h must shrink like
    ``1/sqrt(K)`` for a fixed force tolerance. ``tolerance`` is in units of
    ``k_r * clearance``, ``speed`` in clearances per unit tau.
    """
    if not (tolerance > 0.0 and speed > 0.0 and K > 0.0):
        raise ValueError("K, tolerance and speed must be positive")
    unit = taylor_error_bound(K, mu, 1.0, z0, direction)
    if unit == 0.0:
        return math.inf
    return math.sqrt(tolerance / unit) / speed


# -------------------------------------------------------------------- eigenvalues


def damped_eigenvalues(stiffness: np.ndarray, nu: float) -> np.ndarray:
    """Eigenvalues of ``x'' + 2 nu x' + S x = 0`` (first-order 4x4 form), closed form.

    ``stiffness`` has shape ``(..., 2, 2)``. Because the damping is ``2 nu I``, every
    eigenvalue ``sigma`` of S gives the pair ``lambda = -nu +/- sqrt(nu^2 - sigma)``.
    Returns shape ``(..., 4)``, ordered ``(-nu + w1, -nu - w1, -nu + w2, -nu - w2)`` with
    ``w = sqrt(nu^2 - sigma)`` (principal root, so ``Re w >= 0``).
    """
    S = np.asarray(stiffness, dtype=float)
    half_trace = 0.5 * (S[..., 0, 0] + S[..., 1, 1])
    det = S[..., 0, 0] * S[..., 1, 1] - S[..., 0, 1] * S[..., 1, 0]
    root = np.sqrt((half_trace * half_trace - det).astype(complex))
    sigma = np.stack([half_trace + root, half_trace - root], axis=-1)
    w = np.sqrt(nu * nu - sigma)
    lam = np.empty(S.shape[:-2] + (4,), dtype=complex)
    lam[..., 0::2] = -nu + w
    lam[..., 1::2] = -nu - w
    return lam


def modal_summary(eigenvalues: np.ndarray) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
    """``(max_real, freq_1, freq_2)`` from eigenvalues shaped ``(..., 4)`` as returned above.

    The frequencies are the |imaginary parts| of the two eigenvalue pairs, sorted
    ascending; they coincide where friction has merged the modes (flutter).
    """
    lam = np.asarray(eigenvalues)
    max_real = np.max(lam.real, axis=-1)
    pair_freq = np.abs(lam[..., 0::2].imag)
    pair_freq.sort(axis=-1)
    return max_real, pair_freq[..., 0], pair_freq[..., 1]


@dataclass(frozen=True)
class EigenMap:
    """Eigenvalue summary of the linearised contact system on a grid, ``[iy, ix]``.

    NaN outside contact (z <= 1).
    """

    x: np.ndarray
    y: np.ndarray
    max_real: np.ndarray
    freq_1: np.ndarray
    freq_2: np.ndarray
    nu: float
    K: float
    mu_c: float

    @property
    def in_contact(self) -> np.ndarray:
        return np.isfinite(self.max_real)

    @property
    def n_contact_points(self) -> int:
        return int(np.count_nonzero(self.in_contact))

    @property
    def max_real_overall(self) -> float | None:
        """Largest real part over all contact points (None if no grid point is in contact)."""
        return float(np.nanmax(self.max_real)) if self.n_contact_points else None

    @property
    def positive_fraction(self) -> float:
        """Fraction of the grid's contact points where some eigenvalue has Re > 0."""
        if not self.n_contact_points:
            return 0.0
        return float(np.count_nonzero(self.max_real[self.in_contact] > 0.0)) / (
            self.n_contact_points
        )


def eigen_map(
    params: ModelParams, mu_c: float, extent: float, resolution: int,
    deadline: float | None = None,
) -> EigenMap:  # fmt: skip
    """Eigenvalues of the linearised contact system at each contact point of the grid.

    The matrix is ``model.linearised_contact_system`` about the state ``(x0, y0, 0, 0)``
    (the velocity does not enter it); its eigenvalues come from ``damped_eigenvalues``
    applied to the stiffness block (after checking that the damping block is ``2 nu I``).
    WallTimeBudgetError once ``time.perf_counter()`` passes ``deadline`` (checked at every
    block of contact points).
    """
    from rubcli.analysis.orbits.periodic import check_deadline

    axis, X, Y, in_contact = _contact_points(extent, resolution)
    shape = X.shape
    max_real = np.full(shape, np.nan)
    freq_1 = np.full(shape, np.nan)
    freq_2 = np.full(shape, np.nan)
    for iy, ix in _contact_blocks(in_contact):
        check_deadline(deadline)
        stiffness = np.empty((iy.size, 2, 2))
        for n, (j, i) in enumerate(zip(iy, ix, strict=True)):
            A, _ = linearised_contact_system((X[j, i], Y[j, i], 0.0, 0.0), params, mu_c)
            stiffness[n] = -A[2:, :2]
            if n == 0 and not np.array_equal(A[2:, 2:], -2.0 * params.nu * np.eye(2)):
                raise ValueError("the damping block of the linearised system is not 2 nu I")
        summary = modal_summary(damped_eigenvalues(stiffness, params.nu))
        max_real[iy, ix], freq_1[iy, ix], freq_2[iy, ix] = summary
    del X, Y, in_contact
    return EigenMap(
        x=axis,
        y=axis.copy(),
        max_real=max_real,
        freq_1=freq_1,
        freq_2=freq_2,
        nu=float(params.nu),
        K=float(params.K),
        mu_c=float(mu_c),
    )


# Contact points whose eigenvalues are computed at a time (each point's temporaries take
# some 300 bytes: the grid's memory stays that of its result arrays).
CONTACT_BLOCK_POINTS = 65_536


def _contact_blocks(in_contact: np.ndarray, size: int = CONTACT_BLOCK_POINTS):
    """``(iy, ix)`` of the contact points, ``size`` at a time, row by row of the grid."""
    rows_per_block = max(1, size // max(1, in_contact.shape[1]))
    for row in range(0, in_contact.shape[0], rows_per_block):
        iy, ix = np.nonzero(in_contact[row : row + rows_per_block])
        if iy.size:
            yield iy + row, ix


def friction_flutter_radius(mu: float) -> float:
    """Radius z0 beyond which friction makes the contact stiffness eigenvalues complex.

    The force Jacobian ``J = R H`` has ``tr J = 1 + c`` and ``det J = (1 + mu^2) c`` with
    ``c = 1 - 1/z0``, so its eigenvalues ``(1 + c)/2 +/- sqrt((1 - c)^2/4 - mu^2 c)`` turn
    complex (the two contact modes merge: flutter) when ``sqrt(c) > sqrt(1 + mu^2) - mu``.
    Independent of K and of the position's angle. Damping moves the onset of growth
    (Re lambda > 0) slightly further out: it needs ``Im(sigma)^2 > 4 nu^2 Re(sigma)``.
    Infinite for ``mu = 0``.
    """
    mu = abs(float(mu))
    if mu == 0.0:
        return math.inf
    c = (math.sqrt(1.0 + mu * mu) - mu) ** 2
    return 1.0 / (1.0 - c)


def friction_flutter_threshold(z0: FloatOrArray) -> np.ndarray:
    """The friction coefficient at which the contact modes merge at radius ``z0`` (> 1):
    the inverse of ``friction_flutter_radius``, ``mu = (1 - c) / (2 sqrt(c))`` with
    ``c = 1 - 1/z0`` (from ``sqrt(c) = sqrt(1 + mu^2) - mu``). Independent of K and of the
    angle; damping moves the onset of growth to a slightly larger mu. NaN where ``z0 <= 1``
    (no contact)."""
    z0 = np.asarray(z0, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = 1.0 - 1.0 / z0
        mu = (1.0 - c) / (2.0 * np.sqrt(c))
    return np.where(z0 > 1.0, mu, np.nan)

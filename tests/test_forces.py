"""Force maps, Taylor error and contact eigenvalues (rubcli.analysis.charts.forces_map).

Reference numbers come from hand calculations (stated beside them), from central finite
differences of the exact force, or from numpy on matrices assembled here from the paper's
coefficients (eq. 9-14 with the notes' corrections 1-2), never from the code under test.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.charts.forces_map import (
    DIRECTIONS,
    band_radii,
    damped_eigenvalues,
    eigen_map,
    fit_loglog_slope,
    force_map,
    friction_flutter_radius,
    grid_axis,
    modal_summary,
    taylor_error,
    taylor_error_bound,
    taylor_step_bound,
)
from rubcli.case import load_case
from rubcli.cli.app import app
from rubcli.cli.forces_map import output_dir
from rubcli.model import ModelParams, contact_eigenvalues, contact_force, taylor_force
from rubcli.studies.forces_map import FORCES_COLUMNS, write_forces_map

EPS = np.finfo(float).eps
NU = 0.009478  # Table 1


def params(K: float, mu: float, nu: float = NU) -> ModelParams:
    return ModelParams(nu=nu, eta=0.7818, e=7.52, K=K, mu=mu, Rp=46.16)


# --------------------------------------------------------------------------- Figure 2


def test_exact_force_on_a_three_point_grid_matches_hand_values():
    # Grid (-1.5, 0, 1.5)^2, K = 10, mu_c = 0.1. By hand, F = -K (1 - 1/z) (x - mu y, y + mu x):
    #   (1.5, 0):   1 - 1/1.5 = 1/3      -> F = -10/3 (1.5, 0.15) = (-5, -0.5)
    #   (0, -1.5):  1/3                  -> F = -10/3 (0.15, -1.5) = (-0.5, 5)
    #   (1.5, 1.5): z = 2.121320343559643, 1 - 1/z = 0.5285954792089682
    #               -> F = -5.285954792089682 (1.35, 1.65)
    #                    = (-7.136038969321071, -8.721825406947975)
    #   (0, 0): inside the clearance -> 0
    fm = force_map(K=10.0, mu_c=0.1, extent=1.5, resolution=3)
    np.testing.assert_array_equal(fm.x, [-1.5, 0.0, 1.5])
    # arrays are indexed [iy, ix]
    assert fm.Fx_exact[1, 2] == pytest.approx(-5.0, rel=1e-14)
    assert fm.Fy_exact[1, 2] == pytest.approx(-0.5, rel=1e-14)
    assert fm.Fx_exact[0, 1] == pytest.approx(-0.5, rel=1e-14)
    assert fm.Fy_exact[0, 1] == pytest.approx(5.0, rel=1e-14)
    assert fm.Fx_exact[2, 2] == pytest.approx(-7.136038969321071, rel=1e-13)
    assert fm.Fy_exact[2, 2] == pytest.approx(-8.721825406947975, rel=1e-13)
    assert fm.Fx_exact[1, 1] == 0.0 and fm.Fy_exact[1, 1] == 0.0


def test_forces_are_zero_inside_and_on_the_clearance_circle():
    fm = force_map(K=17.6e3, mu_c=0.1, extent=1.0, resolution=41)
    X, Y = np.meshgrid(fm.x, fm.y)
    inside = np.hypot(X, Y) <= 1.0
    assert inside[20, 40]  # the point (1, 0) lies exactly on the circle
    for field in (fm.Fx_exact, fm.Fy_exact, fm.Fx_taylor, fm.Fy_taylor, fm.Fx_diff, fm.Fy_diff):
        assert np.all(field[inside] == 0.0)
    # and outside the circle the force is not zero
    assert np.all(np.hypot(fm.Fx_exact, fm.Fy_exact)[~inside] > 0.0)


def test_own_point_taylor_difference_is_round_off_as_in_figure_2():
    # Paper section 3.1: K = 17.6e3, mu = 0.1, "difference < 1e-10". By construction the
    # expansion is exact at its own point; the difference is a few ulps of |F| ~ K z.
    fm = force_map(K=17.6e3, mu_c=0.1, extent=1.5, resolution=101)
    assert fm.max_abs_diff < 1e-10
    assert fm.max_abs_diff <= 64 * EPS * fm.max_abs_force
    assert fm.max_abs_force > 1e4  # forces of size K (z - 1) with z up to 1.5 sqrt(2)


def test_taylor_expansion_matches_central_finite_differences_of_the_exact_force():
    # Independent check of the Jacobian in model.taylor_force: the slope of the expansion
    # along e_x, e_y equals the central difference of contact_force (error O(h^2)).
    K, mu_c, h = 17.6e3, 0.1, 1e-5
    rng = np.random.default_rng(12)
    for _ in range(20):
        z0, t = rng.uniform(1.01, 2.0), rng.uniform(0.0, 2 * math.pi)
        x0, y0 = z0 * math.cos(t), z0 * math.sin(t)
        T0 = np.array(taylor_force(x0, y0, x0, y0, K, mu_c))
        for ex, ey in ((1.0, 0.0), (0.0, 1.0)):
            plus = np.array(contact_force(x0 + h * ex, y0 + h * ey, K, mu_c))
            minus = np.array(contact_force(x0 - h * ex, y0 - h * ey, K, mu_c))
            fd = (plus - minus) / (2 * h)
            slope = np.array(taylor_force(x0, y0, x0 + ex, y0 + ey, K, mu_c)) - T0
            np.testing.assert_allclose(slope, fd, rtol=1e-6, atol=1e-6 * K)
        np.testing.assert_allclose(T0, contact_force(x0, y0, K, mu_c), rtol=1e-12)


# --------------------------------------------------------------------- Taylor error


@pytest.fixture(scope="module")
def paper_error():
    deltas = np.logspace(-6.0, -1.0, 11)
    return taylor_error([17.6, 1.76e3, 1.76e5], deltas, mu_c=0.1, extent=1.5, n_radii=16)


def test_tangential_error_equals_the_hand_formula(paper_error):
    # Moving tangentially by delta from p0 (|p0| = z0): |p| = sqrt(z0^2 + delta^2), the
    # expansion gives (1 - 1/z0) R p, the exact law (1 - 1/|p|) R p, so
    # |error| = K sqrt(1 + mu^2) (1/z0 - 1/|p|) |p| = K sqrt(1+mu^2) (sqrt(1 + (delta/z0)^2) - 1),
    # largest at the innermost radius of the band.
    z0 = paper_error.band_radii.min()
    d = paper_error.directions.index("tangential")
    for k, K in enumerate(paper_error.K_values):
        hand = K * math.sqrt(1.01) * (np.sqrt(1.0 + (paper_error.deltas / z0) ** 2) - 1.0)
        hand_stable = (
            K
            * math.sqrt(1.01)
            * (paper_error.deltas / z0) ** 2
            / (np.sqrt(1.0 + (paper_error.deltas / z0) ** 2) + 1.0)
        )
        np.testing.assert_allclose(hand, hand_stable, rtol=1e-4)
        np.testing.assert_allclose(
            paper_error.max_abs_error[k, d], hand_stable, rtol=1e-3, atol=200 * EPS * K
        )


def test_radial_error_is_round_off(paper_error):
    # Along a ray in contact the force -K (z - 1) R u is linear in z: the expansion is exact.
    d = paper_error.directions.index("radial")
    for k, K in enumerate(paper_error.K_values):
        assert np.all(paper_error.max_abs_error[k, d] < paper_error.round_off_floor(K))
        assert paper_error.slope(K, "radial") is None


@pytest.mark.parametrize("direction", ["tangential", "worst"])
def test_fitted_slope_of_the_error_against_delta_is_two(paper_error, direction):
    for K in paper_error.K_values:
        assert paper_error.slope(K, direction) == pytest.approx(2.0, abs=0.01)


def test_error_grows_linearly_with_K(paper_error):
    # F_exact and F_taylor are both K times a function of position.
    err = paper_error.max_abs_error
    for d, direction in enumerate(paper_error.directions):
        if direction == "radial":
            continue
        for k in range(1, paper_error.K_values.size):
            ratio = err[k, d, 2:] / err[0, d, 2:]  # deltas >= 1e-5, far above round-off
            K_ratio = paper_error.K_values[k] / paper_error.K_values[0]
            np.testing.assert_allclose(ratio, K_ratio, rtol=1e-5)


def test_worst_direction_matches_a_continuous_maximisation(paper_error):
    # Independent of the 1-degree sampling: maximise the error over the direction angle
    # with a scalar optimiser at the innermost expansion point, delta = 1e-2, over the
    # outward directions (inward ones leave contact there). A brute-force search over
    # z0 and 20001 angles puts the supremum at that point and angle, 55.04 deg.
    K, mu_c, delta = 17.6, 0.1, 1e-2
    z0 = paper_error.band_radii.min()
    x0, y0 = 0.0, z0  # any polar position: the error is rotation invariant

    def minus_error(a):
        # u = (0, 1) radial, v = (-1, 0) tangential at (0, z0)
        x, y = x0 - delta * math.sin(a), y0 + delta * math.cos(a)
        F = np.array(contact_force(x, y, K, mu_c))
        T = np.array(taylor_force(x0, y0, x, y, K, mu_c))
        return -float(np.hypot(*(F - T)))

    best = max(
        -minimize_scalar(minus_error, bounds=(lo, lo + math.pi / 2), method="bounded").fun
        for lo in (-math.pi / 2, 0.0)
    )
    j = int(np.argmin(np.abs(paper_error.deltas - delta)))
    measured = paper_error.max_abs_error[0, DIRECTIONS.index("worst"), j]
    assert measured == pytest.approx(best, rel=2e-4)
    assert measured <= best * (1 + 1e-9)
    # and the leading-order hand value: K sqrt(1 + mu^2) delta^2 / sqrt(3) at z0 -> 1
    assert best == pytest.approx(17.6 * math.sqrt(1.01) * 1e-4 / math.sqrt(3.0), rel=0.02)


def test_worst_to_tangential_ratio_is_two_over_root_three(paper_error):
    # Hand: the second-order error of p -> p/|p| for d = delta (cos a u + sin a v) has norm
    # delta^2 |sin a| sqrt(cos^2 a + sin^2 a / 4) / z0^2, maximal at cos^2 a = 1/3:
    # delta^2 / sqrt(3) / z0^2, against delta^2 / 2 / z0^2 at a = pi/2.
    t, w = DIRECTIONS.index("tangential"), DIRECTIONS.index("worst")
    # Third-order terms shift the ratio by O(delta): use delta = 1e-5 ... 1e-4.
    ratio = paper_error.max_abs_error[:, w, 2:5] / paper_error.max_abs_error[:, t, 2:5]
    np.testing.assert_allclose(ratio, 2.0 / math.sqrt(3.0), rtol=1e-4)


def test_error_bound_and_step_bound_agree_with_the_measured_error(paper_error):
    w = DIRECTIONS.index("worst")
    bound = taylor_error_bound(17.6, 0.1, paper_error.deltas)
    np.testing.assert_allclose(paper_error.max_abs_error[0, w, 3:7], bound[3:7], rtol=1e-3)
    # a step that moves the point by delta = speed * h meets its tolerance
    speed, tolerance = 0.96, 1e-6
    for K in (17.6, 17.6e3):
        h = taylor_step_bound(K, 0.1, tolerance, speed)
        measured = taylor_error([K], [speed * h], mu_c=0.1, extent=1.5, n_radii=16)
        assert measured.max_abs_error[0, w, 0] == pytest.approx(tolerance, rel=1e-3)
    assert taylor_step_bound(17.6e3, 0.1, tolerance, speed) == pytest.approx(
        taylor_step_bound(17.6, 0.1, tolerance, speed) / math.sqrt(1000.0), rel=1e-12
    )


def test_band_and_slope_fit_helpers():
    radii = band_radii(1.5, 5)
    assert radii[0] > 1.0 and radii[-1] == pytest.approx(1.5) and np.all(np.diff(radii) > 0)
    with pytest.raises(ValueError):
        band_radii(1.0)
    deltas = np.logspace(-4, -1, 7)
    assert fit_loglog_slope(deltas, 3.0 * deltas**2) == pytest.approx(2.0, abs=1e-12)
    assert fit_loglog_slope(deltas, np.full(7, 1e-20), floor=1e-15) is None
    with pytest.raises(ValueError):
        grid_axis(1.5, 1)


# -------------------------------------------------------------------- eigenvalues


def paper_stiffness(x0: float, y0: float, K: float, mu_c: float) -> np.ndarray:
    """[[F_a1, F_b1], [F_b2, F_a2]] from the paper's A1, A2, B1 = B2 (eq. 9-14, notes 2.2)."""
    alpha = x0 * x0 + y0 * y0
    A1 = 1 - 1 / math.sqrt(alpha) + x0 * x0 / alpha**1.5
    A2 = 1 - 1 / math.sqrt(alpha) + y0 * y0 / alpha**1.5
    B1 = B2 = x0 * y0 / alpha**1.5
    return np.array(
        [
            [1 + K * (A1 - mu_c * B2), K * (B1 - mu_c * A2)],
            [K * (B2 + mu_c * A1), 1 + K * (A2 + mu_c * B1)],
        ]
    )


def first_order_matrix(S: np.ndarray, nu: float) -> np.ndarray:
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2:, :2] = -S
    A[2, 2] = A[3, 3] = -2 * nu
    return A


def assert_same_spectrum(actual, desired, rtol: float = 1e-9) -> None:
    """Each eigenvalue of ``desired`` is matched by a distinct one of ``actual``."""
    remaining = list(np.asarray(actual))
    scale = np.max(np.abs(desired))
    for value in np.asarray(desired):
        distances = [abs(value - other) for other in remaining]
        best = int(np.argmin(distances))
        assert distances[best] <= rtol * scale, (value, remaining)
        remaining.pop(best)


@pytest.mark.parametrize("mu_c", [0.0, 0.1, 0.5])
def test_closed_form_eigenvalues_match_numpy_on_an_independent_matrix(mu_c):
    rng = np.random.default_rng(3)
    for _ in range(10):
        z0, t = rng.uniform(1.001, 3.0), rng.uniform(0.0, 2 * math.pi)
        x0, y0 = z0 * math.cos(t), z0 * math.sin(t)
        S = paper_stiffness(x0, y0, 17.6e3, mu_c)
        reference = np.linalg.eigvals(first_order_matrix(S, NU))
        closed = damped_eigenvalues(S, NU)
        assert_same_spectrum(closed, reference)
        # and numpy on the model's own matrix
        model = contact_eigenvalues(x0, y0, params(17.6e3, mu_c), mu_c)
        assert_same_spectrum(closed, model)


def test_without_friction_the_system_is_symmetric_and_decays_at_nu():
    # mu = 0: S = I + K H, H symmetric with eigenvalues 1 (radial) and 1 - 1/z0 (tangential),
    # so sigma = 1 + K and 1 + K (1 - 1/z0); all lambda = -nu +/- i sqrt(sigma - nu^2).
    K = 17.6e3
    em = eigen_map(params(K, 0.0), 0.0, extent=1.5, resolution=31)
    X, Y = np.meshgrid(em.x, em.y)
    z = np.hypot(X, Y)
    contact = z > 1.0
    assert np.array_equal(em.in_contact, contact)
    np.testing.assert_allclose(em.max_real[contact], -NU, rtol=1e-9)
    np.testing.assert_allclose(em.freq_2[contact], math.sqrt(1 + K - NU**2), rtol=1e-12)
    hand_1 = np.sqrt(1 + K * (1 - 1 / z[contact]) - NU**2)
    np.testing.assert_allclose(em.freq_1[contact], hand_1, rtol=1e-10)
    assert np.all(np.isnan(em.max_real[~contact]))
    assert em.positive_fraction == 0.0
    # the model's stiffness block I + K J (what the solvers use) is symmetric at mu = 0,
    # and J is the Jacobian of the force (1 - 1/z)(x, y): central differences of it
    A, _ = model.linearised_contact_system((1.1, 0.4, 0.0, 0.0), params(K, 0.0), 0.0)
    S = -A[2:, :2]
    np.testing.assert_allclose(S, S.T, rtol=1e-15, atol=0)
    assert np.all(np.isreal(np.linalg.eigvals(S)))

    def force(x, y):
        z = math.hypot(x, y)
        return np.array([(1 - 1 / z) * x, (1 - 1 / z) * y])

    h = 1e-6
    fd = np.column_stack(
        [(force(1.1 + h, 0.4) - force(1.1 - h, 0.4)) / (2 * h),
         (force(1.1, 0.4 + h) - force(1.1, 0.4 - h)) / (2 * h)]
    )  # fmt: skip
    np.testing.assert_allclose(S, np.eye(2) + K * fd, rtol=1e-8)


def test_eigen_map_matches_model_eigenvalues_with_friction():
    # mu = 0.5 over extent 2.5 crosses the flutter radius (1.618): both regimes are checked.
    p = params(17.6e3, 0.5)
    em = eigen_map(p, 0.5, extent=2.5, resolution=15)
    X, Y = np.meshgrid(em.x, em.y)
    for iy, ix in zip(*np.nonzero(em.in_contact), strict=True):
        lam = contact_eigenvalues(X[iy, ix], Y[iy, ix], p, 0.5)
        freqs = np.sort(np.abs(lam.imag))
        assert em.max_real[iy, ix] == pytest.approx(lam.real.max(), abs=1e-9 * abs(lam).max())
        assert em.freq_1[iy, ix] == pytest.approx(freqs[0], rel=1e-9)
        assert em.freq_2[iy, ix] == pytest.approx(freqs[3], rel=1e-9)
    assert 0.0 < em.positive_fraction < 1.0


def test_paper_figure_2_parameters_have_no_friction_instability_within_1_5_clearances():
    # K = 17.6e3, mu = 0.1: flutter needs z0 > 5.52 (hand: sqrt(1.01) - 0.1 = 0.904988,
    # c = 0.819003, z0 = 1/(1 - c) = 5.5249), so every mode decays at exactly nu here.
    em = eigen_map(params(17.6e3, 0.1), 0.1, extent=1.5, resolution=41)
    np.testing.assert_allclose(em.max_real[em.in_contact], -NU, rtol=1e-8)
    assert em.positive_fraction == 0.0
    assert friction_flutter_radius(0.1) == pytest.approx(5.524937810560, rel=1e-10)


def test_flutter_radius_separates_real_and_merged_modes():
    # mu = 0.5: sqrt(c) = sqrt(1.25) - 0.5 = 0.6180340, z0 = 1/(1 - 0.3819660) = golden ratio.
    assert friction_flutter_radius(0.5) == pytest.approx((1 + math.sqrt(5)) / 2, rel=1e-12)
    assert friction_flutter_radius(0.0) == math.inf
    K, mu = 17.6e3, 0.5
    undamped = params(K, mu, nu=0.0)
    inside = contact_eigenvalues(1.60, 0.0, undamped, mu)
    outside = contact_eigenvalues(1.64, 0.0, undamped, mu)
    assert np.max(np.abs(inside.real)) < 1e-9 * np.max(np.abs(inside))  # pure oscillation
    assert outside.real.max() > 1.0  # a growing mode
    freqs = np.sort(np.abs(outside.imag))
    assert freqs[0] == pytest.approx(freqs[3], rel=1e-9)  # the two modes share a frequency


def test_modal_summary_on_hand_eigenvalues():
    lam = np.array([-0.1 + 2j, -0.1 - 2j, 0.3 + 1j, 0.3 - 1j])
    max_real, f1, f2 = modal_summary(lam)
    assert (max_real, f1, f2) == (0.3, 1.0, 2.0)


# ------------------------------------------------------------------------------- CLI

REPO = Path(__file__).resolve().parents[1]

SMALL_CASE = """\
[case]
name = "small-map"

[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6e3
mu = 0.1
Rp = 46.16

[initial]
x = 0.88544
y = -0.8039
vx = 0.0
vy = 0.0

[time]
periods = 1
samples_per_period = 10
"""


def write_small_case(tmp_path: Path, forces_map: str) -> Path:
    path = tmp_path / "case.toml"
    path.write_text(SMALL_CASE + "\n[forces_map]\n" + forces_map, encoding="utf-8")
    return path


def read_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return rows[0], rows[1:]


def invoke(*args) -> object:
    return CliRunner().invoke(app, [str(a) for a in args])


def test_cli_writes_only_the_eigen_map_when_only_it_is_asked(tmp_path):
    case = write_small_case(tmp_path, 'products = ["eigen"]\nresolution = 11\nextent = 2.0\n')
    out = tmp_path / "out"
    result = invoke("forces-map", case, "--out", out)
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {"eigen_map.csv", "eigen_map.png", "report.json"}
    header, rows = read_rows(out / "eigen_map.csv")
    assert header == ["x", "y", "max_real", "freq_1", "freq_2"]
    assert len(rows) == 121
    # the point (2, 0) is in contact; (0, 0) is not (empty fields)
    by_point = {(float(r[0]), float(r[1])): r[2:] for r in rows}
    assert by_point[(0.0, 0.0)] == ["", "", ""]
    assert float(by_point[(2.0, 0.0)][0]) == pytest.approx(-NU, rel=1e-9)
    report = json.loads((out / "report.json").read_text())
    assert list(report["products"]) == ["eigen"]
    eigen = report["products"]["eigen"]
    assert eigen["max_real_part"] == pytest.approx(-NU, rel=1e-9)
    assert eigen["positive_fraction_of_contact_points"] == 0.0
    assert eigen["flutter_radius_undamped"] == pytest.approx(5.524937810560, rel=1e-10)
    assert report["case"]["settings"]["forces_map"]["products"] == ["eigen"]


@pytest.mark.slow
def test_cli_writes_every_product_with_the_requested_columns(tmp_path):
    case = write_small_case(
        tmp_path,
        "resolution = 9\nextent = 1.5\ndeltas = [1e-4, 1e-3, 1e-2]\nK_values = [17.6, 1760.0]\n",
    )
    out = tmp_path / "out"
    result = invoke("forces-map", case, "--out", out)
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {
        "forces_map.csv",
        "forces_map.png",
        "taylor_error.csv",
        "taylor_error.png",
        "eigen_map.csv",
        "eigen_map.png",
        "report.json",
    }
    header, rows = read_rows(out / "forces_map.csv")
    assert header == list(FORCES_COLUMNS)
    assert len(rows) == 81
    table = {(float(r[0]), float(r[1])): [float(v) for v in r[2:]] for r in rows}
    # hand value at (1.5, 0): F = -K/3 (1.5, 0.15) = (-8800, -880)
    Fx, Fy, Tx, Ty, dx, dy = table[(1.5, 0.0)]
    assert (Fx, Fy) == (pytest.approx(-8800.0, rel=1e-13), pytest.approx(-880.0, rel=1e-13))
    assert (Tx, Ty) == (pytest.approx(Fx, rel=1e-13), pytest.approx(Fy, rel=1e-13))
    assert table[(0.0, 0.0)] == [0.0] * 6

    header, rows = read_rows(out / "taylor_error.csv")
    assert header == ["K", "delta", "direction", "max_abs_error"]
    assert len(rows) == 2 * 3 * 3
    assert {r[2] for r in rows} == set(DIRECTIONS)
    # tangential, K = 1760, delta = 1e-2 at z0 -> 1: K sqrt(1.01) (sqrt(1 + 1e-4) - 1)
    tangential = {(float(r[0]), float(r[1])): float(r[3]) for r in rows if r[2] == "tangential"}
    hand = 1760.0 * math.sqrt(1.01) * (math.sqrt(1 + 1e-4) - 1)
    assert tangential[(1760.0, 1e-2)] == pytest.approx(hand, rel=1e-5)

    report = json.loads((out / "report.json").read_text())
    slopes = report["products"]["taylor_error"]["fitted_slope"]
    assert slopes["radial"] == {"17.6": None, "1760.0": None}
    for direction in ("tangential", "worst"):
        for slope in slopes[direction].values():
            assert slope == pytest.approx(2.0, abs=0.01)
    assert report["products"]["forces"]["max_abs_diff"] < 1e-10
    assert report["files"][-1] == "report.json"


def test_default_output_dir_is_a_subdirectory_of_the_case_output_dir(tmp_path):
    # Without --out the files go to <output dir>/forces-map, so that the report.json of
    # `rubcli run` on the same case is not overwritten.
    path = tmp_path / "case.toml"
    path.write_text(SMALL_CASE + '\n[output]\ndir = "' + (tmp_path / "o").as_posix() + '"\n')
    case = load_case(path)
    assert case.settings.forces_map is None
    assert output_dir(case, None) == tmp_path / "o" / "forces-map"
    assert output_dir(case, tmp_path / "x") == tmp_path / "x"


@pytest.mark.parametrize(
    "table, field",
    [
        ("extent = 1.0\n", "forces_map.extent"),
        ("resolution = 2\n", "forces_map.resolution"),
        ('products = ["orbit"]\n', "forces_map.products"),
        ("deltas = [-1e-3]\n", "forces_map.deltas"),
        ("K_values = [0.0]\n", "forces_map.K_values"),
        ("colour = 1\n", "forces_map.colour"),
    ],
)
def test_cli_rejects_bad_input_with_exit_2_and_writes_nothing(tmp_path, table, field):
    case = write_small_case(tmp_path, table)
    out = tmp_path / "out"
    result = invoke("forces-map", case, "--out", out)
    assert result.exit_code == 2, result.output
    assert field in result.output
    assert "Traceback" not in result.output
    assert not out.exists()


def test_cli_rejects_an_output_path_that_is_a_file(tmp_path):
    case = write_small_case(tmp_path, 'products = ["eigen"]\nresolution = 5\n')
    out = tmp_path / "out"
    out.write_text("not a directory")
    result = invoke("forces-map", case, "--out", out)
    assert result.exit_code == 2
    assert "not a directory" in result.output


@pytest.mark.slow
@pytest.mark.parametrize("name", ["paper/fig2.toml", "examples/eigen-only.toml"])
def test_shipped_forces_map_cases_run_at_a_small_resolution(tmp_path, name):
    case = load_case(REPO / "cases" / name)
    settings = case.settings.forces_map
    assert settings is not None
    if name == "paper/fig2.toml":
        # paper section 3.1 and Figure 2 caption; Table 1
        assert (case.params.K, case.params.mu) == (17.6e3, 0.1)
        assert (case.params.nu, case.params.eta, case.params.Rp) == (0.009478, 0.7818, 46.16)
    small = settings.model_copy(update={"resolution": 15})
    case = dataclasses.replace(
        case, settings=case.settings.model_copy(update={"forces_map": small})
    )
    report = write_forces_map(case, tmp_path, command_line={"case_file": name})
    expected = {
        "forces": "forces_map.csv",
        "taylor_error": "taylor_error.csv",
        "eigen": "eigen_map.csv",
    }
    written = {p.name for p in tmp_path.iterdir()}
    assert {expected[p] for p in settings.products} <= written
    assert {v for k, v in expected.items() if k not in settings.products}.isdisjoint(written)
    if "eigen" in settings.products and name == "examples/eigen-only.toml":
        # the grid reaches beyond the flutter radius: some contact points are unstable
        assert report["products"]["eigen"]["positive_fraction_of_contact_points"] > 0.0


def test_grid_csv_is_formatted_in_blocks_row_by_row():
    """The grid tables are formatted a block of rows at a time (one 8.3 GiB block once
    failed at resolution 6688): the blocks cover the grid in its order (y outer, x inner)
    and hold at most ``rows`` rows each."""
    from rubcli.studies.forces_map import grid_blocks

    x, y = np.linspace(-1.0, 1.0, 5), np.linspace(-2.0, 2.0, 4)
    field = np.arange(20.0).reshape(4, 5)
    blocks = list(grid_blocks(x, y, [field, -field], rows=7))
    assert [b[0].size for b in blocks] == [7, 7, 6]
    X, Y = np.meshgrid(x, y, indexing="xy")
    expected = [X.ravel(), Y.ravel(), field.ravel(), -field.ravel()]
    for got, want in zip(zip(*blocks, strict=True), expected, strict=True):
        np.testing.assert_array_equal(np.concatenate(got), want)

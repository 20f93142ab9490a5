"""The physics in model.py against hand values, finite differences and the notes' numbers."""

import math

import numpy as np
import pytest

from rubcli import model
from rubcli.model import ModelParams

P = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.05, Rp=46.16)


def test_contact_force_hand_values():
    # (x, y) = (1.2, 0): z = 1.2, 1 - 1/z = 1/6; f = (1/6)(1.2, 0.05 * 1.2) = (0.2, 0.01)
    fx, fy = model.contact_force(1.2, 0.0, K=10.0, mu_c=0.05)
    assert fx == pytest.approx(-2.0, rel=1e-14)
    assert fy == pytest.approx(-0.1, rel=1e-14)
    # (0, 2): 1 - 1/z = 1/2; f = (1/2)(0 - mu*2, 2) = (-mu, 1)
    fx, fy = model.contact_force(0.0, 2.0, K=3.0, mu_c=0.1)
    assert (fx, fy) == pytest.approx((0.3, -3.0), rel=1e-14)


def test_contact_force_zero_inside_and_on_clearance():
    x = np.array([0.0, 0.5, 1.0, 0.6])
    y = np.array([0.0, -0.5, 0.0, 0.8])  # last point is on the circle
    fx, fy = model.contact_force(x, y, K=1e5, mu_c=0.1)
    assert np.all(fx == 0.0) and np.all(fy == 0.0)


def test_friction_opposes_positive_slip():
    # At (1.1, 0) the tangential direction of positive whirl is +y; with v_r > 0 the
    # friction on the rotor must point to -y.
    _, fy = model.contact_force(1.1, 0.0, K=1.0, mu_c=+0.1)
    assert fy < 0.0


def test_slip_velocity_spin_plus_whirl():
    # r theta' at (2, 0) with velocity (0, 3) is 3.
    assert model.slip_velocity(2.0, 0.0, 0.0, 3.0, Rp=10.0, eta=0.5) == pytest.approx(8.0)


@pytest.mark.parametrize("point", [(1.3, 0.2), (-0.9, 0.8), (0.1, -1.7)])
@pytest.mark.parametrize("mu_c", [0.0, 0.1, -0.05])
def test_jacobian_against_central_differences(point, mu_c):
    x0, y0 = point
    J = model.force_jacobian(x0, y0, mu_c)
    eps = 1e-6

    def f(x, y):
        fx, fy = model.contact_force(x, y, K=1.0, mu_c=mu_c)
        return -np.array([fx, fy])

    fd = np.column_stack(
        [
            (f(x0 + eps, y0) - f(x0 - eps, y0)) / (2 * eps),
            (f(x0, y0 + eps) - f(x0, y0 - eps)) / (2 * eps),
        ]
    )
    np.testing.assert_allclose(J, fd, atol=1e-8)


def test_taylor_force_exact_at_its_point_and_second_order_away():
    x0, y0, K, mu_c = 1.1, 0.3, 17.6, 0.1
    exact = np.array(model.contact_force(x0, y0, K, mu_c))
    assert np.allclose(model.taylor_force(x0, y0, x0, y0, K, mu_c), exact, atol=1e-14)
    errs = []
    deltas = [1e-2, 5e-3, 2.5e-3]
    for d in deltas:
        approx = np.array(model.taylor_force(x0, y0, x0 + d, y0 + d, K, mu_c))
        errs.append(np.linalg.norm(approx - np.array(model.contact_force(x0 + d, y0 + d, K, mu_c))))
    slope = np.polyfit(np.log(deltas), np.log(errs), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.05)


def test_linearised_system_reproduces_rhs_at_expansion_point():
    s0 = np.array([1.05, -0.4, 0.3, 0.7])
    for regime in (model.SLIP_POSITIVE, model.SLIP_NEGATIVE):
        mu_c = P.mu * model.friction_sign(regime)
        A, b = model.linearised_contact_system(s0, P, mu_c)
        tau = 0.37
        q = np.array([0, 0, P.E * math.cos(P.eta * tau), P.E * math.sin(P.eta * tau)])
        np.testing.assert_allclose(A @ s0 + b + q, model.rhs(tau, s0, P, regime), atol=1e-12)
        np.testing.assert_allclose(A, model.rhs_jacobian(tau, s0, P, regime), atol=1e-12)


@pytest.mark.parametrize("nu", [0.0, 0.009478, 0.5, 1.0, 2.5])
def test_free_flight_satisfies_the_ode(nu):
    """Residual of the closed form in the free ODE, by central differences (independent)."""
    p = ModelParams(nu=nu, eta=0.7818, e=0.3, K=17.6, phi0=0.4)
    s0 = (0.2, -0.1, 0.3, -0.05)
    tau = np.linspace(0.5, 20.0, 7)
    d = 1e-5
    S = model.free_flight(tau, 0.0, s0, p)
    dS = (model.free_flight(tau + d, 0.0, s0, p) - model.free_flight(tau - d, 0.0, s0, p)) / (2 * d)
    rhs = np.array([model.rhs(t, S[:, i], p, model.FREE) for i, t in enumerate(tau)]).T
    np.testing.assert_allclose(dS, rhs, atol=1e-8)
    np.testing.assert_allclose(model.free_flight(0.0, 0.0, s0, p), s0, atol=1e-15)


def test_synchronous_rub_radius_matches_notes():
    p = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.0, Rp=46.16)
    radii = model.synchronous_rub_radii(p)
    assert radii[-1] == pytest.approx(1.23389475778, abs=1e-10)  # notes section 5
    assert abs(model.synchronous_rub_amplitude(radii[-1], p)) == pytest.approx(radii[-1])


@pytest.mark.parametrize("mu", [0.0, 0.01, 0.05])
def test_synchronous_rub_satisfies_the_ode(mu):
    p = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=mu, Rp=46.16)
    tau = np.linspace(0.0, 10.0, 9)
    S = model.synchronous_rub(tau, p)
    assert np.allclose(np.hypot(S[0], S[1]), model.synchronous_rub_radii(p)[-1])
    for i, t in enumerate(tau):
        d = model.rhs(t, S[:, i], p, model.SLIP_POSITIVE)
        np.testing.assert_allclose(d[2:], -(p.eta**2) * S[:2, i], atol=1e-12)

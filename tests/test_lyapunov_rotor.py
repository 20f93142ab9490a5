"""The rotor-level Lyapunov estimate (analysis/response/classification.py:
``rotor_propagator`` and the Lyapunov branch of ``classify_solution``) against independent
expectations.

- On the stable synchronous full annular rub with mu = 0 every rotating-frame eigenvalue
  has real part -nu (checked first with ``analysis.orbits.synchronous``): a perturbation decays
  like exp(-nu tau) times a bounded rotation, so the largest exponent is exactly -nu.
- On a quasi-periodic torus (Figure 3 at mu = 0.02, docs/reproduction.md) the largest
  exponent is zero: a shift along the torus neither grows nor decays.
- At mu = 0.04 the motion from the caption's start is a chaotic transient
  (docs/reproduction.md): a positive exponent beyond its error bar.

The propagator is dop853-jit (the DOP853 steps of scipy's dop853, compiled) so that each
test takes well under a few seconds; the budgets are in periods, not in wall time.
"""

import math

import numpy as np
import pytest

from rubcli import model
from rubcli.analysis.orbits.synchronous import synchronous_rubs
from rubcli.analysis.response import classification as rsp
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

NU, ETA, E, K, RP = 0.009478, 0.7818, 7.52, 17.6, 46.16  # Figure 3 caption
FIG3_START = (0.88544, -0.8039, 0.0, 0.0)


def fig3(mu: float) -> ModelParams:
    return ModelParams(nu=NU, eta=ETA, e=E, K=K, mu=mu, Rp=RP)


def test_synchronous_rub_at_mu0_decays_at_rate_nu_in_every_mode():
    """The claim the -nu expectation rests on: with mu = 0 the rotating-frame Jacobian of
    the synchronous rub has four eigenvalues, all with real part -nu (and none real)."""
    (rub,) = synchronous_rubs(fig3(0.0))
    assert rub.stable and rub.forward_slip
    assert np.allclose(rub.eigenvalues.real, -NU, rtol=0.0, atol=1e-12)
    assert np.all(np.abs(rub.eigenvalues.imag) > 1.0)
    # with friction the real parts split: the claim is specific to mu = 0
    (rub_mu,) = synchronous_rubs(fig3(0.02))
    assert np.ptp(rub_mu.eigenvalues.real) > 1e-3


def test_exponent_on_the_stable_synchronous_rub_is_minus_nu():
    p = fig3(0.0)
    on_rub = model.synchronous_rub(np.array([0.0]), p)[:, 0]
    propagate = rsp.rotor_propagator(p, "dop853-jit", rtol=1e-12, atol=1e-14)
    est = rsp.largest_lyapunov(
        propagate, 0.0, on_rub, interval=p.period, n_intervals=200, d0=1e-7,
        transient_intervals=2,
    )  # fmt: skip
    # the error bar must be able to tell -nu from zero, and -nu must lie within it
    assert 3.0 * est.stderr < 0.3 * NU
    assert abs(est.exponent + NU) < 3.0 * est.stderr
    assert est.n_intervals == 200 and est.running.size == 200


def test_classifier_reads_a_section_still_contracting_as_converging():
    """Started 0.01 off the rub, the section has not settled within 1e-4 after 40 periods
    (the offset decays like exp(-nu tau): ~5e-4 left). The section map is linear there
    and contracts by exp(-nu T) a period (every rotating-frame eigenvalue has real part
    -nu at mu = 0): "converging to period 1" with that rate, and no exponent needed."""
    p = fig3(0.0)
    start = model.synchronous_rub(np.array([0.0]), p)[:, 0] + np.array([0.01, 0.0, 0.0, 0.0])
    sol = solve(Problem.from_periods(p, tuple(start), 40, 50), "dop853-jit", rtol=1e-10)
    assert sol.success, sol.message
    response = rsp.classify_solution(sol, transient_periods=20, lyapunov_method="dop853-jit")
    assert (response.kind, response.period) == (rsp.CONVERGING, 1), response.message
    assert response.lyapunov is None
    rate = response.contraction.rate
    assert rate == pytest.approx(math.exp(-NU * p.period), abs=3 * response.contraction.rate_stderr)
    assert response.contraction.rate_stderr < 1e-3


def test_exponent_on_a_quasi_periodic_torus_is_zero():
    """Figure 3 at mu = 0.02: the synchronous rub is unstable and the orbit settles on a
    torus (docs/reproduction.md). 100 periods of transient, 100 of Lyapunov run."""
    p = fig3(0.02)
    (rub,) = synchronous_rubs(p)
    assert not rub.stable  # so the torus, not the rub, is the attractor
    sol = solve(Problem.from_periods(p, FIG3_START, 150, 50), "dop853-jit", rtol=1e-10)
    assert sol.success, sol.message
    response = rsp.classify_solution(
        sol, transient_periods=100, lyapunov_periods=100, lyapunov_method="dop853-jit"
    )
    lyap = response.lyapunov
    assert response.kind == rsp.QUASI_PERIODIC, response.message
    assert lyap is not None and "zero within its error" in response.message
    # zero within its error, and an error small enough to tell zero from -nu
    assert abs(lyap.exponent) <= max(rsp.LYAPUNOV_FLOOR, rsp.LYAPUNOV_SIGMAS * lyap.stderr)
    assert rsp.LYAPUNOV_SIGMAS * lyap.stderr < 0.5 * NU


def test_chaotic_transient_at_mu_004():
    """The paper's method from the caption's start at mu = 0.04 (400 steps per period),
    over 60 periods: the run is in its chaotic transient (docs/reproduction.md: it later
    falls into dry whip or onto a partial-rub torus, a matter of chance that
    `rubcli ensemble cases/paper/fig3-ensemble.toml` counts). A DOP853 Lyapunov run from
    its end, renormalised once per period, d0 = 1e-7: positive beyond three standard
    errors. How long a full-length run stays chaotic, and so the exponent of its last
    100 periods, is what round-off decides."""
    p = fig3(0.04)
    sol = solve(Problem.from_periods(p, FIG3_START, 60, 50), "analytic", steps_per_period=400)
    assert sol.success, sol.message
    response = rsp.classify_solution(
        sol, transient_periods=30, lyapunov_periods=50, lyapunov_method="dop853-jit"
    )
    lyap = response.lyapunov
    assert response.kind == rsp.CHAOTIC, response.message
    assert lyap.exponent > rsp.LYAPUNOV_SIGMAS * lyap.stderr
    assert 0.02 < lyap.exponent < 0.2 and lyap.stderr < 0.05


def test_rotor_propagator_reports_a_failed_solve():
    p = fig3(0.0)
    propagate = rsp.rotor_propagator(p, "dop853-jit", max_steps=3)
    with pytest.raises(RuntimeError, match="dop853-jit failed in the Lyapunov run: step budget"):
        propagate(0.0, np.array(FIG3_START), 10 * p.period)

"""The response classes of the rotor where the section-return and exponent rules failed.

Each case is a short run whose answer is known independently:

- near the Neimark-Sacker point of the paper's machine (mu = 0.0102872) the leading
  multiplier of the synchronous rub turns 51.75 degrees a period, about 360/7, so a
  section that spirals slowly returns close to itself after 7 periods. Its modulus is
  ``exp(g T)`` with ``g`` the largest real part of the rotating-frame eigenvalues
  (``analysis.orbits.synchronous``): the section must be "converging" (|multiplier| < 1) or
  "leaving" (> 1) at that rate, never "period 7" or a torus;
- on the paper's machine with a small unbalance (e = 0.05) and no friction, every
  rotating-frame eigenvalue of the synchronous rub has real part -nu, and the free whirl
  decays exactly like exp(-nu tau): transients contract by exp(-nu T) a period. A
  run-up's transient (started on the rub of the previous speed) and the lightly damped
  free whirl from rest must be "converging to period 1" at that rate.

Sweep settings: dop853-jit at rtol 1e-8, 32 samples a period; a few tenths of a second
per case.
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

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16}
RUN_UP = {"nu": 0.009478, "e": 0.05, "K": 17.6, "mu": 0.0, "Rp": 46.16}
FIG3_START = (0.88544, -0.8039, 0.0, 0.0)


def classify(params, start, periods, transient):
    problem = Problem.from_periods(params, tuple(start), periods, 32)
    sol = solve(problem, "dop853-jit", rtol=1e-8, atol=1e-10)
    assert sol.success, sol.message
    return rsp.classify_solution(
        sol, transient_periods=transient, lyapunov_periods=100, lyapunov_method="dop853-jit"
    )


def leading_multiplier(params) -> complex:
    (rub,) = synchronous_rubs(params)
    eig = rub.eigenvalues[np.argmax(rub.eigenvalues.real)]
    return complex(np.exp(eig * params.period))


@pytest.mark.parametrize("mu", [0.0105, 0.011])
def test_section_leaving_the_rub_past_the_neimark_sacker_point_is_not_period_7(mu):
    """The state a mu sweep carries in: the rub of the previous value (mu = 0.01)."""
    params = ModelParams(mu=mu, **FIG3)
    carried = model.synchronous_rub(np.array([0.0]), ModelParams(mu=0.01, **FIG3))[:, 0]
    result = classify(params, carried, 300, 200)
    assert result.kind == rsp.UNDECIDED and result.reason == rsp.RECORD_TOO_SHORT
    assert result.period == 1 and "leaving" in result.message, result.message
    exact = leading_multiplier(params)
    assert abs(exact) > 1.0  # past the Neimark-Sacker point: the rub repels
    fit = result.contraction
    assert fit.rate == pytest.approx(abs(exact), abs=3 * fit.rate_stderr + 1e-6)
    turn = abs(math.atan2(exact.imag, exact.real)) / (2 * math.pi)
    assert abs(fit.rotation) == pytest.approx(turn, abs=1e-5)


def test_fresh_start_below_the_neimark_sacker_point_is_converging_to_period_1():
    params = ModelParams(mu=0.008, **FIG3)
    result = classify(params, FIG3_START, 300, 200)
    assert (result.kind, result.period) == (rsp.CONVERGING, 1), result.message
    exact = abs(leading_multiplier(params))
    assert exact < 1.0
    assert result.contraction.rate == pytest.approx(exact, abs=1e-5)
    evidence = result.to_dict()["evidence"]
    assert evidence["contraction_rate"] == result.contraction.rate
    assert evidence["rotation_number"] == pytest.approx(51.75 / 360.0, abs=1e-4)


@pytest.mark.parametrize("eta", [3.3, 4.0])
def test_run_up_transient_onto_the_rub_is_converging_not_a_torus(eta):
    """The run-up carries the rub of the previous speed (eta - 0.05) into this one."""
    params = ModelParams(eta=eta, **RUN_UP)
    # the large rub (the one a run-up follows; the smaller is a saddle): at mu = 0 each of
    # its modes decays at -nu
    rub = max(synchronous_rubs(params), key=lambda r: r.r)
    assert np.allclose(rub.eigenvalues.real, -RUN_UP["nu"], atol=1e-12)
    carried = model.synchronous_rub(np.array([0.0]), ModelParams(eta=eta - 0.05, **RUN_UP))
    result = classify(params, carried[:, 0], 200, 150)
    assert (result.kind, result.period) == (rsp.CONVERGING, 1), result.message
    fit = result.contraction
    assert fit.rate == pytest.approx(math.exp(-RUN_UP["nu"] * params.period),
                                     abs=3 * fit.rate_stderr)  # fmt: skip
    assert fit.rate_stderr < 5e-3


@pytest.mark.parametrize("eta", [4.3, 4.8])
def test_lightly_damped_free_whirl_is_converging_not_period_4_or_5(eta):
    """From rest the free whirl (no contact: z ~ 0.05) carries its homogeneous part,
    decaying like exp(-nu tau) and turning by the natural frequency: the free flight is
    linear, so the section map is exactly linear."""
    params = ModelParams(eta=eta, **RUN_UP)
    result = classify(params, (0.0, 0.0, 0.0, 0.0), 200, 150)
    assert (result.kind, result.period) == (rsp.CONVERGING, 1), result.message
    assert result.contraction.rate == pytest.approx(math.exp(-RUN_UP["nu"] * params.period),
                                                    abs=1e-7)  # fmt: skip
    beta = math.sqrt(1.0 - RUN_UP["nu"] ** 2)  # damped natural frequency
    turn = (beta * params.period / (2 * math.pi)) % 1.0
    assert abs(result.contraction.rotation) == pytest.approx(min(turn, 1 - turn), abs=1e-7)


def test_every_claim_the_docs_name_is_in_the_claims_script():
    """docs/claims.py regenerates the numbers that docs/ quotes next to its name."""
    import importlib.util
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("claims", root / "docs" / "claims.py")
    claims = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(claims)
    named = set()
    for path in [root / "README.md", *(root / "docs").glob("*.md")]:
        named |= set(re.findall(r"python docs/claims\.py ([a-z-]+)", path.read_text()))
    assert named and named <= set(claims.CLAIMS), named - set(claims.CLAIMS)

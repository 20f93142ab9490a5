"""The general machine (docs/machines.md): an offset stator, a static load, anisotropic
and cross-coupled supports. Checked against exact solutions (the static equilibrium
S w = g, the steady forced response of the 2x2 complex system, the free whirl's
eigenvalues and the self-excitation threshold of cross-coupling), the energy balance
with every term, the paper's machine as the default, and the methods against each
other on rubbing cases with stick and slip."""

from __future__ import annotations

import csv
import json
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.energy.balance import energy_balance, energy_totals, mechanical_energy
from rubcli.case import CaseError, load_case_text
from rubcli.cli.app import app
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.solvers.registry import GENERAL_MACHINE, RTOL, SPECS, options_for

REPO = Path(__file__).resolve().parents[1]
GENERAL_METHODS = [name for name, spec in SPECS.items() if GENERAL_MACHINE in spec.features]
INTEGRATORS = [name for name in GENERAL_METHODS if SPECS[name].knob == RTOL]
STIFFNESS = ((1.0, 0.15), (-0.1, 1.6))  # anisotropic, cross-coupled (q = 0.125)
DAMPING = ((0.05, 0.01), (0.0, 0.08))


def general(**overrides) -> ModelParams:
    values = dict(nu=0.0, eta=0.7, e=0.05, K=50.0, mu=0.1, Rp=2.0, offset=(0.1, -0.05),
                  load=(0.0, -0.3), stiffness=STIFFNESS, damping=DAMPING)  # fmt: skip
    return ModelParams(**{**values, **overrides})


def forced_response(p: ModelParams, t: np.ndarray) -> np.ndarray:
    """States (4, n) of the steady response without contact (docs/machines.md, reference
    2): w = Re(W exp(i (eta tau + phi0))) + S^{-1} g with (S - eta^2 I + 2 i eta D) W =
    e eta^2 (1, -i), relative to the stator's centre (d = w - c)."""
    S, D = np.array(p.stiffness), np.array(p.damping_matrix)
    W = np.linalg.solve(S - p.eta**2 * np.eye(2) + 2j * p.eta * D, p.E * np.array([1.0, -1.0j]))
    rest = np.linalg.solve(S, np.array(p.load)) - np.array(p.offset)
    turn = np.exp(1j * (p.eta * t + p.phi0))
    w = np.real(np.outer(W, turn)) + rest[:, None]
    v = np.real(np.outer(1j * p.eta * W, turn))
    return np.vstack((w, v))


def test_the_paper_machine_is_the_default_and_its_record_departs_by_nothing():
    p = ModelParams(nu=0.05, eta=1.2, e=0.3, K=20.0, mu=0.1, Rp=2.0)
    assert p.is_paper_machine and p.machine_dict() == {}
    assert model.params_vector(p)[model.P_SXX :] == (0.0,) * (model.N_PARAMS - model.P_SXX)
    # an isotropic damping matrix is the paper's nu: every method runs it
    iso = ModelParams(nu=0.0, eta=1.2, e=0.3, K=20.0, damping=((0.05, 0.0), (0.0, 0.05)))
    assert iso.is_paper_machine and iso.nu == 0.05


def test_the_static_position_solves_S_w_equals_g():
    p = general(e=0.0)
    d = np.array(p.static_position())
    w = d + np.array(p.offset)
    assert np.allclose(np.array(p.stiffness) @ w, p.load, rtol=0, atol=1e-15)


@pytest.mark.parametrize("method", GENERAL_METHODS)
def test_a_rotor_at_its_static_position_stays_there(method):
    """e = 0 and no contact: the static equilibrium is a fixed point of every method."""
    p = general(e=0.0)
    start = (*p.static_position(), 0.0, 0.0)
    tight = options_for(method, {"rtol": 1e-10, "atol": 1e-12})
    sol = solve(Problem(p, start, np.linspace(0.0, 30.0, 31)), method, **tight)
    assert sol.success and len(sol.events) == 0
    assert np.abs(sol.states - np.array(start)).max() < 1e-10


@pytest.mark.parametrize("method", GENERAL_METHODS)
def test_the_forced_response_without_contact_is_the_closed_form(method):
    """Started on the steady response of the anisotropic, cross-coupled, offset and
    loaded rotor, every method stays on it within its tolerance (it never reaches the
    clearance: |d| <= 0.19)."""
    p = general()
    t = np.linspace(0.0, 40.0, 401)
    exact = forced_response(p, t)
    assert np.hypot(exact[0], exact[1]).max() < 0.5
    tight = options_for(method, {"rtol": 1e-10, "atol": 1e-12})  # analytic: exact here
    sol = solve(Problem(p, tuple(exact[:, 0]), t), method, **tight)
    assert sol.success and len(sol.events) == 0
    assert np.abs(sol.states.T - exact).max() < 1e-7


def test_cross_coupling_whirls_on_its_own_above_twice_the_damping():
    """S = [[1, q], [-q, 1]], D = nu I: S w = (1 - i q) w in complex form, so the free
    rotor's exponents solve l^2 + 2 nu l + 1 - i q = 0; the forward mode grows when
    q > 2 nu (the classical threshold at the natural frequency). The amplitude of a
    small whirl grows (decays) at the root's real part."""
    nu = 0.02
    for q in (0.03, 0.05):  # below and above 2 nu = 0.04
        p = ModelParams(nu=nu, eta=1.0, e=0.0, K=20.0, stiffness=((1.0, q), (-q, 1.0)))
        roots = np.roots([1.0, 2.0 * nu, 1.0 - 1j * q])
        growth = max(roots.real)
        lam = roots[np.argmax(roots.real)]
        a = 1e-3  # a pure forward mode: w = a exp(lam tau)
        start = (a, 0.0, (a * lam).real, (a * lam).imag)
        t = np.linspace(0.0, 200.0, 201)
        sol = solve(Problem(p, start, t), "taylor", rtol=1e-12, atol=1e-16)
        radius = np.hypot(sol.x, sol.y)
        assert np.allclose(radius, a * np.exp(growth * t), rtol=1e-8, atol=0)
        assert (growth > 0) == (q > 2 * nu)


def test_the_anisotropic_threshold_of_cross_coupling_is_the_closed_form():
    """S = [[1, q], [-q, 1 + delta]], D = nu I: det(l^2 + 2 nu l + S) = 0 gives
    (l^2 + 2 nu l + 1 + delta/2)^2 = delta^2/4 - q^2, and a root crosses the imaginary axis
    at l = i omega, omega^2 = 1 + delta/2, where q_th^2 = delta^2/4 + 4 nu^2 (1 + delta/2)
    (cases/machines/cross-coupled.toml: 0.0647). Checked on the free-flight system's
    eigenvalues (model.free_flight_system) and by time integration on either side: an
    e = 0 rotor started near rest grows past the clearance above q_th and decays below."""
    nu, delta = 0.02, 0.1
    q_th = np.sqrt(delta**2 / 4 + 4 * nu**2 * (1 + delta / 2))
    assert q_th == pytest.approx(0.0647, abs=5e-5)
    for q, grows in ((0.98 * q_th, False), (1.02 * q_th, True), (0.8 * q_th, False),
                     (1.3 * q_th, True)):  # fmt: skip
        p = ModelParams(nu=nu, eta=0.6, e=0.0, K=20.0, mu=0.1, Rp=2.0,
                        stiffness=((1.0, q), (-q, 1.0 + delta)))  # fmt: skip
        lam = np.linalg.eigvals(model.free_flight_system(p)[0])
        assert (lam.real.max() > 0) == grows
        if abs(q / q_th - 1.0) < 0.1:  # too slow to integrate: the eigenvalues decide
            continue
        t = np.linspace(0, 10.0 / abs(lam.real.max()), 1001)  # ten e-folds of the mode
        sol = solve(Problem(p, (0.01, 0.0, 0.0, 0.0), t), "taylor", rtol=1e-10, atol=1e-14)
        assert sol.success
        assert (sol.n_contact_switches > 0) == grows
        if not grows:
            assert np.hypot(sol.x[-1], sol.y[-1]) < 0.01


def test_small_oscillations_about_a_loaded_contact_are_the_linear_modes():
    """mu = 0, e = 0, D = 0, a load pressing the rotor into an offset stator on an
    anisotropic support: the rotor rests in permanent contact at d* with g - S (d* + c) =
    K (1 - 1/z) d* (solved here by scipy's fsolve), and a small displacement from it moves
    as the linearised system's exp(A tau) (scipy's expm), A = [[0, I], [-(S + K_t), 0]]
    with the contact's tangent stiffness K_t = K ((1 - 1/z) I + (1/z) n n^T)."""
    from scipy.linalg import expm
    from scipy.optimize import fsolve

    S = np.array([[1.0, 0.2], [0.2, 1.5]])
    p = ModelParams(nu=0.0, eta=1.0, e=0.0, K=20.0, offset=(0.2, -0.1), load=(0.3, -2.5),
                    stiffness=((1.0, 0.2), (0.2, 1.5)))  # fmt: skip
    g, c = np.array(p.load), np.array(p.offset)

    def residual(d: np.ndarray) -> np.ndarray:
        z = np.hypot(*d)
        return g - S @ (d + c) - p.K * (1.0 - 1.0 / z) * d

    rest = fsolve(residual, np.array([0.0, -1.2]), xtol=1e-14)
    z = np.hypot(*rest)
    assert z > 1.04 and np.abs(residual(rest)).max() < 1e-13
    n = rest / z
    Kt = p.K * ((1.0 - 1.0 / z) * np.eye(2) + np.outer(n, n) / z)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-(S + Kt), np.zeros((2, 2))]])
    kick = 1e-6 * np.array([0.3, -0.7, 0.5, 0.2])
    t = np.linspace(0.0, 20.0, 201)
    linear = np.array([np.concatenate((rest, (0.0, 0.0))) + expm(A * tau) @ kick for tau in t])
    for method in ("taylor", "dop853-jit", "analytic"):
        tight = {"steps_per_period": 4000, "rtol": 1e-13, "atol": 1e-16}
        options = options_for(method, tight)
        sol = solve(Problem(p, tuple(linear[0]), t), method, **options)
        assert sol.success and sol.n_contact_switches == 0
        # the nonlinearity's share: |kick|^2; the method's own below it
        assert np.abs(sol.states - linear).max() < 1e-11, method


def rubbing_cases() -> dict[str, ModelParams]:
    """Two rubs on the general machine: a partial rub with long stick episodes (low
    speed, a heavy unbalance) and a fast one with stick, slip reversals and contacts."""
    base = dict(nu=0.0, K=20.0, mu=0.4, Rp=1.0, offset=(0.2, 0.1), load=(0.0, -1.5),
                stiffness=((1.0, 0.1), (-0.1, 1.3)),
                damping=((0.05, 0.0), (0.01, 0.07)))  # fmt: skip
    return {
        "slow": ModelParams(**base, eta=0.3, e=1.0),
        "fast": ModelParams(**base, eta=1.5, e=0.3),
    }


@pytest.mark.slow
@pytest.mark.parametrize("name", ["slow", "fast"])
def test_the_methods_agree_with_a_tight_reference_on_a_rub_with_stick(name):
    """Every integrator that runs the general machine finds the events of DOP853 at 1e-13
    (the same kinds, as many) and lies near it, closer at a tighter tolerance."""
    p = rubbing_cases()[name]
    problem = Problem(p, (0.0, 0.0, 0.0, 0.0), np.linspace(0.0, 60.0, 601))
    ref = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-15)
    kinds = Counter(ev.kind for ev in ref.events)
    assert kinds["stick_entry"] >= 3 and kinds["contact_entry"] >= 10
    for method in INTEGRATORS:
        errors = []
        for rtol in (1e-7, 1e-10):
            sol = solve(problem, method, rtol=rtol, atol=rtol * 1e-2)
            assert sol.success, (method, sol.message)
            assert Counter(ev.kind for ev in sol.events) == kinds, method
            errors.append(np.abs(sol.states - ref.states).max())
        assert errors[1] < 1e-5, (method, errors)
        assert errors[1] < errors[0] or errors[0] < 1e-9, (method, errors)


@pytest.mark.parametrize("compiled", [True, False])
def test_the_analytic_method_converges_at_order_two_on_the_general_machine(compiled):
    """The paper's local linearisation on the general machine (its free flight the exact
    linear propagator, its contact the linearised one with the support's departures):
    the same events as the reference, and the error falls at the method's order 2 as
    the step halves (observed order within 1.7-2.3), compiled slip steps or Python."""
    p = rubbing_cases()["slow"]
    problem = Problem(p, (0.0, 0.0, 0.0, 0.0), np.linspace(0.0, 60.0, 601))
    ref = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-15)
    kinds = Counter(ev.kind for ev in ref.events)
    errors = []
    for steps in (400, 800, 1600):
        sol = solve(problem, "analytic", steps_per_period=steps, compiled=compiled)
        assert sol.success and Counter(ev.kind for ev in sol.events) == kinds
        errors.append(np.abs(sol.states - ref.states).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 1.7) & (orders < 2.3)), (errors, orders)


def test_the_energy_balance_closes_with_every_term_of_the_general_machine():
    """Support potential (with the load and the offset), contact, damping matrix,
    friction in slip and stick, and the cross-coupling's work: the residual is the
    quadrature's, and falls at order 4 with the sample spacing."""
    p = rubbing_cases()["fast"]
    residuals = []
    for samples in (400, 1600):
        problem = Problem.from_periods(p, (0.0, 0.0, 0.0, 0.0), 15, samples)
        sol = solve(problem, "taylor", rtol=1e-13, atol=1e-15)
        assert {ev.kind for ev in sol.events} >= {"stick_entry", "contact_exit"}
        balance = energy_balance(sol)
        totals = energy_totals(sol)
        assert totals.cross_coupling == pytest.approx(balance.cross_coupling[-1], rel=1e-12)
        assert totals.cross_coupling != 0.0
        residuals.append(balance.relative_residual)
    assert residuals[1] < 1e-11
    assert residuals[0] / residuals[1] > 4**4 / 2  # order 4, with margin


def test_the_energy_of_an_undamped_frictionless_anisotropic_rotor_is_conserved():
    """mu = 0, D = 0, e = 0, a symmetric anisotropic support and an offset stator: the
    mechanical energy (kinetic, support, contact) is constant sample by sample, over
    many contacts."""
    p = ModelParams(nu=0.0, eta=1.0, e=0.0, K=30.0, offset=(0.3, -0.2),
                    stiffness=((1.0, 0.2), (0.2, 2.0)))  # fmt: skip
    problem = Problem(p, (0.0, 0.0, 1.5, 0.7), np.linspace(0.0, 50.0, 501))
    sol = solve(problem, "taylor", rtol=1e-13, atol=1e-15)
    assert sol.n_contact_switches >= 20
    energy = sum(mechanical_energy(sol.states, p, sol.regimes))
    assert np.abs(energy - energy[0]).max() < 1e-10 * energy[0]


def test_the_polar_method_refuses_the_general_machine_by_name():
    problem = Problem(general(), (0.0, 0.0, 0.0, 0.0), np.linspace(0.0, 1.0, 3))
    with pytest.raises(ValueError, match="analytic-polar does not run the general machine"):
        solve(problem, "analytic-polar")


CASE = """
[case]
name = "general"
[model]
eta = 1.5
e = 0.3
K = 20.0
mu = 0.4
Rp = 1.0
offset = [0.2, 0.1]
load = [0.0, -1.5]
stiffness = [[1.0, 0.1], [-0.1, 1.3]]
damping = [[0.05, 0.0], [0.01, 0.07]]
[initial]
x = 0.0
y = 0.0
vx = 0.0
vy = 0.0
[time]
periods = 5
samples_per_period = 50
"""


def test_a_case_file_describes_the_general_machine():
    case = load_case_text(CASE)
    p = case.params
    assert p.offset == (0.2, 0.1) and p.load == (0.0, -1.5) and p.nu == 0.0
    assert p.damping == ((0.05, 0.0), (0.01, 0.07))
    assert case.methods == ["analytic", "rk45"]  # the default, as on the paper's machine


@pytest.mark.parametrize(
    ("change", "field", "why"),
    [
        ("nu = 0.05\n", "damping", "given twice"),
        ("", "stiffness", "positive-definite"),
        ("", "solver.methods", "analytic-polar does not run the general machine"),
    ],
)
def test_bad_general_machines_are_refused_naming_the_field(change, field, why):
    text = CASE.replace("mu = 0.4\n", "mu = 0.4\n" + change)
    if field == "stiffness":
        text = text.replace("[[1.0, 0.1], [-0.1, 1.3]]", "[[1.0, 2.0], [2.0, 1.3]]")
    if field == "solver.methods":
        text += '[solver]\nmethods = ["analytic-polar"]\n'
    with pytest.raises(CaseError) as info:
        load_case_text(text)
    assert field in str(info.value) and why in str(info.value)


def test_the_physical_table_converts_the_general_machine_once():
    """SI values: offset in m, load in N, stiffness in N/m over k_r, damping in N s/m over
    2 m omega."""
    text = """
[case]
name = "si"
[physical]
m = 10.0
k_r = 1.0e6
k_s = 2.0e7
clearance = 1.0e-4
e = 5.0e-5
Omega = 400.0
mu = 0.1
offset = [2.0e-5, 0.0]
load = [0.0, -98.1]
stiffness = [[1.0e6, 1.0e5], [-1.0e5, 1.5e6]]
damping = [[200.0, 0.0], [0.0, 300.0]]
[initial]
x = 0.0
y = 0.0
vx = 0.0
vy = 0.0
[time]
periods = 2
samples_per_period = 20
"""
    p = load_case_text(text).params
    omega = 316.22776601683796
    assert p.offset == pytest.approx((0.2, 0.0))
    assert p.load == pytest.approx((0.0, -0.981))
    assert p.stiffness == ((1.0, 0.1), (-0.1, 1.5))
    assert p.damping[0][0] == pytest.approx(200.0 / (2 * 10.0 * omega))
    assert p.damping[1][1] == pytest.approx(300.0 / (2 * 10.0 * omega))


def test_run_writes_the_rotor_position_and_echoes_the_machine(tmp_path):
    case = tmp_path / "general.toml"
    case.write_text(CASE + f'[output]\ndir = "{tmp_path / "out"}"\n')
    result = CliRunner().invoke(app, ["run", str(case), "--method", "dop853-jit"])
    assert result.exit_code == 0, result.output
    out = tmp_path / "out"
    report = json.loads((out / "report.json").read_text())
    params = report["case"]["nondimensional"]["params"]
    assert params["offset"] == [0.2, 0.1] and params["stiffness"] == [[1.0, 0.1], [-0.1, 1.3]]
    rows = np.genfromtxt(out / "dop853-jit.csv", delimiter=",", names=True)
    assert np.allclose(rows["rotor_x"], rows["x"] + 0.2, rtol=0, atol=1e-15)
    assert np.allclose(rows["rotor_y"], rows["y"] + 0.1, rtol=0, atol=1e-15)


def test_orbits_shoots_and_continues_on_the_general_machine(tmp_path):
    """`rubcli orbits` on the misaligned stator: the period-one partial rub of the run,
    found by shooting from the end of a transient, continued in eta; its stroboscopic
    point is the run's (to the shooting tolerance) and the synchronous rub's closed form
    (the paper machine's) is refused as a start."""
    base = (REPO / "cases" / "machines" / "misaligned.toml").read_text()
    text = base.replace('dir = "out/misaligned"', f'dir = "{tmp_path / "out"}"')
    orbits = '\n[orbits]\nparameter = "eta"\nmin = 1.09\nmax = 1.12\nstep = 0.01\n'
    path = tmp_path / "case.toml"
    path.write_text(text + orbits + 'start = "synchronous_rub"\n')
    refused = CliRunner().invoke(app, ["orbits", str(path)])
    assert refused.exit_code == 2 and "closed form on the paper's machine only" in refused.output
    path.write_text(text + orbits + 'start = "transient"\ntransient_periods = 100\n')
    result = CliRunner().invoke(app, ["orbits", str(path), "--quick"])
    assert result.exit_code == 0, result.output
    branch = np.genfromtxt(tmp_path / "out" / "orbits" / "branch.csv", delimiter=",", names=True)
    at = np.argmin(np.abs(branch["value"] - 1.1))
    case = load_case_text(base)
    sol = solve(case.problem, "dop853-jit", rtol=1e-11, atol=1e-13)
    end = sol.states[-1]  # 60 periods: the transient has decayed by exp(-0.05 * 340)
    assert branch["value"][at] == pytest.approx(1.1, abs=1e-12)
    assert np.hypot(branch["x"][at] - end[0], branch["y"][at] - end[1]) < 1e-6


@pytest.mark.slow
def test_compare_measures_every_method_against_a_numerical_reference(tmp_path):
    """The paper machine's exact references (free flight, synchronous rub) are not the
    general machine's: compare takes the numerical one, and each method's error falls as
    its setting tightens (the analytic method at order 2: 16 times per fourfold steps,
    within 10-22)."""
    base = (REPO / "cases" / "machines" / "misaligned.toml").read_text()
    path = tmp_path / "case.toml"
    path.write_text(base.replace('dir = "out/misaligned"', f'dir = "{tmp_path / "out"}"'))
    result = CliRunner().invoke(app, ["compare", str(path), "--quick"])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "out" / "compare" / "report.json").read_text())
    assert not report["reference"]["kind"].startswith("exact")
    with open(tmp_path / "out" / "compare" / "work_precision.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    for method in ("analytic", "dop853-jit", "taylor"):
        errors = [float(r["error_max"]) for r in rows if r["method"] == method]
        assert errors == sorted(errors, reverse=True) and errors[-1] < 1e-4, (method, errors)
    analytic = [float(r["error_max"]) for r in rows if r["method"] == "analytic"]
    assert all(10 < a / b < 22 for a, b in zip(analytic, analytic[1:], strict=False))

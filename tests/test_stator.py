"""A stator with its own mass (rubcli.stator, docs/machines.md): two bodies, ten states.

Checked against exact and independent references: the two bodies' linear normal modes
in permanent contact about a static preload (the eigenvectors of the linearised
system, each returning after its own period), a very heavy, very stiff stator
approaching the rigid one, the conservation of energy without damping and friction,
the energy balance with every term converging at its rule's order, the rolling
constraint's projection (momentum kept), and every method that runs it against a
tight ``dop853-jit`` and against scipy's own DOP853 in Python."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import fsolve
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.energy.two_body import energy_at, two_body_energy_summary
from rubcli.analysis.orbits import periodic as orbits
from rubcli.case import CaseError, load_case, load_case_text
from rubcli.cli.app import app
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.solvers.registry import MOVING_STATOR, RTOL, SPECS
from rubcli.solvers.rub import friction_force, normal_force, slip_velocity
from rubcli.solvers.two_body import full_states
from rubcli.stator import Stator, two_body_projection

REPO = Path(__file__).resolve().parents[1]
STATOR_METHODS = [name for name, spec in SPECS.items() if MOVING_STATOR in spec.features]
RING = Stator(0.2, (2.0, 4.0), (0.05, 0.05))


def ring_machine(**overrides) -> ModelParams:
    values = dict(nu=0.05, eta=1.2, e=0.25, K=10.0, mu=0.1, Rp=3.0, offset=(0.3, 0.0),
                  stiffness=((1.0, 0.0), (0.0, 1.3)), stator=RING)  # fmt: skip
    return ModelParams(**{**values, **overrides})


def rotor_and_ring(solution) -> np.ndarray:
    """The rotor's position from its support's centre and the ring's, (4, n)."""
    c = np.array(solution.problem.params.offset)
    s = solution.stator_states[:, :2]
    return np.vstack([(solution.states[:, :2] + s + c).T, s.T])


def test_the_ring_moves_and_the_rigid_stator_is_the_default():
    p = ring_machine()
    assert not p.is_paper_machine and "stator m=0.2" in p.machine_text()
    assert dataclasses.replace(p, stator=None).stator is None
    with pytest.raises(ValueError, match="mass must be > 0"):
        Stator(-1.0, (1.0, 1.0))
    with pytest.raises(ValueError, match=r"stiffness\[1\] must be > 0"):
        Stator(1.0, (1.0, 0.0))
    with pytest.raises(ValueError, match=r"damping\[0\] must be >= 0"):
        Stator(1.0, (1.0, 1.0), (-0.1, 0.0))
    problem = Problem.from_periods(p, (-0.3, 0.0, 0.0, 0.0), 20, 50)
    sol = solve(problem, "dop853-jit", rtol=1e-10, atol=1e-12)
    assert sol.success and sol.contact_fraction() > 0.2
    assert np.max(np.abs(sol.stator_states[:, :2])) > 0.1  # struck, the ring moves
    assert sol.stator_events.shape == (len(sol.events), 4)


def _preloaded(K: float, load: float, stator: Stator, S: np.ndarray):
    """The loaded equilibrium of rotor and ring in permanent contact (mu = 0, e = 0):
    the rotor's position w, the ring's s, and the linearised stiffness and mass."""
    g = np.array([load, 0.0])
    ks = np.diag(stator.stiffness)

    def residual(q: np.ndarray) -> np.ndarray:
        w, s = q[:2], q[2:]
        d = w - s
        z = np.linalg.norm(d)
        F = -K * (z - 1.0) * d / z
        return np.concatenate((-S @ w + g + F, -ks @ s - F))

    q = fsolve(residual, np.array([1.2, 0.0, 0.1, 0.0]), xtol=1e-13, full_output=True)[0]
    assert np.max(np.abs(residual(q))) < 1e-13
    w, s = q[:2], q[2:]
    d = w - s
    z = np.linalg.norm(d)
    n = d / z
    Kt = K * ((1.0 - 1.0 / z) * np.eye(2) + np.outer(n, n) / z)  # tangent contact stiffness
    stiffness = np.block([[S + Kt, -Kt], [-Kt, ks + Kt]])
    mass = np.diag([1.0, 1.0, stator.mass, stator.mass])
    return w, s, stiffness, mass


@pytest.mark.parametrize("mode", range(4))
def test_two_body_normal_modes_in_permanent_contact(mode):
    """Reference 4 of general-machine.md: about a static preload pressing the rotor into
    the ring (mu = 0, e = 0, no damping), each linear mode of the two bodies, started
    small along its eigenvector, is reversed after half its period and back after a
    whole one; the modes come from the generalised eigenproblem K q = omega^2 M q."""
    stator = Stator(0.5, (4.0, 6.0))
    S = np.array([[1.0, 0.0], [0.0, 1.4]])
    K, load = 10.0, 1.6
    w, s, stiffness, mass = _preloaded(K, load, stator, S)
    assert np.linalg.norm(w - s) > 1.0  # in contact
    omega2, vectors = np.linalg.eig(np.linalg.solve(mass, stiffness))
    order = np.argsort(omega2.real)
    omega = np.sqrt(omega2.real[order][mode])
    phi = vectors[:, order][:, mode].real
    phi /= np.max(np.abs(phi))
    a = 1e-5
    params = ModelParams(nu=0.0, eta=1.0, e=0.0, K=K, stiffness=tuple(map(tuple, S)),
                         load=(load, 0.0), stator=stator)  # fmt: skip
    q0 = np.concatenate((w, s)) + a * phi
    period = 2.0 * np.pi / omega
    problem = Problem(params, (*(q0[:2] - q0[2:]), 0.0, 0.0), np.array([0.0, period / 2, period]),
                      stator_initial=(*q0[2:], 0.0, 0.0))  # fmt: skip
    sol = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-15)
    assert sol.success and len(sol.events) == 0  # never leaves contact
    q = rotor_and_ring(sol)
    rest = np.concatenate((w, s))
    assert np.max(np.abs(q[:, 1] - (rest - a * phi))) < 2e-3 * a  # half a period: reversed
    assert np.max(np.abs(q[:, 2] - q0)) < 2e-3 * a  # a whole one: back
    # and not back at another mode's period: the frequencies are told apart
    others = np.sqrt(np.sort(omega2.real))
    assert np.min(np.abs(np.delete(others, mode) - omega)) > 0.05 * omega


def test_a_heavy_stiff_stator_approaches_the_rigid_one():
    """Reference 5: the ring's deflection under the rub's force goes as 1/k_s, so the
    distance from the rigid stator's run falls about a hundredfold per hundredfold
    stiffness (the ring's own frequency held at 20)."""
    base = dict(nu=0.05, eta=1.1, e=0.3, K=20.0, mu=0.1, Rp=3.0)
    problem = Problem.from_periods(ModelParams(**base), (0.0, 0.0, 0.0, 0.0), 10, 20)
    rigid = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14)
    distances = []
    for k in (1e3, 1e5, 1e7):
        ring = Stator(k / 400.0, (k, k), (0.0, 0.0))
        two = solve(dataclasses.replace(problem, params=ModelParams(**base, stator=ring)),
                    "dop853-jit", rtol=1e-12, atol=1e-14)  # fmt: skip
        assert two.success and two.n_contact_switches == rigid.n_contact_switches
        distances.append(np.max(np.abs(two.states - rigid.states)))
    assert distances[1] < distances[0] / 30.0 and distances[2] < distances[1] / 30.0
    assert distances[2] < 1e-4


def test_energy_is_conserved_without_damping_friction_load_or_unbalance():
    """Reference 6: mu = 0, D = 0, n_s = 0, g = 0, e = 0 (an offset stator and an
    anisotropic support kept): the two bodies' energy is constant through the rubs."""
    p = ModelParams(nu=0.0, eta=1.0, e=0.0, K=30.0, offset=(0.2, 0.1),
                    stiffness=((1.0, 0.2), (0.2, 1.5)), stator=Stator(0.4, (3.0, 5.0)))  # fmt: skip
    problem = Problem.from_periods(p, (-0.2, -0.1, 1.4, 0.6), 10, 50)
    sol = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14)
    assert sol.success and sol.n_contact_switches > 10
    E = energy_at(p, full_states(sol))
    assert np.max(np.abs(E - E[0])) < 1e-9 * E[0]


def test_energy_balance_closes_at_the_rules_order():
    """Every term (unbalance, rotor and ring damping, cross-coupling, friction with the
    spin's share, load): the residual falls as the fourth power of the sample spacing
    (the Hermite rule's order) and matches the rule's own estimate."""
    p = ring_machine(load=(0.0, -0.2), nu=0.0, damping=((0.05, 0.01), (0.0, 0.08)),
                     stiffness=((1.0, 0.1), (-0.05, 1.3)))  # fmt: skip
    residuals = []
    for spp in (200, 400):
        problem = Problem.from_periods(p, (-0.3, 0.0, 0.0, 0.0), 20, spp)
        sol = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14)
        summary = two_body_energy_summary(sol)
        assert summary["cross_coupling_work"] != 0.0 and summary["contact_dissipation"] > 0
        residuals.append(summary["energy_residual"])
        assert summary["energy_residual"] < 3.0 * summary["energy_quadrature_error"] + 1e-10
    order = np.log(residuals[0] / residuals[1]) / np.log(2.0)
    assert 3.5 < order < 4.5
    assert residuals[1] < 1e-7


def test_the_projection_onto_rolling_keeps_momentum():
    x, y, vx, vy, up, vp, spin, m_inv = 1.02, -0.3, 0.4, 0.9, -0.2, 0.1, 0.7, 1.0 / 0.3
    vx2, vy2, up2, vp2 = two_body_projection(x, y, vx, vy, up, vp, spin, m_inv)
    assert model.slip_velocity_value(x, y, vx2, vy2, spin) == pytest.approx(0.0, abs=1e-15)
    rotor = np.array([vx2 + up2 - vx - up, vy2 + vp2 - vy - vp])  # the rotor's change
    ring = np.array([up2 - up, vp2 - vp]) / m_inv  # the ring's momentum change
    assert np.allclose(rotor + ring, 0.0, atol=1e-15)
    normal = np.array([x, y]) / np.hypot(x, y)
    assert abs(rotor @ normal) < 1e-15  # a tangential impulse


def _stick_machine() -> ModelParams:
    # a heavy, high-friction rub on a rotor too slow to whip: the rotor rolls on the ring
    return ModelParams(nu=0.02, eta=0.9, e=0.6, K=30.0, mu=0.5, Rp=0.2,
                       stator=Stator(0.5, (3.0, 3.0), (0.1, 0.1)))  # fmt: skip


def test_stick_on_a_moving_ring_holds_the_rolling_constraint():
    problem = Problem.from_periods(_stick_machine(), (0.0, 0.0, 0.0, 0.0), 20, 100)
    sol = solve(problem, "dop853-jit", rtol=1e-11, atol=1e-13)
    assert sol.success
    stick = sol.regimes == model.STICK
    assert np.count_nonzero(stick) > 50
    assert np.max(np.abs(slip_velocity(sol)[stick])) < 1e-12
    T = friction_force(sol)[stick]
    assert np.all(np.abs(T) <= 0.5 * normal_force(sol)[stick] * (1.0 + 1e-9))


@pytest.mark.slow
@pytest.mark.parametrize("machine", ["ring", "stick"])
def test_every_method_agrees_with_a_tight_reference(machine):
    p = ring_machine() if machine == "ring" else _stick_machine()
    start = (-0.3, 0.0, 0.0, 0.0) if machine == "ring" else (0.0, 0.0, 0.0, 0.0)
    problem = Problem.from_periods(p, start, 8, 20)
    ref = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14)
    python = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14, compiled=False)
    assert ref.success and python.success
    assert len(python.events) == len(ref.events)
    assert np.max(np.abs(python.states - ref.states)) < 1e-9  # scipy's DOP853 step for step
    for method in (m for m in STATOR_METHODS if SPECS[m].knob == RTOL):
        sol = solve(problem, method, rtol=1e-10, atol=1e-12)
        assert sol.success, (method, sol.message)
        assert list(sol.events.kinds) == list(ref.events.kinds), method
        assert np.allclose(sol.events.tau, ref.events.tau, atol=1e-5), method
        assert np.max(np.abs(sol.states - ref.states)) < 1e-5, method
        assert np.max(np.abs(sol.stator_states - ref.stator_states)) < 1e-5, method


def _errors(problem: Problem, ref, **options) -> tuple[float, object]:
    sol = solve(problem, "analytic", **options)
    assert sol.success, sol.message
    error = max(np.max(np.abs(sol.states - ref.states)),
                np.max(np.abs(sol.stator_states - ref.stator_states)))  # fmt: skip
    return float(error), sol


@pytest.mark.slow
@pytest.mark.parametrize("machine", ["ring", "stick"])
def test_analytic_converges_at_order_two_on_the_two_bodies(machine):
    # the paper's scheme on eight states: exact free flights, slip linearised each step
    # (global order 2), stick by RK4; the same events as a tight reference
    p = ring_machine() if machine == "ring" else _stick_machine()
    start = (-0.3, 0.0, 0.0, 0.0) if machine == "ring" else (0.0, 0.0, 0.0, 0.0)
    problem = Problem.from_periods(p, start, 8, 20)
    ref = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14)
    errors = []
    for n in (200, 400, 800):
        error, sol = _errors(problem, ref, steps_per_period=n)
        assert list(sol.events.kinds) == list(ref.events.kinds), n
        errors.append(error)
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 1.8) & (orders < 2.4)), (errors, orders)
    if machine == "stick":
        assert sol.stats["n_stick_steps"] > 0
        stick = sol.regimes == model.STICK
        assert np.max(np.abs(slip_velocity(sol)[stick])) < 1e-12  # samples on the constraint
    python, _ = _errors(problem, ref, steps_per_period=200, compiled=False)
    assert python == pytest.approx(errors[0], rel=1e-6)  # the interpreter's right-hand side


def test_analytic_free_flight_of_the_two_bodies_is_exact():
    # no contact: both bodies linear, the closed form exact whatever the step
    p = ring_machine(e=0.05, offset=(0.0, 0.0), load=(0.0, -0.1))
    problem = dataclasses.replace(Problem.from_periods(p, (0.0, 0.0, 0.1, 0.0), 6, 20),
                                  stator_initial=(0.05, 0.0, 0.0, 0.2))  # fmt: skip
    ref = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-15)
    assert len(ref.events) == 0 and np.max(ref.z) < 0.9
    error, sol = _errors(problem, ref, steps_per_period=4)
    assert error < 1e-10 and sol.stats["n_free_segments"] == 1


@pytest.mark.slow
def test_analytic_step_doubling_follows_its_tolerance():
    problem = Problem.from_periods(ring_machine(), (-0.3, 0.0, 0.0, 0.0), 4, 20)
    ref = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14)
    loose, _ = _errors(problem, ref, analytic_tol=1e-6)
    tight, sol = _errors(problem, ref, analytic_tol=1e-9)
    assert list(sol.events.kinds) == list(ref.events.kinds)
    # local error ~ h^3 and steps ~ tol^(-1/3): the global error falls about as tol^(2/3)
    assert 30.0 < loose / tight < 3000.0 and tight < 1e-5
    assert sol.settings["analytic_tol"] == 1e-9


def test_the_methods_without_it_refuse_naming_the_feature():
    problem = Problem.from_periods(ring_machine(), (-0.3, 0.0, 0.0, 0.0), 1, 20)
    with pytest.raises(ValueError, match="stator with its own mass"):
        solve(problem, "analytic-polar")


CASE = """
[case]
name = "ring"
[model]
nu = 0.05
eta = 1.2
e = 0.25
K = 10.0
mu = 0.1
Rp = 3.0
[stator]
mass = 0.2
stiffness = [2.0, 4.0]
[initial]
x = 0.0
y = 0.0
[time]
periods = 2
samples_per_period = 20
[solver]
methods = ["dop853-jit"]
"""


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("mass = 0.2", "mass = -0.2"), "stator.mass"),
        (("stiffness = [2.0, 4.0]", "stiffness = [2.0, 0.0]"), "stator.stiffness"),
        (('methods = ["dop853-jit"]', 'methods = ["analytic-polar"]'), "solver.methods"),
        (
            (
                "[solver]",
                "[speed]\nprofile = 'ramp'\nstart = 1.0\nend = 1.5\nrate = 0.01\n[solver]",
            ),
            "speed",
        ),
        (("[output]", "[output]"), None),
    ],
)
def test_bad_stator_input_names_the_field(change, message):
    text = CASE.replace(*change)
    if message is None:
        assert load_case_text(text).params.stator == Stator(0.2, (2.0, 4.0))
        return
    with pytest.raises(CaseError, match=message):
        load_case_text(text)


def test_initial_stator_needs_a_stator_and_sets_its_start():
    case = load_case_text(CASE.replace("y = 0.0\n", "y = 0.0\nstator = [0.1, 0.0, 0.0, 0.2]\n"))
    assert case.problem.stator_initial == (0.1, 0.0, 0.0, 0.2)
    sol = solve(case.problem, "dop853-jit")
    assert tuple(sol.stator_states[0]) == (0.1, 0.0, 0.0, 0.2)
    rigid = CASE.replace("[stator]\nmass = 0.2\nstiffness = [2.0, 4.0]\n", "")
    with pytest.raises(CaseError, match="initial.stator: needs a"):
        load_case_text(rigid.replace("y = 0.0\n", "y = 0.0\nstator = [0.1, 0.0, 0.0, 0.0]\n"))


def test_physical_stator_converts_once():
    text = """
[case]
name = "ring-si"
[physical]
m = 10.0
k_r = 1e6
d_r = 316.2
k_s = 1e7
clearance = 1e-4
e = 2e-5
Omega = 350.0
[stator]
mass = 2.0
stiffness = [2e6, 4e6]
damping = [63.2, 126.5]
[initial]
x = 0.0
y = 0.0
[time]
periods = 2
samples_per_period = 20
"""
    p = load_case_text(text).params
    assert p.stator.mass == pytest.approx(0.2)
    assert p.stator.stiffness == pytest.approx((2.0, 4.0))
    assert p.stator.damping == pytest.approx((0.01, 0.02), rel=1e-3)  # over 2 sqrt(k_r m)


@pytest.mark.slow
def test_run_writes_the_ring_columns(tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(
        app, ["run", str(REPO / "cases" / "machines" / "snubber.toml"), "--out", str(out),
              "--periods", "4"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    header = (out / "dop853-jit.csv").read_text().splitlines()[0].split(",")
    assert header[-6:] == ["rotor_x", "rotor_y", "stator_x", "stator_y", "stator_vx", "stator_vy"]
    rows = np.loadtxt(out / "dop853-jit.csv", delimiter=",", skiprows=1,
                      usecols=[header.index(n) for n in ("x", "rotor_x", "stator_x")])  # fmt: skip
    assert np.allclose(rows[:, 1], rows[:, 0] + rows[:, 2] + 0.3, atol=1e-12)  # w = d + s + c
    report = json.loads((out / "report.json").read_text())
    assert report["case"]["nondimensional"]["stator"]["mass"] == 0.2
    energy = report["methods"]["dop853-jit"]["energy"]
    assert energy["energy_residual"] < 3.0 * energy["energy_quadrature_error"] + 1e-9


@pytest.mark.slow
def test_compare_runs_the_ring(tmp_path):
    out = tmp_path / "out"
    case = REPO / "cases" / "machines" / "snubber.toml"
    result = CliRunner().invoke(app, ["compare", str(case), "--out", str(out), "--quick"])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    # the reference checked against lsoda, an independent family, on the two bodies
    assert report["reference"]["error_estimate"] < 1e-8
    rows = report["work_precision"]["rows"]
    assert {row["method"] for row in rows} == {"dop853-jit", "dop853", "analytic"}
    assert all(row["status"] == "success" for row in rows)
    # analytic: order 2, so four times the steps cut the error about sixteenfold
    ladder = sorted((row["setting"], row["error_max"]) for row in rows
                    if row["method"] == "analytic")  # fmt: skip
    ratios = [a[1] / b[1] for a, b in zip(ladder[:-1], ladder[1:], strict=True)]
    assert len(ratios) == 2 and all(8.0 < r < 25.0 for r in ratios), ladder


def test_the_compare_orbit_panel_holds_the_rotors_orbit():
    # the panel is drawn about the support's centre: its axes hold the rotor's own orbit
    # (relative position plus the ring's displacement plus the offset), not the relative
    from rubcli.plotting.compare import orbits_figure

    problem = Problem.from_periods(ring_machine(), (-0.3, 0.0, 0.0, 0.0), 6, 20)
    sol = solve(problem, "dop853-jit")
    fig = orbits_figure([{"title": "ring", "solutions": [sol]}], "ring")
    (x0, x1), (y0, y1) = fig.axes[0].get_xlim(), fig.axes[0].get_ylim()
    w = rotor_and_ring(sol)[:2]
    assert x0 < w[0].min() and w[0].max() < x1 and y0 < w[1].min() and w[1].max() < y1
    assert max(np.ptp(w[0]), np.ptp(w[1])) > 0.6 * (x1 - x0)  # and is not lost in them


def test_the_snubber_case_is_a_moving_stator():
    case = load_case(REPO / "cases" / "machines" / "snubber.toml")
    assert case.params.stator is not None and case.params.offset == (0.3, 0.0)


def _applied_both_ways(run_class: type, problem: Problem, method: str) -> tuple:
    """A system's run with the loop applying its events, and with the loop returning at
    each event for Python to apply it: (solution, run) of each."""
    from rubcli.solvers.extended import solve_extended

    class PythonApplies(run_class):
        loop_applies_events = False

    out = []
    for kind in (run_class, PythonApplies):
        run = kind(problem, method, max_steps=10**6, max_wall_time_s=600.0)
        out.append((solve_extended(run, method, 1e-8, 1e-10, True), run))
    return tuple(out)


@pytest.mark.parametrize("machine", ["snubber", "stick ring", "driven dry whip"])
@pytest.mark.parametrize("method", ["dop853-jit", "taylor"])
def test_the_loops_apply_the_events_as_python_does(machine, method):
    """The compiled loop applies a system's events itself (``events.switch_rule`` with
    the system's stick law, and its projection where stick begins or ends): the same
    events, states at them and end state as when the loop returns at each event and
    Python applies it (``ExtendedRun.switch``). The snubber makes more events than the
    loop's buffer holds (its flush and the segment Python then starts); the ring with
    stick and the driven dry whip stick and slip (the projections)."""
    from rubcli.solvers import driven, two_body
    from rubcli.solvers.extended import EVENT_BUFFER

    if machine == "snubber":
        run_class = two_body.TwoBodyRun
        problem = load_case(REPO / "cases" / "machines" / "snubber.toml").problem
    elif machine == "stick ring":
        run_class = two_body.TwoBodyRun
        problem = Problem.from_periods(_stick_machine(), (0.0, 0.0, 0.0, 0.0), 20, 100)
    else:
        run_class = driven.DrivenRun
        problem = load_case(REPO / "cases" / "runup" / "driven-dry-whip.toml").problem
    (loop, loop_run), (python, _) = _applied_both_ways(run_class, problem, method)
    assert loop.status == python.status == "success"
    kinds = [e.kind for e in loop.events]
    assert kinds == [e.kind for e in python.events]
    assert [e.regime_after for e in loop.events] == [e.regime_after for e in python.events]
    if machine == "snubber":
        assert len(kinds) > EVENT_BUFFER
    else:
        assert {"stick_entry", "stick_exit"} <= set(kinds)
    # the same steps and events; Python evaluates the event's state on its own copy of
    # the dense output (the step's length as t_new - t_old), so to round-off
    np.testing.assert_allclose(loop.events.tau, python.events.tau, rtol=0, atol=1e-9)
    np.testing.assert_allclose(loop.events.state, python.events.state, rtol=0, atol=1e-8)
    np.testing.assert_allclose(loop.states, python.states, rtol=0, atol=1e-7)
    assert loop.stats["nsteps"] == python.stats["nsteps"]
    assert loop.stats["n_segments"] == python.stats["n_segments"]
    if run_class is two_body.TwoBodyRun:
        assert len(loop_run.event_stators) == len(kinds)
        np.testing.assert_allclose(loop.stator_events, python.stator_events, rtol=0, atol=1e-8)


def _multipliers_match(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Each multiplier of ``a`` has one of ``b`` within ``tol`` (and the counts agree)."""
    left = list(b)
    for m in a:
        i = int(np.argmin([abs(m - o) for o in left]))
        if abs(m - left[i]) > tol:
            return False
        left.pop(i)
    return not left


@pytest.mark.slow
def test_the_two_body_monodromy_without_contact_is_the_exponential():
    """Without contact the two bodies are linear and apart: the multipliers of the
    flow's monodromy (one smooth segment's differences) are those of exp(A T) of each
    body."""
    from scipy.linalg import expm

    p = ring_machine(e=0.02, mu=0.0)
    S, D = np.array(p.stiffness), np.array(p.damping_matrix)
    st = p.stator
    ks, ns = np.diag(st.stiffness), np.diag(st.damping)
    rotor = np.block([[np.zeros((2, 2)), np.eye(2)], [-S, -2.0 * D]])
    ring = np.block([[np.zeros((2, 2)), np.eye(2)], [-ks / st.mass, -2.0 * ns / st.mass]])
    expected = np.concatenate([np.linalg.eigvals(expm(M * p.period)) for M in (rotor, ring)])
    orbit = orbits.shoot(p, np.array([-0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), 1)
    assert orbit.flow.max_z < 1.0 and orbit.flow.events == []
    assert _multipliers_match(orbit.multipliers, expected, 1e-6)


@pytest.mark.parametrize("machine", ["ring", "stick"])
def test_the_saltation_monodromy_is_the_flows_differences(machine):
    # the monodromy through the switches (segments' Jacobians, saltation matrices, the
    # rolling projection's Jacobian) against central differences of the whole flow, an
    # independent construction: the perturbed flows switch where their own events lie
    p = ring_machine() if machine == "ring" else _stick_machine()
    start = (-0.3, 0.0, 0.0, 0.0) if machine == "ring" else (0.0, 0.0, 0.0, 0.0)
    sol = solve(Problem.from_periods(p, start, 20, 20), "dop853-jit", rtol=1e-11, atol=1e-13)
    q = np.concatenate((sol.states[-1], sol.stator_states[-1]))
    t0 = float(sol.t[-1])
    result = orbits.flow(p, q, t0, t0 + p.period)
    kinds = {kind for _, kind, _, _ in result.events}
    expected = {"contact_entry", "contact_exit"}
    assert kinds == (expected if machine == "ring" else expected | {"stick_entry", "stick_exit"})
    differences = np.empty((8, 8))
    for j in range(8):
        h = 1e-5 * (1.0 + abs(q[j]))
        ends = [orbits.flow(p, q + sign * h * np.eye(8)[j], t0, t0 + p.period,
                            variational=False).state for sign in (1.0, -1.0)]  # fmt: skip
        differences[:, j] = (ends[0] - ends[1]) / (2.0 * h)
    assert np.max(np.abs(result.monodromy - differences)) < 1e-6


def test_the_two_body_monodromy_across_rubs_keeps_liouvilles_determinant():
    """The contact force and the friction are continuous at z = 1 and the friction in
    slip does not depend on the velocities: across contact entries and exits the
    saltation is the identity and the monodromy's determinant is exp of the trace of
    the damping over the period, exp(-(2 tr D + 2 tr(N_s) / m_s) T) (Liouville)."""
    p = ring_machine()
    guess = orbits.transient_state(p, np.array([-0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), 40)
    orbit = orbits.shoot(p, guess, 1)
    kinds = {kind for _, kind, _, _ in orbit.flow.events}
    assert orbit.flow.contact_phases >= 1 and kinds == {"contact_entry", "contact_exit"}
    trace = 2.0 * np.trace(np.array(p.damping_matrix)) + 2.0 * sum(p.stator.damping) / p.stator.mass
    expected = np.exp(-trace * p.period)
    assert np.linalg.det(orbit.monodromy) == pytest.approx(expected, rel=1e-5)
    # the orbit is one: a run from it returns after a period
    problem = Problem(p, tuple(orbit.state[:4]), np.array([0.0, p.period]),
                      stator_initial=tuple(orbit.state[4:]))  # fmt: skip
    sol = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-14)
    back = np.concatenate((sol.states[-1], sol.stator_states[-1]))
    assert np.max(np.abs(back - orbit.state)) < 1e-8


@pytest.mark.slow
def test_orbits_continues_the_ring_branch(tmp_path):
    out = tmp_path / "out"
    case = REPO / "cases" / "machines" / "snubber.toml"
    result = CliRunner().invoke(app, ["orbits", str(case), "--out", str(out), "--quick"])
    assert result.exit_code == 0, result.output
    header = (out / "branch.csv").read_text().splitlines()[0].split(",")
    assert header[4:12] == ["x", "y", "vx", "vy", "stator_x", "stator_y", "stator_vx",
                            "stator_vy"]  # fmt: skip
    assert "multiplier8_re" in header
    report = json.loads((out / "report.json").read_text())
    assert report["branch"]["status"] == "ok"


def test_a_shortened_problem_keeps_the_rings_start():
    from rubcli.analysis.accuracy.reference import truncate_problem

    problem = Problem.from_periods(ring_machine(), (-0.3, 0.0, 0.0, 0.0), 4, 20)
    problem = dataclasses.replace(problem, stator_initial=(0.1, 0.0, 0.0, 0.3))
    short = truncate_problem(problem, problem.params.period)
    assert short.stator_initial == (0.1, 0.0, 0.0, 0.3) and short.t_eval.size < 30


def test_forces_map_refuses_the_eigen_map_of_a_moving_stator(tmp_path):
    case = tmp_path / "ring.toml"
    case.write_text(CASE + '[forces_map]\nresolution = 21\nproducts = ["eigen"]\n')
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["forces-map", str(case), "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert '"eigen"' in result.output and "stator" in result.output
    assert not out.exists()

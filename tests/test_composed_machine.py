"""The composed machine (rubcli.machine) and its one system (rubcli.system), on every
machine and every method that runs it.

References: the rotor's own solvers at a tight tolerance (the paper's machine, the
general machine, the snubber ring: independent derivations of the same equations, each
checked against its own references in test_model, test_machine and test_stator); the
exact rolling whirl (test_stick); the exact steady unbalance response of a linear
structure, ``(K - W^2 M + i W (C + W G)) Q = F``; machines that reduce exactly to a
single rotor (two uncoupled rotors, two coupled rotors moving in symmetry); energy
conservation without damping, friction and forcing.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from rubcli import model
from rubcli.machine import (
    ContactLaw,
    Machine,
    Speed,
    SpeedTable,
    Station,
    Structure,
    Unbalance,
    jeffcott_machine,
)
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.stator import Stator
from rubcli.system import METHODS, energy_residual, simulate, station_series

PAPER = ModelParams(nu=0.05, eta=1.2, e=0.3, K=50.0, mu=0.1, Rp=10.0)
GENERAL = ModelParams(
    nu=0.05, eta=1.2, e=0.3, K=50.0, mu=0.1, Rp=10.0, offset=(0.3, 0.1), load=(0.0, -0.2),
    stiffness=((1.0, 0.2), (-0.2, 1.3)),
)  # fmt: skip
SNUBBER = ModelParams(
    nu=0.05, eta=1.2, e=0.3, K=50.0, mu=0.1, Rp=10.0, stator=Stator(2.0, (5.0, 7.0), (0.1, 0.1))
)
TIGHT = {"rtol": 1e-12, "atol": 1e-14}
MACHINES = Path(__file__).resolve().parents[1] / "cases" / "machines"


def _beam_script():
    """cases/machines/make_beam.py, the script that makes the shipped beam rotor."""
    spec = importlib.util.spec_from_file_location("make_beam", MACHINES / "make_beam.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _reference_states(solution, params: ModelParams) -> np.ndarray:
    """The rotor solvers' states as the composed machine's (q, v): their rotor position is
    relative to the stator's centre (and to the ring's displacement)."""
    c = np.array(params.offset)
    if solution.stator_states is None:
        states = solution.states.copy()
        states[:, :2] += c
        return states
    ring = solution.stator_states
    return np.hstack([solution.states[:, :2] + ring[:, :2] + c, ring[:, :2],
                      solution.states[:, 2:] + ring[:, 2:], ring[:, 2:]])  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("name", ["paper", "general", "snubber"])
@pytest.mark.parametrize("method", ["dop853-jit", "analytic", "dop853", "radau"])
def test_jeffcott_machines_agree_with_the_rotor_solvers(name, method):
    params = {"paper": PAPER, "general": GENERAL, "snubber": SNUBBER}[name]
    t = np.linspace(0.0, 20.0 * np.pi, 801)  # 12 forcing periods, 30-odd contacts
    reference = solve(Problem(params, (0.0, 0.0, 0.0, 0.0), t), "dop853-jit", **TIGHT)
    machine = jeffcott_machine(params)
    start = np.zeros(2 * machine.size)
    start[:2] = params.offset
    tol = {"rtol": 1e-11, "atol": 1e-13} if method != "radau" else {"rtol": 1e-9, "atol": 1e-11}
    solution = simulate(machine, t, initial=start, method=method, **tol)
    assert solution.success, solution.message
    assert solution.events.kinds() == [ev.kind for ev in reference.events]
    assert len(solution.events) > 20
    times = np.array([ev.tau for ev in reference.events])
    # the flow amplifies a difference about 1e5-fold over these 12 periods (two runs of
    # one method at rtol 1e-11 and 1e-13 differ by that much more than their tolerance)
    limit = 2e-5 if method != "radau" else 1e-3
    assert np.max(np.abs(solution.events.t - times)) < limit
    assert np.max(np.abs(solution.states - _reference_states(reference, params))) < limit
    assert np.max(np.abs(energy_residual(solution))) < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
def test_every_method_holds_the_exact_rolling_whirl(method):
    """Stick on a circle of radius r whirling backward at Rp eta / r (test_stick)."""
    p = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.3, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    t = np.linspace(0.0, 4.0 * np.pi, 41)
    solution = simulate(jeffcott_machine(p), t, initial=[r, 0.0, 0.0, -p.Rp * p.eta],
                        method=method, rtol=1e-10, atol=1e-12)  # fmt: skip
    assert solution.success, solution.message
    assert len(solution.events) == 0 and np.all(solution.regimes == model.STICK)
    w = solution.states[:, 0] + 1j * solution.states[:, 1]
    exact = r * np.exp(-1j * p.Rp * p.eta / r * t)
    assert np.max(np.abs(w - exact)) < (1e-6 if method in ("bdf", "lsoda") else 1e-8)
    values = station_series(solution)
    assert np.max(np.abs(values[:, 0, 1])) < 1e-12  # v_r held at 0
    # the rolling friction: T = 2 nu Rp eta on the exact whirl (test_stick)
    np.testing.assert_allclose(values[:, 0, 3], 2 * p.nu * p.Rp * p.eta, rtol=1e-6)


def test_stick_slip_cycle_matches_the_rotor_solvers():
    p = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    start = (r, 0.0, 0.0, -p.Rp * p.eta)
    problem = Problem.from_periods(p, start, 3, 50)
    reference = solve(problem, "dop853", rtol=1e-12, atol=1e-13)
    solution = simulate(jeffcott_machine(p), problem.t_eval, initial=start, rtol=1e-11,
                        atol=1e-13)  # fmt: skip
    kinds = [ev.kind for ev in reference.events]
    assert kinds[:4] == ["stick_exit", "stick_entry", "stick_exit", "stick_entry"]
    assert solution.events.kinds() == kinds
    assert np.max(np.abs(solution.events.t - [ev.tau for ev in reference.events])) < 1e-6
    assert np.max(np.abs(solution.states - reference.states)) < 1e-6
    values = station_series(solution)
    stick = solution.regimes[:, 0] == model.STICK
    assert stick.any() and (~stick).any()
    assert np.max(np.abs(values[stick, 0, 1])) < 1e-9
    limit = p.mu * values[stick, 0, 2]
    assert np.all(np.abs(values[stick, 0, 3]) <= limit * (1 + 1e-8))


def _pair_of_rotors(mass_coupling: float, spring_coupling: float, p: ModelParams) -> Machine:
    """Two Jeffcott rotors side by side, coupled through M and K (0: not coupled), each
    with its own station; moving in symmetry, each is the Jeffcott rotor of mass 1 + b
    and stiffness 1 - k_c (all scaled so that this is ``p``'s)."""
    a, b, kc = 1.0 - mass_coupling, mass_coupling, spring_coupling
    eye = np.eye(2)
    M = np.kron([[a, b], [b, a]], eye)
    K = np.kron([[1.0 + kc, -kc], [-kc, 1.0 + kc]], eye)
    C = 2.0 * p.nu * np.eye(4)
    law = ContactLaw(p.K)
    stations = tuple(
        Station((2 * i, 2 * i + 1), 1.0, law, p.mu, p.Rp, name=f"s{i}") for i in (0, 1)
    )
    unbalances = tuple(Unbalance((2 * i, 2 * i + 1), p.e, p.phi0) for i in (0, 1))
    return Machine(Structure(M=M, K=K, C=C), stations, Speed.constant(p.eta), unbalances)


def test_two_uncoupled_rotors_are_two_runs_of_one():
    t = np.linspace(0.0, 20.0 * np.pi, 801)
    other = ModelParams(nu=0.05, eta=1.2, e=0.3, K=50.0, mu=0.1, Rp=10.0, phi0=1.0)
    machine = Machine(
        Structure(M=np.eye(4), K=np.eye(4), C=0.1 * np.eye(4)),
        tuple(Station((2 * i, 2 * i + 1), 1.0, ContactLaw(50.0), 0.1, 10.0) for i in (0, 1)),
        Speed.constant(1.2),
        (Unbalance((0, 1), 0.3, 0.0), Unbalance((2, 3), 0.3, 1.0)),
    )
    both = simulate(machine, t, rtol=1e-11, atol=1e-13)
    first = simulate(jeffcott_machine(PAPER), t, rtol=1e-11, atol=1e-13)
    second = simulate(jeffcott_machine(other), t, rtol=1e-11, atol=1e-13)
    assert both.success
    # the pair's steps are not each rotor's own; their difference is amplified as in
    # test_jeffcott_machines_agree_with_the_rotor_solvers
    for s, alone in enumerate((first, second)):
        assert both.events.at_station(s).kinds() == alone.events.kinds()
        np.testing.assert_allclose(both.events.at_station(s).t, alone.events.t, atol=2e-5)
        got = both.states[:, [2 * s, 2 * s + 1, 4 + 2 * s, 5 + 2 * s]]
        assert np.max(np.abs(got - alone.states)) < 2e-5


@pytest.mark.slow
@pytest.mark.parametrize("method", ["dop853-jit", "analytic", "radau"])
def test_two_coupled_stations_in_stick_together(method):
    """Coupled through the mass matrix, the two stations' mobilities are a full 2 x 2
    matrix; in symmetry both hold the exact rolling whirl of the equivalent rotor."""
    b, kc = 0.2, 0.3
    p = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.3, Rp=2.0)
    machine = _pair_of_rotors(b, kc, p)
    # the equivalent rotor: mass a + b = 1, stiffness 1, damping 2 nu: p's own
    r = model.rolling_whirl_radius(p)
    w0 = [r, 0.0, 0.0, -p.Rp * p.eta]
    start = [w0[0], w0[1], w0[0], w0[1], w0[2], w0[3], w0[2], w0[3]]
    t = np.linspace(0.0, 4.0 * np.pi, 41)
    solution = simulate(machine, t, initial=start, method=method, rtol=1e-10, atol=1e-12)
    assert solution.success, solution.message
    assert np.all(solution.regimes == model.STICK) and len(solution.events) == 0
    exact = r * np.exp(-1j * p.Rp * p.eta / r * t)
    for s in (0, 1):
        w = solution.states[:, 2 * s] + 1j * solution.states[:, 2 * s + 1]
        assert np.max(np.abs(w - exact)) < 1e-8
    values = station_series(solution)
    np.testing.assert_allclose(values[:, :, 3], 2 * p.nu * p.Rp * p.eta, rtol=1e-6)


def test_two_coupled_rotors_in_symmetry_rub_as_one():
    """Coupled in M and K and forced alike, two rotors move as one Jeffcott rotor: each
    station's events and orbit are the single rotor's (the events of the two stations
    coincide: located together, switched one after the other at one instant). A machine
    whose symmetric motion is stable (on PAPER's, the pair leaves it after 7 periods)."""
    p = ModelParams(nu=0.05, eta=1.0, e=0.15, K=20.0, mu=0.1, Rp=2.0)
    machine = _pair_of_rotors(0.2, 0.3, p)
    t = np.linspace(0.0, 20.0 * np.pi, 801)
    pair = simulate(machine, t, rtol=1e-11, atol=1e-13)
    alone = simulate(jeffcott_machine(p), t, rtol=1e-11, atol=1e-13)
    assert pair.success and len(alone.events) > 20
    for s in (0, 1):
        assert pair.events.at_station(s).kinds() == alone.events.kinds()
        got = pair.states[:, [2 * s, 2 * s + 1, 4 + 2 * s, 5 + 2 * s]]
        assert np.max(np.abs(got - alone.states)) < 1e-6


def _bouncing(law: ContactLaw) -> tuple[Machine, np.ndarray]:
    """A frictionless, undamped, unforced rotor thrown into its stator."""
    machine = Machine(
        Structure(M=np.eye(2), K=np.eye(2)),
        (Station((0, 1), 1.0, law),),
        Speed.constant(1.0),
    )
    return machine, np.array([0.0, 0.0, 1.5, 0.4])


@pytest.mark.parametrize("method", ["dop853-jit", "analytic"])
@pytest.mark.parametrize("exponent", [1.0, 1.5])
def test_energy_is_conserved_without_damping_friction_or_forcing(exponent, method):
    machine, start = _bouncing(ContactLaw(40.0, 0.0, exponent))
    t = np.linspace(0.0, 30.0, 601)
    solution = simulate(machine, t, initial=start, method=method, rtol=1e-12, atol=1e-14)
    assert solution.success and len(solution.events) > 10
    assert np.max(np.abs(solution.work)) == 0.0
    E0 = 0.5 * (1.5**2 + 0.4**2)
    assert np.max(np.abs(energy_residual(solution))) < 1e-9 * E0


@pytest.mark.parametrize("method", ["dop853-jit", "analytic"])
def test_contact_damping_dissipates_what_the_balance_says(method):
    machine, start = _bouncing(ContactLaw(40.0, 2.0, 1.5))
    t = np.linspace(0.0, 30.0, 601)
    solution = simulate(machine, t, initial=start, method=method, rtol=1e-12, atol=1e-14)
    assert solution.success
    assert solution.work[-1] < -0.1  # each impact loses energy to the contact damping
    assert np.all(np.diff(solution.work) <= 1e-15)
    assert np.max(np.abs(energy_residual(solution))) < 1e-9
    values = station_series(solution)
    assert np.all(values[:, 0, 2] >= 0.0)  # the damped contact never pulls


def test_hertzian_law_changes_the_contact_duration_as_its_exponent_says():
    """A head-on impact of a frictionless point mass on k delta^p lasts
    ``2 (m / k)^(1/(p+1)) v^((1-p)/(p+1)) I_p``, I_p = integral_0^1 du / sqrt(1 - u^(p+1))
    times ((p+1)/2)^(1/(p+1)): for p = 1.5 it scales as v^(-1/5) (Hertz)."""
    durations = []
    for speed in (0.5, 2.0):
        machine = Machine(
            Structure(M=np.eye(2), K=1e-12 * np.eye(2)),
            (Station((0, 1), 1.0, ContactLaw(100.0, 0.0, 1.5)),),
            Speed.constant(1.0),
        )
        t = np.linspace(0.0, 2.5 / speed, 201)
        solution = simulate(machine, t, initial=[0.0, 0.0, speed, 0.0], rtol=1e-12, atol=1e-14)
        events = solution.events
        assert events.kinds()[:2] == ["contact_entry", "contact_exit"]
        durations.append(events.t[1] - events.t[0])
    assert durations[1] / durations[0] == pytest.approx(4.0 ** (-0.2), rel=1e-6)


def test_linear_structure_holds_its_exact_steady_unbalance_response():
    """A 24-coordinate beam rotor with gyroscopics, started on its steady response to an
    unbalance (solved here as complex amplitudes), stays on it while free."""
    arrays = _beam_script().beam_matrices()
    structure = Structure(M=arrays["M"], K=arrays["K"], C=arrays["C"], G=arrays["G"],
                          dof_per_node=4)  # fmt: skip
    omega = 2000.0 * 2 * math.pi / 60
    n = structure.size
    F = np.zeros(n, dtype=complex)
    F[8], F[9] = 1e-4 * omega**2, -1j * 1e-4 * omega**2
    dynamic = (
        structure.K - omega**2 * structure.M + 1j * omega * (structure.C + omega * structure.G)
    )
    Q = np.linalg.solve(dynamic, F)
    far = Station(structure.lateral(2), 1.0, ContactLaw(1e6))  # never reached
    machine = Machine(structure, (far,), Speed.constant(omega), (Unbalance((8, 9), 1e-4),))
    t = np.linspace(0.0, 0.03, 61)
    start = np.concatenate([Q.real, (1j * omega * Q).real])
    solution = simulate(machine, t, initial=start, rtol=1e-11, atol=1e-16)
    exact = (Q[None, :] * np.exp(1j * omega * t)[:, None]).real
    assert solution.success and len(solution.events) == 0
    assert np.max(np.abs(solution.states[:, :n] - exact)) < 1e-7 * np.max(np.abs(Q))


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: Structure(M=np.array([[1.0, 0.1], [0.0, 1.0]]), K=np.eye(2)), "symmetric"),
        (lambda: Structure(M=-np.eye(2), K=np.eye(2)), "positive definite"),
        (lambda: Structure(M=np.eye(2), K=np.eye(3)), "2 x 2"),
        (lambda: Structure(M=np.eye(2), K=[[np.nan, 0], [0, 1]]), "finite"),
        (lambda: Structure(M=np.eye(4), K=np.eye(4), dof_per_node=3), "divide"),
        (lambda: ContactLaw(-1.0), "stiffness"),
        (lambda: ContactLaw(1.0, -1.0), "damping"),
        (lambda: ContactLaw(1.0, 0.0, 0.5), "exponent"),
        (lambda: Machine(Structure(M=np.eye(2), K=np.eye(2)), (), Speed.constant(1.0)), "station"),
        (
            lambda: Machine(
                Structure(M=np.eye(2), K=np.eye(2)),
                (Station((0, 2), 1.0, ContactLaw(1.0)),),
                Speed.constant(1.0),
            ),
            "not a coordinate",
        ),  # fmt: skip
        (lambda: Speed((0.0, 1.0), (1.0, -1.0)), "> 0"),
    ],
)
def test_a_machine_is_checked_once_at_its_boundary(build, message):
    with pytest.raises((TypeError, ValueError), match=message):
        build()


def test_simulate_refuses_what_it_cannot_run():
    machine = jeffcott_machine(PAPER)
    t = np.linspace(0.0, 1.0, 3)
    with pytest.raises(ValueError, match="unknown method 'taylor'"):
        simulate(machine, t, method="taylor")
    with pytest.raises(ValueError, match="initial must be 4"):
        simulate(machine, t, initial=[0.0, 0.0])
    with pytest.raises(ValueError, match="rtol"):
        simulate(machine, t, rtol=float("nan"))
    with pytest.raises(ValueError, match="max_steps must be an int > 0"):
        simulate(machine, t, max_steps=2.5)
    with pytest.raises(ValueError, match="max_wall_time_s must be a finite number"):
        simulate(machine, t, max_wall_time_s=float("nan"))


def test_a_run_stops_at_its_step_budget_with_the_samples_so_far():
    t = np.linspace(0.0, 60.0, 601)
    solution = simulate(jeffcott_machine(PAPER), t, max_steps=50)
    assert not solution.success and "max_steps" in solution.message
    assert 1 < solution.t.size < t.size


def test_the_docs_example_runs(capsys):
    """The Python example of docs/composed-machine.md, as written."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "composed-machine.md").read_text()
    code = text.split("```python\n", 1)[1].split("```", 1)[0]
    exec(compile(code, "docs/composed-machine.md", "exec"), {})
    status, events, residual = capsys.readouterr().out.split()
    assert status == "success" and int(events) > 10 and float(residual) < 1e-7


def test_a_rotor_touching_a_ring_that_touches_a_casing():
    """Two stations in a chain: the rotor against a ring (a pair of the structure's
    coordinates) and the ring against a rigid casing. Without damping, friction and
    forcing the energy is conserved; both stations make contact, and the ring's
    reaction pushes it into the casing."""
    M = np.diag([1.0, 1.0, 0.5, 0.5])
    K = np.diag([1.0, 1.0, 2.0, 2.0])
    stations = (
        Station((0, 1), 1.0, ContactLaw(30.0), stator=(2, 3), name="rotor-ring"),
        Station((2, 3), 0.3, ContactLaw(80.0), name="ring-casing"),
    )
    machine = Machine(Structure(M=M, K=K), stations, Speed.constant(1.0))
    t = np.linspace(0.0, 40.0, 801)
    run = simulate(machine, t, initial=[0.0, 0.0, 0.0, 0.0, 2.0, 0.5, 0.0, 0.0],
                   rtol=1e-12, atol=1e-14)  # fmt: skip
    assert run.success, run.message
    for s in (0, 1):
        assert "contact_entry" in run.events.at_station(s).kinds()
    E0 = 0.5 * (2.0**2 + 0.5**2)
    assert np.max(np.abs(energy_residual(run))) < 1e-9 * E0
    first_ring = run.events.at_station(1).t[0]
    assert first_ring > run.events.at_station(0).t[0]  # pushed by the rotor


@pytest.mark.parametrize("regime", [model.FREE, model.SLIP_POSITIVE, model.STICK])
@pytest.mark.parametrize("speed", ["constant", "run-up", "run-up on bearings of the speed"])
def test_the_implicit_methods_jacobian_is_the_derivative_of_the_system(regime, speed):
    """The Jacobian radau, bdf and lsoda get (exact from the matrices in the columns no
    station reads, differenced in the stations' own, all differenced in stick) against
    central differences of the right-hand side at ten times its step: a structure
    coupled in every matrix, gyroscopic at a speed that changes (and with bearings whose
    coefficients change with it, on a station's coordinate and on two no station reads),
    a station on a ring of the structure and a rigid one with contact damping, both in
    contact."""
    from rubcli.system.arrays import SystemArrays
    from rubcli.system.kernels import jacobian_into, rhs_into

    rng = np.random.default_rng(3)
    n = 8  # coordinates 6 and 7: read by no station
    A = rng.normal(size=(n, n))
    M = np.eye(n) + 0.1 * (A + A.T)
    K = np.eye(n) * 3.0 + 0.2 * rng.normal(size=(n, n))
    G = 0.05 * (A - A.T)
    C = 0.02 * np.eye(n) + 0.01 * (A @ A.T)
    stations = (
        Station((0, 1), 1.0, ContactLaw(30.0, damping=0.2), 0.2, 2.0, stator=(4, 5)),
        Station((2, 3), 1.0, ContactLaw(50.0), 0.1, 1.5),
    )
    profile = Speed.constant(1.2) if speed == "constant" else Speed((0.0, 10.0), (0.5, 2.0))
    table = None
    if speed.endswith("speed"):
        blocks = rng.normal(size=(3, 3, 3))
        table = SpeedTable((5, 6, 7), [0.0, 1.0, 3.0], 2.0 + blocks, 0.1 * np.abs(blocks))
    machine = Machine(Structure(M=M, K=K, C=C, G=G, speed_table=table), stations, profile,
                      (Unbalance((2, 3), 0.3, 0.4),))  # fmt: skip
    arrays = SystemArrays.of(machine)
    ctx = arrays.context(np.full(2, regime, dtype=np.int64))
    # both stations in contact: 1.2 clearances between the rotor points and their stators
    q = np.array([1.0, 0.5, 0.9, -0.7, 0.1, -0.2, 0.3, 0.4]) + 0.01 * rng.normal(size=n)
    y = np.concatenate([q, rng.normal(size=n), [0.0]])
    m = y.size
    scale = np.concatenate([np.ones(n), np.full(n, 2.0), [1.0]])
    jac = np.empty((m, m))
    jacobian_into(3.0, y, ctx, scale, jac, np.empty(m), np.empty(m), np.empty(m))
    reference = np.zeros((m, m))
    for j in range(m - 1):
        h = 1e-5 * max(abs(y[j]), scale[j])
        f_plus, f_minus = np.empty(m), np.empty(m)
        rhs_into(3.0, y + h * np.eye(m)[j], ctx, 0, f_plus)
        rhs_into(3.0, y - h * np.eye(m)[j], ctx, 0, f_minus)
        reference[:, j] = (f_plus - f_minus) / (2.0 * h)
    rows = slice(0, 2 * n)  # the work's row is not a derivative any method needs
    size = np.max(np.abs(reference[rows]))
    assert np.max(np.abs(jac[rows] - reference[rows])) < 1e-7 * size
    assert np.all(jac[:, -1] == 0.0)


def test_a_station_on_its_surface_in_contact_has_its_damping_force():
    """At ``delta = 0`` exactly in a contact regime (where a segment after an entry
    starts) the normal force is already ``c z'``: once it was 0 there and c z' an instant
    later, a jump at the step's start that radau's error estimate cannot pass (it failed
    at such an entry on ROSS's rotor with two seals, cases/rotors/ross-two-seals.toml)."""
    from rubcli.system.arrays import SystemArrays
    from rubcli.system.kernels import V_NORMAL, evaluate

    law = ContactLaw(50.0, damping=0.3)
    machine = Machine(Structure(M=np.eye(2), K=np.eye(2)), (Station((0, 1), 1.0, law, 0.1, 1.0),),
                      Speed.constant(1.0))  # fmt: skip
    arrays = SystemArrays.of(machine)
    for regime, expected in ((model.SLIP_POSITIVE, 0.3 * 0.2), (model.FREE, 0.0)):
        ctx = arrays.context(np.array([regime], dtype=np.int64))
        y = np.array([1.0, 0.0, 0.2, 0.5, 0.0])  # on the surface, moving out at z' = 0.2
        out, vals = np.empty(5), np.empty((1, 4))
        evaluate(0.0, y, ctx, out, vals)
        assert vals[0, V_NORMAL] == pytest.approx(expected, rel=1e-15)

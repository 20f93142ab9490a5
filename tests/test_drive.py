"""The driven rotor (rubcli.drive, rubcli.solvers.driven): the spin a state, driven by a
motor and braked by the rub. Checked against the Lagrangian's energy (exact, with the
motor's work), the constant-speed solvers in the limit of a heavy rotor, the closed-form
synchronous rub with the torque balance (the speed a weak drive is captured at), and the
case files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.accuracy.reference import truncate_problem
from rubcli.analysis.energy.drive_torques import revolution_means, sample_torques
from rubcli.analysis.energy.transient import drive_energy, drive_energy_summary
from rubcli.case import CaseError, load_case, load_case_text
from rubcli.cli.app import app
from rubcli.drive import Drive
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.solvers.rub import slip_velocity

REPO = Path(__file__).resolve().parents[1]

RUN_UP = dict(nu=0.05, e=0.3, K=10.0, mu=0.02, Rp=5.0)
CASES = REPO / "cases" / "runup"


def constant_torque(torque: float, inertia: float, start: float) -> Drive:
    """A motor whose torque is the same at every speed (a flat table)."""
    return Drive(inertia=inertia, start=start, table_speed=(0.0, 100.0),
                 table_torque=(torque, torque))  # fmt: skip


def idle_motor(inertia: float, start: float) -> Drive:
    """A linear motor whose torque is 0 at the start speed."""
    return Drive(inertia=inertia, start=start, stall_torque=1.0, no_load_speed=start)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["dop853", "rk45", "radau", "taylor"])
def test_energy_changes_by_the_motors_work_exactly(method):
    """mu = 0, nu = 0 and a constant motor torque T: the energy of the Lagrangian changes
    by T (p - p0), the angle being a state: no quadrature, the coupling of the rotor's
    and the drive's equations through the unbalance (e = 0.3) checked to the tolerance,
    over many contacts."""
    p = model.ModelParams(nu=0.0, eta=0.8, e=0.3, K=20.0, mu=0.0, Rp=2.0)
    drive = constant_torque(0.05, inertia=2.0, start=0.8)
    t = np.linspace(0.0, 60.0, 3001)
    sol = solve(Problem(p, (1.02, 0.0, 0.0, 1.2), t, drive=drive), method, rtol=1e-11,
                atol=1e-12)  # fmt: skip
    assert sol.success, sol.message
    assert sol.n_contact_switches >= 6
    energy = drive_energy(sol)
    work = 0.05 * (sol.phase - sol.phase[0])
    assert sol.speed[-1] > 1.5  # the motor did accelerate it
    assert np.max(np.abs(energy - energy[0] - work)) < 1e-7 * (energy[0] + work[-1])


@pytest.mark.parametrize("method", ["dop853", "dop853-jit", "taylor"])
def test_a_heavy_rotor_runs_as_at_constant_speed(method):
    """With j = 1e12 and no motor torque the speed cannot change (the rub's torque gives
    eta' ~ 1e-11): the driven run with friction, stick and slip is the constant-speed
    run of the compiled DOP853 (its own code and event search), event for event."""
    p = model.ModelParams(nu=0.02, eta=2.0, e=0.5, K=20.0, mu=0.3, Rp=1.0)
    t = np.linspace(0.0, 80.0, 1601)
    drive = idle_motor(inertia=1e12, start=2.0)
    s0 = (1.05, 0.0, 0.0, -1.0)
    driven = solve(Problem(p, s0, t, drive=drive), method, rtol=1e-11, atol=1e-12)
    fixed = solve(Problem(p, s0, t), "dop853-jit", rtol=1e-11, atol=1e-12)
    assert driven.success and fixed.success
    assert len(driven.events) == len(fixed.events) > 10
    assert set(fixed.events.kinds) >= {"stick_entry", "stick_exit", "contact_exit"}
    assert list(driven.events.kinds) == list(fixed.events.kinds)
    np.testing.assert_allclose(driven.events.tau, fixed.events.tau, atol=1e-6)
    np.testing.assert_allclose(driven.states, fixed.states, atol=1e-5)
    assert np.ptp(driven.speed) < 1e-9


def _captured_speed(params: model.ModelParams, drive: Drive) -> float:
    """The speed at which the motor's torque balances the steady synchronous rub's
    (closed form, notes section 5): T_m(eta) = Rp mu K (r - 1) - e eta^2 Im(A e^{-i phi0}),
    the rub's moment and the unbalance's reaction on the spin."""

    def imbalance(eta: float) -> float:
        at = model.ModelParams(**{**params.as_dict(), "eta": eta})
        r = model.synchronous_rub_radii(at)[-1]
        A = model.synchronous_rub_amplitude(r, at)
        load = at.Rp * at.mu * at.K * (r - 1.0) - at.e * eta**2 * (A * np.exp(-1j * at.phi0)).imag
        return drive.motor_torque(eta) - load

    return brentq(imbalance, 1.5, 3.0, xtol=1e-12)


@pytest.mark.slow
def test_a_weak_drive_is_captured_where_the_torques_balance():
    """The Sommerfeld effect on the rub branch: the weak motor of driven-captured.toml
    stays at the speed where its torque equals the steady synchronous rub's (closed
    form), and its run reports it captured; twice the torque passes through to the
    motor's no-load speed."""
    case = load_case(CASES / "driven-captured.toml")
    sol = solve(case.problem, "dop853", rtol=1e-10, atol=1e-12)
    assert sol.success, sol.message
    expected = _captured_speed(case.params, case.problem.drive)
    assert 2.6 < expected < 2.8
    assert sol.speed[-1] == pytest.approx(expected, abs=1e-6)
    torques = sample_torques(sol)
    last = sol.t > sol.t[-1] - 20.0
    # the motor's torque (about 6.5) goes to the rub and the vibration; the inertia's
    # share has died out to the run's tolerance
    assert np.max(np.abs(torques["inertia"][last])) < 1e-5 * np.max(torques["motor"][last])
    through = load_case(CASES / "driven-through.toml")
    fast = solve(through.problem, "dop853", rtol=1e-10, atol=1e-12)
    assert fast.speed[-1] == pytest.approx(through.problem.drive.free_speed(), rel=2e-3)
    assert fast.contact[-200:].max() == 0


@pytest.mark.slow
def test_a_dry_whip_brakes_the_drive_and_rolls_in_stick():
    case = load_case(CASES / "driven-dry-whip.toml")
    sol = solve(case.problem, "dop853", rtol=1e-9, atol=1e-11)
    assert sol.success, sol.message
    stick = sol.regimes == model.STICK
    assert stick.mean() > 0.5
    assert np.max(np.abs(slip_velocity(sol)[stick])) < 1e-9  # projected onto v_r = 0
    assert sol.speed[-1] < 0.4 * sol.speed[0]  # braked from 3.5, the motor holding 4
    whirl = np.diff(np.unwrap(np.angle(sol.w[-400:]))).mean() / np.diff(sol.t[-400:]).mean()
    assert whirl < -1.0  # backward
    means = revolution_means(sol)
    assert means.rub[-1] < -1.0 and means.motor[-1] > 1.0


@pytest.mark.slow
def test_the_energy_balance_holds_with_friction_and_the_motor():
    """With damping, friction, stick and the linear motor the report's balance closes
    to its quadrature error (the trapezoid on the samples)."""
    case = load_case(CASES / "driven-dry-whip.toml")
    sol = solve(case.problem, "dop853", rtol=1e-10, atol=1e-12)
    summary = drive_energy_summary(sol)
    assert summary["rub_dissipation"] > 10.0 and summary["motor_work"] > 10.0
    assert summary["energy_residual"] < max(10 * summary["energy_quadrature_error"], 1e-9)
    assert summary["energy_residual"] < 1e-3


def test_the_interpreters_drive_is_the_compiled_one():
    """compiled=False runs the same cores through the interpreter: the same events, the
    states to round-off (libm against CPython's math, amplified along the run)."""
    case = load_case(CASES / "driven-dry-whip.toml")
    problem = truncate_problem(case.problem, 20.0)
    fast = solve(problem, "dop853", rtol=1e-10, atol=1e-12)
    slow = solve(problem, "dop853", rtol=1e-10, atol=1e-12, compiled=False)
    assert fast.settings["compiled"] and not slow.settings["compiled"]
    assert list(fast.events.kinds) == list(slow.events.kinds) and len(fast.events) > 3
    np.testing.assert_allclose(slow.states, fast.states, atol=1e-8)


FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16}


@pytest.mark.slow
def test_a_bouncing_heavy_rotor_runs_as_at_constant_speed():
    """The paper's start, already inside a stiff stator (K = 1.76e3, mu = 0.05): 79
    contacts and slips in three revolutions, some 0.0025 apart, inside one scan interval
    of a step. With j = 1e12 and no torque the driven runs are the constant-speed
    ``dop853-jit`` run (its own compiled event search) event for event."""
    p = model.ModelParams(**FIG3, K=1.76e3, mu=0.05)
    t = np.linspace(0.0, 3 * p.period, 3001)
    s0 = (0.88544, -0.8039, 0.0, 0.0)
    fixed = solve(Problem(p, s0, t), "dop853-jit", rtol=1e-10, atol=1e-12)
    assert len(fixed.events) == 79 and np.diff(fixed.events.tau).min() < 0.003
    problem = Problem(p, s0, t, drive=idle_motor(inertia=1e12, start=p.eta))
    for method in ("dop853", "rk45", "dop853-jit", "taylor"):
        sol = solve(problem, method, rtol=1e-10, atol=1e-12)
        assert list(sol.events.kinds) == list(fixed.events.kinds), method
        np.testing.assert_allclose(sol.events.tau, fixed.events.tau, atol=1e-6)
        np.testing.assert_allclose(sol.states, fixed.states, atol=1e-4)


@pytest.mark.parametrize("method", ["dop853", "rk45", "lsoda", "dop853-jit", "taylor"])
def test_a_start_on_the_clearance_moving_out_is_a_contact_at_once(method):
    """Started exactly on the clearance, moving along it (outward, since a straight line
    leaves the circle): the contact begins at tau = 0, as at constant speed, also when
    the first step is so short that z^2 - 1 rounds to 0 over it (lsoda at 1e-12)."""
    p = model.ModelParams(nu=0.05, eta=3.5, e=0.3, K=10.0, mu=0.3, Rp=5.0)
    t = np.linspace(0.0, 10.0, 1001)
    fixed = solve(Problem(p, (1.0, 0.0, 0.0, -5.0), t), "dop853-jit")
    assert fixed.events.kinds[0] == "contact_entry" and fixed.events.tau[0] == 0.0
    drive = Drive(inertia=200.0, start=3.5, stall_torque=4.0, no_load_speed=4.0)
    sol = solve(Problem(p, (1.0, 0.0, 0.0, -5.0), t, drive=drive), method, rtol=1e-12,
                atol=1e-14)  # fmt: skip
    assert sol.events.kinds[0] == "contact_entry" and sol.events.tau[0] < 1e-8
    assert sol.regimes[1] != model.FREE


@pytest.mark.slow
@pytest.mark.parametrize("method", ["radau", "bdf", "lsoda"])
def test_the_implicit_methods_roll_a_driven_rotor(method):
    """A driven rotor rolling on the stator all the way (e = 0: the angle does not enter
    the equations; in stick the velocity along the constraint does not either): the
    implicit methods, with the drive's own difference Jacobian, follow DOP853 at rtol
    1e-11 while the motor accelerates the rolling whirl, and hold v_r = 0."""
    p = model.ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.5, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    drive = Drive(inertia=20.0, start=1.0, stall_torque=1.0, no_load_speed=2.0)
    problem = Problem(p, (r, 0.0, 0.0, -p.Rp), np.linspace(0, 50, 501), drive=drive)
    ref = solve(problem, "dop853", rtol=1e-11, atol=1e-12)
    sol = solve(problem, method, rtol=1e-10, atol=1e-12)
    assert sol.success, sol.message
    assert np.all(sol.regimes == model.STICK) and len(sol.events) == 0
    assert sol.speed[-1] > 1.4  # accelerated while rolling
    np.testing.assert_allclose(sol.states, ref.states, atol=1e-5)
    assert np.max(np.abs(slip_velocity(sol))) < 1e-9


@pytest.mark.slow
def test_the_methods_agree_on_a_driven_stick_slip():
    """The rolling whirl with a little unbalance sticks and slips twice a period while a
    weak motor holds the speed: three scipy methods, the compiled DOP853 and
    taylor see the same 56 stick entries and exits, end at the same speed, and close the
    energy balance."""
    p = model.ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    drive = Drive(inertia=5.0, start=1.0, stall_torque=0.2, no_load_speed=1.5)
    problem = Problem(p, (r, 0.0, 0.0, -p.Rp), np.linspace(0, 60, 1201), drive=drive)
    methods = ("dop853", "rk45", "lsoda", "dop853-jit", "taylor")
    runs = [solve(problem, m, rtol=1e-10, atol=1e-12) for m in methods]
    for sol in runs:
        assert sol.success, sol.message
        assert list(sol.events.kinds) == ["stick_exit", "stick_entry"] * 28, sol.method
        assert sol.speed[-1] == pytest.approx(runs[0].speed[-1], abs=1e-6)
        assert drive_energy_summary(sol)["energy_residual"] < 1e-6
    np.testing.assert_allclose(runs[1].events.tau, runs[0].events.tau, atol=1e-6)
    np.testing.assert_allclose(runs[3].events.tau, runs[0].events.tau, atol=1e-9)
    np.testing.assert_allclose(runs[4].events.tau, runs[0].events.tau, atol=1e-6)


@pytest.mark.parametrize("method", ["dop853", "dop853-jit", "taylor"])
def test_a_rotor_that_stops_ends_the_run_with_a_message(method):
    """A motor that brakes (negative torque) stops the rotor: the run ends failed where
    the speed reaches 0 (without unbalance w = 1 - 0.5 tau: at tau = 2), its samples up
    to there kept."""
    p = model.ModelParams(**{**RUN_UP, "eta": 1.0, "e": 0.0})
    drive = constant_torque(-0.5 * 20.0, inertia=20.0, start=1.0)
    sol = solve(Problem(p, (0.0, 0.0, 0.0, 0.0), np.linspace(0, 10, 101), drive=drive), method)
    assert not sol.success
    assert "speed fell to 0 at tau = 2:" in sol.message
    assert sol.t[-1] == pytest.approx(1.9) and np.all(sol.speed > 0)


@pytest.mark.slow
@pytest.mark.parametrize(
    "case", ["driven-dry-whip", "driven-captured", "driven-through", "driven-physical"]
)
def test_the_compiled_loop_takes_dop853s_steps_on_a_driven_rotor(case):
    """``dop853-jit`` on a driven rotor is scipy's DOP853 step for step: the same number
    of steps and the same events, located by the same event search (``events.event_search``
    compiled in the kernel, run by Python on scipy's steps), the states to round-off
    amplified along the run; every step stays in the kernel (only a stopped rotor's goes
    to Python). With ``compiled=False`` it is scipy's ``dop853`` itself (the interpreter's
    right-hand side)."""
    problem = load_case(CASES / f"{case}.toml").problem
    scipy = solve(problem, "dop853", rtol=1e-9, atol=1e-12)
    jit = solve(problem, "dop853-jit", rtol=1e-9, atol=1e-12)
    assert jit.success and jit.method == "dop853-jit"
    assert jit.stats["nsteps"] == scipy.stats["nsteps"]
    assert list(jit.events.kinds) == list(scipy.events.kinds)
    np.testing.assert_allclose(jit.events.tau, scipy.events.tau, rtol=0, atol=1e-8)
    np.testing.assert_allclose(jit.states, scipy.states, rtol=0, atol=1e-6)
    np.testing.assert_allclose(jit.drive_states, scipy.drive_states, rtol=1e-8)
    assert jit.stats["python_steps"] == 0
    short = truncate_problem(problem, 10.0)
    slow = solve(short, "dop853-jit", rtol=1e-9, atol=1e-12, compiled=False)
    interpreted = solve(short, "dop853", rtol=1e-9, atol=1e-12, compiled=False)
    assert slow.method == "dop853-jit" and not slow.settings["compiled"]
    np.testing.assert_array_equal(slow.states, interpreted.states)


@pytest.mark.parametrize(
    "case", ["driven-dry-whip", "driven-captured", "driven-through", "driven-physical"]
)
def test_taylor_on_a_driven_rotor_against_a_tight_reference(case):
    """``taylor``'s series of the six states (compiled.driven_taylor): on every shipped
    driven rotor the events of DOP853 at rtol 1e-13, the states within 1e-6 and the
    final speed within 1e-8 at rtol 1e-10, and its error falling with the tolerance."""
    problem = load_case(CASES / f"{case}.toml").problem
    ref = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-15)
    errors = []
    for rtol in (1e-7, 1e-10):
        sol = solve(problem, "taylor", rtol=rtol, atol=rtol / 100)
        assert sol.success and sol.method == "taylor"
        assert list(sol.events.kinds) == list(ref.events.kinds)
        errors.append(np.max(np.hypot(sol.x - ref.x, sol.y - ref.y)))
    assert errors[1] < 1e-6 and errors[1] < errors[0]
    np.testing.assert_allclose(sol.events.tau, ref.events.tau, rtol=0, atol=1e-6)
    assert sol.speed[-1] == pytest.approx(ref.speed[-1], abs=1e-8)
    stick = sol.regimes == model.STICK
    if np.any(stick):
        assert np.max(np.abs(slip_velocity(sol)[stick])) < 1e-9


def test_the_motor_line_is_the_table_where_it_holds():
    """``drive.motor_line`` (the line a Taylor step carries) against the motor's torque
    less drag (``np.interp`` of the table): equal at every speed inside the range it
    returns, the range a piece of the table (or its held ends), and at a corner the piece
    on the side the speed moves to."""
    from rubcli.drive import motor_line, shaft_torque_value

    drive = Drive(inertia=20.0, start=0.5, table_speed=(0.5, 1.0, 2.0, 3.5),
                  table_torque=(20.0, 18.0, 13.0, 0.0), drag=0.3)  # fmt: skip
    record, (ts, tt) = drive.record(), drive.table()
    for w in (0.1, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 3.5, 5.0):
        for rising in (True, False):
            torque, slope, low, high = motor_line(w, rising, record, ts, tt)
            assert low <= w <= high
            assert (w > low or rising or low == -np.inf) and (w < high or not rising)
            probe = np.linspace(max(low, w - 2.0), min(high, w + 2.0), 41)
            np.testing.assert_allclose(torque + slope * probe,
                                       shaft_torque_value(probe, record, ts, tt),
                                       rtol=0, atol=1e-13)  # fmt: skip
    linear = Drive(inertia=20.0, start=0.5, stall_torque=4.0, no_load_speed=3.0, drag=0.1)
    torque, slope, low, high = motor_line(1.7, True, linear.record(), *linear.table())
    assert (low, high) == (-np.inf, np.inf)
    assert torque + slope * 2.5 == pytest.approx(linear.shaft_torque(2.5), abs=1e-14)


def test_taylor_steps_end_at_the_corners_of_a_motor_table():
    """A run-up captured on the rub by a motor table whose speed crosses two of its
    corners on the way (the speed where the table's torque balances the closed-form
    synchronous rub's, 2.83): ``taylor`` ends a step where the speed reaches a corner
    (its series carry one line of the table), and finds DOP853's contact at rtol 1e-13,
    its states within 1e-8 and its final speed within 1e-10 at rtol 1e-10."""
    p = model.ModelParams(eta=0.5, **RUN_UP)
    drive = Drive(inertia=200.0, start=0.5, table_speed=(0.0, 1.0, 2.0, 3.0, 3.5, 4.0),
                  table_torque=(20.0, 18.0, 13.0, 9.0, 4.0, 0.0))  # fmt: skip
    problem = Problem(p, (0.0, 0.0, 0.0, 0.0), np.linspace(0.0, 400.0, 8001), drive=drive)
    ref = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-15)
    sol = solve(problem, "taylor", rtol=1e-10, atol=1e-12)
    captured = _captured_speed(p, drive)
    assert 2.0 < captured < 3.0  # past two corners
    assert ref.speed[-1] == pytest.approx(captured, abs=1e-6) and len(ref.events) > 0
    assert sol.success
    assert list(sol.events.kinds) == list(ref.events.kinds)
    np.testing.assert_allclose(sol.events.tau, ref.events.tau, rtol=0, atol=1e-8)
    assert np.max(np.hypot(sol.x - ref.x, sol.y - ref.y)) < 1e-8
    assert sol.speed[-1] == pytest.approx(ref.speed[-1], abs=1e-10)


@pytest.mark.parametrize("method", ["analytic", "analytic-polar"])
def test_methods_without_the_drive_refuse_it_naming_the_feature(method):
    p = model.ModelParams(eta=0.5, **RUN_UP)
    problem = Problem(p, (0.0, 0.0, 0.0, 0.0), np.linspace(0, 10, 11),
                      drive=constant_torque(1.0, 20.0, 0.5))  # fmt: skip
    with pytest.raises(ValueError, match=f"{method} does not run a driven rotor"):
        solve(problem, method)


def test_a_drive_needs_more_inertia_than_its_unbalance():
    p = model.ModelParams(eta=0.5, **RUN_UP)
    with pytest.raises(ValueError, match="inertia = 0.05 must exceed e\\^2"):
        Problem(p, (0.0, 0.0, 0.0, 0.0), np.linspace(0, 1, 3), drive=constant_torque(1, 0.05, 0.5))


DRIVEN_TABLES = {
    "case": 'name = "drive"\n',
    "model": "nu = 0.05\ne = 0.3\nK = 10.0\nmu = 0.02\nRp = 5.0\n",
    "speed": 'profile = "driven"\nstart = 0.5\ninertia = 20.0\nstall_torque = 4.0\n'
    "no_load_speed = 4.0\n",
    "initial": "x = 0.0\ny = 0.0\n",
    "time": "end = 50.0\nsamples_per_period = 16\n",
}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"speed": 'profile = "driven"\nstart = 0.5\ninertia = 20.0\n'},
         "profile = 'driven' needs stall_torque, no_load_speed"),
        ({"speed": 'profile = "driven"\nstart = 0.5\ninertia = 20.0\nstall_torque = 1.0\n'
                   "no_load_speed = 2.0\nmotor_speed = [0.0, 1.0]\nmotor_torque = [1.0, 0.0]\n"},
         "not both"),
        ({"speed": 'profile = "driven"\nstart = 0.5\ninertia = 0.01\nstall_torque = 1.0\n'
                   "no_load_speed = 2.0\n"}, "speed.inertia: drive: inertia = 0.01 must exceed"),
        ({"speed": 'profile = "driven"\nstart = 0.5\ninertia = 2.0\nmotor_speed = [0.0, 1.0]\n'
                   "motor_torque = [1.0, 0.5, 0.0]\n"}, "give one torque per speed"),
        ({"speed": 'profile = "driven"\nstart = 0.5\ninertia = 2.0\nstall_torque = 1.0\n'
                   "no_load_speed = 2.0\nrate = 0.1\n"}, "rate do not belong to profile"),
        ({"time": "samples_per_period = 16\n"}, "time.end: missing; a driven rotor"),
        ({"solver": 'methods = ["analytic"]\n'}, "analytic does not run a driven rotor"),
    ],
)  # fmt: skip
def test_a_bad_drive_is_refused_naming_the_field(change, message):
    tables = {**DRIVEN_TABLES, **change}
    text = "".join(f"[{name}]\n{body}\n" for name, body in tables.items())
    with pytest.raises(CaseError, match=message):
        load_case_text(text, "drive.toml")


def test_a_physical_drive_converts_once_at_the_edge():
    """kg m^2, N m, rpm and N m s to j, torques, eta and c_b: the same machine given in
    [model] and in [physical] is the same problem."""
    m, k_r, gamma = 10.0, 1e6, 1e-4
    omega = math.sqrt(k_r / m)
    torque_unit = k_r * gamma**2
    rpm = 60.0 / (2.0 * math.pi)
    physical = (
        '[case]\nname = "drive"\n[physical]\n'
        f"m = {m}\nk_r = {k_r}\nd_r = {0.1 * 2 * omega * m}\nk_s = {10 * k_r}\n"
        f"clearance = {gamma}\ne = {0.3 * gamma}\nRp = {5 * gamma}\nmu = 0.02\n"
        f'[speed]\nprofile = "driven"\nstart = {0.5 * omega * rpm}\ninertia = {20 * m * gamma**2}\n'
        f"stall_torque = {4 * torque_unit}\nno_load_speed = {4 * omega * rpm}\n"
        f"drag = {0.1 * torque_unit / omega}\n"
        f"[initial]\nx = 0.0\ny = 0.0\n[time]\nend = {50 / omega}\nsamples_per_period = 16\n"
    )
    case = load_case_text(physical, "physical.toml")
    drive = case.problem.drive
    assert drive.inertia == pytest.approx(20.0, rel=1e-12)
    assert drive.stall_torque == pytest.approx(4.0, rel=1e-12)
    assert drive.no_load_speed == pytest.approx(4.0, rel=1e-12)
    assert drive.start == pytest.approx(0.5, rel=1e-12) == case.params.eta
    assert drive.drag == pytest.approx(0.1, rel=1e-12)
    assert case.problem.t_span[1] == pytest.approx(50.0, rel=1e-12)
    # titles speak the case's units
    stall, free = 4 * torque_unit, 4 * omega * rpm
    assert f"motor {stall:g} N m stall, {free:g} rpm no-load" in case.speed_text()


@pytest.mark.slow
def test_run_on_a_driven_rotor_writes_its_products(tmp_path):
    case = tmp_path / "drive.toml"
    case.write_text("".join(f"[{name}]\n{body}\n" for name, body in DRIVEN_TABLES.items()))
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(out)])
    assert result.exit_code == 0, result.output
    names = {p.name for p in out.iterdir()}
    assert {"drive.png", "bode.png", "dop853-jit.csv", "report.json"} <= names
    header = (out / "dop853-jit.csv").read_text().splitlines()[0].split(",")
    assert {"eta", "phase", "drive_torque", "rub_torque"} <= set(header)
    entry = json.loads((out / "report.json").read_text())["methods"]["dop853-jit"]
    assert entry["status"] == "success"
    assert entry["energy_residual"] < 1e-3
    assert entry["transient"]["drive"]["start_speed"] == 0.5
    assert set(entry["transient"]["drive"]["last_revolution_torques"]) == {
        "motor", "rub", "vibration", "inertia"
    }  # fmt: skip

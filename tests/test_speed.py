"""A speed that changes in time (rubcli.speed, [speed] in case files).

Every number here comes from an exact solution or an independent method: the phase as the
exact integral of a piecewise-linear speed, the unbalance force as the second derivative
of the unbalance's position (the Lagrangian's inertia term), an independent integration
of the hand-written equations with scipy, the steady forced response at the
instantaneous speed (model notes), and the synchronous rub's closed form with its fold.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.response.order_tracking import analyse_transient
from rubcli.case import CaseError, load_case_text
from rubcli.cli.app import app
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.solvers.rub import slip_velocity
from rubcli.speed import SpeedProfile

TABLE = SpeedProfile(tau=(5.0, 20.0, 30.0, 50.0), eta=(0.4, 1.1, 0.9, 1.6))


def test_phase_is_the_exact_integral_of_the_speed():
    phi0 = 0.3
    tau = np.linspace(0.0, 60.0, 600_001)
    speed = TABLE.speed(tau)
    # trapezoids are exact on a piecewise-linear speed whose knots are grid points
    integral = phi0 + np.concatenate(([0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * 1e-4)))
    assert np.max(np.abs(TABLE.phase(tau, phi0) - integral)) < 1e-9
    assert TABLE.speed(0.0) == 0.4 and TABLE.speed(100.0) == 1.6  # held at both ends
    assert TABLE.rate(10.0) == pytest.approx(0.7 / 15.0) and TABLE.rate(60.0) == 0.0


def test_each_leg_continues_the_speed_and_the_phase():
    params = model.ModelParams(nu=0.1, eta=1.0, e=0.2, K=5.0, phi0=0.3)
    legs = TABLE.legs(params, 0.0, 60.0)
    assert [start for start, _ in legs] == [0.0, 5.0, 20.0, 30.0, 50.0]
    for start, leg in legs:
        for t in (start, start + 1.0):
            phase = leg.eta * t + leg.phi0 + 0.5 * leg.rate * (t - leg.tau0) ** 2
            assert phase == pytest.approx(TABLE.phase(t, 0.3), abs=1e-12)
            assert leg.speed(t) == pytest.approx(TABLE.speed(t), abs=1e-14)


def test_the_unbalance_force_is_the_inertia_of_the_unbalance():
    """Lagrangian: the unbalance e (cos p, sin p) about the centre pulls it with
    -e d^2/dtau^2 (cos p, sin p) = e (p'^2 (cos p, sin p) + p'' (sin p, -cos p))."""
    eta, rate, tau0, phi0, e = 1.3, 0.07, 2.0, 0.4, 0.25
    E = e * eta**2

    def position(t):
        p = eta * t + phi0 + 0.5 * rate * (t - tau0) ** 2
        return e * np.array([np.cos(p), np.sin(p)])

    for t in (0.0, 3.7, 11.2):
        h = 1e-4
        second = (position(t + h) - 2.0 * position(t) + position(t - h)) / h**2
        force = model.unbalance_value(t, eta, E, phi0, e, rate, tau0)
        assert np.allclose(force, -second, atol=1e-6)


def _free_ramp_reference(p: model.ModelParams, prof: SpeedProfile, t: np.ndarray, s0):
    """The equations written out here, without rubcli.model: w'' + 2 nu w' + w =
    e (eta^2 (cos p, sin p) + eta' (sin p, -cos p)), scipy's DOP853 at rtol 1e-13."""

    def rhs(tau, s):
        eta, rate, phase = prof.speed(tau), prof.rate(tau), prof.phase(tau, p.phi0)
        fx = p.e * (eta * eta * math.cos(phase) + rate * math.sin(phase))
        fy = p.e * (eta * eta * math.sin(phase) - rate * math.cos(phase))
        return [s[2], s[3], fx - 2 * p.nu * s[2] - s[0], fy - 2 * p.nu * s[3] - s[1]]

    # the kink of the speed at the ramp's end lies on a span boundary
    out = []
    bounds = [t[0], *[k for k in prof.tau if t[0] < k < t[-1]], t[-1]]
    state = np.array(s0, dtype=float)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        grid = t[(t >= a) & (t <= b)]
        sol = solve_ivp(rhs, (a, b), state, method="DOP853", rtol=1e-13, atol=1e-14,
                        t_eval=grid, dense_output=True)  # fmt: skip
        out.append(sol.y.T if not out else sol.y.T[1:] if grid[0] == a else sol.y.T)
        state = sol.sol(b)
    return np.vstack(out)


def test_the_taylor_series_of_the_unbalance_force_on_a_ramp():
    """``taylor``'s series of the force on a leg, e (w^2 - i rate) exp(i p) with w and p
    a line and a parabola (compiled.taylor._profile_forcing), summed at offsets s from
    the step's start, is the force itself (model.unbalance_value) up to its truncation
    term, which falls as s^N (observed order N = 8), and to round-off with 20 terms."""
    from rubcli.solvers.compiled import taylor as kernels

    p = model.ModelParams(nu=0.05, eta=1.3, e=0.25, K=10.0, phi0=0.4)
    pars = np.array(model.params_vector(p))
    pars[model.P_RATE], pars[model.P_TAU0] = 0.07, 2.0
    t0 = 5.3

    def error(order: int, s_: float) -> float:
        W = np.zeros((kernels.WORK_ROWS, kernels.WORK_COLS))
        kernels._profile_forcing(t0, pars, order, W)
        powers = s_ ** np.arange(order)
        fx, fy = W[kernels.FORCE_X, :order] @ powers, W[kernels.FORCE_Y, :order] @ powers
        exact = model.unbalance_value(t0 + s_, p.eta, p.E, p.phi0, p.e, 0.07, 2.0)
        return math.hypot(fx - exact[0], fy - exact[1])

    errors = [error(8, s_) for s_ in (0.4, 0.2, 0.1)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 8.0) < 0.3), (errors, orders)
    assert error(20, 0.4) < 2e-15 and error(20, 0.05) < 2e-15  # the force is ~0.6


@pytest.mark.slow
@pytest.mark.parametrize("method", ["dop853-jit", "taylor", "rk45", "radau"])
def test_a_linear_ramp_without_contact_against_an_independent_integration(method):
    p = model.ModelParams(nu=0.05, eta=0.3, e=0.05, K=10.0, phi0=0.2)
    prof = SpeedProfile.ramp(0.3, 1.6, 0.02)  # through the critical speed, then held
    t = np.linspace(0.0, 80.0, 801)
    problem = Problem(p, (0.1, 0.0, 0.0, 0.1), t, speed=prof)
    sol = solve(problem, method, rtol=1e-10, atol=1e-12)
    assert sol.success and len(sol.events) == 0 and np.max(sol.z) < 1.0
    ref = _free_ramp_reference(p, prof, t, problem.initial)
    # a damped linear system: local errors of 1e-10 stay of that order
    assert np.max(np.abs(sol.states - ref)) < 1e-7


def test_a_slow_ramp_approaches_the_steady_response_at_the_instantaneous_speed():
    """Off resonance the response lags the steady one by O(rate): halving the rate
    halves the distance (observed order 1)."""
    p = model.ModelParams(nu=0.1, eta=0.3, e=0.05, K=10.0)
    errors = []
    for rate in (4e-4, 2e-4, 1e-4):
        prof = SpeedProfile.ramp(0.3, 0.6, rate)
        t = np.linspace(0.0, prof.end, 4001)
        start = model.free_steady_state(0.0, p)
        s0 = (start[0].real, start[0].imag, start[1].real, start[1].imag)
        sol = solve(Problem(p, s0, t, speed=prof), "dop853-jit", rtol=1e-11, atol=1e-13)
        eta, phase = prof.speed(t), prof.phase(t, p.phi0)
        steady = p.e * eta**2 * np.exp(1j * phase) / (1.0 - eta**2 + 2j * p.nu * eta)
        late = t > 0.3 * prof.end  # after the start's own transient has decayed
        w = sol.x + 1j * sol.y
        errors.append(np.max(np.abs(w[late] - steady[late]) / np.abs(steady[late])))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] < 1e-2
    assert np.all(np.abs(orders - 1.0) < 0.15), (errors, orders)


RUN_UP = model.ModelParams(nu=0.05, eta=0.5, e=0.3, K=10.0, mu=0.02, Rp=5.0)


def _steady_fold() -> float:
    """The largest speed with a synchronous rub (model.synchronous_rub_radii), by bisection."""
    lo, hi = 2.0, 4.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        radii = model.synchronous_rub_radii(model.ModelParams(**{**RUN_UP.as_dict(), "eta": mid}))
        lo, hi = (mid, hi) if radii else (lo, mid)
    return lo


def test_a_run_up_follows_the_steady_rub_and_drops_off_past_its_fold():
    """As the rate falls, the 1X whirl approaches the synchronous rub's closed-form radius
    at the instantaneous speed, and the jump down comes later than the steady fold, less
    late the slower the ramp (the delay of a jump with acceleration)."""
    fold = _steady_fold()
    assert fold == pytest.approx(3.0651, abs=1e-3)  # as continuation finds it (docs/orbits.md)
    ends, errors = [], []
    for rate in (0.004, 0.002, 0.001):
        prof = SpeedProfile.ramp(0.5, 4.0, rate)
        t = np.linspace(0.0, prof.end, int(prof.end * 8) + 1)  # 12 samples a turn at eta 4
        sol = solve(Problem(RUN_UP, (0.0, 0.0, 0.0, 0.0), t, speed=prof), "dop853-jit",
                    rtol=1e-9, atol=1e-11)  # fmt: skip
        assert sol.success
        revs, events, _ = analyse_transient(sol.t, sol.x, sol.y, sol.phase, sol.speed,
                                            sol.regimes)  # fmt: skip
        ends.append(events.end_eta)
        band = (revs.eta > 1.5) & (revs.eta < 2.8)
        radius = np.array([
            max(model.synchronous_rub_radii(model.ModelParams(**{**RUN_UP.as_dict(), "eta": v})))
            for v in revs.eta[band]
        ])  # fmt: skip
        errors.append(np.max(np.abs(np.abs(revs.forward[band]) - radius) / radius))
    assert fold < ends[2] < ends[1] < ends[0]
    assert errors[2] < errors[1] < errors[0] and errors[2] < 0.03


@pytest.mark.slow
def test_the_compiled_and_the_python_event_code_agree_on_a_ramp_with_rubbing():
    prof = SpeedProfile.ramp(0.5, 4.0, 0.01)
    t = np.linspace(0.0, prof.end, 3501)
    problem = Problem(RUN_UP, (0.0, 0.0, 0.0, 0.0), t, speed=prof)
    runs = {m: solve(problem, m, rtol=1e-10, atol=1e-12) for m in ("dop853-jit", "dop853")}
    python = solve(problem, "dop853-jit", rtol=1e-10, atol=1e-12, compiled_events=False)
    a, b = runs["dop853-jit"], runs["dop853"]
    assert len(a.events) > 10
    for other in (b, python):
        assert list(other.events.kind_code) == list(a.events.kind_code)
        assert np.allclose(other.events.tau, a.events.tau, atol=1e-7)
        assert np.max(np.abs(other.states - a.states)) < 1e-5
    # taylor, its events compiled and in Python, against DOP853 at rtol 1e-13 (whose
    # own distance from taylor at 1e-14 is 3e-7; dop853-jit at 1e-10 is 2e-5 off it)
    tight = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-14)
    for events in (True, False):
        sol = solve(problem, "taylor", rtol=1e-10, atol=1e-12, compiled_events=events)
        assert list(sol.events.kind_code) == list(tight.events.kind_code)
        assert np.allclose(sol.events.tau, tight.events.tau, atol=1e-6)
        assert np.max(np.abs(sol.states - tight.states)) < 1e-5


@pytest.mark.parametrize("method", ["dop853-jit", "taylor"])
def test_stick_on_a_ramp_holds_the_rolling_constraint(method):
    """A rotor rolling on the stator (e = 0, the rolling whirl's start) while the speed
    ramps: in stick v_r = Rp eta(tau) + r theta' stays 0 at every sample."""
    p = model.ModelParams(nu=0.02, eta=1.0, e=0.0, K=10.0, mu=0.5, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    s0 = (r, 0.0, 0.0, -p.Rp * p.eta)  # rolling backward at r theta' = -Rp eta
    prof = SpeedProfile.ramp(1.0, 1.2, 0.002)
    t = np.linspace(0.0, 150.0, 1501)
    sol = solve(Problem(p, s0, t, speed=prof), method, rtol=1e-10, atol=1e-12)
    stick = sol.regimes == model.STICK
    assert sol.success and stick.mean() > 0.9
    assert np.max(np.abs(slip_velocity(sol)[stick])) < 1e-9


def test_taylor_sticks_and_slips_on_a_ramp_as_dop853_does():
    """The rolling whirl with a little unbalance sticks and slips while the speed ramps
    (the rolling law with Rp eta' in the friction, the force with its eta' term), once
    each time the unbalance (at +eta) goes round the backward rolling whirl (at
    -Rp eta / r): ``taylor``'s series, with its events compiled or in Python, find
    DOP853's stick entries and exits at rtol 1e-12, to the tolerance."""
    p = model.ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)
    r = model.rolling_whirl_radius(p)
    problem = Problem(p, (r, 0.0, 0.0, -p.Rp), np.linspace(0.0, 60.0, 1201),
                      speed=SpeedProfile.ramp(1.0, 1.3, 0.005))  # fmt: skip
    ref = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-13)
    kinds = list(ref.events.kinds)
    cycles = len(kinds) // 2
    assert kinds == ["stick_exit", "stick_entry"] * cycles
    # the unbalance's turns relative to the whirl: the ramp's mean speed 1.15 over 60 tau
    relative = 1.15 * (1.0 + p.Rp / r) * 60.0 / (2.0 * math.pi)
    assert abs(cycles - relative) < 1.0, (cycles, relative)
    for events in (True, False):
        sol = solve(problem, "taylor", rtol=1e-10, atol=1e-12, compiled_events=events)
        assert list(sol.events.kinds) == list(ref.events.kinds)
        np.testing.assert_allclose(sol.events.tau, ref.events.tau, atol=1e-8)
        np.testing.assert_allclose(sol.states, ref.states, atol=1e-8)
        stick = sol.regimes == model.STICK
        assert np.max(np.abs(slip_velocity(sol)[stick])) < 1e-12


def test_methods_without_the_feature_refuse_it_with_the_reason():
    problem = Problem(RUN_UP, (0.0, 0.0, 0.0, 0.0), np.linspace(0, 10, 11),
                      speed=SpeedProfile.ramp(0.5, 1.0, 0.05))  # fmt: skip
    for method, why in (("analytic", "closed forms"), ("analytic-polar", "closed forms")):
        with pytest.raises(ValueError, match=f"{method} does not run a speed .*{why}"):
            solve(problem, method)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"model": "eta = 1.0\n"}, "model.eta: the speed is given by \\[speed\\]"),
        ({"speed": 'profile = "ramp"\nfrom = 2.0\nto = 1.0\nrate = 0.01\n'},
         "rate = 0.01 goes away from to = 1.0"),
        ({"speed": 'profile = "table"\ntau = [0.0, 5.0, 4.0]\neta = [1.0, 2.0, 3.0]\n'},
         "tau must increase"),
        ({"speed": 'profile = "ramp"\nfrom = 1.0\nto = 2.0\n'}, "needs rate"),
        ({"speed": 'profile = "driven"\n'}, "profile = 'driven' needs start, inertia"),
        ({"solver": 'methods = ["analytic"]\n'}, "solver.methods: analytic does not run"),
        ({"time": "periods = 10\nsamples_per_period = 20\n"}, "time.periods: a speed that"),
        ({"output": 'plots = ["orbit"]\n'}, "output.plots: orbit count periods of a constant"),
        ({"analysis": "response = true\n"}, "\\[analysis\\]: needs a constant speed"),
    ],
)  # fmt: skip
def test_a_bad_speed_table_is_refused_naming_the_field(change, message):
    tables = {
        "case": 'name = "ramp"\n',
        "model": "nu = 0.05\ne = 0.3\nK = 10.0\n",
        "speed": 'profile = "ramp"\nfrom = 0.5\nto = 1.0\nrate = 0.05\n',
        "initial": "x = 0.0\ny = 0.0\n",
        "time": "samples_per_period = 20\n",
        "solver": 'methods = ["dop853-jit"]\n',
    }
    for key, text in change.items():
        tables[key] = tables[key] + text if key == "model" else text
    text = "".join(f"[{name}]\n{body}\n" for name, body in tables.items())
    with pytest.raises(CaseError, match=message):
        load_case_text(text, "ramp.toml")


@pytest.mark.slow
def test_run_on_a_ramp_writes_the_transient_products(tmp_path):
    case = tmp_path / "ramp.toml"
    case.write_text(
        '[case]\nname = "ramp"\n[model]\nnu = 0.05\ne = 0.3\nK = 10.0\nmu = 0.02\nRp = 5.0\n'
        '[speed]\nprofile = "ramp"\nfrom = 0.5\nto = 4.0\nrate = 0.02\n'
        "[initial]\nx = 0.0\ny = 0.0\n[time]\nsamples_per_period = 32\n"
    )
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(out)])
    assert result.exit_code == 0, result.output
    names = {p.name for p in out.iterdir()}
    assert {"bode.png", "polar.png", "cascade.png", "orbits.png", "dop853-jit.csv"} <= names
    header = (out / "dop853-jit.csv").read_text().splitlines()[0].split(",")
    assert header[-2:] == ["eta", "phase"]
    report = json.loads((out / "report.json").read_text())
    transient = report["methods"]["dop853-jit"]["transient"]
    # the free whirl e eta^2 / |1 - eta^2 + 2 i nu eta| reaches the clearance at eta = 0.8846;
    # a run-up touches later (the whirl lags its steady amplitude), and peaks after
    low = model.ModelParams(nu=0.05, eta=0.8846, e=0.3, K=10.0)
    assert abs(model.free_steady_state(0.0, low)[0]) == pytest.approx(1.0, abs=1e-3)
    assert 0.8846 < transient["rub_onset_eta"] < transient["peak_1x_forward_eta"]
    assert report["case"]["nondimensional"]["speed"]["profile"] == "ramp"


@pytest.mark.slow
def test_compare_measures_error_against_run_time_on_a_ramp(tmp_path):
    """The reference of a changing speed is numerical (the closed forms are constant-speed
    ones): dop853-jit against lsoda; the error falls with the tolerance."""
    out = tmp_path / "cmp"
    case = "cases/runup/ramp-up-fast.toml"
    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    result = CliRunner().invoke(app, ["compare", str(root / case), "--quick", "--out", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    rows = report["work_precision"]["rows"]
    errors = [r["error_max"] for r in rows if r["method"] == "dop853-jit"]
    assert len(errors) >= 3 and errors == sorted(errors, reverse=True) and errors[-1] < 1e-7
    # no orbits.png or spectrum.png: their keyphasor and orders count periods of one speed
    assert not (out / "orbits.png").exists() and not (out / "spectrum.png").exists()


@pytest.mark.slow
def test_run_overlays_a_sweep_of_the_same_machine_under_the_bode_plot(tmp_path):
    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    runner = CliRunner()
    sweep = tmp_path / "sweep"
    result = runner.invoke(app, ["sweep", str(root / "cases/examples/run-up.toml"), "--quick",
                                 "--out", str(sweep)])  # fmt: skip
    assert result.exit_code == 0, result.output
    ramp = root / "cases/runup/ramp-up-fast.toml"
    out = tmp_path / "out"
    overlay = ["--overlay", str(sweep / "sweep.nc")]
    result = runner.invoke(app, ["run", str(ramp), "--out", str(out), *overlay])
    assert result.exit_code == 0, result.output
    assert (out / "bode.png").stat().st_size > 0

    from rubcli.case import load_case
    from rubcli.studies.transient import load_steady

    steady = load_steady(sweep / "sweep.nc", load_case(ramp))
    assert set(steady.z_max) == {"up", "down"}
    # on the rub branch the steady 1X whirl is the closed-form synchronous rub radius
    k = int(np.argmin(np.abs(steady.eta - 2.0)))
    rub = max(model.synchronous_rub_radii(
        model.ModelParams(**{**RUN_UP.as_dict(), "eta": float(steady.eta[k])})))  # fmt: skip
    assert steady.forward_1x["up"][k] == pytest.approx(rub, rel=1e-3)

    # another machine, or a case without [speed]: exit 2 naming the problem
    other = tmp_path / "other.toml"
    other.write_text(ramp.read_text().replace("e = 0.3", "e = 0.2"))
    result = runner.invoke(app, ["run", str(other), "--out", str(tmp_path / "o2"), *overlay])
    assert result.exit_code == 2 and "another machine: e = 0.3" in result.output
    result = runner.invoke(app, ["run", str(root / "cases/paper/fig3a.toml"), "--out",
                                 str(tmp_path / "o3"), *overlay])  # fmt: skip
    assert result.exit_code == 2 and "has no [speed]" in result.output


def test_the_energy_balance_of_a_ramp_holds_with_the_tangential_inertia_term():
    """The eta' term against the Lagrangian: on a fast ramp through the critical speed
    without contact, damping or friction, the rotor's energy changes by the unbalance's
    work with its tangential term e eta' (sin p, -cos p); the residual falls as the
    trapezoid rule's h^2 (observed order 2) and ends far below that term's work, which
    a balance without it would miss."""
    from rubcli.analysis.energy.transient import profile_energy_summary

    p = model.ModelParams(nu=0.0, eta=0.5, e=0.05, K=10.0)
    profile = SpeedProfile.ramp(0.5, 1.5, 0.05)
    residuals = []
    for per_rev in (50, 100, 200):
        n = int(20.0 / (2 * math.pi / 1.5) * per_rev) + 1
        problem = Problem(p, (0.0, 0.0, 0.0, 0.0), np.linspace(0, 20.0, n), speed=profile)
        sol = solve(problem, "dop853-jit", rtol=1e-12, atol=1e-13)
        assert sol.success and sol.z.max() < 1.0
        summary = profile_energy_summary(sol)
        residuals.append(summary["energy_residual"])
    orders = np.log2(np.array(residuals[:-1]) / np.array(residuals[1:]))
    assert np.all(np.abs(orders - 2.0) < 0.3), (orders, residuals)
    # the tangential term's own work: e eta' (sin p, -cos p) . v integrated
    phase = sol.phase
    term = 0.05 * 0.05 * (np.sin(phase) * sol.vx - np.cos(phase) * sol.vy)
    share = abs(np.sum(0.5 * (term[1:] + term[:-1]) * np.diff(sol.t)))
    assert residuals[-1] * summary["energy_throughput"] < 1e-3 * share

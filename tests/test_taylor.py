"""taylor: the adaptive Taylor-series method (rubcli/solvers/taylor.py, compiled/taylor.py).

The series are checked by their order: the local error of the order-N polynomial of one
step against exact solutions (free flight, the synchronous rub with friction, the rolling
whirl in stick) must fall like h^(N+1). Whole runs must agree with the exact solutions
to their tolerance, with the Figure 3 references (dop853-jit at 1e-12: the same events,
states within the tolerance), locate contact switches on the surface, and give the same
events and states whether the events are located in the kernel or by the Python event
code (events.earliest_event on the step's polynomial).
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rubcli import model
from rubcli.analysis.accuracy.stress import touching_start
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import FAILED, SUCCESS
from rubcli.solvers import METHODS, options_for, solve
from rubcli.solvers import taylor as taylor_solver
from rubcli.solvers.compiled import taylor as tk
from rubcli.solvers.events import ENTRY

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16}
START = (0.88544, -0.8039, 0.0, 0.0)
ROLLING = {"nu": 0.01, "eta": 1.0, "e": 0.0, "K": 100.0, "mu": 0.3, "Rp": 2.0}


def _spin(pars: np.ndarray) -> float:
    """Rp eta, the surface speed the pre-checks take (at a constant speed)."""
    return float(pars[model.P_RP] * pars[model.P_ETA])


def fig3_problem(mu: float, periods: float, samples: int = 50, **overrides) -> Problem:
    params = ModelParams(**{**FIG3, **overrides}, mu=mu)
    return Problem.from_periods(params, START, periods, samples)


def rolling_state(p: ModelParams, tau):
    """The exact rolling backward whirl w = r exp(-i (Rp eta / r) tau) (e = 0)."""
    r = model.rolling_whirl_radius(p)
    omega = -p.Rp * p.eta / r
    w = r * np.exp(1j * omega * np.asarray(tau, dtype=float))
    v = 1j * omega * w
    return np.array([w.real, w.imag, v.real, v.imag])


def exact_cases():
    """(name, params, regime, exact state at tau) for each regime's series."""
    free = ModelParams(nu=0.05, eta=0.7, e=0.05, K=17.6, mu=0.03, Rp=1.0, phi0=0.3)
    s0 = (0.2, -0.1, 0.3, 0.1)

    def free_exact(tau):
        return model.free_flight(tau, 0.0, s0, free)

    rub = ModelParams(**FIG3, mu=0.03, phi0=0.4)

    def rub_exact(tau):
        return model.synchronous_rub(tau, rub)

    rolling = ModelParams(**ROLLING)
    # a general contact state (z, r', theta' all varying), slipping backwards: scipy's
    # DOP853 at rtol 1e-13 on the regime-locked right-hand side as the reference
    slip = ModelParams(**FIG3, mu=0.05, phi0=0.2)
    s1, t1 = np.array([1.08, -0.35, 0.9, -1.3]), 0.37

    def slip_reference(tau):
        out = solve_ivp(
            model.rhs, (t1, tau), s1, method="DOP853", rtol=1e-13, atol=1e-15,
            args=(slip, model.SLIP_NEGATIVE),
        )  # fmt: skip
        return out.y[:, -1]

    return [
        ("free flight", free, model.FREE, free_exact),
        ("synchronous rub, slip+", rub, model.SLIP_POSITIVE, rub_exact),
        ("rolling whirl, stick", rolling, model.STICK, lambda tau: rolling_state(rolling, tau)),
        ("general contact, slip-", slip, model.SLIP_NEGATIVE, slip_reference),
    ]


@pytest.mark.slow
@pytest.mark.parametrize("case", exact_cases(), ids=lambda c: c[0])
@pytest.mark.parametrize("order", [6, 10])
def test_series_local_error_has_order_n_plus_1(case, order):
    """One step of the order-N polynomial from an exact state: error ~ C h^(N+1)."""
    name, params, regime, exact = case
    pars = np.array(model.params_vector(params))
    t0 = 0.37
    C = np.zeros((4, tk.MAX_ORDER + 1))
    W = np.zeros((tk.WORK_ROWS, tk.WORK_COLS))
    tk.taylor_coefficients(t0, np.array(exact(t0), dtype=float), pars, regime, order, C, W)
    out = np.empty(4)

    def error(h):
        tk.dense_at(t0 + h, t0, C, order, out)
        return float(np.max(np.abs(out - exact(t0 + h))))

    # the reference of the general case is good to ~1e-13: stay far above it
    general = name.startswith("general")
    order_floor, start = (1e-11, 1e-2) if general else (1e-13, 1e-4)
    h = 4.0  # the largest step of the asymptotic range: error below ``start`` there
    while error(h) > start:
        h /= 2.0
    errors = [error(h), error(h / 2), error(h / 4)]
    observed = np.log(np.array(errors[:-1]) / errors[1:]) / np.log(2.0)
    assert errors[-1] > order_floor, errors  # above round-off: the ratio measures truncation
    assert np.all(np.abs(observed - (order + 1)) < 0.6), (errors, observed)


@pytest.mark.parametrize("order", [5, 6, 13, 18])
def test_dense_output_is_the_polynomial_and_the_same_in_python(order):
    """dense_at (Estrin's scheme) agrees with Horner's rule to round-off, and the Python
    path's TaylorDense repeats its operations bit for bit, at one time and at many, for
    odd and even orders."""
    rng = np.random.default_rng(order)
    C = np.zeros((4, tk.MAX_ORDER + 1))
    C[:, : order + 1] = rng.normal(size=(4, order + 1)) / np.arange(1, order + 2) ** 2
    t0 = 0.3
    t = t0 + np.linspace(-0.2, 0.9, 12)
    compiled = tk.dense(t, t0, C, order)
    horner = np.zeros((4, t.size))
    for k in range(order, -1, -1):
        horner = horner * (t - t0) + C[:, k : k + 1]
    assert np.max(np.abs(compiled - horner)) < 1e-14
    python = taylor_solver.TaylorDense(t0, C, order)
    assert np.array_equal(python(t), compiled)
    assert all(np.array_equal(python(tj), compiled[:, j]) for j, tj in enumerate(t))


def test_frictionless_slip_series_leaves_out_only_the_unused_top_order():
    """Without friction the slip series stops before z_N and P_N (no acceleration needs
    them): the state's coefficients and the surface's series q are those of the full
    series (here with a friction coefficient too small to change any rounding), and so
    are P's up to order N - 1."""
    order = 13
    s0 = np.array([1.08, -0.35, 0.9, -1.3])
    rows = {}
    for mu in (0.0, 1e-300):
        pars = np.array(model.params_vector(ModelParams(**FIG3, mu=mu)))
        C = np.zeros((4, tk.MAX_ORDER + 1))
        W = np.full((tk.WORK_ROWS, tk.WORK_COLS), np.nan)
        tk.taylor_coefficients(0.37, s0, pars, model.SLIP_POSITIVE, order, C, W)
        rows[mu] = C[:, : order + 1], W[0, : order + 1], W[4:6, : order + 1]
    (c0, q0, p0), (c1, q1, p1) = rows[0.0], rows[1e-300]
    assert np.array_equal(c0, c1) and np.array_equal(q0, q1)
    assert np.array_equal(p0[:, :order], p1[:, :order])
    assert np.all(np.isnan(p0[:, order])) and np.all(np.isfinite(p1[:, order]))


@pytest.mark.parametrize("rtol", [1e-7, 1e-11])
def test_free_flight_matches_closed_form(rtol):
    p = ModelParams(nu=0.05, eta=0.7, e=0.05, K=17.6, mu=0.03, Rp=1.0, phi0=0.3)
    prob = Problem.from_periods(p, (0.2, -0.1, 0.3, 0.1), 10, 20)
    sol = solve(prob, "taylor", rtol=rtol, atol=rtol / 100)
    assert sol.success and not sol.events
    exact = model.free_flight(prob.t_eval, 0.0, prob.initial, p)
    err = np.max(np.abs(sol.states.T - exact))
    assert err < 30 * rtol
    assert err > 1e-16  # not a closed form in disguise


@pytest.mark.parametrize("mu", [0.0, 0.03])
def test_synchronous_rub_matches_exact_solution(mu):
    p = ModelParams(**FIG3, mu=mu)
    prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p)), 10, 20)
    errors = []
    for rtol in (1e-6, 1e-9, 1e-12):
        sol = solve(prob, "taylor", rtol=rtol, atol=rtol / 100)
        assert sol.success and not sol.events
        errors.append(np.max(np.abs(sol.states.T - model.synchronous_rub(prob.t_eval, p))))
        assert errors[-1] < 30 * rtol
    # tolerance proportionality: each 1000x tighter rtol gains at least 100x
    assert errors[1] < errors[0] / 100 and errors[2] < errors[1] / 100


def test_stays_on_exact_rolling_whirl():
    p = ModelParams(**ROLLING)
    prob = Problem(p, tuple(rolling_state(p, 0.0)), np.linspace(0.0, 30.0, 301))
    sol = solve(prob, "taylor", rtol=1e-10, atol=1e-12)
    assert sol.success and not sol.events
    assert np.all(sol.regimes == model.STICK)
    assert np.max(np.abs(sol.states.T - rolling_state(p, prob.t_eval))) < 1e-8


def dry_whip_problem(periods: float) -> Problem:
    """Figure 3 with mu = 0.05 from period 67 of the reference run, just before the
    rotor first sticks (at period 68.3; before it the transient is chaotic, so runs at
    different tolerances part after some 60 periods and stick at different times)."""
    p = ModelParams(**FIG3, mu=0.05)
    lead = Problem.from_periods(p, START, 67, 1)
    s0 = solve(lead, "dop853-jit", rtol=1e-13, atol=1e-15).states[-1]
    t0 = float(lead.t_eval[-1])
    return Problem(p, tuple(s0), np.linspace(t0, t0 + periods * p.period, 50 * periods + 1))


@pytest.mark.parametrize("mu", [0.0, 0.03, "stick"])
def test_agrees_with_figure3_reference(mu):
    """The Figure 3 case against dop853-jit at 1e-12 (the reference solver of compare):
    the same events (contact, slip reversals; stick entries and exits in the dry whip)
    within the tolerance, the same samples within it."""
    prob = dry_whip_problem(3) if mu == "stick" else fig3_problem(mu, 10)
    ref = solve(prob, "dop853-jit", rtol=1e-12, atol=1e-14)
    sol = solve(prob, "taylor", rtol=1e-10, atol=1e-12)
    assert sol.status == ref.status == SUCCESS
    assert [e.kind for e in sol.events] == [e.kind for e in ref.events]
    assert len(sol.events) > 0
    if mu == "stick":
        assert {"stick_entry", "stick_exit"} <= {e.kind for e in sol.events}
    times = np.array([e.tau for e in sol.events]) - [e.tau for e in ref.events]
    assert np.max(np.abs(times)) < 1e-6
    assert np.array_equal(sol.regimes, ref.regimes)
    assert np.max(np.abs(sol.w - ref.w)) < 1e-6


def test_contact_switches_lie_on_the_surface():
    sol = solve(fig3_problem(0.03, 10), "taylor", rtol=1e-9, atol=1e-11)
    switches = [e for e in sol.events if e.kind in ("contact_entry", "contact_exit")]
    assert len(switches) > 20
    z = np.array([math.hypot(e.state[0], e.state[1]) for e in switches])
    assert np.max(np.abs(z - 1.0)) < 1e-12


@pytest.mark.parametrize(
    ("K", "mu", "periods"), [(17.6, 0.03, 10), (17.6, 0.05, 10), (1.76e4, 0.03, 0.5)]
)  # K = 1.76e4: impacts with slip reversals and stick
def test_compiled_events_match_the_python_event_code(K, mu, periods):
    """Events located in the kernel (a transcription of events.first_crossing on the
    step's polynomial, roots._apply_event) against the same steps with every step that
    may hold an event handed to events.earliest_event / apply_event: the same events at
    the same times, the same steps, the same states to round-off."""
    prob = fig3_problem(mu, periods, K=K)
    fast = solve(prob, "taylor", rtol=1e-9, atol=1e-11)
    slow = solve(prob, "taylor", rtol=1e-9, atol=1e-11, compiled_events=False)
    assert fast.status == slow.status == SUCCESS
    assert slow.stats["python_steps"] > 0 and fast.stats["python_steps"] == 0
    assert [e.kind for e in fast.events] == [e.kind for e in slow.events]
    assert len(fast.events) > 0
    if K > 1e3:
        assert {"stick_entry", "stick_exit", "slip_reversal"} <= {e.kind for e in fast.events}
    times = np.array([e.tau for e in fast.events]) - [e.tau for e in slow.events]
    assert np.max(np.abs(times)) < 1e-11
    assert fast.stats["nsteps"] == slow.stats["nsteps"]
    assert np.array_equal(fast.regimes, slow.regimes)
    assert np.max(np.abs(fast.states - slow.states)) < 1e-9


def test_stiff_persistent_contact_agrees_with_dop853_jit():
    """K = 1.75e6 on the synchronous rub, raised off it: the fast contact mode rings."""
    p = ModelParams(**{**FIG3, "K": 1.75e6}, mu=0.0)
    r = model.synchronous_rub_radii(p)[-1]
    s0 = model.synchronous_rub(0.0, p, r)
    s0[:2] *= 1.0 + 0.5 * (r - 1.0)
    prob = Problem.from_periods(p, tuple(s0), 0.1, 200)
    ref = solve(prob, "dop853-jit", rtol=1e-12, atol=1e-14)
    sol = solve(prob, "taylor", rtol=1e-10, atol=1e-12)
    assert sol.success and ref.success and not sol.events
    assert np.max(np.abs(sol.w - ref.w)) < 1e-8


def test_budgets_progress_and_registration(monkeypatch):
    assert "taylor" in METHODS
    assert options_for("taylor", {"rtol": 1e-6, "atol": 1e-8, "steps_per_period": 9}) == {
        "rtol": 1e-6,
        "atol": 1e-8,
    }
    prob = fig3_problem(0.03, 10)
    short = solve(prob, "taylor", rtol=1e-8, atol=1e-10, max_steps=50)
    assert short.status == FAILED and "step" in short.message
    assert 1 < short.t.size < prob.t_eval.size
    seen = []  # progress: between kernel chunks (here 2000 steps) and at the end
    monkeypatch.setattr(taylor_solver, "CHUNK_STEPS", 2000)
    long = fig3_problem(0.03, 100)
    sol = solve(long, "taylor", rtol=1e-8, atol=1e-10, progress=seen.append)
    assert sol.success and seen[-1] == long.t_eval[-1] and len(seen) >= 2
    assert np.all(np.diff(seen) > 0)
    assert sol.settings["order"] == tk.taylor_order(1e-8) == sol.stats["order"]


@pytest.mark.parametrize("depth", [1e-5, 1e-8])
def test_shallow_contact_is_found_as_by_dop853_jit(depth):
    """A free orbit scaled to penetrate the clearance by ``depth`` (e = 0: free flight is
    linear, so scaling the start scales the orbit): the series pre-check must not clear
    the step that holds the contact. Same events as dop853-jit, on the surface."""
    p = ModelParams(nu=0.05, eta=0.7818, e=0.0, K=17.6, mu=0.1, Rp=46.16)
    start, touch = touching_start(p, (0.3, -0.5, 0.4, 0.6))
    prob = Problem.from_periods(p, tuple(np.array(start) * (1.0 + depth)), 3, 50)
    ref = solve(prob, "dop853-jit", rtol=1e-12, atol=1e-14)
    sol = solve(prob, "taylor", rtol=1e-12, atol=1e-14)
    assert sol.success and ref.success
    kinds = [e.kind for e in sol.events]
    assert kinds[0] == "contact_entry" and kinds[-1] == "contact_exit"
    assert kinds == [e.kind for e in ref.events]
    assert abs(sol.events[0].tau - touch) < 0.1
    times = np.array([e.tau for e in sol.events]) - [e.tau for e in ref.events]
    assert np.max(np.abs(times)) < 1e-8


def test_precheck_flags_a_shallow_crossing_and_clears_a_clear_step():
    """The series pre-check on one short step over the apex of an orbit that penetrates
    by 1e-5: it must flag the step (the surface polynomial peaks above zero there); on
    the same orbit shrunk by 1% (the apex 1e-2 inside) it must clear it."""
    p = ModelParams(nu=0.05, eta=0.7818, e=0.0, K=17.6, mu=0.1, Rp=46.16)
    start, touch = touching_start(p, (0.3, -0.5, 0.4, 0.6))
    pars = np.array(model.params_vector(p))
    order, h = 16, 0.1
    C = np.zeros((4, tk.MAX_ORDER + 1))
    W = np.zeros((tk.WORK_ROWS, tk.WORK_COLS))
    flags = []
    for scale in (1.0 + 1e-5, 0.99):
        t0 = touch - h / 2
        s0 = model.free_flight(t0, 0.0, np.array(start) * scale, p)
        tk.taylor_coefficients(t0, s0, pars, model.FREE, order, C, W)
        flags.append(bool(tk._may_have_event(C, order, h, model.FREE, pars, W, 1e-14, _spin(pars))))
    assert flags == [True, False]


@pytest.mark.parametrize("storm", [False, True])
def test_batch_event_record_equals_the_event_by_event_record(storm):
    """driver.record_kernel_events (one batch copied into the columns at once) against
    the event-by-event record through the storm guard (driver._record_one_by_one): the same
    SwitchEvents, last kind, status and message; with 21 events at one instant (a switch
    storm) both fail at the same event."""
    from rubcli.solvers import driver

    rng = np.random.default_rng(3)
    n = 40
    taus = np.sort(rng.uniform(0.0, 50.0, n))
    if storm:
        taus[10:32] = taus[10]  # 22 events at one instant: the 21st is a storm
    kinds = rng.integers(0, 5, n)
    states = rng.normal(size=(n, 4))
    regimes = rng.integers(-1, 3, (n, 2))
    runs = []
    for record in (driver.record_kernel_events, driver._record_one_by_one):
        run = driver.Run(fig3_problem(0.03, 10), "taylor", max_steps=10, max_wall_time_s=10.0)
        ok = record(run, 20, taus, kinds, states, regimes)  # two batches of 20
        ok = ok and record(run, n - 20, taus[20:], kinds[20:], states[20:], regimes[20:])
        runs.append((ok, run))
    (ok_a, a), (ok_b, b) = runs
    assert ok_a == ok_b == (not storm)
    assert a.events == b.events and len(a.events) == (31 if storm else n)
    assert all(type(e) is type(b.events[0]) for e in a.events)
    assert (a.status, a.message, a.last_kind) == (b.status, b.message, b.last_kind)


def _scan_step(pars, regime, s0, rtol, starts, band, n=64):
    """One step of taylor from s0 at tau = 0.3: its coefficients, length, the pre-check's
    decision (compiled/taylor.step_events) and the event locate finds on a fine grid."""
    order = tk.taylor_order(rtol)
    C = np.zeros((4, tk.MAX_ORDER + 1))
    W = np.zeros((tk.WORK_ROWS, tk.WORK_COLS))
    t0 = 0.3
    tk.taylor_coefficients(t0, np.asarray(s0, dtype=float), pars, regime, order, C, W)
    h, eps = tk.step_size(C, order, rtol, rtol * 1e-2)
    scan = tk.step_events(C, order, h, regime, pars, W, eps, starts, band, _spin(pars))
    grid = np.linspace(t0, t0 + h, n + 1)
    buffers = np.empty(n + 1), np.empty(n + 1), np.empty(4), np.empty(4)
    t_ev, kind = tk.locate(t0, C, order, pars, regime, grid, n, *buffers, starts, band)
    return scan, kind


@pytest.mark.slow
def test_start_precheck_clears_only_steps_without_events():
    """Steps that start on the contact surface (after an exit, in free flight; after an
    entry, in slip), from states on z = 1 with radial rates from clearly inward to
    tangential and outward: a step the pre-check clears (SCAN_NONE) holds no event that
    locate finds on a grid 16x finer than taylor's; tangential and wrong-way starts and
    quick returns are flagged; clearly inward starts are cleared."""
    p = ModelParams(nu=0.01, eta=0.7818, e=0.3, K=17.6, mu=0.1, Rp=46.16)
    pars = np.array(model.params_vector(p))
    starts = (True, False, True)  # the segment starts at a contact entry or exit
    decisions = {}
    for regime, inward in ((model.FREE, -1.0), (model.SLIP_POSITIVE, 1.0)):
        for theta in (0.3, 2.0, 4.4):
            for rate in (1.0, 0.1, 1e-3, 1e-7, 0.0, -1e-3, -0.5):
                for tangential in (0.5, 2.0):
                    radial = np.array([math.cos(theta), math.sin(theta)])
                    v = inward * rate * radial + tangential * np.array([-radial[1], radial[0]])
                    s0 = (*radial, *v)
                    scan, kind = _scan_step(pars, regime, s0, 1e-8, starts, 1e-8)
                    if scan == tk.SCAN_NONE:
                        assert kind < 0, (regime, theta, rate, tangential)
                    decisions[(regime, theta, rate, tangential)] = scan
                    if regime == model.FREE and rate == 1e-3 and tangential == 2.0:
                        assert kind == ENTRY  # it turns back out within the step
    # outward (wrong-way) and tangential starts are always flagged
    assert all(d != tk.SCAN_NONE for k, d in decisions.items() if k[2] <= 1e-7)
    # free flight on the surface turning back out within the step (fast whirl): flagged
    assert all(d != tk.SCAN_NONE for k, d in decisions.items() if k[0] == model.FREE
               and k[2] == 1e-3 and k[3] == 2.0)  # fmt: skip
    # clearly inward starts are cleared where the step holds no event (the check does
    # its job): into contact at rate 1, into free flight at rate 0.1 (at rate 1 the long
    # free step reaches the surface again: flagged, and locate finds that entry)
    assert all(d == tk.SCAN_NONE for k, d in decisions.items() if k[0] != model.FREE
               and k[2] == 1.0)  # fmt: skip
    assert all(d == tk.SCAN_NONE for k, d in decisions.items() if k[0] == model.FREE
               and k[2] == 0.1 and k[3] == 0.5)  # fmt: skip
    assert sum(d == tk.SCAN_NONE for d in decisions.values()) >= 12


def test_slip_bound_clears_only_steps_without_a_reversal():
    """_slip_clear, the O(N) bound of v_r on the state polynomials: contact steps with
    v_r from far from zero to through zero (the whirl against the spin Rp eta): cleared
    steps hold no slip reversal (v_r keeps its sign on a fine grid of the polynomials),
    steps across v_r = 0 are flagged, and steps far from it are cleared."""
    p = ModelParams(nu=0.01, eta=0.7818, e=0.3, K=17.6, mu=0.1, Rp=1.0)
    pars = np.array(model.params_vector(p))
    order, rtol = tk.taylor_order(1e-8), 1e-8
    C = np.zeros((4, tk.MAX_ORDER + 1))
    W = np.zeros((tk.WORK_ROWS, tk.WORK_COLS))
    cleared = flagged = 0
    for whirl in np.linspace(-3.0, 3.0, 61):  # theta' z: v_r = Rp eta + whirl
        s0 = np.array([1.02, 0.0, 0.05, whirl])
        regime = model.SLIP_POSITIVE if p.Rp * p.eta + whirl / 1.02 >= 0 else model.SLIP_NEGATIVE
        tk.taylor_coefficients(0.0, s0, pars, regime, order, C, W)
        h, _ = tk.step_size(C, order, rtol, rtol * 1e-2)
        S = tk.dense(np.linspace(0.0, h, 401), 0.0, C, order)
        v_r = model.slip_velocity(S[0], S[1], S[2], S[3], p.Rp, p.eta)
        keeps_sign = bool(np.all(regime * v_r > 0.0))
        if tk._slip_clear(C, order, h, regime, pars, _spin(pars)):
            assert keeps_sign, whirl
            cleared += 1
        elif not keeps_sign:
            flagged += 1
    assert cleared > 30 and flagged > 0


def _walk_steps(p, regime, s0, rtol, n_steps):
    """Up to n_steps regime-locked taylor steps from s0 at tau = 0: (C, W, h, eps) of each
    (copies), by the kernels the step loop uses."""
    pars = np.array(model.params_vector(p))
    order = tk.taylor_order(rtol)
    C = np.zeros((4, tk.MAX_ORDER + 1))
    W = np.zeros((tk.WORK_ROWS, tk.WORK_COLS))
    s, tau, steps = np.asarray(s0, dtype=float), 0.0, []
    for _ in range(n_steps):
        tk.taylor_coefficients(tau, s, pars, regime, order, C, W)
        h, eps = tk.step_size(C, order, rtol, rtol * 1e-2)
        steps.append((tau, C.copy(), W.copy(), h, eps))
        s = np.empty(4)
        tk.dense_at(tau + h, tau, C, order, s)
        tau += h
        if regime != model.FREE and math.hypot(s[0], s[1]) < 1.0:
            break  # the contact ended: the regime-locked series no longer applies
    return pars, order, steps


@pytest.mark.slow
def test_step_clear_clears_only_what_step_events_clears():
    """step_clear (the O(N) pre-check inlined into the step loop) against step_events (the
    full pre-check): on free-flight, slip and stick steps and every start flag, a step it
    clears is one step_events clears too, it never clears a step that starts on an event
    surface or a stick step, and it clears most plain free and slip steps."""
    free = ModelParams(nu=0.05, eta=0.7, e=0.05, K=17.6, mu=0.03, Rp=1.0)
    rub = ModelParams(**{**FIG3, "K": 1.75e6}, mu=0.03)  # stiff: short steps
    s_rub = model.synchronous_rub(0.0, rub)
    v_r = model.slip_velocity(*s_rub, rub.Rp, rub.eta)
    slip = model.SLIP_POSITIVE if v_r > 0.0 else model.SLIP_NEGATIVE
    rolling = ModelParams(**ROLLING)
    cases = [
        (free, model.FREE, (0.2, -0.1, 0.3, 0.1), 1e-8),
        (rub, slip, s_rub, 1e-6),
        (rolling, model.STICK, rolling_state(rolling, 0.0), 1e-8),
    ]
    cleared = {}
    for p, regime, s0, rtol in cases:
        pars, order, steps = _walk_steps(p, regime, s0, rtol, 150)
        for starts in ((False, False, True), (True, False, True), (False, True, True)):
            for _, C, W, h, eps in steps:
                spin = _spin(pars)
                clear = tk.step_clear(C, order, h, regime, pars, W, starts, spin)
                if clear:
                    scan = tk.step_events(C, order, h, regime, pars, W, eps, starts, 1e-12, spin)
                    assert scan == tk.SCAN_NONE
                cleared.setdefault((regime, starts), []).append(clear)
    for (regime, starts), flags in cleared.items():
        if regime == model.STICK or starts[0] or starts[1]:
            assert not any(flags)
        else:
            assert np.mean(flags) > 0.5, (regime, np.mean(flags))


@pytest.mark.slow
def test_taylor_fill_equals_the_event_functions_point_by_point():
    """_taylor_fill (the scan grid of locate in one call) gives, bit for bit, the event
    functions of events.event_search (sign (z^2 - 1), -sign v_r, the stick margin) and
    their rates evaluated point by point on the step's polynomial (_taylor_ev)."""
    from rubcli.solvers import events

    for p, regime, s0 in (
        (ModelParams(**FIG3, mu=0.03), model.SLIP_NEGATIVE, (1.02, -0.1, 0.3, 0.9)),
        (ModelParams(**ROLLING), model.STICK, rolling_state(ModelParams(**ROLLING), 0.0)),
    ):
        pars, order, steps = _walk_steps(p, regime, s0, 1e-8, 1)
        t0, C, _, h, _ = steps[0]
        ctx = np.empty(tk.CTX_SIZE)
        tk.fill_context(ctx, t0, C, order, pars, regime)
        n, d = 7, 1e-6
        grid = np.linspace(t0, t0 + h, n + 1)
        row, drow = np.empty(4), np.empty(4)
        fns = [(events.FN_SURFACE, -1.0), (events.FN_SLIP, float(regime))]
        if regime == model.STICK:
            fns = [(events.FN_SURFACE, -1.0), (events.FN_STICK, 1.0), (events.FN_STICK, -1.0)]
        for fn, sign in fns:
            hv, hd = np.empty(n + 1), np.empty(n + 1)
            tk._taylor_fill(ctx, fn, sign, grid, n, pars, d, row, drow, hv, hd)
            for i, t in enumerate(grid):
                if fn == events.FN_STICK:
                    margin = []
                    for u in (t, t + d, t - d):
                        tk._taylor_ev(u, False, ctx, row, drow)
                        margin.append(events.stick_margin(u, *row, pars, sign))
                    value, rate = margin[0], (margin[1] - margin[2]) / (2.0 * d)
                else:
                    tk._taylor_ev(t, fn == events.FN_SLIP, ctx, row, drow)
                    x, y, vx, vy = row
                    if fn == events.FN_SURFACE:
                        value, rate = sign * (x**2 + y**2 - 1.0), sign * (2.0 * (x * vx + y * vy))
                    else:
                        spin = pars[6] * pars[1]
                        value = -sign * model.slip_velocity_value(x, y, vx, vy, spin)
                        rate = -sign * model.slip_velocity_rate(x, y, vx, vy, drow[2], drow[3])
                assert (hv[i], hd[i]) == (value, rate), (fn, sign, i)

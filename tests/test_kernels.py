"""The numba kernels (rubcli/solvers/compiled/) against the pure-Python path.

The compiled path must give the Python path's numbers to round-off: the same events of
the same kinds at the same times, the same regimes, the same states. Round-off differs
only through the eigen-decomposition (hand-written QR in the kernel, LAPACK in Python)
and libm versus CPython's hypot; tolerances below allow ~1e3 ulp of accumulation.
The kernels compile once per machine (cache=True); later test runs load them.
"""

import math

import numpy as np
import pytest

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import FAILED, SUCCESS
from rubcli.solvers import analytic, compiled, control, solve
from rubcli.solvers.compiled import cache, linalg, propagators

ANALYTIC = ["analytic", "analytic-polar"]
FIG3_INITIAL = (0.88544, -0.8039, 0.0, 0.0)
FORCED = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)  # test_stick.py


def assert_same_solution(compiled, python, state_tol=1e-10, time_tol=1e-11):
    assert compiled.status == python.status
    assert compiled.t.size == python.t.size
    assert [ev.kind for ev in compiled.events] == [ev.kind for ev in python.events]
    assert [(ev.regime_before, ev.regime_after) for ev in compiled.events] == [
        (ev.regime_before, ev.regime_after) for ev in python.events
    ]
    times = np.array([ev.tau for ev in compiled.events])
    np.testing.assert_allclose(times, [ev.tau for ev in python.events], rtol=0, atol=time_tol)
    np.testing.assert_array_equal(compiled.regimes, python.regimes)
    scale = 1.0 + np.abs(python.states)
    assert np.max(np.abs(compiled.states - python.states) / scale) < state_tol


def both_paths(prob, method, **options):
    compiled = solve(prob, method, compiled=True, **options)
    python = solve(prob, method, compiled=False, **options)
    assert python.stats.get("n_compiled_steps", 0) == 0
    return compiled, python


# ------------------------------------------------------------------ shared physics


def test_compiled_cores_agree_with_model(fig3_params):
    """compiled.rhs / rhs_jacobian / rhs_columns and the probe of every registered core
    against model.py's public functions, on random states in every regime."""
    assert compiled.ensure_fresh()
    np.testing.assert_allclose(
        cache._probe(cache.PROBE_POINT), cache._probe_values(cache.PROBE_POINT), rtol=1e-13
    )
    p = fig3_params(0.05, phi0=0.4)
    pars = np.array(model.params_vector(p))
    rng = np.random.default_rng(7)
    for _ in range(50):
        s = rng.normal(size=4) * [1.2, 1.2, 3.0, 3.0]
        tau = rng.uniform(0.0, 50.0)
        for regime in (model.FREE, model.SLIP_POSITIVE, model.SLIP_NEGATIVE, model.STICK):
            expected = model.rhs(tau, s, p, regime)
            np.testing.assert_allclose(compiled.rhs(tau, s, pars, regime), expected, rtol=1e-13)
            columns = compiled.rhs_columns(np.array([tau]), s[:, None].copy(), pars, regime)
            np.testing.assert_allclose(columns[:, 0], expected, rtol=1e-13)
            np.testing.assert_allclose(
                compiled.rhs_jacobian(tau, s, pars, regime),
                model.rhs_jacobian(tau, s, p, regime),
                rtol=1e-9 if regime == model.STICK else 1e-13,  # central differences
                atol=1e-9 if regime == model.STICK else 0.0,
            )


@pytest.mark.parametrize("mu_c", [0.0, 0.05, -0.05])
def test_kernel_step_data_agree_with_model(mu_c, fig3_params):
    """What a kernel step is built from (the polar state, rhs, Jacobian and f_tau; the
    Cartesian linearised system A, b) equals model.py's public functions."""
    p = fig3_params(abs(mu_c), phi0=0.4, K=176.0)
    pars = np.array(model.params_vector(p))
    s0 = np.array([1.02, -0.31, 0.4, 1.3])
    tau0 = 2.7
    ws = propagators.workspace()
    propagators._prepare_polar(tau0, s0, pars, mu_c, ws, False)
    real, M = ws[5], ws[6]
    p0 = model.to_polar(s0)
    J, f_tau = model.polar_jacobian(tau0, p0, p, mu_c)
    np.testing.assert_allclose(real[0:4], p0, rtol=1e-15)
    np.testing.assert_allclose(real[4:8], model.polar_rhs(tau0, p0, p, mu_c), rtol=1e-13)
    np.testing.assert_allclose(real[8:12], f_tau, rtol=1e-13)
    np.testing.assert_allclose(M, J, rtol=1e-13)
    propagators._prepare_cartesian(tau0, s0, pars, mu_c, ws, False)
    A, b = model.linearised_contact_system(s0, p, mu_c)
    np.testing.assert_allclose(M, A, rtol=1e-13)
    np.testing.assert_allclose(real[4:8], b, rtol=1e-13)
    np.testing.assert_allclose(real[0:4], np.linalg.solve(A, -b), rtol=1e-12)  # s_c


def test_probe_mismatch_flushes_and_falls_back(monkeypatch):
    """ensure_fresh: a stale probe triggers a recompile of every cached kernel, and a
    persistent disagreement disables the kernels (pure Python, with a warning)."""

    class FakeDispatcher:
        recompiled = 0

        def recompile(self):
            FakeDispatcher.recompiled += 1

    fakes = [FakeDispatcher(), FakeDispatcher()]
    monkeypatch.setattr(cache, "_dispatchers", lambda: fakes)
    monkeypatch.setattr(cache, "_usable", None)
    monkeypatch.setattr(cache, "_probe_values", lambda x: cache._probe(x) + 1.0)
    with pytest.warns(RuntimeWarning, match="pure-Python"):
        assert compiled.ensure_fresh() is False
    assert FakeDispatcher.recompiled == len(fakes)
    prob = Problem.from_periods(FORCED, (1.2, 0.0, 0.0, 1.0), 0.2, 10)
    assert solve(prob, "analytic-polar").settings["compiled"] is False
    monkeypatch.setattr(cache, "_usable", None)
    monkeypatch.setattr(cache, "_probe_values", cache._probe)
    assert compiled.ensure_fresh() is True


def test_changed_core_source_recompiles_every_kernel(monkeypatch, tmp_path):
    """ensure_fresh: a cache built from other sources of the compiled-in files (model.py,
    events.py, control.py: a changed event rule the probe cannot see) is flushed, and
    the new fingerprint stored; the next process with the same sources keeps it."""

    class FakeDispatcher:
        recompiled = 0

        def recompile(self):
            FakeDispatcher.recompiled += 1

    fakes = [FakeDispatcher(), FakeDispatcher()]
    stored = tmp_path / "cores.fingerprint"
    stored.write_text("built from other sources\n")
    monkeypatch.setattr(cache, "FINGERPRINT", stored)
    monkeypatch.setattr(cache, "_dispatchers", lambda: fakes)
    monkeypatch.setattr(cache, "_usable", None)
    assert compiled.ensure_fresh() is True
    assert FakeDispatcher.recompiled == len(fakes)
    assert stored.read_text().strip() == cache._fingerprint()
    monkeypatch.setattr(cache, "_usable", None)
    assert compiled.ensure_fresh() is True
    assert FakeDispatcher.recompiled == len(fakes)  # same sources: nothing flushed


def test_fingerprint_covers_every_file_compiled_into_the_kernels():
    """numba sees a change only in a kernel's own file: the fingerprint must cover the
    registered cores' files and every module of the compiled sub-package (a kernel calls
    into roots.py, precheck.py, ...), so that a change to any of them recompiles."""
    from pathlib import Path

    from rubcli import model
    from rubcli.solvers import control, events
    from rubcli.solvers.compiled import jit

    package = Path(cache.__file__).parent
    modules = {p.name for p in package.glob("*.py")}
    assert {"roots.py", "precheck.py", "taylor.py", "jit.py", "dop853_loop.py"} <= modules
    covered = {Path(p).resolve() for p in cache.CORE_FILES}
    assert {p.resolve() for p in package.glob("*.py")} <= covered
    for core in jit.COMPILABLE_CORES:  # every registered core's own file
        assert Path(core.__code__.co_filename).resolve() in covered, core.__name__
    assert {Path(m.__file__).resolve() for m in (model, events, control)} <= covered


# ------------------------------------------------------------------ eigen-decomposition


def _eig(M):
    ws = propagators.workspace()
    lam, V, _, _, _, _, Mw, B, Q, H, Z, scale, x, _, _, _ = ws
    Mw[:, :] = M
    ok = linalg._eig_small(Mw, lam, V, B, Q, H, Z, scale, x)
    return ok, lam.copy(), V.copy(), ws


def _contact_matrices(p, mu, tau=0.3):
    """The polar J and the Cartesian A at a state just outside the synchronous rub."""
    r = model.synchronous_rub_radii(p)[-1]
    s = model.synchronous_rub(tau, p, r)
    s[:2] *= 1.0 + 0.3 * (r - 1.0)
    J, _ = model.polar_jacobian(tau, model.to_polar(s), p, mu)
    A, _ = model.linearised_contact_system(s, p, mu)
    return J, A


@pytest.mark.parametrize("K", [17.6, 17.6e3, 1.75e6])
@pytest.mark.parametrize("mu", [0.0, 0.02, 0.3])
def test_eigensolver_matches_lapack_on_contact_matrices(K, mu, fig3_params):
    for M in _contact_matrices(fig3_params(mu, K=K), mu):
        ok, lam, V, _ = _eig(M)
        assert ok
        reference = np.linalg.eigvals(M)
        scale = np.abs(reference).max()
        for value in lam:  # every eigenvalue is one of LAPACK's, to round-off
            assert np.min(np.abs(reference - value)) < 1e-13 * scale
        np.testing.assert_allclose(np.linalg.norm(V, axis=0), 1.0, rtol=1e-14)
        # the residual relative to the balanced norm, as linalg._residual_ok checks it
        assert linalg._residual_ok(M, lam, V, _eig(M)[3][11])


@pytest.mark.parametrize("K", [17.6, 1.75e6])
@pytest.mark.parametrize("mu", [0.0, 0.02])
def test_warm_eigensolver_from_nearby_eigenvalues(K, mu, fig3_params):
    """_eig_warm (Newton on the characteristic quartic from the previous step's
    eigenvalues, structured eigenvectors, V^-1 from the left eigenvectors) agrees with
    LAPACK whenever it accepts; it declines (for the QR path) from coincident guesses.

    For the polar J it must accept. The Cartesian stiffness block has entries ~K, so at
    K = 1.75e6 the quartic's value cancels to ~eps K^2 and Newton may not meet its
    tolerance: declining is then the right answer (the QR path takes over)."""
    J, A = _contact_matrices(fig3_params(mu, K=K), mu)
    J_next, A_next = _contact_matrices(fig3_params(mu, K=K), mu, tau=0.32)  # one step on
    for M, M_next, must_accept in ((J, J_next, True), (A, A_next, K < 1e3)):
        ok, previous, _, ws = _eig(M)
        assert ok
        lam, V, Vinv, B, scale = ws[0], ws[1], ws[15], ws[7], ws[11]
        accepted = linalg._eig_warm(M_next, lam, V, Vinv, previous, B, scale)
        assert accepted or not must_accept
        if accepted:
            reference = np.linalg.eigvals(M_next)
            for value in lam:
                assert np.min(np.abs(reference - value)) < 1e-13 * np.abs(reference).max()
            assert linalg._residual_ok(M_next, lam, V, scale)
            np.testing.assert_allclose(Vinv @ V, np.eye(4), atol=1e-12)
        same = np.full(4, previous[0])
        assert not linalg._eig_warm(M_next, lam, V, Vinv, same, B, scale)


def test_eigensolver_random_and_defective_matrices():
    rng = np.random.default_rng(3)
    for _ in range(300):
        M = rng.normal(size=(4, 4)) * 10.0 ** rng.uniform(-3, 3, size=(4, 4))
        ok, lam, V, _ = _eig(M)
        assert ok
        residual = np.abs(M @ V - V * lam).max()
        assert residual < 1e-12 * np.abs(M).sum(axis=0).max()
    jordan = np.diag(np.ones(3), 1)  # defective: no eigenbasis
    ws = propagators.workspace()
    ws[6][:, :] = jordan
    assert not propagators._eigenbasis(ws, False) < 1e10  # handed to Python's expm fallback


# ------------------------------------------------------------------ kernel vs Python


@pytest.mark.parametrize("method", ANALYTIC)
def test_paper_case_with_contacts(method, fig3_params):
    prob = Problem.from_periods(fig3_params(0.02), FIG3_INITIAL, 3, 50)
    compiled, python = both_paths(prob, method)
    assert compiled.status == SUCCESS and len(compiled.events) >= 2
    assert compiled.stats["n_compiled_steps"] > 0.9 * compiled.stats["n_contact_steps"]
    assert_same_solution(compiled, python)


@pytest.mark.parametrize("method", ANALYTIC)
def test_chaotic_case_with_many_switches(method, fig3_params):
    """mu = 0.05 (the paper's chaotic case) with a coarse step: many entries and exits."""
    prob = Problem.from_periods(fig3_params(0.05), FIG3_INITIAL, 2, 50)
    compiled, python = both_paths(prob, method, steps_per_period=200)
    assert compiled.stats["n_compiled_steps"] > 0
    assert_same_solution(compiled, python, state_tol=1e-9, time_tol=1e-10)


@pytest.mark.slow
@pytest.mark.parametrize("method", ANALYTIC)
def test_stick_slip_case(method):
    r = model.rolling_whirl_radius(FORCED)
    prob = Problem.from_periods(FORCED, (r, 0.0, 0.0, -FORCED.Rp * FORCED.eta), 3, 50)
    compiled, python = both_paths(prob, method, steps_per_period=800)
    kinds = {ev.kind for ev in compiled.events}
    assert {"stick_exit", "stick_entry"} <= kinds
    assert compiled.stats["n_compiled_steps"] > 0 and compiled.stats["n_stick_steps"] > 0
    assert_same_solution(compiled, python)


def test_exact_synchronous_rub_at_stiff_stator(fig3_params):
    """K = 1.75e6, analytic-polar: both paths stay on the exact orbit to round-off."""
    p = fig3_params(0.01, K=1.75e6)
    r = model.synchronous_rub_radii(p)[-1]
    prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p, r)), 1, 10)
    compiled, python = both_paths(prob, "analytic-polar", steps_per_period=100)
    assert not compiled.events
    assert compiled.stats["n_compiled_steps"] == python.stats["n_contact_steps"] >= 100
    exact = model.synchronous_rub(prob.t_eval, p, r).T
    assert np.max(np.abs(compiled.states[:, :2] - exact[:, :2])) < 1e-9
    assert_same_solution(compiled, python, state_tol=1e-11)


@pytest.mark.slow
@pytest.mark.parametrize("method", ANALYTIC)
def test_ill_conditioned_steps_are_left_to_python(method, fig3_params, monkeypatch):
    """With a condition limit of 1 every eigenbasis is 'ill-conditioned': the kernel hands
    every step back and Python takes it with its expm fallback."""
    monkeypatch.setattr(analytic, "EIGVEC_COND_LIMIT", 1.0)
    prob = Problem.from_periods(fig3_params(0.02), FIG3_INITIAL, 0.3, 20)
    compiled, python = both_paths(prob, method)
    assert compiled.stats["n_compiled_steps"] == 0
    assert compiled.stats["n_expm_fallbacks"] == compiled.stats["n_contact_steps"] > 0
    assert_same_solution(compiled, python, state_tol=1e-13, time_tol=1e-13)


@pytest.mark.parametrize("method", ANALYTIC)
def test_step_budget_stops_both_paths_at_the_same_step(method, fig3_params):
    prob = Problem.from_periods(fig3_params(0.02), FIG3_INITIAL, 3, 50)
    compiled, python = both_paths(prob, method, max_steps=700)
    assert compiled.status == FAILED and "max_steps" in compiled.message
    assert compiled.stats["nsteps"] == python.stats["nsteps"] == 700
    assert compiled.message == python.message
    assert_same_solution(compiled, python)


# ------------------------------------------------------------------ adaptive steps

ADAPTIVE_TOLS = [1e-4, 1e-7]
STEP_COUNTS = ("nsteps", "n_contact_steps", "n_stick_steps", "n_rejected_steps")


def assert_same_steps(compiled, python):
    """The same step sequence: every count of the Python path's, and no expm fallback."""
    for key in STEP_COUNTS:
        assert compiled.stats[key] == python.stats[key], key
    assert compiled.stats["n_expm_fallbacks"] == python.stats["n_expm_fallbacks"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("tol", ADAPTIVE_TOLS)
@pytest.mark.parametrize("method", ANALYTIC)
@pytest.mark.parametrize("perturbation", [0.0, 0.3])
def test_adaptive_steps_compiled_on_the_synchronous_rub(perturbation, method, tol, fig3_params):
    """On the exact synchronous rub (and off it by 30% of the penetration) the run stays
    in slip+ contact: every step is compiled, with the Python path's step sequence."""
    p = fig3_params(0.02)
    r = model.synchronous_rub_radii(p)[-1]
    s0 = model.synchronous_rub(0.0, p, r)
    s0[:2] *= 1.0 + perturbation * (r - 1.0)
    prob = Problem.from_periods(p, tuple(s0), 2, 10)
    compiled, python = both_paths(prob, method, analytic_tol=tol)
    assert compiled.status == SUCCESS and not compiled.events
    assert compiled.settings["compiled"] and not python.settings["compiled"]
    assert compiled.stats["n_compiled_steps"] == compiled.stats["n_contact_steps"] > 0
    assert_same_steps(compiled, python)
    assert_same_solution(compiled, python)


@pytest.mark.slow
@pytest.mark.parametrize("tol", ADAPTIVE_TOLS)
@pytest.mark.parametrize("method", ANALYTIC)
def test_adaptive_steps_compiled_on_the_paper_case(method, tol, fig3_params):
    """Figure 3 at mu = 0.02 over 3 periods: contact exits and re-entries. The steps near
    each event are recomputed by Python's loop (the kernel hands back before the pair)."""
    prob = Problem.from_periods(fig3_params(0.02), FIG3_INITIAL, 3, 50)
    compiled, python = both_paths(prob, method, analytic_tol=tol)
    kinds = [ev.kind for ev in compiled.events]
    assert compiled.status == SUCCESS and {"contact_exit", "contact_entry"} <= set(kinds)
    assert compiled.stats["n_rejected_steps"] > 0
    assert compiled.stats["n_compiled_steps"] > 0.9 * compiled.stats["n_contact_steps"]
    assert_same_steps(compiled, python)
    assert_same_solution(compiled, python, time_tol=1e-10)


@pytest.mark.parametrize("method", ANALYTIC)
def test_adaptive_steps_compiled_around_stick(method):
    """Stick-slip: adaptive stick steps stay in Python, slip steps between them compile."""
    r = model.rolling_whirl_radius(FORCED)
    prob = Problem.from_periods(FORCED, (r, 0.0, 0.0, -FORCED.Rp * FORCED.eta), 3, 50)
    compiled, python = both_paths(prob, method, analytic_tol=1e-4)
    assert {"stick_exit", "stick_entry"} <= {ev.kind for ev in compiled.events}
    assert compiled.stats["n_compiled_steps"] > 0 and compiled.stats["n_stick_steps"] > 0
    assert_same_steps(compiled, python)
    assert_same_solution(compiled, python, time_tol=1e-10)


@pytest.mark.parametrize("max_steps", [700, 701])
def test_adaptive_step_budget_stops_both_paths_at_the_same_step(max_steps, fig3_params):
    """The budget may end between the two half steps of a pair (701): the kernel leaves
    a pair that does not fit to Python, which stops after its first half."""
    prob = Problem.from_periods(fig3_params(0.02), FIG3_INITIAL, 3, 50)
    compiled, python = both_paths(prob, "analytic-polar", analytic_tol=1e-5, max_steps=max_steps)
    assert compiled.status == FAILED and "max_steps" in compiled.message
    assert compiled.stats["nsteps"] == python.stats["nsteps"] == max_steps
    assert compiled.message == python.message
    assert_same_steps(compiled, python)
    assert_same_solution(compiled, python)


@pytest.mark.slow
@pytest.mark.parametrize("method", ANALYTIC)
def test_ill_conditioned_adaptive_steps_are_left_to_python(method, fig3_params, monkeypatch):
    monkeypatch.setattr(analytic, "EIGVEC_COND_LIMIT", 1.0)
    prob = Problem.from_periods(fig3_params(0.02), FIG3_INITIAL, 0.3, 20)
    compiled, python = both_paths(prob, method, analytic_tol=1e-5)
    assert compiled.stats["n_compiled_steps"] == 0
    assert compiled.stats["n_expm_fallbacks"] == compiled.stats["n_contact_steps"] > 0
    assert_same_solution(compiled, python, state_tol=1e-13, time_tol=1e-13)


def test_adaptive_kernel_hands_back_whole_pairs(fig3_params):
    """advance_contact_adaptive on its own: with no room for a pair it takes none (h and
    the state as given), a pair is taken as two steps, at t_end it stops with the
    controller's proposed step, and a pair whose scan grid outgrows the buffers is
    handed back untaken with the size it needs."""
    p = fig3_params(0.02)
    r = model.synchronous_rub_radii(p)[-1]
    s0 = model.synchronous_rub(0.0, p, r)
    s0[:2] *= 1.0 + 0.3 * (r - 1.0)  # off the orbit, in slip+ contact with no event
    t_eval = np.linspace(0.0, p.period, 11)
    pars = np.array(model.params_vector(p))
    h0 = p.period / 400
    settings = (
        1e-7,
        control.SAFETY,
        control.MIN_FACTOR,
        control.MAX_FACTOR,
        p.period * control.MAX_STEP_FRACTION,
        control.MIN_STEP_FRACTION * p.period,
    )

    def advance(pairs, size=analytic.KERNEL_SCAN_POINTS):
        state = s0.copy()
        out = np.full((t_eval.size, 4), np.nan)
        regimes = np.zeros(t_eval.size, dtype=np.int64)
        result = compiled.advance_contact_adaptive(
            True, 0.0, state, h0, t_eval[-1], model.SLIP_POSITIVE, pars, t_eval, out,
            regimes, 1, pairs, analytic.CONTACT_SCAN_FRACTION, analytic.EIGVEC_COND_LIMIT,
            (False, False, False), settings, compiled.adaptive_work(size),
        )  # fmt: skip
        return state, regimes, result

    state, _, (tau, k, steps, rejected, h, reason, _) = advance(0)
    assert (tau, k, steps, rejected, h, reason) == (0.0, 1, 0, 0, h0, compiled.STOP_LIMIT)
    np.testing.assert_array_equal(state, s0)
    state, _, (tau, _, steps, _, h, reason, _) = advance(1)
    assert (steps, reason) == (2, compiled.STOP_LIMIT) and tau > 0.0 and h != h0
    assert not np.array_equal(state, s0)
    _, regimes, (tau, k, steps, _, h, reason, _) = advance(10**9)
    assert reason == compiled.STOP_END and tau >= t_eval[-1] and k == t_eval.size
    assert steps % 2 == 0 and 0.0 < h <= 4 * settings[4]
    assert np.all(regimes[1:] == model.SLIP_POSITIVE)
    state, _, (tau, k, steps, _, h, reason, need) = advance(10**9, size=1)
    assert (tau, k, steps, h, reason) == (0.0, 1, 0, h0, compiled.STOP_GROW) and need >= 2
    np.testing.assert_array_equal(state, s0)


# ------------------------------------------------------------------ scipy right-hand sides


@pytest.mark.slow
@pytest.mark.parametrize("method", ["rk45", "radau"])
def test_scipy_compiled_rhs_gives_the_same_solution(method, fig3_params):
    prob = Problem.from_periods(fig3_params(0.02), FIG3_INITIAL, 2, 50)
    compiled, python = both_paths(prob, method, rtol=1e-9, atol=1e-11)
    assert compiled.settings["compiled"] and not python.settings["compiled"]
    # the rhs agree to round-off; the step controllers may still diverge at that level
    assert_same_solution(compiled, python, state_tol=1e-8, time_tol=1e-8)


def _closure_dispatchers(fn, seen=None):
    """The numba dispatchers a compiled event-search function reaches through its
    closure (the search's functions are closures of ``events.event_search``)."""
    from numba.core.dispatcher import Dispatcher

    seen = {} if seen is None else seen
    for cell in fn.py_func.__closure__ or ():
        value = cell.cell_contents
        if isinstance(value, Dispatcher) and value.py_func.__qualname__ not in seen:
            seen[value.py_func.__qualname__] = value
            _closure_dispatchers(value, seen)
    return seen


@pytest.mark.slow
def test_event_search_compiles_each_function_once(fig3_params):
    """numba compiles a callee once for every distinct constant argument it is handed:
    the event search passes its kinds and flags as run-time values (``events.run_time``),
    so that one locate over every regime (free, slip with friction, stick) compiles each
    of its functions once, with no constant-typed argument (before: three to six times
    each, half of a first run's 87 s compile). Compiled here without a cache, so that
    every signature is made in this test."""
    import numba

    from rubcli.solvers import events

    @numba.njit
    def ev(t, deriv, ctx, row, drow):
        r = 1.0 - 0.5 * math.cos(t)
        c, s = math.cos(t), math.sin(t)
        row[0], row[1] = r * c, r * s
        row[2] = 0.5 * math.sin(t) * c - r * s
        row[3] = 0.5 * math.sin(t) * s + r * c
        if deriv:
            drow[0], drow[1] = row[2], row[3]
            drow[2], drow[3] = -row[0], -row[1]

    locate, _ = events.event_search(ev, compile=numba.njit)
    pars = np.array(model.params_vector(fig3_params(0.03)))
    n = 64
    grid = np.linspace(0.0, 6.0, n + 1)
    hv, hd, row, drow = np.empty(n + 1), np.empty(n + 1), np.empty(4), np.empty(4)
    starts = events.start_flags(events.NO_EVENT)
    kinds = []
    for regime in (model.FREE, model.SLIP_POSITIVE, model.STICK):
        kinds.append(locate(0.0, regime, pars, grid, n, starts, 1e-12, hv, hd, row, drow)[1])
    assert kinds[0] == events.ENTRY  # the orbit reaches the surface from inside
    searched = _closure_dispatchers(locate)
    for name in ("crossing", "_crossing_scan", "fill_values", "event_values"):
        # reached by every locate above: compiled exactly once
        assert len(searched[f"event_search.<locals>.{name}"].signatures) == 1, name
    for name, dispatcher in searched.items():
        signatures = [str(s) for s in dispatcher.signatures]
        assert len(signatures) <= 1, (name, signatures)
        assert not any("Literal" in s for s in signatures), (name, signatures)

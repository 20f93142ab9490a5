"""Shared fixtures: the paper's Figure 3 parameters (model notes, section 6)."""

import pytest

from rubcli.model import ModelParams

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16, "phi0": 0.0}
FIG3_INITIAL = (0.88544, -0.8039, 0.0, 0.0)


@pytest.fixture
def fig3_params():
    def make(mu: float = 0.0, **overrides) -> ModelParams:
        return ModelParams(**{**FIG3, "mu": mu, **overrides})

    return make


@pytest.fixture(scope="session", autouse=True)
def private_state_dir(tmp_path_factory):
    """The key that signs output-dir manifests (rubcli.io.manifest) is kept in a
    session's temporary dir, for the commands run in this process and in subprocesses,
    so that the tests never write into the user's home."""
    import os

    from rubcli.io import manifest

    if not os.environ.get(manifest.STATE_ENV):
        os.environ[manifest.STATE_ENV] = str(tmp_path_factory.mktemp("rubcli-state"))
        manifest._key.cache_clear()
    return os.environ[manifest.STATE_ENV]


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels():
    """Compile (or load) every numba kernel once, before any test runs.

    On a fresh machine the first compiled call compiles for tens of seconds; a test that
    gives a solver a tight wall-time budget must not pay that inside its budget. A few
    periods of the Figure 3 case with friction (contact switches, slip reversals) and
    of a stick-slip case reach every kernel: fixed and adaptive analytic steps, the
    compiled DOP853 with its events, and the scipy methods' compiled right-hand sides.
    """
    from rubcli.problem import Problem
    from rubcli.solvers import solve

    p = ModelParams(**{**FIG3, "mu": 0.03})
    prob = Problem.from_periods(p, FIG3_INITIAL, 3, 10)
    stiff = Problem.from_periods(
        ModelParams(**{**FIG3, "K": 1.76e4, "mu": 0.03}), FIG3_INITIAL, 0.2, 10
    )
    for problem in (prob, stiff):
        solve(problem, "analytic", steps_per_period=100)
        solve(problem, "analytic-polar", steps_per_period=100)
        solve(problem, "analytic-polar", analytic_tol=1e-5)
        solve(problem, "analytic", analytic_tol=1e-5)
        solve(problem, "dop853-jit", rtol=1e-6, atol=1e-8)
        solve(problem, "taylor", rtol=1e-6, atol=1e-8)
        solve(problem, "radau", rtol=1e-4, atol=1e-6)

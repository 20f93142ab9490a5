"""Golden regression: every method's outputs on short scenarios, pinned.

``tests/golden/solvers.json`` holds, for each scenario and method setting of
``tests/golden/scenarios.py``, every output sample, every located event (time, kind,
regimes), the step counts and the status. A change of the solvers must reproduce them to
what each method guarantees on any machine, whatever its BLAS:

- **exactly**: the status, the kind and regimes of every event, the regime of every
  sample: a rounding difference cannot change them unless an event lies within the
  run's error of a sample time or of grazing, which the scenarios avoid (measured: they
  never change between BLAS kernels, ``tests/golden/kernel_spread.py``);
- **to 1e-12** (relative to max(1, |value|)), states, event times and the step counts
  exactly, for the method settings in ``BLAS_FREE``: every step runs in numba-compiled
  code with its own 4x4 arithmetic (``rubcli/solvers/compiled/``), or in scalar Python,
  and calls no BLAS or LAPACK routine, so the numbers do not depend on the BLAS kernel
  (measured: bit-identical under five OpenBLAS kernels);
- **to the method's error propagated by the flow** for every other setting (scipy's
  integrators, the pure-Python paths and the adaptive analytic methods, whose linear
  algebra goes through numpy's BLAS): a kernel changes the rounding of each BLAS call,
  which can flip a decision of the step-size controller (accept or reject, the next
  step) and so change the run by up to about one local error, ``rtol + atol`` of the
  state's size (``analytic_tol`` for the adaptive analytic methods; for a fixed-step
  path only rounding, 4 eps per step), carried to the end by the flow's growth of a
  perturbation over the scenario ``G`` (``flow_growth``: measured by finite differences
  of the start with ``dop853-jit``, itself BLAS-free; 4-7 for the Figure 3 start, 1.3e4
  for the stiff stator, 4e5 for the ringing rub at K = 1.75e6). The states and the event
  times are pinned to that bound (never tighter than 1e-12). It is meant as a bound, not
  an estimate: the spreads measured across kernels lie 50 times below it (DOP853 on the
  stiff stator under Haswell) to 1e11 times, mostly 1e4-1e8. Their step counts are
  pinned to ``COUNT_TOLERANCE`` and ``COUNT_SLACK`` (10 % plus 10): a flipped decision
  changes the counts; measured, only LSODA's changed (673 -> 713 steps, 32 -> 37
  Jacobians on the ringing rub under Haswell), whose Fortran core also switches method
  and order on BLAS results.

``.ci/run`` runs this test under two ``OPENBLAS_CORETYPE`` values besides the plain suite.
Where an algorithm changes on purpose, regenerate with ``python tests/golden/make_golden.py``,
review the diff and say why in the commit; ``python tests/golden/kernel_spread.py``
measures the spread of every pinned run across BLAS kernels again.
"""

import functools
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

GOLDEN = Path(__file__).parent / "golden"
sys.path.insert(0, str(GOLDEN))

from scenarios import record, runs, scenarios  # noqa: E402

from rubcli.problem import Problem  # noqa: E402
from rubcli.solvers import solve  # noqa: E402

PINNED = json.loads((GOLDEN / "solvers.json").read_text())
TOLERANCE = 1e-12
RUNS = list(runs())
# Method settings whose numbers do not depend on the BLAS kernel (module docstring).
BLAS_FREE = frozenset(
    {"analytic", "analytic-polar", "dop853-jit", "dop853-jit-python-events", "taylor",
     "taylor-python-events"}
)  # fmt: skip
# Change of a step count allowed where BLAS is used: 10 % plus 10 (measured: at most 6 %,
# LSODA's steps, and 5 of 32 of its Jacobians, on the ringing rub under Haswell).
COUNT_TOLERANCE, COUNT_SLACK = 0.1, 10
ROUNDING_PER_STEP = 4 * np.finfo(float).eps  # a fixed-step path: rounding only
GROWTH_PERTURBATION = 1e-7  # relative size of the start's perturbation in flow_growth


@functools.cache
def flow_growth(scenario: str) -> float:
    """The growth over the scenario of a perturbation of its start: the largest relative
    change (to max(1, |value|), as the pins are measured) of any output sample per
    relative change of one start component, by finite differences with ``dop853-jit``
    at rtol 1e-12 (BLAS-free, so the same on every machine)."""
    problem = scenarios()[scenario]
    options = {"rtol": 1e-12, "atol": 1e-14, "max_steps": 1_000_000, "max_wall_time_s": 600.0}
    base = solve(problem, "dop853-jit", **options).states
    growth = 1.0
    for j in range(4):
        start = np.array(problem.initial)
        start[j] += GROWTH_PERTURBATION * max(1.0, abs(start[j]))
        moved = Problem(problem.params, tuple(start), problem.t_eval, problem.name)
        states = solve(moved, "dop853-jit", **options).states
        change = np.abs(states - base) / np.maximum(1.0, np.abs(base)) / GROWTH_PERTURBATION
        growth = max(growth, float(change.max()))
    return growth


def state_tolerance(scenario: str, label: str, options: dict, nsteps: int) -> float:
    """The pin on states and event times of one run (module docstring)."""
    if label in BLAS_FREE:
        return TOLERANCE
    if "rtol" in options:
        local = options["rtol"] + options["atol"]
    elif options.get("analytic_tol") is not None:
        local = options["analytic_tol"]
    else:
        local = nsteps * ROUNDING_PER_STEP
    return max(TOLERANCE, local * flow_growth(scenario))


def _close(a, b, tolerance: float) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(
        np.all(np.abs(a - b) <= tolerance * np.maximum(1.0, np.abs(b)))
    )


def _counts_close(got: dict, expected: dict, label: str) -> bool:
    if label in BLAS_FREE or got.keys() != expected.keys():
        return got == expected
    return all(abs(got[k] - v) <= COUNT_TOLERANCE * v + COUNT_SLACK for k, v in expected.items())


@pytest.mark.parametrize(
    "scenario, label, problem, method, options",
    RUNS,
    ids=[f"{r[0]}-{r[1]}" for r in RUNS],
)
def test_outputs_are_pinned(scenario, label, problem, method, options):
    expected = PINNED[scenario][label]
    got = record(solve(problem, method, **options))
    assert got["status"] == expected["status"], got["message"]
    assert [e[1:] for e in got["events"]] == [e[1:] for e in expected["events"]]
    assert got["regimes"] == expected["regimes"]
    tolerance = state_tolerance(scenario, label, options, expected["stats"]["nsteps"])
    assert _close([e[0] for e in got["events"]], [e[0] for e in expected["events"]], tolerance)
    assert _close(got["states"], expected["states"], tolerance)
    assert math.isclose(got["t_end"], expected["t_end"], rel_tol=TOLERANCE)
    assert _counts_close(got["stats"], expected["stats"], label), (got["stats"], expected["stats"])


def test_every_pinned_run_is_run():
    labels = {(r[0], r[1]) for r in RUNS}
    assert labels == {(s, m) for s, runs_ in PINNED.items() for m in runs_}


def test_blas_free_settings_are_pinned_tightly():
    """Every setting named BLAS-free is a pinned one: a renamed label must not fall back
    to the looser pin unnoticed."""
    labels = {label for runs_ in PINNED.values() for label in runs_}
    assert labels >= BLAS_FREE

"""Golden regression: every method's outputs on short scenarios, pinned (issue 10).

``tests/golden/solvers.json`` holds, for each scenario and method setting of
``tests/golden/scenarios.py``, every output sample, every located event (time, kind,
regimes), the step counts and the status, as produced before the solver package was
restructured. A restructuring must reproduce them: the same events and counts exactly,
and the states and event times to 1e-12 (relative to max(1, |value|)). Where an
algorithm changes on purpose, regenerate with ``python tests/golden/make_golden.py``,
review the diff and say why in the commit.
"""

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

GOLDEN = Path(__file__).parent / "golden"
sys.path.insert(0, str(GOLDEN))

from scenarios import record, runs  # noqa: E402

from rubcli.solvers import solve  # noqa: E402

PINNED = json.loads((GOLDEN / "solvers.json").read_text())
TOLERANCE = 1e-12
RUNS = list(runs())


def _close(a, b) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(
        np.all(np.abs(a - b) <= TOLERANCE * np.maximum(1.0, np.abs(b)))
    )


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
    assert _close([e[0] for e in got["events"]], [e[0] for e in expected["events"]])
    assert got["regimes"] == expected["regimes"]
    assert _close(got["states"], expected["states"])
    assert math.isclose(got["t_end"], expected["t_end"], rel_tol=TOLERANCE)
    assert got["stats"] == expected["stats"]


def test_every_pinned_run_is_run():
    labels = {(r[0], r[1]) for r in RUNS}
    assert labels == {(s, m) for s, runs_ in PINNED.items() for m in runs_}

"""Does the paper's machine keep its speed? Every method's time on the paper's cases
here and at an earlier revision, measured side by side.

    python benchmarks/against_revision.py REV            # e.g. a commit before a change

The revision is checked out into a temporary git worktree; the same timing code runs in a
fresh process for each tree (``PYTHONPATH`` pointing at it), alternating, twice, each
process warming the kernels first (each tree compiles its own on first use) and taking
the best of its repeats; each cell is the better of the two processes. The cases are
the peers' (benchmarks/peers.py): the Figure 3 machine over 100 forcing periods at mu =
0 and 0.03, and the dry whip (mu = 0.05, 100 periods from period 67), final state only.
Writes benchmarks/against_revision.md.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16}
START = (0.88544, -0.8039, 0.0, 0.0)
METHODS = {
    "dop853-jit": {"rtol": 1e-7, "atol": 1e-9},
    "taylor": {"rtol": 1e-7, "atol": 1e-9},
    "analytic": {"steps_per_period": 400},
    "analytic-polar": {"steps_per_period": 400},
}
REPEATS = 10
ROUNDS = 2


def worker() -> None:
    """Time every method on every case in this process; print JSON {case: {method: s}}."""
    import numpy as np

    from rubcli.model import ModelParams
    from rubcli.problem import Problem
    from rubcli.solvers import solve

    def problem(mu: float, lead: int) -> Problem:
        params = ModelParams(mu=mu, **FIG3)
        start, t0 = START, 0.0
        if lead:
            first = Problem.from_periods(params, START, lead, 1)
            start = tuple(solve(first, "dop853-jit", rtol=1e-13, atol=1e-15).states[-1])
            t0 = lead * params.period
        return Problem(params, start, np.array([t0, t0 + 100 * params.period]))

    cases = {"mu = 0": problem(0.0, 0), "mu = 0.03": problem(0.03, 0),
             "dry whip": problem(0.05, 67)}  # fmt: skip
    out: dict[str, dict[str, float]] = {}
    for name, prob in cases.items():
        out[name] = {}
        for method, options in METHODS.items():
            solve(prob, method, **options)
            best = float("inf")
            for _ in range(REPEATS):
                start = time.perf_counter()
                solve(prob, method, **options)
                best = min(best, time.perf_counter() - start)
            out[name][method] = best
    print(json.dumps(out))


def run_tree(tree: Path) -> dict[str, dict[str, float]]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, __file__, "--worker"], env=env, check=True,
                          capture_output=True, text=True)  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(revision: str) -> None:
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "tree"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(tree),
                        revision], check=True)  # fmt: skip
        try:
            runs: dict[str, list] = {"here": [], revision: []}
            for _ in range(ROUNDS):
                runs["here"].append(run_tree(ROOT))
                runs[revision].append(run_tree(tree))
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                           check=True)  # fmt: skip
    best = {
        key: {case: {m: min(r[case][m] for r in results) for m in METHODS} for case in results[0]}
        for key, results in runs.items()
    }
    lines = [
        "# The paper's machine against an earlier revision",
        "",
        f"Command: `python benchmarks/against_revision.py {revision}`",
        "",
        f"Load average at start: {load:.2f}. Best of {REPEATS} solves in a "
        f"process, better of {ROUNDS} processes per tree (alternating).",
        "",
        f"| case | method | here (ms) | {revision[:10]} (ms) | here / before |",
        "|---|---|---:|---:|---:|",
    ]
    for case in best["here"]:
        for method in METHODS:
            now, then = best["here"][case][method], best[revision][case][method]
            lines.append(f"| {case} | `{method}` | {now * 1e3:.2f} | {then * 1e3:.2f} | "
                         f"{now / then:.2f} |")  # fmt: skip
    text = "\n".join(lines) + "\n"
    (HERE / "against_revision.md").write_text(text)
    print(text)


if __name__ == "__main__":
    if sys.argv[1:] == ["--worker"]:
        worker()
    elif len(sys.argv) == 2:
        main(sys.argv[1])
    else:
        sys.exit(__doc__)

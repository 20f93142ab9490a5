"""Solve times of every method family on a few cases, for an A/B comparison of two checkouts.

Run it once per checkout, alternately, in the same hour (issue 10: the redesign must not
make any method slower than the run-to-run noise)::

    PYTHONPATH=/path/to/old python benchmarks/redesign_ab.py --tag old
    python benchmarks/redesign_ab.py --tag new

Each row is the median (and minimum) of ``--repeats`` in-process solves after a warm-up
(numba's cache load is not timed). Output: one line per (case, method) and a JSON file
``benchmarks/redesign_ab-<tag>.json`` that ``--compare old new`` turns into a ratio table.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16}
START = (0.88544, -0.8039, 0.0, 0.0)


def cases():
    p0 = ModelParams(**FIG3, K=17.6, mu=0.0)
    p3 = ModelParams(**FIG3, K=17.6, mu=0.03)
    stiff = ModelParams(**FIG3, K=1.76e4, mu=0.03)
    whip = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)
    r = model.rolling_whirl_radius(whip)
    return {
        "fig3 mu=0, 100 periods": Problem.from_periods(p0, START, 100, 20),
        "fig3 mu=0.03, 100 periods": Problem.from_periods(p3, START, 100, 20),
        "stick-slip K=100, 20 periods": Problem.from_periods(
            whip, (r, 0.0, 0.0, -whip.Rp * whip.eta), 20, 20
        ),
        "impacts K=1.76e4 mu=0.03, 2 periods": Problem.from_periods(stiff, START, 2, 50),
    }


RUNS = {
    "dop853-jit": ("dop853-jit", {"rtol": 1e-8, "atol": 1e-10}),
    "analytic-polar": ("analytic-polar", {"steps_per_period": 400}),
    "analytic tol": ("analytic", {"analytic_tol": 1e-6}),
    "dop853": ("dop853", {"rtol": 1e-8, "atol": 1e-10}),
    "radau": ("radau", {"rtol": 1e-6, "atol": 1e-8}),
}
SLOW = {"dop853", "radau"}  # scipy: only the short cases


def measure(repeats: int) -> dict:
    out = {}
    for case, problem in cases().items():
        for label, (method, options) in RUNS.items():
            if label in SLOW and problem.periods > 20:
                continue
            solve(problem, method, **options)  # warm-up
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                sol = solve(problem, method, **options)
                times.append(time.perf_counter() - start)
            key = f"{case} | {label}"
            out[key] = {"median": statistics.median(times), "min": min(times),
                        "events": len(sol.events), "status": sol.status}  # fmt: skip
            print(f"{key:60} {out[key]['median']:9.4f} s  (min {min(times):.4f})", flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tag", default="new")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--compare", nargs=2, metavar=("A", "B"))
    args = parser.parse_args()
    here = Path(__file__).parent
    if args.compare:
        a, b = (json.loads((here / f"redesign_ab-{t}.json").read_text()) for t in args.compare)
        print(f"| case and method | {args.compare[0]} (s) | {args.compare[1]} (s) | ratio |")
        print("|---|---|---|---|")
        for key in a:
            if key in b:
                ra, rb = a[key]["min"], b[key]["min"]
                print(f"| {key} | {ra:.4f} | {rb:.4f} | {rb / ra:.3f} |")
        return
    result = measure(args.repeats)
    (here / f"redesign_ab-{args.tag}.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()

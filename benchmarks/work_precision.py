"""Work-precision benchmark: every method on K = 17.6, 17.6e3, 1.75e6 and mu = 0, 0.03,
and on persistent stiff contact (a perturbed synchronous rub at K = 17.6e3 and 1.75e6).

Run from the repository root:

    python benchmarks/work_precision.py            # full (tens of minutes)
    python benchmarks/work_precision.py --quick    # short horizons and ladders
    python benchmarks/work_precision.py --K 1.75e6 --start near-rub --tag stiff  # a subset

For each case it builds the reference (``rubcli.analysis.accuracy.reference``: exact where the
case has one, otherwise DOP853 at 1e-12 checked against LSODA at 1e-12, errors only over
the span where the reference is trusted), runs each method over its ladder of settings
(``rubcli.analysis.accuracy.work_precision``: median of repeats for short runs, one-off start-up
such as numba compilation measured apart), and reports for each target error the
cheapest setting of each method. Speed-ups are ratios of times measured in this one run
on this machine, never absolute limits. It also measures the throughput (forcing periods
per second) of the cheapest rubcli setting that reaches 1e-6, and the peak memory of a
10,000-period run at 100 samples per period (in a child process).

The tables are printed and written to ``benchmarks/work_precision[-quick][-TAG].md``
(and ``.csv``; ``--tag`` names a subset run, so runs of different subsets do not
overwrite each other); copy the summary into RESULTS.md with the command.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path

from machine import describe

from rubcli.analysis.accuracy import work_precision as wpm
from rubcli.analysis.accuracy.reference import reference_solution
from rubcli.model import ModelParams, synchronous_rub, synchronous_rub_radii
from rubcli.problem import Problem

HERE = Path(__file__).resolve().parent
FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16, "phi0": 0.0}
START = (0.88544, -0.8039, 0.0, 0.0)  # Figure 3 caption
RUBCLI = ("analytic", "analytic-polar", "dop853-jit", "taylor")
SCIPY = ("rk45", "dop853", "radau", "bdf", "lsoda")
TARGET = 1e-6

TARGETS = (1e-3, 1e-6)

# Horizons: the stiff cases are short because the explicit scipy methods need steps of
# order 1/sqrt(K) (every method still gets the same problem).
FULL = {17.6: 100, 17.6e3: 10, 1.75e6: 2}
QUICK = {17.6: 10, 17.6e3: 2, 1.75e6: 0.5}
# Persistent stiff contact: the synchronous full annular rub (mu = 0) with its radius
# raised by half its penetration, so that the fast contact mode (frequency ~ sqrt(K)) is
# excited and rings (it decays only at the rate nu); no impacts, no events.
NEAR_RUB_PERIODS = {17.6e3: 10, 1.75e6: 10}
NEAR_RUB_QUICK = {17.6e3: 2, 1.75e6: 1}


def near_rub_start(params: ModelParams) -> tuple[float, ...]:
    r = synchronous_rub_radii(params)[-1]
    s0 = synchronous_rub(0.0, params, r)
    s0[:2] *= 1.0 + 0.5 * (r - 1.0)
    return tuple(float(v) for v in s0)


def run_case(
    K: float, mu: float, periods: float, quick: bool, budget: float, methods=None, start="fig3"
):
    params = ModelParams(K=K, mu=mu, **FIG3)
    initial = START if start == "fig3" else near_rub_start(params)
    name = f"K={K:g} mu={mu:g} {start} start"
    problem = Problem.from_periods(params, initial, periods, 50, name=name)
    t0 = time.perf_counter()
    reference = reference_solution(problem)
    ref_time = time.perf_counter() - t0
    rtols = wpm.QUICK_RTOLS if quick else wpm.DEFAULT_RTOLS
    steps = (100, 400, 1600) if quick else wpm.DEFAULT_STEPS_PER_PERIOD
    settings = wpm.ladder(methods or RUBCLI + SCIPY, rtols=rtols, steps_per_period=steps)
    print(
        f"   reference {reference.kind}: error {reference.error_estimate:.2g}, trusted until "
        f"tau = {reference.trusted_until:.6g} of {problem.t_span[1]:.6g} ({ref_time:.0f} s)",
        flush=True,
    )
    wp = wpm.run_work_precision(
        problem, reference, settings, repeats=1 if quick else 3, max_wall_time_s=budget
    )
    return problem, reference, ref_time, wp


def memory_probe(periods: int) -> dict:
    """Peak resident memory of a child process running one long analytic-polar solve."""
    code = f"""
import resource, json, time
from rubcli.model import ModelParams, synchronous_rub, synchronous_rub_radii
from rubcli.problem import Problem
from rubcli.solvers import solve
p = ModelParams(K=17.6, mu=0.0, **{FIG3!r})
prob = Problem.from_periods(p, {START!r}, {periods}, 100)
t = time.perf_counter()
sol = solve(prob, "analytic-polar")
print(json.dumps({{"status": sol.status, "wall_time_s": time.perf_counter() - t,
    "samples": int(sol.t.size),
    "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}}))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if out.returncode != 0:
        return {"status": "error", "message": out.stderr[-500:]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def case_list(args) -> list[tuple[float, float, float, str]]:
    """(K, mu, periods, start) of every case the arguments select."""
    horizons = QUICK if args.quick else FULL
    near = NEAR_RUB_QUICK if args.quick else NEAR_RUB_PERIODS
    cases = [(K, mu, n, "fig3") for K, n in horizons.items() for mu in (0.0, 0.03)]
    cases += [(K, 0.0, n, "near-rub") for K, n in near.items()]
    if args.K:
        cases = [c for c in cases if any(abs(c[0] / k - 1) < 1e-9 for k in args.K)]
    if args.start:
        cases = [c for c in cases if c[3] in args.start]
    return cases


def _cell(row) -> str:
    return "none" if row is None else f"{row.method} {row.setting_name}={row.label}"


def _secs(row) -> str:
    return "-" if row is None else f"{row.wall_time_s:.3g}"


def _ratio(ours, theirs) -> str:
    if ours is None or theirs is None:
        return "-"
    return f"**{theirs.wall_time_s / ours.wall_time_s:.3g}x**"


def summary_rows(K, mu, periods, start, ref, wp, methods) -> list[str]:
    """One summary line per target: the cheapest rubcli and scipy settings reaching it."""
    rows = []
    for target in TARGETS:
        if target < wpm.RESOLUTION_FACTOR * ref.error_estimate:
            rows.append(
                f"| {K:g} | {mu:g} | {start} | {periods} | {target:g} | not resolvable: the "
                f"reference's own error is {ref.error_estimate:.2g} | | | | | | |"
            )
            continue
        best = {m: wpm.cheapest_for(wp.rows_of(m), target, ref) for m in methods}
        ours = [best[m] for m in RUBCLI if best.get(m) is not None]
        theirs = [best[m] for m in SCIPY if best.get(m) is not None]
        b_ours = min(ours, key=lambda r: r.wall_time_s) if ours else None
        b_theirs = min(theirs, key=lambda r: r.wall_time_s) if theirs else None
        rk45 = best.get("rk45")
        rows.append(
            f"| {K:g} | {mu:g} | {start} | {periods} | {target:g} | {_cell(b_ours)} | "
            f"{_secs(b_ours)} | {_cell(b_theirs)} | {_secs(b_theirs)} | {_secs(rk45)} | "
            f"{_ratio(b_ours, b_theirs)} | {_ratio(b_ours, rk45)} |"
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--budget", type=float, default=120.0, help="max seconds per solve")
    parser.add_argument("--no-memory", action="store_true")
    parser.add_argument("--K", type=float, nargs="+", help="only these stiffness ratios")
    parser.add_argument("--start", nargs="+", choices=("fig3", "near-rub"), help="only these")
    parser.add_argument("--methods", nargs="+", help="only these methods (default: all)")
    parser.add_argument("--tag", default="", help="suffix of the output files")
    args = parser.parse_args()
    methods = tuple(args.methods or RUBCLI + SCIPY)

    lines = [
        "# Work-precision benchmark",
        "",
        f"Command: `python benchmarks/{' '.join([Path(sys.argv[0]).name, *sys.argv[1:]])}`  ",
        f"Date and machine: {describe()}",
        "",
        "Starts: `fig3` is the Figure 3 caption state; `near-rub` the synchronous rub "
        "(mu = 0) with its radius raised by half its penetration. nu, eta, e, Rp of Figure 3. "
        "Error: max over the samples of |w - w_ref| (clearances) within the reference's "
        "trusted span. Times: median of 3 repeats for runs under 5 s; start-up (first call, "
        "numba cache load) measured apart.",
        "",
    ]
    summary = [
        "| K | mu | start | periods | target | cheapest rubcli | s | cheapest scipy | s "
        "| rk45 s | speed-up vs best scipy | vs rk45 |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    csv_rows = []
    throughput = []
    for K, mu, periods, start in case_list(args):
        print(f"== K = {K:g}, mu = {mu:g}, {start} start, {periods} periods", flush=True)
        problem, ref, ref_time, wp = run_case(
            K, mu, periods, args.quick, args.budget, list(methods), start
        )
        lines += [
            f"## K = {K:g}, mu = {mu:g}, {start} start, {periods} forcing periods",
            "",
            f"Reference: {ref.kind} ({ref.description}); estimated error "
            f"{ref.error_estimate:.2g}; trusted until tau = {ref.trusted_until:.6g} of "
            f"{problem.t_span[1]:.6g}; built in {ref_time:.1f} s. Start-up per method (s): "
            + ", ".join(f"{m} {t:.3g}" for m, t in wp.startup_s.items()),
            "",
            "| method | setting | wall s | error max | error final | steps | events | status |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for row in wp.rows:
            lines.append(
                f"| {row.method} | {row.setting_name} = {row.label} | "
                f"{row.wall_time_s:.4g} | {row.error_max:.3g} | {row.error_final:.3g} | "
                f"{row.nsteps} | {row.n_events} | {row.status} |"
            )
            csv_rows.append({"K": K, "mu": mu, "start": start, "periods": periods, **row.record()})
        if wp.skipped:
            lines += ["", "Skipped after a budget stop: " + "; ".join(wp.skipped)]
        lines.append("")
        new_rows = summary_rows(K, mu, periods, start, ref, wp, methods)
        summary += new_rows
        print("\n".join(new_rows), flush=True)
        best = wpm.cheapest_for([r for m in RUBCLI for r in wp.rows_of(m)], TARGET, ref)
        if best is not None:
            span = (ref.trusted_until - problem.t_span[0]) / problem.params.period
            throughput.append((K, mu, start, best, span / best.wall_time_s))
        (HERE / "work_precision-partial.md").write_text("\n".join(lines + summary))
    (HERE / "work_precision-partial.md").unlink(missing_ok=True)

    lines += ["## Summary: cheapest setting per target error", "", *summary, ""]
    if throughput:
        lines += [
            f"## Throughput at error {TARGET:g}",
            "",
            "| K | mu | start | cheapest rubcli setting | forcing periods per second |",
            "|---|---|---|---|---|",
        ]
        lines += [
            f"| {K:g} | {mu:g} | {start} | {_cell(row)} | {rate:.4g} |"
            for K, mu, start, row, rate in throughput
        ]
        lines.append("")
    if not args.no_memory:
        mem = memory_probe(1000 if args.quick else 10_000)
        lines += [
            f"Memory: one analytic-polar run of {1000 if args.quick else 10_000} periods at "
            f"100 samples per period: {json.dumps(mem)}",
            "",
        ]
    text = "\n".join(lines)
    print(text)
    suffix = ("-quick" if args.quick else "") + (f"-{args.tag}" if args.tag else "")
    (HERE / f"work_precision{suffix}.md").write_text(text)
    with open(HERE / f"work_precision{suffix}.csv", "w", newline="") as fh:
        if csv_rows:
            writer = csv.DictWriter(fh, fieldnames=list(csv_rows[0]))
            writer.writeheader()
            for r in csv_rows:
                writer.writerow(
                    {k: (json.dumps(v) if isinstance(v, dict) else v) for k, v in r.items()}
                )


if __name__ == "__main__":
    main()

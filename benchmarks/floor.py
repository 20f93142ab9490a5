"""The cost floor: a bare compiled fixed-step RK4, and every method's cost per step beside it.

Run from the repository root:

    python benchmarks/floor.py              # 20 forcing periods per method (~1 min + compile)
    python benchmarks/floor.py --periods 5  # quicker

Case: the paper's Figure 3 (nu = 0.009478, eta = 0.7818, e = 7.52, K = 17.6, Rp = 46.16,
mu = 0.02, start x = 0.88544, y = -0.8039 at rest): mostly in contact (slip+), with
contact exits and re-entries (about 4 events per forcing period after the tenth).

- **Floor**: classical RK4 at 400 steps per forcing period on ``model.rhs_entries``
  compiled with numba, the regime chosen from z (and the sign of v_r) at every stage, no
  event handling and no output: the least any explicit step on this right-hand side
  costs. Reported in ns per step and forcing periods per second.
- **Contact steps alone**: the analytic methods on the exact synchronous full annular
  rub of the same parameters (notes section 5; K = 17.6, and 1.75e6 for analytic-polar),
  where no event ever occurs, so every step is a contact step: the compiled kernel's
  cost per step against the Python propagator's.
- **Methods**: ``analytic`` and ``analytic-polar`` at 400 steps per period, compiled and
  pure Python; the scipy methods at their default tolerances (rtol = 1e-8,
  atol = 1e-10), compiled and Python right-hand sides; ``dop853-jit`` at the same
  tolerances (its pure-Python path is scipy's ``dop853``). Cost per step (wall time / steps;
  a scipy step is an accepted step of several right-hand-side calls) and per forcing
  period, each as a multiple of the floor's, with the maximum position error against a
  DOP853 reference at rtol = atol = 1e-13 over the same span. Timings are the best of
  up to 3 repeats after one warm-up run (the warm-up pays numba's compilation or cache
  load).
- **Compile time**, measured apart in child processes: the first ``solve`` of each
  compiled path with an empty numba cache (compilation), then again in a new process
  with the cache filled (load from disk, paid once per process), and a later call in
  the same process.

Prints the tables and writes them to ``benchmarks/floor.md`` with the command, the
machine and its load. Ratios are measured in one run on one machine.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np
from machine import cpu_model

import rubcli.solvers.compiled  # noqa: F401  (registers the model cores with numba)
from rubcli import model
from rubcli.model import ModelParams, rhs_entries
from rubcli.problem import Problem
from rubcli.solvers import solve

HERE = Path(__file__).resolve().parent
FIG3 = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, Rp=46.16, mu=0.02)
START = (0.88544, -0.8039, 0.0, 0.0)
STEPS_PER_PERIOD = 400
SAMPLES_PER_PERIOD = 100
SCIPY = ("rk45", "dop853", "radau", "bdf", "lsoda")


@numba.njit(cache=True)
def _rhs_by_position(t, s, pars):
    """model.rhs with the regime taken from the state: free inside, slip by sign(v_r)."""
    x, y, vx, vy = s[0], s[1], s[2], s[3]
    regime = 0
    if x * x + y * y > 1.0:
        regime = 1
        if pars[5] > 0.0 and pars[6] * pars[1] + (x * vy - y * vx) / math.hypot(x, y) < 0.0:
            regime = -1
    return rhs_entries(
        t, x, y, vx, vy, pars[0], pars[1], pars[2], pars[3], pars[4], pars[5], pars[6], regime
    )


@numba.njit(cache=True)
def rk4_floor(tau0, state, h, n_steps, pars):
    """n_steps classical RK4 steps from (tau0, state); returns the final state."""
    s = state.copy()
    k1 = np.empty(4)
    k2 = np.empty(4)
    k3 = np.empty(4)
    k4 = np.empty(4)
    tmp = np.empty(4)
    t = tau0
    for _ in range(n_steps):
        d = _rhs_by_position(t, s, pars)
        for i in range(4):
            k1[i] = d[i]
            tmp[i] = s[i] + 0.5 * h * k1[i]
        d = _rhs_by_position(t + 0.5 * h, tmp, pars)
        for i in range(4):
            k2[i] = d[i]
            tmp[i] = s[i] + 0.5 * h * k2[i]
        d = _rhs_by_position(t + 0.5 * h, tmp, pars)
        for i in range(4):
            k3[i] = d[i]
            tmp[i] = s[i] + h * k3[i]
        d = _rhs_by_position(t + h, tmp, pars)
        for i in range(4):
            k4[i] = d[i]
            s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        t += h
    return s


def best_time(fn, repeats: int = 3, budget_s: float = 20.0) -> tuple[float, object]:
    """Best wall time of up to ``repeats`` calls after one warm-up (fewer if slow)."""
    start = time.perf_counter()
    result = fn()  # warm-up: compilation or cache load, and a first timing
    best = time.perf_counter() - start
    spent = best
    for _ in range(repeats - 1):
        if spent + best > budget_s:
            break
        start = time.perf_counter()
        result = fn()
        elapsed = time.perf_counter() - start
        spent += elapsed
        best = min(best, elapsed)
    return best, result


def measure_floor(periods: float) -> dict:
    pars = np.array(model.params_vector(FIG3))
    h = FIG3.period / STEPS_PER_PERIOD
    n_steps = int(round(periods * STEPS_PER_PERIOD))
    state = np.array(START)
    rk4_floor(0.0, state, h, 10, pars)  # compile or load
    seconds, final = best_time(lambda: rk4_floor(0.0, state, h, n_steps, pars), repeats=5)
    ns_per_step = seconds / n_steps * 1e9
    return {
        "steps": n_steps,
        "seconds": seconds,
        "ns_per_step": ns_per_step,
        "periods_per_s": 1e9 / (ns_per_step * STEPS_PER_PERIOD),
        "final": [float(v) for v in final],
    }


def measure_contact_steps(periods: float) -> list[dict]:
    """Cost per step on the exact synchronous rub: contact steps only, no events."""
    rows = []
    for K in (17.6, 1.75e6):
        p = ModelParams(**{**FIG3.as_dict(), "K": K})
        r = model.synchronous_rub_radii(p)[-1]
        prob = Problem.from_periods(p, tuple(model.synchronous_rub(0.0, p, r)), periods, 100)
        # the Cartesian linearisation leaves the exact orbit at K = 1.75e6 at this step
        # (its error grows with K, docs), so it would no longer be contact-only there
        for method in ("analytic", "analytic-polar") if K < 1e3 else ("analytic-polar",):
            row = {"K": K, "method": method}
            for compiled in (True, False):
                seconds, sol = best_time(
                    lambda m=method, c=compiled, q=prob: solve(
                        q, m, steps_per_period=STEPS_PER_PERIOD, compiled=c
                    )
                )
                assert not sol.events
                row["compiled" if compiled else "python"] = seconds / sol.stats["nsteps"] * 1e6
            rows.append(row)
            print(
                f"  K = {K:g} {method:15s} compiled {row['compiled']:8.2f} us/step, "
                f"python {row['python']:8.2f} us/step"
            )
    return rows


def measure_methods(periods: float, floor_ns: float) -> list[dict]:
    prob = Problem.from_periods(FIG3, START, periods, SAMPLES_PER_PERIOD, name="fig3")
    reference = solve(prob, "dop853", rtol=1e-13, atol=1e-13)
    runs = [(m, {"steps_per_period": STEPS_PER_PERIOD}) for m in ("analytic", "analytic-polar")]
    runs += [(m, {}) for m in (*SCIPY, "dop853-jit")]
    rows = []
    for method, options in runs:
        for compiled in (True, False):
            seconds, sol = best_time(
                lambda m=method, o=options, c=compiled: solve(prob, m, **o, compiled=c)
            )
            steps = sol.stats["nsteps"]
            per_step_ns = seconds / steps * 1e9
            per_period_s = seconds / periods
            n = min(sol.t.size, reference.t.size)
            rows.append(
                {
                    "method": method,
                    "compiled": compiled,
                    "settings": ", ".join(f"{k}={v}" for k, v in options.items())
                    or "rtol=1e-8, atol=1e-10",
                    "status": sol.status,
                    "events": len(sol.events),
                    "steps": steps,
                    "compiled_steps": sol.stats.get("n_compiled_steps"),
                    "seconds": seconds,
                    "us_per_step": per_step_ns / 1e3,
                    "x_floor_step": per_step_ns / floor_ns,
                    "ms_per_period": per_period_s * 1e3,
                    "x_floor_period": per_period_s / (floor_ns * 1e-9 * STEPS_PER_PERIOD),
                    "periods_per_s": 1.0 / per_period_s,
                    "max_error": float(np.max(np.abs(sol.w[:n] - reference.w[:n]))),
                }
            )
            print(
                f"  {method:15s} {'compiled' if compiled else 'python':8s} "
                f"{rows[-1]['us_per_step']:10.2f} us/step  x{rows[-1]['x_floor_step']:9.1f}"
            )
    return rows


CHILD = r"""
import json, sys, time
start = time.perf_counter()
from rubcli.problem import Problem
from rubcli.solvers import solve
sys.path.insert(0, {here!r})
import floor
imported = time.perf_counter() - start
prob = Problem.from_periods(floor.FIG3, floor.START, 2, 20)
out = {{"import_s": imported}}
paths = (("analytic-polar", "analytic-polar"), ("analytic", "analytic"),
         ("scipy rhs (rk45)", "rk45"), ("dop853-jit", "dop853-jit"))
for name, method in paths:
    times = []
    for _ in range(2):
        t = time.perf_counter()
        solve(prob, method)
        times.append(time.perf_counter() - t)
    python = time.perf_counter()
    solve(prob, method, compiled=False)
    out[name] = {{"first": times[0], "later": times[1], "python": time.perf_counter() - python}}
import numpy as np
pars = np.array(floor.model.params_vector(floor.FIG3))
t = time.perf_counter()
floor.rk4_floor(0.0, np.array(floor.START), 0.01, 800, pars)
first = time.perf_counter() - t
t = time.perf_counter()
floor.rk4_floor(0.0, np.array(floor.START), 0.01, 800, pars)
out["floor RK4"] = {{"first": first, "later": time.perf_counter() - t, "python": None}}
print(json.dumps(out))
"""


def measure_compile_time() -> dict:
    """First calls with an empty numba cache, then with the filled cache, in children."""
    code = CHILD.format(here=str(HERE))
    results = {}
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        for label in ("empty cache", "filled cache"):
            done = subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
            )
            results[label] = json.loads(done.stdout.strip().splitlines()[-1])
    return results


def render(args, floor: dict, contact: list[dict], rows: list[dict], compile_times: dict) -> str:
    lines = [
        "# Cost floor: bare compiled RK4 beside every method",
        "",
        f"Command: `{' '.join(['python benchmarks/floor.py', *args])}`",
        "",
        f"Machine: `nproc` = {len(os.sched_getaffinity(0))}, {cpu_model()}; "
        f"Python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}.",
        f"Load average at the end of the run: "
        f"{LOAD[0]} (other work on the machine inflates every timing alike).",
        "",
        "Case: the paper's Figure 3 (nu = 0.009478, eta = 0.7818, e = 7.52, K = 17.6, "
        "Rp = 46.16, mu = 0.02, x0 = 0.88544, y0 = -0.8039, at rest): mostly in contact "
        "(slip+), with contact exits and re-entries. Ratios are from this one run on this "
        "machine.",
        "",
        "## Floor",
        "",
        "Classical RK4, 400 steps per forcing period, on `model.rhs_entries` compiled with "
        "numba, regime from z and sign(v_r) at every stage, no events, no output "
        f"({floor['steps']} steps, best of 5).",
        "",
        "| ns per step | forcing periods per second (400 steps/period) |",
        "|---:|---:|",
        f"| {floor['ns_per_step']:.0f} | {floor['periods_per_s']:,.0f} |",
        "",
        "## Contact steps alone",
        "",
        "The analytic methods on the exact synchronous full annular rub of the same "
        "parameters (no event ever occurs: every step is a contact step), "
        f"{STEPS_PER_PERIOD} steps per period, {CONTACT_PERIODS[0]:g} periods; at "
        "K = 1.75e6 the event scan needs ~70 grid points per step (1/16 of the period "
        "sqrt(K) sets), in both paths. (`analytic`, the Cartesian linearisation, leaves "
        "the exact orbit at K = 1.75e6 at this step, so it is not timed there.)",
        "",
        "| K | method | compiled us/step | x floor | python us/step | x floor | speed-up |",
        "|---:|---|---:|---:|---:|---:|---:|",
        *[
            f"| {c['K']:g} | {c['method']} | {c['compiled']:.2f} "
            f"| {c['compiled'] * 1e3 / floor['ns_per_step']:,.0f} | {c['python']:.1f} "
            f"| {c['python'] * 1e3 / floor['ns_per_step']:,.0f} "
            f"| {c['python'] / c['compiled']:.0f} |"
            for c in contact
        ],
        "",
        "## Methods on the case",
        "",
        f"Horizon {PERIODS[0]:g} forcing periods, "
        f"{SAMPLES_PER_PERIOD} samples per period. Analytic methods at "
        f"{STEPS_PER_PERIOD} steps per period; scipy methods at their defaults. Cost per "
        "step = wall time / steps (a scipy or dop853-jit step is one accepted step of 12 "
        "stages plus 3 for the dense output; an RK4 floor step is 4 stages); x floor = that "
        "cost over the floor's per step or per forcing period. Error: max |w - w_ref| "
        "against DOP853 at rtol = atol = 1e-13. Best of up to 3 runs after a warm-up.",
        "",
        "| method | path | settings | events | steps | compiled steps | us/step "
        "| x floor (step) | ms/period | x floor (period) | periods/s | max error |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        path = "compiled" if r["compiled"] else "python"
        if r["method"] in SCIPY:
            path += " rhs"
        elif r["method"] == "dop853-jit" and not r["compiled"]:
            path = "python (= scipy dop853)"
        compiled_steps = "" if r["compiled_steps"] is None else str(r["compiled_steps"])
        lines.append(
            f"| {r['method']} | {path} | {r['settings']} | {r['events']} | {r['steps']} "
            f"| {compiled_steps} "
            f"| {r['us_per_step']:.2f} | {r['x_floor_step']:,.0f} | {r['ms_per_period']:.2f} "
            f"| {r['x_floor_period']:,.0f} | {r['periods_per_s']:,.1f} | {r['max_error']:.1e} |"
        )
    speedups = []
    for method in ("analytic", "analytic-polar", *SCIPY, "dop853-jit"):
        by_path = {r["compiled"]: r for r in rows if r["method"] == method}
        speedups.append(
            f"| {method} | {by_path[False]['us_per_step']:.2f} | "
            f"{by_path[True]['us_per_step']:.2f} | "
            f"{by_path[False]['us_per_step'] / by_path[True]['us_per_step']:.1f} |"
        )
    lines += [
        "",
        "Along this orbit the analytic methods' error at 400 steps per period grows with "
        "the horizon (the response is quasi-periodic and sensitive); costs at equal error "
        "are the work-precision benchmark's subject. The compiled analytic paths take "
        "every step in the compiled loop, the events and free flights included: "
        "`compiled steps` counts their slip and stick steps, the other `steps` are their "
        "free flights (one step each).",
        "",
        "Compiled against Python, per step:",
        "",
        "| method | python us/step | compiled us/step | speed-up |",
        "|---|---:|---:|---:|",
        *speedups,
        "",
        "## Compile time (apart from the runs above)",
        "",
        "First `solve` of each path in a new process (2 periods of the case; 800 steps for "
        "the floor), with an empty "
        "numba cache (compilation) and again in a new process with the cache filled "
        "(loading the machine code from disk, once per process), and a later call in the "
        "same process; the pure-Python path of the same call for comparison. With "
        "`cache=True` the compiled code is kept in `__pycache__` next to the sources (or "
        "`NUMBA_CACHE_DIR`), so compilation is paid once per machine and installation.",
        "",
        "| path | empty cache: first call (s) | filled cache: first call (s) "
        "| later call (s) | pure Python (s) |",
        "|---|---:|---:|---:|---:|",
    ]
    cold, warm = compile_times["empty cache"], compile_times["filled cache"]
    if not cold:
        lines += ["(not measured: --no-compile-time)", ""]
        return "\n".join(lines)
    for name in ("analytic-polar", "analytic", "scipy rhs (rk45)", "dop853-jit", "floor RK4"):
        python = warm[name]["python"]
        lines.append(
            f"| {name} | {cold[name]['first']:.3f} | {warm[name]['first']:.3f} "
            f"| {warm[name]['later']:.4f} | {'' if python is None else f'{python:.3f}'} |"
        )
    lines += [
        "",
        f"Importing rubcli.solvers (numba included): {warm['import_s']:.2f} s. The first "
        "compiled call in a process also runs the cache-freshness probe "
        "(`compiled.ensure_fresh`). The analytic paths share most kernels, so the second "
        "one compiles faster after the first.",
        "",
    ]
    return "\n".join(lines)


PERIODS = [20.0]
LOAD = ["unknown"]
CONTACT_PERIODS = [5.0]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--periods", type=float, default=20.0, help="horizon of the method runs")
    parser.add_argument("--floor-periods", type=float, default=500.0, help="horizon of the floor")
    parser.add_argument(
        "--contact-periods", type=float, default=5.0, help="horizon of the contact-only runs"
    )
    parser.add_argument("--no-compile-time", action="store_true", help="skip the child runs")
    args = parser.parse_args(argv)
    PERIODS[0] = args.periods
    CONTACT_PERIODS[0] = args.contact_periods
    print("floor (compiled RK4) ...")
    floor = measure_floor(args.floor_periods)
    print(f"  {floor['ns_per_step']:.0f} ns/step, {floor['periods_per_s']:,.0f} periods/s")
    print("contact steps alone ...")
    contact = measure_contact_steps(args.contact_periods)
    print("methods ...")
    rows = measure_methods(args.periods, floor["ns_per_step"])
    compile_times = {"empty cache": {}, "filled cache": {}}
    if not args.no_compile_time:
        print("compile time (child processes) ...")
        compile_times = measure_compile_time()
    LOAD[0] = " / ".join(f"{v:.2f}" for v in os.getloadavg()) + " (1 / 5 / 15 min)"
    text = render(sys.argv[1:] if argv is None else argv, floor, contact, rows, compile_times)
    (HERE / "floor.md").write_text(text)
    print()
    print(text)


if __name__ == "__main__":
    main()

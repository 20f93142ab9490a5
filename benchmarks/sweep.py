"""The sweep engine's cost: a 400-point speed sweep, 300 forcing periods per point.

Run from the repository root:

    python benchmarks/sweep.py                 # 400 points (a few minutes on 2 cores)
    python benchmarks/sweep.py --points 100    # quicker

Case: the run-up machine of ``cases/examples/run-up.toml`` (nu = 0.05, e = 0.3, K = 10,
mu = 0.02, Rp = 5, start at rest) over eta = 0.5 ... 4.0, ``direction = "independent"``
(every point its own chain), 200 transient + 100 recorded periods per point, 32 samples
per period, ``dop853-jit`` at rtol 1e-8, atol 1e-10, no energy balance (its cost is
measured apart, on a subset). Measured, all in this one process and run:

- 1 worker (in-process), 2 local worker processes and a 2-worker Dask LocalCluster
  (processes, loopback; its start-up is reported apart): total wall time, forcing
  periods per second, parallel efficiency (wall at 1 worker / wall at N);
- the engine's per-point overhead at 1 worker: (wall time - the points' own compute
  time) / points, as a fraction of the mean compute time of a point. The compute time of
  a point is timed inside ``compute_point`` (solve + analysis); everything else
  (scheduling, the store's file per point, building the Dataset) is the engine's;
- the energy balance's cost per point (on ``--subset`` points);
- the plain scipy loop a user would write instead: ``solve_ivp`` (RK45, the same
  tolerances) restarted at every contact and slip event, sampled once per period, one
  point after another, timed on ``--subset`` points and extrapolated to all.

Prints a table and writes it to ``benchmarks/sweep.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from rubcli import model
from rubcli.analysis.sweep import Axis, SweepPlan, execute
from rubcli.analysis.sweep.dataset import build_dataset
from rubcli.model import ModelParams

HERE = Path(__file__).resolve().parent
PARAMS = ModelParams(nu=0.05, eta=1.0, e=0.3, K=10.0, mu=0.02, Rp=5.0, phi0=0.0)
OPTIONS = {"rtol": 1e-8, "atol": 1e-10}
SPP = 32
TRANSIENT, RECORD = 200, 100  # per point; --transient and --record change them


def set_periods(transient: int, record: int) -> None:
    global TRANSIENT, RECORD
    TRANSIENT, RECORD = transient, record


def plan_for(n: int, energy: bool = False) -> SweepPlan:
    return SweepPlan(
        PARAMS, (0.0, 0.0, 0.0, 0.0), (Axis("eta", tuple(np.linspace(0.5, 4.0, n))),),
        direction="independent", transient_periods=TRANSIENT, record_periods=RECORD,
        samples_per_period=SPP, options=OPTIONS, energy=energy, name="bench",
    )  # fmt: skip


def _cpu() -> float:
    """CPU time of this process and of its finished children (pool workers)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


BUILD_SECONDS = []  # the one-off Dataset build of each timed sweep


def timed(plan: SweepPlan, **kwargs):
    """(wall, results, cpu): cpu counts this process and its (joined) worker processes."""
    with tempfile.TemporaryDirectory() as tmp:
        cpu0 = _cpu()
        start = time.perf_counter()
        results, stats, where = execute(plan, store_dir=Path(tmp) / "store", **kwargs)
        built = time.perf_counter()
        build_dataset(plan, results)
        wall = time.perf_counter() - start
        BUILD_SECONDS.append(time.perf_counter() - built)
        cpu = _cpu() - cpu0
    return wall, results, cpu


def scipy_point(params: ModelParams, periods: int) -> np.ndarray:
    """The user's loop body: solve_ivp restarted at each contact/slip event."""
    period = params.period
    t_end = periods * period
    t, s = 0.0, np.zeros(4)
    samples = [s]
    next_sample = period
    while t < t_end - 1e-12 * period:
        regime = model.regime_of_state(s, params, t)

        def contact(tau, y):
            return y[0] ** 2 + y[1] ** 2 - 1.0

        def slip(tau, y, regime=regime):
            if regime == model.FREE:
                return 1.0
            return model.slip_velocity(y[0], y[1], y[2], y[3], params.Rp, params.eta)

        contact.terminal = slip.terminal = True
        grid = np.arange(next_sample, t_end + 0.5 * period, period)
        grid = np.minimum(grid[grid <= t_end + 1e-9 * period], t_end)
        grid = grid[grid >= t]
        sol = solve_ivp(
            lambda tau, y, regime=regime: model.rhs(tau, y, params, regime),
            (t, t_end), s, method="RK45", t_eval=grid, events=(contact, slip), **OPTIONS,
        )  # fmt: skip
        if np.size(sol.t):
            samples.extend(np.asarray(sol.y).T)
            next_sample = float(sol.t[-1]) + period
        if sol.status != 1:
            break
        hits = [
            (float(e[0]), y[0]) for e, y in zip(sol.t_events, sol.y_events, strict=True) if e.size
        ]
        t, state = min(hits, key=lambda h: h[0])
        # step off the switching surface into the new regime
        s = np.asarray(state, dtype=float)
        s = s + 1e-12 * model.rhs(t, s, params, model.regime_of_state(s, params, t))
    return np.asarray(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, default=400)
    parser.add_argument("--subset", type=int, default=8, help="points for energy and scipy")
    parser.add_argument("--transient", type=int, default=TRANSIENT)
    parser.add_argument("--record", type=int, default=RECORD)
    args = parser.parse_args()
    set_periods(args.transient, args.record)
    n, sub = args.points, args.subset
    load_before = os.getloadavg()[0]
    periods = n * (TRANSIENT + RECORD)
    plan = plan_for(n)
    import xarray  # noqa: F401  (its import, ~1 s once per process, is not the engine's)

    execute(plan_for(2), workers=1)  # numba kernels compiled or loaded

    rows = []
    wall1, res1, cpu1 = timed(plan, workers=1)
    compute = sum(r.wall_time_s for r in res1.values())
    rows.append(("1 worker (in-process)", wall1, wall1, 1))
    wall2, res2, cpu2 = timed(plan, workers=2)
    rows.append(("2 local processes", wall2, wall1, 2))
    compute2 = sum(r.wall_time_s for r in res2.values())

    from distributed import Client, LocalCluster

    start = time.perf_counter()
    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    )  # fmt: skip
    client = Client(cluster, set_as_default=False)
    execute(plan_for(4), client=client)  # the workers load the kernels and import rubcli
    dask_startup = time.perf_counter() - start
    wall3, res3, _ = timed(plan, client=client)
    client.close()
    cluster.close()
    rows.append(("Dask LocalCluster, 2 workers", wall3, wall1, 2))
    same = all(res1[k].final_state == res2[k].final_state == res3[k].final_state for k in res1)

    overhead = (wall1 - compute) / n
    mean_point = compute / n
    picks = plan.axes[0].values[:: max(1, n // sub)][:sub]
    sub_plan = dataclasses.replace(plan_for(n), axes=(Axis("eta", picks),))
    e_wall, e_res, _ = timed(dataclasses.replace(sub_plan, energy=True), workers=1)
    ne_wall, ne_res, _ = timed(sub_plan, workers=1)
    energy_per_point = (e_wall - ne_wall) / sub
    start = time.perf_counter()
    for eta in sub_plan.axes[0].values:
        scipy_point(dataclasses.replace(PARAMS, eta=eta), TRANSIENT + RECORD)
    scipy_per_point = (time.perf_counter() - start) / sub
    ne_per_point = ne_wall / sub

    lines = [
        "# Sweep engine benchmark (`benchmarks/sweep.py`)",
        "",
        f"Command: `python benchmarks/sweep.py --points {n} --subset {sub} --transient "
        f"{TRANSIENT} --record {RECORD}`. "
        f"Python {platform.python_version()}, "
        f"{platform.machine()}, 2 cores shared with other work (load average "
        f"{load_before:.1f} before, {os.getloadavg()[0]:.1f} after).",
        "",
        f"{n} points x {TRANSIENT + RECORD} forcing periods = {periods} periods.",
        "",
        "| executor | wall (s) | periods / s | speed-up vs 1 worker | parallel efficiency |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, wall, base, workers in rows:
        speed = base / wall
        lines.append(
            f"| {name} | {wall:.2f} | {periods / wall:,.0f} | {speed:.2f}x | "
            f"{speed / workers:.0%} |"
        )
    lines += [
        "",
        f"- Dask LocalCluster start-up and a 4-point warm-up sweep on it (not in the table): "
        f"{dask_startup:.2f} s.",
        f"- Identical final states on all three executors: {same}.",
        f"- CPU time (this process + its joined workers): 1 worker {cpu1:.2f} s, 2 local "
        f"processes {cpu2:.2f} s: the pool costs {cpu2 / cpu1 - 1:+.1%} CPU, so on an idle "
        f"2-core machine its speed-up would be at most {2 * cpu1 / cpu2:.2f}x. (On a "
        f"machine as loaded as this one the wall-time speed-up measures the load, not "
        f"the engine.)",
        f"- Mean compute of one point (solve + analysis, no energy): {mean_point * 1e3:.1f} ms;"
        f" engine overhead per point at 1 worker: {overhead * 1e3:.2f} ms = "
        f"{overhead / mean_point:.1%} of it; without the one-off build of the Dataset "
        f"({BUILD_SECONDS[0]:.2f} s per sweep) {overhead - BUILD_SECONDS[0] / n:.2e} s = "
        f"{(overhead - BUILD_SECONDS[0] / n) / mean_point:.1%} per point.",
        f"- Engine overhead with 2 local processes, in CPU: (CPU of this process and its "
        f"workers - the points' own compute) / that compute = "
        f"{(cpu2 - compute2) / compute2:.1%} (the Dataset's build "
        f"{BUILD_SECONDS[1] / compute2:.1%} of it).",
        f"- Energy balance of the recorded window: +{energy_per_point * 1e3:.0f} ms per point "
        f"({energy_per_point / ne_per_point:.1f}x a point without it; {sub} points).",
        f"- Plain scipy loop (solve_ivp RK45 with events, one point after another): "
        f"{scipy_per_point:.2f} s per point on {sub} points, extrapolated to {n}: "
        f"{scipy_per_point * n:.0f} s = {scipy_per_point * n / wall1:.0f}x the 1-worker sweep, "
        f"{scipy_per_point * n / wall2:.0f}x the 2-worker sweep.",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    (HERE / "sweep.md").write_text(text)


if __name__ == "__main__":
    main()

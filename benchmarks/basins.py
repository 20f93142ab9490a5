"""Basins at full resolution: early stopping against integrating every start, a million
starts end to end, and Dask per-worker throughput.

Run from the repository root:

    python benchmarks/basins.py              # all parts (about 15 minutes on 2 cores)
    python benchmarks/basins.py --no-hires   # without the million-start run

Machine: ``cases/examples/basins.toml`` (nu = 0.05, eta = 2, e = 0.3, K = 10, mu = 0.02,
Rp = 5; starts at rest on x, y in [-1.5, 1.5]; budget 150 + 16 periods; dop853-jit at
rtol 1e-8, atol 1e-10). Measured in this one run:

- **early stopping**: a 101 x 101 grid with recognition, in this process (periods
  integrated per start, CPU per start), against a sample of its starts integrated for
  the whole budget as every start was before (CPU per start); and the labels of that
  sample against the attractor each one's final state lies on (agreement);
- **a million starts**: ``rubcli sweep cases/examples/basins-hires.toml`` as a user runs
  it (all cores): wall time, CPU time, and the peak resident memory of the whole process
  tree (sampled every 0.2 s from /proc);
- **2 workers**: a 201 x 201 grid on 1 worker, 2 local processes and a 2-worker Dask
  LocalCluster: wall and CPU time, points per second per worker, and the projection
  for 1e8 starts on N such workers.

Writes ``benchmarks/basins.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from rubcli.analysis.sweep import Axis, SweepPlan, execute
from rubcli.analysis.sweep.attractors import Recognition
from rubcli.analysis.sweep.basins import run_basins
from rubcli.analysis.sweep.engine import InProcessExecutor, warm_up
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
MACHINE = ModelParams(nu=0.05, eta=2.0, e=0.3, K=10.0, mu=0.02, Rp=5.0, phi0=0.0)
OPTIONS = {"rtol": 1e-8, "atol": 1e-10}
TRANSIENT, RECORD = 150, 16


def plan_for(n: int) -> SweepPlan:
    values = tuple(np.linspace(-1.5, 1.5, n))
    return SweepPlan(
        MACHINE, (0.0, 0.0, 0.0, 0.0), (Axis("x", values), Axis("y", values)),
        transient_periods=TRANSIENT, record_periods=RECORD, options=OPTIONS,
        recognition=Recognition(),
    )  # fmt: skip


def _cpu() -> float:
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def early_stopping(n: int, sample: int) -> list[str]:
    plan = plan_for(n)
    warm_up(plan.method, plan.options, recognition=True)
    cpu0 = time.process_time()
    result = run_basins(plan, plan.recognition, InProcessExecutor())
    per_start = (time.process_time() - cpu0) / plan.n_points
    budget = TRANSIENT + RECORD
    rng = np.random.default_rng(1)
    picks = rng.choice(plan.n_points, size=sample, replace=False)
    centres = np.array([[a["x_mean"], a["y_mean"]] for a in result.attractors])
    values = np.asarray(plan.axes[0].values)
    agree = 0
    cpu0 = time.process_time()
    for flat in picks:
        i, j = np.unravel_index(flat, plan.shape)
        start = (values[i], values[j], 0.0, 0.0)
        final = solve(Problem.from_periods(MACHINE, start, budget, 1), "dop853-jit",
                      **OPTIONS).states[-1]  # fmt: skip
        gaps = np.hypot(*(final[:2] - centres).T)
        agree += int(gaps.min() < 1e-2 and np.argmin(gaps) == result.label[i, j])
    full = (time.process_time() - cpu0) / sample
    periods = result.periods.mean()
    names = ", ".join(f"{a['kind']} z {a['z_min']:.3f}" for a in result.attractors)
    return [
        f"## Early stopping ({n} x {n} starts, this process)",
        "",
        "| | periods integrated a start | CPU per start (ms) |",
        "|---|---:|---:|",
        f"| every start to its budget | {budget} | {1e3 * full:.2f} |",
        f"| with recognition | {periods:.1f} | {1e3 * per_start:.2f} |",
        f"| ratio | {budget / periods:.1f}x fewer | {full / per_start:.1f}x faster |",
        "",
        f"- The seed ({result.seed_points} starts to the budget) is in the CPU per start.",
        f"- Labels of {sample} random starts against the attractor their final state lies on "
        f"after the whole budget: {agree} of {sample} agree.",
        f"- Attractors: {names}; {result.cells} basin cells.",
        "",
    ]


def _tree_rss(root: int) -> int:
    """Resident bytes of ``root`` and all its descendants (from /proc)."""
    parents: dict[int, int] = {}
    rss: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            status = (entry / "status").read_text()
        except OSError:
            continue
        fields = dict(line.split(":", 1) for line in status.splitlines() if ":" in line)
        parents[int(entry.name)] = int(fields.get("PPid", "0").strip())
        rss[int(entry.name)] = int(fields.get("VmRSS", "0 kB").split()[0]) * 1024
    tree, frontier = {root}, [root]
    while frontier:
        pid = frontier.pop()
        for child, parent in parents.items():
            if parent == pid and child not in tree:
                tree.add(child)
                frontier.append(child)
    return sum(rss.get(pid, 0) for pid in tree)


def million() -> list[str]:
    case = REPO / "cases" / "examples" / "basins-hires.toml"
    with tempfile.TemporaryDirectory() as tmp:
        cpu0 = _cpu()
        start = time.perf_counter()
        command = [sys.executable, "-m", "rubcli", "sweep", str(case), "--out", f"{tmp}/out"]
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
        peak = [0]

        def sample() -> None:
            while proc.poll() is None:
                peak[0] = max(peak[0], _tree_rss(proc.pid))
                time.sleep(0.2)

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        output, _ = proc.communicate()
        sampler.join()
        wall = time.perf_counter() - start
        cpu = _cpu() - cpu0
        sizes = {p.name: p.stat().st_size for p in (Path(tmp) / "out").iterdir()}
    summary = [line for line in output.splitlines() if "A0" in line or "A1" in line
               or "labelled by" in line]  # fmt: skip
    return [
        "## A million starts, end to end",
        "",
        "Command: `rubcli sweep cases/examples/basins-hires.toml` (all cores), exit "
        f"{proc.returncode}.",
        "",
        f"- Wall time {wall:.0f} s ({wall / 60:.1f} min); CPU time {cpu:.0f} s "
        f"({1e3 * cpu / 1e6:.2f} ms a start, all in).",
        f"- Peak resident memory of the process tree (parent and workers): "
        f"{peak[0] / 2**20:.0f} MiB.",
        f"- Files: {', '.join(f'{k} {v / 2**20:.1f} MiB' for k, v in sorted(sizes.items()))}.",
        *[f"- `{line.strip()}`" for line in summary],
        "",
    ]


def workers(n: int) -> list[str]:
    plan = plan_for(n)
    rows = []
    reference = None
    for label, kwargs in (("1 worker (in-process)", {"workers": 1}),
                          ("2 local processes", {"workers": 2})):  # fmt: skip
        cpu0 = _cpu()
        start = time.perf_counter()
        result, _, _ = execute(plan, **kwargs)
        wall, cpu = time.perf_counter() - start, _cpu() - cpu0
        reference = result.label if reference is None else reference
        rows.append((label, wall, cpu, bool((result.label == reference).all())))
    dask_line = "Dask: not installed."
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        pass
    else:
        with (
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                         host="127.0.0.1", dashboard_address=None) as cluster,
            Client(cluster, set_as_default=False) as client,
        ):  # fmt: skip
            execute(plan_for(5), client=client)  # start-up and warm-up, not timed
            start = time.perf_counter()
            result, _, _ = execute(plan, client=client)
            wall = time.perf_counter() - start
        rows.append(("Dask LocalCluster, 2 workers", wall, float("nan"),
                     bool((result.label == reference).all())))  # fmt: skip
        per_worker = plan.n_points / wall / 2
        dask_line = (
            f"Dask: {per_worker:.0f} starts per second per worker; 1e8 starts would take "
            f"{1e8 / per_worker / 64 / 3600:.1f} h on 64 such workers "
            f"({1e8 / per_worker / 1024 / 3600:.2f} h on 1024), if the scheduler keeps up "
            "(a chunk of 4096 starts is one task: 24,000 tasks)."
        )
    one = rows[0][1]
    lines = [
        f"## 1 and 2 workers ({n} x {n} starts)",
        "",
        "| executor | wall (s) | CPU (s) | speed-up | same labels |",
        "|---|---:|---:|---:|---|",
    ]
    for label, wall, cpu, same in rows:
        cpu_text = "" if np.isnan(cpu) else f"{cpu:.1f}"
        lines.append(f"| {label} | {wall:.1f} | {cpu_text} | {one / wall:.2f}x | {same} |")
    cpu_ratio = rows[1][2] / rows[0][2]
    lines += [
        "",
        f"- The pool costs {100 * (cpu_ratio - 1):+.1f} % CPU against one worker, so on an "
        f"idle 2-core machine its speed-up would be at most {2 / cpu_ratio:.2f}x.",
        f"- {dask_line}",
        "",
    ]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--no-hires", action="store_true", help="skip the million starts")
    parser.add_argument("--grid", type=int, default=101, help="early-stopping grid side")
    parser.add_argument("--sample", type=int, default=300, help="starts checked in full")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    text = [
        "# Basins at full resolution (`benchmarks/basins.py`)",
        "",
        f"Command: `python benchmarks/basins.py{' --no-hires' if args.no_hires else ''}`. "
        f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} cores "
        f"(load average {load:.1f} at the start).",
        "",
    ]
    text += early_stopping(args.grid, args.sample)
    text += workers(201)
    if not args.no_hires:
        text += million()
    (HERE / "basins.md").write_text("\n".join(text))
    print("\n".join(text))


if __name__ == "__main__":
    main()

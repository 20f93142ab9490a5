"""What machine a benchmark ran on, and the timing rule of a solve (shared by the
benchmark scripts)."""

from __future__ import annotations

import os
import platform
from pathlib import Path


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def describe() -> str:
    """One line: cores, CPU model, numpy/numba versions, Python, load average at the start."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (
        f"{os.cpu_count()} cores, {cpu_model()}; "
        f"Python {platform.python_version()}; load average at start {load:.2f}"
    )


def best_of(problem, method: str, repeats: int, **options):
    """``(best wall time in s, a solution)`` of ``repeats`` solves after one warm-up (the
    compilation or the cache load): the rule every timed solve of the scripts follows."""
    from rubcli.solvers import solve

    solve(problem, method, **options)
    runs = [solve(problem, method, **options) for _ in range(repeats)]
    return min(r.wall_time_s for r in runs), runs[0]

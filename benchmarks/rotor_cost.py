"""What a finite-element rotor costs: compile time, solve time and peak memory of
`rubcli run` on ROSS's example rotor, the full model (136 lateral coordinates of ROSS's
204, radau) and its 24-mode reduction (30 coordinates, dop853-jit).

Run from the repository root: ``python benchmarks/rotor_cost.py`` (about 3 minutes; needs
ROSS). Each case runs ``rubcli run CASE`` in a fresh process whose ``NUMBA_CACHE_DIR`` is
a new empty directory (every kernel the command needs is compiled: the system's
right-hand side and Jacobian, the event loop, the CSV formatter), then once more with
that cache, as every later run finds it. The table gives the wall time of each command,
the solve's own wall time from its report, and the process's peak resident memory.
Writes ``benchmarks/rotor_cost.md``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from end_to_end import LAUNCH  # the CLI imported from a given source tree
from machine import describe

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
CASES = ("cases/rotors/ross-rub.toml", "cases/rotors/ross-rub-reduced.toml")


def run_once(case: str, cache: Path, out: Path) -> dict:
    """`rubcli run case` with ``cache`` as numba's cache: wall s, solve s, peak MiB."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-c", LAUNCH, str(ROOT), "run", case, "--out", str(out), "--force"],
        cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    stderr = proc.stderr.read().decode() if proc.stderr else ""
    if status != 0:
        raise RuntimeError(f"{case} failed:\n{stderr[-2000:]}")
    report = json.loads((out / "report.json").read_text())
    method, entry = next(iter(report["methods"].items()))
    return {
        "wall_s": wall,
        "solve_s": entry["wall_time_s"],
        "method": method,
        "coordinates": report["machine"]["coordinates"],
        "peak_mib": usage.ru_maxrss / 1024.0,  # kilobytes on Linux
    }


def main() -> int:
    rows = []
    with tempfile.TemporaryDirectory(prefix="rubcli-rotor-cost-") as scratch:
        for k, case in enumerate(CASES):
            cache = Path(scratch) / f"cache-{k}"
            out = Path(scratch) / f"out-{k}"
            cold = run_once(case, cache, out)
            warm = run_once(case, cache, out)
            rows.append((case, cold, warm))
            print(
                f"{case}: {cold['coordinates']} coordinates, {cold['method']}; empty cache "
                f"{cold['wall_s']:.1f} s (solve {cold['solve_s']:.1f} s, {cold['peak_mib']:.0f} "
                f"MiB), cached {warm['wall_s']:.1f} s (solve {warm['solve_s']:.1f} s, "
                f"{warm['peak_mib']:.0f} MiB)",
                flush=True,
            )
    lines = [
        "# What a finite-element rotor costs: compile time, solve time, memory",
        "",
        f"Command: `python benchmarks/rotor_cost.py`. {describe()}",
        "",
        "`rubcli run CASE` (0.5 s of ROSS's rub example, its CSV, figures and report) with "
        "numba's cache empty, then cached; the solve is the report's `wall_time_s`; the "
        "compile time is about the difference of the two commands' wall times.",
        "",
        "| case | coordinates | method | empty cache: wall s | solve s | cached: wall s | "
        "solve s | peak memory MiB (empty, cached) |",
        "|---|---:|---|---:|---:|---:|---:|---|",
    ]
    for case, cold, warm in rows:
        lines.append(
            f"| {case} | {cold['coordinates']} | {cold['method']} | {cold['wall_s']:.1f} | "
            f"{cold['solve_s']:.1f} | {warm['wall_s']:.1f} | {warm['solve_s']:.1f} | "
            f"{cold['peak_mib']:.0f}, {warm['peak_mib']:.0f} |"
        )
    (HERE / "rotor_cost.md").write_text("\n".join(lines) + "\n")
    print("wrote benchmarks/rotor_cost.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())

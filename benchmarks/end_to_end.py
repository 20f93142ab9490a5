"""End to end: the wall time and peak memory of a whole `rubcli run`.

Runs ``rubcli run CASE --method METHOD --periods P`` in a fresh process for each P, and
measures the process's wall time, CPU time (user + system) and peak resident memory
(``os.wait4``: the child's own ``ru_utime``, ``ru_stime``, ``ru_maxrss``), beside the solve
time and the start-up (numba cache load, the first compiled call) that the run reports in
its report.json; ``ratio`` is wall / (solve + start-up): what a run costs beyond its solve.
With ``--source DIR`` the CLI is imported from another source tree (e.g. an older commit
extracted with ``git archive``), so that two versions are measured in one run, alternating
per horizon::

    git archive REV rubcli | tar -x -C out/before
    python benchmarks/end_to_end.py --periods 5000 10000 20000 \\
        --source out/before --label before --source . --label after

``--max-steps N`` runs a copy of the case with ``[solver] max_steps = N`` (the 10M-sample
run needs more than the default 5,000,000 steps). Prints a table and writes
``benchmarks/end_to_end.md`` and ``.csv`` (``--tag`` names them).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAUNCH = """
import sys
root = sys.argv.pop(1)
sys.path.insert(0, root)
import rubcli
assert rubcli.__file__.startswith(root), rubcli.__file__
from rubcli.cli.app import main
sys.argv[0] = "rubcli"
main()
"""


def run_once(source: Path, args: list[str]) -> dict:
    """One `rubcli` process from ``source``: exit code, wall time, peak RSS (MB)."""
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-c", LAUNCH, str(source.resolve()), *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        cwd=ROOT,
    )
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    return {
        "returncode": os.waitstatus_to_exitcode(status),
        "wall_s": wall,
        "cpu_s": usage.ru_utime + usage.ru_stime,
        "peak_rss_mb": usage.ru_maxrss / 1024.0,  # Linux: kilobytes
        "stderr_tail": err.strip().splitlines()[-1:] if err.strip() else [],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="cases/paper/fig3a.toml")
    parser.add_argument("--method", default="dop853-jit")
    parser.add_argument("--periods", type=float, nargs="+", default=[5000, 10000, 20000])
    parser.add_argument("--source", action="append", default=None, help="source tree (repeat)")
    parser.add_argument("--label", action="append", default=None, help="label per --source")
    parser.add_argument("--out", default="out/end_to_end", help="scratch dir for the runs")
    parser.add_argument("--tag", default="end_to_end")
    parser.add_argument(
        "--no-plots", action="store_true", help="a copy of the case with plots = [] (CSV only)"
    )
    parser.add_argument("--max-steps", type=int, default=None,
                        help="a copy of the case with [solver] max_steps = N")  # fmt: skip
    opts = parser.parse_args()
    sources = [Path(s) for s in (opts.source or ["."])]
    labels = opts.label or [str(s) for s in sources]
    if len(labels) != len(sources):
        parser.error("give one --label per --source")
    scratch = ROOT / opts.out
    scratch.mkdir(parents=True, exist_ok=True)
    case = opts.case
    if opts.no_plots:
        text = (ROOT / case).read_text()
        lines = [("plots = []" if line.startswith("plots =") else line)
                 for line in text.splitlines()]  # fmt: skip
        case = str(scratch / ("csv-only-" + Path(case).name))
        Path(case).write_text("\n".join(lines) + "\n")
    if opts.max_steps is not None:
        text = (ROOT / case).read_text()
        text = text.replace("[solver]\n", f"[solver]\nmax_steps = {opts.max_steps}\n", 1)
        case = str(scratch / (f"steps{opts.max_steps}-" + Path(case).name))
        Path(case).write_text(text)
    rows = []
    for source, label in zip(sources, labels, strict=True):  # warm each tree's numba cache
        shutil.rmtree(scratch / f"warm-{label}", ignore_errors=True)
        run_once(source, ["run", case, "-m", opts.method, "--periods", "2",
                          "--out", str(scratch / f"warm-{label}")])  # fmt: skip
    for periods in opts.periods:
        for source, label in zip(sources, labels, strict=True):
            target = scratch / f"{label}-{periods:g}"
            shutil.rmtree(target, ignore_errors=True)
            args = ["run", case, "-m", opts.method, "--periods", f"{periods:g}",
                    "--out", str(target)]  # fmt: skip
            result = run_once(source, args)
            report_path = target / "report.json"
            report = json.loads(report_path.read_text()) if report_path.exists() else {}
            entry = report.get("methods", {}).get(opts.method, {})
            csv_path = target / f"{opts.method}.csv"
            solve, startup = entry.get("wall_time_s"), entry.get("startup_s")
            base = solve + startup if solve is not None and startup is not None else None
            row = {
                "version": label,
                "periods": periods,
                "samples": entry.get("n_samples"),
                "exit": result["returncode"],
                "wall_s": round(result["wall_s"], 2),
                "cpu_s": round(result["cpu_s"], 2),
                "solve_s": None if solve is None else round(solve, 3),
                "startup_s": None if startup is None else round(startup, 3),
                "ratio": None if base is None else round(result["wall_s"] / base, 2),
                "peak_rss_mb": round(result["peak_rss_mb"]),
                "csv_mb": round(csv_path.stat().st_size / 1e6, 1) if csv_path.exists() else None,
                "note": "; ".join(result["stderr_tail"]) if result["returncode"] else "",
            }
            rows.append(row)
            print(", ".join(f"{k}={v}" for k, v in row.items()), flush=True)
            shutil.rmtree(target, ignore_errors=True)

    columns = list(rows[0])
    command = "python benchmarks/end_to_end.py " + " ".join(sys.argv[1:])
    what = " (plots = [], CSV only)" if opts.no_plots else ""
    if opts.max_steps is not None:
        what += f" (max_steps = {opts.max_steps})"
    lines = [f"# End to end: `rubcli run {opts.case} -m {opts.method}`{what}", "",
             f"Command: `{command}`", "",
             "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]  # fmt: skip
    for row in rows:
        cells = ["-" if v is None else f"{v:.3g}" if isinstance(v, float) else str(v)
                 for v in row.values()]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    text = "\n".join(lines) + "\n"
    print(text)
    (ROOT / "benchmarks" / f"{opts.tag}.md").write_text(text)
    with open(ROOT / "benchmarks" / f"{opts.tag}.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())

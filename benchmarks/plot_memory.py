"""Peak memory and wall time of `rubcli run` with and without its figures.

The paper's case (Figure 3(a) parameters), 10,000 forcing periods at 100 samples per period
(1,000,001 samples), one fast method (`dop853-jit`), no CSV (its cost is
measured by ``end_to_end.py``): each configuration runs `rubcli run` in a fresh process under
`/usr/bin/time -v`, which reports the peak resident set size of the whole command.

    python benchmarks/plot_memory.py                      # this checkout
    python benchmarks/plot_memory.py --baseline DIR       # and an older checkout beside it

``--baseline DIR`` runs the same commands with ``PYTHONPATH=DIR`` (a tree of an older
commit, e.g. ``git archive REV | tar -x -C DIR``), in the same run, so the two
are measured side by side. A warm-up run first loads (or compiles) the numba cache of
each tree. Prints a markdown table and writes it to ``benchmarks/plot_memory.md``.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from machine import describe  # noqa: E402

CASE = """\
[case]
name = "long"
[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6
mu = 0.0
Rp = 46.16
[initial]
x = 0.88544
y = -0.8039
[time]
periods = {periods}
samples_per_period = 100
[solver]
methods = ["dop853-jit"]
rtol = 1e-8
atol = 1e-10
[output]
csv = false
plots = {plots}
"""
CONFIGS = {"no figures": "[]", "orbit + time": '["orbit", "time"]'}
NEW_CONFIGS = {
    "orbit + time + energy": '["orbit", "time", "energy"]',
    "orbit + time + energy + spectrum": '["orbit", "time", "energy", "spectrum"]',
}


def measure(case: Path, out: Path, pythonpath: str | None) -> tuple[float, float, int]:
    """(peak RSS in MB, wall s, exit code) of `rubcli run CASE --out OUT`."""
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "rubcli", "run", str(case),
           "--out", str(out)]  # fmt: skip
    # run from the case's directory: `python -m` puts the working directory first on
    # sys.path, which would shadow PYTHONPATH with the checkout the script is run from
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=case.parent)
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", proc.stderr)
    seconds = 0.0
    for part in wall.group(1).split(":") if wall else []:
        seconds = 60.0 * seconds + float(part)
    return (int(rss.group(1)) / 1024.0 if rss else float("nan")), seconds, proc.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, help="tree of an older checkout")
    parser.add_argument("--periods", type=float, default=10_000)
    args = parser.parse_args()
    trees = [("this checkout", None)]
    if args.baseline:
        trees.append((f"baseline {args.baseline}", str(args.baseline.resolve())))
    lines = [
        f"Machine: {describe()}",
        "",
        f"`rubcli run`, Figure 3(a) parameters, {args.periods:g} forcing periods at 100 "
        "samples per period, `dop853-jit`, csv = false; peak RSS of the whole command.",
        "",
        "| tree | plots | peak RSS (MB) | wall (s) | exit |",
        "|---|---|---:|---:|---:|",
    ]
    with tempfile.TemporaryDirectory(prefix="plot-memory-") as tmp:
        tmp = Path(tmp)
        warm = tmp / "warm.toml"
        warm.write_text(CASE.format(periods=2, plots="[]"))
        for label, path in trees:
            measure(warm, tmp / "warm", path)  # numba cache of this tree
            configs = dict(CONFIGS)
            if path is None:
                configs.update(NEW_CONFIGS)
            for name, plots in configs.items():
                case = tmp / "case.toml"
                case.write_text(CASE.format(periods=args.periods, plots=plots))
                rss, wall, code = measure(case, tmp / "out", path)
                lines.append(f"| {label} | {name} | {rss:.0f} | {wall:.1f} | {code} |")
                print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    (HERE / "plot_memory.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()

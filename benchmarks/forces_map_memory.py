"""Peak memory of ``rubcli forces-map`` per grid point, measured (the case's memory check).

Runs the real command (``python -m rubcli forces-map``) on the Figure 2 machine for each
product alone and for all products, at two resolutions, and reads each child's peak
resident set size (``os.wait4``'s ``ru_maxrss``). The cost per grid point is the slope
between the two resolutions, ``(RSS(n2) - RSS(n1)) / (n2^2 - n1^2)``, so that the fixed
cost of the process (Python, numpy, matplotlib: the intercept) drops out.

    python benchmarks/forces_map_memory.py [--resolutions 1000 2000] [--out FILE.md]

``rubcli.case.FORCES_MAP_BYTES_PER_POINT`` is set from the largest slope this writes (with
a margin, see there). Writes ``benchmarks/forces_map_memory.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
CASE = """\
[case]
name = "memory"

[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6e3
mu = 0.1
Rp = 46.16

[initial]
x = 0.5
y = 0.0

[time]
periods = 1
samples_per_period = 10

[forces_map]
resolution = {resolution}
products = {products}
"""
PRODUCTS = (["forces"], ["eigen"], ["forces", "taylor_error", "eigen"])


def peak_rss(resolution: int, products: list[str], workdir: Path) -> tuple[int, float]:
    """(peak RSS in bytes, wall seconds) of one ``rubcli forces-map`` run."""
    case = workdir / f"case-{resolution}-{'-'.join(products)}.toml"
    case.write_text(CASE.format(resolution=resolution, products=products).replace("'", '"'))
    out = workdir / f"out-{resolution}-{'-'.join(products)}"
    start = time.perf_counter()
    child = subprocess.Popen(
        [sys.executable, "-m", "rubcli", "forces-map", str(case), "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip
    _, status, usage = os.wait4(child.pid, 0)
    seconds = time.perf_counter() - start
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise RuntimeError(f"forces-map exited {child.returncode}: {child.stderr.read()!r}")
    child.stderr.close()
    return usage.ru_maxrss * 1024, seconds  # ru_maxrss is in kB on Linux


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--resolutions", type=int, nargs=2, default=(1000, 2000))
    ap.add_argument("--out", type=Path, default=HERE / "forces_map_memory.md")
    args = ap.parse_args()
    n1, n2 = args.resolutions
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for products in PRODUCTS:
            (r1, s1), (r2, s2) = (peak_rss(n, products, Path(tmp)) for n in (n1, n2))
            slope = (r2 - r1) / (n2 * n2 - n1 * n1)
            rows.append((" + ".join(products), r1, r2, slope, s1, s2))
            print(f"{rows[-1][0]:30} {r1 / 2**20:8.0f} MiB {r2 / 2**20:8.0f} MiB "
                  f"{slope:7.0f} B/point {s1:6.1f} s {s2:6.1f} s")  # fmt: skip
    lines = [
        "# `rubcli forces-map`: peak memory per grid point",
        "",
        f"`python benchmarks/forces_map_memory.py --resolutions {n1} {n2}` on "
        f"{platform.machine()}, Python {platform.python_version()}: peak resident set "
        "size of the whole command (`os.wait4`), and the slope between the two "
        "resolutions (bytes per grid point; the fixed cost of the process drops out).",
        "",
        f"| products | peak at {n1}^2 | peak at {n2}^2 | bytes per point | s at {n1} | s at {n2} |",
        "|---|---|---|---|---|---|",
    ]
    for name, r1, r2, slope, s1, s2 in rows:
        lines.append(f"| {name} | {r1 / 2**20:.0f} MiB | {r2 / 2**20:.0f} MiB | {slope:.0f} | "
                     f"{s1:.1f} | {s2:.1f} |")  # fmt: skip
    args.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""Peak memory of ``rubcli sweep`` per point, measured (the case's memory check).

Runs the real command (``python -m rubcli sweep --workers 1``) on a cheap machine at two
grid sizes, for a model-parameter sweep (every point's section and scalars kept until
the files are written) and for a basin grid with recognition (a label, a time and a cost
per start), and reads each child's peak resident set size (``os.wait4``'s
``ru_maxrss``). The cost per point is the slope between the two sizes, so the fixed cost
of the process drops out.

    python benchmarks/sweep_memory.py

``rubcli.case.sweep.SWEEP_POINT_BYTES``, ``SWEEP_PERIOD_BYTES`` (per recorded period of a point) and
``BASIN_BYTES_PER_START`` are set from what this writes, with a margin (see there).
Writes ``benchmarks/sweep_memory.md``.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
MACHINE = """\
[case]
name = "memory"
[model]
nu = 0.05
eta = 2.0
e = 0.3
K = 10.0
mu = 0.02
Rp = 5.0
[initial]
x = 0.0
y = 0.0
[time]
periods = 10
samples_per_period = 8
[solver]
rtol = 1e-6
atol = 1e-8
"""
SWEEP = """\
[sweep]
parameter = "eta"
start = 0.5
stop = 4.0
num = {n}
transient_periods = 0
record_periods = {record}
energy = false
spectrum = {spectrum}
max_points = 1000000
"""
BASINS = """\
[sweep]
direction = "independent"
transient_periods = 20
record_periods = 8
max_points = 10000000
[[sweep.axes]]
parameter = "x"
start = -1.5
stop = 1.5
num = {n}
[[sweep.axes]]
parameter = "y"
start = -1.5
stop = 1.5
num = {n}
"""


def peak_rss(text: str) -> int:
    with tempfile.TemporaryDirectory() as tmp:
        case = Path(tmp) / "case.toml"
        case.write_text(text)
        proc = subprocess.Popen(
            [sys.executable, "-m", "rubcli", "sweep", str(case), "--workers", "1", "--out",
             f"{tmp}/out"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        )  # fmt: skip
        _, status, usage = os.wait4(proc.pid, 0)
        if status != 0:
            raise RuntimeError(proc.stderr.read().decode())
        return usage.ru_maxrss * 1024


def main() -> None:
    lines = [
        "# Peak memory of `rubcli sweep` per point (`benchmarks/sweep_memory.py`)",
        "",
        f"Command: `python benchmarks/sweep_memory.py`. Python {platform.python_version()}, "
        f"{platform.machine()}.",
        "",
        "| sweep | sizes | peak RSS (MiB) | bytes per point | per recorded period |",
        "|---|---|---|---:|---:|",
    ]
    for record, spectrum in ((8, "false"), (64, "false"), (64, "true")):
        a, b = 2000, 8000
        ra = peak_rss(MACHINE + SWEEP.format(n=a, record=record, spectrum=spectrum))
        rb = peak_rss(MACHINE + SWEEP.format(n=b, record=record, spectrum=spectrum))
        slope = (rb - ra) / (b - a)
        label = f"eta, {record} recorded periods" + (", spectrum" if spectrum == "true" else "")
        lines.append(f"| {label} | {a}, {b} points | {ra / 2**20:.0f}, {rb / 2**20:.0f} | "
                     f"{slope:.0f} | {slope / record:.0f} |")  # fmt: skip
    a, b = 100, 300
    ra = peak_rss(MACHINE + BASINS.format(n=a))
    rb = peak_rss(MACHINE + BASINS.format(n=b))
    slope = (rb - ra) / (b * b - a * a)
    lines.append(f"| basins, recognition | {a}^2, {b}^2 starts | {ra / 2**20:.0f}, "
                 f"{rb / 2**20:.0f} | {slope:.0f} | |")  # fmt: skip
    text = "\n".join(lines) + "\n"
    (HERE / "sweep_memory.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()

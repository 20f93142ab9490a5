"""A driven rotor: error against run time of every method that runs it.

Run from the repository root:

    python benchmarks/driven.py      # about 6 minutes on 2 cores

Cases: the shipped driven rotors `cases/runup/driven-captured.toml` (a run-up captured
on the rub branch, 165 revolutions, one contact entry and permanent slip) and
`cases/runup/driven-dry-whip.toml` (a dry whip braking the drive: 75 revolutions of
stick and slip). Each method that runs a driven rotor (scipy's, ``dop853-jit`` and
``taylor``) at rtol = 1e-6 and 1e-9 (atol = rtol / 100), the best of 3 timed runs after
a warm-up.
The error is the largest distance of the sampled positions from a reference (dop853 at
rtol = 1e-12), beside the error of the final speed; the reference's own error is
estimated by its distance from lsoda at rtol = 1e-12. Writes benchmarks/driven.md.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from machine import best_of, describe

from rubcli.case import load_case
from rubcli.solvers import solve

ROOT = Path(__file__).resolve().parents[1]
CASES = ("driven-captured", "driven-dry-whip")
METHODS = ("dop853-jit", "taylor", "dop853", "rk45", "radau", "bdf", "lsoda")
TOLERANCES = (1e-6, 1e-9)
REPEATS = 3


def measure(name: str) -> list[str]:
    problem = load_case(ROOT / "cases" / "runup" / f"{name}.toml").problem
    reference = solve(problem, "dop853", rtol=1e-12, atol=1e-14)
    check = solve(problem, "lsoda", rtol=1e-12, atol=1e-14)
    ref_error = float(np.max(np.hypot(check.x - reference.x, check.y - reference.y)))
    lines = [
        f"## {name}",
        "",
        f"tau 0 .. {problem.t_span[1]:g}, {problem.t_eval.size} samples; reference dop853 at "
        f"rtol 1e-12 ({len(reference.events)} events, final speed "
        f"{reference.speed[-1]:.8g}), its distance from lsoda at rtol 1e-12: "
        f"{ref_error:.2g} clearances.",
        "",
        "| method | rtol | wall ms (best of 3) | x dop853 | max position error "
        "| final speed error | steps | events |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rows = []
    for method in METHODS:
        for rtol in TOLERANCES:
            options = {"rtol": rtol, "atol": rtol / 100}
            best, sol = best_of(problem, method, REPEATS, **options)
            n = min(sol.t.size, reference.t.size)
            error = float(
                np.max(np.hypot(sol.x[:n] - reference.x[:n], sol.y[:n] - reference.y[:n]))
            )
            speed = abs(float(sol.speed[-1] - reference.speed[-1]))
            status = "" if sol.success else f" ({sol.status})"
            rows.append((method + status, rtol, best, error, speed, sol.stats["nsteps"],
                         len(sol.events)))  # fmt: skip
            print(f"{name} {method:<7} rtol {rtol:g}: {best * 1e3:9.1f} ms, error {error:.2g}")
    fastest = {rtol: next(r[2] for r in rows if r[1] == rtol and r[0] == "dop853")
               for rtol in TOLERANCES}  # fmt: skip
    for method, rtol, best, error, speed, steps, events in rows:
        lines.append(f"| `{method}` | {rtol:g} | {best * 1e3:.1f} | {best / fastest[rtol]:.2g} "
                     f"| {error:.2g} | {speed:.2g} | {steps} | {events} |")  # fmt: skip
    return lines + [""]


def main() -> None:
    lines = [
        "# A driven rotor: error against run time",
        "",
        "Command: `python benchmarks/driven.py` (the script's docstring says what it runs).",
        f"Machine: {describe()}.",
        "",
    ]
    for name in CASES:
        lines += measure(name)
    out = Path(__file__).with_name("driven.md")
    out.write_text("\n".join(lines))
    print(f"wrote {out}", file=sys.stderr)


if __name__ == "__main__":
    started = time.perf_counter()
    main()
    print(f"{time.perf_counter() - started:.0f} s", file=sys.stderr)

"""A run-up through resonance with rub: error against run time of every method that runs a
speed that changes.

Run from the repository root:

    python benchmarks/runup.py      # about 13 minutes on 2 cores (radau's ladder is 10 of them)

Case: the run-up machine of cases/runup (nu = 0.05, e = 0.3, K = 10, mu = 0.02, Rp = 5)
ramped from eta = 0.5 to 4 at the rate that makes 1,000 revolutions (d eta / d tau =
1.253e-3), from the steady free whirl at eta = 0.5: contact near eta = 0.9, the
synchronous rub through the critical speed, the jump down past the steady fold. Sampled
16 times per revolution at the highest speed.

Each method at rtol = 1e-6 and 1e-9 (atol = rtol / 100), the best of 3 timed runs after a
warm-up; the error is the largest distance of the sampled positions from a reference
(dop853-jit at rtol = 1e-13), whose own error is estimated by its distance from lsoda at
rtol = 1e-12 (that distance bounds the error of the less accurate of the two). Writes
benchmarks/runup.md.

heyoka (``pip install -e ".[bench]"``; skipped with a note when it is not installed)
integrates the same run-up as its users would write it: one Taylor integrator whose
right-hand side depends on time (the phase eta0 tau + a tau^2 / 2, the speed, the
unbalance's tangential term), its contact force and friction sign switched at terminal
events (``peers.Heyoka`` with a ramp rate), at tol = 1e-6 and 1e-9. It gives the final
state only (its dense output is not sampled here), so every method's error is also
stated at the final state, and dop853-jit and taylor are timed once more giving the
final state only (no samples), as heyoka does.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from machine import best_of, describe
from peers import Heyoka

from rubcli import model
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.speed import SpeedProfile

PARAMS = model.ModelParams(nu=0.05, eta=0.5, e=0.3, K=10.0, mu=0.02, Rp=5.0)
START, END, REVOLUTIONS = 0.5, 4.0, 1000
METHODS = ("dop853-jit", "taylor", "dop853", "rk45", "radau", "lsoda")
TOLERANCES = (1e-6, 1e-9)
REPEATS = 3


def problem() -> Problem:
    span = REVOLUTIONS * 2.0 * math.pi / (0.5 * (START + END))
    profile = SpeedProfile.ramp(START, END, (END - START) / span)
    n = int(math.ceil(span / (2.0 * math.pi / (16 * END)))) + 1
    # on the steady free whirl at the start speed (heyoka's contact terms divide by z, and
    # their Taylor coefficients overflow at the origin, so no run starts from rest there)
    w, v = model.free_steady_state(0.0, PARAMS)
    initial = (w.real, w.imag, v.real, v.imag)
    return Problem(PARAMS, initial, np.linspace(0.0, span, n), speed=profile)


def main() -> None:
    p = problem()
    reference = solve(p, "dop853-jit", rtol=1e-13, atol=1e-15)
    check = solve(p, "lsoda", rtol=1e-12, atol=1e-14)
    ref_error = float(np.max(np.hypot(check.x - reference.x, check.y - reference.y)))
    rows = []
    for method in METHODS:
        for rtol in TOLERANCES:
            options = {"rtol": rtol, "atol": rtol / 100}
            best, sol = best_of(p, method, REPEATS, **options)
            error = float(np.max(np.hypot(sol.x - reference.x, sol.y - reference.y)))
            final = float(np.hypot(*(sol.states[-1, :2] - reference.states[-1, :2])))
            rows.append((method, rtol, best, error, final, sol.stats["nsteps"], len(sol.events)))
            print(f"{method:<11} rtol {rtol:g}: {best * 1e3:9.2f} ms, error {error:.2g}")
    rows += heyoka_rows(p, reference)
    fastest = {rtol: min(r[2] for r in rows if r[1] == rtol and r[0] == "dop853-jit")
               for rtol in TOLERANCES}  # fmt: skip
    lines = [
        "# Run-up through resonance with rub: error against run time",
        "",
        "Command: `python benchmarks/runup.py` (the script's docstring says what it runs).",
        f"Machine: {describe()}.",
        "",
        f"{REVOLUTIONS} revolutions, eta {START} to {END}, {p.t_eval.size} samples; reference "
        f"dop853-jit at rtol 1e-13 ({len(reference.events)} events), its distance from lsoda "
        f"at rtol 1e-12: {ref_error:.2g} clearances.",
        "",
        f"The reference's events: {event_counts(reference)}.",
        "",
        "| method | rtol | wall ms (best of 3) | x dop853-jit | max position error "
        "| final position error | steps | events |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for method, rtol, best, error, final, steps, events in rows:
        ratio = best / fastest[rtol]
        shown = "final state only" if error is None else f"{error:.2g}"
        lines.append(f"| `{method}` | {rtol:g} | {best * 1e3:.2f} | {ratio:.2g} | {shown} "
                     f"| {final:.2g} | {steps} | {events} |")  # fmt: skip
    if not any(r[0] == "heyoka" for r in rows):
        lines += ["", 'heyoka is not installed: `pip install -e ".[bench]"` to measure it.']
    out = Path(__file__).with_name("runup.md")
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}", file=sys.stderr)


def event_counts(solution) -> str:
    kinds, counts = np.unique(solution.events.kinds, return_counts=True)
    return ", ".join(f"{n} {k}" for k, n in zip(kinds, counts, strict=True))


def heyoka_rows(p: Problem, reference) -> list[tuple]:
    """heyoka on the same run-up (module docstring): final-state errors only."""
    try:
        import heyoka  # noqa: F401
    except ImportError:
        print("heyoka is not installed: skipped", file=sys.stderr)
        return []
    rate = p.speed.rate(0.0)
    t_end = float(p.t_eval[-1])
    rows = []
    ends = Problem(p.params, p.initial, p.t_eval[[0, -1]], speed=p.speed)  # no samples
    for tol in TOLERANCES:
        options = {"rtol": tol, "atol": tol / 100}
        for method in ("dop853-jit", "taylor"):
            best, sol = best_of(ends, method, REPEATS, **options)
            final = float(np.hypot(*(sol.states[-1, :2] - reference.states[-1, :2])))
            rows.append((f"{method}, final state only", tol, best, None, final,
                         sol.stats["nsteps"], len(sol.events)))  # fmt: skip
        integrator = Heyoka(p.params, tol, rate=rate)  # LLVM compilation, not timed
        times = []
        for _ in range(REPEATS + 1):  # the first a warm-up
            start = time.perf_counter()
            state, events, steps, status, note = integrator.run(p.initial, t_end, 600.0)
            times.append(time.perf_counter() - start)
        if status != "success":
            print(f"heyoka tol {tol:g}: {status} {note}", file=sys.stderr)
        final = float(np.hypot(*(np.asarray(state[:2]) - reference.states[-1, :2])))
        rows.append(("heyoka", tol, min(times[1:]), None, final, steps, events))
        print(f"heyoka      tol  {tol:g}: {min(times[1:]) * 1e3:9.2f} ms, final {final:.2g}")
    return rows


if __name__ == "__main__":
    started = time.perf_counter()
    main()
    print(f"{time.perf_counter() - started:.0f} s", file=sys.stderr)

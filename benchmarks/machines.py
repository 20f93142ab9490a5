"""The general machine (docs/machines.md): error against run time of the methods that run
it, and heyoka with the cheapest correct model a heyoka user would write.

Run from the repository root:

    python benchmarks/machines.py      # about 8 minutes on 2 cores (radau is 6 of them)

Cases: the four of cases/machines (a misaligned stator, a rotor under gravity, an
anisotropic cross-coupled support, a snubber ring with its own mass), each over its
[time] span from its [initial] state; the snubber ring by the methods that run a moving
stator (``TWO_BODY_METHODS``).
Each method at rtol = 1e-6 and 1e-9 (atol = rtol / 100; ``analytic`` at 400 and 1600
steps per period), the best of 3 timed runs after a warm-up; errors against a reference
(dop853-jit at rtol = 1e-13), whose own error is estimated by its distance from lsoda at
rtol = 1e-12.

heyoka (``pip install -e ".[bench]"``; skipped with a note when it is not installed) gives
the final state only, so the final position error is stated for every row, and
dop853-jit and taylor are timed once more giving the final state only, as heyoka does.
Its model is the one a heyoka user would write for the case: the slip of these cases never
reverses and they never stick (checked on the reference), so two integrators, free flight
and contact in forward slip, switched at terminal events on the clearance
(``peers.HeyokaSwitched``), with the general machine's support terms
(``peers.support_terms``); for the snubber ring the same two integrators on the two
bodies' eight states (``HeyokaTwoBody``). Writes benchmarks/machines.md.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from machine import best_of, describe
from peers import HeyokaSwitched

from rubcli import model
from rubcli.case import load_case
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

REPO = Path(__file__).resolve().parents[1]
CASES = ("misaligned", "gravity", "cross-coupled", "snubber")
METHODS = ("taylor", "dop853-jit", "dop853", "rk45", "radau", "analytic")
TWO_BODY_METHODS = ("taylor", "dop853-jit", "dop853", "rk45")  # analytic refuses it
TOLERANCES = (1e-6, 1e-9)
STEPS = {1e-6: 400, 1e-9: 1600}  # the analytic method's setting in each row
REPEATS = 3


def options(method: str, tol: float) -> dict:
    if method == "analytic":
        return {"steps_per_period": STEPS[tol]}
    return {"rtol": tol, "atol": tol / 100}


def final_error(state, reference) -> float:
    return float(np.hypot(*(np.asarray(state[:2]) - reference.states[-1, :2])))


def case_rows(name: str) -> tuple[list[str], list[tuple]]:
    p = load_case(REPO / "cases" / "machines" / f"{name}.toml").problem
    reference = solve(p, "dop853-jit", rtol=1e-13, atol=1e-15)
    check = solve(p, "lsoda", rtol=1e-12, atol=1e-14)
    ref_error = float(np.max(np.hypot(check.x - reference.x, check.y - reference.y)))
    kinds = sorted(set(reference.events.kinds))
    rows = []
    methods = TWO_BODY_METHODS if p.params.stator is not None else METHODS
    for tol in TOLERANCES:
        for method in methods:
            best, sol = best_of(p, method, REPEATS, **options(method, tol))
            error = float(np.max(np.hypot(sol.x - reference.x, sol.y - reference.y)))
            final = final_error(sol.states[-1], reference)
            rows.append((method, tol, best, error, final, sol.stats["nsteps"], len(sol.events)))
            print(f"{name} {method:<11} {tol:g}: {best * 1e3:9.2f} ms, error {error:.2g}")
        rows += heyoka_rows(p, reference, tol, kinds)
    head = [
        f"## `cases/machines/{name}.toml`",
        "",
        f"{p.params.machine_text()}; {p.periods:g} periods, {p.t_eval.size} samples; "
        f"reference dop853-jit at rtol 1e-13 ({len(reference.events)} events: "
        f"{', '.join(kinds)}), its distance from lsoda at rtol 1e-12: {ref_error:.2g} "
        "clearances.",
        "",
    ]
    return head, rows


def heyoka_rows(p: Problem, reference, tol: float, kinds: list[str]) -> list[tuple]:
    """heyoka on the case (module docstring), with dop853-jit and taylor giving the final
    state only beside it."""
    try:
        import heyoka  # noqa: F401
    except ImportError:
        return []
    if set(kinds) - {"contact_entry", "contact_exit"}:
        print(
            "the case reverses or sticks: heyoka's switched model does not apply", file=sys.stderr
        )
        return []
    rows = []
    ends = Problem(p.params, p.initial, p.t_eval[[0, -1]], stator_initial=p.stator_initial)
    for method in ("taylor", "dop853-jit"):
        best, sol = best_of(ends, method, REPEATS, **options(method, tol))
        rows.append((f"{method}, final state only", tol, best, None,
                     final_error(sol.states[-1], reference), sol.stats["nsteps"],
                     len(sol.events)))  # fmt: skip
    if p.params.stator is not None:  # LLVM compilation, not timed
        integrator, initial = HeyokaTwoBody(p.params, tol), (*p.initial, *p.stator_initial)
    else:
        integrator, initial = HeyokaSwitched(p.params, tol), p.initial
    times = []
    t_end = float(p.t_eval[-1])
    for _ in range(REPEATS + 1):  # the first a warm-up
        start = time.perf_counter()
        state, events, steps, status, note = integrator.run(initial, t_end, 600.0)
        times.append(time.perf_counter() - start)
    if status != "success":
        print(f"heyoka tol {tol:g}: {status} {note}", file=sys.stderr)
    rows.append(("heyoka", tol, min(times[1:]), None, final_error(state, reference), steps,
                 events))  # fmt: skip
    return rows


class HeyokaTwoBody(HeyokaSwitched):
    """``peers.HeyokaSwitched`` on a stator with its own mass: the state (d, d', s, s')
    with d the rotor relative to the ring's centre (``rubcli.stator``), two integrators
    (free flight, contact in forward slip) switched at terminal events on the clearance.
    ``run`` is the parent's: it reads the clearance from the first two entries."""

    def __init__(self, params: ModelParams, tol: float):
        import heyoka as hy

        self.hy = hy
        x, y, vx, vy, u, v, up, vp = hy.make_vars("x", "y", "vx", "vy", "u", "v", "up", "vp")
        r = model.params_vector(params)
        st = params.stator
        (sxx, sxy), (syx, syy) = params.stiffness
        (dxx, dxy), (dyx, dyy) = params.damping_matrix
        phase = params.eta * hy.time + params.phi0
        wx, wy, wvx, wvy = x + u, y + v, vx + up, vy + vp  # from the support, less c
        ax = (params.E * hy.cos(phase) + r[model.P_GX] - (sxx * wx + sxy * wy)
              - 2.0 * (dxx * wvx + dxy * wvy))  # fmt: skip
        ay = (params.E * hy.sin(phase) + r[model.P_GY] - (syx * wx + syy * wy)
              - 2.0 * (dyx * wvx + dyy * wvy))  # fmt: skip
        m_inv = 1.0 / st.mass
        bx = -(st.stiffness[0] * u + 2.0 * st.damping[0] * up) * m_inv
        by = -(st.stiffness[1] * v + 2.0 * st.damping[1] * vp) * m_inv
        fac = params.K * (1.0 - 1.0 / hy.sqrt(x * x + y * y))
        fx, fy = -fac * (x - params.mu * y), -fac * (y + params.mu * x)

        def system(fx, fy) -> list:
            rx, ry = bx - fx * m_inv, by - fy * m_inv  # the ring's accelerations
            return [(x, vx), (y, vy), (vx, ax + fx - rx), (vy, ay + fy - ry), (u, up),
                    (v, vp), (up, rx), (vp, ry)]  # fmt: skip

        surface = x * x + y * y - 1.0
        rising = [hy.t_event(surface, direction=hy.event_direction.positive)]
        falling = [hy.t_event(surface, direction=hy.event_direction.negative)]
        self.free = hy.taylor_adaptive(system(0.0, 0.0), [0.0] * 8, tol=tol, t_events=rising)
        self.contact = hy.taylor_adaptive(system(fx, fy), [0.0] * 8, tol=tol,
                                          t_events=falling)  # fmt: skip
        self.params = params


def main() -> None:
    lines = [
        "# The general machine: error against run time",
        "",
        "Command: `python benchmarks/machines.py` (the script's docstring says what it runs).",
        f"Machine: {describe()}.",
        "",
    ]
    for name in CASES:
        head, rows = case_rows(name)
        fastest = {tol: min(r[2] for r in rows if r[1] == tol and r[0] == "taylor")
                   for tol in TOLERANCES}  # fmt: skip
        lines += head
        lines += [
            "| method | setting | wall ms (best of 3) | x taylor | max position error "
            "| final position error | steps | events |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for method, tol, best, error, final, steps, events in rows:
            setting = f"{STEPS[tol]} steps/period" if method == "analytic" else f"rtol {tol:g}"
            shown = "final state only" if error is None else f"{error:.2g}"
            lines.append(f"| `{method}` | {setting} | {best * 1e3:.3g} | "
                         f"{best / fastest[tol]:.2g} | {shown} | {final:.2g} | {steps} | "
                         f"{events} |")  # fmt: skip
        lines.append("")
    try:
        import heyoka  # noqa: F401
    except ImportError:
        lines += ['heyoka is not installed: `pip install -e ".[bench]"` to measure it.', ""]
    out = Path(__file__).with_name("machines.md")
    out.write_text("\n".join(lines))
    print(f"wrote {out}", file=sys.stderr)


if __name__ == "__main__":
    started = time.perf_counter()
    main()
    print(f"{time.perf_counter() - started:.0f} s", file=sys.stderr)

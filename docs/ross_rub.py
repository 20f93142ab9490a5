"""Regenerate what docs/rotors.md states about ROSS's own rub example beside rubcli's.

    python docs/ross_rub.py            # needs ROSS (pip install -e ".[ross]"), about 6 min
    python docs/ross_rub.py reduction  # part 3 alone, and its figure
    python docs/ross_rub.py analytic   # part 4 alone, about 3 min

The machine is cases/rotors/ross-rub.toml (ROSS's example rotor with damping, rub at
node 12, 1200 rpm, from rest, 0.5 s). Printed:

0. The full model's stiffest eigenvalue (why an implicit method runs it).
1. ROSS's law as ROSS runs it (``Rotor.run_rubbing``, its documented step 1e-4 s, friction
   0.3, contact damping 40 N s/m) beside rubcli's run of the shipped case: the largest
   radial displacement at node 12, the contact share of the last 0.25 s, the largest
   normal force, the wall time.
2. Where the two laws are the same (no friction, no contact damping: a radial spring),
   ROSS at three steps against rubcli's radau at rtol 1e-7: its largest position error at
   node 12 in clearances, and the order it converges at; rubcli's own case tolerance
   (rtol 1e-6) against the same reference.
3. The Craig-Bampton reduction (``[rotor] modes``) of the shipped case against its full
   model (radau, rtol 1e-7) over the 0.5 s: the largest position error at node 12 in
   clearances and dop853-jit's wall time for each number of modes, beside the full model
   by radau; the figure docs/images/rotors-reduction.png.
4. ``analytic`` on the full model (exact free flight, no stability limit from its stiff
   modes) and on the 24-mode reduction, at three tolerances, beside radau and dop853-jit:
   the error at node 12 in clearances against the full model's radau at rtol 1e-7 (the
   reduction's against the reduction's own dop853-jit at rtol 1e-12), steps, wall time.
Run from the repository root.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

from rubcli.case.rotor import assemble_rotor_case, load_rotor_case
from rubcli.machine import ContactLaw, linear
from rubcli.machine.ross import load_ross_rotor
from rubcli.system import simulate

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "rotors" / "ross-rub.toml"
ROTOR = ROOT / "cases" / "rotors" / "ross_example.toml"
NODE = 12
CLEARANCE = 7.95e-5  # m
STIFFNESS = 1.1e6  # N/m
STEPS = (1e-4, 2e-5, 5e-6)  # s: ROSS's documented step, then finer
MODES = (2, 4, 8, 12, 16, 24, 32, 48)
FIGURE = ROOT / "docs" / "images" / "rotors-reduction.png"


def ross_run(rotor, step: float, friction: float, damping: float):
    """ROSS's rub at node 12 over 0.5 s at ``step``: (t, x, y at node 12, wall time)."""
    t = np.arange(0.0, 0.5, step)
    started = time.perf_counter()
    result = rotor.run_rubbing(
        n=NODE, distance=CLEARANCE, contact_stiffness=STIFFNESS, contact_damping=damping,
        friction_coeff=friction, node=[NODE], unbalance_magnitude=[5e-4],
        unbalance_phase=[-math.pi / 2], speed=1200.0 * 2.0 * math.pi / 60.0, t=t,
    )  # fmt: skip
    wall = time.perf_counter() - started
    per_node = rotor.number_dof
    return t, result.yout[:, per_node * NODE], result.yout[:, per_node * NODE + 1], wall


def summary(t, x, y) -> str:
    """The largest radius at node 12, the contact share of the last 0.25 s, and the
    largest spring force ``k (r - delta)`` (the same quantity under both laws; rubcli's
    normal force adds its damping along the normal, ROSS's damping acts on the whole
    velocity)."""
    r = np.hypot(x, y)
    late = t >= 0.25
    spring = STIFFNESS * max(float(r.max()) - CLEARANCE, 0.0)
    return (
        f"largest radius {r.max() * 1e6:.1f} um, in contact {np.mean(r[late] > CLEARANCE):.1%}"
        f" of the last 0.25 s, largest spring force {spring:.1f} N"
    )


def reduction() -> None:
    case = load_rotor_case(CASE)
    ix, iy = case.lateral(NODE)
    print("3. The reduced model (dop853-jit, rtol 1e-9) against the full one (radau, rtol 1e-7)")
    reference = simulate(case.machine, case.t_eval, method="radau", rtol=1e-7, atol=1e-12)
    ref = reference.states[:, [ix, iy]]
    print(f"   reference: {reference.wall_time_s:.1f} s, {len(reference.events)} events")
    full = simulate(case.machine, case.t_eval, method="radau", rtol=1e-6, atol=1e-10)
    full_error = np.max(np.hypot(*(full.states[:, [ix, iy]] - ref).T)) / CLEARANCE
    print(f"   full model, radau rtol 1e-6: {full_error:.2g} clearances, {full.wall_time_s:.1f} s")
    rows = []
    for modes in MODES:
        text = CASE.read_text().replace("speed = 1200.0", f"speed = 1200.0\nmodes = {modes}")
        reduced = assemble_rotor_case(tomllib.loads(text), CASE)
        simulate(reduced.machine, case.t_eval[:3], rtol=1e-9, atol=1e-14)  # compiled once
        run = simulate(reduced.machine, case.t_eval, rtol=1e-9, atol=1e-14)
        a, b = reduced.lateral(NODE)
        error = np.max(np.hypot(*(run.states[:, [a, b]] - ref).T)) / CLEARANCE
        rows.append((modes, error, run.wall_time_s, len(run.events)))
        print(f"   {modes:2d} modes ({reduced.machine.size} coordinates): {error:.2g} clearances,"
              f" {len(run.events)} events, {run.wall_time_s:.2f} s")  # fmt: skip
    _figure(rows, full_error, full.wall_time_s)


def _figure(rows, full_error: float, full_time: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    modes, errors, times, _ = (np.array(c) for c in zip(*rows, strict=True))
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2), constrained_layout=True)
    left.semilogy(modes, errors, "o-", color="C0", label="Craig-Bampton, N modes")
    left.axhline(full_error, color="C3", ls="--", label="full model, radau rtol 1e-6")
    left.set(xlabel="fixed-interface modes N", ylabel="largest error at node 12 (clearances)",
             title="Error of the reduced model against N")  # fmt: skip
    right.loglog(times, errors, "o-", color="C0", label="reduced, dop853-jit rtol 1e-9")
    for n, e, w in zip(modes, errors, times, strict=True):
        right.annotate(f"N={n}", (w, e), textcoords="offset points", xytext=(6, 2), fontsize=8)
    right.loglog([full_time], [full_error], "s", color="C3", label="full model, radau rtol 1e-6")
    right.set(xlabel="wall time (s)", ylabel="largest error at node 12 (clearances)",
              title="Error against run time")  # fmt: skip
    for ax in (left, right):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    fig.suptitle("ross-rub (ROSS's example rotor, rub at node 12, 0.5 s) reduced against full")
    fig.savefig(FIGURE, dpi=110)
    print(f"   wrote {FIGURE.relative_to(ROOT)}")


def analytic() -> None:
    case = load_rotor_case(CASE)
    ix, iy = case.lateral(NODE)
    t = case.t_eval
    print("4. analytic on the full model and on its 24-mode reduction")

    def line(name: str, run, ref, a: int, b: int) -> None:
        error = np.max(np.hypot(*(run.states[:, [a, b]] - ref).T)) / CLEARANCE
        print(f"   {name}: {error:.2g} clearances, {run.stats['steps']} steps, "
              f"{len(run.events)} events, {run.wall_time_s:.1f} s")  # fmt: skip

    reference = simulate(case.machine, t, method="radau", rtol=1e-7, atol=1e-12)
    ref = reference.states[:, [ix, iy]]
    print(f"   full model ({case.machine.size} coordinates), reference radau rtol 1e-7: "
          f"{reference.wall_time_s:.1f} s")  # fmt: skip
    for rtol in (1e-5, 1e-6):
        run = simulate(case.machine, t, method="radau", rtol=rtol, atol=rtol * 1e-4)
        line(f"radau rtol {rtol:g}", run, ref, ix, iy)
    simulate(case.machine, t[:3], method="analytic")  # compiled once
    for rtol in (1e-4, 1e-6, 1e-8):
        run = simulate(case.machine, t, method="analytic", rtol=rtol, atol=rtol * 1e-2 * CLEARANCE)
        line(f"analytic rtol {rtol:g}", run, ref, ix, iy)
    text = CASE.read_text().replace("speed = 1200.0", "speed = 1200.0\nmodes = 24")
    reduced = assemble_rotor_case(tomllib.loads(text), CASE)
    a, b = reduced.lateral(NODE)
    own = simulate(reduced.machine, t, rtol=1e-12, atol=1e-16)
    ref = own.states[:, [a, b]]
    print(f"   24 modes ({reduced.machine.size} coordinates), reference dop853-jit rtol 1e-12: "
          f"{own.wall_time_s:.1f} s")  # fmt: skip
    run = simulate(reduced.machine, t, rtol=1e-9, atol=1e-14)
    line("dop853-jit rtol 1e-9", run, ref, a, b)
    for rtol in (1e-4, 1e-6, 1e-8):
        run = simulate(reduced.machine, t, method="analytic", rtol=rtol,
                       atol=rtol * 1e-2 * CLEARANCE)  # fmt: skip
        line(f"analytic rtol {rtol:g}", run, ref, a, b)


def main() -> None:
    if sys.argv[1:] == ["reduction"]:
        reduction()
        return
    if sys.argv[1:] == ["analytic"]:
        analytic()
        return
    rotor = load_ross_rotor(ROTOR)
    case = load_rotor_case(CASE)
    ix, iy = case.lateral(NODE)
    full = case.full_machine
    values = linear.eigenvalues(full.structure, full.speed.values[0])
    print(f"0. the full model's most negative eigenvalue: {values.real.min():.3g} 1/s")

    print("1. ROSS's law (friction 0.3, contact damping 40 N s/m) and rubcli's")
    t, x, y, wall = ross_run(rotor, STEPS[0], 0.3, 40.0)
    print(f"   ROSS run_rubbing, step {STEPS[0]:g} s: {summary(t, x, y)}; {wall:.1f} s")
    run = simulate(case.machine, case.t_eval, method="radau", rtol=1e-6, atol=1e-10)
    mine = summary(run.t, run.states[:, ix], run.states[:, iy])
    print(f"   rubcli radau rtol 1e-6: {mine}; {len(run.events)} events; {run.wall_time_s:.1f} s")

    print("2. The same law (no friction, no contact damping): errors at node 12 in clearances")
    law = ContactLaw(STIFFNESS)
    stations = tuple(dataclasses.replace(s, mu=0.0, law=law) for s in case.machine.stations)
    spring = dataclasses.replace(case.machine, stations=stations)
    grid = np.arange(0.0, 0.5, STEPS[0])  # ROSS's own times, every step's grid holds them
    reference = simulate(spring, grid, method="radau", rtol=1e-7, atol=1e-12)
    ref = reference.states[:, [ix, iy]]
    print(f"   reference: rubcli radau rtol 1e-7, {reference.wall_time_s:.1f} s")
    errors = []
    for step in STEPS:
        t, x, y, wall = ross_run(rotor, step, 0.0, 0.0)
        every = round(STEPS[0] / step)
        got = np.column_stack([x[::every], y[::every]])[: grid.size]
        errors.append(np.max(np.hypot(*(got - ref).T)) / CLEARANCE)
        print(f"   ROSS step {step:g} s: {errors[-1]:.3g} clearances, {wall:.1f} s")
    for k in range(len(STEPS) - 1):
        order = math.log(errors[k] / errors[k + 1]) / math.log(STEPS[k] / STEPS[k + 1])
        print(f"   observed order {STEPS[k]:g} -> {STEPS[k + 1]:g} s: {order:.2f}")
    mine = simulate(spring, grid, method="radau", rtol=1e-6, atol=1e-10)
    error = np.max(np.hypot(*(mine.states[:, [ix, iy]] - ref).T)) / CLEARANCE
    print(f"   rubcli radau rtol 1e-6: {error:.2g} clearances, {mine.wall_time_s:.1f} s")
    reduction()
    analytic()


if __name__ == "__main__":
    main()

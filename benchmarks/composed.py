"""The composed machine's one system (rubcli.system, docs/composed-machine.md): what the
generic path costs on the paper's machine against the rotor's own hand-written
``dop853-jit`` (ratio in one run), a two-station machine, and error against run time on
the shipped matrices case (cases/machines/two-seals.toml: a 24-coordinate beam rotor
rubbing at two seals).

Run from the repository root:

    python benchmarks/composed.py      # about 3 minutes on 2 cores

Each timing is the best of 3 after a warm-up (the compile or the cache load). Errors are
the largest position error over the run's samples against a reference (radau at rtol
1e-12 for the beam, the rotor's dop853-jit at rtol 1e-13 for the paper's machine), in
clearances of the station. Writes benchmarks/composed.md.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from machine import describe

from rubcli.case.rotor import load_rotor_case
from rubcli.machine import (
    ContactLaw,
    Machine,
    Speed,
    Station,
    Structure,
    Unbalance,
    jeffcott_machine,
)
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.system import simulate

REPEATS = 3
ROOT = Path(__file__).resolve().parents[1]
FIG3 = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.03, Rp=46.16)
START = (0.88544, -0.8039, 0.0, 0.0)


def best(fn):
    fn()
    runs = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        result = fn()
        runs.append(time.perf_counter() - start)
    return min(runs), result


def paper_rows() -> list[str]:
    problem = Problem.from_periods(FIG3, START, 100, 20)
    reference = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-15)
    machine = jeffcott_machine(FIG3)
    rows = []
    for rtol in (1e-6, 1e-9):
        options = {"rtol": rtol, "atol": rtol / 100}
        t_old, old = best(lambda o=options: solve(problem, "dop853-jit", **o))
        t_new, new = best(lambda o=options: simulate(machine, problem.t_eval, initial=START, **o))
        e_old = np.max(np.abs(old.states[:, :2] - reference.states[:, :2]))
        e_new = np.max(np.abs(new.states[:, :2] - reference.states[:, :2]))
        rows.append(
            f"| {rtol:g} | {1e3 * t_old:.1f} ms ({e_old:.1e}) | {1e3 * t_new:.1f} ms "
            f"({e_new:.1e}) | {t_new / t_old:.2f} | {new.stats['steps']} / {old.stats['nsteps']} |"
        )
    return rows


def pair_rows() -> list[str]:
    p = ModelParams(nu=0.05, eta=1.0, e=0.15, K=20.0, mu=0.1, Rp=2.0)
    M = np.kron([[0.8, 0.2], [0.2, 0.8]], np.eye(2))
    K = np.kron([[1.3, -0.3], [-0.3, 1.3]], np.eye(2))
    stations = tuple(Station((2 * i, 2 * i + 1), 1.0, ContactLaw(p.K), p.mu, p.Rp) for i in (0, 1))
    pair = Machine(
        Structure(M=M, K=K, C=2 * p.nu * np.eye(4)), stations, Speed.constant(p.eta),
        tuple(Unbalance((2 * i, 2 * i + 1), p.e) for i in (0, 1)),
    )  # fmt: skip
    t = np.linspace(0.0, 100 * 2 * np.pi / p.eta, 2001)
    rows = []
    for label, machine in (("one station", jeffcott_machine(p)), ("two stations", pair)):
        seconds, run = best(lambda m=machine: simulate(m, t, rtol=1e-9, atol=1e-11))
        rows.append(
            f"| {label} | {machine.size} | {1e3 * seconds:.1f} ms | {run.stats['steps']} | "
            f"{len(run.events)} |"
        )
    return rows


def beam_rows() -> list[str]:
    case = load_rotor_case(ROOT / "cases" / "machines" / "two-seals.toml")
    reference = simulate(case.machine, case.t_eval, method="radau", rtol=1e-12, atol=1e-16)
    clearance = min(s.clearance for s in case.machine.stations)
    rows = []
    for method, rtols in (("dop853-jit", (1e-5, 1e-7, 1e-9)), ("radau", (1e-5, 1e-7)),
                          ("bdf", (1e-5,)), ("lsoda", (1e-5, 1e-7))):  # fmt: skip
        for rtol in rtols:
            seconds, run = best(
                lambda m=method, r=rtol: simulate(
                    case.machine, case.t_eval, method=m, rtol=r, atol=r * 1e-5
                )
            )
            n = case.machine.size
            error = np.max(np.abs(run.states[:, :n] - reference.states[:, :n])) / clearance
            rows.append(
                f"| `{method}` | {rtol:g} | {seconds:.2f} s | {error:.1e} | "
                f"{run.stats['steps']} | {run.stats['nfev']} |"
            )
    return rows


def main() -> None:
    out = [
        "# The composed machine's system",
        "",
        f"`python benchmarks/composed.py`; {describe()}.",
        "",
        "## The paper's machine: the generic path against the rotor's own dop853-jit",
        "",
        "Figure 3's case at mu = 0.03, 100 forcing periods at 20 samples a period; the "
        "largest position error against the rotor's dop853-jit at rtol 1e-13 in brackets.",
        "",
        "| rtol | rotor's dop853-jit | generic dop853-jit | generic / rotor's "
        "| steps (generic / rotor's) |",
        "|---|---|---|---:|---|",
        *paper_rows(),
        "",
        "## One station and two",
        "",
        "The Jeffcott rotor and two rotors coupled through M and K with a station each "
        "(tests/test_composed_machine.py), 100 forcing periods, dop853-jit at rtol 1e-9.",
        "",
        "| machine | coordinates | time | steps | events |",
        "|---|---:|---:|---:|---:|",
        *pair_rows(),
        "",
        "## A matrices case: the 24-coordinate beam rotor at two seals",
        "",
        "cases/machines/two-seals.toml over its [time] span; error: the largest position "
        "error over the samples against radau at rtol 1e-12, "
        "in clearances of the tighter seal (15 um); atol = rtol x 1e-5 m.",
        "",
        "| method | rtol | time | error (clearances) | steps | evaluations |",
        "|---|---:|---:|---:|---:|---:|",
        *beam_rows(),
        "",
    ]
    text = "\n".join(out)
    (ROOT / "benchmarks" / "composed.md").write_text(text)
    sys.stdout.write(text)


if __name__ == "__main__":
    main()

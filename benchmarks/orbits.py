"""Cost of periodic orbits: the monodromy matrix by variational equations against central
differences, and the two shipped continuation cases.

Run from the repository root:

    python benchmarks/orbits.py            # ~30 s on a shared 2-core machine, cache warm
    python benchmarks/orbits.py --repeats 1

1. **Monodromy matrix** of one forcing period, two ways, in one process: the variational
   equations integrated with the trajectory (the variational mode of
   ``rubcli.solvers.variational``: 6 + 16 equations in ``dop853-jit``'s compiled loop,
   saltation matrices at the switches; ``rubcli.analysis.orbits.periodic.stroboscopic_map``)
   against central differences of the map (8 plain integrations of 6 equations), at the
   same tolerances (1e-12). Cases: the paper's
   synchronous rub (mu = 0.02, no switch) and a transient with contact entry, exit and a
   slip reversal. Times are the best of ``--repeats``; the table gives the ratio and the
   largest difference between the two matrices relative to the largest entry.
2. **Branches**: ``continue_branch`` on ``cases/paper/fig3-orbits.toml``,
   ``cases/examples/run-up-orbits.toml`` and ``cases/machines/snubber.toml`` (a stator
   with its own mass: eight multipliers; their full [orbits] settings, the start's
   transient excluded): points, map evaluations, wall time, time per point, the located
   bifurcations.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from rubcli import model
from rubcli.analysis.orbits import continuation as cn
from rubcli.analysis.orbits import periodic as ob
from rubcli.case import load_case
from rubcli.model import ModelParams
from rubcli.studies.orbits import settings_from_case, start_guess

ROOT = Path(__file__).resolve().parents[1]


def _best(fn, repeats: int):
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _fd(params, s0, h=1e-6):
    fd = np.zeros((4, 4))
    for j in range(4):
        sp = np.array(s0, dtype=float)
        sm = sp.copy()
        sp[j] += h
        sm[j] -= h
        fd[:, j] = (
            ob.stroboscopic_map(params, sp, variational=False).state
            - ob.stroboscopic_map(params, sm, variational=False).state
        ) / (2 * h)
    return fd


def monodromy_table(repeats: int) -> list[str]:
    paper = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.02, Rp=46.16)
    cases = [
        ("paper's synchronous rub, mu = 0.02", paper,
         model.synchronous_rub(np.array([0.0]), paper)[:, 0]),
        ("contact entry/exit + slip reversal",
         ModelParams(nu=0.02, eta=0.8716, e=0.3, K=17.6, mu=0.1, Rp=0.2),
         np.array([1.05, 0.0, 0.0, -0.2318])),
    ]  # fmt: skip
    lines = [
        "| case | events | variational (ms) | central differences (ms) | ratio "
        "| max diff / max entry |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, params, s0 in cases:
        t_var, fl = _best(lambda p=params, s=s0: ob.stroboscopic_map(p, s), repeats)
        t_fd, fd = _best(lambda p=params, s=s0: _fd(p, s), repeats)
        diff = np.max(np.abs(fl.monodromy - fd)) / np.max(np.abs(fd))
        lines.append(
            f"| {name} | {len(fl.events)} | {1e3 * t_var:.2f} | {1e3 * t_fd:.2f} | "
            f"{t_fd / t_var:.2f} | "
            f"{diff:.1e} |"
        )
    return lines


def _counting(original, calls: list[int]):
    def counted(*args, **kw):
        calls[0] += 1
        return original(*args, **kw)

    return counted


def branch_table() -> list[str]:
    lines = [
        "| case | points | map evaluations | wall time (s) | ms per point | bifurcations |",
        "|---|---:|---:|---:|---:|---|",
    ]
    for rel in ("cases/paper/fig3-orbits.toml", "cases/examples/run-up-orbits.toml",
                "cases/machines/snubber.toml"):  # fmt: skip
        case = load_case(ROOT / rel)
        settings = settings_from_case(case)
        guess = start_guess(case, case.settings.orbits)
        calls = [0]
        original = ob.stroboscopic_map
        cn.ob.stroboscopic_map = _counting(original, calls)
        try:
            t0 = time.perf_counter()
            branch = cn.continue_branch(case.params, guess, settings)
            wall = time.perf_counter() - t0
        finally:
            cn.ob.stroboscopic_map = original
        bifs = ", ".join(f"{b.kind} {b.parameter:.8g}" for b in branch.bifurcations)
        n = len(branch.points)
        lines.append(f"| `{rel}` | {n} | {calls[0]} | {wall:.2f} | {1e3 * wall / n:.1f} | {bifs} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print("## Monodromy matrix of one forcing period\n")
    print("\n".join(monodromy_table(args.repeats)))
    print("\n## Continuation of the shipped cases\n")
    print("\n".join(branch_table()))


if __name__ == "__main__":
    main()

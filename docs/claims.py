"""Regenerate the numbers that docs/ states about the paper's machine, claim by claim.

    python docs/claims.py                 # every claim below
    python docs/claims.py ns-torus        # one (names: python docs/claims.py --list)

Each claim is a function that solves what it needs (dop853-jit, as the sweep does) and
prints the numbers the docs quote; the docs name the claim next to the sentence. Claims
that a command regenerates whole are named with that command instead:
``rubcli ensemble cases/paper/fig3-ensemble.toml`` (the mu = 0.04 statistics),
``rubcli compare cases/paper/fig3.toml`` (the Figure 3 table), ``rubcli sweep
cases/paper/fig3-mu-sweep.toml`` (the friction sweep), ``rubcli orbits
cases/paper/fig3-whirls.toml`` (the whirls). Run from the repository root.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from rubcli import model
from rubcli.analysis.orbits.synchronous import synchronous_rubs
from rubcli.analysis.response import classification as rsp
from rubcli.analysis.response.spectrum import full_spectrum
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16}
START = (0.88544, -0.8039, 0.0, 0.0)
NEIMARK_SACKER_MU = 0.0102872304102  # docs/orbits.md, located by rubcli orbits
SPP = 16


def _params(mu: float) -> ModelParams:
    return ModelParams(mu=mu, **FIG3)


def _run(params, start, periods, spp=SPP):
    sol = solve(Problem.from_periods(params, tuple(start), periods, spp), "dop853-jit",
                rtol=1e-8, atol=1e-10)  # fmt: skip
    if not sol.success:
        raise RuntimeError(sol.message)
    return sol


def _lines(sol, params, periods: int, count: int = 4, spp: int = SPP) -> str:
    """The strongest lines of the full spectrum over the last ``periods``."""
    k = -periods * spp - 1
    spec = full_spectrum(sol.t[k:-1], sol.w[k:-1], params.eta)
    amp = spec.amplitude
    peaks = [i for i in range(1, amp.size - 1) if amp[i] >= amp[i - 1] and amp[i] >= amp[i + 1]]
    peaks = sorted(peaks, key=lambda i: -amp[i])[:count]
    return ", ".join(f"{spec.order[i]:+.2f}X ({amp[i]:.3f})" for i in peaks)


def _end(sol, params, periods: int, spp: int = SPP) -> str:
    window = slice(-periods * spp, None)
    contact = float(np.mean(sol.regimes[window] != model.FREE))
    response = rsp.classify_solution(
        sol, transient_periods=sol.problem.periods - periods, lyapunov_periods=200,
        lyapunov_method="dop853-jit",
    )  # fmt: skip
    rot = response.evidence()["rotation_number"]
    return (f"contact {contact:.3f}, z {sol.z[window].min():.3f} ... {sol.z[window].max():.3f}, "
            f"{response.label}, section turns {rot:+.5f} per period")  # fmt: skip


def ns_torus() -> None:
    """docs/orbits.md: what grows out of the rub past the Neimark-Sacker point."""
    p = _params(NEIMARK_SACKER_MU)
    (rub,) = synchronous_rubs(p)
    lam = rub.eigenvalues[np.argmax(np.abs(rub.eigenvalues.imag) > 3)]
    print(f"  at the Neimark-Sacker point: rotating-frame pair +-{abs(lam.imag):.4f} i, "
          f"{abs(lam.imag) / p.eta:.3f} orders: lines +{1 + abs(lam.imag) / p.eta:.2f}X and "
          f"{1 - abs(lam.imag) / p.eta:.2f}X; section turns "
          f"{(abs(lam.imag) * p.period / (2 * math.pi)) % 1:.5f} per period")  # fmt: skip
    for mu, periods in ((0.0104, 12000), (0.011, 4000), (0.014, 4000), (0.0195, 4000),
                        (0.02, 4000), (0.03, 4000)):  # fmt: skip
        p = _params(mu)
        start = model.synchronous_rub(np.array([0.0]), p)[:, 0] * 1.01  # 1 % off the rub
        sol = _run(p, start, periods)
        print(
            f"  mu = {mu}: from 1 % off the rub, after {periods} periods: "
            f"{_end(sol, p, 500)}; lines {_lines(sol, p, 500)}"
        )


def sweep_rub_extent() -> None:
    """docs/sweeps.md: the run-up in mu of cases/paper/fig3-mu-sweep.toml, 0 ... 0.013."""
    from rubcli.analysis.sweep.point import PointTask, compute_point

    state = START
    for mu in np.round(np.arange(0.0, 0.0131, 0.0005), 6):
        task = PointTask(_params(float(mu)), state, 200, 100, 32, "dop853-jit",
                         {"rtol": 1e-8, "atol": 1e-10}, energy=False, lyapunov=True)  # fmt: skip
        result = compute_point(task)
        label = rsp.KINDS[int(result.scalars["response_class"])]
        rate = result.scalars["contraction_rate"]
        print(
            f"  mu = {mu:.4f}: {label:15s} period {result.scalars['response_period']:.0f}, "
            f"contraction {rate:.6f}, contact {result.scalars['contact_fraction']:.3f}"
        )
        state = result.final_state


def dry_whip() -> None:
    """docs/reproduction.md: mu = 0.05 ends rolling backward at -Rp eta / r."""
    p = _params(0.05)
    sol = _run(p, START, 300, 32)
    window = slice(-100 * 32, None)
    stick = float(np.mean(sol.regimes[window] == model.STICK))
    r = float(np.mean(sol.z[window]))
    theta = np.unwrap(np.angle(sol.w[window]))
    rate = float(np.polyfit(sol.t[window], theta, 1)[0])
    print(
        f"  mu = 0.05, last 100 of 300 periods: stick {stick:.3f}, mean r {r:.3f}, whirl "
        f"{rate:.4f} per tau ({rate / p.eta:.3f}X) against -Rp eta / r = "
        f"{-p.Rp * p.eta / r:.4f}; lines {_lines(sol, p, 100, 2, 32)}"
    )


def whip_onset() -> None:
    """docs/sweeps.md and cases/paper/fig3-basins.toml: when starts at rest fall into dry
    whip at mu = 0.04 (z above 5), over 1500 periods."""
    p = _params(0.04)
    for start in ((0.0, 0.0), (0.5, 0.5), (-1.0, 1.0), (0.3, -0.7)):
        sol = _run(p, (*start, 0.0, 0.0), 1500, 1)
        whip = np.flatnonzero(sol.z > 5)
        tail = sol.z[-100:]
        when = f"period {whip[0]}" if whip.size else "never in 1500 periods"
        print(f"  start {start}: first z > 5 at {when}; last 100 periods z "
              f"{tail.min():.2f} ... {tail.max():.2f}")  # fmt: skip


CLAIMS = {"ns-torus": ns_torus, "sweep-rub-extent": sweep_rub_extent, "dry-whip": dry_whip,
          "whip-onset": whip_onset}  # fmt: skip


def main(argv: list[str]) -> int:
    if argv[:1] == ["--list"]:
        print("\n".join(CLAIMS))
        return 0
    unknown = [a for a in argv if a not in CLAIMS]
    if unknown:
        print(f"unknown claim(s) {', '.join(unknown)}; known: {', '.join(CLAIMS)}")
        return 2
    for name in argv or list(CLAIMS):
        started = time.perf_counter()
        print(f"{name}: {CLAIMS[name].__doc__.strip()}")
        CLAIMS[name]()
        print(f"  ({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""Example figures of docs/transient.md: a linear run-up through the critical speed with
a rub near it, analysed by ``rubcli.analysis.order_tracking`` and drawn by
``rubcli.plotting.transient``.

The run is a *demonstration* integration, not a rubcli solver: scipy's DOP853 on the
model's equations (``model.contact_force``) with the speed ramp's unbalance force
``e (p'^2 - i p'') exp(i p)`` and the friction sign smoothed as ``tanh(v_r / 1e-3)`` (no
stick). It stands in for the transient solver until that exists.

    .venv/bin/python docs/transient_example.py [--all] [output directory, default docs/images]

writes transient-bode.png and transient-cascade.png (docs/transient.md shows these two),
with ``--all`` also transient-polar.png and transient-orbits.png.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from rubcli import model
from rubcli.analysis.order_tracking import analyse_transient, order_cascade
from rubcli.io import save_figure
from rubcli.plotting.transient import (
    bode_figure,
    cascade_figure,
    orbit_snapshots_figure,
    polar_figure,
)

PARAMS = model.ModelParams(nu=0.05, eta=1.0, e=0.12, K=5.0, mu=0.1, Rp=5.0)
ETA0, ETA1, RATE = 0.3, 2.0, 1.5e-3  # eta(tau) = ETA0 + RATE tau up to ETA1
DT = 0.02  # sampling step in tau (157 samples per revolution at ETA1)
SLIP_SMOOTHING = 1e-3


def run_up() -> tuple[np.ndarray, ...]:
    """(tau, x, y, phase, eta, regimes) of the demonstration run-up."""
    p = PARAMS
    duration = (ETA1 - ETA0) / RATE

    def rhs(tau, s):
        x, y, vx, vy = s
        eta, phase = ETA0 + RATE * tau, ETA0 * tau + 0.5 * RATE * tau * tau
        spin = model.slip_velocity(float(x), float(y), float(vx), float(vy), p.Rp, eta)
        fx, fy = model.contact_force(x, y, p.K, p.mu * math.tanh(spin / SLIP_SMOOTHING))
        force = p.e * (eta * eta - 1j * RATE) * complex(math.cos(phase), math.sin(phase))
        ax = force.real + fx - 2.0 * p.nu * vx - x
        ay = force.imag + fy - 2.0 * p.nu * vy - y
        return (vx, vy, ax, ay)

    tau = np.arange(0.0, duration, DT)
    start = model.free_steady_state(0.0, model.ModelParams(p.nu, ETA0, p.e, p.K))
    s0 = (start[0].real, start[0].imag, start[1].real, start[1].imag)
    sol = solve_ivp(rhs, (0.0, tau[-1]), s0, method="DOP853", t_eval=tau, rtol=1e-9,
                    atol=1e-11, max_step=0.1)  # fmt: skip
    x, y, vx, vy = sol.y
    eta = ETA0 + RATE * tau
    phase = ETA0 * tau + 0.5 * RATE * tau * tau
    spin = p.Rp * eta + (x * vy - y * vx) / np.hypot(x, y)
    regimes = np.where(np.hypot(x, y) > 1.0, np.where(spin > 0, 1, -1), 0)
    return tau, x, y, phase, eta, regimes


def main(out: Path, everything: bool = False) -> None:
    tau, x, y, phase, eta, regimes = run_up()
    revolutions, events, summary = analyse_transient(tau, x, y, phase, eta, regimes)
    cascade = order_cascade(tau, x, y, phase)
    title = "demonstration run-up (eta 0.3 to 2, rate 1.5e-3)"
    out.mkdir(parents=True, exist_ok=True)
    save_figure(bode_figure(revolutions, events, title=title), out / "transient-bode.png")
    save_figure(cascade_figure(cascade, params=PARAMS, title=title),
                out / "transient-cascade.png")  # fmt: skip
    if everything:
        save_figure(polar_figure(revolutions, title=title), out / "transient-polar.png")
        save_figure(orbit_snapshots_figure(tau, x, y, revolutions, title=title),
                    out / "transient-orbits.png")  # fmt: skip
    print(summary.to_dict())


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--all"]
    main(Path(args[0]) if args else Path(__file__).parent / "images", "--all" in sys.argv)

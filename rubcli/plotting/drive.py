"""drive.png: a driven rotor's run against time (``drive_figure``).

Three panels on one time axis: the speed (with the linear critical speed and the speed the
motor holds unloaded marked), the torques on the spin averaged over each revolution (the
motor's less drag, the rub's, and the unbalance's reaction, which add up to the
inertia's ``j p''``), and the largest radius of each revolution against the clearance,
the revolutions with contact shaded. A drive captured at a resonance shows as a speed
that stops rising while the motor's torque is taken by the rub and the vibration.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from rubcli.analysis.energy.drive_torques import DriveTorques
from rubcli.plotting.run import _new_figure
from rubcli.plotting.transient import RUB_SHADE, SpeedAxis

TORQUE_STYLES = {  # the net first, thick and light: the motor's line lies on it at no load
    "inertia": {"color": "0.6", "lw": 4.0, "alpha": 0.5, "label": "net: j p'' (acceleration)"},
    "motor": {"color": "tab:green", "lw": 1.6, "label": "motor less drag"},
    "rub": {"color": "tab:red", "lw": 1.5, "label": "rub (friction's moment)"},
    "vibration": {
        "color": "tab:purple",
        "lw": 1.2,
        "ls": "--",
        "label": "unbalance reaction (vibration)",
    },  # fmt: skip
}


def drive_figure(
    torques: DriveTorques,
    *,
    speed: SpeedAxis,
    free_speed: float | None,
    title: str = "",
    time_factor: float = 1.0,
    time_label: str = "time tau = omega t (-)",
    torque_factor: float = 1.0,
    torque_label: str = "torque / (k_r gamma^2) (-)",
) -> Figure:
    """drive.png (module docstring). ``time_factor`` and ``torque_factor`` convert tau
    and the nondimensional torques to the labelled units (seconds, N m)."""
    fig = _new_figure(11.0, 9.0)
    ax_speed, ax_torque, ax_radius = fig.subplots(3, 1, sharex=True)
    t = torques.tau * time_factor
    ax_speed.plot(torques.tau_samples * time_factor, speed(torques.speed_samples),
                  color="tab:blue", lw=1.4, label="speed")  # fmt: skip
    ax_speed.axhline(float(speed(1.0)), color="0.4", ls="--", lw=1.0,
                     label=f"linear critical speed ({speed.text(1.0)})")  # fmt: skip
    if free_speed is not None:
        label = f"motor unloaded, against its drag ({speed.text(free_speed)})"
        ax_speed.axhline(float(speed(free_speed)), color="tab:green", ls=":", lw=1.2, label=label)
    ax_speed.set_ylabel(speed.label)
    ax_speed.set_ylim(bottom=0.0)
    ax_speed.legend(loc="best", fontsize="small")
    ax_speed.set_title("speed", fontsize="medium")
    for name, style in TORQUE_STYLES.items():
        ax_torque.plot(t, getattr(torques, name) * torque_factor, **style)
    ax_torque.axhline(0.0, color="0.7", lw=0.8)
    ax_torque.set_ylabel(torque_label)
    ax_torque.legend(loc="best", fontsize="small", ncols=2)
    ax_torque.set_title("torques on the spin, mean of each revolution", fontsize="medium")
    ax_radius.plot(t, torques.radius, color="tab:blue", lw=1.4, label="largest radius z")
    ax_radius.axhline(1.0, color="k", lw=1.0, label="clearance")
    for a, b in _spans(torques.contact > 0.0):
        ax_radius.axvspan(t[a], t[b], **RUB_SHADE)
    ax_radius.set_ylim(bottom=0.0)
    ax_radius.set_ylabel("radius (clearances)")
    ax_radius.set_xlabel(time_label)
    ax_radius.legend(loc="best", fontsize="small")
    ax_radius.set_title("largest radius of each revolution (shaded: with contact)",
                        fontsize="medium")  # fmt: skip
    for ax in (ax_speed, ax_torque, ax_radius):
        ax.grid(True, alpha=0.3)
    ax_radius.set_xlim(float(torques.tau_samples[0] * time_factor),
                       float(torques.tau_samples[-1] * time_factor))  # fmt: skip
    fig.suptitle(f"{title}\nthe drive: speed, torques and response against time",
                 fontsize="medium")  # fmt: skip
    return fig


def _spans(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(int), [0]))))
    return [(int(a), int(b - 1)) for a, b in zip(edges[::2], edges[1::2], strict=True)]

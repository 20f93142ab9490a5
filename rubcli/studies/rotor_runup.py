"""The run-up products of a rotor case whose speed changes (``[speed]`` on a matrices or
ROSS case), in SI and rpm: what an engineer reads from a run-up or a coast-down.

Over the part of the run in which the speed changes (a speed held after a ramp is in
time.png):

- **Order tracking per revolution** (``analysis.response.order_tracking``, on the spin
  angle ``integral Omega``): each probe's 1X amplitude and phase lag, the lag by which
  its 1X peak follows the instant the first unbalance points at the probe (the probe
  convention of the Jeffcott rotor's run-up), and its peak to peak; each station's
  largest distance from its stator's centre (in clearances) and share in contact.
- **The linear response** of the same machine without contact, the steady unbalance
  response at each speed (``machine.linear.steady_response``, bearings at that speed):
  drawn under the tracked 1X, so the rub's effect and the critical speeds show; the
  critical speed of each probe is the peak of its linear 1X amplitude.
- **The full-spectrum cascade** of each probe's node (``x + i y``, resampled in the spin
  angle), with the machine's lowest natural frequencies as orders of the speed.

``bode.png``, ``polar.png``, ``cascade.png`` (``plotting.rotor_runup``) and report.json's
``runup`` entry.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rubcli import io
from rubcli.analysis.response import order_tracking as ot
from rubcli.analysis.response.rotor_tracking import ProbeTrack, RotorRunup, StationTrack
from rubcli.case.rotor import RotorCase
from rubcli.machine.linear import eigenvalues, steady_response
from rubcli.system import MachineSolution

FIGURES = ("bode.png", "polar.png", "cascade.png")
LINEAR_SPEEDS = 400  # the linear response's speeds across the run's range
MODE_SPEEDS = 24  # the natural frequencies' speeds across it
MODES_DRAWN = 4  # the lowest natural frequencies drawn in the cascade
MAX_DAMPING_RATIO = 0.3  # ... of the modes damped less (the heavily damped ones cannot ring)
RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)


def unbalance_phase(case: RotorCase) -> float:
    """The phase the probes' lag is measured from: the first unbalance's (as ROSS's)."""
    return case.machine.unbalances[0].phase if case.machine.unbalances else 0.0


def reference_phase(case: RotorCase, solution: MachineSolution) -> np.ndarray:
    """The angle the probes' lag is measured from at each sample: the spin angle plus the
    first unbalance's phase (the instant it points along x)."""
    return case.machine.speed.at(solution.t)[1] + unbalance_phase(case)


def track(
    case: RotorCase,
    solution: MachineSolution,
    readings: list[np.ndarray],
    orbits: list[np.ndarray],
) -> RotorRunup | str:
    """The run-up's tracking (module docstring) from each probe's reading and each
    station's orbit about its stator's centre at the samples (m), or why there is none (a
    run that did not reach a whole revolution, or too few samples in one)."""
    if solution.t.size < 2 or not np.all(np.isfinite(solution.states)):
        return "the run has no whole revolution to track"
    # the samples while the speed changes: a speed held after the ramp would draw its
    # revolutions on one abscissa (that part is in time.png)
    times, values = case.machine.speed.times, case.machine.speed.values
    moving = [k for k in range(len(values) - 1) if values[k + 1] != values[k]]
    if not moving:
        return "the speed does not change"
    t = solution.t
    part = (t >= times[moving[0]]) & (t <= times[moving[-1] + 1])
    t = t[part]
    omega, _ = case.machine.speed.at(t)
    phase = reference_phase(case, solution)[part]
    rpm = omega * RPM_PER_RAD_S
    zeros = np.zeros(t.size)
    try:
        revolutions = []
        for reading in readings:
            revolutions.append(ot.order_track(t, reading[part], zeros, phase, rpm))
        station_revs = []
        for s in range(len(case.station_names)):
            d = orbits[s][part] / case.machine.stations[s].clearance
            regimes = solution.regimes[part, s]
            station_revs.append(
                (ot.order_track(t, d[:, 0], d[:, 1], phase, rpm, regimes),
                 ot.rub_events(t, d[:, 0], d[:, 1], rpm, regimes))
            )  # fmt: skip
    except ValueError as exc:
        return str(exc)
    first = revolutions[0]
    low, high = float(np.min(omega)), float(np.max(omega))
    linear_w = np.linspace(low, high, LINEAR_SPEEDS)
    # the linear amplitudes relative to the reference phase (the first unbalance's)
    turn = np.exp(-1j * unbalance_phase(case))
    responses = [turn * steady_response(case.machine, float(w))[1] for w in linear_w]
    probes = []
    for probe, rev in zip(case.probes, revolutions, strict=True):
        ix, iy = case.lateral(probe.node)
        reading = np.array([r[ix] * np.cos(probe.angle) + r[iy] * np.sin(probe.angle)
                            for r in responses])  # fmt: skip
        # Re(R e^{i p}) = a cos p + b sin p with a = Re R, b = -Im R
        lag = ot.probe_lag_deg(reading.real, -reading.imag, math.degrees(probe.angle))
        probes.append(
            ProbeTrack(
                name=probe.name,
                node=probe.node,
                angle=probe.angle,
                amplitude=rev.x_amplitude,
                lag_deg=np.mod(rev.x_lag_deg - math.degrees(probe.angle) + 90.0, 360.0) - 90.0,
                peak_to_peak=rev.x_peak_to_peak,
                linear_amplitude=np.abs(reading),
                linear_lag_deg=lag,
            )
        )
    stations = tuple(
        StationTrack(name, case.station_nodes[s][0], rev.z_max, rev.contact_fraction,
                     events.onset_eta, events.end_eta)
        for s, (name, (rev, events)) in enumerate(zip(case.station_names, station_revs,
                                                      strict=True))
    )  # fmt: skip
    cascades = []
    for node in dict.fromkeys(p.node for p in case.probes):
        names = ", ".join(p.name for p in case.probes if p.node == node)
        ix, iy = case.lateral(node)
        try:
            cascade = ot.order_cascade(
                t, solution.states[part, ix], solution.states[part, iy], phase
            )
        except ValueError:
            continue  # fewer revolutions than a window: the figure says so
        cascades.append((f"node {node} ({names})", cascade))
    mode_w = np.linspace(low, high, MODE_SPEEDS)
    mode_hz = np.array([_lowest_frequencies(case, float(w)) for w in mode_w])
    return RotorRunup(
        t=first.tau,
        rpm=first.eta,
        probes=tuple(probes),
        stations=stations,
        linear_rpm=linear_w * RPM_PER_RAD_S,
        cascades=tuple(cascades),
        mode_rpm=mode_w * RPM_PER_RAD_S,
        mode_hz=mode_hz,
    )


def _lowest_frequencies(case: RotorCase, omega: float) -> np.ndarray:
    """The ``MODES_DRAWN`` lowest damped natural frequencies (Hz) at ``omega`` of the
    modes that can resonate (damping ratio below ``MAX_DAMPING_RATIO``)."""
    values = eigenvalues(case.machine.structure, omega)
    light = (values.imag > 0.0) & (-values.real < MAX_DAMPING_RATIO * np.abs(values))
    hz = values.imag[light] / (2.0 * math.pi)
    out = np.full(MODES_DRAWN, np.nan)
    out[: min(MODES_DRAWN, hz.size)] = hz[:MODES_DRAWN]
    return out


def write_runup(case: RotorCase, runup: RotorRunup, method: str, staged: Any) -> None:
    """bode.png, polar.png and cascade.png of ``runup`` into ``staged`` (an
    ``io.StagedOutput``)."""
    from rubcli.plotting import rotor_runup as figures

    title = f"{case.name} ({method}, {case.speed_text})"
    io.save_figure(figures.bode_figure(title, runup), staged.path("bode.png"))
    io.save_figure(figures.polar_figure(title, runup), staged.path("polar.png"))
    io.save_figure(figures.cascade_figure(title, runup), staged.path("cascade.png"))

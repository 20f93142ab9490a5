"""``rubcli run`` on a machine given as matrices (``rubcli.case.rotor``), in SI.

Each method of the case runs the composed machine's system (``rubcli.system.simulate``);
then, into the output dir as one commit:

- ``<method>.csv``: the time ``t_s`` (s); in a run-up the speed ``speed_rpm``; every
  station's node (and its stator's, when it is a node of the structure) and every
  probe's as ``x_<node>``, ``y_<node>`` (m); per
  station ``<name>_penetration_m`` (``z - clearance``, negative when free),
  ``<name>_clearances`` (``z`` over the clearance), ``<name>_regime`` (free, slip+,
  slip-, stick), ``<name>_normal_N``, ``<name>_friction_N`` (the tangential force on the
  rotor against the slip, in stick the force that holds it) and ``<name>_slip_m_s``
  (``v_r``); per probe ``<name>_m``, what it reads (``probe_reading``);
- ``orbit.png``: every station's orbit inside its clearance circle and every probe's
  node's orbit (the first method's);
- ``time.png`` (``plots = ["time"]``): each station's distance from its stator's
  centre against time with its clearance, and each probe's reading;
- ``shaft.png`` (``plots = ["shaft"]``, a rotor whose file gives its nodes' positions):
  the shaft with its disks, bearings, stations and probes, and the deflection envelope;
- for a run-up or coast-down (``[speed]``): ``bode.png``, ``polar.png``, ``cascade.png``
  at the probes and stations, and report.json's ``runup`` (``studies.rotor_runup``), of
  the first method;
- ``shape.png`` and ``shapes.csv`` (``[output] shapes``, instants in s): every node's x
  and y deflection at the sample nearest each instant, along the shaft;
- ``report.json``: per method its status, statistics, wall time and energy balance; per
  station its contact share, stick share, deepest penetration, largest forces and events
  by kind; per probe its largest reading and its peak to peak over the last quarter (the
  figure's steady part); every node's largest deflection over the last quarter.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import io
from rubcli.case.rotor import Probe, RotorCase
from rubcli.model import REGIME_NAMES, STICK
from rubcli.system import KIND_NAMES, MachineSolution, simulate
from rubcli.system.series import energy, station_series

STEADY_SHARE = 0.25  # the last quarter of a run: its steady part, as the orbit figure's


def steady_part(samples: int) -> slice:
    """The samples of a run's steady part: its last ``STEADY_SHARE``."""
    return slice(-max(1, int(round(STEADY_SHARE * samples))), None)


ORBIT_FIGURE = "orbit.png"
SHAFT_FIGURE = "shaft.png"
TIME_FIGURE = "time.png"
SHAPE_FIGURE = "shape.png"
SHAPES_CSV = "shapes.csv"


def expected_files(case: RotorCase) -> tuple[str, ...]:
    names = [f"{m}.csv" for m in case.methods] if case.settings.output.csv else []
    if "orbit" in case.settings.output.plots:
        names.append(ORBIT_FIGURE)
    if "shaft" in case.settings.output.plots:
        names.append(SHAFT_FIGURE)
    if "time" in case.settings.output.plots:
        names.append(TIME_FIGURE)
    if case.settings.output.shapes:
        names += [SHAPE_FIGURE, SHAPES_CSV]
    if case.runup:
        from rubcli.studies.rotor_runup import FIGURES

        names += FIGURES
    return (*names, io.REPORT_NAME)


def run_rotor_case(
    case: RotorCase,
    max_wall_time_s: float | None = None,
    on_method: Callable[[str], None] | None = None,
) -> list[MachineSolution]:
    """Every method of the case, one after the other, each within ``[solver]
    max_wall_time_s`` and all within ``max_wall_time_s`` (None: no whole budget)."""
    solver = case.settings.solver
    deadline = None if max_wall_time_s is None else time.perf_counter() + max_wall_time_s
    solutions = []
    for method in case.methods:
        if on_method is not None:
            on_method(method)
        budget = solver.max_wall_time_s
        if deadline is not None:
            left = max(deadline - time.perf_counter(), 1e-3)
            budget = left if budget is None else min(budget, left)
        solutions.append(
            simulate(
                case.machine,
                case.t_eval,
                method=method,
                rtol=solver.rtol,
                atol=solver.atol,
                max_steps=solver.max_steps,
                max_wall_time_s=budget,
            )  # fmt: skip
        )
    return solutions


def relative_orbit(case: RotorCase, solution: MachineSolution, s: int) -> np.ndarray:
    """Station s's rotor point relative to its stator's centre (k, 2), m."""
    station = case.machine.stations[s]
    d = solution.coordinates(station.rotor) - np.array(station.offset)
    if station.stator is not None:
        d = d - solution.coordinates(station.stator)
    return d


def csv_columns(
    case: RotorCase, solution: MachineSolution, values: np.ndarray
) -> tuple[list[str], list]:
    """The CSV's header and columns (module docstring); ``values`` the stations' values
    at the samples (``station_series``)."""
    header, columns = ["t_s"], [solution.t]
    if case.runup:
        header.append("speed_rpm")
        columns.append(case.machine.speed.at(solution.t)[0] * 60.0 / (2.0 * math.pi))
    for node in case.nodes:
        ix, iy = case.lateral(node)
        header += [f"x_{node}", f"y_{node}"]
        columns += [solution.states[:, ix], solution.states[:, iy]]
    for s, name in enumerate(case.station_names):
        station = case.machine.stations[s]
        z = np.hypot(*relative_orbit(case, solution, s).T)
        labels = [REGIME_NAMES[r] for r in solution.regimes[:, s].tolist()]
        header += [f"{name}_{c}" for c in ("penetration_m", "clearances", "regime",
                                           "normal_N", "friction_N", "slip_m_s")]  # fmt: skip
        columns += [values[:, s, 0], z / station.clearance, labels, values[:, s, 2],
                    values[:, s, 3], values[:, s, 1]]  # fmt: skip
    for probe in case.probes:
        header.append(f"{probe.name}_m")
        columns.append(probe_reading(case, solution, probe))
    return header, columns


def probe_reading(case: RotorCase, solution: MachineSolution, probe: Probe) -> np.ndarray:
    """What ``probe`` reads at the samples, ``x cos(angle) + y sin(angle)`` (m), as
    ROSS's Probe."""
    ix, iy = case.lateral(probe.node)
    return solution.states[:, ix] * np.cos(probe.angle) + solution.states[:, iy] * np.sin(
        probe.angle
    )


def deflection_envelope(
    case: RotorCase, solution: MachineSolution
) -> tuple[np.ndarray, np.ndarray]:
    """Each node's largest radial deflection ``hypot(x, y)`` (m) over the run and over
    its last quarter, in the full model's coordinates (a reduction's mapped back)."""
    q = solution.states[:, : case.machine.size]
    if case.reduction is not None:
        q = case.reduction.full_positions(q)
    structure = case.full_machine.structure
    pairs = structure.lateral_pairs()
    radial = np.hypot(q[:, pairs[:, 0]], q[:, pairs[:, 1]])
    steady = radial[steady_part(radial.shape[0])]
    return np.max(radial, axis=0), np.max(steady, axis=0)


def method_entry(case: RotorCase, solution: MachineSolution, values: np.ndarray) -> dict[str, Any]:
    """The report's entry of one method (``values`` as for ``csv_columns``)."""
    E = energy(solution, values[:, :, 0])
    residual = E - E[0] - (solution.work - solution.work[0])
    scale = max(float(np.max(np.abs(E))), float(np.max(np.abs(solution.work))), 1e-300)
    stations = {}
    for s, name in enumerate(case.station_names):
        regimes = solution.regimes[:, s]
        events = solution.events.at_station(s)
        rotor_node, stator_node = case.station_nodes[s]
        stations[name] = {
            "node": rotor_node,
            "stator_node": stator_node,
            "contact_share": float(np.mean(regimes != 0)),
            "stick_share": float(np.mean(regimes == STICK)),
            "max_penetration_m": float(np.max(values[:, s, 0])),
            "max_normal_N": float(np.max(values[:, s, 2])),
            "max_friction_N": float(np.max(np.abs(values[:, s, 3]))),
            "events": dict(Counter(KIND_NAMES[k] for k in events.kind.tolist())),
        }
    steady = steady_part(solution.t.size)
    probes = {}
    for probe in case.probes:
        reading = probe_reading(case, solution, probe)
        probes[probe.name] = {
            "node": probe.node,
            "angle_rad": probe.angle,
            "max_abs_m": float(np.max(np.abs(reading))),
            "peak_to_peak_last_quarter_m": float(np.ptp(reading[steady])),
        }
    _, envelope = deflection_envelope(case, solution)
    return {
        "status": solution.status,
        "message": solution.message,
        "wall_time_s": solution.wall_time_s,
        "stats": solution.stats,
        "samples": int(solution.t.size),
        "energy_residual_J": float(np.max(np.abs(residual))),
        "energy_residual_relative": float(np.max(np.abs(residual)) / scale),
        "stations": stations,
        "probes": probes,
        "deflection": {
            "largest_node_last_quarter": int(np.argmax(envelope)),
            "largest_last_quarter_m": float(np.max(envelope)),
            "envelope_last_quarter_m": [float(r) for r in envelope],  # a node each
        },
    }


def write_rotor_outputs(
    case: RotorCase,
    solutions: list[MachineSolution],
    plan: io.OutputPlan,
    command_line: dict[str, Any],
) -> dict[str, Any]:
    """Writes the case's products (module docstring) as one commit; returns the report."""
    with io.staged_output_dir(case.output_dir, plan) as staged:
        entries = {}
        for solution in solutions:
            values = station_series(solution)
            entries[solution.method] = method_entry(case, solution, values)
            if case.settings.output.csv:
                header, columns = csv_columns(case, solution, values)
                io.write_csv(staged.path(f"{solution.method}.csv"), header, [columns])
        if "orbit" in case.settings.output.plots and solutions:
            _write_orbits(case, solutions[0], staged.path(ORBIT_FIGURE))
        if "shaft" in case.settings.output.plots and solutions:
            _write_shaft(case, solutions[0], staged.path(SHAFT_FIGURE))
        if "time" in case.settings.output.plots and solutions:
            _write_traces(case, solutions[0], staged.path(TIME_FIGURE))
        if case.settings.output.shapes and solutions:
            _write_shapes(case, solutions[0], staged.path(SHAPE_FIGURE), staged.path(SHAPES_CSV))
        runup = None
        if case.runup and solutions:
            from rubcli.studies import rotor_runup

            first = solutions[0]
            readings = [probe_reading(case, first, p) for p in case.probes]
            orbits = [relative_orbit(case, first, s) for s in range(len(case.station_names))]
            tracked = rotor_runup.track(case, first, readings, orbits)
            if isinstance(tracked, str):
                runup = {"of_method": solutions[0].method, "none": tracked}
            else:
                rotor_runup.write_runup(case, tracked, solutions[0].method, staged)
                runup = {"of_method": solutions[0].method, **tracked.to_dict()}
        report = {
            **io.report_envelope("run", command_line, case.to_dict()),
            "machine": machine_summary(case),
            "methods": entries,
            **({"runup": runup} if runup is not None else {}),
            "files": [*staged.names(), io.REPORT_NAME],
        }
        staged.write_report(report)
    return report


def machine_summary(case: RotorCase) -> dict[str, Any]:
    machine = case.machine
    full = case.full_machine.structure
    reduction = case.reduction
    return {
        "coordinates": machine.size,
        "nodes": full.nodes,
        "number_dof": full.dof_per_node,
        "full_coordinates": full.size,
        "reduction": None
        if reduction is None
        else {
            "method": "craig-bampton",
            "kept_coordinates": len(reduction.kept),
            "modes": reduction.modes,
            "static_vectors": reduction.static_vectors,
        },
        "speed_rad_s": machine.speed.values[0] if machine.speed.is_constant else None,
        "speed_knots": {"t_s": list(machine.speed.times), "rad_s": list(machine.speed.values)},
        "bearings_at_speed": None
        if machine.structure.speed_table is None
        else {
            "coordinates": len(machine.structure.speed_table.coordinates),
            "tabulated_speeds": int(machine.structure.speed_table.speeds.size),
        },
        "stations": [
            {"name": name, "law": station.law.text(), "clearance_m": station.clearance}
            for name, station in zip(case.station_names, machine.stations, strict=True)
        ],
    }


def _write_orbits(case: RotorCase, solution: MachineSolution, path: Path) -> None:
    from rubcli.plotting.stations import StationOrbit, station_orbits_figure

    orbits = []
    for s, name in enumerate(case.station_names):
        station = case.machine.stations[s]
        rotor, stator = case.station_nodes[s]
        where = f"node {rotor}" + (f" on node {stator}" if stator is not None else "")
        orbits.append(
            StationOrbit(
                label=f"station {name} ({where}), mu = {station.mu:g}",
                relative=relative_orbit(case, solution, s),
                clearance=station.clearance,
                contact=solution.regimes[:, s] != 0,
            )
        )
    for probe in case.probes:
        ix, iy = case.lateral(probe.node)
        angle = math.degrees(probe.angle)
        orbits.append(
            StationOrbit(
                label=f"{probe.name} (probe at node {probe.node}, {angle:.4g} deg)",
                relative=solution.states[:, [ix, iy]],
                clearance=None,
                contact=None,
                direction=probe.angle,
            )
        )
    angle = case.machine.speed.at(solution.t[[0, -1]])[1]
    revolutions = float(angle[1] - angle[0]) / (2.0 * np.pi)
    title = (
        f"{case.name}: orbits at the contact stations{' and probes' if case.probes else ''} "
        f"({solution.method}, "
        f"{case.speed_text})"
    )
    io.save_figure(station_orbits_figure(title, orbits, solution.t, revolutions), path)


def _write_shaft(case: RotorCase, solution: MachineSolution, path: Path) -> None:
    from rubcli.plotting.shaft import Marked, shaft_figure

    layout = case.layout  # the case refuses "shaft" without one
    stations = [
        Marked(name, node, station.clearance)
        for name, (node, _), station in zip(
            case.station_names, case.station_nodes, case.machine.stations, strict=True
        )
    ]
    probes = [Marked(p.name, p.node) for p in case.probes]
    whole, last = deflection_envelope(case, solution)
    title = f"{case.name}: the shaft and its deflection ({solution.method}, "
    title += f"{case.speed_text}, 0 .. {solution.t[-1]:.3g} s)"
    figure = shaft_figure(title, layout.positions, layout.radii, layout.disks, layout.bearings,
                          stations, probes, whole, last)  # fmt: skip
    io.save_figure(figure, path)


def _write_traces(case: RotorCase, solution: MachineSolution, path: Path) -> None:
    from rubcli.plotting.stations import Trace, traces_figure

    stations = [
        Trace(f"{name} (node {node})", np.hypot(*relative_orbit(case, solution, s).T),
              case.machine.stations[s].clearance, solution.regimes[:, s] != 0)
        for s, (name, (node, _)) in enumerate(zip(case.station_names, case.station_nodes,
                                                   strict=True))
    ]  # fmt: skip
    probes = [
        Trace(f"{p.name} (node {p.node}, {math.degrees(p.angle):.4g} deg)",
              probe_reading(case, solution, p))
        for p in case.probes
    ]  # fmt: skip
    title = (f"{case.name}: time traces ({solution.method}, "
             f"{case.speed_text})")  # fmt: skip
    io.save_figure(traces_figure(title, solution.t, stations, probes), path)


def deflected_shapes(
    case: RotorCase, solution: MachineSolution, times: list[float]
) -> tuple[np.ndarray, np.ndarray]:
    """The samples nearest ``times`` (their times, s) and every node's x and y there
    (instants, nodes, 2; m), in the full model's coordinates (a reduction's mapped back)."""
    index = np.array([int(np.argmin(np.abs(solution.t - t))) for t in times], dtype=np.int64)
    q = solution.states[index, : case.machine.size]
    if case.reduction is not None:
        q = case.reduction.full_positions(q)
    structure = case.full_machine.structure
    pairs = structure.lateral_pairs()
    return solution.t[index], np.stack([q[:, pairs[:, 0]], q[:, pairs[:, 1]]], axis=-1)


def _write_shapes(case: RotorCase, solution: MachineSolution, figure: Path, table: Path) -> None:
    from rubcli.plotting.shaft import Marked, shapes_figure

    layout = case.layout  # the case refuses shapes without one
    times, shapes = deflected_shapes(case, solution, list(case.settings.output.shapes))
    header = ["node", "position_m"]
    columns: list = [np.arange(shapes.shape[1]), layout.positions]
    for k, t in enumerate(times):
        header += [f"x_at_{t:.6g}s_m", f"y_at_{t:.6g}s_m"]
        columns += [shapes[k, :, 0], shapes[k, :, 1]]
    io.write_csv(table, header, [columns])
    stations = [
        Marked(name, node, station.clearance)
        for name, (node, stator), station in zip(
            case.station_names, case.station_nodes, case.machine.stations, strict=True
        )
        if stator is None  # a stator that is a node moves: its wall is not a fixed line
    ]
    offsets = [s.offset for s, (_, stator) in zip(case.machine.stations, case.station_nodes,
                                                  strict=True) if stator is None]  # fmt: skip
    title = f"{case.name}: the deflected shape ({solution.method}, {case.speed_text})"
    io.save_figure(
        shapes_figure(title, layout.positions, list(times), shapes, stations, offsets), figure
    )

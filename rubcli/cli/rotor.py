"""``rubcli run`` and ``rubcli validate`` on a case whose machine is given as matrices
(``[rotor] matrices``, ``rubcli.case.rotor``; ``rubcli.studies.rotor_run`` writes it).

The exit codes are ``run``'s: 0, 1 (a method failed: its failure is in report.json, the
outputs are still written), 2 (invalid input, nothing solved or written), 74, 75.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from rubcli.case import CaseError, read_case_file
from rubcli.cli import console, tables
from rubcli.cli.common import (
    EXIT_INVALID,
    emit,
    machine_readable,
    prepare_output,
    report_stale,
)

if TYPE_CHECKING:
    from rubcli.case.rotor import RotorCase


def rotor_case_or_none(path: Path, json: bool = False) -> RotorCase | None:
    """The matrices case at ``path``, or None if it is another kind of case (its errors
    are then ``load_case``'s); exit 2 naming every problem of a matrices case (with
    ``json``, as ``validate --json`` reports them)."""
    try:
        raw = read_case_file(path)
        if "rotor" not in raw:  # (checked before the composed machine's modules load)
            return None
        from rubcli.case.rotor import assemble_rotor_case

        return assemble_rotor_case(raw, Path(path))
    except CaseError as exc:
        if json:
            from rubcli import io

            envelope = io.report_envelope("validate", {"case_file": str(path)})
            emit({**envelope, "valid": False, "problems": exc.problems}, json)
        else:
            console.error_lines(f"invalid case file {path}", exc.problems)
        raise typer.Exit(EXIT_INVALID) from None


def summary_lines(case: RotorCase) -> list[str]:
    machine = case.machine
    st = case.full_machine.structure
    lines = [
        f"case      {case.name}",
        f"rotor     {case.rotor_file}: {st.size} coordinates, {st.nodes} nodes of "
        f"{st.dof_per_node}; {case.speed_text}",
    ]
    if case.runup:
        table = st.speed_table
        lines.append(
            f"speed     {case.settings.speed.profile}: "
            + ", ".join(
                f"{rpm:g} rpm at {t:g} s"
                for t, rpm in zip(*case.settings.speed.knots_rpm(), strict=True)
            )
            + "; bearings: "
            + (
                "coefficients constant (the rotor's file holds one speed's)"
                if table is None
                else f"{len(table.coordinates)} coordinates' coefficients at the current speed "
                f"(ROSS's interpolant tabulated at {table.speeds.size} speeds)"
            )
        )
    if case.reduction is not None:
        r = case.reduction
        extra = " and the weight's static deflection" if r.static_vectors else ""
        bearings = " and bearings" if st.speed_table is not None else ""
        lines.append(
            f"reduced   {machine.size} coordinates (Craig-Bampton): the {len(r.kept)} of the "
            f"stations, unbalances, probes{bearings}, {r.modes} fixed-interface modes{extra}"
        )
    for name, station, (node, stator) in zip(
        case.station_names, machine.stations, case.station_nodes, strict=True
    ):
        where = f"node {node}" + (f" against node {stator}" if stator is not None else "")
        lines.append(
            f"station   {name}: {where}, clearance {station.clearance:.6g} m, "
            f"{station.law.text()}, mu {station.mu:g}, radius {station.radius:g} m"
        )
    lines += [
        f"time      0 .. {case.t_eval[-1]:.6g} s, {case.t_eval.size} samples",
        f"methods   {', '.join(case.methods)}",
        f"output    {case.output_dir}",
    ]
    return lines


def validate(case: RotorCase, case_file: Path, json: bool) -> None:
    if json:
        from rubcli import io

        envelope = io.report_envelope("validate", {"case_file": str(case_file)}, case.to_dict())
        emit({**envelope, "valid": True, "summary": summary_lines(case)}, json)
        return
    for line in summary_lines(case):
        console.info(line)
    console.success(f"{case_file}: valid")


def run(
    case: RotorCase,
    case_file: Path,
    methods: list[str] | None,
    out: Path | None,
    periods: float | None,
    max_wall_time: float | None,
    force: bool,
    wait: bool,
    json: bool,
) -> None:
    """``rubcli run`` on a matrices case."""
    from rubcli.studies import rotor_run
    from rubcli.system import METHODS

    if periods is not None:
        console.error(f"{case_file}: --periods: a machine given as matrices runs [time] end (s)")
        raise typer.Exit(EXIT_INVALID)
    if methods:
        unknown = [m for m in methods if m not in METHODS]
        if unknown:
            console.error(
                f"--method: {', '.join(map(repr, unknown))} cannot run a machine given as "
                f"matrices; choose from {', '.join(METHODS)}"
            )
            raise typer.Exit(EXIT_INVALID)
        solver = case.settings.solver.model_copy(update={"methods": list(dict.fromkeys(methods))})
        case = _with_settings(case, solver=solver)
    if out is not None:
        output = case.settings.output.model_copy(update={"dir": str(out)})
        case = _with_settings(case, output=output)
    plan = prepare_output(case.output_dir, force, wait, rotor_run.expected_files(case))
    command_line = {"case_file": str(case_file), "methods": methods or None,
                    "out": str(out) if out is not None else None,
                    "max_wall_time": max_wall_time}  # fmt: skip
    with machine_readable(json):
        console.info(
            f"{case.name}: {case.machine.size} coordinates, {len(case.machine.stations)} "
            f"stations, 0 .. {case.t_eval[-1]:.6g} s; methods {', '.join(case.methods)}"
        )
        solutions = rotor_run.run_rotor_case(
            case, max_wall_time, on_method=lambda m: console.info(f"running {m}")
        )
        report = rotor_run.write_rotor_outputs(case, solutions, plan, command_line)
        report_stale(plan)
        _table(case, report)
        console.info(f"wrote {len(report['files'])} files to {case.output_dir}: "
                     f"{', '.join(report['files'])}")  # fmt: skip
    emit(report, json)
    failed = {n: e for n, e in report["methods"].items() if e["status"] != "success"}
    for name, entry in failed.items():
        console.error(f"method {name} {entry['status']}: {entry['message']}")
    if failed:
        raise typer.Exit(1)


def _with_settings(case: RotorCase, **sections: Any) -> RotorCase:
    from dataclasses import replace

    return replace(case, settings=case.settings.model_copy(update=sections))


def _table(case: RotorCase, report: dict[str, Any]) -> None:
    rows = []
    for method, entry in report["methods"].items():
        for name, station in entry["stations"].items():
            rows.append([
                method, entry["status"], f"{entry['wall_time_s']:.3g}", name,
                f"{100 * station['contact_share']:.3g} %", f"{100 * station['stick_share']:.3g} %",
                f"{station['max_penetration_m']:.3g}", f"{station['max_normal_N']:.3g}",
                f"{entry['energy_residual_relative']:.2g}",
            ])  # fmt: skip
    columns = ["method", "status", "time s", "station", "contact", "stick",
               "max penetration m", "max F_N N", "energy residual"]  # fmt: skip
    tables.table(f"{case.name}: results", columns, rows)


def compare(
    case: RotorCase,
    case_file: Path,
    out: Path | None,
    max_wall_time: float | None,
    force: bool,
    wait: bool,
    json: bool,
) -> None:
    """``rubcli compare`` on a matrices or ROSS case: error against run time."""
    from rubcli.studies import rotor_compare

    target = out if out is not None else case.output_dir / "compare"
    plan = prepare_output(target, force, wait, rotor_compare.expected_files())
    command_line = {"case_file": str(case_file), "out": str(out) if out is not None else None,
                    "max_wall_time": max_wall_time}  # fmt: skip
    with machine_readable(json):
        try:
            result = rotor_compare.compare_rotor_case(
                case, max_wall_time, on_run=lambda text: console.info(f"running {text}")
            )
        except RuntimeError as exc:
            console.error(f"{case_file}: {exc}")
            raise typer.Exit(1) from None
        report = rotor_compare.write_compare_outputs(case, result, str(target), plan, command_line)
        report_stale(plan)
        rows = [[r["model"], str(r["coordinates"]), r["method"], f"{r['rtol']:g}", r["status"],
                 f"{r['wall_time_s']:.3g}", f"{r['error_clearances']:.3g}"]
                for r in report["runs"]]  # fmt: skip
        tables.table(
            f"{case.name}: error against run time (reference: full model, radau)",
            ["model", "coordinates", "method", "rtol", "status", "time s", "error (clearances)"],
            rows,
        )
        console.info(f"wrote {len(report['files'])} files to {target}: "
                     f"{', '.join(report['files'])}")  # fmt: skip
    emit(report, json)

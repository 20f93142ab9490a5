"""``rubcli compare`` on a machine given as matrices or a ROSS rotor: error against run time.

The reference is the full model (never the reduction) by ``radau`` at rtol 1e-7, atol
1e-12 (SI; tighter, Newton's iterations on a finite-element model stall on rounding:
docs/rotors.md). Each method of the case then runs the case's machine (its reduction,
when it has one) at three tolerances, and ``radau`` also runs the full model of a reduced
case, so the reduction's own error stands beside the methods'. An entry's error is the
largest distance, over the samples and the stations, between its station's rotor point
and the reference's, in clearances of that station. Into the output dir, as one commit:

- ``compare.csv``: one row a run (model, coordinates, method, rtol, atol, status, wall
  time, steps, events, error in clearances);
- ``compare.png``: error against wall time, a series per model and method, log-log;
- ``report.json``: the same rows, the reference's settings, statistics and wall time.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from rubcli import io
from rubcli.case.rotor import RotorCase
from rubcli.machine import Machine
from rubcli.system import MachineSolution, simulate
from rubcli.system.run import IMPLICIT as IMPLICIT_METHODS

REFERENCE = {"method": "radau", "rtol": 1e-7, "atol": 1e-12}
# rtol ladders: the implicit methods' floor on a finite-element model is about 1e-7
LADDERS = {
    "implicit": (1e-4, 1e-5, 1e-6),
    "explicit": (1e-6, 1e-8, 1e-10),
    "analytic": (1e-4, 1e-6, 1e-8),  # its error is about 1e-2 of its rtol (docs/rotors.md)
}
ATOL_PER_RTOL = 1e-2  # atol = rtol * 1e-2 * the smallest clearance (m, m/s): below rtol |q|
FILES = ("compare.csv", "compare.png")
COLUMNS = ("model", "coordinates", "method", "rtol", "atol", "status", "wall_time_s",
           "steps", "events", "error_clearances")  # fmt: skip


def expected_files() -> tuple[str, ...]:
    return (*FILES, io.REPORT_NAME)


def _runs(case: RotorCase) -> list[tuple[str, Machine, str, float]]:
    """(model, machine, method, rtol) of every run the comparison makes."""
    model = "full" if case.reduction is None else f"{case.reduction.modes} modes"
    runs = []
    for method in case.methods:
        kind = "implicit" if method in IMPLICIT_METHODS else "explicit"
        kind = "analytic" if method == "analytic" else kind
        runs += [(model, case.machine, method, rtol) for rtol in LADDERS[kind]]
    if case.reduction is not None:
        runs += [("full", case.full_machine, "radau", rtol) for rtol in LADDERS["implicit"]]
    return runs


def _station_points(case: RotorCase, solution: MachineSolution, full: bool) -> np.ndarray:
    """(k, S, 2): each station's rotor point (absolute, m) in a run of the full model
    (``full``) or of the case's machine."""
    points = []
    for node, _ in case.station_nodes:
        ix, iy = case.full_machine.structure.lateral(node) if full else case.lateral(node)
        points.append(solution.states[:, [ix, iy]])
    return np.stack(points, axis=1)


def compare_rotor_case(
    case: RotorCase,
    max_wall_time_s: float | None = None,
    on_run: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """The reference and every run (module docstring); a wall-time budget for the whole
    comparison (a run it cuts short is reported as failed)."""
    started = time.perf_counter()

    def budget() -> float | None:
        if max_wall_time_s is None:
            return None
        return max(max_wall_time_s - (time.perf_counter() - started), 1e-3)

    if on_run:
        on_run(f"reference: the full model by radau, rtol {REFERENCE['rtol']:g}")
    reference = simulate(case.full_machine, case.t_eval, **REFERENCE, max_wall_time_s=budget())
    if not reference.success:
        raise RuntimeError(f"the reference (radau, full model) failed: {reference.message}")
    ref = _station_points(case, reference, full=True)
    clearances = np.array([s.clearance for s in case.machine.stations])
    rows = []
    for model, machine, method, rtol in _runs(case):
        atol = rtol * ATOL_PER_RTOL * float(np.min(clearances))
        if on_run:
            on_run(f"{method} on the {model} model, rtol {rtol:g}")
        run = simulate(machine, case.t_eval, method=method, rtol=rtol, atol=atol,
                       max_wall_time_s=budget())  # fmt: skip
        error = float("nan")
        if run.success:
            got = _station_points(case, run, full=machine is case.full_machine)
            error = float(np.max(np.hypot(*np.moveaxis(got - ref, 2, 0)) / clearances))
        rows.append({
            "model": model, "coordinates": machine.size, "method": method, "rtol": rtol,
            "atol": atol, "status": run.status, "wall_time_s": run.wall_time_s,
            "steps": run.stats["steps"], "events": run.stats["events"],
            "error_clearances": error,
        })  # fmt: skip
    return {
        "reference": {
            **REFERENCE,
            "model": "full",
            "coordinates": case.full_machine.size,
            "wall_time_s": reference.wall_time_s,
            "stats": reference.stats,
        },  # fmt: skip
        "runs": rows,
    }


def write_compare_outputs(
    case: RotorCase, result: dict[str, Any], target: str, plan: io.OutputPlan,
    command_line: dict[str, Any],
) -> dict[str, Any]:  # fmt: skip
    """Writes compare.csv, compare.png and report.json as one commit; returns the report."""
    with io.staged_output_dir(target, plan) as staged:
        rows = result["runs"]
        columns = [[row[c] for row in rows] for c in COLUMNS]
        io.write_csv(staged.path("compare.csv"), list(COLUMNS), [columns])
        io.save_figure(_figure(case, result), staged.path("compare.png"))
        report = {
            **io.report_envelope("compare", command_line, case.to_dict()),
            "reference": result["reference"],
            "runs": rows,
            "files": [*staged.names(), io.REPORT_NAME],
        }
        staged.write_report(report)
    return report


def _figure(case: RotorCase, result: dict[str, Any]):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 5.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    series: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in result["runs"]:
        series.setdefault((row["model"], row["method"]), []).append(row)
    markers = "osD^v<>p"
    for k, ((model, method), rows) in enumerate(series.items()):
        done = [r for r in rows if r["status"] == "success" and r["error_clearances"] > 0]
        if not done:
            continue
        label = f"{method}, {model} model ({done[0]['coordinates']} coordinates)"
        ax.loglog([r["wall_time_s"] for r in done], [r["error_clearances"] for r in done],
                  marker=markers[k % len(markers)], linestyle="-" if model != "full" else "--",
                  label=label)  # fmt: skip
        for r in done:
            ax.annotate(f"{r['rtol']:.0e}", (r["wall_time_s"], r["error_clearances"]),
                        textcoords="offset points", xytext=(5, 3), fontsize=7)  # fmt: skip
    ref = result["reference"]
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("largest station error (clearances)")
    ax.set_title(f"{case.name}: error against run time (labels: rtol)\nreference: the full "
                 f"model by radau, rtol {ref['rtol']:g}, {ref['wall_time_s']:.3g} s",
                 fontsize="medium")  # fmt: skip
    ax.grid(True, which="both", linewidth=0.3)
    ax.legend(fontsize=8, loc="best")
    return fig

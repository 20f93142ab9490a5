"""``rubcli orbits CASE`` with ``[orbits] kind = "whirl"``: whirls of unknown rate.

On the symmetric machine (``e = 0``) the circular whirls in contact, slipping or rolling,
are found in closed form and continued in the ``[orbits]`` parameter
(``rubcli.analysis.orbits.whirls``, docs/orbits.md). Writes

- ``branch.csv``: one row per whirl in branch order, the columns of a periodic-orbit
  branch (the state at tau = 0, ``max_z = min_z = radius``, stability, the multipliers
  ``exp(lambda T)`` of the co-rotating eigenvalues over one forcing period, label) and
  ``branch``, ``mode``, ``radius``, ``whirl_rate``, ``whirl_order``, ``slip_velocity``,
  ``friction_needed``, ``growth_rate``, the four eigenvalues;
- ``branch.png``: radius and whirl rate against the parameter;
- ``report.json``: the case, the settings, the whirls at the case's parameters, every
  branch with why it stopped, every event located.

``[orbits] max_wall_time_s`` (``--max-wall-time S``) bounds the run as it bounds a
periodic-orbit branch: the whirls traced by then are written.

Exit codes as ``rubcli orbits``: 0 done; 1 no whirl at the case's parameters, or the
wall-time budget ran out (the whirls traced are written, the report says so); 2 invalid.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import typer

from rubcli import io
from rubcli.analysis.orbits import whirls as wh
from rubcli.case import Case, OrbitsSection, paper_machine_problem
from rubcli.cli import console, progress, tables
from rubcli.cli.common import emit, prepare_output, report_stale
from rubcli.studies.orbits import CSV_COLUMNS as ORBIT_COLUMNS

EXIT_FAILED = 1
QUICK_MAX_POINTS = 12
UNUSED = ("period", "start", "transient_periods", "rtol", "atol")  # periodic orbits only
EXPECTED_FILES = ("branch.csv", "branch.png", "report.json")
CSV_COLUMNS = (
    *ORBIT_COLUMNS,  # a periodic orbit's columns, then the whirl's own
    "branch", "mode", "radius", "whirl_rate", "whirl_order", "slip_velocity",
    "friction_needed", "growth_rate",
    *(f"eigenvalue{i}_{part}" for i in range(1, 5) for part in ("re", "im")),
)  # fmt: skip


def check_case(case: Case) -> list[str]:
    """Problems of a whirl case beyond the schema (file and field named)."""
    src, o = case.source, case.settings.orbits
    problems = []
    if case.params.e != 0.0:
        problems.append(
            f'{src}: orbits.kind: "whirl" needs the symmetric machine, e = 0 (the case has '
            f"e = {case.params.e:g}): with unbalance a whirl is not a relative equilibrium"
        )
    general = paper_machine_problem(case, 'orbits.kind: "whirl"', "a circular whirl is a "
                                    "relative equilibrium of a rotationally symmetric machine "
                                    "alone")  # fmt: skip
    if general is not None:
        problems.append(general)
    if o.parameter not in wh.PARAMETERS:
        problems.append(
            f"{src}: orbits.parameter: whirls are continued in {', '.join(wh.PARAMETERS)} "
            f"(got {o.parameter!r}: e must stay 0)"
        )
    value = float(getattr(case.params, o.parameter))
    if not o.min <= value <= o.max:
        problems.append(f"{src}: orbits.min/max: the starting value {o.parameter} = "
                        f"{value:.6g} lies outside the window [{o.min:g}, {o.max:g}]")  # fmt: skip
    for key in UNUSED:
        if key in o.model_fields_set:
            problems.append(f'{src}: orbits.{key}: not used with kind = "whirl"')
    return problems


def settings_from_case(
    o: OrbitsSection, quick: bool, max_wall_time_s: float | None = None
) -> wh.WhirlSettings:
    """The whirl settings of an [orbits] table (``max_wall_time_s``: the command line's
    budget instead of the table's)."""
    directions = {"both": (1, -1), "up": (1,), "down": (-1,)}[o.directions]
    return wh.WhirlSettings(
        parameter=o.parameter, p_min=o.min, p_max=o.max, step=o.step,
        min_step=o.resolved_min_step(), max_step=o.resolved_max_step(),
        max_points=min(o.max_points, QUICK_MAX_POINTS) if quick else o.max_points,
        directions=directions, newton_tol=min(o.newton_tol, 1e-10), locate=o.locate,
        max_wall_time_s=o.max_wall_time_s if max_wall_time_s is None else max_wall_time_s,
    )  # fmt: skip


def _cells(index: int, parameter: str, pt: wh.WhirlPoint) -> list[str]:
    w = pt.whirl
    mult = w.multipliers()
    eig = w.eigenvalues
    cells = [str(index), parameter, f"{pt.value:.17g}", "0"]
    cells += [f"{v:.17g}" for v in w.state]
    cells += [f"{w.radius:.17g}", f"{w.radius:.17g}", "1", "1" if w.mode == wh.ROLLING else "0",
              "1", str(w.stable).lower(), str(w.n_unstable),
              f"{float(np.max(np.abs(mult))):.17g}"]  # fmt: skip
    for v in mult:
        cells += [f"{v.real:.17g}", f"{v.imag:.17g}"]
    cells += [pt.label, str(bool(pt.label)).lower(), str(pt.newton_iterations)]
    cells += [str(pt.branch), wh.MODE_NAMES[w.mode], f"{w.radius:.17g}", f"{w.rate:.17g}",
              f"{w.order:.17g}", f"{w.slip_velocity:.17g}", f"{w.friction_needed:.17g}",
              f"{w.growth_rate:.17g}"]  # fmt: skip
    for v in eig:
        cells += [_number(v.real), _number(v.imag)]
    return cells


def _number(x: float) -> str:
    return f"{x:.17g}" if math.isfinite(x) else ("-inf" if x < 0 else "inf")


def write_branch_csv(path: Path, result: wh.WhirlContinuation) -> None:
    lines = [",".join(CSV_COLUMNS)]
    lines += [",".join(_cells(i, result.parameter, pt)) for i, pt in enumerate(result.rows())]
    io.write_text(path, "\n".join(lines) + "\n")


def run(
    case_file: Path,
    case: Case,
    target: Path,
    force: bool,
    wait: bool,
    quick: bool,
    json: bool,
    max_wall_time: float | None = None,
) -> None:
    """The whole command for a whirl case (inputs checked by the caller's schema;
    ``max_wall_time``: the budget instead of the table's)."""
    problems = check_case(case)
    if problems:
        console.error_lines(f"cannot continue whirls of {case_file}", problems)
        raise typer.Exit(2)
    o = case.settings.orbits
    settings = settings_from_case(o, quick, max_wall_time)
    plan = prepare_output(target, force, wait, EXPECTED_FILES)
    with console.machine_readable(json):
        t0 = time.perf_counter()
        total = float(settings.max_points * len(settings.directions) * 2)
        with progress.progress_bar(f"whirls in {o.parameter}", total=total) as update:
            result = wh.continue_whirls(case.params, settings, progress=lambda n: update(n),
                                        deadline=t0 + settings.max_wall_time_s)  # fmt: skip
        wall = time.perf_counter() - t0
        command_line = {"case_file": str(case_file), "out": str(target), "quick": quick,
                        "max_wall_time": max_wall_time}  # fmt: skip
        report = {
            **io.report_envelope("orbits", command_line, case.to_dict()),
            "kind": "whirl",
            "wall_time_s": wall,
            "quick": quick,
            "continuation": dict(settings.__dict__),
            "whirls": result.to_dict(),
        }
        with io.staged_output_dir(target, plan) as staged:
            if result.status == "ok":
                from rubcli.plotting.whirls import whirl_figure

                write_branch_csv(staged.path("branch.csv"), result)
                p = case.params
                fixed = ", ".join(f"{k}={v:g}" for k, v in p.as_dict().items()
                                  if k not in (o.parameter, "phi0"))  # fmt: skip
                title = f"{case.name}: whirls continued in {o.parameter}\n{fixed}"
                io.save_figure(whirl_figure(result, title), staged.path("branch.png"))
            report["files"] = staged.names() + ["report.json"]
            staged.write_report(report)
        report_stale(plan)
        emit(report, json)
        if result.status != "ok":
            console.error(f"{case_file}: {result.message}; report.json written to {target}")
            raise typer.Exit(EXIT_FAILED)
        if result.budget_exhausted:
            console.error(
                f"{case_file}: stopped by the wall-time budget ({settings.max_wall_time_s:g} s): "
                f"the {len(result.rows())} whirls traced are written to {target} "
                "(--max-wall-time or [orbits] max_wall_time_s for more)"
            )
            raise typer.Exit(EXIT_FAILED)
        for w in result.start_whirls:
            console.info(f"{wh.MODE_NAMES[w.mode]} whirl: r = {w.radius:.6g}, rate "
                         f"{w.rate:.6g} ({w.order:.4g} X), "
                         + ("stable" if w.stable else f"unstable ({w.n_unstable})"))  # fmt: skip
        rows = [[e.kind, f"{e.value:.10g}", f"{e.point.whirl.radius:.6g}", e.note]
                for e in result.events]  # fmt: skip
        if rows:
            tables.table(f"events along {o.parameter}", ["kind", o.parameter, "r", "note"], rows)
        console.success(f"wrote {', '.join(report['files'])} to {target}")

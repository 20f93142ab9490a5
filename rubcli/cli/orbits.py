"""``rubcli orbits CASE [--out DIR] [--overlay sweep.nc] [--quick]``: continue a periodic orbit.

Output dir: ``--out DIR``, else ``orbits/`` inside the case's output dir.

Reads the case's ``[orbits]`` table (docs/orbits.md), finds the starting periodic orbit by
shooting (from ``[initial]``, from the end of a transient, or from the exact synchronous
rub), continues it in one parameter by pseudo-arclength in both directions, detects and
locates folds, period doublings, Neimark-Sacker points, grazing and stick onset, and writes

- ``branch.csv`` and ``branch.nc``: one row per orbit (parameter, k, state on the section,
  max/min z, contact and stick fractions, multipliers, stability, bifurcation label);
  located bifurcation points are rows with their label, in branch order;
- ``branch.png`` (max z against the parameter, stable solid, unstable dashed, bifurcations
  marked; over the sweep's stroboscopic z with ``--overlay``) and ``multipliers.png``;
- ``report.json``: the case, the settings, why each direction stopped, the bifurcations.

``--quick`` (for CI) caps each direction at 12 points and loosens the integration to 1e-10.

``[orbits] max_wall_time_s`` (default 3600 s; ``--max-wall-time S``) bounds the whole
run, the transient included: what is computed by then is written. Where no progress bar
shows (stderr not a terminal), a ``progress:`` line goes to stderr every 10 s.

Exit codes: 0 done (a direction that stopped early says why in the report); 2 invalid
input (nothing written); 1 no starting orbit (only report.json, with the reason), or the
wall-time budget ran out (the orbits computed are written, the report says so).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from rubcli import __version__, io, model
from rubcli.analysis import continuation as cn
from rubcli.analysis import orbits as ob
from rubcli.case import Case, OrbitsSection
from rubcli.cli import console
from rubcli.cli.common import (
    ForceOption,
    JsonOption,
    WaitOption,
    command_dir,
    emit,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit

EXIT_FAILED = 1
EXPECTED_FILES = ("branch.csv", "branch.nc", "branch.png", "multipliers.png", "report.json")
QUICK_MAX_POINTS = 12
QUICK_TOL = 1e-10
OVERLAY_CANDIDATES = ("strobe_z", "section_z", "z_section", "stroboscopic_z", "poincare_z", "z")
CSV_COLUMNS = (
    "index", "parameter", "value", "k", "x", "y", "vx", "vy", "max_z", "min_z",
    "contact_fraction", "stick_fraction", "contact_phases", "stable", "n_unstable",
    "max_multiplier_modulus", *(f"multiplier{i}_{part}" for i in range(1, 5)
                                for part in ("re", "im")),
    "label", "located", "newton_iterations",
)  # fmt: skip


def settings_from_case(
    case: Case, quick: bool = False, max_wall_time_s: float | None = None
) -> cn.ContinuationSettings:
    """The continuation settings of a case's [orbits] table (``max_wall_time_s``: the
    command line's budget instead of the table's)."""
    o = case.settings.orbits
    assert o is not None
    directions = {"both": (1, -1), "up": (1,), "down": (-1,)}[o.directions]
    return cn.ContinuationSettings(
        parameter=o.parameter,
        p_min=o.min,
        p_max=o.max,
        step=o.step,
        min_step=o.resolved_min_step(),
        max_step=o.resolved_max_step(),
        max_points=min(o.max_points, QUICK_MAX_POINTS) if quick else o.max_points,
        directions=directions,
        k=o.period,
        newton_tol=max(o.newton_tol, 1e-9) if quick else o.newton_tol,
        max_newton=o.max_newton,
        rtol=max(o.rtol, QUICK_TOL) if quick else o.rtol,
        atol=max(o.atol, QUICK_TOL) if quick else o.atol,
        locate=o.locate,
        max_wall_time_s=o.max_wall_time_s if max_wall_time_s is None else max_wall_time_s,
    )


def check_case(case: Case) -> list[str]:
    """Problems of a case for ``rubcli orbits`` beyond the schema (file and field named)."""
    src, o = case.source, case.settings.orbits
    if o is None:
        return [f"{src}: orbits: missing table [orbits] (rubcli orbits needs it; docs/orbits.md)"]
    value = float(getattr(case.params, o.parameter))
    problems = []
    if not o.min <= value <= o.max:
        table = "model" if case.settings.model is not None else "physical (nondimensional)"
        problems.append(
            f"{src}: orbits.min/max: the starting value {table} {o.parameter} = {value:.6g} "
            f"lies outside the window [{o.min:g}, {o.max:g}]"
        )
    if o.start == "synchronous_rub":
        rubs = [r for r in model.synchronous_rub_radii(case.params)]
        if not rubs or not model.synchronous_rub_is_forward(rubs[-1], case.params):
            problems.append(
                f"{src}: orbits.start: these parameters have no forward synchronous full "
                'annular rub to start from (use start = "initial" or "transient")'
            )
    elif o.start == "initial" and o.transient_periods:
        problems.append(f'{src}: orbits.transient_periods: only used with start = "transient"')
    return problems


def load_overlay(path: Path, parameter: str, variable: str | None):
    """(parameter values, z values, label) of a sweep.nc, or a list of problems."""
    try:
        import xarray as xr
    except ImportError:  # pragma: no cover - xarray is a dependency
        return [f"{path}: --overlay needs xarray and h5netcdf (pip install xarray h5netcdf)"]
    if not path.is_file():
        return [f"{path}: --overlay: file not found"]
    try:
        ds = xr.open_dataset(path, engine="h5netcdf")
    except Exception as exc:  # any unreadable file is bad input, not a crash
        return [f"{path}: --overlay: not a readable NetCDF file ({type(exc).__name__}: {exc})"]
    with ds:
        if parameter not in ds.coords and parameter not in ds.dims:
            return [f"{path}: --overlay: no coordinate {parameter!r} (the branch's parameter);"
                    f" coordinates: {', '.join(map(str, ds.coords)) or 'none'}"]  # fmt: skip
        names = [variable] if variable else [n for n in OVERLAY_CANDIDATES if n in ds.data_vars]
        if not names:
            names = [str(n) for n, v in ds.data_vars.items() if parameter in v.dims and "z" in n]
        if not names or names[0] not in ds.data_vars:
            wanted = variable or " or ".join(OVERLAY_CANDIDATES)
            return [f"{path}: --overlay: no stroboscopic variable {wanted} over {parameter!r}"]
        var = ds[names[0]]
        if parameter not in var.dims:
            return [f"{path}: --overlay: variable {names[0]!r} does not depend on {parameter!r}"]
        var = var.transpose(parameter, ...)
        values = np.asarray(var.values, dtype=float)
        coord = np.asarray(ds[parameter].values, dtype=float)
    from rubcli.plotting.orbits import overlay_points

    px, pz = overlay_points(coord, values)
    return px, pz, f"sweep: {names[0]} ({path.name})"


# ------------------------------------------------------------------------ products


def _row(index: int, name: str, pt: cn.BranchPoint) -> list[str]:
    m = np.zeros(4, dtype=complex)
    m[: pt.multipliers.size] = pt.multipliers[:4]
    cells = [str(index), name, f"{pt.parameter:.17g}", str(pt.k)]
    cells += [f"{v:.17g}" for v in pt.state]
    cells += [f"{pt.max_z:.17g}", f"{pt.min_z:.17g}", f"{pt.contact_fraction:.12g}",
              f"{pt.stick_fraction:.12g}", str(pt.contact_phases), str(pt.stable).lower(),
              str(pt.n_unstable), f"{np.max(np.abs(pt.multipliers)):.17g}"]  # fmt: skip
    for v in m:
        cells += [f"{v.real:.17g}", f"{v.imag:.17g}"]
    cells += [pt.label, str(bool(pt.label)).lower(), str(pt.newton_iterations)]
    return cells


def write_branch_csv(path: Path, branch: cn.Branch) -> None:
    lines = [",".join(CSV_COLUMNS)]
    for i, pt in enumerate(branch.rows()):
        lines.append(",".join(_row(i, branch.parameter, pt)))
    io.write_text(path, "\n".join(lines) + "\n")


def branch_dataset(branch: cn.Branch, attrs: dict[str, Any]):
    """The branch as an xarray Dataset (dims ``point`` and ``multiplier``)."""
    import xarray as xr

    rows = branch.rows()
    n = len(rows)
    mult = np.zeros((n, 4), dtype=complex)
    for i, pt in enumerate(rows):
        mult[i, : pt.multipliers.size] = pt.multipliers[:4]
    states = np.array([pt.state for pt in rows]).reshape(n, 4)
    data = {
        branch.parameter: ("point", np.array([pt.parameter for pt in rows])),
        "k": ("point", np.array([pt.k for pt in rows], dtype=np.int32)),
        "max_z": ("point", np.array([pt.max_z for pt in rows])),
        "min_z": ("point", np.array([pt.min_z for pt in rows])),
        "contact_fraction": ("point", np.array([pt.contact_fraction for pt in rows])),
        "stick_fraction": ("point", np.array([pt.stick_fraction for pt in rows])),
        "contact_phases": ("point", np.array([pt.contact_phases for pt in rows], dtype=np.int32)),
        "stable": ("point", np.array([pt.stable for pt in rows], dtype=np.int8)),
        "multiplier_re": (("point", "multiplier"), mult.real),
        "multiplier_im": (("point", "multiplier"), mult.imag),
        "label": ("point", np.array([pt.label for pt in rows], dtype=object).astype(str)),
    }
    for j, name in enumerate(("x", "y", "vx", "vy")):
        data[name] = ("point", states[:, j])
    ds = xr.Dataset(data, coords={"point": np.arange(n), "multiplier": np.arange(4)})
    ds["stable"].attrs["meaning"] = "1 if every multiplier lies inside the unit circle"
    ds["max_z"].attrs["units"] = "clearances"
    ds.attrs.update({k: v if isinstance(v, str | int | float) else io_json(v)
                     for k, v in attrs.items()})  # fmt: skip
    return ds


def io_json(value: Any) -> str:
    import json

    return json.dumps(io.to_jsonable(value))


def write_branch_nc(path: Path, branch: cn.Branch, attrs: dict[str, Any]) -> None:
    io.write_netcdf(branch_dataset(branch, attrs), path)


def _title(case: Case, branch: cn.Branch) -> str:
    p = case.params
    fixed = {k: v for k, v in p.as_dict().items() if k != branch.parameter}
    text = ", ".join(f"{k}={v:g}" for k, v in fixed.items())
    head = f"{case.name}: periodic orbits (k={branch.settings.k}) continued in {branch.parameter}"
    return f"{head}\n{text}"


def summary_lines(branch: cn.Branch) -> list[list[str]]:
    """The console's table of bifurcations, in increasing order of the parameter (the
    branch lists them in the order continuation met them: one direction, then the other)."""
    rows = []
    for b in sorted(branch.bifurcations, key=lambda b: b.parameter):
        mods = ", ".join(f"{abs(m):.6f}" for m in b.point.multipliers)
        rows.append([b.kind, f"{b.parameter:.10g}", "yes" if b.located else "no",
                     f"{b.point.max_z:.6g}", mods, b.note])  # fmt: skip
    return rows


# ------------------------------------------------------------------------ command


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", metavar="DIR", help="Output dir (default: <case output dir>/orbits)."
        ),
    ] = None,
    overlay: Annotated[
        Path | None,
        typer.Option("--overlay", help="A sweep.nc of the same machine to draw the branch over."),
    ] = None,
    overlay_var: Annotated[
        str | None,
        typer.Option("--overlay-var", help="The stroboscopic variable of the sweep.nc to draw."),
    ] = None,
    quick: Annotated[
        bool, typer.Option("--quick", help="CI mode: 12 points per direction, tolerance 1e-10.")
    ] = False,
    max_wall_time: Annotated[
        float | None,
        typer.Option(
            "--max-wall-time",
            metavar="S",
            help="Wall-time budget in seconds instead of [orbits] max_wall_time_s.",
        ),
    ] = None,  # fmt: skip
    json: JsonOption = False,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Periodic orbits, Floquet multipliers and continuation in one parameter (orbits table)."""
    case = load_or_exit(case_file)
    if case.settings.orbits is not None and case.settings.orbits.kind == "whirl":
        from rubcli.cli import whirls

        if overlay is not None:
            console.error(
                f'{case_file}: --overlay: draws periodic-orbit branches, not kind = "whirl"'
            )
            raise typer.Exit(EXIT_INVALID)
        target = command_dir(case, "orbits", out)
        return whirls.run(case_file, case, target, force, wait, quick, json)
    problems = check_case(case)
    if max_wall_time is not None and not (math.isfinite(max_wall_time) and max_wall_time > 0):
        problems.append(f"--max-wall-time: must be a finite number > 0 (got {max_wall_time!r})")
    overlay_data = None
    if not problems and overlay is not None:
        loaded = load_overlay(overlay, case.settings.orbits.parameter, overlay_var)
        if isinstance(loaded, list):
            problems = loaded
        else:
            overlay_data = loaded
    if problems:
        console.error_lines(f"cannot continue orbits of {case_file}", problems)
        raise typer.Exit(EXIT_INVALID)
    o: OrbitsSection = case.settings.orbits
    settings = settings_from_case(case, quick, max_wall_time)
    target = command_dir(case, "orbits", out)
    plan = prepare_output(target, force, wait, EXPECTED_FILES)  # before any work
    with console.machine_readable(json):
        _orbits(case_file, case, o, settings, target, plan, overlay, overlay_data, quick, json)


def _orbits(case_file, case, o, settings, target, plan, overlay, overlay_data, quick, json):
    """The work of the command, once its inputs and output dir are checked."""
    t0 = time.perf_counter()
    params = case.params
    deadline = cn.deadline_of(settings, t0)
    done = [0]
    phase = ["the starting orbit"]

    def status() -> str:
        return (f"orbits: {phase[0]}, {done[0]} orbits, {time.perf_counter() - t0:.0f} s of "
                f"the {settings.max_wall_time_s:g} s budget")  # fmt: skip

    def count(n: int) -> None:
        done[0] = n
        update(n)

    with console.progress_lines(status):
        with console.progress_bar("start orbit", total=1.0) as update:
            try:
                guess = start_guess(case, o, deadline)
            except ob.WallTimeBudgetError:
                guess = None
            update(1.0)
        phase[0] = f"continuation in {o.parameter}"
        total = float(settings.max_points * len(settings.directions) + 1)
        with console.progress_bar(f"continuation in {o.parameter}", total=total) as update:
            if guess is None:
                branch = cn.Branch(o.parameter, settings, [], [], {}, 0, "failed",
                                   f"no starting orbit: wall-time budget exhausted "
                                   f"(max_wall_time_s = {settings.max_wall_time_s:g}) in the "
                                   "transient", budget_exhausted=True)  # fmt: skip
            else:
                branch = cn.continue_branch(params, guess, settings, count, deadline)
    wall = time.perf_counter() - t0
    command_line = {"case_file": str(case_file), "out": str(target), "quick": quick,
                    "overlay": str(overlay) if overlay is not None else None}  # fmt: skip
    report = {
        **io.report_envelope("orbits", command_line, case.to_dict()),
        "wall_time_s": wall,
        "quick": quick,
        "continuation": {k: v for k, v in settings.__dict__.items()},
        "start_guess": None if guess is None else [float(v) for v in guess],
        "branch": branch.to_dict(),
        "overlay": str(overlay) if overlay is not None else None,
    }
    with io.staged_output_dir(target, plan) as staged:
        if branch.status == "ok":
            attrs = {"case": case.name, "parameter": branch.parameter,
                     "rubcli_version": __version__, "stops": branch.stops}  # fmt: skip
            write_branch_csv(staged.path("branch.csv"), branch)
            write_branch_nc(staged.path("branch.nc"), branch, attrs)
            from rubcli.plotting.orbits import branch_figure, multipliers_figure

            title = _title(case, branch)
            io.save_figure(branch_figure(branch, title, overlay_data), staged.path("branch.png"))
            io.save_figure(multipliers_figure(branch, title), staged.path("multipliers.png"))
        report["files"] = sorted(p.name for p in staged.staging.iterdir()) + ["report.json"]
        staged.write_report(report)
    report_stale(plan)
    emit(report, json)
    if branch.status != "ok":
        console.error(f"{case_file}: {branch.message}; report.json written to {target}")
        raise typer.Exit(EXIT_FAILED)
    console.info(
        f"{len(branch.points)} orbits in {wall:.1f} s; "
        + "; ".join(f"{k}: {v}" for k, v in branch.stops.items())
    )
    if branch.budget_exhausted:
        console.error(
            f"{case_file}: stopped by the wall-time budget ({settings.max_wall_time_s:g} s): "
            f"the {len(branch.points)} orbits computed are written to {target} "
            "(--max-wall-time or [orbits] max_wall_time_s for more)"
        )
        raise typer.Exit(EXIT_FAILED)
    if branch.bifurcations:
        console.table(
            f"bifurcations along {branch.parameter}",
            ["kind", branch.parameter, "located", "max z", "|multipliers|", "note"],
            summary_lines(branch),
        )
    else:
        console.info("no bifurcation detected on the branch")
    console.success(
        f"wrote branch.csv, branch.nc, branch.png, multipliers.png, report.json to {target}"
    )


def start_guess(case: Case, o: OrbitsSection, deadline: float | None = None) -> np.ndarray:
    """The starting guess for shooting: [initial], after a transient, or the exact rub
    (WallTimeBudgetError if the transient runs past ``deadline``)."""
    params = case.params
    if o.start == "synchronous_rub":
        return model.synchronous_rub(np.array([0.0]), params)[:, 0]
    initial = np.array(case.problem.initial, dtype=float)
    if o.start == "transient":
        try:
            return ob.transient_state(params, initial, o.transient_periods * o.period, deadline)
        except ob.OrbitError:
            return initial
    return initial

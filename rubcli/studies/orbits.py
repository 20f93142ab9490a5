"""Periodic orbits of a case continued in one parameter (``rubcli orbits``), as a library
study: ``continue_orbits(case)`` returns an ``OrbitsResult``, whose ``write(directory)``
writes ``branch.csv``, ``branch.nc``, ``branch.png``, ``multipliers.png`` and
``report.json`` in one atomic commit (``rubcli.io``).

The case's ``[orbits]`` table (docs/orbits.md) sets the continuation; the starting orbit
is shot from ``[initial]``, from the end of a transient, or from the exact synchronous rub.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rubcli import __version__, io, model
from rubcli.analysis.orbits import continuation as cn
from rubcli.analysis.orbits import curves as cv
from rubcli.analysis.orbits import periodic as ob
from rubcli.case import Case, OrbitsSection

if TYPE_CHECKING:
    import xarray as xr

FILES = ("branch.csv", "branch.nc", "branch.png", "multipliers.png", "report.json")
CURVE_FILES = ("curve.csv", "curves.png")  # with [orbits] second_parameter
QUICK_MAX_POINTS = 12
QUICK_CURVE_POINTS = 3
QUICK_TOL = 1e-10
OVERLAY_CANDIDATES = ("strobe_z", "section_z", "z_section", "stroboscopic_z", "poincare_z", "z")
CSV_COLUMNS = (
    "index", "parameter", "value", "k", "x", "y", "vx", "vy", "max_z", "min_z",
    "contact_fraction", "stick_fraction", "contact_phases", "stable", "n_unstable",
    "max_multiplier_modulus", *(f"multiplier{i}_{part}" for i in range(1, 5)
                                for part in ("re", "im")),
    "label", "located", "newton_iterations",
)  # fmt: skip
# a stator with its own mass: its four states on the section, and four more multipliers
STATE_NAMES = ("x", "y", "vx", "vy", "stator_x", "stator_y", "stator_vx", "stator_vy")


def csv_columns(size: int) -> tuple[str, ...]:
    """The branch CSV's columns for a state of ``size`` entries (4, or 8 with a moving
    stator): ``CSV_COLUMNS`` with the state and the multipliers of that size."""
    if size == 4:
        return CSV_COLUMNS
    head, tail = CSV_COLUMNS[:4], CSV_COLUMNS[8:16]
    pairs = tuple(f"multiplier{i}_{part}" for i in range(1, size + 1) for part in ("re", "im"))
    return (*head, *STATE_NAMES[:size], *tail, *pairs, *CSV_COLUMNS[-3:])


# Progress of a study: (phase, orbits computed so far, orbits at most).
Progress = Callable[[str, int, int], None]


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


def files_for(case: Case) -> tuple[str, ...]:
    """The files ``rubcli orbits`` writes for this case."""
    o = case.settings.orbits
    return FILES + (CURVE_FILES if o is not None and o.second_parameter else ())


def curve_settings_from_case(case: Case, quick: bool = False) -> cv.CurveSettings | None:
    """The settings of the curves of a case's [orbits] table (None: no second parameter)."""
    o = case.settings.orbits
    if o is None or o.second_parameter is None:
        return None
    branch = settings_from_case(case, quick)
    return cv.CurveSettings(
        parameter=o.parameter, p_min=o.min, p_max=o.max, second=o.second_parameter,
        s_min=o.second_min, s_max=o.second_max, step=o.curve_step,
        max_points=min(o.curve_points, QUICK_CURVE_POINTS) if quick else o.curve_points,
        k=o.period, newton_tol=branch.newton_tol, max_newton=branch.max_newton,
        rtol=branch.rtol, atol=branch.atol,
    )  # fmt: skip


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
    if o.start == "synchronous_rub" and not case.params.is_paper_machine:
        problems.append(
            f"{src}: orbits.start: the synchronous full annular rub has a closed form on the "
            "paper's machine only (a concentric stator, an isotropic support, no load); on "
            'the general machine use start = "initial" or "transient"'
        )
    elif o.start == "synchronous_rub":
        rubs = [r for r in model.synchronous_rub_radii(case.params)]
        if not rubs or not model.synchronous_rub_is_forward(rubs[-1], case.params):
            problems.append(
                f"{src}: orbits.start: these parameters have no forward synchronous full "
                'annular rub to start from (use start = "initial" or "transient")'
            )
    elif o.start == "initial" and o.transient_periods:
        problems.append(f'{src}: orbits.transient_periods: only used with start = "transient"')
    if o.second_parameter is not None:
        second = float(getattr(case.params, o.second_parameter))
        if not o.second_min <= second <= o.second_max:
            problems.append(
                f"{src}: orbits.second_min/second_max: the case's {o.second_parameter} = "
                f"{second:.6g} (where the branch's bifurcations lie) is outside the window "
                f"[{o.second_min:g}, {o.second_max:g}]"
            )
    return problems


def load_overlay(
    path: Path, parameter: str, variable: str | None
) -> tuple[np.ndarray, np.ndarray, str] | list[str]:
    """(parameter values, z values, label) of a sweep.nc, or a list of problems."""
    from rubcli.studies.sweep import open_overlay

    ds = open_overlay(path)
    if isinstance(ds, list):
        return ds
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


# ------------------------------------------------------------------------ the study


@dataclass
class OrbitsResult:
    """A continued branch with what produced it; ``write`` puts it in a directory."""

    case: Case
    settings: cn.ContinuationSettings
    guess: np.ndarray | None  # the starting guess (None: the transient ran out of time)
    branch: cn.Branch
    wall_time_s: float
    quick: bool = False
    overlay: tuple | None = field(default=None, repr=False)  # (x, z, label) under the branch
    curves: list[cv.Curve] = field(default_factory=list)  # bifurcations in a 2nd parameter

    @property
    def ok(self) -> bool:
        return self.branch.status == "ok"

    @cached_property
    def distances(self) -> list[list[float]]:
        """Each curve point's distance from its closed form (``closed_form_distances``),
        computed once for curve.csv and report.json."""
        return [closed_form_distances(c, self.case) for c in self.curves]

    def report(self, command_line: dict[str, Any]) -> dict[str, Any]:
        """The report.json of the study (``command_line``: what was asked for)."""
        return {
            **io.report_envelope("orbits", command_line, self.case.to_dict()),
            "wall_time_s": self.wall_time_s,
            "quick": self.quick,
            "continuation": dict(self.settings.__dict__),
            "start_guess": None if self.guess is None else [float(v) for v in self.guess],
            "branch": self.branch.to_dict(),
            "overlay": command_line.get("overlay"),
            **(
                {
                    "curves": [
                        curve_report(c, d) for c, d in zip(self.curves, self.distances, strict=True)
                    ]
                }
                if self.case.settings.orbits.second_parameter
                else {}
            ),  # fmt: skip
        }

    def write(
        self, directory: str | Path, plan: io.OutputPlan | None = None,
        command_line: dict[str, Any] | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Write the outputs into ``directory`` as one commit (``plan``: the dir as the
        caller opened and checked it; without one it is opened here); returns the report.
        A failed branch writes report.json alone."""
        report = self.report(command_line or {"out": str(directory)})
        branch = self.branch
        with io.staged_output_dir(directory, plan) as staged:
            if self.ok:
                attrs = {"case": self.case.name, "parameter": branch.parameter,
                         "rubcli_version": __version__, "stops": branch.stops}  # fmt: skip
                write_branch_csv(staged.path("branch.csv"), branch)
                io.write_netcdf(branch_dataset(branch, attrs), staged.path("branch.nc"))
                from rubcli.plotting.orbits import branch_figure, multipliers_figure

                title = title_of(self.case, branch)
                io.save_figure(branch_figure(branch, title, self.overlay),
                               staged.path("branch.png"))  # fmt: skip
                io.save_figure(multipliers_figure(branch, title), staged.path("multipliers.png"))
                if self.case.settings.orbits.second_parameter:
                    self.write_curves(staged)
            report["files"] = staged.names() + ["report.json"]
            staged.write_report(report)
        return report

    def write_curves(self, staged: io.StagedOutput) -> None:
        """curve.csv and curves.png of the bifurcations continued in the second parameter."""
        from rubcli.plotting.orbits import curves_figure

        o = self.case.settings.orbits
        names = (o.parameter, o.second_parameter)
        lines = [",".join(curve_columns(names))]
        for i, (curve, distances) in enumerate(zip(self.curves, self.distances, strict=True)):
            for pt, distance in zip(curve.points, distances, strict=True):
                cells = [str(i), curve.kind, *(f"{v:.17g}" for v in pt.values)]
                cells += [f"{v:.17g}" for v in pt.state]
                cells += [f"{pt.max_z:.17g}", f"{pt.contact_fraction:.12g}",
                          f"{pt.test_value:.6g}", f"{distance:.3g}" if math.isfinite(distance)
                          else ""]  # fmt: skip
                lines.append(",".join(cells))
        io.write_text(staged.path("curve.csv"), "\n".join(lines) + "\n")
        title = (
            f"{self.case.name}: bifurcations of the k={o.period} orbits continued in "
            f"({o.parameter}, {o.second_parameter})\n{fixed_text(self.case, names)}"
        )
        windows = ((o.min, o.max), (o.second_min, o.second_max))
        closed = None
        if o.period == 1:  # the synchronous motions' closed-form curves, as a check
            from rubcli.analysis.charts import stability as charts

            closed = charts.closed_form_chart(self.case.params, o.parameter, windows[0],
                                              o.second_parameter, windows[1], 121, 81)  # fmt: skip
        here = float(getattr(self.case.params, o.second_parameter))
        figure = curves_figure(self.curves, names, windows, here, title, closed)
        io.save_figure(figure, staged.path("curves.png"))


def curve_columns(names: tuple[str, str]) -> tuple[str, ...]:
    """The columns of curve.csv: one per parameter, the orbit, and the closed-form check."""
    return ("curve", "kind", *names, "x", "y", "vx", "vy", "max_z", "contact_fraction",
            "test_value", "distance_to_closed_form")  # fmt: skip


def closed_form_distances(curve: cv.Curve, case: Case) -> list[float]:
    """Each point's distance in the second parameter from the closed-form curve of its
    kind at its first parameter (nan where no closed form applies: k > 1, a period
    doubling, a fold or Neimark-Sacker point of an orbit not in contact all round)."""
    from rubcli.analysis.charts import stability as charts

    o = case.settings.orbits
    kind = cv.CLOSED_FORMS.get(curve.kind)
    out = []
    for pt in curve.points:
        rub = curve.kind == cn.GRAZING or pt.contact_fraction == 1.0
        if kind is None or o.period != 1 or not rub:
            out.append(math.nan)
            continue
        at = ob.with_parameter(case.params, o.parameter, pt.values[0])
        span = 0.05 * (o.second_max - o.second_min)
        root = charts.closed_form_root(at, kind, o.second_parameter, pt.values[1], span)
        out.append(abs(pt.values[1] - root))
    return out


def curve_report(curve: cv.Curve, distances: list[float]) -> dict[str, Any]:
    """A curve in report.json, with its largest distance from the closed form."""
    distances = [d for d in distances if math.isfinite(d)]
    return {**curve.to_dict(),
            "max_distance_to_closed_form": max(distances) if distances else None}  # fmt: skip


def fixed_text(case: Case, names: tuple[str, ...]) -> str:
    """The parameters held fixed, as text."""
    fixed = {k: v for k, v in case.params.as_dict().items() if k not in names}
    text = ", ".join(f"{k}={v:g}" for k, v in fixed.items())
    return "\n".join([text, *case.params.machine_lines()])  # the general machine's, apart


def continue_orbits(
    case: Case,
    *,
    quick: bool = False,
    max_wall_time_s: float | None = None,
    overlay: tuple | None = None,
    progress: Progress | None = None,
) -> OrbitsResult:
    """Shoot the case's starting orbit and continue it (its ``[orbits]`` table; checked
    first with ``check_case``). ``quick``: 12 points per direction at tolerance 1e-10;
    ``max_wall_time_s``: the budget instead of the table's; ``progress(phase, done,
    total)`` as it goes."""
    problems = check_case(case)
    if problems:
        raise ValueError("; ".join(problems))
    o: OrbitsSection = case.settings.orbits
    settings = settings_from_case(case, quick, max_wall_time_s)
    t0 = time.perf_counter()
    deadline = cn.deadline_of(settings, t0)
    total = settings.max_points * len(settings.directions) + 1
    report = progress or (lambda phase, done, total: None)
    report("the starting orbit", 0, total)
    try:
        guess = start_guess(case, o, deadline)
    except ob.WallTimeBudgetError:
        guess = None
    phase = f"continuation in {o.parameter}"
    report(phase, 0, total)
    if guess is None:
        branch = cn.Branch(o.parameter, settings, [], [], {}, 0, "failed",
                           "no starting orbit: wall-time budget exhausted (max_wall_time_s = "
                           f"{settings.max_wall_time_s:g}) in the transient",
                           budget_exhausted=True)  # fmt: skip
    else:

        def count(n: int) -> None:
            report(phase, n, total)

        branch = cn.continue_branch(case.params, guess, settings, count, deadline)
    curves: list[cv.Curve] = []
    curve_settings = curve_settings_from_case(case, quick)
    if curve_settings is not None and branch.status == "ok" and not branch.budget_exhausted:
        phase = f"bifurcations continued in {o.second_parameter}"
        report(phase, 0, 1)

        def counted(n: int) -> None:
            report(phase, n, 2 * curve_settings.max_points + 1)

        curves = cv.continue_curves(case.params, branch, curve_settings, deadline, counted)
    wall = time.perf_counter() - t0
    return OrbitsResult(case, settings, guess, branch, wall, quick, overlay, curves)


# ------------------------------------------------------------------------ products


def _row(index: int, name: str, pt: cn.BranchPoint) -> list[str]:
    size = pt.state.size
    m = np.zeros(size, dtype=complex)
    m[: pt.multipliers.size] = pt.multipliers[:size]
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
    rows = branch.rows()
    lines = [",".join(csv_columns(rows[0].state.size if rows else 4))]
    for i, pt in enumerate(rows):
        lines.append(",".join(_row(i, branch.parameter, pt)))
    io.write_text(path, "\n".join(lines) + "\n")


def branch_dataset(branch: cn.Branch, attrs: dict[str, Any]) -> xr.Dataset:
    """The branch as an xarray Dataset (dims ``point`` and ``multiplier``)."""
    import xarray as xr

    rows = branch.rows()
    n = len(rows)
    size = rows[0].state.size if rows else 4
    mult = np.zeros((n, size), dtype=complex)
    for i, pt in enumerate(rows):
        mult[i, : pt.multipliers.size] = pt.multipliers[:size]
    states = np.array([pt.state for pt in rows]).reshape(n, size)
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
    for j, name in enumerate(STATE_NAMES[:size]):
        data[name] = ("point", states[:, j])
    ds = xr.Dataset(data, coords={"point": np.arange(n), "multiplier": np.arange(size)})
    ds["stable"].attrs["meaning"] = "1 if every multiplier lies inside the unit circle"
    ds["max_z"].attrs["units"] = "clearances"
    ds.attrs.update({k: v if isinstance(v, str | int | float) else io_json(v)
                     for k, v in attrs.items()})  # fmt: skip
    return ds


def io_json(value: Any) -> str:
    import json

    return json.dumps(io.to_jsonable(value))


def title_of(case: Case, branch: cn.Branch) -> str:
    text = fixed_text(case, (branch.parameter,))
    head = f"{case.name}: periodic orbits (k={branch.settings.k}) continued in {branch.parameter}"
    return f"{head}\n{text}"


def start_guess(case: Case, o: OrbitsSection, deadline: float | None = None) -> np.ndarray:
    """The starting guess for shooting: [initial], after a transient, or the exact rub
    (WallTimeBudgetError if the transient runs past ``deadline``)."""
    params = case.params
    if o.start == "synchronous_rub":
        return model.synchronous_rub(np.array([0.0]), params)[:, 0]
    initial = np.array(case.problem.initial, dtype=float)
    if params.stator is not None:  # the two bodies' section: the ring's state after
        initial = np.concatenate((initial, case.problem.stator_initial))
    if o.start == "transient":
        try:
            return ob.transient_state(params, initial, o.transient_periods * o.period, deadline)
        except ob.OrbitError:
            return initial
    return initial

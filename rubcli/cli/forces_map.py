"""``rubcli forces-map CASE [--out DIR]``: Figure 2, the Taylor error, contact eigenvalues.

The case's ``[forces_map]`` table (defaults when it is absent) says which products to make;
only those are computed and written:

- ``forces``: ``forces_map.csv`` (x, y, Fx_exact, Fy_exact, Fx_taylor, Fy_taylor, Fx_diff,
  Fy_diff) and ``forces_map.png``: exact force and its Taylor expansion at its own point,
  K and mu of ``[model]``/``[physical]``;
- ``taylor_error``: ``taylor_error.csv`` (K, delta, direction, max_abs_error) and
  ``taylor_error.png``: error of the expansion at a distance delta, for every K of
  ``K_values`` and the case's mu;
- ``eigen``: ``eigen_map.csv`` (x, y, max_real, freq_1, freq_2; empty fields outside
  contact) and ``eigen_map.png``: eigenvalues of the linearised contact system, mu_c = +mu;
- ``report.json`` always: the case echoed, the fitted slopes, the eigenvalue summary.

Everything is nondimensional (clearances, units of ``k_r * clearance``, of ``omega``); the
report gives the newtons per force unit when the case has a ``[physical]`` table.

Output dir: ``--out DIR``, else ``forces-map/`` inside the case's output dir, so that the
report of ``rubcli run`` on the same case is not overwritten. Exit 0 on success, 2 on
invalid input (nothing written). Files are staged and moved in at the end.
"""

from __future__ import annotations

import contextlib
import resource
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from rubcli import case as case_module
from rubcli import io
from rubcli.analysis import forces
from rubcli.case import Case, ForcesMapSection
from rubcli.cli import console
from rubcli.cli.common import ForceOption, WaitOption, command_dir, prepare_output, report_stale
from rubcli.cli.validate import EXIT_INVALID, load_or_exit

FORCES_COLUMNS = ("x", "y", "Fx_exact", "Fy_exact", "Fx_taylor", "Fy_taylor", "Fx_diff", "Fy_diff")
TAYLOR_COLUMNS = ("K", "delta", "direction", "max_abs_error")
EIGEN_COLUMNS = ("x", "y", "max_real", "freq_1", "freq_2")
OUTPUT_SUBDIR = "forces-map"


def output_dir(case: Case, out: Path | None) -> Path:
    """``--out`` if given, else ``<case output dir>/forces-map``."""
    return command_dir(case, OUTPUT_SUBDIR, out)


# Rows of a grid table formatted at a time: the text of one block (about 100 bytes a row)
# is all the CSV holds in memory, whatever the resolution.
GRID_BLOCK_ROWS = 65_536


def grid_blocks(
    x: np.ndarray, y: np.ndarray, fields: list[np.ndarray], rows: int = GRID_BLOCK_ROWS
):
    """The grid table in blocks of ``rows`` rows, one row per grid point (y outer, x
    inner): x, y, then each field (indexed ``[iy, ix]``); nothing of the size of the grid
    is allocated."""
    n = x.size
    flat = [f.reshape(-1) for f in fields]
    for start in range(0, n * y.size, rows):
        index = np.arange(start, min(start + rows, n * y.size))
        yield [x[index % n], y[index // n], *(f[start : start + index.size] for f in flat)]


def write_grid_csv(path: Path, columns: tuple[str, ...], x, y, fields) -> Path:
    """Numeric CSV of a grid, shortest round-trip repr of each float, NaN an empty field,
    formatted and written block by block (``grid_blocks``). Atomic."""
    return io.write_csv(path, columns, grid_blocks(x, y, fields), nonfinite="")


def write_taylor_csv(path: Path, error: forces.TaylorError) -> Path:
    return io.write_rows_csv(path, TAYLOR_COLUMNS, error.rows(), nonfinite="")


def _forces_product(case: Case, settings: ForcesMapSection, title: str, staged) -> dict:
    from rubcli.plotting import forces as plots

    p = case.params
    fm = forces.force_map(p.K, p.mu, settings.extent, settings.resolution)
    fields = [fm.Fx_exact, fm.Fy_exact, fm.Fx_taylor, fm.Fy_taylor, fm.Fx_diff, fm.Fy_diff]
    write_grid_csv(staged.path("forces_map.csv"), FORCES_COLUMNS, fm.x, fm.y, fields)
    del fields  # (the differences, made for the table)
    io.save_figure(plots.forces_map_figure(fm, title), staged.path("forces_map.png"))
    return {
        "K": fm.K,
        "mu_c": fm.mu_c,
        "max_abs_force": fm.max_abs_force,
        "max_abs_diff": fm.max_abs_diff,
        "max_abs_diff_over_max_abs_force": fm.max_abs_diff / fm.max_abs_force
        if fm.max_abs_force > 0
        else None,
        "note": "Taylor expansion evaluated at its own point (paper Figure 2): exact by "
        "construction, the difference is round-off (model notes 2.8)",
        "files": ["forces_map.csv", "forces_map.png"],
    }


def _taylor_product(case: Case, settings: ForcesMapSection, title: str, staged) -> dict:
    from rubcli.plotting import forces as plots

    mu = case.params.mu
    error = forces.taylor_error(
        settings.resolved_K_values(), settings.resolved_deltas(), mu, settings.extent
    )
    write_taylor_csv(staged.path("taylor_error.csv"), error)
    io.save_figure(plots.taylor_error_figure(error, title), staged.path("taylor_error.png"))
    return {
        "mu_c": error.mu_c,
        "K_values": error.K_values,
        "deltas": error.deltas,
        "band": {
            "z0_min": float(error.band_radii.min()),
            "z0_max": float(error.band_radii.max()),
            "n_radii": int(error.band_radii.size),
            "n_polar_positions": forces.BAND_POLAR_ANGLES,
            "n_directions_worst": forces.DIRECTION_ANGLES,
        },
        "error_measure": "max over the band of |F_exact(p0 + delta d) - F_taylor(p0; p0 + "
        "delta d)| (Euclidean norm, units of k_r*clearance), displaced point in contact",
        "fitted_slope": error.slopes(),
        "slope_note": "least-squares slope of log error vs log delta over errors above "
        f"{forces.ROUND_OFF_FACTOR:g} eps K extent; null: all round-off (radial: the force "
        "is linear along rays)",
        "leading_order": "worst: K sqrt(1+mu^2) delta^2/sqrt(3) / z0^2; tangential: "
        "K sqrt(1+mu^2) delta^2/2 / z0^2; radial: 0",
        "files": ["taylor_error.csv", "taylor_error.png"],
    }


def _eigen_product(case: Case, settings: ForcesMapSection, title: str, staged) -> dict:
    from rubcli.plotting import forces as plots

    p = case.params
    em = forces.eigen_map(p, p.mu, settings.extent, settings.resolution)
    flutter = forces.friction_flutter_radius(p.mu)
    fields = [em.max_real, em.freq_1, em.freq_2]
    write_grid_csv(staged.path("eigen_map.csv"), EIGEN_COLUMNS, em.x, em.y, fields)
    figure = plots.eigen_map_figure(em, title, flutter_radius=flutter)
    io.save_figure(figure, staged.path("eigen_map.png"))
    contact = em.in_contact
    return {
        "K": em.K,
        "nu": em.nu,
        "mu_c": em.mu_c,
        "n_grid_points": int(em.max_real.size),
        "n_contact_points": em.n_contact_points,
        "max_real_part": em.max_real_overall,
        "positive_fraction_of_contact_points": em.positive_fraction,
        "freq_1_range": [float(em.freq_1[contact].min()), float(em.freq_1[contact].max())]
        if em.n_contact_points
        else None,
        "freq_2_range": [float(em.freq_2[contact].min()), float(em.freq_2[contact].max())]
        if em.n_contact_points
        else None,
        "flutter_radius_undamped": flutter,
        "files": ["eigen_map.csv", "eigen_map.png"],
    }


PRODUCTS = {"forces": _forces_product, "taylor_error": _taylor_product, "eigen": _eigen_product}
PRODUCT_FILES = {"forces": "forces_map", "taylor_error": "taylor_error", "eigen": "eigen_map"}


def expected_files(settings: ForcesMapSection) -> tuple[str, ...]:
    """The files ``rubcli forces-map`` writes for these settings."""
    stems = [PRODUCT_FILES[product] for product in settings.products]
    return (*(f"{stem}{ext}" for stem in stems for ext in (".csv", ".png")), "report.json")


def make_outputs(
    case: Case, target: Path, command_line: dict[str, Any], plan: io.OutputPlan | None = None
) -> dict[str, Any]:
    """Compute the requested products, write them and report.json into ``target`` (staged)."""
    settings = case.settings.forces_map or ForcesMapSection()
    p = case.params
    title = f"{case.name}: nu={p.nu:g}, eta={p.eta:g}, K={p.K:g}, mu={p.mu:g}"
    results: dict[str, Any] = {}
    files: list[str] = []
    with io.staged_output_dir(target, plan) as staged:
        for product in settings.products:
            results[product] = PRODUCTS[product](case, settings, title, staged)
            files.extend(results[product]["files"])
        files.append("report.json")
        report = {
            **io.report_envelope("forces-map", command_line, case.to_dict()),
            "forces_map": {
                **settings.model_dump(mode="json"),
                "resolved_deltas": settings.resolved_deltas(),
                "resolved_K_values": settings.resolved_K_values(),
                "from_case": case.settings.forces_map is not None,
            },
            "sign_convention": "F = force of the stator on the rotor = -K f, f = (1 - 1/z)"
            "(x - mu_c y, y + mu_c x) for z > 1, 0 otherwise; nondimensional, units of "
            "k_r*clearance; positions in clearances; eigenvalues in units of omega; "
            "mu_c = +mu (friction for forward spin, v_r > 0)",
            "force_unit_N": case.scale.force if case.scale is not None else None,
            "products": results,
            "files": files,
        }
        staged.write_report(report)
    return report


def _slope_text(slope: float | None) -> str:
    return "round-off" if slope is None else f"{slope:.4f}"


def _print_summary(report: dict[str, Any]) -> None:
    products = report["products"]
    if "forces" in products:
        f = products["forces"]
        console.info(
            f"forces: K={f['K']:g}, mu_c={f['mu_c']:g}: max |F| = {f['max_abs_force']:.6g}, "
            f"max |exact - Taylor at own point| = {f['max_abs_diff']:.3g} (round-off)"
        )
    if "taylor_error" in products:
        slopes = products["taylor_error"]["fitted_slope"]
        K_labels = list(next(iter(slopes.values())))
        rows = [
            [direction]
            + [
                "round-off" if slopes[direction][k] is None else f"{slopes[direction][k]:.4f}"
                for k in K_labels
            ]
            for direction in slopes
        ]
        console.table(
            "Taylor error: fitted slope of log error vs log delta",
            ["direction", *(f"K={float(k):g}" for k in K_labels)],
            rows,
        )
    if "eigen" in products:
        e = products["eigen"]
        max_real = e["max_real_part"]
        console.info(
            f"eigen: K={e['K']:g}, nu={e['nu']:g}, mu_c={e['mu_c']:g}: "
            f"max real part {'-' if max_real is None else f'{max_real:.6g}'}, "
            f"Re > 0 on {100 * e['positive_fraction_of_contact_points']:.2f}% of "
            f"{e['n_contact_points']} contact points; "
            f"modes merge beyond z0 = {e['flutter_radius_undamped']:.6g} (undamped)"
        )


def available_memory_bytes() -> float | None:
    """The memory this process may still take: the kernel's MemAvailable, or the address
    space limit (RLIMIT_AS) if lower; None if neither is known."""
    limits = []
    with contextlib.suppress(OSError, ValueError):
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                limits.append(int(line.split()[1]) * 1024)
    with contextlib.suppress(ValueError, OSError, AttributeError):
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            limits.append(soft)
    return float(min(limits)) if limits else None


def _check_memory(case_file: Path, resolution: int) -> None:
    """Exit 2 if the grid will not fit in the memory this process may take (the case's
    own check bounds it by 8 GiB on any machine)."""
    need, have = case_module.forces_map_memory_bytes(resolution), available_memory_bytes()
    if have is None or need <= have:
        return
    largest = case_module.largest_forces_map_resolution(have)
    console.error(
        f"{case_file}: forces_map.resolution: a {resolution} x {resolution} grid needs about "
        f"{need / 1024**3:.3g} GiB of memory, and this process may take "
        f"{have / 1024**3:.3g} GiB; at most {largest} fits"
    )
    raise typer.Exit(EXIT_INVALID)


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            metavar="DIR",
            help=f"Output dir (default: {OUTPUT_SUBDIR}/ inside the case's output dir).",
        ),
    ] = None,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Contact force maps (paper Figure 2), Taylor error vs distance, contact eigenvalues."""
    case = load_or_exit(case_file)
    target = output_dir(case, out)
    settings = case.settings.forces_map or ForcesMapSection()
    _check_memory(case_file, settings.resolution)
    plan = prepare_output(target, force, wait, expected_files(settings))
    source = (
        "[forces_map]" if case.settings.forces_map is not None else "defaults (no [forces_map])"
    )
    console.info(
        f"{case.name}: {', '.join(settings.products)} on a {settings.resolution}^2 grid, "
        f"extent {settings.extent:g} clearances; settings from {source}"
    )
    command_line = {"case_file": str(case_file), "out": str(out) if out is not None else None}
    report = make_outputs(case, target, command_line, plan)
    report_stale(plan)
    _print_summary(report)
    console.info(f"wrote {len(report['files'])} files to {target}: {', '.join(report['files'])}")

"""The contact force maps of a case (``rubcli forces-map``; paper Figure 2), as a library
study: ``write_forces_map(case, directory)`` computes the products its ``[forces_map]``
table asks for (defaults without one), each written as soon as it is made so that only one
grid is held at a time, and commits them with ``report.json`` into ``directory`` at once
(``rubcli.io``):

- ``forces``: the exact force and its Taylor expansion at its own point;
- ``taylor_error``: the expansion's error at a distance delta, for every K;
- ``eigen``: the eigenvalues of the linearised contact system.
"""

from __future__ import annotations

import contextlib
import resource
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import io
from rubcli.analysis.charts import forces_map as forces
from rubcli.analysis.orbits.periodic import check_deadline
from rubcli.case import Case, ForcesMapSection

FORCES_COLUMNS = ("x", "y", "Fx_exact", "Fy_exact", "Fx_taylor", "Fy_taylor", "Fx_diff", "Fy_diff")
TAYLOR_COLUMNS = ("K", "delta", "direction", "max_abs_error")
EIGEN_COLUMNS = ("x", "y", "max_real", "freq_1", "freq_2")


# Rows of a grid table formatted at a time: the text of one block (about 100 bytes a row)
# is all the CSV holds in memory, whatever the resolution.
GRID_BLOCK_ROWS = 65_536


def grid_blocks(
    x: np.ndarray, y: np.ndarray, fields: list[np.ndarray], rows: int = GRID_BLOCK_ROWS,
    deadline: float | None = None,
) -> Iterator[list[np.ndarray]]:  # fmt: skip
    """The grid table in blocks of ``rows`` rows, one row per grid point (y outer, x
    inner): x, y, then each field (indexed ``[iy, ix]``); nothing of the size of the grid
    is allocated. WallTimeBudgetError before a block once ``deadline`` has passed."""
    n = x.size
    flat = [f.reshape(-1) for f in fields]
    for start in range(0, n * y.size, rows):
        check_deadline(deadline)
        index = np.arange(start, min(start + rows, n * y.size))
        yield [x[index % n], y[index // n], *(f[start : start + index.size] for f in flat)]


def write_grid_csv(
    path: Path, columns: tuple[str, ...], x: np.ndarray, y: np.ndarray,
    fields: list[np.ndarray], deadline: float | None = None,
) -> Path:  # fmt: skip
    """Numeric CSV of a grid, shortest round-trip repr of each float, NaN an empty field,
    formatted and written block by block (``grid_blocks``, ``deadline`` its budget). Atomic."""
    blocks = grid_blocks(x, y, fields, deadline=deadline)
    return io.write_csv(path, columns, blocks, nonfinite="")


def write_taylor_csv(path: Path, error: forces.TaylorError) -> Path:
    return io.write_rows_csv(path, TAYLOR_COLUMNS, error.rows(), nonfinite="")


def _forces_product(
    case: Case, settings: ForcesMapSection, title: str, staged, deadline: float | None
) -> dict:
    from rubcli.plotting import forces as plots

    p = case.params
    fm = forces.force_map(p.K, p.mu, settings.extent, settings.resolution)
    fields = [fm.Fx_exact, fm.Fy_exact, fm.Fx_taylor, fm.Fy_taylor, fm.Fx_diff, fm.Fy_diff]
    write_grid_csv(staged.path("forces_map.csv"), FORCES_COLUMNS, fm.x, fm.y, fields, deadline)
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


def _taylor_product(
    case: Case, settings: ForcesMapSection, title: str, staged, deadline: float | None
) -> dict:
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


def _eigen_product(
    case: Case, settings: ForcesMapSection, title: str, staged, deadline: float | None
) -> dict:
    from rubcli.plotting import forces as plots

    p = case.params
    em = forces.eigen_map(p, p.mu, settings.extent, settings.resolution, deadline)
    flutter = forces.friction_flutter_radius(p.mu)
    fields = [em.max_real, em.freq_1, em.freq_2]
    write_grid_csv(staged.path("eigen_map.csv"), EIGEN_COLUMNS, em.x, em.y, fields, deadline)
    if not p.is_paper_machine:  # the map is the paper machine's linearisation: said so
        title += f"\n{PAPER_MACHINE_EIGEN}"
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
        **({"machine_note": PAPER_MACHINE_EIGEN} if not p.is_paper_machine else {}),
        "files": ["eigen_map.csv", "eigen_map.png"],
    }


# the eigen map linearises the contact of the paper's machine (forces.eigen_map)
PAPER_MACHINE_EIGEN = (
    "eigenvalues of the contact linearised on the paper's machine (isotropic support nu, "
    "rigid stator), not of this case's general machine"
)


PRODUCTS = {"forces": _forces_product, "taylor_error": _taylor_product, "eigen": _eigen_product}
PRODUCT_FILES = {"forces": "forces_map", "taylor_error": "taylor_error", "eigen": "eigen_map"}


def expected_files(settings: ForcesMapSection) -> tuple[str, ...]:
    """The files ``rubcli forces-map`` writes for these settings."""
    stems = [PRODUCT_FILES[product] for product in settings.products]
    return (*(f"{stem}{ext}" for stem in stems for ext in (".csv", ".png")), "report.json")


def write_forces_map(
    case: Case, target: str | Path, plan: io.OutputPlan | None = None,
    command_line: dict[str, Any] | None = None, max_wall_time_s: float | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Compute the requested products, write them and report.json into ``target`` in one
    commit (``plan``: the dir as the caller opened and checked it; without one it is
    opened here); returns the report. The whole is bounded by ``[forces_map]
    max_wall_time_s`` (``max_wall_time_s``: a budget instead of the table's):
    ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` once it is spent, nothing written."""
    deadline = time.perf_counter()
    command_line = command_line or {"out": str(target)}
    settings = case.settings.forces_map or ForcesMapSection()
    deadline += settings.max_wall_time_s if max_wall_time_s is None else max_wall_time_s
    p = case.params
    title = f"{case.name}: nu={p.nu:g}, eta={p.eta:g}, K={p.K:g}, mu={p.mu:g}"
    results: dict[str, Any] = {}
    files: list[str] = []
    with io.staged_output_dir(target, plan) as staged:
        for product in settings.products:
            check_deadline(deadline)
            results[product] = PRODUCTS[product](case, settings, title, staged, deadline)
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

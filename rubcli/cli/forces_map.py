"""``rubcli forces-map CASE [--out DIR] [--max-wall-time S]``: Figure 2, the Taylor error,
contact eigenvalues.

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
report of ``rubcli run`` on the same case is not overwritten. ``[forces_map]
max_wall_time_s`` (default 3600 s; ``--max-wall-time S``) bounds the whole command,
checked between products and at every block of rows of the eigenvalue map and the CSV
tables. Exit 0 on success, 1 when the wall-time budget ran
out (nothing written), 2 on invalid input (nothing written). Files are staged and moved
in at the end.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from rubcli import case as case_module
from rubcli.case import Case, ForcesMapSection
from rubcli.cli import console, tables
from rubcli.cli.common import (
    ForceOption,
    WaitOption,
    budget_spent,
    check_max_wall_time,
    command_dir,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit, paper_machine_or_exit
from rubcli.studies import forces_map as study

OUTPUT_SUBDIR = "forces-map"


def output_dir(case: Case, out: Path | None) -> Path:
    """``--out`` if given, else ``<case output dir>/forces-map``."""
    return command_dir(case, OUTPUT_SUBDIR, out)


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
        tables.table(
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
            + (f"; {e['machine_note']}" if "machine_note" in e else "")
        )


def _check_memory(case_file: Path, resolution: int) -> None:
    """Exit 2 if the grid will not fit in the memory this process may take (the case's
    own check bounds it by 8 GiB on any machine)."""
    need = case_module.forces_map_memory_bytes(resolution)
    have = study.available_memory_bytes()
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
    max_wall_time: Annotated[
        float | None,
        typer.Option(
            "--max-wall-time",
            metavar="S",
            help="Wall-time budget in seconds instead of [forces_map] max_wall_time_s.",
        ),
    ] = None,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Contact force maps (paper Figure 2), Taylor error vs distance, contact eigenvalues."""
    check_max_wall_time(max_wall_time)
    case = load_or_exit(case_file)
    target = output_dir(case, out)
    settings = case.settings.forces_map or ForcesMapSection()
    if "eigen" in settings.products:
        paper_machine_or_exit(case, 'forces_map.products: "eigen"', "it linearises the "
                              "contact of a concentric rigid stator on an isotropic support; "
                              "leave it out to map the forces")  # fmt: skip
    _check_memory(case_file, settings.resolution)
    plan = prepare_output(target, force, wait, study.expected_files(settings))
    source = (
        "[forces_map]" if case.settings.forces_map is not None else "defaults (no [forces_map])"
    )
    console.info(
        f"{case.name}: {', '.join(settings.products)} on a {settings.resolution}^2 grid, "
        f"extent {settings.extent:g} clearances; settings from {source}"
    )
    command_line = {"case_file": str(case_file), "out": str(out) if out is not None else None,
                    "max_wall_time": max_wall_time}  # fmt: skip
    from rubcli.analysis.orbits.periodic import WallTimeBudgetError

    try:
        report = study.write_forces_map(case, target, plan, command_line, max_wall_time)
    except WallTimeBudgetError:
        budget = settings.max_wall_time_s if max_wall_time is None else max_wall_time
        raise budget_spent(case_file, budget, "[forces_map] max_wall_time_s") from None
    report_stale(plan)
    _print_summary(report)
    console.info(f"wrote {len(report['files'])} files to {target}: {', '.join(report['files'])}")

"""The writing side of a parameter sweep (``rubcli sweep``): the files of a finished
sweep in one atomic commit (``write_outputs``), what they are (``expected_files``), and
where a sweep keeps its finished points until then (``store_dir_for``, ``kept_text``,
``stale_stores``).

The sweep itself is ``rubcli.sweep(case)`` (``rubcli.sweeps``: the plan of a case, the
engine ``rubcli.analysis.sweep``); docs/sweeps.md.
"""

from __future__ import annotations

import glob
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rubcli import io

if TYPE_CHECKING:  # (the engine, xarray and Dask load only when a sweep runs)
    import xarray as xr

    from rubcli.analysis.sweep import SweepPlan
    from rubcli.analysis.sweep.engine import RunStats
    from rubcli.case import Case
    from rubcli.model import ModelParams


STORE_PREFIX = ".rubcli-sweep-"  # rubcli's own hidden entry (``rubcli.io.outputs``)


def store_dir_for(target: Path, digest: str) -> Path:
    """The hidden store of finished points, inside the output dir (under its lock)."""
    return Path(target) / f"{STORE_PREFIX}{digest}"


_STORE_NAME = re.compile(r"^\.rubcli-sweep-[0-9a-f]{8,64}$")
_STORE_FILE = re.compile(r"^(plan\.json|.+\.point|.+\.chunk|\..+\.tmp)$")


def stale_stores(target: Path, digest: str) -> list[Path]:
    """The stores of earlier sweeps into ``target`` whose case has changed since: inside
    the dir, or beside it as older rubcli kept them (``.<dir name>.sweep-<digest>``); only
    dirs that hold nothing but a store's files."""
    target = Path(target)
    found = [p for p in target.glob(f"{STORE_PREFIX}*")
             if _STORE_NAME.match(p.name) and p.name != f"{STORE_PREFIX}{digest}"]  # fmt: skip
    absolute = Path(os.path.abspath(target))
    if absolute.name:
        older = re.compile(rf"^\.{re.escape(absolute.name)}\.sweep-[0-9a-f]{{8,64}}$")
        found += [p for p in absolute.parent.glob(f".{glob.escape(absolute.name)}.sweep-*")
                  if older.match(p.name)]  # fmt: skip
    return sorted(p for p in found if _only_store_files(p))


def _only_store_files(path: Path) -> bool:
    try:
        return (
            path.is_dir()
            and not path.is_symlink()
            and all(_STORE_FILE.match(p.name) and not p.is_dir() for p in path.iterdir())
        )
    except OSError:
        return False


def expected_files(plan: SweepPlan) -> tuple[str, ...]:
    """The files ``rubcli sweep`` writes for ``plan``."""
    return ("sweep.nc", "sweep.csv", *figures(plan), "report.json")


def figures(plan: SweepPlan) -> list[str]:
    """The figures of a sweep, by file name (``rubcli.plotting.sweep.<stem>_figure``)."""
    if plan.is_basin:
        return ["basins.png"] + (["convergence.png"] if plan.recognition is not None else [])
    if len(plan.axes) == 1:
        return ["bifurcation.png", "summary.png"] + (["cascade.png"] if plan.spectrum else [])
    return ["map.png"]


def write_outputs(
    case: Case, plan: SweepPlan, ds: xr.Dataset, results: Any, stats: RunStats, where: str,
    wall: float, target: str | Path,
    output: io.OutputPlan | None = None, command_line: dict[str, Any] | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Write a finished sweep's files into ``target`` in one commit (``output``: the dir as
    the caller opened and checked it; without one it is opened here): sweep.nc, sweep.csv,
    its figures and report.json; returns the report. ``results``, ``stats`` and
    ``where`` are ``rubcli.analysis.sweep.execute``'s; ``ds`` its dataset."""
    from rubcli.analysis.sweep import basins
    from rubcli.analysis.sweep.dataset import csv_text
    from rubcli.plotting import sweep as plots

    recognised = plan.recognition is not None
    title, files = title_of(case, plan), []
    with io.staged_output_dir(target, output) as staged:
        io.write_netcdf(ds, staged.path("sweep.nc"))
        text = basins.csv_text(ds, plan) if recognised else csv_text(ds, plan)
        io.write_text(staged.path("sweep.csv"), text)
        files += ["sweep.nc", "sweep.csv"]
        for name in figures(plan):
            stem = name.removesuffix(".png")
            make = getattr(plots, f"recognised_{stem}_figure" if stem == "basins" and
                           recognised else f"{stem}_figure")  # fmt: skip
            io.save_figure(make(ds, title), staged.path(name))
            files.append(name)
        files.append("report.json")
        found = basins.summary(ds) if recognised else None
        n_failed = found["failed"] if found else int((ds["status"].values != 0).sum())
        computed_s = (
            results.compute_s if recognised else sum(r.wall_time_s for r in results.values())
        )
        report = {
            **io.report_envelope("sweep", command_line or {"out": str(target)}, case.to_dict()),
            "plan": plan.to_dict(),
            "plan_digest": plan.digest(),
            "executor": where,
            "points": plan.n_points,
            "points_computed_this_run": stats.computed,
            "points_resumed": stats.resumed,
            # resubmissions after a lost local worker; on Dask, Dask's own (not seen here)
            "points_retried": None if where.startswith("dask") else stats.retried,
            "points_failed": n_failed,
            **(
                {"basins": found}
                if found
                else {"failed": failures(ds), "class_counts": class_counts(ds)}
            ),
            "compute_time_s": computed_s,
            "wall_time_s": wall,
            "files": files,
        }
        staged.write_report(report)
    return report


def title_of(case: Case, plan: SweepPlan) -> str:
    p = case.params
    swept = {a.parameter for a in plan.axes}
    fixed = ", ".join(f"{k}={v:g}" for k, v in p.as_dict().items() if k not in swept)
    fixed = "\n".join([fixed, *p.machine_lines(omit=swept)])  # the machine's lines apart
    axes = " and ".join(a.parameter for a in plan.axes)
    if plan.recognition is not None:
        budget = plan.transient_periods + plan.record_periods
        how = f"each start until its attractor is recognised, at most {budget} periods"
    else:
        how = (f"{plan.direction}; {plan.transient_periods} transient + "
               f"{plan.record_periods} recorded periods per point")  # fmt: skip
    return f"{case.name}: sweep of {axes} ({how})\n{fixed}"


def failures(ds: xr.Dataset) -> list[dict]:
    out = []
    status = ds["status"]
    dims = status.dims
    for index in zip(*(status.values != 0).nonzero(), strict=True):
        at = {d: ds[d].values[i].item() for d, i in zip(dims, index, strict=True)}
        at["message"] = str(ds["message"].values[index])
        out.append(at)
    return out


def class_counts(ds: xr.Dataset) -> dict[str, int]:
    from rubcli.analysis.sweep.point import RESPONSE_CLASSES

    ok = ds["status"].values == 0
    codes = ds["response_class"].values[ok].astype(int)
    counts = {name: int((codes == i).sum()) for i, name in enumerate(RESPONSE_CLASSES)}
    counts["failed"] = int((~ok).sum())
    return {k: v for k, v in counts.items() if v}


MAX_OVERLAY_BYTES = 8 << 30  # the largest --overlay file read
UNCONFIRMED = "chaotic, unconfirmed (Birkhoff test only: no Lyapunov exponent computed)"


def class_lines(ds: xr.Dataset) -> list[tuple[str, int]]:
    """The class counts as the console prints them: a "chaotic" point without a Lyapunov
    exponent is counted apart as unconfirmed, as its row of sweep.csv says."""
    import numpy as np

    from rubcli.analysis.sweep.point import RESPONSE_CLASSES

    counts = class_counts(ds)
    chaotic = RESPONSE_CLASSES.index("chaotic")
    ok = ds["status"].values == 0
    unconfirmed = int(
        (ok & (ds["response_class"].values == chaotic) & ~np.isfinite(ds["lyapunov"].values)).sum()
    )
    lines = []
    for name, count in counts.items():
        if name == "chaotic" and unconfirmed:
            if count > unconfirmed:
                lines.append(("chaotic (positive Lyapunov exponent)", count - unconfirmed))
            lines.append((UNCONFIRMED, unconfirmed))
        else:
            lines.append((name, count))
    return lines


def summary_lines(plan: SweepPlan, report: dict, ds: xr.Dataset, counts: str) -> list[str]:
    """What ``rubcli sweep`` prints once its files are written: the points' count and
    where they ran (``counts``), then a basin grid's attractors and how its starts were
    labelled, or the response classes."""
    lines = [f"{plan.n_points} points on {counts}"]
    if plan.recognition is None:
        return lines + [f"  {name}: {count}" for name, count in class_lines(ds)]
    found = report["basins"]
    for a in found["attractors"]:
        lines.append(f"  A{a['label']}: {a['name']}: {100 * a['basin_fraction']:.1f} % of starts")
    for name in ("not_recognised", "diverged", "failed"):
        if found[name]:
            lines.append(f"  {name.replace('_', ' ')}: {found[name]} starts")
    how = ", ".join(f"{n} {k}" for k, n in found["recognised_by"].items() if n)
    lines.append(f"  labelled by: {how}; {found['mean_periods_integrated']:.1f} periods "
                 "integrated a start on average")  # fmt: skip
    return lines


def describe(case: Case, plan: SweepPlan, quick: bool = False) -> str:
    """One line on what the sweep runs."""
    return (
        f"{case.name}: sweep of {', '.join(a.parameter for a in plan.axes)} "
        f"({plan.n_points} points, {plan.direction}, {plan.transient_periods} + "
        f"{plan.record_periods} periods each"
        + (", stopped once the attractor is recognised" if plan.recognition else "")
        + f", {plan.method})"
        + (" (quick)" if quick else "")
    )


def dataset(case: Case, plan: SweepPlan, results: dict) -> xr.Dataset:
    """The results of every point as the sweep's Dataset (a basin grid's with its
    attractors when it recognises them)."""
    from rubcli import sweeps
    from rubcli.analysis.sweep import basins
    from rubcli.analysis.sweep.dataset import build_dataset

    build = basins.build_dataset if plan.recognition is not None else build_dataset
    return build(plan, results, sweeps.case_attrs(case))


def kept_text(store_dir: Path, plan: SweepPlan) -> str:
    """How many finished points the store holds: one a ``.point`` file, or the starts of
    each ``chunk-<c>.chunk`` of a basin grid with recognition."""
    if not store_dir.is_dir():
        kept = 0
    elif plan.recognition is not None:
        from rubcli.analysis.sweep.basins import chunk_size

        n, size = plan.n_points, chunk_size(plan.n_points)
        chunks = [p.name.removeprefix("chunk-").removesuffix(".chunk")
                  for p in store_dir.glob("chunk-*.chunk")]  # fmt: skip
        kept = sum(max(0, min(size, n - int(c) * size)) for c in chunks if c.isdigit())
    else:
        kept = len(list(store_dir.glob("*.point")))
    return f"{kept} of {plan.n_points} points are kept in {store_dir}"


def local_cluster(workers: int | None) -> tuple[Any, Any]:
    """A local Dask cluster of processes on loopback (for trying the Dask path)."""
    from rubcli.analysis import sweep as engine

    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise engine.SchedulerError('Dask is not installed: pip install -e ".[dask]"') from None
    n = workers or engine.default_workers()
    cluster = LocalCluster(
        n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    )  # fmt: skip
    return Client(cluster, set_as_default=False), cluster


def open_overlay(path: Path) -> xr.Dataset | list[str]:
    """A sweep.nc given to ``--overlay`` (``rubcli chart``, ``rubcli run``, ``rubcli
    orbits``), opened, or why it cannot be read (bad input, never a crash).

    Only a regular file of at most MAX_OVERLAY_BYTES is read: the path is opened without
    blocking (a FIFO or a device would hold the command for ever) and checked on the open
    descriptor before xarray reads it from there."""
    import os
    import stat

    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        return [f"{path}: --overlay: file not found"]
    except OSError as exc:
        return [f"{path}: --overlay: cannot be opened ({exc.strerror})"]
    info = os.fstat(fd)
    problem = ""
    if not stat.S_ISREG(info.st_mode):
        problem = "not a regular file (a sweep.nc is one)"
    elif info.st_size > MAX_OVERLAY_BYTES:
        problem = (
            f"{info.st_size / 2**30:.3g} GiB, above the {MAX_OVERLAY_BYTES >> 30} GiB of a sweep.nc"
        )
    if problem:
        os.close(fd)
        return [f"{path}: --overlay: {problem}"]
    os.set_blocking(fd, True)
    handle = os.fdopen(fd, "rb")
    try:
        import xarray as xr

        return xr.open_dataset(handle, engine="h5netcdf")
    except Exception as exc:  # any unreadable file is bad input, not a crash
        handle.close()
        return [f"{path}: --overlay: not a readable NetCDF file ({type(exc).__name__}: {exc})"]


def other_machine(ds: xr.Dataset, params: ModelParams, free: tuple[str, ...]) -> list[str]:
    """The parameters, other than ``free``, that the sweep held at other values than
    ``params`` (``"e = 0.3 (this case: 0.2)"``): empty for the same machine."""
    import json
    import math

    try:
        held = json.loads(ds.attrs.get("plan", "{}")).get("params", {})
    except ValueError:
        held = {}
    ours = params.as_dict()
    return [f"{k} = {v:g} (this case: {ours[k]:g})" for k, v in held.items()
            if k in ours and k not in free and not math.isclose(
                v, ours[k], rel_tol=1e-12, abs_tol=1e-15)]  # fmt: skip

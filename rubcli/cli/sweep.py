"""``rubcli sweep CASE [--out DIR] [--workers N] [--scheduler ADDRESS] [--quick]``.

Runs the case's ``[sweep]`` (docs/sweeps.md): every point solved and analysed, on all
local cores (``--workers``, 1 = in this process) or on a Dask cluster (``--scheduler``,
or ``[sweep] scheduler``; ``--scheduler local`` starts a local Dask cluster to try it).
Writes ``sweep.nc``, ``sweep.csv``, ``bifurcation.png`` and ``summary.png`` (1-D model
sweeps), ``cascade.png`` (with ``spectrum = true``), ``map.png`` (2-D model sweeps),
``basins.png`` (initial-state grids) and ``report.json``.

Finished points are kept in a hidden store beside the output dir
(``.<dir name>.sweep-<digest>``) as they finish; running the same command again after an
interruption computes only the missing points. The outputs appear together, when every
point is done; the store is then removed.

Output dir: ``--out DIR``, else ``sweep/`` inside the case's output dir.

A Dask sweep whose scheduler stays unreachable, or has no worker left, for
``[sweep] scheduler_lost_timeout_s`` stops with exit 69; the finished points are kept.

Exit codes: 0 done (failed points are results); 2 invalid input or unreachable scheduler;
69 the Dask scheduler or all its workers were lost mid-sweep (the finished points are
kept); 74 the outputs could not be written (the finished points are kept); 75 the output
dir is in use; 128 + N stopped by signal N (130 Ctrl-C; the finished points are kept).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from rubcli import io
from rubcli.cli import console
from rubcli.cli.common import (
    EXIT_WRITE,
    ForceOption,
    JsonOption,
    WaitOption,
    command_dir,
    emit,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit

LOCAL_SCHEDULER = "local"
EXIT_INTERRUPTED = 130  # Ctrl-C: the finished points are kept for the next run
EXIT_LOST = 69  # EX_UNAVAILABLE: the Dask scheduler or its workers were lost mid-sweep
CLOSE_TIMEOUT_S = 5.0  # bounded wait to close a Dask client (its scheduler may be gone)


def store_dir_for(target: Path, digest: str) -> Path:
    """The hidden store of finished points, beside the output dir."""
    return target.parent / f".{target.name}.sweep-{digest}"


def command(
    case_file: Annotated[Path, typer.Argument(metavar="CASE", help="The case file (TOML).")],
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", metavar="DIR", help="Output dir (default: <case dir>/sweep)."),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option("--workers", "-w", min=1, help="Local processes (default: all cores)."),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            metavar="ADDRESS",
            help="Dask scheduler (tcp://host:port); 'local' starts a local Dask cluster.",
        ),
    ] = None,
    quick: Annotated[
        bool,
        typer.Option(
            "--quick", help="At most 5 values per axis, 20+16 periods, Lyapunov over 20 (CI)."
        ),
    ] = False,
    oversubscribe: Annotated[
        bool,
        typer.Option("--oversubscribe", help="Allow more --workers than this machine's cores."),
    ] = False,
    json: JsonOption = False,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Sweep parameters: bifurcation diagrams, run-up/run-down, 2-D maps, basins."""
    case = load_or_exit(case_file)
    cfg = case.settings.sweep
    if cfg is None:
        console.error(f"{case_file}: sweep: missing table [sweep] (see docs/sweeps.md)")
        raise typer.Exit(EXIT_INVALID)
    from rubcli import sweeps
    from rubcli.analysis import sweep as engine

    address = scheduler if scheduler is not None else cfg.scheduler
    if address in (None, LOCAL_SCHEDULER):  # local processes, or a local Dask cluster
        try:
            workers = engine.check_workers(workers, oversubscribe=oversubscribe)
        except ValueError as exc:
            console.error(f"--{exc}; --oversubscribe allows it")
            raise typer.Exit(EXIT_INVALID) from None
    target = command_dir(case, "sweep", out)
    plan = sweeps.plan_from_case(case, quick)
    output = prepare_output(target, force, wait, expected_files(plan))  # before any work
    client = cluster = None
    if address is not None:
        try:
            if address == LOCAL_SCHEDULER:
                client, cluster = _local_cluster(workers)
            else:
                client = engine.connect(address, timeout=cfg.scheduler_timeout_s)
        except engine.SchedulerError as exc:
            field = "--scheduler" if scheduler is not None else "sweep.scheduler"
            console.error(f"{case_file}: {field}: {exc}")
            raise typer.Exit(EXIT_INVALID) from None

    with console.machine_readable(json):
        _sweep(case_file, case, plan, target, output, client, cluster, workers, scheduler, out,
               quick, json)  # fmt: skip


def _sweep(case_file, case, plan, target, output, client, cluster, workers, scheduler, out,
           quick, json) -> None:  # fmt: skip
    """The sweep itself, once its inputs, output dir and executor are checked."""
    from rubcli import sweeps
    from rubcli.analysis import sweep as engine
    from rubcli.analysis.sweep import basins
    from rubcli.analysis.sweep.dataset import build_dataset

    store_dir = store_dir_for(target, plan.digest())
    console.info(
        f"{case.name}: sweep of {', '.join(a.parameter for a in plan.axes)} "
        f"({plan.n_points} points, {plan.direction}, {plan.transient_periods} + "
        f"{plan.record_periods} periods each"
        + (", stopped once the attractor is recognised" if plan.recognition else "")
        + f", {plan.method})"
        + (" (quick)" if quick else "")
    )
    started = time.perf_counter()
    try:
        with console.count_bar("sweep points", total=plan.n_points) as bar:
            results, stats, where = engine.execute(
                plan,
                workers=workers,
                client=client,
                store_dir=store_dir,
                oversubscribe=True,  # the command checked --workers against the cores
                progress=lambda done, total: bar(done),
                lost_timeout_s=case.settings.sweep.scheduler_lost_timeout_s,
            )
    except engine.StoreError as exc:
        console.error(str(exc))
        raise typer.Exit(EXIT_INVALID) from None
    except engine.ExecutorLostError as exc:
        console.error(f"{case_file}: {exc}: {_kept(store_dir, plan)}; run the same command "
                      "again once the cluster is back (or with --workers to run here)")  # fmt: skip
        raise typer.Exit(EXIT_LOST) from None
    except (KeyboardInterrupt, io.Terminated) as exc:
        _interrupted(exc, store_dir, plan)
    finally:
        if client is not None:
            engine.close_client(client, CLOSE_TIMEOUT_S)
        if cluster is not None:
            cluster.close()
    wall = time.perf_counter() - started
    files: list[str] = []
    try:
        build = basins.build_dataset if plan.recognition is not None else build_dataset
        ds = build(plan, results, sweeps.case_attrs(case))
        report = _write(case_file, case, plan, ds, results, stats, where, wall, target,
                        output, files, _title(case, plan), workers, scheduler, out,
                        quick)  # fmt: skip
    except (KeyboardInterrupt, io.Terminated) as exc:
        if target not in io.outputs.COMMITTED:
            _interrupted(exc, store_dir, plan)
        engine.PointStore(store_dir, plan.digest()).remove()  # the outputs are in place
        raise
    except io.OutputWriteError as exc:
        console.error(f"{exc}; {_kept(store_dir, plan)}: make room and run the same command "
                      "again to write them")  # fmt: skip
        raise typer.Exit(EXIT_WRITE) from None
    engine.PointStore(store_dir, plan.digest()).remove()
    report_stale(output)
    emit(report, json)
    n_failed = report["points_failed"]
    console.info(
        f"{plan.n_points} points on {where} in {wall:.1f} s "
        f"({stats.computed} computed, {stats.resumed} resumed, {n_failed} failed)"
    )
    if stats.rejected:
        console.warning(
            f"{stats.rejected} stored file(s) in {store_dir} failed the store's check "
            "(edited, corrupted or not written by this user): those points were computed again"
        )
    if plan.recognition is not None:
        _basin_lines(report["basins"])
    else:
        for name, count in _class_lines(ds):
            console.info(f"  {name}: {count}")
    console.info(f"wrote {len(files)} files to {target}: {', '.join(files)}")


def _kept(store_dir: Path, plan) -> str:
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


def _interrupted(exc: BaseException, store_dir: Path, plan) -> None:
    """Stopped before the outputs were written: say where the finished points are kept."""
    console.error(
        f"interrupted: {_kept(store_dir, plan)}; "
        "run the same command again to compute only the others (or remove it)"
    )
    code = exc.exit_code if isinstance(exc, io.Terminated) else EXIT_INTERRUPTED
    raise typer.Exit(code) from None


def _write(case_file, case, plan, ds, results, stats, where, wall, target, output, files,
           title, workers, scheduler, out, quick) -> dict:  # fmt: skip
    """Write the sweep's files into its output dir (staged, committed as a whole)."""
    from rubcli.analysis.sweep import basins
    from rubcli.analysis.sweep.dataset import csv_text
    from rubcli.plotting import sweep as plots

    recognised = plan.recognition is not None
    with io.staged_output_dir(target, output) as staged:
        io.write_netcdf(ds, staged.path("sweep.nc"))
        text = basins.csv_text(ds, plan) if recognised else csv_text(ds, plan)
        io.write_text(staged.path("sweep.csv"), text)
        files += ["sweep.nc", "sweep.csv"]
        for name in _figures(plan):
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
        command_line = {"case_file": str(case_file), "out": str(out) if out else None,
                        "workers": workers, "scheduler": scheduler, "quick": quick}  # fmt: skip
        report = {
            **io.report_envelope("sweep", command_line, case.to_dict()),
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
                else {"failed": _failures(ds), "class_counts": _class_counts(ds)}
            ),
            "compute_time_s": computed_s,
            "wall_time_s": wall,
            "files": files,
        }
        staged.write_report(report)
    return report


def expected_files(plan) -> tuple[str, ...]:
    """The files ``rubcli sweep`` writes for ``plan``."""
    return ("sweep.nc", "sweep.csv", *_figures(plan), "report.json")


def _figures(plan) -> list[str]:
    """The figures of a sweep, by file name (``rubcli.plotting.sweep.<stem>_figure``)."""
    if plan.is_basin:
        return ["basins.png"] + (["convergence.png"] if plan.recognition is not None else [])
    if len(plan.axes) == 1:
        return ["bifurcation.png", "summary.png"] + (["cascade.png"] if plan.spectrum else [])
    return ["map.png"]


def _local_cluster(workers: int | None):
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


def _title(case, plan) -> str:
    p = case.params
    swept = {a.parameter for a in plan.axes}
    fixed = ", ".join(f"{k}={v:g}" for k, v in p.as_dict().items() if k not in swept)
    axes = " and ".join(a.parameter for a in plan.axes)
    if plan.recognition is not None:
        budget = plan.transient_periods + plan.record_periods
        how = f"each start until its attractor is recognised, at most {budget} periods"
    else:
        how = (f"{plan.direction}; {plan.transient_periods} transient + "
               f"{plan.record_periods} recorded periods per point")  # fmt: skip
    return f"{case.name}: sweep of {axes} ({how})\n{fixed}"


def _basin_lines(found: dict) -> None:
    """The attractors of a basin grid and how its starts were labelled, on the console."""
    for a in found["attractors"]:
        console.info(f"  A{a['label']}: {a['name']}: {100 * a['basin_fraction']:.1f} % of starts")
    for name in ("not_recognised", "diverged", "failed"):
        if found[name]:
            console.info(f"  {name.replace('_', ' ')}: {found[name]} starts")
    how = ", ".join(f"{n} {k}" for k, n in found["recognised_by"].items() if n)
    console.info(f"  labelled by: {how}; {found['mean_periods_integrated']:.1f} periods "
                 "integrated a start on average")  # fmt: skip


def _failures(ds) -> list[dict]:
    out = []
    status = ds["status"]
    dims = status.dims
    for index in zip(*(status.values != 0).nonzero(), strict=True):
        at = {d: ds[d].values[i].item() for d, i in zip(dims, index, strict=True)}
        at["message"] = str(ds["message"].values[index])
        out.append(at)
    return out


def _class_counts(ds) -> dict[str, int]:
    from rubcli.analysis.sweep.point import RESPONSE_CLASSES

    ok = ds["status"].values == 0
    codes = ds["response_class"].values[ok].astype(int)
    counts = {name: int((codes == i).sum()) for i, name in enumerate(RESPONSE_CLASSES)}
    counts["failed"] = int((~ok).sum())
    return {k: v for k, v in counts.items() if v}


UNCONFIRMED = "chaotic, unconfirmed (Birkhoff test only: no Lyapunov exponent computed)"


def _class_lines(ds) -> list[tuple[str, int]]:
    """The class counts as the console prints them: a "chaotic" point without a Lyapunov
    exponent is counted apart as unconfirmed, as its row of sweep.csv says."""
    import numpy as np

    from rubcli.analysis.sweep.point import RESPONSE_CLASSES

    counts = _class_counts(ds)
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

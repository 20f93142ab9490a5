"""``rubcli sweep CASE [--out DIR] [--workers N] [--scheduler ADDRESS] [--quick]``.

Runs the case's ``[sweep]`` (docs/sweeps.md): every point solved and analysed, on all
local cores (``--workers``, 1 = in this process) or on a Dask cluster (``--scheduler``,
or ``[sweep] scheduler``; ``--scheduler local`` starts a local Dask cluster to try it).
Writes ``sweep.nc``, ``sweep.csv``, ``bifurcation.png`` and ``summary.png`` (1-D model
sweeps), ``cascade.png`` (with ``spectrum = true``), ``map.png`` (2-D model sweeps),
``basins.png`` (initial-state grids) and ``report.json``.

Finished points are kept in a hidden store inside the output dir
(``.rubcli-sweep-<digest>``) as they finish; running the same command again after an
interruption computes only the missing points. The outputs appear together, when every
point is done; the store is then removed, and so are the stores of earlier sweeps into
the dir whose settings have changed since (named in a warning).

Output dir: ``--out DIR``, else ``sweep/`` inside the case's output dir.

A Dask sweep whose scheduler stays unreachable, or has no worker left, for
``[sweep] scheduler_lost_timeout_s`` stops with exit 69; the finished points are kept.

``[sweep] max_wall_time_s`` (default: none; ``--max-wall-time S``) bounds the whole sweep,
looked at every few seconds between points: past it the sweep stops with exit 1, the
finished points kept for the next run.

Exit codes: 0 done (failed points are results); 1 every point failed (the outputs are
written), or the wall-time budget ran out (the finished points are kept); 2 invalid input
or unreachable scheduler; 69 no Dask scheduler answered at the address within
``scheduler_timeout_s`` (another service, a silent listener), or the scheduler or all its
workers were lost mid-sweep (the finished points are kept); 74 the outputs could not be
written (the finished points are kept); 75 the output dir is in use; 128 + N stopped by
signal N (130 Ctrl-C; the finished points are kept).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from rubcli import io
from rubcli.cli import console, progress
from rubcli.cli.common import (
    EXIT_WRITE,
    ForceOption,
    JsonOption,
    WaitOption,
    check_max_wall_time,
    command_dir,
    emit,
    prepare_output,
    report_stale,
)
from rubcli.cli.validate import EXIT_INVALID, load_or_exit
from rubcli.studies import sweep as study

LOCAL_SCHEDULER = "local"
EXIT_BUDGET = 1  # the wall-time budget ran out (the finished points are kept), as for orbits
EXIT_INTERRUPTED = 130  # Ctrl-C: the finished points are kept for the next run
EXIT_LOST = 69  # EX_UNAVAILABLE: no Dask scheduler answered, or it or its workers were lost
CLOSE_TIMEOUT_S = 5.0  # bounded wait to close a Dask client (its scheduler may be gone)


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
    max_wall_time: Annotated[
        float | None,
        typer.Option(
            "--max-wall-time",
            metavar="S",
            help="Wall-time budget in seconds instead of [sweep] max_wall_time_s.",
        ),
    ] = None,
    json: JsonOption = False,
    force: ForceOption = False,
    wait: WaitOption = False,
) -> None:
    """Sweep parameters: bifurcation diagrams, run-up/run-down, 2-D maps, basins."""
    check_max_wall_time(max_wall_time)
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
    output = prepare_output(target, force, wait, study.expected_files(plan))  # before any work
    client = cluster = None
    if address is not None:
        try:
            if address == LOCAL_SCHEDULER:
                client, cluster = study.local_cluster(workers)
            else:
                client = engine.connect(address, timeout=cfg.scheduler_timeout_s)
        except engine.SchedulerError as exc:
            field = "--scheduler" if scheduler is not None else "sweep.scheduler"
            console.error(f"{case_file}: {field}: {exc}")
            lost = isinstance(exc, engine.SchedulerUnavailableError)
            raise typer.Exit(EXIT_LOST if lost else EXIT_INVALID) from None

    with console.machine_readable(json):
        _sweep(case_file, case, plan, target, output, client, cluster, workers, scheduler, out,
               quick, json, max_wall_time)  # fmt: skip


def _sweep(case_file, case, plan, target, output, client, cluster, workers, scheduler, out,
           quick, json, max_wall_time=None) -> None:  # fmt: skip
    """The sweep itself, once its inputs, output dir and executor are checked."""
    from rubcli.analysis import sweep as engine

    store_dir = study.store_dir_for(target, plan.digest())
    console.info(study.describe(case, plan, quick))
    started = time.perf_counter()
    budget = case.settings.sweep.max_wall_time_s if max_wall_time is None else max_wall_time
    try:
        with progress.count_bar("sweep points", total=plan.n_points) as bar:
            results, stats, where = engine.execute(
                plan,
                workers=workers,
                client=client,
                store_dir=store_dir,
                oversubscribe=True,  # the command checked --workers against the cores
                progress=lambda done, total: bar(done),
                lost_timeout_s=case.settings.sweep.scheduler_lost_timeout_s,
                deadline=None if budget is None else started + budget,
            )
    except engine.StoreError as exc:
        console.error(str(exc))
        raise typer.Exit(EXIT_INVALID) from None
    except engine.ExecutorLostError as exc:
        kept = study.kept_text(store_dir, plan)
        console.error(f"{case_file}: {exc}: {kept}; run the same command again once the "
                      "cluster is back (or with --workers to run here)")  # fmt: skip
        raise typer.Exit(EXIT_LOST) from None
    except engine.SweepBudgetError:
        kept = study.kept_text(store_dir, plan)
        console.error(f"{case_file}: stopped by the wall-time budget ({budget:g} s): {kept}; "
                      "run the same command again to compute only the others")  # fmt: skip
        raise typer.Exit(EXIT_BUDGET) from None
    except (KeyboardInterrupt, io.Terminated) as exc:
        _interrupted(exc, store_dir, plan)
    finally:
        if client is not None:
            engine.close_client(client, CLOSE_TIMEOUT_S)
        if cluster is not None:
            cluster.close()
    wall = time.perf_counter() - started
    command_line = {"case_file": str(case_file), "out": str(out) if out else None,
                    "workers": workers, "scheduler": scheduler, "quick": quick,
                    "max_wall_time": max_wall_time}  # fmt: skip
    try:
        ds = study.dataset(case, plan, results)
        report = study.write_outputs(case, plan, ds, results, stats, where, wall, target,
                                     output, command_line)  # fmt: skip
    except (KeyboardInterrupt, io.Terminated) as exc:
        if target not in io.outputs.COMMITTED:
            _interrupted(exc, store_dir, plan)
        engine.PointStore(store_dir, plan.digest()).remove()  # the outputs are in place
        raise
    except io.OutputWriteError as exc:
        kept = study.kept_text(store_dir, plan)
        console.error(f"{exc}; {kept}: make room and run the same command again to write "
                      "them")  # fmt: skip
        raise typer.Exit(EXIT_WRITE) from None
    engine.PointStore(store_dir, plan.digest()).remove()
    _remove_stale_stores(target, plan)
    report_stale(output)
    emit(report, json)
    counts = (f"{where} in {wall:.1f} s ({stats.computed} computed, {stats.resumed} resumed, "
              f"{report['points_failed']} failed)")  # fmt: skip
    for line in study.summary_lines(plan, report, ds, counts):
        console.info(line)
    if stats.rejected:
        console.warning(
            f"{stats.rejected} stored file(s) in {store_dir} failed the store's check "
            "(edited, corrupted or not written by this user): those points were computed again"
        )
    files = report["files"]
    console.info(f"wrote {len(files)} files to {target}: {', '.join(files)}")
    if report["points_failed"] == plan.n_points:
        first = (report.get("failed") or [{}])[0].get("message")
        why = f" (the first: {first})" if first else ""
        console.error(f"{case_file}: every point failed{why}; see {target}/report.json")
        raise typer.Exit(1)


def _remove_stale_stores(target: Path, plan) -> None:
    """The sweep is written: the stores of earlier sweeps into this dir with other settings
    are removed (if this user's own), and named."""
    from rubcli.analysis import sweep as engine

    for path in study.stale_stores(target, plan.digest()):
        if engine.PointStore(path, "").remove():
            console.warning(f"removed {path}: the finished points of an earlier sweep into "
                            f"{target} whose settings have changed since")  # fmt: skip
        else:
            console.warning(f"{path}: a resume store of an earlier sweep into {target} whose "
                            "settings have changed since; not this user's own, so left as it "
                            "is: remove it if it is not needed")  # fmt: skip


def _interrupted(exc: BaseException, store_dir: Path, plan) -> None:
    """Stopped before the outputs were written: say where the finished points are kept."""
    console.error(
        f"interrupted: {study.kept_text(store_dir, plan)}; "
        "run the same command again to compute only the others (or remove it)"
    )
    code = exc.exit_code if isinstance(exc, io.Terminated) else EXIT_INTERRUPTED
    raise typer.Exit(code) from None

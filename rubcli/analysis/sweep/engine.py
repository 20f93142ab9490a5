"""Running a plan: the chains on an executor, every finished point stored as it arrives.

The parent process drives the chains: it submits the first missing point of every chain,
and when a point comes back it stores it and submits the chain's next point with the
final state it carries. Points of different chains run at the same time; the points of
one chain one after the other. Every point is computed by the same pure function from
the same inputs whatever runs it, so the numbers do not depend on the executor or on the
number of workers.

Executors (all ``concurrent.futures`` executors):

- ``InProcessExecutor``: runs each point at submission (``--workers 1``);
- ``concurrent.futures.ProcessPoolExecutor``: a local pool; a worker that dies breaks the
  pool, which is rebuilt, and the points it held are submitted again (up to
  ``MAX_RETRIES`` times each);
- Dask: ``distributed.Client(address).get_executor()``, Dask's own executor over its
  futures; Dask itself retries the tasks of a lost worker. A ``watch`` callable, called
  every ``WATCH_INTERVAL_S`` while points are in flight, raises ``ExecutorLostError`` when the
  scheduler or every worker has been gone too long: the finished points stay stored.
  A task that comes back cancelled (its scheduler connection dropped) is never recorded
  as a result: its point is held and submitted again once the watch finds the executor
  well (``ExecutorLostError`` after ``MAX_RETRIES`` such drops of one point).

The numba kernels are compiled (or loaded from numba's cache) in the parent by a tiny
solve before any worker starts (``warm_up``).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from rubcli.analysis.sweep.plan import Chain, Point, SweepPlan
from rubcli.analysis.sweep.point import PointResult, PointTask, compute_points, failed
from rubcli.analysis.sweep.store import PointStore

if TYPE_CHECKING:
    from collections.abc import Iterable

MAX_RETRIES = 3  # a point whose worker died this many times is recorded as failed
IN_FLIGHT_PER_WORKER = 4  # points queued per worker (keeps memory and Ctrl-C short)
WATCH_INTERVAL_S = 2.0  # how often ``watch`` looks at the executor while waiting


class ExecutorLostError(Exception):
    """The executor can no longer run points (a Dask scheduler gone, no worker left)."""


class InProcessExecutor(cf.Executor):
    """Runs every submitted call at once, in this process (``--workers 1``)."""

    def submit(  # type: ignore[override]
        self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any
    ) -> cf.Future:
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:
            future.set_exception(exc)
        return future


def task_for(plan: SweepPlan, point: Point, start: Iterable[float]) -> PointTask:
    return PointTask(
        params=point.params,
        start=tuple(float(v) for v in start),  # type: ignore[arg-type]
        transient_periods=plan.transient_periods,
        record_periods=plan.record_periods,
        samples_per_period=plan.samples_per_period,
        method=plan.method,
        options=dict(plan.options),
        energy=plan.energy,
        spectrum=plan.spectrum,
        spectrum_max_order=plan.spectrum_max_order,
        lyapunov=plan.lyapunov,
        lyapunov_periods=plan.lyapunov_periods,
    )


def warm_up(method: str, options: dict, recognition: bool = False) -> None:
    """Compile or load the solver's kernels here, before workers start (a 2-period solve),
    and with ``recognition`` the basin recognition kernel."""
    from rubcli.model import ModelParams
    from rubcli.problem import Problem
    from rubcli.solvers import solve

    params = ModelParams(nu=0.01, eta=0.8, e=1.0, K=10.0, mu=0.1, Rp=5.0, phi0=0.0)
    problem = Problem.from_periods(params, (0.9, 0.0, 0.0, 0.0), 2, 8)
    solve(problem, method, **options)
    if recognition:
        from rubcli.analysis.sweep import recognise_kernel

        recognise_kernel.warm_up()


@dataclass
class _Cursor:
    chain: Chain
    position: int = 0
    carry: tuple | None = None  # final state of the chain's last good point


@dataclass
class RunStats:
    computed: int = 0  # points computed in this run
    resumed: int = 0  # points found in the store
    rejected: int = 0  # stored point files that failed the store's check (recomputed)
    retried: int = 0  # resubmissions after a lost worker
    pool_restarts: int = 0


def run_plan(
    plan: SweepPlan,
    executor: cf.Executor,
    *,
    store: PointStore | None = None,
    workers: int = 1,
    batch: int = 1,
    progress: Callable[[int, int], None] | None = None,
    rebuild: Callable[[], cf.Executor] | None = None,
    watch: Callable[[], None] | None = None,
) -> tuple[dict[str, PointResult], RunStats]:
    """Compute every missing point of ``plan``; returns all results by point key.

    ``batch`` points of different chains go in one task (fewer round trips on Dask; the
    points of a batch are stored when it returns). ``rebuild`` makes a new executor when
    the current one breaks (a local pool whose worker died); ``progress(done, total)`` is
    called after every point; ``watch()`` is called at least every ``WATCH_INTERVAL_S``
    and raises ``ExecutorLostError`` to stop the run (the points finished so far are stored).
    """
    results: dict[str, PointResult] = dict(store.load()) if store is not None else {}
    stats = RunStats(resumed=len(results), rejected=len(store.rejected) if store else 0)
    total = plan.n_points
    cursors = [_Cursor(chain) for chain in plan.chains()]
    ready = list(reversed(cursors))  # a stack: chains are started in plan order
    in_flight: dict[cf.Future, list[tuple[_Cursor, Point, PointTask]]] = {}
    attempts: dict[str, int] = {}
    limit = max(1, workers * IN_FLIGHT_PER_WORKER)
    done_count = len(results)
    if progress is not None:
        progress(done_count, total)

    def next_task(cursor: _Cursor) -> tuple[Point, PointTask] | None:
        """Advance through stored points; the chain's first missing point, or None."""
        points = cursor.chain.points
        while cursor.position < len(points):
            point = points[cursor.position]
            start = point.start if point.start is not None else cursor.carry
            if start is None:  # a continuation with no good state before it
                start = plan.initial
            stored = results.get(point.key)
            if stored is None:
                return point, task_for(plan, point, start)
            if stored.ok and stored.final_state is not None:
                cursor.carry = stored.final_state
            elif point.start is not None:
                cursor.carry = None
            cursor.position += 1
        return None

    def fill() -> None:
        while ready and len(in_flight) < limit:
            group: list[tuple[_Cursor, Point, PointTask]] = []
            while ready and len(group) < batch:
                cursor = ready.pop()
                found = next_task(cursor)
                if found is not None:
                    group.append((cursor, *found))
            if group:
                tasks = [task for _, _, task in group]
                in_flight[executor.submit(compute_points, tasks)] = group

    def record(point: Point, result: PointResult) -> None:
        nonlocal done_count
        results[point.key] = result
        if store is not None:
            store.save(point.key, result)
        stats.computed += 1
        done_count += 1
        if progress is not None:
            progress(done_count, total)

    held: list[tuple[_Cursor, Point]] = []  # points whose task the executor dropped
    cancelled: dict[str, int] = {}
    watched = time.monotonic()

    def look() -> None:
        """``watch()`` (ExecutorLostError stops the run); the held points go back once it
        finds the executor well."""
        nonlocal watched
        assert watch is not None
        watch()
        watched = time.monotonic()
        for cursor, point in held:
            cancelled[point.key] = cancelled.get(point.key, 0) + 1
            if cancelled[point.key] > MAX_RETRIES:
                dropped = f"the executor dropped point {point.key} {MAX_RETRIES} times"
                raise ExecutorLostError(dropped)
            ready.append(cursor)
        held.clear()

    try:
        fill()
        while in_flight or held:
            if not in_flight:
                time.sleep(WATCH_INTERVAL_S)
                finished: set[cf.Future] = set()
            else:
                finished, _ = cf.wait(
                    list(in_flight),
                    timeout=None if watch is None else WATCH_INTERVAL_S,
                    return_when=cf.FIRST_COMPLETED,
                )
            if watch is not None and (held or time.monotonic() - watched >= WATCH_INTERVAL_S):
                look()
            broken = False
            for future in finished:
                group = in_flight.pop(future)
                try:
                    returned = future.result()
                except BrokenProcessPool:
                    broken = True
                    for cursor, point, _task in group:
                        attempts[point.key] = attempts.get(point.key, 0) + 1
                        if attempts[point.key] < MAX_RETRIES:
                            stats.retried += 1  # submitted again from the same state
                        else:
                            record(point, failed(f"worker died {MAX_RETRIES} times on it"))
                        ready.append(cursor)
                    continue
                except Exception as exc:  # compute_points never raises: the executor did
                    if watch is not None and type(exc).__name__ != "KilledWorker":
                        # Dask cancelled it (its scheduler connection dropped): not a
                        # result; held until the watch finds the executor well again
                        held.extend((cursor, point) for cursor, point, _task in group)
                        continue
                    # KilledWorker: the point killed Dask's workers as often as Dask allows
                    message = f"executor: {type(exc).__name__}: {exc}"
                    returned = [failed(message)] * len(group)
                for (cursor, point, _task), result in zip(group, returned, strict=True):
                    record(point, result)
                    ready.append(cursor)
            if broken:
                if rebuild is None:
                    raise RuntimeError("the process pool broke and cannot be rebuilt")
                # every point still held by the broken pool is lost: submit it again
                for group in in_flight.values():
                    for cursor, point, _task in group:
                        attempts[point.key] = attempts.get(point.key, 0) + 1
                        ready.append(cursor)
                        stats.retried += 1
                in_flight.clear()
                executor.shutdown(wait=False, cancel_futures=True)
                executor = rebuild()
                stats.pool_restarts += 1
            fill()
    finally:
        for future in in_flight:
            with contextlib.suppress(Exception):  # a closed Dask client may refuse
                future.cancel()
    return results, stats

"""Parameter sweeps: bifurcation diagrams, run-up/run-down, 2-D maps and basins.

- ``plan``: the axes, points and continuation chains (``SweepPlan``);
- ``point``: one point solved and analysed (``compute_point``, run by every executor);
- ``engine``: the chains on an executor, finished points stored as they arrive;
- ``store``: the resumable store (one ``.point`` file per point, keyed by the plan's digest);
- ``dataset``: the results as an ``xarray.Dataset``, NetCDF and CSV.

``execute(plan, workers=..., scheduler=..., store_dir=...)`` picks the executor and runs
the plan; ``rubcli.sweeps.sweep`` does the same from a case file. docs/sweeps.md.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import os
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from rubcli.analysis.runs.processes import local_pool
from rubcli.analysis.sweep.engine import (
    ExecutorLostError,
    InProcessExecutor,
    RunStats,
    run_plan,
    warm_up,
)
from rubcli.analysis.sweep.plan import Axis, SweepPlan
from rubcli.analysis.sweep.store import PointStore, StoreError

if TYPE_CHECKING:
    from distributed import Client

    from rubcli.analysis.sweep.basins import BasinResult
    from rubcli.analysis.sweep.point import PointResult

__all__ = [
    "Axis",
    "ExecutorLostError",
    "PointStore",
    "StoreError",
    "RunStats",
    "SchedulerError",
    "SchedulerUnavailableError",
    "SweepBudgetError",
    "SweepPlan",
    "dask_executor",
    "default_workers",
    "execute",
    "run_plan",
]

CONNECT_TIMEOUT_S = 10.0  # bounded wait for a Dask scheduler
LOST_TIMEOUT_S = 60.0  # bounded wait for a lost scheduler, or for a worker when none is left
MAX_GREETING_BYTES = 1 << 16  # a Dask handshake is a small dict: a longer one is not one
MAX_BATCH = 8  # points per task at most: a Dask round trip costs milliseconds, a pool's ~0.1


class SchedulerError(Exception):
    """The Dask scheduler cannot be reached (or Dask is not installed)."""


class SweepBudgetError(Exception):
    """The sweep's wall-time budget is spent (the points finished so far are in the store)."""


class SchedulerUnavailableError(SchedulerError):
    """Something answers at the scheduler's address, but no Dask scheduler in time."""


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def check_workers(workers: int | None, *, oversubscribe: bool = False) -> int:
    """The number of local worker processes: ``workers`` (default: all cores).

    More processes than the cores this process may use only slow a sweep down (each point
    is CPU-bound) and, by the thousand, exhaust the machine's memory and process table:
    refused unless ``oversubscribe``.
    """
    cores = default_workers()
    if workers is None:
        return cores
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers: must be a positive integer (got {workers!r})")
    if workers > cores and not oversubscribe:
        raise ValueError(
            f"workers: {workers} processes on {cores} core(s): at most {cores} "
            "(each run is CPU-bound: more processes only slow the work down)"
        )
    return workers


def reachable_or_raise(address: str, timeout: float) -> None:
    """SchedulerError unless ``address`` is a tcp:// or tls:// address that accepts a
    connection (checked before a ``Client`` is made, since a Client whose connection fails
    prints a traceback from its finaliser some 20 s later); SchedulerUnavailableError
    unless, on tcp://, what answers there greets as a Dask peer within ``timeout``.

    A Dask peer writes its handshake as soon as a connection is made: an 8-byte length,
    then that many bytes of msgpack frames holding a dict. The greeting is read here, on a
    plain socket with a deadline, because ``distributed`` reads a peer's handshake without
    one (a silent listener holds the Client for ever) and allocates whatever length the
    first 8 bytes say (random bytes: exabytes, a MemoryError)."""
    import socket

    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        host, port = parse_host_port(location)
    except ValueError as exc:
        raise SchedulerError(f"not a scheduler address ({exc}): give tcp://host:port") from None
    if scheme not in ("tcp", "tls"):
        raise SchedulerError(
            f"{address!r}: a Dask scheduler speaks tcp:// or tls://, not {scheme}://"
        )
    deadline = time.monotonic() + timeout
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as exc:
        raise SchedulerError(
            f"cannot reach the Dask scheduler at {address!r} within {timeout:g} s: {exc}"
        ) from None
    with sock:
        # on tls:// the greeting comes after the TLS handshake: connect's deadline holds
        problem = _greeting_problem(sock, deadline) if scheme == "tcp" else ""
    if problem:
        raise SchedulerUnavailableError(
            f"no Dask scheduler answered at {address!r} within {timeout:g} s: {problem}"
        )


def _greeting_problem(sock, deadline: float) -> str:
    """Why what ``sock`` sends first is not a Dask handshake ('' if it is)."""
    import struct

    header = _receive(sock, 8, deadline)
    if len(header) < 8:
        return "the handshake was cut short" if header else "the peer sent no handshake"
    (length,) = struct.unpack("<Q", header)
    if not 0 < length <= MAX_GREETING_BYTES:
        return "the peer's first bytes are not a Dask handshake"
    body = _receive(sock, length, deadline)
    if len(body) < length:
        return "the handshake was cut short"
    try:
        from distributed.protocol import loads
        from distributed.protocol.utils import unpack_frames

        greeting = loads(unpack_frames(body))
    except Exception:  # any bytes may come: whatever fails to decode is not a handshake
        greeting = None
    return "" if isinstance(greeting, dict) else "the peer's first bytes are not a Dask handshake"


def _receive(sock, n: int, deadline: float) -> bytes:
    """Up to ``n`` bytes from ``sock``, fewer if it closes or ``deadline`` passes."""
    out = bytearray()
    while len(out) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            break
        sock.settimeout(left)
        try:
            chunk = sock.recv(n - len(out))
        except OSError:  # the deadline passed, or the peer reset the connection
            break
        if not chunk:
            break
        out += chunk
    return bytes(out)


def connect(address: str, timeout: float = CONNECT_TIMEOUT_S) -> Client:
    """A ``distributed.Client`` of the scheduler at ``address`` within about ``timeout``
    s; SchedulerError if it cannot be reached, SchedulerUnavailableError if no scheduler
    answers there in time (a wrong service, a silent listener). The Client is made in a
    thread with ``timeout`` of its own, and waited for at most twice that: no peer holds
    the command longer."""
    import threading

    try:
        from distributed import Client
    except ImportError:
        raise SchedulerError(
            'Dask is not installed: pip install -e ".[dask]" (or "rubcli[dask]")'
        ) from None
    reachable_or_raise(address, timeout)
    made: dict = {}

    def make() -> None:
        try:
            made["client"] = Client(address, timeout=timeout, set_as_default=False)
        except Exception as exc:  # raised again in the caller's thread, below
            made["error"] = exc

    thread = threading.Thread(target=make, name="rubcli-dask-connect", daemon=True)
    thread.start()
    thread.join(2.0 * timeout)
    if thread.is_alive():
        raise SchedulerUnavailableError(
            f"no Dask scheduler answered at {address!r} within {timeout:g} s"
        )
    exc = made.get("error")
    if isinstance(exc, (OSError, TimeoutError, ValueError)):
        raise SchedulerError(
            f"cannot reach the Dask scheduler at {address!r} within {timeout:g} s: {exc}"
        )
    if exc is not None:
        raise SchedulerUnavailableError(
            f"no Dask scheduler answered at {address!r}: {type(exc).__name__}: {exc}"
        )
    return made["client"]


@contextlib.contextmanager
def dask_executor(client: Client) -> Iterator[cf.Executor]:
    """Dask's own ``concurrent.futures`` executor over ``client``."""
    executor = client.get_executor(pure=False)  # no hashing of the arguments per task
    try:
        yield executor
    finally:
        with contextlib.suppress(Exception):  # a client that lost its scheduler may refuse
            executor.shutdown(wait=False)


def task_batch(n_points: int, n_workers: int, n_chains: int | None = None) -> int:
    """Points per task (Dask or a local pool): up to MAX_BATCH, keeping >= 8 tasks per
    worker and, as a batch holds the next points of different chains, no more chains in
    a batch than keep every worker busy (two chains on two workers: one point a task,
    not one task holding both chains' points on one worker)."""
    limit = MAX_BATCH if n_chains is None else max(1, n_chains // n_workers)
    return max(1, min(MAX_BATCH, limit, n_points // (8 * n_workers)))


def dask_workers(client: Client) -> int:
    """The scheduler's worker count now (0 when it has none)."""
    try:
        return len(client.scheduler_info(n_workers=-1)["workers"])
    except TypeError:  # older distributed without n_workers
        return len(client.scheduler_info()["workers"])


def dask_watch(client: Client, lost_timeout_s: float) -> Callable[[], None]:
    """A ``run_plan`` watch: ``ExecutorLostError`` once the scheduler has been unreachable, or
    has had no worker, for ``lost_timeout_s`` (at once when the client gave up and closed).

    A scheduler killed mid-sweep cancels every task in flight and leaves the client
    reconnecting; workers that all died leave the tasks pending with nobody to run them.
    Either way nothing would ever come back: the watch bounds the wait."""
    address = client.scheduler.address
    lost_since: float | None = None

    def watch() -> None:
        nonlocal lost_since
        problem = None
        if client.status != "running":
            problem = f"the Dask scheduler at {address} is unreachable"
        else:
            try:
                if dask_workers(client) == 0:
                    problem = f"the Dask scheduler at {address} has no worker"
            except Exception:  # its connection dropped between the two calls
                problem = f"the Dask scheduler at {address} is unreachable"
        now = time.monotonic()
        if problem is None:
            lost_since = None
            return
        if lost_since is None:
            lost_since = now
        if client.status in ("closing", "closed") or now - lost_since >= lost_timeout_s:
            raise ExecutorLostError(f"{problem} (waited {now - lost_since:.0f} s)")

    return watch


def close_client(client: Client, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Close a Dask client in bounded time, quietly (its scheduler may be gone)."""
    with quiet_dask_client(), contextlib.suppress(Exception):
        client.close(timeout=timeout)


@contextlib.contextmanager
def quiet_dask_client() -> Iterator[None]:
    """Silence ``distributed``'s logs in this process (``distributed.client``'s errors, and
    the INFO record with a traceback that ``distributed.batched`` writes when the
    connection to a killed scheduler closes in the middle of a write), and tornado's log of
    an exception in an event-loop callback (the client's, when its connection breaks),
    while a sweep runs: a lost scheduler or worker is reported by the sweep in one line,
    not by tracebacks."""
    import logging

    names = ("distributed", "distributed.client", "tornado.application")
    loggers = [logging.getLogger(name) for name in names]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels, strict=True):
            logger.setLevel(level)


def budget_watch(
    deadline: float | None, inner: Callable[[], None] | None = None
) -> Callable[[], None] | None:
    """A ``run_plan`` watch: ``inner()``, then ``SweepBudgetError`` once
    ``time.perf_counter()`` has passed ``deadline`` (``inner`` alone without a deadline)."""
    if deadline is None:
        return inner

    def watch() -> None:
        if inner is not None:
            inner()
        if time.perf_counter() > deadline:
            raise SweepBudgetError("wall-time budget exhausted")

    return watch


def _run(plan: SweepPlan, executor: cf.Executor, *, store, workers: int = 1, batch: int = 1,
         progress=None, rebuild=None, watch=None):  # fmt: skip
    """``engine.run_plan``, or ``basins.run_basins`` for a grid with recognition."""
    if plan.recognition is None:
        return run_plan(plan, executor, store=store, workers=workers, batch=batch,
                        progress=progress, rebuild=rebuild, watch=watch)  # fmt: skip
    from rubcli.analysis.sweep.basins import run_basins

    result = run_basins(plan, plan.recognition, executor, store=store, progress=progress,
                        rebuild=rebuild, watch=watch)  # fmt: skip
    stats = RunStats(computed=result.points_computed, resumed=result.points_resumed,
                     rejected=result.chunks_rejected)  # fmt: skip
    return result, stats


def execute(
    plan: SweepPlan,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    client: Client | None = None,
    store_dir: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
    oversubscribe: bool = False,
    lost_timeout_s: float = LOST_TIMEOUT_S,
    deadline: float | None = None,
) -> tuple[dict[str, PointResult] | BasinResult, RunStats, str]:
    """Run ``plan``; returns ``(results by point key, RunStats, executor description)``;
    for a basin grid with recognition, the results are a ``basins.BasinResult``.

    ``client`` (a ``distributed.Client``) or ``scheduler`` (its address) runs the points
    on Dask; otherwise ``workers`` local processes (default: all cores; 1 runs here).
    ``store_dir`` keeps finished points so that an interrupted run resumes.
    ``oversubscribe`` allows more local processes than cores (``check_workers``).
    On Dask, ``ExecutorLostError`` once the scheduler has been unreachable, or has had no
    worker, for ``lost_timeout_s`` (the finished points are in the store).
    ``SweepBudgetError`` once ``time.perf_counter()`` passes ``deadline`` (looked at every
    few seconds between points; the finished points are in the store).
    """
    if client is None and scheduler is None:
        n = check_workers(workers, oversubscribe=oversubscribe)
    store = PointStore(store_dir, plan.digest(), plan.to_dict()) if store_dir else None
    if store is not None:
        store.check()  # StoreError before any work when the store is not this user's
    warm_up(plan.method, plan.options, plan.recognition is not None)
    own_client = None
    if client is None and scheduler is not None:
        client = own_client = connect(scheduler)
    try:
        if client is not None:
            n = max(1, dask_workers(client))
            # the kernels loaded on every worker
            client.run(warm_up, plan.method, plan.options, plan.recognition is not None)
            with quiet_dask_client(), dask_executor(client) as executor:
                results, stats = _run(
                    plan, executor, store=store, workers=n, progress=progress,
                    batch=task_batch(plan.n_points, n, plan.n_chains),
                    watch=budget_watch(deadline, dask_watch(client, lost_timeout_s)),
                )  # fmt: skip
            return (
                results,
                stats,
                (
                    f"dask ({n} workers at the start, scheduler {client.scheduler.address}; "
                    "Dask resubmits a lost worker's tasks itself, uncounted here)"
                ),
            )
        if n == 1:
            results, stats = _run(plan, InProcessExecutor(), store=store, progress=progress,
                                  watch=budget_watch(deadline))  # fmt: skip
            return results, stats, "this process (1 worker)"
        pools: list[cf.ProcessPoolExecutor] = []

        def rebuild() -> cf.Executor:
            pools.append(local_pool(n))
            return pools[-1]

        try:
            results, stats = _run(
                plan, rebuild(), store=store, workers=n, progress=progress, rebuild=rebuild,
                batch=task_batch(plan.n_points, n, plan.n_chains), watch=budget_watch(deadline),
            )  # fmt: skip
        finally:
            for pool in pools:
                pool.shutdown(wait=True, cancel_futures=True)
        return results, stats, f"process pool ({n} workers)"
    finally:
        if own_client is not None:
            close_client(own_client)

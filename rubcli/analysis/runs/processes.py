"""Local worker processes that never outlive the command that started them.

A ``ProcessPoolExecutor``'s workers wait for their next task on a pipe; when the parent is
killed outright (SIGKILL, the OOM killer) nothing tells them, and they go on computing
their current task and then wait for ever. On Linux each worker asks the kernel to kill it
when its parent dies (``prctl(PR_SET_PDEATHSIG, SIGKILL)``): the parent keeps every
finished result, so a worker has nothing to save. Elsewhere nothing ends such workers
early: stop a command with Ctrl-C or SIGTERM, which shut its pool down.

A terminal's Ctrl-C (SIGINT) and hang-up (SIGHUP) go to the whole process group: the
workers ignore them and the parent, which handles them (``rubcli.io.signals``), stops its
pool (``LocalPool``: the workers are killed, whatever the pipes between them hold). A
SIGTERM ends a worker at once, its default.
"""

from __future__ import annotations

import concurrent.futures as cf
import ctypes
import functools
import multiprocessing.connection
import os
import signal
import sys
from collections.abc import Callable
from typing import Any

from rubcli.io.signals import deferred

PR_SET_PDEATHSIG = 1  # linux/prctl.h
STOP_S = 10.0  # how long stopping a pool waits for its workers and its thread (a bound)


def die_with_parent(parent: int) -> None:
    """Worker initializer: be killed when ``parent`` dies (Linux); exit now if it has."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the request took effect
        os._exit(0)


def start_worker(parent: int) -> None:
    """Worker initializer: ``die_with_parent``; the terminal's signals are the parent's to
    handle (ignored here), SIGTERM ends the worker (the default, not the parent's
    handler that the worker inherits)."""
    die_with_parent(parent)
    for name in ("SIGINT", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _settle(outer: cf.Future, inner: cf.Future) -> None:
    """Give ``outer`` the outcome of the pool's own future ``inner``."""
    if inner.cancelled():
        outer.set_exception(cf.CancelledError())
    elif inner.exception() is not None:
        outer.set_exception(inner.exception())
    else:
        outer.set_result(inner.result())


class LocalPool(cf.ProcessPoolExecutor):
    """A ``ProcessPoolExecutor`` that stops in bounded time when its work is abandoned.

    ``shutdown(cancel_futures=True)`` while work is still queued or running (a command
    leaving on a signal or an error), and leaving its ``with`` block on an exception,
    kill the workers (nobody will read their results), then let the pool's thread end:
    a task half-written into a worker's pipe or a result half-written back cannot block
    it. Otherwise ``shutdown`` is the executor's own.

    The futures it returns are never cancelled by their ``cancel()`` (which returns
    False): the pool drops its own queued work when shut down. (A future cancelled under
    the pool's thread makes that thread fail when a worker dies, on Python 3.11, before
    it has released the pipes.)
    """

    def __init__(self, workers: int) -> None:
        super().__init__(max_workers=workers, initializer=start_worker, initargs=(os.getpid(),))

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future:
        inner = super().submit(fn, *args, **kwargs)
        outer: cf.Future = cf.Future()
        outer.set_running_or_notify_cancel()  # cancel() is now a no-op
        inner.add_done_callback(functools.partial(_settle, outer))
        return outer

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        if cancel_futures and self._pending_work_items:
            self._stop()
        else:
            super().shutdown(wait, cancel_futures=cancel_futures)

    def __exit__(self, kind, value, traceback) -> bool:
        self.shutdown(wait=True, cancel_futures=kind is not None)
        return False

    def _stop(self) -> None:
        """Cancel the queued work, kill the workers, and wait (at most ``STOP_S`` each)
        for them to die and for the pool's thread to end; a signal meanwhile is raised
        after (``deferred``)."""
        workers = list((self._processes or {}).values())
        results, thread = self._result_queue, self._executor_manager_thread
        with deferred():
            super().shutdown(wait=False, cancel_futures=True)
            for worker in workers:
                worker.kill()
            multiprocessing.connection.wait([w.sentinel for w in workers], timeout=STOP_S)
            if results is not None:
                # The pool's thread may be reading a result that a killed worker left
                # half-written: with this process's own end of the pipe closed it reads
                # the end of the pipe (and finds the pool broken) instead of waiting.
                results._writer.close()
            if thread is not None:
                thread.join(STOP_S)


def local_pool(workers: int) -> LocalPool:
    """A pool of ``workers`` processes that die with this one (``LocalPool``)."""
    return LocalPool(workers)

"""A command's work beside its main thread (``Background``). The termination signals are
in ``signals``: leaving the block on their ``Terminated`` stops the job."""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from typing import Any

from rubcli.io.signals import checkpoint


class Cancelled(Exception):  # noqa: N818 - not an error: the job was told to stop
    """A background job stopped because the command is leaving on an exception."""


class Background:
    """One worker thread for a command's output work, beside the main thread.

    ``rubcli run`` writes the methods' CSVs here while the main thread computes the
    report entries (the energy balance) and draws the figures, once every method is
    solved (a timed solve never shares the machine with it): the CSV formatter and the
    energy kernel are compiled ``nogil``, so on two cores the two threads overlap. Jobs
    run one at a time in submission order.

    Leaving the block normally waits for every job and re-raises the first job's
    exception. Leaving it on an exception (a signal's ``Terminated`` included) drops
    the queued jobs and stops a running one at its next progress report (``Cancelled``),
    then waits for the thread: nothing writes into a staged dir after it is discarded.
    """

    POLL_S = 0.05  # how often ``wait`` refreshes a progress bar

    def __init__(self) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rubcli-output")
        self._cancel = threading.Event()
        self._jobs: list[
            tuple[Future, str | None, float, list[float], Callable[[], bool] | None]
        ] = []

    def submit(self, fn: Callable[..., Any], *args: Any, progress: tuple[str, float] | None
               = None, helper: Callable[[], bool] | None = None,
               **kwargs: Any) -> Future:  # fmt: skip
        """Run ``fn(*args, **kwargs)`` in the worker. With ``progress = (label, total)``,
        ``fn`` also gets ``on_rows=`` (``write_csv``'s callback), which records the work
        done for ``wait``'s progress bar and stops the job when the command is leaving.
        ``helper``: a piece of the job the waiting thread may do itself (it returns False
        when there is none left to take: ``SharedBlocks.work``)."""
        done = [0.0]
        if progress is not None:

            def on_rows(count: float) -> None:
                if self._cancel.is_set():
                    raise Cancelled
                done[0] = count

            kwargs["on_rows"] = on_rows
        future = self._pool.submit(fn, *args, **kwargs)
        label, total = progress if progress is not None else (None, 0.0)
        self._jobs.append((future, label, total, done, helper))
        return future

    def wait(self, bar: Callable[[str, float], Any] | None = None) -> None:
        """Wait for every job, in order, doing the pieces of it the job offers (``helper``)
        meanwhile; a job still running shows ``bar(label, total)`` (a context manager
        yielding ``update(done)``, as ``progress.progress_bar``). Re-raises the first
        failed job's exception."""
        for future, label, total, done, helper in self._jobs:
            if not future.done() and bar is not None and label is not None:
                with bar(label, total) as update:
                    self._help_until_done(future, helper, lambda u=update, d=done: u(d[0]))
                    update(total)
            elif not future.done():
                self._help_until_done(future, helper, lambda: None)
            future.result()

    def _help_until_done(self, future: Future, helper: Callable[[], bool] | None,
                         report: Callable[[], Any]) -> None:  # fmt: skip
        while not future.done():
            checkpoint()  # a termination signal that something swallowed
            if helper is None or not helper():
                wait_for([future], timeout=self.POLL_S)
            report()

    def __enter__(self) -> Background:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is not None:
            self._cancel.set()
            self._pool.shutdown(wait=True, cancel_futures=True)
            return
        try:
            self.wait()
        finally:
            self._cancel.set()
            self._pool.shutdown(wait=True, cancel_futures=True)

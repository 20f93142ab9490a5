"""Progress on the terminal (rich): a bar over a quantity, a bar over counted items,
and, where no bar shows (a log, a pipe), a progress line every few seconds. Shown on
stderr; nothing in machine-readable mode (``console.machine_readable``)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from rubcli.cli.console import is_machine_readable, printable, stderr_console


@contextmanager
def progress_bar(description: str, total: float) -> Iterator[Callable[[float], None]]:
    """A progress bar from 0 to ``total``; yields ``update(done)``.

    Shown only on a terminal (in a pipe or a log it would only add noise). Updates are
    thinned to about 200 per bar, so that a solver calling back at every step is not slowed.
    """
    console = stderr_console()
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TaskProgressColumn(),
        TimeElapsedColumn(),
        console=console,
        disable=is_machine_readable() or not console.is_terminal,
        transient=False,
    )
    task = bar.add_task(printable(description), total=total)
    stride = total / 200.0 if total > 0 else 0.0
    last = [-float("inf")]

    def update(done: float) -> None:
        if done - last[0] >= stride:
            last[0] = done
            bar.update(task, completed=min(done, total))

    with bar:
        yield update
        bar.update(task, completed=last[0] if last[0] > 0 else 0.0)


@contextmanager
def count_bar(description: str, total: int) -> Iterator[Callable[[int], None]]:
    """A bar of ``total`` items (done/total, rate, elapsed, ETA); yields ``update(done)``.

    For work counted in items (the points of a sweep). Shown only on a terminal.
    """
    console = stderr_console()
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=console,
        disable=not console.is_terminal,
        transient=False,
    )
    task = bar.add_task(printable(description), total=total, rate="")
    started: list = [None]

    def update(done: int) -> None:
        now = time.perf_counter()
        if started[0] is None:
            started[0] = (now, done)
        t0, d0 = started[0]
        rate = (done - d0) / (now - t0) if now > t0 and done > d0 else 0.0
        bar.update(task, completed=done, rate=f"{rate:.2f} points/s" if rate else "")

    with bar:
        yield update


@contextmanager
def progress_lines(status: Callable[[], str], every_s: float = 10.0) -> Iterator[None]:
    """Where no progress bar shows (stderr is not a terminal: a log, a pipe, a batch job),
    print ``progress: <status()>`` on stderr when the block starts and every ``every_s``
    seconds while it runs, so that a long computation is never silent. Nothing on a
    terminal (the bars show there)."""
    if stderr_console().is_terminal:
        yield
        return
    done = threading.Event()

    def line() -> None:
        stderr_console().print(f"progress: {printable(status())}", markup=False, soft_wrap=True)

    def beat() -> None:
        while not done.wait(every_s):
            line()

    line()

    thread = threading.Thread(target=beat, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()

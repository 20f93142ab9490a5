"""All terminal output of the command line goes through this module (rich).

Results and plain text go to stdout, diagnostics (errors, warnings) to stderr. The rich
consoles follow ``sys.stdout``/``sys.stderr`` at the time of each call, so output can be
captured (typer's ``CliRunner``, pytest's capsys). Markup is off for text that comes from
users or exceptions, so square brackets in ``[model]`` are printed as they are.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

from rich import box
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table


def _stdout() -> Console:
    return Console(file=sys.stdout, highlight=False)


def _stderr() -> Console:
    return Console(file=sys.stderr, highlight=False)


def raw(text: str) -> None:
    """Print text exactly as it is (no markup, no wrapping), e.g. a sample case file."""
    sys.stdout.write(text)
    sys.stdout.flush()


def info(message: str) -> None:
    _stdout().print(message, markup=False, soft_wrap=True)


def success(message: str) -> None:
    _stdout().print(message, style="green", markup=False, soft_wrap=True)


def warning(message: str) -> None:
    _stderr().print(f"warning: {message}", style="yellow", markup=False, soft_wrap=True)


def error(message: str) -> None:
    """An error for the user; each line of ``message`` printed as it is."""
    _stderr().print(f"error: {message}", style="bold red", markup=False, soft_wrap=True)


def error_lines(header: str, lines: Sequence[str]) -> None:
    """An error with one line per problem (e.g. every invalid field of a case file)."""
    console = _stderr()
    console.print(f"error: {header}", style="bold red", markup=False, soft_wrap=True)
    for line in lines:
        console.print(f"  {line}", style="red", markup=False, soft_wrap=True)


def exception(exc: BaseException) -> None:
    """An unexpected exception with its traceback (never swallowed silently)."""
    from rich.traceback import Traceback

    _stderr().print(Traceback.from_exception(type(exc), exc, exc.__traceback__))


def table(
    title: str, columns: Sequence[str], rows: Sequence[Sequence[str]], caption: str | None = None
) -> None:
    """A table of results on stdout. Cells keep their width (a header may fold instead)."""
    out = Table(
        title=title, title_justify="left", box=box.SIMPLE_HEAD, caption=caption,
        caption_justify="left", pad_edge=False, collapse_padding=True,
    )  # fmt: skip
    for i, name in enumerate(columns):
        width = max((len(str(row[i])) for row in rows), default=0)
        out.add_column(name, overflow="fold", min_width=width)
    for row in rows:
        out.add_row(*row)
    _stdout().print(out)


@contextmanager
def progress_bar(description: str, total: float) -> Iterator[Callable[[float], None]]:
    """A progress bar from 0 to ``total``; yields ``update(done)``.

    Shown only on a terminal (in a pipe or a log it would only add noise). Updates are
    thinned to about 200 per bar, so that a solver calling back at every step is not slowed.
    """
    console = _stderr()
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TaskProgressColumn(),
        TimeElapsedColumn(),
        console=console,
        disable=not console.is_terminal,
        transient=False,
    )
    task = bar.add_task(description, total=total)
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
    console = _stderr()
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
    task = bar.add_task(description, total=total, rate="")
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

"""Tables of results on stdout, fitted to the output's width (rich): columns of words wrap,
numbers and names are never cut. Nothing is printed in machine-readable mode
(``console.machine_readable``)."""

from __future__ import annotations

import os
from collections.abc import Sequence

from rich import box
from rich.console import Console
from rich.table import Table

from rubcli.cli.console import (
    is_machine_readable,
    printable,
    require_stdout,
    stdout_console,
    writing_stdout,
)


def table(
    title: str, columns: Sequence[str], rows: Sequence[Sequence[str]], caption: str | None = None
) -> None:
    """A table of results on stdout, fitted to ``output_width()``.

    Columns of words (notes, messages) wrap within their cells; numbers and names are
    never cut or wrapped. Only when those alone are wider than the width is the table
    printed wider (a cut number would be a wrong number)."""
    if is_machine_readable():
        return
    title, caption = printable(title), caption and printable(caption)
    rows = [[printable(str(cell)) for cell in row] for row in rows]
    out = Table(
        title=title, title_justify="left", box=box.SIMPLE_HEAD, caption=caption,
        caption_justify="left", pad_edge=False, collapse_padding=True,
    )  # fmt: skip
    fixed = 0  # the width the unbreakable columns need
    for i, name in enumerate(columns):
        cells = [str(row[i]) for row in rows]
        width = max((len(c) for c in cells), default=0)
        words = any(" " in c for c in cells)
        if words:  # wraps at spaces, down to its longest word
            longest = max((len(w) for c in cells for w in c.split()), default=0)
            out.add_column(name, overflow="fold", min_width=min(longest, 12))
            fixed += max(longest, min(len(name), 12)) + 2
        else:
            out.add_column(name, overflow="fold", min_width=width, no_wrap=True)
            fixed += max(width, min(len(name), 12)) + 2
    for row in rows:
        out.add_row(*row)
    width = max(output_width(), fixed)
    with writing_stdout():
        Console(file=require_stdout(), highlight=False, width=width).print(out)


DEFAULT_WIDTH = 100  # text width when stdout is not a terminal and COLUMNS is not set


def output_width() -> int:
    """The width text is fitted to: the terminal's, or (a pipe, a log file) ``COLUMNS``
    when it is set, else ``DEFAULT_WIDTH``."""
    console = stdout_console()
    if console.is_terminal:
        return console.width
    columns = os.environ.get("COLUMNS", "")
    return int(columns) if columns.isdigit() and int(columns) > 0 else DEFAULT_WIDTH

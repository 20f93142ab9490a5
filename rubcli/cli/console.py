"""All terminal output of the command line goes through this module (rich).

Results and plain text go to stdout, diagnostics (errors, warnings) to stderr. The rich
consoles follow ``sys.stdout``/``sys.stderr`` at the time of each call, so output can be
captured (typer's ``CliRunner``, pytest's capsys). Markup is off for text that comes from
users or exceptions, so square brackets in ``[model]`` are printed as they are, and
control characters in it (an escape sequence in a case's description, name or path, which
would retitle or reprogram the terminal) are printed escaped (``printable``).

Machine-readable mode (``--json``, ``machine_readable()``): stdout carries only the JSON
result (``json_result``); text, tables and progress bars are not shown; warnings and
errors still go to stderr. Python warnings (e.g. numpy's "invalid value encountered")
are shown as one formatted ``warning:`` line (``show_python_warning``), never raw.

A failure to write stdout (``> /dev/full``, a closed pipe, no stdout at all: ``>&-``)
raises ``StdoutError``, which the command line turns into a message on stderr and exit
code 74 (141 for a closed pipe). Without a stderr (``2>&-``) diagnostics are dropped.
"""

from __future__ import annotations

import errno
import io
import re
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

from rich.console import Console


class StdoutError(Exception):
    """Standard output could not be written (a full disk, a closed pipe)."""

    def __init__(self, exc: OSError):
        self.errno = exc.errno
        super().__init__(exc.strerror or str(exc))


@contextmanager
def writing_stdout() -> Iterator[None]:
    """A write to stdout: its OSError raised as ``StdoutError``."""
    try:
        yield
    except OSError as exc:
        raise StdoutError(exc) from None


def require_stdout() -> TextIO:
    """``sys.stdout``; ``StdoutError`` if the process has none (started with it closed)."""
    if sys.stdout is None:
        raise StdoutError(OSError(errno.EBADF, "it is closed"))
    return sys.stdout


def flush_stdout() -> None:
    """Flush stdout now (a write error then surfaces as ``StdoutError``, not at exit)."""
    with writing_stdout():
        require_stdout().flush()


_machine = [False]  # --json: stdout carries only the JSON result
MAX_VALUE_CHARS = 200  # longer user values are shortened in messages (shorten())


def stdout_console() -> Console:
    """The console of results (stdout, followed at each call)."""
    return Console(file=require_stdout(), highlight=False)


@contextmanager
def machine_readable(enabled: bool = True) -> Iterator[None]:
    """While the block runs, print nothing on stdout but ``json_result`` (if enabled)."""
    previous = _machine[0]
    _machine[0] = enabled or previous
    try:
        yield
    finally:
        _machine[0] = previous


def is_machine_readable() -> bool:
    return _machine[0]


def json_result(text: str) -> None:
    """The JSON result of a command (``--json``): on stdout, exactly as given."""
    with writing_stdout():
        stdout = require_stdout()
        stdout.write(text)
        stdout.flush()


# C0 and C1 controls but newline and tab, DEL, and the invisible bidirectional overrides
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")


def printable(text: str) -> str:
    """``text`` with its control characters written as escapes (``\\x1b``): a value from a
    case file or a path cannot drive the terminal it is printed on."""
    return _CONTROL.sub(lambda m: repr(m.group())[1:-1], text)


def shorten(text: str, limit: int = MAX_VALUE_CHARS) -> str:
    """``text`` cut to ``limit`` characters, saying how long it was."""
    if len(text) <= limit:
        return text
    return f"{text[: limit - 30]}... ({len(text)} characters)"


def show_python_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """``warnings.showwarning`` replacement: one formatted line on stderr."""
    where = f"{Path(filename).name}:{lineno}"
    warning(f"{category.__name__}: {shorten(str(message))} ({where})")


@contextmanager
def formatted_python_warnings() -> Iterator[None]:
    """Show Python warnings (numpy's included) through ``warning``, once per place."""
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = show_python_warning
        yield


def stderr_console() -> Console:
    """The console of diagnostics and progress (stderr, followed at each call; a process
    without a stderr drops them, where rich would print them on stdout)."""
    return Console(file=sys.stderr if sys.stderr is not None else io.StringIO(), highlight=False)


def raw(text: str) -> None:
    """Print text exactly as it is (no markup, no wrapping), e.g. a sample case file."""
    with writing_stdout():
        stdout = require_stdout()
        stdout.write(text)
        stdout.flush()


def info(message: str) -> None:
    if not _machine[0]:
        with writing_stdout():
            stdout_console().print(printable(message), markup=False, soft_wrap=True)


@contextmanager
def notice_if_slow(message: str, after_s: float = 3.0) -> Iterator[None]:
    """Print ``message`` (as ``info``) if the block is still running ``after_s`` seconds
    in: for a wait that is usually short and only sometimes long (numba compiling the
    kernels on a first run, which would otherwise look like a hang). Printed from a timer
    thread; nothing if the block ends sooner."""
    timer = threading.Timer(after_s, info, args=(message,))
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


def success(message: str) -> None:
    if not _machine[0]:
        with writing_stdout():
            stdout_console().print(printable(message), style="green", markup=False, soft_wrap=True)


def warning(message: str) -> None:
    text = f"warning: {printable(message)}"
    stderr_console().print(text, style="yellow", markup=False, soft_wrap=True)


def error(message: str) -> None:
    """An error for the user; each line of ``message`` printed as it is."""
    text = f"error: {printable(message)}"
    stderr_console().print(text, style="bold red", markup=False, soft_wrap=True)


def error_lines(header: str, lines: Sequence[str]) -> None:
    """An error with one line per problem (e.g. every invalid field of a case file)."""
    console = stderr_console()
    console.print(f"error: {printable(header)}", style="bold red", markup=False, soft_wrap=True)
    for line in lines:
        console.print(f"  {printable(line)}", style="red", markup=False, soft_wrap=True)


def exception(exc: BaseException) -> None:
    """An unexpected exception with its traceback (never swallowed silently)."""
    from rich.traceback import Traceback

    stderr_console().print(Traceback.from_exception(type(exc), exc, exc.__traceback__))

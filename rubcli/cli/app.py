"""The ``rubcli`` typer app. It registers commands (one module per command) and turns what
ends a command early into a message and its documented exit code (``RubcliGroup``).

To add a command, write ``rubcli/cli/<name>.py`` with a ``command`` function and add one
line below, e.g. ``app.command("forces-map")(forces_map.command)``.
"""

from __future__ import annotations

import errno
import os
import sys
from typing import Annotated, Any

import typer
from typer.core import TyperGroup

from rubcli import __version__, io
from rubcli.cli import (
    chart,
    compare,
    console,
    ensemble,
    export_matrices,
    forces_map,
    init,
    orbits,
    run,
    stress,
    sweep,
    validate,
)
from rubcli.cli.common import EXIT_BUSY, EXIT_INVALID, EXIT_WRITE, close_outputs
from rubcli.cli.entry import main
from rubcli.io import signals

__all__ = ["app", "main"]


class RubcliGroup(TyperGroup):
    """Runs a command; a signal, an unusable or busy output dir, a full disk or a stdout
    that cannot be written end it with a message on stderr and its exit code, never a
    traceback (README, "Exit codes")."""

    def make_context(
        self, info_name: str | None, args: list[str], parent: Any = None, **extra: Any
    ) -> typer.Context:
        # The group's own help (--help, or no arguments) is printed while its arguments are
        # parsed, before invoke: a stdout that is missing or cannot be written ends it too.
        try:
            console.require_stdout()
            return super().make_context(info_name, args, parent, **extra)
        except console.StdoutError as exc:
            _stdout_failed(exc)
        except OSError as exc:
            if not io.is_write_failure(exc):
                raise
            _stdout_failed(console.StdoutError(exc))

    def invoke(self, ctx: typer.Context) -> Any:
        io.outputs.COMMITTED.clear()
        try:
            console.require_stdout()  # no stdout at all (>&-): refused before anything runs
            result = super().invoke(ctx)
            console.flush_stdout()  # a full stdout fails here, not at the interpreter's exit
            return result
        except (typer.Exit, typer.Abort, typer.TyperException):
            raise
        except signals.Terminated as exc:
            _leave(signals.stop_message(exc.signum), exc.exit_code)
        except io.OutputBusy as exc:
            _leave(str(exc), EXIT_BUSY)
        except io.OutputWriteError as exc:
            _leave(str(exc), EXIT_WRITE)
        except io.OutputError as exc:
            _leave(str(exc), EXIT_INVALID)
        except console.StdoutError as exc:
            _stdout_failed(exc)
        except MemoryError:
            _leave("out of memory: the command needed more memory than this process may "
                   "take (a smaller case, or more memory)", EXIT_INVALID)  # fmt: skip
        except Exception as exc:
            if signals.pending() is not None:  # what a signal left behind
                _leave(signals.stop_message(signals.pending()), 128 + signals.pending())
            if io.is_write_failure(exc):
                where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
                _leave(f"could not write: {where}{exc.strerror or exc}", EXIT_WRITE)
            raise
        finally:
            close_outputs()  # the output dirs' locks, on every way out


def _leave(message: str, code: int):
    console.error(message)
    raise typer.Exit(code) from None


def _stdout_failed(exc: console.StdoutError):
    _silence_stdout()
    if exc.errno == errno.EPIPE:  # a reader that stopped reading (| head): no message
        raise typer.Exit(128 + 13) from None
    _leave(f"cannot write to standard output: {exc}", EXIT_WRITE)


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's last flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass


def _flags_show_no_type() -> None:
    """Boolean flags (``--quick``, ``--json``, ``--help``) listed in ``--help`` without a
    type: they take no value. Some typer releases print every option's type in the rich
    help panel, a flag as ``--quick <bool>``, which reads as if it wanted a value; typer's
    plain help already leaves it out. A no-op where typer has no such hook."""
    from typer import core

    option = getattr(core, "TyperOption", None)
    shown = getattr(option, "display_type_rich", None)
    if shown is None or getattr(shown, "_rubcli_flags", False):
        return

    def display_type_rich(self: Any, ctx: typer.Context) -> str | None:  # self: TyperOption
        if getattr(self, "is_flag", False) and not getattr(self, "count", False):
            return None
        return shown(self, ctx)

    display_type_rich._rubcli_flags = True
    option.display_type_rich = display_type_rich


def _help_to_a_closed_pipe_is_a_stdout_error() -> None:
    """typer prints the help through a rich console of its own, whose closed pipe (``rubcli
    --help | head -1``) is rich's silent exit 1: there it raises ``StdoutError``, so that
    the help ends as a command's output to a closed pipe does (exit 141). A no-op where
    typer prints no rich help."""
    try:
        from typer import rich_utils
    except ImportError:
        return
    made = getattr(rich_utils, "_get_rich_console", None)
    if made is None or getattr(made, "_rubcli_pipe", False):
        return

    def _get_rich_console(stderr: bool = False) -> Any:
        help_console = made(stderr=stderr)
        if not stderr:

            def on_broken_pipe() -> None:
                help_console.quiet = True
                raise console.StdoutError(OSError(errno.EPIPE, os.strerror(errno.EPIPE)))

            help_console.on_broken_pipe = on_broken_pipe
        return help_console

    _get_rich_console._rubcli_pipe = True
    rich_utils._get_rich_console = _get_rich_console


_flags_show_no_type()
_help_to_a_closed_pipe_is_a_stdout_error()

app = typer.Typer(
    name="rubcli",
    cls=RubcliGroup,
    help="Jeffcott rotor rubbing on a circular stator: the paper's analytic solution "
    "beside scipy's integrators, driven by TOML case files.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
)

app.command("init")(init.command)
app.command("validate")(validate.command)
app.command("run")(run.command)
app.command("forces-map")(forces_map.command)
app.command("compare")(compare.command)
app.command("stress")(stress.command)
app.command("sweep")(sweep.command)
app.command("orbits")(orbits.command)
app.command("ensemble")(ensemble.command)
app.command("chart")(chart.command)
app.command("export-matrices")(export_matrices.command)


def _version(value: bool) -> None:
    if value:
        try:
            console.info(f"rubcli {__version__}")
        except console.StdoutError as exc:
            _stdout_failed(exc)
        raise typer.Exit()


@app.callback()
def _root(
    ctx: typer.Context,
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Show the version."),
    ] = False,
) -> None:
    """Jeffcott rotor rubbing on a circular stator (rubcli)."""
    # For the whole command: Python warnings as formatted lines, and SIGTERM/SIGINT/SIGHUP
    # as io.Terminated (installed by the entry point already; here for in-process runs).
    ctx.with_resource(console.formatted_python_warnings())
    ctx.with_resource(signals.termination_as_exception())

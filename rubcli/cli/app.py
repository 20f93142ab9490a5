"""The ``rubcli`` typer app. It only registers commands: one module per command.

To add a command, write ``rubcli/cli/<name>.py`` with a ``command`` function and add one
line below, e.g. ``app.command("forces-map")(forces_map.command)``.
"""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from rubcli import __version__, io
from rubcli.cli import compare, forces_map, init, orbits, run, stress, sweep, validate


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

    def display_type_rich(self, ctx):
        if getattr(self, "is_flag", False) and not getattr(self, "count", False):
            return None
        return shown(self, ctx)

    display_type_rich._rubcli_flags = True
    option.display_type_rich = display_type_rich


_flags_show_no_type()

app = typer.Typer(
    name="rubcli",
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


def _version(value: bool) -> None:
    if value:
        from rubcli.cli import console

        console.info(f"rubcli {__version__}")
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
    from rubcli.cli import console

    # For the whole command: Python warnings as formatted lines, and SIGTERM/SIGINT/SIGHUP
    # as io.Terminated, so that staged outputs are removed on the way out.
    ctx.with_resource(console.formatted_python_warnings())
    ctx.with_resource(io.termination_as_exception())


def main() -> None:
    """Entry point of the ``rubcli`` script and ``python -m rubcli``.

    A termination signal ends the command with exit code 128 + the signal number (130 for
    Ctrl-C, 143 for SIGTERM), after its staged outputs were removed; earlier outputs stay.
    """
    try:
        app()
    except io.Terminated as exc:
        from rubcli.cli import console

        console.error(f"{exc}: stopped, no outputs of this run were written")
        sys.exit(exc.exit_code)

"""The ``rubcli`` typer app. It only registers commands: one module per command.

To add a command, write ``rubcli/cli/<name>.py`` with a ``command`` function and add one
line below, e.g. ``app.command("forces-map")(forces_map.command)``.
"""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from rubcli import __version__, io
from rubcli.cli import (
    compare,
    ensemble,
    forces_map,
    init,
    orbits,
    run,
    stress,
    sweep,
    validate,
)

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
app.command("ensemble")(ensemble.command)


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

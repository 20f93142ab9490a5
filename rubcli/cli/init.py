"""``rubcli init``: print a commented sample case file to stdout (``rubcli.samples``)."""

from __future__ import annotations

from typing import Annotated

import typer

from rubcli.cli import console
from rubcli.samples import MACHINES, sample_case


def command(
    physical: Annotated[
        bool,
        typer.Option("--physical", help="Print a sample in SI units (a \\[physical] table)."),
    ] = False,
    machine: Annotated[
        str,
        typer.Option(
            "--machine",
            help="paper (a concentric rigid stator, isotropic support) or general (an offset "
            "stator, a static load, anisotropic and cross-coupled supports).",
        ),
    ] = "paper",
) -> None:
    """Print a commented sample case file (redirect it: rubcli init > my.toml)."""
    if machine not in MACHINES:
        console.error(f"--machine: must be paper or general (got {machine!r})")
        raise typer.Exit(2)
    console.raw(sample_case(machine, physical))

"""``rubcli export-matrices``: a ROSS rotor file's matrices at a speed, as the ``.npz`` a
matrices case reads without ROSS (``[rotor] matrices``; ``rubcli.machine.ross``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from rubcli.case import CaseError
from rubcli.cli import console
from rubcli.cli.common import EXIT_INVALID


def command(
    rotor_file: Annotated[
        Path, typer.Argument(help="A ROSS rotor file (Rotor.save: .toml, .json).")
    ],
    speed: Annotated[
        float, typer.Option("--speed", help="The running speed (rpm): bearings at this speed.")
    ],
    out: Annotated[Path, typer.Option("--out", help="The .npz file to write.")],
    force: Annotated[bool, typer.Option("--force", help="Replace an existing file.")] = False,
) -> None:
    """Write a ROSS rotor's M, K, C, G (and its shaft's outer radius a node) at a speed."""
    from rubcli.case.rotor import MAX_SPEED_RPM, check_ross_file
    from rubcli.machine import ross

    if not (math.isfinite(speed) and 0.0 <= speed <= MAX_SPEED_RPM):
        _refuse(f"--speed: must be between 0 and {MAX_SPEED_RPM:g} rpm (got {speed:g})")
    if out.suffix != ".npz" or "\0" in str(out):
        _refuse(f"--out: {out}: the matrices file's name must end in .npz")
    if (out.exists() or out.is_symlink()) and not force:
        _refuse(f"--out: {out} exists (--force replaces it)")
    if out.is_dir():
        _refuse(f"--out: {out} is a directory")
    try:
        check_ross_file(rotor_file, "ROTOR_FILE")
        rotor = ross.load_ross_rotor(rotor_file)
        arrays = ross.export_matrices(rotor, speed * 2.0 * math.pi / 60.0, out)
    except CaseError as exc:
        console.error_lines(f"cannot export {rotor_file}", exc.problems)
        raise typer.Exit(EXIT_INVALID) from None
    except ross.RossError as exc:
        _refuse(f"ROTOR_FILE: {exc}")
    n = arrays["M"].shape[0]
    console.success(
        f"wrote {out}: {n} coordinates ({int(arrays['number_dof'])} a node) at {speed:g} rpm"
    )


def _refuse(message: str) -> None:
    console.error(message)
    raise typer.Exit(EXIT_INVALID)

"""What every command shares: the ``--json``, ``--force`` and ``--out`` options, the output
dir check (once, before anything is computed), and how a result reaches the user.

A command that writes files::

    plan = prepare_output(target, force)          # exit 2 with the reason if unusable
    with machine_readable(json):                  # --json: stdout is only the result
        ...compute...
        with io.staged_output_dir(target, plan) as staged:
            ...write into staged.path(name)...
        report_stale(plan)                        # name the stale files removed
        emit(report, json)                        # the JSON result with --json

New commands (sweep, orbits) use the same three options and the same helpers.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from rubcli import io
from rubcli.cli import console
from rubcli.cli.console import machine_readable

__all__ = [
    "EXIT_INVALID",
    "ForceOption",
    "JsonOption",
    "emit",
    "machine_readable",
    "prepare_output",
    "report_stale",
]

EXIT_INVALID = 2

JsonOption = Annotated[
    bool,
    typer.Option(
        "--json",
        help="Print only the JSON result (the report) on stdout: no tables, no progress.",
    ),
]
ForceOption = Annotated[
    bool,
    typer.Option(
        "--force",
        help="Write into a non-empty output dir that rubcli did not write (its other "
        "files are left alone).",
    ),
]


def prepare_output(target: Path, force: bool = False) -> io.OutputPlan:
    """Check the output dir before solving (``io.check_output_dir``); exit 2 if unusable."""
    try:
        plan = io.check_output_dir(target, force=force)
    except io.OutputError as exc:
        console.error(str(exc))
        raise typer.Exit(EXIT_INVALID) from None
    if plan.foreign and force and not plan.previous:
        console.warning(
            f"{target}: --force: writing beside {len(plan.foreign)} files rubcli did not write"
        )
    return plan


def report_stale(plan: io.OutputPlan) -> None:
    """Warn about the files of the previous run that were removed as stale."""
    if plan.removed:
        console.warning(
            f"{plan.target}: removed {len(plan.removed)} files of the previous run that this "
            f"run did not produce: {', '.join(plan.removed)}"
        )


def emit(report: dict[str, Any], json: bool) -> None:
    """With ``--json``, print the report as the command's only stdout."""
    if json:
        console.json_result(io.json_text(report))

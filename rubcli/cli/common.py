"""What every command shares: the ``--json``, ``--force``, ``--wait`` and ``--out`` options,
the output dir rule, the output dir check (once, before anything is computed: the dir is
then locked until the command ends), and how a result reaches the user.

A command that writes files::

    target = command_dir(case, "compare", out)    # --out, else <case output dir>/compare
    plan = prepare_output(target, force, wait)    # exit 2 (75 if busy) with the reason
    with machine_readable(json):                  # --json: stdout is only the result
        ...compute...
        with io.staged_output_dir(target, plan) as staged:
            ...write into staged.path(name)...
        report_stale(plan)                        # name the stale files removed
        emit(report, json)                        # the JSON result with --json

Exit codes of every command (README, "Exit codes"): 2 invalid input or an unusable output
dir, 74 the outputs (or the output dir's lock) could not be written (disk full; nothing of
the run is written), 75 the output dir is in use by another rubcli command, 128 + N
stopped by signal N.
"""

from __future__ import annotations

import atexit
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from rubcli import io
from rubcli.cli import console
from rubcli.cli.console import machine_readable

if TYPE_CHECKING:
    from rubcli.case import Case

__all__ = [
    "EXIT_BUSY",
    "EXIT_INVALID",
    "EXIT_WRITE",
    "ForceOption",
    "JsonOption",
    "WaitOption",
    "budget_spent",
    "check_max_wall_time",
    "check_memory",
    "close_outputs",
    "command_dir",
    "emit",
    "machine_readable",
    "prepare_output",
    "report_stale",
]

EXIT_INVALID = 2
EXIT_WRITE = 74  # sysexits' EX_IOERR: the outputs could not be written
EXIT_BUSY = 75  # sysexits' EX_TEMPFAIL: the output dir is in use; try again (or --wait)


def budget_spent(case_file: object, budget: float, field: str) -> typer.Exit:
    """A command stopped by its wall-time budget before writing anything: the message, and
    the exit (1) for the caller to raise; ``field`` is the case's key of that budget."""
    console.error(f"{case_file}: stopped by the wall-time budget ({budget:g} s): nothing "
                  f"written (--max-wall-time or {field} for more)")  # fmt: skip
    return typer.Exit(1)


def check_max_wall_time(max_wall_time: float | None) -> None:
    """``--max-wall-time``, if given, must be a finite number > 0 (else exit 2)."""
    if max_wall_time is not None and not (math.isfinite(max_wall_time) and max_wall_time > 0):
        console.error(f"--max-wall-time: must be a finite number > 0 (got {max_wall_time!r})")
        raise typer.Exit(EXIT_INVALID)


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
        help="Write into an output dir that holds files rubcli did not write (or that were "
        "changed since): files named like this command's outputs are replaced, the others "
        "are kept.",
    ),
]
WaitOption = Annotated[
    bool,
    typer.Option(
        "--wait",
        help="If another rubcli command is writing to the output dir, wait for it to finish "
        "(without: stop at once, exit 75).",
    ),
]


def check_memory(case_file: Path, samples: int, methods: int, fields: str = "time.periods") -> None:
    """Exit 2 if ``samples`` output samples for each of ``methods`` solutions held at once
    will not fit in the memory this process may take (``case.run_memory_bytes``, the
    estimate of ``rubcli run``; the case's own check bounds them by 8 GiB on any machine);
    ``fields``: the entry that sets the span, named in the message."""
    from rubcli import case as case_module
    from rubcli.studies.forces_map import available_memory_bytes

    need = case_module.run_memory_bytes(samples, methods)
    have = available_memory_bytes()
    if have is None or need <= have:
        return
    per = f"{methods} method" + ("s" if methods > 1 else "")
    console.error(
        f"{case_file}: {fields}, time.samples_per_period: {samples:,} output samples x "
        f"{per} need about {need / 1024**3:.3g} GiB of memory, and this process may take "
        f"{have / 1024**3:.3g} GiB; shorten the run or take fewer samples per period"
    )
    raise typer.Exit(EXIT_INVALID)


def command_dir(case: Case, command: str, out: Path | None) -> Path:
    """The output dir rule: ``--out`` if given, else ``<case output dir>/<command>``
    (``run`` alone writes the case's output dir itself)."""
    return Path(out) if out is not None else case.output_dir / command


def prepare_output(
    target: Path, force: bool = False, wait: bool = False, expected: tuple[str, ...] = ()
) -> io.OutputPlan:
    """Lock and check the output dir before anything is computed (``io.open_output_dir``);
    exit 2 if unusable, 74 if it cannot be written (a full disk), 75 if another command
    holds it (unless ``wait``). The lock is released when the command ends
    (``close_outputs``). ``expected``: names the command will write."""

    def waiting(holder: str) -> None:
        console.warning(f"{target}: in use by {holder}; waiting for it (--wait)")

    try:
        plan = io.open_output_dir(
            target, force=force, wait=wait, expected=expected, on_wait=waiting
        )
    except io.OutputBusy as exc:
        console.error(str(exc))
        raise typer.Exit(EXIT_BUSY) from None
    except io.OutputWriteError as exc:  # no room even for its lock (or the manifest key)
        console.error(str(exc))
        raise typer.Exit(EXIT_WRITE) from None
    except io.OutputError as exc:
        console.error(str(exc))
        raise typer.Exit(EXIT_INVALID) from None
    _open_plans.append(plan)
    for line in plan.recovered:
        console.warning(f"{target}: {line}")
    if plan.foreign and force and not plan.previous:
        console.warning(
            f"{target}: --force: writing beside {len(plan.foreign)} files rubcli did not write"
        )
    return plan


_open_plans: list[io.OutputPlan] = []  # output dirs locked by this command


@atexit.register
def close_outputs() -> None:
    """Release the output dirs ``prepare_output`` locked (when the command ends)."""
    while _open_plans:
        _open_plans.pop().close()


def report_stale(plan: io.OutputPlan) -> None:
    """Warn about the files of the previous run that were removed as stale, and those kept
    because they changed since rubcli wrote them."""
    if plan.removed:
        console.warning(
            f"{plan.target}: removed {len(plan.removed)} files of the previous run that this "
            f"run did not produce: {', '.join(plan.removed)}"
        )
    if plan.kept:
        console.warning(
            f"{plan.target}: kept {', '.join(plan.kept)}: written by an earlier run but "
            "changed since, so not rubcli's to remove"
        )


def emit(report: dict[str, Any], json: bool) -> None:
    """With ``--json``, print the report as the command's only stdout."""
    if json:
        console.json_result(io.json_text(report))

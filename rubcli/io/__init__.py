"""Writing results: atomic files, CSV tables, JSON reports, figures, output dirs.

- ``files``: ``atomic_path`` (written beside the target, moved over it: a reader never
  sees a half-written file), text, JSON reports (``report_envelope``), figures;
- ``tables``: the CSV of a solution and the one CSV writer, ``write_csv`` (shortest
  round-trip floats, in blocks of rows, compiled formatting for large blocks), with
  ``SharedBlocks`` for a second thread to format ahead of the writer;
- ``outputs``: the one writer of output dirs: locked (``lock``), checked before anything
  is computed (``open_output_dir``), written staged and committed as a whole
  (``staged_output_dir``), with a signed manifest of the files rubcli wrote (``manifest``);
- ``background``: a command's work beside its main thread (``Background``);
- ``signals``: the termination signals as ``Terminated``, raised only where it is safe,
  held across a commit.

The commands use them as ``from rubcli import io`` then ``io.write_csv``, ``io.Background``
and so on: the names below are the package's interface. They are imported on first use,
so that ``rubcli.io.signals`` (standard library only) loads before numpy does.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

_MODULES = {
    "background": ("Background", "Cancelled"),
    "signals": ("TERMINATION_SIGNALS", "Terminated", "checkpoint", "deferred",
                "termination_as_exception"),
    "files": ("atomic_path", "environment_info", "json_text", "report_envelope", "save_figure",
              "to_jsonable", "write_json", "write_netcdf", "write_text"),
    "outputs": ("REPORT_NAME", "STAGING_PREFIX", "OutputBusy", "OutputError", "OutputPlan",
                "OutputWriteError", "StagedOutput", "is_write_failure",
                "open_output_dir", "read_manifest", "staged_output_dir"),
    "tables": ("CSV_BLOCK_ROWS", "CSV_COLUMNS", "CSV_COMPILED_MIN_ROWS", "CSV_PHYSICAL_COLUMNS",
               "Labels", "SharedBlocks", "csv_field", "rows_to_block", "shared_solution_blocks",
               "solution_blocks", "solution_columns", "solution_header", "write_csv",
               "write_rows_csv", "write_solution_csv"),
}  # fmt: skip
_WHERE = {name: module for module, names in _MODULES.items() for name in names}

__all__ = [
    "Background",
    "CSV_BLOCK_ROWS",
    "CSV_COLUMNS",
    "CSV_COMPILED_MIN_ROWS",
    "CSV_PHYSICAL_COLUMNS",
    "Cancelled",
    "Labels",
    "OutputBusy",
    "OutputError",
    "OutputPlan",
    "OutputWriteError",
    "REPORT_NAME",
    "STAGING_PREFIX",
    "SharedBlocks",
    "StagedOutput",
    "TERMINATION_SIGNALS",
    "Terminated",
    "atomic_path",
    "checkpoint",
    "csv_field",
    "deferred",
    "environment_info",
    "is_write_failure",
    "json_text",
    "open_output_dir",
    "read_manifest",
    "report_envelope",
    "rows_to_block",
    "save_figure",
    "shared_solution_blocks",
    "solution_blocks",
    "solution_columns",
    "solution_header",
    "staged_output_dir",
    "termination_as_exception",
    "to_jsonable",
    "write_csv",
    "write_json",
    "write_netcdf",
    "write_rows_csv",
    "write_solution_csv",
    "write_text",
]

if TYPE_CHECKING:
    from rubcli.io.background import Background, Cancelled
    from rubcli.io.files import (
        atomic_path,
        environment_info,
        json_text,
        report_envelope,
        save_figure,
        to_jsonable,
        write_json,
        write_netcdf,
        write_text,
    )
    from rubcli.io.outputs import (
        REPORT_NAME,
        STAGING_PREFIX,
        OutputBusy,
        OutputError,
        OutputPlan,
        OutputWriteError,
        StagedOutput,
        is_write_failure,
        open_output_dir,
        read_manifest,
        staged_output_dir,
    )
    from rubcli.io.signals import (
        TERMINATION_SIGNALS,
        Terminated,
        checkpoint,
        deferred,
        termination_as_exception,
    )
    from rubcli.io.tables import (
        CSV_BLOCK_ROWS,
        CSV_COLUMNS,
        CSV_COMPILED_MIN_ROWS,
        CSV_PHYSICAL_COLUMNS,
        Labels,
        SharedBlocks,
        csv_field,
        rows_to_block,
        shared_solution_blocks,
        solution_blocks,
        solution_columns,
        solution_header,
        write_csv,
        write_rows_csv,
        write_solution_csv,
    )


def __getattr__(name: str) -> Any:
    if name in _MODULES or name in ("lock", "manifest"):
        return importlib.import_module(f"rubcli.io.{name}")
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'rubcli.io' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"rubcli.io.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

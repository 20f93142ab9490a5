"""Writing results: atomic files, CSV tables, JSON reports, figures, staged output dirs.

- ``files``: ``atomic_path`` (written beside the target, moved over it: a reader never
  sees a half-written file), text, JSON reports (``report_envelope``), figures;
- ``tables``: the CSV of a solution and the one CSV writer, ``write_csv`` (shortest
  round-trip floats, in blocks of rows, compiled formatting for large blocks), with
  ``SharedBlocks`` for a second thread to format ahead of the writer;
- ``outputs``: the rules of an output dir (``check_output_dir``) and staged writing
  (``staged_output_dir``): a run that fails part way leaves no outputs;
- ``background``: a command's work beside its main thread (``Background``) and the
  termination signals as an exception (``Terminated``).

The commands use them as ``from rubcli import io`` then ``io.write_csv``, ``io.Background``
and so on: the names below are the package's interface.
"""

from rubcli.io.background import (
    TERMINATION_SIGNALS,
    Background,
    Cancelled,
    Terminated,
    termination_as_exception,
)
from rubcli.io.files import (
    atomic_path,
    environment_info,
    json_text,
    report_envelope,
    save_figure,
    to_jsonable,
    write_json,
    write_text,
)
from rubcli.io.outputs import (
    REPORT_NAME,
    STAGING_PREFIX,
    OutputError,
    OutputPlan,
    StagedOutput,
    check_output_dir,
    read_manifest,
    staged_output_dir,
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

__all__ = [
    "CSV_BLOCK_ROWS",
    "CSV_COLUMNS",
    "CSV_COMPILED_MIN_ROWS",
    "CSV_PHYSICAL_COLUMNS",
    "REPORT_NAME",
    "STAGING_PREFIX",
    "TERMINATION_SIGNALS",
    "Background",
    "Cancelled",
    "Labels",
    "OutputError",
    "OutputPlan",
    "SharedBlocks",
    "StagedOutput",
    "Terminated",
    "atomic_path",
    "check_output_dir",
    "csv_field",
    "environment_info",
    "json_text",
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
    "write_rows_csv",
    "write_solution_csv",
    "write_text",
]

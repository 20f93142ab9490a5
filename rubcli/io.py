"""Writing results: atomic files, CSV tables, JSON reports, figures, staged output dirs.

Every writer goes through ``atomic_path``: the data are written to a temporary file in the
target's own directory and moved over the target with ``os.replace``, so a reader never
sees a half-written file. ``staged_output_dir`` does the same for a whole run: every file
is written into a hidden staging directory and moved in only when the run got that far,
so a run that fails part way (an exception, Ctrl-C, SIGTERM) leaves no outputs.

The rules of an output dir (``check_output_dir``, called by every command before it
computes anything):

- it must be a directory or not exist yet, and be creatable and writable (tried, not
  guessed: a probe directory is made and removed);
- a dir that holds files is used only if rubcli wrote it: its ``report.json`` is a rubcli
  report whose ``files`` list is the *manifest* of the run that wrote it. Files of that
  manifest which the new run does not write are removed after the new run committed
  (they would be stale results beside a new report) and named in a warning;
- a non-empty dir without a manifest (``--out .``, a home dir, someone's data) is refused
  unless ``force``; with ``force`` rubcli writes its files and leaves the others alone.
  Sub-directories that hold a rubcli manifest (the ``compare/`` and ``forces-map/`` dirs
  inside a case's output dir) do not count.

Every CSV goes through ``write_csv`` (one formatting rule: shortest round-trip floats,
written in blocks of rows, so a 10-million-sample solution never sits in memory as
text; large numpy blocks are formatted by compiled code, ``rubcli.csvtext``, to the same
bytes), every report through ``report_envelope`` + ``write_json``.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import errno
import json
import math
import os
import shutil
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from dataclasses import dataclass, field
from dataclasses import replace as _replace
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import units
from rubcli.model import REGIME_NAMES
from rubcli.solution import Solution

# Columns of a solution CSV, in order. Nondimensional first (clearances, tau, units of
# k_r * clearance for forces); the physical ones follow when the case has a scale.
CSV_COLUMNS = (
    "tau",
    "x",
    "y",
    "vx",
    "vy",
    "z",
    "contact",
    "regime",
    "regime_name",
    "v_r",
    "normal_force",
    "friction_force",
)
CSV_PHYSICAL_COLUMNS = (
    "t_s",
    "x_m",
    "y_m",
    "vx_m_s",
    "vy_m_s",
    "normal_force_N",
    "friction_force_N",
)
# Rows per block of a solution CSV: bounds the memory of the writer (about 40 MB of text
# and columns per block) whatever the number of samples.
CSV_BLOCK_ROWS = 65_536
# Blocks with at least this many rows are formatted by compiled code (rubcli.csvtext);
# smaller tables (reports, sweeps) need no numba.
CSV_COMPILED_MIN_ROWS = 1024
REPORT_NAME = "report.json"
STAGING_PREFIX = ".rubcli-staging-"


class OutputError(Exception):
    """An output location that cannot be used; the message says which and why."""


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success move it over ``path``.

    The temporary file keeps the target's suffix (so that e.g. matplotlib picks the
    format from it). On an exception it is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path: str | Path, text: str) -> Path:
    """Write text atomically (UTF-8, newline as given)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8", newline="")
    return Path(path)


def solution_columns(
    solution: Solution, scale: units.PhysicalScale | None = None
) -> dict[str, np.ndarray | Labels]:
    """The CSV columns of a solution, in order (``CSV_COLUMNS`` + physical ones if scaled);
    ``regime_name`` as ``Labels`` (the regime codes and their names)."""
    columns: dict[str, np.ndarray] = {
        "tau": solution.t,
        "x": solution.x,
        "y": solution.y,
        "vx": solution.vx,
        "vy": solution.vy,
        "z": solution.z,
        "contact": solution.contact,
        "regime": np.asarray(solution.regimes, dtype=int),
        "regime_name": _regime_names(solution.regimes),
        "v_r": solution.slip_velocity,
        "normal_force": solution.normal_force,
        "friction_force": solution.friction_force,
    }
    if scale is not None:
        columns.update(
            {
                "t_s": units.seconds(solution.t, scale),
                "x_m": units.metres(solution.x, scale),
                "y_m": units.metres(solution.y, scale),
                "vx_m_s": units.metres_per_second(solution.vx, scale),
                "vy_m_s": units.metres_per_second(solution.vy, scale),
                "normal_force_N": units.newtons(solution.normal_force, scale),
                "friction_force_N": units.newtons(solution.friction_force, scale),
            }
        )
    return columns


@dataclass(frozen=True)
class Labels:
    """A text column given as integer codes and the text of each code (a solution CSV's
    regime names): the compiled formatter writes it with no Python string per row."""

    codes: np.ndarray
    names: Mapping[int, str]

    def __len__(self) -> int:
        return len(self.codes)

    def tolist(self) -> list[str]:
        return [self.names[code] for code in np.asarray(self.codes).tolist()]


def _regime_names(regimes: np.ndarray) -> Labels:
    return Labels(np.asarray(regimes, dtype=np.int64), REGIME_NAMES)


def solution_blocks(
    solution: Solution,
    scale: units.PhysicalScale | None = None,
    rows: int | None = None,
) -> Iterator[list[np.ndarray]]:
    """The solution's CSV columns, ``rows`` (default ``CSV_BLOCK_ROWS``) samples at a time,
    each column computed on the block only: the memory does not grow with the samples."""
    rows = rows or CSV_BLOCK_ROWS
    n = int(solution.t.size)
    for a in range(0, n, rows):
        b = min(n, a + rows)
        part = _replace(
            solution,
            t=solution.t[a:b],
            states=solution.states[a:b],
            regimes=solution.regimes[a:b],
            events=[],
        )
        yield list(solution_columns(part, scale).values())


def solution_header(scale: units.PhysicalScale | None = None) -> tuple[str, ...]:
    return CSV_COLUMNS + (CSV_PHYSICAL_COLUMNS if scale is not None else ())


def write_solution_csv(
    path: str | Path,
    solution: Solution,
    scale: units.PhysicalScale | None = None,
    *,
    on_rows: Callable[[int], None] | None = None,
    blocks: SharedBlocks | None = None,
) -> Path:
    """One row per output sample, streamed in blocks; floats in shortest round-trip form
    (``repr``: exact), non-finite values as ``nan``/``inf``. ``on_rows(done)`` reports
    progress after each block. ``blocks``: the solution's blocks as ``shared_solution_blocks``
    made them, for other threads to help format."""
    if blocks is None:
        blocks = solution_blocks(solution, scale)
    return write_csv(path, solution_header(scale), blocks, on_rows=on_rows)


def shared_solution_blocks(
    solution: Solution, scale: units.PhysicalScale | None = None
) -> SharedBlocks:
    """A solution's CSV blocks, to be formatted by any thread (``SharedBlocks``)."""
    return SharedBlocks(solution_blocks(solution, scale), len(solution_header(scale)))


# ------------------------------------------------------------------------------ CSV


def csv_field(value: object, nonfinite: str | None = None) -> str:
    """One CSV field. Floats: shortest round-trip text; non-finite as ``repr`` (``nan``,
    ``inf``) or as ``nonfinite`` if given. None: empty. Text is quoted when it must be."""
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, float | np.floating):
        value = float(value)
        if nonfinite is not None and not math.isfinite(value):
            return nonfinite
        return repr(value)
    if isinstance(value, int | np.integer):
        return str(int(value))
    text = str(value)
    if any(c in text for c in ',"\n\r'):
        text = '"' + text.replace('"', '""') + '"'
    return text


def _column_texts(column: Sequence[object] | np.ndarray, nonfinite: str | None) -> list[str]:
    """The fields of one column (fast paths for float and integer arrays)."""
    if isinstance(column, Labels):
        column = np.array(column.tolist(), dtype=object)
    if isinstance(column, np.ndarray) and column.dtype.kind == "f":
        texts = [repr(v) for v in column.astype(float, copy=False).tolist()]
        if nonfinite is not None:
            for i in np.flatnonzero(~np.isfinite(column)).tolist():
                texts[i] = nonfinite
        return texts
    if isinstance(column, np.ndarray) and column.dtype.kind in "iu":
        return [str(v) for v in column.tolist()]
    if isinstance(column, np.ndarray) and column.dtype.kind in "OU":
        values = column.tolist()
        if all(type(v) is str for v in set(values)):  # e.g. regime names: few distinct texts
            fields = {v: csv_field(v) for v in set(values)}
            return [fields[v] for v in values]
    return [csv_field(v, nonfinite) for v in column]


def rows_to_block(rows: Iterable[Sequence[object]], width: int) -> list[list[object]]:
    """Rows (lists of values) as a block of columns for ``write_csv``."""
    columns: list[list[object]] = [[] for _ in range(width)]
    for row in rows:
        if len(row) != width:
            raise ValueError(f"a CSV row has {len(row)} fields, the header {width}")
        for column, value in zip(columns, row, strict=True):
            column.append(value)
    return columns


def write_csv(
    path: str | Path,
    header: Sequence[str],
    blocks: Iterable[Sequence[Sequence[object] | np.ndarray]] | SharedBlocks,
    *,
    nonfinite: str | None = None,
    on_rows: Callable[[int], None] | None = None,
) -> Path:
    """Write a CSV table atomically: the header, then each block of columns as rows.

    The one CSV writer of rubcli. ``blocks`` yields lists of columns (numpy arrays or
    lists, one per header name, of equal length); they are formatted and written one block
    at a time, so the text of a large table is never held whole. ``nonfinite`` replaces
    NaN/inf (default: written as ``nan``/``inf``); None is an empty field. ``blocks`` may
    be a ``SharedBlocks`` (its own ``nonfinite`` then applies): other threads may format
    its blocks ahead while this one writes them, in order.
    """
    width = len(header)
    done = 0
    if isinstance(blocks, SharedBlocks):
        if blocks.width != width:
            raise ValueError(f"the shared blocks have {blocks.width} columns, the header {width}")
        formatted: Iterable[tuple[int, Any]] = blocks.in_order()
    else:
        formatted = (_formatted_block(block, width, nonfinite) for block in blocks)
    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        handle.write((",".join(csv_field(h) for h in header) + "\n").encode("utf-8"))
        for rows, data in formatted:
            if rows == 0:
                continue
            handle.write(data)
            done += rows
            if on_rows is not None:
                on_rows(done)
    return Path(path)


def _formatted_block(block: Sequence[Sequence[object] | np.ndarray], width: int,
                     nonfinite: str | None) -> tuple[int, bytes | memoryview | None]:  # fmt: skip
    """``(rows, text)`` of one block of columns, checked against the header's width."""
    if len(block) != width:
        raise ValueError(f"a CSV block has {len(block)} columns, the header {width}")
    lengths = {len(column) for column in block}
    if len(lengths) > 1:
        raise ValueError(f"CSV columns of unequal length {sorted(lengths)}")
    rows = lengths.pop() if lengths else 0
    return rows, (_block_bytes(block, rows, nonfinite) if rows else None)


class SharedBlocks:
    """The blocks of one CSV, formatted by whichever thread has nothing else to do and
    written in order by ``write_csv``.

    ``rubcli run``'s background thread writes a solution's CSV while the main thread draws
    the figures; when the main thread is done it calls ``work`` (through
    ``Background.wait``) and formats blocks ahead of the writer instead of waiting (the
    formatter releases the GIL, so the two run on two cores). At most ``AHEAD`` formatted
    blocks wait to be written (about 10 MB each). A block that fails to format fails the
    writer with the same exception; a thread stopped by a signal while formatting makes
    the writer stop too (``Cancelled``), so nothing waits for a block that never comes.
    """

    AHEAD = 2

    def __init__(self, blocks: Iterable[Sequence[Sequence[object] | np.ndarray]], width: int,
                 nonfinite: str | None = None) -> None:  # fmt: skip
        self.width = width
        self.nonfinite = nonfinite
        self._blocks = iter(blocks)
        self._ready: dict[int, tuple[int, Any]] = {}
        self._claimed = 0  # blocks taken from the iterator so far
        self._exhausted = False
        self._error: BaseException | None = None
        self._changed = threading.Condition()

    def _claim(self) -> tuple[int, Any] | None:
        """The next block to format, with its index (None if there is none to take now)."""
        with self._changed:
            if self._exhausted or self._error is not None or len(self._ready) >= self.AHEAD:
                return None
            try:
                block = next(self._blocks)
            except StopIteration:
                self._exhausted = True
                self._changed.notify_all()
                return None
            index = self._claimed
            self._claimed += 1
            return index, block

    def _fail(self, exc: BaseException) -> None:
        with self._changed:
            if self._error is None:
                self._error = exc if isinstance(exc, Exception) else Cancelled()
            self._changed.notify_all()

    def work(self) -> bool:
        """Format one block not yet taken; False if there was none to take (all taken, too
        many waiting, or a failure). An exception is kept for the writer, not raised,
        unless it is a signal's (then the writer is told to stop and it propagates)."""
        try:  # from the claim on: a block taken is either stored or its failure is
            claim = self._claim()
            if claim is None:
                return False
            index, block = claim
            result = _formatted_block(block, self.width, self.nonfinite)
        except Exception as exc:  # noqa: BLE001 - the writer raises it
            self._fail(exc)
            return False
        except BaseException as exc:
            self._fail(exc)
            raise
        with self._changed:
            self._ready[index] = result
            self._changed.notify_all()
        return True

    def in_order(self) -> Iterator[tuple[int, Any]]:
        """``(rows, text)`` of every block in order (the writer): it formats blocks itself
        and waits only for a block another thread is formatting."""
        index = 0
        while True:
            with self._changed:
                if self._error is not None:
                    raise self._error
                result = self._ready.pop(index, None)
                if result is None and self._exhausted and index >= self._claimed:
                    return
                if result is not None:
                    self._changed.notify_all()  # room ahead again
            if result is not None:
                yield result
                index += 1
            elif not self.work():
                with self._changed:
                    elsewhere = not (self._exhausted and index >= self._claimed)
                    if index not in self._ready and self._error is None and elsewhere:
                        self._changed.wait()  # block ``index`` is being formatted elsewhere


def _block_bytes(block: Sequence[Sequence[object] | np.ndarray], rows: int,
                 nonfinite: str | None) -> bytes | memoryview:  # fmt: skip
    """The rows of one block as UTF-8 text (bytes-like). Blocks of
    ``CSV_COMPILED_MIN_ROWS`` rows or more whose columns are numpy arrays are formatted by
    compiled code (``rubcli.csvtext``: the same text, about 10x faster); the others
    here."""
    if rows >= CSV_COMPILED_MIN_ROWS and all(isinstance(c, np.ndarray | Labels) for c in block):
        from rubcli import csvtext

        data = csvtext.format_block(list(block), csv_field, nonfinite)
        if data is not None:
            return data
    texts = [_column_texts(column, nonfinite) for column in block]
    return ("\n".join(map(",".join, zip(*texts, strict=True))) + "\n").encode("utf-8")


def write_rows_csv(
    path: str | Path,
    header: Sequence[str],
    rows: Iterable[Sequence[object]],
    *,
    nonfinite: str | None = None,
) -> Path:
    """``write_csv`` for a table given as rows (small tables: reports, sweeps)."""
    return write_csv(path, header, [rows_to_block(rows, len(header))], nonfinite=nonfinite)


# ----------------------------------------------------------------------------- JSON


def to_jsonable(value: Any) -> Any:
    """Plain JSON types from numpy scalars/arrays, paths and tuples; NaN and inf -> None."""
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [to_jsonable(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return to_jsonable(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, str | int | bool):
        return value
    return str(value)


def json_text(data: Any) -> str:
    """``data`` as indented JSON text (non-finite floats become null)."""
    return json.dumps(to_jsonable(data), indent=2, allow_nan=False) + "\n"


def write_json(path: str | Path, data: Any) -> Path:
    """Write ``data`` as indented JSON, atomically (non-finite floats become null)."""
    return write_text(path, json_text(data))


def report_envelope(
    command: str, command_line: dict[str, Any], case: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The first keys of every report.json: version, time, environment, what was run and
    on which case (``Case.to_dict()``); each command adds its results after them."""
    envelope = {
        "rubcli_version": _version(),
        "created_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "environment": environment_info(),
        "command": command,
        "command_line": command_line,
    }
    if case is not None:
        envelope["case"] = case
    return envelope


def _version() -> str:
    from rubcli import __version__

    return __version__


def save_figure(fig, path: str | Path, *, dpi: int = 120, close: bool = True) -> Path:
    """Save a matplotlib figure atomically; the format follows the suffix of ``path``."""
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi)
    finally:
        pyplot = sys.modules.get("matplotlib.pyplot")
        if close and pyplot is not None:  # figures made without pyplot need no closing
            pyplot.close(fig)
    return Path(path)


# ----------------------------------------------------------------------- output dirs


@dataclass
class OutputPlan:
    """What ``check_output_dir`` found: where to write and what a previous run left."""

    target: Path
    previous: list[str] = field(default_factory=list)  # files of the previous manifest
    foreign: list[str] = field(default_factory=list)  # files no rubcli manifest lists
    removed: list[str] = field(default_factory=list)  # stale files removed at commit


def read_manifest(directory: Path) -> list[str] | None:
    """The ``files`` of a rubcli report.json in ``directory``, or None if it has none."""
    try:
        report = json.loads((directory / REPORT_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(report, dict) or "rubcli_version" not in report:
        return None
    files = report.get("files")
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        return None
    return [f for f in files if Path(f).name == f and f not in ("", ".", "..")]


def _nearest_existing(path: Path) -> Path:
    for candidate in (path, *path.parents):
        if os.path.lexists(candidate):
            return candidate
    return Path(".")


def check_output_dir(target: str | Path, *, force: bool = False) -> OutputPlan:
    """Check an output dir before anything is computed; raise OutputError saying why not.

    See the module docstring for the rules. Nothing is created or changed here (the probe
    directory is removed again).
    """
    target = Path(target)
    if target.exists() and not target.is_dir():
        raise OutputError(f"{target}: output dir exists and is not a directory")
    if os.path.lexists(target) and not target.exists():
        raise OutputError(f"{target}: output dir is a broken symbolic link")
    base = _nearest_existing(target.absolute())
    if not base.is_dir():
        raise OutputError(f"{target}: cannot create the output dir: {base} is not a directory")
    try:
        probe = tempfile.mkdtemp(dir=base, prefix=".rubcli-probe-")
        os.rmdir(probe)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise OutputError(f"{target}: output dir is not writable ({base}: {reason})") from None
    plan = OutputPlan(target=target)
    if not target.is_dir():
        return plan
    entries = sorted(
        p.name
        for p in target.iterdir()
        if not p.name.startswith(STAGING_PREFIX)
        # a sub-dir written by rubcli (`compare/`, `forces-map/` of a case) is no obstacle
        and not (p.is_dir() and read_manifest(p) is not None)
    )
    if not entries:
        return plan
    manifest = read_manifest(target)
    if manifest is None:
        if not force:
            shown = ", ".join(entries[:5]) + (f" and {len(entries) - 5} more" if len(entries) > 5
                                              else "")  # fmt: skip
            raise OutputError(
                f"{target}: output dir is not empty and was not written by rubcli (no rubcli "
                f"report.json; it holds {shown}); choose a new or empty dir, or pass --force "
                "to write beside these files"
            )
        plan.foreign = entries
        return plan
    plan.previous = manifest
    plan.foreign = [e for e in entries if e not in manifest and e != REPORT_NAME]
    return plan


def _move(source: Path, destination: Path) -> None:
    """Move a staged file over ``destination`` atomically, also across filesystems (a
    copy to a temporary file beside the destination, then a rename there)."""
    try:
        os.replace(source, destination)
    except OSError as exc:
        if exc.errno != errno.EXDEV:
            raise
        with atomic_path(destination) as tmp:
            shutil.copyfile(source, tmp)
        source.unlink(missing_ok=True)


def _same_device(a: Path, b: Path) -> bool:
    try:
        return os.stat(a).st_dev == os.stat(b).st_dev
    except OSError:
        return True


class StagedOutput:
    """A staging directory whose files are moved into ``target`` by ``commit()``.

    The staging directory is made in the target's real parent (symbolic links resolved),
    or inside the target itself when the target is a mount point, so that the final moves
    are renames on one filesystem; a move that still crosses filesystems is copied.
    """

    def __init__(self, target: str | Path, plan: OutputPlan | None = None):
        self.target = Path(target)
        self.plan = plan
        self.created: list[Path] = []  # directories made for the target (removed on failure)
        real = self.target.resolve()
        parent = real.parent
        for directory in reversed((real, *real.parents)):
            if directory != real and not directory.exists():
                directory.mkdir()
                self.created.append(directory)
        if real.is_dir() and not _same_device(real, parent):
            parent = real
        self.staging = Path(tempfile.mkdtemp(dir=parent, prefix=f"{STAGING_PREFIX}{real.name}-"))
        self.committed: list[Path] = []

    def path(self, name: str) -> Path:
        """Where to write the output ``name`` (a plain file name) while staging."""
        if Path(name).name != name or name in ("", ".", ".."):
            raise ValueError(f"output names are plain file names, not {name!r}")
        return self.staging / name

    def commit(self, last: tuple[str, ...] = (REPORT_NAME,)) -> list[Path]:
        """Move every staged file into the target; the names in ``last`` go last.

        Each move is atomic per file. A report written last marks that the files before it
        are complete. Then the files of the previous run's manifest that this run did not
        write are removed (``plan.removed`` names them).
        """
        try:
            self.target.mkdir(parents=True, exist_ok=True)
            staged = sorted(p for p in self.staging.iterdir() if p.is_file())
            staged.sort(key=lambda p: p.name in last)
            for item in staged:
                destination = self.target / item.name
                _move(item, destination)
                self.committed.append(destination)
            self.created.clear()
            written = {p.name for p in self.committed}
            if self.plan is not None:
                for name in self.plan.previous:
                    stale = self.target / name
                    if name not in written and stale.is_file():
                        stale.unlink()
                        self.plan.removed.append(name)
        finally:
            self.discard()
        return self.committed

    def discard(self) -> None:
        """Remove the staging directory and whatever is still in it, and the directories
        made for a target that was never committed."""
        shutil.rmtree(self.staging, ignore_errors=True)
        for directory in reversed(self.created):
            with contextlib.suppress(OSError):
                directory.rmdir()
        self.created.clear()


@contextlib.contextmanager
def staged_output_dir(target: str | Path, plan: OutputPlan | None = None) -> Iterator[StagedOutput]:
    """Stage a run's outputs; move them into ``target`` only if the block completes.

    ::

        with staged_output_dir("out/fig3a") as out:
            write_json(out.path("report.json"), report)
        # now out/fig3a/report.json exists; after an exception nothing would.

    ``plan`` (from ``check_output_dir``) lets the commit remove the stale files of the
    previous run.
    """
    staged = StagedOutput(target, plan)
    try:
        yield staged
    except BaseException:
        staged.discard()
        raise
    staged.commit()


# ------------------------------------------------------------------ background work


class Cancelled(Exception):  # noqa: N818 - not an error: the job was told to stop
    """A background job stopped because the command is leaving on an exception."""


class Background:
    """One worker thread for a command's output work, beside the main thread.

    ``rubcli run`` writes the methods' CSVs here while the main thread computes the
    report entries (the energy balance) and draws the figures, once every method is
    solved (a timed solve never shares the machine with it): the CSV formatter and the
    energy kernel are compiled ``nogil``, so on two cores the two threads overlap. Jobs
    run one at a time in submission order.

    Leaving the block normally waits for every job and re-raises the first job's
    exception. Leaving it on an exception (a signal's ``Terminated`` included) drops
    the queued jobs and stops a running one at its next progress report (``Cancelled``),
    then waits for the thread: nothing writes into a staged dir after it is discarded.
    """

    POLL_S = 0.05  # how often ``wait`` refreshes a progress bar

    def __init__(self) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rubcli-output")
        self._cancel = threading.Event()
        self._jobs: list[
            tuple[Future, str | None, float, list[float], Callable[[], bool] | None]
        ] = []

    def submit(self, fn: Callable[..., Any], *args: Any, progress: tuple[str, float] | None
               = None, helper: Callable[[], bool] | None = None,
               **kwargs: Any) -> Future:  # fmt: skip
        """Run ``fn(*args, **kwargs)`` in the worker. With ``progress = (label, total)``,
        ``fn`` also gets ``on_rows=`` (``write_csv``'s callback), which records the work
        done for ``wait``'s progress bar and stops the job when the command is leaving.
        ``helper``: a piece of the job the waiting thread may do itself (it returns False
        when there is none left to take: ``SharedBlocks.work``)."""
        done = [0.0]
        if progress is not None:

            def on_rows(count: float) -> None:
                if self._cancel.is_set():
                    raise Cancelled
                done[0] = count

            kwargs["on_rows"] = on_rows
        future = self._pool.submit(fn, *args, **kwargs)
        label, total = progress if progress is not None else (None, 0.0)
        self._jobs.append((future, label, total, done, helper))
        return future

    def wait(self, bar: Callable[[str, float], Any] | None = None) -> None:
        """Wait for every job, in order, doing the pieces of it the job offers (``helper``)
        meanwhile; a job still running shows ``bar(label, total)`` (a context manager
        yielding ``update(done)``, as ``console.progress_bar``). Re-raises the first
        failed job's exception."""
        for future, label, total, done, helper in self._jobs:
            if not future.done() and bar is not None and label is not None:
                with bar(label, total) as update:
                    self._help_until_done(future, helper, lambda u=update, d=done: u(d[0]))
                    update(total)
            elif not future.done():
                self._help_until_done(future, helper, lambda: None)
            future.result()

    def _help_until_done(self, future: Future, helper: Callable[[], bool] | None,
                         report: Callable[[], Any]) -> None:  # fmt: skip
        while not future.done():
            if helper is None or not helper():
                wait_for([future], timeout=self.POLL_S)
            report()

    def __enter__(self) -> Background:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is not None:
            self._cancel.set()
            self._pool.shutdown(wait=True, cancel_futures=True)
            return
        try:
            self.wait()
        finally:
            self._cancel.set()
            self._pool.shutdown(wait=True, cancel_futures=True)


# --------------------------------------------------------------------------- signals


class Terminated(BaseException):  # noqa: N818 - like KeyboardInterrupt, not an error
    """Raised in the main thread when the process receives SIGTERM, SIGINT or SIGHUP, so
    that staged outputs are removed on the way out; exit with ``exit_code``."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(f"terminated by {signal.Signals(signum).name}")

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


TERMINATION_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGTERM", "SIGINT", "SIGHUP") if hasattr(signal, name)
)


@contextlib.contextmanager
def termination_as_exception() -> Iterator[None]:
    """Turn the termination signals into ``Terminated`` while the block runs (main thread
    only; elsewhere a no-op). A compiled solver loop sees it at its next progress report."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: object) -> None:
        raise Terminated(signum)

    previous = {sig: signal.signal(sig, handler) for sig in TERMINATION_SIGNALS}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def environment_info() -> dict[str, str]:
    """Versions that a result depends on, for reports."""
    import platform

    import scipy

    from rubcli import __version__

    return {
        "rubcli": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "platform": platform.platform(terse=True),
    }

"""CSV tables: a solution's columns, the one CSV writer, blocks shared between threads.

Every CSV goes through ``write_csv`` (one formatting rule: shortest round-trip floats,
written in blocks of rows, so a 10-million-sample solution never sits in memory as
text; large numpy blocks are formatted by compiled code, ``rubcli.csvtext``, to the same
bytes). ``SharedBlocks`` lets another thread format a CSV's blocks ahead of its writer.
"""

from __future__ import annotations

import hashlib
import math
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import replace as _replace
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import units
from rubcli.io.background import Cancelled
from rubcli.io.files import atomic_path, remember_digest
from rubcli.labels import Labels
from rubcli.model import REGIME_NAMES
from rubcli.solution import Solution
from rubcli.solvers import rub

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


# A run whose speed changes (``Problem.speed``): the speed ratio and the unbalance phase
# (rad, the exact integral of the speed), and with [physical] the speed in rpm.
CSV_SPEED_COLUMNS = ("eta", "phase")
CSV_SPEED_PHYSICAL_COLUMNS = ("speed_rpm",)
# an offset or moving stator: x, y are the rotor's centre relative to the stator's (the
# model's coordinates); these are the rotor's position about its support's centre, x + s + c
CSV_OFFSET_COLUMNS = ("rotor_x", "rotor_y")
CSV_OFFSET_PHYSICAL_COLUMNS = ("rotor_x_m", "rotor_y_m")
# a stator with its own mass: its displacement from its rest position, and velocity
CSV_STATOR_COLUMNS = ("stator_x", "stator_y", "stator_vx", "stator_vy")
CSV_STATOR_PHYSICAL_COLUMNS = ("stator_x_m", "stator_y_m", "stator_vx_m_s", "stator_vy_m_s")
# a driven rotor: the motor's torque less the bearing drag, and the rub's, on the spin
CSV_DRIVE_COLUMNS = ("drive_torque", "rub_torque")
CSV_DRIVE_PHYSICAL_COLUMNS = ("drive_torque_Nm", "rub_torque_Nm")

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


def solution_columns(
    solution: Solution, scale: units.PhysicalScale | None = None
) -> dict[str, np.ndarray | Labels]:
    """The CSV columns of a solution, in order (``CSV_COLUMNS`` + physical ones if scaled);
    ``regime_name`` as ``Labels`` (the regime codes and their names)."""
    normal, friction = rub.normal_force(solution), rub.friction_force(solution)
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
        "v_r": rub.slip_velocity(solution),
        "normal_force": normal,
        "friction_force": friction,
    }
    if scale is not None:
        columns.update(
            {
                "t_s": units.seconds(solution.t, scale),
                "x_m": units.metres(solution.x, scale),
                "y_m": units.metres(solution.y, scale),
                "vx_m_s": units.metres_per_second(solution.vx, scale),
                "vy_m_s": units.metres_per_second(solution.vy, scale),
                "normal_force_N": units.newtons(normal, scale),
                "friction_force_N": units.newtons(friction, scale),
            }
        )
    cx, cy = solution.problem.params.offset
    stator = solution.stator_states
    if cx != 0.0 or cy != 0.0 or stator is not None:
        if stator is not None:
            cx, cy = cx + stator[:, 0], cy + stator[:, 1]
        columns.update({"rotor_x": solution.x + cx, "rotor_y": solution.y + cy})
        if scale is not None:
            columns["rotor_x_m"] = units.metres(solution.x + cx, scale)
            columns["rotor_y_m"] = units.metres(solution.y + cy, scale)
    if stator is not None:
        columns.update(dict(zip(CSV_STATOR_COLUMNS, stator.T, strict=True)))
        if scale is not None:
            columns.update({
                "stator_x_m": units.metres(stator[:, 0], scale),
                "stator_y_m": units.metres(stator[:, 1], scale),
                "stator_vx_m_s": units.metres_per_second(stator[:, 2], scale),
                "stator_vy_m_s": units.metres_per_second(stator[:, 3], scale),
            })  # fmt: skip
    if solution.problem.changes_speed:
        eta = solution.speed
        columns.update({"eta": eta, "phase": solution.phase})
        if scale is not None:
            columns["speed_rpm"] = units.rpm(eta, scale)
    drive = solution.problem.drive
    if drive is not None:
        torques = {"drive_torque": drive.shaft_torque(eta),
                   "rub_torque": -solution.problem.params.Rp * friction}  # fmt: skip
        columns.update(torques)
        if scale is not None:  # the torque unit k_r gamma^2 (N m)
            unit = scale.k_r * scale.clearance**2
            columns.update({f"{name}_Nm": value * unit for name, value in torques.items()})
    return columns


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
        own = {name: getattr(solution, name)[a:b] for name in ("drive_states", "stator_states")
               if getattr(solution, name) is not None}  # fmt: skip
        part = _replace(
            solution,
            t=solution.t[a:b],
            states=solution.states[a:b],
            regimes=solution.regimes[a:b],
            events=[],
            **own,
        )
        yield list(solution_columns(part, scale).values())


def solution_header(
    scale: units.PhysicalScale | None = None,
    speed: bool = False,
    drive: bool = False,
    offset: bool = False,
    stator: bool = False,
) -> tuple[str, ...]:
    """The CSV header of a solution (``speed``: its speed changes, ``Problem.changes_speed``;
    ``drive``: a driven rotor's torques; ``offset``: an offset or moving stator's rotor
    position; ``stator``: a moving stator's own states)."""
    header = CSV_COLUMNS + (CSV_PHYSICAL_COLUMNS if scale is not None else ())
    if offset or stator:
        header += CSV_OFFSET_COLUMNS + (CSV_OFFSET_PHYSICAL_COLUMNS if scale is not None else ())
    if stator:
        header += CSV_STATOR_COLUMNS + (CSV_STATOR_PHYSICAL_COLUMNS if scale is not None else ())
    if speed:
        header += CSV_SPEED_COLUMNS + (CSV_SPEED_PHYSICAL_COLUMNS if scale is not None else ())
    if drive:
        header += CSV_DRIVE_COLUMNS + (CSV_DRIVE_PHYSICAL_COLUMNS if scale is not None else ())
    return header


def _extra_columns(solution: Solution) -> tuple[bool, bool, bool, bool]:
    """(speed, drive, offset, stator) flags of ``solution_header`` for ``solution``."""
    problem = solution.problem
    offset = problem.params.offset != (0.0, 0.0)
    stator = problem.params.stator is not None
    return problem.changes_speed, problem.drive is not None, offset, stator


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
    header = solution_header(scale, *_extra_columns(solution))
    return write_csv(path, header, blocks, on_rows=on_rows)


def shared_solution_blocks(
    solution: Solution, scale: units.PhysicalScale | None = None
) -> SharedBlocks:
    """A solution's CSV blocks, to be formatted by any thread (``SharedBlocks``)."""
    width = len(solution_header(scale, *_extra_columns(solution)))
    return SharedBlocks(solution_blocks(solution, scale), width)


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
    digest = hashlib.sha256()  # for the output dir's manifest: no second read to hash it
    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        head = (",".join(csv_field(h) for h in header) + "\n").encode("utf-8")
        handle.write(head)
        digest.update(head)
        for rows, data in formatted:
            if rows == 0:
                continue
            handle.write(data)
            digest.update(data)
            done += rows
            if on_rows is not None:
                on_rows(done)
    remember_digest(path, digest.hexdigest())
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

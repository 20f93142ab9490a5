"""Reading a case file (or TOML text) and loading it: read, validate, assemble."""

from __future__ import annotations

import os
import re
import stat
import tomllib
from pathlib import Path
from typing import Any

from rubcli.case.assemble import Case, assemble_case
from rubcli.case.base import CaseError
from rubcli.case.casefile import validate_case

# A case file is a few kB of TOML (a sweep's value list some 100 kB): a larger file is
# refused before it is read.
MAX_CASE_FILE_BYTES = 8 * 1024**2


def open_regular_file(path: Path, shown: str, kind: str) -> tuple[int, os.stat_result]:
    """``path`` opened for reading, and its status: a regular file only (a directory, a
    FIFO, a device are refused before anything is read); CaseError lines begin with
    ``shown`` and call the file a ``kind``."""
    if "\0" in str(path):
        raise CaseError([f"{shown}: the name holds a NUL byte (\\0), which no file name may hold"])
    try:
        # O_NONBLOCK: opening a FIFO does not wait for a writer; it is refused just below
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise CaseError([f"{shown}: file not found"]) from None
    except IsADirectoryError:
        raise CaseError([f"{shown}: is a directory, not a {kind}"]) from None
    except OSError as exc:
        raise CaseError([f"{shown}: cannot read: {exc.strerror or exc}"]) from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        if stat.S_ISDIR(info.st_mode):
            raise CaseError([f"{shown}: is a directory, not a {kind}"])
        raise CaseError(
            [f"{shown}: is not a regular file ({_file_kind(info.st_mode)}), not a {kind}"]
        )
    return fd, info


def read_case_file(path: str | Path) -> dict[str, Any]:
    """Step 1: read and parse the TOML file. Raises CaseError naming the file.

    Only a regular file of at most ``MAX_CASE_FILE_BYTES`` is read: a directory, a FIFO
    (which would wait for a writer), a device (``/dev/zero`` never ends) or a larger file
    is refused before its content is read.
    """
    path = Path(path)
    fd, info = open_regular_file(path, str(path), "case file")
    with os.fdopen(fd, "rb") as handle:
        too_big = (
            f"{path}: is larger than {MAX_CASE_FILE_BYTES // 1024**2} MiB, the most a case "
            "file may hold (a case is a few kB of TOML)"
        )
        if info.st_size > MAX_CASE_FILE_BYTES:
            raise CaseError([too_big])
        try:
            data = handle.read(MAX_CASE_FILE_BYTES + 1)  # a file that grows while read
        except OSError as exc:
            raise CaseError([f"{path}: cannot read: {exc.strerror or exc}"]) from None
    if len(data) > MAX_CASE_FILE_BYTES:
        raise CaseError([too_big])
    return parse_case_text(data, str(path))


def _file_kind(mode: int) -> str:
    kinds = {stat.S_ISFIFO: "a FIFO", stat.S_ISCHR: "a character device",
             stat.S_ISBLK: "a block device", stat.S_ISSOCK: "a socket"}  # fmt: skip
    return next((name for test, name in kinds.items() if test(mode)), "a special file")


def parse_case_text(data: str | bytes, source: str = "<case>") -> dict[str, Any]:
    """Parse TOML text; a syntax error names the source and the line."""
    if isinstance(data, bytes):
        try:
            data = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise CaseError([f"{source}: not valid TOML: not UTF-8 text ({exc.reason})"]) from None
    try:
        return tomllib.loads(data)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        found = re.search(r"\(at line (\d+), column (\d+)\)", message)
        if found:
            reason = message[: found.start()].strip()
            where = f"line {found.group(1)}, column {found.group(2)}"
            raise CaseError([f"{source}: {where}: not valid TOML: {reason}"]) from None
        raise CaseError([f"{source}: not valid TOML: {message}"]) from None
    except RecursionError:
        raise CaseError(
            [f"{source}: not a case file: arrays or tables nested too deeply"]
        ) from None


def load_case(path: str | Path) -> Case:
    """Read, validate and assemble a case file. Raises CaseError (TypeError if ``path``
    is not a path)."""
    if not isinstance(path, str | os.PathLike):
        raise TypeError(f"load_case(): path must be a str or a path, got {type(path).__name__}")
    if "\0" in str(path):
        raise ValueError("load_case(): path holds a NUL byte (\\0), which no file name may hold")
    raw = read_case_file(path)
    return assemble_case(validate_case(raw, str(path)), path)


def load_case_text(text: str, source: str = "<case>") -> Case:
    """Like ``load_case`` for TOML text in memory (e.g. the sample of ``rubcli init``)."""
    return assemble_case(validate_case(parse_case_text(text, source), source), None, source)

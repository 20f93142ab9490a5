"""Atomic files: text, JSON reports and figures.

Every writer goes through ``atomic_path``: the data are written to a temporary file in the
target's own directory and moved over the target with ``os.replace``, so a reader never
sees a half-written file. Every report goes through ``report_envelope`` + ``write_json``.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import json
import math
import os
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.figure import Figure


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success move it over ``path``.

    The temporary file keeps the target's suffix (so that e.g. matplotlib picks the
    format from it). On an exception it is removed and ``path`` is untouched (an OSError
    that names no file is given ``path``'s name: a full disk says which file).
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
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.filename is None:
            exc.filename = str(path)  # a failed write() names no file: name the target
        raise


# SHA-256 of files as they were written, by (device, inode, size, mtime): the output
# dir's manifest takes a file's digest from here instead of reading it again.
_DIGESTS: dict[tuple[int, int, int, int], str] = {}


def _identity(path: str | Path) -> tuple[int, int, int, int] | None:
    try:
        st = os.lstat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def remember_digest(path: str | Path, sha256: str) -> None:
    """Record the SHA-256 of the file just written at ``path`` (by its writer, which saw
    every byte); a later change of the file changes its identity and voids this."""
    identity = _identity(path)
    if identity is not None:
        _DIGESTS[identity] = sha256


def known_digest(path: str | Path) -> tuple[int, str] | None:
    """(size, SHA-256) recorded by ``remember_digest`` for the file as it is now."""
    identity = _identity(path)
    sha = _DIGESTS.get(identity) if identity is not None else None
    return None if sha is None else (identity[2], sha)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path: str | Path, text: str) -> Path:
    """Write text atomically (UTF-8, newline as given)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8", newline="")
    return Path(path)


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
    from rubcli.version import __version__

    return __version__


def environment_info() -> dict[str, str]:
    """Versions that a result depends on, for reports."""
    import platform

    import scipy

    from rubcli.version import __version__

    return {
        "rubcli": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "platform": platform.platform(terse=True),
    }


def write_netcdf(dataset: xr.Dataset, path: str | Path) -> Path:
    """Write an xarray Dataset as NetCDF4 (h5netcdf), atomically.

    The file is made in memory and written as bytes: HDF5 writing to a full disk itself
    fails part way with pages of "Exception ignored" tracebacks, or crashes the process
    (a segmentation fault inside h5py, seen with a file size limit); writing the bytes
    fails with one OSError, which the caller reports (``staged_output_dir``).
    """
    data = dataset.to_netcdf(engine="h5netcdf")
    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        handle.write(data)
    return Path(path)


def save_figure(fig: Figure, path: str | Path, *, dpi: int = 120, close: bool = True) -> Path:
    """Save a matplotlib figure atomically; the format follows the suffix of ``path``."""
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi)
    finally:
        pyplot = sys.modules.get("matplotlib.pyplot")
        if close and pyplot is not None:  # figures made without pyplot need no closing
            pyplot.close(fig)
    return Path(path)

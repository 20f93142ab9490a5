"""Writing results: atomic files, solution CSVs, JSON reports, figures, staged output dirs.

Every writer goes through ``atomic_path``: the data are written to a temporary file in the
target's own directory and moved over the target with ``os.replace``, so a reader never
sees a half-written file. ``staged_output_dir`` does the same for a whole run: every file
is written into a hidden staging directory beside the target and moved in only when the
run got that far, so a run that fails part way (an exception, Ctrl-C) leaves no outputs.
Files already in the target directory that the run does not write are left alone.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
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
_INTEGER_COLUMNS = frozenset({"contact", "regime"})
_TEXT_COLUMNS = frozenset({"regime_name"})  # free, slip+, slip-, stick (model.REGIME_NAMES)


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
) -> dict[str, np.ndarray]:
    """The CSV columns of a solution, in order (``CSV_COLUMNS`` + physical ones if scaled)."""
    columns: dict[str, np.ndarray] = {
        "tau": solution.t,
        "x": solution.x,
        "y": solution.y,
        "vx": solution.vx,
        "vy": solution.vy,
        "z": solution.z,
        "contact": solution.contact,
        "regime": np.asarray(solution.regimes, dtype=int),
        "regime_name": np.array([REGIME_NAMES[int(r)] for r in solution.regimes], dtype=object),
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


def write_solution_csv(
    path: str | Path, solution: Solution, scale: units.PhysicalScale | None = None
) -> Path:
    """One row per output sample; floats with 17 significant digits (round-trip exact)."""
    columns = solution_columns(solution, scale)
    names = list(columns)
    table = np.column_stack(
        [np.asarray(columns[n], dtype=object if n in _TEXT_COLUMNS else float) for n in names]
    )
    fmt = [
        "%s" if n in _TEXT_COLUMNS else "%d" if n in _INTEGER_COLUMNS else "%.17g" for n in names
    ]
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as handle:
        handle.write(",".join(names) + "\n")
        if table.size:
            np.savetxt(handle, table, fmt=fmt, delimiter=",")
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


def write_json(path: str | Path, data: Any) -> Path:
    """Write ``data`` as indented JSON, atomically (non-finite floats become null)."""
    text = json.dumps(to_jsonable(data), indent=2, allow_nan=False) + "\n"
    return write_text(path, text)


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


class StagedOutput:
    """A staging directory whose files are moved into ``target`` by ``commit()``."""

    def __init__(self, target: str | Path):
        self.target = Path(target)
        parent = self.target.parent
        parent.mkdir(parents=True, exist_ok=True)
        self.staging = Path(tempfile.mkdtemp(dir=parent, prefix=f".{self.target.name}.staging-"))
        self.committed: list[Path] = []

    def path(self, name: str) -> Path:
        """Where to write the output ``name`` (a plain file name) while staging."""
        if Path(name).name != name or name in ("", ".", ".."):
            raise ValueError(f"output names are plain file names, not {name!r}")
        return self.staging / name

    def commit(self, last: tuple[str, ...] = ("report.json",)) -> list[Path]:
        """Move every staged file into the target; the names in ``last`` go last.

        Each move is an ``os.replace`` (atomic per file). A report written last marks
        that the files before it are complete.
        """
        self.target.mkdir(parents=True, exist_ok=True)
        staged = sorted(p for p in self.staging.iterdir() if p.is_file())
        staged.sort(key=lambda p: p.name in last)
        for item in staged:
            destination = self.target / item.name
            os.replace(item, destination)
            self.committed.append(destination)
        self.discard()
        return self.committed

    def discard(self) -> None:
        """Remove the staging directory and whatever is still in it."""
        shutil.rmtree(self.staging, ignore_errors=True)


@contextlib.contextmanager
def staged_output_dir(target: str | Path) -> Iterator[StagedOutput]:
    """Stage a run's outputs; move them into ``target`` only if the block completes.

    ::

        with staged_output_dir("out/fig3a") as out:
            write_json(out.path("report.json"), report)
        # now out/fig3a/report.json exists; after an exception nothing would.
    """
    staged = StagedOutput(target)
    try:
        yield staged
    except BaseException:
        staged.discard()
        raise
    staged.commit()


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

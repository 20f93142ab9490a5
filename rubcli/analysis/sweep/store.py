"""The resumable store of finished points: one small ``.npz`` file per point.

The store is a directory named after the plan's digest (a hash of everything that
changes the numbers), so a changed case never reuses another case's points. Each point
is written atomically (a temporary file moved into place with ``os.replace``) by the
process that collects the results, as soon as it arrives: an interruption (Ctrl-C,
SIGKILL) loses at most the points being computed, never a finished one. Floats are
stored in binary, so a resumed chain continues from exactly the state it would have had.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from rubcli.analysis.sweep.point import PointResult

FORMAT = 1


class PointStore:
    """Finished points of one plan, in ``directory`` (created on first use)."""

    def __init__(self, directory: str | Path, digest: str, plan: dict | None = None):
        self.directory = Path(directory)
        self.digest = digest
        self.plan = plan

    def _file(self, key: str) -> Path:
        return self.directory / f"{key}.npz"

    def save(self, key: str, result: PointResult) -> None:
        """Write one point atomically."""
        self.directory.mkdir(parents=True, exist_ok=True)
        marker = self.directory / "plan.json"
        if self.plan is not None and not marker.exists():
            text = json.dumps({"digest": self.digest, "plan": self.plan}, indent=1)
            _atomic_bytes(marker, text.encode())
        meta = {
            "format": FORMAT,
            "digest": self.digest,
            "ok": result.ok,
            "message": result.message,
            "scalars": result.scalars,
            "wall_time_s": result.wall_time_s,
        }
        arrays = {
            "meta": np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8),
            "section": np.asarray(result.section, dtype=float),
            "final_state": np.asarray(
                result.final_state if result.final_state is not None else [], dtype=float
            ),
            "spectrum": np.asarray(result.spectrum if result.spectrum is not None else []),
        }
        fd, tmp = tempfile.mkstemp(dir=self.directory, prefix=f".{key}.", suffix=".npz")
        try:
            with os.fdopen(fd, "wb") as handle:
                np.savez(handle, **arrays)
                handle.flush()
                os.fsync(handle.fileno())
            os.replace(tmp, self._file(key))
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def load(self) -> dict[str, PointResult]:
        """Every stored point of this plan, by key (unreadable files are ignored)."""
        out: dict[str, PointResult] = {}
        if not self.directory.is_dir():
            return out
        for path in sorted(self.directory.glob("*.npz")):
            if path.name.startswith("."):
                continue
            try:
                with np.load(path) as data:
                    meta = json.loads(bytes(data["meta"]).decode())
                    if meta.get("digest") != self.digest or meta.get("format") != FORMAT:
                        continue
                    final = data["final_state"]
                    spectrum = data["spectrum"]
                    out[path.stem] = PointResult(
                        ok=bool(meta["ok"]),
                        message=str(meta["message"]),
                        scalars={k: float(v) for k, v in meta["scalars"].items()},
                        section=np.array(data["section"], dtype=float).reshape(-1, 4),
                        final_state=tuple(float(v) for v in final) if final.size else None,
                        spectrum=np.array(spectrum, dtype=float) if spectrum.size else None,
                        wall_time_s=float(meta.get("wall_time_s", 0.0)),
                    )
            except (OSError, ValueError, KeyError, json.JSONDecodeError):
                continue  # a file cut short by a crash: that point is computed again
        return out

    def remove(self) -> None:
        shutil.rmtree(self.directory, ignore_errors=True)


def _atomic_bytes(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise

"""The resumable store of finished points: one small file per point.

The store is a directory named after the plan's digest (a hash of everything that
changes the numbers), so a changed case never reuses another case's points. Each point
is written atomically (a temporary file moved into place with ``os.replace``) by the
process that collects the results, as soon as it arrives: an interruption (Ctrl-C,
SIGKILL) loses at most the points being computed, never a finished one. A file holds a
JSON header line (scalars, message, array sizes) and the arrays' float64 bytes, so a
resumed chain continues from exactly the state it would have had. (The files are not
fsync'ed: a crash of the machine itself may lose the last points, never corrupt a
result: a short file is detected and its point computed again.)
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

from rubcli.analysis.sweep.point import PointResult

FORMAT = 2
SUFFIX = ".point"


class PointStore:
    """Finished points of one plan, in ``directory`` (created on first use)."""

    def __init__(self, directory: str | Path, digest: str, plan: dict | None = None):
        self.directory = Path(directory)
        self.digest = digest
        self.plan = plan
        self._ready = False

    def _file(self, key: str) -> Path:
        return self.directory / f"{key}{SUFFIX}"

    def save(self, key: str, result: PointResult) -> None:
        """Write one point atomically: a JSON header line, then the arrays' float64 bytes."""
        if not self._ready:
            self.directory.mkdir(parents=True, exist_ok=True)
            marker = self.directory / "plan.json"
            if self.plan is not None and not marker.exists():
                text = json.dumps({"digest": self.digest, "plan": self.plan}, indent=1)
                _atomic_bytes(marker, text.encode())
            self._ready = True
        section = np.ascontiguousarray(result.section, dtype=np.float64)
        final = np.asarray(result.final_state if result.final_state is not None else [], float)
        spectrum = np.asarray(result.spectrum if result.spectrum is not None else [], float)
        meta = {
            "format": FORMAT,
            "digest": self.digest,
            "ok": result.ok,
            "message": result.message,
            "scalars": result.scalars,
            "wall_time_s": result.wall_time_s,
            "sizes": [section.size, final.size, spectrum.size],
        }
        payload = b"".join(
            (json.dumps(meta).encode(), b"\n", section.tobytes(), final.tobytes(),
             spectrum.astype(np.float64).tobytes())
        )  # fmt: skip
        _atomic_bytes(self._file(key), payload)

    def load(self) -> dict[str, PointResult]:
        """Every stored point of this plan, by key (unreadable files are ignored)."""
        out: dict[str, PointResult] = {}
        if not self.directory.is_dir():
            return out
        for path in sorted(self.directory.glob(f"*{SUFFIX}")):
            if path.name.startswith("."):
                continue
            try:
                data = path.read_bytes()
                head, _, body = data.partition(b"\n")
                meta = json.loads(head.decode())
                if meta.get("digest") != self.digest or meta.get("format") != FORMAT:
                    continue
                n_section, n_final, n_spectrum = meta["sizes"]
                values = np.frombuffer(body, dtype=np.float64)
                if values.size != n_section + n_final + n_spectrum:
                    continue  # cut short: that point is computed again
                section = values[:n_section].reshape(-1, 4).copy()
                final = values[n_section : n_section + n_final]
                spectrum = values[n_section + n_final :]
                out[path.name[: -len(SUFFIX)]] = PointResult(
                    ok=bool(meta["ok"]),
                    message=str(meta["message"]),
                    scalars={k: float(v) for k, v in meta["scalars"].items()},
                    section=section,
                    final_state=tuple(float(v) for v in final) if final.size else None,
                    spectrum=spectrum.copy() if spectrum.size else None,
                    wall_time_s=float(meta.get("wall_time_s", 0.0)),
                )
            except (OSError, ValueError, KeyError, UnicodeDecodeError):
                continue  # an unreadable file: that point is computed again
        return out

    def remove(self) -> None:
        shutil.rmtree(self.directory, ignore_errors=True)


def _atomic_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to a temporary name in the same directory, then rename it over ``path``."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise

"""The resumable store of finished points: one small file per point (or, for a basin
grid with recognition, one file per chunk of starts).

The store is a directory named after the plan's digest (a hash of everything that
changes the numbers), so a changed case never reuses another case's points. Each point
is written atomically (a temporary file moved into place with ``os.replace``) by the
process that collects the results, as soon as it arrives: an interruption (Ctrl-C,
SIGKILL) loses at most the points being computed, never a finished one. A file holds a
JSON header line (scalars, message, array sizes) and the arrays' float64 bytes, so a
resumed chain continues from exactly the state it would have had. (The files are not
fsync'ed: a crash of the machine itself may lose the last points, never corrupt a
result: a short file is detected and its point computed again.)

A store is trusted only when it is ours and intact. The directory is created private to
the user (mode 0700); one that exists already is used only if this user owns it and no
one else can write to it (else ``StoreError``: it is never adopted, written or removed).
Every point file begins with an HMAC-SHA256 (the user's private manifest key,
``rubcli.io.manifest``) over the plan's digest, the point's key and its bytes, so a file
edited, copied under another point's name, or made by someone else fails the check; such
a file is ignored (``rejected``) and its point computed again. A chain's stored final
state is inside the checked bytes, so a tampered state never seeds the next point.
Without a private place for the key the check falls back to SHA-256 (it still catches
corruption; the ownership check keeps other users out).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import shutil
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from rubcli.analysis.sweep.point import PointResult

FORMAT = 3
SUFFIX = ".point"
CHUNK_SUFFIX = ".chunk"  # a chunk of basin starts (``basins``), checked like a point
MAX_POINT_BYTES = 1 << 30  # no point's sections and spectrum come near this
MAC_BYTES = 64  # hex digits of the HMAC-SHA256 that begins each point file


class StoreError(ValueError):
    """A store directory that is not this user's own: never adopted, written or removed."""


def _mac(digest: str, key: str, payload: bytes) -> bytes:
    from rubcli.io import manifest

    found = manifest._key()
    message = b"rubcli point\0" + digest.encode() + b"\0" + key.encode() + b"\0" + payload
    if found is None:
        return hashlib.sha256(message).hexdigest().encode()
    return hmac.new(found[0], message, hashlib.sha256).hexdigest().encode()


class PointStore:
    """Finished points of one plan, in ``directory`` (created on first use)."""

    def __init__(self, directory: str | Path, digest: str, plan: dict | None = None):
        self.directory = Path(directory)
        self.digest = digest
        self.plan = plan
        self._ready = False
        self.rejected: list[str] = []  # point files that failed the check (recomputed)

    def check(self, *, create: bool = False) -> bool:
        """True when the directory exists and is this user's own (made now if ``create``);
        False when it does not exist; StoreError when it is someone else's or open to
        others' writes."""
        if create:
            try:
                self.directory.parent.mkdir(parents=True, exist_ok=True)
                self.directory.mkdir(mode=0o700)
                return True
            except FileExistsError:
                pass
        try:
            st = os.lstat(self.directory)
        except FileNotFoundError:
            return False
        problem = None
        if not stat.S_ISDIR(st.st_mode):
            problem = "is not a directory (a link or a file)"
        elif st.st_uid != os.getuid():
            problem = f"belongs to another user (uid {st.st_uid})"
        elif st.st_mode & 0o022:
            problem = f"can be written by other users (mode {stat.S_IMODE(st.st_mode):o})"
        if problem:
            raise StoreError(
                f"{self.directory}: the resume store {problem}: it is not trusted and not "
                f"used; remove it (rm -r '{self.directory}') or choose another output dir"
            )
        return True

    def _file(self, key: str) -> Path:
        return self.directory / f"{key}{SUFFIX}"

    def _prepare(self) -> None:
        if not self._ready:
            self.check(create=True)
            marker = self.directory / "plan.json"
            if self.plan is not None and not marker.exists():
                text = json.dumps({"digest": self.digest, "plan": self.plan}, indent=1)
                _atomic_bytes(marker, text.encode())
            self._ready = True

    def save_blob(self, name: str, payload: bytes) -> None:
        """Write one chunk of results (``name.chunk``) atomically, checksummed as a point."""
        self._prepare()
        path = self.directory / f"{name}{CHUNK_SUFFIX}"
        _atomic_bytes(path, _mac(self.digest, name, payload) + b"\n" + payload)

    def load_blobs(self) -> dict[str, bytes]:
        """Every stored chunk that passes the check, by name (the others are listed in
        ``rejected`` and computed again)."""
        self.rejected = []
        return dict(self._verified(CHUNK_SUFFIX))

    def _verified(self, suffix: str) -> Iterator[tuple[str, bytes]]:
        """``(name, payload)`` of every ``*suffix`` file of the store that is a regular
        file of at most MAX_POINT_BYTES whose checksum holds; the others go to
        ``rejected``."""
        if not self.check():
            return
        for path in sorted(self.directory.glob(f"*{suffix}")):
            if path.name.startswith("."):
                continue
            name = path.name[: -len(suffix)]
            try:
                if not path.is_file() or path.is_symlink():
                    raise ValueError("not a regular file")
                if path.stat().st_size > MAX_POINT_BYTES:
                    raise ValueError("too large for the store")
                data = path.read_bytes()
            except (OSError, ValueError):
                self.rejected.append(path.name)
                continue
            mac, payload = data[:MAC_BYTES], data[MAC_BYTES + 1 :]
            if data[MAC_BYTES : MAC_BYTES + 1] != b"\n" or not hmac.compare_digest(
                mac, _mac(self.digest, name, payload)
            ):
                self.rejected.append(path.name)  # edited, corrupted or not ours
                continue
            yield name, payload

    def save(self, key: str, result: PointResult) -> None:
        """Write one point atomically: a JSON header line, then the arrays' float64 bytes."""
        self._prepare()
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
        _atomic_bytes(self._file(key), _mac(self.digest, key, payload) + b"\n" + payload)

    def load(self) -> dict[str, PointResult]:
        """Every stored point of this plan, by key: only files that pass the check (the
        others are listed in ``rejected`` and their points computed again)."""
        out: dict[str, PointResult] = {}
        self.rejected = []
        for key, payload in self._verified(SUFFIX):
            try:
                head, _, body = payload.partition(b"\n")
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
                out[key] = PointResult(
                    ok=bool(meta["ok"]),
                    message=str(meta["message"]),
                    scalars={k: float(v) for k, v in meta["scalars"].items()},
                    section=section,
                    final_state=tuple(float(v) for v in final) if final.size else None,
                    spectrum=spectrum.copy() if spectrum.size else None,
                    wall_time_s=float(meta.get("wall_time_s", 0.0)),
                )
            except (ValueError, KeyError, TypeError, UnicodeDecodeError):
                self.rejected.append(f"{key}{SUFFIX}")  # that point is computed again
        return out

    def remove(self) -> bool:
        """Remove the store, only if it is this user's own; True if it was removed."""
        try:
            if not self.check():
                return False
        except StoreError:
            return False
        shutil.rmtree(self.directory, ignore_errors=True)
        return not os.path.lexists(self.directory)


def _atomic_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to a new temporary file in the same directory (made here, never an
    existing name or link), then rename it over ``path``."""
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    tmp = Path(name)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise

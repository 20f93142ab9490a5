"""The manifest of an output dir: which files rubcli wrote there, in a form nobody can forge.

Every ``report.json`` that rubcli commits ends with a ``manifest`` key::

    "manifest": {"format": 1, "key": "<key id>", "report_sha256": "...",
                 "files": {"rk45.csv": {"size": 1234, "sha256": "..."}, ...},
                 "signature": "<HMAC-SHA256 of the rest>"}

- ``files``: the size and SHA-256 of every other file the run wrote;
- ``report_sha256``: the SHA-256 of report.json's text before the manifest, so that an
  edited report is no longer rubcli's;
- ``signature``: an HMAC-SHA256 over the rest, with a key private to the user
  (``manifest.key``, 32 random bytes made on first use, mode 0600, in
  ``$RUBCLI_STATE_DIR``, else ``$XDG_STATE_HOME/rubcli``, else ``~/.local/state/rubcli``;
  if none of these can hold it, a private ``rubcli-<uid>`` dir in the temporary dir).

A file is rubcli's own when a manifest whose signature verifies lists it with its present
size and hash. A ``report.json`` typed or copied by someone (``{"rubcli_version": "x",
"files": ["thesis.tex"]}``), a manifest of another user (another key) or a file changed
since rubcli wrote it is not: rubcli never replaces or removes such a file without
``--force`` (``outputs``).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import hashlib
import hmac
import json
import os
import secrets
import stat
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

FORMAT = 1
KEY = "manifest"  # the report's key that holds the manifest
KEY_FILE = "manifest.key"
STATE_ENV = "RUBCLI_STATE_DIR"
_MARK = f'\n  "{KEY}": '  # where the manifest starts in a committed report.json
_CHUNK = 1 << 20


def file_digest(path: Path, *, fresh: bool = False) -> tuple[int, str]:
    """(size, SHA-256 hex) of a file's content (from its writer when it recorded it:
    ``files.remember_digest``, unless ``fresh``)."""
    if not fresh:
        from rubcli.io.files import known_digest

        known = known_digest(path)
        if known is not None:
            return known
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as handle:
        while chunk := handle.read(_CHUNK):
            digest.update(chunk)
            size += len(chunk)
    return size, digest.hexdigest()


# ---------------------------------------------------------------------------- the key


def state_dirs() -> list[Path]:
    """Where the key may live, in order of preference."""
    override = os.environ.get(STATE_ENV)
    if override:
        return [Path(override)]
    dirs = []
    xdg = os.environ.get("XDG_STATE_HOME")
    if xdg:
        dirs.append(Path(xdg) / "rubcli")
    else:
        with contextlib.suppress(RuntimeError):  # no home directory
            dirs.append(Path.home() / ".local" / "state" / "rubcli")
    uid = os.geteuid() if hasattr(os, "geteuid") else 0
    with contextlib.suppress(OSError):  # no usable temporary dir at all (a full disk)
        dirs.append(Path(tempfile.gettempdir()) / f"rubcli-{uid}")
    return dirs


def _private(st: os.stat_result, *, directory: bool) -> bool:
    """Owned by this user, and nobody else may change it (a file: nor read it)."""
    uid = os.geteuid() if hasattr(os, "geteuid") else st.st_uid
    kind = stat.S_ISDIR(st.st_mode) if directory else stat.S_ISREG(st.st_mode)
    others = 0o022 if directory else 0o077
    return kind and st.st_uid == uid and not st.st_mode & others


def _read_key(path: Path) -> bytes | None:
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except FileNotFoundError:
        return None
    try:
        st = os.fstat(fd)
        if not _private(st, directory=False) or st.st_size != 32:
            raise ValueError(f"{path}: not a private 32-byte key of this user")
        return os.read(fd, 32)
    finally:
        os.close(fd)


def _load_or_create(directory: Path) -> bytes:
    if os.path.lexists(directory) and not os.path.isdir(directory):
        raise ValueError(f"{directory}: not a directory")
    directory.mkdir(mode=0o700, parents=True, exist_ok=True)
    if not _private(os.lstat(directory), directory=True):
        raise ValueError(f"{directory}: not a private directory of this user (a link, "
                         "another user's, or open to others' writes)")  # fmt: skip
    path = directory / KEY_FILE
    key = _read_key(path)
    if key is not None:
        return key
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{KEY_FILE}.")  # mode 0600
    try:
        if os.write(fd, secrets.token_bytes(32)) != 32:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), tmp)
        os.fsync(fd)
        os.close(fd)
        fd = -1
        with contextlib.suppress(FileExistsError):
            os.link(tmp, path)  # never over a key another process made meanwhile
    finally:
        if fd >= 0:
            os.close(fd)
        os.unlink(tmp)
    key = _read_key(path)
    if key is None:
        raise OSError(f"{path}: could not be created")
    return key


class KeyUnavailable(Exception):  # noqa: N818 - a state, reported to the user
    """No private place can hold the manifest key; ``errno``: the failed write's, if any."""

    def __init__(self, message: str, errno_: int | None):
        super().__init__(message)
        self.errno = errno_


_KEY_PROBLEMS: list[tuple[Path, Exception]] = []  # why each state dir could not hold it


@functools.cache
def _key() -> tuple[bytes, str] | None:
    """(key, key id), or None when no private place can hold a key (``require_key``)."""
    _KEY_PROBLEMS.clear()
    for directory in state_dirs():
        try:
            key = _load_or_create(directory)
        except (OSError, ValueError) as exc:
            _KEY_PROBLEMS.append((directory, exc))
            continue
        return key, hashlib.sha256(b"rubcli manifest key id\0" + key).hexdigest()[:16]
    return None


def require_key() -> None:
    """Raise ``KeyUnavailable`` saying why when no private place can hold the key: rubcli
    then writes no output dir (an unsigned manifest would make the next command refuse
    the dir as not rubcli's)."""
    if _key() is not None:
        return
    why = "; ".join(
        str(exc) if isinstance(exc, ValueError) or exc.filename else f"{where}: {exc}"
        for where, exc in _KEY_PROBLEMS
    )
    codes = [exc.errno for _, exc in _KEY_PROBLEMS if isinstance(exc, OSError)]
    raise KeyUnavailable(
        f"no private place for the key that signs rubcli's output dirs ({why}); set "
        f"{STATE_ENV} to a directory that only you can write (rubcli makes it, mode 0700)",
        codes[-1] if codes else None,
    )


def _sign(body: dict) -> str | None:
    found = _key()
    if found is None:
        return None
    text = json.dumps(body, sort_keys=True, separators=(",", ":")).encode()
    return hmac.new(found[0], text, hashlib.sha256).hexdigest()


def sign(body: dict) -> str | None:
    """The HMAC-SHA256 of a JSON object with this user's key (None without a key)."""
    return _sign(body)


def signed(body: dict, signature: object) -> bool:
    """Whether ``signature`` is this user's signature of ``body`` (``sign``)."""
    expected = _sign(body)
    return (
        isinstance(signature, str)
        and expected is not None
        and (hmac.compare_digest(signature, expected))
    )


# ----------------------------------------------------------------------- writing


def add_to_report(report: Path, files: dict[str, tuple[int, str]]) -> dict:
    """Append the signed manifest of ``files`` (name -> (size, sha256)) to the JSON object
    in ``report`` (a staged file, replaced by a new one); return the manifest."""
    text = report.read_text(encoding="utf-8")
    body = text.rstrip()
    if not body.endswith("}"):
        raise ValueError(f"{report}: not a JSON object")
    inner = body[:-1].rstrip()
    prefix = inner + ("" if inner.endswith("{") else ",")
    found = _key()
    manifest = {
        "format": FORMAT,
        "key": None if found is None else found[1],
        "report_sha256": hashlib.sha256(prefix.encode("utf-8")).hexdigest(),
        "files": {n: {"size": size, "sha256": sha} for n, (size, sha) in sorted(files.items())},
    }
    manifest["signature"] = _sign(manifest)
    block = json.dumps(manifest, indent=2).replace("\n", "\n  ")
    from rubcli.io.files import write_text

    write_text(report, prefix + _MARK + block + "\n}\n")  # a fresh file moved over it
    return manifest


# ----------------------------------------------------------------------- reading


@dataclass
class Manifest:
    """What a directory's report.json says about the files rubcli wrote there.

    ``valid``: the signature verifies with this user's key and report.json is unchanged;
    otherwise ``reason`` says why not, and nothing in the directory counts as rubcli's.
    """

    valid: bool = False
    reason: str = "no report.json"
    files: dict[str, tuple[int, str]] = field(default_factory=dict)

    def owns(self, directory: Path, name: str) -> bool:
        """Whether ``name`` in ``directory`` is, byte for byte, a file this manifest lists."""
        if not self.valid:
            return False
        if name == REPORT:
            return True  # verified with the manifest itself
        expected = self.files.get(name)
        path = directory / name
        try:
            st = os.lstat(path)
        except OSError:
            return False
        if expected is None or not stat.S_ISREG(st.st_mode) or st.st_size != expected[0]:
            return False
        try:
            return file_digest(path, fresh=True) == expected
        except OSError:
            return False


REPORT = "report.json"


def read(directory: Path) -> Manifest:
    """The manifest of ``directory``'s report.json, verified (see ``Manifest``)."""
    path = directory / REPORT
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode):
            return Manifest(reason="report.json is not a regular file")
        if st.st_size > 256 << 20:
            return Manifest(reason="report.json is too large to be rubcli's")
        text = path.read_text(encoding="utf-8")
        report = json.loads(text)
    except FileNotFoundError:
        return Manifest()
    except (OSError, ValueError):
        return Manifest(reason="report.json is not readable JSON")
    manifest = report.get(KEY) if isinstance(report, dict) else None
    if not isinstance(manifest, dict):
        if isinstance(report, dict) and "rubcli_version" in report:
            return Manifest(reason="its report.json has no manifest: written by an older "
                                   "rubcli, or by hand")  # fmt: skip
        return Manifest(reason="its report.json is not rubcli's")
    found = _key()
    if found is None:
        return Manifest(reason="no key to verify manifests (no private state dir)")
    if manifest.get("key") != found[1]:
        return Manifest(reason="its manifest was signed with another key (another user, "
                               "or another machine)")  # fmt: skip
    body = {k: v for k, v in manifest.items() if k != "signature"}
    signature = manifest.get("signature")
    if not signed(body, signature):
        return Manifest(reason="its manifest's signature does not match")
    at = text.rfind(_MARK)
    prefix_hash = hashlib.sha256(text[: max(at, 0)].encode("utf-8")).hexdigest()
    if at < 0 or prefix_hash != manifest.get("report_sha256"):
        return Manifest(reason="report.json was changed after rubcli wrote it")
    try:
        files = {str(n): (int(e["size"]), str(e["sha256"])) for n, e in manifest["files"].items()}
    except (KeyError, TypeError, ValueError, AttributeError):
        return Manifest(reason="its manifest is malformed")
    files = {n: e for n, e in files.items() if Path(n).name == n and n not in ("", ".", "..")}
    return Manifest(valid=True, reason="", files=files)

"""Output dirs: locked, checked before anything is computed, written staged, committed whole.

This is rubcli's one writer of output dirs. A command (or a library ``write(directory)``)::

    plan = open_output_dir("out/fig3a", force=False, wait=False)   # lock, recover, check
    try:
        ...compute...
        with staged_output_dir("out/fig3a", plan) as staged:        # stage, then commit
            write_json(staged.path("report.json"), report)
    finally:
        plan.close()                                                # unlock

``staged_output_dir(target)`` without a plan opens and closes one itself.

**Lock.** One command per output dir at a time (``lock.DirLock``, an OS lock on
``DIR/.rubcli.lock``, held from the check to the end of the command); another is refused
(``OutputBusy``) or waits (``wait=True``).

**Check** (``open_output_dir``, before anything is computed): the dir must be a directory
or creatable, and writable (tried: the dir and its lock file are made; a full disk is
``OutputWriteError``, no lock left); every name in the path must fit the file system and
hold no NUL byte; the manifest key must have a private place (``manifest.require_key``):
rubcli writes no dir it could not sign. A name like an output's that is a directory is
refused, also with ``force``. The files in it are sorted into rubcli's own (listed,
byte for byte, by the signed manifest of its report.json: ``manifest``) and the others.
A dir that holds other files and no valid manifest (``--out .``, a home dir, someone's
data, a report.json typed by hand) is refused unless ``force``. A file rubcli did not
write, or changed since, is never replaced or removed without ``force`` (the message
names it); with ``force`` the files named like this run's outputs are replaced and the
others kept. Entries that are rubcli's own never count: its lock, staging dirs, a sweep's
resume store (hidden names starting with ``.rubcli``, and older stores named
``.NAME.sweep-DIGEST``) and sub-dirs that are rubcli output dirs.

**Staging and commit.** Files are written into ``DIR/.rubcli-staging-PID-XXXX`` (inside
the target: one file system and one mount, so every move is a rename, also when the dir
is a mount point or a bind mount). ``commit`` adds the signed manifest to report.json and
writes a journal (signed for its staging dir, with the identity of each file it moves),
then moves the replaced and stale files of the previous run into the
staging dir and the new files in (report.json out first and in last: a dir whose
report.json is present is complete), with termination signals held (``signals.deferred``).
A move that fails (EXDEV, EIO, ...) rolls the moves back: nothing of the run is written,
the previous outputs are unchanged. A process killed during the commit (SIGKILL, power)
leaves the journal: the next command on the dir completes the commit before anything
else, if the journal is rubcli's and each file it moves unchanged (``_recover``; any other
journal is refused and left alone); a staging dir without a journal (killed before its
commit) is removed.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from rubcli.io import manifest, signals
from rubcli.io.files import atomic_path, json_text
from rubcli.io.lock import Busy, DirLock, NotALock

REPORT_NAME = "report.json"
STAGING_PREFIX = ".rubcli-staging-"
JOURNAL_NAME = ".rubcli-journal.json"
MARK_NAME = ".rubcli-staged.json"  # in a staging dir: signed by the command that made it
REPLACED_NAME = ".rubcli-replaced"  # in a staging dir: the files a commit moved out
OWN_PREFIX = ".rubcli"  # every hidden entry rubcli makes starts so (lock, staging, stores)
# A sweep's resume store of finished points beside its output dir, as older rubcli named
# it (.<dir name>.sweep-<digest>); newer stores start with OWN_PREFIX.
SWEEP_STORE = re.compile(r"^\..+\.sweep-[0-9a-f]{8,64}$")
# The errors of writing that are the machine's, not rubcli's: reported, exit 74.
WRITE_ERRNOS = frozenset(
    getattr(errno, name)
    for name in ("ENOSPC", "EDQUOT", "EFBIG", "EIO", "EROFS")
    if hasattr(errno, name)
)

COMMITTED: list[Path] = []  # output dirs committed by this process (for a signal's message)


class OutputError(Exception):
    """An output location that cannot be used; the message says which and why (exit 2)."""


class OutputBusy(OutputError):  # noqa: N818 - a state, like TimeoutError
    """The output dir is in use by another rubcli command (exit 75)."""


class OutputWriteError(OutputError):
    """The outputs could not be written (disk full, I/O error; exit 74). Nothing of the run
    was written; the previous outputs are unchanged."""


@dataclass
class OutputPlan:
    """An output dir opened by ``open_output_dir``: locked, checked; what it holds."""

    target: Path
    force: bool = False
    previous: list[str] = field(default_factory=list)  # rubcli's own files (manifest-verified)
    foreign: list[str] = field(default_factory=list)  # entries rubcli did not write
    changed: list[str] = field(default_factory=list)  # listed by the manifest, changed since
    removed: list[str] = field(default_factory=list)  # stale files removed at commit
    kept: list[str] = field(default_factory=list)  # stale, kept: changed since rubcli wrote them
    recovered: list[str] = field(default_factory=list)  # what was found of interrupted runs
    written: list[str] = field(default_factory=list)  # the names committed
    manifest_reason: str = ""  # why the dir's report.json is not rubcli's (if not)
    _lock: DirLock | None = field(default=None, repr=False)
    _created: list[Path] = field(default_factory=list, repr=False)
    _signature: dict[str, tuple] = field(default_factory=dict, repr=False)

    def close(self) -> None:
        """Release the lock and remove the dirs made for a target that got no outputs."""
        if self._lock is not None:
            self._lock.release()
            self._lock = None
        for directory in reversed(self._created):
            with contextlib.suppress(OSError):
                directory.rmdir()  # only if empty
        self._created.clear()

    def __enter__(self) -> OutputPlan:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def ours(self, name: str) -> bool:
        """Whether ``name`` is rubcli's and unchanged since the check."""
        if name not in self.previous:
            return False
        return _signature(self.target / name) == self._signature.get(name)


# ------------------------------------------------------------------- recognition


def is_own_entry(path: Path) -> bool:
    """rubcli's lock, staging, probe or a sweep's resume store (any hidden name that
    starts with ``.rubcli``, or an older store's): never an obstacle, never removed here
    (but for stale staging dirs of dead commands, under the lock)."""
    name = path.name
    return name.startswith(OWN_PREFIX) or (
        bool(SWEEP_STORE.match(name)) and path.is_dir() and not path.is_symlink()
    )


def _is_output_subdir(path: Path) -> bool:
    """A sub-dir that is itself a rubcli output dir (``compare/`` inside a case's dir):
    a manifest, an older rubcli report, or only rubcli's own entries (a command running)."""
    if path.is_symlink() or not path.is_dir():
        return False
    if manifest.read(path).valid or _legacy_report(path):
        return True
    try:
        entries = list(path.iterdir())
    except OSError:
        return False
    return bool(entries) and all(is_own_entry(p) for p in entries)


def _legacy_report(directory: Path) -> bool:
    """A report.json of a rubcli without manifests (only to accept a sub-dir as rubcli's;
    never a licence to replace or remove anything)."""
    try:
        report = json.loads((directory / REPORT_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(report, dict) and "rubcli_version" in report and "files" in report


def read_manifest(directory: Path) -> list[str] | None:
    """The files that ``directory``'s verified manifest lists (None without one)."""
    found = manifest.read(Path(directory))
    return sorted([*found.files, REPORT_NAME]) if found.valid else None


# --------------------------------------------------------------------- the check


def _signature(path: Path) -> tuple | None:
    try:
        st = os.lstat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def _shorten(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else f"{text[: limit - 20]}...({len(text)} characters)"


def _check_names(target: Path) -> None:
    """Every component of the path must fit the file system (else a clear message)."""
    if "\0" in str(target):
        raise OutputError(f"{_shorten(repr(str(target)), 120)}: the output dir's name holds a NUL "
                          "byte (\\0), which no file name may hold")  # fmt: skip
    absolute = Path(os.path.abspath(target))
    base = absolute
    while not os.path.lexists(base) and base != base.parent:
        base = base.parent
    try:
        name_max = os.pathconf(base if base.is_dir() else base.parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    for part in absolute.parts[1:]:
        size = len(os.fsencode(part))
        if size > name_max:
            raise OutputError(
                f"{_shorten(str(target), 120)}: the name {_shorten(part)!r} is {size} bytes "
                f"long; this file system allows at most {name_max}"
            )
    if len(os.fsencode(str(absolute))) > 4000:
        raise OutputError(f"{_shorten(str(target), 120)}: the path is too long")


def _reason(exc: OSError) -> str:
    """The cause of an OSError in a few words (h5py's carry the errno inside a page of
    text: "... errno = 28, error message = ...")."""
    if exc.strerror:
        return exc.strerror
    found = re.search(r"errno = (\d+)", str(exc))
    if found:
        return os.strerror(int(found.group(1)))
    first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return first if len(first) <= 120 else first[:100] + "..."


def _make_dirs(target: Path, created: list[Path]) -> None:
    """Create ``target`` and its missing parents, recording the ones made."""
    if os.path.lexists(target) and not target.exists():
        raise OutputError(f"{target}: output dir is a broken symbolic link")
    if target.exists() and not target.is_dir():
        raise OutputError(f"{target}: output dir exists and is not a directory")
    missing = []
    for directory in (target, *target.parents):
        if os.path.lexists(directory):
            if not directory.is_dir():
                raise OutputError(f"{target}: cannot create the output dir: {directory} is "
                                  "not a directory")  # fmt: skip
            break
        missing.append(directory)
    for directory in reversed(missing):
        try:
            directory.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise _unwritable(target, exc, f"{directory}: ") from None
        created.append(directory)


def open_output_dir(
    target: str | Path,
    *,
    force: bool = False,
    wait: bool = False,
    expected: Iterable[str] = (),
    on_wait: Callable[[str], None] | None = None,
) -> OutputPlan:
    """Lock, recover and check an output dir before anything is computed (see the module
    docstring); raise ``OutputError`` (``OutputBusy`` when locked) saying why not.

    ``expected``: names the command will write, so that a file of the user's with one of
    these names is refused now rather than at the commit. The caller must ``close()`` the
    plan (a ``with`` block does).
    """
    target = Path(target)
    _check_names(target)
    try:
        manifest.require_key()  # else its manifest would be unsigned, the dir not rubcli's
    except manifest.KeyUnavailable as exc:
        error = OutputWriteError if exc.errno in WRITE_ERRNOS else OutputError
        raise error(f"{target}: {exc}") from None
    plan = OutputPlan(target=target, force=force)
    try:
        for attempt in range(100):
            _make_dirs(target, plan._created)
            lock = DirLock(target)
            try:
                lock.acquire(wait=wait, on_wait=on_wait)
            except FileNotFoundError:
                if attempt == 99:
                    raise OutputError(f"{target}: output dir keeps vanishing") from None
                continue  # the dir was removed meanwhile (by a holder that made it)
            except Busy as exc:
                raise OutputBusy(
                    f"{target}: output dir is in use by {exc.holder}; wait for it to finish, "
                    "or pass --wait to wait for it"
                ) from None
            except NotALock as exc:
                raise OutputError(f"{target}: {exc}") from None
            except OSError as exc:
                raise _unwritable(target, exc) from None
            plan._lock = lock
            break
        _recover(plan)
        _inspect(plan)
        _refuse(plan, list(expected))
    except BaseException:
        plan.close()
        raise
    return plan


def _unwritable(target: Path, exc: OSError, where: str = "") -> OutputError:
    """The dir or its lock could not be made: exit 74 for the machine's reasons (a full
    disk), 2 for the others (permissions, a file in the way)."""
    if is_write_failure(exc):
        return OutputWriteError(f"{target}: the output dir cannot be written ({where}"
                                f"{_reason(exc)}); nothing was written")  # fmt: skip
    return OutputError(f"{target}: output dir is not writable ({where}{_reason(exc)})")


def _inspect(plan: OutputPlan) -> None:
    target = plan.target
    try:
        entries = sorted(target.iterdir(), key=lambda p: p.name)
    except OSError as exc:
        raise OutputError(f"{target}: output dir is not readable ({_reason(exc)})") from None
    found = manifest.read(target)
    plan.manifest_reason = found.reason
    listed = set(found.files) | {REPORT_NAME} if found.valid else set()
    for path in entries:
        name = path.name
        if is_own_entry(path) or (name not in listed and _is_output_subdir(path)):
            continue
        if name in listed and found.owns(target, name):
            plan.previous.append(name)
            plan._signature[name] = _signature(path)
        else:
            plan.foreign.append(name)
            if name in listed:
                plan.changed.append(name)


def _listing(names: list[str], limit: int = 6) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def _refuse(plan: OutputPlan, expected: list[str]) -> None:
    folders = [n for n in expected if _is_folder(plan.target / n)]
    if folders:
        raise OutputError(_folder_message(plan.target, folders))
    if plan.force:
        return
    if plan.foreign and not plan.previous:
        why = plan.manifest_reason or "no report.json"
        raise OutputError(
            f"{plan.target}: output dir is not empty and was not written by rubcli ({why}; "
            f"it holds {_listing(plan.foreign)}); rubcli never replaces or removes files it "
            "did not write: choose a new or empty dir, or pass --force to write beside them "
            "(files named like this command's outputs are then replaced)"
        )
    collide = [n for n in expected if n in plan.foreign]
    if collide:
        raise OutputError(_collision_message(plan, collide))


def _is_folder(path: Path) -> bool:
    return path.is_dir() and not path.is_symlink()


def _folder_message(target: Path, names: list[str]) -> str:
    one = len(names) == 1
    return (
        f"{target}: {_listing(names)} {'is a directory' if one else 'are directories'}, "
        f"and this command writes a file of {'that name' if one else 'those names'}; rubcli "
        f"never replaces or removes a directory (not with --force either): move "
        f"{'it' if one else 'them'} away, or choose another output dir"
    )


def _collision_message(plan: OutputPlan, names: list[str]) -> str:
    changed = [n for n in names if n in plan.changed]
    one = len(names) == 1
    if len(changed) == len(names):
        what = f"{'was' if one else 'were'} changed since rubcli wrote {'it' if one else 'them'}"
    else:
        what = f"{'was' if one else 'were'} not written by rubcli" + (
            " (or changed since)" if changed else ""
        )
    it = "it" if one else "them"
    return (
        f"{plan.target}: {_listing(names)} {what}, and this command would replace {it}: "
        f"move {it} away, or pass --force to replace {it}"
    )


# ------------------------------------------------------------------ staging, commit


class StagedOutput:
    """A staging dir inside the target whose files ``commit()`` moves in, all together."""

    def __init__(self, target: str | Path, plan: OutputPlan):
        self.target = Path(target)
        self.plan = plan
        prefix = f"{STAGING_PREFIX}{os.getpid()}-"
        try:
            self.staging = Path(tempfile.mkdtemp(dir=self.target, prefix=prefix))
        except OSError as exc:
            raise _write_error(self.target, exc) from None
        try:
            _write_json(self.staging / MARK_NAME, _signed_mark(self.staging))
        except OSError as exc:
            shutil.rmtree(self.staging, ignore_errors=True)  # just made: nothing else in it
            raise _write_error(self.target, exc) from None
        self.committed: list[Path] = []
        self._report: dict | None = None

    def write_report(self, report: dict) -> Path:
        """Stage ``report`` as report.json; the commit adds its manifest to this dict too
        (so that a command printing the report prints what the file holds)."""
        self._report = report
        return _write_json(self.path(REPORT_NAME), report)

    def path(self, name: str) -> Path:
        """Where to write the output ``name`` (a plain file name) while staging."""
        if Path(name).name != name or name in ("", ".", "..") or name.startswith(".rubcli"):
            raise ValueError(f"output names are plain file names, not {name!r}")
        return self.staging / name

    def names(self) -> list[str]:
        """The outputs staged so far, sorted (what the commit moves in; not the staging
        dir's own hidden entries)."""
        return sorted(p.name for p in self.staging.iterdir()
                      if p.is_file() and not p.name.startswith("."))  # fmt: skip

    def commit(self, last: tuple[str, ...] = (REPORT_NAME,)) -> list[Path]:
        """Move every staged file into the target, as a whole (see the module docstring);
        the names in ``last`` go in last. Then the stale files of the previous run are
        gone (``plan.removed``), except those changed since rubcli wrote them (``kept``)."""
        with signals.deferred():
            try:
                self._commit(last)
            except BaseException:
                self.discard()
                raise
        return self.committed

    def _commit(self, last: tuple[str, ...]) -> None:
        plan, target = self.plan, self.target
        try:
            staged = self.names()
            if REPORT_NAME not in staged:
                from rubcli.io.files import report_envelope

                files = [*staged, REPORT_NAME]
                _write_json(self.staging / REPORT_NAME,
                            {**report_envelope("write", {}), "files": files})  # fmt: skip
                staged.append(REPORT_NAME)
            digests = {n: manifest.file_digest(self.staging / n)
                       for n in staged if n != REPORT_NAME}  # fmt: skip
            added = manifest.add_to_report(self.staging / REPORT_NAME, digests)
        except OSError as exc:
            raise _write_error(target, exc) from None
        # Who may be replaced: rubcli's own unchanged files, anything with force.
        collide = [n for n in staged if os.path.lexists(target / n) and not plan.ours(n)]
        folders = [n for n in collide if _is_folder(target / n)]
        if folders:
            raise OutputError(_folder_message(target, folders))
        if collide and not plan.force:
            raise OutputError(_collision_message(plan, collide))
        stale = [n for n in plan.previous if n not in staged and plan.ours(n)]
        plan.kept = [n for n in plan.previous + plan.changed
                     if n not in staged and n not in stale
                     and os.path.lexists(target / n)]  # fmt: skip
        staged.sort(key=lambda n: (n in last, last.index(n) if n in last else 0, n))
        out = [n for n in (*reversed(last), *staged, *stale)
               if os.path.lexists(target / n) and (n in staged or n in stale)]  # fmt: skip
        out = list(dict.fromkeys(out))
        journal = _signed_journal(self.staging, out, staged)
        try:
            _write_json(self.staging / JOURNAL_NAME, journal, sync=True)
            (self.staging / REPLACED_NAME).mkdir()
        except OSError as exc:
            raise _write_error(target, exc) from None
        done_out: list[str] = []
        done_in: list[str] = []
        try:
            for name in out:
                os.rename(target / name, self.staging / REPLACED_NAME / name)
                done_out.append(name)
            for name in staged:
                os.rename(self.staging / name, target / name)
                done_in.append(name)
        except OSError as exc:
            if not _roll_back(target, self.staging, done_out, done_in):
                raise OutputWriteError(
                    f"{target}: the commit failed ({_reason(exc)}) and could not be undone; "
                    f"the next rubcli command on this dir completes it from {self.staging.name}"
                ) from None
            raise _write_error(target, exc, moving=True) from None
        (self.staging / JOURNAL_NAME).unlink()
        _sync_dir(target)
        if self._report is not None:
            self._report[manifest.KEY] = added
        self.committed = [target / n for n in staged]
        plan.written = staged
        plan.removed = stale
        COMMITTED.append(target)
        shutil.rmtree(self.staging, ignore_errors=True)

    def discard(self) -> None:
        """Remove the staging dir and what is in it (never a journal's files: a commit
        that could not be undone is left for the next command to complete)."""
        if (self.staging / JOURNAL_NAME).exists():
            return
        shutil.rmtree(self.staging, ignore_errors=True)


def _release_quietly(exc: BaseException) -> None:
    """Free what a failed write left referenced by the exception's frames (an h5py file
    whose deallocation fails again on the full disk and prints "Exception ignored"
    tracebacks), with those messages silenced: the failure is reported once, as ours."""
    import gc
    import sys
    import traceback

    hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: None
    try:
        traceback.clear_frames(exc.__traceback__)
        exc.__traceback__ = None
        gc.collect()
    finally:
        sys.unraisablehook = hook


def _roll_back(target: Path, staging: Path, done_out: list[str], done_in: list[str]) -> bool:
    """Undo a commit's moves; True if the dir is as before."""
    try:
        for name in reversed(done_in):
            os.rename(target / name, staging / name)
        for name in reversed(done_out):
            os.rename(staging / REPLACED_NAME / name, target / name)
    except OSError:
        return False
    (staging / JOURNAL_NAME).unlink(missing_ok=True)
    return True


def _write_json(path: Path, data, sync: bool = False) -> Path:
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as handle:
        handle.write(json_text(data))
        if sync:
            handle.flush()
            os.fsync(handle.fileno())
    return path


def _sync_dir(directory: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _write_error(target: Path, exc: OSError, moving: bool = False) -> OutputWriteError:
    where = f" ({Path(exc.filename).name})" if getattr(exc, "filename", None) else ""
    step = "move the outputs into place" if moving else "write the outputs"
    return OutputWriteError(
        f"{target}: could not {step}: {_reason(exc)}{where}; nothing of this run was "
        "written, the previous outputs are unchanged"
    )


def is_write_failure(exc: BaseException) -> bool:
    """An OSError of writing that is the machine's (disk full, quota, file size limit,
    I/O error, read-only, permissions), also as h5py reports it (errno in the text)."""
    if not isinstance(exc, OSError):
        return False
    if exc.errno in WRITE_ERRNOS:
        return True
    text = str(exc)
    return any(f"errno = {n}," in text or f"errno = {n} " in text or os.strerror(n) in text
               for n in (errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EIO))  # fmt: skip


# ------------------------------------------------------------------- recovery


def _recover(plan: OutputPlan) -> None:
    """Under the lock: complete the commits of killed commands, remove their staging.

    A staging dir without a journal (its command was killed before its commit) is removed
    when rubcli can show it made it (``_remove_staging``); any other is refused, left as
    it is. A journal is acted on only when it is rubcli's: signed
    with this user's key (``manifest.sign``) for this staging dir, and every file it would
    move still the very file it recorded (device, inode, size, time). Any other journal is
    refused and its staging dir left as it is: it may hold a user's files (or a commit of
    another key's), and moving or removing them could lose them."""
    target = plan.target
    for path in sorted(target.glob(f"{STAGING_PREFIX}*")):
        try:
            st = os.lstat(path)
        except OSError:
            continue
        uid = os.geteuid() if hasattr(os, "geteuid") else st.st_uid
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != uid:
            continue  # not ours to touch (it counts as foreign)
        with signals.deferred():
            if not os.path.lexists(path / JOURNAL_NAME):
                _remove_staging(target, path)
                plan.recovered.append(f"removed {path.name}, left by an interrupted command")
                continue
            journal = _read_journal(path)
            if journal is None:
                raise OutputError(
                    f"{target}: {path.name} holds a commit journal that rubcli did not sign "
                    "with your key: it is not acted on, nothing in the dir was moved or "
                    f"removed; look at what it holds and remove it (rm -r '{path}')"
                )
            _roll_forward(target, path, journal)
            plan.recovered.append(
                f"completed the interrupted commit of an earlier command (pid "
                f"{journal.get('pid')}): {', '.join(journal['in'])}"
            )
            shutil.rmtree(path, ignore_errors=True)


def _signed_mark(staging: Path) -> dict:
    """The mark a command leaves in the staging dir it made: the dir's name and identity
    (device, inode), signed, so that a mark copied into another dir is not valid."""
    st = os.lstat(staging)
    mark = {"staging": staging.name, "dir": [st.st_dev, st.st_ino], "pid": os.getpid()}
    return {**mark, "signature": manifest.sign(mark)}


def _remove_staging(target: Path, staging: Path) -> None:
    """Remove a staging dir left without a journal, if rubcli can show it made it and it
    holds only what a command stages: an empty dir (killed as it was made), or a dir with
    a valid mark (``_signed_mark``) and nothing but regular files (staged outputs and
    their temporary files). Anything else (no mark, another dir's or key's mark, a
    subdirectory, a link) is refused with nothing removed: the files may be anyone's."""
    try:
        entries = list(os.scandir(staging))
        st = os.lstat(staging)
        mark = json.loads((staging / MARK_NAME).read_text(encoding="utf-8")) if entries else {}
    except (OSError, ValueError):
        entries, mark = [], None
        ours = False
    else:
        ours = not entries
    if isinstance(mark, dict) and entries:
        body = {k: v for k, v in mark.items() if k != "signature"}
        ours = (
            manifest.signed(body, mark.get("signature"))
            and body.get("staging") == staging.name
            and body.get("dir") == [st.st_dev, st.st_ino]
            and all(e.is_file(follow_symlinks=False) for e in entries)
        )
    if not ours:
        raise OutputError(
            f"{target}: {staging.name} is a staging dir that rubcli cannot show it made "
            "(no mark signed with your key for it, or it holds more than staged files): it "
            f"is left as it is, nothing in the dir was moved or removed; look at what it "
            f"holds and remove it (rm -r '{staging}')"
        )
    with contextlib.suppress(OSError):  # what cannot be removed is left (it is ours)
        for entry in entries:
            if entry.name != MARK_NAME:
                os.unlink(entry.path)
        if entries:
            os.unlink(staging / MARK_NAME)
        os.rmdir(staging)


def _identity(path: Path) -> list[int] | None:
    """What a commit records of a file it moves (a rename keeps all four)."""
    found = _signature(path)
    return None if found is None else list(found[:4])


def _signed_journal(staging: Path, out: list[str], staged: list[str]) -> dict:
    """The journal of a commit: the files it moves out and in, each with its identity,
    signed for this staging dir."""
    target = staging.parent
    journal = {
        "journal": "rubcli commit",
        "pid": os.getpid(),
        "staging": staging.name,
        "out": {n: _identity(target / n) for n in out},
        "in": {n: _identity(staging / n) for n in staged},
    }
    return {**journal, "signature": manifest.sign(journal)}


def _read_journal(staging: Path) -> dict | None:
    """The journal in ``staging`` if rubcli signed it there with this user's key."""
    try:
        journal = json.loads((staging / JOURNAL_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(journal, dict):
        return None
    body = {k: v for k, v in journal.items() if k != "signature"}
    if not manifest.signed(body, journal.get("signature")) or body.get("staging") != staging.name:
        return None
    ok = all(isinstance(journal.get(k), dict) for k in ("in", "out")) and all(
        Path(n).name == n and n not in ("", ".", "..") and not n.startswith(OWN_PREFIX)
        for n in [*journal["in"], *journal["out"]]
    )
    return journal if ok else None


def _roll_forward(target: Path, staging: Path, journal: dict) -> None:
    """Complete a journal's moves; first check that each is what the commit recorded (a
    file changed or made since is never moved or replaced: OutputError, nothing moved)."""
    moved_in = {n: ident[:2] for n, ident in journal["in"].items() if ident}
    out, changed = [], []
    for name, ident in journal["out"].items():
        now = _identity(target / name)
        if now is None or now[:2] == moved_in.get(name):
            continue  # moved out already (and perhaps its new file in)
        (out if now == ident else changed).append(name)
    pending = [n for n in journal["in"] if os.path.lexists(staging / n)]
    for name in pending:
        if _identity(staging / name) != journal["in"][name]:
            changed.append(name)
        elif os.path.lexists(target / name) and name not in out:
            changed.append(name)  # made since: it would be replaced
    if changed:
        raise OutputError(
            f"{target}: the interrupted commit in {staging.name} cannot be completed: "
            f"{_listing(sorted(set(changed)))} changed since it began; nothing was moved: "
            f"move {'it' if len(set(changed)) == 1 else 'them'} away and run again"
        )
    replaced = staging / REPLACED_NAME
    try:
        replaced.mkdir(exist_ok=True)
        for name in out:
            os.rename(target / name, replaced / name)
        for name in pending:
            os.rename(staging / name, target / name)
    except OSError as exc:
        raise OutputWriteError(
            f"{target}: the interrupted commit in {staging.name} could not be completed "
            f"({_reason(exc)}); the next rubcli command on this dir tries again"
        ) from None
    _sync_dir(target)


# ------------------------------------------------------------------ the block


@contextlib.contextmanager
def staged_output_dir(
    target: str | Path, plan: OutputPlan | None = None, *, force: bool = False
) -> Iterator[StagedOutput]:
    """Stage outputs; commit them into ``target`` as a whole only if the block completes.

    ::

        with staged_output_dir("out/fig3a", plan) as out:
            write_json(out.path("report.json"), report)
        # now out/fig3a/report.json exists; after an exception nothing would.

    ``plan``: from ``open_output_dir`` (kept open by the caller); without one the dir is
    opened (locked, checked with ``force``) here and closed after the commit. A failure to
    write (disk full, ...) raises ``OutputWriteError``.
    """
    own = plan is None
    if plan is None:
        plan = open_output_dir(target, force=force)
    try:
        staged = None
        try:
            # the staging dir is made with termination signals held, so that a signal
            # arriving as it is made finds it known here, and removed
            with signals.deferred():
                staged = StagedOutput(target, plan)
            yield staged
        except BaseException as exc:
            if staged is None:
                raise
            if is_write_failure(exc):
                error = _write_error(Path(target), exc)
                _release_quietly(exc)
                staged.discard()
                raise error from None
            staged.discard()
            raise
        staged.commit()
    finally:
        if own:
            plan.close()

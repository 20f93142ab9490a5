"""One rubcli command per output dir at a time: an OS lock (``flock``) on ``.rubcli.lock``.

The lock file is made inside the output dir and removed when the command ends; the OS
releases the lock of a process that dies (SIGKILL included), so a lock is never stale.
The file holds the holder's pid and command, for the message of a command refused.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import errno
import os
import stat
import sys
from collections.abc import Callable
from pathlib import Path

LOCK_NAME = ".rubcli.lock"

try:
    import fcntl
except ImportError:  # pragma: no cover - not on POSIX: no locking
    fcntl = None


class Busy(Exception):  # noqa: N818 - a state, reported to the user
    """The output dir is locked by another process; ``holder`` describes it."""

    def __init__(self, directory: Path, holder: str):
        self.directory = directory
        self.holder = holder
        super().__init__(f"{directory}: in use by {holder}")


def _describe_me() -> str:
    command = " ".join(["rubcli", *sys.argv[1:2]])  # e.g. "rubcli run"
    started = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    return f"{command} (pid {os.getpid()}, since {started})"


def _holder(fd: int) -> str:
    try:
        text = os.pread(fd, 400, 0).decode("utf-8", "replace").strip()
    except OSError:
        text = ""
    return text or "another rubcli command"


class NotALock(Exception):  # noqa: N818 - a state, reported to the user
    """The lock's name is taken by something that is not rubcli's lock file (a symbolic or
    hard link, a directory, ...): it is neither written nor removed."""

    def __init__(self, path: Path, what: str):
        self.path = path
        super().__init__(
            f"{path.name} is {what}, not rubcli's lock file; rubcli writes nothing through "
            f"it: remove it (rm '{path}') if no rubcli command is running there"
        )


class DirLock:
    """The lock of one output dir (``acquire``/``release``)."""

    def __init__(self, directory: Path):
        self.directory = Path(directory)
        self.path = self.directory / LOCK_NAME
        self.fd: int | None = None

    def acquire(self, wait: bool = False, on_wait: Callable[[str], None] | None = None) -> None:
        """Take the lock; raise ``Busy`` if another process holds it (with ``wait``: block
        until it is free, calling ``on_wait(holder)`` once first), ``NotALock`` if the name
        is taken by something that is not rubcli's lock file. A termination signal
        interrupts the wait (its handler raises). A failure once locked (a full disk) leaves
        no lock file."""
        told = False
        while True:
            fd = self._open()
            locked = False
            try:
                if fcntl is not None:
                    try:
                        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    except BlockingIOError:
                        holder = _holder(fd)
                        if not wait:
                            raise Busy(self.directory, holder) from None
                        if not told and on_wait is not None:
                            on_wait(holder)
                            told = True
                        fcntl.flock(fd, fcntl.LOCK_EX)
                locked = True
                if not self._still_named(fd):  # removed by its last holder: take the new one
                    os.close(fd)
                    continue
                self._check(fd)  # (again: linked meanwhile?) never written through a link
                if os.fstat(fd).st_uid == (os.geteuid() if hasattr(os, "geteuid") else 0):
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, (_describe_me() + "\n").encode(), 0)
            except BaseException:
                if locked and self._still_named(fd):
                    with contextlib.suppress(OSError):
                        os.unlink(self.path)  # as ``release`` does: no lock file left behind
                os.close(fd)
                raise
            self.fd = fd
            return

    def _open(self) -> int:
        """Open the lock file (made now if missing), checked to be one."""
        flags = os.O_RDWR | os.O_CLOEXEC | getattr(os, "O_NOFOLLOW", 0) | os.O_NONBLOCK
        for _ in range(100):
            try:
                fd = os.open(self.path, flags | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                try:
                    fd = os.open(self.path, flags)
                except FileNotFoundError:
                    continue  # removed by its holder meanwhile: make it
                except OSError as exc:
                    if exc.errno in (errno.ELOOP, errno.EISDIR, errno.ENXIO):
                        raise NotALock(self.path, self._kind()) from None
                    raise
            try:
                self._check(fd)
            except BaseException:
                os.close(fd)
                raise
            return fd
        raise OSError(errno.EAGAIN, "the lock file keeps vanishing", str(self.path))

    def _kind(self) -> str:
        try:
            mode = os.lstat(self.path).st_mode
        except OSError:
            return "not a regular file"
        if stat.S_ISLNK(mode):
            return "a symbolic link"
        return "a directory" if stat.S_ISDIR(mode) else "not a regular file"

    def _check(self, fd: int) -> None:
        """A regular file with this one name: writing it never writes a file elsewhere."""
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise NotALock(self.path, "not a regular file")
        if st.st_nlink != 1:
            raise NotALock(self.path, f"a hard link (one of {st.st_nlink} names of one file)")

    def _still_named(self, fd: int) -> bool:
        try:
            named = os.lstat(self.path)
        except FileNotFoundError:
            return False
        mine = os.fstat(fd)
        return (named.st_dev, named.st_ino) == (mine.st_dev, mine.st_ino)

    def release(self) -> None:
        """Remove the lock file (a waiter then locks a new one) and release the lock."""
        if self.fd is None:
            return
        try:
            if self._still_named(self.fd):
                os.unlink(self.path)
        except OSError:
            pass
        finally:
            os.close(self.fd)
            self.fd = None

    @property
    def held(self) -> bool:
        return self.fd is not None

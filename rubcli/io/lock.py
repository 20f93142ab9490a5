"""One rubcli command per output dir at a time: an OS lock (``flock``) on ``.rubcli.lock``.

The lock file is made inside the output dir and removed when the command ends; the OS
releases the lock of a process that dies (SIGKILL included), so a lock is never stale.
The file holds the holder's pid and command, for the message of a command refused.
"""

from __future__ import annotations

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


class DirLock:
    """The lock of one output dir (``acquire``/``release``)."""

    def __init__(self, directory: Path):
        self.directory = Path(directory)
        self.path = self.directory / LOCK_NAME
        self.fd: int | None = None

    def acquire(self, wait: bool = False, on_wait: Callable[[str], None] | None = None) -> None:
        """Take the lock; raise ``Busy`` if another process holds it (with ``wait``: block
        until it is free, calling ``on_wait(holder)`` once first). A termination signal
        interrupts the wait (its handler raises)."""
        told = False
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC
                         | getattr(os, "O_NOFOLLOW", 0), 0o644)  # fmt: skip
            try:
                if not stat.S_ISREG(os.fstat(fd).st_mode):
                    raise OSError(errno.EINVAL, "the lock file is not a regular file", self.path)
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
                if not self._still_named(fd):  # removed by its last holder: take the new one
                    os.close(fd)
                    continue
                if os.fstat(fd).st_uid == (os.geteuid() if hasattr(os, "geteuid") else 0):
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, (_describe_me() + "\n").encode(), 0)
            except BaseException:
                os.close(fd)
                raise
            self.fd = fd
            return

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

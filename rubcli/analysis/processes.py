"""Local worker processes that never outlive the command that started them.

A ``ProcessPoolExecutor``'s workers wait for their next task on a pipe; when the parent is
killed outright (SIGKILL, the OOM killer) nothing tells them, and they go on computing
their current task and then wait for ever. On Linux each worker asks the kernel to kill it
when its parent dies (``prctl(PR_SET_PDEATHSIG, SIGKILL)``): the parent keeps every
finished result, so a worker has nothing to save. Elsewhere nothing ends such workers
early: stop a command with Ctrl-C or SIGTERM, which shut its pool down.
"""

from __future__ import annotations

import concurrent.futures as cf
import ctypes
import os
import signal
import sys

PR_SET_PDEATHSIG = 1  # linux/prctl.h


def die_with_parent(parent: int) -> None:
    """Worker initializer: be killed when ``parent`` dies (Linux); exit now if it has."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the request took effect
        os._exit(0)


def local_pool(workers: int) -> cf.ProcessPoolExecutor:
    """A pool of ``workers`` processes that die with this one."""
    return cf.ProcessPoolExecutor(
        max_workers=workers, initializer=die_with_parent, initargs=(os.getpid(),)
    )

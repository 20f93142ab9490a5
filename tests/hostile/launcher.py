"""Run the rubcli command line with one fault injected at a chosen point.

Used by the hostile tests (``conftest.run_cli(..., fault=...)``); run as
``python launcher.py ARGS...`` with the fault in the environment variable
``RUBCLI_HOSTILE_FAULT`` (JSON)::

    {"at": "import:numpy"                  # when the process imports numpy
           | "call:rubcli.solvers:solve"   # when module.attr is called (nth call;
                                           #  "module:Class.method" for a method)
           | "move:2",                     # at the 2nd rename of an output dir's commit
     "nth": 1,                             # which call (default the first)
     "within": "module:attr",              # count only calls made inside this call
     "frame": "callee",                    # the fault runs as if in the callee's own
                                           # source file (numba's, say)
     "do": "signal" | "kill" | "hold" | "exdev" | "nomemory",
     "signal": 15, "delay": 0.0,           # "signal": this signal, after delay seconds
     "hold": 1.0,                          # "hold": sleep this long (signal from outside)
     "marker": "/path/file"}               # made when the point is reached

``signal`` sends a real signal to this process (from a timer thread after ``delay``, so
that it lands inside the call, compiled code included; at once if 0); ``kill`` sends
SIGKILL; ``hold`` waits, so that the test can signal from outside once the marker exists;
``exdev`` fails the rename as between file systems; ``nomemory`` raises MemoryError from
the call. ``move`` points act after the rename
(``exdev``: instead of it). Works with the rubcli of any version (its entry point is
``rubcli.cli.entry.main`` or, before that, ``rubcli.cli.app.main``).
"""

from __future__ import annotations

import errno
import importlib
import json
import os
import sys
import threading
import time

# POSIX numbers: the signal module is not imported here, so that a fault may be set at
# its import by the command line
SIGKILL, SIGTERM = 9, 15
FAULT = json.loads(os.environ.get("RUBCLI_HOSTILE_FAULT", "{}"))


def _reached() -> None:
    marker = FAULT.get("marker")
    if marker:
        with open(marker, "w") as handle:
            handle.write(str(os.getpid()))
    action = FAULT.get("do", "signal")
    if action == "kill":
        os.kill(os.getpid(), SIGKILL)
    elif action == "hold":
        time.sleep(float(FAULT.get("hold", 1.0)))
    elif action == "nomemory":
        raise MemoryError
    elif action == "signal":
        signum, delay = int(FAULT.get("signal", SIGTERM)), float(FAULT.get("delay", 0))
        if delay > 0:
            timer = threading.Timer(delay, os.kill, args=(os.getpid(), signum))
            timer.daemon = True
            timer.start()
        else:
            os.kill(os.getpid(), signum)


def _counter():
    calls = [0]

    def due() -> bool:
        calls[0] += 1
        return calls[0] == int(FAULT.get("nth", 1))

    return due


def _on_import(name: str) -> None:
    due = _counter()

    def hook(event, args):
        if event == "import" and args and args[0] == name and due():
            _reached()

    sys.addaudithook(hook)


def _resolve(where: str):
    module_name, path = where.rsplit(":", 1)
    owner = importlib.import_module(module_name)
    *parents, attr = path.split(".")  # "Class.method" patches the class's method
    for name in parents:
        owner = getattr(owner, name)
    return owner, attr


WRAPPER = """
def wrapped(*args, **kwargs):
    if inside[0] and due():
        reached()
    return real(*args, **kwargs)
"""


def _on_call(where: str) -> None:
    owner, attr = _resolve(where)
    real = getattr(owner, attr)
    inside = [True]
    if FAULT.get("within"):
        inside[0] = False
        outer_owner, outer_attr = _resolve(FAULT["within"])
        outer = getattr(outer_owner, outer_attr)

        def tracked(*args, **kwargs):
            inside[0] = True
            try:
                return outer(*args, **kwargs)
            finally:
                inside[0] = False

        setattr(outer_owner, outer_attr, tracked)
    # "frame": "callee": the wrapper's code carries the callee's file name, so that a
    # signal handler running in it sees the frame the real callee would give it.
    filename = real.__code__.co_filename if FAULT.get("frame") == "callee" else __file__
    scope = {"inside": inside, "due": _counter(), "reached": _reached, "real": real}
    exec(compile(WRAPPER, filename, "exec"), scope)
    setattr(owner, attr, scope["wrapped"])


class _OsWithFaultyMoves:
    """The ``os`` module as the output commit sees it, its renames counted."""

    def __init__(self, nth: int):
        self._nth = nth
        self._moves = 0

    def __getattr__(self, name):
        return getattr(os, name)

    def _move(self, real, src, dst):
        self._moves += 1
        if self._moves == self._nth and FAULT.get("do") == "exdev":
            raise OSError(errno.EXDEV, os.strerror(errno.EXDEV), str(src))
        result = real(src, dst)
        if self._moves == self._nth:
            _reached()
        return result

    def rename(self, src, dst):
        return self._move(os.rename, src, dst)

    def replace(self, src, dst):
        return self._move(os.replace, src, dst)


def _on_move(nth: int) -> None:
    from rubcli.io import outputs

    outputs.os = _OsWithFaultyMoves(nth)


def main() -> None:
    at = FAULT.get("at", "")
    kind, _, where = at.partition(":")
    if kind == "import":
        _on_import(where)
    elif kind == "call":
        _on_call(where)
    elif kind == "move":
        _on_move(int(where))
    sys.argv = ["rubcli", *sys.argv[1:]]
    try:
        from rubcli.cli.entry import main as rubcli_main
    except ImportError:  # a rubcli before its light entry point
        from rubcli.cli.app import main as rubcli_main
    rubcli_main()


if __name__ == "__main__":
    main()

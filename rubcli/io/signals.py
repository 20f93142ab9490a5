"""Termination signals (SIGTERM, SIGINT, SIGHUP) as ``Terminated``, raised only where safe.

The ``rubcli`` entry point calls ``install()`` on its first line, before numpy and the
commands are imported, so that a signal at any moment ends the command with exit code
128 + N and a one-line message, never a ``KeyboardInterrupt`` traceback.

The handler records the signal and raises ``Terminated`` in the main thread, except

- inside ``deferred()`` (an output dir's commit): the block runs to its end, then
  ``Terminated`` is raised, so that a commit is never cut in two;
- while the interrupted Python frame is numba's or llvmlite's own code, called from
  compiled code (numba's dispatcher unpickling or boxing a result): an exception raised
  there is lost by the dispatcher (``SystemError: CPUDispatcher(...) returned a result with
  an exception set``); or the import system's, which holds the global import lock in
  places where an exception would never release it (a later import in another thread
  then waits for ever). A timer (``SIGALRM``, every 10 ms) then tries again, until the
  main thread is in a frame where raising is safe.

Where Python cannot pass an exception on (an at-fork hook such as logging's, run as a
pool forks a worker; a ``__del__``; a weakref callback) it prints ``Terminated`` as
"Exception ignored" and drops it: ``install`` also hooks ``sys.unraisablehook``, which
takes such a ``Terminated`` back and raises it again at the next try of the timer.

``Terminated`` is raised once per process; ``checkpoint()`` (called where a long loop
reports progress) raises it again if something swallowed it, and ``pending()`` lets a
last-resort handler tell that an exception is the consequence of a signal.

This module imports only the standard library (it runs before anything else).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

__all__ = [
    "TERMINATION_SIGNALS",
    "Terminated",
    "checkpoint",
    "deferred",
    "finish",
    "install",
    "pending",
    "stop_message",
    "termination_as_exception",
]


class Terminated(BaseException):  # noqa: N818 - like KeyboardInterrupt, not an error
    """Raised in the main thread when the process receives SIGTERM, SIGINT or SIGHUP, so
    that staged outputs are removed on the way out; exit with ``exit_code``."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(f"terminated by {signal.Signals(signum).name}")

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


TERMINATION_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGTERM", "SIGINT", "SIGHUP") if hasattr(signal, name)
)

# Frames where raising is unsafe: numba's and llvmlite's (run inside compiled code's C
# calls) and the import system's (the import lock).
_UNSAFE_PARTS = (*(f"{os.sep}{name}{os.sep}" for name in ("numba", "llvmlite", "importlib")),
                 "<frozen importlib")  # fmt: skip
RETRY_S = 0.01


class _State:
    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.pending: int | None = None  # the first termination signal received
        self.raised = False  # Terminated was raised for it
        self.deferred = 0  # depth of deferred() blocks in the main thread
        self.pid = os.getpid()  # the process that installed the handlers


_state = _State()
_RETRY_SIGNAL = (signal.SIGALRM,) if hasattr(signal, "setitimer") else ()
_installed: dict[int, object] = {}  # signal -> the handler it replaced
_unraisable_hook: list = []  # the sys.unraisablehook that install replaced


def _safe(frame) -> bool:
    """Whether raising in ``frame`` is safe (see the module docstring)."""
    name = frame.f_code.co_filename if frame is not None else ""
    return not any(part in name for part in _UNSAFE_PARTS)


def _retry_soon() -> None:
    """Try raising again in RETRY_S (a SIGALRM: no thread, no lock in a handler)."""
    if hasattr(signal, "setitimer") and signal.SIGALRM in _installed:
        signal.setitimer(signal.ITIMER_REAL, RETRY_S)


def _raise() -> None:
    """Raise ``Terminated`` for the pending signal (no retry left armed: at the
    interpreter's exit a SIGALRM would kill the process)."""
    if _RETRY_SIGNAL:
        signal.setitimer(signal.ITIMER_REAL, 0)
    _state.raised = True
    raise Terminated(_state.pending)


def _handler(signum: int, frame) -> None:
    if os.getpid() != _state.pid:
        return  # a forked worker before its initializer: the signal is its parent's
    if signum != getattr(signal, "SIGALRM", None) and _state.pending is None:
        _state.pending = signum
    if _state.pending is None or _state.raised or _state.deferred:
        return  # nothing to raise; already leaving; or deferred() raises when it ends
    if not _safe(frame):
        _retry_soon()
        return
    _raise()


def _unraisable(unraisable) -> None:
    """A ``Terminated`` that Python dropped is raised again (by the timer, or at the next
    ``checkpoint``), without the "Exception ignored" lines; anything else goes to the
    hook this one replaced."""
    if isinstance(unraisable.exc_value, Terminated):
        _state.raised = False
        _retry_soon()
        return
    (_unraisable_hook or [sys.__unraisablehook__])[0](unraisable)


def install(received: int | None = None) -> bool:
    """Handle the termination signals as described above (main thread only; a no-op
    elsewhere or when already installed). Returns whether this call installed them.

    ``received``: a signal that arrived before (the entry point records one while this
    module loads); ``Terminated`` is then raised at once."""
    if _installed or threading.current_thread() is not threading.main_thread():
        return False
    _state.reset()
    for sig in (*TERMINATION_SIGNALS, *_RETRY_SIGNAL):
        _installed[sig] = signal.signal(sig, _handler)
    _unraisable_hook[:] = [sys.unraisablehook]
    sys.unraisablehook = _unraisable
    if received is not None:
        _state.pending = received
        _state.raised = True
        raise Terminated(received)
    return True


def uninstall() -> None:
    """Restore the handlers that ``install`` replaced, and forget any pending signal."""
    if _RETRY_SIGNAL:
        signal.setitimer(signal.ITIMER_REAL, 0)
    for sig, old in _installed.items():
        signal.signal(sig, old)
    _installed.clear()
    if _unraisable_hook:
        sys.unraisablehook = _unraisable_hook.pop()
    _state.reset()


def finish() -> int | None:
    """At the end of the process: stop any retry, ignore the termination signals from
    now on (the interpreter's exit would put back their default action, and a signal in
    its last milliseconds would kill a command that is done), and return a signal
    received that was never raised (it came as the command ended), so that the exit code
    can say so."""
    if _installed:
        if _RETRY_SIGNAL:
            signal.setitimer(signal.ITIMER_REAL, 0)
        for sig in TERMINATION_SIGNALS:
            signal.signal(sig, signal.SIG_IGN)
    return _state.pending if not _state.raised else None


def pending() -> int | None:
    """The termination signal received (None if none)."""
    return _state.pending


def checkpoint() -> None:
    """Raise ``Terminated`` if a termination signal was received (main thread only): for
    the places where long work reports progress, and after code that catches broadly."""
    if _state.pending is not None and threading.current_thread() is threading.main_thread():
        _raise()


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Hold termination signals while the block runs; raise ``Terminated`` after it if one
    arrived (only when the block ends normally: an exception of its own goes first)."""
    main = threading.current_thread() is threading.main_thread()
    if main:
        _state.deferred += 1
    try:
        yield
    finally:
        if main:
            _state.deferred -= 1
    if main and not _state.deferred and _state.pending is not None and not _state.raised:
        _raise()


@contextlib.contextmanager
def termination_as_exception() -> Iterator[None]:
    """Handle the termination signals while the block runs (for a command run in-process,
    e.g. by typer's test runner); when ``install`` was already called, leave it alone."""
    mine = install()
    try:
        yield
    finally:
        if mine:
            uninstall()


def stop_message(signum: int) -> str:
    """What a command stopped by ``signum`` tells the user: whether its outputs were
    written (an output dir whose commit completed before the signal was handled)."""
    outputs = sys.modules.get("rubcli.io.outputs")
    committed = list(dict.fromkeys(str(p) for p in outputs.COMMITTED)) if outputs else []
    name = signal.Signals(signum).name
    if committed:
        return (f"terminated by {name}: stopped after the outputs of this run were written "
                f"to {', '.join(committed)}")  # fmt: skip
    return f"terminated by {name}: stopped; no outputs of this run were written"

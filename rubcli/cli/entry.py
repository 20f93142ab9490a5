"""The entry point of the ``rubcli`` script and ``python -m rubcli``.

Its first instruction makes the termination signals (SIGTERM, SIGINT, SIGHUP) end the
command cleanly: a signal is recorded until ``rubcli.io.signals`` handles it, before
numpy, typer and the commands (and even the ``signal`` module) are imported. A Ctrl-C at
any moment from then on, the start-up included, exits with 128 + N and one line on
stderr, never a traceback; so does a ``KeyboardInterrupt`` from Python's own handler (a
Ctrl-C just before). Importing this module changes no handler.
"""

from __future__ import annotations

import _signal  # the C module, loaded with the interpreter (``signal`` imports enum first)
import sys

_NAMES = ("SIGTERM", "SIGINT", "SIGHUP")


def main() -> None:
    """Run the ``rubcli`` command line (``rubcli.cli.app``)."""
    early: list[int] = []  # a signal before the real handler is in place: kept for it
    while True:
        try:
            for sig in (getattr(_signal, n) for n in _NAMES if hasattr(_signal, n)):
                _signal.signal(sig, lambda signum, frame: early.append(signum))
            break
        except KeyboardInterrupt:  # Python's handler was still in place: install them all
            early.append(_signal.SIGINT)

    from rubcli.io import signals

    try:
        code = _run(signals, early[0] if early else None)
    except (signals.Terminated, KeyboardInterrupt) as exc:  # in the moments after the end
        code = _stopped(signals, getattr(exc, "signum", _signal.SIGINT))
    sys.exit(code)


def _run(signals, early: int | None) -> int | str | None:
    """The command line's exit code (a signal's 128 + N with its message)."""
    try:
        signals.install(early)
        from rubcli.cli.app import app

        app()  # ends with SystemExit
    except SystemExit as exc:
        late = signals.finish()
        # a signal as the command ended, never raised: say so in the exit code
        return _stopped(signals, late) if late is not None else exc.code
    except BaseException as exc:
        if isinstance(exc, signals.Terminated):
            signum = exc.signum
        elif isinstance(exc, KeyboardInterrupt):  # Python's own handler, put back by a library
            signum = _signal.SIGINT
        else:
            signum = signals.pending()
        signals.finish()
        if signum is None:
            raise
        # a signal during the imports, or an error it caused (an import cut short)
        return _stopped(signals, signum)
    return 0


def _stopped(signals, signum: int) -> int:
    import contextlib

    signals.finish()
    with contextlib.suppress(OSError):
        sys.stderr.write(f"error: {signals.stop_message(signum)}\n")
    return 128 + signum

"""The entry point of the ``rubcli`` script and ``python -m rubcli``.

Its first line makes the termination signals (SIGTERM, SIGINT, SIGHUP) end the command
cleanly (``rubcli.io.signals``), before numpy, typer and the commands are imported: a
Ctrl-C at any moment, the start-up included, exits with 128 + N and one line on stderr,
never a traceback. Only the standard library is imported before that.
"""

from __future__ import annotations

import contextlib
import sys


def main() -> None:
    """Run the ``rubcli`` command line (``rubcli.cli.app``)."""
    import signal

    early: list[int] = []  # a signal before the real handler is in place: kept for it
    names = ("SIGTERM", "SIGINT", "SIGHUP")
    for sig in (getattr(signal, n) for n in names if hasattr(signal, n)):
        signal.signal(sig, lambda signum, frame: early.append(signum))

    from rubcli.io import signals

    try:
        code = _run(signals, early[0] if early else None)
    except signals.Terminated as exc:  # raised in the moments after the command's end
        code = _stopped(signals, exc.signum)
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
        signum = exc.signum if isinstance(exc, signals.Terminated) else signals.pending()
        signals.finish()
        if signum is None:
            raise
        # a signal during the imports, or an error it caused (an import cut short)
        return _stopped(signals, signum)
    return 0


def _stopped(signals, signum: int) -> int:
    signals.finish()
    with contextlib.suppress(OSError):
        sys.stderr.write(f"error: {signals.stop_message(signum)}\n")
    return 128 + signum

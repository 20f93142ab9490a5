"""The entry point of the ``rubcli`` script and ``python -m rubcli``.

Its first line makes the termination signals (SIGTERM, SIGINT, SIGHUP) end the command
cleanly (``rubcli.io.signals``), before numpy, typer and the commands are imported: a
Ctrl-C at any moment, the start-up included, exits with 128 + N and one line on stderr,
never a traceback. Only the standard library is imported before that.
"""

from __future__ import annotations

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
        signals.install(early[0] if early else None)
        from rubcli.cli.app import app

        app()
    except SystemExit:
        late = signals.finish()
        if late is not None:  # a signal as the command ended, never raised: say so
            sys.stderr.write(f"error: {signals.stop_message(late)}\n")
            sys.exit(128 + late)
        raise
    except BaseException as exc:
        signals.finish()
        signum = exc.signum if isinstance(exc, signals.Terminated) else signals.pending()
        if signum is None:
            raise
        # A signal during the imports, or an error it caused (an import cut short)
        sys.stderr.write(f"error: {signals.stop_message(signum)}\n")
        sys.exit(128 + signum)

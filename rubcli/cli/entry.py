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
    from rubcli.io import signals

    signals.install()
    try:
        from rubcli.cli.app import app

        app()
    except SystemExit:
        raise
    except BaseException as exc:
        signum = exc.signum if isinstance(exc, signals.Terminated) else signals.pending()
        if signum is None:
            raise
        # A signal during the imports, or an error it caused (an import cut short)
        sys.stderr.write(f"error: {signals.stop_message(signum)}\n")
        sys.exit(128 + signum)

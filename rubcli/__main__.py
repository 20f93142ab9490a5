"""``python -m rubcli``: the same as the ``rubcli`` command."""

from rubcli.cli.app import main

main()

"""``python -m rubcli``: the same as the ``rubcli`` command."""

from rubcli.cli.entry import main

main()

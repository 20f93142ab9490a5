"""The hostile suite: rubcli end to end under faults (see conftest.py)."""

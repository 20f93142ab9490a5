"""rubcli's version, recorded in every report and in the key of a resumable sweep store.

Its own module, below everything, so that the writers that record it do not import the
package's front (``rubcli/__init__.py``, which imports on first use from all of rubcli).
"""

__version__ = "0.1.0"

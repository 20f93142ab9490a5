"""A text column given as integer codes and the text of each code.

Below both its writer (``rubcli.io.tables``) and its compiled formatter
(``rubcli.csvtext``), so that neither imports the other for it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Labels:
    """A text column given as integer codes and the text of each code (a solution CSV's
    regime names): the compiled formatter writes it with no Python string per row."""

    codes: np.ndarray
    names: Mapping[int, str]

    def __len__(self) -> int:
        return len(self.codes)

    def tolist(self) -> list[str]:
        return [self.names[code] for code in np.asarray(self.codes).tolist()]

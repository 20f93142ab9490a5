"""The contact law of a station: the normal force of a penetration, in one module.

A law is the few numbers ``ContactLaw.record()`` packs (``LAW_SIZE`` of them), read by its
compilable cores from row ``s`` of a table, from column ``first`` on (the system keeps
each station's law in its parameters' row): ``normal_force`` (the force along the normal,
never pulling), ``elastic_force`` and ``stored_energy`` (the elastic part and its
potential, for the energy balance). The system
(``rubcli.system``) calls nothing else of a law, so a new law is a change here only.

The law: ``F_N = max(0, k delta^p + c z')`` while the station is in contact (``delta =
z - clearance > 0``), ``k`` the contact stiffness, ``p`` the Hertzian exponent (1: the
paper's linear spring), ``c`` the contact damping on the normal rate ``z'``. Its elastic
part stores ``k delta^(p + 1) / (p + 1)``; the damping dissipates ``(F_N - k delta^p) z'``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rubcli.model import MAX_MAGNITUDE, real_number

LAW_SIZE = 3  # stiffness, damping, exponent
MAX_EXPONENT = 10.0


@dataclass(frozen=True)
class ContactLaw:
    """A station's normal force: ``stiffness`` k > 0, ``damping`` c >= 0 (the force on the
    normal rate z'), ``exponent`` p in [1, MAX_EXPONENT]; ValueError or TypeError naming
    the field."""

    stiffness: float
    damping: float = 0.0
    exponent: float = 1.0

    def __post_init__(self) -> None:
        for name in ("stiffness", "damping", "exponent"):
            value = real_number("contact law", name, getattr(self, name))
            if not (math.isfinite(value) and abs(value) <= MAX_MAGNITUDE):
                raise ValueError(f"contact law: {name} must be finite (got {value!r})")
            object.__setattr__(self, name, value)
        if not self.stiffness > 0.0:
            raise ValueError(f"contact law: stiffness must be > 0 (got {self.stiffness!r})")
        if not self.damping >= 0.0:
            raise ValueError(f"contact law: damping must be >= 0 (got {self.damping!r})")
        if not 1.0 <= self.exponent <= MAX_EXPONENT:
            raise ValueError(
                f"contact law: exponent must be in [1, {MAX_EXPONENT:g}] (got {self.exponent!r})"
            )

    def record(self) -> np.ndarray:
        """The law as its compilable cores read it (``LAW_SIZE`` floats)."""
        return np.array([self.stiffness, self.damping, self.exponent])

    def text(self) -> str:
        """The law in a few words, for reports."""
        elastic = "k delta" if self.exponent == 1.0 else f"k delta^{self.exponent:g}"
        damped = f" + {self.damping:.6g} z'" if self.damping else ""
        return f"F_N = {elastic}{damped} (k = {self.stiffness:.6g})"


def elastic_force(table: np.ndarray, s: int, first: int, penetration: float) -> float:
    """The elastic part ``k delta^p`` at a penetration ``delta >= 0`` (compilable core)."""
    k, p = table[s, first], table[s, first + 2]
    if p == 1.0:
        return k * penetration
    return k * penetration**p


def normal_force(table: np.ndarray, s: int, first: int, penetration: float, rate: float) -> float:
    """``max(0, k delta^p + c z')`` (compilable core): the contact pushes, never pulls."""
    force = elastic_force(table, s, first, penetration) + table[s, first + 1] * rate
    return force if force > 0.0 else 0.0


def stored_energy(table: np.ndarray, s: int, first: int, penetration: float) -> float:
    """The elastic part's potential ``k delta^(p + 1) / (p + 1)`` (0 out of contact)."""
    if penetration <= 0.0:
        return 0.0
    k, p = table[s, first], table[s, first + 2]
    return k * penetration ** (p + 1.0) / (p + 1.0)

"""[forces_map]: the contact force and Taylor error maps of `rubcli forces-map`."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field, field_validator
from pydantic_core import PydanticCustomError

from rubcli.case.base import MAX_CASE_MEMORY_BYTES, PositiveFloat, _gib, _Section, _unique

ForcesMapProduct = Literal["forces", "taylor_error", "eigen"]

# Defaults of [forces_map] when a list is not given (notes 2.8 and section 6).
DEFAULT_FORCES_MAP_DELTAS: tuple[float, ...] = tuple(float(d) for d in np.logspace(-6, -1, 11))
DEFAULT_FORCES_MAP_K_VALUES: tuple[float, ...] = (17.6, 1.76e3, 1.76e5, 1.75e6)

# `forces-map` holds at its peak FORCES_MAP_BYTES_PER_POINT bytes per grid point beside the
# process's own FORCES_MAP_BASE_BYTES (measured for each product and for all three: at most
# 172 bytes per point and 380 MiB, benchmarks/forces_map_memory.md), kept with a 25 %
# margin. At run time it must also fit in the memory the process may take.
FORCES_MAP_BYTES_PER_POINT = 215
FORCES_MAP_BASE_BYTES = 512 * 1024**2


def forces_map_memory_bytes(resolution: int) -> int:
    """The peak memory of ``rubcli forces-map`` on a ``resolution`` x ``resolution`` grid."""
    return FORCES_MAP_BASE_BYTES + FORCES_MAP_BYTES_PER_POINT * resolution * resolution


def largest_forces_map_resolution(memory_bytes: float) -> int:
    """The largest grid side whose ``forces_map_memory_bytes`` fits in ``memory_bytes``."""
    points = (memory_bytes - FORCES_MAP_BASE_BYTES) / FORCES_MAP_BYTES_PER_POINT
    return math.isqrt(int(max(points, 0)))


class ForcesMapSection(_Section):
    """[forces_map]: settings of ``rubcli forces-map`` (contact force and Taylor error maps)."""

    extent: float = Field(default=1.5, gt=1)  # half-width of the square grid, clearances
    resolution: int = Field(default=201, ge=3)  # grid points per side (memory-bounded)
    products: list[ForcesMapProduct] = Field(
        default_factory=lambda: ["forces", "taylor_error", "eigen"], min_length=1
    )
    deltas: list[PositiveFloat] | None = Field(default=None, min_length=1)
    K_values: list[PositiveFloat] | None = Field(default=None, min_length=1)
    max_wall_time_s: float = Field(default=3600.0, gt=0)  # the run's budget, seconds

    _products_unique = field_validator("products")(_unique)

    @field_validator("resolution")
    @classmethod
    def _resolution_fits_in_memory(cls, value: int) -> int:
        need = forces_map_memory_bytes(value)
        if need > MAX_CASE_MEMORY_BYTES:
            largest = largest_forces_map_resolution(MAX_CASE_MEMORY_BYTES)
            raise PydanticCustomError(
                "too_much_memory",
                f"a {value} x {value} grid needs about {_gib(need)} of memory, more than the "
                f"{_gib(MAX_CASE_MEMORY_BYTES)} a case may ask for; at most {largest}",
            )
        return value

    def resolved_deltas(self) -> tuple[float, ...]:
        """``deltas`` or the default: 11 points logarithmically spaced over 1e-6 ... 1e-1."""
        return tuple(self.deltas) if self.deltas is not None else DEFAULT_FORCES_MAP_DELTAS

    def resolved_K_values(self) -> tuple[float, ...]:
        """``K_values`` or the default: 17.6, 1.76e3, 1.76e5, 1.75e6 (the paper's range)."""
        if self.K_values is not None:
            return tuple(self.K_values)
        return DEFAULT_FORCES_MAP_K_VALUES

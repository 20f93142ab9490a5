"""What every section of the case schema shares: the common base model, the field
validators, the error type and the memory budget a case may ask for."""

from __future__ import annotations

import math
from typing import Annotated, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field
from pydantic_core import PydanticCustomError

from rubcli import model
from rubcli.solvers import registry

MethodName = Literal[registry.NAMES]  # every method of the registry
KNOWN_METHODS: tuple[str, ...] = get_args(MethodName)

# Every size a case can set is bounded by a memory estimate, refused at validation: a run
# holds, per method and output sample, t, the state, the regime and the arrays of its
# report (energy balance, regimes): about RUN_BYTES_PER_SAMPLE bytes (measured: 580 bytes
# per sample for the paper's case over 1,000,001 samples, benchmarks/RESULTS.md).
MAX_CASE_MEMORY_BYTES = 8 * 1024**3
RUN_BYTES_PER_SAMPLE = 600
RUN_BASE_BYTES = 640 * 1024**2  # a small run's own address space (609 MiB measured)


def run_memory_bytes(n_samples: int, n_methods: int) -> int:
    """The peak memory of ``rubcli run`` keeping ``n_samples`` output samples per method."""
    return RUN_BASE_BYTES + RUN_BYTES_PER_SAMPLE * n_samples * n_methods


# the annotated field types the sections share
PositiveFloat = Annotated[float, Field(gt=0)]
# a vector [x, y] and a 2x2 matrix [[xx, xy], [yx, yy]] of a case file
Pair = Annotated[list[float], Field(min_length=2, max_length=2)]
Matrix = Annotated[list[Pair], Field(min_length=2, max_length=2)]
Rtol = Annotated[float, Field(gt=0, lt=1)]
PositiveInt = Annotated[int, Field(gt=0)]
NonNegativeFloat = Annotated[float, Field(ge=0)]


def _gib(n_bytes: float) -> str:
    return f"{n_bytes / 1024**3:.3g} GiB"


class CaseError(Exception):
    """An invalid case: ``problems`` has one line per problem, each naming file and field."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


class _Section(BaseModel):
    """Common configuration: unknown keys are errors, no NaN or infinity, no coercion.

    ``strict`` keeps TOML's own types: a string is never read as a number, a float never
    as an integer (an integer is still accepted where a float is expected).
    """

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)


def _unique(values: list) -> list:
    """Field validator: a list without repeated entries."""
    seen = set()
    for value in values:
        if value in seen:
            raise PydanticCustomError("duplicate", "'{value}' is listed twice", {"value": value})
        seen.add(value)
    return values


def _state_problem(value: float) -> str | None:
    """Why a start-state value lies outside the model's domain, or None."""
    if not math.isfinite(value):
        return "must be finite"
    if abs(value) > model.MAX_MAGNITUDE:
        return (
            f"must be at most {model.MAX_MAGNITUDE:g} in size (the model's domain, docs/cases.md)"
        )
    return None

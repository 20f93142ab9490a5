"""[compare] and [analysis]: `rubcli compare` and the response analysis (docs/compare.md).

Defaults of the ladders live in rubcli.analysis.accuracy.work_precision; None means "use that
default".
"""

from __future__ import annotations

from pydantic import Field, field_validator

from rubcli.case.base import MethodName, NonNegativeFloat, PositiveInt, Rtol, _Section, _unique


class CompareSection(_Section):
    """[compare]: `rubcli compare` (work-precision ladders, reference, mu sweep)."""

    methods: list[MethodName] | None = Field(default=None, min_length=1)  # default [solver]
    rtols: list[Rtol] | None = Field(default=None, min_length=1)  # default 1e-3 ... 1e-11
    atol_factor: float = Field(default=1e-2, gt=0)  # atol = rtol * atol_factor
    steps_per_period: list[PositiveInt] | None = Field(default=None, min_length=1)
    repeats: int = Field(default=3, ge=1)  # timing: median of this many runs
    horizon_periods: float | None = Field(default=None, gt=0)  # default [time] periods
    reference_threshold: float = Field(default=1e-6, gt=0)  # predictability horizon
    max_wall_time_s: float = Field(default=120.0, gt=0)  # per solve; tighter settings skipped
    total_wall_time_s: float | None = Field(default=None, gt=0)  # the run's budget (None: none)
    work_precision: bool = True  # run the ladders (false: sweep/orbits only)
    mu: list[NonNegativeFloat] | None = Field(default=None, min_length=1, max_length=12)

    _methods_unique = field_validator("methods")(_unique)
    _mu_unique = field_validator("mu")(_unique)


class AnalysisSection(_Section):
    """[analysis]: response classification in `run` and `compare` (Poincare, Lyapunov)."""

    response: bool = False
    transient_periods: float | None = Field(default=None, ge=0)  # default: half the run
    lyapunov: bool = True  # back a non-periodic class with the largest exponent
    lyapunov_periods: int = Field(default=100, gt=0)
    rel_tol: float = Field(default=1e-4, gt=0, lt=1)  # periodicity tolerance / orbit size
    max_period: int = Field(default=16, ge=1)

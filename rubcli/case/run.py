"""The tables of a run: [case], [initial], [time], [solver] and [output]."""

from __future__ import annotations

from typing import Annotated, Any, Literal, get_args

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from rubcli.case.base import MethodName, _Section, _unique
from rubcli.problem import MAX_OUTPUT_SAMPLES
from rubcli.solvers import registry

CASE_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]*$"

PlotName = Literal["orbit", "time", "energy", "spectrum"]
KNOWN_PLOTS: tuple[str, ...] = get_args(PlotName)
DEFAULT_PLOTS: tuple[str, ...] = ("orbit", "time")  # "energy" only when asked


# ============================================================================ [case]


class CaseSection(_Section):
    """[case]: the name (used for the default output dir) and an optional description."""

    name: str = Field(pattern=CASE_NAME_PATTERN, max_length=100)
    description: str = ""


# ========================================================================= [initial]


class InitialSection(_Section):
    """[initial]: state at tau = 0 (clearances and d/dtau; metres and m/s with [physical])."""

    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    # a stator with its own mass: its displacement from its rest position and velocity
    # [u, v, u', v'] (default: at rest there)
    stator: Annotated[list[float], Field(min_length=4, max_length=4)] | None = None


# ============================================================================ [time]


class TimeSection(_Section):
    """[time]: duration in forcing periods 2 pi / eta and the output sampling. With
    [speed]: ``end`` (tau, or seconds with [physical]; default the profile's end) and
    samples per revolution at the profile's highest speed."""

    periods: float | None = Field(default=None, gt=0)
    samples_per_period: int = Field(gt=0)
    end: float | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _not_too_many_samples(self) -> TimeSection:
        if self.periods is None:  # a [speed] run: checked once its span is known
            return self
        n = self.periods * self.samples_per_period
        if n > MAX_OUTPUT_SAMPLES:
            # pydantic fills {name} templates without format specs: format here
            raise PydanticCustomError(
                "too_many_samples",
                f"periods * samples_per_period = {n:.3g} output samples, more than "
                f"{MAX_OUTPUT_SAMPLES:,}",
            )
        return self


# ========================================================================== [solver]


class SolverSection(_Section):
    """[solver]: which methods run and their settings (each method takes the ones it uses)."""

    methods: list[MethodName] = Field(default_factory=lambda: ["analytic", "rk45"], min_length=1)
    rtol: float = Field(default=1e-8, ge=registry.MIN_RTOL, lt=1)  # scipy methods
    atol: float = Field(default=1e-10, ge=registry.MIN_ATOL)  # scipy methods
    steps_per_period: int = Field(default=400, gt=0)  # analytic: step = period / this
    # analytic methods: adaptive steps (step doubling) with this local error tolerance;
    # steps_per_period then sets the first step
    analytic_tol: float | None = Field(default=None, gt=0, lt=1)
    max_steps: int = Field(default=5_000_000, gt=0)
    max_wall_time_s: float = Field(default=600.0, gt=0)
    # the whole of `rubcli run`, every method's solve with it (None: none)
    total_wall_time_s: float | None = Field(default=None, gt=0)

    _methods_unique = field_validator("methods")(_unique)

    def options(self) -> dict[str, Any]:
        """The settings as keyword options (``Case.options_for`` picks one method's)."""
        return self.model_dump(exclude={"methods", "total_wall_time_s"})


# ========================================================================== [output]


class OutputSection(_Section):
    """[output]: where and what to write. Only what is asked is computed and written."""

    dir: str | None = Field(default=None, min_length=1)  # default out/<case name>
    csv: bool = True
    plots: list[PlotName] = Field(default_factory=lambda: list(DEFAULT_PLOTS))

    _plots_unique = field_validator("plots")(_unique)

    @field_validator("dir")
    @classmethod
    def _no_nul(cls, value: str | None) -> str | None:
        if value is not None and "\0" in value:
            raise PydanticCustomError(
                "nul_byte", "holds a NUL byte (\\0), which no file name may hold"
            )
        return value

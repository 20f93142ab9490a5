"""Problem: parameters, initial state and time grid. Pure data, no solver choices."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rubcli.drive import Drive
from rubcli.model import MAX_MAGNITUDE, FloatOrArray, ModelParams, real_number
from rubcli.speed import SpeedProfile

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

# The shortest time scale of the model, a contact oscillation (period 2 pi / sqrt(1 + K)),
# must span at least this many doubles of tau anywhere in the span: a step of a twentieth
# of it then still spans 500 doubles, so that rounding tau costs less than 0.2 % of a
# step. Beyond, no method can resolve contact (docs/cases.md, "The model's domain").
RESOLUTION_ULPS = 1e4
# A run keeps every output sample in memory (8 floats of state per sample and method,
# plus the CSV columns); beyond this many samples a problem (or a case) is refused as a
# likely typo.
MAX_OUTPUT_SAMPLES = 10_000_000


@dataclass(frozen=True)
class Problem:
    """One initial-value problem of the rubbing rotor, nondimensional.

    ``t_eval`` holds the sample times at which every solver reports the state; the
    span is ``(t_eval[0], t_eval[-1])``.
    """

    params: ModelParams
    initial: tuple[float, float, float, float]  # (x, y, vx, vy) at t_eval[0]
    t_eval: np.ndarray = field(repr=False)
    name: str = "problem"
    # a speed that changes in time (None: the constant params.eta)
    speed: SpeedProfile | None = None
    # a driven rotor: the speed is a state, its start params.eta (rubcli.drive)
    drive: Drive | None = None
    # a stator with its own mass (params.stator): its (u, v, u', v') at t_eval[0], from
    # its rest position (default: at rest there)
    stator_initial: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not isinstance(self.params, ModelParams):
            raise TypeError(f"Problem: params must be a ModelParams, got {_kind(self.params)}")
        object.__setattr__(self, "initial", _initial_state(self.initial))
        stator = _initial_state(self.stator_initial, "stator_initial")
        object.__setattr__(self, "stator_initial", stator)
        object.__setattr__(self, "t_eval", _time_grid(self.t_eval))
        if not isinstance(self.name, str):
            raise TypeError(f"Problem: name must be a str, got {_kind(self.name)}")
        if self.speed is not None and not isinstance(self.speed, SpeedProfile):
            raise TypeError(f"Problem: speed must be a SpeedProfile, got {_kind(self.speed)}")
        if self.drive is not None:
            if not isinstance(self.drive, Drive):
                raise TypeError(f"Problem: drive must be a Drive, got {_kind(self.drive)}")
            if self.speed is not None:
                raise ValueError("Problem: a driven rotor has no prescribed speed profile")
            if self.params.eta != self.drive.start:
                raise ValueError(
                    f"Problem: params.eta = {self.params.eta!r} must be the drive's start "
                    f"speed {self.drive.start!r}"
                )
            self.drive.check(self.params.e)
        problem = resolution_problem(self.params, self.t_eval)
        if problem:
            raise ValueError(f"Problem: params.K = {self.params.K!r}: {problem}")

    @classmethod
    def from_periods(
        cls,
        params: ModelParams,
        initial: Iterable[float],
        periods: float,
        samples_per_period: int = 100,
        name: str = "problem",
    ) -> Problem:
        """Sample ``periods`` forcing periods from tau = 0 at ``samples_per_period``: at
        most ``MAX_OUTPUT_SAMPLES`` samples, as in a case file."""
        if not isinstance(params, ModelParams):
            raise TypeError(f"Problem: params must be a ModelParams, got {_kind(params)}")
        periods = real_number("Problem.from_periods", "periods", periods)
        if not (math.isfinite(periods) and periods > 0.0):
            raise ValueError(
                f"Problem.from_periods: periods must be finite and > 0 (got {periods!r})"
            )
        if isinstance(samples_per_period, bool) or not isinstance(
            samples_per_period, numbers.Integral
        ):
            raise TypeError(
                "Problem.from_periods: samples_per_period must be an int, got "
                f"{_kind(samples_per_period)}"
            )
        if samples_per_period <= 0:
            raise ValueError(
                f"Problem.from_periods: samples_per_period must be > 0 (got {samples_per_period})"
            )

        # bounded as a case file's [time] table (compared so that no int overflows a float)
        if samples_per_period > MAX_OUTPUT_SAMPLES / periods:
            raise ValueError(
                f"Problem.from_periods: periods * samples_per_period is more than "
                f"{MAX_OUTPUT_SAMPLES:,} samples (periods = {periods:.6g}, samples_per_period "
                f"= {samples_per_period!r})"
            )
        t_end = periods * params.period
        if not t_end <= MAX_MAGNITUDE:
            raise ValueError(
                f"Problem.from_periods: {periods!r} periods end at tau = {t_end!r}, beyond "
                f"{MAX_MAGNITUDE:g} (the model's domain, docs/cases.md)"
            )
        n = max(2, int(round(periods * samples_per_period)) + 1)
        t_eval = np.linspace(0.0, t_end, n)
        return cls(params=params, initial=initial, t_eval=t_eval, name=name)

    @property
    def changes_speed(self) -> bool:
        """Whether the speed changes in time: a profile or a driven rotor."""
        return self.speed is not None or self.drive is not None

    def speed_text(self) -> str | None:
        """The profile or the drive in a few words (None at a constant speed)."""
        if self.drive is not None:
            return self.drive.text()
        return self.speed.text() if self.speed is not None else None

    @property
    def t_span(self) -> tuple[float, float]:
        return float(self.t_eval[0]), float(self.t_eval[-1])

    def speed_at(self, tau: FloatOrArray) -> FloatOrArray:
        """The speed ratio at tau (params.eta when the speed is constant; a driven
        rotor's speed is known from its solution only, ``Solution.speed``)."""
        if self.drive is not None:
            raise ValueError("Problem.speed_at: a driven rotor's speed is a state of its run")
        if self.speed is None:
            return self.params.eta if np.ndim(tau) == 0 else np.full(np.shape(tau), self.params.eta)
        return self.speed.speed(tau)

    def legs(self) -> list[tuple[float, ModelParams]]:
        """``(start, params)`` of each leg of constant eta' over the span (one leg, from
        its start, at constant speed; ``SpeedProfile.legs``)."""
        t0, t1 = self.t_span
        if self.speed is None:
            return [(t0, self.params)]
        return self.speed.legs(self.params, t0, t1)

    @property
    def periods(self) -> float:
        """The span in forcing periods (with a speed that changes: revolutions of the
        unbalance; a driven rotor's counted at its start speed)."""
        t0, t1 = self.t_span
        if self.speed is not None:
            return (self.speed.phase(t1, 0.0) - self.speed.phase(t0, 0.0)) / (2.0 * math.pi)
        return (t1 - t0) / self.params.period


def _kind(value) -> str:
    return type(value).__name__


def _initial_state(initial, field: str = "initial") -> tuple[float, float, float, float]:
    """``initial`` (the field ``field``) checked: 4 finite real numbers of at most
    MAX_MAGNITUDE in size."""
    names = ("x", "y", "vx", "vy") if field == "initial" else ("u", "v", "u'", "v'")
    return state_values("Problem", field, initial, names)


def state_values(owner: str, field: str, value: object, names: Sequence[str]) -> tuple[float, ...]:
    """``value`` (the argument ``field`` of ``owner``) checked as a state: one finite real
    number of at most MAX_MAGNITUDE in size for each of ``names``; a TypeError or
    ValueError naming ``owner: field``."""
    order = ", ".join(names)
    try:
        if isinstance(value, str | bytes | dict):
            raise TypeError
        values = list(value)
    except TypeError:
        raise TypeError(
            f"{owner}: {field} must be a sequence of {len(names)} numbers ({order}), got "
            f"{_kind(value)}"
        ) from None
    if len(values) != len(names):
        raise ValueError(
            f"{owner}: {field} must hold {len(names)} numbers ({order}), got {len(values)}"
        )
    out = []
    for name, entry in zip(names, values, strict=True):
        v = real_number(owner, f"{field} {name}", entry)
        if not math.isfinite(v):
            raise ValueError(f"{owner}: {field} {name} must be finite (got {v!r})")
        if abs(v) > MAX_MAGNITUDE:
            raise ValueError(
                f"{owner}: {field} {name} must be at most {MAX_MAGNITUDE:g} in size (got {v!r}): "
                "the model's domain (docs/cases.md)"
            )
        out.append(v)
    return tuple(out)


def _time_grid(t_eval) -> np.ndarray:
    """``t_eval`` checked: a 1-D array of at least 2 finite, strictly increasing times."""
    try:
        if t_eval is None or isinstance(t_eval, str | bytes):
            raise TypeError
        t = np.asarray(t_eval, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"Problem: t_eval must be an array of times, got {_kind(t_eval)}") from None
    if t.ndim != 1 or t.size < 2:
        raise ValueError(
            f"Problem: t_eval must be a 1-D array of at least 2 times (got shape {t.shape})"
        )
    if not np.all(np.isfinite(t)):
        raise ValueError("Problem: t_eval must be finite (it holds nan or inf)")
    if not np.all(np.diff(t) > 0):
        i = int(np.argmin(np.diff(t) > 0))
        raise ValueError(
            f"Problem: t_eval must be strictly increasing (t_eval[{i + 1}] = "
            f"{float(t[i + 1])!r} after t_eval[{i}] = {float(t[i])!r})"
        )
    if np.max(np.abs(t[[0, -1]])) > MAX_MAGNITUDE:
        raise ValueError(f"Problem: t_eval must stay within +-{MAX_MAGNITUDE:g}")
    return t


def resolution_problem(params: ModelParams, t_eval: Sequence[float] | np.ndarray) -> str | None:
    """Why the span ``t_eval`` cannot resolve the contact oscillation of ``params``
    (``RESOLUTION_ULPS``), or None."""
    shortest = 2.0 * math.pi / math.sqrt(1.0 + params.K)
    far = max(1.0, abs(float(t_eval[0])), abs(float(t_eval[-1])))
    spacing = math.ulp(far)
    if shortest >= RESOLUTION_ULPS * spacing:
        return None
    return (
        f"a contact oscillation (period 2 pi / sqrt(1 + K) = {shortest:.3g}) is shorter "
        f"than {RESOLUTION_ULPS:g} doubles of tau at tau = {far:.6g} (spacing "
        f"{spacing:.3g}): no method can resolve it over this span (the model's domain, "
        "docs/cases.md)"
    )

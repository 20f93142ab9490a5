"""The machine's tables: [model] (nondimensional) or [physical] (SI units), and [stator]."""

from __future__ import annotations

import math
from typing import Any

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from rubcli import model
from rubcli.case.base import Matrix, Pair, _Section
from rubcli.model import ModelParams
from rubcli.stator import Stator


def _general_problem(name: str, value: Pair | Matrix | None) -> None:
    """A general machine's vector or matrix outside the model's domain (too large; a
    support matrix without a rest position or that feeds energy in): PydanticCustomError."""
    if value is None:
        return
    entries = [v for row in value for v in row] if name in ("stiffness", "damping") else value
    for v in entries:
        if abs(v) > model.MAX_MAGNITUDE:
            raise PydanticCustomError(
                "model_domain",
                f"entries must be at most {model.MAX_MAGNITUDE:g} in size (the model's domain, "
                "docs/cases.md)",
            )
    if name in ("stiffness", "damping"):
        why = model.support_problem(name, value)
        if why:
            raise PydanticCustomError("support_matrix", why)


class ModelSection(_Section):
    """[model]: nondimensional parameters (notes section 1), and the general machine's
    (docs/machines.md): all in the model's units (clearances, k_r clearance)."""

    nu: float | None = Field(default=None, ge=0)  # damping ratio d_r / (2 omega m)
    eta: float | None = Field(default=None, gt=0)  # speed ratio Omega / omega (or [speed])
    e: float = Field(ge=0)  # unbalance eccentricity / clearance
    K: float = Field(gt=0)  # stator / rotor stiffness ratio
    mu: float = Field(default=0.0, ge=0)  # Coulomb friction coefficient
    Rp: float = Field(default=0.0, ge=0)  # rotor radius / clearance
    phi0: float = 0.0  # unbalance phase, rad
    offset: Pair | None = None  # the stator's centre from the support's, clearances
    load: Pair | None = None  # a static force on the rotor, units of k_r clearance
    stiffness: Matrix | None = None  # the support stiffness matrix over k_r
    damping: Matrix | None = None  # the support damping matrix (forces 2 D w'), or nu

    @field_validator("nu", "eta", "e", "K", "mu", "Rp", "phi0")
    @classmethod
    def _in_the_models_domain(cls, value: float | None, info) -> float | None:
        """The model's domain (``model.parameter_problem``), the rule a [physical] table's
        converted values are checked against too."""
        if value is None:  # eta given by [speed]; nu by damping
            return value
        problem = model.parameter_problem(info.field_name, value)
        if problem:
            raise PydanticCustomError("model_domain", problem)
        return value

    @field_validator("offset", "load", "stiffness", "damping")
    @classmethod
    def _general_in_domain(cls, value, info):
        _general_problem(info.field_name, value)
        return value

    @model_validator(mode="after")
    def _damping_once(self) -> ModelSection:
        if self.nu is not None and self.damping is not None:
            raise PydanticCustomError(
                "damping_twice",
                "damping: the support damping is given twice, as nu and as damping; give one "
                "(damping = [[nu, 0], [0, nu]] is the isotropic nu)",
            )
        if self.nu is None and self.damping is None:
            raise PydanticCustomError("damping_missing", "nu: missing (or give damping)")
        return self

    def params(self) -> ModelParams:
        return ModelParams(**machine_values(self.model_dump()))


def machine_values(values: dict[str, Any]) -> dict[str, Any]:
    """A [model] table's (or [physical]'s converted) values as ``ModelParams`` takes them:
    the general machine's entries left out where not given, nu 0 with a damping matrix."""
    out = {k: v for k, v in values.items() if v is not None or k == "eta"}
    if out.get("damping") is not None:
        out["nu"] = 0.0
    return out


class PhysicalSection(_Section):
    """[physical]: the same machine in SI units, converted once by ``rubcli.units``."""

    m: float = Field(gt=0)  # rotor mass, kg
    k_r: float = Field(gt=0)  # rotor (shaft) stiffness, N/m
    d_r: float | None = Field(default=None, ge=0)  # rotor damping, N s/m (or damping)
    k_s: float = Field(gt=0)  # stator stiffness, N/m
    clearance: float = Field(gt=0)  # radial clearance, m
    e: float = Field(ge=0)  # unbalance eccentricity, m
    Omega: float | None = Field(default=None, gt=0)  # spin speed, rad/s (or [speed])
    Rp: float = Field(default=0.0, ge=0)  # rotor radius at the rub, m
    mu: float = Field(default=0.0, ge=0)  # Coulomb friction coefficient
    phi0: float = 0.0  # unbalance phase, rad
    offset: Pair | None = None  # the stator's centre from the support's, m
    load: Pair | None = None  # a static force on the rotor, N
    stiffness: Matrix | None = None  # the support stiffness matrix, N/m (k_r the reference)
    damping: Matrix | None = None  # the support damping matrix, N s/m (instead of d_r)

    @field_validator("stiffness", "damping")
    @classmethod
    def _support(cls, value, info):
        _general_problem(info.field_name, value)
        return value

    @model_validator(mode="after")
    def _damping_once(self) -> PhysicalSection:
        if self.d_r is not None and self.damping is not None:
            raise PydanticCustomError(
                "damping_twice",
                "damping: the support damping is given twice, as d_r and as damping; give one",
            )
        if self.d_r is None and self.damping is None:
            raise PydanticCustomError("damping_missing", "d_r: missing (or give damping)")
        return self


# ========================================================================== [stator]


class StatorSection(_Section):
    """[stator]: a stator (snubber ring) with its own mass on its own supports
    (``rubcli.stator``); no [stator] is the rigid stator. With [model]: the mass ratio
    M_s / m, the stiffness ratios k_s / k_r, the damping n_s (forces 2 n_s s'). With
    [physical]: kg, N/m and N s/m, converted once."""

    mass: float = Field(gt=0)
    stiffness: Pair
    damping: Pair = Field(default_factory=lambda: [0.0, 0.0])

    @field_validator("stiffness")
    @classmethod
    def _positive(cls, value: list[float]) -> list[float]:
        if not all(v > 0.0 for v in value):
            raise PydanticCustomError(
                "stator_stiffness",
                "both entries must be > 0 (a stator without support has no rest position)",
            )
        return value

    @field_validator("damping")
    @classmethod
    def _not_negative(cls, value: list[float]) -> list[float]:
        if not all(v >= 0.0 for v in value):
            raise PydanticCustomError("stator_damping", "both entries must be >= 0")
        return value

    def stator(self, physical: PhysicalSection | None) -> Stator:
        """The nondimensional stator (converted from SI with [physical]: over m, k_r and
        2 sqrt(k_r m), as the rotor's own)."""
        if physical is None:
            return Stator(self.mass, tuple(self.stiffness), tuple(self.damping))
        m, k_r = physical.m, physical.k_r
        unit = 2.0 * math.sqrt(k_r * m)
        return Stator(
            self.mass / m,
            (self.stiffness[0] / k_r, self.stiffness[1] / k_r),
            (self.damping[0] / unit, self.damping[1] / unit),
        )

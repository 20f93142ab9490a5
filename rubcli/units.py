"""Conversion between SI quantities and the nondimensional model (model notes, section 1).

    omega = sqrt(k_r / m)        tau = omega t           nu = d_r / (2 omega m)
    eta = Omega / omega          K = k_s / k_r           x^ = x / clearance
    e^ = e / clearance           Rp^ = Rp / clearance    v^ = v / (omega clearance)

Forces: the nondimensional contact force ``-K f`` is in units of ``k_r * clearance``, so
the normal force ``K (z - 1)`` becomes ``k_s (r - clearance)`` in newtons (notes 1).

Pure functions on floats and numpy arrays; a case file is converted here once, and every
physical output column is converted back here.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

from rubcli.model import ModelParams

if TYPE_CHECKING:
    from rubcli.model import FloatOrArray


@dataclass(frozen=True)
class PhysicalScale:
    """The SI scales of one machine: natural frequency, clearance and the two stiffnesses."""

    omega: float  # rotor natural frequency sqrt(k_r / m), rad/s
    clearance: float  # radial clearance gamma, m
    k_r: float  # rotor stiffness, N/m
    k_s: float  # stator stiffness, N/m

    @property
    def force(self) -> float:
        """The force unit k_r * clearance, in newtons."""
        return self.k_r * self.clearance

    @property
    def velocity(self) -> float:
        """The velocity unit omega * clearance, in m/s."""
        return self.omega * self.clearance

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def physical_scale(m: float, k_r: float, k_s: float, clearance: float) -> PhysicalScale:
    """The scale of a machine of mass ``m`` (kg), stiffnesses in N/m, clearance in m."""
    return PhysicalScale(omega=math.sqrt(k_r / m), clearance=clearance, k_r=k_r, k_s=k_s)


def nondimensional_values(
    *,
    m: float,
    k_r: float,
    d_r: float | None,
    k_s: float,
    clearance: float,
    e: float,
    Omega: float | None,
    Rp: float = 0.0,
    mu: float = 0.0,
    phi0: float = 0.0,
    offset: tuple[float, float] | None = None,
    load: tuple[float, float] | None = None,
    stiffness: tuple[tuple[float, float], tuple[float, float]] | None = None,
    damping: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> tuple[dict, PhysicalScale]:
    """The nondimensional parameters (by name, not yet checked against the model's domain:
    SI values valid one by one can convert to an overflow or an underflow to 0) and the
    scale, from SI values (notes section 1; docs/machines.md for the general machine).

    ``d_r`` in N s/m, ``e`` and ``Rp`` in m, ``Omega`` in rad/s, ``phi0`` in rad; the
    general machine's ``offset`` in m, ``load`` in N, ``stiffness`` in N/m (over k_r, the
    reference) and ``damping`` in N s/m (over 2 omega m, as d_r; None: d_r).
    """
    scale = physical_scale(m, k_r, k_s, clearance)
    damping_unit = 2.0 * scale.omega * m
    values = {
        "nu": d_r / damping_unit if d_r is not None else None,
        "eta": Omega / scale.omega if Omega is not None else None,
        "e": e / clearance,
        "K": k_s / k_r,
        "mu": mu,
        "Rp": Rp / clearance,
        "phi0": phi0,
        "offset": _scaled(offset, clearance),
        "load": _scaled(load, scale.force),
        "stiffness": _scaled(stiffness, k_r),
        "damping": _scaled(damping, damping_unit),
    }
    return values, scale


def _scaled(value, unit: float):
    """A vector or a 2x2 matrix (nested sequences) over ``unit``; None stays None."""
    if value is None:
        return None
    if isinstance(value[0], float | int):
        return tuple(v / unit for v in value)
    return tuple(tuple(v / unit for v in row) for row in value)


RAD_PER_S = {"rpm": 2.0 * math.pi / 60.0, "rad/s": 1.0}


def speed_unit(unit: str) -> float:
    """rad/s per ``unit`` of speed ("rpm" or "rad/s")."""
    return RAD_PER_S[unit]


def rpm(eta: FloatOrArray, scale: PhysicalScale) -> FloatOrArray:
    """A speed ratio as a spin speed in rpm."""
    return eta * scale.omega * 60.0 / (2.0 * math.pi)


def nondimensional_params(**si: float) -> tuple[ModelParams, PhysicalScale]:
    """``nondimensional_values`` as ``ModelParams`` (ValueError naming a parameter that
    converts outside the model's domain)."""
    values, scale = nondimensional_values(**si)
    general = {k: v for k, v in values.items() if v is not None or k == "eta"}
    if general.get("damping") is not None:
        general["nu"] = 0.0
    return ModelParams(**general), scale


def nondimensional_state(
    x: float, y: float, vx: float, vy: float, scale: PhysicalScale
) -> tuple[float, float, float, float]:
    """A state in metres and m/s as a nondimensional state (x^, y^, x^', y^')."""
    return (
        x / scale.clearance,
        y / scale.clearance,
        vx / scale.velocity,
        vy / scale.velocity,
    )


def seconds(tau: FloatOrArray, scale: PhysicalScale) -> FloatOrArray:
    """Nondimensional time tau as seconds, t = tau / omega."""
    return tau / scale.omega


def metres(position: FloatOrArray, scale: PhysicalScale) -> FloatOrArray:
    """Positions in clearances as metres."""
    return position * scale.clearance


def metres_per_second(velocity: FloatOrArray, scale: PhysicalScale) -> FloatOrArray:
    """Nondimensional velocities d(x^)/dtau as m/s."""
    return velocity * scale.velocity


def newtons(force: FloatOrArray, scale: PhysicalScale) -> FloatOrArray:
    """Nondimensional forces (units of k_r * clearance) as newtons."""
    return force * scale.force

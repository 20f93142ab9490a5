"""[speed]: a speed that changes in time, by a profile or a driven rotor."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

from rubcli import units
from rubcli.case.base import _Section
from rubcli.drive import Drive
from rubcli.speed import SpeedProfile

SpeedProfileName = Literal["ramp", "table", "driven"]
SpeedUnit = Literal["rpm", "rad/s"]


class SpeedSection(_Section):
    """[speed]: a speed that changes in time (docs/runup.md). With [model]: speeds as eta,
    ``rate`` in d eta / d tau, ``tau`` in tau. With [physical]: speeds in ``unit`` (rpm
    unless given), ``rate`` in that unit per second, ``t`` in seconds."""

    model_config = ConfigDict(populate_by_name=True)

    profile: SpeedProfileName
    start: float | None = Field(default=None, alias="from", gt=0)  # ramp; driven: at tau 0
    to: float | None = Field(default=None, gt=0)  # ramp
    rate: float | None = None  # ramp: signed, its sign that of to - from
    tau: list[float] | None = Field(default=None, min_length=2)  # table, [model]
    eta: list[float] | None = Field(default=None, min_length=2)  # table, [model]
    t: list[float] | None = Field(default=None, min_length=2)  # table, [physical]: s
    speed: list[float] | None = Field(default=None, min_length=2)  # table, [physical]
    unit: SpeedUnit | None = None  # [physical] only
    # driven: the polar moment about the geometric centre (j, or kg m^2 with [physical]),
    # the motor (linear: stall torque and no-load speed; or a table of speed and torque;
    # torques nondimensional, or N m) and the bearing drag (torque per speed; N m s)
    inertia: float | None = Field(default=None, gt=0)
    stall_torque: float | None = Field(default=None, gt=0)
    no_load_speed: float | None = Field(default=None, gt=0)
    motor_speed: list[Annotated[float, Field(ge=0)]] | None = Field(default=None, min_length=2)
    motor_torque: list[float] | None = Field(default=None, min_length=2)
    drag: float = Field(default=0.0, ge=0)
    # speeds (as the profile's) at which orbits.png draws a revolution (default: picked)
    snapshots: list[Annotated[float, Field(gt=0)]] | None = Field(default=None, min_length=1)

    @model_validator(mode="after")
    def _complete(self) -> SpeedSection:
        ramp = {"from": self.start, "to": self.to, "rate": self.rate}
        table = {"tau": self.tau, "eta": self.eta, "t": self.t, "speed": self.speed}
        drive = {"inertia": self.inertia, "stall_torque": self.stall_torque,
                 "no_load_speed": self.no_load_speed, "motor_speed": self.motor_speed,
                 "motor_torque": self.motor_torque}  # fmt: skip
        if self.drag and self.profile != "driven":
            drive["drag"] = self.drag
        if self.profile == "driven":
            return self._complete_driven(ramp, table, drive)
        mine, other = (ramp, table) if self.profile == "ramp" else (table, ramp)
        extra = [k for k, v in {**other, **drive}.items() if v is not None]
        if extra:
            raise PydanticCustomError(
                "speed_keys",
                f"{', '.join(extra)} do not belong to profile = '{self.profile}'",
            )
        if self.profile == "ramp":
            missing = [k for k, v in mine.items() if v is None]
            if missing:
                raise PydanticCustomError(
                    "speed_keys", f"profile = 'ramp' needs {', '.join(missing)}"
                )
        else:
            pairs = [(a, b) for a, b in (("tau", "eta"), ("t", "speed"))
                     if table[a] is not None or table[b] is not None]  # fmt: skip
            if len(pairs) != 1 or table[pairs[0][0]] is None or table[pairs[0][1]] is None:
                raise PydanticCustomError(
                    "speed_keys",
                    "profile = 'table' needs tau and eta (with [model]) or t and speed "
                    "(with [physical])",
                )
        return self

    def _complete_driven(self, ramp: dict, table: dict, drive: dict) -> SpeedSection:
        extra = [k for k, v in {**ramp, **table}.items() if v is not None and k != "from"]
        if extra:
            raise PydanticCustomError(
                "speed_keys", f"{', '.join(extra)} do not belong to profile = 'driven'"
            )
        missing = [k for k in ("start", "inertia") if getattr(self, k) is None]
        linear = self.stall_torque is not None or self.no_load_speed is not None
        tabled = self.motor_speed is not None or self.motor_torque is not None
        if linear and tabled:
            raise PydanticCustomError(
                "speed_keys",
                "profile = 'driven': give the motor as stall_torque and no_load_speed or as "
                "motor_speed and motor_torque, not both",
            )
        pair = ("stall_torque", "no_load_speed") if not tabled else ("motor_speed", "motor_torque")
        missing += [k for k in pair if getattr(self, k) is None]
        if missing:
            raise PydanticCustomError(
                "speed_keys", f"profile = 'driven' needs {', '.join(missing)}"
            )
        if tabled and len(self.motor_speed) != len(self.motor_torque):
            raise PydanticCustomError(
                "speed_keys",
                f"motor_speed has {len(self.motor_speed)} values and motor_torque "
                f"{len(self.motor_torque)}: give one torque per speed",
            )
        return self

    @property
    def driven(self) -> bool:
        return self.profile == "driven"

    def drive_of(self, scale: units.PhysicalScale | None) -> Drive:
        """The nondimensional drive (ValueError naming the problem). With [physical]:
        j = J omega^2 / (k_r gamma^2), torques over k_r gamma^2, speeds in ``unit``."""
        if scale is None:
            if self.unit is not None:
                raise ValueError("unit belongs to a [physical] case")
            speed_to_eta, torque_unit, j, drag = 1.0, 1.0, self.inertia, self.drag
        else:
            speed_to_eta = units.speed_unit(self.unit or "rpm") / scale.omega
            torque_unit = scale.k_r * scale.clearance**2
            j = self.inertia * scale.omega**2 / torque_unit
            drag = self.drag * scale.omega / torque_unit
        if self.stall_torque is not None:
            motor = {"stall_torque": self.stall_torque / torque_unit,
                     "no_load_speed": self.no_load_speed * speed_to_eta}  # fmt: skip
        else:
            motor = {"table_speed": tuple(v * speed_to_eta for v in self.motor_speed),
                     "table_torque": tuple(v / torque_unit for v in self.motor_torque)}  # fmt: skip
        return Drive(inertia=j, start=self.start * speed_to_eta, drag=drag, **motor)

    def snapshot_etas(self, scale: units.PhysicalScale | None) -> list[float] | None:
        """``snapshots`` as speed ratios."""
        if self.snapshots is None or scale is None:
            return self.snapshots
        per = units.speed_unit(self.unit or "rpm")
        return [v * per / scale.omega for v in self.snapshots]

    def profile_of(self, scale: units.PhysicalScale | None) -> SpeedProfile:
        """The nondimensional profile (ValueError naming the problem)."""
        assert not self.driven
        if scale is None:
            if self.unit is not None or self.t is not None:
                raise ValueError("unit and t belong to a [physical] case; use tau and eta")
            if self.profile == "ramp":
                return SpeedProfile.ramp(self.start, self.to, self.rate)
            return SpeedProfile(tau=tuple(self.tau), eta=tuple(self.eta))
        if self.tau is not None:
            raise ValueError("tau and eta belong to a [model] case; use t (s) and speed")
        per = units.speed_unit(self.unit or "rpm")  # rad/s per unit
        if self.profile == "ramp":
            start, end = self.start * per / scale.omega, self.to * per / scale.omega
            rate = self.rate * per / scale.omega**2  # (unit/s) -> d eta / d tau
            return SpeedProfile.ramp(start, end, rate)
        taus = tuple(t * scale.omega for t in self.t)
        return SpeedProfile(tau=taus, eta=tuple(v * per / scale.omega for v in self.speed))

"""A driven rotor: the spin is a state, driven by a motor, braked by the rub.

A non-ideal source (``../shared/docs/general-machine.md``, "Speed that changes"): the
rotor's angle ``p`` and speed ``w = p'`` join the state, ``(x, y, vx, vy, p, w)``. From
the Lagrangian of a rotor whose centre of mass sits at ``e (cos p, sin p)`` from its
geometric centre, with polar moment ``j`` about that centre (``j = J_p / (m gamma^2)``):

    w'' + e p'' t - e p'^2 r = F            (r = (cos p, sin p), t = (-sin p, cos p))
    j p'' + e t . w''        = Q

``F`` is the support, damping and contact force on the rotor (as at constant speed) and
``Q = T_m(w) - c_b w - Rp T`` the torque about the geometric centre: the motor, the
bearing drag and the moment of the rub's tangential force ``T`` (positive opposing
positive slip; ``mu_c K (z - 1)`` in slip). Both equations share ``w''`` and ``p''``;
eliminating ``t . w''`` gives ``(j - e^2) p'' = Q - e t . F``, so ``j > e^2`` (a
positive kinetic energy) is required.

In stick the rub force is a multiplier: ``T`` keeps the slip velocity
``v_r = Rp w + (x vy - y vx) / z`` at zero, which with the two equations is a linear
system in ``p''``, ``T`` and the accelerations, solved in closed form
(``stick_torque_value``). The slip regimes and Filippov's rule at ``v_r = 0`` are those
of the constant-speed model, with the spin ``Rp w`` read from the state.

The energy ``|w'|^2 / 2 + e w t . w' + j w^2 / 2 + |w|^2 / 2 + K (z - 1)^2 / 2`` changes by
the motor's and drag's power ``(T_m - c_b w) w``, the damping's ``-2 nu |w'|^2`` and the
rub's ``-T v_r`` (zero in stick): ``energy_value`` and ``power_value``, which the tests
integrate.

The motor: a linear characteristic ``T_m = T_0 (1 - w / w_s)`` (stall torque ``T_0``,
no-load speed ``w_s``; a generator above ``w_s``), or a table of ``(speed, torque)``,
linear between its points and held outside them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rubcli.model import FREE, MAX_MAGNITUDE, STICK, FloatOrArray, friction_sign

# The drive's record for the compiled cores: one float64 array, read by these names.
DRIVE_RECORD = ("inertia", "drag", "stall_torque", "no_load_speed")
D_INERTIA, D_DRAG, D_STALL, D_NO_LOAD = range(len(DRIVE_RECORD))


@dataclass(frozen=True)
class Drive:
    """A motor driving the rotor (module docstring), nondimensional, checked on
    construction: ValueError naming the field and the problem.

    The motor is linear (``stall_torque``, ``no_load_speed``) or a table
    (``table_speed``, ``table_torque``), not both."""

    inertia: float  # j = J_p / (m gamma^2)
    start: float  # the speed at tau = 0
    stall_torque: float | None = None
    no_load_speed: float | None = None
    table_speed: tuple[float, ...] = ()
    table_torque: tuple[float, ...] = ()
    drag: float = 0.0  # bearing drag c_b: T_b = c_b w

    def __post_init__(self) -> None:
        for name in ("inertia", "start", "drag"):
            _finite(name, getattr(self, name))
        if not self.inertia > 0.0:
            raise ValueError(f"drive: inertia must be > 0 (got {self.inertia!r})")
        if not self.start > 0.0:
            raise ValueError(f"drive: start must be > 0 (got {self.start!r})")
        if self.drag < 0.0:
            raise ValueError(f"drive: drag must be >= 0 (got {self.drag!r})")
        linear = self.stall_torque is not None or self.no_load_speed is not None
        table = bool(self.table_speed) or bool(self.table_torque)
        if linear == table:
            raise ValueError(
                "drive: give the motor either as stall_torque and no_load_speed or as a "
                "table of speed and torque"
            )
        if linear:
            if self.stall_torque is None or self.no_load_speed is None:
                raise ValueError("drive: a linear motor needs stall_torque and no_load_speed")
            _finite("stall_torque", self.stall_torque)
            _finite("no_load_speed", self.no_load_speed)
            if not self.stall_torque > 0.0:
                raise ValueError(f"drive: stall_torque must be > 0 (got {self.stall_torque!r})")
            if not self.no_load_speed > 0.0:
                raise ValueError(f"drive: no_load_speed must be > 0 (got {self.no_load_speed!r})")
            return
        speed = tuple(float(v) for v in self.table_speed)
        torque = tuple(float(v) for v in self.table_torque)
        if len(speed) != len(torque) or len(speed) < 2:
            raise ValueError(
                f"drive: the motor table needs as many torques as speeds, at least 2 (got "
                f"{len(speed)} speeds and {len(torque)} torques)"
            )
        for i, (s, t) in enumerate(zip(speed, torque, strict=True)):
            _finite(f"table speed[{i}]", s)
            _finite(f"table torque[{i}]", t)
            if s < 0.0:
                raise ValueError(f"drive: table speed[{i}] must be >= 0 (got {s!r})")
            if i and not s > speed[i - 1]:
                raise ValueError(f"drive: table speeds must increase (speed[{i}] = {s!r})")
        object.__setattr__(self, "table_speed", speed)
        object.__setattr__(self, "table_torque", torque)

    def check(self, e: float) -> None:
        """ValueError unless the kinetic energy is positive with the unbalance ``e``."""
        if not self.inertia > e * e:
            raise ValueError(
                f"drive: inertia = {self.inertia!r} must exceed e^2 = {e * e!r} (the polar "
                "moment about the geometric centre is at least the unbalance's m e^2)"
            )

    def record(self) -> np.ndarray:
        """The drive as the compiled cores take it (``DRIVE_RECORD``; a table motor has
        stall torque and no-load speed 0 and passes its table beside)."""
        linear = self.stall_torque is not None
        return np.array(
            [
                self.inertia,
                self.drag,
                self.stall_torque if linear else 0.0,
                self.no_load_speed if linear else 0.0,
            ]
        )

    def table(self) -> tuple[np.ndarray, np.ndarray]:
        """The motor table (empty for a linear motor)."""
        return np.array(self.table_speed, dtype=float), np.array(self.table_torque, dtype=float)

    def motor_torque(self, w: FloatOrArray) -> FloatOrArray:
        """T_m at the speed ``w`` (scalars or arrays)."""
        speed, torque = self.table()
        out = motor_torque_value(np.asarray(w, dtype=float), self.record(), speed, torque)
        return float(out) if np.ndim(out) == 0 else out

    def free_speed(self) -> float:
        """The speed the motor holds against its drag alone (no rotor load): where
        T_m(w) = c_b w (for a table, the first such speed along it; its last speed if
        the torque exceeds the drag all along)."""
        if self.stall_torque is not None:
            return self.stall_torque / (self.stall_torque / self.no_load_speed + self.drag)
        speed, torque = self.table()
        net = torque - self.drag * speed
        for i in range(1, speed.size):
            if net[i - 1] > 0.0 >= net[i]:
                return float(speed[i - 1] + (speed[i] - speed[i - 1]) * net[i - 1]
                             / (net[i - 1] - net[i]))  # fmt: skip
        return float(speed[-1]) if net[-1] > 0.0 else float(speed[0])

    def shaft_torque(self, w: FloatOrArray) -> FloatOrArray:
        """The motor's torque less the bearing drag at the speed ``w``."""
        speed, torque = self.table()
        out = shaft_torque_value(np.asarray(w, dtype=float), self.record(), speed, torque)
        return float(out) if np.ndim(out) == 0 else out

    def text(self) -> str:
        """The drive in a few words (figure titles)."""
        if self.stall_torque is not None:
            motor = f"motor {self.stall_torque:g} stall, {self.no_load_speed:g} no-load"
        else:
            motor = f"motor table of {len(self.table_speed)} points"
        return f"driven from eta {self.start:g}, j {self.inertia:g}, {motor}"


def _finite(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value)) or abs(value) > MAX_MAGNITUDE:
        raise ValueError(f"drive: {name} must be a finite number (got {value!r})")


# ------------------------------------------------------------------ compilable cores


def motor_torque_value(
    w: FloatOrArray, drive: np.ndarray, table_speed: np.ndarray, table_torque: np.ndarray
) -> FloatOrArray:
    """T_m(w) (compilable core): the table, else the linear characteristic."""
    if table_speed.shape[0]:
        return np.interp(w, table_speed, table_torque)
    return drive[D_STALL] * (1.0 - w / drive[D_NO_LOAD])


def shaft_torque_value(
    w: FloatOrArray, drive: np.ndarray, table_speed: np.ndarray, table_torque: np.ndarray
) -> FloatOrArray:
    """The motor's torque less the bearing drag, T_m(w) - c_b w (compilable core)."""
    return motor_torque_value(w, drive, table_speed, table_torque) - drive[D_DRAG] * w


def motor_line(
    w: float, rising: bool, drive: np.ndarray, table_speed: np.ndarray, table_torque: np.ndarray
) -> tuple[float, float, float, float]:
    """The motor's torque less drag near the speed w as a line, ``torque + slope w``, and
    the speeds ``(low, high)`` between which it holds: the linear characteristic
    everywhere; a table's piece that the speed is in, or enters (``rising``: upward)
    from one of its corners, its end values held outside it (``np.interp``; compilable
    core: the Taylor series of a driven rotor carry one such line a step)."""
    drag = drive[D_DRAG]
    n = table_speed.shape[0]
    if n == 0:
        stall = drive[D_STALL]
        return stall, -(stall / drive[D_NO_LOAD] + drag), -math.inf, math.inf
    if w < table_speed[0] or (w == table_speed[0] and not rising):
        return table_torque[0], -drag, -math.inf, table_speed[0]
    if w > table_speed[n - 1] or (w == table_speed[n - 1] and rising):
        return table_torque[n - 1], -drag, table_speed[n - 1], math.inf
    i = 0
    while i < n - 2 and (w > table_speed[i + 1] or (w == table_speed[i + 1] and rising)):
        i += 1
    low, high = table_speed[i], table_speed[i + 1]
    slope = (table_torque[i + 1] - table_torque[i]) / (high - low)
    return table_torque[i] - slope * low, slope - drag, low, high


def stick_torque_value(
    x: float, y: float, vx: float, vy: float, p: float, w: float, nu: float, K: float,
    e: float, Rp: float, j: float, Q0: float,
) -> tuple[float, float]:  # fmt: skip
    """In stick: ``(T, p'')``, the rolling friction (positive opposing positive slip) and
    the angular acceleration, with ``Q0`` the motor's torque less drag (compilable core).

    Unknowns ``p''``, ``T``, ``a = t . w''`` and ``b = h . w''`` (``h`` the contact's
    tangent): the rotor's equation along ``h`` and ``t``, the drive's, and the rolling
    constraint ``Rp p'' + b = theta' z'`` (``d/dtau v_r = 0``). Eliminating ``a`` and
    ``b``: ``T = A + B p''`` with ``A = h . F0 + e w^2 h . r - theta' z'``,
    ``B = Rp - e h . t``, and ``(j - e^2 + B^2) p'' = Q0 - e t . F0 - B A``.
    """
    z = math.hypot(x, y)
    nx, ny = x / z, y / z
    hx, hy = -ny, nx
    c, s = math.cos(p), math.sin(p)
    normal = K * (z - 1.0)
    f0x = -x - 2.0 * nu * vx - normal * nx
    f0y = -y - 2.0 * nu * vy - normal * ny
    z_dot = (x * vx + y * vy) / z
    theta_dot = (x * vy - y * vx) / (z * z)
    h_t = -hx * s + hy * c
    h_r = hx * c + hy * s
    A = hx * f0x + hy * f0y + e * w * w * h_r - theta_dot * z_dot
    B = Rp - e * h_t
    t_f0 = -s * f0x + c * f0y
    p_dd = (Q0 - e * t_f0 - B * A) / (j - e * e + B * B)
    return A + B * p_dd, p_dd


def driven_rhs_entries(
    x: float, y: float, vx: float, vy: float, p: float, w: float, nu: float, K: float,
    mu: float, Rp: float, e: float, j: float, Q0: float, regime: int,
) -> tuple[float, float, float, float, float, float, float]:  # fmt: skip
    """The driven rotor's right-hand side in ``regime`` (compilable core): the six
    derivatives and the rub's tangential force ``T`` (module docstring). ``Q0``: the
    motor's torque less drag at ``w``."""
    c, s = math.cos(p), math.sin(p)
    fx = -x - 2.0 * nu * vx
    fy = -y - 2.0 * nu * vy
    T = 0.0
    if regime == STICK:
        T, p_dd = stick_torque_value(x, y, vx, vy, p, w, nu, K, e, Rp, j, Q0)
        z = math.hypot(x, y)
        normal = K * (z - 1.0) / z
        fx -= normal * x - T * y / z
        fy -= normal * y + T * x / z
    else:
        if regime != FREE:
            z = math.hypot(x, y)
            normal = K * (z - 1.0)
            T = mu * friction_sign(regime) * normal
            fx -= (normal * x - T * y) / z
            fy -= (normal * y + T * x) / z
        p_dd = (Q0 - Rp * T - e * (-s * fx + c * fy)) / (j - e * e)
    ax = fx + e * w * w * c + e * p_dd * s
    ay = fy + e * w * w * s - e * p_dd * c
    return vx, vy, ax, ay, w, p_dd, T


def rolling_projection(
    x: float, y: float, vx: float, vy: float, p: float, w: float, e: float, Rp: float, j: float
) -> tuple[float, float, float]:
    """The velocities ``(vx, vy, w)`` with ``v_r = 0`` exactly, moved along the kinetic
    energy's metric (the least change of the energy; compilable core): the constraint's
    gradient ``g = (h, Rp)`` through the inverse of the mass matrix."""
    z = math.hypot(x, y)
    hx, hy = -y / z, x / z
    c, s = math.cos(p), math.sin(p)
    u_p = (Rp - e * (-hx * s + hy * c)) / (j - e * e)
    ux, uy = hx + e * u_p * s, hy - e * u_p * c
    v_r = Rp * w + hx * vx + hy * vy
    scale = v_r / (hx * ux + hy * uy + Rp * u_p)
    return vx - scale * ux, vy - scale * uy, w - scale * u_p


def energy_value(
    x: FloatOrArray, y: FloatOrArray, vx: FloatOrArray, vy: FloatOrArray, p: FloatOrArray,
    w: FloatOrArray, K: float, e: float, j: float,
) -> FloatOrArray:  # fmt: skip
    """The driven rotor's energy, kinetic (with the unbalance's coupling) and elastic."""
    z = np.hypot(x, y)
    kinetic = 0.5 * (vx * vx + vy * vy) + e * w * (-np.sin(p) * vx + np.cos(p) * vy)
    kinetic = kinetic + 0.5 * j * w * w
    contact = np.where(z > 1.0, 0.5 * K * (z - 1.0) ** 2, 0.0)
    return kinetic + 0.5 * (x * x + y * y) + contact

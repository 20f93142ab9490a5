"""The physics of the rubbing Jeffcott rotor: the one place where it is written.

Everything here is nondimensional (model notes, section 1):

    x'' + 2 nu x' + x + K f_x = E cos(eta tau + phi0)
    y'' + 2 nu y' + y + K f_y = E sin(eta tau + phi0),       E = e eta^2

    f = (1 - 1/z) (x - mu_c y, y + mu_c x)   for z > 1,   f = 0 for z <= 1
    mu_c = mu sign(v_r),   v_r = Rp eta + (x y' - y x') / z

The sign convention is that of the notes (correction 1 to the paper): ``K f`` stands on
the left-hand side, so the force the stator exerts on the rotor is ``-K f``. It pushes
the rotor back towards the centre, and its tangential part opposes the slip ``v_r``.

State vectors are ``s = (x, y, vx, vy)`` with ``vx = dx/dtau``. The functions work on
plain floats and numpy arrays; nothing here imports a solver, pydantic, matplotlib or numba.

The formulas the compiled kernels need (``rubcli/solvers/compiled/``) are written once,
as the ``*_entries`` / ``*_arrays`` / ``*_value`` cores below: plain functions on floats
(some also on arrays) in the subset of Python that numba compiles. The public functions
here call them, and ``compiled/jit.py`` registers the same function objects with numba
(``register_jitable``), so the Python and the compiled paths share one definition.
"""

from __future__ import annotations

import cmath
import math
import numbers
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

    from numpy.typing import ArrayLike

# What the cores that work "from scalars or arrays" take and give: a float or an array
FloatOrArray = float | np.ndarray
ComplexOrArray = complex | np.ndarray

# Regime codes carried by solutions (one per sample and per segment).
FREE = 0
SLIP_POSITIVE = 1  # in contact, v_r > 0, mu_c = +mu
SLIP_NEGATIVE = -1  # in contact, v_r < 0, mu_c = -mu
STICK = 2  # in contact, rolling without slip: v_r = 0 held by friction within mu F_N
# Stick ends where the needed friction exceeds mu F_N by this relative margin, so that
# the slip that follows moves away from v_r = 0 (its rate is this margin times mu F_N)
STICK_EXIT_MARGIN = 1e-9
REGIME_NAMES = {FREE: "free", SLIP_POSITIVE: "slip+", SLIP_NEGATIVE: "slip-", STICK: "stick"}


# The model's domain (docs/cases.md, "The model's domain"). Every parameter and every
# state is at most MAX_MAGNITUDE in size, so that any product of three of them (the
# equations form e eta^2, K (z - 1) x, x vy) stays below the largest double, 1.8e308; a
# divisor (eta, in the period 2 pi / eta) is at least 1 / MAX_MAGNITUDE.
MAX_MAGNITUDE = 1e100
# The sign each parameter must have: "> 0", ">= 0" or None (any).
PARAMETER_SIGNS: dict[str, str | None] = {
    "nu": ">= 0", "eta": "> 0", "e": ">= 0", "K": "> 0", "mu": ">= 0", "Rp": ">= 0",
    "phi0": None,
}  # fmt: skip
DIVISORS = ("eta",)  # parameters that divide (the period 2 pi / eta)


def parameter_problem(name: str, value: float) -> str | None:
    """Why ``value`` lies outside the domain of the parameter ``name`` (without the value
    itself), or None."""
    if not math.isfinite(value):
        return "must be finite"
    sign = PARAMETER_SIGNS[name]
    if (sign == "> 0" and value <= 0.0) or (sign == ">= 0" and value < 0.0):
        return f"must be {sign}"
    if abs(value) > MAX_MAGNITUDE:
        return (
            f"must be at most {MAX_MAGNITUDE:g} in size: beyond that the products the "
            "equations form overflow (the model's domain, docs/cases.md)"
        )
    if name in DIVISORS and abs(value) < 1.0 / MAX_MAGNITUDE:
        return (
            f"must be at least {1.0 / MAX_MAGNITUDE:g}: it divides, and 1/{name} must stay "
            f"below {MAX_MAGNITUDE:g} (the model's domain, docs/cases.md)"
        )
    return None


def real_number(owner: str, name: str, value: object) -> float:
    """``value`` as a float; TypeError naming ``owner.name`` if it is not a real number
    (a bool, a string, None, an array are refused), ValueError if it is too large for a
    float (an int such as 10**400)."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise TypeError(f"{owner}: {name} must be a real number, got {type(value).__name__}")
    try:
        return float(value)
    except OverflowError:  # an int (or a Fraction) beyond the largest double
        raise ValueError(
            f"{owner}: {name} must be finite (got a number beyond the largest double)"
        ) from None


# The stator's record for the compiled cores: one float64 array, read by these names.
STATOR_RECORD = ("inverse_mass", "k_x", "k_y", "n_x", "n_y")
S_INV_MASS, S_KX, S_KY, S_NX, S_NY = range(len(STATOR_RECORD))


@dataclass(frozen=True)
class Stator:
    """A stator with its own mass (its equations: ``rubcli.stator``): its mass ratio,
    support stiffness ratios and damping, nondimensional, checked on construction:
    ValueError naming the field."""

    mass: float  # m_s = M_s / m
    stiffness: tuple[float, float]  # (k_sx, k_sy) over k_r
    damping: tuple[float, float] = (0.0, 0.0)  # (n_sx, n_sy): forces 2 n_s s'

    def __post_init__(self) -> None:
        mass = _stator_number("mass", self.mass)
        if not mass > 0.0:
            raise ValueError(f"stator: mass must be > 0 (got {self.mass!r})")
        object.__setattr__(self, "mass", mass)
        for name, low in (("stiffness", "> 0"), ("damping", ">= 0")):
            pair = getattr(self, name)
            if isinstance(pair, str) or not hasattr(pair, "__len__") or len(pair) != 2:
                raise TypeError(f"stator: {name} must be a pair [x, y] of real numbers")
            values = tuple(_stator_number(f"{name}[{i}]", v) for i, v in enumerate(pair))
            for i, v in enumerate(values):
                if not (v > 0.0 if low == "> 0" else v >= 0.0):
                    raise ValueError(f"stator: {name}[{i}] must be {low} (got {v!r})")
            object.__setattr__(self, name, values)

    def record(self) -> np.ndarray:
        """The stator as the compiled cores take it (``STATOR_RECORD``)."""
        (kx, ky), (nx, ny) = self.stiffness, self.damping
        return np.array([1.0 / self.mass, kx, ky, nx, ny])

    def as_dict(self) -> dict[str, object]:
        """The stator as a case file's ``[stator]`` table holds it."""
        return {"mass": self.mass, "stiffness": list(self.stiffness),
                "damping": list(self.damping)}  # fmt: skip

    def text(self) -> str:
        """The stator in a few words (titles, ``validate``)."""
        (kx, ky), (nx, ny) = self.stiffness, self.damping
        return f"stator mass {self.mass:g}, stiffness [{kx:g}, {ky:g}], damping [{nx:g}, {ny:g}]"

    def natural_frequencies(self) -> tuple[float, float]:
        """The stator's own undamped natural frequencies along x and y, sqrt(k_s / m_s)
        (in units of the rotor's omega)."""
        kx, ky = self.stiffness
        return math.sqrt(kx / self.mass), math.sqrt(ky / self.mass)


def _stator_number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"stator: {name} must be a real number (got {value!r})")
    value = float(value)
    if not (math.isfinite(value) and abs(value) <= MAX_MAGNITUDE):
        raise ValueError(f"stator: {name} must be a finite number (got {value!r})")
    return value


@dataclass(frozen=True)
class ModelParams:
    """Nondimensional parameters (notes section 1), checked against the model's domain
    (``parameter_problem``): TypeError or ValueError naming the parameter."""

    nu: float  # damping ratio d_r / (2 omega m)
    eta: float  # speed ratio Omega / omega
    e: float  # unbalance eccentricity / clearance
    K: float  # stator / rotor stiffness ratio
    mu: float = 0.0  # Coulomb friction coefficient
    Rp: float = 0.0  # rotor radius / clearance
    phi0: float = 0.0  # unbalance phase (rad)
    # A speed that changes (rubcli.speed): on one leg of a speed profile the speed is
    # eta + rate (tau - tau0) and the unbalance phase eta tau + phi0 + rate (tau - tau0)^2 / 2
    # (its exact integral). rate = 0 is the constant speed of the paper.
    rate: float = 0.0
    tau0: float = 0.0
    # The general machine (docs/machines.md); the defaults are the paper's machine.
    # offset: the stator's centre from the rotor support's centre, in clearances;
    # load: a static force on the rotor (gravity, a side load), in units of k_r clearance;
    # stiffness: the support stiffness matrix S over k_r, ((k_xx, k_xy), (k_yx, k_yy));
    # damping: the support damping matrix D, forces 2 D w' (None: nu I; an isotropic
    # matrix is taken as its nu, and giving both a nonzero nu and a matrix is an error).
    offset: tuple[float, float] = (0.0, 0.0)
    load: tuple[float, float] = (0.0, 0.0)
    stiffness: tuple[tuple[float, float], tuple[float, float]] = ((1.0, 0.0), (0.0, 1.0))
    damping: tuple[tuple[float, float], tuple[float, float]] | None = None
    # A stator with its own mass on its own supports (rubcli.stator; None: rigid).
    stator: Stator | None = None

    def __post_init__(self) -> None:
        for name in PARAMETER_SIGNS:
            value = real_number("ModelParams", name, getattr(self, name))
            problem = parameter_problem(name, value)
            if problem:
                raise ValueError(f"ModelParams: {name} {problem} (got {value!r})")
            object.__setattr__(self, name, value)
        for name in ("rate", "tau0"):
            value = real_number("ModelParams", name, getattr(self, name))
            if not (math.isfinite(value) and abs(value) <= MAX_MAGNITUDE):
                raise ValueError(f"ModelParams: {name} must be finite (got {value!r})")
            object.__setattr__(self, name, value)
        for name in ("offset", "load"):
            object.__setattr__(self, name, _vector(name, getattr(self, name)))
        object.__setattr__(self, "stiffness", _matrix("stiffness", self.stiffness))
        why = support_problem("stiffness", self.stiffness)
        if why:
            raise ValueError(f"ModelParams: stiffness {why}")
        if self.damping is not None:
            damping = _matrix("damping", self.damping)
            why = support_problem("damping", damping)
            if why:
                raise ValueError(f"ModelParams: damping {why}")
            if self.nu != 0.0:
                raise ValueError(
                    "ModelParams: give the support damping as nu or as a damping matrix, "
                    f"not both (nu = {self.nu!r} with damping = {damping!r})"
                )
            (dxx, dxy), (dyx, dyy) = damping
            if dxy == 0.0 and dyx == 0.0 and dxx == dyy:  # isotropic: the paper's nu
                object.__setattr__(self, "nu", dxx)
                damping = None
            object.__setattr__(self, "damping", damping)
        if self.stator is not None and not isinstance(self.stator, Stator):
            raise TypeError(f"ModelParams: stator must be a rubcli.stator.Stator or None, got "
                            f"{type(self.stator).__name__}")  # fmt: skip

    def speed(self, tau: FloatOrArray) -> FloatOrArray:
        """The speed ratio at tau: eta, or on a leg of a speed profile eta + rate (tau - tau0)."""
        if self.rate == 0.0:
            return self.eta if np.ndim(tau) == 0 else np.full(np.shape(tau), self.eta)
        return self.eta + self.rate * (np.asarray(tau, dtype=float) - self.tau0)

    def spin(self, tau: FloatOrArray) -> FloatOrArray:
        """The rotor's surface speed Rp eta(tau) (the first term of v_r)."""
        return self.Rp * self.speed(tau)

    @property
    def E(self) -> float:
        """Amplitude of the unbalance forcing, e eta^2."""
        return self.e * self.eta**2

    @property
    def period(self) -> float:
        """Forcing period 2 pi / eta in tau."""
        return 2.0 * math.pi / self.eta

    def as_dict(self) -> dict[str, float]:
        """The machine's scalar parameters (without a speed profile's leg and without the
        general machine's vectors and matrices: ``machine_dict``)."""
        return {name: getattr(self, name) for name in PARAMETER_SIGNS}

    @property
    def damping_matrix(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The support damping matrix D (nu I unless a matrix was given)."""
        if self.damping is None:
            return ((self.nu, 0.0), (0.0, self.nu))
        return self.damping

    @property
    def is_paper_machine(self) -> bool:
        """Whether this is the paper's machine: a rigid concentric stator, no static load and
        an isotropic support (S = I, D = nu I)."""
        return (
            self.stator is None
            and self.offset == (0.0, 0.0)
            and self.load == (0.0, 0.0)
            and self.stiffness == ((1.0, 0.0), (0.0, 1.0))
            and self.damping is None
        )

    def machine_dict(self) -> dict[str, list]:
        """The general machine's entries that differ from the paper's machine, as lists
        (what a case file's [model] holds)."""
        out: dict[str, list] = {}
        if self.offset != (0.0, 0.0):
            out["offset"] = list(self.offset)
        if self.load != (0.0, 0.0):
            out["load"] = list(self.load)
        if self.stiffness != ((1.0, 0.0), (0.0, 1.0)):
            out["stiffness"] = [list(row) for row in self.stiffness]
        if self.damping is not None:
            out["damping"] = [list(row) for row in self.damping]
        return out

    def machine_text(self) -> str:
        """The general machine's entries in one line (``offset=[0.6, 0], ...``), or ''."""
        return ", ".join(self.machine_lines())

    def machine_lines(self, omit: Iterable[str] = ()) -> list[str]:
        """The general machine's entries: the support's and the offset and load in one
        line, a moving stator's in another (none on the paper's machine). ``omit``: the
        ``MACHINE_PARAMETERS`` a figure varies, whose entries are not one value."""
        omit = {_ENTRY_OF.get(name, name) for name in omit}

        def text(value: list) -> str:
            inner = (text(v) if isinstance(v, list) else f"{v:g}" for v in value)
            return "[" + ", ".join(inner) + "]"

        entries = self.machine_dict().items()
        line = ", ".join(f"{k}={text(v)}" for k, v in entries if k not in omit)
        lines = [line] if line else []
        if self.stator is not None:
            (kx, ky), (nx, ny) = self.stator.stiffness, self.stator.damping
            ring = [f"m={self.stator.mass:g}" if "stator_mass" not in omit else "",
                    f"k=[{kx:g}, {ky:g}]" if "stator_stiffness" not in omit else "",
                    f"n=[{nx:g}, {ny:g}]"]  # fmt: skip
            lines.append(" ".join(["stator", *filter(None, ring)]))
        return lines

    @property
    def static_force(self) -> tuple[float, float]:
        """The constant force on the rotor in the model's coordinates (relative to the
        stator's centre): the load less the support's pull towards its own centre,
        ``g - S c``."""
        (sxx, sxy), (syx, syy) = self.stiffness
        cx, cy = self.offset
        return self.load[0] - (sxx * cx + sxy * cy), self.load[1] - (syx * cx + syy * cy)

    def static_position(self) -> tuple[float, float]:
        """The rotor's rest position without contact and unbalance, in the model's
        coordinates: the solution of ``S (d + c) = g``, less ``c``."""
        (sxx, sxy), (syx, syy) = self.stiffness
        gx, gy = self.static_force
        det = sxx * syy - sxy * syx
        return (syy * gx - sxy * gy) / det, (sxx * gy - syx * gx) / det


# The general machine's scalars a sweep can vary (docs/machines.md), with their meaning.
# "offset" and "load" are magnitudes along the case's own direction (x for an offset the
# case does not give, -y for a load: gravity); "cross_coupling" is q of the antisymmetric
# part q [[0, 1], [-1, 0]] of the stiffness, its symmetric part kept.
MACHINE_PARAMETERS = {
    "offset": "stator offset (clearances)",
    "offset_x": "stator offset c_x (clearances)",
    "offset_y": "stator offset c_y (clearances)",
    "load": "static load (k_r clearance)",
    "load_x": "static load g_x (k_r clearance)",
    "load_y": "static load g_y (k_r clearance)",
    "k_xx": "support stiffness k_xx / k_r (-)",
    "k_xy": "support stiffness k_xy / k_r (-)",
    "k_yx": "support stiffness k_yx / k_r (-)",
    "k_yy": "support stiffness k_yy / k_r (-)",
    "cross_coupling": "cross-coupled stiffness q / k_r (-)",
    "stator_mass": "stator mass M_s / m (-)",
    "stator_k_x": "stator support stiffness k_sx / k_r (-)",
    "stator_k_y": "stator support stiffness k_sy / k_r (-)",
}


# the entry of ``machine_lines`` each of ``MACHINE_PARAMETERS`` changes
_ENTRY_OF = {
    "offset_x": "offset", "offset_y": "offset", "load_x": "load", "load_y": "load",
    "k_xx": "stiffness", "k_xy": "stiffness", "k_yx": "stiffness", "k_yy": "stiffness",
    "cross_coupling": "stiffness", "stator_k_x": "stator_stiffness",
    "stator_k_y": "stator_stiffness",
}  # fmt: skip


def with_value(params: ModelParams, name: str, value: float) -> ModelParams:
    """``params`` with one parameter set: a scalar of ``PARAMETER_SIGNS`` or one of the
    general machine's ``MACHINE_PARAMETERS``; ValueError (from ``ModelParams``) where the
    value leaves the model's domain."""
    value = float(value)
    if name in PARAMETER_SIGNS:
        return replace(params, **{name: value})
    (sxx, sxy), (syx, syy) = params.stiffness
    if name in ("offset", "load"):
        vector = params.offset if name == "offset" else params.load
        size = math.hypot(*vector)
        unit = (vector[0] / size, vector[1] / size) if size > 0.0 else _DIRECTIONS[name]
        return replace(params, **{name: (value * unit[0], value * unit[1])})
    if name in ("offset_x", "offset_y", "load_x", "load_y"):
        base, axis = name.split("_")
        vector = list(getattr(params, base))
        vector["xy".index(axis)] = value
        return replace(params, **{base: tuple(vector)})
    if name == "cross_coupling":
        mean = 0.5 * (sxy + syx)
        return replace(params, stiffness=((sxx, mean + value), (mean - value, syy)))
    if name in ("k_xx", "k_xy", "k_yx", "k_yy"):
        entries = {"k_xx": sxx, "k_xy": sxy, "k_yx": syx, "k_yy": syy, name: value}
        return replace(
            params,
            stiffness=((entries["k_xx"], entries["k_xy"]), (entries["k_yx"], entries["k_yy"])),
        )
    if name.startswith("stator_"):
        if params.stator is None:
            raise ValueError(f"{name} needs a stator with its own mass ([stator] in the case)")
        stator = params.stator
        if name == "stator_mass":
            return replace(params, stator=replace(stator, mass=value))
        stiffness = list(stator.stiffness)
        stiffness["xy".index(name[-1])] = value
        return replace(params, stator=replace(stator, stiffness=tuple(stiffness)))
    raise ValueError(f"unknown parameter {name!r}")


_DIRECTIONS = {"offset": (1.0, 0.0), "load": (0.0, -1.0)}


def _vector(name: str, value: object) -> tuple[float, float]:
    """``value`` as a pair of finite floats within the model's domain; TypeError or
    ValueError naming ``ModelParams.name``."""
    if isinstance(value, str) or not hasattr(value, "__len__") or len(value) != 2:
        raise TypeError(f"ModelParams: {name} must be a pair [x, y] of real numbers")
    pair = tuple(real_number("ModelParams", f"{name}[{i}]", v) for i, v in enumerate(value))
    for i, v in enumerate(pair):
        if not (math.isfinite(v) and abs(v) <= MAX_MAGNITUDE):
            raise ValueError(
                f"ModelParams: {name}[{i}] must be finite and at most {MAX_MAGNITUDE:g} in "
                f"size (got {v!r})"
            )
    return pair[0] + 0.0, pair[1] + 0.0  # no -0.0: the paper's machine compares equal


def _matrix(name: str, value: object) -> tuple[tuple[float, float], tuple[float, float]]:
    """``value`` as a 2x2 matrix of finite floats (rows); TypeError or ValueError."""
    if isinstance(value, str) or not hasattr(value, "__len__") or len(value) != 2:
        raise TypeError(f"ModelParams: {name} must be a 2x2 matrix [[xx, xy], [yx, yy]]")
    return _vector(f"{name}[0]", value[0]), _vector(f"{name}[1]", value[1])


def support_problem(
    name: str, matrix: tuple[tuple[float, float], tuple[float, float]]
) -> str | None:
    """Why a support matrix cannot be the machine's (without its value), or None.

    The stiffness's symmetric part must be positive definite (else the rotor has no rest
    position); the damping's positive semi-definite (else it feeds energy in). Their
    antisymmetric parts are free: cross-coupled stiffness, gyroscopic damping."""
    (a, b), (c, d) = matrix
    off = 0.5 * (b + c)
    det = a * d - off * off
    if name == "stiffness" and not (a > 0.0 and d > 0.0 and det > 0.0):
        return (
            f"must have a positive-definite symmetric part (k_xx > 0, k_yy > 0 and "
            f"k_xx k_yy > ((k_xy + k_yx)/2)^2; got {[list(matrix[0]), list(matrix[1])]}): "
            "without it the rotor has no rest position"
        )
    if name == "damping" and not (a >= 0.0 and d >= 0.0 and det >= 0.0):
        return (
            f"must have a positive semi-definite symmetric part (d_xx >= 0, d_yy >= 0 and "
            f"d_xx d_yy >= ((d_xy + d_yx)/2)^2; got {[list(matrix[0]), list(matrix[1])]}): "
            "otherwise the support feeds energy in"
        )
    return None


# The parameter record of the compiled cores: one float64 array (``params_vector``), read
# by these names, never by position. A parameter of the machine is added here (and in
# ``ModelParams`` and the case schema); the loops pass the record through unread.
# e, rate and tau0 are read only where the speed changes (``unbalance_value``).
# The general machine enters as its departure from the paper's (``support_extra``): the
# stiffness S - I (s_xx .. s_yy), the damping D - nu I (d_xx .. d_yy) and the constant
# force g - S c (g_x, g_y); all 0 on the paper's machine, where "general" is 0 too (1 on the
# general machine: the hot paths test this one entry, not the ten, before adding them).
PARAMETER_RECORD = (
    "nu", "eta", "E", "phi0", "K", "mu", "Rp", "e", "rate", "tau0",
    "s_xx", "s_xy", "s_yx", "s_yy", "d_xx", "d_xy", "d_yx", "d_yy", "g_x", "g_y", "general",
)  # fmt: skip
(
    P_NU, P_ETA, P_E, P_PHI0, P_K, P_MU, P_RP, P_ECC, P_RATE, P_TAU0,
    P_SXX, P_SXY, P_SYX, P_SYY, P_DXX, P_DXY, P_DYX, P_DYY, P_GX, P_GY, P_GENERAL,
) = range(len(PARAMETER_RECORD))  # fmt: skip
N_PARAMS = len(PARAMETER_RECORD)


def params_vector(params: ModelParams) -> tuple[float, ...]:
    """The parameters as the cores take them, in the order of ``PARAMETER_RECORD``."""
    (sxx, sxy), (syx, syy) = params.stiffness
    (dxx, dxy), (dyx, dyy) = params.damping_matrix
    nu = params.nu
    extra = (sxx - 1.0, sxy, syx, syy - 1.0, dxx - nu, dxy, dyx, dyy - nu, *params.static_force)
    scalars = tuple(float(getattr(params, name)) for name in PARAMETER_RECORD[:P_SXX])
    general = 0.0 if params.is_paper_machine else 1.0
    return scalars + tuple(float(v) + 0.0 for v in extra) + (general,)


def support_extra(
    x: FloatOrArray, y: FloatOrArray, vx: FloatOrArray, vy: FloatOrArray,
    pars: np.ndarray | tuple[float, ...],
) -> tuple[FloatOrArray, FloatOrArray]:  # fmt: skip
    """The general machine's acceleration beyond the paper's (compilable core; scalars or
    arrays): ``g - S c - (S - I) d - 2 (D - nu I) d'`` at the relative position ``d =
    (x, y)`` and velocity ``d' = (vx, vy)``. Exactly 0 on the paper's machine, so that
    adding it leaves the paper's numbers bit for bit."""
    ax = (
        pars[P_GX]
        - (pars[P_SXX] * x + pars[P_SXY] * y)
        - 2.0 * (pars[P_DXX] * vx + pars[P_DXY] * vy)
    )
    ay = (
        pars[P_GY]
        - (pars[P_SYX] * x + pars[P_SYY] * y)
        - 2.0 * (pars[P_DYX] * vx + pars[P_DYY] * vy)
    )
    return ax, ay


def friction_sign(regime: int) -> float:
    """The sign of mu_c in a regime (0 in free flight and in stick). Compilable core."""
    if regime in (SLIP_POSITIVE, SLIP_NEGATIVE):
        return float(regime)
    return 0.0


# --------------------------------------------------------------------------- forces


def radius(x: FloatOrArray, y: FloatOrArray) -> FloatOrArray:
    """z = sqrt(x^2 + y^2), in clearances."""
    return np.hypot(x, y)


def penetration_factor(x: FloatOrArray, y: FloatOrArray) -> FloatOrArray:
    """(1 - 1/z) where z > 1, else 0: the scalar factor of the contact force."""
    z = np.hypot(x, y)
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(z > 1.0, 1.0 - 1.0 / z, 0.0)
    return factor if np.ndim(factor) else float(factor)


def contact_force(
    x: FloatOrArray, y: FloatOrArray, K: float, mu_c: float
) -> tuple[FloatOrArray, FloatOrArray]:
    """Force of the stator on the rotor, ``(Fx, Fy) = -K f``, nondimensional (eq. 5-6 corrected).

    Zero inside the clearance (z <= 1). ``mu_c`` is the signed friction coefficient
    (``mu sign(v_r)``). Divide by nothing: in units of ``k_r * clearance`` this is the
    force; multiply by ``k_r * clearance`` for newtons.
    """
    factor = penetration_factor(x, y)
    fx = -K * factor * (x - mu_c * y)
    fy = -K * factor * (y + mu_c * x)
    return fx, fy


def normal_force(x: FloatOrArray, y: FloatOrArray, K: float) -> FloatOrArray:
    """Magnitude of the normal contact force, K (z - 1) for z > 1, else 0."""
    z = np.hypot(x, y)
    out = np.where(z > 1.0, K * (z - 1.0), 0.0)
    return out if np.ndim(out) else float(out)


def slip_velocity_value(x: float, y: float, vx: float, vy: float, spin: float) -> float:
    """v_r of one state from scalars, ``spin = Rp eta`` (compilable core; 0 whirl at z = 0)."""
    z = math.hypot(x, y)
    return spin + ((x * vy - y * vx) / z if z > 0.0 else 0.0)


def slip_velocity(
    x: FloatOrArray, y: FloatOrArray, vx: FloatOrArray, vy: FloatOrArray, Rp: float, eta: float
) -> FloatOrArray:
    """v_r = Rp eta + (x vy - y vx) / z: slip of the rotor surface on the stator (notes 1, 6)."""
    if isinstance(x, float) and isinstance(y, float):  # one state: the event code's case
        return float(slip_velocity_value(x, y, vx, vy, Rp * eta))
    z = np.hypot(x, y)
    with np.errstate(divide="ignore", invalid="ignore"):
        whirl = np.where(z > 0.0, (x * vy - y * vx) / np.where(z > 0.0, z, 1.0), 0.0)
    out = Rp * eta + whirl
    return out if np.ndim(out) else float(out)


def slip_velocity_rate(
    x: FloatOrArray,
    y: FloatOrArray,
    vx: FloatOrArray,
    vy: FloatOrArray,
    ax: FloatOrArray,
    ay: FloatOrArray,
) -> FloatOrArray:
    """d v_r / dtau from the state and its acceleration (ax, ay); scalars or arrays.

    v_r = Rp eta + w / z with w = x vy - y vx, so dv_r/dtau = (x ay - y ax) / z - w z' / z^2
    (compilable core).
    """
    z = np.hypot(x, y)
    whirl = x * vy - y * vx
    zdot = (x * vx + y * vy) / z
    return (x * ay - y * ax) / z - whirl * zdot / (z * z)


def force_jacobian_entries(x0: float, y0: float, mu_c: float) -> tuple[float, float, float, float]:
    """Entries (j00, j01, j10, j11) of ``force_jacobian`` (compilable core)."""
    a = x0 * x0 + y0 * y0
    z0 = math.sqrt(a)
    inv_z = 1.0 / z0
    inv_z3 = 1.0 / (a * z0)
    A1 = 1.0 - inv_z + x0 * x0 * inv_z3
    A2 = 1.0 - inv_z + y0 * y0 * inv_z3
    B = x0 * y0 * inv_z3
    # F_a1 - 1, F_b1 (over K); F_b2, F_a2 - 1 (over K)
    return A1 - mu_c * B, B - mu_c * A2, B + mu_c * A1, A2 + mu_c * B


def force_jacobian(x0: float, y0: float, mu_c: float) -> np.ndarray:
    """Jacobian of f = (1 - 1/z) R (x, y) at (x0, y0), R = [[1, -mu_c], [mu_c, 1]].

    With the paper's coefficients (eq. 9-12) this is R [[A1, B1], [B2, A2]].
    """
    j00, j01, j10, j11 = force_jacobian_entries(float(x0), float(y0), float(mu_c))
    return np.array([[j00, j01], [j10, j11]])


def taylor_force(
    x0: float, y0: float, x: FloatOrArray, y: FloatOrArray, K: float, mu_c: float
) -> tuple[FloatOrArray, FloatOrArray]:
    """First-order Taylor expansion about (x0, y0) of the contact force ``-K f`` (eq. 9-14).

    Uses the paper's constant terms D1 = -x0/sqrt(alpha), D2 = -y0/sqrt(alpha), so
    ``f ~ R ((A1 x + B1 y + D1), (B2 x + A2 y + D2))``. Valid as an approximation for an
    expansion point in contact (z0 > 1 or on the circle).
    """
    A1, B, _, A2 = force_jacobian_entries(x0, y0, 0.0)  # the coefficients without friction
    inv_z = 1.0 / math.sqrt(x0 * x0 + y0 * y0)
    f1x = A1 * x + B * y - x0 * inv_z
    f1y = B * x + A2 * y - y0 * inv_z
    return -K * (f1x - mu_c * f1y), -K * (f1y + mu_c * f1x)


def linearised_contact_arrays(
    x0: float, y0: float, K: float, nu: float, mu_c: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` of ``linearised_contact_system`` from scalars (compilable core)."""
    j00, j01, j10, j11 = force_jacobian_entries(x0, y0, mu_c)
    factor = 1.0 - 1.0 / math.hypot(x0, y0)
    f0x = factor * (x0 - mu_c * y0)
    f0y = factor * (y0 + mu_c * x0)
    A = np.zeros((4, 4))
    A[0, 2] = 1.0
    A[1, 3] = 1.0
    A[2, 0] = -(1.0 + K * j00)
    A[2, 1] = -(K * j01)
    A[3, 0] = -(K * j10)
    A[3, 1] = -(1.0 + K * j11)
    A[2, 2] = -2.0 * nu
    A[3, 3] = -2.0 * nu
    b = np.zeros(4)
    b[2] = -K * (f0x - (j00 * x0 + j01 * y0))
    b[3] = -K * (f0y - (j10 * x0 + j11 * y0))
    return A, b


def add_support_linear(A: np.ndarray, b: np.ndarray, pars: np.ndarray | tuple[float, ...]) -> None:
    """The general machine's departures (``support_extra``: linear in the state, with a
    constant force) added to a first-order system ``s' = A s + b`` in place (compilable
    core; on the paper's machine it returns at once)."""
    if not is_general_record(pars):
        return
    subtract_support(A, pars)
    b[2] += pars[P_GX]
    b[3] += pars[P_GY]


def subtract_support(M: np.ndarray, pars: np.ndarray | tuple[float, ...]) -> None:
    """The linear part of ``support_extra``, ``-(S - I)`` on the positions and ``-2 (D -
    nu I)`` on the velocities, added to a system matrix or a Jacobian (4, 4) in place
    (compilable core)."""
    M[2, 0] -= pars[P_SXX]
    M[2, 1] -= pars[P_SXY]
    M[3, 0] -= pars[P_SYX]
    M[3, 1] -= pars[P_SYY]
    M[2, 2] -= 2.0 * pars[P_DXX]
    M[2, 3] -= 2.0 * pars[P_DXY]
    M[3, 2] -= 2.0 * pars[P_DYX]
    M[3, 3] -= 2.0 * pars[P_DYY]


def linearised_contact_record(
    x0: float, y0: float, pars: np.ndarray | tuple[float, ...], mu_c: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` of the contact equation of the general machine linearised about (x0,
    y0), from a record (compilable core): ``linearised_contact_arrays`` with the
    departures of ``add_support_linear``."""
    A, b = linearised_contact_arrays(x0, y0, pars[P_K], pars[P_NU], mu_c)
    add_support_linear(A, b, pars)
    return A, b


def free_flight_record(pars: np.ndarray | tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` of the free flight of the general machine, ``s' = A s + b + q(tau)``
    with ``q = (0, 0, E cos(eta tau + phi0), E sin(eta tau + phi0))``, from a record
    (compilable core): linear, so its solution is exact (the analytic method's free
    flight off the paper's machine)."""
    A = np.zeros((4, 4))
    A[0, 2] = 1.0
    A[1, 3] = 1.0
    A[2, 0] = -1.0
    A[3, 1] = -1.0
    A[2, 2] = -2.0 * pars[P_NU]
    A[3, 3] = -2.0 * pars[P_NU]
    b = np.zeros(4)
    add_support_linear(A, b, pars)
    return A, b


def free_flight_system(params: ModelParams) -> tuple[np.ndarray, np.ndarray]:
    """``free_flight_record`` of ``params``."""
    return free_flight_record(params_vector(params))


def linearised_contact_system(
    s0: Sequence[float] | np.ndarray, params: ModelParams, mu_c: float
) -> tuple[np.ndarray, np.ndarray]:
    """The contact equation linearised about the state ``s0`` (eq. 13-14, corrected).

    Returns ``(A, b)`` of the first-order system ``s' = A s + b + q(tau)`` where
    ``q = (0, 0, E cos(eta tau + phi0), E sin(eta tau + phi0))``. The stiffness block is
    ``I + K J`` with ``J = force_jacobian``: rows ``[F_a1, F_b1]`` and ``[F_b2, F_a2]``
    (correction 2), and ``b`` carries ``-K (f(s0) - J p0)``.
    """
    return linearised_contact_record(float(s0[0]), float(s0[1]), params_vector(params), float(mu_c))


def contact_eigenvalues(x0: float, y0: float, params: ModelParams, mu_c: float) -> np.ndarray:
    """Eigenvalues of the linearised contact system at the point (x0, y0)."""
    A, _ = linearised_contact_system((x0, y0, 0.0, 0.0), params, mu_c)
    return np.linalg.eigvals(A)


def unbalance_value(
    tau: FloatOrArray, eta: float, E: float, phi0: float, e: float, rate: float, tau0: float
) -> tuple[FloatOrArray, FloatOrArray]:
    """The unbalance force (fx, fy) at tau, scalars or arrays (compilable core).

    At constant speed (rate = 0) ``E (cos p, sin p)`` with ``p = eta tau + phi0``. On a leg
    of a speed profile the speed is ``w = eta + rate (tau - tau0)``, the phase its exact
    integral ``p = eta tau + phi0 + rate (tau - tau0)^2 / 2``, and the force
    ``e (w^2 (cos p, sin p) + rate (sin p, -cos p))``: the second term is the tangential
    inertia of the unbalance while the speed changes (docs/runup.md).
    """
    if rate == 0.0:
        phase = eta * tau + phi0
        return E * np.cos(phase), E * np.sin(phase)
    d = tau - tau0
    phase = eta * tau + phi0 + 0.5 * rate * d * d
    w = eta + rate * d
    c, sn = np.cos(phase), np.sin(phase)
    return e * (w * w * c + rate * sn), e * (w * w * sn - rate * c)


def stick_friction_value(
    tau: FloatOrArray,
    x: FloatOrArray,
    y: FloatOrArray,
    vx: FloatOrArray,
    vy: FloatOrArray,
    nu: float,
    eta: float,
    E: float,
    phi0: float,
    e: float = 0.0,
    rate: float = 0.0,
    tau0: float = 0.0,
    Rp: float = 0.0,
) -> FloatOrArray:
    """``stick_friction`` from scalars or arrays (compilable core); ``e``, ``rate``,
    ``tau0``, ``Rp`` are read only while the speed changes (``unbalance_value``)."""
    r = np.hypot(x, y)
    r_dot = (x * vx + y * vy) / r
    r_theta_dot = (x * vy - y * vx) / r
    theta_dot = r_theta_dot / r
    if rate == 0.0:
        phase = eta * tau + phi0
        sin_rel = (np.sin(phase) * x - np.cos(phase) * y) / r  # sin(phase - theta)
        return E * sin_rel - r_dot * theta_dot - 2.0 * nu * r_theta_dot
    # the unbalance force along theta-hat, and r theta' = -Rp eta(tau) held: its rate
    # -Rp rate is a tangential acceleration the friction must supply
    fx, fy = unbalance_value(tau, eta, E, phi0, e, rate, tau0)
    return (fy * x - fx * y) / r - r_dot * theta_dot - 2.0 * nu * r_theta_dot + Rp * rate


def stick_friction(
    tau: FloatOrArray,
    x: FloatOrArray,
    y: FloatOrArray,
    vx: FloatOrArray,
    vy: FloatOrArray,
    params: ModelParams,
) -> FloatOrArray:
    """Tangential force T = mu_eq K (z - 1) that holds v_r constant (notes section 4).

    From the polar equations with (r theta')' = 0:
    ``T = E sin(eta tau + phi0 - theta) - r' theta' - 2 nu r theta'``. Positive T acts
    like friction opposing positive slip. Rolling holds while ``|T| <= mu K (z - 1)``.
    Works on scalars and arrays. On the general machine the tangential part of
    ``support_extra`` joins the applied force (``stick_friction_record``).
    """
    tau = np.asarray(tau, dtype=float)
    return stick_friction_record(tau, x, y, vx, vy, params_vector(params))


def tangential_force(
    tau: FloatOrArray,
    x: FloatOrArray,
    y: FloatOrArray,
    vx: FloatOrArray,
    vy: FloatOrArray,
    params: ModelParams,
    regime: int | np.ndarray,
) -> FloatOrArray:
    """Signed tangential contact force in each regime (positive opposes positive slip).

    ``mu_c K (z - 1)`` when slipping, the rolling force ``stick_friction`` in stick,
    0 in free flight. ``regime`` may be an array of regime codes.
    """
    regime = np.asarray(regime)
    z = np.hypot(x, y)
    slip = np.where(regime == SLIP_POSITIVE, 1.0, np.where(regime == SLIP_NEGATIVE, -1.0, 0.0))
    out = slip * params.mu * params.K * (z - 1.0)
    stick = regime == STICK
    if np.any(stick):  # evaluated on the stick samples only (z > 1 there, no 0/0 elsewhere)
        if np.ndim(out):
            out = np.array(out, dtype=float)
            tau, x, y, vx, vy = np.broadcast_arrays(tau, x, y, vx, vy)
            out[stick] = stick_friction(tau[stick], x[stick], y[stick], vx[stick], vy[stick],
                                        params)  # fmt: skip
        else:
            out = stick_friction(tau, x, y, vx, vy, params)
    return out if np.ndim(out) else float(out)


# ------------------------------------------------------------------ right-hand side


def rhs_entries(
    tau: float, x: float, y: float, vx: float, vy: float, nu: float, eta: float, E: float,
    phi0: float, K: float, mu: float, Rp: float, regime: int, e: float = 0.0,
    rate: float = 0.0, tau0: float = 0.0,
) -> tuple[float, float, float, float]:  # fmt: skip
    """``rhs`` from scalars: (vx, vy, ax, ay) (compilable core); ``e``, ``rate``, ``tau0``
    are read only while the speed changes (``unbalance_value``)."""
    if regime == STICK:
        vx, vy = rolling_velocity(x, y, vx, vy, Rp * (eta + rate * (tau - tau0)))
    if rate == 0.0:
        phase = eta * tau + phi0
        fx, fy = E * math.cos(phase), E * math.sin(phase)
    else:
        fx, fy = unbalance_value(tau, eta, E, phi0, e, rate, tau0)
    ax = fx - 2.0 * nu * vx - x
    ay = fy - 2.0 * nu * vy - y
    if regime == STICK:
        # normal force K (z - 1) along -r_hat, rolling friction T along -theta_hat
        z = math.hypot(x, y)
        normal = K * (z - 1.0) / z
        T = stick_friction_value(tau, x, y, vx, vy, nu, eta, E, phi0, e, rate, tau0, Rp)
        tangential = T / z
        ax -= normal * x - tangential * y
        ay -= normal * y + tangential * x
    elif regime != FREE:
        mu_c = mu * friction_sign(regime)
        factor = K * (1.0 - 1.0 / math.hypot(x, y))
        ax -= factor * (x - mu_c * y)
        ay -= factor * (y + mu_c * x)
    return vx, vy, ax, ay


def rhs_jacobian_array(
    tau: float, x: float, y: float, vx: float, vy: float, nu: float, eta: float, E: float,
    phi0: float, K: float, mu: float, Rp: float, regime: int,
) -> np.ndarray:  # fmt: skip
    """``rhs_jacobian`` from scalars in free flight and in slip (compilable core; stick,
    which has no closed form kept for the rolling law, is ``rhs_jacobian_record``'s
    central differences)."""
    jac = np.zeros((4, 4))
    jac[0, 2] = 1.0
    jac[1, 3] = 1.0
    jac[2, 0] = -1.0
    jac[3, 1] = -1.0
    jac[2, 2] = -2.0 * nu
    jac[3, 3] = -2.0 * nu
    if regime == STICK:
        raise ValueError("rhs_jacobian_array: stick is rhs_jacobian_record's")
    elif regime != FREE:
        mu_c = mu * friction_sign(regime)
        j00, j01, j10, j11 = force_jacobian_entries(x, y, mu_c)
        jac[2, 0] -= K * j00
        jac[2, 1] -= K * j01
        jac[3, 0] -= K * j10
        jac[3, 1] -= K * j11
    return jac


def is_general_record(pars: np.ndarray | tuple[float, ...]) -> bool:
    """Whether a record holds a general machine (its ``general`` entry): on the paper's
    machine ``support_extra`` is 0 and is skipped (compilable core)."""
    return pars[P_GENERAL] != 0.0


def is_paper_record(pars: np.ndarray | tuple[float, ...]) -> bool:
    """Whether a record holds the paper's machine at a constant speed: no general
    machine's terms and no speed rate, so the kernels built without them (the compiled
    stages, the stick step and its pre-check) may run it (compilable core)."""
    return pars[P_RATE] == 0.0 and pars[P_GENERAL] == 0.0


def add_support_extra(
    x: float, y: float, vx: float, vy: float, ax: float, ay: float,
    pars: np.ndarray | tuple[float, ...], regime: int,
) -> tuple[float, float]:  # fmt: skip
    """The paper machine's acceleration ``(ax, ay)`` with the general machine's
    ``support_extra`` added (compilable core). ``(vx, vy)`` is the velocity the law was
    evaluated at (projected in stick). In stick the rolling constraint fixes the
    tangential acceleration: the friction takes up the extra force's tangential part, so
    only its normal part is added. Skipped on the paper's machine (``is_general_record``)."""
    if not is_general_record(pars):
        return ax, ay
    ex, ey = support_extra(x, y, vx, vy, pars)
    if regime == STICK:
        tangential = (ey * x - ex * y) / (x * x + y * y)
        ex += tangential * y
        ey -= tangential * x
    return ax + ex, ay + ey


def rhs_record(
    tau: float, x: float, y: float, vx: float, vy: float, pars: np.ndarray | tuple[float, ...],
    regime: int,
) -> tuple[float, float, float, float]:  # fmt: skip
    """The regime-locked right-hand side of the general machine, with the parameters from
    a record (``params_vector``): ``rhs_entries`` plus ``support_extra``. Compilable
    core."""
    vx, vy, ax, ay = rhs_entries(
        tau, x, y, vx, vy, pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0], pars[P_K],
        pars[P_MU], pars[P_RP], regime, pars[P_ECC], pars[P_RATE], pars[P_TAU0],
    )  # fmt: skip
    ax, ay = add_support_extra(x, y, vx, vy, ax, ay, pars, regime)
    return vx, vy, ax, ay


def rhs_jacobian_record(
    tau: float, x: float, y: float, vx: float, vy: float, pars: np.ndarray, regime: int
) -> np.ndarray:
    """The Jacobian of ``rhs_record`` (compilable core): ``rhs_jacobian_array`` with the
    general machine's linear terms, and in stick central differences of ``rhs_record``."""
    if regime == STICK:
        jac = np.zeros((4, 4))
        s = np.array([x, y, vx, vy])
        for j in range(4):
            step = 1e-7 * max(1.0, abs(s[j]))
            sp = s.copy()
            sm = s.copy()
            sp[j] += step
            sm[j] -= step
            fp = rhs_record(tau, sp[0], sp[1], sp[2], sp[3], pars, STICK)
            fm = rhs_record(tau, sm[0], sm[1], sm[2], sm[3], pars, STICK)
            for i in range(4):
                jac[i, j] = (fp[i] - fm[i]) / (2 * step)
        return jac
    jac = rhs_jacobian_array(
        tau, x, y, vx, vy, pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0], pars[P_K],
        pars[P_MU], pars[P_RP], regime,
    )  # fmt: skip
    if is_general_record(pars):
        subtract_support(jac, pars)
    return jac


def stick_friction_record(
    tau: FloatOrArray, x: FloatOrArray, y: FloatOrArray, vx: FloatOrArray, vy: FloatOrArray,
    pars: np.ndarray | tuple[float, ...],
) -> FloatOrArray:  # fmt: skip
    """``stick_friction_value`` of the general machine, from a record (compilable core;
    scalars or arrays): the paper's rolling force plus the tangential part of
    ``support_extra``, which the friction must also hold."""
    T = stick_friction_value(
        tau, x, y, vx, vy, pars[P_NU], pars[P_ETA], pars[P_E], pars[P_PHI0], pars[P_ECC],
        pars[P_RATE], pars[P_TAU0], pars[P_RP],
    )  # fmt: skip
    if not is_general_record(pars):
        return T
    ex, ey = support_extra(x, y, vx, vy, pars)
    return T + (ey * x - ex * y) / np.hypot(x, y)


def zero_slip_regime_record(
    tau: float, x: float, y: float, vx: float, vy: float, pars: np.ndarray | tuple[float, ...]
) -> int:
    """Filippov's rule at v_r = 0 on the general machine (``regime_at_zero_slip``;
    compilable core)."""
    needed = stick_friction_record(tau, x, y, vx, vy, pars)
    return filippov_regime(needed, pars[P_MU] * pars[P_K] * (math.hypot(x, y) - 1.0))


def _rhs_args(tau, s, params: ModelParams, regime: int):
    return (
        float(tau),
        float(s[0]),
        float(s[1]),
        float(s[2]),
        float(s[3]),
        params_vector(params),
        int(regime),
    )


def rhs(
    tau: float, s: Sequence[float] | np.ndarray, params: ModelParams, regime: int
) -> np.ndarray:
    """Right-hand side in a fixed regime (regime-locked, smooth in s).

    In a contact regime the contact law is applied whatever z is (its smooth extension),
    so a solver that stops at the events z = 1 and v_r = 0 never steps across a kink.
    In stick the law is evaluated on the state projected to rolling (``project_to_rolling``).
    """
    return np.array(rhs_record(*_rhs_args(tau, s, params, regime)))


def rhs_jacobian(
    tau: float, s: Sequence[float] | np.ndarray, params: ModelParams, regime: int
) -> np.ndarray:
    """Jacobian of ``rhs`` with respect to the state (for implicit solvers)."""
    return rhs_jacobian_record(*_rhs_args(tau, s, params, regime))


def entry_regime_value(x: float, y: float, vx: float, vy: float, mu: float, spin: float) -> int:
    """The slip direction a contact starts in: the sign of v_r (compilable core)."""
    if mu == 0.0:
        return SLIP_POSITIVE
    return SLIP_POSITIVE if slip_velocity_value(x, y, vx, vy, spin) >= 0.0 else SLIP_NEGATIVE


def zero_slip_regime_value(
    tau: float, x: float, y: float, vx: float, vy: float, nu: float, eta: float, E: float,
    phi0: float, K: float, mu: float, e: float = 0.0, rate: float = 0.0, tau0: float = 0.0,
    Rp: float = 0.0,
) -> int:  # fmt: skip
    """``regime_at_zero_slip`` from scalars: Filippov's rule (compilable core)."""
    needed = stick_friction_value(tau, x, y, vx, vy, nu, eta, E, phi0, e, rate, tau0, Rp)
    return filippov_regime(needed, mu * K * (math.hypot(x, y) - 1.0))


def filippov_regime(needed: float, limit: float) -> int:
    """Filippov's rule at v_r = 0 from the friction ``needed`` to hold it and the cone's
    ``limit`` (``regime_at_zero_slip``; compilable core)."""
    if needed > limit:
        return SLIP_POSITIVE
    if needed < -limit:
        return SLIP_NEGATIVE
    return STICK


def regime_of_state(
    s: Sequence[float] | np.ndarray, params: ModelParams, tau: float | None = None
) -> int:
    """The regime a state is in by position and slip (z > 1 means contact; v_r = 0 may stick)."""
    x, y, vx, vy = s[0], s[1], s[2], s[3]
    if math.hypot(x, y) <= 1.0:
        return FREE
    if params.mu == 0.0:
        return SLIP_POSITIVE
    tau = params.tau0 if tau is None else tau
    spin = params.spin(tau)
    v_r = slip_velocity_value(x, y, vx, vy, spin)
    if abs(v_r) <= 1e-12 * (1.0 + abs(spin)):
        return regime_at_zero_slip(tau, s, params)
    return SLIP_POSITIVE if v_r >= 0.0 else SLIP_NEGATIVE


def regime_at_zero_slip(tau: float, s: Sequence[float] | np.ndarray, params: ModelParams) -> int:
    """Regime of a contact state with v_r = 0 (notes section 4), by Filippov's rule.

    With T the friction needed to hold v_r = 0 and L = mu K (z - 1) the friction limit,
    slip+ (friction -L) gives dv_r/dtau = T - L and slip- gives T + L. A slip direction
    is taken only if v_r leaves zero in it: slip+ if T > L, slip- if T < -L; otherwise
    neither is consistent and the rotor sticks (rolls).
    """
    return zero_slip_regime_record(
        float(tau), float(s[0]), float(s[1]), float(s[2]), float(s[3]), params_vector(params)
    )


def project_to_rolling(
    s: ArrayLike, params: ModelParams, tau: FloatOrArray | None = None
) -> np.ndarray:
    """The state with its tangential velocity set so that v_r = 0 exactly (r theta' = -Rp eta).

    In stick the tangential velocity is fixed by the rolling constraint, not a free
    state: the stick law is evaluated on the projected state, stick samples are reported
    projected, and the state is projected at stick entry and exit, so integration drift
    in v_r is neither fed back nor read as a new slip reversal. Shape (4,) or (4, n);
    ``tau`` (a time or one per column) matters only while the speed changes.
    """
    s = np.asarray(s, dtype=float)
    x, y, vx, vy = s
    spin = params.Rp * params.eta if params.rate == 0.0 else params.spin(tau)
    vx, vy = rolling_velocity(x, y, vx, vy, spin)
    return np.array([x, y, vx, vy])


def rolling_velocity(
    x: FloatOrArray, y: FloatOrArray, vx: FloatOrArray, vy: FloatOrArray, spin: float
) -> tuple[FloatOrArray, FloatOrArray]:
    """Velocity with its radial part kept and r theta' = -spin (compilable core)."""
    r = np.hypot(x, y)
    radial = (x * vx + y * vy) / r
    tangential = -spin
    return (radial * x - tangential * y) / r, (radial * y + tangential * x) / r


def rolling_whirl_radius(params: ModelParams) -> float:
    """Radius of the exact rolling backward whirl without unbalance (e = 0; notes 4).

    w = r exp(-i (Rp eta / r) tau) rolls without slip when
    (1 + K) r^2 - K r - (Rp eta)^2 = 0; it needs the friction T = 2 nu Rp eta, so it
    sticks while 2 nu Rp eta <= mu K (r - 1).
    """
    K, spin = params.K, params.Rp * params.eta
    return (K + math.sqrt(K * K + 4.0 * (1.0 + K) * spin * spin)) / (2.0 * (1.0 + K))


# ------------------------------------------------------------------ polar form


def polar_entries(
    x: FloatOrArray, y: FloatOrArray, vx: FloatOrArray, vy: FloatOrArray
) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray, FloatOrArray]:
    """(r, theta, r', theta') from (x, y, vx, vy), scalars or arrays (compilable core)."""
    r = np.hypot(x, y)
    return r, np.arctan2(y, x), (x * vx + y * vy) / r, (x * vy - y * vx) / (r * r)


def cartesian_entries(
    r: FloatOrArray, theta: FloatOrArray, u: FloatOrArray, omega: FloatOrArray
) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray, FloatOrArray]:
    """(x, y, vx, vy) from (r, theta, r', theta'), scalars or arrays (compilable core)."""
    c = np.cos(theta)
    sn = np.sin(theta)
    return r * c, r * sn, u * c - r * omega * sn, u * sn + r * omega * c


def to_polar(s: ArrayLike) -> np.ndarray:
    """(x, y, vx, vy) -> (r, theta, r', theta'); shape (4,) or (4, n)."""
    x, y, vx, vy = np.asarray(s, dtype=float)
    return np.array(polar_entries(x, y, vx, vy))


def from_polar(p: ArrayLike) -> np.ndarray:
    """(r, theta, r', theta') -> (x, y, vx, vy); shape (4,) or (4, n)."""
    r, theta, u, omega = np.asarray(p, dtype=float)
    return np.array(cartesian_entries(r, theta, u, omega))


def polar_rhs_entries(
    tau: float, r: float, theta: float, u: float, omega: float, nu: float, eta: float,
    E: float, phi0: float, K: float, mu_c: float,
) -> tuple[float, float, float, float]:  # fmt: skip
    """``polar_rhs`` from scalars: (r', theta', r'', theta'') (compilable core)."""
    psi = eta * tau + phi0 - theta
    r_acc = r * omega * omega - 2.0 * nu * u - r - K * (r - 1.0) + E * math.cos(psi)
    tangential = -2.0 * u * omega - 2.0 * nu * r * omega - mu_c * K * (r - 1.0)
    return u, omega, r_acc, (tangential + E * math.sin(psi)) / r


def polar_jacobian_arrays(
    tau: float, r: float, theta: float, u: float, omega: float, nu: float, eta: float,
    E: float, phi0: float, K: float, mu_c: float,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """``(J, f_tau)`` of ``polar_jacobian`` from scalars (compilable core)."""
    psi = eta * tau + phi0 - theta
    sin_psi = math.sin(psi)
    cos_psi = math.cos(psi)
    numerator = -2.0 * u * omega - 2.0 * nu * r * omega - mu_c * K * (r - 1.0) + E * sin_psi
    J = np.zeros((4, 4))
    J[0, 2] = 1.0
    J[1, 3] = 1.0
    J[2, 0] = omega * omega - 1.0 - K
    J[2, 1] = E * sin_psi
    J[2, 2] = -2.0 * nu
    J[2, 3] = 2.0 * r * omega
    J[3, 0] = (-2.0 * nu * omega - mu_c * K) / r - numerator / (r * r)
    J[3, 1] = -E * cos_psi / r
    J[3, 2] = -2.0 * omega / r
    J[3, 3] = -2.0 * (u + nu * r) / r
    f_tau = np.zeros(4)
    f_tau[2] = -E * eta * sin_psi
    f_tau[3] = E * eta * cos_psi / r
    return J, f_tau


def _polar_args(tau, p, params: ModelParams, mu_c: float):
    nu, eta, E, phi0, K = params_vector(params)[:5]
    r, theta, u, omega = (float(v) for v in p)
    return float(tau), r, theta, u, omega, nu, eta, E, phi0, K, float(mu_c)


def polar_rhs(
    tau: float, p: Sequence[float] | np.ndarray, params: ModelParams, mu_c: float
) -> np.ndarray:
    """Contact equations in polar form (notes section 1), slipping with friction mu_c.

    r'' = r theta'^2 - 2 nu r' - r - K (r - 1) + E cos(psi)
    theta'' = (-2 r' theta' - 2 nu r theta' - mu_c K (r - 1) + E sin(psi)) / r,
    psi = eta tau + phi0 - theta. K enters only linearly in r - 1.
    """
    return np.array(polar_rhs_entries(*_polar_args(tau, p, params, mu_c)))


def polar_jacobian(
    tau: float, p: Sequence[float] | np.ndarray, params: ModelParams, mu_c: float
) -> tuple[np.ndarray, np.ndarray]:
    """(J, f_tau): Jacobian of ``polar_rhs`` in (r, theta, r', theta') and its tau-derivative."""
    return polar_jacobian_arrays(*_polar_args(tau, p, params, mu_c))


# ------------------------------------------------------------------ exact solutions


def free_steady_state(
    tau: FloatOrArray, params: ModelParams
) -> tuple[ComplexOrArray, ComplexOrArray]:
    """Steady free whirl (notes 5): w_p = E exp(i(eta tau + phi0)) / (1 - eta^2 + 2 i nu eta).

    Returns complex position and complex velocity (arrays or scalars). At the undamped
    exact resonance the secular particular solution is returned instead.
    """
    tau = np.asarray(tau, dtype=float)
    return free_steady_value(tau, params.nu, params.eta, params.E, params.phi0)


def free_steady_value(
    tau: FloatOrArray, nu: float, eta: float, E: float, phi0: float
) -> tuple[ComplexOrArray, ComplexOrArray]:
    """``free_steady_state`` from scalars, tau a scalar or an array (compilable core)."""
    denom = complex(1.0 - eta**2, 2.0 * nu * eta)
    rot = np.exp(1j * (eta * tau + phi0))
    if denom == 0.0:
        # Undamped exact resonance (nu = 0, eta = 1): w_p = (E / 2i) tau exp(i(tau + phi0)).
        w = E / 2j * tau * rot
        return w, E / 2j * rot * (1.0 + 1j * tau)
    w = E / denom * rot
    return w, 1j * eta * w


def damped_basis(dt: FloatOrArray, nu: float) -> tuple[FloatOrArray, FloatOrArray]:
    """C(t) = cos(beta t), S(t) = sin(beta t)/beta with beta^2 = 1 - nu^2, for any nu >= 0;
    dt a scalar or an array (compilable core).

    Written so that over-damped (nu > 1) and critically damped (nu = 1) rotors work too.
    """
    beta2 = 1.0 - nu * nu
    if beta2 > 0.0:
        beta = math.sqrt(beta2)
        return np.cos(beta * dt), np.sin(beta * dt) / beta
    if beta2 < 0.0:
        kappa = math.sqrt(-beta2)
        return np.cosh(kappa * dt), np.sinh(kappa * dt) / kappa
    return 0.0 * dt + 1.0, dt + 0.0


def free_flight_value(
    tau: FloatOrArray, tau0: float, d0: complex, dv0: complex, nu: float, eta: float, E: float,
    phi0: float,
) -> tuple[ComplexOrArray, ComplexOrArray]:  # fmt: skip
    """(w, v) = (x + i y, vx + i vy) at tau (a scalar or an array) of the free flight
    whose homogeneous part is d0, dv0 at tau0 (the start minus ``free_steady_value``
    there): eq. (7-8) with exp(-nu tau), correction 4 (compilable core)."""
    dt = tau - tau0
    C, S = damped_basis(dt, nu)
    decay = np.exp(-nu * dt)
    wh = decay * (d0 * C + (dv0 + nu * d0) * S)
    vh = decay * (dv0 * C - (d0 + nu * dv0) * S)
    wp, vp = free_steady_value(tau, nu, eta, E, phi0)
    return wp + wh, vp + vh


def free_flight(
    tau: FloatOrArray, tau0: float, s0: Sequence[float] | np.ndarray, params: ModelParams
) -> np.ndarray:
    """Closed-form free flight (eq. 7-8, with exp(-nu tau), correction 4).

    The state at times ``tau`` (scalar or array) of the linear no-contact system started
    from ``s0`` at ``tau0``. Exact for all time; shape (4,) or (4, n).
    """
    w0 = complex(s0[0], s0[1])
    v0 = complex(s0[2], s0[3])
    wp0, vp0 = free_steady_state(tau0, params)
    d0, dv0 = w0 - complex(wp0), v0 - complex(vp0)
    p = params
    tau = np.asarray(tau, dtype=float)
    w, v = free_flight_value(tau, tau0, d0, dv0, p.nu, p.eta, p.E, p.phi0)
    return np.array([np.real(w), np.imag(w), np.real(v), np.imag(v)])


def synchronous_rub_radii(params: ModelParams) -> list[float]:
    """Radii r > 1 of the synchronous forward full annular rub (notes section 5).

    Solves (a r - K)^2 + (b r - mu K)^2 = E^2 with a = 1 - eta^2 + K,
    b = 2 nu eta + mu K; returns the roots greater than 1, ascending (may be empty or two).
    Written in delta = r - 1, where a r - K = a delta + (1 - eta^2) and
    b r - mu K = b delta + 2 nu eta, and solved with the cancellation-free quadratic
    formula: the form in r loses ~K * 1e-16 relative accuracy (9e-6 at K = 1.75e6).
    """
    K, mu, E = params.K, params.mu, params.E
    a = 1.0 - params.eta**2 + K
    b = 2.0 * params.nu * params.eta + mu * K
    c1, c2 = 1.0 - params.eta**2, 2.0 * params.nu * params.eta
    qa = a * a + b * b
    qb = 2.0 * (a * c1 + b * c2)
    qc = c1 * c1 + c2 * c2 - E * E
    disc = qb * qb - 4.0 * qa * qc
    if disc < 0.0:
        return []
    q = -0.5 * (qb + math.copysign(math.sqrt(disc), qb))
    deltas = {q / qa} if q == 0.0 else {q / qa, qc / q}
    return sorted(1.0 + d for d in deltas if d > 0.0)


def synchronous_rub_amplitude(r: float, params: ModelParams) -> complex:
    """Complex amplitude A of w = A exp(i eta tau) on the synchronous rub of radius r."""
    denom = complex(1.0 - params.eta**2, 2.0 * params.nu * params.eta) + params.K * (
        1.0 - 1.0 / r
    ) * complex(1.0, params.mu)
    return params.E * cmath.exp(1j * params.phi0) / denom


def synchronous_rub(tau: FloatOrArray, params: ModelParams, r: float | None = None) -> np.ndarray:
    """Exact synchronous forward full annular rub w = A exp(i eta tau): states, shape (4, n).

    ``r`` defaults to the largest admissible radius. Valid only while v_r > 0 on it
    (forward slip, mu_c = +mu), which ``synchronous_rub_is_forward`` checks.
    """
    if r is None:
        radii = synchronous_rub_radii(params)
        if not radii:
            raise ValueError("these parameters have no synchronous full annular rub (r > 1)")
        r = radii[-1]
    A = synchronous_rub_amplitude(r, params)
    w = A * np.exp(1j * params.eta * np.asarray(tau, dtype=float))
    v = 1j * params.eta * w
    return np.array([np.real(w), np.imag(w), np.real(v), np.imag(v)])


def synchronous_rub_is_forward(r: float, params: ModelParams) -> bool:
    """True when the slip on the synchronous rub is positive (Rp eta + r eta > 0)."""
    return params.Rp * params.eta + r * params.eta > 0.0

"""The method registry: what each method is, as data.

Every method is one ``MethodSpec``, built by keyword: its name, its family (the module
that runs it), the setting that tunes its accuracy (``knob``: ``rtol`` for the
error-controlled integrators, ``steps_per_period`` for the fixed-step analytic methods),
its typed options (``StepOptions``, ``ToleranceOptions``, ``CompiledOptions``: every field
checked on construction), its order, whether it uses the Jacobian, and a one-line summary.
Everything that needs to know about methods derives from this table: the case schema's
list of method names (``rubcli.case``), the family module ``solve`` imports, the
work-precision ladders (``analysis.accuracy.work_precision.ladder``), the stress suite's variants,
the scipy methods' Jacobian, ``solve``'s options (``method_options``: an option the
method does not take is a ``TypeError`` naming it; a value out of its domain a
``ValueError``), ``options_for`` (a settings dict cut down to one method's options) and
the method table of docs/solvers.md (tests/test_registry.py).

This module is data only: it imports nothing heavy, so that the case schema can use it
without loading numba or scipy. The solver functions register themselves against these
names here (``register``, into ``REGISTERED``), apart from ``rubcli.solvers.solve``, which
runs them; a name registered without a spec, or a spec without a solver, is an error
found by tests/test_case.py.

To add a method: add its spec here, write its stepper (docs/solvers.md, "How a method
plugs in"), and register the solver function under the same name.
"""

from __future__ import annotations

import difflib
import importlib
import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rubcli.problem import Problem
    from rubcli.solution import Solution

RTOL, STEPS_PER_PERIOD = "rtol", "steps_per_period"
# The smallest tolerances a method takes. Below MIN_RTOL a step's relative error is
# round-off (scipy raises its rtol to 100 eps, 2.2e-14, itself; [orbits] rtol has the
# same floor). Below MIN_ATOL the error norms divide by a scale that underflows (atol =
# 5e-324: a ZeroDivisionError in dop853-jit, radau's error norm infinite, lsoda stuck at
# its first step): 1 / atol stays within the model's domain, 1e100, as 1 / eta does.
MIN_RTOL = 1e-14
MIN_ATOL = 1e-100


@dataclass(frozen=True, kw_only=True)
class Options:
    """What every method takes: its budgets, the compiled switch and a progress callback
    of tau. Each field is checked on construction (``option_problem``): a TypeError or
    ValueError naming the option."""

    max_steps: int = 5_000_000
    max_wall_time_s: float = 600.0
    compiled: bool = True  # False: the pure-Python path (taylor: the Python event code)
    progress: Callable[[float], None] | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            found = option_problem(f.name, getattr(self, f.name))
            if found is not None:
                kind, why = found
                raise kind(f"solve(): option {f.name} {why}")

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))


@dataclass(frozen=True, kw_only=True)
class StepOptions(Options):
    """The analytic methods': fixed steps of period / steps_per_period in contact, or
    adaptive steps by step doubling to ``analytic_tol`` (steps_per_period sets the first)."""

    steps_per_period: int = 400
    analytic_tol: float | None = None


@dataclass(frozen=True, kw_only=True)
class ToleranceOptions(Options):
    """The error-controlled integrators': relative and absolute local error per step."""

    rtol: float = 1e-8
    atol: float = 1e-10


@dataclass(frozen=True, kw_only=True)
class CompiledOptions(ToleranceOptions):
    """The compiled loops': ``compiled_events=False`` hands every step where an event is
    possible to the Python event code (a check of the compiled one)."""

    compiled_events: bool = True


@dataclass(frozen=True, kw_only=True)
class MethodSpec:
    """One method, as data."""

    name: str
    family: str  # the module that runs it: a key of FAMILY_MODULES
    knob: str  # the accuracy setting a work-precision ladder varies: RTOL or STEPS_PER_PERIOD
    options: type[Options]  # its typed options
    order: int | None  # its (highest) global order; None: set by the tolerance (taylor)
    implicit: bool  # uses the Jacobian of the right-hand side (stiff-capable)
    adaptive: str | None  # the option that switches on adaptive steps, if the knob is not one
    summary: str
    # what the method runs beyond the paper's machine at constant speed (FEATURES)
    features: frozenset[str] = frozenset()

    @property
    def takes(self) -> tuple[str, ...]:
        """Every option ``solve`` accepts for this method."""
        return self.options.names()


# The module of each family: it registers the family's solver functions (``register``).
FAMILY_MODULES = {
    "analytic": "rubcli.solvers.analytic",
    "scipy": "rubcli.solvers.scipy_ivp",
    "compiled-rk": "rubcli.solvers.dop853_jit",
    "compiled-taylor": "rubcli.solvers.taylor",
}


# Features of a machine or a run that not every method supports, with why a method
# without it refuses: the case validation and ``solve`` derive their refusals from here.
SPEED_PROFILE = "speed profile"
DRIVEN = "driven rotor"
GENERAL_MACHINE = "general machine"
MOVING_STATOR = "moving stator"
FEATURES = {
    SPEED_PROFILE: "a speed that changes in time ([speed])",
    DRIVEN: "a driven rotor (the speed a state, [speed] profile = 'driven')",
    GENERAL_MACHINE: "the general machine (an offset stator, a static load, anisotropic or "
    "cross-coupled supports: [model] offset, load, stiffness, damping)",
    MOVING_STATOR: "a stator with its own mass on its own supports ([stator])",
}
# why the methods without a feature lack it (named in the refusal)
LACKS = {
    ("analytic", SPEED_PROFILE): "its closed forms assume a constant speed",
    ("analytic-polar", SPEED_PROFILE): "its closed forms assume a constant speed",
    ("analytic", DRIVEN): "its closed forms assume a constant speed",
    ("analytic-polar", DRIVEN): "its closed forms assume a constant speed",
    ("analytic-polar", GENERAL_MACHINE): "its polar form needs a concentric stator and an "
    "isotropic support",
    ("analytic-polar", MOVING_STATOR): "its polar form needs a rigid concentric stator",
}


def _scipy(name: str, order: int, implicit: bool, summary: str) -> MethodSpec:
    return MethodSpec(
        name=name, family="scipy", knob=RTOL, options=ToleranceOptions, order=order,
        implicit=implicit, adaptive=None, summary=summary,
        features=frozenset({SPEED_PROFILE, DRIVEN, GENERAL_MACHINE, MOVING_STATOR}),
    )  # fmt: skip


SPECS: dict[str, MethodSpec] = {
    spec.name: spec
    for spec in (
        MethodSpec(
            name="analytic",
            family="analytic",
            knob=STEPS_PER_PERIOD,
            options=StepOptions,
            order=2,
            implicit=False,
            adaptive="analytic_tol",
            summary="the paper's method: closed-form free flight, first-order Taylor "
            "linearisation of the contact force in Cartesian coordinates each step, solved "
            "exactly",
            features=frozenset({GENERAL_MACHINE, MOVING_STATOR}),
        ),
        MethodSpec(
            name="analytic-polar",
            family="analytic",
            knob=STEPS_PER_PERIOD,
            options=StepOptions,
            order=2,
            implicit=False,
            adaptive="analytic_tol",
            summary="the same scheme with the contact phase locally linearised in polar "
            "coordinates, where `K` is linear",
        ),
        _scipy(
            "rk45",
            5,
            False,
            "scipy RK45, Dormand-Prince 5(4) (error estimate of order "
            "4): MATLAB's ODE45, the paper's reference",
        ),
        _scipy("dop853", 8, False, "scipy DOP853, Dormand-Prince 8(5,3)"),
        _scipy("radau", 5, True, "scipy Radau IIA, implicit, L-stable"),
        _scipy("bdf", 5, True, "scipy BDF, implicit multistep, variable order 1-5"),
        _scipy(
            "lsoda",
            12,
            True,
            "scipy LSODA (ODEPACK), switching between Adams (orders 1-12) and BDF (1-5)",
        ),
        MethodSpec(
            name="dop853-jit",
            family="compiled-rk",
            knob=RTOL,
            options=CompiledOptions,
            order=8,
            implicit=False,
            adaptive=None,
            summary="scipy's DOP853, step for step, with the step loop compiled (numba)",
            features=frozenset({SPEED_PROFILE, DRIVEN, GENERAL_MACHINE, MOVING_STATOR}),
        ),
        MethodSpec(
            name="taylor",
            family="compiled-taylor",
            knob=RTOL,
            options=CompiledOptions,
            order=None,
            implicit=False,
            adaptive=None,
            summary="adaptive Taylor series of the rub equations (automatic-differentiation "
            "recurrences, compiled), events on each step's polynomial; order N = "
            "ceil(-0.5 ln rtol) + 6: 13 at 1e-6, 18 at 1e-10",
            features=frozenset({SPEED_PROFILE, DRIVEN, GENERAL_MACHINE, MOVING_STATOR}),
        ),
    )  # fmt: skip
}
NAMES: tuple[str, ...] = tuple(SPECS)
ALL_OPTIONS: tuple[str, ...] = tuple(dict.fromkeys(o for s in SPECS.values() for o in s.takes))


# The solver function of each method, ``fn(problem, options)`` with the method's typed
# options, by name: filled by ``register`` as each family's module is imported (``solve``
# imports the family of the method it runs; ``rubcli.solvers.METHODS``, every family).
SolverFn = Callable[["Problem", Options], "Solution"]
REGISTERED: dict[str, SolverFn] = {}


def register(name: str) -> Callable[[SolverFn], SolverFn]:
    """Register the solver function of the method ``name`` (which must have a spec)."""
    if name not in SPECS:
        raise ValueError(f"method {name!r} has no spec in rubcli/solvers/registry.py")

    def deco(fn: SolverFn) -> SolverFn:
        REGISTERED[name] = fn
        return fn

    return deco


def registered(family: str | None = None) -> dict[str, SolverFn]:
    """The registered solver functions, after importing the modules of ``family`` (every
    family if None; imported once, a no-op afterwards)."""
    for name in FAMILY_MODULES if family is None else (family,):
        importlib.import_module(FAMILY_MODULES[name])
    return REGISTERED


def method_table() -> str:
    """The table of methods in docs/solvers.md (tests/test_registry.py keeps it current)."""
    rows = ["| method | what it is | highest order | settings |", "|---|---|---|---|"]
    for m in SPECS.values():
        order = "from `rtol`" if m.order is None else str(m.order)
        if m.knob == STEPS_PER_PERIOD:
            settings = " or ".join(f"`{k}`" for k in (m.knob, m.adaptive) if k)
        else:
            settings = ", ".join(
                f"`{k}`" for k in m.takes if k in ("rtol", "atol", "compiled_events")
            )
        rows.append(f"| `{m.name}` | {m.summary} | {order} | {settings} |")
    return "\n".join(rows) + "\n"


def unsupported(method: str, feature: str) -> str | None:
    """Why ``method`` cannot run ``feature`` (a key of FEATURES), or None if it can."""
    if feature in spec(method).features:
        return None
    able = ", ".join(n for n, m in SPECS.items() if feature in m.features)
    why = LACKS.get((method, feature), "it does not implement it")
    return f"{method} does not run {FEATURES[feature]}: {why}; use one of {able}"


def spec(name: str) -> MethodSpec:
    """The spec of a method; ValueError naming the known ones if there is none (a
    TypeError if ``name`` is no str)."""
    if not isinstance(name, str):
        raise TypeError(
            f"method must be a method name (a str), got {type(name).__name__}; choose from "
            f"{', '.join(NAMES)}"
        )
    try:
        return SPECS[name]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(NAMES)}") from None


def options_for(method: str, options: dict) -> dict:
    """The entries of ``options`` that ``method`` takes (the others are dropped).

    The documented way to drive several methods from one settings dict (a case's [solver]
    table): ``solve(problem, m, **options_for(m, settings))``. ``solve`` itself refuses an
    option its method does not take.
    """
    takes = spec(method).takes
    return {k: v for k, v in options.items() if k in takes}


def method_options(method: str, options: dict) -> Options:
    """``options`` as ``method``'s typed options: a TypeError naming every option the
    method does not take (a misspelling, or an option of another method, ``rtol`` given
    to ``analytic``, which would otherwise be dropped without a word), then a TypeError
    or ValueError naming the first value out of its domain."""
    takes = spec(method).takes
    foreign = [k for k in options if k not in takes]
    if foreign:
        names = ", ".join(repr(k) for k in foreign)
        others = sorted(
            {m for k in foreign for m, s in SPECS.items() if k in s.takes and m != method}
        )
        hint = (
            f" ({'it is' if len(foreign) == 1 else 'they are'} an option of "
            f"{', '.join(others)}: for a settings dict shared by several methods, use "
            f"solve(problem, method, **options_for(method, settings)))"
            if others
            else ""
        )
        close = [m for k in foreign for m in difflib.get_close_matches(k, takes, n=1)]
        if close and not others:
            hint = f" (did you mean {', '.join(repr(c) for c in close)}?)"
        raise TypeError(
            f"solve() got option(s) {names} that {method!r} does not take{hint}; "
            f"{method!r} takes {', '.join(takes)}"
        )
    return spec(method).options(**options)


def _is_int(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _is_bool(value) -> bool:
    # numpy's bool too (its type is named bool_ before numpy 2, bool since)
    return isinstance(value, bool) or type(value).__name__ in ("bool", "bool_")


def _finite(value: float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an int beyond the largest double
        return False


def option_problem(name: str, value: object) -> tuple[type[Exception], str] | None:
    """(exception class, why) if ``value`` is not valid for the option ``name``."""
    if name in ("rtol", "analytic_tol"):
        if name == "analytic_tol" and value is None:
            return None
        if not _is_real(value):
            return TypeError, f"must be a real number, got {type(value).__name__}"
        if not (_finite(value) and 0.0 < value < 1.0):
            return ValueError, f"must satisfy 0 < {name} < 1 (got {value!r})"
        if name == "rtol" and value < MIN_RTOL:
            return ValueError, (
                f"must be at least {MIN_RTOL:g} (got {value!r}): below, a step's relative "
                "error is round-off"
            )
    elif name == "atol":
        if not _is_real(value):
            return TypeError, f"must be a real number, got {type(value).__name__}"
        if not (_finite(value) and value > 0.0):
            return ValueError, f"must be finite and > 0 (got {value!r})"
        if value < MIN_ATOL:
            return ValueError, (
                f"must be at least {MIN_ATOL:g} (got {value!r}): a smaller one underflows the "
                "error norms"
            )
    elif name in ("max_steps", "steps_per_period"):
        if not _is_int(value):
            return TypeError, f"must be an int, got {type(value).__name__} {value!r}"
        if value <= 0:
            return ValueError, f"must be > 0 (got {value!r})"
    elif name == "max_wall_time_s":
        if not _is_real(value):
            return TypeError, f"must be a real number, got {type(value).__name__}"
        if not (_finite(value) and value > 0.0):
            return ValueError, f"must be finite and > 0 seconds (got {value!r})"
    elif name in ("compiled", "compiled_events"):
        if not _is_bool(value):
            return TypeError, f"must be True or False, got {type(value).__name__} {value!r}"
    elif name == "progress" and value is not None and not callable(value):
        return TypeError, f"must be a callable of tau (or None), got {type(value).__name__}"
    return None

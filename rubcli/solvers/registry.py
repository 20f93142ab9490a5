"""The method registry: what each method is, as data.

Every method is one ``MethodSpec``: its name, its family, the setting that tunes its
accuracy (``knob``: ``rtol`` for the error-controlled integrators, ``steps_per_period``
for the fixed-step analytic methods), the options it takes, its order and what it can do.
Everything that needs to know about methods derives from this table: the case schema's
list of method names (``rubcli.case``), the work-precision ladders
(``analysis.work_precision.ladder``), the stress suite's variants, ``solve``'s check of
its options (an option the method does not take is a ``TypeError`` naming it; a value
out of its domain a ``ValueError``) and ``options_for`` (a settings dict cut down to one
method's options).

This module is data only: it imports nothing heavy, so that the case schema can use it
without loading numba or scipy. The solver functions register themselves against these
names in ``rubcli.solvers`` (``register``); a name registered without a spec, or a spec
without a solver, is an error found by tests/test_case.py.

To add a method: add its spec here, write its stepper (docs/solvers.md, "How a method
plugs in"), and register the solver function under the same name.
"""

from __future__ import annotations

import difflib
import math
import numbers
from dataclasses import dataclass

# Options every method takes (besides ``progress``, a callback of tau).
COMMON_OPTIONS = ("max_steps", "max_wall_time_s", "compiled")
RTOL, STEPS_PER_PERIOD = "rtol", "steps_per_period"


@dataclass(frozen=True)
class MethodSpec:
    """One method, as data."""

    name: str
    family: str  # "analytic" (closed forms + linearised contact), "scipy", "compiled-rk"
    knob: str  # the accuracy setting a work-precision ladder varies: RTOL or STEPS_PER_PERIOD
    options: tuple[str, ...]  # its own options, besides COMMON_OPTIONS and progress
    order: int | None  # global order in its step (error-controlled: of the scheme; None: set
    # by the tolerance)
    implicit: bool  # uses a Jacobian (stiff-capable in the usual sense)
    compiled: bool  # has a numba path (``compiled=False`` selects the pure-Python one)
    adaptive: str | None  # the option that switches on adaptive steps, if the knob is not one
    summary: str

    @property
    def takes(self) -> tuple[str, ...]:
        """Every option ``solve`` accepts for this method."""
        return COMMON_OPTIONS + self.options + ("progress",)


_ANALYTIC = ("steps_per_period", "analytic_tol")
_TOLERANCES = ("rtol", "atol")

SPECS: dict[str, MethodSpec] = {
    spec.name: spec
    for spec in (
        MethodSpec(
            "analytic",
            "analytic",
            STEPS_PER_PERIOD,
            _ANALYTIC,
            2,
            False,
            True,
            "analytic_tol",
            "the paper's method: closed-form free flight, Cartesian Taylor-linearised contact",
        ),
        MethodSpec(
            "analytic-polar",
            "analytic",
            STEPS_PER_PERIOD,
            _ANALYTIC,
            2,
            False,
            True,
            "analytic_tol",
            "the paper's idea with the contact linearised in polar form (K enters linearly)",
        ),
        MethodSpec(
            "rk45",
            "scipy",
            RTOL,
            _TOLERANCES,
            5,
            False,
            True,
            None,
            "scipy RK45 (Dormand-Prince 5(4), the paper's ODE45) with event restarts",
        ),
        MethodSpec(
            "dop853",
            "scipy",
            RTOL,
            _TOLERANCES,
            8,
            False,
            True,
            None,
            "scipy DOP853 (Hairer's 8(5,3)) with event restarts",
        ),
        MethodSpec(
            "radau",
            "scipy",
            RTOL,
            _TOLERANCES,
            5,
            True,
            True,
            None,
            "scipy Radau IIA (implicit, order 5) with event restarts",
        ),
        MethodSpec(
            "bdf",
            "scipy",
            RTOL,
            _TOLERANCES,
            5,
            True,
            True,
            None,
            "scipy BDF (implicit multistep, orders 1-5) with event restarts",
        ),
        MethodSpec(
            "lsoda",
            "scipy",
            RTOL,
            _TOLERANCES,
            12,
            True,
            True,
            None,
            "scipy LSODA (ODEPACK Adams/BDF switching) with event restarts",
        ),
        MethodSpec(
            "dop853-jit",
            "compiled-rk",
            RTOL,
            _TOLERANCES + ("compiled_events",),
            8,
            False,
            True,
            None,
            "scipy's DOP853 step for step in a numba loop, events located in compiled code",
        ),
        MethodSpec(
            "taylor",
            "compiled-taylor",
            RTOL,
            _TOLERANCES + ("compiled_events",),
            None,
            False,
            True,
            None,
            "adaptive Taylor series (order from rtol) in a numba loop, events on its polynomial",
        ),
    )  # fmt: skip
}
NAMES: tuple[str, ...] = tuple(SPECS)
ALL_OPTIONS: tuple[str, ...] = tuple(dict.fromkeys(o for s in SPECS.values() for o in s.takes))


def spec(name: str) -> MethodSpec:
    """The spec of a method; ValueError naming the known ones if there is none."""
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


def check_options(method: str, options: dict) -> None:
    """TypeError naming every option ``method`` does not take: a misspelling, or an option
    of another method (``rtol`` given to ``analytic``), which would otherwise be dropped
    without a word. Then ``check_option_values``."""
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
    check_option_values(options)


def _is_int(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _is_bool(value) -> bool:
    # numpy's bool too (its type is named bool_ before numpy 2, bool since)
    return isinstance(value, bool) or type(value).__name__ in ("bool", "bool_")


def _option_problem(name: str, value) -> tuple[type[Exception], str] | None:
    """(exception class, why) if ``value`` is not valid for the option ``name``."""
    if name in ("rtol", "analytic_tol"):
        if name == "analytic_tol" and value is None:
            return None
        if not _is_real(value):
            return TypeError, f"must be a real number, got {type(value).__name__}"
        if not (math.isfinite(value) and 0.0 < value < 1.0):
            return ValueError, f"must satisfy 0 < {name} < 1 (got {value!r})"
    elif name == "atol":
        if not _is_real(value):
            return TypeError, f"must be a real number, got {type(value).__name__}"
        if not (math.isfinite(value) and value > 0.0):
            return ValueError, f"must be finite and > 0 (got {value!r})"
    elif name in ("max_steps", "steps_per_period"):
        if not _is_int(value):
            return TypeError, f"must be an int, got {type(value).__name__} {value!r}"
        if value <= 0:
            return ValueError, f"must be > 0 (got {value!r})"
    elif name == "max_wall_time_s":
        if not _is_real(value):
            return TypeError, f"must be a real number, got {type(value).__name__}"
        if not (math.isfinite(value) and value > 0.0):
            return ValueError, f"must be finite and > 0 seconds (got {value!r})"
    elif name in ("compiled", "compiled_events"):
        if not _is_bool(value):
            return TypeError, f"must be True or False, got {type(value).__name__} {value!r}"
    elif name == "progress" and value is not None and not callable(value):
        return TypeError, f"must be a callable of tau (or None), got {type(value).__name__}"
    return None


def check_option_values(options: dict) -> None:
    """TypeError or ValueError naming the first option whose value is out of its domain
    (docs/cases.md, [solver]): tolerances finite with 0 < rtol < 1 and atol > 0, counts
    positive ints, the wall-time budget finite and positive, switches bools, ``progress``
    a callable."""
    for name, value in options.items():
        found = _option_problem(name, value)
        if found is not None:
            kind, why = found
            raise kind(f"solve(): option {name} {why}")

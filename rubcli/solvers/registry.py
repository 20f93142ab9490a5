"""The method registry: what each method is, as data (issue 10).

Every method is one ``MethodSpec``: its name, its family, the setting that tunes its
accuracy (``knob``: ``rtol`` for the error-controlled integrators, ``steps_per_period``
for the fixed-step analytic methods), the options it takes, its order and what it can do.
Everything that needs to know about methods derives from this table: the case schema's
list of method names (``rubcli.case``), the work-precision ladders
(``analysis.work_precision.ladder``), the stress suite's variants, ``solve``'s check of
its options (an option the method does not take is a ``TypeError`` naming it) and
``options_for`` (a settings dict cut down to one method's options).

This module is data only: it imports nothing heavy, so that the case schema can use it
without loading numba or scipy. The solver functions register themselves against these
names in ``rubcli.solvers`` (``register``); a name registered without a spec, or a spec
without a solver, is an error found by tests/test_case.py.

To add a method: add its spec here, write its stepper (docs/solvers.md, "How a method
plugs in"), and register the solver function under the same name.
"""

from __future__ import annotations

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
    order: int  # global order of accuracy in its step (error-controlled: of the scheme)
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

    For settings shared by several methods (a case's [solver] table):
    ``solve(problem, m, **options_for(m, settings))``.
    """
    takes = spec(method).takes
    return {k: v for k, v in options.items() if k in takes}


def check_options(method: str, options: dict) -> None:
    """TypeError naming every option that no method takes (a typo is never dropped).

    An option of another method (``rtol`` given to ``analytic``) is allowed, so that one
    settings dict can drive every method; ``solve`` passes each method only its own.
    """
    spec(method)
    unknown = [k for k in options if k not in ALL_OPTIONS]
    if unknown:
        names = ", ".join(repr(k) for k in unknown)
        raise TypeError(
            f"solve() got unknown option(s) {names}; {method!r} takes "
            f"{', '.join(spec(method).takes)}, and the other methods also "
            f"{', '.join(sorted(set(ALL_OPTIONS) - set(spec(method).takes)))}"
        )

"""Solvers: ``solve(problem, method, **options)`` for every method of the registry.

The methods are described as data in ``registry.py`` (name, family, knob, typed options,
order); each family's module registers its solver functions, ``fn(problem, options)``
with the method's typed options, against those names with ``registry.register`` (the
table of registered functions is the registry's, so a family does not import ``solve``).
A family is imported when one of its methods first runs (every family on first use of
``METHODS``), so that ``rubcli.solvers.registry`` (used by the case schema) stays light.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Iterator
from contextvars import ContextVar
from functools import partial
from typing import TYPE_CHECKING, Any

from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers.registry import (  # noqa: F401
    DRIVEN,
    FAMILY_MODULES,
    GENERAL_MACHINE,
    MOVING_STATOR,
    SPECS,
    SPEED_PROFILE,
    method_options,
    option_problem,
    options_for,
    register,
    registered,
    unsupported,
)

if TYPE_CHECKING:
    from rubcli.solvers.driver import Watch


def __getattr__(name: str) -> Any:
    if name == "METHODS":  # the registered solver functions, by method name
        return registered()
    raise AttributeError(f"module 'rubcli.solvers' has no attribute {name!r}")


def problem_features(problem: Problem) -> list[str]:
    """The features (``registry.FEATURES``) a problem asks of the method that solves it."""
    found = [MOVING_STATOR] if problem.params.stator is not None else []
    if problem.speed is not None:
        found.append(SPEED_PROFILE)
    if problem.drive is not None:
        found.append(DRIVEN)
    if not problem.params.is_paper_machine:
        found.append(GENERAL_MACHINE)
    return found


def solve(problem: Problem, method: str, *, watch: Watch | None = None, **options: Any) -> Solution:
    """Solve ``problem`` with ``method`` (a name of the registry).

    ``watch`` (a ``driver.Watch``) looks at the samples as they are filled and may end
    the run early (attractor recognition in basin sweeps); the solution then holds the
    samples up to that point, with success and the watch's message.

    ``options`` are the method's own (``registry.SPECS[method].takes``): an option it does
    not take (a misspelling, or another method's, e.g. ``rtol`` for ``analytic``) is a
    TypeError naming it, and a value out of its domain (``rtol = nan``, ``max_steps =
    2.5``) a TypeError or ValueError naming it, as ``scipy.integrate.solve_ivp`` does. A
    settings dict shared by several methods goes through ``options_for``:
    ``solve(problem, m, **options_for(m, settings))``. The wall time is measured here.
    """
    if not isinstance(problem, Problem):
        raise TypeError(
            f"solve(): problem must be a rubcli Problem, got {type(problem).__name__}"
            " (build one with Problem(params, initial, t_eval) or Problem.from_periods)"
        )
    if not isinstance(method, str):
        raise TypeError(
            f"solve(): method must be a method name (a str), got {type(method).__name__}; "
            f"choose from {', '.join(SPECS)}"
        )
    if method not in SPECS:
        raise ValueError(f"solve(): unknown method {method!r}; choose from {', '.join(SPECS)}")
    typed = method_options(method, options)
    for feature in problem_features(problem):
        refused = unsupported(method, feature)
        if refused:
            raise ValueError(f"solve(): {refused}")
    if problem.drive is not None and not problem.params.is_paper_machine:
        raise ValueError(
            "solve(): a driven rotor runs on the paper's machine only (the drive's equations, "
            "rubcli.drive, have no offset, static load, anisotropic support or moving stator)"
        )
    if problem.speed is not None and problem.params.stator is not None:
        raise ValueError(
            "solve(): a stator with its own mass runs at a constant speed only (its "
            "equations, rubcli.stator, carry the speed as a constant state)"
        )
    methods = registered(SPECS[method].family)
    if problem.drive is not None:
        from rubcli.solvers.driven import solve_driven

        methods = {method: partial(solve_driven, name=method)}
    elif problem.params.stator is not None:
        from rubcli.solvers.two_body import solve_two_body

        methods = {method: partial(solve_two_body, name=method)}
    deadline = DEADLINE.get()
    if deadline is not None:  # a command's budget: this solve gets at most what is left
        left = max(deadline - time.perf_counter(), LAST_SOLVE_S)
        if left < typed.max_wall_time_s:
            typed = dataclasses.replace(typed, max_wall_time_s=left)
    start = time.perf_counter()
    if watch is None:
        solution = methods[method](problem, typed)
    else:
        from rubcli.solvers.driver import WATCH, Watch

        if not isinstance(watch, Watch):
            raise TypeError(f"solve(): watch must be a rubcli.solvers.driver.Watch, got {watch!r}")
        token = WATCH.set(watch)
        try:
            solution = methods[method](problem, typed)
        finally:
            WATCH.reset(token)
    solution.wall_time_s = time.perf_counter() - start
    return solution


# The deadline (``time.perf_counter()``) of the command whose solves run in this context
# (``wall_time_budget``): every ``solve`` takes the earlier of its own budget and it.
DEADLINE: ContextVar[float | None] = ContextVar("rubcli_deadline", default=None)
# The budget of a solve started at or past the deadline: it stops at its first check.
LAST_SOLVE_S = 1e-3


def wall_time_deadline(name: str, max_wall_time_s: object) -> float | None:
    """The ``time.perf_counter()`` at which a budget of ``max_wall_time_s`` seconds from now
    runs out (None for None: no budget); a TypeError or ValueError naming ``name`` for a
    value that is not a finite number > 0, as ``solve`` checks its own."""
    if max_wall_time_s is None:
        return None
    found = option_problem("max_wall_time_s", max_wall_time_s)
    if found is not None:
        kind, why = found
        raise kind(f"{name}: max_wall_time_s {why}")
    return time.perf_counter() + float(max_wall_time_s)  # type: ignore[arg-type]


@contextlib.contextmanager
def wall_time_budget(deadline: float | None) -> Iterator[None]:
    """Within: every ``solve`` of this context ends by ``deadline`` (``time.perf_counter()``;
    None: no deadline), its ``max_wall_time_s`` cut to the time left (at least
    ``LAST_SOLVE_S``). The caller checks the deadline between its solves
    (``rubcli.analysis.orbits.periodic.check_deadline``): a solve cut short fails as on its own
    budget."""
    token = DEADLINE.set(deadline)
    try:
        yield
    finally:
        DEADLINE.reset(token)


# Bounds of a warm-up solve (``warm_up_options``): enough to load or compile every kernel
# a run reaches, never the run's own budgets (a run of 5e6 steps paid twice).
WARM_UP_MAX_STEPS = 2000
WARM_UP_WALL_TIME_S = 2.0


def warm_up_options(options: dict) -> dict:
    """``options`` with the budgets of a warm-up: at most ``WARM_UP_MAX_STEPS`` steps and
    ``WARM_UP_WALL_TIME_S`` seconds past the kernels' compilation (the budget is checked
    between the compiled chunks, so a first call that compiles ends at its first check)."""
    return {
        **options,
        "max_steps": min(options.get("max_steps", WARM_UP_MAX_STEPS), WARM_UP_MAX_STEPS),
        "max_wall_time_s": min(
            options.get("max_wall_time_s", WARM_UP_WALL_TIME_S), WARM_UP_WALL_TIME_S
        ),
    }

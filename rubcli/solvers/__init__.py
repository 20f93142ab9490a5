"""Solver registry: ``solve(problem, method, **options)`` for every method."""

from __future__ import annotations

import time
from collections.abc import Callable

from rubcli.problem import Problem
from rubcli.solution import Solution

SolverFn = Callable[..., Solution]
METHODS: dict[str, SolverFn] = {}


def register(name: str) -> Callable[[SolverFn], SolverFn]:
    def deco(fn: SolverFn) -> SolverFn:
        METHODS[name] = fn
        return fn

    return deco


# The options each family of methods takes (besides ``progress``). ``options_for`` filters
# a settings dict (e.g. a case's [solver] table) down to what one method uses.
COMMON_OPTIONS = ("max_steps", "max_wall_time_s", "compiled")
_FAMILY_OPTIONS = {
    "analytic": ("steps_per_period", "analytic_tol"),
    "scipy": ("rtol", "atol"),
    "dop853-jit": ("rtol", "atol", "compiled_events"),
    "taylor": ("rtol", "atol", "compiled_events"),
}


def _family(method: str) -> str:
    if method.startswith("analytic"):
        return "analytic"
    return method if method in ("dop853-jit", "taylor") else "scipy"


def options_for(method: str, options: dict) -> dict:
    """The entries of ``options`` that ``method`` uses (the rest would be ignored by it).

    Pass a method only its own options: ``solve(problem, m, **options_for(m, settings))``.
    """
    known = COMMON_OPTIONS + _FAMILY_OPTIONS[_family(method)] + ("progress",)
    return {k: v for k, v in options.items() if k in known}


def solve(problem: Problem, method: str, **options) -> Solution:
    """Solve ``problem`` with ``method`` (a key of ``METHODS``).

    Options by method: scipy methods take ``rtol``, ``atol``, ``max_steps``,
    ``max_wall_time_s``; ``analytic`` takes ``steps_per_period``, ``max_steps``,
    ``max_wall_time_s``. Unknown options are ignored by a method that has no use for
    them, so one settings dict can drive every method. The wall time is measured here.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    start = time.perf_counter()
    solution = METHODS[method](problem, **options)
    solution.wall_time_s = time.perf_counter() - start
    return solution


from rubcli.solvers import analytic, dop853_jit, scipy_ivp, taylor  # noqa: E402,F401  (registers them)

"""Solvers: ``solve(problem, method, **options)`` for every method of the registry.

The methods are described as data in ``registry.py`` (name, knob, options, order,
capabilities); each family's module registers its solver function against those names
with ``register``. The families are imported on first use of ``solve`` or ``METHODS``,
so that ``rubcli.solvers.registry`` (used by the case schema) stays light.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from typing import Any

from rubcli.problem import Problem
from rubcli.solution import Solution
from rubcli.solvers.registry import SPECS, check_options, options_for  # noqa: F401

SolverFn = Callable[..., Solution]
_METHODS: dict[str, SolverFn] = {}
# The modules that register the methods' solver functions.
_FAMILIES = ("rubcli.solvers.analytic", "rubcli.solvers.scipy_ivp", "rubcli.solvers.dop853_jit")


def register(name: str) -> Callable[[SolverFn], SolverFn]:
    """Register the solver function of the method ``name`` (which must have a spec)."""
    if name not in SPECS:
        raise ValueError(f"method {name!r} has no spec in rubcli/solvers/registry.py")

    def deco(fn: SolverFn) -> SolverFn:
        _METHODS[name] = fn
        return fn

    return deco


def _methods() -> dict[str, SolverFn]:
    for module in _FAMILIES:  # (imported once; a no-op afterwards)
        importlib.import_module(module)
    return _METHODS


def __getattr__(name: str) -> Any:
    if name == "METHODS":  # the registered solver functions, by method name
        return _methods()
    raise AttributeError(f"module 'rubcli.solvers' has no attribute {name!r}")


def solve(problem: Problem, method: str, **options) -> Solution:
    """Solve ``problem`` with ``method`` (a name of the registry).

    ``options`` may be a settings dict shared by several methods: the method gets the
    ones it takes (``registry.SPECS[method].takes``); an option that no method takes (a
    misspelling) raises TypeError naming it. The wall time is measured here.
    """
    methods = _methods()
    if method not in methods:
        raise ValueError(f"unknown method {method!r}; choose from {', '.join(methods)}")
    check_options(method, options)
    start = time.perf_counter()
    solution = methods[method](problem, **options_for(method, options))
    solution.wall_time_s = time.perf_counter() - start
    return solution

"""rubcli: a Jeffcott rotor rubbing on a circular stator.

The paper's piecewise analytical solution beside scipy's integrators, one ``solve``
for all of them, and case files that drive the ``rubcli`` command line::

    from rubcli import load_case, solve

    case = load_case("cases/paper/fig3a.toml")
    solution = solve(case.problem, "analytic", steps_per_period=400)

Periodic orbits and their continuation are ``shoot`` and ``continue_branch`` (keyword
``ContinuationSettings``); a solution's switches are its ``Events``.

Every name is imported on first use, so that ``import rubcli`` itself is light (the
``rubcli`` command handles signals before numpy is imported) and importing the numerical
core (``rubcli.model``) does not load the solvers.
"""

from __future__ import annotations

from rubcli.version import __version__

TYPE_CHECKING = False  # (typing itself is not imported: ``import rubcli`` stays light)

__all__ = [
    "METHODS",
    "Case",
    "CaseError",
    "ContinuationSettings",
    "Events",
    "ModelParams",
    "PeriodicOrbit",
    "Problem",
    "Solution",
    "SwitchEvent",
    "__version__",
    "continue_branch",
    "load_case",
    "shoot",
    "solve",
    "sweep",
]

_LAZY = {
    "ModelParams": "rubcli.model",
    "Problem": "rubcli.problem",
    "Solution": "rubcli.solution",
    "Events": "rubcli.solution",
    "SwitchEvent": "rubcli.solution",
    "shoot": "rubcli.analysis.orbits.periodic",
    "PeriodicOrbit": "rubcli.analysis.orbits.periodic",
    "continue_branch": "rubcli.analysis.orbits.continuation",
    "ContinuationSettings": "rubcli.analysis.orbits.continuation",
    "solve": "rubcli.solvers",
    "METHODS": "rubcli.solvers",
    "load_case": "rubcli.case",
    "Case": "rubcli.case",
    "CaseError": "rubcli.case",
    "sweep": "rubcli.sweeps",
}

if TYPE_CHECKING:
    from typing import Any

    from rubcli.analysis.orbits.continuation import ContinuationSettings, continue_branch
    from rubcli.analysis.orbits.periodic import PeriodicOrbit, shoot
    from rubcli.case import Case, CaseError, load_case
    from rubcli.model import ModelParams
    from rubcli.problem import Problem
    from rubcli.solution import Events, Solution, SwitchEvent
    from rubcli.solvers import METHODS, solve
    from rubcli.sweeps import sweep


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rubcli' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

"""The domain of the periodic-orbit settings, one source for the case file's ``[orbits]``
table (``rubcli.case.OrbitsSection``) and the Python API (``shoot``,
``ContinuationSettings``), which check their arguments as the table's keys are checked.

Plain data (no numpy, no pydantic): the case schema loads it without the solvers.
"""

from __future__ import annotations

from rubcli.solvers.registry import MIN_ATOL

# key -> bounds as pydantic's Field takes them (gt, ge, lt, le)
ORBITS_BOUNDS: dict[str, dict[str, float]] = {
    "step": {"gt": 0},  # the first step, in parameter units
    "min_step": {"gt": 0},
    "max_step": {"gt": 0},
    "max_points": {"ge": 1, "le": 100_000},  # per direction
    "period": {"ge": 1, "le": 64},  # k: orbits of k forcing periods
    "newton_tol": {"gt": 0, "lt": 1},
    "max_newton": {"ge": 1, "le": 100},
    "rtol": {"ge": 1e-14, "lt": 1e-3},  # integration of the map
    "atol": {"ge": MIN_ATOL, "lt": 1e-3},
    "max_wall_time_s": {"gt": 0},
}
ORBITS_WALL_TIME_S = 3600.0  # the default budget of an orbits run, seconds
# The smallest step of a continuation, as a fraction of its window: below it a step is
# lost in the rounding of the parameter.
MIN_ORBIT_STEP_FRACTION = 1e-12

"""Step-size control of the analytic methods' adaptive steps (``analytic_tol``).

Step doubling: a step of length ``h`` is compared with two steps of ``h / 2``; the
largest difference of the two end states, relative to ``1 + |state|`` per component,
times 4/3, estimates the local error of the half steps (the method's local error is
``O(h^3)``). The next step is ``h * min(MAX_FACTOR, max(MIN_FACTOR, SAFETY * (tol /
err)^(1/3)))``; a step is accepted when ``err <= tol`` or it is already as short as
allowed. These are compilable cores: the Python stepper (``analytic.PiecewiseStepper``)
and the compiled one (``compiled/contact.py``) call the same functions; the Python
steppers (the rotor's, ``two_body_analytic``'s) retry a step through ``accepted_pair``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 4.0
MAX_STEP_FRACTION = 1.0 / 8.0  # of the forcing period, in adaptive mode
MIN_STEP_FRACTION = 1e-12  # of the forcing period: a step this short is always accepted


def doubling_error(full: np.ndarray, halves: np.ndarray, start: np.ndarray) -> float:
    """The step-doubling error estimate from the end of the full step, the end of the two
    half steps and the start state (arrays of 4; a NaN propagates). Compilable core."""
    largest = 0.0
    for j in range(4):
        d = abs(full[j] - halves[j]) / (1.0 + abs(start[j]))
        if not d <= largest:  # (a NaN propagates, as in np.max)
            largest = d
    return largest * 4.0 / 3.0


def next_step(
    step: float, err: float, tol: float, safety: float, min_factor: float, max_factor: float,
    min_step: float,
) -> tuple[float, bool]:  # fmt: skip
    """(the proposed next step, accept this one) after a step of ``step`` with error
    ``err`` (compilable core)."""
    factor = safety * (tol / max(err, 1e-300)) ** (1 / 3)
    return step * min(max_factor, max(min_factor, factor)), err <= tol or step <= min_step


def accepted_pair(
    pair: Callable[[float], tuple[float, Any, Any]], h: float, h_max: float, t_left: float,
    tol: float, min_step: float,
) -> tuple[Any, Any, float, float, int]:  # fmt: skip
    """Step doubling's next accepted pair of half steps (the Python steppers'):
    ``pair(step) -> (error, first half, second half)`` is tried at ``min(h, h_max,
    t_left)`` and retried at the controller's shorter step until accepted. Returns
    ``(first, second, step, next h, rejections)``."""
    rejected = 0
    while True:
        step = min(h, h_max, t_left)
        err, first, second = pair(step)
        h, accept = next_step(step, err, tol, SAFETY, MIN_FACTOR, MAX_FACTOR, min_step)
        if accept:
            return first, second, step, h, rejected
        rejected += 1

"""A solution cut into its smooth pieces: one per regime phase, bounded by located events.

Every solver stops at each non-smoothness (contact entry and exit, slip reversal, stick
entry and exit) and records the event with its exact time and state
(``Solution.events``). Between two consecutive events the motion is smooth, so a
quantity that has a kink at a switch (the contact force, the friction) is integrated
piece by piece. The same pieces give the exact time spent in each regime: from the
located switch times, not from counting samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rubcli import model
from rubcli.solution import Solution


@dataclass(frozen=True)
class Piece:
    """One smooth stretch of a solution in a single regime.

    ``tau`` holds the piece's start, the output samples strictly inside it and its end;
    ``states`` the states there (shape (n, 4)). The start and end states are those of
    the events that bound the piece (or the first and last samples of the solution).
    """

    regime: int
    tau: np.ndarray
    states: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.tau[-1] - self.tau[0])


def solution_pieces(solution: Solution) -> list[Piece]:
    """The solution's smooth pieces in time order, from its located events.

    The pieces cover ``[t[0], t[-1]]`` (a failed run's partial span). Events after the
    last sample (a failed run may locate one before it stops) are ignored, and so are
    pieces of zero duration (two events at one instant, e.g. a grazing touch).
    """
    t = np.asarray(solution.t, dtype=float)
    if t.size == 0:
        return []
    states = np.asarray(solution.states, dtype=float)
    t_end = float(t[-1])
    bounds: list[tuple[float, np.ndarray, int]] = [
        (float(t[0]), states[0], int(solution.regimes[0]))
    ]
    for event in solution.events:
        if event.tau > t_end:
            break
        bounds.append((float(event.tau), np.asarray(event.state, dtype=float), event.regime_after))
    pieces = []
    for i, (start, start_state, regime) in enumerate(bounds):
        if i + 1 < len(bounds):
            end, end_state = bounds[i + 1][0], bounds[i + 1][1]
        else:
            end, end_state = t_end, states[-1]
        if not end > start:
            continue
        lo = int(np.searchsorted(t, start, side="right"))
        hi = int(np.searchsorted(t, end, side="left"))
        tau = np.concatenate(([start], t[lo:hi], [end]))
        piece_states = np.vstack((start_state, states[lo:hi], end_state))
        pieces.append(Piece(regime=regime, tau=tau, states=piece_states))
    return pieces


def time_in_regimes(solution: Solution) -> dict[str, float]:
    """Time (in tau) spent in each regime, keyed by ``model.REGIME_NAMES``, from the events.

    Every regime name is present (0.0 when never entered); the values add up to the
    simulated span ``t[-1] - t[0]``.
    """
    out = {name: 0.0 for name in model.REGIME_NAMES.values()}
    for piece in solution_pieces(solution):
        out[model.REGIME_NAMES[piece.regime]] += piece.duration
    return out

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
from rubcli.solution import Solution, ordered_sum


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


@dataclass(frozen=True)
class PieceBounds:
    """Where each smooth piece starts and ends, without copying the samples.

    Piece ``p`` runs from ``start_tau[p]`` (state ``start_state[p]``) through the samples
    ``t[lo[p]:hi[p]]`` to ``end_tau[p]`` (state ``end_state[p]``), in regime
    ``regime[p]``; ``solution_pieces`` assembles the same nodes into arrays. Compiled
    code walks these bounds over the solution's own arrays (``analysis.energy.balance``).
    """

    regime: np.ndarray  # (m,) int64
    start_tau: np.ndarray  # (m,)
    start_state: np.ndarray  # (m, 4)
    end_tau: np.ndarray  # (m,)
    end_state: np.ndarray  # (m, 4)
    lo: np.ndarray  # (m,) int64
    hi: np.ndarray  # (m,) int64

    @property
    def size(self) -> int:
        return int(self.regime.size)

    @property
    def n_nodes(self) -> int:
        """Nodes of all pieces together (each piece: its start, inner samples, end)."""
        return int(np.sum(self.hi - self.lo) + 2 * self.size)


def piece_bounds(solution: Solution) -> PieceBounds:
    """The bounds of the solution's smooth pieces in time order, from its located events.

    The pieces cover ``[t[0], t[-1]]`` (a failed run's partial span). Events after the
    last sample (a failed run may locate one before it stops) are ignored, and so are
    pieces of zero duration (two events at one instant, e.g. a grazing touch).
    """
    t = np.asarray(solution.t, dtype=float)
    states = np.asarray(solution.states, dtype=float)
    if t.size:
        events = solution.events.until(float(t[-1]))
        start_tau = np.concatenate((t[:1], events.tau))
        start_state = np.concatenate((states[:1], events.state))
        regime = np.concatenate((np.asarray(solution.regimes[:1]), events.regime_after))
        end_tau = np.concatenate((events.tau, t[-1:]))
        end_state = np.concatenate((events.state, states[-1:]))
    else:
        start_tau = end_tau = t
        start_state = end_state = np.empty((0, 4))
        regime = np.empty(0, dtype=np.int64)
    keep = end_tau > start_tau  # not the pieces of zero duration
    start_tau, end_tau = start_tau[keep], end_tau[keep]
    return PieceBounds(
        regime=regime[keep].astype(np.int64),
        start_tau=start_tau,
        start_state=start_state[keep],
        end_tau=end_tau,
        end_state=end_state[keep],
        lo=np.searchsorted(t, start_tau, side="right").astype(np.int64),
        hi=np.searchsorted(t, end_tau, side="left").astype(np.int64),
    )


def solution_pieces(solution: Solution) -> list[Piece]:
    """The solution's smooth pieces in time order, from its located events
    (``piece_bounds``), each with its nodes copied into arrays."""
    t = np.asarray(solution.t, dtype=float)
    states = np.asarray(solution.states, dtype=float)
    b = piece_bounds(solution)
    pieces = []
    for p in range(b.size):
        lo, hi = int(b.lo[p]), int(b.hi[p])
        tau = np.concatenate(([b.start_tau[p]], t[lo:hi], [b.end_tau[p]]))
        piece_states = np.vstack((b.start_state[p], states[lo:hi], b.end_state[p]))
        pieces.append(Piece(regime=int(b.regime[p]), tau=tau, states=piece_states))
    return pieces


def time_in_regimes(solution: Solution) -> dict[str, float]:
    """Time (in tau) spent in each regime, keyed by ``model.REGIME_NAMES``, from the events.

    Every regime name is present (0.0 when never entered); the values add up to the
    simulated span ``t[-1] - t[0]``.
    """
    b = piece_bounds(solution)
    durations = b.end_tau - b.start_tau
    return {
        name: ordered_sum(durations[b.regime == code]) for code, name in model.REGIME_NAMES.items()
    }

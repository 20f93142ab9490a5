"""The compiled (numba) code of the solvers, split by concern.

- ``jit.py``: compile settings, the model and event cores registered with numba (the
  physics and the event rules are written once, in ``model.py`` and ``events.py``; the
  event search is ``events.event_search``, built per kind of segment), the stop codes
  every kernel returns;
- ``linalg.py``: LU and a small eigensolver for the 4x4 linearised contact systems;
- ``propagators.py``: the analytic methods' linearised contact steps (Cartesian, polar);
- ``precheck.py``: the conservative event pre-check of a step;
- ``contact.py``: the analytic methods' linearised slip step's scan and pre-check, and
  their adaptive slip steps (``analytic_tol``) in the event loop;
- ``piecewise.py``: the analytic methods' free flight and stick step, and the ``ev``
  functions of their propagators for the event search;
- ``piecewise_loop.py``: the analytic methods' fixed steps in the event loop: every
  regime, events located by ``events.event_search`` and applied in the loop;
- ``rhs.py``: the regime-locked right-hand side for scipy and the compiled DOP853;
- ``dop853.py``: scipy's DOP853 step, error norm, dense output and initial step, built
  per right-hand side (``dop853_step``: the rotor's four states, an extended system's);
- ``roots.py``: the event pre-check and the event search (``events.event_search``) on a
  DOP853 step's dense output, and the application of an event;
- ``event_loop.py``: the one step-and-event loop of every compiled method, built from
  the method's parts;
- ``dop853_loop.py``: the compiled DOP853 method's parts in it (``dop853-jit``);
- ``extended_loop.py``: a system with states beyond the rotor's four in it (its event
  pre-check, search and projection), and DOP853 on such a system, built per system;
- ``drive.py`` and ``driven_taylor.py``: the driven rotor's right-hand side, its DOP853
  loop (``dop853-jit``) and its Taylor series and loop (``taylor``);
- ``two_body.py`` and ``two_body_taylor.py``: the stator with its own mass: its
  right-hand side, its DOP853 loop and its Taylor series and loop;
- ``variational.py``: the rotor at a constant speed as such a system, with or without
  its variational matrix (``orbits``' flow) and its DOP853 loops;
- ``taylor.py``: the ``taylor`` method's series, step size, event pre-check, the event
  search (``events.event_search``) on the step polynomial, and its parts in the event
  loop (about 1,150 lines, over the usual 500: the series are written out once per
  regime, free, slip and stick, as straight-line recurrences, which is where its speed
  comes from, and the pre-checks bound those series; split, each part would import the
  other's internals);
- ``cache.py``: numba's cache kept fresh when model.py, events.py or control.py change
  (a fingerprint of their sources and a probe).

What the drivers call is re-exported here.
"""

from rubcli.solvers.compiled.cache import ensure_fresh
from rubcli.solvers.compiled.contact import adaptive_work, advance_contact_adaptive
from rubcli.solvers.compiled.dop853 import dop853_dense, dop853_dense_point, dop853_initial_step
from rubcli.solvers.compiled.dop853_loop import advance_dop853, advance_paper_dop853
from rubcli.solvers.compiled.jit import (
    STOP_END,
    STOP_EVENT,
    STOP_FULL,
    STOP_GROW,
    STOP_LIMIT,
    STOP_PYTHON,
    STOP_REASONS,
    STOP_SMALL_STEP,
)
from rubcli.solvers.compiled.piecewise_loop import (
    N_COUNTS,
    PIECEWISE_COUNTS,
    advance_piecewise,
    piecewise_work,
)
from rubcli.solvers.compiled.rhs import rhs, rhs_columns, rhs_jacobian

__all__ = [
    "STOP_END",
    "STOP_EVENT",
    "STOP_FULL",
    "STOP_GROW",
    "STOP_LIMIT",
    "STOP_PYTHON",
    "STOP_REASONS",
    "STOP_SMALL_STEP",
    "adaptive_work",
    "advance_contact_adaptive",
    "advance_dop853",
    "advance_paper_dop853",
    "advance_piecewise",
    "piecewise_work",
    "N_COUNTS",
    "PIECEWISE_COUNTS",
    "dop853_dense",
    "dop853_dense_point",
    "dop853_initial_step",
    "ensure_fresh",
    "rhs",
    "rhs_columns",
    "rhs_jacobian",
]

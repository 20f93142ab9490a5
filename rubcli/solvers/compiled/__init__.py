"""The compiled (numba) code of the solvers, split by concern.

- ``jit.py``: compile settings, the model and event cores registered with numba (the
  physics and the event rules are written once, in ``model.py`` and ``events.py``), the
  stop codes every kernel returns;
- ``linalg.py``: LU and a small eigensolver for the 4x4 linearised contact systems;
- ``propagators.py``: the analytic methods' linearised contact steps (Cartesian, polar);
- ``precheck.py``: the conservative event pre-check of a step;
- ``contact.py``: the analytic methods' compiled bulk of event-free slip steps (the
  adaptive steps, ``analytic_tol``);
- ``piecewise.py``: the analytic methods' free flight and stick step, and the ``ev``
  functions of their propagators for the event search;
- ``piecewise_loop.py``: the analytic methods' compiled loop (fixed steps): every
  regime, events located by ``events.locate`` and applied in the loop;
- ``rhs.py``: the regime-locked right-hand side for scipy and the compiled DOP853;
- ``dop853.py``: scipy's DOP853 step, error norm, dense output and initial step;
- ``roots.py``: events located and applied on a DOP853 step's dense output;
- ``dop853_loop.py``: the compiled DOP853 loop (``dop853-jit``);
- ``taylor.py``: the ``taylor`` method's series, step size, event location and loop
  (one file of about 700 lines: its event search is a transcription of ``roots.py``'s
  for the step polynomial, to be merged with it when the event search becomes one
  compilable function, issue 10);
- ``cache.py``: numba's cache kept fresh when model.py or events.py change.

What the drivers call is re-exported here.
"""

from rubcli.solvers.compiled.cache import ensure_fresh
from rubcli.solvers.compiled.contact import advance_contact, advance_contact_adaptive
from rubcli.solvers.compiled.dop853 import dop853_dense, dop853_dense_point, dop853_initial_step
from rubcli.solvers.compiled.dop853_loop import advance_dop853

try:  # TEMPORARY until events.locate lands
    from rubcli.solvers.compiled.piecewise_loop import N_COUNTS, PIECEWISE_COUNTS, advance_piecewise  # noqa
except ImportError:
    pass
from rubcli.solvers.compiled.jit import (
    STOP_END,
    STOP_EVENT,
    STOP_FULL,
    STOP_LIMIT,
    STOP_PYTHON,
    STOP_REASONS,
    STOP_SMALL_STEP,
)
from rubcli.solvers.compiled.rhs import rhs, rhs_columns, rhs_jacobian

__all__ = [
    "STOP_END",
    "STOP_EVENT",
    "STOP_FULL",
    "STOP_LIMIT",
    "STOP_PYTHON",
    "STOP_REASONS",
    "STOP_SMALL_STEP",
    "advance_contact",
    "advance_contact_adaptive",
    "advance_dop853",
    "advance_piecewise",
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

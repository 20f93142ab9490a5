"""Compile settings of the compiled sub-package, the model and event cores registered
with numba, the stop codes every kernel returns, and the constants they share.

The physics and the event rules are not written in this sub-package: they are
``model.py``'s and ``events.py``'s compilable cores (plain functions in the subset of
Python numba compiles), registered here with ``register_jitable`` so that compiled code
calls the very functions the Python paths call.
"""

from __future__ import annotations

import numpy as np
from numba.extending import register_jitable

from rubcli import drive, model, stator
from rubcli.cached_jit import njit
from rubcli.solvers import control, events

# The model's compilable cores, registered so that compiled code calls the same functions.
COMPILABLE_CORES = (
    model.friction_sign,
    model.force_jacobian_entries,
    model.linearised_contact_arrays,
    model.add_support_linear,
    model.subtract_support,
    model.linearised_contact_record,
    model.free_flight_record,
    model.unbalance_value,
    model.stick_friction_value,
    model.rolling_velocity,
    model.rhs_entries,
    model.rhs_jacobian_array,
    model.rhs_record,
    model.rhs_jacobian_record,
    model.support_extra,
    model.is_general_record,
    model.is_paper_record,
    model.add_support_extra,
    model.stick_friction_record,
    model.zero_slip_regime_record,
    model.slip_velocity_rate,
    model.polar_entries,
    model.cartesian_entries,
    model.polar_rhs_entries,
    model.polar_jacobian_arrays,
    model.slip_velocity_value,
    model.entry_regime_value,
    model.filippov_regime,
    model.zero_slip_regime_value,
    model.free_steady_value,
    model.damped_basis,
    model.free_flight_value,
    events.start_flags,
    events.switch_rule,
    events.switch_regime,
    control.doubling_error,
    control.next_step,
    events.stick_margin,
    events.spin_at,
    events.linspace_into,
    events.run_time,
    drive.motor_torque_value,
    drive.shaft_torque_value,
    drive.motor_line,
    drive.stick_torque_value,
    drive.driven_rhs_entries,
    drive.rolling_projection,
    stator.two_body_projection,
    stator.two_body_entries,
)


for _core in COMPILABLE_CORES:
    register_jitable(_core)


# Why a compiled loop stopped (event_loop.event_loop and its entry points).
STOP_END = 0  # reached t_end
STOP_EVENT = 1  # the next step may contain an event: Python takes it
STOP_PYTHON = 2  # the next step needs Python (conditioning, singular system, non-finite)
STOP_LIMIT = 3  # the step limit it was given is reached
STOP_SMALL_STEP = 4  # DOP853: the step size fell below scipy's minimum (10 ulp of tau)
STOP_FULL = 5  # the loop's event buffers are full
STOP_GROW = 6  # the analytic methods: a step's scan grid needs larger buffers


STOP_REASONS = {
    STOP_END: "end",
    STOP_EVENT: "event",
    STOP_PYTHON: "python",
    STOP_LIMIT: "limit",
    STOP_SMALL_STEP: "small step",
    STOP_FULL: "event buffer full",
    STOP_GROW: "scan buffers too small",
}


EPS = np.finfo(float).eps
# nogil: a kernel releases the GIL while it runs, so that threads can solve side by side
# (a library user's thread pool; `rubcli run` itself never runs anything beside a timed
# solve, see rubcli/io/background.py ``Background``).
# _nrt set, not left to its default: a kernel inherits an unset flag from its caller,
# and the event loop (``jit_loop``) is compiled without reference counting
jit = njit(nogil=True, _nrt=True)
# inlined in numba IR into its caller (and compiled with the caller's flags): no call, so
# the arrays it takes are not passed and reference-counted again (taylor's pre-checks and
# the event search's pointwise evaluation)
jit_inline = njit(nogil=True, inline="always")
# compiled without numba's reference counting: the step-and-event loop
# (``event_loop.event_loop``), whose plugged-in parts bind the method's arrays on every
# step; it allocates nothing (its entry point does), and what it calls counts its own
jit_loop = njit(nogil=True, _nrt=False)
# No fastmath but one flag in one place: every kernel rounds as IEEE arithmetic in source
# order, the same on every machine, except taylor's free-flight and slip series
# (``jit_fused``), whose products and sums may fuse into FMA instructions where the host
# has them (every x86-64 since 2013, every ARM64): each fused a * b + c is rounded once
# instead of twice, so those series round a little differently on a host without FMA.
# It makes a frictionless taylor run about 4 % faster (measured against the uncontracted
# series in one run).
# (taylor's series once allowed reassociation, which vectorised their short sums: on an
# AMD EPYC (Zen 4) host that was 7-16 % slower per run, and its rounding followed the
# host's vector width.)
jit_fused = njit(nogil=True, _nrt=True, fastmath={"contract"})

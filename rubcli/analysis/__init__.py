"""Analyses of solutions: functions of arrays and Solutions, no I/O, no plotting.

- ``response``: stroboscopic Poincare sections, response classification (periodic,
  quasi-periodic, chaotic, unbounded) and the largest Lyapunov exponent (Benettin).
- ``reference``: the reference solution of a Problem (exact where the case has one),
  with an honest estimate of its own error and, for chaotic cases, its horizon.
- ``work_precision``: error against run time over ladders of solver settings.
- ``synchronous``: existence and stability of the synchronous full annular rub.
- ``orbits``: orbit panels (each method on one mu, errors, agreement, synchronous rubs)
  and response runs, typed, with progress callbacks (`rubcli compare` and `rubcli run`).
- ``checks``: the report entry of one method and its plausibility warnings (non-finite
  states, energy balance against its floor, penetration against a static bound).
"""

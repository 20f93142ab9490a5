"""Analyses of solutions: functions of arrays and Solutions, no I/O, no plotting.

- ``response``: stroboscopic Poincare sections, response classification (periodic,
  quasi-periodic, chaotic, unbounded) and the largest Lyapunov exponent (Benettin).
- ``reference``: the reference solution of a Problem (exact where the case has one),
  with an honest estimate of its own error and, for chaotic cases, its horizon.
- ``work_precision``: error against run time over ladders of solver settings.
- ``synchronous``: existence and stability of the synchronous full annular rub.
"""

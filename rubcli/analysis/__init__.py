"""Analyses of solutions: functions of arrays and Solutions, no I/O, no plotting.

One sub-package per concern:

- ``energy``: energy balances (the rigid stator's, a run whose speed changes, a stator
  with its own mass) and a solution cut into its smooth pieces between events.
- ``orbits``: periodic orbits, their Floquet multipliers, the synchronous full annular
  rub in closed form, pseudo-arclength continuation in one parameter and bifurcations in
  a second, whirls of unknown rate.
- ``response``: response classification from stroboscopic sections (periodic,
  quasi-periodic, chaotic, unbounded) with the largest Lyapunov exponent (Benettin), the
  spectrum, order tracking, and the orbit panels and response runs of `compare` and `run`.
- ``charts``: stability charts in a parameter plane (closed form) and contact-force maps.
- ``accuracy``: the reference solution of a Problem with an honest estimate of its own
  error, work-precision ladders and the stress suite.
- ``ensembles``: ensembles of runs and basin stability along a parameter.
- ``runs``: a method's report entry with its plausibility warnings, and local worker
  processes.
- ``sweep``: parameter sweeps, maps and basins.
"""

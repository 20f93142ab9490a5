"""The one system of a composed machine (``rubcli.machine``): its right-hand side, event
functions, stick forces, projection onto rolling and energy rate, compiled once for every
machine (``kernels``); a run of it with every method (``run.simulate``); and the meaning
of its samples (``series``)."""

from rubcli.system.run import METHODS, simulate
from rubcli.system.series import energy, energy_residual, station_series
from rubcli.system.solution import KIND_NAMES, MachineSolution, StationEvents

__all__ = [
    "KIND_NAMES",
    "METHODS",
    "MachineSolution",
    "StationEvents",
    "energy",
    "energy_residual",
    "simulate",
    "station_series",
]

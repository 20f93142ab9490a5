"""Ensembles of runs whose single outcome is fragile: attractor fractions and escape times
(``ensemble``) and the basin stability along a parameter (``basin_stability``)."""

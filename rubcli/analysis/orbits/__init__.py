"""Periodic orbits and their branches: the stroboscopic map, monodromy and Floquet
multipliers (``periodic``, its settings' domain ``bounds``), the synchronous full annular
rub in closed form (``synchronous``), pseudo-arclength continuation with bifurcation
detection (``continuation``), bifurcations continued in a second parameter (``curves``)
and whirls of unknown rate (``whirls``)."""

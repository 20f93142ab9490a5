"""The studies behind the commands, as library functions.

Each module takes a validated case (``rubcli.load_case``) and its options, does the work,
and returns a typed result whose ``write(directory)`` writes the command's files in one
atomic commit through ``rubcli.io``; progress comes back through a callback. The command
line (``rubcli.cli``) only parses, calls and prints.

- ``run``: a case solved with each of its methods, its CSVs, figures and report
  (``rubcli run``);
- ``compare``: the reference, the work-precision ladders and the orbit panels
  (``rubcli compare``);
- ``orbits``: periodic orbits continued in one parameter (``rubcli orbits``);
- ``chart``: the stability chart of a parameter plane (``rubcli chart``);
- ``ensemble``: runs from a cloud (or a box) of starts at every setting of a tolerance
  ladder, each end classified and named (``rubcli ensemble``);
- ``basin_stability``: the share of a box of starts on each attractor along a parameter,
  and the minimal perturbation off the free whirl (``rubcli ensemble`` with
  ``[ensemble] parameter``);
- ``forces_map``: the contact force maps, the Taylor error, the contact eigenvalues
  (``rubcli forces-map``; each product written as it is made, to hold one grid at a time);
- ``stress``: the built-in suite of extreme cases (``rubcli stress``);
- ``sweep``: the files of a finished parameter sweep and the store of its finished points
  (``rubcli sweep``; the sweep itself is ``rubcli.sweep(case)``).
"""

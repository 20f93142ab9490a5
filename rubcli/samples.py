"""The commented sample case files that ``rubcli init`` prints: ``sample_case``.

The samples are tested to validate, to name every method and every table of the schema
(tests/test_cli.py); keep them in step with ``rubcli/case/`` and ``docs/cases.md``.
"""

from __future__ import annotations

from rubcli.case import KNOWN_METHODS, KNOWN_PLOTS

MACHINES = ("paper", "general")

_METHODS = ", ".join(KNOWN_METHODS)
_PLOTS = ", ".join(KNOWN_PLOTS)

# The optional tables, commented out, shared by both samples.
_OPTIONAL_TABLES = """
# Optional tables (docs/cases.md and the docs of each command); uncomment to use.

# [speed]                       # a speed that changes: run-up, coast-down (docs/runup.md)
# profile = "ramp"              # or "table" (tau = [...], eta = [...]; t, speed in SI)
# from = 0.5                    # the speed at tau = 0 (rpm with [physical])
# to = 2.0                      # held once reached
# rate = 0.002                  # d eta / d tau (rpm/s with [physical]), signed
# (with [speed]: no eta/Omega and no [time] periods; the run spans the profile;
#  methods dop853-jit or a scipy method)
# profile = "driven"            # or the speed a state, driven by a motor (give [time] end):
# start = 0.5                   #   the speed at tau = 0
# inertia = 200.0               #   j = J_p / (m gamma^2) (kg m^2 with [physical])
# stall_torque = 20.0           #   torque over k_r gamma^2 (N m with [physical])
# no_load_speed = 4.0

# [stator]                      # a stator with its own mass: a snubber ring on its own
# mass = 0.2                    #   supports (docs/machines.md); M_s / m (kg with [physical])
# stiffness = [2.0, 4.0]        #   k_sx / k_r, k_sy / k_r (N/m), forces k_s s axis by axis
# damping = [0.05, 0.05]        #   forces 2 n_s s' (N s/m); run by dop853-jit, taylor or a
#                               #   scipy method; [initial] stator = [u, v, u', v'] its start

# [analysis]                    # response class of each run (Poincare section, Lyapunov)
# response = true
# transient_periods = 10        # default: half the run

# [compare]                     # `rubcli compare`: work-precision ladders, mu sweep
# methods = ["analytic", "dop853-jit"]  # default: [solver] methods
# mu = [0.0, 0.01, 0.02]        # one orbit panel per friction coefficient
# work_precision = true

# [forces_map]                  # `rubcli forces-map`: contact force maps (paper Figure 2)
# extent = 1.5                  # half-width of the grid, clearances
# resolution = 201              # grid points per side (bounded by a memory estimate)
# products = ["forces", "taylor_error", "eigen"]

# [orbits]                      # `rubcli orbits`: periodic orbits and continuation
# kind = "periodic"             # or "whirl": whirls of unknown rate (needs e = 0)
# parameter = "mu"              # continued in: eta, mu, K, e, nu or Rp (docs/orbits.md)
# min = 0.0                     # the window; the case's value must lie in it
# max = 0.06
# step = 0.002                  # first continuation step
# start = "synchronous_rub"     # guess: "initial", "transient" or "synchronous_rub"
# second_parameter = "eta"      # each located bifurcation continued in a second parameter
# second_min = 0.6              # its window (curve.csv, curves.png)
# second_max = 1.0

# [sweep]                       # `rubcli sweep`: bifurcation diagrams, maps, basins
# parameter = "mu"              # nu, eta, e, K, mu, Rp, phi0 (or x, y, vx, vy: basins)
# start = 0.0                   # values: start/stop/num, or values = [...]
# stop = 0.06
# num = 31
# direction = "both"            # up, down, both (run-up and run-down) or independent
# transient_periods = 200       # discarded at every point
# record_periods = 100          # recorded at every point

# [chart]                       # `rubcli chart`: regions of the synchronous motions
# x = "eta"                     # a plane of two of nu, eta, e, K, mu, Rp (docs/charts.md)
# x_min = 0.1
# x_max = 2.0
# y = "mu"
# y_min = 0.0
# y_max = 0.1

# [ensemble]                    # `rubcli ensemble`: a cloud of starts, a tolerance ladder
# runs = 20                     # starts: [initial] and 19 within `spread` of it
# spread = 1e-6                 # clearances
# periods = 2000                # per run
# rtols = [1e-8, 1e-10]         # every start at every tolerance
# parameter = "eta"             # or: the same starts at each value (basin stability,
# start = 1.0                   #   docs/charts.md); values: start/stop/num or values = [...]
# stop = 3.4
# num = 13
# starts = "box"                # uniform over a box (a side not given stays at [initial])
# box_x = [-1.5, 1.5]
# box_y = [-1.5, 1.5]
# minimal_perturbation = true   # the smallest kick found off the free whirl, per value
"""

SAMPLE_CASE = f"""\
# A rubcli case file (TOML). Reference: docs/cases.md. Check it with `rubcli validate`.
# Values: the paper's Figure 3(b) (El-Sayed et al., COBEM 2021), mu = 0.01.

[case]
name = "my-case"                # names the default output dir out/<name>
description = "Jeffcott rotor rubbing on a stator, Figure 3(b) parameters"

[model]                         # nondimensional (docs/cases.md; or [physical] in SI units)
nu = 0.009478                   # damping ratio d_r / (2 omega m), >= 0
eta = 0.7818                    # speed ratio Omega / omega, > 0
e = 7.52                        # unbalance eccentricity / clearance, >= 0
K = 17.6                        # stator / rotor stiffness ratio k_s / k_r, > 0
mu = 0.01                       # Coulomb friction coefficient, >= 0 (default 0)
Rp = 46.16                      # rotor radius / clearance, >= 0 (default 0)
phi0 = 0.0                      # unbalance phase at tau = 0, rad (default 0)

[initial]                       # state at tau = 0, in clearances and d/dtau
x = 0.88544
y = -0.8039
vx = 0.0                        # default 0
vy = 0.0                        # default 0

[time]
periods = 20                    # duration in forcing periods 2 pi / eta, > 0
samples_per_period = 100        # output samples per period (integer > 0)

[solver]
# any of: {_METHODS}
methods = ["analytic", "rk45"]
rtol = 1e-8                     # rk45 ... lsoda, dop853-jit: relative tolerance
atol = 1e-10                    # rk45 ... lsoda, dop853-jit: absolute tolerance
steps_per_period = 400          # analytic methods: fixed step = forcing period / this
# analytic_tol = 1e-8           # analytic methods: adaptive steps with this local error
max_steps = 5000000             # give up after this many steps (status "failed")
max_wall_time_s = 600           # give up after this many seconds, per method

[output]
# dir = "out/my-case"           # default out/<case name>, relative to the working dir
csv = true                      # write <method>.csv for each method
plots = ["orbit", "time"]       # any of: {_PLOTS} ([] for none)
{_OPTIONAL_TABLES}"""

SAMPLE_PHYSICAL_CASE = f"""\
# A rubcli case file in SI units (TOML). Reference: docs/cases.md.
# [physical] is converted once to the nondimensional model; outputs get SI columns too.

[case]
name = "my-machine"
description = "A small test rig: 4 kg disc on a 4e5 N/m shaft in a stiff casing, 0.2 mm clearance"

[physical]
m = 4.0                         # rotor (disc) mass, kg
k_r = 4.0e5                     # shaft stiffness, N/m       -> omega = sqrt(k_r/m) = 316 rad/s
d_r = 25.3                      # shaft damping, N s/m       -> nu = d_r/(2 omega m) = 0.01
k_s = 1.0e8                     # stator stiffness, N/m      -> K = k_s/k_r = 250
clearance = 2.0e-4              # radial clearance, m
e = 2.5e-4                      # unbalance eccentricity, m  -> e/clearance = 1.25
Omega = 250.0                   # spin speed, rad/s          -> eta = Omega/omega = 0.79
Rp = 0.05                       # rotor radius at the rub, m (default 0)
mu = 0.05                       # Coulomb friction coefficient (default 0)
phi0 = 0.0                      # unbalance phase, rad (default 0)

[initial]                       # at t = 0, in metres and m/s: at rest, half the clearance off
x = 1.0e-4
y = 0.0
vx = 0.0
vy = 0.0

[time]
periods = 20                    # duration in forcing periods 2 pi / Omega, > 0
samples_per_period = 100

[solver]
methods = ["analytic", "rk45"]  # any of: {_METHODS}

[output]
csv = true
plots = ["orbit", "time"]       # any of: {_PLOTS}
{_OPTIONAL_TABLES}"""


SAMPLE_GENERAL_CASE = f"""\
# A rubcli case file for the general machine (TOML). Reference: docs/machines.md.
# A horizontal rotor whose seal is misaligned, on anisotropic, cross-coupled bearings.

[case]
name = "my-machine"
description = "Misaligned seal, gravity, anisotropic and cross-coupled bearings"

[model]                         # nondimensional (docs/cases.md, docs/machines.md)
eta = 1.1                       # speed ratio Omega / omega, > 0 (omega = sqrt(k_r / m))
e = 0.1                         # unbalance eccentricity / clearance, >= 0
K = 20.0                        # stator / rotor stiffness ratio k_s / k_r, > 0
mu = 0.1                        # Coulomb friction coefficient, >= 0
Rp = 3.0                        # rotor radius / clearance, >= 0
# The general machine (each entry optional; leaving all out is the paper's machine):
offset = [0.3, 0.0]             # the stator's centre from the support's, clearances
load = [0.0, -0.5]              # static force on the rotor (gravity: -m g / (k_r clearance))
stiffness = [[1.0, 0.02],       # support stiffness S / k_r: k_xx = 1 is the reference k_r,
             [-0.02, 1.2]]      #   k_xy - k_yx = 2 q the cross-coupling; sym. part > 0
damping = [[0.05, 0.0],         # support damping D (forces 2 D w'), instead of nu;
           [0.0, 0.06]]         #   damping = [[nu, 0], [0, nu]] is the isotropic nu

[initial]                       # relative to the stator's centre: the rotor's own position
x = -0.3                        #   is x + offset_x (here: at rest on its support's centre)
y = 0.0
vx = 0.0
vy = 0.0

[time]
periods = 60                    # duration in forcing periods 2 pi / eta, > 0
samples_per_period = 100

[solver]
# any of: {_METHODS} (not analytic-polar)
methods = ["analytic", "dop853-jit"]
rtol = 1e-9
atol = 1e-11
steps_per_period = 800

[output]
csv = true                      # x, y relative to the stator; rotor_x, rotor_y the rotor's
plots = ["orbit", "time"]       # any of: {_PLOTS}
{_OPTIONAL_TABLES}"""

# the general machine's entries of a [physical] table (docs/machines.md)
_PHYSICAL_GENERAL = """\
# The general machine in SI units (each entry optional; docs/machines.md):
offset = [6.0e-5, 0.0]          # the stator's centre from the support's, m
load = [0.0, -39.2]             # static force on the rotor, N (gravity: -m g)
stiffness = [[4.0e5, 8.0e3],    # support stiffness, N/m (k_r is the reference: k_xx here)
             [-8.0e3, 4.8e5]]
# damping = [[25.3, 0.0], [0.0, 30.0]]  # support damping, N s/m, instead of d_r
"""


def sample_case(machine: str = "paper", physical: bool = False) -> str:
    """The sample of ``machine`` (one of ``MACHINES``), in SI units with ``physical``."""
    if machine not in MACHINES:
        raise ValueError(f"machine must be one of {', '.join(MACHINES)} (got {machine!r})")
    if machine == "general" and physical:  # the general entries after the [physical] table's
        last = SAMPLE_PHYSICAL_CASE.index("\n", SAMPLE_PHYSICAL_CASE.index("phi0 = ")) + 1
        return SAMPLE_PHYSICAL_CASE[:last] + _PHYSICAL_GENERAL + SAMPLE_PHYSICAL_CASE[last:]
    if machine == "general":
        return SAMPLE_GENERAL_CASE
    return SAMPLE_PHYSICAL_CASE if physical else SAMPLE_CASE

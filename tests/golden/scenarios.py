"""The solver outputs pinned by tests/test_golden.py: scenarios x method settings.

Each scenario is short (a few forcing periods at most) and covers a kind of event:
contact entry/exit and slip reversals (the paper's Figure 3 start with friction), dry whip
and a stick-slip cycle (stick entry/exit, Filippov's rule), stiff impacts with stick-slip
(K = 1.76e4), a tangential touch at K = 1.75e6 and persistent contact at K = 1.75e6. Runs are
bounded by steps only (never by wall time), so they are deterministic.

``python tests/golden/make_golden.py`` regenerates ``solvers.json`` (review the diff: a
change there is a change of the numbers every method produces).
"""

from __future__ import annotations

from rubcli import model
from rubcli.analysis.accuracy import stress
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers.registry import SPECS

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16}
FIG3_START = (0.88544, -0.8039, 0.0, 0.0)
MAX_STEPS = 200_000


def scenarios() -> dict[str, Problem]:
    out = {}
    for mu in (0.0, 0.03, 0.05):
        p = ModelParams(**FIG3, K=17.6, mu=mu)
        out[f"fig3-mu{mu:g}"] = Problem.from_periods(p, FIG3_START, 2, 20)
    stiff = ModelParams(**FIG3, K=1.76e4, mu=0.03)
    out["stiff-K1.76e4-mu0.03"] = Problem.from_periods(stiff, FIG3_START, 0.2, 50)
    whip = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.1, Rp=2.0)
    r_roll = model.rolling_whirl_radius(whip)
    start = (r_roll, 0.0, 0.0, -whip.Rp * whip.eta)
    out["dry-whip"] = Problem.from_periods(whip, start, 1, 20)
    slip = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)
    out["stick-slip"] = Problem.from_periods(slip, start, 2, 20)
    touch = ModelParams(nu=0.05, eta=FIG3["eta"], e=0.0, K=1.75e6, mu=0.1, Rp=FIG3["Rp"])
    touch_start, _ = stress.touching_start(touch, (0.3, -0.5, 0.4, 0.6))
    out["touch-K1.75e6"] = Problem.from_periods(touch, touch_start, 1, 20)
    sync = ModelParams(**FIG3, K=1.75e6, mu=0.01)
    r = model.synchronous_rub_radii(sync)[-1]
    s0 = model.synchronous_rub(0.0, sync, r)
    kick = (float(s0[0]) * (1 + 1e-4), float(s0[1]), float(s0[2]), float(s0[3]))
    out["ring-K1.75e6"] = Problem.from_periods(sync, kick, 0.05, 400)
    return out


def settings() -> dict[str, tuple[str, dict]]:
    """Label -> (method, options)."""
    base = {"max_steps": MAX_STEPS, "max_wall_time_s": 1e9}
    out = {}
    for m in ("analytic", "analytic-polar"):
        out[m] = (m, {**base, "steps_per_period": 200})
        out[f"{m}-adaptive"] = (m, {**base, "analytic_tol": 1e-6})
    for m in ("rk45", "dop853", "radau", "bdf", "lsoda", "dop853-jit"):
        out[m] = (m, {**base, "rtol": 1e-8, "atol": 1e-10})
    out["dop853-jit-python-events"] = (
        "dop853-jit",
        {**base, "rtol": 1e-8, "atol": 1e-10, "compiled_events": False},
    )
    out["taylor"] = ("taylor", {**base, "rtol": 1e-8, "atol": 1e-10})
    out["taylor-python-events"] = (
        "taylor",
        {**base, "rtol": 1e-8, "atol": 1e-10, "compiled_events": False},
    )
    return out


# Settings run only on the cheapest scenarios: the pure-Python paths.
PYTHON_SCENARIOS = ("fig3-mu0.03", "stick-slip")


def python_settings() -> dict[str, tuple[str, dict]]:
    base = {"max_steps": MAX_STEPS, "max_wall_time_s": 1e9, "compiled": False}
    return {
        "analytic-python": ("analytic", {**base, "steps_per_period": 200}),
        "analytic-polar-adaptive-python": ("analytic-polar", {**base, "analytic_tol": 1e-6}),
        "dop853-jit-python": ("dop853-jit", {**base, "rtol": 1e-8, "atol": 1e-10}),
        "rk45-python": ("rk45", {**base, "rtol": 1e-8, "atol": 1e-10}),
    }


# The implicit scipy methods cost about a second a run: pinned where events of every kind
# occur (their steppers share the event code and the driver with rk45 and dop853).
IMPLICIT = tuple(m for m, spec in SPECS.items() if spec.implicit)  # radau, bdf, lsoda
IMPLICIT_SCENARIOS = ("stiff-K1.76e4-mu0.03", "stick-slip", "ring-K1.75e6")


def runs():
    """(scenario, label, problem, method, options) of every pinned run."""
    problems = scenarios()
    for name, problem in problems.items():
        for label, (method, options) in settings().items():
            if label in IMPLICIT and name not in IMPLICIT_SCENARIOS:
                continue
            yield name, label, problem, method, options
    for name in PYTHON_SCENARIOS:
        for label, (method, options) in python_settings().items():
            yield name, label, problems[name], method, options


def record(solution) -> dict:
    """What is pinned of a run: every sample, every event, the counts and the status."""
    return {
        "status": solution.status,
        "message": solution.message,
        "t_end": float(solution.t[-1]),
        "states": [[float(v) for v in row] for row in solution.states],
        "regimes": [int(r) for r in solution.regimes],
        "events": [
            [float(ev.tau), ev.kind, int(ev.regime_before), int(ev.regime_after)]
            for ev in solution.events
        ],
        "stats": {k: int(v) for k, v in solution.stats.items()},
    }

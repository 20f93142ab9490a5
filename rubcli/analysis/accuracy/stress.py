"""The stress suite: extreme cases, each run with every method, within a budget.

``stress_cases(quick)`` lists the built-in cases: stiff stators from
``K = 17.6`` to ``1.75e6`` (Table 1's range), friction ``mu = 0 ... 0.1`` including the
dry-whip (stick/roll) regime, no damping, grazing orbits, a 10,000-period horizon, a
large eccentricity and starts deep inside the stator. ``run_suite`` solves each case with
every method of the registry at the case-file defaults (and the analytic methods also with
adaptive steps, ``analytic_tol = 1e-6``), under a per-run budget (``max_wall_time_s``,
``max_steps``), and measures each run against the best available reference:

- **exact** where the case has one: the free flight in closed form
  (``analysis.accuracy.reference.exact_reference``), including a free orbit that only *touches*
  the clearance (penetration below the grazing tolerance, so no contact force ever acts),
  and the synchronous full annular rub started on its orbit;
- otherwise **numerical**: DOP853 at ``rtol = atol = 1e-12`` under the same budget (run
  as ``dop853-jit``: scipy's DOP853 step for step, compiled); if that run does not
  finish, Radau at ``1e-10``; failing both, the tightest successful dop853/radau run of
  the suite itself. The reference used is named in every row. A numerical reference is
  *confirmed* over the case's horizon when a different method of the suite (rk45, radau
  or lsoda at the suite's rtol 1e-8) agrees with it within ``CONFIRM_ERROR`` = 1e-4: the
  horizon is then inside the horizon of predictability and the reference is trusted.

Each run also gets its energy residual (``analysis.energy.balance``), its largest penetration
and a check for non-finite values. A run that reports success is given a *warning* when
its energy balance fails by more than 1e-2 of the throughput or it is more than 1e-2
clearances from an exact or a confirmed reference: a wrong orbit must not pass
unremarked. Nothing here
writes files (``cli/stress.py`` does).

The error is ``max |w - w_ref|`` over the samples the run and its reference share (a
failed run is compared over its partial span). For a chaotic case (the paper's
``mu = 0.05``) two correct solutions separate after a finite horizon, so a large error
there says "beyond the horizon of predictability", not "wrong"; the energy residual is
the check that still means something.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from rubcli import model
from rubcli.analysis.accuracy.reference import EXACT_FREE_FLIGHT, exact_reference
from rubcli.analysis.energy.balance import energy_balance
from rubcli.analysis.energy.regimes import time_in_regimes
from rubcli.drive import Drive
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solution import SUCCESS, Solution
from rubcli.solvers.registry import (
    DRIVEN,
    GENERAL_MACHINE,
    MOVING_STATOR,
    SPECS,
    SPEED_PROFILE,
    options_for,
    unsupported,
)
from rubcli.speed import SpeedProfile
from rubcli.stator import Stator

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

ERROR = "error"  # status of a run whose solver raised (a bug: never expected)
REFUSED = "refused"  # a method that does not run the case's feature (a speed that changes)

# The Figure 3 machine of the paper (model notes, section 6) and its start, which lies
# inside the stator already (z0 = 1.196).
FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "Rp": 46.16}
FIG3_START = (0.88544, -0.8039, 0.0, 0.0)

# Budgets per run. Full mode is generous but bounded; quick mode is for tests.
FULL_BUDGET = {"max_wall_time_s": 120.0, "max_steps": 5_000_000}
QUICK_BUDGET = {"max_wall_time_s": 0.5, "max_steps": 20_000}
LONG_BUDGET = {"max_wall_time_s": 600.0, "max_steps": 20_000_000}  # the 10,000-period case
SOLVER_OPTIONS = {"rtol": 1e-8, "atol": 1e-10, "steps_per_period": 400}  # the case defaults
# Besides every method at the case defaults, the analytic methods with adaptive steps.
ADAPTIVE_TOL = 1e-6
# A successful run is flagged when its energy balance fails by more than this (relative),
# or when it is this far (clearances) from an exact reference.
SUSPECT_ENERGY_RESIDUAL = 1e-2
SUSPECT_EXACT_ERROR = 1e-2
REFERENCE_RUNS = (
    ("dop853-jit", {"rtol": 1e-12, "atol": 1e-12}),
    ("radau", {"rtol": 1e-10, "atol": 1e-12}),
)
# A numerical reference is trusted when one of these suite runs agrees with it this well.
CONFIRM_METHODS = ("rk45", "radau", "lsoda")
CONFIRM_ERROR = 1e-4
TOUCH_CHECK_POINTS_PER_PERIOD = 4000  # grid on which a touching free orbit is checked


@dataclass(frozen=True)
class StressCase:
    """One extreme case: the machine, the start, the horizon (full and quick) and why."""

    name: str
    description: str
    params: ModelParams
    initial: tuple[float, float, float, float]
    periods: float
    quick_periods: float
    samples_per_period: int = 100
    touches: bool = False  # a free orbit built to touch z = 1 tangentially (exact reference)
    budget: dict = field(default_factory=lambda: dict(FULL_BUDGET))
    # a speed that changes: a profile, or a driven rotor (its periods at the start speed)
    speed: SpeedProfile | None = None
    drive: Drive | None = None

    @property
    def feature(self) -> str | None:
        """The registry feature the case needs of a method (None: any method runs it)."""
        if self.drive is not None:
            return DRIVEN
        if self.speed is not None:
            return SPEED_PROFILE
        if self.params.stator is not None:
            return MOVING_STATOR
        return None if self.params.is_paper_machine else GENERAL_MACHINE

    def problem(self, quick: bool) -> Problem:
        periods = self.quick_periods if quick else self.periods
        if self.speed is None and self.drive is None:
            return Problem.from_periods(
                self.params, self.initial, periods, self.samples_per_period, name=self.name
            )
        n = max(2, int(round(periods * self.samples_per_period)) + 1)
        t_eval = np.linspace(0.0, periods * self.params.period, n)
        return Problem(self.params, self.initial, t_eval, name=self.name, speed=self.speed,
                       drive=self.drive)  # fmt: skip


@dataclass
class StressRun:
    """The outcome of one method on one case (one row of stress.csv)."""

    case: str
    method: str
    status: str
    message: str
    wall_time_s: float
    periods: float  # periods simulated (the partial span of a failed run)
    target_periods: float
    n_steps: int | None = None
    n_events: int = 0
    n_contact_switches: int = 0
    reference: str = ""
    error: float | None = None
    warning: str = ""
    energy_residual: float | None = None
    energy_quadrature_error: float | None = None
    max_penetration: float | None = None
    nan: bool = False
    stick_fraction: float = 0.0

    def as_row(self) -> dict[str, object]:
        return {name: getattr(self, name) for name in RUN_COLUMNS}


RUN_COLUMNS = (
    "case",
    "method",
    "status",
    "message",
    "wall_time_s",
    "periods",
    "target_periods",
    "n_steps",
    "n_events",
    "n_contact_switches",
    "reference",
    "error",
    "warning",
    "energy_residual",
    "energy_quadrature_error",
    "max_penetration",
    "nan",
    "stick_fraction",
)


# ---------------------------------------------------------------------------- the cases


def steady_unit_whirl(
    nu: float, eta: float, K: float, mu: float, Rp: float
) -> tuple[ModelParams, tuple[float, float, float, float]]:
    """Parameters and start of a free whirl whose steady radius is exactly 1 (grazing).

    ``|w_p| = E / |1 - eta^2 + 2 i nu eta| = 1`` gives ``e = |1 - eta^2 + 2 i nu eta| / eta^2``;
    started on the steady orbit ``w_p(0)``, the exact motion rides along the clearance
    circle with zero penetration: every point is a touch.
    """
    e = abs(complex(1.0 - eta * eta, 2.0 * nu * eta)) / (eta * eta)
    params = ModelParams(nu=nu, eta=eta, e=e, K=K, mu=mu, Rp=Rp)
    w, v = model.free_steady_state(0.0, params)
    return params, (float(w.real), float(w.imag), float(v.real), float(v.imag))


def touching_start(
    params: ModelParams, direction: ArrayLike, period_fraction: float = 1.0
) -> tuple[tuple[float, ...], float]:
    """A start whose free flight touches z = 1 once, tangentially, at its first maximum.

    Needs ``e = 0``: the free flight is then linear in the start, so scaling
    ``direction`` by ``1 / max z`` over the first ``period_fraction`` natural periods makes
    that maximum exactly 1 (to round-off). The maximum is the root of the radial rate
    ``x vx + y vy`` (Brent, to 1e-15 in tau). Returns the start and the touch time.
    """
    from scipy.optimize import brentq

    if params.e != 0.0:
        raise ValueError("touching_start needs e = 0 (a free flight linear in the start)")
    s = np.asarray(direction, dtype=float)
    t = np.linspace(0.0, period_fraction * 2.0 * math.pi, 4001)
    S = model.free_flight(t, 0.0, s, params)
    i = int(np.clip(np.argmax(np.hypot(S[0], S[1])), 1, t.size - 2))

    def radial_rate(tau: float) -> float:
        x, y, vx, vy = model.free_flight(tau, 0.0, s, params)
        return float(x * vx + y * vy)

    touch = brentq(radial_rate, t[i - 1], t[i + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps)
    z_max = float(np.hypot(*model.free_flight(touch, 0.0, s, params)[:2]))
    return tuple(float(v) for v in s / z_max), float(touch)


def stress_cases() -> list[StressCase]:
    """The built-in suite (full horizons in ``periods``, quick ones in ``quick_periods``)."""
    cases: list[StressCase] = []
    for K, periods, quick, spp in (
        (17.6, 100, 1, 100),
        (1.76e3, 100, 0.5, 100),
        (1.76e5, 20, 0.2, 100),
        (1.75e6, 5, 0.05, 100),
    ):
        params = ModelParams(**FIG3, K=K, mu=0.01)
        r = model.synchronous_rub_radii(params)[-1]
        start = tuple(float(v) for v in model.synchronous_rub(0.0, params, r))
        cases.append(
            StressCase(
                f"sync-K{K:g}",
                f"synchronous full annular rub, K = {K:g}, mu = 0.01, started on the exact "
                f"orbit r = {r:.10g} (stable): exact reference",
                params, start, periods, quick, spp,
            )
        )  # fmt: skip
    for K, mu, periods, quick, spp in (
        (17.6, 0.05, 100, 1, 100),
        (1.76e3, 0.05, 20, 0.2, 400),
        (1.76e5, 0.05, 3, 0.03, 4000),
        (1.75e6, 0.1, 1, 0.01, 20000),
    ):
        cases.append(
            StressCase(
                f"fig3-K{K:g}-mu{mu:g}",
                f"the paper's Figure 3 machine and start (z0 = 1.196: inside the stator), "
                f"K = {K:g}, mu = {mu:g}",
                ModelParams(**FIG3, K=K, mu=mu), FIG3_START, periods, quick, spp,
            )
        )  # fmt: skip
    cases.append(
        StressCase(
            "fig3-nu0-mu0",
            "no dissipation at all (nu = 0, mu = 0), Figure 3 machine and start, K = 17.6",
            ModelParams(**{**FIG3, "nu": 0.0}, K=17.6, mu=0.0), FIG3_START, 100, 1,
        )
    )  # fmt: skip
    cases.append(
        StressCase(
            "large-e",
            "large eccentricity e = 46.16 (Table 1's value), K = 17.6, mu = 0.05",
            ModelParams(**{**FIG3, "e": 46.16}, K=17.6, mu=0.05), FIG3_START, 100, 1,
        )
    )  # fmt: skip
    cases.append(
        StressCase(
            "deep-start",
            "start deep inside a stiff stator: z0 = 2 at K = 1.76e3 (force 1760), mu = 0.05",
            ModelParams(**FIG3, K=1.76e3, mu=0.05), (2.0, 0.0, 0.0, 0.0), 20, 0.2, 400,
        )
    )  # fmt: skip
    whip = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.1, Rp=2.0)
    r_roll = model.rolling_whirl_radius(whip)
    cases.append(
        StressCase(
            "dry-whip",
            "dry whip: backward rolling whirl (stick), nu = 0.01, eta = 1, e = 0.05, K = 100, "
            "mu = 0.1, Rp = 2, started rolling at r = "
            f"{r_roll:.6g}",
            whip, (r_roll, 0.0, 0.0, -whip.Rp * whip.eta), 100, 1,
        )
    )  # fmt: skip
    slip = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.02, Rp=2.0)
    cases.append(
        StressCase(
            "stick-slip",
            "stick-slip cycle: the rolling whirl with mu = 0.02, the unbalance pushes the "
            "needed friction across the cone edge twice a period",
            slip, (r_roll, 0.0, 0.0, -slip.Rp * slip.eta), 100, 1,
        )
    )  # fmt: skip
    graze, start = steady_unit_whirl(FIG3["nu"], FIG3["eta"], 17.6, 0.05, FIG3["Rp"])
    cases.append(
        StressCase(
            "grazing-whirl",
            f"free whirl of steady radius exactly 1 (e = {graze.e:.6g}), started on it: the "
            "exact orbit slides along the clearance with zero penetration",
            graze, start, 100, 1, touches=True,
        )
    )  # fmt: skip
    touch = ModelParams(nu=0.05, eta=FIG3["eta"], e=0.0, K=1.75e6, mu=0.1, Rp=FIG3["Rp"])
    touch_start, _ = touching_start(touch, (0.3, -0.5, 0.4, 0.6))
    cases.append(
        StressCase(
            "grazing-touch",
            "a free orbit (e = 0, nu = 0.05) that touches the clearance once, tangentially: "
            "a contact of vanishing duration, K = 1.75e6",
            touch, touch_start, 20, 1, touches=True,
        )
    )  # fmt: skip
    cases += _changing_speed_cases()
    cases += _general_machine_cases()
    long = cases[0]
    cases.append(
        replace(
            long,
            name="long-horizon",
            description="10,000 forcing periods on the synchronous rub, K = 17.6, mu = 0.01: "
            "exact reference; long-time drift",
            periods=10_000,
            quick_periods=5,
            samples_per_period=20,
            budget=dict(LONG_BUDGET),
        )
    )
    return cases


def _changing_speed_cases() -> list[StressCase]:
    """The speed changing under a stiff stator, in stick, and driven into a dry whip."""
    runup = ModelParams(nu=0.05, eta=0.5, e=0.3, K=1.76e4, mu=0.05, Rp=5.0)
    roll = ModelParams(nu=0.01, eta=1.0, e=0.0, K=100.0, mu=0.5, Rp=2.0)
    r_roll = model.rolling_whirl_radius(roll)
    whip = ModelParams(nu=0.05, eta=3.5, e=0.3, K=1.76e3, mu=0.3, Rp=5.0)
    return [
        StressCase(
            "runup-stiff",
            "a run-up through the critical speed onto a stiff stator: eta 0.5 to 2 at "
            "d eta / d tau = 0.01, K = 1.76e4, mu = 0.05 (the run-up machine, stiffened)",
            runup,
            (0.0, 0.0, 0.0, 0.0),
            20,
            4,
            4000,  # the samples resolve the stiff contact for the energy balance
            speed=SpeedProfile.ramp(0.5, 2.0, 0.01),
        ),  # fmt: skip
        StressCase(
            "coast-down-rolling",
            "rolling (stick) while the speed falls: the rolling whirl of nu = 0.01, K = 100, "
            "mu = 0.5, Rp = 2 started at eta = 1, coasting down at -0.005 per tau",
            roll,
            (r_roll, 0.0, 0.0, -roll.Rp * roll.eta),
            20,
            2,
            100,
            speed=SpeedProfile.ramp(1.0, 0.5, -0.005),
        ),  # fmt: skip
        StressCase(
            "driven-dry-whip-stiff",
            "a driven rotor (j = 200, stall torque 4, no-load speed 4) started on a stiff "
            "stator (K = 1.76e3, mu = 0.3), moving backward along it, at eta = 3.5: the "
            "dry whip brakes the drive, in stick and slip",
            whip,
            (1.0, 0.0, 0.0, -5.0),
            20,
            2,
            400,
            drive=Drive(inertia=200.0, start=3.5, stall_torque=4.0, no_load_speed=4.0),
        ),  # fmt: skip
    ]


def _general_machine_cases() -> list[StressCase]:
    """The general machine (docs/machines.md) on a stiff stator, rolling under a load,
    and whirling on its own."""
    offset = ModelParams(nu=0.05, eta=1.1, e=0.1, K=1.76e4, mu=0.1, Rp=3.0, offset=(0.6, 0.0))
    loaded = ModelParams(nu=0.02, eta=1.0, e=0.05, K=100.0, mu=0.5, Rp=2.0, load=(0.0, -3.0),
                         offset=(0.1, 0.0), stiffness=((1.0, 0.05), (-0.05, 1.2)))  # fmt: skip
    crossed = ModelParams(nu=0.01, eta=1.0, e=0.05, K=100.0, mu=0.3, Rp=2.0,
                          stiffness=((1.0, 0.3), (-0.3, 1.2)))  # fmt: skip
    return [
        StressCase(
            "offset-stiff",
            "a misaligned stator (offset 0.6) made stiff, K = 1.76e4: short partial rubs "
            "once per revolution, from rest on the support's centre",
            offset,
            (-0.6, 0.0, 0.0, 0.0),
            periods=20,
            quick_periods=3,
            samples_per_period=2000,  # the samples resolve the stiff contact
        ),
        StressCase(
            "loaded-whip",
            "a load of 3 clearances pressing the rotor into an offset stator (K = 100, "
            "mu = 0.5, anisotropic, cross-coupled support), started rolling backward at the "
            "bottom: stick, slip reversals and bounces",
            loaded,
            (-0.1, -1.02, -2.0, 0.0),
            periods=20,
            quick_periods=1,
            samples_per_period=200,
        ),
        StressCase(
            "cross-whip",
            "cross-coupling q = 0.3 well above its threshold (anisotropic support, nu = "
            "0.01): a self-excited whirl grows into the stator (K = 100, mu = 0.3)",
            crossed,
            (0.9, 0.0, 0.0, 0.0),
            periods=20,
            quick_periods=3,
            samples_per_period=200,
        ),
        StressCase(
            "stiff-ring",
            "a snubber ring with its own mass (0.5) on stiff supports (k_s = 1000, its own "
            "frequency 45 times the rotor's) struck by a stiff contact, K = 1e4, under a load",
            ModelParams(
                nu=0.05,
                eta=1.2,
                e=0.25,
                K=1e4,
                mu=0.1,
                Rp=3.0,
                offset=(0.3, 0.0),
                load=(0.0, -0.2),
                stator=Stator(0.5, (1e3, 1e3), (0.5, 0.5)),
            ),
            (-0.3, -0.2, 0.0, 0.0),
            periods=20,
            quick_periods=3,
            samples_per_period=2000,  # the samples resolve the stiff contact and ring
        ),
    ]


# ----------------------------------------------------------------------------- references


@dataclass
class StressReference:
    label: str
    t: np.ndarray
    states: np.ndarray
    exact: bool = False


def touching_free_flight(problem: Problem, tolerance: float) -> np.ndarray | None:
    """Closed-form free flight at the samples if it never penetrates beyond ``tolerance``.

    Checked on a grid of ``TOUCH_CHECK_POINTS_PER_PERIOD`` points per forcing period: a
    sanity check of a start built to touch, not a proof for an arbitrary start.
    """
    params, t = problem.params, problem.t_eval
    n = max(2, int(math.ceil(problem.periods * TOUCH_CHECK_POINTS_PER_PERIOD)) + 1)
    grid = np.linspace(t[0], t[-1], n)
    for chunk in np.array_split(grid, max(1, n // 200_000)):
        S = model.free_flight(chunk, float(t[0]), problem.initial, params)
        if np.max(np.hypot(S[0], S[1])) - 1.0 > tolerance:
            return None
    return model.free_flight(t, float(t[0]), problem.initial, params).T


def stress_reference(
    case: StressCase,
    problem: Problem,
    budget: dict,
    solve: Callable[..., Solution],
) -> StressReference | None:
    """The best available reference of a case (exact, else a tight dop853/radau run)."""
    exact = exact_reference(problem)
    if exact is not None:
        label = "exact free flight" if exact.kind == EXACT_FREE_FLIGHT else "exact sync rub"
        return StressReference(label, exact.t, exact.states, exact=True)
    if case.touches:
        states = touching_free_flight(problem, tolerance=1e-9)
        if states is not None:
            return StressReference(
                "exact free flight (touching)", problem.t_eval, states, exact=True
            )
    for method, options in REFERENCE_RUNS:
        solution = solve(
            problem, method, **options_for(method, {**SOLVER_OPTIONS, **budget, **options})
        )
        if solution.success and np.all(np.isfinite(solution.states)):
            return StressReference(
                f"{method} rtol={options['rtol']:g}", solution.t, solution.states
            )
    return None


def position_error(solution: Solution, reference: StressReference) -> float | None:
    """max |w - w_ref| over the shared samples (None if they share fewer than two)."""
    n = min(solution.t.size, reference.t.size)
    if n < 2:
        return None
    dw = np.hypot(
        solution.states[:n, 0] - reference.states[:n, 0],
        solution.states[:n, 1] - reference.states[:n, 1],
    )
    return float(np.max(dw)) if np.all(np.isfinite(dw)) else math.inf


# ----------------------------------------------------------------------------------- runs


def measure_run(case: StressCase, solution: Solution, target_periods: float) -> StressRun:
    """A StressRun from a solution (reference error filled in later)."""
    t0, t1 = solution.problem.t_span
    finite = bool(np.all(np.isfinite(solution.states)))
    residual = quadrature = None
    if finite and solution.problem.changes_speed:
        from rubcli.analysis.energy.transient import speed_energy_summary

        summary = speed_energy_summary(solution)
        residual, quadrature = summary["energy_residual"], summary["energy_quadrature_error"]
    elif finite and solution.stator_states is not None:
        from rubcli.analysis.energy.two_body import two_body_energy_summary

        summary = two_body_energy_summary(solution)
        residual, quadrature = summary["energy_residual"], summary["energy_quadrature_error"]
    elif finite:
        balance = energy_balance(solution)
        residual, quadrature = balance.relative_residual, balance.quadrature_error
    regimes = time_in_regimes(solution)
    span = sum(regimes.values())
    done = (float(solution.t[-1]) - t0) / (t1 - t0) if solution.t.size else 0.0
    return StressRun(
        case=case.name,
        method=solution.method,
        status=solution.status,
        message=solution.message,
        wall_time_s=solution.wall_time_s,
        periods=done * target_periods,
        target_periods=target_periods,
        n_steps=solution.stats.get("nsteps"),
        n_events=len(solution.events),
        n_contact_switches=solution.n_contact_switches,
        energy_residual=residual,
        energy_quadrature_error=quadrature,
        max_penetration=solution.max_penetration() if finite else None,
        nan=not finite,
        stick_fraction=regimes["stick"] / span if span > 0 else 0.0,
    )


def method_variants(methods: Iterable[str]) -> list[tuple[str, str, dict]]:
    """(label, method, extra options): every method at the case defaults, and each
    fixed-step method with an adaptive switch (the analytic methods' ``analytic_tol``)
    also with adaptive steps at ``ADAPTIVE_TOL``."""
    variants = []
    for method in methods:
        variants.append((method, method, {}))
        adaptive = SPECS[method].adaptive  # a fixed-step method's adaptive switch
        if adaptive is not None:
            label = f"{method} tol={ADAPTIVE_TOL:g}"
            variants.append((label, method, {adaptive: ADAPTIVE_TOL}))
    return variants


def warning_of(run: StressRun, exact_reference: bool, confirmed_reference: bool = False) -> str:
    """Why a run that reports success should not be trusted ("" if nothing is wrong).

    Its error counts against an exact reference, or a numerical one that another method
    confirms (``confirmed_reference``); against an unconfirmed one (a chaotic case beyond
    its horizon) it is no verdict."""
    if run.status != SUCCESS:
        return ""
    reasons = []
    if run.nan:
        reasons.append("non-finite state")
    if run.energy_residual is not None and not run.energy_residual <= SUSPECT_ENERGY_RESIDUAL:
        reasons.append(f"energy residual {run.energy_residual:.2g}")
    if exact_reference and run.error is not None and not run.error <= SUSPECT_EXACT_ERROR:
        reasons.append(f"error {run.error:.2g} against the exact solution")
    elif confirmed_reference and run.error is not None and not run.error <= SUSPECT_EXACT_ERROR:
        reasons.append(f"error {run.error:.2g} against the confirmed reference")
    return "; ".join(reasons)


def run_case(
    case: StressCase,
    methods: Iterable[str],
    *,
    quick: bool,
    on_run: Callable[[StressRun], None] | None = None,
) -> list[StressRun]:
    """Every method variant on one case, then the reference and each run's error."""
    from rubcli.solvers import solve

    problem = case.problem(quick)
    budget = dict(QUICK_BUDGET) if quick else dict(case.budget)
    runs: list[StressRun] = []
    solutions: dict[str, Solution] = {}
    for label, method, extra in method_variants(methods):
        refused = unsupported(method, case.feature) if case.feature else None
        if refused:
            run = StressRun(
                case=case.name, method=label, status=REFUSED, message=refused,
                wall_time_s=0.0, periods=0.0, target_periods=problem.periods,
            )  # fmt: skip
            runs.append(run)
            if on_run is not None:
                on_run(run)
            continue
        start = time.perf_counter()
        try:
            # a run that blows up is reported in the table, not by numpy warnings
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                solution = solve(
                    problem, method, **options_for(method, {**SOLVER_OPTIONS, **budget, **extra})
                )
        except Exception as exc:  # noqa: BLE001 - a solver that raises is a reported bug
            run = StressRun(
                case=case.name, method=label, status=ERROR,
                message=f"{type(exc).__name__}: {exc}",
                wall_time_s=time.perf_counter() - start, periods=0.0,
                target_periods=problem.periods,
            )  # fmt: skip
        else:
            solutions[label] = solution
            run = measure_run(case, solution, problem.periods)
            run.method = label
        runs.append(run)
        if on_run is not None:
            on_run(run)
    reference = stress_reference(case, problem, budget, solve)
    independent = reference is not None  # not one of the runs it would be confirmed by
    if reference is None:
        reference = _fallback_reference(solutions)
    for run in runs:
        solution = solutions.get(run.method)
        if reference is not None and solution is not None:
            run.reference = reference.label
            run.error = position_error(solution, reference)
    exact = reference is not None and reference.exact
    confirmed = independent and not exact and _confirmed(runs)
    for run in runs:
        run.warning = warning_of(run, exact, confirmed)
    return runs


def _confirmed(runs: list[StressRun]) -> bool:
    """Whether another method of the suite agrees with the reference within CONFIRM_ERROR."""
    return any(
        run.method in CONFIRM_METHODS
        and run.status == SUCCESS
        and run.error is not None
        and run.error <= CONFIRM_ERROR
        for run in runs
    )


def _fallback_reference(solutions: dict[str, Solution]) -> StressReference | None:
    """The suite's own successful dop853 (else radau) run, at the suite's tolerance."""
    for method in ("dop853", "radau"):
        solution = solutions.get(method)
        if solution is not None and solution.status == SUCCESS:
            label = f"{method} rtol={SOLVER_OPTIONS['rtol']:g} (suite run)"
            return StressReference(label, solution.t, solution.states)
    return None


def run_suite(
    cases: Iterable[StressCase],
    methods: Iterable[str],
    *,
    quick: bool,
    on_run: Callable[[StressRun], None] | None = None,
) -> list[StressRun]:
    """Every case with every method; ``on_run`` is called after each run (progress)."""
    methods = list(methods)
    runs: list[StressRun] = []
    for case in cases:
        runs.extend(run_case(case, methods, quick=quick, on_run=on_run))
    return runs


def clean(run: StressRun) -> bool:
    """A run that ended as a user may see it: success, failed with a reason, or refused
    (a method without the case's feature) naming why; no NaN."""
    return run.status in (SUCCESS, "failed", REFUSED) and bool(run.message) and not run.nan

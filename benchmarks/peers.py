"""rubcli against the fastest compiled integrators users know: heyoka and CyRK.

Run from the repository root, with the benchmark extras installed
(``pip install -e ".[bench]"``: heyoka and CyRK, never runtime dependencies):

    python benchmarks/peers.py            # full: 5 repeats, half-decade tolerance ladders
    python benchmarks/peers.py --quick    # 2 repeats, decade ladders, short stiff case

Each peer is driven as its own users would drive it:

- rubcli ``taylor`` and ``dop853-jit``: ``rubcli.solvers.solve`` with ``rtol`` and
  ``atol = rtol * 1e-2`` (every event located, the stick law, the final state only);
  ``analytic-polar`` (the paper's scheme, linearised in polar coordinates, where the
  stator stiffness is exact) on a ladder of fixed steps per period instead of a
  tolerance (its ``tol`` column holds the steps per period);
- heyoka (Taylor method compiled by LLVM): a ``taylor_adaptive`` integrator with
  terminal events (``t_event``: the contact surface z^2 = 1 and, with friction, the slip
  reversal v_r = 0) switching the contact force on or off and the friction sign (runtime
  parameters) in a Python loop, ``tol`` = the ladder's value. It has no stick regime: at
  v_r = 0 it flips the sign;
- heyoka-switched: the cheapest model a heyoka user writes where the slip never reverses
  (the paper's case at mu = 0 and 0.03): two integrators, free flight and contact in
  forward slip, switched at direction-filtered terminal events on the clearance
  (``HeyokaSwitched``). Where it misses an event its error says so, and the row is not
  counted: each target takes each method's cheapest run that reached it;
- CyRK (``nbsolve_ivp``, numba, DOP853): the piecewise right-hand side (contact force
  where z > 1, friction sign(v_r)), no events, ``rtol`` and ``atol = rtol * 1e-2``.

Every run's error is the final-state position error |w - w_ref| against a reference:
rubcli's ``dop853-jit`` at rtol 1e-13 (atol 1e-15); ``taylor`` at rtol 1e-14 gives the
reference's own uncertainty (both printed). For each target error (1e-6, 1e-10) each
method's cheapest setting that reaches it is taken, and the ratios are times measured in
this one run (minimum over the repeats; medians are printed too). The repeats are taken
round-robin over every method and setting of a case (one run of each per round), so a
slower or faster spell of the shared machine falls on all of them alike. The integrators'
one-off costs (numba and LLVM compilation, building heyoka's integrators) are measured
apart and are in no row. A method that stalls (chatter at a stick) is stopped by its
budget (``--budget`` seconds per run, or CyRK's step limit) and reported as such.

Cases: the paper's Figure 3 case (K = 17.6, 100 forcing periods) with mu = 0 and 0.03;
with mu = 0.05 the dry whip (stick phases), 100 periods from the state the Figure 3
start reaches at period 67 (``dry_whip_start`` says why); and persistent stiff contact
at K = 1.75e6 (the synchronous rub perturbed as in ``work_precision.py``, 10 periods:
the explicit methods need some 1300 steps per time unit there).

The tables are printed and written to ``benchmarks/peers[-quick][-TAG].md`` and ``.csv``.
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from machine import describe
from work_precision import FIG3, START, near_rub_start

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve

HERE = Path(__file__).resolve().parent
TARGETS = (1e-6, 1e-10)
RUBCLI = ("taylor", "analytic-polar", "dop853-jit")
FIXED_STEP = {"analytic-polar"}  # ladders of steps per period, not of tolerances
PEERS = ("heyoka", "heyoka-switched", "cyrk")
ATOL_FACTOR = 1e-2
REFERENCE_RTOL, REFERENCE_ATOL = 1e-13, 1e-15
CHECK_RTOL = 1e-14  # taylor at this rtol: the reference's own uncertainty
CYRK_MAX_STEPS = 1_000_000
HEYOKA_MAX_EVENTS = 50_000


@dataclass(frozen=True)
class Case:
    label: str
    K: float
    mu: float
    start: str  # "fig3", "dry-whip" or "near-rub"
    periods: float

    @property
    def params(self) -> ModelParams:
        return ModelParams(K=self.K, mu=self.mu, **FIG3)

    def problem(self) -> Problem:
        p = self.params
        if self.start == "dry-whip":
            initial = dry_whip_start(p)
        else:
            initial = START if self.start == "fig3" else near_rub_start(p)
        # the final state only, as the peers give it (no sample output on either side)
        t_end = self.periods * p.period
        return Problem(p, initial, np.array([0.0, t_end]), name=self.label)


DRY_WHIP_LEAD = 67  # periods: the Figure 3 start with mu = 0.05 first sticks at 68.3


def dry_whip_start(params: ModelParams) -> tuple[float, ...]:
    """The state after DRY_WHIP_LEAD periods from the Figure 3 start (dop853-jit, 1e-13).

    From the Figure 3 start itself the mu = 0.05 run is a chaotic transient for some 60
    periods (runs at different tolerances part there and stick at different times, a
    1e-14 and a 1e-13 reference differ by 0.7 at period 100), so no method has a
    final-state error to speak of over it. From period 67 the rotor falls into the dry
    whip within two periods, stick and slip alternating, and stays in it.
    """
    lead = Problem.from_periods(params, START, DRY_WHIP_LEAD, 1)
    state = solve(lead, "dop853-jit", rtol=REFERENCE_RTOL, atol=REFERENCE_ATOL).states[-1]
    return tuple(float(v) for v in state)


def cases(quick: bool) -> list[Case]:
    return [
        Case("K=17.6 mu=0", 17.6, 0.0, "fig3", 100),
        Case("K=17.6 mu=0.03", 17.6, 0.03, "fig3", 100),
        Case("K=17.6 mu=0.05 dry whip (stick), from period 67", 17.6, 0.05, "dry-whip", 100),
        Case("K=1.75e6 mu=0 persistent contact", 1.75e6, 0.0, "near-rub", 2 if quick else 10),
    ]


@dataclass
class Row:
    case: str
    method: str
    tol: float
    time_min_s: float
    time_median_s: float
    cpu_min_s: float
    repeats: int
    error: float
    status: str
    steps: int | None = None
    events: int | None = None
    note: str = ""
    times: list[float] = field(default_factory=list, repr=False)


# ------------------------------------------------------------------------- the peers


def support_terms(params: ModelParams, x, y, vx, vy) -> tuple:
    """The general machine's force beyond the paper's, ``model.support_extra``, as heyoka
    expressions: ``g - S c - (S - I) d - 2 (D - nu I) d'``."""
    r = model.params_vector(params)
    ex = (r[model.P_GX] - r[model.P_SXX] * x - r[model.P_SXY] * y
          - 2.0 * (r[model.P_DXX] * vx + r[model.P_DXY] * vy))  # fmt: skip
    ey = (r[model.P_GY] - r[model.P_SYX] * x - r[model.P_SYY] * y
          - 2.0 * (r[model.P_DYX] * vx + r[model.P_DYY] * vy))  # fmt: skip
    return ex, ey


class Heyoka:
    """heyoka driven as its users would: one integrator whose contact force is switched
    on and off by a runtime parameter (and its friction sign by another) at terminal
    events, in a Python loop.

    Two integrators (free, contact) switched at the events were tried first: a contact
    exit located with z^2 - 1 = 0.0 exactly made the free integrator miss the next entry
    (its event function is zero at its start), on the paper's case at tol <= 1e-8. One
    integrator keeps heyoka's own cooldown, which handles the restart on the surface.

    ``rate``: a speed ramping from ``params.eta`` at tau = 0 (benchmarks/runup.py), the
    right-hand side then depending on time through the phase, the speed and the
    unbalance's tangential term.
    """

    def __init__(self, params: ModelParams, tol: float, rate: float = 0.0):
        import heyoka as hy

        self.hy = hy
        x, y, vx, vy = hy.make_vars("x", "y", "vx", "vy")
        nu, eta, E, phi0, K, mu, Rp = model.params_vector(params)[:7]  # nu .. Rp
        z = hy.sqrt(x * x + y * y)
        fac = hy.par[1] * K * (1.0 - 1.0 / z)  # par[1]: 1 in contact, 0 in free flight
        mu_c = hy.par[0]
        if rate == 0.0:
            phase = eta * hy.time + phi0
            fx, fy, spin = E * hy.cos(phase), E * hy.sin(phase), Rp * eta
        else:  # a ramp from eta at tau = 0 (benchmarks/runup.py): the time in the forcing
            e, t = params.e, hy.time
            phase = eta * t + 0.5 * rate * t * t + phi0
            w = eta + rate * t
            c, s = hy.cos(phase), hy.sin(phase)
            fx, fy, spin = e * (w * w * c + rate * s), e * (w * w * s - rate * c), Rp * w
        ax = fx - 2.0 * nu * vx - x - fac * (x - mu_c * y)
        ay = fy - 2.0 * nu * vy - y - fac * (y + mu_c * x)
        if not params.is_paper_machine:  # the paper's model stays term for term
            ex, ey = support_terms(params, x, y, vx, vy)
            ax, ay = ax + ex, ay + ey
        system = [(x, vx), (y, vy), (vx, ax), (vy, ay)]
        self.rate = rate
        events = [hy.t_event(x * x + y * y - 1.0)]
        if mu > 0.0:
            events.append(hy.t_event(spin + (x * vy - y * vx) / z))
        self.ta = hy.taylor_adaptive(system, [0.0] * 4, tol=tol, pars=[0.0, 0.0], t_events=events)
        self.params = params

    def run(self, initial, t_end: float, budget_s: float):
        """(final state, events, steps, status, note)."""
        p, ta = self.params, self.ta
        ta.time = 0.0
        ta.state[:] = np.array(initial, dtype=float)
        ta.reset_cooldowns()
        regime = model.regime_of_state(np.array(initial, dtype=float), p)
        n_events = steps = 0
        start = time.perf_counter()
        while True:
            ta.pars[0] = p.mu * float(regime) if regime != model.FREE else 0.0
            ta.pars[1] = 0.0 if regime == model.FREE else 1.0
            outcome, _, _, n_steps, *_ = ta.propagate_until(t_end)
            steps += int(n_steps)
            t, s = float(ta.time), ta.state
            code = int(outcome)
            if outcome == self.hy.taylor_outcome.time_limit or t >= t_end:
                return np.array(s), n_events, steps, "success", ""
            if not -100 < code < 0:
                return np.array(s), n_events, steps, "failed", f"outcome {outcome} at t = {t:.6g}"
            index = -code - 1
            if index == 0:  # the contact surface, either way
                if regime != model.FREE:
                    regime = model.FREE
                else:  # entry: slip direction by v_r
                    v_r = model.slip_velocity(*map(float, s), p.Rp, p.eta + self.rate * t)
                    regime = model.SLIP_POSITIVE if (p.mu == 0.0 or v_r >= 0.0) else -1
                n_events += 1
            elif regime != model.FREE:  # slip reversal: no stick here, the sign flips
                regime = -regime
                n_events += 1
            if n_events >= HEYOKA_MAX_EVENTS or time.perf_counter() - start > budget_s:
                what = "event limit" if n_events >= HEYOKA_MAX_EVENTS else "time budget"
                return (
                    np.array(s), n_events, steps, "stalled",
                    f"{what}: {n_events} events, stopped at t = {t:.6g} "
                    f"({t / p.period:.3g} of {t_end / p.period:.3g} periods)",
                )  # fmt: skip


class HeyokaSwitched:
    """heyoka with the cheapest model a heyoka user writes for a case whose slip never
    reverses (the paper's case at mu = 0 and 0.03): two integrators, free flight (no
    contact term at all) and contact in forward slip (the contact force with mu_c = +mu,
    no runtime parameter), switched at terminal events on the clearance, each event
    function filtered by its direction: the free integrator stops where z^2 - 1 rises
    through zero, the contact one where it falls through zero. heyoka misses every later
    crossing of an event function that is exactly zero at an integrator's start (a contact
    exit located to z^2 - 1 = 0.0 left the free integrator blind to the next entry), so a
    switch moves the state by 4 ulp off the surface, to the side of the new regime: far
    below the errors measured. The model cannot notice a slip reversal or a stick: where
    the case has one, its error against the reference says so, and ``Heyoka`` (one
    integrator, switched parameters) is the model to use.
    """

    def __init__(self, params: ModelParams, tol: float):
        import heyoka as hy

        self.hy = hy
        x, y, vx, vy = hy.make_vars("x", "y", "vx", "vy")
        nu, eta, E, phi0, K, mu, Rp = model.params_vector(params)[:7]  # nu .. Rp
        phase = eta * hy.time + phi0
        fx, fy = E * hy.cos(phase) - 2.0 * nu * vx - x, E * hy.sin(phase) - 2.0 * nu * vy - y
        if not params.is_paper_machine:
            ex, ey = support_terms(params, x, y, vx, vy)
            fx, fy = fx + ex, fy + ey
        fac = K * (1.0 - 1.0 / hy.sqrt(x * x + y * y))
        free = [(x, vx), (y, vy), (vx, fx), (vy, fy)]
        contact = [(x, vx), (y, vy), (vx, fx - fac * (x - mu * y)), (vy, fy - fac * (y + mu * x))]
        surface = x * x + y * y - 1.0
        rising = [hy.t_event(surface, direction=hy.event_direction.positive)]
        falling = [hy.t_event(surface, direction=hy.event_direction.negative)]
        self.free = hy.taylor_adaptive(free, [0.0] * 4, tol=tol, t_events=rising)
        self.contact = hy.taylor_adaptive(contact, [0.0] * 4, tol=tol, t_events=falling)
        self.params = params

    def run(self, initial, t_end: float, budget_s: float):
        """(final state, events, steps, status, note)."""
        t, state = 0.0, np.array(initial, dtype=float)
        in_contact = model.regime_of_state(state[:4], self.params) != model.FREE
        n_events = steps = 0
        start = time.perf_counter()
        while True:
            ta = self.contact if in_contact else self.free
            # at least 4 ulp off the surface, to the new regime's side (a state inside by
            # less, its event function zero to round-off, hid the next crossing too)
            z2 = state[0] ** 2 + state[1] ** 2
            target = 1.0 + (4.0 if in_contact else -4.0) * np.finfo(float).eps
            if (z2 <= target) if in_contact else (z2 >= target):
                state[:2] *= np.sqrt(target / z2)
            ta.time = t
            ta.state[:] = state
            ta.reset_cooldowns()
            outcome, _, _, n_steps, *_ = ta.propagate_until(t_end)
            steps += int(n_steps)
            t, state = float(ta.time), np.array(ta.state)
            if outcome == self.hy.taylor_outcome.time_limit or t >= t_end:
                return state, n_events, steps, "success", ""
            if not -100 < int(outcome) < 0:
                return state, n_events, steps, "failed", f"outcome {outcome} at t = {t:.6g}"
            in_contact = not in_contact
            n_events += 1
            if n_events >= HEYOKA_MAX_EVENTS or time.perf_counter() - start > budget_s:
                what = "event limit" if n_events >= HEYOKA_MAX_EVENTS else "time budget"
                return state, n_events, steps, "stalled", f"{what} at t = {t:.6g}"


def cyrk_rhs():
    import numba

    @numba.njit(cache=True)
    def rhs(t, s, nu, eta, E, phi0, K, mu, Rp):
        x, y, vx, vy = s[0], s[1], s[2], s[3]
        ds = np.empty(4)
        phase = eta * t + phi0
        ax = E * math.cos(phase) - 2.0 * nu * vx - x
        ay = E * math.sin(phase) - 2.0 * nu * vy - y
        z = math.sqrt(x * x + y * y)
        if z > 1.0:
            v_r = Rp * eta + (x * vy - y * vx) / z
            mu_c = mu if v_r > 0.0 else (-mu if v_r < 0.0 else 0.0)
            fac = K * (1.0 - 1.0 / z)
            ax -= fac * (x - mu_c * y)
            ay -= fac * (y + mu_c * x)
        ds[0], ds[1], ds[2], ds[3] = vx, vy, ax, ay
        return ds

    return rhs


def run_cyrk(rhs, params: ModelParams, initial, t_end: float, tol: float):
    from CyRK import nbsolve_ivp

    result = nbsolve_ivp(
        rhs, (0.0, t_end), np.array(initial, dtype=float), args=model.params_vector(params)[:7],
        rtol=tol, atol=tol * ATOL_FACTOR, rk_method=2, max_num_steps=CYRK_MAX_STEPS,
        warnings=False,
    )  # fmt: skip
    status = "success" if result.success and result.t[-1] >= t_end else "stalled"
    note = "" if status == "success" else f"{result.message} at t = {result.t[-1]:.6g}"
    return result.y[:, -1], int(result.size), status, note


# ----------------------------------------------------------------------- measurement


def ladder(quick: bool, stiff: bool) -> list[float]:
    lo = 11 if stiff else 13
    if quick:
        return [10.0**-k for k in range(4, lo + 1, 2)] + ([1e-13] if not stiff else [])
    return [10.0 ** (-k / 2) for k in range(8, 2 * lo + 1)]


def timed_once(fn):
    """(result, wall time, CPU time) of one run."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def steps_ladder(quick: bool) -> list[float]:
    """Steps per forcing period for the fixed-step methods."""
    if quick:
        return [10.0, 100.0, 1000.0]
    return [5.0, 10.0, 25.0, 50.0, 100.0, 200.0, 400.0, 800.0, 1600.0, 3200.0, 6400.0]


def final_error(state, ref_state) -> float:
    return float(abs(complex(state[0], state[1]) - complex(ref_state[0], ref_state[1])))


@dataclass
class Setting:
    """One method at one setting: ``run()`` -> (final state or None, steps, events,
    status, note), and its times over the repeats."""

    method: str
    tol: float
    run: object
    result: tuple | None = None
    times: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)


def measure_case(case: Case, quick: bool, repeats: int, budget: float, log) -> dict:
    """Every method's ladder on one case. A first pass runs each setting once (its error,
    steps, events, status; a fixed-step ladder stops where finer steps only cost more);
    then the settings that finished in under a quarter of the budget are timed again
    round-robin, one run of each per round, so that a slower or faster spell of the
    shared machine falls on every method alike (the ratios are what the targets ask)."""
    problem = case.problem()
    params, t_end = problem.params, float(problem.t_eval[-1])
    ref = solve(problem, "dop853-jit", rtol=REFERENCE_RTOL, atol=REFERENCE_ATOL)
    check = solve(problem, "taylor", rtol=CHECK_RTOL, atol=CHECK_RTOL * 1e-2)
    ref_state = ref.states[-1]
    spread = final_error(check.states[-1], ref_state)
    log(
        f"\n## {case.label}: {case.periods:g} periods, reference dop853-jit rtol 1e-13 "
        f"({ref.wall_time_s:.2f} s, {len(ref.events)} events); taylor rtol 1e-14 differs "
        f"by {spread:.1e}"
    )
    setup: dict[str, float] = {}
    tols = ladder(quick, case.K > 1e3)

    def rubcli_run(method, opts):
        def run():
            sol = solve(problem, method, **opts)
            state = sol.states[-1] if sol.success else None
            status = "success" if sol.success else "stalled"
            note = "" if sol.success else sol.message
            return state, sol.stats.get("nsteps"), len(sol.events), status, note

        return run

    def first_pass(setting: Setting) -> None:
        setting.result, wall, cpu = timed_once(setting.run)
        setting.times.append(wall)
        setting.cpu.append(cpu)

    settings: list[Setting] = []
    for method in RUBCLI:
        fixed = method in FIXED_STEP
        t0 = time.perf_counter()
        warm = {"steps_per_period": 10} if fixed else {"rtol": 1e-3, "atol": 1e-5}
        solve(problem, method, **warm)  # warm-up: numba cache load
        setup[method] = time.perf_counter() - t0
        for tol in steps_ladder(quick) if fixed else tols:
            if fixed:
                opts = {"steps_per_period": int(tol), "max_wall_time_s": budget}
            else:
                opts = {"rtol": tol, "atol": tol * ATOL_FACTOR, "max_wall_time_s": budget}
            setting = Setting(method, tol, rubcli_run(method, opts))
            first_pass(setting)
            settings.append(setting)
            state = setting.result[0]
            err = final_error(state, ref_state) if state is not None else math.inf
            if fixed and (setting.times[0] > budget / 4 or err < min(TARGETS) / 10):
                break  # finer steps only cost more (or the targets are reached already)

    t0 = time.perf_counter()
    rhs = cyrk_rhs()
    run_cyrk(rhs, params, problem.initial, 1.0, 1e-3)  # numba compilation / cache load
    setup["cyrk"] = time.perf_counter() - t0
    for tol in tols:

        def cyrk_run(tol=tol):
            state, steps, status, note = run_cyrk(rhs, params, problem.initial, t_end, tol)
            return state, steps, None, status, note

        setting = Setting("cyrk", tol, cyrk_run)
        first_pass(setting)
        settings.append(setting)

    for name, model_class in (("heyoka", Heyoka), ("heyoka-switched", HeyokaSwitched)):
        build = 0.0
        for tol in tols:
            t0 = time.perf_counter()
            integrator = model_class(params, tol)
            build += time.perf_counter() - t0

            def heyoka_run(integrator=integrator):
                state, events, steps, status, note = integrator.run(problem.initial, t_end, budget)
                return state, steps, events, status, note

            setting = Setting(name, tol, heyoka_run)
            first_pass(setting)
            settings.append(setting)
        setup[name] = build

    timed_again = [s for s in settings if s.result[3] == "success" and s.times[0] <= budget / 4]
    for _ in range(repeats - 1):
        for setting in timed_again:
            _, wall, cpu = timed_once(setting.run)
            setting.times.append(wall)
            setting.cpu.append(cpu)

    rows: list[Row] = []
    for st in settings:
        state, steps, events, status, note = st.result
        err = final_error(state, ref_state) if state is not None else math.nan
        row = Row(
            case.label, st.method, st.tol, min(st.times), statistics.median(st.times),
            min(st.cpu), len(st.times), err, status, steps, events, note, st.times,
        )  # fmt: skip
        rows.append(row)
        setting = f"spp {st.tol:7.0f}" if st.method in FIXED_STEP else f"tol {st.tol:8.1e}"
        log(
            f"  {st.method:14s} {setting}  {row.time_min_s * 1e3:9.3f} ms "
            f"(median {row.time_median_s * 1e3:9.3f}, cpu {row.cpu_min_s * 1e3:9.3f})  "
            f"error {err:8.1e}  steps {steps}  events {events}  {status} {note}"
        )
    return {"case": case, "rows": rows, "setup": setup, "spread": spread, "ref": ref}


def _time(row: Row, clock: str) -> float:
    return row.time_min_s if clock == "wall" else row.cpu_min_s


def cheapest(rows: list[Row], method: str, target: float, clock: str = "wall") -> Row | None:
    ok = [r for r in rows if r.method == method and r.status == "success" and r.error <= target]
    return min(ok, key=lambda r: _time(r, clock)) if ok else None


def summary(result: dict) -> list[str]:
    case, rows, spread = result["case"], result["rows"], result["spread"]
    lines = [
        f"### {case.label} ({case.periods:g} forcing periods)",
        "",
        f"Reference uncertainty (taylor rtol 1e-14 vs dop853-jit rtol 1e-13): {spread:.1e}. "
        "One-off setup, not in any row: "
        + ", ".join(f"{m} {s:.2f} s" for m, s in result["setup"].items())
        + ".",
        "",
        "| target error | "
        + " | ".join(RUBCLI + PEERS)
        + " | fastest rubcli | "
        + " | ".join(f"{peer} / fastest" for peer in PEERS)
        + " |",
        "|---|" + "---|" * (len(RUBCLI) + 2 * len(PEERS) + 1),
        "",
    ]
    table = lines[-3:-1]
    lines = lines[:-3]
    for clock in ("wall", "cpu"):
        lines += [f"Time: {clock} clock, minimum over the repeats.", ""] + table
        for target in TARGETS:
            cells, best = [], {}
            for method in RUBCLI + PEERS:
                row = cheapest(rows, method, target, clock)
                best[method] = row
                if row is None:
                    cells.append("not reached")
                else:
                    setting = (
                        f"{row.tol:.0f} steps/period"
                        if method in FIXED_STEP
                        else f"tol {row.tol:.0e}"
                    )
                    cells.append(
                        f"{_time(row, clock) * 1e3:.2f} ms ({setting}, err {row.error:.0e})"
                    )
            ours = [best[m] for m in RUBCLI if best[m] is not None]
            fastest = min(ours, key=lambda r: _time(r, clock)) if ours else None
            ratios = [fastest.method if fastest else "none"]
            for peer in PEERS:
                if fastest is None or best[peer] is None:
                    ratios.append("-")
                else:
                    ratio = _time(best[peer], clock) / _time(fastest, clock)
                    ratios.append(f"{ratio:.1f}x")
            if target < 10 * spread:
                cells[0] += " (below 10x the reference uncertainty)"
            lines.append(f"| {target:.0e} | " + " | ".join(cells + ratios) + " |")
        lines.append("")
    stalled = [r for r in rows if r.status != "success"]
    if stalled:
        lines += ["", "Runs that did not finish:", ""]
        for r in stalled:
            lines.append(
                f"- {r.method} tol {r.tol:.0e}: {r.status} after {r.time_min_s:.2f} s; {r.note}"
            )
    return lines + [""]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=None)
    ap.add_argument("--budget", type=float, default=10.0, help="seconds per run")
    ap.add_argument("--case", type=int, action="append", help="case index (0-3); repeatable")
    ap.add_argument("--tag", default="", help="suffix of the output files (a subset run)")
    args = ap.parse_args(argv)
    repeats = args.repeats or (2 if args.quick else 5)
    lines: list[str] = []

    def log(msg: str) -> None:
        print(msg, flush=True)

    selected = cases(args.quick)
    if args.case:
        selected = [selected[i] for i in args.case]
    command = "python benchmarks/peers.py " + " ".join(sys.argv[1:] if argv is None else argv)
    lines += [
        "# rubcli against heyoka and CyRK",
        "",
        f"Command: `{command.strip()}`",
        "",
        describe(),
        "",
        "All methods measured in this one process, on a machine shared with other jobs:",
        "wall-clock minimum over the repeats, and the CPU time (process_time) minimum.",
        "",
    ]
    all_rows: list[Row] = []
    for case in selected:
        result = measure_case(case, args.quick, repeats, args.budget, log)
        all_rows += result["rows"]
        lines += summary(result)
        print("\n".join(summary(result)), flush=True)
    tag = ("-quick" if args.quick else "") + (f"-{args.tag}" if args.tag else "")
    (HERE / f"peers{tag}.md").write_text("\n".join(lines) + "\n")
    with open(HERE / f"peers{tag}.csv", "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(
            ["case", "method", "tol", "time_min_s", "time_median_s", "cpu_min_s", "repeats",
             "error", "status", "steps", "events", "note"]
        )  # fmt: skip
        for r in all_rows:
            writer.writerow(
                [r.case, r.method, r.tol, r.time_min_s, r.time_median_s, r.cpu_min_s,
                 r.repeats, r.error, r.status, r.steps, r.events, r.note]
            )  # fmt: skip
    print(f"\nwrote {HERE / f'peers{tag}.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""One point of a sweep: solve the transient and the recorded window, then analyse it.

``compute_point`` is what every executor runs (in this process, in a pool worker, on a
Dask worker): a plain function of picklable data that never raises for a failed point;
the failure is a result with ``ok = False`` and its reason.

The run is split in two solves, both starting at tau = 0: the transient
(``transient_periods``, only its final state is kept) and the recorded window
(``record_periods`` at ``samples_per_period``). The forcing has period T = 2 pi / eta, and
both spans are whole periods, so restarting the clock at 0 changes nothing in the
dynamics; it lets every measure (contact and stick fractions, switches, energy) be taken
over the recorded window alone. The stroboscopic section is the recorded samples at
k T, k = 1 ... record_periods: samples, not interpolated.
"""

from __future__ import annotations

import dataclasses
import math
import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from rubcli.analysis.response import classification as rsp
from rubcli.analysis.response.spectrum import BACKWARD, FORWARD, full_spectrum
from rubcli.model import ModelParams
from rubcli.problem import Problem

# Scalar results of a point, in the order of the CSV columns, with their meaning (units
# in clearances and units of tau). Integers are stored as floats in the arrays (NaN =
# not computed) except where noted in WHOLE.
SCALARS = {
    "z_min": "smallest radial displacement z over the recorded window (clearances)",
    "z_max": "largest radial displacement z over the recorded window (clearances)",
    "contact_fraction": "fraction of the recorded time in contact (from located events)",
    "stick_fraction": "fraction of the recorded time in stick (rolling without slip)",
    "n_contact_switches": "contact entries and exits in the recorded window",
    "whirl_order": "dominant line of the full spectrum of x + i y, in orders of eta "
    "(+1 synchronous forward, negative backward)",
    "whirl_omega": "dominant whirl frequency, rad per unit tau (negative backward)",
    "whirl_amplitude": "whirl radius of the dominant line (clearances)",
    "whirl_direction": "+1 forward, -1 backward, 0 no whirl (static)",
    "static_offset": "amplitude of the 0X line (static offset of the orbit)",
    "response_class": "0 periodic, 1 quasi-periodic, 2 chaotic, 3 unbounded, 4 undecided, "
    "5 converging",
    "response_period": "period of a periodic response, or of the orbit a converging one "
    "approaches, in forcing periods",
    "contraction_rate": "factor by which the section map contracts a period where it decided "
    "in its linear regime (< 1 converging, > 1 leaving, 1 a small torus)",
    "contraction_rate_stderr": "uncertainty of the contraction rate",
    "rotation_number": "rotation of the section per forcing period, in turns (linear fit or "
    "the dominant refined frequency)",
    "frequency_diffusion": "drift of the section's dominant frequency between the halves of "
    "the record, turns per period (small on a torus)",
    "lyapunov": "largest Lyapunov exponent, per unit tau (when asked and needed)",
    "lyapunov_stderr": "standard error of the Lyapunov exponent",
    "energy_residual": "relative energy-balance residual of the recorded window",
    "nsteps": "solver steps (transient + record)",
}
EVIDENCE = (
    "contraction_rate",
    "contraction_rate_stderr",
    "rotation_number",
    "frequency_diffusion",
    "lyapunov",
    "lyapunov_stderr",
)  # from Response.evidence
WHOLE = ("n_contact_switches", "whirl_direction", "response_class", "response_period", "nsteps")
RESPONSE_CLASSES = rsp.KINDS  # index = response_class code
DIRECTION_CODES = {FORWARD: 1, BACKWARD: -1}
# The Lyapunov pair runs on the compiled DOP853 (rtol 1e-10, as classify_solution sets):
# the same algorithm as scipy's dop853, an order of magnitude faster per point.
LYAPUNOV_METHOD = "dop853-jit"


@dataclass(frozen=True)
class PointTask:
    """What a worker needs for one point (small, picklable)."""

    params: ModelParams
    start: tuple[float, float, float, float]
    transient_periods: int
    record_periods: int
    samples_per_period: int
    method: str
    options: dict
    energy: bool = True
    spectrum: bool = False
    spectrum_max_order: float = 3.0
    lyapunov: bool = False
    lyapunov_periods: int = 100


@dataclass
class PointResult:
    """The results of one point: scalars, section, final state, optional spectrum."""

    ok: bool
    message: str
    scalars: dict[str, float] = field(default_factory=dict)
    section: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))  # (R, 4)
    final_state: tuple[float, float, float, float] | None = None
    spectrum: np.ndarray | None = None  # amplitudes on the fixed order grid
    wall_time_s: float = 0.0  # compute time of the point (not part of the saved numbers)

    def scalar(self, name: str) -> float:
        return float(self.scalars.get(name, math.nan))


def spectrum_orders(record_periods: int, max_order: float) -> np.ndarray:
    """The order grid of a point's kept spectrum: k / record_periods, |order| <= max_order.

    The record is a whole number of forcing periods, so the bins of every point fall on
    the same orders whatever eta: the spectra of a speed sweep share one axis.
    """
    kmax = int(math.floor(max_order * record_periods + 1e-9))
    return np.arange(-kmax, kmax + 1) / record_periods


def failed(message: str, wall_time_s: float = 0.0) -> PointResult:
    return PointResult(False, message, wall_time_s=wall_time_s)


def compute_point(task: PointTask) -> PointResult:
    """Solve and analyse one point; a failure is returned, never raised."""
    started = time.perf_counter()
    try:
        result = _compute(task)
    except Exception as exc:  # a point that fails never stops the sweep
        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f"{last.filename.rsplit('/', 1)[-1]}:{last.lineno}"
        result = failed(f"{type(exc).__name__}: {exc} ({where})")
    result.wall_time_s = time.perf_counter() - started
    return result


def compute_points(tasks: list[PointTask]) -> list[PointResult]:
    """Several points in one task (points of different chains; fewer round trips)."""
    return [compute_point(task) for task in tasks]


def _solve(params: ModelParams, start, periods: int, spp: int, task: PointTask):
    from rubcli.solvers import solve

    problem = Problem.from_periods(params, start[:4], periods, spp, name="sweep-point")
    if len(start) == 8:  # a stator with its own mass: its state goes on too
        problem = dataclasses.replace(problem, stator_initial=tuple(start[4:]))
    return solve(problem, task.method, **task.options)


def _last_state(sol) -> tuple[float, ...]:
    """The run's last state: the rotor's, and a moving stator's after it."""
    last = [float(v) for v in sol.states[-1]]
    if sol.stator_states is not None:
        last += [float(v) for v in sol.stator_states[-1]]
    return tuple(last)


def _compute(task: PointTask) -> PointResult:
    from rubcli.analysis.energy.balance import energy_balance
    from rubcli.analysis.energy.regimes import time_in_regimes

    p, spp, record = task.params, task.samples_per_period, task.record_periods
    state = task.start
    nsteps = 0
    if task.transient_periods > 0:
        sol = _solve(p, state, task.transient_periods, 1, task)
        nsteps += int(sol.stats.get("nsteps", 0))
        if not sol.success:
            return failed(f"transient: {sol.message}")
        state = _last_state(sol)
    sol = _solve(p, state, record, spp, task)
    nsteps += int(sol.stats.get("nsteps", 0))
    if not sol.success:
        return failed(f"record: {sol.message}")
    states = np.asarray(sol.states, dtype=float)
    if not np.all(np.isfinite(states)):
        return failed("record: non-finite states")
    section = states[spp::spp].copy()
    z = sol.z
    span = float(sol.t[-1] - sol.t[0])
    stick = time_in_regimes(sol)["stick"] / span
    spec = full_spectrum(sol.t[:-1], sol.w[:-1], p.eta)
    response = rsp.classify_solution(
        sol,
        transient_periods=0.0,
        lyapunov=task.lyapunov,
        lyapunov_periods=task.lyapunov_periods,
        lyapunov_method=LYAPUNOV_METHOD,
    )
    evidence = response.evidence()
    scalars = {
        "z_min": float(np.min(z)),
        "z_max": float(np.max(z)),
        "contact_fraction": float(sol.contact_fraction()),
        "stick_fraction": float(stick),
        "n_contact_switches": float(sol.n_contact_switches),
        "whirl_order": spec.dominant_order,
        "whirl_omega": spec.dominant_omega,
        "whirl_amplitude": spec.dominant_amplitude,
        "whirl_direction": float(DIRECTION_CODES.get(spec.direction, 0)),
        "static_offset": spec.static_offset,
        "response_class": float(RESPONSE_CLASSES.index(response.kind)),
        "response_period": math.nan if response.period is None else float(response.period),
        **{name: float(evidence[name]) for name in EVIDENCE},
        "energy_residual": math.nan,
        "nsteps": float(nsteps),
    }
    if task.energy and sol.stator_states is not None:
        from rubcli.analysis.energy.two_body import two_body_energy_summary

        scalars["energy_residual"] = float(two_body_energy_summary(sol)["energy_residual"])
    elif task.energy:
        scalars["energy_residual"] = float(energy_balance(sol).relative_residual)
    kept = None
    if task.spectrum:
        orders = spectrum_orders(record, task.spectrum_max_order)
        bins = np.rint(spec.order * record).astype(int)
        lookup = dict(zip(bins.tolist(), spec.amplitude.tolist(), strict=True))
        kept = np.array([lookup.get(int(round(o * record)), 0.0) for o in orders])
    final = _last_state(sol)
    return PointResult(True, response.message, scalars, section, final, kept)  # type: ignore[arg-type]

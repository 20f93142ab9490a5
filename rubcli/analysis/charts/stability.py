"""Closed-form stability charts of the synchronous motions in a parameter plane.

On the isotropic machine the two synchronous motions are known exactly (model notes,
section 5), so their existence and stability in any plane of two parameters need no
integration:

- the **free whirl** ``W = E / (1 - eta^2 + 2 i nu eta)`` exists while ``|W| <= 1`` and is
  always stable (a damped linear oscillator); its **grazing** curve is ``|W| = 1``, i.e.
  ``e^2 eta^4 = (1 - eta^2)^2 + (2 nu eta)^2``;
- the **synchronous forward rub** of radius ``r > 1`` solves the quadratic
  ``(a^2 + b^2) r^2 - 2 K (a + mu b) r + K^2 (1 + mu^2) - E^2 = 0`` with
  ``a = 1 - eta^2 + K``, ``b = 2 nu eta + mu K``; its **fold** curve is where the
  quadratic has a double root ``r_f = K (a + mu b) / (a^2 + b^2) > 1`` (discriminant
  ``K^2 (a + mu b)^2 - (a^2 + b^2) (K^2 (1 + mu^2) - E^2) = 0``); its **stability** is that
  of the equilibrium in the frame turning with the forcing
  (``rubcli.analysis.orbits.synchronous``), and its **stability boundary** is where the largest
  real part of those eigenvalues crosses zero (a Neimark-Sacker point of the stroboscopic
  map when the crossing pair is complex).

Each point of the plane is put in one region: free whirl only, synchronous rub only, both
(the hysteresis band of a run-up and run-down), or neither (no stable synchronous motion:
the rotor is in a partial rub, a torus, or dry whip; which of them takes a simulation).
The curves here are the reference against which continued curves are checked.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import brentq

from rubcli import model
from rubcli.analysis.orbits.synchronous import synchronous_rubs
from rubcli.model import ModelParams

if TYPE_CHECKING:
    import xarray as xr

NEITHER, FREE, RUB, BOTH = 0, 1, 2, 3
REGIONS = {
    NEITHER: "no stable synchronous motion (partial rub, torus or dry whip)",
    FREE: "free whirl",
    RUB: "synchronous rub",
    BOTH: "free whirl and synchronous rub (hysteresis)",
}
FREE_GRAZING, RUB_FOLD, RUB_STABILITY = "free_grazing", "rub_fold", "rub_stability"
CURVE_KINDS = (FREE_GRAZING, RUB_FOLD, RUB_STABILITY)


def _with(params: ModelParams, **values: float) -> ModelParams:
    return dataclasses.replace(params, **{k: float(v) for k, v in values.items()})


def free_radius(params: ModelParams) -> float:
    """|W| of the free synchronous whirl (clearances)."""
    w, _ = model.free_steady_state(0.0, params)
    return float(abs(w))


def free_grazing_speeds(nu: float, e: float) -> list[float]:
    """The speed ratios eta > 0 at which the free whirl touches the stator, ascending.

    ``e^2 eta^4 = (1 - eta^2)^2 + 4 nu^2 eta^2`` is a quadratic in ``u = eta^2``:
    ``(1 - e^2) u^2 + (4 nu^2 - 2) u + 1 = 0``.
    """
    a, b, c = 1.0 - e * e, 4.0 * nu * nu - 2.0, 1.0
    if a == 0.0:
        roots = [-c / b]
    else:
        disc = b * b - 4.0 * a * c
        if disc < 0.0:
            return []
        q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
        roots = [q / a, c / q]
    return sorted(math.sqrt(u) for u in roots if u > 0.0)


def rub_fold_discriminant(params: ModelParams) -> float:
    """The quarter discriminant of the synchronous-rub quadratic in r (zero at a fold)."""
    K, mu, E = params.K, params.mu, params.E
    a = 1.0 - params.eta**2 + K
    b = 2.0 * params.nu * params.eta + mu * K
    return K**2 * (a + mu * b) ** 2 - (a * a + b * b) * (K**2 * (1.0 + mu * mu) - E * E)


def rub_fold_radius(params: ModelParams) -> float:
    """The double root r_f = K (a + mu b) / (a^2 + b^2) of the quadratic."""
    K, mu = params.K, params.mu
    a = 1.0 - params.eta**2 + K
    b = 2.0 * params.nu * params.eta + mu * K
    return K * (a + mu * b) / (a * a + b * b)


def _stable_rub_growth(params: ModelParams) -> float:
    """Largest real part of the eigenvalues of the largest forward rub (nan: none)."""
    rubs = [rub for rub in synchronous_rubs(params) if rub.forward_slip]
    return rubs[-1].growth_rate if rubs else math.nan


def region(params: ModelParams) -> int:
    """The region (NEITHER, FREE, RUB, BOTH) of one parameter point."""
    return point_values(params)[0]


def point_values(params: ModelParams) -> tuple[int, float, float, float]:
    """The region of one parameter point and the value there of each curve's function
    (free grazing, rub fold, rub stability; nan where the curve cannot lie), from one
    evaluation of the free whirl and the synchronous rubs."""
    free_r = free_radius(params)
    rubs = synchronous_rubs(params)
    forward = [r for r in rubs if r.forward_slip]
    rub = any(r.stable for r in forward)
    code = (FREE if free_r <= 1.0 else 0) | (RUB if rub else 0)
    growth = forward[-1].growth_rate if forward else math.nan
    return code, free_r - 1.0, _fold_field(params), growth


def _fold_field(params: ModelParams) -> float:
    """The fold discriminant where its double root lies outside the clearance, else nan."""
    return rub_fold_discriminant(params) if rub_fold_radius(params) > 1.0 else math.nan


# The scalar whose zero level is each curve (nan where the curve cannot lie).
CURVE_FUNCTIONS: dict[str, Callable[[ModelParams], float]] = {
    FREE_GRAZING: lambda p: free_radius(p) - 1.0,
    RUB_FOLD: _fold_field,
    RUB_STABILITY: lambda p: _stable_rub_growth(p),
}


@dataclass
class Chart:
    """Regions on a grid and the closed-form curves of one parameter plane."""

    x_name: str
    y_name: str
    x: np.ndarray  # (nx,)
    y: np.ndarray  # (ny,)
    regions: np.ndarray  # (ny, nx) of NEITHER/FREE/RUB/BOTH
    curves: dict[str, list[tuple[float, float]]]  # kind -> located (x, y) points
    fields: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)  # kind -> (ny, nx)
    log_x: bool = False  # the grid values of x are evenly spaced in their logarithm
    log_y: bool = False

    def curve_rows(self) -> list[tuple[float, float, str]]:
        """(x, y, kind) for every curve point, kind by kind, y then x ascending."""
        rows = []
        for kind in CURVE_KINDS:
            points = sorted(self.curves.get(kind, []), key=lambda p: (p[1], p[0]))
            rows.extend((px, py, kind) for px, py in points)
        return rows

    def region_fractions(self) -> dict[str, float]:
        """The share of the grid in each region."""
        return {REGIONS[c]: float(np.mean(self.regions == c)) for c in REGIONS}


def _roots_along(g: Callable[[float], float], xs: np.ndarray, keep) -> list[float]:
    """Roots of g between consecutive grid points with a sign change (Brent), kept if
    ``keep(root)``; nan values (no such motion) bound no bracket."""
    values = [g(float(x)) for x in xs]
    return _roots_in(g, xs, values, keep)


def _roots_in(g, xs, values, keep) -> list[float]:
    out = []
    for x0, x1, g0, g1 in zip(xs[:-1], xs[1:], values[:-1], values[1:], strict=True):
        if not (math.isfinite(g0) and math.isfinite(g1)) or (g0 > 0.0) == (g1 > 0.0):
            continue
        try:
            root = brentq(g, float(x0), float(x1), xtol=1e-13, rtol=1e-14)
        except ValueError:
            continue  # g turned nan inside the bracket
        if keep(root):
            out.append(root)
    return out


def closed_form_chart(
    params: ModelParams,
    x_name: str,
    x_range: tuple[float, float],
    y_name: str,
    y_range: tuple[float, float],
    nx: int = 121,
    ny: int = 61,
    x_spacing: str = "linear",
    y_spacing: str = "linear",
    deadline: float | None = None,
) -> Chart:
    """Regions and curves in the plane (x_name, y_name) over the given ranges; every other
    parameter as in ``params``. Each curve's function is evaluated on the grid
    (``Chart.fields``), and its zeros are located by Brent between grid values of a sign
    change, along x at each grid value of y and along y at each grid value of x (a curve
    that runs nearly parallel to one axis is found along the other). WallTimeBudgetError
    once ``time.perf_counter()`` passes ``deadline`` (checked at every grid line)."""
    from rubcli.analysis.orbits.periodic import check_deadline

    xs = _grid(x_range, nx, x_spacing)
    ys = _grid(y_range, ny, y_spacing)
    regions = np.zeros((ny, nx), dtype=int)
    fields = {k: np.full((ny, nx), math.nan) for k in CURVE_KINDS}
    for j, yv in enumerate(ys):
        check_deadline(deadline)
        row = _with(params, **{y_name: yv})
        for i, xv in enumerate(xs):
            code, *values = point_values(_with(row, **{x_name: xv}))
            regions[j, i] = code
            for kind, value in zip(CURVE_KINDS, values, strict=True):
                fields[kind][j, i] = value
    found: dict[str, set[tuple[float, float]]] = {k: set() for k in CURVE_KINDS}
    for kind, f in CURVE_FUNCTIONS.items():
        keep_x, keep_y = _keep(kind, params, x_name, y_name), _keep(kind, params, y_name, x_name)
        if nx > 1:  # along x, at each grid value of y
            for j, yv in enumerate(ys):
                check_deadline(deadline)
                for root in _roots_on_line(f, params, x_name, y_name, float(yv), xs,
                                           fields[kind][j], keep_x):  # fmt: skip
                    found[kind].add((root, float(yv)))
        if ny > 1:  # along y, at each grid value of x
            for i, xv in enumerate(xs):
                check_deadline(deadline)
                for root in _roots_on_line(f, params, y_name, x_name, float(xv), ys,
                                           fields[kind][:, i], keep_y):  # fmt: skip
                    found[kind].add((float(xv), root))
    curves = {k: sorted(v, key=lambda p: (p[1], p[0])) for k, v in found.items()}
    log_x, log_y = x_spacing == "log", y_spacing == "log"
    return Chart(x_name, y_name, xs, ys, regions, curves, fields, log_x, log_y)


def _roots_on_line(f, params, along: str, held: str, at: float, grid, values, keep):
    """The zeros of a curve's function along one grid line: ``along`` varies over ``grid``
    (where the function has ``values``), ``held`` is ``at``; ``keep(v, at)`` filters."""

    def g(v: float) -> float:
        return f(_with(params, **{along: v, held: at}))

    return _roots_in(g, grid, values, lambda v: keep(v, at))


def _grid(bounds: tuple[float, float], n: int, spacing: str) -> np.ndarray:
    """n values from bounds[0] to bounds[1], evenly spaced ("linear") or evenly spaced in
    their logarithm ("log"; the ends exact)."""
    if spacing == "log":
        values = np.geomspace(*bounds, n)
        values[0], values[-1] = bounds
        return values
    return np.linspace(*bounds, n)


def _keep(kind: str, params: ModelParams, x_name: str, y_name: str):
    """Which zeros of a curve's function are points of the curve, as keep(x value, y
    value): the fold's where its double root lies outside the clearance (its function is
    nan elsewhere, so this only rejects a root Brent found next to that edge)."""
    if kind != RUB_FOLD:
        return lambda xv, yv: True
    return lambda xv, yv: rub_fold_radius(_with(params, **{x_name: xv, y_name: yv})) > 1.0


def chart_dataset(chart: Chart, params: ModelParams) -> xr.Dataset:
    """The chart as an xarray Dataset: ``region`` on the grid (codes in its attributes),
    the function of each curve (its zero level is the curve; nan where it cannot lie), and
    the parameters held fixed."""
    import xarray as xr

    coords = {chart.y_name: chart.y, chart.x_name: chart.x}
    dims = (chart.y_name, chart.x_name)
    data = {
        "region": (dims, chart.regions.astype(np.int8),
                   {"codes": ", ".join(f"{c}: {name}" for c, name in REGIONS.items())}),
        **{f"{kind}_function": (dims, chart.fields[kind]) for kind in CURVE_KINDS},
    }  # fmt: skip
    fixed = {k: float(v) for k, v in params.as_dict().items()
             if k not in (chart.x_name, chart.y_name)}  # fmt: skip
    return xr.Dataset(data, coords=coords, attrs={"fixed_" + k: v for k, v in fixed.items()})


# ------------------------------------------------- the check by continuation


@dataclass(frozen=True)
class ContinuedPoint:
    """A bifurcation of the synchronous rub located by shooting and continuation
    (``rubcli.analysis.orbits.continuation``) at a fixed x, and the closed-form curve's y there."""

    x: float
    y: float
    kind: str  # FREE_GRAZING, RUB_FOLD or RUB_STABILITY
    closed_form_y: float  # nan: no closed-form root near it

    @property
    def deviation(self) -> float:
        return abs(self.y - self.closed_form_y)


# The bifurcations of the rub branch that lie on the chart's curves: its fold, its
# Neimark-Sacker point, and its grazing (r = 1, where it meets the free whirl; the
# nonsmooth fold reported there is that grazing, not the rub's fold).
CONTINUED_KINDS = {"fold": RUB_FOLD, "neimark_sacker": RUB_STABILITY, "grazing": FREE_GRAZING}


def continued_points(
    params: ModelParams, chart: Chart, n: int, progress: Callable[[int], None] | None = None,
    deadline: float | None = None,
) -> list[ContinuedPoint]:  # fmt: skip
    """At ``n`` values of x across the chart (its interior), the synchronous rub shot at the
    first grid value of y where it exists, continued in y over the chart's range both
    ways, and its located folds, Neimark-Sacker points and grazings: an independent check
    of the closed-form curves (each point carries the closed form's y next to it).
    WallTimeBudgetError once ``time.perf_counter()`` passes ``deadline``: a check cut
    short is no check."""
    from rubcli.analysis.orbits import continuation as cn
    from rubcli.analysis.orbits.periodic import check_deadline

    out: list[ContinuedPoint] = []
    lo, hi = float(chart.y[0]), float(chart.y[-1])
    # a first step of 1/30 of the range; on a log-spaced axis a tenth of its lower end, the
    # largest step the range's thirtieth (the corrector's steps grow between the two)
    step, largest = ((0.1 * lo, (hi - lo) / 30.0) if chart.log_y else
                     ((hi - lo) / 30.0, (hi - lo) / 6.0))  # fmt: skip
    for i, xv in enumerate(_interior(chart.x, n)):
        check_deadline(deadline)
        column = _with(params, **{chart.x_name: xv})
        start = next((yv for yv in chart.y if _forward_rub(_with(column, **{chart.y_name: yv}))),
                     None)  # fmt: skip
        if start is not None:
            at = _with(column, **{chart.y_name: float(start)})
            r = max(model.synchronous_rub_radii(at))
            state = model.synchronous_rub(np.array([0.0]), at, r)[:, 0]
            settings = cn.ContinuationSettings(
                parameter=chart.y_name, p_min=lo, p_max=hi, step=min(step, largest),
                max_step=largest, max_points=200,
                rtol=1e-10, atol=1e-10, newton_tol=1e-9, max_wall_time_s=60.0,
            )  # fmt: skip
            ends = cn.deadline_of(settings)  # each branch's own budget, within the run's
            ends = ends if deadline is None else min(ends, deadline)
            branch = cn.continue_branch(at, state, settings, deadline=ends)
            check_deadline(deadline)  # a branch the run's budget cut short
            for b in branch.bifurcations:
                kind = CONTINUED_KINDS.get(b.kind)
                if kind is not None and b.located and not b.nonsmooth:
                    y = float(b.parameter)
                    out.append(ContinuedPoint(xv, y, kind, _closed_form_y(column, chart, kind, y)))
        if progress is not None:
            progress(i + 1)
    return out


def _interior(values: np.ndarray, n: int) -> list[float]:
    """n values of the grid's span, evenly spread inside it (its ends left out)."""
    if n <= 0:
        return []
    fractions = (np.arange(n) + 0.5) / n
    return [float(values[0] + f * (values[-1] - values[0])) for f in fractions]


def _forward_rub(params: ModelParams) -> bool:
    radii = model.synchronous_rub_radii(params)
    return bool(radii) and model.synchronous_rub_is_forward(max(radii), params)


def _closed_form_y(column: ModelParams, chart: Chart, kind: str, y: float) -> float:
    """The closed-form curve's root in y nearest to ``y`` at this x (nan: none within a
    tenth of the chart's height)."""
    span = 0.1 * (chart.y[-1] - chart.y[0])
    window = (float(chart.y[0]), float(chart.y[-1]))
    return closed_form_root(column, kind, chart.y_name, y, span, window)


def closed_form_root(
    params: ModelParams, kind: str, name: str, near: float, span: float,
    window: tuple[float, float] | None = None,
) -> float:  # fmt: skip
    """The root in parameter ``name`` of the closed-form curve ``kind`` (CURVE_KINDS)
    nearest to ``near``, among those within ``span`` of it (and inside ``window``); every
    other parameter as in ``params``. nan: none there."""
    f = CURVE_FUNCTIONS[kind]
    lo, hi = near - span, near + span
    if window is not None:
        lo, hi = max(window[0], lo), min(window[1], hi)
    sign = model.PARAMETER_SIGNS.get(name)  # stay inside the parameter's domain
    if sign == ">= 0":
        lo = max(lo, 0.0)
    elif sign == "> 0":
        lo = max(lo, 1e-3 * near)
    values = np.linspace(lo, hi, 41)

    def g(v: float) -> float:
        return f(_with(params, **{name: v}))

    roots = _roots_along(g, values, lambda v: True)
    return min(roots, key=lambda r: abs(r - near)) if roots else math.nan


# ------------------------------------------------- a sweep beside the regions

# What a sweep's point settled on (``analysis.ensembles.ensemble.regime_of``), drawn beside
# the regions
SWEEP_REGIMES = ("free whirl", "synchronous rub", "modulated full rub", "partial rub",
                 "dry whip", "dry whirl", "no result")  # fmt: skip


@dataclass
class SweepMap:
    """A ``rubcli sweep`` over the chart's two parameters: what each point settled on."""

    path: Path
    direction: str  # the sweep direction shown ("up", "down" or "independent")
    x: np.ndarray  # (nx,) the sweep's values of the chart's x
    y: np.ndarray  # (ny,)
    regimes: np.ndarray  # (ny, nx) indices into SWEEP_REGIMES
    names: tuple[str, str]  # the chart's (x, y) parameters
    labels: tuple[str, ...] = SWEEP_REGIMES  # the name of each regime index

    def cross_table(self, params: ModelParams) -> dict[str, dict[str, int]]:
        """How many sweep points of each regime lie in each closed-form region."""
        table: dict[str, dict[str, int]] = {}
        for j, yv in enumerate(self.y):
            for i, xv in enumerate(self.x):
                at = dataclasses.replace(params, **{self.names[0]: float(xv),
                                                    self.names[1]: float(yv)})  # fmt: skip
                code = region(at)
                row = table.setdefault(REGIONS[code], {})
                name = self.labels[self.regimes[j, i]]
                row[name] = row.get(name, 0) + 1
        return table

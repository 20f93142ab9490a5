"""Basin stability along a parameter: the share of starts that end on each attractor, at
each value of one model parameter, with the attractors followed from value to value, and
the smallest perturbation that throws the rotor off the free whirl.

**Runs.** The same starts (one seeded draw, ``ensemble.box_starts`` or the spread cloud)
are run at every value through the ensemble's member machinery (``ensemble.run_member``:
each run's end classified and named by its regime, with the place and size of its
stroboscopic section). The fraction of the runs that end on an attractor estimates the
volume of its basin within the box of starts (P. J. Menck, J. Heitzig, N. Marwan,
J. Kurths, Nature Physics 9 (2013) 89); its 95 % interval is Wilson's
(``ensemble.wilson_interval``). Runs whose solver failed are counted apart, never in the
fractions.

**Attractors at one value** (``attractors_at``). Runs are on one attractor when their
regime names match and their section centres (the mean of the final window's section
points, as ``(x, y, vx / eta, vy / eta)``) lie within ``tolerance + (s_a + s_b) / 4`` of
each other, ``s`` the length of each section's extent (single linkage). A fixed point is
then a point, a torus or a period-k orbit a cloud whose centre moves little with the
phase of the window. Runs still changing regime at their end are *undecided*.

**Matching from one value to the next** (``match_attractors``). An attractor keeps its
label when the next value has an attractor of the same regime name; where several of one
name exist, they are paired with the labels of that name by the least total distance
between section centres and sizes (``|dc| + |ds|``, the Hungarian assignment), against
each label's last place (also across values where it was absent). An attractor with no
label left to pair opens a new one. A label is its regime name (``synchronous rub``) or,
when that name needs several, the name and a number in order of appearance. Limits: the
name is the identity, so a grid of values too coarse to follow an attractor may join an
attractor that vanished to another of the same name that appeared between two values;
``centres`` in the result shows where each label sat at each value, to check.

**Minimal perturbation** (``minimal_perturbations``). At a value where the free whirl
exists (its closed-form amplitude ``|W| = e eta^2 / |1 - eta^2 + 2 i nu eta| < 1``; it
is then stable) and a rub does too (a stable forward synchronous rub in closed form, or
a run of the ensemble that ended in contact), starts are placed at the free whirl's
stroboscopic point plus ``s d`` for unit directions ``d`` in ``(x, y, vx, vy)`` (the 8
signed axes and ``n`` seeded random ones; ``s`` the Euclidean size in clearances and
clearances per unit tau). Along each direction the sizes ``s_max / 2^k`` are tried from
the smallest up to ``s_max``; the first whose run does not end on the free whirl brackets
the basin's edge with the size before it (0 for the first), and bisection narrows the
bracket to ``rtol`` of its upper end. The smallest upper end over the directions is
reported, with its direction, its bracket and the attractor it reached. It is an **upper
bound** of the minimal perturbation: a direction not tried may leave sooner, and along a
tried direction a thin tongue of another basin below the scan's first step off the free
whirl is not seen.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rubcli import model
from rubcli.analysis.ensembles import ensemble as en
from rubcli.analysis.runs.processes import local_pool
from rubcli.model import ModelParams

FREE_WHIRL = "free whirl"
UNDECIDED = "undecided"  # the run was still changing regime at its end
MATCH_TOLERANCE = 0.05  # normalised section distance under which two centres are one place
SCAN_STEPS = 8  # sizes s_max / 2^7 ... s_max tried along each direction before bisection
MAX_BISECTIONS = 60


# ------------------------------------------------------------------ one parameter value


@dataclass(frozen=True)
class LocalAttractor:
    """An attractor found at one value: its regime name, its section's centre and size,
    the runs on it (indices into that value's runs) and the classes they were given."""

    regime: str
    centre: tuple[float, ...]
    size: float
    runs: tuple[int, ...]
    kinds: tuple[str, ...]


def attractors_at(
    members: Sequence[en.MemberResult], tolerance: float = MATCH_TOLERANCE
) -> list[LocalAttractor]:
    """The attractors the successful runs of one value end on (module docstring); the
    undecided runs as one entry named ``UNDECIDED``; failed runs are left out."""
    groups: dict[str, list[int]] = {}
    for i, m in enumerate(members):
        if m.ok:
            groups.setdefault(UNDECIDED if m.regime == en.CHANGING else m.regime, []).append(i)
    out = []
    for regime, idx in groups.items():
        if regime == UNDECIDED:
            clusters = [idx]
        else:
            centres = np.array([members[i].section_centre for i in idx], dtype=float)
            sizes = np.array([members[i].section_size for i in idx], dtype=float)
            clusters = _single_linkage(idx, centres, sizes, tolerance)
        for cluster in clusters:
            centres = np.array([members[i].section_centre or (np.nan,) * 4 for i in cluster])
            sizes = np.array([members[i].section_size for i in cluster], dtype=float)
            out.append(LocalAttractor(
                regime, tuple(float(v) for v in np.nanmean(centres, axis=0))
                if np.isfinite(centres).any() else (math.nan,) * 4,
                float(np.nanmean(sizes)) if np.isfinite(sizes).any() else math.nan,
                tuple(cluster), tuple(sorted({members[i].kind for i in cluster})),
            ))  # fmt: skip
    return out


def _single_linkage(idx: list[int], centres: np.ndarray, sizes: np.ndarray,
                    tolerance: float) -> list[list[int]]:  # fmt: skip
    """Groups of ``idx`` joined by every pair closer than ``tolerance + (s_a + s_b) / 4``."""
    n = len(idx)
    dist = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=-1)
    near = dist <= tolerance + 0.25 * (sizes[:, None] + sizes[None, :])
    group = -np.ones(n, dtype=int)
    for seed in range(n):
        if group[seed] >= 0:
            continue
        group[seed] = seed
        stack = [seed]
        while stack:
            k = stack.pop()
            for j in np.flatnonzero(near[k] & (group < 0)):
                group[j] = seed
                stack.append(int(j))
    return [[idx[k] for k in np.flatnonzero(group == g)] for g in dict.fromkeys(group)]


# ------------------------------------------------------------------------- matching


def match_attractors(per_value: Sequence[Sequence[LocalAttractor]]) -> list[list[str]]:
    """One label for each attractor of each value, stable along the values (module
    docstring): ``labels[i][j]`` is the label of ``per_value[i][j]``."""
    from scipy.optimize import linear_sum_assignment

    tracks: list[dict] = []  # {"regime", "centre", "size"}: each label's last place
    track_of: list[list[int]] = []
    for found in per_value:
        assigned = [-1] * len(found)
        for regime in dict.fromkeys(a.regime for a in found):
            mine = [j for j, a in enumerate(found) if a.regime == regime]
            known = [t for t, tr in enumerate(tracks) if tr["regime"] == regime]
            if known:
                cost = np.array([[_distance(found[j], tracks[t]) for t in known] for j in mine])
                rows, cols = linear_sum_assignment(cost)
                for r, c in zip(rows, cols, strict=True):
                    assigned[mine[r]] = known[c]
            for j in mine:
                if assigned[j] < 0:  # more attractors of this name than labels: a new one
                    tracks.append({"regime": regime})
                    assigned[j] = len(tracks) - 1
        for j, t in enumerate(assigned):
            tracks[t].update(centre=found[j].centre, size=found[j].size)
        track_of.append(assigned)
    names = _track_names([tr["regime"] for tr in tracks])
    return [[names[t] for t in assigned] for assigned in track_of]


def _distance(a: LocalAttractor, track: dict) -> float:
    """The cost of continuing ``track`` with ``a``: centre distance plus size change
    (0 where either is unknown, as for the undecided runs)."""
    d = float(np.linalg.norm(np.subtract(a.centre, track["centre"]))) + abs(a.size - track["size"])
    return d if math.isfinite(d) else 0.0


def _track_names(regimes: list[str]) -> list[str]:
    """The regime name, numbered in order of appearance where a name has several tracks."""
    total = {r: regimes.count(r) for r in regimes}
    seen: dict[str, int] = {}
    out = []
    for r in regimes:
        seen[r] = seen.get(r, 0) + 1
        out.append(r if total[r] == 1 else f"{r} {seen[r]}")
    return out


# ------------------------------------------------------------------- minimal perturbation


@dataclass(frozen=True)
class PerturbationSettings:
    """How the minimal perturbation is searched (``[ensemble] perturbation_*``)."""

    random_directions: int = 8  # beside the 8 signed axes
    max_size: float = 2.0  # the largest perturbation tried
    rtol: float = 0.02  # bisection stops when the bracket is this share of its upper end
    seed: int = 0

    def directions(self) -> np.ndarray:
        """The unit directions in ``(x, y, vx, vy)``: the signed axes, then the random ones
        (seeded; the same at every value)."""
        axes = np.vstack([np.eye(4), -np.eye(4)]) + 0.0  # (no negative zeros)
        drawn = np.random.default_rng([self.seed, 1]).normal(size=(self.random_directions, 4))
        drawn /= np.linalg.norm(drawn, axis=1, keepdims=True)
        return np.vstack([axes, drawn])


@dataclass(frozen=True)
class DirectionTask:
    """Bisection along one direction at one value (small, picklable)."""

    value_index: int
    direction_index: int
    origin: tuple[float, float, float, float]  # the free whirl's stroboscopic point
    direction: tuple[float, float, float, float]
    run: en.MemberTask  # the run's settings; its start is replaced
    max_size: float
    rtol: float


@dataclass
class DirectionResult:
    value_index: int
    direction_index: int
    direction: tuple[float, ...]
    found: bool = False
    lower: float = math.nan  # the largest size seen to end on the free whirl
    upper: float = math.nan  # the smallest size seen not to
    reached: str = ""  # the attractor the start at ``upper`` ends on
    runs: int = 0
    message: str = ""

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and math.isnan(v) else v)
                for k, v in dataclasses.asdict(self).items()}  # fmt: skip


def _ends(task: DirectionTask, size: float) -> en.MemberResult:
    start = tuple(float(o + size * d) for o, d in zip(task.origin, task.direction, strict=True))
    return en.run_member(dataclasses.replace(task.run, start=start, offset=size))


def bisect_direction(task: DirectionTask) -> DirectionResult:
    """The edge of the free whirl's basin along one direction (module docstring)."""
    out = DirectionResult(task.value_index, task.direction_index, task.direction)
    sizes = task.max_size * 2.0 ** -np.arange(SCAN_STEPS - 1, -1, -1)
    lower, upper, reached = 0.0, math.nan, ""
    for size in sizes:
        m = _ends(task, float(size))
        out.runs += 1
        if not m.ok:
            out.message = f"a run failed at size {size:.6g}: {m.message}"
            return out
        if m.regime != FREE_WHIRL:
            upper, reached = float(size), m.attractor
            break
        lower = float(size)
    if math.isnan(upper):
        out.lower = lower
        out.message = f"every size up to {task.max_size:g} ends on the free whirl"
        return out
    for _ in range(MAX_BISECTIONS):
        if upper - lower <= task.rtol * upper:
            break
        middle = 0.5 * (lower + upper)
        m = _ends(task, middle)
        out.runs += 1
        if not m.ok:
            out.message = f"a run failed at size {middle:.6g}: {m.message}"
            return out
        if m.regime == FREE_WHIRL:
            lower = middle
        else:
            upper, reached = middle, m.attractor
    out.found, out.lower, out.upper, out.reached = True, lower, upper, reached
    return out


@dataclass
class MinimalPerturbation:
    """The minimal perturbation at one value, or why it was not computed."""

    value: float
    computable: bool
    reason: str  # why not computable, or which attractors it lies between
    origin: tuple[float, ...] | None = None  # the free whirl's stroboscopic point
    size: float | None = None  # the upper bound: the smallest upper end over the directions
    lower: float | None = None  # along the same direction, the size seen to return
    direction: tuple[float, ...] | None = None
    reached: str = ""
    directions_tried: int = 0
    runs: int = 0
    by_direction: list[DirectionResult] = field(default_factory=list)

    @property
    def found(self) -> bool:
        return self.size is not None

    def to_dict(self) -> dict:
        out = {k: getattr(self, k) for k in ("value", "computable", "reason", "origin", "size",
                                               "lower", "direction", "reached",
                                               "directions_tried", "runs")}  # fmt: skip
        out["bound"] = (
            f"an upper bound: the smallest of {self.directions_tried} directions tried (the 8 "
            "signed axes and seeded random ones); a direction not tried may need less"
            if self.found else None
        )  # fmt: skip
        out["by_direction"] = [d.to_dict() for d in self.by_direction]
        return out


def free_whirl_point(params: ModelParams) -> tuple[float, float, float, float]:
    """The free whirl's state at tau = 0 (its stroboscopic point), from the closed form."""
    w, dw = model.free_steady_state(0.0, params)
    w, dw = complex(w), complex(dw)
    return (w.real, w.imag, dw.real, dw.imag)


def perturbation_status(params: ModelParams, members: Sequence[en.MemberResult]) -> str | None:
    """Why the minimal perturbation cannot be computed at these parameters (None: it can):
    the free whirl must clear the stator and a rub must exist (module docstring)."""
    from rubcli.analysis.charts.stability import free_radius
    from rubcli.analysis.orbits.synchronous import synchronous_rubs

    if not params.is_paper_machine:  # its start is the paper machine's free whirl
        return ("a general machine: the free whirl's closed form (the perturbation's origin) "
                "holds on the paper's machine only")  # fmt: skip
    radius = free_radius(params)
    if not radius < 1.0:
        return f"no free whirl: its closed-form amplitude |W| = {radius:.4g} reaches the stator"
    stable_rub = any(r.forward_slip and r.stable for r in synchronous_rubs(params))
    in_contact = any(m.ok and m.regime not in (FREE_WHIRL, en.CHANGING) for m in members)
    if not (stable_rub or in_contact):
        return ("no rub: the synchronous rub has no stable root here and no run of the "
                "ensemble ended in contact")  # fmt: skip
    return None


# ------------------------------------------------------------------------------ study


@dataclass
class BasinStability:
    """The runs at every value, the attractor label of each, and the minimal perturbations."""

    parameter: str
    values: list[float]
    members: list[list[en.MemberResult]]  # per value, in the order of the starts
    attractors: list[list[LocalAttractor]]  # per value
    attractor_labels: list[list[str]]  # per value, the label of each of its attractors
    perturbations: list[MinimalPerturbation] = field(default_factory=list)
    settings: dict = field(default_factory=dict)

    @property
    def labels(self) -> list[str]:
        """Every attractor label, in order of first appearance (undecided last)."""
        seen = dict.fromkeys(label for labels in self.attractor_labels for label in labels)
        return [k for k in seen if k != UNDECIDED] + ([UNDECIDED] if UNDECIDED in seen else [])

    def label_of_runs(self, i: int) -> list[str | None]:
        """The label of each run at value ``i`` (None: the run failed)."""
        out: list[str | None] = [None] * len(self.members[i])
        for a, label in zip(self.attractors[i], self.attractor_labels[i], strict=True):
            for k in a.runs:
                out[k] = label
        return out

    def counts(self, i: int) -> dict[str, int]:
        """Runs on each label at value ``i`` (0 where the label is absent)."""
        out = dict.fromkeys(self.labels, 0)
        for a, label in zip(self.attractors[i], self.attractor_labels[i], strict=True):
            out[label] += len(a.runs)
        return out

    def good_runs(self, i: int) -> int:
        return sum(1 for m in self.members[i] if m.ok)

    def failed_runs(self, i: int) -> int:
        return sum(1 for m in self.members[i] if not m.ok)

    def fractions(self, i: int) -> dict[str, dict]:
        """Per label at value ``i``: count, runs, fraction and its 95 % Wilson interval."""
        n = self.good_runs(i)
        out = {}
        for label, k in self.counts(i).items():
            lo, hi = en.wilson_interval(k, n)
            out[label] = {"count": k, "runs": n, "fraction": k / n if n else math.nan,
                          "ci_low": lo, "ci_high": hi}  # fmt: skip
        return out

    def rows(self) -> list[tuple]:
        """basin_stability.csv: (value, attractor, count, runs, fraction, ci_low, ci_high)."""
        return [(v, label, f["count"], f["runs"], f["fraction"], f["ci_low"], f["ci_high"])
                for i, v in enumerate(self.values)
                for label, f in self.fractions(i).items()]  # fmt: skip

    def centres(self) -> dict[str, list]:
        """Each label's section centre and size at each value (None where absent)."""
        out: dict[str, list] = {label: [None] * len(self.values) for label in self.labels}
        for i in range(len(self.values)):
            for a, label in zip(self.attractors[i], self.attractor_labels[i], strict=True):
                if label != UNDECIDED:
                    out[label][i] = {
                        "centre": list(a.centre),
                        "size": a.size,
                        "kinds": list(a.kinds),
                    }
        return out

    def to_dict(self) -> dict:
        return {
            "parameter": self.parameter,
            "values": self.values,
            "settings": self.settings,
            "attractors": self.labels,
            "by_value": [
                {"value": v, "runs": self.good_runs(i), "failed": self.failed_runs(i),
                 "failures": [m.message for m in self.members[i] if not m.ok][:10],
                 "fractions": self.fractions(i)}
                for i, v in enumerate(self.values)
            ],
            "sections": self.centres(),
            "minimal_perturbation": [p.to_dict() for p in self.perturbations],
        }  # fmt: skip


def basin_stability(
    params: ModelParams,
    parameter: str,
    values: Sequence[float],
    start: Sequence[float],
    starts: np.ndarray | None,
    *,
    perturbation: PerturbationSettings | None = None,
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    settings: dict | None = None,
    **run_settings: Any,
) -> BasinStability:
    """Run the same starts at each value of ``parameter`` and name where each run ends.

    ``start``, ``starts`` and ``run_settings`` are those of ``ensemble.member_tasks``
    (``runs``, ``spread``, ``seed``, ``methods``, ``rtols``, ``options``, ``periods``,
    ``samples_per_period``, ``record_periods``, ``lyapunov``, ``lyapunov_periods``,
    ``settle_tolerance``): the same draws at every value. ``perturbation``: also search
    the minimal perturbation off the free whirl at each value. ``workers``: processes
    (1: this one). ``progress(done, total)``: runs and directions finished, of an upper
    bound of the total known from the start.
    """
    per_value = [
        en.member_tasks(dataclasses.replace(params, **{parameter: float(v)}), start,
                        starts=starts, **run_settings)
        for v in values
    ]  # fmt: skip
    flat = [t for tasks in per_value for t in tasks]
    flat = [dataclasses.replace(t, index=k) for k, t in enumerate(flat)]
    directions = perturbation.directions() if perturbation is not None else np.empty((0, 4))
    total = len(flat) + len(values) * len(directions)
    runs = en.run_ensemble(
        flat,
        workers=min(workers, max(len(flat), 1)),
        progress=None if progress is None else lambda n: progress(n, total),
    )
    members, k = [], 0
    for tasks in per_value:
        members.append(runs.members[k : k + len(tasks)])
        k += len(tasks)
    found = [attractors_at(m) for m in members]
    result = BasinStability(parameter, [float(v) for v in values], members, found,
                            match_attractors(found), settings=settings or {})  # fmt: skip
    if perturbation is not None:
        result.perturbations = minimal_perturbations(
            result.values, [t[0] for t in per_value], members, perturbation, workers=workers,
            progress=None if progress is None else lambda n: progress(len(flat) + n, total),
        )  # fmt: skip
    return result


def minimal_perturbations(
    values: Sequence[float],
    templates: Sequence[en.MemberTask],
    members: Sequence[Sequence[en.MemberResult]],
    settings: PerturbationSettings,
    *,
    workers: int = 1,
    progress: Callable[[int], None] | None = None,
) -> list[MinimalPerturbation]:
    """The minimal perturbation at each of ``values`` (module docstring): ``templates[i]``
    gives the parameters and run settings at value ``i`` (its start is replaced; no Lyapunov
    runs), ``members[i]`` the ensemble's runs there (a rub found by them counts as a rub).
    ``progress(n)``: directions finished (those of a value not computable count at once).
    ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` after a direction once the templates'
    deadline (``MemberTask.deadline``) has passed."""
    from rubcli.analysis.orbits.periodic import check_deadline

    directions = settings.directions()
    out: list[MinimalPerturbation] = []
    tasks: list[DirectionTask] = []
    skipped = 0
    for i, (value, template) in enumerate(zip(values, templates, strict=True)):
        value_params = template.params
        why = perturbation_status(value_params, members[i])
        if why is not None:
            out.append(MinimalPerturbation(value, False, why))
            skipped += len(directions)
            continue
        origin = free_whirl_point(value_params)
        out.append(MinimalPerturbation(value, True, "", origin=origin,
                                       directions_tried=len(directions)))  # fmt: skip
        run = dataclasses.replace(template, lyapunov=False)
        for j, d in enumerate(directions):
            tasks.append(DirectionTask(i, j, origin, tuple(float(v) for v in d), run,
                                       settings.max_size, settings.rtol))  # fmt: skip
    if progress is not None:
        progress(skipped)
    results: list[DirectionResult] = []
    deadline = templates[0].deadline if templates else None
    if workers <= 1 or len(tasks) <= 1:
        for task in tasks:
            results.append(bisect_direction(task))
            if progress is not None:
                progress(skipped + len(results))
            check_deadline(deadline)
    else:
        with local_pool(min(workers, len(tasks))) as pool:
            for r in en.within_deadline(pool, pool.map(bisect_direction, tasks), deadline):
                results.append(r)
                if progress is not None:
                    progress(skipped + len(results))
    for r in results:
        out[r.value_index].by_direction.append(r)
    for p in out:
        if p.computable:
            _summarise(p, settings.max_size)
    return out


def _summarise(p: MinimalPerturbation, max_size: float) -> None:
    """The smallest upper end over the directions, or why none was found."""
    p.runs = sum(d.runs for d in p.by_direction)
    found = [d for d in p.by_direction if d.found]
    if not found:
        failed = [d.message for d in p.by_direction if d.message.startswith("a run failed")]
        p.reason = (
            failed[0]
            if failed
            else (
                f"not found: every direction tried ends on the free whirl up to size {max_size:g}"
            )
        )
        return
    best = min(found, key=lambda d: d.upper)
    p.size, p.lower, p.direction, p.reached = best.upper, best.lower, best.direction, best.reached
    p.reason = f"off the free whirl onto {best.reached}"

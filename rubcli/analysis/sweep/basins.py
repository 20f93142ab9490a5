"""Basins of attraction with early stopping: a start grid computed in chunks and rounds.

Every start of an initial-state grid runs until it is recognised (``attractors``): on a
learned attractor for ``consecutive`` periods, or in basin cells of one attractor for
``basin_hits`` periods, or it has spent ``transient_periods + record_periods`` and is
labelled by its last ``record_periods`` section points (a new attractor learned from
them, or a known one they lie on).

**Order and determinism.** A strided *seed* of ``seed_points`` starts runs to the budget
first and its tails are learned, so that the common attractors are known before the grid
starts. The grid is then cut into chunks of consecutive starts (``chunk_points``) and the
chunks into *rounds* (4, 8, 16, ... chunks). Within a round every chunk sees the same
frozen attractors and basin cells; after the round the parent learns the tails of the
starts that ran to the budget and adds the cells of the starts recognised on an
attractor, in chunk order. So the labels do not depend on the executor, the number of
workers or the order in which chunks finish.

**Storage.** A chunk's results are one file of the sweep's resume store (``PointStore``:
private, checksummed, written atomically): a million starts are a few hundred files, and
memory is bounded by the labels of the grid (12 bytes a start) and the cell map
(``attractors.MAX_CELLS``), not by the plan's points.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import io
import math
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rubcli.analysis.sweep.attractors import (
    DIVERGED,
    FAILED,
    SAME_FACTOR,
    UNRECOGNISED,
    AttractorSet,
    CellMap,
    Recognition,
    describe,
    nearest,
    normalised,
)
from rubcli.analysis.sweep.plan import INITIAL_AXES, SweepPlan

if TYPE_CHECKING:
    import xarray as xr

    from rubcli.analysis.sweep.store import PointStore

# how a start was labelled (the codes of ``recognise_kernel``: 1, 2, 3)
HOW = ("budget", "attractor", "basin", "diverged", "failed")
FIRST_ROUND_CHUNKS = 4  # chunks in the first round; each later round doubles
MIN_CHUNK, MAX_CHUNK = 64, 4096  # starts per chunk (fixed by the grid size alone)


def chunk_size(n_points: int) -> int:
    """Starts per chunk: about 64 chunks for a small grid, at most MAX_CHUNK starts."""
    return int(min(MAX_CHUNK, max(MIN_CHUNK, math.ceil(n_points / 64))))


def rounds(n_chunks: int) -> list[range]:
    """The chunks of every round: 4, 8, 16, ... (the last takes what is left)."""
    out, start, size = [], 0, FIRST_ROUND_CHUNKS
    while start < n_chunks:
        out.append(range(start, min(n_chunks, start + size)))
        start, size = start + size, 2 * size
    return out


def starts_of(plan: SweepPlan, flat: np.ndarray) -> np.ndarray:
    """The start states of grid points by flat index (C order over the axes)."""
    index = np.unravel_index(flat, plan.shape)
    states = np.tile(np.asarray(plan.initial, dtype=float), (len(flat), 1))
    for axis, i in zip(plan.axes, index, strict=True):
        states[:, INITIAL_AXES.index(axis.parameter)] = np.asarray(axis.values)[i]
    return states


def seed_indices(shape: tuple[int, ...], seed_points: int) -> np.ndarray:
    """The flat indices of a coarse sub-grid of about ``seed_points`` starts, spread
    evenly along every axis."""
    per_axis = max(1, int(round(seed_points ** (1.0 / len(shape)))))
    picks = [np.unique(np.round(np.linspace(0, n - 1, min(n, per_axis))).astype(np.int64))
             for n in shape]  # fmt: skip
    mesh = np.meshgrid(*picks, indexing="ij")
    return np.ravel_multi_index([m.ravel() for m in mesh], shape)


# ------------------------------------------------------------------ one chunk (worker)


@dataclass
class ChunkTask:
    """A chunk of starts with the attractors and cells frozen for its round."""

    plan: SweepPlan
    recognition: Recognition
    starts: np.ndarray  # (n, 4)
    attractors: list[tuple[np.ndarray, float]]  # (cloud, radius) by label
    cells: CellMap | None
    whole_sections: bool = False  # the seed: keep every section point, not the tail


@dataclass
class ChunkResult:
    """What a chunk's starts did (arrays by start, in chunk order)."""

    label: np.ndarray  # int16: attractor label, or UNRECOGNISED / DIVERGED / FAILED
    how: np.ndarray  # int8: index in HOW
    convergence: np.ndarray  # float32: period the attractor was reached (NaN unknown)
    periods: np.ndarray  # int32: periods integrated
    tails: dict[int, np.ndarray]  # start index -> last section points (ran to budget)
    cell_keys: np.ndarray  # cells visited on the way to an attractor, in visit order
    cell_labels: np.ndarray
    cell_remaining: np.ndarray
    compute_s: float = 0.0
    messages: dict[int, str] = field(default_factory=dict)  # failed starts

    def to_bytes(self) -> bytes:
        buffer = io.BytesIO()
        tail_index = np.array(sorted(self.tails), dtype=np.int64)
        tails = [self.tails[i] for i in tail_index.tolist()]
        np.savez(
            buffer, label=self.label, how=self.how, convergence=self.convergence,
            periods=self.periods, tail_index=tail_index,
            tail_sizes=np.array([len(t) for t in tails], dtype=np.int64),
            tail_points=np.concatenate(tails) if tails else np.empty((0, 4)),
            cell_keys=self.cell_keys, cell_labels=self.cell_labels,
            cell_remaining=self.cell_remaining, compute_s=np.array(self.compute_s),
            message_index=np.array(sorted(self.messages), dtype=np.int64),
            messages=np.array([self.messages[i] for i in sorted(self.messages)], dtype=str),
        )  # fmt: skip
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> ChunkResult:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            sizes = z["tail_sizes"]
            parts = np.split(z["tail_points"], np.cumsum(sizes)[:-1]) if sizes.size else []
            return cls(
                z["label"], z["how"], z["convergence"], z["periods"],
                dict(zip(z["tail_index"].tolist(), parts, strict=True)),
                z["cell_keys"], z["cell_labels"], z["cell_remaining"], float(z["compute_s"]),
                dict(zip(z["message_index"].tolist(), z["messages"].tolist(), strict=True)),
            )  # fmt: skip


def failed_chunk(n: int, message: str) -> ChunkResult:
    """A chunk of ``n`` starts that could not be computed: every start failed."""
    return ChunkResult(
        np.full(n, FAILED, np.int16), np.full(n, HOW.index("failed"), np.int8),
        np.full(n, np.nan, np.float32), np.zeros(n, np.int32), {},
        np.empty(0, np.int64), np.empty(0, np.int16), np.empty(0, np.int32),
        messages=dict.fromkeys(range(n), message),
    )  # fmt: skip


def compute_chunk(task: ChunkTask) -> ChunkResult:
    """Run every start of the chunk until recognised or out of budget (a worker's job;
    a start that fails is recorded as failed, never raised). The looks at a trajectory
    are ``recognise_kernel.scan``, the compiled ``Recogniser.feed_block``."""
    import dataclasses

    from rubcli.analysis.sweep import recognise_kernel as kernel
    from rubcli.problem import Problem
    from rubcli.solvers import solve
    from rubcli.solvers.driver import Watch

    started = time.perf_counter()
    plan, rec = task.plan, task.recognition
    budget = plan.transient_periods + plan.record_periods
    eta = plan.params.eta
    n = len(task.starts)
    out = ChunkResult(
        np.full(n, UNRECOGNISED, np.int16), np.zeros(n, np.int8),
        np.full(n, np.nan, np.float32), np.zeros(n, np.int32), {},
        np.empty(0, np.int64), np.empty(0, np.int16), np.empty(0, np.int32),
    )  # fmt: skip
    clouds = [np.ascontiguousarray(c, dtype=float) for c, _ in task.attractors]
    cloud = np.concatenate(clouds) if clouds else np.empty((0, 4))
    offsets = np.r_[0, np.cumsum([len(c) for c in clouds])].astype(np.int64)
    radii = np.array([r for _, r in task.attractors], dtype=float)
    cells = task.cells if task.cells is not None else CellMap(1.0)
    state = np.empty(6, np.int64)
    template = Problem.from_periods(plan.params, tuple(task.starts[0]), budget, 1)
    keys, labels, left = [], [], []
    for i, start in enumerate(task.starts):
        state[:] = (kernel.NONE, 0, 0, kernel.AMBIGUOUS, 0, 0)
        fed = [0]
        hit: list[tuple[int, int, int, int]] = []  # label, period, how, convergence

        def check(
            states: np.ndarray, fed: list[int] = fed, hit: list[tuple[int, int, int, int]] = hit
        ) -> str | None:
            at, label, how, convergence = kernel.scan(
                normalised(states, eta), fed[0] + 1, cloud, offsets, radii,
                rec.consecutive, cells.keys, cells.labels, cells.remaining, cells.size,
                rec.basin_hits, rec.escape_radius, state,
            )  # fmt: skip
            if at >= 0:
                hit.append((int(label), fed[0] + at + 1, int(how), int(convergence)))
                return "recognised"
            fed[0] += len(states)
            return None

        try:
            problem = dataclasses.replace(template, initial=tuple(start))
            sol = solve(problem, plan.method, watch=Watch(rec.check_every, check),
                        **plan.options)  # fmt: skip
        except Exception as exc:  # a start that cannot run is a failed start
            out.label[i], out.how[i] = FAILED, HOW.index("failed")
            out.messages[i] = f"{type(exc).__name__}: {exc}"
            continue
        states = np.asarray(sol.states)
        if not sol.success:
            out.label[i], out.how[i] = FAILED, HOW.index("failed")
            out.periods[i], out.messages[i] = len(states) - 1, sol.message
            continue
        if not hit:  # ran to the budget: the parent labels it by its tail
            out.periods[i] = budget
            keep = budget if task.whole_sections else plan.record_periods
            out.tails[i] = normalised(states[1:], eta)[-keep:]
            continue
        label, period, how, convergence = hit[0]
        out.label[i], out.periods[i], out.how[i] = label, len(states) - 1, how
        if how != kernel.HOW_DIVERGED:
            out.convergence[i] = convergence
        if how in (kernel.HOW_ATTRACTOR, kernel.HOW_BASIN) and task.cells is not None:
            # the cells on its way: each foretells the periods left to the attractor
            # (a cell reached on the way to two attractors becomes ambiguous)
            section = normalised(states[1 : period + 1], eta)
            keys.append(cells.pack(section))
            labels.append(np.full(period, label, np.int16))
            left.append(np.maximum(0, convergence - np.arange(1, period + 1)))
    if keys:
        out.cell_keys = np.concatenate(keys)
        out.cell_labels = np.concatenate(labels)
        out.cell_remaining = np.concatenate(left).astype(np.int32)
    out.compute_s = time.perf_counter() - started
    return out


# ------------------------------------------------------------------ the grid (parent)


@dataclass
class BasinResult:
    """Every start's attractor, how and when; the attractors learned; the run's counts."""

    label: np.ndarray  # (grid shape) int16
    how: np.ndarray  # int8, index in HOW
    convergence: np.ndarray  # float32
    periods: np.ndarray  # int32
    attractors: list[dict]  # descriptors by label (with radius)
    points_computed: int = 0  # starts computed in this run (the seed's not counted)
    points_resumed: int = 0  # starts found in the store
    seed_points: int = 0  # starts run to the budget first, to learn from
    chunks_computed: int = 0
    chunks_resumed: int = 0
    chunks_rejected: int = 0
    compute_s: float = 0.0
    cells: int = 0
    messages: dict[int, str] = field(default_factory=dict)  # flat index -> failure


class _Learner:
    """The parent's view: attractors and cells, updated after each round in order."""

    def __init__(self, rec: Recognition, record_periods: int):
        self.rec, self._record = rec, record_periods
        self.set = AttractorSet(rec.tolerance, rec.consecutive, rec.escape_radius)
        self.cells = CellMap(rec.basin_cell) if rec.basin_cell > 0 else None

    def frozen(self) -> tuple[list[tuple[np.ndarray, float]], CellMap | None]:
        return [(a.cloud, a.radius) for a in self.set.attractors], self.cells

    def absorb_seed(self, result: ChunkResult) -> None:
        """Learn the seed's attractors from its tails, then add the cells each seed
        trajectory crossed before it settled (from the last period off its attractor)."""
        whole = {}
        for i in sorted(result.tails):
            tail = result.tails[i]
            if len(tail) and np.all(np.isfinite(tail)) and self.set.settled(tail[-self._record :]):
                result.label[i] = self.set.learn(tail[-self._record :])
                whole[i] = tail
        if self.cells is None:
            return
        keys, labels, left = [], [], []
        for i in sorted(whole):
            label = int(result.label[i])
            attractor = self.set.attractors[label]
            # on it: within the reach that learning allows (a torus or a chaotic set is
            # sampled by its tail only, and the earlier points fall between the samples)
            reach = SAME_FACTOR * attractor.radius
            off = np.flatnonzero(nearest(attractor.cloud, whole[i]) > reach)
            settled = int(off[-1]) + 2 if off.size else 1  # first period on it for good
            section = whole[i][: settled - 1]
            keys.append(self.cells.pack(section))
            labels.append(np.full(len(section), label, np.int16))
            left.append(settled - np.arange(1, len(section) + 1))
        if keys:
            self.cells = self.cells.merged(
                np.concatenate(keys), np.concatenate(labels), np.concatenate(left)
            )

    def absorb(self, result: ChunkResult) -> None:
        """Label the chunk's budget-spent starts by their tails; add its cells."""
        for i in sorted(result.tails):
            tail = result.tails[i]
            if len(tail) and np.all(np.isfinite(tail)) and self.set.settled(tail):
                result.label[i] = self.set.learn(tail)  # else: not recognised, said so
        if self.cells is not None and result.cell_keys.size:
            self.cells = self.cells.merged(
                result.cell_keys, result.cell_labels, result.cell_remaining
            )


def run_basins(
    plan: SweepPlan,
    rec: Recognition,
    executor: cf.Executor,
    *,
    store: PointStore | None = None,
    progress: Callable[[int, int], None] | None = None,
    rebuild: Callable[[], cf.Executor] | None = None,
    watch: Callable[[], None] | None = None,
) -> BasinResult:
    """Every start of the basin grid ``plan``, in rounds of chunks (module docstring).

    ``store`` (a ``PointStore``) keeps every finished chunk: a resumed run replays the
    stored chunks and computes only the others. ``rebuild`` replaces a broken local
    pool; ``watch`` is the Dask executor's health check (``engine.run_plan``)."""
    from concurrent.futures.process import BrokenProcessPool

    from rubcli.analysis.sweep.engine import MAX_RETRIES, WATCH_INTERVAL_S, ExecutorLostError

    n = math.prod(plan.shape)
    size = chunk_size(n)
    n_chunks = math.ceil(n / size)
    learner = _Learner(rec, plan.record_periods)
    result = BasinResult(
        np.full(n, UNRECOGNISED, np.int16), np.zeros(n, np.int8),
        np.full(n, np.nan, np.float32), np.zeros(n, np.int32), [],
    )  # fmt: skip
    stored = dict(store.load_blobs()) if store is not None else {}
    result.chunks_rejected = len(store.rejected) if store is not None else 0
    done = 0

    def load(name: str) -> ChunkResult | None:
        data = stored.get(name)
        if data is None:
            return None
        try:
            return ChunkResult.from_bytes(data)
        except (ValueError, KeyError, OSError, EOFError, zipfile.BadZipFile):
            result.chunks_rejected += 1  # checked bytes of another layout: computed again
            return None

    def finish(name: str, chunk: ChunkResult, counted: bool) -> None:
        nonlocal done
        result.chunks_computed += 1
        if store is not None:
            store.save_blob(name, chunk.to_bytes())
        if counted:
            result.points_computed += len(chunk.label)
            done += len(chunk.label)
            if progress is not None:
                progress(done, n)

    def compute(
        names: list[str], tasks: list[ChunkTask], counted: bool = True
    ) -> dict[str, ChunkResult]:
        """The chunks ``names``, all of them: stored ones loaded, the others computed.
        A chunk whose worker died (a broken local pool) or that the executor dropped
        (Dask, its scheduler connection lost) is submitted again; after MAX_RETRIES
        deaths its starts are recorded as failed, after MAX_RETRIES drops the run
        stops (``ExecutorLostError``). ``counted``: its starts count in the progress."""
        nonlocal executor, done
        found: dict[str, ChunkResult] = {}
        todo: dict[str, ChunkTask] = {}
        for name, task in zip(names, tasks, strict=True):
            loaded = load(name)
            if loaded is not None and len(loaded.label) == len(task.starts):
                found[name] = loaded
                result.chunks_resumed += 1
                if counted:
                    result.points_resumed += len(task.starts)
                    done += len(task.starts)
            else:
                todo[name] = task
        if progress is not None and counted:
            progress(done, n)
        deaths: dict[str, int] = {}
        drops: dict[str, int] = {}
        while todo:
            in_flight = {executor.submit(compute_chunk, todo[k]): k for k in todo}
            lost: list[str] = []  # chunks held by a pool that broke
            watched = time.monotonic()
            try:
                while in_flight:
                    finished, _ = cf.wait(
                        list(in_flight), timeout=None if watch is None else WATCH_INTERVAL_S,
                        return_when=cf.FIRST_COMPLETED,
                    )  # fmt: skip
                    if watch is not None and time.monotonic() - watched >= WATCH_INTERVAL_S:
                        watch()
                        watched = time.monotonic()
                    for future in finished:
                        name = in_flight.pop(future)
                        try:
                            chunk = future.result()
                        except BrokenProcessPool:
                            lost.append(name)
                            raise
                        except Exception as exc:  # dropped by the executor, not a result
                            if type(exc).__name__ == "KilledWorker":  # after Dask's retries
                                why = f"the chunk killed Dask's workers: {exc}"
                                chunk = failed_chunk(len(todo.pop(name).starts), why)
                                found[name] = chunk
                                finish(name, chunk, counted)
                                continue
                            drops[name] = drops.get(name, 0) + 1
                            if drops[name] > MAX_RETRIES:
                                raise ExecutorLostError(
                                    f"the executor dropped chunk {name} {MAX_RETRIES} times "
                                    f"({type(exc).__name__})"
                                ) from None
                            if watch is not None:
                                watch()
                            continue
                        found[name] = chunk
                        del todo[name]
                        finish(name, chunk, counted)
            except BrokenProcessPool:
                if rebuild is None:
                    raise RuntimeError("the process pool broke and cannot be rebuilt") from None
                for name in [*lost, *in_flight.values()]:  # lost with the pool
                    deaths[name] = deaths.get(name, 0) + 1
                    if deaths[name] >= MAX_RETRIES:
                        why = f"worker died {MAX_RETRIES} times on its chunk"
                        chunk = failed_chunk(len(todo.pop(name).starts), why)
                        found[name] = chunk
                        finish(name, chunk, counted)
                in_flight = {}
                executor.shutdown(wait=False, cancel_futures=True)
                executor = rebuild()
            finally:
                for future in in_flight:
                    with contextlib.suppress(Exception):  # a closed Dask client may refuse
                        future.cancel()
        return found

    # the seed: strided starts run to the budget (no recognition), learned in order
    seed = seed_indices(plan.shape, rec.seed_points)
    blank = Recognition(**{**rec.to_dict(), "basin_cell": 0.0})
    seed_task = ChunkTask(plan, blank, starts_of(plan, seed), [], None, whole_sections=True)
    seed_result = compute(["seed"], [seed_task], counted=False)["seed"]
    learner.absorb_seed(seed_result)
    result.seed_points = len(seed)
    result.compute_s += seed_result.compute_s
    for chunks in rounds(n_chunks):
        attractors, cells = learner.frozen()
        names, tasks = [], []
        for c in chunks:
            flat = np.arange(c * size, min(n, (c + 1) * size))
            names.append(f"chunk-{c}")
            tasks.append(ChunkTask(plan, rec, starts_of(plan, flat), attractors, cells))
        found = compute(names, tasks)
        for c, name in zip(chunks, names, strict=True):
            chunk = found[name]
            learner.absorb(chunk)  # in chunk order: the same labels whatever ran it
            a = c * size
            b = a + len(chunk.label)
            result.label[a:b], result.how[a:b] = chunk.label, chunk.how
            result.convergence[a:b], result.periods[a:b] = chunk.convergence, chunk.periods
            result.compute_s += chunk.compute_s
            for i, message in chunk.messages.items():
                result.messages[a + i] = message
    for array in ("label", "how", "convergence", "periods"):
        setattr(result, array, getattr(result, array).reshape(plan.shape))
    described = [
        {**describe(a.cloud, rec.tolerance), "radius": a.radius} for a in learner.set.attractors
    ]

    # labels in order of the attractors' smallest z (then largest), not of discovery:
    # the same machine gives the same labels and colours whatever grid found them first
    def by_z(k: int) -> tuple[float, float]:
        return round(described[k]["z_min"], 6), described[k]["z_max"]

    order = sorted(range(len(described)), key=by_z)
    new_label = np.empty(len(order) + 3, np.int16)
    new_label[3:][order] = np.arange(len(order))
    new_label[:3] = (FAILED, DIVERGED, UNRECOGNISED)  # -3, -2, -1 stay
    result.label = new_label[result.label.astype(np.int64) + 3]
    result.attractors = [described[k] for k in order]
    result.cells = 0 if learner.cells is None else int(learner.cells.keys.size)
    return result


# ------------------------------------------------------------------ measures


def basin_entropy(labels: np.ndarray, box: int = 5) -> tuple[float, float]:
    """Basin entropy S_b and boundary basin entropy S_bb of a 2-D label grid (Daza,
    Wagemakers, Georgeot, Guery-Odelin, Sanjuan, Sci. Rep. 6, 31416, 2016): the grid in
    boxes of ``box`` x ``box`` starts, each box's Gibbs entropy of its label shares
    (natural log), averaged over all boxes (S_b) and over the boxes that hold more than
    one label (S_bb). S_bb > ln 2 proves a fractal boundary; 0 means one basin."""
    labels = np.asarray(labels)
    if labels.ndim != 2 or min(labels.shape) < box:
        return math.nan, math.nan
    rows, cols = labels.shape[0] // box, labels.shape[1] // box
    total, boundary, n_boundary = 0.0, 0.0, 0
    for r in range(rows):
        for c in range(cols):
            cell = labels[r * box : (r + 1) * box, c * box : (c + 1) * box].ravel()
            _, counts = np.unique(cell, return_counts=True)
            p = counts / counts.sum()
            s = float(-(p * np.log(p)).sum())
            total += s
            if counts.size > 1:
                boundary += s
                n_boundary += 1
    return total / (rows * cols), (boundary / n_boundary if n_boundary else 0.0)


# ------------------------------------------------------------------ results as files


def attractor_name(descriptor: dict) -> str:
    """A short name of a learned attractor from its descriptors."""
    z = (
        f"z {descriptor['z_min']:.3g}"
        if descriptor["z_max"] - descriptor["z_min"] < 1e-3
        else f"z {descriptor['z_min']:.3g}-{descriptor['z_max']:.3g}"
    )
    where = (
        "rubbing" if descriptor["z_min"] > 1.0
        else "free" if descriptor["z_max"] < 1.0
        else "partial rub"
    )  # fmt: skip
    return f"{descriptor['kind']}, {where}, {z}"


def build_dataset(plan: SweepPlan, result: BasinResult, attrs: dict | None = None) -> xr.Dataset:
    """The basin grid as an xarray Dataset: each start's attractor, how and when it was
    recognised and the periods it cost; the attractors with their descriptors and basin
    fractions; the basin entropies of the grid."""
    import json

    import xarray as xr

    dims = tuple(a.dim for a in plan.axes)
    coords = {a.dim: np.asarray(a.values) for a in plan.axes}
    n_attr = len(result.attractors)
    coords["attractor"] = np.arange(n_attr)
    label = result.label
    total = label.size
    fraction = np.array([(label == k).sum() / total for k in range(n_attr)])
    descriptors = result.attractors
    s_b, s_bb = basin_entropy(label) if label.ndim == 2 else (math.nan, math.nan)
    ds = xr.Dataset(
        {
            "attractor_label": (dims, label, {
                "long_name": "attractor reached (a label of the attractor dimension)",
                "flag_values": "-1 not recognised, -2 diverged, -3 failed"}),
            "recognised_by": (dims, result.how, {
                "long_name": "how the start was labelled",
                "flag_meanings": " ".join(HOW), "flag_values": "0 1 2 3 4"}),
            "convergence_period": (dims, result.convergence, {
                "long_name": "forcing period at which the start reached its attractor "
                "(foretold by its basin cells when recognised by them; NaN unknown)",
                "units": "forcing periods"}),
            "periods_integrated": (dims, result.periods, {
                "long_name": "forcing periods integrated", "units": "forcing periods"}),
            "attractor_kind": (("attractor",), np.array([d["kind"] for d in descriptors],
                                                         dtype=str)),
            "attractor_name": (("attractor",), np.array(
                [attractor_name(d) for d in descriptors], dtype=str)),
            "attractor_period": (("attractor",), np.array([d["period"] for d in descriptors],
                                                          dtype=np.int32)),
            **{
                f"attractor_{k}": (("attractor",), np.array([d[k] for d in descriptors],
                                                            dtype=float))
                for k in ("z_min", "z_max", "x_mean", "y_mean", "radius")
            },
            "basin_fraction": (("attractor",), fraction),
        },
        coords=coords,
        attrs={
            **(attrs or {}),
            "plan": json.dumps(plan.to_dict(), sort_keys=True),
            "plan_digest": plan.digest(),
            "recognition": json.dumps(plan.recognition.to_dict() if plan.recognition else {}),
            "basin_entropy": s_b,
            "boundary_basin_entropy": s_bb,
            "seed_points": result.seed_points,
            "basin_cells": result.cells,
        },
    )  # fmt: skip
    return ds


def csv_text(ds: xr.Dataset, plan: SweepPlan) -> str:
    """One row per start: its state, attractor (label and name), how, when, cost."""
    import csv
    import io as text_io

    buffer = text_io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    dims = [a.dim for a in plan.axes]
    writer.writerow([*dims, "attractor", "attractor_name", "recognised_by",
                     "convergence_period", "periods_integrated"])  # fmt: skip
    names = {int(k): str(v) for k, v in zip(ds["attractor"].values,
                                            ds["attractor_name"].values, strict=True)}  # fmt: skip
    names.update({UNRECOGNISED: "not recognised", DIVERGED: "diverged", FAILED: "failed"})
    coords = [ds[d].values for d in dims]
    label = ds["attractor_label"].values
    how, conv = ds["recognised_by"].values, ds["convergence_period"].values
    periods = ds["periods_integrated"].values
    for index in np.ndindex(*plan.shape):
        c = float(conv[index])
        writer.writerow([
            *(repr(float(v[i])) for v, i in zip(coords, index, strict=True)),
            int(label[index]), names[int(label[index])], HOW[int(how[index])],
            "" if not math.isfinite(c) else int(c), int(periods[index]),
        ])  # fmt: skip
    return buffer.getvalue()


def summary(ds: xr.Dataset) -> dict:
    """What report.json and the console say of a basin grid."""
    how = ds["recognised_by"].values
    label = ds["attractor_label"].values
    return {
        "attractors": [
            {
                "label": int(k),
                "name": str(ds["attractor_name"].values[k]),
                "kind": str(ds["attractor_kind"].values[k]),
                "period": int(ds["attractor_period"].values[k]),
                "z_min": float(ds["attractor_z_min"].values[k]),
                "z_max": float(ds["attractor_z_max"].values[k]),
                "basin_fraction": float(ds["basin_fraction"].values[k]),
            }
            for k in ds["attractor"].values
        ],
        "recognised_by": {name: int((how == i).sum()) for i, name in enumerate(HOW)},
        "not_recognised": int((label == UNRECOGNISED).sum()),
        "diverged": int((label == DIVERGED).sum()),
        "failed": int((label == FAILED).sum()),
        "mean_periods_integrated": float(ds["periods_integrated"].values.mean()),
        "basin_entropy": float(ds.attrs["basin_entropy"]),
        "boundary_basin_entropy": float(ds.attrs["boundary_basin_entropy"]),
    }

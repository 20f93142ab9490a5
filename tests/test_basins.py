"""Basin grids with attractor recognition (rubcli/analysis/sweep/basins.py).

The labels are checked against an independent method: every start integrated for its
whole budget and labelled by the learned attractor its final state lies on. The
compiled scan is checked against the numpy recogniser on exact maps, the watched solve
against an unwatched one, and the basin entropy against boxes counted by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rubcli.analysis.sweep import Axis, SweepPlan, execute
from rubcli.analysis.sweep import recognise_kernel as kernel
from rubcli.analysis.sweep.attractors import (
    AMBIGUOUS,
    AttractorSet,
    CellMap,
    Recogniser,
    Recognition,
    normalised,
)
from rubcli.analysis.sweep.basins import HOW, basin_entropy, rounds, run_basins, seed_indices
from rubcli.analysis.sweep.engine import InProcessExecutor
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.solvers.driver import Watch

# cases/examples/basins.toml: a rub and a free whirl coexist at eta = 2
MACHINE = ModelParams(nu=0.05, eta=2.0, e=0.3, K=10.0, mu=0.02, Rp=5.0, phi0=0.0)
OPTIONS = {"rtol": 1e-8, "atol": 1e-10}


def _plan(n: int, recognition: Recognition | None = None) -> SweepPlan:
    values = tuple(np.linspace(-1.5, 1.5, n))
    return SweepPlan(
        MACHINE, (0.0, 0.0, 0.0, 0.0), (Axis("x", values), Axis("y", values)),
        transient_periods=150, record_periods=16, options=OPTIONS,
        recognition=recognition or Recognition(),
    )  # fmt: skip


def test_a_watched_solve_is_the_same_run_stopped_where_the_watch_says():
    problem = Problem.from_periods(MACHINE, (1.2, 0.3, 0.0, 0.0), 40, 1)
    whole = solve(problem, "dop853-jit", **OPTIONS)
    seen: list[int] = []
    watched = solve(problem, "dop853-jit", watch=Watch(7, lambda s: seen.append(len(s))),
                    **OPTIONS)  # fmt: skip
    assert seen == [7, 7, 7, 7, 7, 5] and watched.success and len(watched.t) == 41
    # the legs end on samples, so the steps differ: states agree to the tolerance
    np.testing.assert_allclose(watched.states, whole.states, atol=1e-6)
    calls: list[int] = []

    def stop_third(states):
        calls.append(1)
        return "seen enough" if len(calls) == 3 else None

    stopped = solve(problem, "rk45", watch=Watch(5, stop_third), **OPTIONS)
    assert stopped.success and stopped.message == "seen enough" and len(stopped.t) == 16
    with pytest.raises(TypeError, match="watch"):
        solve(problem, "rk45", watch=lambda s: None)


def _numpy_scan(known, cells, points, hits):
    recogniser = Recogniser(known, cells, hits)
    found = recogniser.feed_block(points, 1)
    if found is None:
        return None
    return found[0], found[1], recogniser.how, recogniser.convergence


def _kernel_scan(known, cells, points, hits):
    clouds = np.concatenate([a.cloud for a in known.attractors])
    offsets = np.r_[0, np.cumsum([len(a.cloud) for a in known.attractors])].astype(np.int64)
    radii = np.array([a.radius for a in known.attractors])
    state = np.array([kernel.NONE, 0, 0, kernel.AMBIGUOUS, 0, 0], np.int64)
    at, label, how, conv = kernel.scan(
        points, 1, clouds, offsets, radii, known.consecutive, cells.keys, cells.labels,
        cells.remaining, cells.size, hits, known.escape_radius, state,
    )  # fmt: skip
    if at < 0:
        return None
    return int(label), int(at), HOW[int(how)], int(conv)


def test_the_compiled_scan_decides_as_the_numpy_recogniser():
    rng = np.random.default_rng(7)
    centres = np.array([[0.4, -0.2, 0.1, 0.3], [-1.0, 0.5, 0.0, 0.2]])
    known = AttractorSet(tolerance=0.01, consecutive=4)
    for c in centres:
        known.learn(c + 1e-4 * rng.standard_normal((16, 4)))
    # cells: a path to attractor 1 marked with the periods left
    path = centres[1] + np.linspace(1.0, 0.2, 12)[:, None] * np.array([0.5, 0.5, 0.5, 0.5])
    cells = CellMap(0.05).merged(
        CellMap(0.05).pack(path), np.full(12, 1, np.int16), np.arange(30, 18, -1, dtype=np.int32)
    )
    cases = [
        centres[0] + 0.5 ** np.arange(1, 30)[:, None] * 0.3,  # contracts onto attractor 0
        path[2:9] + 1e-3,  # walks the cells of attractor 1
        np.vstack([centres[1] + 2.0, [[np.nan, 0, 0, 0]]]),  # diverges
        centres[1] + 0.3 + 0.01 * rng.standard_normal((20, 4)),  # nowhere known
    ]
    for hits in (1, 3):
        for points in cases:
            expected = _numpy_scan(known, cells, points, hits)
            assert _kernel_scan(known, cells, points, hits) == expected
    assert _numpy_scan(known, cells, cases[0], 3)[2] == "attractor"
    assert _numpy_scan(known, cells, cases[1], 3)[2] == "basin"


def test_cells_reached_on_the_way_to_two_attractors_become_ambiguous():
    cells = CellMap(0.1)
    points = np.array([[0.01, 0, 0, 0], [0.51, 0, 0, 0], [1.01, 0, 0, 0]])
    keys = cells.pack(points)
    first = cells.merged(keys[:2], np.array([0, 0], np.int16), np.array([5, 4], np.int32))
    second = first.merged(keys[1:], np.array([1, 1], np.int16), np.array([9, 8], np.int32))
    labels, left = second.lookup(points)
    assert labels.tolist() == [0, AMBIGUOUS, 1]
    assert left.tolist() == [5, 0, 8]  # an ambiguous cell foretells nothing
    assert second.lookup(np.array([[7.0, 7, 7, 7]]))[0].tolist() == [AMBIGUOUS]
    assert cells.pack(np.array([[1e9, 0, 0, 0]])).tolist() == [-1]


def test_basin_entropy_counts_the_boxes():
    assert basin_entropy(np.zeros((10, 10))) == (0.0, 0.0)
    half = np.zeros((10, 10), int)
    half[:, 5:] = 1  # boxes of 5 x 5: every box holds one label
    assert basin_entropy(half) == (0.0, 0.0)
    stripes = np.zeros((10, 10), int)
    stripes[:, 3:] = 1  # the two left boxes hold 15 and 10 starts of the two labels
    p = np.array([15, 10]) / 25
    s = float(-(p * np.log(p)).sum())
    s_b, s_bb = basin_entropy(stripes)
    assert math.isclose(s_b, s / 2) and math.isclose(s_bb, s)


def test_rounds_and_seed_depend_on_the_grid_alone():
    assert [len(r) for r in rounds(30)] == [4, 8, 16, 2]
    seed = seed_indices((31, 31), 64)
    assert len(seed) == 64 and len(set(seed.tolist())) == 64
    rows, cols = np.unravel_index(seed, (31, 31))
    assert set(rows.tolist()) == set(cols.tolist()) == {0, 4, 9, 13, 17, 21, 26, 30}


@pytest.mark.slow
def test_recognised_labels_agree_with_integrating_every_start_to_its_budget():
    plan = _plan(15)
    result = run_basins(plan, plan.recognition, InProcessExecutor())
    assert len(result.attractors) == 2
    # labelled by z, whatever was found first: the free whirl, then the synchronous rub,
    # each at its closed-form radius (model notes, section 5; E = e eta^2)
    p = MACHINE
    big_e = p.e * p.eta**2
    free = big_e / abs(1 - p.eta**2 + 2j * p.nu * p.eta)
    a, b = 1 - p.eta**2 + p.K, 2 * p.nu * p.eta + p.mu * p.K
    rub = max(np.roots([a * a + b * b, -2 * p.K * (a + p.mu * b),
                        p.K**2 * (1 + p.mu**2) - big_e**2]).real)  # fmt: skip
    radii = [(a_["z_min"], a_["z_max"]) for a_ in result.attractors]
    assert np.allclose(radii, [(free, free), (rub, rub)], atol=1e-4)
    budget = plan.transient_periods + plan.record_periods
    assert result.periods.max() < budget and result.periods.mean() < budget / 4
    centres = np.array([[a["x_mean"], a["y_mean"]] for a in result.attractors])
    values = plan.axes[0].values
    for i, x in enumerate(values):
        for j, y in enumerate(values):
            final = solve(Problem.from_periods(MACHINE, (x, y, 0, 0), budget, 1),
                          "dop853-jit", **OPTIONS).states[-1]  # fmt: skip
            gaps = np.hypot(*(final[:2] - centres).T)
            assert gaps.min() < 1e-3, "a start not settled after its whole budget"
            assert result.label[i, j] == int(np.argmin(gaps)), (x, y)


@pytest.mark.slow
def test_labels_do_not_depend_on_workers_and_survive_a_tampered_store(tmp_path):
    plan = _plan(21)
    alone, _, where = execute(plan, workers=1)
    assert where.startswith("this process")
    store_dir = tmp_path / "store"
    pooled, stats, _ = execute(plan, workers=2, oversubscribe=True, store_dir=store_dir)
    for name in ("label", "how", "convergence", "periods"):
        np.testing.assert_array_equal(getattr(alone, name), getattr(pooled, name))
    assert stats.computed == plan.n_points
    chunks = sorted(store_dir.glob("chunk-*.chunk"))
    assert len(chunks) == math.ceil(plan.n_points / 64)
    data = bytearray(chunks[1].read_bytes())
    data[-20] ^= 1  # one flipped byte
    chunks[1].write_bytes(bytes(data))
    chunks[2].unlink()
    resumed, stats, _ = execute(plan, workers=1, store_dir=store_dir)
    assert stats.rejected == 1 and stats.computed == 2 * 64
    assert stats.resumed == plan.n_points - 2 * 64
    np.testing.assert_array_equal(resumed.label, alone.label)


_DIE: dict = {"marker": "", "always": False, "real": None}


def _dying_chunk(task):
    """Kills its worker process: once (marker file), or every time."""
    import os
    from pathlib import Path

    marker = Path(_DIE["marker"])
    if _DIE["always"] or not marker.exists():
        marker.write_text("died")
        os._exit(1)
    return _DIE["real"](task)


@pytest.mark.slow
@pytest.mark.parametrize("always", [False, True])
def test_a_chunk_whose_worker_dies_is_run_again_or_failed(tmp_path, monkeypatch, always):
    """A worker that dies breaks the pool: its chunks run again on a new pool (the labels
    of a run in one process), and a chunk that kills every worker it meets is recorded
    as failed starts, not retried for ever."""
    import multiprocessing

    from rubcli.analysis.sweep import basins

    if multiprocessing.get_start_method() != "fork":
        pytest.skip("the patched worker function reaches the workers only by fork")
    plan = _plan(9)
    reference, _, _ = execute(plan, workers=1)
    _DIE.update(marker=str(tmp_path / "died"), always=always, real=basins.compute_chunk)
    monkeypatch.setattr(basins, "compute_chunk", _dying_chunk)
    result, _, where = execute(plan, workers=2, oversubscribe=True)
    assert where == "process pool (2 workers)" and (tmp_path / "died").exists()
    if always:
        assert (result.label == -3).all() and "worker died 3 times" in result.messages[0]
    else:
        np.testing.assert_array_equal(result.label, reference.label)


def test_normalised_weighs_velocity_by_the_speed():
    states = np.array([[1.0, 0.0, 0.0, 2.0]])
    np.testing.assert_array_equal(normalised(states, 2.0), [[1.0, 0.0, 0.0, 1.0]])


BASIN_CASE = """
[case]
name = "basins-dask"
[model]
nu = 0.05
eta = 2.0
e = 0.3
K = 10.0
mu = 0.02
Rp = 5.0
[initial]
x = 0.0
y = 0.0
[time]
periods = 10
samples_per_period = 32
[solver]
rtol = 1e-8
atol = 1e-10
[sweep]
direction = "independent"
transient_periods = 150
record_periods = 16
[[sweep.axes]]
parameter = "x"
start = -1.5
stop = 1.5
num = 61
[[sweep.axes]]
parameter = "y"
start = -1.5
stop = 1.5
num = 61
"""


@pytest.mark.serial
@pytest.mark.slow
def test_a_dask_basin_sweep_survives_a_killed_worker(tmp_path):
    """A real scheduler and two workers; one worker is killed mid-sweep: Dask runs its
    chunks on the other, and the labels equal those of this process."""
    import subprocess
    import sys
    import time

    pytest.importorskip("distributed")
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    case = tmp_path / "case.toml"
    case.write_text(BASIN_CASE)
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    scheduler = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
         "--port", str(port), "--no-dashboard"], **quiet,
    )  # fmt: skip
    workers = [
        subprocess.Popen(
            [
                sys.executable,
                "-m",
                "distributed.cli.dask_worker",
                address,
                "--nthreads",
                "1",
                "--no-nanny",
                "--no-dashboard",
            ],
            **quiet,
        )  # fmt: skip
        for _ in range(2)
    ]
    sweep = None
    try:
        sweep = subprocess.Popen(
            [sys.executable, "-m", "rubcli", "sweep", str(case), "--out", str(tmp_path / "out"),
             "--scheduler", address, "--json"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and sweep.poll() is None:
            stores = list((tmp_path / "out").glob(".rubcli-sweep-*"))
            if stores and len(list(stores[0].glob("chunk-*.chunk"))) >= 2:
                break
            time.sleep(0.05)
        workers[0].kill()
        _stdout, stderr = sweep.communicate(timeout=300)
    finally:
        for proc in (sweep, scheduler, *workers):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.wait()
    assert sweep.returncode == 0, stderr
    import xarray as xr

    with xr.open_dataset(tmp_path / "out" / "sweep.nc", engine="h5netcdf") as ds:
        labels = ds["attractor_label"].values
    from rubcli.case import load_case
    from rubcli.sweeps import plan_from_case

    plan = plan_from_case(load_case(case))
    alone, _, _ = execute(plan, workers=1)
    np.testing.assert_array_equal(labels, alone.label)


@pytest.mark.slow
def test_a_chunk_that_kills_dask_workers_is_failed_and_a_dropped_one_run_again():
    """Dask's KilledWorker (the chunk killed every worker Dask gave it) fails the chunk's
    starts; a cancelled task (its scheduler connection dropped) is submitted again."""
    import concurrent.futures as cf

    killed = type("KilledWorker", (Exception,), {})

    class Failing(cf.Executor):
        def __init__(self, error):
            self.error, self.calls = error, 0

        def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
            self.calls += 1
            future: cf.Future = cf.Future()
            if self.error is killed or self.calls % 3 == 1:  # every third task dropped
                if self.error is killed:
                    future.set_exception(killed("worker died"))
                else:  # as Dask's executor does: cancelled, and its waiters told
                    future.cancel()
                    future.set_running_or_notify_cancel()
            else:
                future.set_result(fn(*args, **kwargs))
            return future

    plan = _plan(9)
    result = run_basins(plan, plan.recognition, Failing(killed), watch=lambda: None)
    assert (result.label == -3).all() and "killed Dask's workers" in result.messages[0]
    reference = run_basins(plan, plan.recognition, InProcessExecutor())
    dropping = Failing(cf.CancelledError)
    again = run_basins(plan, plan.recognition, dropping, watch=lambda: None)
    np.testing.assert_array_equal(again.label, reference.label)
    assert dropping.calls > 2


@pytest.mark.slow
def test_an_interrupted_basin_sweep_counts_the_starts_it_keeps(tmp_path):
    """SIGINT during a basin sweep: the message counts the starts in the stored chunks,
    and the same command resumes them."""
    import json
    import signal
    import subprocess
    import sys
    import time

    case = tmp_path / "case.toml"
    case.write_text(BASIN_CASE)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "rubcli", "sweep", str(case), "--out", str(out),
               "--workers", "1"]  # fmt: skip
    sweep = subprocess.Popen(command, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
                             text=True)  # fmt: skip
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and sweep.poll() is None:
        stores = list(out.glob(".rubcli-sweep-*"))
        if stores and len(list(stores[0].glob("chunk-*.chunk"))) >= 3:
            break
        time.sleep(0.05)
    sweep.send_signal(signal.SIGINT)
    _, stderr = sweep.communicate(timeout=120)
    assert sweep.returncode == 130, stderr
    kept = int(stderr.split("interrupted: ")[1].split(" of ")[0])
    assert kept >= 2 * 64 and kept % 64 == 0 and "of 3721 points are kept" in stderr
    resumed = subprocess.run([*command, "--json"], capture_output=True, text=True,
                             timeout=600, check=False)  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["points_resumed"] >= kept


def test_recognition_on_a_parameter_sweep_is_refused_naming_the_table(tmp_path):
    from typer.testing import CliRunner

    from rubcli.cli.app import app

    text = BASIN_CASE.split("[[sweep.axes]]")[0] + (
        'parameter = "eta"\nvalues = [1.0, 2.0]\n[sweep.recognition]\ntolerance = 0.02\n'
    )
    case = tmp_path / "case.toml"
    case.write_text(text)
    result = CliRunner().invoke(app, ["sweep", str(case), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and "[sweep.recognition] is for a grid of start" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "out").exists()


def test_a_watch_must_move_the_run_on():
    with pytest.raises(ValueError, match="every must be an integer >= 1"):
        Watch(0, lambda s: None)
    with pytest.raises(TypeError, match="check must be callable"):
        Watch(3, None)

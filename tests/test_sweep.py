"""`rubcli sweep` and `rubcli.sweep`: numbers against exact solutions, executors that agree
bit for bit, resumption after a kill, and bad sweep tables (docs/sweeps.md).

The sweeps here are tiny (a few points, a few dozen forcing periods each)."""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import rubcli
from rubcli import model
from rubcli.analysis.sweep import Axis, SweepPlan, execute
from rubcli.analysis.sweep.dataset import build_dataset, csv_text
from rubcli.analysis.sweep.point import RESPONSE_CLASSES, SCALARS
from rubcli.case import load_case
from rubcli.cli.app import app
from rubcli.sweeps import plan_from_case

REPO = Path(__file__).resolve().parents[1]
SWEEP_CASES = sorted(
    p
    for p in (REPO / "cases").rglob("*.toml")
    if "case" in (data := tomllib.loads(p.read_text()))
    and "rotor" not in data
    and load_case(p).settings.sweep is not None
)

FREE_CASE = """
[case]
name = "free"
[model]
nu = 0.1
eta = 1.0
e = 0.05
K = 10.0
mu = 0.1
Rp = 2.0
[initial]
x = 0.0
y = 0.0
[time]
periods = 10
samples_per_period = 32
[solver]
rtol = 1e-10
atol = 1e-12
[sweep]
parameter = "eta"
values = [0.5, 0.8, 1.0, 1.3, 2.0]
transient_periods = 80
record_periods = 8
"""


def _write(tmp_path: Path, text: str, name: str = "case.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_rotor_that_never_touches_follows_the_linear_response(tmp_path):
    """r = e eta^2 / |1 - eta^2 + 2 i nu eta| at every point (notes, free steady state)."""
    ds = rubcli.sweep(_write(tmp_path, FREE_CASE), workers=1)
    eta = ds["eta"].values
    assert eta.tolist() == [0.5, 0.8, 1.0, 1.3, 2.0]
    r = 0.05 * eta**2 / np.abs(1.0 - eta**2 + 2j * 0.1 * eta)
    assert r.max() < 0.26  # never near the clearance
    d = ds.sel(direction="independent")
    assert (d["status"].values == 0).all()
    # transient >= 80 periods: the free decay exp(-nu tau) is below 1e-13 of e
    np.testing.assert_allclose(d["section_z"].values, r[:, None] * np.ones(8), rtol=1e-8)
    np.testing.assert_allclose(d["z_max"].values, r, rtol=1e-8)
    np.testing.assert_allclose(d["z_min"].values, r, rtol=1e-8)
    # forward synchronous whirl (1X) of that radius, never in contact
    np.testing.assert_allclose(d["whirl_order"].values, 1.0, atol=1e-9)
    np.testing.assert_allclose(d["whirl_amplitude"].values, r, rtol=1e-6)
    assert (d["whirl_direction"].values == 1).all()
    assert (d["contact_fraction"].values == 0).all()
    assert (d["n_contact_switches"].values == 0).all()
    assert [RESPONSE_CLASSES[int(c)] for c in d["response_class"].values] == ["periodic"] * 5
    assert (d["response_period"].values == 1).all()
    assert (d["energy_residual"].values < 1e-6).all()
    # the phase too: the steady state is w = A exp(i (eta tau + phi0)) at tau = k T
    amp = 0.05 * eta**2 / (1.0 - eta**2 + 2j * 0.1 * eta)
    np.testing.assert_allclose(d["section_x"].values[:, -1], amp.real, atol=1e-9)
    np.testing.assert_allclose(d["section_y"].values[:, -1], amp.imag, atol=1e-9)


def test_full_annular_rub_sits_on_the_closed_form_radius(fig3_params):
    """mu = 0, the paper's machine swept in e by continuation: every point in permanent
    contact lies on the synchronous rub radius (the quadratic of notes section 5)."""
    values = (7.48, 7.5, 7.52, 7.54, 7.56)
    base = fig3_params(mu=0.0)
    import dataclasses

    first = dataclasses.replace(base, e=values[0])
    (r0,) = model.synchronous_rub_radii(first)
    start = model.synchronous_rub(np.array([0.0]), first, r0)[:, 0]
    plan = SweepPlan(
        base, tuple(start), (Axis("e", values),), direction="up", transient_periods=150,
        record_periods=8, samples_per_period=32, options={"rtol": 1e-10, "atol": 1e-12},
        energy=False,
    )  # fmt: skip
    results, stats, _ = execute(plan, workers=1)
    assert stats.computed == 5
    ds = build_dataset(plan, results)
    d = ds.sel(direction="up")
    assert (d["contact_fraction"].values == 1.0).all()  # the test is about these points
    for i, e in enumerate(values):
        radii = model.synchronous_rub_radii(dataclasses.replace(base, e=e))
        assert len(radii) == 1
        np.testing.assert_allclose(d["section_z"].values[i], radii[0], rtol=1e-8)
    assert (d["whirl_direction"].values == 1).all()
    np.testing.assert_allclose(d["whirl_order"].values, 1.0, atol=1e-9)


def _small_plan(fig3_params) -> SweepPlan:
    return SweepPlan(
        fig3_params(mu=0.0), (0.88544, -0.8039, 0.0, 0.0),
        (Axis("mu", (0.0, 0.02, 0.04)),), direction="both", transient_periods=10,
        record_periods=8, samples_per_period=16, options={"rtol": 1e-8, "atol": 1e-10},
        spectrum=True,
    )  # fmt: skip


@pytest.mark.serial
@pytest.mark.slow
def test_results_do_not_depend_on_the_executor(fig3_params):
    """1 worker, 2 local processes, a real 2-worker Dask LocalCluster (processes, loopback)
    and points batched into tasks: identical numbers."""
    distributed = pytest.importorskip("distributed")
    plan = _small_plan(fig3_params)
    one, _, where1 = execute(plan, workers=1)
    two, _, where2 = execute(plan, workers=2, oversubscribe=True)  # any core count
    assert where1 == "this process (1 worker)" and where2 == "process pool (2 workers)"
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        distributed.Client(cluster, set_as_default=False) as client,
    ):  # fmt: skip
        dask, _, where3 = execute(plan, client=client)
    assert where3.startswith("dask (2 workers")
    from rubcli.analysis.sweep.engine import InProcessExecutor, run_plan

    batched, _ = run_plan(plan, InProcessExecutor(), batch=4)  # 4 points per task
    reference = build_dataset(plan, one)
    assert (reference["status"].values == 0).all()
    assert reference["contact_fraction"].values.max() > 0.5  # there is rubbing to get right
    for other in (two, dask, batched):
        ds = build_dataset(plan, other)
        assert ds.identical(reference)
        assert csv_text(ds, plan) == csv_text(reference, plan)
        for key, result in other.items():
            assert result.final_state == one[key].final_state


def test_every_scalar_result_is_one_entry_of_the_table_and_a_column_of_each_output(fig3_params):
    """A point's results are point.SCALARS: each is in docs/sweeps.md's table of what a
    point computes, a variable of sweep.nc (its meaning as long_name) and a column of
    sweep.csv, in the table's order (how a result is added, docs/sweeps.md)."""
    docs = (REPO / "docs" / "sweeps.md").read_text()
    table = docs[docs.index("## What each point computes") : docs.index("## Outputs")]
    documented = set(re.findall(r"`([a-z_]+)`", table))
    assert set(SCALARS) <= documented, sorted(set(SCALARS) - documented)
    plan = SweepPlan(
        fig3_params(mu=0.0), (0.88544, -0.8039, 0.0, 0.0), (Axis("mu", (0.0, 0.02)),),
        transient_periods=2, record_periods=8, samples_per_period=16,
        options={"rtol": 1e-8, "atol": 1e-10},
    )  # fmt: skip
    results, _, _ = execute(plan, workers=1)
    ds = build_dataset(plan, results)
    for name, meaning in SCALARS.items():
        assert ds[name].attrs["long_name"] == meaning
    header = csv_text(ds, plan).splitlines()[0].split(",")
    assert [c for c in header if c in SCALARS] == list(SCALARS)


_DIE_MARKER = None


def _die_once(tasks):
    """A worker function that kills its process the first time (a lost worker)."""
    from rubcli.analysis.sweep.point import compute_points

    marker = Path(_DIE_MARKER)
    if not marker.exists():
        marker.write_text("died")
        os._exit(1)
    return compute_points(tasks)


def test_a_lost_pool_worker_is_replaced_and_its_point_retried(fig3_params, tmp_path, monkeypatch):
    """A worker process that dies breaks the pool: a new pool runs the lost points again,
    and the results equal an in-process run."""
    import multiprocessing

    if multiprocessing.get_start_method() != "fork":
        pytest.skip("the patched worker function reaches the workers only by fork")
    from rubcli.analysis.sweep import engine

    plan = _small_plan(fig3_params)
    reference, _, _ = execute(plan, workers=1)
    global _DIE_MARKER
    _DIE_MARKER = str(tmp_path / "died")
    monkeypatch.setattr(engine, "compute_points", _die_once)
    results, stats, where = execute(plan, workers=2)
    assert (tmp_path / "died").exists()
    assert where == "process pool (2 workers)"
    assert stats.pool_restarts >= 1 and stats.retried >= 1
    assert stats.computed == plan.n_points == 6
    for key, result in reference.items():
        assert results[key].ok
        assert results[key].final_state == result.final_state
        np.testing.assert_equal(results[key].scalars, result.scalars)  # NaN == NaN here


def test_a_failed_point_is_recorded_and_the_chain_goes_on(fig3_params):
    """A step budget that eta = 0.7818 (about 500 steps in 8 periods, rubbing) cannot meet
    fails that point, not the sweep; eta = 3 (about 130 steps, free) then starts again
    from [initial]."""
    plan = SweepPlan(
        fig3_params(mu=0.0), (0.88544, -0.8039, 0.0, 0.0), (Axis("eta", (0.7818, 3.0)),),
        direction="up", transient_periods=0, record_periods=8, samples_per_period=16,
        options={"rtol": 1e-8, "atol": 1e-10, "max_steps": 300}, energy=False,
    )  # fmt: skip
    results, stats, _ = execute(plan, workers=1)
    assert stats.computed == 2
    ds = build_dataset(plan, results)
    d = ds.sel(direction="up")
    assert d["eta"].values.tolist() == [0.7818, 3.0]
    assert d["status"].values.tolist() == [1, 0]
    message = str(d["message"].values[0])
    assert message.startswith("record:") and "300" in message
    assert math.isnan(float(d["z_max"].values[0]))
    assert np.isnan(d["section_z"].values[0]).all()
    # the next point ran from the case's initial state: the same as a fresh run of it
    alone = SweepPlan(
        fig3_params(mu=0.0), (0.88544, -0.8039, 0.0, 0.0), (Axis("eta", (3.0,)),),
        direction="up", transient_periods=0, record_periods=8, samples_per_period=16,
        options={"rtol": 1e-8, "atol": 1e-10, "max_steps": 300}, energy=False,
    )  # fmt: skip
    fresh, _, _ = execute(alone, workers=1)
    assert results["up-1"].final_state == fresh["up-0"].final_state


RESUME_CASE = """
[case]
name = "resume"
[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6
mu = 0.0
Rp = 46.16
[initial]
x = 0.88544
y = -0.8039
[time]
periods = 10
samples_per_period = 16
[solver]
rtol = 1e-8
atol = 1e-10
[sweep]
parameter = "mu"
start = 0.0
stop = 0.05
num = 7
direction = "both"
transient_periods = 40
record_periods = 16
"""


def _run_cli(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "rubcli", *args],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


@pytest.mark.slow
def test_a_killed_sweep_resumes_to_the_same_files(tmp_path):
    """SIGKILL part way, run again: only the missing points are computed, and the files
    are identical to an uninterrupted run's."""
    case = _write(tmp_path, RESUME_CASE)
    plan = plan_from_case(load_case(case))
    total = plan.n_points
    out = tmp_path / "killed"
    store = out / f".rubcli-sweep-{plan.digest()}"
    proc = _run_cli(["sweep", str(case), "--out", str(out), "--workers", "1"])
    deadline = time.monotonic() + 300
    while len(list(store.glob("*.point"))) < 3:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    # nothing appears before the sweep is complete (the dir holds only its hidden store)
    assert not [p for p in out.iterdir() if not p.name.startswith(".")]
    stored = len(list(store.glob("*.point")))
    assert 3 <= stored < total

    result = CliRunner().invoke(app, ["sweep", str(case), "--out", str(out), "--workers", "2"])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    assert report["points_resumed"] == stored
    assert report["points_computed_this_run"] == total - stored
    assert not store.exists()  # the store is removed once the outputs are in place

    fresh = tmp_path / "fresh"
    result = CliRunner().invoke(app, ["sweep", str(case), "--out", str(fresh), "--workers", "1"])
    assert result.exit_code == 0, result.output
    assert json.loads((fresh / "report.json").read_text())["points_resumed"] == 0
    assert (out / "sweep.csv").read_bytes() == (fresh / "sweep.csv").read_bytes()
    import xarray as xr

    with (
        xr.open_dataset(out / "sweep.nc", engine="h5netcdf") as a,
        xr.open_dataset(fresh / "sweep.nc", engine="h5netcdf") as b,
    ):
        assert a.identical(b)
        assert int(a.sizes["mu"]) == 7 and int(a.sizes["section"]) == 16


BAD_TABLES = [
    ('parameter = "omega"\nvalues = [1.0]', "sweep.parameter", "Input should be"),
    ('parameter = "mu"\nvalues = []', "sweep.values", "at least 1 item"),
    ('parameter = "mu"\nvalues = [0.1, nan]', "sweep.values[1]", "finite"),
    ('parameter = "mu"\nstart = 0.0\nstop = 0.1', "sweep", "start, stop and num"),
    ('parameter = "eta"\nvalues = [0.0, 1.0]', "sweep", "eta must be > 0"),
    (
        'direction = "independent"\n[[sweep.axes]]\nparameter = "mu"\nvalues = [0.0]\n'
        '[[sweep.axes]]\nparameter = "x"\nvalues = [0.5]',
        "sweep",
        "mixes a model parameter and an initial-state axis",
    ),
    ('parameter = "x"\nvalues = [0.5]\ndirection = "up"', "sweep", "must be 'independent'"),
    (
        'parameter = "mu"\nstart = 0.0\nstop = 0.1\nnum = 600\ndirection = "both"\n'
        "max_points = 1000",
        "sweep",
        "1200 points",
    ),
    ('parameter = "mu"\nvalues = [0.1]\nsteps = 3', "sweep.steps", "unknown key"),
]


@pytest.mark.parametrize("table,field,problem", BAD_TABLES, ids=[b[2] for b in BAD_TABLES])
def test_bad_sweep_tables_exit_2_and_write_nothing(tmp_path, table, field, problem):
    text = FREE_CASE.split("[sweep]")[0] + "[sweep]\n" + table + "\n"
    case = _write(tmp_path, text)
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["sweep", str(case), "--out", str(out)])
    assert result.exit_code == 2
    assert f"{case}: {field}: " in result.output
    assert problem in result.output
    assert "Traceback" not in result.output
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.toml"]


def test_a_case_without_sweep_table_exits_2(tmp_path):
    case = _write(tmp_path, FREE_CASE.split("[sweep]")[0])
    result = CliRunner().invoke(app, ["sweep", str(case), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert "missing table [sweep]" in result.output
    assert not (tmp_path / "out").exists()


def test_an_unreachable_scheduler_is_a_clear_error_in_bounded_time(tmp_path):
    text = FREE_CASE + "scheduler_timeout_s = 1.0\n"
    case = _write(tmp_path, text)
    out = tmp_path / "out"
    result = CliRunner().invoke(
        app, ["sweep", str(case), "--out", str(out), "--scheduler", "tcp://127.0.0.1:9"]
    )
    assert result.exit_code == 2
    assert f"{case}: --scheduler: cannot reach the Dask scheduler" in result.output
    assert "within 1 s" in result.output
    assert "Traceback" not in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.toml"]


def test_plan_chains_and_quick_mode():
    """Chains: one per direction (1-D), one per row (2-D), one per point (independent)."""
    case = load_case(REPO / "cases" / "examples" / "mu-eta-map.toml")
    plan = plan_from_case(case)
    chains = plan.chains()
    assert len(chains) == 16 and all(len(c.points) == 36 for c in chains)
    assert chains[0].points[0].start is not None and chains[0].points[1].start is None
    quick = plan_from_case(case, quick=True)
    assert quick.shape == (5, 5)
    assert quick.axes[0].values == (0.5, 1.4, 2.3, 3.1, 4.0)  # 36 values: indices 0 9 18 26 35
    assert (quick.transient_periods, quick.record_periods) == (20, 16)
    basins = plan_from_case(load_case(REPO / "cases" / "examples" / "basins.toml"))
    assert len(basins.chains()) == 31 * 31
    point = basins.point("independent", (0, 30))
    assert point.start == (-1.5, 1.5, 0.0, 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("path", SWEEP_CASES, ids=lambda p: p.name)
def test_shipped_sweep_cases_run_quick(path, tmp_path):
    """Every case with a [sweep] table runs `rubcli sweep --quick` and writes its files."""
    out = tmp_path / "out"
    args = ["sweep", str(path), "--out", str(out), "--workers", "1", "--quick"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    plan = plan_from_case(load_case(path), quick=True)
    expected = {"sweep.nc", "sweep.csv", "report.json"}
    if plan.is_basin:
        expected.add("basins.png")
        if plan.recognition is not None:
            expected.add("convergence.png")
    elif len(plan.axes) == 2:
        expected.add("map.png")
    else:
        expected |= {"bifurcation.png", "summary.png"}
        if plan.spectrum:
            expected.add("cascade.png")
    assert {p.name for p in out.iterdir()} == expected
    report = json.loads((out / "report.json").read_text())
    assert report["points"] == plan.n_points == report["points_computed_this_run"]
    assert report["points_failed"] == 0
    lines = (out / "sweep.csv").read_text().splitlines()
    assert len(lines) == 1 + plan.n_points


def test_workers_beyond_the_cores_are_refused_unless_oversubscribed(tmp_path):
    # thousands of processes exhaust the machine (each point is CPU-bound anyway)
    from rubcli.analysis.sweep import check_workers, default_workers

    cores = default_workers()
    assert check_workers(None) == cores
    assert check_workers(cores) == cores
    with pytest.raises(ValueError, match="workers: 100000 processes"):
        check_workers(100000)
    assert check_workers(cores + 1, oversubscribe=True) == cores + 1
    with pytest.raises(ValueError, match="positive integer"):
        check_workers(0)
    with pytest.raises(ValueError, match="workers: 100000"):
        rubcli.sweep(_write(tmp_path, FREE_CASE), workers=100000)
    run = subprocess.run(
        [sys.executable, "-m", "rubcli", "sweep", _write(tmp_path, FREE_CASE), "--workers",
         "100000", "--out", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert run.returncode == 2 and "--workers: 100000 processes" in run.stderr
    assert "Traceback" not in run.stderr and not (tmp_path / "out").exists()
    # a local Dask cluster of as many workers is refused alike
    local = CliRunner().invoke(
        app,
        [
            "sweep",
            str(_write(tmp_path, FREE_CASE)),
            "--scheduler",
            "local",
            "--workers",
            "100000",
            "--out",
            str(tmp_path / "out"),
        ],
    )  # fmt: skip
    assert local.exit_code == 2 and "--workers: 100000 processes" in local.output
    assert not (tmp_path / "out").exists()


def _stored_point(store_dir):
    from rubcli.analysis.sweep.point import PointResult
    from rubcli.analysis.sweep.store import PointStore

    store = PointStore(store_dir, "d1g35t")
    result = PointResult(
        ok=True, message="", scalars={"z_max": 1.25}, section=np.arange(8.0).reshape(2, 4),
        final_state=(0.5, -0.25, 0.125, 1.0), spectrum=np.array([1.0, 2.0]),
    )  # fmt: skip
    store.save("up-0001", result)
    return store, store_dir / "up-0001.point"


def test_the_store_returns_what_it_stored_and_rejects_every_tampering(tmp_path):
    from rubcli.analysis.sweep.store import PointStore

    store, path = _stored_point(tmp_path / "store")
    assert (path.parent.stat().st_mode & 0o777) == 0o700  # private to the user
    loaded = store.load()["up-0001"]
    assert loaded.final_state == (0.5, -0.25, 0.125, 1.0) and loaded.scalars["z_max"] == 1.25
    good = path.read_bytes()
    # the chain's final state (the last-but-two float of the body), a header value, a byte of
    # section data, the same file under another point's name, another plan's digest
    end_state = good[: -16 - 8] + np.float64(0.75).tobytes() + good[-16:]
    tampered = {
        "state": end_state,
        "header": good.replace(b'"z_max": 1.25', b'"z_max": 99.0'),
        "section": good[:200] + bytes([good[200] ^ 1]) + good[201:],
        "ok": good.replace(b'"ok": true', b'"ok": false'),
    }
    for what, data in tampered.items():
        assert data != good, what
        path.write_bytes(data)
        assert store.load() == {} and store.rejected == ["up-0001.point"], what
    path.write_bytes(good)
    (path.parent / "up-0002.point").write_bytes(good)  # copied under another name
    assert set(store.load()) == {"up-0001"} and store.rejected == ["up-0002.point"]
    assert PointStore(path.parent, "other-plan").load() == {}


def test_a_store_not_this_users_own_is_never_adopted_written_or_removed(tmp_path):
    from rubcli.analysis.sweep.store import PointStore, StoreError

    store, path = _stored_point(tmp_path / "store")
    path.parent.chmod(0o777)  # planted open to everyone's writes
    with pytest.raises(StoreError, match="can be written by other users"):
        store.load()
    store.remove()
    assert path.exists()  # not removed either
    link = tmp_path / "link"
    link.symlink_to(path.parent)
    with pytest.raises(StoreError, match="not a directory"):
        PointStore(link, "d1g35t").load()
    if os.getuid() == 0:  # root can make a directory another user's
        foreign = tmp_path / "foreign"
        foreign.mkdir(mode=0o700)
        os.chown(foreign, 65534, 65534)
        with pytest.raises(StoreError, match="belongs to another user"):
            _stored_point(foreign)


def test_a_tampered_chain_point_is_recomputed_not_trusted(fig3_params, tmp_path):
    plan = _small_plan(fig3_params)
    reference, _, _ = execute(plan, workers=1)
    store_dir = tmp_path / "store"
    execute(plan, workers=1, store_dir=store_dir)
    files = sorted(store_dir.glob("*.point"))
    assert len(files) == plan.n_points
    for path in files[:3]:  # the first points of a chain seed the later ones
        data = bytearray(path.read_bytes())
        data[-9] ^= 0x40  # a bit of the last stored float
        path.write_bytes(bytes(data))
    results, stats, _ = execute(plan, workers=1, store_dir=store_dir)
    assert stats.rejected == 3 and stats.computed == 3 and stats.resumed == plan.n_points - 3
    for key, ref in reference.items():
        np.testing.assert_array_equal(results[key].section, ref.section)
        assert results[key].final_state == ref.final_state


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


@pytest.mark.serial
@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_local_workers_die_with_a_killed_sweep(tmp_path):
    # SIGKILL gives the parent no chance to stop its pool: the workers must not live on
    case = Path(__file__).resolve().parents[1] / "cases" / "paper" / "fig3-mu-sweep.toml"
    proc = subprocess.Popen(
        [sys.executable, "-m", "rubcli", "sweep", str(case), "--workers", "2",
         "--oversubscribe", "--out", str(tmp_path / "out")],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip

    def children() -> list[int]:
        found = []
        for entry in Path("/proc").iterdir():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except (OSError, IndexError):
                continue
            if int(fields[1]) == proc.pid:
                found.append(int(entry.name))
        return found

    try:
        deadline = time.monotonic() + 300
        while len(children()) < 2 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        workers = children()
        assert len(workers) >= 2, "the sweep never started its workers"
    finally:
        proc.kill()
        proc.wait()
    deadline = time.monotonic() + 10
    alive = workers
    while alive and time.monotonic() < deadline:
        time.sleep(0.2)
        alive = [pid for pid in workers if _running(pid)]
    for pid in alive:  # do not leave them behind even when the test fails
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
    assert not alive, f"workers {alive} outlived their killed parent"


def test_a_task_batch_never_puts_the_work_of_all_workers_into_one_task(fig3_params):
    from rubcli.analysis.sweep import task_batch

    plan = _small_plan(fig3_params)  # one axis, up and down: two chains
    assert plan.n_chains == 2 and len(plan.chains()) == 2
    assert task_batch(1000, 2, plan.n_chains) == 1  # each worker gets a chain
    assert task_batch(1000, 2) == 8  # independent points: 8 per task
    assert task_batch(1000, 2, 1000) == 8 and task_batch(10, 2, 10) == 1


@pytest.mark.slow
@pytest.mark.parametrize(
    ("address", "says"),
    [("garbage!!", "not a scheduler address"), ("", "not a scheduler address"),
     ("http://127.0.0.1:8786", "not http://")],
)  # fmt: skip
def test_a_bad_scheduler_address_is_one_message_without_a_late_traceback(tmp_path, address, says):
    # a distributed.Client that failed to connect used to print a TimeoutError traceback
    # from its finaliser 20 s after the message
    run = subprocess.run(
        [sys.executable, "-m", "rubcli", "sweep", _write(tmp_path, FREE_CASE), "--scheduler",
         address, "--out", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert run.returncode == 2 and says in run.stderr
    assert "Traceback" not in run.stderr and "Exception ignored" not in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1


def test_a_sweep_case_with_too_few_samples_is_refused_naming_the_field(tmp_path):
    text = FREE_CASE.replace("samples_per_period = 32", "samples_per_period = 4")
    assert text != FREE_CASE
    case = _write(tmp_path, text)
    result = CliRunner().invoke(app, ["sweep", str(case), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and "time.samples_per_period" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("change", "says"),
    [("record_periods = 10000000", "GiB per point"),
     ("record_periods = 8\nspectrum_max_order = 1e9", "at most time.samples_per_period / 2"),
     # 500,000 points of 100 periods: 16 GiB at the measured 4,500 + 300 x 100 bytes
     ("record_periods = 100\nmax_points = 1000000\nstart = 0.5\nstop = 4.0\nnum = 500000",
      "until the files are written")],
)  # fmt: skip
def test_sweep_sizes_that_cannot_work_are_refused_before_any_point(tmp_path, change, says):
    text = FREE_CASE.replace("record_periods = 8", change)
    if "num = 500000" in change:
        text = text.replace("values = [0.5, 0.8, 1.0, 1.3, 2.0]\n", "")
    assert text != FREE_CASE
    case = _write(tmp_path, text)
    result = CliRunner().invoke(app, ["sweep", str(case), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and says in result.output
    assert "Traceback" not in result.output and not (tmp_path / "out").exists()


class _DroppingExecutor(cf.Executor):
    """Runs a task's first ``good`` submissions here, then returns every later one
    cancelled, as Dask's executor does when its scheduler connection drops."""

    def __init__(self, good: int):
        self.good = good

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        future: cf.Future = cf.Future()
        if self.good > 0:
            self.good -= 1
            future.set_result(fn(*args, **kwargs))
        else:  # as Dask's executor does: cancelled, and its waiters told
            future.cancel()
            future.set_running_or_notify_cancel()
        return future


@pytest.mark.slow
def test_a_dropped_task_is_never_stored_as_a_result(fig3_params, tmp_path):
    """Cancelled tasks (a lost scheduler) are held, not recorded as failed points; the
    watch stops the run with the finished points stored and nothing else."""
    from rubcli.analysis.sweep import ExecutorLostError, PointStore, run_plan

    plan = _small_plan(fig3_params)
    store = PointStore(tmp_path / "store", plan.digest(), plan.to_dict())
    calls = []

    def watch() -> None:
        calls.append(1)
        if len(calls) >= 2:
            raise ExecutorLostError("the scheduler is unreachable")

    with pytest.raises(ExecutorLostError):
        run_plan(plan, _DroppingExecutor(good=2), store=store, workers=1, watch=watch)
    stored = dict(PointStore(tmp_path / "store", plan.digest(), plan.to_dict()).load())
    assert len(stored) == 2 and all(r.ok for r in stored.values())


def test_a_dropped_task_goes_back_once_the_executor_is_well(fig3_params):
    from rubcli.analysis.sweep import run_plan

    plan = _small_plan(fig3_params)
    reference, _, _ = execute(plan, workers=1)

    class Flaky(_DroppingExecutor):
        def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
            self.good = 0 if self.good == 3 else 1  # drops every fourth task
            return super().submit(fn, *args, **kwargs)

    results, _stats = run_plan(plan, Flaky(good=1), workers=1, watch=lambda: None)
    assert {k: r.final_state for k, r in results.items()} == {
        k: r.final_state for k, r in reference.items()
    }


def _wait_for_cluster(address: str, timeout: float = 120.0) -> None:
    """Until the scheduler at ``address`` answers and has a worker (bounded)."""
    from distributed import Client

    with Client(address, timeout=timeout, set_as_default=False) as client:
        client.wait_for_workers(1, timeout=timeout)


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.serial
@pytest.mark.slow
@pytest.mark.parametrize("lost", ["scheduler", "workers"])
def test_a_dask_sweep_that_loses_its_cluster_stops_with_its_points_kept(tmp_path, lost):
    """A real scheduler and worker; one of them is killed mid-sweep: the sweep stops in
    bounded time with exit 69, one message and no traceback, its finished points kept for
    a local resume."""
    pytest.importorskip("distributed")
    address = f"tcp://127.0.0.1:{_free_port()}"
    values = ", ".join(f"{0.5 + 0.01 * i:.2f}" for i in range(150))
    text = FREE_CASE.replace("values = [0.5, 0.8, 1.0, 1.3, 2.0]", f"values = [{values}]")
    text = text.replace("transient_periods = 80", "transient_periods = 400")
    case = _write(tmp_path, text + "scheduler_lost_timeout_s = 4.0\n")
    out = tmp_path / "out"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    port = address.rsplit(":", 1)[1]
    scheduler = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
         "--port", port, "--no-dashboard"], **quiet,
    )  # fmt: skip
    worker = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
         "--no-nanny", "--no-dashboard"], **quiet,
    )  # fmt: skip
    sweep = None
    try:
        _wait_for_cluster(address)  # the sweep is started on a cluster that is up
        sweep = _run_cli(["sweep", str(case), "--out", str(out), "--scheduler", address])
        store = None
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and sweep.poll() is None:
            stores = list(out.glob(".rubcli-sweep-*"))
            if stores and len(list(stores[0].glob("*.point"))) >= 3:
                store = stores[0]
                break
            time.sleep(0.1)
        ended = sweep.communicate()[1] if sweep.poll() is not None else ""
        assert store is not None, f"the sweep never stored a point: {ended}"
        (scheduler if lost == "scheduler" else worker).kill()
        killed = time.monotonic()
        _stdout, stderr = sweep.communicate(timeout=120)
        waited = time.monotonic() - killed
    finally:
        for proc in (sweep, scheduler, worker):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.wait()
    assert sweep.returncode == 69, stderr
    says = "is unreachable" if lost == "scheduler" else "has no worker"
    assert says in stderr and "points are kept in" in stderr
    assert "Traceback" not in stderr and "Error" not in stderr.replace(str(case), "")
    assert waited < 60
    assert not [p for p in out.iterdir() if not p.name.startswith(".")]
    kept = len(list(store.glob("*.point")))
    assert 3 <= kept < 150
    resumed = subprocess.run(
        [sys.executable, "-m", "rubcli", "sweep", str(case), "--out", str(out),
         "--workers", "1", "--json"],
        cwd=REPO, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["points_resumed"] == kept and report["points_failed"] == 0


def test_a_sweep_on_dask_shows_none_of_distributeds_logs():
    """While a sweep runs on Dask, no record of distributed's reaches its stderr handler:
    among them the INFO record with a traceback that ``distributed.batched`` writes when
    the connection to a killed scheduler closes in the middle of a write (the sweep says
    in one line that its scheduler is lost); their levels are restored afterwards."""
    pytest.importorskip("distributed")
    import logging

    from rubcli.analysis.sweep import quiet_dask_client

    names = ["distributed.batched", "distributed.core", "distributed.client", "tornado.application"]
    before = [logging.getLogger(name).getEffectiveLevel() for name in names]
    with quiet_dask_client():
        for name in names:
            assert not logging.getLogger(name).isEnabledFor(logging.ERROR), name
    assert [logging.getLogger(name).getEffectiveLevel() for name in names] == before

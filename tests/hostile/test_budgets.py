"""Budgets end to end: ``rubcli orbits`` bounded in wall time with progress in a log, and
inputs that once ran for minutes refused or stopped at once (real subprocesses).

Every run here is ``python -m rubcli`` in a subprocess with a timeout, as a user runs it;
each checks the exit code, the message and that no traceback was printed. Runs are kept
to seconds with small budgets (``--max-wall-time``, ``--periods``, ``--quick``).
"""

from __future__ import annotations

import json
import math
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .conftest import SWEEP_CASE

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT_S = 120
TRACEBACK = re.compile(r'Traceback|^\s*File "', re.M)

ORBITS_CASE = """\
[case]
name = "orbits"

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
periods = 1
samples_per_period = 50

[orbits]
parameter = "mu"
min = 0.0
max = 0.06
step = 0.002
max_step = 0.005
start = "synchronous_rub"
"""


def rubcli(tmp_path: Path, *args, timeout: float = TIMEOUT_S) -> subprocess.CompletedProcess:
    """``python -m rubcli ARGS`` in ``tmp_path``, its stdout and stderr not terminals;
    fails the test on a traceback or a timeout."""
    env = {**os.environ, "RUBCLI_STATE_DIR": str(tmp_path / ".state"), "COLUMNS": "100"}
    done = subprocess.run(
        [sys.executable, "-m", "rubcli", *map(str, args)], cwd=tmp_path, env=env,
        capture_output=True, text=True, timeout=timeout, check=False,
    )  # fmt: skip
    assert not TRACEBACK.search(done.stderr), done.stderr
    return done


def case(tmp_path: Path, text: str, **table) -> Path:
    """A case file: ``text`` with the keys of ``table`` set in [orbits]."""
    lines = [ln for ln in text.splitlines() if ln.split(" = ")[0] not in table]
    i = lines.index("[orbits]")
    lines[i + 1 : i + 1] = [f"{k} = {json.dumps(v)}" for k, v in table.items()]
    path = tmp_path / "case.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.slow
@pytest.mark.parametrize(
    "table",
    [
        {"period": 64, "start": "initial"},
        {"start": "transient", "transient_periods": 100000},
    ],
    ids=["period-64", "transient-1e5"],
)
def test_orbits_ends_within_its_wall_time_budget_with_a_message(tmp_path, table):
    """A period-64 search and a 1e5-period transient once ran past 300 s with no word;
    both now stop at the budget (here 3 s), exit 1, say so, and report it."""
    path = case(tmp_path, ORBITS_CASE, **table)
    start = time.perf_counter()
    done = rubcli(tmp_path, "orbits", path, "--out", "out", "--max-wall-time", 3)
    elapsed = time.perf_counter() - start
    assert done.returncode == 1, done.stderr
    assert "wall-time budget" in done.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["branch"]["wall_time_budget_exhausted"] is True
    assert report["continuation"]["max_wall_time_s"] == 3
    assert elapsed < TIMEOUT_S  # (the subprocess timeout is the real guard)


@pytest.mark.slow
def test_orbits_prints_progress_where_no_bar_shows(tmp_path):
    """On a non-terminal (a log, CI) orbits once printed nothing until the end."""
    path = case(tmp_path, ORBITS_CASE, max_points=3)
    done = rubcli(tmp_path, "orbits", path, "--out", "out", "--quick")
    assert done.returncode == 0, done.stderr
    assert "progress: orbits: the starting orbit, 0 orbits, 0 s of the 3600 s budget" in (
        done.stderr
    )


@pytest.mark.slow
def test_orbits_budget_is_checked_as_input(tmp_path):
    path = case(tmp_path, ORBITS_CASE)
    done = rubcli(tmp_path, "orbits", path, "--out", "out", "--max-wall-time", "nan")
    assert done.returncode == 2 and "--max-wall-time: must be a finite number > 0" in done.stderr
    done = rubcli(tmp_path, "orbits", case(tmp_path, ORBITS_CASE, max_wall_time_s=0.0))
    assert done.returncode == 2 and "orbits.max_wall_time_s" in done.stderr
    assert not (tmp_path / "out").exists()


def test_orbits_step_that_cannot_move_the_parameter_is_refused(tmp_path):
    """``step = 1e-300`` left mu where it was, point after point, until killed."""
    done = rubcli(tmp_path, "orbits", case(tmp_path, ORBITS_CASE, step=1e-300), "--out", "out")
    assert done.returncode == 2, done.stderr
    assert "orbits: min_step 1e-303 is below 1e-12 of the window" in done.stderr
    assert not (tmp_path / "out").exists()


RUN_CASE = """\
[case]
name = "run"

[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6
mu = 0.03
Rp = 46.16

[initial]
x = 0.88544
y = -0.8039

[time]
periods = 50
samples_per_period = 20
"""


@pytest.mark.slow
@pytest.mark.parametrize(
    ("change", "field"),
    [("K = 1e300", "model.K"), ("e = 1e308", "model.e"), ("eta = 1e-300", "model.eta"),
     ("K = 1e60", "model.K")],
)  # fmt: skip
def test_run_refuses_magnitudes_that_once_ran_for_minutes(tmp_path, change, field):
    """``K = 1e300``, ``e = 1e308`` (3 minutes with the analytic methods and rk45) and
    ``eta = 1e-300`` (741 s with rk45) are outside the model's domain: exit 2 at once,
    naming the field, nothing written."""
    name = change.split(" = ")[0]
    text = "\n".join(ln for ln in RUN_CASE.splitlines() if not ln.startswith(f"{name} = "))
    path = tmp_path / "case.toml"
    path.write_text(text.replace("[model]", f"[model]\n{change}") + "\n")
    done = rubcli(tmp_path, "run", path, "--out", "out", "-m", "lsoda", "-m", "analytic")
    assert done.returncode == 2, done.stderr
    assert f"case.toml: {field}: " in done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_run_at_the_edge_of_the_domain_fails_within_its_budget(tmp_path):
    """K = 1e19 (in the domain, not integrable in a small budget): every method fails with
    its reason within [solver] max_steps, exit 1, outputs written."""
    text = RUN_CASE.replace("K = 17.6", "K = 1e19") + "\n[solver]\nmax_steps = 20000\n"
    path = tmp_path / "case.toml"
    path.write_text(text)
    done = rubcli(tmp_path, "run", path, "--out", "out", "--periods", "2", "-m", "lsoda",
                  "-m", "rk45", "-m", "analytic", "--json")  # fmt: skip
    assert done.returncode == 1, done.stderr
    methods = json.loads(done.stdout)["methods"]
    for name, entry in methods.items():
        assert entry["status"] == "failed", name
        assert entry["stats"]["nsteps"] <= 20000


FORCES_CASE = RUN_CASE + '\n[forces_map]\nresolution = {resolution}\nproducts = ["eigen"]\n'


def test_forces_map_refuses_a_grid_that_will_not_fit_in_memory(tmp_path):
    """A 3000^2 grid needs about 2.3 GiB (measured per point, benchmarks/
    forces_map_memory.md); with 2 GiB of address space it is refused at once, exit 2,
    naming the field and the largest grid that fits (it once ran into a MemoryError)."""
    path = tmp_path / "case.toml"
    path.write_text(FORCES_CASE.format(resolution=3000))

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 * 1024**3, 2 * 1024**3))

    env = {**os.environ, "RUBCLI_STATE_DIR": str(tmp_path / ".state")}
    done = subprocess.run(
        [sys.executable, "-m", "rubcli", "forces-map", str(path), "--out", "out"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=TIMEOUT_S,
        check=False, preexec_fn=cap,
    )  # fmt: skip
    assert not TRACEBACK.search(done.stderr), done.stderr
    assert done.returncode == 2, done.stderr
    assert "forces_map.resolution: a 3000 x 3000 grid needs about 2.3 GiB" in done.stderr
    assert re.search(r"at most \d+ fits", done.stderr)
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_forces_map_case_limit_follows_the_measured_cost(tmp_path):
    """The largest grid a case may ask for (8 GiB) follows the measured cost per point:
    6688, which the old estimate of 192 bytes per point accepted, needs about 9.5 GiB."""
    path = tmp_path / "case.toml"
    path.write_text(FORCES_CASE.format(resolution=6688))
    done = rubcli(tmp_path, "validate", path)
    assert done.returncode == 2, done.stderr
    assert "forces_map.resolution: a 6688 x 6688 grid needs about 9.46 GiB" in done.stderr
    assert "at most 6120" in done.stderr


def whirl_case(tmp_path: Path, **table) -> Path:
    """The paper's whirl case (e = 0) with the keys of ``table`` set in [orbits]."""
    text = (ROOT / "cases" / "paper" / "fig3-whirls.toml").read_text()
    text = text.replace('dir = "out/fig3-whirls"', 'dir = "out"')
    return case(tmp_path, text, **table)


# Steps of 1e-7 in a window of 0.1: a million corrector solves, minutes without a budget.
CRAWLING_WHIRLS = {"step": 1e-7, "min_step": 1e-9, "max_step": 1e-7, "max_points": 100000}


@pytest.mark.slow
@pytest.mark.parametrize("where", ["option", "table"])
def test_whirls_end_within_their_wall_time_budget(tmp_path, where):
    """``kind = "whirl"`` once ignored both the table's budget and --max-wall-time (still
    tracing after 150 s with 3 s): now it stops at the budget like a periodic-orbit
    branch, writes the whirls traced, says so and exits 1."""
    if where == "option":
        path, extra = whirl_case(tmp_path, **CRAWLING_WHIRLS), ["--max-wall-time", 2]
    else:
        path, extra = whirl_case(tmp_path, **CRAWLING_WHIRLS, max_wall_time_s=2.0), []
    done = rubcli(tmp_path, "orbits", path, "--out", "out", *extra, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "stopped by the wall-time budget (2 s)" in done.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["whirls"]["wall_time_budget_exhausted"] is True
    assert report["continuation"]["max_wall_time_s"] == 2
    stops = report["whirls"]["branches"][0]["stops"]
    assert "wall-time budget exhausted (max_wall_time_s = 2)" in stops.values()
    assert (tmp_path / "out" / "branch.csv").exists()


def test_whirls_budget_is_checked_as_input(tmp_path):
    done = rubcli(tmp_path, "orbits", whirl_case(tmp_path), "--out", "out",
                  "--max-wall-time", "nan")  # fmt: skip
    assert done.returncode == 2 and "--max-wall-time: must be a finite number > 0" in done.stderr
    assert not (tmp_path / "out").exists()


@pytest.fixture
def wrong_service():
    """``start(mode)``: a TCP server on 127.0.0.1 that is not a Dask scheduler and its
    tcp:// address: ``silent`` accepts and says nothing, ``http`` answers like an HTTP
    server, ``random`` sends random bytes first. Each serves in a daemon thread that stops
    by itself after 90 s, or when the test ends."""
    import socket
    import threading

    servers = []

    def start(mode: str) -> str:
        server = socket.create_server(("127.0.0.1", 0))
        server.settimeout(1.0)
        servers.append(server)
        stop_at = time.monotonic() + 90

        def serve() -> None:
            held = []
            while time.monotonic() < stop_at:
                try:
                    conn, _ = server.accept()
                except TimeoutError:
                    continue
                except OSError:  # closed by the test's end
                    break
                held.append(conn)
                if mode == "http":
                    conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
                elif mode == "random":
                    conn.sendall(os.urandom(4096))
            for conn in held:
                conn.close()

        threading.Thread(target=serve, daemon=True).start()
        return f"tcp://127.0.0.1:{server.getsockname()[1]}"

    yield start
    for server in servers:
        server.close()


@pytest.mark.serial
@pytest.mark.slow
@pytest.mark.parametrize("mode", ["silent", "http", "random"])
def test_sweep_refuses_a_service_that_is_not_a_dask_scheduler(
    run_cli, case_file, out_dir, wrong_service, mode
):
    """A listener that says nothing and an HTTP server once held ``--scheduler`` for
    minutes whatever scheduler_timeout_s; random bytes first ended in a MemoryError of
    exabytes. Each is now refused within the timeout: exit 69, the address named."""
    pytest.importorskip("distributed")
    address = wrong_service(mode)
    path = case_file(SWEEP_CASE.replace("[sweep]", "[sweep]\nscheduler_timeout_s = 2"))
    start = time.monotonic()
    done = run_cli("sweep", path, "--out", out_dir, "--scheduler", address, timeout=60)
    assert done.code == 69, done.stderr
    assert f"--scheduler: no Dask scheduler answered at '{address}' within 2 s" in done.stderr
    assert "MemoryError" not in done.stderr
    assert not out_dir.exists()
    assert time.monotonic() - start < 50  # 2 s and the start-up, not minutes


@pytest.mark.slow
@pytest.mark.parametrize(
    ("command", "shipped"),
    [("chart", "examples/mu-eta-map.toml"), ("run", "runup/driven-dry-whip.toml"),
     ("orbits", None)],
)  # fmt: skip
def test_an_overlay_that_is_not_a_regular_file_is_refused_at_once(
    run_cli, case_file, out_dir, tmp_path, command, shipped
):
    """``--overlay`` at a FIFO once blocked for ever in open(); now anything but a regular
    file is refused before it is read: exit 2, the path named, nothing written."""
    text = (ROOT / "cases" / shipped).read_text() if shipped else ORBITS_CASE
    path = case_file(text)
    fifo = tmp_path / "sweep.nc"
    os.mkfifo(fifo)
    done = run_cli(command, path, "--out", out_dir, "--overlay", fifo, timeout=60)
    assert done.code == 2, done.stderr
    assert f"{fifo}: --overlay: not a regular file" in done.stderr
    assert not out_dir.exists()


def largest_chart(tmp_path: Path, extra: str = "") -> Path:
    """The shipped mu-eta chart on the largest grid a case may ask for (2001 x 2001, once
    8 minutes and more), with ``extra`` lines in its [chart] table."""
    text = (ROOT / "cases" / "examples" / "mu-eta-map.toml").read_text()
    path = tmp_path / "chart.toml"
    path.write_text(text.replace("y_max = 0.3", f"y_max = 0.3\nnx = 2001\nny = 2001\n{extra}"))
    return path


@pytest.mark.slow
@pytest.mark.parametrize("where", ["option", "table"])
def test_chart_ends_within_its_wall_time_budget(tmp_path, where):
    """``rubcli chart`` had no budget; now the largest grid stops at it: exit 1, one
    message, nothing written."""
    if where == "option":
        path, extra = largest_chart(tmp_path), ["--max-wall-time", 2]
    else:
        path, extra = largest_chart(tmp_path, "max_wall_time_s = 2.0"), []
    done = rubcli(tmp_path, "chart", path, "--out", "out", *extra, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "chart.toml: stopped by the wall-time budget (2 s): nothing written" in done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_chart_budget_is_checked_as_input(tmp_path):
    done = rubcli(tmp_path, "chart", largest_chart(tmp_path), "--max-wall-time", "inf")
    assert done.returncode == 2 and "--max-wall-time: must be a finite number > 0" in done.stderr
    done = rubcli(tmp_path, "chart", largest_chart(tmp_path, "max_wall_time_s = 0.0"))
    assert done.returncode == 2 and "chart.max_wall_time_s" in done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
@pytest.mark.parametrize("where", ["option", "table"])
def test_forces_map_ends_within_its_wall_time_budget(tmp_path, where):
    """``rubcli forces-map`` had no wall-time budget (the largest grid a case may ask for
    runs for many minutes); now it stops at one: exit 1, one message, nothing written."""
    table = FORCES_CASE.format(resolution=2000)
    if where == "table":
        table += "max_wall_time_s = 1.0\n"
    path = tmp_path / "case.toml"
    path.write_text(table)
    extra = ["--max-wall-time", 1] if where == "option" else []
    done = rubcli(tmp_path, "forces-map", path, "--out", "out", *extra, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "case.toml: stopped by the wall-time budget (1 s): nothing written" in done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_sweep_ends_within_its_wall_time_budget(run_cli, case_file, out_dir):
    """``rubcli sweep`` had no budget of its own (only each point's); now it stops at one,
    exit 1, keeping the finished points for the next run, its outputs not written."""
    # 40 points of 5000 periods each: half a minute or more without a budget
    long_points = SWEEP_CASE.replace("transient_periods = 20", "transient_periods = 5000")
    long_points = long_points.replace("values = [0.5, 0.8, 1.0, 1.3, 2.0]",
                                      "start = 0.5\nstop = 2.0\nnum = 40")  # fmt: skip
    path = case_file(long_points.replace("[sweep]", "[sweep]\nmax_wall_time_s = 2.0"))
    done = run_cli("sweep", path, "--out", out_dir, "--workers", 1, timeout=90)
    assert done.code == 1, done.stderr
    assert "case.toml: stopped by the wall-time budget (2 s): " in done.stderr
    assert "run the same command again to compute only the others" in done.stderr
    assert not (out_dir / "sweep.nc").exists()
    done = run_cli("sweep", path, "--out", out_dir, "--max-wall-time", "nan")
    assert done.code == 2 and "--max-wall-time: must be a finite number > 0" in done.stderr


@pytest.mark.slow
@pytest.mark.parametrize("where", ["option", "table"])
def test_run_ends_within_its_wall_time_budget(tmp_path, where):
    """``rubcli run`` was bounded only by each method's budget (600 s apiece); now the
    whole run stops at its own: exit 1, one message, nothing written."""
    text = RUN_CASE + '\n[solver]\nmethods = ["rk45", "lsoda"]\n'
    if where == "table":
        text += "total_wall_time_s = 2.0\n"
    path = tmp_path / "case.toml"
    path.write_text(text)
    extra = ["--max-wall-time", 2] if where == "option" else []
    done = rubcli(tmp_path, "run", path, "--out", "out", "--periods", 100000, *extra,
                  timeout=60)  # fmt: skip
    assert done.returncode == 1, done.stderr
    assert "case.toml: stopped by the wall-time budget (2 s): nothing written" in done.stderr
    assert not (tmp_path / "out").exists()
    done = rubcli(tmp_path, "run", path, "--out", "out", "--max-wall-time", "-1")
    assert done.returncode == 2 and "--max-wall-time: must be a finite number > 0" in done.stderr


@pytest.mark.slow
def test_stress_ends_within_its_wall_time_budget(tmp_path):
    """``rubcli stress`` (the full suite runs for many minutes) was bounded only by each
    run's budget; now the whole suite stops at its own: exit 1, one message, nothing
    written."""
    done = rubcli(tmp_path, "stress", "--out", "out", "--max-wall-time", 2, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "stress: stopped by the wall-time budget (2 s) after " in done.stderr
    assert "nothing written" in done.stderr
    assert not (tmp_path / "out").exists()
    done = rubcli(tmp_path, "stress", "--out", "out", "--max-wall-time", "nan")
    assert done.returncode == 2 and "--max-wall-time: must be a finite number > 0" in done.stderr


def ensemble_case(tmp_path: Path, shipped: str, budget: str = "", **changes: str) -> Path:
    """A shipped ensemble case, each ``key = value`` line of ``changes`` replaced, and
    ``budget`` added to its [ensemble] table."""
    lines = (ROOT / "cases" / shipped).read_text().splitlines()
    lines = [f"{ln.split(' = ')[0]} = {changes[ln.split(' = ')[0]]}"
             if ln.split(" = ")[0] in changes else ln for ln in lines]  # fmt: skip
    path = tmp_path / "case.toml"
    lines.insert(lines.index("[ensemble]") + 1, budget)
    path.write_text("\n".join(lines) + "\n")
    return path


# The basin stability of two values, two starts each, then the minimal perturbation along
# a thousand directions: the budget runs out in the bisections.
PERTURBATIONS = {"start": "1.8", "stop": "1.9", "num": "2", "runs": "2",
                 "perturbation_directions": "1000"}  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(
    ("shipped", "changes", "budget", "extra"),
    [("paper/fig3-ensemble.toml", {}, "", ["--max-wall-time", 3, "--workers", 2]),
     ("paper/fig3-ensemble.toml", {}, "max_wall_time_s = 3.0", ["--workers", 1]),
     ("examples/basin-stability.toml", {}, "max_wall_time_s = 3.0", ["--workers", 2]),
     ("examples/basin-stability.toml", PERTURBATIONS, "", ["--max-wall-time", 6,
                                                          "--workers", 1])],
    ids=["cloud-option", "cloud-table", "basin-table", "perturbation-option"],
)  # fmt: skip
def test_ensemble_ends_within_its_wall_time_budget(tmp_path, shipped, changes, budget, extra):
    """``rubcli ensemble`` (a cloud of runs, the basin stability along a parameter and its
    minimal perturbations: minutes to hours) was bounded only by each run's budget; now
    the whole command stops at its own: exit 1, one message, nothing written."""
    path = ensemble_case(tmp_path, shipped, budget, **changes)
    done = rubcli(tmp_path, "ensemble", path, "--out", "out", *extra, timeout=60)
    assert done.returncode == 1, done.stderr
    seconds = 6 if "perturbation_directions" in changes else 3
    assert f"case.toml: stopped by the wall-time budget ({seconds} s): nothing written" in (
        done.stderr
    )
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_ensemble_budget_is_checked_as_input(tmp_path):
    path = ensemble_case(tmp_path, "paper/fig3-ensemble.toml")
    done = rubcli(tmp_path, "ensemble", path, "--out", "out", "--max-wall-time", "0")
    assert done.returncode == 2 and "--max-wall-time: must be a finite number > 0" in done.stderr
    path = ensemble_case(tmp_path, "paper/fig3-ensemble.toml", "max_wall_time_s = -1.0")
    done = rubcli(tmp_path, "ensemble", path, "--out", "out")
    assert done.returncode == 2 and "ensemble.max_wall_time_s" in done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
@pytest.mark.parametrize("where", ["option", "table"])
def test_compare_ends_within_its_wall_time_budget(tmp_path, where):
    """``rubcli compare`` (a reference, then every method at nine tolerances, three times
    each, then the orbits: here minutes) was bounded only by each solve's budget; now the
    whole command stops at its own: exit 1, one message, nothing written."""
    text = RUN_CASE.replace("periods = 50", "periods = 2000")
    text += '\n[solver]\nmethods = ["rk45", "lsoda"]\n\n[compare]\nmu = [0.0, 0.01, 0.02]\n'
    if where == "table":
        text += "total_wall_time_s = 3.0\n"
    path = tmp_path / "case.toml"
    path.write_text(text)
    extra = ["--max-wall-time", 3] if where == "option" else []
    done = rubcli(tmp_path, "compare", path, "--out", "out", *extra, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "case.toml: stopped by the wall-time budget (3 s): nothing written" in done.stderr
    assert not (tmp_path / "out").exists()
    done = rubcli(tmp_path, "compare", path, "--out", "out", "--max-wall-time", "inf")
    assert done.returncode == 2 and "--max-wall-time: must be a finite number > 0" in done.stderr


@pytest.mark.parametrize(
    ("entry", "shipped"),
    [("run.run_case", None), ("compare.compare_case", None), ("stress.run_stress", None),
     ("ensemble.ensemble_of", "paper/fig3-ensemble.toml"),
     ("basin_stability.basin_stability_of", "examples/basin-stability.toml")],
)  # fmt: skip
def test_study_entries_check_their_wall_time_budget(tmp_path, entry, shipped):
    """The library functions behind run, compare, stress and ensemble take the command's
    budget, checked as ``solve`` checks its own: the function and the argument named."""
    import importlib

    from rubcli import load_case

    module, name = entry.split(".")
    function = getattr(importlib.import_module(f"rubcli.studies.{module}"), name)
    path = tmp_path / "case.toml"
    path.write_text((ROOT / "cases" / shipped).read_text() if shipped else RUN_CASE)
    args = () if module == "stress" else (load_case(path),)
    for bad in (math.nan, -1.0, 0.0):
        with pytest.raises(ValueError, match=rf"^{name}\(\): max_wall_time_s must be finite"):
            function(*args, max_wall_time_s=bad)
    with pytest.raises(TypeError, match=rf"^{name}\(\): max_wall_time_s must be a real number"):
        function(*args, max_wall_time_s="3")

"""The command line through the real typer app: exit codes, files written, report, CSV."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import solvers
from rubcli.case import load_case
from rubcli.cli.app import app
from rubcli.io import CSV_COLUMNS, CSV_PHYSICAL_COLUMNS

ROOT_CASE = Path(__file__).resolve().parents[1] / "cases" / "paper" / "fig3a.toml"

runner = CliRunner()

CASE = """\
[case]
name = "short"

[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6
mu = 0.01
Rp = 46.16

[initial]
x = 0.88544
y = -0.8039

[time]
periods = 2
samples_per_period = 20

[solver]
methods = ["rk45"]
"""

PHYSICAL_CASE = """\
[case]
name = "machine"

[physical]
m = 4.0
k_r = 4.0e4
d_r = 8.0
k_s = 8.0e5
clearance = 1.0e-3
e = 2.0e-3
Omega = 80.0
Rp = 0.05
mu = 0.01

[initial]
x = 5.0e-4
y = 0.0

[time]
periods = 2
samples_per_period = 20

[solver]
methods = ["rk45"]
"""


def write_case(tmp_path: Path, text: str, output: str = "", name: str = "case.toml") -> Path:
    path = tmp_path / name
    path.write_text(text + ("\n[output]\n" + output if output else ""), encoding="utf-8")
    return path


def invoke(*args: str):
    return runner.invoke(app, [str(a) for a in args])


def files_in(directory: Path) -> set[str]:
    return {p.name for p in directory.iterdir()} if directory.exists() else set()


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and the numbers of a solution CSV (text columns such as regime_name as NaN)."""
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    text = [i for i, name in enumerate(rows[0]) if name == "regime_name"]
    for row in rows[1:]:
        for i in text:
            row[i] = "nan"
    return rows[0], np.array(rows[1:], dtype=float)


def read_regime_names(path: Path) -> list[str]:
    with open(path, newline="") as handle:
        return [row["regime_name"] for row in csv.DictReader(handle)]


# ------------------------------------------------------------------ init and validate


@pytest.mark.parametrize(
    "flags",
    [[], ["--physical"], ["--machine", "general"], ["--machine", "general", "--physical"]],
)
def test_init_prints_a_case_that_validates(tmp_path, flags):
    result = invoke("init", *flags)
    assert result.exit_code == 0
    path = tmp_path / "my.toml"
    path.write_text(result.stdout, encoding="utf-8")
    assert "#" in result.stdout  # commented
    load_case(path)
    check = invoke("validate", path)
    assert check.exit_code == 0, check.output
    assert "valid" in check.stdout


def test_init_general_describes_the_general_machine_and_refuses_an_unknown_one(tmp_path):
    result = invoke("init", "--machine", "general")
    path = tmp_path / "general.toml"
    path.write_text(result.stdout, encoding="utf-8")
    p = load_case(path).params
    assert not p.is_paper_machine and {"offset", "load", "stiffness", "damping"} <= set(
        p.machine_dict()
    )
    bad = invoke("init", "--machine", "rigid")
    assert bad.exit_code == 2 and "--machine: must be paper or general" in bad.stderr


def test_validate_shows_the_converted_physical_case(tmp_path):
    result = invoke("validate", write_case(tmp_path, PHYSICAL_CASE))
    assert result.exit_code == 0, result.output
    assert "K=20" in result.stdout and "eta=0.8" in result.stdout
    assert "omega=100 rad/s" in result.stdout


def test_validate_invalid_exits_2_naming_file_and_field(tmp_path):
    path = write_case(tmp_path, CASE.replace("K = 17.6", "K = -17.6"))
    result = invoke("validate", path)
    assert result.exit_code == 2
    assert f"{path}: model.K: Input should be greater than 0" in result.stderr
    assert "Traceback" not in result.output


def test_validate_missing_file_exits_2(tmp_path):
    result = invoke("validate", tmp_path / "none.toml")
    assert result.exit_code == 2
    assert "none.toml: file not found" in result.stderr


def test_version_and_help():
    assert invoke("--version").stdout.strip() == "rubcli 0.1.0"
    result = invoke("--help")
    assert result.exit_code == 0
    for command in ("init", "validate", "run"):
        assert command in result.stdout


def test_python_dash_m_entry_point():
    result = subprocess.run(
        [sys.executable, "-m", "rubcli", "--version"], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "rubcli 0.1.0"


# ------------------------------------------------------------------------------- run


def test_run_writes_exactly_the_requested_files(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, CASE, 'csv = true\nplots = ["orbit"]\n')
    result = invoke("run", path, "--out", out)
    assert result.exit_code == 0, result.output
    assert files_in(out) == {"rk45.csv", "orbit.png", "report.json"}
    assert files_in(tmp_path) == {"case.toml", "out"}  # no staging dir left behind
    report = json.loads((out / "report.json").read_text())
    assert report["files"] == ["rk45.csv", "orbit.png", "report.json"]


def test_run_without_products_writes_only_the_report(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, CASE, "csv = false\nplots = []\n")
    result = invoke("run", path, "--out", out)
    assert result.exit_code == 0, result.output
    assert files_in(out) == {"report.json"}


def test_run_default_output_dir_and_case_output_dir(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = write_case(tmp_path, CASE, 'plots = ["time"]\n')
    assert invoke("run", path).exit_code == 0
    assert files_in(tmp_path / "out" / "short") == {"rk45.csv", "time.png", "report.json"}
    path = write_case(tmp_path, CASE, 'dir = "elsewhere"\ncsv = false\nplots = []\n')
    assert invoke("run", path).exit_code == 0
    assert files_in(tmp_path / "elsewhere") == {"report.json"}


def test_method_option_overrides_the_case(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, CASE, "plots = []\n")
    result = invoke("run", path, "--method", "analytic", "-m", "dop853", "--out", out)
    assert result.exit_code == 0, result.output
    assert files_in(out) == {"analytic.csv", "dop853.csv", "report.json"}
    report = json.loads((out / "report.json").read_text())
    assert list(report["methods"]) == ["analytic", "dop853"]
    assert report["case"]["settings"]["solver"]["methods"] == ["analytic", "dop853"]
    assert report["command_line"]["methods"] == ["analytic", "dop853"]


def test_periods_option_overrides_the_horizon(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, CASE, "plots = []\n")
    result = invoke("run", path, "--periods", "0.5", "--out", out)
    assert result.exit_code == 0, result.output
    header, table = read_csv(out / "rk45.csv")
    assert table.shape[0] == 11  # 0.5 periods * 20 samples + 1
    assert table[-1, 0] == pytest.approx(0.5 * 2 * math.pi / 0.7818)


def test_report_contents(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, CASE, "plots = []\n")
    assert invoke("run", path, "-m", "analytic", "-m", "rk45", "--out", out).exit_code == 0
    report = json.loads((out / "report.json").read_text())
    assert report["success"] is True
    assert report["rubcli_version"] == "0.1.0"
    case = report["case"]
    assert case["source"] == str(path)
    assert case["settings"]["model"]["K"] == 17.6
    assert case["settings"]["solver"]["rtol"] == 1e-8  # defaults are echoed
    assert case["nondimensional"]["n_samples"] == 41
    assert case["scale"] is None
    # the contact numbers against an independent tight run of the same problem
    ref = solvers.solve(load_case(path).problem, "dop853-jit", rtol=1e-12, atol=1e-13)
    assert len(ref.events) >= 4  # the case has contacts to count
    for name in ("analytic", "rk45"):
        entry = report["methods"][name]
        assert entry["status"] == "success"
        assert entry["message"] == "reached the end of the time span"
        assert entry["wall_time_s"] > 0
        assert entry["stats"]["nsteps"] > 0
        assert entry["n_contact_switches"] == ref.n_contact_switches
        assert entry["contact_fraction"] == pytest.approx(ref.contact_fraction(), abs=1e-3)
        # the paper's case starts 0.196 inside the stator
        assert entry["max_penetration"] == pytest.approx(ref.max_penetration(), abs=1e-3)
        assert entry["settings"]
        assert entry["files"] == [f"{name}.csv"]
    assert report["methods"]["rk45"]["settings"]["rtol"] == 1e-8
    assert report["methods"]["analytic"]["settings"]["steps_per_period"] == 400


def test_csv_columns_and_values(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, CASE, "plots = []\n")
    assert invoke("run", path, "--out", out).exit_code == 0
    header, table = read_csv(out / "rk45.csv")
    assert header == list(CSV_COLUMNS)
    col = {name: table[:, i] for i, name in enumerate(header)}
    assert table.shape[0] == 41
    np.testing.assert_allclose(col["z"], np.hypot(col["x"], col["y"]), rtol=1e-15)
    assert set(np.unique(col["contact"])) <= {0.0, 1.0}
    assert set(np.unique(col["regime"])) <= {-1.0, 0.0, 1.0, 2.0}  # slip-, free, slip+, stick
    np.testing.assert_array_equal(col["contact"], (col["regime"] != 0).astype(float))
    names = {-1: "slip-", 0: "free", 1: "slip+", 2: "stick"}
    assert read_regime_names(out / "rk45.csv") == [names[int(r)] for r in col["regime"]]
    in_contact = col["contact"] == 1
    np.testing.assert_allclose(
        col["normal_force"][in_contact], 17.6 * (col["z"][in_contact] - 1.0), rtol=1e-12
    )
    assert np.all(col["normal_force"][~in_contact] == 0.0)
    slipping = np.abs(col["regime"]) == 1  # in stick the friction is below mu F_N
    np.testing.assert_allclose(
        np.abs(col["friction_force"][slipping]), 0.01 * col["normal_force"][slipping], rtol=1e-12
    )


def test_physical_csv_columns(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, PHYSICAL_CASE, "plots = []\n")
    assert invoke("run", path, "--out", out).exit_code == 0
    header, table = read_csv(out / "rk45.csv")
    assert header == list(CSV_COLUMNS) + list(CSV_PHYSICAL_COLUMNS)
    col = {name: table[:, i] for i, name in enumerate(header)}
    # omega = 100 rad/s, clearance = 1 mm, k_r * clearance = 40 N (see tests/test_case.py)
    np.testing.assert_allclose(col["t_s"], col["tau"] / 100.0, rtol=1e-15)
    np.testing.assert_allclose(col["x_m"], col["x"] * 1e-3, rtol=1e-15)
    np.testing.assert_allclose(col["vy_m_s"], col["vy"] * 0.1, rtol=1e-15)
    np.testing.assert_allclose(col["normal_force_N"], col["normal_force"] * 40.0, rtol=1e-15)
    np.testing.assert_allclose(col["friction_force_N"], col["friction_force"] * 40.0, rtol=1e-15)
    assert col["x"][0] == pytest.approx(0.5)  # 0.5 mm in a 1 mm clearance
    report = json.loads((out / "report.json").read_text())
    assert report["case"]["scale"] == {"omega": 100.0, "clearance": 1e-3, "k_r": 4e4, "k_s": 8e5}


def test_physical_plots(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, PHYSICAL_CASE, "csv = false\n")
    assert invoke("run", path, "--out", out).exit_code == 0
    assert files_in(out) == {"orbit.png", "time.png", "report.json"}
    assert (out / "orbit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------------- failures


@pytest.mark.parametrize(
    ("text", "args", "words"),
    [
        (CASE.replace("K = 17.6", "K = nan"), [], "model.K: Input should be a finite number"),
        (CASE.replace("[time]", "[time]\nstep = 1"), [], "time.step: unknown key"),
        (CASE.replace("[case]", "[case"), [], "not valid TOML"),
        (CASE, ["--method", "euler"], "--method: unknown method 'euler'"),
        (CASE, ["--periods", "-1"], "--periods"),
        (CASE, ["--periods", "nan"], "--periods"),
        (CASE, ["--periods", "inf"], "--periods: must be a finite number > 0"),
        # the override re-validates the case: 1e9 periods x 20 samples is too many
        (CASE, ["--periods", "1e9"], "invalid command-line override"),
        (CASE, ["--periods", "1e9"], "time: periods * samples_per_period = 2e+10 output"),
    ],
)
def test_invalid_input_exits_2_and_writes_nothing(tmp_path, text, args, words):
    out = tmp_path / "results" / "out"
    path = write_case(tmp_path, text)
    result = invoke("run", path, *args, "--out", out)
    assert result.exit_code == 2, result.output
    assert words in result.stderr
    assert "Traceback" not in result.output
    assert not (tmp_path / "results").exists()
    assert files_in(tmp_path) == {"case.toml"}


def test_missing_case_file_exits_2(tmp_path):
    result = invoke("run", tmp_path / "none.toml", "--out", tmp_path / "out")
    assert result.exit_code == 2
    assert "none.toml: file not found" in result.stderr
    assert files_in(tmp_path) == set()


def test_output_dir_that_is_a_file_exits_2(tmp_path):
    (tmp_path / "taken").write_text("x")
    result = invoke("run", write_case(tmp_path, CASE), "--out", tmp_path / "taken")
    assert result.exit_code == 2
    assert "not a directory" in result.stderr


def test_solver_failure_exits_1_and_still_writes(tmp_path):
    out = tmp_path / "out"
    text = CASE.replace('methods = ["rk45"]', 'methods = ["analytic", "rk45"]\nmax_steps = 1')
    path = write_case(tmp_path, text, "plots = []\n")
    result = invoke("run", path, "--out", out)
    assert result.exit_code == 1, result.output
    assert "method analytic failed" in result.stderr
    assert "method rk45 failed" in result.stderr
    assert "Traceback" not in result.output
    report = json.loads((out / "report.json").read_text())
    assert report["success"] is False
    for name in ("analytic", "rk45"):
        assert report["methods"][name]["status"] == "failed"
        assert report["methods"][name]["message"]
    assert files_in(out) == {"analytic.csv", "rk45.csv", "report.json"}


def test_solver_exception_is_reported_not_swallowed(tmp_path, monkeypatch):
    def broken(problem, options):
        raise RuntimeError("solver exploded")

    monkeypatch.setitem(solvers.METHODS, "dop853", broken)
    out = tmp_path / "out"
    path = write_case(tmp_path, CASE, 'plots = ["orbit"]\n')
    result = invoke("run", path, "-m", "dop853", "-m", "rk45", "--out", out)
    assert result.exit_code == 1
    assert "solver exploded" in result.stderr
    assert "Traceback" in result.stderr  # the traceback is shown
    report = json.loads((out / "report.json").read_text())
    assert report["methods"]["dop853"]["status"] == "error"
    assert "RuntimeError: solver exploded" in report["methods"]["dop853"]["message"]
    assert report["methods"]["rk45"]["status"] == "success"
    assert files_in(out) == {"rk45.csv", "orbit.png", "report.json"}


def test_interrupted_run_writes_nothing(tmp_path, monkeypatch):
    """An exception after solving (here: in plotting) leaves no partial output dir."""
    from rubcli.plotting import run as plots

    def broken_figure(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, "time_figure", broken_figure)
    out = tmp_path / "out"
    path = write_case(tmp_path, CASE, 'plots = ["orbit", "time"]\n')
    result = invoke("run", path, "--out", out)
    assert result.exit_code == 130  # typer's exit code for an interrupt (128 + SIGINT)
    assert not out.exists()
    assert files_in(tmp_path) == {"case.toml"}


@pytest.mark.slow
def test_a_run_of_a_compiled_method_loads_no_scipy_integrator(tmp_path):
    """`rubcli run` imports scipy's integrators only for a scipy method (they cost about
    0.3 s of every run's start): the registry, the analysis modules and the CLI import
    them when a function needs them."""
    out = tmp_path / "out"
    script = (
        "import sys\n"
        "from rubcli.cli.app import main\n"
        f"sys.argv = ['rubcli', 'run', {str(ROOT_CASE)!r}, '-m', 'dop853-jit', '--periods',"
        f" '0.5', '--out', {str(out)!r}]\n"
        "try:\n    main()\nexcept SystemExit as exc:\n    assert not exc.code, exc.code\n"
        "loaded = [m for m in ('scipy.integrate', 'scipy.optimize', 'scipy.interpolate')"
        " if m in sys.modules]\n"
        "assert loaded == [], loaded\n"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-2000:]
    assert (out / "dop853-jit.csv").is_file() and (out / "orbit.png").is_file()


def test_no_output_work_runs_beside_a_timed_solve(tmp_path, monkeypatch):
    """`rubcli run` solves every method alone (a method's reported time is its own) and
    only then hands its background thread the plotting import and the CSVs."""
    from rubcli import io

    log = []
    original_solve, original_submit = solvers.solve, io.Background.submit

    def solve(problem, method, **options):
        log.append(("solve", method))
        return original_solve(problem, method, **options)

    def submit(self, fn, *args, **kwargs):
        log.append(("background", fn.__name__))
        return original_submit(self, fn, *args, **kwargs)

    monkeypatch.setattr(solvers, "solve", solve)
    monkeypatch.setattr(io.Background, "submit", submit)
    out = tmp_path / "out"
    result = invoke("run", write_case(tmp_path, CASE), "-m", "dop853", "-m", "rk45", "--out", out)
    assert result.exit_code == 0, result.output
    timed = [i for i, (kind, _) in enumerate(log) if kind == "solve"][-2:]  # (after start-up)
    background = [i for i, (kind, _) in enumerate(log) if kind == "background"]
    assert min(background) > max(timed)
    assert [log[i][1] for i in background] == ["_import_plotting"] + ["write_solution_csv"] * 2
    assert (out / "dop853.csv").is_file() and (out / "rk45.csv").is_file()


def test_notice_if_slow_prints_only_for_a_long_wait(monkeypatch):
    """The notice comes from a timer thread once the block has run ``after_s`` seconds,
    and never once the block has ended."""
    import threading

    from rubcli.cli import console

    printed = threading.Event()
    messages = []

    def info(message):
        messages.append(message)
        printed.set()

    monkeypatch.setattr(console, "info", info)
    with console.notice_if_slow("still busy", after_s=0.01):
        assert printed.wait(timeout=30.0)  # the block outlasts after_s: the notice comes
    assert messages == ["still busy"]
    printed.clear()
    with console.notice_if_slow("not shown", after_s=0.5):
        pass
    assert not printed.wait(timeout=1.0)  # the block ended first: the timer is cancelled
    assert messages == ["still busy"]


def test_run_says_the_kernels_compile_when_start_up_is_slow(tmp_path, monkeypatch):
    """A start-up that takes long (numba compiling on a first run: 10 s to 1.5 min) is
    announced while it runs, instead of a silent wait that looks like a hang."""
    import threading

    from rubcli.cli import console, run
    from rubcli.studies import run as run_study

    original = run_study.start_up
    announced = threading.Event()
    original_info = console.info

    def info(message):
        if message == run.COMPILING_NOTICE:
            announced.set()
        original_info(message)

    def slow_start_up(case):
        assert announced.wait(timeout=30.0)  # announced while the start-up still runs
        return original(case)

    monkeypatch.setattr(console, "info", info)
    monkeypatch.setattr(run_study, "start_up", slow_start_up)
    monkeypatch.setattr(run, "START_UP_NOTICE_S", 0.01)
    out = tmp_path / "out"
    result = invoke("run", write_case(tmp_path, CASE), "-m", "dop853-jit", "--out", out)
    assert result.exit_code == 0, result.output
    assert "compiling the numba kernels" in result.output

"""Reliability defects, one test each, and --json.

Output dirs: checked before solving, staged on the target's filesystem, cleaned on
signals, with a manifest (report.json's ``files``) that makes reruns safe. Results: a
"success" that fails a plausibility check is a warning. Messages: formatted, short,
never a raw numpy warning. Samples and docs: every method and table named.
"""

from __future__ import annotations

import ast
import errno
import json
import os
import re
import signal
import subprocess
import sys
import time
import tomllib
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import io, model, solvers
from rubcli.case import KNOWN_METHODS, CaseFile, load_case_text
from rubcli.cli import console, tables
from rubcli.cli.app import app
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.samples import SAMPLE_CASE, SAMPLE_PHYSICAL_CASE
from rubcli.solution import Solution
from rubcli.solvers.rub import slip_velocity

ROOT = Path(__file__).resolve().parents[1]
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


def write_case(tmp_path: Path, text: str = CASE, output: str = "") -> Path:
    path = tmp_path / "case.toml"
    path.write_text(text + ("\n[output]\n" + output if output else ""), encoding="utf-8")
    return path


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def names(directory: Path) -> set[str]:
    return {p.name for p in directory.iterdir()} if directory.exists() else set()


@pytest.fixture
def count_solves(monkeypatch):
    """Count the solves of rk45 (to prove that nothing was solved)."""
    calls = []
    original = solvers.METHODS["rk45"]

    def counting(problem, options):
        calls.append(problem)
        return original(problem, options)

    monkeypatch.setitem(solvers.METHODS, "rk45", counting)
    return calls


# ------------------------------------------------------------------ 1. checked first


def test_unwritable_output_dir_is_refused_before_solving(tmp_path, count_solves):
    locked = tmp_path / "locked"
    locked.mkdir()
    if os.geteuid() == 0:  # root writes anywhere but in /proc
        target = Path("/proc/self/rubcli-out")
    else:
        locked.chmod(0o500)
        target = locked / "out"
    result = invoke("run", write_case(tmp_path), "--out", target)
    assert result.exit_code == 2, result.output
    assert "not writable" in result.stderr and str(target) in result.stderr
    assert "Traceback" not in result.output
    assert count_solves == []  # refused before any solve


def test_output_dir_that_is_a_file_is_refused_by_every_command(tmp_path):
    (tmp_path / "taken").write_text("x")
    path = write_case(tmp_path)
    for args in (["run", path], ["compare", path, "--quick"], ["forces-map", path],
                 ["stress", "--quick"]):  # fmt: skip
        result = invoke(*args, "--out", tmp_path / "taken")
        assert result.exit_code == 2, (args, result.output)
        assert "not a directory" in result.stderr


# ------------------------------------------------------------ 2. other filesystems


def test_staging_survives_a_cross_device_target(tmp_path, monkeypatch):
    """A rename out of the target's own tree fails as between filesystems (a bind mount):
    the commit never needs one (it stages inside the target) and leaks no staging."""
    real_replace, real_rename = os.replace, os.rename
    target = tmp_path / "out"

    def cross_device(real):
        def move(src, dst):
            if target not in Path(src).parents or target not in Path(dst).parents:
                raise OSError(errno.EXDEV, "Invalid cross-device link")
            return real(src, dst)

        return move

    monkeypatch.setattr(os, "replace", cross_device(real_replace))
    monkeypatch.setattr(os, "rename", cross_device(real_rename))
    with io.staged_output_dir(target) as staged:
        io.write_text(staged.path("a.csv"), "1\n")
        io.write_text(staged.path("report.json"), "{}\n")
    assert names(target) == {"a.csv", "report.json"}
    assert names(tmp_path) == {"out"}  # no .staging-* left


def test_staging_into_a_symlink_to_another_filesystem(tmp_path):
    shm = Path("/dev/shm")
    if not shm.is_dir() or os.stat(shm).st_dev == os.stat(tmp_path).st_dev:
        pytest.skip("needs /dev/shm on another filesystem than the test's tmp dir")
    import tempfile

    elsewhere = Path(tempfile.mkdtemp(dir=shm, prefix="rubcli-test-"))
    try:
        (tmp_path / "link").symlink_to(elsewhere)
        result = invoke("run", write_case(tmp_path, output="plots = []\n"), "--out",
                        tmp_path / "link")  # fmt: skip
        assert result.exit_code == 0, result.output
        assert names(elsewhere) == {"rk45.csv", "report.json"}
        assert names(tmp_path) == {"case.toml", "link"}
        assert not [p for p in shm.iterdir() if p.name.startswith(".rubcli-staging-")]
    finally:
        import shutil

        shutil.rmtree(elsewhere, ignore_errors=True)


def test_a_failed_commit_leaks_no_staging(tmp_path, monkeypatch):
    def broken(src, dst):
        raise OSError(errno.EIO, "I/O error")

    monkeypatch.setattr(os, "replace", broken)
    with pytest.raises(io.OutputWriteError), io.staged_output_dir(tmp_path / "out") as staged:
        (staged.path("a.csv")).write_text("1")
    assert not [p for p in tmp_path.rglob("*") if "staging" in p.name]


# ------------------------------------------------------------------- 3. signals

SLOW_WRITE = """
import sys, time
from rubcli.io import outputs
real = outputs.StagedOutput.write_report

def slow(*args, **kwargs):  # the report is written last, into the staging dir
    print("WRITING", flush=True)
    time.sleep(60)
    return real(*args, **kwargs)

outputs.StagedOutput.write_report = slow
sys.argv = ["rubcli", *sys.argv[1:]]
from rubcli.cli.app import main
main()
"""


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_signal_during_writing_removes_staging_and_keeps_earlier_outputs(tmp_path, signum):
    out = tmp_path / "out"
    path = write_case(tmp_path, output="plots = []\n")
    assert invoke("run", path, "--out", out).exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    script = tmp_path / "slow.py"
    script.write_text(SLOW_WRITE)
    proc = subprocess.Popen(
        [sys.executable, str(script), "run", str(path), "--out", str(out), "--periods", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        line = ""
        while "WRITING" not in line and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line and proc.poll() is not None:
                break
        assert "WRITING" in line, proc.stderr.read()
        assert [p for p in out.iterdir() if "staging" in p.name]  # mid-write
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signum, err
    assert "Traceback" not in err
    assert "no outputs of this run were written" in err
    assert names(tmp_path) == {"case.toml", "out", "slow.py"}  # no staging left
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


# -------------------------------------------------------------- 6. memory bounds


def test_forces_map_resolution_is_bounded_by_memory(tmp_path):
    path = write_case(tmp_path, CASE + "\n[forces_map]\nresolution = 100000\n")
    result = invoke("validate", path)
    assert result.exit_code == 2
    assert "forces_map.resolution" in result.stderr and "GiB of memory" in result.stderr
    assert "at most" in result.stderr
    ok = write_case(tmp_path, CASE + "\n[forces_map]\nresolution = 4000\n")
    assert invoke("validate", ok).exit_code == 0


def test_samples_times_methods_are_bounded_by_memory(tmp_path):
    text = CASE.replace("periods = 2\n", "periods = 90000\n").replace(
        "samples_per_period = 20", "samples_per_period = 100"
    )
    text = text.replace('methods = ["rk45"]', 'methods = ["rk45", "dop853", "radau"]')
    result = invoke("validate", write_case(tmp_path, text))
    assert result.exit_code == 2
    assert "3 methods need about" in result.stderr


# ------------------------------------------------------------ 7. loose tolerances


def test_loose_tolerance_nonsense_is_a_warning_not_a_success(tmp_path):
    text = CASE.replace('methods = ["rk45"]', 'methods = ["rk45"]\nrtol = 0.999999\natol = 1e300')
    out = tmp_path / "out"
    result = invoke("run", write_case(tmp_path, text, "plots = []\n"), "--out", out)
    report = json.loads((out / "report.json").read_text())
    entry = report["methods"]["rk45"]
    assert entry["solver_status"] == "success"
    assert entry["status"] == "warning" and entry["warnings"]
    assert entry["max_penetration"] > entry["penetration_bound"]
    assert report["success"] is False
    assert result.exit_code == 3
    assert "do not trust this result" in result.stderr


def test_plausibility_checks_on_known_solutions():
    from rubcli.analysis.runs import checks

    params = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.0, Rp=46.16)
    start = model.synchronous_rub(np.array([0.0]), params)[:, 0]
    problem = Problem.from_periods(params, start, 2, 20)
    exact = model.synchronous_rub(problem.t_eval, params).T
    regimes = np.full(problem.t_eval.size, model.SLIP_POSITIVE)
    good = Solution(problem, "exact", problem.t_eval, exact, regimes)
    assert checks.method_summary(good)["warnings"] == []  # the exact orbit passes
    bound = checks.penetration_bound(problem)
    deep = exact * (1.0 + 2.0 * bound)  # the same orbit, far beyond the bound
    warnings = checks.plausibility_warnings(
        Solution(problem, "deep", problem.t_eval, deep, regimes), None
    )
    assert any("static bound" in w for w in warnings)
    nan = exact.copy()
    nan[5, 0] = np.nan
    summary = checks.method_summary(Solution(problem, "nan", problem.t_eval, nan, regimes))
    assert summary["status"] == "warning" and "non-finite" in summary["warnings"][0]
    energy = {"energy_residual": 0.5, "energy_quadrature_error": 1e-6}
    assert "energy balance" in checks.plausibility_warnings(good, energy)[0]
    energy["energy_quadrature_error"] = 0.1  # a residual within its floor says nothing
    assert checks.plausibility_warnings(good, energy) == []


def test_penetration_bound_covers_the_rolling_whirl():
    from rubcli.analysis.runs import checks

    params = ModelParams(nu=0.01, eta=0.79, e=1.25, K=10.0, mu=0.1, Rp=250.0)
    problem = Problem.from_periods(params, (0.0, 0.0, 0.0, 0.0), 1, 10)
    assert checks.penetration_bound(problem) > model.rolling_whirl_radius(params) - 1.0
    assert checks.penetration_bound(Problem.from_periods(
        ModelParams(nu=0.0, eta=0.79, e=1.25, K=10.0), (0.5, 0, 0, 0), 1, 10)) is None  # fmt: skip


# ------------------------------------------------------------------- 8. reruns


def test_rerun_removes_the_stale_files_of_the_previous_run(tmp_path):
    out = tmp_path / "out"
    path = write_case(tmp_path, output='plots = ["orbit"]\n')
    assert invoke("run", path, "-m", "rk45", "-m", "dop853", "--out", out).exit_code == 0
    assert names(out) == {"rk45.csv", "dop853.csv", "orbit.png", "report.json"}
    (out / "notes.txt").write_text("mine")
    result = invoke("run", path, "-m", "rk45", "--out", out)
    assert result.exit_code == 0, result.output
    assert names(out) == {"rk45.csv", "orbit.png", "report.json", "notes.txt"}
    assert "removed 1 files of the previous run" in result.stderr
    assert "dop853.csv" in result.stderr
    assert json.loads((out / "report.json").read_text())["files"] == [
        "rk45.csv", "orbit.png", "report.json"]  # fmt: skip


def test_a_case_dir_holding_only_rubcli_sub_dirs_is_usable(tmp_path):
    """`rubcli compare` first (out/<case>/compare/), then `rubcli run` into out/<case>."""
    out = tmp_path / "out"
    (out / "compare").mkdir(parents=True)
    report = {**io.report_envelope("compare", {}), "files": ["report.json"]}
    io.write_json(out / "compare" / "report.json", report)
    result = invoke("run", write_case(tmp_path, output="plots = []\n"), "--out", out)
    assert result.exit_code == 0, result.output
    assert names(out) == {"compare", "rk45.csv", "report.json"}
    assert names(out / "compare") == {"report.json"}


@pytest.mark.parametrize("where", ["here", "data"])
def test_non_empty_dir_not_written_by_rubcli_is_refused_unless_force(
    tmp_path, monkeypatch, count_solves, where
):
    monkeypatch.chdir(tmp_path)
    data = tmp_path / "data"
    data.mkdir()
    (data / "precious.csv").write_text("keep me")
    path = write_case(tmp_path, output="plots = []\n")
    target = "." if where == "here" else "data"
    result = invoke("run", path, "--out", target)
    assert result.exit_code == 2
    assert "not written by rubcli" in result.stderr and "--force" in result.stderr
    assert count_solves == []
    result = invoke("run", path, "--out", "data", "--force")
    assert result.exit_code == 0, result.output
    assert (data / "precious.csv").read_text() == "keep me"
    assert names(data) == {"precious.csv", "rk45.csv", "report.json"}


# ------------------------------------------------------------ 9. python warnings

OLD_PHYSICAL_SAMPLE = (
    SAMPLE_PHYSICAL_CASE.replace("k_s = 1.0e8 ", "k_s = 4.0e6 ")
    .replace("mu = 0.05 ", "mu = 0.1 ")
    .replace("x = 1.0e-4\n", "x = 0.0\n")
)


@pytest.mark.slow
def test_no_raw_numpy_warning_reaches_the_console(tmp_path):
    """The former physical sample: starts at x = y = 0 and sticks (0/0 in the stick force
    of the first sample); every stderr line is a formatted rubcli message. In a real
    process: under pytest, warnings would be captured by pytest instead."""
    text = OLD_PHYSICAL_SAMPLE.replace('methods = ["analytic", "rk45"]', 'methods = ["rk45"]')
    path = write_case(tmp_path, text)
    proc = subprocess.run(
        [sys.executable, "-m", "rubcli", "run", str(path), "--out", str(tmp_path / "out"),
         "--periods", "20"],
        capture_output=True, text=True, timeout=300, cwd=tmp_path,
    )  # fmt: skip
    assert proc.returncode in (0, 3), proc.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["methods"]["rk45"]["time_in_regime"]["stick"] > 0
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert all(line.startswith(("warning:", "error:", "  ")) for line in lines), lines
    assert "RuntimeWarning" not in proc.stderr


def test_python_warnings_are_formatted(capsys):
    with console.formatted_python_warnings():
        np.array([0.0]) / np.array([0.0])
    err = capsys.readouterr().err
    assert err.startswith("warning: RuntimeWarning: invalid value encountered in divide")
    assert "test_reliability.py:" in err and len(err.strip().splitlines()) == 1


def test_physical_sample_is_a_sensible_machine(tmp_path):
    case = load_case_text(SAMPLE_PHYSICAL_CASE)
    assert case.problem.initial[:2] != (0.0, 0.0)
    path = tmp_path / "p.toml"
    path.write_text(SAMPLE_PHYSICAL_CASE.replace('"analytic", "rk45"', '"rk45"'))
    out = tmp_path / "out"
    result = invoke("run", path, "--out", out, "--periods", "10")
    assert result.exit_code == 0, result.output
    assert result.stderr.strip() == ""
    entry = json.loads((out / "report.json").read_text())["methods"]["rk45"]
    assert 0.0 < entry["max_penetration"] < 0.5  # it rubs, a fraction of the clearance deep


# ------------------------------------------------------------------ 10. messages


def test_sample_limit_message_is_formatted(tmp_path):
    result = invoke("run", write_case(tmp_path), "--periods", "1e9", "--out", tmp_path / "o")
    assert result.exit_code == 2
    assert "{" not in result.stderr
    assert "2e+10 output samples, more than 10,000,000" in result.stderr


def test_init_help_shows_the_physical_table():
    result = invoke("init", "--help")
    assert "[physical]" in result.stdout


@pytest.mark.slow
def test_long_values_are_shortened_in_messages(tmp_path):
    huge = "x" * 5_000_000
    path = write_case(
        tmp_path, CASE.replace('name = "short"', f'name = "short"\ndescription = "{huge}"')
    )
    result = invoke("validate", path)
    assert result.exit_code == 0 and len(result.output) < 5_000
    assert "(5000000 characters)" in result.stdout
    bad = write_case(tmp_path, CASE.replace('name = "short"', f'name = "a{huge}"'))
    result = invoke("validate", bad)
    assert result.exit_code == 2 and len(result.output) < 5_000


def test_name_rule_says_ascii(tmp_path):
    result = invoke("validate", write_case(tmp_path, CASE.replace('"short"', '"größe"')))
    assert result.exit_code == 2
    assert "ASCII letters" in result.stderr


# -------------------------------------------------------------- 11. out of date


@pytest.mark.parametrize("sample", [SAMPLE_CASE, SAMPLE_PHYSICAL_CASE])
def test_init_samples_name_every_method_and_table(sample):
    for method in KNOWN_METHODS:
        assert method in sample, method
    for table in CaseFile.model_fields:
        if table in ("model", "physical"):
            continue  # one of the two, by sample
        assert f"[{table}]" in sample, table


def test_docs_cases_name_every_method_and_table():
    text = (ROOT / "docs" / "cases.md").read_text()
    for method in KNOWN_METHODS:
        assert f"`{method}`" in text, method
    for table in CaseFile.model_fields:
        assert f"`[{table}]`" in text, table
    example = re.search(r"solver\.methods\[1\]: Input should be (.*) \(got", text).group(1)
    assert all(f"'{m}'" in example for m in KNOWN_METHODS)


def test_console_tables_never_cut_a_number(capsys, monkeypatch):
    """At a width too narrow for the whole row (as a pipe or a CI log gets), a cell of
    words may wrap at its spaces, a number never."""
    monkeypatch.setattr(tables, "output_width", lambda: 60)
    rows = [["dop853-jit", "rtol = 1e-11", "0.01234", "1.234e-11", "2.345e-12", "14072",
             "1407200", "success"]]  # fmt: skip
    tables.table("work-precision", ["method", "setting", "wall s", "error max",
                  "error final", "steps", "f evals", "status"], rows)  # fmt: skip
    out = capsys.readouterr().out
    for cell in rows[0]:
        for word in cell.split():
            assert word in out, word


# --------------------------------------------------------------- 12. dependencies


def test_every_imported_package_is_declared():
    """Each third-party package imported by rubcli is a declared dependency (rich came
    only through typer's extras), or, for an optional feature, in its extra (dask, ross)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    declared = project["dependencies"] + extras["dask"] + extras["ross"]
    declared = {
        re.split(r"[<>=\[ ;]", d, maxsplit=1)[0].lower().replace("-", "_") for d in declared
    }
    imported = set()
    for path in (ROOT / "rubcli").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                imported |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                imported.add(node.module.split(".")[0])
    third_party = {m for m in imported if m not in sys.stdlib_module_names and m != "rubcli"}
    third_party -= {"pydantic_core"}  # part of pydantic
    # dask[distributed]; ross-rotordynamics is imported as ross
    aliases = {"tomli_w": "tomli_w", "distributed": "dask", "ross": "ross_rotordynamics"}
    missing = {m for m in third_party if aliases.get(m, m) not in declared}
    assert not missing, f"imported but not declared in pyproject.toml: {sorted(missing)}"


# ------------------------------------------------------------------ --json


def test_run_json_prints_only_the_report(tmp_path):
    out = tmp_path / "out"
    result = invoke("run", write_case(tmp_path, output="plots = []\n"), "--out", out, "--json")
    assert result.exit_code == 0, result.output
    printed = json.loads(result.stdout)  # nothing but the JSON
    assert printed == json.loads((out / "report.json").read_text())
    assert printed["command"] == "run" and printed["methods"]["rk45"]["status"] == "success"


def test_validate_json(tmp_path):
    result = invoke("validate", write_case(tmp_path), "--json")
    assert result.exit_code == 0
    data = json.loads(result.stdout)
    assert data["valid"] is True and data["case"]["settings"]["model"]["K"] == 17.6
    result = invoke("validate", write_case(tmp_path, CASE.replace("K = 17.6", "K = -1")),
                    "--json")  # fmt: skip
    assert result.exit_code == 2
    data = json.loads(result.stdout)
    assert data["valid"] is False and "model.K" in data["problems"][0]


def test_stress_json_prints_only_the_report(tmp_path):
    out = tmp_path / "s"
    result = invoke("stress", "--quick", "--case", "grazing-touch", "--method", "rk45",
                    "--out", out, "--json")  # fmt: skip
    assert result.exit_code == 0, result.output
    printed = json.loads(result.stdout)
    assert printed == json.loads((out / "report.json").read_text())
    assert printed["runs"][0]["case"] == "grazing-touch"
    assert names(out) == {"stress.csv", "stress.md", "report.json"}


# ---------------------------------------------------------------- streaming CSV


def _long_solution(n: int) -> Solution:
    params = ModelParams(nu=0.05, eta=0.5, e=0.5, K=10.0)
    t = np.linspace(0.0, 50.0, n)
    problem = Problem(params, (0.3, 0.0, 0.0, 0.1), t)
    states = model.free_flight(t, 0.0, problem.initial, params).T
    return Solution(problem, "exact", t, states, np.zeros(n, dtype=np.int64))


@pytest.mark.slow
def test_solution_csv_is_streamed_in_blocks_and_exact(tmp_path, monkeypatch):
    monkeypatch.setattr(io.tables, "CSV_BLOCK_ROWS", 1000)
    peaks = {}
    for n in (20_000, 60_000):
        sol = _long_solution(n)
        tracemalloc.start()
        io.write_solution_csv(tmp_path / f"{n}.csv", sol)
        peaks[n] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    # Three times the rows, about the same peak: the writer holds one block at a time.
    assert peaks[60_000] < 1.3 * peaks[20_000], peaks
    data = np.genfromtxt(tmp_path / "60000.csv", delimiter=",", names=True, dtype=None,
                         encoding="utf-8")  # fmt: skip
    sol = _long_solution(60_000)
    np.testing.assert_array_equal(data["x"], sol.x)  # round-trip exact
    np.testing.assert_array_equal(data["v_r"], slip_velocity(sol))
    assert set(data["regime_name"]) == {"free"}


def test_csv_fields():
    assert io.csv_field(0.1) == "0.1" and float(io.csv_field(1 / 3)) == 1 / 3
    assert io.csv_field(float("nan")) == "nan" and io.csv_field(float("nan"), "") == ""
    assert io.csv_field(None) == "" and io.csv_field(True) == "true"
    assert io.csv_field('a, "b"') == '"a, ""b"""'


# ------------------------------------------------------------- layers


def _imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module)
            found |= {f"{node.module}.{a.name}" for a in node.names}
    return found


def test_the_numerical_core_and_analysis_stay_below_the_cli():
    core = [ROOT / "rubcli" / f"{m}.py" for m in ("model", "problem", "solution")]
    core += list((ROOT / "rubcli" / "solvers").rglob("*.py"))
    core += list((ROOT / "rubcli" / "analysis").rglob("*.py"))
    banned = ("typer", "pydantic", "matplotlib", "rubcli.cli", "rubcli.case", "rubcli.plotting")
    for path in core:
        bad = {m for m in _imports(path) if m.split(".")[0] in banned or m.startswith(banned)}
        assert not bad, f"{path.relative_to(ROOT)} imports {sorted(bad)}"


def test_cli_commands_do_not_import_each_other():
    # A command module defines `command` (app.py registers it); the others are helpers
    # (console, common, or the part of one command kept in its own module).
    shared = {"validate"}  # a command that is also a helper (load_or_exit)
    cli = ROOT / "rubcli" / "cli"
    modules = {p.stem for p in cli.glob("*.py")} - {"__init__", "app"}
    commands = {m for m in modules if "\ndef command(" in (cli / f"{m}.py").read_text()}
    assert {"run", "orbits", "sweep", "validate"} <= commands
    for name in modules:
        imported = _imports(ROOT / "rubcli" / "cli" / f"{name}.py")
        others = {c for c in commands - shared - {name}
                  if f"rubcli.cli.{c}" in imported}  # fmt: skip
        assert not others, f"cli/{name}.py imports cli/{sorted(others)}"

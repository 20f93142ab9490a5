"""Exit codes and atomic outputs of `compare`, `forces-map` and `stress` (the real CLI).

Documented behaviour (docs/compare.md, docs/forces-map.md, docs/stability.md and the
commands' docstrings): compare exits 1 when no reference can be built and 2 for methods
that are not available or an output path that is a file; stress exits 1 when a run
raised or produced a non-finite state and 2 for unknown names; every command writes its
files into a staging dir and moves them in at the end, so an interrupted run leaves the
output dir as it was (nothing new, no staging dir) and files already there that the run
does not write are left alone.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rubcli import solvers
from rubcli.analysis.accuracy import stress
from rubcli.cli.app import app

FREE_CASE = """\
[case]
name = "free"

[model]
nu = 0.05
eta = 0.5
e = 0.5
K = 10.0
mu = 0.0
Rp = 1.0

[initial]
x = 0.3
y = 0.0
vy = 0.1

[time]
periods = 1
samples_per_period = 20

[solver]
methods = ["dop853-jit"]

[compare]
work_precision = false
"""

MAP_CASE = """\
[case]
name = "small-map"

[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6e3
mu = 0.1
Rp = 46.16

[initial]
x = 0.88544
y = -0.8039

[time]
periods = 1
samples_per_period = 10

[forces_map]
products = ["eigen"]
resolution = 5
extent = 2.0
"""

STRESS_SELECTION = ["--quick", "--case", "grazing-touch", "--method", "dop853-jit"]


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def write(tmp_path: Path, text: str, name: str = "case.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def names(directory: Path) -> set[str]:
    return {p.name for p in directory.iterdir()} if directory.exists() else set()


def interrupt(*args, **kwargs):
    raise KeyboardInterrupt


# ------------------------------------------------------------------------ compare


def test_compare_without_a_reference_exits_1_and_writes_nothing(tmp_path, monkeypatch):
    """A reference solver that stops before its first sample (here its step budget cut to
    one step; the start lies in contact, so no closed form serves as the reference): there
    is no reference, so exit 1 with the reason and no files."""
    real_solve = solvers.solve

    def starved(problem, method, **options):
        return real_solve(problem, method, **{**options, "max_steps": 1})

    monkeypatch.setattr(solvers, "solve", starved)
    path = write(tmp_path, FREE_CASE.replace("x = 0.3", "x = 1.2"))
    out = tmp_path / "out"
    result = invoke("compare", path, "--quick", "--out", out)
    assert result.exit_code == 1, result.output
    assert "no reference solution: reference solver dop853-jit failed at the start" in (
        result.stderr
    )
    assert "step budget exhausted" in result.stderr
    assert "Traceback" not in result.output
    assert names(tmp_path) == {"case.toml"}


def test_compare_refuses_a_forcing_beyond_the_models_domain(tmp_path):
    """A forcing of 1e300 (once a reference failing at tau = 0) is refused as input."""
    path = write(tmp_path, FREE_CASE.replace("e = 0.5", "e = 1e300"))
    result = invoke("compare", path, "--quick", "--out", tmp_path / "out")
    assert result.exit_code == 2, result.output
    assert "model.e: must be at most 1e+100" in result.stderr
    assert names(tmp_path) == {"case.toml"}


def test_compare_with_a_method_that_is_not_available_exits_2(tmp_path, monkeypatch):
    """A method the case schema knows but this installation lacks (an optional extra)."""
    monkeypatch.setattr(solvers, "METHODS", {k: v for k, v in solvers.METHODS.items()
                                             if k != "dop853-jit"})  # fmt: skip
    path = write(tmp_path, FREE_CASE)
    result = invoke("compare", path, "--quick", "--out", tmp_path / "out")
    assert result.exit_code == 2, result.output
    assert f"{path}: methods not available: dop853-jit" in result.stderr
    assert names(tmp_path) == {"case.toml"}


def test_compare_into_a_file_exits_2(tmp_path):
    path = write(tmp_path, FREE_CASE)
    (tmp_path / "taken").write_text("x")
    result = invoke("compare", path, "--quick", "--out", tmp_path / "taken")
    assert result.exit_code == 2, result.output
    assert "output dir exists and is not a directory" in result.stderr
    assert (tmp_path / "taken").read_text() == "x"


def test_compare_into_an_existing_dir_and_interrupted(tmp_path, monkeypatch):
    path = write(tmp_path, FREE_CASE)
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    (out / "report.json").write_text('{"old": true}')
    from rubcli.studies import compare as compare_study

    # interrupted after orbits.png is staged, before report.md and report.json
    monkeypatch.setattr(compare_study, "report_markdown", interrupt)
    result = invoke("compare", path, "--quick", "--out", out, "--force")
    assert result.exit_code == 130  # typer's exit code for an interrupt (128 + SIGINT)
    assert names(out) == {"keep.txt", "report.json"}
    assert (out / "report.json").read_text() == '{"old": true}'
    assert names(tmp_path) == {"case.toml", "out"}  # no staging dir left beside it

    monkeypatch.undo()
    result = invoke("compare", path, "--quick", "--out", out, "--force")
    assert result.exit_code == 0, result.output
    assert {"keep.txt", "orbits.png", "report.md", "report.json"} <= names(out)
    assert (out / "keep.txt").read_text() == "mine"
    report = json.loads((out / "report.json").read_text())
    assert "old" not in report
    assert names(tmp_path) == {"case.toml", "out"}


# ---------------------------------------------------------------------- forces-map


def test_forces_map_into_an_existing_dir_and_interrupted(tmp_path, monkeypatch):
    path = write(tmp_path, MAP_CASE)
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    result = invoke("forces-map", path, "--out", out, "--force")
    assert result.exit_code == 0, result.output
    assert names(out) == {"keep.txt", "eigen_map.csv", "eigen_map.png", "report.json"}
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    from rubcli.plotting import forces as plots

    monkeypatch.setattr(plots, "eigen_map_figure", interrupt)
    result = invoke("forces-map", path, "--out", out, "--force")
    assert result.exit_code == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert names(tmp_path) == {"case.toml", "out"}

    fresh = tmp_path / "fresh"
    result = invoke("forces-map", path, "--out", fresh, "--force")
    assert result.exit_code == 130 and not fresh.exists()
    assert names(tmp_path) == {"case.toml", "out"}


# ------------------------------------------------------------------------- stress


def test_stress_runs_a_selection(tmp_path):
    """--case/--method pick exactly those rows; the exact reference of the touch case."""
    out = tmp_path / "out"
    result = invoke("stress", *STRESS_SELECTION, "--method", "analytic", "--out", out)
    assert result.exit_code == 0, result.output
    with open(out / "stress.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["case"], r["method"]) for r in rows] == [
        ("grazing-touch", "dop853-jit"),
        ("grazing-touch", "analytic"),
        ("grazing-touch", "analytic tol=1e-06"),
    ]
    for row in rows:
        assert row["status"] == "success" and row["warning"] == ""
        assert row["reference"] == "exact free flight (touching)"
        assert float(row["error"]) < 1e-5  # dop853 at rtol 1e-8 through a stiff touch
    assert names(out) == {"stress.csv", "stress.md", "report.json"}
    text = (out / "stress.md").read_text()
    cmd = "rubcli stress --quick --case grazing-touch --method dop853-jit --method analytic"
    assert f"`{cmd}`" in text


def test_stress_exits_1_when_a_solver_raises(tmp_path, monkeypatch):
    """A solver that raises is a bug the suite reports: status 'error', exit 1, and the
    table is still written."""

    def broken(problem, options):
        raise RuntimeError("solver exploded")

    monkeypatch.setitem(solvers.METHODS, "dop853-jit", broken)
    out = tmp_path / "out"
    result = invoke("stress", *STRESS_SELECTION, "--out", out)
    assert result.exit_code == 1, result.output
    assert "grazing-touch / dop853-jit: error: RuntimeError: solver exploded" in result.stderr
    with open(out / "stress.csv", newline="") as handle:
        (row,) = list(csv.DictReader(handle))
    assert row["status"] == stress.ERROR


def test_stress_into_a_file_exits_2(tmp_path):
    (tmp_path / "taken").write_text("x")
    result = invoke("stress", *STRESS_SELECTION, "--out", tmp_path / "taken")
    assert result.exit_code == 2
    assert "output dir exists and is not a directory" in result.stderr
    assert (tmp_path / "taken").read_text() == "x"


def test_stress_into_an_existing_dir_and_interrupted(tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    (out / "stress.csv").write_text("old")
    from rubcli.studies import stress as stress_study

    monkeypatch.setattr(stress_study, "markdown_text", interrupt)
    result = invoke("stress", *STRESS_SELECTION, "--out", out, "--force")
    assert result.exit_code == 130
    assert (out / "stress.csv").read_text() == "old"  # the half-staged table never moved in
    assert names(out) == {"keep.txt", "stress.csv"}
    assert names(tmp_path) == {"out"}
    monkeypatch.undo()
    result = invoke("stress", *STRESS_SELECTION, "--out", out, "--force")
    assert result.exit_code == 0, result.output
    assert names(out) == {"keep.txt", "stress.csv", "stress.md", "report.json"}
    assert (out / "stress.csv").read_text().startswith("case,method,status")


@pytest.mark.parametrize("args", [["--case", "nope"], ["--method", "euler"]])
def test_stress_unknown_names_exit_2(tmp_path, args):
    result = invoke("stress", "--quick", *args, "--out", tmp_path / "out")
    assert result.exit_code == 2
    assert not (tmp_path / "out").exists()

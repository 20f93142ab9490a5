"""Every case file shipped under cases/ runs through `rubcli run` and writes its outputs.

The cases' own horizons (50 periods for the paper's) take about 10 s each; here each
runs for ``--periods`` 3 (forcing periods) so that the whole set stays within CI time.
Set RUBCLI_FULL_CASES=1 to run every case at its own horizon instead.

Each case is also checked against its own physics: every method's contact switches,
contact fraction, largest penetration and final position against an independent tight
run of the same problem (dop853-jit at rtol 1e-12; 3 periods are inside the horizon of
predictability of every case), and the largest penetration against the start's own
(z0 - 1, exact from the case file, where the case starts in contact). The paper's method
at its 400 steps per period cannot follow the stiff stator (K = 17.6e3) of the Figure 2
cases from the Figure 3 start (docs/stability.md): there the report must flag it by its
energy residual instead.
"""

from __future__ import annotations

import csv
import json
import math
import os
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rubcli import solvers
from rubcli.case import load_case
from rubcli.cli.app import app

REPO = Path(__file__).resolve().parents[1]
CASES = sorted(
    # a Jeffcott case: [case] and no [rotor] (a ROSS rotor file has neither)
    p
    for p in (REPO / "cases").rglob("*.toml")
    if "case" in (data := tomllib.loads(p.read_text())) and "rotor" not in data
)  # (the cases given as matrices: test_rotor_case)
SMOKE_PERIODS = "3"
# (case, method) whose run is known to be wrong: 300 contact switches in the first period
# where the tight reference has 48, energy residual ~0.3. These cases run 1 period (the
# wrong run's ~300 events a period in Python took 10 s of the suite at 3).
KNOWN_INACCURATE = {("paper/fig2.toml", "analytic"), ("examples/eigen-only.toml", "analytic")}
SHORT = {"paper/fig2.toml": "1", "examples/eigen-only.toml": "1"}


def test_there_are_cases():
    names = {p.relative_to(REPO / "cases").as_posix() for p in CASES}
    assert {f"paper/fig3{letter}.toml" for letter in "abcdef"} <= names
    assert "examples/physical-units.toml" in names
    assert any(name.startswith("paper/variants/") for name in names)


@pytest.mark.slow
@pytest.mark.parametrize("path", CASES, ids=lambda p: p.relative_to(REPO / "cases").as_posix())
def test_case_runs(path, tmp_path):
    label = path.relative_to(REPO / "cases").as_posix()
    out = tmp_path / "out"
    args = ["run", str(path), "--out", str(out)]
    speed = load_case(path).problem.changes_speed  # a run-up runs its whole profile
    if not os.environ.get("RUBCLI_FULL_CASES") and not speed:
        args += ["--periods", SHORT.get(label, SMOKE_PERIODS)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output

    case = load_case(path)
    expected = {"report.json"} | {f"{plot}.png" for plot in case.settings.output.plots}
    if case.settings.output.csv:
        expected |= {f"{method}.csv" for method in case.methods}
    if case.settings.analysis is not None and case.settings.analysis.response:
        expected.add("poincare.png")  # [analysis] response = true (docs/compare.md)
    if speed:
        expected |= {"bode.png", "polar.png", "cascade.png", "orbits.png"}
    if case.problem.drive is not None:
        expected.add("drive.png")
    assert {p.name for p in out.iterdir()} == expected
    report = json.loads((out / "report.json").read_text())
    assert report["success"] is True
    assert list(report["methods"]) == case.methods
    for entry in report["methods"].values():
        assert entry["status"] == "success", entry["message"]

    # the case's own physics, against an independent tight run of the same problem
    problem = case.problem if os.environ.get("RUBCLI_FULL_CASES") or speed else None
    if problem is None:
        problem = case.with_overrides(periods=float(SHORT.get(label, SMOKE_PERIODS))).problem
    # (a driven rotor: scipy's DOP853 far tighter, its steps not the compiled loop's)
    tight = "dop853" if problem.drive is not None else "dop853-jit"
    ref = solvers.solve(problem, tight, rtol=1e-12, atol=1e-13)
    assert ref.success, ref.message
    z0 = math.hypot(problem.initial[0], problem.initial[1])
    assert ref.max_penetration() >= z0 - 1.0 - 1e-15  # at least the start's own
    for name, entry in report["methods"].items():
        where = f"{name}: {entry}"
        if (label, name) in KNOWN_INACCURATE:
            assert entry["energy_residual"] > 1e-2, where  # the report flags it
            assert entry["n_contact_switches"] > 5 * ref.n_contact_switches, where
            continue
        if speed:  # the balance with the work of the drive that keeps the speed
            assert entry["energy_residual"] < 1e-3 and entry["transient"]["revolutions"] > 10
        else:
            assert entry["energy_residual"] < 1e-2, where
        assert entry["n_contact_switches"] == ref.n_contact_switches, where
        assert entry["contact_fraction"] == pytest.approx(ref.contact_fraction(), abs=2e-3)
        assert entry["max_penetration"] == pytest.approx(ref.max_penetration(), abs=1e-3)
        if case.settings.output.csv and not case.scale:
            with open(out / f"{name}.csv", newline="") as handle:
                last = list(csv.DictReader(handle))[-1]
            end = complex(float(last["x"]), float(last["y"]))
            assert abs(end - complex(*ref.states[-1, :2])) < 2e-2, where

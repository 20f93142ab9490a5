"""Every case file shipped under cases/ runs through `rubcli run` and writes its outputs.

The cases' own horizons (50 periods for the paper's) take about 10 s each; here each
runs for ``--periods`` 3 (forcing periods) so that the whole set stays within CI time.
Set RUBCLI_FULL_CASES=1 to run every case at its own horizon instead.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rubcli.case import load_case
from rubcli.cli.app import app

REPO = Path(__file__).resolve().parents[1]
CASES = sorted((REPO / "cases").rglob("*.toml"))
SMOKE_PERIODS = "3"


def test_there_are_cases():
    names = {p.relative_to(REPO / "cases").as_posix() for p in CASES}
    assert {f"paper/fig3{letter}.toml" for letter in "abcdef"} <= names
    assert "examples/physical-units.toml" in names
    assert any(name.startswith("paper/variants/") for name in names)


@pytest.mark.parametrize("path", CASES, ids=lambda p: p.relative_to(REPO / "cases").as_posix())
def test_case_runs(path, tmp_path):
    out = tmp_path / "out"
    args = ["run", str(path), "--out", str(out)]
    if not os.environ.get("RUBCLI_FULL_CASES"):
        args += ["--periods", SMOKE_PERIODS]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output

    case = load_case(path)
    expected = {"report.json"} | {f"{plot}.png" for plot in case.settings.output.plots}
    if case.settings.output.csv:
        expected |= {f"{method}.csv" for method in case.methods}
    if case.settings.analysis is not None and case.settings.analysis.response:
        expected.add("poincare.png")  # [analysis] response = true (docs/compare.md)
    assert {p.name for p in out.iterdir()} == expected
    report = json.loads((out / "report.json").read_text())
    assert report["success"] is True
    assert list(report["methods"]) == case.methods
    for entry in report["methods"].values():
        assert entry["status"] == "success", entry["message"]

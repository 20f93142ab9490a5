"""Figures through `rubcli run`: spectrum.png on request, the spectrum in report.json,
figures (with their message) even when every method failed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rubcli.case import load_case
from rubcli.cli.app import app

CASE = """\
[case]
name = "short"

[{section}]
{model}

[initial]
x = {x}
y = 0.0

[time]
periods = 6
samples_per_period = 40

[solver]
methods = ["rk45"]
{solver}

[output]
csv = false
plots = ["orbit", "time", "energy", "spectrum"]
"""
MODEL = "nu = 0.009478\neta = 0.7818\ne = 7.52\nK = 17.6\nmu = 0.0\nRp = 46.16"
PHYSICAL = (
    "m = 4.0\nk_r = 4.0e5\nd_r = 25.3\nk_s = 4.0e6\nclearance = 2.0e-4\ne = 1.5e-4\n"
    "Omega = 250.0\nRp = 0.05\nmu = 0.0"
)


def run(tmp_path: Path, text: str):
    case = tmp_path / "case.toml"
    case.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(out)])
    return case, out, result


def is_png(path: Path) -> bool:
    return path.is_file() and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
@pytest.mark.parametrize("physical", [False, True], ids=["model", "physical"])
def test_run_writes_spectrum_png_and_the_dominant_whirl(tmp_path, physical):
    text = CASE.format(section="physical" if physical else "model",
                       model=PHYSICAL if physical else MODEL,
                       x=1.0e-4 if physical else 0.5, solver="")  # fmt: skip
    case_path, out, result = run(tmp_path, text)
    assert result.exit_code == 0, result.output
    for name in ("orbit.png", "time.png", "energy.png", "spectrum.png"):
        assert is_png(out / name), name
    report = json.loads((out / "report.json").read_text())
    assert "spectrum.png" in report["files"]
    spectrum = report["methods"]["rk45"]["spectrum"]
    # driven by the unbalance, the whirl over the steady span is dominated by +1X forward
    assert spectrum["direction"] == "forward"
    assert abs(spectrum["dominant_order"] - 1.0) < spectrum["resolution_order"]
    if physical:
        scale = load_case(case_path).scale
        assert spectrum["dominant_omega_rad_s"] == pytest.approx(
            spectrum["dominant_omega"] * scale.omega
        )
        # Omega = 250 rad/s, within the resolution of a 3-period record
        assert abs(spectrum["dominant_omega_rad_s"] - 250.0) < 250.0 * spectrum["resolution_order"]
    else:
        assert "dominant_omega_rad_s" not in spectrum


def test_run_where_every_method_failed_still_writes_its_figures(tmp_path):
    text = CASE.format(section="model", model=MODEL, x=0.5, solver="max_steps = 3")
    _, out, result = run(tmp_path, text)
    assert result.exit_code == 1
    report = json.loads((out / "report.json").read_text())
    assert report["methods"]["rk45"]["status"] != "success"
    assert report["methods"]["rk45"]["spectrum"] is None
    for name in ("orbit.png", "time.png", "energy.png", "spectrum.png"):
        assert is_png(out / name), name

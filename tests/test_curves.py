"""Bifurcations continued in a second parameter (rubcli.analysis.orbits.curves, [orbits]
second_parameter): each continued point checked against the closed forms of the isotropic
machine (model notes 5; rubcli.analysis.charts.stability and analysis.orbits.synchronous,
which compute them without integrating), the curves' stops, the case table's checks and the
files."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.charts import stability as charts
from rubcli.analysis.orbits import continuation as cn
from rubcli.analysis.orbits import curves as cv
from rubcli.cli.app import app
from rubcli.model import ModelParams

ROOT = Path(__file__).resolve().parents[1]
PAPER = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.0095, Rp=46.16)
# the run-up machine (cases/examples/run-up-orbits.toml) at an unbalance just above the
# smallest at which its free whirl reaches the stator (0.0999), so its hysteresis is short
RUN_UP = ModelParams(nu=0.05, eta=0.6, e=0.105, K=2.0, mu=0.02, Rp=0.5)


def _paper_ns() -> cn.Branch:
    s0 = model.synchronous_rub(np.array([0.0]), PAPER, max(model.synchronous_rub_radii(PAPER)))
    settings = cn.ContinuationSettings(
        parameter="mu", p_min=0.0, p_max=0.02, step=0.001, max_points=4, directions=(1,)
    )
    return cn.continue_branch(PAPER, s0[:, 0], settings)


@pytest.mark.slow
def test_neimark_sacker_of_the_paper_rub_continued_in_eta_lies_on_the_stability_boundary():
    branch = _paper_ns()
    (ns,) = [b for b in branch.bifurcations if b.kind == cn.NEIMARK_SACKER]
    settings = cv.CurveSettings(
        parameter="mu", p_min=0.0, p_max=0.02, second="eta", s_min=0.74, s_max=0.82, step=0.1
    )
    (curve,) = cv.continue_curves(PAPER, branch, settings)
    assert curve.status == "ok" and set(curve.stops.values()) == {
        "reached the lower bound eta = 0.74", "reached the upper bound eta = 0.82"
    }  # fmt: skip
    assert len(curve.points) >= 4
    for pt in curve.points:
        at = dataclasses.replace(PAPER, mu=pt.values[0], eta=pt.values[1])
        # the closed form: the largest real part of the rotating-frame eigenvalues is 0
        assert abs(charts.CURVE_FUNCTIONS[charts.RUB_STABILITY](at)) < 1e-8
        root = charts.closed_form_root(at, charts.RUB_STABILITY, "mu", pt.values[0], 1e-3)
        assert abs(root - pt.values[0]) < 1e-9
        assert cn._unit_pair(pt.multipliers) is not None  # a complex pair on the circle
    # the curve passes through the located point and mu falls as eta rises (docs/charts.md)
    values = np.array([pt.values for pt in curve.points])
    assert np.all(np.diff(values[:, 1]) * np.diff(values[:, 0]) < 0.0)


def _run_up_branch() -> cn.Branch:
    settings = cn.ContinuationSettings(
        parameter="eta", p_min=0.9, p_max=1.3, step=0.02, max_step=0.05, max_points=80,
        directions=(1,), rtol=1e-11, atol=1e-11,
    )  # fmt: skip
    return cn.continue_branch(dataclasses.replace(RUN_UP, eta=0.9), [0.0] * 4, settings)


@pytest.fixture(scope="module")
def run_up_curves() -> list[cv.Curve]:
    branch = _run_up_branch()
    assert {b.kind for b in branch.bifurcations} >= {cn.GRAZING, cn.FOLD}
    settings = cv.CurveSettings(
        parameter="eta", p_min=0.9, p_max=1.3, second="e", s_min=0.09, s_max=0.11,
        step=0.1, max_points=20, rtol=1e-11, atol=1e-11,
    )  # fmt: skip
    return cv.continue_curves(RUN_UP, branch, settings)


@pytest.mark.slow
def test_grazings_of_the_free_whirl_are_one_curve_on_the_closed_form(run_up_curves):
    grazings = [c for c in run_up_curves if c.kind == cn.GRAZING]
    assert [c.status for c in grazings] == ["ok", "same curve"]  # the two are one curve
    (curve,) = [c for c in grazings if c.points]
    p1 = [pt.values[0] for pt in curve.points]
    assert min(p1) < 1.0 < max(p1)  # it turns below the critical speed's unbalance
    for pt in curve.points:
        at = dataclasses.replace(RUN_UP, eta=pt.values[0], e=pt.values[1])
        assert abs(abs(model.free_steady_state(0.0, at)[0]) - 1.0) < 1e-9
    # it turns at the smallest unbalance that reaches the stator, e = 2 nu sqrt(1 - nu^2)
    lowest = min(pt.values[1] for pt in curve.points)
    assert 0.0 <= lowest - 2 * RUN_UP.nu * math.sqrt(1 - RUN_UP.nu**2) < 1e-3


@pytest.mark.slow
def test_fold_of_the_rub_continued_in_e_lies_on_the_double_root(run_up_curves):
    (curve,) = [c for c in run_up_curves if c.kind == cn.FOLD]
    assert curve.status == "ok" and len(curve.points) >= 3
    for pt in curve.points:
        at = dataclasses.replace(RUN_UP, eta=pt.values[0], e=pt.values[1])
        root = charts.closed_form_root(at, charts.RUB_FOLD, "e", pt.values[1], 1e-3)
        assert abs(root - pt.values[1]) < 1e-9
        assert pt.contact_fraction == 1.0 and pt.max_z > 1.0
        assert np.min(np.abs(pt.multipliers - 1.0)) < 1e-6  # a multiplier at +1


@pytest.mark.parametrize(
    "change, message",
    [
        ({"second": "mu"}, "parameter and second are both 'mu'"),
        ({"s_min": 0.9}, "each window must have min below max"),
        ({"step": 0.0}, "step must lie in (0, 0.5]"),
        ({"max_points": 0}, "max_points must be an int >= 1"),
        ({"second": "phi0"}, "second must be one of"),
    ],
)
def test_curve_settings_are_checked(change, message):
    base = dict(parameter="mu", p_min=0.0, p_max=0.02, second="eta", s_min=0.6, s_max=0.8)
    with pytest.raises(
        ValueError, match=f"CurveSettings: {message.replace('(', '.').replace(')', '.')}"
    ):
        cv.CurveSettings(**{**base, **change})


def _case_text(extra: str) -> str:
    text = (ROOT / "cases/examples/run-up-curves.toml").read_text()
    start = text.index("second_parameter")
    end = text.index("[output]")
    return text[:start] + extra + "\n" + text[end:]


@pytest.mark.parametrize(
    "extra, message",
    [
        ('second_parameter = "eta"\nsecond_min = 0.1\nsecond_max = 0.2',
         "second_parameter must differ from parameter"),
        ('second_parameter = "e"\nsecond_min = 0.1', "needs second_min and second_max"),
        ('second_parameter = "e"\nsecond_min = 0.2\nsecond_max = 0.1',
         "second_min must be below second_max"),
        ('second_parameter = "e"\nsecond_min = -0.1\nsecond_max = 0.2', "e must be >= 0"),
        ("second_min = 0.1\nsecond_max = 0.2", "second_min/second_max need second_parameter"),
        ('second_parameter = "e"\nsecond_min = 0.13\nsecond_max = 0.2',
         "is outside the window [0.13, 0.2]"),
        ('second_parameter = "e"\nsecond_min = 0.1\nsecond_max = 0.2\ncurve_points = 0',
         "curve_points"),
    ],
)  # fmt: skip
def test_bad_second_parameter_tables_exit_2_and_write_nothing(tmp_path, extra, message):
    case = tmp_path / "case.toml"
    case.write_text(_case_text(extra))
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["orbits", str(case), "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split()) and "Traceback" not in result.output
    assert not out.exists()


@pytest.mark.slow
def test_shipped_curves_case_quick_writes_the_curves(tmp_path):
    out = tmp_path / "out"
    case = ROOT / "cases/examples/run-up-curves.toml"
    result = CliRunner().invoke(app, ["orbits", str(case), "--out", str(out), "--quick"])
    assert result.exit_code == 0, result.output
    names = {p.name for p in out.iterdir()}
    assert {"curve.csv", "curves.png", "branch.csv", "report.json"} <= names
    report = json.loads((out / "report.json").read_text())
    lines = (out / "curve.csv").read_text().splitlines()
    assert lines[0].split(",") == [
        "curve", "kind", "eta", "e", "x", "y", "vx", "vy", "max_z", "contact_fraction",
        "test_value", "distance_to_closed_form",
    ]  # fmt: skip
    located = [b for b in report["branch"]["bifurcations"] if b["located"] and not b["nonsmooth"]]
    assert len(report["curves"]) == len(located) >= 1
    for row in lines[1:]:
        distance = row.split(",")[-1]
        assert distance == "" or float(distance) < 1e-8
    for curve in report["curves"]:
        assert curve["points"] <= 2 * 3 + 1
        if curve["max_distance_to_closed_form"] is not None:
            assert curve["max_distance_to_closed_form"] < 1e-8
    assert math.isfinite(report["wall_time_s"])

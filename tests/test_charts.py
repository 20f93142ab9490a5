"""Closed-form charts of the synchronous motions (rubcli.analysis.charts.stability).

Each located curve point is checked by a different route than the one that located it:
the grazing speeds (roots of a quadratic in eta^2) against the free whirl's amplitude from
``model.free_steady_state``; the folds (roots of the discriminant) against the number of
roots ``model.synchronous_rub_radii`` finds on either side; the stability boundary
against the sign of the rotating-frame eigenvalues on either side.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.charts import stability as ch
from rubcli.analysis.orbits.synchronous import synchronous_rubs
from rubcli.case import load_case
from rubcli.cli.app import app
from rubcli.model import ModelParams

# The paper's machine (model notes, section 6) with a light unbalance, without friction:
# the run-up through the critical speed with its hysteresis band.
RUN_UP = ModelParams(nu=0.009478, eta=1.0, e=0.05, K=17.6, mu=0.0, Rp=46.16)


def test_free_grazing_speeds_touch_the_stator():
    speeds = ch.free_grazing_speeds(RUN_UP.nu, RUN_UP.e)
    assert len(speeds) == 2 and speeds[0] < 1.0 < speeds[1]
    for eta in speeds:
        w, _ = model.free_steady_state(0.0, dataclasses.replace(RUN_UP, eta=eta))
        assert abs(w) == pytest.approx(1.0, abs=1e-12)
    # a large unbalance grazes once only (the free whirl stays outside above resonance)
    assert len(ch.free_grazing_speeds(0.05, 1.5)) == 1


def test_chart_curves_agree_with_independent_counts():
    chart = ch.closed_form_chart(RUN_UP, "eta", (0.5, 5.0), "e", (0.03, 0.07), nx=46, ny=3)
    rows = set(chart.y.tolist())
    folds = chart.curves[ch.RUB_FOLD]
    assert len([f for f in folds if f[1] in rows]) == 3  # one fold of the rub per row of e
    assert len(folds) > 3  # and where the fold curve crosses the columns of eta
    for eta, e in folds:
        # the curve is crossed along the axis on which the point was located
        step = {"e": 1e-7} if e not in rows else {"eta": 1e-6}
        (name, d), p = next(iter(step.items())), dataclasses.replace(RUN_UP, eta=eta, e=e)
        below = model.synchronous_rub_radii(dataclasses.replace(p, **{name: getattr(p, name) - d}))
        above = model.synchronous_rub_radii(dataclasses.replace(p, **{name: getattr(p, name) + d}))
        assert {len(below), len(above)} == {0, 2}
        pair = below or above
        r_f = ch.rub_fold_radius(p)
        assert min(pair) < r_f < max(pair) and max(pair) - min(pair) < 1e-2
    grazings = chart.curves[ch.FREE_GRAZING]
    assert len([g for g in grazings if g[1] in rows]) == 6  # both sides of resonance, 3 rows
    for eta, e in grazings:
        w, _ = model.free_steady_state(0.0, dataclasses.replace(RUN_UP, eta=eta, e=e))
        assert abs(w) == pytest.approx(1.0, abs=1e-9)
        if e in rows:
            assert eta == pytest.approx(
                min(ch.free_grazing_speeds(RUN_UP.nu, e), key=lambda s: abs(s - eta)), abs=1e-10
            )
    # inside the hysteresis band both motions are stable; beyond the fold only the free one
    upper_graze = ch.free_grazing_speeds(RUN_UP.nu, 0.05)[1]
    fold = next(eta for eta, e in folds if abs(e - 0.05) < 1e-12)
    assert ch.region(dataclasses.replace(RUN_UP, eta=0.5 * (upper_graze + fold))) == ch.BOTH
    assert ch.region(dataclasses.replace(RUN_UP, eta=fold + 0.1)) == ch.FREE
    assert ch.region(dataclasses.replace(RUN_UP, eta=0.5 * (1.0 + upper_graze))) == ch.RUB


def test_rub_stability_boundary_in_friction():
    """The paper's machine at eta = 0.7818: the synchronous rub loses stability in mu where
    a complex pair crosses the imaginary axis (the Neimark-Sacker point of the map)."""
    paper = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.0, Rp=46.16)
    chart = ch.closed_form_chart(paper, "mu", (0.0, 0.03), "eta", (0.7818, 0.7818), nx=7, ny=1)
    ((mu_ns, _),) = chart.curves[ch.RUB_STABILITY]
    # the Neimark-Sacker point that continuation locates by shooting and Floquet
    # multipliers (docs/orbits.md; tests/test_orbits.py), an independent route
    assert mu_ns == pytest.approx(0.0102872304102, abs=1e-9)
    for mu, stable in ((mu_ns - 1e-7, True), (mu_ns + 1e-7, False)):
        rub = synchronous_rubs(dataclasses.replace(paper, mu=mu))[-1]
        assert rub.stable == stable
        crossing = rub.eigenvalues[abs(rub.eigenvalues.real) < 1e-4]
        assert crossing.size == 2 and abs(crossing[0].imag) > 0.1


# ------------------------------------------------------------------ rubcli chart

REPO = Path(__file__).resolve().parents[1]
CHART_CASES = ("paper/fig3-chart.toml", "examples/run-up-chart.toml", "examples/mu-eta-map.toml")


@pytest.mark.slow
@pytest.mark.parametrize("name", CHART_CASES)
def test_chart_command_on_the_shipped_cases(name, tmp_path):
    """Every curve point it writes lies on its curve by an independent route: the free
    whirl's amplitude is 1 (model.free_steady_state), the rub's quadratic has a double
    root there (its two radii meet), the rub's eigenvalues cross the imaginary axis."""
    out = tmp_path / "chart"
    result = CliRunner().invoke(app, ["chart", str(REPO / "cases" / name), "--quick",
                                      "--out", str(out)])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {"chart.png", "curve.csv", "chart.nc",
                                               "report.json"}  # fmt: skip
    case = load_case(REPO / "cases" / name)
    c = case.settings.chart
    report = json.loads((out / "report.json").read_text())
    assert report["plane"]["nx"] == 41 and report["plane"]["ny"] == 21
    assert sum(report["region_fractions"].values()) == pytest.approx(1.0)
    with (out / "curve.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert rows and set(rows[0]) == {c.x, c.y, "kind", "source", "distance_to_closed_form"}
    closed = [r for r in rows if r["source"] == "closed form"]
    continued = [r for r in rows if r["source"] == "continuation"]
    counts = {k: sum(r["kind"] == k for r in closed) for k in ch.CURVE_KINDS}
    assert counts == report["curve_points"]
    # the check: the rub shot and continued at 2 speeds (quick), its bifurcations located
    # from its multipliers, on the closed-form curves
    checked = min(c.check_points, 2)
    assert report["continuation_check"]["x_values"] == checked and len(continued) >= checked
    for row in continued:
        assert float(row["distance_to_closed_form"]) < 1e-8
    for row in rows:
        p = dataclasses.replace(case.params, **{c.x: float(row[c.x]), c.y: float(row[c.y])})
        if row["kind"] == ch.FREE_GRAZING:
            assert abs(model.free_steady_state(0.0, p)[0]) == pytest.approx(1.0, abs=1e-9)
        elif row["kind"] == ch.RUB_FOLD:
            eps = 1e-6 * max(1.0, abs(p.eta))
            radii = [model.synchronous_rub_radii(dataclasses.replace(p, eta=p.eta + d))
                     for d in (-eps, eps)]  # fmt: skip
            assert (
                sorted(len(r) for r in radii) == [0, 2]
                or max(abs(r[0] - r[-1]) for r in radii if r) < 1e-2
            )
        else:
            rub = [r for r in synchronous_rubs(p) if r.forward_slip][-1]
            assert abs(rub.growth_rate) < 1e-8
    import xarray as xr

    with xr.open_dataset(out / "chart.nc", engine="h5netcdf") as ds:
        assert ds["region"].shape == (21, 41)
        assert set(np.unique(ds["region"].values)) <= set(ch.REGIONS)


@pytest.fixture(scope="module")
def quick_map_sweep(tmp_path_factory) -> Path:
    """The quick run-up map (5 x 5 points) of cases/examples/mu-eta-map.toml."""
    out = tmp_path_factory.mktemp("sweep")
    case = REPO / "cases/examples/mu-eta-map.toml"
    result = CliRunner().invoke(app, ["sweep", str(case), "--quick", "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out / "sweep.nc"


@pytest.mark.slow
def test_chart_with_a_sweep_beside_it(quick_map_sweep, tmp_path):
    """What each point of the sweep settled on agrees with the closed forms: a point on
    the free whirl where the free whirl exists (|W| < 1, model.free_steady_state), one on
    the synchronous rub where a stable rub exists (analysis.orbits.synchronous)."""
    out = tmp_path / "chart"
    case = REPO / "cases/examples/mu-eta-map.toml"
    result = CliRunner().invoke(app, ["chart", str(case), "--quick", "--out", str(out),
                                      "--overlay", str(quick_map_sweep)])  # fmt: skip
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    overlay = report["sweep_overlay"]
    assert overlay["direction"] == "up" and overlay["points"] == 25
    assert sum(sum(row.values()) for row in overlay["by_region"].values()) == 25
    assert overlay["contradictions"] == 0
    from rubcli.studies.chart import load_sweep_map

    params = load_case(case).params
    sweep = load_sweep_map(quick_map_sweep, load_case(case).settings.chart, params)
    for j, mu in enumerate(sweep.y):
        for i, eta in enumerate(sweep.x):
            at = dataclasses.replace(params, eta=float(eta), mu=float(mu))
            name = sweep.labels[sweep.regimes[j, i]]
            if name == "free whirl":
                assert abs(model.free_steady_state(0.0, at)[0]) < 1.0
            elif name == "synchronous rub":
                assert any(r.stable and r.forward_slip for r in synchronous_rubs(at))


def test_chart_refuses_an_overlay_of_another_machine_or_plane(quick_map_sweep, tmp_path):
    runner = CliRunner()
    for case, overlay, message in [
        ("paper/fig3-chart.toml", quick_map_sweep, "another machine: K = 10 (this case: 17.6)"),
        ("examples/run-up-chart.toml", quick_map_sweep, "not a sweep over (eta, e): no e"),
        ("examples/mu-eta-map.toml", tmp_path / "none.nc", "file not found"),
    ]:  # fmt: skip
        out = tmp_path / "out"
        result = runner.invoke(app, ["chart", str(REPO / "cases" / case), "--out", str(out),
                                     "--overlay", str(overlay)])  # fmt: skip
        assert result.exit_code == 2, result.output
        assert message in " ".join(result.output.split()), result.output
        assert not out.exists() and "Traceback" not in result.output


def test_chart_refuses_an_overlay_that_varies_a_third_parameter(tmp_path):
    import xarray as xr

    dims = ("direction", "eta", "mu", "K")
    shape = (1, 2, 2, 2)
    names = ("contact_fraction", "stick_fraction", "whirl_order", "status", "response_class",
             "response_period")  # fmt: skip
    ds = xr.Dataset({n: (dims, np.zeros(shape)) for n in names},
                    coords={"direction": ["up"], "eta": [1.0, 2.0], "mu": [0.0, 0.1],
                            "K": [5.0, 10.0]})  # fmt: skip
    path = tmp_path / "sweep.nc"
    ds.to_netcdf(path, engine="h5netcdf")
    out = tmp_path / "out"
    case = REPO / "cases/examples/mu-eta-map.toml"
    result = CliRunner().invoke(app, ["chart", str(case), "--out", str(out), "--overlay",
                                      str(path)])  # fmt: skip
    assert result.exit_code == 2, result.output
    assert "the sweep also varies K" in " ".join(result.output.split())
    assert not out.exists() and "Traceback" not in result.output


def test_chart_refuses_a_case_without_or_with_a_bad_table(tmp_path):
    base = (REPO / "cases" / "paper" / "fig3-chart.toml").read_text()
    head = base[: base.index("[chart]")]
    runner = CliRunner()
    for table, message in [
        ("", "missing table [chart]"),
        ('[chart]\nx = "eta"\nx_min = 0.1\nx_max = 2.0\ny = "eta"\ny_min = 0.1\ny_max = 1.0\n',
         "two different parameters"),
        ('[chart]\nx = "eta"\nx_min = 2.0\nx_max = 0.1\ny = "mu"\ny_min = 0\ny_max = 1\n',
         "x_min must be below x_max"),
        ('[chart]\nx = "eta"\nx_min = 0.0\nx_max = 2.0\ny = "mu"\ny_min = 0\ny_max = 1\n',
         "eta must be > 0"),
        ('[chart]\nx = "omega"\nx_min = 0.1\nx_max = 2.0\ny = "mu"\ny_min = 0\ny_max = 1\n',
         "chart.x"),
    ]:  # fmt: skip
        path = tmp_path / "case.toml"
        path.write_text(head + table)
        out = tmp_path / "out"
        result = runner.invoke(app, ["chart", str(path), "--out", str(out)])
        assert result.exit_code == 2, (table, result.output)
        assert message in result.output and str(path) in result.output, result.output
        assert "Traceback" not in result.output
        assert not out.exists()


def test_chart_study_from_python(tmp_path):
    """The library path of the command: the study, then its files in one commit."""
    from rubcli.studies.chart import FILES, chart_of

    text = (REPO / "cases" / "examples" / "run-up-chart.toml").read_text()
    path = tmp_path / "case.toml"
    path.write_text(text.replace("check_points = 6", "check_points = 0"))  # (checked above)
    case = load_case(path)
    result = chart_of(case, quick=True)
    assert result.continued == [] and result.check_summary()["x_values"] == 0
    assert result.chart.regions.shape == (21, 41)
    report = result.write(tmp_path / "chart")
    assert sorted(report["files"]) == sorted(FILES)
    assert {p.name for p in (tmp_path / "chart").iterdir()} == set(FILES)
    with pytest.raises(ValueError, match="missing table \\[chart\\]"):
        chart_of(load_case(REPO / "cases" / "paper" / "fig3a.toml"))
    general = tmp_path / "general.toml"  # the same chart on a machine with an offset stator
    general.write_text(path.read_text().replace("[model]\n", "[model]\noffset = [0.3, 0.0]\n"))
    with pytest.raises(ValueError, match="offset.*makes this machine general"):
        chart_of(load_case(general), quick=True)


def test_a_log_spaced_axis_spans_decades(tmp_path):
    """K over six decades: the grid is geometric with exact ends, the figure's axis is
    logarithmic, and a log axis that starts at zero is refused."""
    base = (REPO / "cases" / "paper" / "fig3-chart.toml").read_text()
    head = base[: base.index("[chart]")]
    plane = '[chart]\nx = "K"\nx_min = 1\nx_max = 1e6\nx_spacing = "log"\ny = "mu"\n'
    path = tmp_path / "case.toml"
    path.write_text(head + plane + "y_min = 0\ny_max = 0.1\nnx = 13\nny = 5\n")
    from rubcli.studies.chart import chart_of

    result = chart_of(load_case(path))
    x = result.chart.x
    assert x[0] == 1.0 and x[-1] == 1e6 and result.chart.log_x and not result.chart.log_y
    assert np.allclose(np.diff(np.log10(x)), 0.5)
    report = result.write(tmp_path / "out")
    assert report["plane"]["x_spacing"] == "log"
    path.write_text(head + plane.replace("x_min = 1", "x_min = 0") + "y_min = 0\ny_max = 0.1\n")
    out = tmp_path / "refused"
    cli = CliRunner().invoke(app, ["chart", str(path), "--out", str(out)])
    assert cli.exit_code == 2 and 'x_spacing = "log" needs x_min > 0' in cli.output
    assert not out.exists()

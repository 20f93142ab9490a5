"""Ensembles (analysis/ensembles/ensemble.py, `rubcli ensemble`): the statistics on samples
whose law is known, and the rotor where every run must reach the same attractor."""

import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli.analysis.ensembles import ensemble as en
from rubcli.cli.app import app
from rubcli.model import ModelParams

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16}
FIG3_START = (0.88544, -0.8039, 0.0, 0.0)


def test_exponential_mean_interval_covers_the_truth_95_percent_of_the_time():
    """4000 ensembles of 30 runs with exponential lifetimes (mean 100), each cut at 150:
    the interval of time-censored data must contain 100 in at least 95 % of them (it is
    conservative: its lower end counts one escape more), within three standard errors of
    the share (0.0034); a 90 % interval (covering 0.92 here) fails."""
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(4000):
        life = rng.exponential(100.0, size=30)
        seen = np.minimum(life, 150.0)
        ci = en.exponential_mean(float(seen.sum()), int(np.sum(life < 150.0)))
        hits += ci["lower"] <= 100.0 <= ci["upper"]
    assert 0.94 <= hits / 4000 <= 0.98


def test_wilson_interval_covers_and_has_its_closed_form_at_zero():
    z2 = 1.959963984540054**2
    assert en.wilson_interval(0, 10)[1] == pytest.approx(z2 / (10 + z2), rel=1e-12)
    rng = np.random.default_rng(3)
    draws = rng.binomial(40, 0.3, size=4000)
    hits = sum(lo <= 0.3 <= hi for lo, hi in (en.wilson_interval(int(k), 40) for k in draws))
    assert 0.93 <= hits / 4000 <= 0.975


def test_kaplan_meier_by_hand():
    # times 2, 3 (censored), 5, 5, 8 (censored), 9: at 2, 6 at risk -> 5/6; at 5, 4 at risk
    # with 2 escapes -> 5/6 * 2/4; at 9, 1 at risk -> 0
    curve = en.kaplan_meier([2, 3, 5, 5, 8, 9], [True, False, True, True, False, True])
    assert curve == [(2.0, pytest.approx(5 / 6)), (5.0, pytest.approx(5 / 12)), (9.0, 0.0)]


def test_settle_period_is_the_last_section_point_away_from_the_final_set():
    final = np.column_stack([np.cos(np.linspace(0, 6.28, 50)), np.sin(np.linspace(0, 6.28, 50))])
    away = np.full((37, 2), 3.0)
    sections = np.vstack([away, final, final])
    assert en.settle_period(sections, final, np.ones(2), 0.05) == 37.0


def _tasks(mu, runs, periods, record):
    params = ModelParams(mu=mu, **FIG3)
    return en.member_tasks(
        params, FIG3_START, runs=runs, spread=1e-6, seed=1, methods=["dop853-jit"],
        rtols=[1e-8], options={"atol": 1e-10}, periods=periods, samples_per_period=16,
        record_periods=record, lyapunov=False, lyapunov_periods=50, settle_tolerance=0.05,
    )  # fmt: skip


def test_every_run_at_mu_005_ends_in_dry_whip():
    """docs/reproduction.md: at mu = 0.05 the chaotic transient ends in the rolling
    backward whirl at -Rp / r orders (about -5.2) within about a hundred periods."""
    result = en.run_ensemble(_tasks(0.05, 3, 250, 60))
    assert [m.attractor for m in result.members] == ["dry whip, quasi-periodic"] * 3
    for m in result.members:
        assert m.stick_fraction == 1.0 and m.settled and 0 < m.settle_period < 190
        assert m.whirl_order == pytest.approx(-5.215, abs=0.01)  # -5.215X of the docs
    life = result.lifetimes()
    assert life["escaped"] == 3 and life["censored"] == 0


def test_every_run_at_mu_0_ends_on_the_synchronous_rub():
    result = en.run_ensemble(_tasks(0.0, 2, 200, 50))
    for m in result.members:
        assert m.regime == "synchronous rub" and m.kind in ("periodic", "converging")
        assert m.settled and m.settle_period < 150


CASE = """
[case]
name = "ens"
[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6
mu = 0.05
Rp = 46.16
[initial]
x = 0.88544
y = -0.8039
[time]
periods = 200
samples_per_period = 16
[solver]
methods = ["dop853-jit"]
{ensemble}
"""


def test_ensemble_command_writes_fractions_and_lifetimes(tmp_path):
    case = tmp_path / "ens.toml"
    case.write_text(CASE.format(ensemble="[ensemble]\nruns = 2\nrecord_periods = 50\n"
                                         "rtols = [1e-6, 1e-8]\nlyapunov = false"))  # fmt: skip
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["ensemble", str(case), "--out", str(out), "-w", "1",
                                      "--json"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["outcomes"]  # --json: stdout is the report alone
    assert {p.name for p in out.iterdir()} == {"ensemble.csv", "ensemble.png", "report.json"}
    rows = list(csv.DictReader((out / "ensemble.csv").open()))
    assert len(rows) == 4 and {r["rtol"] for r in rows} == {"1e-06", "1e-08"}
    report = json.loads((out / "report.json").read_text())
    assert report["outcomes"]["dry whip, quasi-periodic"]["runs"] == 4
    assert set(report["by_setting"]) == {"dop853-jit rtol=1e-06", "dop853-jit rtol=1e-08"}
    mean = report["lifetime"]["mean_lifetime"]
    assert mean["lower"] < mean["mean"] < mean["upper"] and math.isfinite(mean["mean"])


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("", "ensemble: missing table [ensemble]"),
        ("[ensemble]\nrecord_periods = 300", "ensemble.record_periods: 300 must be below"),
        ("[ensemble]\nrtols = [0.5]", "each rtol must lie in (0, 1e-2)"),
    ],
)
def test_bad_ensemble_tables_exit_2_and_write_nothing(tmp_path, table, message):
    case = tmp_path / "ens.toml"
    case.write_text(CASE.format(ensemble=table))
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["ensemble", str(case), "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split())
    assert not out.exists()

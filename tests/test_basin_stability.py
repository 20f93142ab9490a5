"""Basin stability along a parameter (analysis/ensembles/basin_stability.py, `rubcli ensemble` with
`[ensemble] parameter`): intervals against their closed form, the attractor labels on
synthetic input, the rotor where the closed forms leave one attractor, the bracket of the
minimal perturbation checked by independent runs, the case table's checks, the files."""

import csv
import json
import math
from pathlib import Path
from statistics import NormalDist

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli import model, solvers
from rubcli.analysis.ensembles import basin_stability as bs
from rubcli.analysis.ensembles import ensemble as en
from rubcli.cli.app import app
from rubcli.model import ModelParams
from rubcli.problem import Problem

REPO = Path(__file__).resolve().parents[1]
RUN_UP = {"nu": 0.05, "e": 0.3, "K": 10.0, "mu": 0.02, "Rp": 5.0}  # cases/examples/run-up.toml
BOX = {"x": (-1.5, 1.5), "y": (-1.5, 1.5), "vx": (-1.5, 1.5), "vy": (-1.5, 1.5)}
RUNS = {"spread": 0.0, "seed": 0, "methods": ["dop853-jit"], "rtols": [1e-8],
        "options": {"atol": 1e-10}, "periods": 300, "samples_per_period": 16,
        "record_periods": 100, "lyapunov": False, "lyapunov_periods": 50,
        "settle_tolerance": 0.05}  # fmt: skip


def _free_amplitude(eta: float) -> float:
    """|W| = e eta^2 / |1 - eta^2 + 2 i nu eta| (the free whirl without a stator)."""
    return RUN_UP["e"] * eta**2 / abs(complex(1.0 - eta**2, 2.0 * RUN_UP["nu"] * eta))


# ------------------------------------------------------------------------ statistics


@pytest.mark.parametrize(("k", "n"), [(0, 12), (3, 12), (150, 300), (299, 300), (300, 300)])
def test_fraction_intervals_are_the_roots_of_wilsons_quadratic(k, n):
    """Wilson's interval is the set of p with (k/n - p)^2 <= z^2 p (1 - p) / n: its ends
    are the roots of (1 + z^2/n) p^2 - (2 k/n + z^2/n) p + (k/n)^2 = 0."""
    z2 = NormalDist().inv_cdf(0.975) ** 2

    def roots(count):
        p_hat = count / n
        return np.sort(np.roots([1.0 + z2 / n, -(2.0 * p_hat + z2 / n), p_hat**2]).real)

    members = [en.MemberResult(i, "m", None, 0.0, True, "", regime="free whirl",
                               section_centre=(0.0,) * 4, section_size=0.0)
               if i < k else
               en.MemberResult(i, "m", None, 0.0, True, "", regime="synchronous rub",
                               section_centre=(1.0,) * 4, section_size=0.0)
               for i in range(n)]  # fmt: skip
    members.append(en.MemberResult(n, "m", None, 0.0, False, "failed"))  # counted apart
    found = [bs.attractors_at(members)]
    result = bs.BasinStability("eta", [2.0], [members], found, bs.match_attractors(found))
    assert result.failed_runs(0) == 1
    fractions = result.fractions(0)
    expected = {"free whirl": k, "synchronous rub": n - k}
    assert set(fractions) == {name for name, count in expected.items() if count}
    for name, f in fractions.items():
        count = expected[name]
        assert (f["count"], f["runs"], f["fraction"]) == (count, n, count / n)
        low, high = roots(count)
        assert f["ci_low"] == pytest.approx(max(low, 0.0), abs=1e-12)
        assert f["ci_high"] == pytest.approx(min(high, 1.0), abs=1e-12)


# -------------------------------------------------------------------------- matching


def _a(regime, centre, size=0.0, runs=(0,)):
    return bs.LocalAttractor(regime, tuple(float(c) for c in centre) + (0.0,) * (4 - len(centre)),
                             size, runs, ("periodic",))  # fmt: skip


def test_labels_follow_the_attractors_by_name_and_nearest_centre():
    """Two partial rubs drift apart, listed in a different order at each value; the free
    whirl vanishes for one value and comes back: every attractor keeps its label."""
    per_value = [
        [_a("free whirl", [0.3]), _a("synchronous rub", [1.2])],
        [_a("partial rub", [-2.0]), _a("free whirl", [0.32]), _a("partial rub", [2.0]),
         _a("synchronous rub", [1.3])],
        [_a("synchronous rub", [1.4]), _a("partial rub", [2.2]), _a("partial rub", [-2.3])],
        [_a("partial rub", [-2.5]), _a("free whirl", [0.35]), _a("partial rub", [2.4])],
    ]  # fmt: skip
    labels = bs.match_attractors(per_value)
    assert labels[0] == ["free whirl", "synchronous rub"]
    assert labels[1] == ["partial rub 1", "free whirl", "partial rub 2", "synchronous rub"]
    assert labels[2] == ["synchronous rub", "partial rub 2", "partial rub 1"]
    assert labels[3] == ["partial rub 1", "free whirl", "partial rub 2"]


def test_a_third_attractor_of_a_name_opens_a_label_and_the_nearest_keep_theirs():
    per_value = [
        [_a("partial rub", [1.0]), _a("partial rub", [-1.0])],
        [_a("partial rub", [0.0, 3.0]), _a("partial rub", [-1.1]), _a("partial rub", [1.1])],
    ]
    assert bs.match_attractors(per_value) == [
        ["partial rub 1", "partial rub 2"],
        ["partial rub 3", "partial rub 2", "partial rub 1"],
    ]


def test_runs_of_one_regime_are_split_by_the_place_of_their_section():
    def run(i, centre, size=0.0, regime="partial rub", kind="periodic"):
        return en.MemberResult(i, "m", None, 0.0, True, "", regime=regime, kind=kind,
                               section_centre=tuple(centre), section_size=size)  # fmt: skip

    points = [run(0, (1, 0, 0, 0)), run(1, (1.01, 0, 0, 0)), run(2, (-1, 0, 0, 0))]
    others = [run(4, (0, 0, 0, 0), regime=en.CHANGING),
              en.MemberResult(5, "m", None, 0.0, False, "failed")]  # fmt: skip
    found = bs.attractors_at(points)
    assert sorted(a.runs for a in found) == [(0, 1), (2,)]
    # a section of extent s reaches 0.05 + s / 4 further: a torus of extent 3.9 centred
    # between the two points (1 from each) joins them; one of extent 3.6 does not
    torus = run(3, (0, 0, 0, 0), size=3.9, kind="quasi-periodic")
    found = bs.attractors_at([*points, torus, *others])
    assert sorted((a.regime, a.runs) for a in found) == [
        ("partial rub", (0, 1, 2, 3)), (bs.UNDECIDED, (4,))]  # fmt: skip
    torus = run(3, (0, 0, 0, 0), size=3.6, kind="quasi-periodic")
    found = bs.attractors_at([*points, torus, *others])
    assert sorted((a.regime, a.runs) for a in found) == [
        ("partial rub", (0, 1)), ("partial rub", (2,)), ("partial rub", (3,)),
        (bs.UNDECIDED, (4,))]  # fmt: skip


# ---------------------------------------------------------------- the run-up machine


def test_box_starts_are_uniform_in_the_box_and_hold_the_other_coordinates():
    start = (0.1, -0.2, 0.3, 0.4)
    drawn = en.box_starts(start, {"x": (-1.0, 2.0), "vy": (0.5, 0.75)}, 4000, 3)
    assert np.all(drawn[:, 1] == -0.2) and np.all(drawn[:, 2] == 0.3)
    assert drawn[:, 0].min() >= -1.0 and drawn[:, 0].max() < 2.0
    assert drawn[:, 3].min() >= 0.5 and drawn[:, 3].max() < 0.75
    # uniform: mean and variance of U(a, b) within four standard errors
    for column, (a, b) in ((0, (-1.0, 2.0)), (3, (0.5, 0.75))):
        sd = (b - a) / math.sqrt(12.0)
        assert abs(drawn[:, column].mean() - (a + b) / 2) < 4 * sd / math.sqrt(4000)
        assert drawn[:, column].std() == pytest.approx(sd, rel=0.05)
    # a side's draws do not depend on which other sides are drawn
    alone = en.box_starts(start, {"x": (-1.0, 2.0)}, 4000, 3)
    assert np.array_equal(alone[:, 0], drawn[:, 0])


def test_where_the_rub_cannot_exist_every_start_ends_on_the_free_whirl():
    """At eta = 0.5 and 0.7 (below the band) the free whirl clears the stator (|W| = 0.10,
    0.26) and the synchronous rub's quadratic has no root r > 1: the free whirl is the only
    synchronous motion, and starts in contact or far out with any velocity in the box all
    end on it; the minimal perturbation is not computable (no rub)."""
    values = [0.5, 0.7]
    for eta in values:
        params = ModelParams(eta=eta, **RUN_UP)
        assert _free_amplitude(eta) < 1.0 and model.synchronous_rub_radii(params) == []
    starts = en.box_starts((0.0,) * 4, BOX, 30, 0)
    result = bs.basin_stability(
        ModelParams(eta=2.0, **RUN_UP), "eta", values, (0.0,) * 4, starts,
        perturbation=bs.PerturbationSettings(random_directions=0), runs=30, **RUNS,
    )  # fmt: skip
    z2 = NormalDist().inv_cdf(0.975) ** 2
    for i in range(2):
        f = result.fractions(i)
        assert list(f) == ["free whirl"]
        assert f["free whirl"]["count"] == 30 and f["free whirl"]["fraction"] == 1.0
        assert f["free whirl"]["ci_low"] == pytest.approx(30 / (30 + z2), rel=1e-12)
        assert not result.perturbations[i].computable
        assert result.perturbations[i].reason.startswith("no rub")


def _ends_on(params: ModelParams, start, periods: int = 300) -> str:
    """Where a run ends, by its last stroboscopic point against the closed forms: the free
    whirl ``W`` or the synchronous rub (each forward rub root of the quadratic), else "?"."""
    sol = solvers.solve(Problem.from_periods(params, start, periods, 8), "dop853-jit",
                        rtol=1e-11, atol=1e-13)  # fmt: skip
    assert sol.success, sol.message
    end = np.asarray(sol.states)[-1]
    if np.allclose(end, bs.free_whirl_point(params), atol=1e-4):
        return "free whirl"
    for r in model.synchronous_rub_radii(params):
        if np.allclose(end, model.synchronous_rub(np.array([0.0]), params, r)[:, 0], atol=1e-4):
            return "synchronous rub"
    return "?"


@pytest.mark.slow
def test_the_minimal_perturbation_brackets_the_edge_of_the_free_whirls_basin():
    """At eta = 2 (both motions stable: |W| = 0.40, a stable rub at r = 1.59) the bound
    found along the axes is bracketed: a start at that size along that direction ends on
    the rub, one at the bracket's lower end on the free whirl, by independent runs at a
    tighter tolerance judged against the closed-form motions."""
    eta = 2.0
    params = ModelParams(eta=eta, **RUN_UP)
    assert _free_amplitude(eta) < 1.0
    settings = bs.PerturbationSettings(random_directions=2, rtol=0.05, max_size=4.0)
    result = bs.basin_stability(params, "eta", [eta], (0.0,) * 4,
                                en.box_starts((0.0,) * 4, BOX, 4, 0), perturbation=settings,
                                runs=4, **RUNS)  # fmt: skip
    p = result.perturbations[0]
    assert p.computable and p.found and p.directions_tried == 10
    assert p.reached.startswith("synchronous rub")
    d = np.array(p.direction)
    assert np.linalg.norm(d) == pytest.approx(1.0, rel=1e-12)
    assert 0.0 < p.lower < p.size and p.size - p.lower <= 0.05 * p.size
    assert p.size == min(r.upper for r in p.by_direction if r.found)
    origin = np.array(p.origin)
    w, dw = model.free_steady_state(0.0, params)
    assert np.allclose(origin, [w.real, w.imag, dw.real, dw.imag], rtol=0, atol=1e-15)
    assert _ends_on(params, origin + p.size * d) == "synchronous rub"
    assert _ends_on(params, origin + p.lower * d) == "free whirl"


# ------------------------------------------------------------------------ the command


CASE = """
[case]
name = "bs"
[model]
nu = 0.05
eta = 2.0
e = 0.3
K = 10.0
mu = 0.02
Rp = 5.0
[initial]
x = 0.0
y = 0.0
[time]
periods = 50
samples_per_period = 16
[solver]
methods = ["dop853-jit"]
[ensemble]
runs = 2
periods = 100
record_periods = 50
lyapunov = false
{table}
"""


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('parameter = "eta"\nvalues = [1.0, 2.0]\nstart = 1.0\nstop = 2.0\nnum = 3',
         "ensemble: values, start/stop/num: give either values = [...] or start, stop and num"),
        ('parameter = "eta"\nstart = 1.0\nstop = 2.0\nnum = 1',
         "ensemble.num: Input should be greater than or equal to 2"),
        ('parameter = "eta"\nstart = 1.0\nstop = 2.0',
         "ensemble: parameter = eta: give values = [...] or start, stop and num (missing: num)"),
        ('parameter = "eta"\nvalues = [1.0, 0.0]',
         "ensemble: values: every value of eta must be > 0 (got 0.0)"),
        ('parameter = "nu"\nstart = -0.1\nstop = 0.1\nnum = 3',
         "ensemble: start/stop: every value of nu must be >= 0 (got -0.1)"),
        ('parameter = "phi0"\nvalues = [0.0, 1.0]', "ensemble.parameter: Input should be"),
        ("values = [1.0, 2.0]", "ensemble: values: values of what? give parameter"),
        ("minimal_perturbation = true", "ensemble: minimal_perturbation: computed at each value"),
        ("box_x = [-1.0, 1.0]", 'ensemble: box_x: a box side is for starts = "box"'),
        ('starts = "box"', 'ensemble: starts = "box" needs at least one of box_x'),
        ('starts = "box"\nbox_vy = [1.0, -1.0]', "ensemble.box_vy: give [lo, hi] with lo < hi"),
        ('starts = "box"\nbox_x = [1.0]', "ensemble.box_x: List should have at least 2 items"),
    ],
)  # fmt: skip
def test_bad_parameter_or_box_exits_2_naming_the_field(tmp_path, table, message):
    case = tmp_path / "bs.toml"
    case.write_text(CASE.format(table=table))
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["ensemble", str(case), "--out", str(out)])
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    assert f"{case}: {message}" in text
    assert not out.exists()


@pytest.mark.slow
def test_quick_run_of_the_shipped_case_writes_every_file(tmp_path):
    """cases/examples/basin-stability.toml --quick: eta = 1.0, 2.2, 3.4. At 1.0 the free
    whirl would reach 3 clearances (e eta^2 / (2 nu eta) = 3): every run ends on the rub
    and no perturbation can start from the free whirl; at 3.4 the rub's quadratic has no
    root outside the clearance: every run ends on the free whirl."""
    out = tmp_path / "out"
    args = ["ensemble", str(REPO / "cases/examples/basin-stability.toml"), "--quick",
            "--out", str(out), "-w", "1", "--json"]  # fmt: skip
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["mode"] == "basin_stability"
    assert {p.name for p in out.iterdir()} == {"basin_stability.csv", "basin_stability.png",
                                               "report.json"}  # fmt: skip
    rows = list(csv.DictReader((out / "basin_stability.csv").open()))
    assert list(rows[0]) == ["eta", "attractor", "count", "runs", "fraction", "ci_low", "ci_high"]
    by_value: dict[float, dict[str, dict]] = {}
    for row in rows:
        by_value.setdefault(float(row["eta"]), {})[row["attractor"]] = row
    assert list(by_value) == [1.0, 2.2, 3.4]
    for value, found in by_value.items():
        assert sum(int(r["count"]) for r in found.values()) == 12, value
        for r in found.values():
            assert float(r["ci_low"]) <= float(r["fraction"]) <= float(r["ci_high"])
    assert _free_amplitude(1.0) == pytest.approx(3.0, rel=1e-12)
    assert int(by_value[1.0]["synchronous rub"]["count"]) == 12
    assert model.synchronous_rub_radii(ModelParams(eta=3.4, **RUN_UP)) == []
    assert int(by_value[3.4]["free whirl"]["count"]) == 12
    report = json.loads((out / "report.json").read_text())
    kicks = report["minimal_perturbation"]
    assert [k["value"] for k in kicks] == [1.0, 2.2, 3.4]
    assert kicks[0]["reason"].startswith("no free whirl") and not kicks[0]["computable"]
    assert kicks[2]["reason"].startswith("no rub") and not kicks[2]["computable"]
    assert kicks[1]["computable"] and kicks[1]["size"] > 0 and kicks[1]["directions_tried"] == 8


def test_the_shaded_band_runs_from_the_free_whirls_grazing_to_the_rubs_fold():
    """The figure's shaded span: from the grazing speed (the quadratic in eta^2 of
    e^2 eta^4 = (1 - eta^2)^2 + 4 nu^2 eta^2) to the double root of the rub's quadratic."""
    from scipy.optimize import brentq

    from rubcli.analysis.charts.stability import rub_fold_discriminant
    from rubcli.case import load_case
    from rubcli.studies.basin_stability import both_spans

    nu, e = RUN_UP["nu"], RUN_UP["e"]
    a, b = 1.0 - e * e, 4.0 * nu * nu - 2.0
    grazing = math.sqrt((-b + math.sqrt(b * b - 4.0 * a)) / (2.0 * a))  # the upper root
    fold = brentq(lambda eta: rub_fold_discriminant(ModelParams(eta=eta, **RUN_UP)), 2.5, 3.4)
    case = load_case(REPO / "cases/examples/basin-stability.toml")
    [(lo, hi)] = both_spans(case, "eta", [1.0, 3.4])
    assert lo == pytest.approx(grazing, abs=1e-8) and hi == pytest.approx(fold, abs=1e-8)


def test_a_single_ensemble_can_draw_its_starts_from_a_box(tmp_path):
    """Without a parameter, starts = "box" replaces the cloud: at eta = 0.5 (the free whirl
    alone) every start ends on it, and each run's offset is its start's distance from
    [initial]: only x is drawn, uniform on [-1, 1], so the offsets lie in [0, 1] and the
    first is |lo + (hi - lo) u| for the seed's first uniform."""
    case = tmp_path / "bs.toml"
    table = 'starts = "box"\nbox_x = [-1.0, 1.0]\nseed = 5'
    text = CASE.format(table=table).replace("eta = 2.0", "eta = 0.5")
    case.write_text(text.replace("runs = 2", "runs = 3"))
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["ensemble", str(case), "--out", str(out), "-w", "1"])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader((out / "ensemble.csv").open()))
    assert [r["attractor"] for r in rows] == ["free whirl, periodic"] * 3
    offsets = [float(r["start_offset"]) for r in rows]
    assert all(0.0 <= d <= 1.0 for d in offsets) and len(set(offsets)) == 3
    first_uniform = np.random.default_rng(5).random(4)[0]
    assert offsets[0] == pytest.approx(abs(-1.0 + 2.0 * first_uniform), rel=1e-12)


@pytest.mark.parametrize(
    "general",
    [{"offset": (0.3, 0.0)}, {"load": (0.0, -0.2)}, {"stiffness": ((1.0, 0.0), (0.0, 1.5))}],
)
def test_the_minimal_perturbation_is_not_computed_on_a_general_machine(general):
    """Its origin is the paper machine's free whirl (a closed form): on a general machine
    it says why instead of perturbing a state that is not the free whirl."""
    params = ModelParams(nu=0.05, eta=0.7, e=0.1, K=20.0, mu=0.1, Rp=10.0, **general)
    why = bs.perturbation_status(params, [])
    assert why is not None and "general machine" in why and "paper's machine only" in why

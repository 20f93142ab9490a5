"""Periodic orbits, monodromy matrices through switches, continuation and `rubcli orbits`.

Reference numbers come from independent determinations: the rotating-frame linearisation
of the synchronous rub (analysis/orbits/synchronous.py), the closed-form multipliers of the free
Jeffcott rotor, central finite differences of the stroboscopic map, the closed-form free
whirl radius and the discriminant of the synchronous-rub quadratic (model notes 5).
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis.orbits import continuation as cn
from rubcli.analysis.orbits import periodic as ob
from rubcli.analysis.orbits.synchronous import synchronous_rubs
from rubcli.cli.app import app
from rubcli.model import ModelParams
from rubcli.solvers import variational

PAPER = ModelParams(nu=0.009478, eta=0.7818, e=7.52, K=17.6, mu=0.0, Rp=46.16)
# A transient through contact entry and exit and a slip reversal (slip+ -> slip-) in one
# period; another through stick entry and stick exit (found by a scan of starts).
REVERSAL = (ModelParams(nu=0.02, eta=0.8716, e=0.3, K=17.6, mu=0.1, Rp=0.2),
            [1.05, 0.0, 0.0, -0.2318], 1)  # fmt: skip
STICK = (ModelParams(nu=0.05, eta=0.5, e=0.5, K=5.0, mu=0.6, Rp=0.05), [1.2, 0.0, 0.0, -0.1], 3)
RUN_UP = ModelParams(nu=0.05, eta=0.6, e=0.12, K=2.0, mu=0.02, Rp=0.5)


def _match(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between two multiplier sets, each of a matched to its nearest in b."""
    b = list(b)
    worst = 0.0
    for value in a:
        j = int(np.argmin([abs(value - other) for other in b]))
        worst = max(worst, abs(value - b.pop(j)))
    return worst


def _fd_monodromy(params, s0, k, h=1e-6):
    fd = np.zeros((4, 4))
    for j in range(4):
        sp = np.array(s0, dtype=float)
        sm = sp.copy()
        sp[j] += h
        sm[j] -= h
        plus = ob.stroboscopic_map(params, sp, k, variational=False).state
        minus = ob.stroboscopic_map(params, sm, k, variational=False).state
        fd[:, j] = (plus - minus) / (2.0 * h)
    return fd


# ------------------------------------------------------------------ multipliers


@pytest.mark.parametrize("mu", [0.005, 0.03])
def test_synchronous_rub_multipliers_are_exp_of_rotating_frame_eigenvalues(mu):
    params = dataclasses.replace(PAPER, mu=mu)
    rub = synchronous_rubs(params)[-1]
    s0 = model.synchronous_rub(np.array([0.0]), params, rub.r)[:, 0]
    orbit = ob.shoot(params, s0 + 1e-4)  # Newton back onto the exact orbit
    assert np.max(np.abs(orbit.state - s0)) < 1e-10
    expected = np.exp(rub.eigenvalues * params.period)
    assert _match(orbit.multipliers, expected) < 1e-8
    assert orbit.stable == rub.stable == (mu < 0.0102)


@pytest.mark.parametrize("k", [1, 2])
def test_free_rotor_multipliers_in_closed_form(k):
    params = dataclasses.replace(RUN_UP, eta=0.6)
    orbit = ob.shoot(params, [0.0, 0.0, 0.0, 0.0], k)
    w, _ = model.free_steady_state(0.0, params)
    assert orbit.flow.max_z < 1.0 and not orbit.flow.events
    assert abs(complex(*orbit.state[:2]) - w) < 1e-11  # the free whirl, notes 5
    assert _match(orbit.multipliers, ob.free_multipliers(params, k)) < 1e-10


def test_extremes_of_z_are_the_closed_form_free_flights():
    """A flow's largest and smallest z are refined from its samples to where z turns: on
    a free flight they are the closed form's (``model.free_flight``, its extremes by
    Brent's method on a fine grid's best) to 1e-11, where its samples alone miss them by
    far more."""
    from scipy.optimize import minimize_scalar

    params = dataclasses.replace(RUN_UP, eta=0.6)
    s0 = np.array([0.3, 0.0, 0.0, 0.4])
    T = params.period
    fl = ob.flow(params, s0, 0.0, T, variational=False)
    assert not fl.events

    def z(t):
        s = model.free_flight(t, 0.0, s0, params)
        return np.hypot(s[0], s[1])

    grid = np.linspace(0.0, T, 20001)
    for sign, found in ((1.0, fl.max_z), (-1.0, fl.min_z)):
        i = int(np.argmax(sign * z(grid)))
        best = minimize_scalar(lambda t, sign=sign: -sign * z(t), bounds=(grid[i - 1], grid[i + 1]),
                               method="bounded", options={"xatol": 1e-14})  # fmt: skip
        exact = float(z(best.x))
        assert abs(found - exact) < 1e-11
        samples = float(np.max(sign * z(ob.sample_grid(params, 0.0, T))) * sign)
        assert abs(samples - exact) > 1e-7


# --------------------------------------------------------- monodromy through switches


@pytest.mark.parametrize(
    ("example", "kinds"),
    [(REVERSAL, {"contact_entry", "contact_exit", "slip_reversal"}),
     (STICK, {"stick_entry", "stick_exit", "contact_exit"})],
    ids=["contact-and-slip-reversal", "stick"],
)  # fmt: skip
def test_monodromy_matches_central_differences(example, kinds):
    params, s0, k = example
    fl = ob.stroboscopic_map(params, s0, k)
    assert kinds <= {e[1] for e in fl.events}
    fd = _fd_monodromy(params, s0, k)
    assert np.max(np.abs(fl.monodromy - fd)) < 1e-6 * np.max(np.abs(fd))


def test_without_saltation_the_monodromy_is_wrong(monkeypatch):
    """The check above can fail: drop the saltation matrices and it does."""
    params, s0, k = REVERSAL
    fd = _fd_monodromy(params, s0, k)
    monkeypatch.setattr(variational, "saltation_matrix", lambda *args, **kw: np.eye(4))
    broken = ob.stroboscopic_map(params, s0, k).monodromy
    assert np.max(np.abs(broken - fd)) > 1e-2 * np.max(np.abs(fd))


def test_saltation_is_identity_at_contact_and_not_at_slip_reversal():
    params = REVERSAL[0]
    on_circle = np.array([0.6, 0.8, -0.3, 0.5])  # z = 1
    grad = np.array([1.2, 1.6, 0.0, 0.0])
    S = variational.saltation_matrix(0.3, on_circle, params, model.FREE, model.SLIP_POSITIVE, grad)
    assert np.array_equal(S, np.eye(4))
    s = np.array([1.02, 0.0, 0.0, -params.Rp * params.eta])  # v_r = 0 in contact
    grad = variational.surface_gradient(ob.ev.REVERSAL, 0.0, s, params, model.SLIP_POSITIVE)[0]
    S = variational.saltation_matrix(0.0, s, params, model.SLIP_POSITIVE, model.SLIP_NEGATIVE, grad)
    # the friction force jumps by 2 mu K (z - 1) along the tangent (here +y) when the slip
    # reverses; S = I + jump e_y grad^T / (grad . f-), grad . f- = dv_r/dtau before
    f_minus = model.rhs(0.0, s, params, model.SLIP_POSITIVE)
    jump = 2.0 * params.mu * params.K * (1.02 - 1.0)
    expected = np.eye(4)
    expected[3] += jump * grad / float(grad @ f_minus)
    assert np.max(np.abs(S - expected)) < 1e-12
    assert np.max(np.abs(S - np.eye(4))) > 1e-3


# ------------------------------------------------------------------ continuation


def test_neimark_sacker_of_the_synchronous_rub_located_to_the_eigenvalue_crossing():
    def growth(mu):
        return synchronous_rubs(dataclasses.replace(PAPER, mu=mu))[-1].growth_rate

    independent = brentq(growth, 0.0, 0.06, xtol=1e-15)
    assert abs(independent - 0.0103) < 1e-4  # the value docs/stability.md quotes
    params = dataclasses.replace(PAPER, mu=0.008)
    s0 = model.synchronous_rub(np.array([0.0]), params)[:, 0]
    settings = cn.ContinuationSettings(
        parameter="mu",
        p_min=0.008,
        p_max=0.014,
        step=0.002,
        min_step=1e-6,
        max_step=0.004,
        max_points=5,
        directions=(1,),
    )
    branch = cn.continue_branch(params, s0, settings)
    kinds = [b.kind for b in branch.bifurcations]
    assert kinds == [cn.NEIMARK_SACKER]
    ns = branch.bifurcations[0]
    assert ns.located and abs(ns.parameter - independent) < 1e-6
    moduli = np.sort(np.abs(ns.point.multipliers))
    assert np.allclose(moduli[2:], 1.0, atol=1e-6)  # the critical pair on the circle
    assert branch.stops["forward"].startswith("reached the upper bound")


def test_fold_of_the_rub_branch_located_to_the_quadratics_double_root():
    def discriminant(eta):  # of the synchronous-rub quadratic in r - 1 (notes 5)
        p = dataclasses.replace(RUN_UP, eta=eta)
        a = 1.0 - eta**2 + p.K
        b = 2.0 * p.nu * eta + p.mu * p.K
        c1, c2 = 1.0 - eta**2, 2.0 * p.nu * eta
        qa, qb, qc = a * a + b * b, 2.0 * (a * c1 + b * c2), c1 * c1 + c2 * c2 - p.E**2
        return qb * qb - 4.0 * qa * qc

    independent = brentq(discriminant, 1.2, 1.3, xtol=1e-15)
    params = dataclasses.replace(RUN_UP, eta=1.23)
    s0 = model.synchronous_rub(np.array([0.0]), params)[:, 0]
    settings = cn.ContinuationSettings(
        parameter="eta",
        p_min=1.2,
        p_max=1.3,
        step=0.005,
        min_step=1e-6,
        max_step=0.01,
        max_points=10,
        directions=(1,),
    )
    branch = cn.continue_branch(params, s0, settings)
    folds = [b for b in branch.bifurcations if b.kind == cn.FOLD]
    assert len(folds) == 1 and folds[0].located
    assert abs(folds[0].parameter - independent) < 1e-6
    assert abs(np.max(np.abs(folds[0].point.multipliers)) - 1.0) < 1e-6
    # after the fold the branch comes back, unstable, towards lower eta
    assert branch.points[-1].parameter < folds[0].parameter and not branch.points[-1].stable


def test_grazing_of_the_free_whirl_located_to_the_closed_form():
    def free_radius_minus_one(eta):
        return RUN_UP.e * eta**2 / abs(1 - eta**2 + 2j * RUN_UP.nu * eta) - 1.0

    independent = brentq(free_radius_minus_one, 0.9, 1.0, xtol=1e-15)
    params = dataclasses.replace(RUN_UP, eta=0.96)
    settings = cn.ContinuationSettings(
        parameter="eta",
        p_min=0.96,
        p_max=0.99,
        step=0.005,
        min_step=1e-6,
        max_step=0.01,
        max_points=6,
        directions=(1,),
    )
    branch = cn.continue_branch(params, [0.0, 0.0, 0.0, 0.0], settings)
    grazes = [b for b in branch.bifurcations if b.kind == cn.GRAZING]
    assert len(grazes) == 1 and grazes[0].located
    assert abs(grazes[0].parameter - independent) < 1e-6
    assert branch.points[0].contact_fraction == 0.0 and branch.points[-1].contact_fraction == 1.0


def test_unstable_rub_meets_the_free_branch_in_a_nonsmooth_fold_at_grazing():
    """Down the unstable rub branch to r = 1, where it turns into the free whirl (eta up)."""

    def free_radius_minus_one(eta):
        return RUN_UP.e * eta**2 / abs(1 - eta**2 + 2j * RUN_UP.nu * eta) - 1.0

    independent = brentq(free_radius_minus_one, 1.0, 1.2, xtol=1e-15)
    params = dataclasses.replace(RUN_UP, eta=1.0687)
    r_unstable = model.synchronous_rub_radii(params)[0]
    s0 = model.synchronous_rub(np.array([0.0]), params, r_unstable)[:, 0]
    settings = cn.ContinuationSettings(
        parameter="eta",
        p_min=0.6,
        p_max=1.6,
        step=0.02,
        min_step=1e-6,
        max_step=0.05,
        max_points=4,
        directions=(-1,),
    )
    branch = cn.continue_branch(params, s0, settings)
    assert not branch.points[-1].stable and branch.points[0].stable  # unstable rub -> free
    kinds = {b.kind: b for b in branch.bifurcations}
    assert set(kinds) == {cn.GRAZING, cn.FOLD}
    for bif in kinds.values():
        assert bif.located and abs(bif.parameter - independent) < 1e-6
    assert "nonsmooth fold" in kinds[cn.FOLD].note


# A stiff stator without friction: the synchronous whirl is a circle, so the free branch
# touches the stator all round at once, and past it the amplitude saturates: the branch
# leaves each grazing at a sharp corner that a tangent predictor cannot follow.
STIFF = ModelParams(nu=0.02, eta=1.0, e=0.05, K=10.0, mu=0.0, Rp=5.0)


def _stiff_grazings() -> tuple[float, float]:
    def free_radius_minus_one(eta):
        return STIFF.e * eta**2 / abs(1 - eta**2 + 2j * STIFF.nu * eta) - 1.0

    return (brentq(free_radius_minus_one, 0.9, 1.0, xtol=1e-15),
            brentq(free_radius_minus_one, 1.0, 1.2, xtol=1e-15))  # fmt: skip


def _stiff_settings(lo: float, hi: float, direction: int) -> cn.ContinuationSettings:
    return cn.ContinuationSettings(
        parameter="eta", p_min=lo, p_max=hi, step=0.01, max_points=40,
        directions=(direction,), rtol=1e-11, atol=1e-11,
    )  # fmt: skip


def test_stiff_stator_free_branch_continues_through_grazing_onto_the_rub():
    lower, _ = _stiff_grazings()
    params = dataclasses.replace(STIFF, eta=0.97)
    branch = cn.continue_branch(params, [0.0, 0.0, 0.0, 0.0], _stiff_settings(0.97, 1.0, 1))
    assert "upper bound" in branch.stops["forward"], branch.stops
    (graze,) = [b for b in branch.bifurcations if b.kind == cn.GRAZING]
    assert graze.located and abs(graze.parameter - lower) < 1e-9
    assert branch.points[0].max_z < 1.0 and branch.points[-1].contact_fraction == 1.0
    assert branch.points[-1].stable  # the rub born at the lower grazing is stable


@pytest.mark.slow
@pytest.mark.parametrize("side", ["unstable rub", "free whirl"])
def test_stiff_stator_nonsmooth_fold_at_the_upper_grazing_from_either_side(side):
    """Down the unstable rub to r = 1, where the branch turns back up as the free whirl; or
    down the free whirl to r = 1, where it turns back up as the unstable rub."""
    _, upper = _stiff_grazings()
    params = dataclasses.replace(STIFF, eta=1.04)
    if side == "unstable rub":
        r_unstable = model.synchronous_rub_radii(params)[0]
        s0 = model.synchronous_rub(np.array([0.0]), params, r_unstable)[:, 0]
    else:
        w, v = model.free_steady_state(0.0, params)
        s0 = [w.real, w.imag, v.real, v.imag]
    branch = cn.continue_branch(params, s0, _stiff_settings(1.0, 1.04, -1))
    assert "upper bound" in branch.stops["backward"], branch.stops
    kinds = {b.kind: b for b in branch.bifurcations}
    assert set(kinds) == {cn.GRAZING, cn.FOLD}
    for bif in kinds.values():
        assert bif.located and abs(bif.parameter - upper) < 1e-9
    assert "nonsmooth fold" in kinds[cn.FOLD].note
    ends = {pt.stable for pt in (branch.points[0], branch.points[-1])}
    assert ends == {True, False}  # the free whirl is stable, the small rub is not


def test_newton_failure_and_point_budget_end_cleanly():
    with pytest.raises(ob.NewtonError) as info:
        ob.shoot(PAPER, [3.0, 0.0, 0.0, 0.0], max_iter=1)
    assert "did not converge in 1 iterations" in str(info.value)
    assert info.value.state.shape == (4,) and info.value.residual > 1e-3
    settings = cn.ContinuationSettings(
        parameter="eta", p_min=0.6, p_max=1.6, step=0.02, min_step=1e-5, max_step=0.05, max_points=2
    )
    branch = cn.continue_branch(RUN_UP, [0.0, 0.0, 0.0, 0.0], settings)
    assert branch.stops == {"forward": "point budget used (2 points)",
                            "backward": "reached the lower bound eta = 0.6"}  # fmt: skip
    assert len(branch.points) == 3  # the start (on the lower bound) and two points up
    assert np.all(np.diff([p.parameter for p in branch.points]) > 0)


# ------------------------------------------------------------------------- CLI

BASE = """
[case]
name = "t"
[model]
nu = 0.05
eta = {eta}
e = 0.12
K = 2.0
mu = 0.02
Rp = 0.5
[initial]
x = 0.0
y = 0.0
vx = 0.0
vy = 0.0
[time]
periods = 1
samples_per_period = 10
"""
GOOD_ORBITS = """
[orbits]
parameter = "eta"
min = 0.96
max = 0.99
step = 0.005
max_step = 0.01
max_points = 8
"""


def _write(tmp_path, text, eta=0.96):
    path = tmp_path / "case.toml"
    path.write_text(BASE.format(eta=eta) + text)
    return path


def test_cli_writes_the_branch(tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(
        app, ["orbits", str(_write(tmp_path, GOOD_ORBITS)), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {
        "branch.csv", "branch.nc", "branch.png", "multipliers.png", "report.json"}  # fmt: skip
    report = json.loads((out / "report.json").read_text())
    (graze,) = [b for b in report["branch"]["bifurcations"] if b["kind"] == "grazing"]
    lines = (out / "branch.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = [dict(zip(header, line.split(","), strict=True)) for line in lines[1:]]
    labelled = [r for r in rows if r["label"]]
    assert [r["label"] for r in labelled] == ["grazing"]
    assert float(labelled[0]["value"]) == pytest.approx(graze["parameter"], abs=1e-15)
    assert abs(float(labelled[0]["max_z"]) - 1.0) < 1e-7
    import xarray as xr

    with xr.open_dataset(out / "branch.nc", engine="h5netcdf") as ds:
        assert ds.sizes["point"] == len(rows)
        np.testing.assert_allclose(ds["eta"].values, [float(r["value"]) for r in rows], rtol=0)
        np.testing.assert_allclose(
            ds["multiplier_re"].values[:, 0], [float(r["multiplier1_re"]) for r in rows], rtol=0
        )


@pytest.mark.parametrize(
    ("table", "eta", "message"),
    [
        ("", 0.96, "missing table [orbits]"),
        (GOOD_ORBITS.replace('"eta"', '"phi0"'), 0.96, "orbits.parameter"),
        (GOOD_ORBITS + "bogus = 1\n", 0.96, "orbits.bogus: unknown key"),
        (GOOD_ORBITS.replace("max = 0.99", "max = 0.9"), 0.96, "min must be below max"),
        (GOOD_ORBITS.replace("min = 0.96", "min = 0.0"), 0.96, "eta must stay positive"),
        (GOOD_ORBITS.replace("step = 0.005", "step = 0.5"), 0.96, "wider than the window"),
        (GOOD_ORBITS.replace("step = 0.005", "step = -0.005"), 0.96, "orbits.step"),
        (GOOD_ORBITS, 1.2, "lies outside the window"),
        (GOOD_ORBITS + 'start = "synchronous_rub"\n', 0.96, "no forward synchronous"),
    ],
)
def test_bad_orbits_tables_exit_2_and_write_nothing(tmp_path, table, eta, message):
    out = tmp_path / "out"
    path = _write(tmp_path, table, eta)
    result = CliRunner().invoke(app, ["orbits", str(path), "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert message in result.output and str(path) in result.output
    assert "Traceback" not in result.output
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["case.toml"]


def test_no_starting_orbit_exits_1_with_the_reason(tmp_path):
    out = tmp_path / "out"
    path = _write(tmp_path, GOOD_ORBITS + "max_newton = 1\n")
    path.write_text(path.read_text().replace("x = 0.0", "x = 3.0"))
    result = CliRunner().invoke(app, ["orbits", str(path), "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert [p.name for p in out.iterdir()] == ["report.json"]
    report = json.loads((out / "report.json").read_text())
    assert report["branch"]["status"] == "failed"
    assert "did not converge in 1 iterations" in report["branch"]["message"]


def _sweep_nc(path, coordinate="eta"):
    import xarray as xr

    eta = np.linspace(0.96, 0.99, 7)
    strobe = 0.5 + 0.01 * np.arange(7)[:, None, None] + np.zeros((7, 2, 5))
    strobe[3, 1, :] = np.nan  # a failed point
    ds = xr.Dataset({"strobe_z": ((coordinate, "direction", "section"), strobe)},
                    coords={coordinate: eta, "direction": ["up", "down"]})  # fmt: skip
    ds.to_netcdf(path, engine="h5netcdf")


def test_overlay_of_a_sweep(tmp_path):
    from rubcli.studies.orbits import load_overlay

    nc = tmp_path / "sweep.nc"
    _sweep_nc(nc)
    px, pz, label = load_overlay(nc, "eta", None)
    assert px.size == pz.size == 7 * 2 * 5 - 5 and "strobe_z" in label
    np.testing.assert_allclose(pz[px == px[0]], 0.5)
    out = tmp_path / "out"
    case = _write(tmp_path, GOOD_ORBITS.replace("max_points = 8", "max_points = 2"))
    result = CliRunner().invoke(app, ["orbits", str(case), "--out", str(out), "--overlay", str(nc)])
    assert result.exit_code == 0, result.output
    assert json.loads((out / "report.json").read_text())["overlay"] == str(nc)
    bad = tmp_path / "bad.nc"
    _sweep_nc(bad, coordinate="mu")
    out2 = tmp_path / "out2"
    result = CliRunner().invoke(
        app, ["orbits", str(case), "--out", str(out2), "--overlay", str(bad)]
    )
    assert result.exit_code == 2 and "no coordinate 'eta'" in result.output
    assert not out2.exists()


@pytest.mark.parametrize("name", ["paper/fig3-orbits.toml", "examples/run-up-orbits.toml"])
def test_shipped_orbit_cases_quick(tmp_path, name):
    from pathlib import Path

    case = Path(__file__).resolve().parents[1] / "cases" / name
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["orbits", str(case), "--out", str(out), "--quick"])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    points = report["branch"]["n_points"]
    assert 2 <= points <= 2 * 12 + 1
    if name.startswith("paper"):
        (ns,) = report["branch"]["bifurcations"]
        assert ns["kind"] == "neimark_sacker"
        assert abs(ns["parameter"] - 0.010287230410) < 1e-6  # brentq value, test above
    assert math.isfinite(report["wall_time_s"])


def test_orbits_study_from_python(tmp_path):
    """The library path of `rubcli orbits`: the study with its progress, then its files."""
    from pathlib import Path

    from rubcli.case import load_case
    from rubcli.studies.orbits import FILES, continue_orbits

    case = load_case(Path(__file__).resolve().parents[1] / "cases/paper/fig3-orbits.toml")
    seen = []
    result = continue_orbits(case, quick=True, progress=lambda *a: seen.append(a))
    assert result.ok and seen[0][0] == "the starting orbit"
    assert seen[-1][1] == len(result.branch.points) and seen[-1][2] == 2 * 12 + 1
    (ns,) = result.branch.bifurcations
    assert ns.kind == cn.NEIMARK_SACKER and abs(ns.parameter - 0.010287230410) < 1e-6
    report = result.write(tmp_path / "orbits")
    assert {p.name for p in (tmp_path / "orbits").iterdir()} == set(FILES)
    assert report["branch"]["n_points"] == len(result.branch.points)
    bad = load_case(Path(__file__).resolve().parents[1] / "cases/paper/fig3a.toml")
    with pytest.raises(ValueError, match=r"missing table \[orbits\]"):
        continue_orbits(bad)

"""Closed-form charts of the synchronous motions (rubcli.analysis.charts).

Each located curve point is checked by a different route than the one that located it:
the grazing speeds (roots of a quadratic in eta^2) against the free whirl's amplitude from
``model.free_steady_state``; the folds (roots of the discriminant) against the number of
roots ``model.synchronous_rub_radii`` finds on either side; the stability boundary
against the sign of the rotating-frame eigenvalues on either side.
"""

from __future__ import annotations

import dataclasses

import pytest

from rubcli import model
from rubcli.analysis import charts as ch
from rubcli.analysis.synchronous import synchronous_rubs
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
    folds = chart.curves[ch.RUB_FOLD]
    assert len(folds) == 3  # one fold of the rub branch per value of e
    for eta, e in folds:
        p = dataclasses.replace(RUN_UP, e=e)
        below = model.synchronous_rub_radii(dataclasses.replace(p, eta=eta - 1e-6))
        above = model.synchronous_rub_radii(dataclasses.replace(p, eta=eta + 1e-6))
        assert {len(below), len(above)} == {0, 2}
        pair = below or above
        r_f = ch.rub_fold_radius(dataclasses.replace(p, eta=eta))
        assert min(pair) < r_f < max(pair) and max(pair) - min(pair) < 1e-2
    grazings = chart.curves[ch.FREE_GRAZING]
    assert len(grazings) == 6  # both sides of the critical speed, three values of e
    for eta, e in grazings:
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
    for mu, stable in ((mu_ns - 1e-7, True), (mu_ns + 1e-7, False)):
        rub = synchronous_rubs(dataclasses.replace(paper, mu=mu))[-1]
        assert rub.stable == stable
        crossing = rub.eigenvalues[abs(rub.eigenvalues.real) < 1e-4]
        assert crossing.size == 2 and abs(crossing[0].imag) > 0.1

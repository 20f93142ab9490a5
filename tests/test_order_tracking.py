"""Order tracking of a run whose speed changes (analysis/response/order_tracking.py) and its
figures (plotting/transient.py), on synthetic signals whose 1X vectors are known exactly:
constant-speed sums of whirls, and linear run-ups ``eta = eta0 + a tau`` with the exact
phase ``eta0 tau + a tau^2 / 2`` and the free whirl's closed-form amplitude
``A(eta) = e eta^2 / (1 - eta^2 + 2 i nu eta)`` (model notes 5). Nothing is solved.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rubcli import model
from rubcli.analysis.response.order_tracking import (
    analyse_transient,
    order_cascade,
    order_track,
    rub_events,
    time_in_regimes,
)
from rubcli.io import save_figure
from rubcli.plotting import transient

NU, E = 0.05, 0.12  # the free whirl of the run-ups: peak e / (2 nu) = 1.2 clearances


def free_whirl(eta):
    """The free whirl's 1X vector and its first two derivatives in eta (closed form)."""
    d = 1.0 - eta**2 + 2j * NU * eta
    d1, d2 = -2.0 * eta + 2j * NU, -2.0
    a = E * eta**2 / d
    a1 = E * (2.0 * eta / d - eta**2 * d1 / d**2)
    a2 = E * (2.0 / d - 4.0 * eta * d1 / d**2 - eta**2 * d2 / d**2 + 2.0 * eta**2 * d1**2 / d**3)
    return a, a1, a2


def run_up(eta0=0.5, eta1=1.5, rate=2e-3, dt=0.02):
    """(tau, eta, phase, w) of a linear run-up on the free whirl's closed form."""
    tau = np.arange(0.0, (eta1 - eta0) / rate, dt)
    eta = eta0 + rate * tau
    phase = eta0 * tau + 0.5 * rate * tau**2
    return tau, eta, phase, free_whirl(eta)[0] * np.exp(1j * phase)


def test_constant_speed_recovers_both_1x_vectors_to_round_off():
    eta, n, turns, phase0 = 0.8, 50, 12, 0.3
    tau = np.arange(turns * n + 7) * (2.0 * math.pi / (eta * n))  # a partial turn at the end
    phase = eta * tau + phase0
    forward, backward, offset = 0.7 * np.exp(-0.4j), 0.2 * np.exp(1.1j), 0.1 - 0.05j
    w = (offset + forward * np.exp(1j * phase) + backward * np.exp(-1j * phase)
         + 0.3j * np.exp(2j * phase))  # fmt: skip
    r = order_track(tau, w.real, w.imag, phase, np.full(tau.size, eta))
    assert len(r) == turns  # the trailing partial revolution is left out
    assert np.all(r.stop - r.start == n)
    assert np.max(np.abs(r.forward - forward)) < 1e-13
    assert np.max(np.abs(r.backward - backward)) < 1e-13
    assert np.max(np.abs(r.offset - offset)) < 1e-13
    # probes: x = Re((A_f + conj A_b) e^{ip}), y = Im(...) = Re(-i (A_f - conj A_b) e^{ip})
    px, py = forward + np.conj(backward), forward - np.conj(backward)
    assert np.allclose(r.x_amplitude, abs(px), rtol=0, atol=1e-13)
    assert np.allclose(r.y_amplitude, abs(py), rtol=0, atol=1e-13)
    assert np.allclose(r.x_lag_deg, -np.degrees(np.angle(px)), rtol=0, atol=1e-11)
    assert np.allclose(r.y_lag_deg, -np.degrees(np.angle(py)), rtol=0, atol=1e-11)
    assert np.allclose(r.eta, eta)


@pytest.mark.parametrize("lag_deg", [0.0, 30.0, 90.0, 150.0, 200.0, -60.0])
def test_probe_lag_convention(lag_deg):
    """x = R cos(p - lag) and y = R cos(p - 90 deg - lag): both probes report ``lag``."""
    eta, n = 1.3, 64
    tau = np.arange(4 * n + 1) * (2.0 * math.pi / (eta * n))
    phase = eta * tau
    lag = math.radians(lag_deg)
    x = 0.4 * np.cos(phase - lag)
    y = 0.4 * np.cos(phase - 0.5 * math.pi - lag)
    r = order_track(tau, x, y, phase, np.full(tau.size, eta))
    assert np.allclose(r.x_lag_deg, lag_deg, atol=1e-10)
    assert np.allclose(r.y_lag_deg, lag_deg, atol=1e-10)
    assert np.allclose(r.x_amplitude, 0.4, atol=1e-13)
    assert np.allclose(np.abs(r.forward), 0.4, atol=1e-13)  # a forward circular whirl
    assert np.allclose(np.abs(r.backward), 0.0, atol=1e-13)


def test_free_whirl_lags_90_degrees_at_the_critical_speed():
    params = model.ModelParams(nu=NU, eta=1.0, e=E, K=1.0)
    tau = np.arange(3 * 80 + 1) * (2.0 * math.pi / 80)
    w, _ = model.free_steady_state(tau, params)
    r = order_track(tau, w.real, w.imag, tau, np.ones(tau.size))
    assert np.allclose(r.x_lag_deg, 90.0, atol=1e-9)
    assert np.allclose(r.y_lag_deg, 90.0, atol=1e-9)
    assert np.allclose(np.abs(r.forward), E / (2 * NU), rtol=1e-12)


@pytest.mark.parametrize("rate", [1e-3, 2e-3, 4e-3])
def test_run_up_bias_within_the_derived_bound(rate):
    """On a linear ramp, the fitted A_f differs from A at the revolution's mean speed by
    delta = eps^2 (pi^2/6 eta^2 A'' + 5/4 eta A'), eps = a / eta^2 (order_tracking), up
    to a remainder below (2 pi / n) eps eta |A'| for n samples per revolution."""
    tau, eta, phase, w = run_up(rate=rate)
    r = order_track(tau, w.real, w.imag, phase, eta)
    a, a1, a2 = free_whirl(r.eta)
    eps = rate / r.eta**2
    leading = eps**2 * (math.pi**2 / 6.0 * r.eta**2 * a2 + 1.25 * r.eta * a1)
    remainder = 2.0 * math.pi / (r.stop - r.start) * eps * r.eta * np.abs(a1)
    error = r.forward - a
    assert np.all(np.abs(error - leading) <= remainder)
    assert np.all(np.abs(error) <= np.abs(leading) + remainder)
    # the bound: under 1 % of the peak up to a = 2e-3 (nu = 0.05); 2.3 % at 4e-3
    share = np.max(np.abs(leading) + remainder) / np.max(np.abs(a))
    assert share < (1e-2 if rate <= 2e-3 else 3e-2)
    # the linear change of A over a revolution leaks into A_b: |A_b| = eps eta |A'| / 2
    # (first order), within the remainder and a second-order term
    leak = 0.5 * eps * r.eta * np.abs(a1)
    second = eps**2 * r.eta**2 * np.abs(a2)
    assert np.all(np.abs(np.abs(r.backward) - leak) <= remainder + second)


def test_rub_events_and_time_in_each_regime():
    tau = np.arange(100.0)
    eta = 1.0 + 0.01 * tau
    regimes = np.zeros(100, dtype=int)
    regimes[20:30], regimes[30:35], regimes[60:70] = 1, 2, -1
    x = np.where(regimes != 0, 1.1, 0.5)
    events = rub_events(tau, x, np.zeros(100), eta, regimes)
    assert events.transition_tau.tolist() == [19.5, 34.5, 59.5, 69.5]
    assert events.transition_on.tolist() == [True, False, True, False]
    assert events.onset_eta == pytest.approx(1.195)
    assert events.end_eta == pytest.approx(1.695)
    assert not events.contact_at_start and not events.contact_at_end
    times = time_in_regimes(tau, regimes)
    assert times == {"free": 74.0, "slip+": 10.0, "slip-": 10.0, "stick": 5.0}
    # in contact at the start and at the end: onset at the first sample, no end
    events = rub_events(tau, x, np.zeros(100), eta, np.roll(regimes, -25))
    assert events.contact_at_start and events.onset_tau == 0.0
    assert events.end_eta is None and events.contact_at_end


def test_summary_of_a_run_up_through_the_clearance():
    """The free whirl run-up crosses z = 1 on both sides of its peak: contact from z > 1."""
    tau, eta, phase, w = run_up()
    revolutions, events, summary = analyse_transient(tau, w.real, w.imag, phase, eta)
    radius = np.abs(free_whirl(eta)[0])
    inside = np.flatnonzero(radius > 1.0)
    assert summary.rub_onset_eta == pytest.approx(eta[inside[0]], abs=0.02)
    assert summary.rub_end_eta == pytest.approx(eta[inside[-1]], abs=0.02)
    assert summary.rub_transitions == 2
    step = 2.0 * math.pi * 2e-3 / 1.0  # speed change over one revolution near eta = 1
    assert summary.peak_forward_eta == pytest.approx(eta[np.argmax(radius)], abs=step)
    k = int(np.argmax(np.abs(revolutions.forward)))
    v, n = revolutions.eta[k], revolutions.stop[k] - revolutions.start[k]
    exact, a1, a2 = free_whirl(v)
    eps = 2e-3 / v**2  # the bound of test_run_up_bias_within_the_derived_bound
    bound = eps**2 * abs(
        math.pi**2 / 6 * v**2 * a2 + 1.25 * v * a1
    ) + 2 * math.pi / n * eps * v * abs(a1)
    assert abs(summary.peak_forward_amplitude - abs(exact)) <= bound
    duration = tau[-1] - tau[0]
    assert sum(summary.time_in_regime.values()) == pytest.approx(duration)
    assert set(summary.time_in_regime) == {"free", "contact"}
    report = summary.to_dict(rpm_per_eta=1000.0)
    assert report["rub_onset_rpm"] == pytest.approx(1000.0 * summary.rub_onset_eta)
    assert 0.0 < revolutions.contact_fraction.max() <= 1.0


def test_cascade_keeps_locked_lines_on_their_orders_under_a_changing_speed():
    tau = np.arange(0.0, 500.0, 0.02)  # eta = 0.5 + 2e-3 tau
    phase = 0.5 * tau + 1e-3 * tau**2
    w = 0.8 * np.exp(1j * phase) + 0.2 * np.exp(2j * phase) + 0.1 * np.exp(-1j * phase)
    c = order_cascade(tau, w.real, w.imag, phase)
    assert c.amplitude.shape == (c.eta.size, 8 * 64)
    assert np.all(np.diff(c.eta) > 0) and 0.5 < c.eta[0] < c.eta[-1] < 1.5
    assert np.all(c.order[np.argmax(c.amplitude, axis=1)] == 1.0)
    for order, amplitude in ((1.0, 0.8), (2.0, 0.2), (-1.0, 0.1)):
        k = int(np.flatnonzero(c.order == order)[0])
        assert np.allclose(c.amplitude[:, k], amplitude, rtol=1e-6)


def test_cascade_needs_a_whole_window():
    tau = np.arange(0.0, 20.0, 0.02)
    with pytest.raises(ValueError, match="fewer than 8 revolutions"):
        order_cascade(tau, np.cos(tau), np.sin(tau), tau)


def test_snapshots_pick_resonance_rub_onset_and_largest_z():
    tau, eta, phase, w = run_up()
    r = order_track(tau, w.real, w.imag, phase, eta)
    picks = transient.snapshot_revolutions(r)
    reasons = " | ".join(reason for _, reason in picks)
    assert "rub onset" in reasons and "peak 1X" in reasons and "largest z" in reasons
    assert [k for k, _ in picks] == sorted({k for k, _ in picks})
    asked = transient.snapshot_revolutions(r, speeds=[0.7, 1.2])
    assert [abs(r.eta[k] - v) < 0.01 for (k, _), v in zip(asked, [0.7, 1.2], strict=True)]


@pytest.mark.slow
@pytest.mark.parametrize("speed_unit", ["eta", "rpm"])
def test_figures_render_with_their_labels(tmp_path, speed_unit):
    tau, eta, phase, w = run_up()
    revolutions, events, _ = analyse_transient(tau, w.real, w.imag, phase, eta)
    cascade = order_cascade(tau, w.real, w.imag, phase)
    params = model.ModelParams(nu=NU, eta=1.0, e=E, K=5.0, mu=0.1, Rp=0.5)
    rpm = 3000.0 if speed_unit == "rpm" else None
    label = transient.RPM_LABEL if rpm else transient.ETA_LABEL
    unit = {"speed_unit": speed_unit, "rpm_per_eta": rpm, "title": "synthetic"}
    figures = {
        "bode": transient.bode_figure(revolutions, events, **unit),
        "polar": transient.polar_figure(revolutions, **unit),
        "cascade": transient.cascade_figure(cascade, params=params, **unit),
        "orbits": transient.orbit_snapshots_figure(tau, w.real, w.imag, revolutions, **unit),
    }
    for name, fig in figures.items():
        path = save_figure(fig, tmp_path / f"{name}.png")
        assert path.stat().st_size > 10_000
        assert fig._suptitle.get_text().startswith("synthetic")
    bode_axes = figures["bode"].axes
    assert [ax.get_xlabel() for ax in bode_axes[-2:]] == [label, label]
    assert bode_axes[4].get_ylabel() == "1X phase lag (degrees)"
    legend = [t.get_text() for t in figures["bode"].legends[0].get_texts()]
    assert any(t.startswith("rub onset") for t in legend)
    assert any(t.startswith("rub ends") for t in legend)
    line = bode_axes[0].get_lines()[0]  # forward 1X against speed, in the chosen unit
    assert np.allclose(line.get_xdata(), revolutions.eta * (rpm or 1.0))
    cascade_ax = figures["cascade"].axes[0]
    assert cascade_ax.get_xlabel() == label
    assert "order" in cascade_ax.get_ylabel()
    names = [t.get_text() for t in cascade_ax.get_legend().get_texts()]
    assert any("dry whip" in t for t in names) and any("free whirl" in t for t in names)
    assert {t.get_text() for t in cascade_ax.texts} >= {"1X", "2X", "1/2X", "-1X"}
    assert figures["polar"].axes[2].get_ylabel() == label  # the colour bar
    orbit_axes = [ax for ax in figures["orbits"].axes if ax.axison]
    assert len({ax.get_xlim() for ax in orbit_axes}) == 1  # common axes
    assert all(ax.get_aspect() == 1.0 for ax in orbit_axes)


def test_dry_whip_order_is_minus_rp_over_the_rolling_radius():
    params = model.ModelParams(nu=NU, eta=1.0, e=E, K=17.6, mu=0.3, Rp=46.16)
    r = model.rolling_whirl_radius(params)
    assert transient.dry_whip_order(params, [1.0])[0] == pytest.approx(-46.16 / r)
    # the rolling condition (1 + K) r^2 - K r - (Rp eta)^2 = 0
    assert (1 + 17.6) * r * r - 17.6 * r - 46.16**2 == pytest.approx(0.0, abs=1e-9)


def test_speed_axis_rejects_rpm_without_a_factor():
    with pytest.raises(ValueError, match="rpm_per_eta"):
        transient.speed_axis("rpm")

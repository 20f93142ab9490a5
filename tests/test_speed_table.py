"""Bearings whose coefficients change with the speed (``machine.SpeedTable``), as the
system runs them: the right-hand side against the equation written out with numpy, the
energy balance through a run-up with contact, the reduction that keeps them, and a slow
run-up converging to the steady linear response at first order in its rate.
(The Jacobian with a table: tests/test_composed_machine.py; the table against ROSS's own
coefficients and the shipped run-up: tests/test_ross.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rubcli.analysis.response import order_tracking as ot
from rubcli.machine import ContactLaw, Machine, Speed, SpeedTable, Station, Structure, Unbalance
from rubcli.machine.linear import eigenvalues, steady_response
from rubcli.machine.reduction import reduce_machine
from rubcli.system import energy_residual, simulate


def _table(coordinates=(2, 3)) -> SpeedTable:
    """Direct stiffness rising with the speed, damping falling, a cross-coupling."""
    speeds = np.array([0.0, 1.0, 2.5])
    K = np.array([[[1.0, 0.0], [0.0, 1.2]], [[1.4, 0.1], [-0.1, 1.6]], [[2.0, 0.25], [-0.25, 2.2]]])
    C = np.array([[[0.3, 0.0], [0.0, 0.3]], [[0.2, 0.0], [0.0, 0.25]], [[0.1, 0.02], [0.0, 0.15]]])
    return SpeedTable(coordinates, speeds, K, C)


def _two_nodes(
    table: SpeedTable | None, speed: Speed, clearance: float = 100.0, damping: float = 0.05
) -> Machine:
    """Two nodes (x, y each) joined by a shaft spring, the first carrying the unbalance
    and a station, the second on the bearing of ``table``."""
    shaft = np.array([[1.0, -1.0], [-1.0, 1.0]])
    K = np.kron(shaft, np.eye(2))
    M = np.diag([1.0, 1.0, 0.5, 0.5])
    C = damping * np.eye(4)
    G = 0.02 * np.kron(np.eye(2), np.array([[0.0, 1.0], [-1.0, 0.0]]))
    structure = Structure(M=M, K=K, C=C, G=G, speed_table=table)
    station = Station((0, 1), clearance, ContactLaw(40.0, damping=0.1), 0.1, 0.5)
    return Machine(structure, (station,), speed, (Unbalance((0, 1), 0.02, 0.3),))


def test_the_table_is_interpolated_linearly_and_held_beyond_its_speeds():
    table = _table()
    K, C = table.at(0.5)
    assert np.allclose(K, 0.5 * (table.K[0] + table.K[1]), rtol=0, atol=1e-15)
    assert np.allclose(C, 0.5 * (table.C[0] + table.C[1]), rtol=0, atol=1e-15)
    assert np.array_equal(table.at(-1.0)[0], table.K[0])
    assert np.array_equal(table.at(9.0)[1], table.C[-1])


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: SpeedTable((0, 0), [0.0], np.zeros((1, 2, 2)), np.zeros((1, 2, 2))), "distinct"),
        (
            lambda: SpeedTable((0, 1), [1.0, 0.0], np.zeros((2, 2, 2)), np.zeros((2, 2, 2))),
            "increase",
        ),
        (lambda: SpeedTable((0, 1), [0.0], np.zeros((2, 2, 2)), np.zeros((1, 2, 2))), "K must be"),
        (lambda: Structure(M=np.eye(2), K=np.eye(2), speed_table=_table((2, 3))), "outside"),
    ],  # fmt: skip
)
def test_a_bad_table_is_refused_naming_the_problem(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_the_system_adds_the_table_at_the_current_speed():
    """The derivative the compiled system gives, against ``M v' = f - K(Omega) q -
    (C(Omega) + Omega G) v + unbalance`` and the power of everything non-conservative
    (the table's whole force among it: ``SpeedTable``), written out with numpy."""
    from rubcli.system.arrays import SystemArrays
    from rubcli.system.kernels import evaluate

    machine = _two_nodes(_table(), Speed((0.0, 4.0), (0.4, 2.4)))
    arrays = SystemArrays.of(machine)
    ctx = arrays.context(np.zeros(1, dtype=np.int64))
    rng = np.random.default_rng(5)
    q, v = rng.normal(size=4), rng.normal(size=4)
    t = 1.5
    omega, rate, angle = 0.4 + 0.5 * t, 0.5, 0.4 * t + 0.25 * t * t
    out, vals = np.empty(9), np.empty((1, 4))
    evaluate(t, np.concatenate([q, v, [0.0]]), ctx, out, vals)
    st = machine.structure
    K, C = st.at_speed(omega)
    p = 0.3 + angle
    force = np.zeros(4)
    force[0] = 0.02 * (omega**2 * math.cos(p) + rate * math.sin(p))
    force[1] = 0.02 * (omega**2 * math.sin(p) - rate * math.cos(p))
    expected = np.linalg.solve(st.M, force - K @ q - (C + omega * st.G) @ v)
    assert np.allclose(out[:4], v, rtol=0, atol=0)
    assert np.allclose(out[4:8], expected, rtol=1e-13, atol=1e-13)
    # the power: unbalance, damping (C's own, G's is skew), and the table's whole force
    b = list(st.speed_table.coordinates)
    Kb, Cb = st.speed_table.at(omega)
    power = v @ force - v @ (0.5 * (st.C + st.C.T)) @ v - v[b] @ (Kb @ q[b] + Cb @ v[b])
    assert out[8] == pytest.approx(power, rel=1e-13, abs=1e-13)


def test_the_energy_balance_closes_through_a_runup_with_contact():
    machine = _two_nodes(_table(), Speed((0.0, 60.0), (0.3, 2.4)), clearance=0.08)
    t = np.linspace(0.0, 60.0, 3001)
    for method in ("dop853-jit", "radau"):
        solution = simulate(machine, t, method=method, rtol=1e-10, atol=1e-12)
        assert solution.success, solution.message
        assert np.count_nonzero(solution.regimes[:, 0]) > 0  # it rubs
        residual = energy_residual(solution)
        scale = np.max(np.abs(solution.work))
        assert np.max(np.abs(residual)) < 1e-7 * scale


def test_a_reduction_keeps_the_tables_coordinates_and_with_every_mode_is_the_full_model():
    machine = _two_nodes(_table((2, 3)), Speed((0.0, 10.0), (0.3, 2.4)))
    # the station's and unbalance's (0, 1) and the table's (2, 3): nothing is left to
    # reduce on four coordinates, so give the structure more
    n = 10
    rng = np.random.default_rng(2)
    A = rng.normal(size=(n, n))
    M = np.eye(n) + 0.05 * (A + A.T)
    K = 4.0 * np.eye(n) + 0.3 * (A @ A.T) / n
    structure = Structure(M=M, K=K, C=0.02 * K, G=0.01 * (A - A.T), speed_table=_table((6, 7)))
    machine = Machine(structure, machine.stations, machine.speed, machine.unbalances)
    reduced, reduction = reduce_machine(machine, modes=4)
    assert {6, 7} <= set(reduction.kept)
    table = reduced.structure.speed_table
    assert [reduction.kept[c] for c in table.coordinates] == [6, 7]
    whole, _ = reduce_machine(machine, modes=n - len(reduction.kept))
    for omega in (0.5, 2.0):
        full = eigenvalues(machine.structure, omega)
        again = eigenvalues(whole.structure, omega)
        assert np.allclose(np.sort_complex(again), np.sort_complex(full), rtol=1e-9, atol=1e-9)


def _tracking_error(rate: float) -> float:
    """The largest gap (a share of the largest linear 1X) between a run-up's tracked 1X
    at the first node's x and the steady linear response at each revolution's speed,
    the run started on the steady state at its first speed."""
    low, high = 0.4, 2.2
    end = (high - low) / rate
    machine = _two_nodes(_table(), Speed((0.0, end), (low, high)), damping=0.2)
    _, Q = steady_response(machine, low)
    initial = np.concatenate([Q.real, (1j * low * Q).real])
    t = np.linspace(0.0, end, int(end * high / (2 * math.pi) * 64))
    solution = simulate(machine, t, initial, rtol=1e-10, atol=1e-12)
    assert solution.success, solution.message
    omega, angle = machine.speed.at(t)
    phase = angle + 0.3  # the unbalance's
    rev = ot.order_track(t, solution.states[:, 0], np.zeros(t.size), phase, omega)
    tracked = rev.x_amplitude * np.exp(-1j * np.radians(rev.x_lag_deg))
    turn = np.exp(-0.3j)
    linear = np.array([turn * steady_response(machine, float(w))[1][0] for w in rev.eta])
    inside = (rev.eta > 0.6) & (rev.eta < 2.1)
    return float(np.max(np.abs(tracked - linear)[inside]) / np.max(np.abs(linear)))


def test_a_slow_runup_converges_to_the_linear_response_at_first_order_in_its_rate():
    """Through the resonance the response lags the steady state by a delay set by the
    damping, so the gap falls as the rate: observed order 1 between halved rates (the
    order tracking's own error is second order, ``order_tracking``)."""
    errors = [_tracking_error(rate) for rate in (2e-3, 1e-3, 5e-4)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:], strict=False)]
    assert errors[-1] < 0.03
    assert all(0.9 < p < 1.1 for p in orders), (errors, orders)

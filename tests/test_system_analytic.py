"""``analytic`` on a composed machine (rubcli/system/analytic.py): the exponential
integrator's functions, the free flight exact on a stiff structure at a cost its stiffness
does not set, contact against a tight reference, and what it refuses."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from scipy.integrate import quad
from typer.testing import CliRunner

from rubcli.case.rotor import load_rotor_case
from rubcli.cli.app import app
from rubcli.machine import ContactLaw, Machine, Speed, Station, Structure, Unbalance
from rubcli.system import energy_residual, simulate
from rubcli.system.analytic import INVERSE_FACTORIALS, modal_states

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


def _phi_by_quadrature(z: complex, k: int) -> complex:
    """phi_k(z) = integral_0^1 e^{(1 - u) z} u^{k-1} / (k-1)! du."""

    def part(u: float, which) -> float:
        return which(np.exp((1.0 - u) * z) * u ** (k - 1)) * INVERSE_FACTORIALS[k - 1]

    re = quad(part, 0.0, 1.0, args=(np.real,), epsabs=0.0, epsrel=1e-13, limit=200)[0]
    im = quad(part, 0.0, 1.0, args=(np.imag,), epsabs=0.0, epsrel=1e-13, limit=200)[0]
    return re + 1j * im


@pytest.mark.parametrize(
    "z", [1e-9, 0.3 + 0.4j, 0.999, 1.001, -1.2 + 3.0j, -40.0, -3e4 + 5e3j, 2.5 - 0.5j]
)
def test_the_step_functions_are_the_exponential_integrators(z):
    """One mode, w0 = 0, station forces c_k = 1: the change over s = 1 is
    sum_k k! phi_{k+1}(lambda), each phi against its integral."""
    lam = np.array([z], dtype=complex)
    c = np.ones((4, 1), dtype=complex)
    out = np.empty((1, 1), dtype=complex)
    modal_states(lam, np.zeros(1, complex), c, np.zeros(1, complex), np.zeros(1, complex),
                 0.0, 0.0, np.array([1.0]), out)  # fmt: skip
    expected = sum(math.factorial(k) * _phi_by_quadrature(z, k + 1) for k in range(4))
    assert abs(out[0, 0] - expected) <= 1e-12 * abs(expected)


def _chain(stiff: float) -> Structure:
    """Two nodes (x, y each): the rotor on a unit spring, a light node tied to it by a
    spring ``stiff`` (a finite-element model's stiff high mode), damped lightly."""
    M = np.diag([1.0, 1.0, 1e-2, 1e-2])
    K = np.zeros((4, 4))
    for a, b in ((0, 2), (1, 3)):
        K[a, a] += 1.0 + stiff
        K[b, b] += stiff
        K[a, b] = K[b, a] = -stiff
    C = 0.02 * np.eye(4) + 1e-4 * K / max(stiff, 1.0) ** 0.5
    G = np.zeros((4, 4))
    G[0, 1], G[1, 0] = 0.05, -0.05
    return Structure(M=M, K=K, C=C, G=G, static=np.array([0.0, -0.01, 0.0, 0.0]))


def _exact_free(structure: Structure, omega: float, me: float, phase: float, t, y0):
    """The free flight by the matrix exponential of the structure and a harmonic
    oscillator for the unbalance (``Re(me omega^2 e^{i(omega t + phase)})`` on x, its
    imaginary part on y), written here from the matrices."""
    n = structure.M.shape[0]
    Minv = np.linalg.inv(structure.M)
    size = 2 * n + 3
    A = np.zeros((size, size))
    A[:n, n : 2 * n] = np.eye(n)
    A[n : 2 * n, :n] = -Minv @ structure.K
    A[n : 2 * n, n : 2 * n] = -Minv @ (structure.C + omega * structure.G)
    force_cos = np.zeros(n)  # the force on (cos(omega t), sin(omega t))
    force_sin = np.zeros(n)
    amplitude = me * omega**2
    force_cos[0], force_sin[0] = amplitude * math.cos(phase), -amplitude * math.sin(phase)
    force_cos[1], force_sin[1] = amplitude * math.sin(phase), amplitude * math.cos(phase)
    A[n : 2 * n, 2 * n] = Minv @ force_cos
    A[n : 2 * n, 2 * n + 1] = Minv @ force_sin
    A[n : 2 * n, 2 * n + 2] = Minv @ structure.static
    A[2 * n, 2 * n + 1] = -omega  # (cos, sin)' = omega (-sin, cos)
    A[2 * n + 1, 2 * n] = omega
    start = np.concatenate([y0, [1.0, 0.0, 1.0]])
    return np.array([(scipy.linalg.expm(A * tk) @ start)[: 2 * n] for tk in t])


def _free_machine(stiff: float) -> Machine:
    return Machine(
        _chain(stiff),
        (Station((0, 1), 1.0, ContactLaw(10.0)),),  # never reached (the motion is < 0.6)
        Speed.constant(1.3),
        (Unbalance((0, 1), 0.05, 0.4),),
    )


Y0 = np.array([0.3, -0.1, 0.3, -0.1, 0.0, 0.2, 0.0, 0.2])  # the two nodes together


@pytest.mark.parametrize("stiff", [1e2, 1e5])
def test_free_flight_is_the_exact_flow(stiff):
    machine = _free_machine(stiff)
    t = np.linspace(0.0, 30.0, 61)
    solution = simulate(machine, t, initial=Y0, method="analytic", rtol=1e-8, atol=1e-12)
    assert solution.success, solution.message
    exact = _exact_free(machine.structure, 1.3, 0.05, 0.4, t, Y0)
    assert np.max(np.abs(solution.states - exact)) < 1e-9 * np.max(np.abs(exact))
    # the work counts the resolved motion: the stiff mode, which the start excites about
    # 1e-9 clearances deep (below rtol: not resolved), dissipates about 1e-8 unseen
    assert np.max(np.abs(energy_residual(solution))) < (1e-9 if stiff < 1e3 else 3e-8)


def test_free_flight_costs_what_its_slow_motion_does_however_stiff_the_structure():
    """The stiffer the tie, the less the start and the unbalance excite its mode (their
    deflection of it falls as 1 / stiffness), so the fewer steps resolve it: the steps
    fall as the stiffness grows, where dop853-jit's stability bounds its step by the stiff
    mode. Against the matrix exponential to 1e-6 only: scaling and squaring ``A t`` of
    norm 3e11 rounds at about that, and so does the eigenbasis of a structure this stiff
    (its condition grows with the stiffness ratio)."""
    t = np.linspace(0.0, 30.0, 61)
    steps = []
    for stiff in (1e6, 1e8):
        machine = _free_machine(stiff)
        solution = simulate(machine, t, initial=Y0, method="analytic", rtol=1e-8, atol=1e-12)
        assert solution.success, solution.message
        exact = _exact_free(machine.structure, 1.3, 0.05, 0.4, t, Y0)
        assert np.max(np.abs(solution.states - exact)) < 1e-6
        steps.append(solution.stats["steps"])
    assert steps[1] < steps[0]
    window = t[:3]
    explicit = simulate(_free_machine(1e6), window, initial=Y0, method="dop853-jit", rtol=1e-8,
                        atol=1e-12)  # fmt: skip
    assert explicit.stats["steps"] > 10 * steps[0] * (window[-1] / t[-1])


def test_a_stiff_mode_excited_is_resolved_only_while_it_moves_the_station():
    """Started with the light node displaced, the stiff mode rings and decays; the steps
    resolve it at first, then grow back to the slow motion's."""
    machine = _free_machine(1e5)
    t = np.linspace(0.0, 30.0, 61)
    y0 = Y0.copy()
    y0[2] += 1e-3
    solution = simulate(machine, t, initial=y0, method="analytic", rtol=1e-8, atol=1e-12)
    assert solution.success, solution.message
    exact = _exact_free(machine.structure, 1.3, 0.05, 0.4, t, y0)
    assert np.max(np.abs(solution.states - exact)) < 1e-9 * np.max(np.abs(exact))
    calm = simulate(machine, t, initial=Y0, method="analytic", rtol=1e-8, atol=1e-12)
    # resolved over the whole run, the stiff mode would take 8 steps a period
    rate = (
        np.max(np.abs(np.linalg.eigvals(np.linalg.solve(machine.structure.M, machine.structure.K))))
        ** 0.5
    )
    throughout = 8 * t[-1] * rate / (2 * np.pi)  # fmt: skip
    assert calm.stats["steps"] + 20 < solution.stats["steps"] < 0.5 * throughout
    assert np.max(np.abs(energy_residual(solution))) < 1e-9


def test_a_matrices_case_with_two_seals_agrees_with_a_tight_reference():
    """The shipped two-seals beam (24 coordinates, two stations, one offset and damped):
    the same events, the stations within their tolerance's share of the clearance, the
    energy balance closed; the error falls with the tolerance."""
    case = load_rotor_case(ROOT / "cases" / "machines" / "two-seals.toml")
    t = case.t_eval[case.t_eval <= 0.12]
    reference = simulate(case.machine, t, method="dop853-jit", rtol=1e-12, atol=1e-18)
    assert reference.success and len(reference.events) > 10
    errors = []
    for rtol in (1e-5, 1e-8):
        solution = simulate(
            case.machine, t, method="analytic", rtol=rtol, atol=1e-2 * rtol * 1.5e-5
        )
        assert solution.success, solution.message
        assert solution.events.kinds() == reference.events.kinds()
        error = max(
            np.max(np.hypot(*(solution.states[:, st.rotor] - reference.states[:, st.rotor]).T))
            / st.clearance
            for st in case.machine.stations
        )
        assert error < 10 * rtol
        assert np.max(np.abs(energy_residual(solution))) < 1e-9
        errors.append(error)
    assert errors[1] < errors[0] / 30


def test_analytic_refuses_what_it_cannot_run():
    ramp = Machine(_chain(1.0), (Station((0, 1), 1.0, ContactLaw(10.0)),),
                   Speed((0.0, 10.0), (1.0, 2.0)))  # fmt: skip
    with pytest.raises(ValueError, match="analytic needs a constant speed"):
        simulate(ramp, np.linspace(0.0, 1.0, 3), method="analytic")
    # critically damped: a double, defective eigenvalue has no eigenbasis
    defective = Machine(
        Structure(M=np.eye(2), K=np.eye(2), C=2.0 * np.eye(2)),
        (Station((0, 1), 1.0, ContactLaw(10.0)),),
        Speed.constant(1.0),
    )
    solution = simulate(defective, np.linspace(0.0, 1.0, 3), initial=[0.1, 0, 0, 0],
                        method="analytic")  # fmt: skip
    assert not solution.success and "ill-conditioned" in solution.message


def test_a_runup_case_refuses_analytic_naming_the_field(tmp_path):
    source = (ROOT / "cases" / "machines" / "two-seals.toml").read_text()
    text = (
        source.replace("speed = 2500.0                 # rpm\n", "")
        .replace(
            "[time]",
            '[speed]\nprofile = "ramp"\nfrom = 1000.0\nto = 2000.0\nrate = 4000.0\n\n'
            "[[probe]]\nnode = 2\nangle = 0.0\n\n[time]",
        )
        .replace('methods = ["dop853-jit"]', 'methods = ["analytic"]')
    )
    for name in ("beam.npz",):
        (tmp_path / name).write_bytes((ROOT / "cases" / "machines" / name).read_bytes())
    path = tmp_path / "case.toml"
    path.write_text(text)
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    said = " ".join(result.output.split())
    assert "solver.methods" in said and "analytic" in said and "constant speed" in said
    assert "Traceback" not in result.output

"""The Craig-Bampton reduction (rubcli/machine/reduction.py, ``[rotor] modes``): exact when
every interior mode is kept, statically exact at the kept coordinates (and under the
weight, through its static vector), its lowest eigenvalues converging to the full model's
from above as modes are added, and the case's checks. On the shipped beam rotor
(cases/machines/beam.npz: 24 coordinates); the ROSS rotor's time response against the full
model is in test_ross."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli.case.rotor import load_rotor_case
from rubcli.cli.app import app
from rubcli.machine import Machine, Structure, linear
from rubcli.machine.reduction import craig_bampton, kept_coordinates, reduce_machine
from rubcli.system import simulate

REPO = Path(__file__).resolve().parents[1]
CASE = REPO / "cases" / "machines" / "two-seals.toml"
runner = CliRunner()


@pytest.fixture(scope="module")
def beam() -> Machine:
    return load_rotor_case(CASE).machine


def _undamped(structure: Structure) -> Structure:
    return Structure(M=structure.M, K=structure.K, dof_per_node=structure.dof_per_node)


def _frequencies(structure: Structure) -> np.ndarray:
    """The undamped natural frequencies (rad/s), ascending."""
    return np.sort(np.abs(linear.eigenvalues(_undamped(structure), 0.0).imag))


def test_every_interior_mode_kept_is_the_full_model(beam):
    speed = beam.speed.values[0]
    kept = kept_coordinates(beam)  # the two stations' pairs (the unbalance is at one)
    assert kept == (*beam.stations[0].rotor, *beam.stations[1].rotor)
    reduced, reduction = reduce_machine(beam, beam.size - len(kept))
    assert reduced.size == beam.size
    full = linear.eigenvalues(beam.structure, speed)
    np.testing.assert_allclose(linear.eigenvalues(reduced.structure, speed), full, rtol=1e-9)
    t = np.linspace(0.0, 0.05, 101)
    a = simulate(beam, t, rtol=1e-10, atol=1e-14)
    b = simulate(reduced, t, rtol=1e-10, atol=1e-14)
    assert a.events.kinds() == b.events.kinds() and len(a.events) > 0
    positions = reduction.full_positions(b.states[:, : reduced.size])
    clearance = beam.stations[0].clearance
    assert np.max(np.abs(positions - a.states[:, : beam.size])) < 1e-6 * clearance


def test_forces_at_the_kept_coordinates_are_statically_exact(beam):
    structure = beam.structure
    kept = (*beam.stations[0].rotor, *beam.stations[1].rotor)
    reduced, reduction = craig_bampton(structure, kept, 2)
    force = np.zeros(structure.size)
    force[list(kept)] = [3.0, -1.0, 0.5, 2.0]
    full = np.linalg.solve(structure.K, force)
    mine = reduction.full_positions(np.linalg.solve(reduced.K, reduction.basis.T @ force))
    np.testing.assert_allclose(mine, full, rtol=1e-9, atol=1e-12 * np.max(np.abs(full)))


def test_the_weight_is_statically_exact_through_its_vector(beam):
    structure = beam.structure
    weight = linear.gravity_load(structure.M, structure.lateral_pairs(), (0.0, -9.81))
    heavy = Structure(M=structure.M, K=structure.K, static=weight, dof_per_node=4)
    kept = beam.stations[0].rotor
    reduced, reduction = craig_bampton(heavy, kept, 2)
    assert reduction.static_vectors == 1 and reduced.size == 2 + 2 + 1
    full = np.linalg.solve(heavy.K, weight)
    mine = reduction.full_positions(np.linalg.solve(reduced.K, reduced.static))
    np.testing.assert_allclose(mine, full, rtol=1e-9, atol=1e-12 * np.max(np.abs(full)))
    # without its vector the sag is not exact: the vector is what makes it so
    _, bare = craig_bampton(Structure(M=structure.M, K=structure.K, dof_per_node=4), kept, 2)
    T = bare.basis
    sag = bare.full_positions(np.linalg.solve(T.T @ heavy.K @ T, T.T @ weight))
    assert np.max(np.abs(sag - full)) > 1e-4 * np.max(np.abs(full))


def test_the_lowest_frequencies_converge_from_above_as_modes_are_added(beam):
    full = _frequencies(beam.structure)[:4]
    errors = []
    for modes in (2, 4, 8, 12):
        reduced, _ = reduce_machine(beam, modes)
        mine = _frequencies(reduced.structure)[:4]
        assert np.all(mine >= full * (1.0 - 1e-12))  # a Rayleigh-Ritz bound
        errors.append(np.max((mine - full) / full))
    assert all(b < a for a, b in zip(errors, errors[1:], strict=False))
    assert errors[-1] < 2e-4  # 9e-5 with 12 of the 20 interior modes


@pytest.mark.parametrize(
    ("modes", "message"),
    [(0, "modes must be an int >= 1"), (21, "modes = 21 is more than the 20 coordinates"),
     (2.5, "modes must be an int >= 1"), (True, "modes must be an int >= 1")],
)  # fmt: skip
def test_reduce_machine_refuses_what_it_cannot_reduce(beam, modes, message):
    with pytest.raises(ValueError, match=message):
        reduce_machine(beam, modes)


def test_an_unsupported_interior_is_refused():
    """A station's node on its own spring, and two nodes joined to each other but to
    nothing else: with the station held, the pair can still move as one."""
    pair = np.kron([[1.0, -1.0], [-1.0, 1.0]], np.eye(2))
    K = np.zeros((6, 6))
    K[:2, :2] = np.eye(2)
    K[2:, 2:] = pair
    with pytest.raises(ValueError, match="interior stiffness is singular"):
        craig_bampton(Structure(M=np.eye(6), K=K), (0, 1), 1)
    K[2:4, 2:4] += np.eye(2)  # the pair grounded: supported
    craig_bampton(Structure(M=np.eye(6), K=K), (0, 1), 1)


@pytest.fixture
def case_dir(tmp_path):
    for name in ("two-seals.toml", "beam.npz"):
        shutil.copy(REPO / "cases" / "machines" / name, tmp_path / name)
    return tmp_path


def _with_modes(case_dir: Path, line: str) -> Path:
    path = case_dir / "two-seals.toml"
    path.write_text(path.read_text().replace("speed = 2500.0", f"speed = 2500.0\n{line}"))
    return path


def test_a_reduced_case_runs_and_says_so(case_dir):
    path = _with_modes(case_dir, "modes = 8")
    case = load_rotor_case(path)
    assert case.machine.size == 4 + 8 and case.full_machine.size == 24
    done = runner.invoke(app, ["validate", str(path)])
    assert done.exit_code == 0 and "reduced   12 coordinates (Craig-Bampton)" in done.output
    out = case_dir / "out"
    done = runner.invoke(app, ["run", str(path), "--out", str(out)])
    assert done.exit_code == 0, done.output
    import json

    report = json.loads((out / "report.json").read_text())
    assert report["machine"]["coordinates"] == 12 and report["machine"]["full_coordinates"] == 24
    assert report["machine"]["reduction"] == {
        "method": "craig-bampton", "kept_coordinates": 4, "modes": 8, "static_vectors": 0
    }  # fmt: skip
    # the stations' columns are their physical coordinates: the full model's to within the
    # reduction's error (8 of 20 interior modes, far above the run's frequencies)
    full = simulate(case.full_machine, case.t_eval, rtol=1e-10, atol=1e-14)
    header = (out / "dop853-jit.csv").read_text().splitlines()
    columns = header[0].split(",")
    last = dict(zip(columns, header[-1].split(","), strict=True))
    ix, iy = case.full_machine.structure.lateral(2)
    clearance = case.machine.stations[0].clearance
    assert math.isclose(float(last["x_2"]), full.states[-1, ix], abs_tol=1e-3 * clearance)
    assert math.isclose(float(last["y_2"]), full.states[-1, iy], abs_tol=1e-3 * clearance)


@pytest.mark.parametrize(
    ("line", "message"),
    [("modes = 40", "rotor.modes: reduction: modes = 40 is more than the 20 coordinates"),
     ("modes = -1", "rotor.modes"), ('modes = "six"', "rotor.modes")],
)  # fmt: skip
def test_a_bad_modes_is_refused_naming_it(case_dir, line, message):
    path = _with_modes(case_dir, line)
    done = runner.invoke(app, ["validate", str(path)])
    assert done.exit_code == 2, done.output
    assert message in " ".join(done.output.split())
    assert "Traceback" not in done.output

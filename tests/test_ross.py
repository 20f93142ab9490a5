"""ROSS rotors (rubcli/machine/ross.py, [rotor] ross in a case, rubcli export-matrices):
the structure rubcli builds against ROSS's own linear analyses on the same rotor, the
lateral coordinates' exactness, and the refusals of a rotor file that cannot be used.

The rotor is ROSS's example with damping (cases/rotors/ross_example.toml). These tests
need ROSS (the test extra installs it: ROSS 2.3 on Python 3.11-3.12, ROSS 3 on 3.13+)."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from rubcli.case.rotor import assemble_rotor_case, load_rotor_case
from rubcli.cli.app import app
from rubcli.machine import ContactLaw, linear
from rubcli.machine.ross import (
    NodeStation,
    RossError,
    import_ross,
    lateral_coordinates,
    load_ross_rotor,
    outer_radii,
    ross_machine,
    ross_matrices,
    ross_structure,
    shaft_layout,
)
from rubcli.model import FREE
from rubcli.system import simulate

REPO = Path(__file__).resolve().parents[1]
ROTOR_FILE = REPO / "cases" / "rotors" / "ross_example.toml"
SPEED = 1200.0 * 2.0 * math.pi / 60.0  # rad/s: ROSS's rub example
NODE = 12  # the disk, where ROSS's example rubs
runner = CliRunner()

try:
    import_ross()
except RossError:
    pytest.skip("ROSS is not installed (pip install -e '.[ross]')", allow_module_level=True)


@pytest.fixture(scope="module")
def rotor():
    return load_ross_rotor(ROTOR_FILE)


def test_eigenvalues_are_ross_run_modal(rotor):
    # the full model (all 6 coordinates a node) against ROSS's own modal analysis
    full = ross_matrices(rotor, SPEED)
    from rubcli.machine import Structure

    structure = Structure(full["M"], full["K"], full["C"], full["G"], dof_per_node=6)
    ours = linear.eigenvalues(structure, SPEED)
    ours = np.concatenate([ours, ours.conj()])
    # every mode (ROSS's dense eigensolver: its sparse one is converged to about 1e-7 only)
    modal = rotor.run_modal(SPEED, num_modes=2 * structure.size, sparse=False)
    theirs = np.asarray(modal.evalues)
    assert theirs.size >= structure.size
    # relative to each eigenvalue, and to the spectrum's scale for the near-defective
    # overdamped rigid-body pair of the axial and torsional coordinates (no supports)
    distance = np.array([np.min(np.abs(ours - v)) for v in theirs])
    assert np.all(distance < 1e-8 * np.abs(theirs) + 1e-10 * np.max(np.abs(ours)))


def test_the_lateral_model_is_exact(rotor):
    # eig(full) = eig(lateral) + eig(axial and torsional): the dropped block is uncoupled
    full = ross_matrices(rotor, SPEED)
    keep, per_node, _ = lateral_coordinates(full)
    assert per_node == 4 and keep.size == 4 * len(rotor.nodes)
    other = np.setdiff1d(np.arange(full["M"].shape[0]), keep)

    def eig(idx):
        n = idx.size
        M, K = full["M"][np.ix_(idx, idx)], full["K"][np.ix_(idx, idx)]
        D = full["C"][np.ix_(idx, idx)] + SPEED * full["G"][np.ix_(idx, idx)]
        A = np.block(
            [[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]]
        )
        return np.linalg.eigvals(A)

    whole = eig(np.arange(full["M"].shape[0]))
    parts = np.concatenate([eig(keep), eig(other)])
    scale = np.max(np.abs(whole))
    assert whole.size == parts.size
    # each eigenvalue of the whole found among the parts' (to the eigensolver's round-off)
    assert np.max([np.min(np.abs(parts - v)) for v in whole]) < 1e-9 * scale
    structure = ross_structure(rotor, SPEED)
    np.testing.assert_array_equal(structure.M, full["M"][np.ix_(keep, keep)])


RING_FILE = REPO / "cases" / "rotors" / "ross_ring.toml"


def test_a_support_node_keeps_its_own_coordinates():
    """A rotor with a support node (the snubber ring of ross_ring.toml, ROSS's node 34:
    3 coordinates after the shaft's): the lateral model keeps the ring's x and y, maps
    node 34 to them, is exact (the dropped z's and the shaft's axial and torsional
    coordinates are uncoupled: eig(full) = eig(lateral) + eig(rest)), its eigenvalues
    are among ROSS's own run_modal's, and the weight loads the ring too."""
    rotor = load_ross_rotor(RING_FILE)
    assert rotor.ndof == 6 * 34 + 3
    full = ross_matrices(rotor, SPEED)
    keep, per_node, node_xy = lateral_coordinates(full, len(rotor.nodes))
    assert per_node == 4 and keep.size == 4 * 34 + 2
    assert list(keep[node_xy[34]]) == [204, 205] and list(keep[node_xy[18]]) == [108, 109]
    structure = ross_structure(rotor, SPEED, gravity=(0.0, -9.81))
    assert structure.nodes == 35 and structure.lateral(34) == (136, 137)
    ours = linear.eigenvalues(structure, SPEED)
    ours = np.concatenate([ours, ours.conj()])
    modal = rotor.run_modal(SPEED, num_modes=2 * full["M"].shape[0], sparse=False)
    theirs = np.asarray(modal.evalues)
    # each of ours is one of ROSS's (the full model has the axial and torsional ones too)
    distance = np.array([np.min(np.abs(theirs - v)) for v in ours])
    assert np.all(distance < 1e-8 * np.abs(ours) + 1e-10 * np.max(np.abs(theirs)))
    mass = sum(float(e.m) for e in rotor.shaft_elements) + sum(
        float(d.m) for d in rotor.disk_elements
    ) + sum(float(p.m) for p in rotor.point_mass_elements)  # fmt: skip
    fy = structure.static[structure.lateral_pairs()[:, 1]].sum()
    assert fy == pytest.approx(-9.81 * mass, rel=1e-9)
    layout = shaft_layout(rotor)  # the ring's node is off the shaft; its zero link no bearing
    assert layout["node_position"].size == 35 and np.isnan(layout["node_position"][34])
    assert list(layout["bearing_nodes"]) == [4, 31]


def test_the_shipped_ring_file_is_what_its_script_makes():
    script = {}
    exec(compile((RING_FILE.parent / "make_ross_ring.py").read_text(), "make", "exec"), script)
    shipped = ross_matrices(load_ross_rotor(RING_FILE), SPEED)
    if not import_ross().__version__.startswith("2.3"):  # ROSS 3's example differs from 2.3's
        assert shipped["M"].shape == (207, 207)
        return
    made = ross_matrices(script["ring_rotor"](import_ross()), SPEED)
    for name in shipped:
        np.testing.assert_allclose(shipped[name], made[name], rtol=1e-12, atol=0)


def test_a_support_node_travels_with_the_exported_matrices(tmp_path):
    npz = tmp_path / "ring.npz"
    (tmp_path / "rotor.toml").write_bytes(RING_FILE.read_bytes())
    result = runner.invoke(
        app, ["export-matrices", str(tmp_path / "rotor.toml"), "--speed", "1200", "--out", str(npz)]
    )
    assert result.exit_code == 0, result.output
    ring = "\n[[station]]\nnode = 18\nstator_node = 34\nclearance = 6e-5\n"
    ring += "contact_stiffness = 2e6\nradius = 0.0095\n"
    built = []
    for rotor in ("ross = 'rotor.toml'", "matrices = 'ring.npz'"):
        path = _case(tmp_path, rotor, "gravity = [0.0, -9.81]")
        path.write_text(path.read_text().replace("[time]", ring + "[time]"))
        built.append(load_rotor_case(path))
    a, b = (case.machine.structure for case in built)
    for name in ("M", "K", "C", "G", "static"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.lateral(34) == b.lateral(34) == (136, 137)
    assert built[1].machine.stations[1].stator == (136, 137)


def test_unbalance_response_is_ross_run_unbalance_response(rotor):
    machine = ross_machine(
        rotor, SPEED, [NodeStation(12, 1.0, ContactLaw(1e6))], [(12, 5e-4, -math.pi / 2)]
    )
    static, amplitudes = linear.steady_response(machine)
    assert not np.any(static)
    # ROSS 2.3 names the speeds `frequency`, ROSS 3 `speed_range`
    ross = import_ross()
    speeds = "frequency" if ross.__version__.startswith("2.") else "speed_range"
    response = rotor.run_unbalance_response(12, 5e-4, -math.pi / 2, **{speeds: np.array([SPEED])})
    keep, _, _ = lateral_coordinates(ross_matrices(rotor, SPEED))
    theirs = np.asarray(response.forced_resp)[keep, 0]
    assert np.max(np.abs(theirs - amplitudes)) < 1e-8 * np.max(np.abs(theirs))


def test_outer_radius_and_gravity(rotor):
    radii = outer_radii(rotor)
    assert radii.shape == (len(rotor.nodes),) and radii[12] == pytest.approx(0.019 / 2)
    structure = ross_structure(rotor, SPEED, gravity=(0.0, -9.81))
    # the weight: the static force sums to the rotor's mass times g along y
    mass = sum(float(e.m) for e in rotor.shaft_elements) + sum(
        float(d.m) for d in rotor.disk_elements
    )
    fy = structure.static[1 :: structure.dof_per_node].sum()
    fx = structure.static[0 :: structure.dof_per_node].sum()
    assert fy == pytest.approx(-9.81 * mass, rel=1e-9) and abs(fx) < 1e-12


def _case(tmp_path: Path, rotor: str = "ross = 'rotor.toml'", extra: str = "") -> Path:
    if "rotor.toml" in rotor and not (tmp_path / "rotor.toml").exists():
        (tmp_path / "rotor.toml").write_bytes(ROTOR_FILE.read_bytes())
    path = tmp_path / "case.toml"
    path.write_text(
        f"""
[case]
name = "r"
[rotor]
{rotor}
speed = 1200.0
{extra}
[[unbalance]]
node = 12
magnitude = 5e-4
[[station]]
node = 12
clearance = 7.95e-5
contact_stiffness = 1.1e6
mu = 0.3
[time]
end = 0.01
"""
    )
    return path


def test_a_shape_after_the_runs_end_is_refused_naming_it(tmp_path):
    path = _case(tmp_path)
    path.write_text(path.read_text() + "[output]\nshapes = [0.005, 0.02]\n")
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    assert "output.shapes: 0.02 s is after the run's end (0.01 s)" in text, result.output


def test_a_ross_case_and_its_exported_matrices_are_the_same_machine(tmp_path):
    case = load_rotor_case(_case(tmp_path, extra="gravity = [0.0, -9.81]"))
    assert case.machine.size == 136 and case.machine.stations[0].radius == pytest.approx(0.0095)
    npz = tmp_path / "rotor.npz"
    result = runner.invoke(
        app, ["export-matrices", str(tmp_path / "rotor.toml"), "--speed", "1200", "--out", str(npz)]
    )
    assert result.exit_code == 0, result.output
    other = load_rotor_case(_case(tmp_path, "matrices = 'rotor.npz'", "gravity = [0.0, -9.81]"))
    for name in ("M", "K", "C", "G", "static"):
        np.testing.assert_array_equal(
            getattr(other.machine.structure, name), getattr(case.machine.structure, name)
        )
    assert other.machine.stations[0].radius == case.machine.stations[0].radius
    with np.load(npz) as arrays:
        assert float(arrays["speed_rpm"]) == pytest.approx(1200.0)
        assert list(arrays["disk_nodes"]) == [12, 24] and list(arrays["bearing_nodes"]) == [4, 31]
    # the shaft's layout travels with the matrices
    np.testing.assert_array_equal(other.layout.positions, case.layout.positions)
    assert other.layout.disks == case.layout.disks == (12, 24)
    assert case.layout.positions[0] == 0.0 and np.all(np.diff(case.layout.positions) > 0)
    # an existing file is kept unless --force
    again = runner.invoke(
        app, ["export-matrices", str(tmp_path / "rotor.toml"), "--speed", "1200", "--out", str(npz)]
    )
    assert again.exit_code == 2 and "--force" in again.output


# the shipped ROSS cases at a constant speed (a run-up's: tests/test_ross_runup.py)
ROSS_CASES = sorted(
    p
    for p in (REPO / "cases").rglob("*.toml")
    if "ross" in (data := tomllib.loads(p.read_text())).get("rotor", {}) and "speed" not in data
)


def test_there_are_ross_cases():
    assert REPO / "cases" / "rotors" / "ross-rub.toml" in ROSS_CASES


def _reference(path: Path):
    """The full model of a shipped ROSS case over its first 0.1 s by radau at rtol 1e-7,
    atol 1e-12 (test_ross_case_runs says why this tolerance); computed once for the
    cases that differ only in their reduction."""
    case = load_rotor_case(path)
    data = tomllib.loads(path.read_text())
    data["rotor"].pop("modes", None)
    return _full_reference(json.dumps({"rotor": data["rotor"], "station": data["station"],
                                       "unbalance": data.get("unbalance")}), case)  # fmt: skip


_REFERENCES: dict[str, object] = {}


def _full_reference(key: str, case):
    if key not in _REFERENCES:
        t = case.t_eval[case.t_eval <= 0.1]
        reference = simulate(case.full_machine, t, method="radau", rtol=1e-7, atol=1e-12)
        assert reference.success, reference.message
        _REFERENCES[key] = reference
    return _REFERENCES[key]


@pytest.mark.slow
@pytest.mark.parametrize("path", ROSS_CASES, ids=lambda p: p.name)
def test_ross_case_runs(path, tmp_path):
    """Each shipped ROSS case through `rubcli run`: its files, a report that closes its
    energy balance, and, over its first 0.1 s (the first contacts), its contact events
    and the stations' positions against radau ten times tighter (rtol 1e-7, atol
    1e-12; the two differ by about 3e-7 clearances on ross-rub; a reduced case against
    its full model, so its reduction's error too). Tighter than that the full model's
    Newton iterations stall on rounding (its matrices span 1e12)."""
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    case = load_rotor_case(path)
    plots = {f"{p}.png" for p in case.settings.output.plots}
    expected = {"report.json"} | plots | {f"{m}.csv" for m in case.methods}
    if case.settings.output.shapes:
        expected |= {"shape.png", "shapes.csv"}
    assert {p.name for p in out.iterdir()} == expected
    report = json.loads((out / "report.json").read_text())
    assert report["machine"]["coordinates"] == case.machine.size
    if "shaft" in case.settings.output.plots:
        with Image.open(out / "shaft.png") as image:
            assert image.size[0] > 1.2 * image.size[1]
    reference = _reference(path)
    t = reference.t
    for method, entry in report["methods"].items():
        assert entry["status"] == "success", entry["message"]
        assert entry["energy_residual_relative"] < 1e-5
        with open(out / f"{method}.csv", newline="") as handle:
            rows = list(csv.DictReader(handle))[: t.size]
        for s, name in enumerate(case.station_names):
            events = reference.events.at_station(s)
            assert len(events) > 0  # the first 0.1 s hold contacts
            station = entry["stations"][name]
            assert sum(station["events"].values()) >= len(events)
            node = case.station_nodes[s][0]
            ix, iy = case.full_machine.structure.lateral(node)
            clearance = case.machine.stations[s].clearance
            got = np.array([[float(r[f"x_{node}"]), float(r[f"y_{node}"])] for r in rows])
            assert np.max(np.abs(got - reference.states[:, [ix, iy]])) < 1e-4 * clearance
            # the deflection envelope at the station's node: its CSV orbit's largest radius
            # over the last quarter of the run
            with open(out / f"{method}.csv", newline="") as handle:
                every = list(csv.DictReader(handle))
            steady = every[-round(0.25 * len(every)) :]
            radius = max(math.hypot(float(r[f"x_{node}"]), float(r[f"y_{node}"])) for r in steady)
            envelope = entry["deflection"]["envelope_last_quarter_m"]
            assert len(envelope) == case.full_machine.structure.nodes
            assert envelope[node] == pytest.approx(radius, rel=1e-12)
            if case.settings.output.shapes:  # the shape at a sample: the CSV's row there
                with open(out / "shapes.csv", newline="") as handle:
                    shape = list(csv.DictReader(handle))[node]
                for instant in case.settings.output.shapes:
                    row = min(every, key=lambda r: abs(float(r["t_s"]) - instant))
                    label = f"{float(row['t_s']):.6g}s_m"
                    for axis in ("x", "y"):
                        assert float(shape[f"{axis}_at_{label}"]) == pytest.approx(
                            float(row[f"{axis}_{node}"]), rel=1e-12, abs=1e-18
                        )
            regimes = [r[f"{name}_regime"] for r in rows]
            touching = np.array([r != "free" for r in regimes])
            ref_touching = reference.regimes[:, s] != FREE
            assert np.mean(touching != ref_touching) < 0.02  # samples beside an event


def _refused(tmp_path: Path, case: Path, *needles: str) -> None:
    result = runner.invoke(app, ["validate", str(case)])
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    assert "Traceback" not in text
    for needle in needles:
        assert needle in text, text


def test_rotor_files_that_cannot_be_used_are_refused_naming_them(tmp_path):
    def rotor_file(name: str, content: str | bytes) -> str:
        path = tmp_path / name
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        return f"ross = '{name}'"

    good = ROTOR_FILE.read_text()
    cases = [
        ("ross = 'missing.toml'", ("rotor.ross", "missing.toml", "file not found")),
        (rotor_file("r.txt", good), ("rotor.ross", "r.txt", ".toml or .json")),
        (
            rotor_file("bad.toml", "[[[ nonsense"),
            ("rotor.ross", "bad.toml", "not a ROSS rotor file"),
        ),
        (rotor_file("list.json", "[1, 2]"), ("list.json", "top level is not a table")),
        (rotor_file("bin.toml", b"\xff\xfe\x00"), ("bin.toml", "not a text file")),
        (rotor_file("none.toml", "ross_version = '2.3.0'\n[parameters]\n"), ("no ShaftElement",)),
        (rotor_file("neg.toml", '["ShaftElement_a"]\nn = -1\n'), ("ShaftElement_a.n", ">= 0")),
        (rotor_file("huge.toml", '["ShaftElement_a"]\nn = 100000\n'), ("100002 nodes", "reduce")),
        (
            rotor_file("broken.toml", '["ShaftElement_a"]\nn = 0\nL = "long"\n'),
            ("broken.toml", "ROSS cannot build this rotor"),
        ),
        (
            rotor_file("alien.toml", '["Nonsense_a"]\nn = 0\n["ShaftElement_b"]\nn = 0\n'),
            ("alien.toml", "ROSS cannot build this rotor"),
        ),  # fmt: skip
    ]
    for rotor, needles in cases:
        _refused(tmp_path, _case(tmp_path, rotor), *needles)
    (tmp_path / "dir.toml").mkdir()
    _refused(tmp_path, _case(tmp_path, "ross = 'dir.toml'"), "dir.toml", "is a directory")
    os.mkfifo(tmp_path / "fifo.toml")
    _refused(tmp_path, _case(tmp_path, "ross = 'fifo.toml'"), "fifo.toml", "regular file")
    both = "ross = 'rotor.toml'\nmatrices = 'rotor.npz'"
    _refused(tmp_path, _case(tmp_path, both), "rotor", "give the structure once")
    _refused(tmp_path, _case(tmp_path, "ross = 'rotor.toml'\nnumber_dof = 6"), "number_dof")
    _refused(tmp_path, _case(tmp_path, "ross = 'rotor.toml'", "gravity = [0.0]"), "gravity")


def test_a_station_at_a_node_the_rotor_lacks_is_refused(tmp_path):
    path = _case(tmp_path)
    path.write_text(path.read_text().replace("node = 12\nclearance", "node = 34\nclearance"))
    _refused(tmp_path, path, "station[0].node", "node 34 does not exist")


def test_without_ross_the_case_says_how_to_get_it(tmp_path):
    case = _case(tmp_path)
    code = (
        "import sys; sys.modules['ross'] = None\n"
        "from rubcli.cli.entry import main\n"
        f"sys.argv = ['rubcli', 'validate', {str(case)!r}]\n"
        "main()\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 2, result.stderr
    assert "needs ROSS" in result.stderr and 'pip install -e ".[ross]"' in result.stderr
    assert "Traceback" not in result.stderr


def test_the_python_api_refuses_what_is_not_a_rotor(rotor):
    with pytest.raises(TypeError, match="ross.Rotor"):
        ross_structure(object(), SPEED)
    with pytest.raises(ValueError, match="speed"):
        ross_structure(rotor, float("nan"))
    with pytest.raises(TypeError, match="NodeStation"):
        ross_machine(rotor, SPEED, [{"node": 12}])
    with pytest.raises(ValueError, match="node"):
        ross_machine(rotor, SPEED, [NodeStation(99, 1e-4, ContactLaw(1e6))])


def test_ross_import_prints_nothing():
    # ROSS's import talks about optional libraries; a command's --json output stays JSON
    code = "from rubcli.machine.ross import import_ross; import_ross(); print('{}')"
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0 and json.loads(result.stdout) == {}
    assert result.stderr == ""


def test_the_shipped_rotor_file_is_what_its_script_makes(tmp_path):
    # the script's rotor (ROSS's example, as ROSS 2.3 builds it) gives the shipped file's
    # matrices; ROSS 3's example differs from 2.3's in some entries (0.1% of them), so
    # there the file is only loaded
    if not import_ross().__version__.startswith("2.3"):
        assert load_ross_rotor(ROTOR_FILE).ndof == 204
        return
    shipped = ross_matrices(load_ross_rotor(ROTOR_FILE), SPEED)
    made = ross_matrices(import_ross().rotor_example_with_damping(), SPEED)
    for name in shipped:
        np.testing.assert_allclose(shipped[name], made[name], rtol=1e-12, atol=0)
    assert tomllib.loads(ROTOR_FILE.read_text())["ross_version"].startswith("2.3")


@pytest.mark.slow
def test_the_reduced_rotor_converges_to_the_full_one():
    """ross-rub on its Craig-Bampton reduction ([rotor] modes), run by dop853-jit (the
    reduced model is not stiff: an explicit method runs it), against the full model over
    its first contacts: the error at the station falls as modes are added, the contact
    events stay the same, and 24 modes are within 1e-4 clearances."""
    path = REPO / "cases" / "rotors" / "ross-rub.toml"
    reference = _reference(path)
    full = load_rotor_case(path)
    ix, iy = full.lateral(NODE)
    errors = []
    for modes in (4, 12, 24):
        text = path.read_text().replace("speed = 1200.0", f"speed = 1200.0\nmodes = {modes}")
        case = assemble_rotor_case(tomllib.loads(text), path)
        assert case.machine.size == 6 + modes  # node 12 and the two probes kept
        run = simulate(case.machine, reference.t, rtol=1e-10, atol=1e-15)
        assert run.success, run.message
        a, b = case.lateral(NODE)
        miss = np.hypot(run.states[:, a] - reference.states[:, ix],
                        run.states[:, b] - reference.states[:, iy])  # fmt: skip
        errors.append(float(np.max(miss)) / full.machine.stations[0].clearance)
        assert run.events.kinds() == reference.events.kinds()
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1e-4  # about 4e-6

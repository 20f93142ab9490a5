"""Cases whose machine is given as matrices (``[rotor] matrices``): every shipped one runs,
its outputs hold what docs/composed-machine.md says, and a bad matrices file or table is refused
with exit 2 naming the file, the field and the problem, nothing written."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import shutil
import textwrap
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from rubcli.case.rotor import load_rotor_case
from rubcli.cli.app import app
from rubcli.machine import linear
from rubcli.system import simulate

REPO = Path(__file__).resolve().parents[1]
MATRICES_CASES = sorted(  # (the cases on a ROSS rotor file: test_ross)
    p
    for p in (REPO / "cases").rglob("*.toml")
    if "matrices" in tomllib.loads(p.read_text()).get("rotor", {})
)
runner = CliRunner()


def test_there_are_matrices_cases():
    assert REPO / "cases" / "machines" / "two-seals.toml" in MATRICES_CASES


def test_the_beam_file_is_what_its_script_makes():
    script = REPO / "cases" / "machines" / "make_beam.py"
    spec = importlib.util.spec_from_file_location("make_beam", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    made = module.beam_matrices()
    with np.load(REPO / "cases" / "machines" / "beam.npz") as shipped:
        assert sorted(shipped.files) == sorted(made)
        for name, array in made.items():
            np.testing.assert_allclose(shipped[name], array, rtol=1e-15, atol=0)


@pytest.mark.slow
@pytest.mark.parametrize("path", MATRICES_CASES, ids=lambda p: p.name)
def test_matrices_case_runs(path, tmp_path):
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    case = load_rotor_case(path)
    expected = {"report.json", "orbit.png"} | {f"{m}.csv" for m in case.methods}
    assert {p.name for p in out.iterdir()} == expected
    report = json.loads((out / "report.json").read_text())
    assert report["machine"]["coordinates"] == case.machine.size
    # an independent integration of the same machine: radau, tight
    reference = simulate(case.machine, case.t_eval, method="radau", rtol=1e-8, atol=1e-14)
    assert reference.success
    for method, entry in report["methods"].items():
        assert entry["status"] == "success", entry["message"]
        assert entry["energy_residual_relative"] < 1e-6
        assert set(entry["stations"]) == set(case.station_names)
        with open(out / f"{method}.csv", newline="") as handle:
            rows = list(csv.DictReader(handle))
        assert len(rows) == case.t_eval.size
        for s, name in enumerate(case.station_names):
            station = entry["stations"][name]
            events = reference.events.at_station(s)
            assert sum(station["events"].values()) == len(events)
            node = case.station_nodes[s][0]
            ix, iy = case.machine.structure.lateral(node)
            last = rows[-1]
            clearance = case.machine.stations[s].clearance
            assert abs(float(last[f"x_{node}"]) - reference.states[-1, ix]) < 1e-3 * clearance
            assert abs(float(last[f"y_{node}"]) - reference.states[-1, iy]) < 1e-3 * clearance
            regimes = {row[f"{name}_regime"] for row in rows}
            assert regimes <= {"free", "slip+", "slip-", "stick"} and "free" in regimes
            touching = [float(r[f"{name}_normal_N"]) for r in rows if r[f"{name}_regime"] != "free"]
            assert touching and min(touching) >= 0.0


@pytest.fixture
def case_dir(tmp_path):
    """A copy of the two-seal case and its beam, to break."""
    for name in ("two-seals.toml", "beam.npz"):
        shutil.copy(REPO / "cases" / "machines" / name, tmp_path / name)
    return tmp_path


def _save(path: Path, **arrays) -> None:
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)


def _beam(case_dir: Path) -> dict[str, np.ndarray]:
    with np.load(case_dir / "beam.npz") as data:
        return {k: data[k] for k in data.files}


def _huge_header(path: Path) -> None:
    """An .npz whose M declares 50000 x 50000 (20 GB) in its header, with no data."""
    with zipfile.ZipFile(path, "w") as archive:
        for name in ("M", "K", "C"):
            with archive.open(f"{name}.npy", "w") as member:
                header = {"descr": "<f8", "fortran_order": False, "shape": (50000, 50000)}
                np.lib.format.write_array_header_1_0(member, header)


BROKEN = {
    "missing": (lambda d: (d / "beam.npz").unlink(), "beam.npz: file not found"),
    "not a zip": (lambda d: (d / "beam.npz").write_text("M = 1"), "not an .npz file"),
    "a directory": (
        lambda d: ((d / "beam.npz").unlink(), (d / "beam.npz").mkdir()),
        "is a directory",
    ),  # fmt: skip
    "no C": (
        lambda d: _save(d / "beam.npz", **{k: v for k, v in _beam(d).items() if k != "C"}),
        "has no matrix C",
    ),  # fmt: skip
    "not square": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "K": np.ones((24, 23))}),
        "K must be a square matrix",
    ),  # fmt: skip
    "wrong size": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "C": np.eye(12)}),
        "C must be 24 x 24",
    ),  # fmt: skip
    "not symmetric": (
        lambda d: _save(
            d / "beam.npz", **{**_beam(d), "M": _beam(d)["M"] + np.triu(np.ones((24, 24)), 1)}
        ),
        "M must be symmetric",
    ),  # fmt: skip
    "not definite": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "M": -_beam(d)["M"]}),
        "M must be positive definite",
    ),  # fmt: skip
    "nan": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "K": _beam(d)["K"] * np.nan}),
        "K must be finite",
    ),  # fmt: skip
    "objects": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "G": np.array([None, 1])}),
        "G must hold plain numbers",
    ),  # fmt: skip
    "huge": (lambda d: _huge_header(d / "beam.npz"), "more than 2000"),
    "no number_dof": (
        lambda d: _save(d / "beam.npz", **{k: v for k, v in _beam(d).items() if k != "number_dof"}),
        "rotor.number_dof: give the coordinates a node",
    ),  # fmt: skip
    "bad number_dof": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "number_dof": np.array(5)}),
        "dof_per_node = 5 must be >= 2 and divide the 24",
    ),  # fmt: skip
    "positions too few": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "node_position": np.arange(5.0)}),
        "node_position must be 6 positions (m; nan off the shaft)",
    ),  # fmt: skip
    "positions decreasing": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "node_position": -np.arange(6.0)}),
        "node_position must not decrease",
    ),  # fmt: skip
    "disk beyond": (
        lambda d: _save(
            d / "beam.npz",
            **{**_beam(d), "node_position": np.arange(6.0), "disk_nodes": np.array([7])},
        ),
        "disk_nodes must be nodes on the shaft (0 to 5)",
    ),  # fmt: skip
    "disk off the shaft": (
        lambda d: _save(
            d / "beam.npz",
            **{**_beam(d), "disk_nodes": np.array([5]), "node_position": [0, 1, 2, 3, 4, np.nan]},
        ),
        "disk_nodes must be nodes on the shaft",
    ),  # fmt: skip
    "positions 2-D": (
        lambda d: _save(d / "beam.npz", **{**_beam(d), "node_position": np.ones((6, 2))}),
        "node_position must be a list of numbers a node",
    ),  # fmt: skip
}


@pytest.mark.parametrize("kind", list(BROKEN))
def test_a_bad_matrices_file_is_refused_naming_it(case_dir, kind, tmp_path):
    breaks, message = BROKEN[kind]
    breaks(case_dir)
    out = tmp_path / "out"
    for command in (["validate"], ["run", "--out", str(out)]):
        result = runner.invoke(app, [command[0], str(case_dir / "two-seals.toml"), *command[1:]])
        assert result.exit_code == 2, result.output
        assert "rotor.matrices" in result.output or "rotor.number_dof" in result.output
        assert message in " ".join(result.output.split()), result.output
        assert "Traceback" not in result.output
    assert not out.exists()


TABLE_ERRORS = {
    "node beyond": (
        "node = 4\nclearance = 1.5e-5",
        "node = 9\nclearance = 1.5e-5",
        "station[1].node: node 9 does not exist (the matrices have 6 nodes",
    ),  # fmt: skip
    "unknown key": (
        "offset = [5e-6, 0.0]",
        "offset = [5e-6, 0.0]\nmue = 1",
        "station[1].mue: unknown key",
    ),  # fmt: skip
    "no radius": (
        "radius = 0.02                  # m\noffset",
        "offset",
        "station[1].radius: give the rotor's surface radius at the station (m)",
    ),  # fmt: skip
    "bad speed": ("speed = 2500.0", "speed = -1.0", "rotor.speed: Input should be greater than 0"),
    "nul in the name": (
        'matrices = "beam.npz"',
        'matrices = "beam\\u0000.npz"',
        "the name holds a NUL byte",
    ),  # fmt: skip
    "bad method": (
        'methods = ["dop853-jit"]',
        'methods = ["taylor"]',
        "'taylor' cannot run a machine given as matrices",
    ),  # fmt: skip
    "shaft without positions": (
        'dir = "out/two-seals"',
        'dir = "out/two-seals"\nplots = ["orbit", "shaft"]',
        "output.plots: 'shaft' needs the nodes' positions",
    ),  # fmt: skip
    "shapes without positions": (
        'dir = "out/two-seals"',
        'dir = "out/two-seals"\nshapes = [0.1]',
        "output.shapes: a deflected shape needs the nodes' positions",
    ),  # fmt: skip
    "same node": (
        "offset = [5e-6, 0.0]",
        "offset = [5e-6, 0.0]\nstator_node = 4",
        "station[1].stator_node: the station's own node",
    ),  # fmt: skip
}


@pytest.mark.parametrize("kind", list(TABLE_ERRORS))
def test_a_bad_table_is_refused_naming_its_field(case_dir, kind):
    old, new, message = TABLE_ERRORS[kind]
    path = case_dir / "two-seals.toml"
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split()), result.output


PROBES = """
[[probe]]
name = "bearing_side"
node = 1
angle = 0.5

[[probe]]
node = 4
angle = -1.5707963267948966
"""


@pytest.mark.parametrize("modes", [0, 10])
def test_probes_read_as_rosss_and_are_reported(case_dir, modes):
    """A probe reads x cos(angle) + y sin(angle) at its node (ROSS's Probe), on the full
    model and on a reduction (which keeps its node's coordinates): its CSV column, its
    report entry and its panel in the orbit figure."""
    path = case_dir / "two-seals.toml"
    text = path.read_text().replace("[time]", PROBES + "\n[time]")
    text = text.replace('dir = "out/two-seals"', 'dir = "out/two-seals"\nplots = ["orbit", "time"]')
    if modes:
        text = text.replace("speed = 2500.0", f"speed = 2500.0\nmodes = {modes}")
    path.write_text(text)
    case = load_rotor_case(path)
    assert [p.name for p in case.probes] == ["bearing_side", "probe1"]
    out = case_dir / "out"
    result = runner.invoke(app, ["run", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    with open(out / "dop853-jit.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    # the probes' own columns against the full model's nodes (a reduction's error aside)
    full = simulate(case.full_machine, case.t_eval, rtol=1e-10, atol=1e-14)
    clearance = case.machine.stations[0].clearance
    for name, node, angle in (("bearing_side", 1, 0.5), ("probe1", 4, -math.pi / 2)):
        ix, iy = case.full_machine.structure.lateral(node)
        expected = full.states[:, ix] * math.cos(angle) + full.states[:, iy] * math.sin(angle)
        got = np.array([float(r[f"{name}_m"]) for r in rows])
        assert np.max(np.abs(got - expected)) < 1e-3 * clearance
        from_nodes = [float(r[f"x_{node}"]) * math.cos(angle) + float(r[f"y_{node}"])
                      * math.sin(angle) for r in rows]  # fmt: skip
        np.testing.assert_allclose(got, from_nodes, rtol=1e-12, atol=1e-20)
    entry = json.loads((out / "report.json").read_text())["methods"]["dop853-jit"]["probes"]
    assert set(entry) == {"bearing_side", "probe1"}
    assert entry["probe1"]["node"] == 4
    got = np.array([float(r["probe1_m"]) for r in rows])
    assert entry["probe1"]["max_abs_m"] == pytest.approx(np.max(np.abs(got)), rel=1e-12)
    with Image.open(out / "orbit.png") as image:  # three panels side by side: a wide figure
        assert image.size[0] > 2.5 * image.size[1]
    with Image.open(out / "time.png") as image:  # the stations above the probes
        assert image.size[1] > 0.6 * image.size[0]


@pytest.mark.parametrize(
    ("probe", "message"),
    [("node = 99\nangle = 0.0", "probe[0].node: node 99 does not exist"),
     ('name = "disk_seal"\nnode = 1\nangle = 0.0', "disk_seal is a station's name too"),
     ("node = 1", "probe[0].angle: missing required key"),
     ("node = 1\nangle = 0.0\ndirection = 'axial'", "probe[0].direction: unknown key")],
)  # fmt: skip
def test_a_bad_probe_is_refused_naming_it(case_dir, probe, message):
    path = case_dir / "two-seals.toml"
    path.write_text(path.read_text().replace("[time]", f"[[probe]]\n{probe}\n\n[time]"))
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split()), result.output
    assert "Traceback" not in result.output


def test_validate_json_and_the_other_commands(case_dir):
    path = case_dir / "two-seals.toml"
    result = runner.invoke(app, ["validate", str(path), "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["valid"] is True
    result = runner.invoke(app, ["sweep", str(path)])
    assert result.exit_code == 2
    assert "runs with `rubcli validate`, `rubcli run` and `rubcli compare`" in " ".join(
        result.output.split()
    )
    result = runner.invoke(app, ["compare", str(path), "--quick"])
    assert result.exit_code == 2 and "--quick" in result.output
    result = runner.invoke(app, ["run", str(path), "--periods", "3"])
    assert result.exit_code == 2 and "[time] end" in result.output
    result = runner.invoke(app, ["run", str(path), "--method", "taylor"])
    assert result.exit_code == 2 and "cannot run a machine given as matrices" in result.output
    (case_dir / "beam.npz").write_text("x")
    result = runner.invoke(app, ["validate", str(path), "--json"])
    assert result.exit_code == 2
    assert json.loads(result.output)["valid"] is False


def test_a_run_too_large_for_memory_is_refused_before_it_runs(case_dir):
    path = case_dir / "two-seals.toml"
    text = path.read_text()
    text = text.replace("end = 0.48", "end = 100.0").replace(
        "samples_per_revolution = 100", "samples_per_revolution = 2000"
    )
    text = text.replace('methods = ["dop853-jit"]', 'methods = ["dop853-jit", "rk45", "radau"]')
    path.write_text(text)
    result = runner.invoke(app, ["run", str(path), "--out", str(case_dir / "out")])
    assert result.exit_code == 2, result.output
    assert "GiB, more than the 8 GiB a run may hold" in " ".join(result.output.split())
    assert not (case_dir / "out").exists()


def test_the_documented_case_validates(case_dir):
    """The matrices case of docs/composed-machine.md, as written, beside the beam."""
    text = (REPO / "docs" / "composed-machine.md").read_text()
    start = text.index("    [case]\n")
    block = text[start : text.index("\n\n`rubcli validate`", start)]
    path = case_dir / "documented.toml"
    path.write_text(textwrap.dedent(block) + "\n")
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    assert [p.name for p in load_rotor_case(path).probes] == ["bearing_side"]


@pytest.mark.slow
def test_compare_states_the_reductions_error_beside_the_methods(case_dir):
    """`rubcli compare` on a reduced case: the full model by radau as the reference, the
    case's method on the reduction at three tolerances, radau on the full model at three.
    radau's error on the full model falls with its tolerance; the reduction's does not (it
    is the reduction's own, the same at every tolerance) and is above radau's."""
    path = case_dir / "two-seals.toml"
    path.write_text(path.read_text().replace("speed = 2500.0", "speed = 2500.0\nmodes = 8"))
    out = case_dir / "cmp"
    result = runner.invoke(app, ["compare", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {"compare.csv", "compare.png", "report.json"}
    report = json.loads((out / "report.json").read_text())
    assert report["reference"]["method"] == "radau" and report["reference"]["coordinates"] == 24
    runs = report["runs"]
    assert all(r["status"] == "success" for r in runs)
    reduced = [r["error_clearances"] for r in runs if r["model"] == "8 modes"]
    full = [r["error_clearances"] for r in runs if r["model"] == "full"]
    assert len(reduced) == 3 and len(full) == 3
    assert full[0] > full[1] > full[2]
    assert max(reduced) < 1.1 * min(reduced) and min(reduced) > 10 * full[2]
    with open(out / "compare.csv", newline="") as handle:
        assert len(list(csv.DictReader(handle))) == 6


def test_the_shaft_view_skips_nodes_off_the_shaft(case_dir):
    """A node with no position (nan: off the shaft, as a ROSS bearing's support node)
    is left out of the shaft view; the stations on the shaft are drawn."""
    arrays = _beam(case_dir)
    _save(case_dir / "beam.npz", **arrays, node_position=np.array([0, 0.1, 0.2, 0.3, 0.4, np.nan]),
          disk_nodes=np.array([2]), bearing_nodes=np.array([0, 4]))  # fmt: skip
    path = case_dir / "two-seals.toml"
    old = 'dir = "out/two-seals"'
    text = path.read_text().replace(old, old + '\nplots = ["shaft"]')
    path.write_text(text)
    case = load_rotor_case(path)
    assert case.layout.disks == (2,) and np.isnan(case.layout.positions[5])
    out = case_dir / "out"
    result = runner.invoke(app, ["run", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    with Image.open(out / "shaft.png") as image:
        assert image.size[0] > 1.2 * image.size[1]


RAMP = """
[speed]
profile = "ramp"
from = 1500.0
to = 3500.0
rate = 4000.0
"""


def test_a_runup_on_matrices_writes_its_bode_polar_and_cascade(case_dir):
    """A matrices case with [speed] (its bearings' coefficients constant: the file holds
    one speed's, as validate says): the run-up's figures and report, the CSV's speed the
    ramp's, the probes' linear critical speed the structure's own natural frequency
    there (the peak of the steady response), and the seals' rub at the stations."""
    path = case_dir / "two-seals.toml"
    text = path.read_text().replace("speed = 2500.0                 # rpm\n", "")
    text = text.replace("[time]", RAMP + PROBES + "\n[time]")
    path.write_text(text.replace("end = 0.48", "end = 0.6"))
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    assert "coefficients constant" in result.output
    out = case_dir / "out"
    result = runner.invoke(app, ["run", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    names = {p.name for p in out.iterdir()}
    assert {"bode.png", "polar.png", "cascade.png", "orbit.png"} <= names
    report = json.loads((out / "report.json").read_text())
    assert report["methods"]["dop853-jit"]["energy_residual_relative"] < 1e-6
    runup = report["runup"]
    assert set(runup["probes"]) == {"bearing_side", "probe1"}
    assert set(runup["stations"]) == {"disk_seal", "offset_seal"}
    case = load_rotor_case(path)
    structure = case.machine.structure
    for entry in runup["probes"].values():
        critical = entry["linear_critical_rpm"] * 2 * math.pi / 60
        frequencies = np.abs(linear.eigenvalues(structure, critical).imag)
        if 1500 < entry["linear_critical_rpm"] < 3500:  # a peak inside the range
            assert np.min(np.abs(frequencies - critical)) < 0.01 * critical
    with open(out / "dop853-jit.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    t = np.array([float(r["t_s"]) for r in rows])
    rpm = np.array([float(r["speed_rpm"]) for r in rows])
    np.testing.assert_allclose(rpm, np.minimum(1500.0 + 4000.0 * t, 3500.0), rtol=1e-12)
    with Image.open(out / "bode.png") as image:
        assert image.size[0] > image.size[1]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t: t.replace("[time]", RAMP + PROBES + "\n[time]"), "give the speed once"),
        (lambda t: t.replace("speed = 2500.0                 # rpm\n", "")
         .replace("[time]", RAMP + "\n[time]"), "give at least one [[probe]]"),
        (lambda t: t.replace("speed = 2500.0                 # rpm\n", "")
         .replace("[time]", RAMP.replace("4000.0", "-40.0") + PROBES + "\n[time]"),
         "rate must be nonzero with the sign of to - from"),
        (lambda t: t.replace("speed = 2500.0                 # rpm\n", "")
         .replace("[time]", '[speed]\nprofile = "driven"\n' + PROBES + "\n[time]"),
         "speed.profile: Input should be 'ramp' or 'table'"),
        (lambda t: t.replace("speed = 2500.0                 # rpm\n", "")
         .replace("[time]", '[speed]\nprofile = "table"\nt = [0.0, 0.1]\nspeed = [100.0]\n'
                  + PROBES + "\n[time]"), "speed.speed: List should have at least 2 items"),
    ],
)  # fmt: skip
def test_a_bad_speed_is_refused_naming_it(case_dir, change, message):
    path = case_dir / "two-seals.toml"
    path.write_text(change(path.read_text()))
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split()), result.output
    assert "Traceback" not in result.output

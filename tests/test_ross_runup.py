"""A ROSS rotor run up through its critical speed (cases/rotors/ross-runup.toml, on
bearings whose coefficients change with the speed: cases/rotors/ross_runup.toml): the
bearings at each speed against ROSS's own matrices there, the run-up's linear critical
speed against ROSS's ``run_modal``, and the shipped case through ``rubcli run``.

These tests need ROSS (the test extra installs it)."""

from __future__ import annotations

import csv
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rubcli.case.rotor import load_rotor_case
from rubcli.cli.app import app
from rubcli.machine.ross import (
    TABLE_RTOL,
    RossError,
    import_ross,
    lateral_coordinates,
    load_ross_rotor,
    ross_matrices,
    ross_speed_table,
    ross_structure,
)
from rubcli.system import simulate

REPO = Path(__file__).resolve().parents[1]
ROTOR_FILE = REPO / "cases" / "rotors" / "ross_runup.toml"
CASE = REPO / "cases" / "rotors" / "ross-runup.toml"
RPM = 2.0 * math.pi / 60.0
LOW, HIGH = 600.0 * RPM, 3000.0 * RPM  # the shipped run-up's speeds
runner = CliRunner()

try:
    import_ross()
except RossError:
    pytest.skip("ROSS is not installed (pip install -e '.[ross]')", allow_module_level=True)


@pytest.fixture(scope="module")
def rotor():
    return load_ross_rotor(ROTOR_FILE)


def test_the_bearings_at_each_speed_are_rosss(rotor):
    """The structure of a run-up: its matrices plus the speed table at a speed, against
    ROSS's ``K(speed)``, ``C(speed)`` there (its spline through the bearings' tables),
    at speeds between the table's, to the table's stated error; ``M`` and ``G`` as
    ROSS's."""
    structure = ross_structure(rotor, LOW, speed_range=(LOW, HIGH))
    table = structure.speed_table
    assert table is not None and len(table.coordinates) == 4  # x, y of the two bearings
    *_, error = ross_speed_table(rotor, LOW, HIGH)
    assert error <= TABLE_RTOL
    for speed in np.linspace(LOW, HIGH, 7)[1:-1] + 0.37 * (HIGH - LOW) / 6:
        ross = ross_matrices(rotor, speed)
        keep, _, _ = lateral_coordinates(ross)
        K, C = structure.at_speed(speed)
        for name, ours in (("K", K), ("C", C)):
            theirs = ross[name][np.ix_(keep, keep)]
            bearing = np.max(np.abs(table.K if name == "K" else table.C))
            assert np.max(np.abs(ours - theirs)) <= 2 * TABLE_RTOL * bearing, name
        np.testing.assert_allclose(structure.M, ross["M"][np.ix_(keep, keep)], rtol=0, atol=0)
        np.testing.assert_allclose(structure.G, ross["G"][np.ix_(keep, keep)], rtol=0, atol=0)


def test_the_python_api_builds_the_cases_runup(rotor):
    """``ross_machine`` on a ``Speed`` profile: the machine the shipped case builds
    (before its reduction), bearings' table and all."""
    from rubcli.machine import ContactLaw, Speed
    from rubcli.machine.ross import NodeStation, ross_machine

    case = load_rotor_case(CASE)
    profile = Speed((0.0, 3.0), (LOW, HIGH))
    station = NodeStation(13, 1e-4, ContactLaw(2e6, damping=20.0), mu=0.05)
    machine = ross_machine(rotor, profile, [station], [(12, 1e-4, 0.0)])
    ours, theirs = machine.structure, case.full_machine.structure
    for name in ("M", "K", "C", "G"):
        np.testing.assert_array_equal(getattr(ours, name), getattr(theirs, name))
    np.testing.assert_array_equal(ours.speed_table.K, theirs.speed_table.K)
    assert machine.speed == case.full_machine.speed
    assert machine.stations[0].rotor == case.full_machine.stations[0].rotor


def test_a_constant_speed_has_no_table(rotor):
    structure = ross_structure(rotor, LOW)
    assert structure.speed_table is None
    np.testing.assert_array_equal(structure.at_speed(LOW)[0], structure.K)


def test_the_shipped_file_is_what_its_script_makes():
    # the script's bearings are the file's tables
    data = tomllib.loads(ROTOR_FILE.read_text())
    script = {}
    exec(compile((ROTOR_FILE.parent / "make_ross_runup.py").read_text(), "make", "exec"), script)
    bearing = data["BearingElement_Bearing 0"]
    np.testing.assert_allclose(bearing["frequency"], script["FREQUENCY"], rtol=0, atol=0)
    np.testing.assert_allclose(bearing["kxx"], 4.40e5 * script["STIFFENING"], rtol=1e-15)
    np.testing.assert_allclose(bearing["kxy"], 4.40e5 * script["STIFFENING"] * script["CROSS"],
                               rtol=1e-15)  # fmt: skip


@pytest.mark.slow
def test_the_shipped_runup_runs(tmp_path):
    """``rubcli run`` on the shipped run-up: its files; the energy balance closed through
    the bearings that change with the speed and the rub; the linear critical speed of
    each probe's direction at a speed where one of ROSS's own damped natural frequencies
    (``run_modal`` there) equals the speed; the rub's onset after the linear response at
    the seal passes the clearance; the CSV's speed the profile's."""
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", str(CASE), "--out", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    names = {p.name for p in out.iterdir()}
    assert {"bode.png", "polar.png", "cascade.png", "report.json", "dop853-jit.csv"} <= names
    entry = report["methods"]["dop853-jit"]
    assert entry["status"] == "success"
    assert entry["energy_residual_relative"] < 1e-6
    runup = report["runup"]
    assert runup["revolutions"] in (89, 90)  # the ramp's 90 turns (3 s at 1800 rpm on average)
    rotor = load_ross_rotor(ROTOR_FILE)
    for name in ("probe14x", "probe14y"):
        critical = runup["probes"][name]["linear_critical_rpm"] * RPM
        modal = rotor.run_modal(critical, num_modes=8)
        assert min(abs(w - critical) for w in modal.wd[:2]) < 0.01 * critical, name
    seal = runup["stations"]["seal"]
    assert 1200.0 < seal["rub_onset_rpm"] < 1800.0
    with open(out / "dop853-jit.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    t = np.array([float(r["t_s"]) for r in rows])
    rpm = np.array([float(r["speed_rpm"]) for r in rows])
    np.testing.assert_allclose(rpm, np.minimum(600.0 + 800.0 * t, 3000.0), rtol=1e-12)


@pytest.mark.slow
def test_the_runup_agrees_with_scipys_dop853_through_the_first_contacts():
    """The shipped method and tolerance against scipy's own DOP853 (an independent
    implementation, stepping in Python, its own step control and event location) over
    the first 1.4 s (the rub's first contacts, near the critical speed): contact regimes
    per sample and the seal's orbit to 1e-6 clearances. (At ten times tighter the two
    agree to about 1e-10 clearances: the reduced model's stiffest, overdamped mode holds
    the explicit step near 3 us, far below what the tolerance asks.)"""
    case = load_rotor_case(CASE)
    t = case.t_eval[case.t_eval <= 1.4]
    ours = simulate(case.machine, t, method="dop853-jit", rtol=1e-9, atol=1e-14)
    reference = simulate(case.machine, t, method="dop853", rtol=1e-9, atol=1e-14)
    assert ours.success and reference.success, (ours.message, reference.message)
    assert len(reference.events.at_station(0)) > 0
    ix, iy = case.machine.stations[0].rotor
    gap = np.max(np.abs(ours.states[:, [ix, iy]] - reference.states[:, [ix, iy]]))
    assert gap < 1e-6 * case.machine.stations[0].clearance
    assert np.array_equal(ours.regimes[:, 0], reference.regimes[:, 0])

"""Case files: valid ones load, physical units convert as by hand, every invalid input is named."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rubcli import units
from rubcli.case import (
    DEFAULT_FORCES_MAP_DELTAS,
    DEFAULT_FORCES_MAP_K_VALUES,
    KNOWN_METHODS,
    CaseError,
    CaseFile,
    load_case,
    load_case_text,
    validate_case,
)

REPO = Path(__file__).resolve().parents[1]

MINIMAL = """\
[case]
name = "t"

[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6

[initial]
x = 0.88544
y = -0.8039

[time]
periods = 2
samples_per_period = 10
"""

# A machine with round numbers, converted by hand (model notes section 1):
#   omega = sqrt(k_r/m) = sqrt(4e4/4) = 100 rad/s
#   nu = d_r/(2 omega m) = 8/(2*100*4) = 0.01       eta = Omega/omega = 80/100 = 0.8
#   K = k_s/k_r = 8e5/4e4 = 20                      e^ = 2e-3/1e-3 = 2, Rp^ = 0.05/1e-3 = 50
#   x^ = 5e-4/1e-3 = 0.5, y^ = -1e-3/1e-3 = -1     vx^ = 0.1/(100*1e-3) = 1, vy^ = -0.05/0.1 = -0.5
#   one period 2 pi/eta = 7.854 in tau, 2 pi/80 = 0.07854 s; force unit k_r*clearance = 40 N
PHYSICAL = """\
[case]
name = "machine"

[physical]
m = 4.0
k_r = 4.0e4
d_r = 8.0
k_s = 8.0e5
clearance = 1.0e-3
e = 2.0e-3
Omega = 80.0
Rp = 0.05
mu = 0.1
phi0 = 0.3

[initial]
x = 5.0e-4
y = -1.0e-3
vx = 0.1
vy = -0.05

[time]
periods = 3
samples_per_period = 20
"""


def write(tmp_path: Path, text: str, name: str = "case.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def replace(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def problems_of(tmp_path: Path, text: str) -> list[str]:
    path = write(tmp_path, text)
    with pytest.raises(CaseError) as info:
        load_case(path)
    problems = info.value.problems
    assert problems, "a CaseError has at least one line"
    for line in problems:
        assert line.startswith(f"{path}: "), line
    return problems


# ------------------------------------------------------------------------ valid files


def test_minimal_case_fills_defaults(tmp_path):
    case = load_case(write(tmp_path, MINIMAL))
    s = case.settings
    assert s.model.mu == 0.0 and s.model.Rp == 0.0 and s.model.phi0 == 0.0
    assert s.initial.vx == 0.0 and s.initial.vy == 0.0
    assert s.solver.methods == ["analytic", "rk45"]
    assert (s.solver.rtol, s.solver.atol) == (1e-8, 1e-10)
    assert s.solver.steps_per_period == 400
    assert s.solver.max_steps == 5_000_000 and s.solver.max_wall_time_s == 600
    assert s.output.csv is True and s.output.plots == ["orbit", "time"]
    assert s.forces_map is None
    assert case.output_dir == Path("out/t")
    assert case.scale is None
    assert case.solver_options == {
        "rtol": 1e-8,
        "atol": 1e-10,
        "steps_per_period": 400,
        "analytic_tol": None,
        "max_steps": 5_000_000,
        "max_wall_time_s": 600.0,
    }


def test_problem_is_built_from_the_case(tmp_path):
    case = load_case(write(tmp_path, MINIMAL))
    p = case.problem
    assert p.params.K == 17.6 and p.params.e == 7.52
    assert p.initial == (0.88544, -0.8039, 0.0, 0.0)
    assert p.t_eval.size == 2 * 10 + 1
    assert p.t_span[1] == pytest.approx(2 * 2 * math.pi / 0.7818, rel=1e-15)
    assert p.name == "t"


@pytest.mark.parametrize(
    "path",
    sorted(
        # a Jeffcott case: [case] and no [rotor] (a ROSS rotor file has neither)
        p
        for p in (REPO / "cases").rglob("*.toml")
        if "case" in (data := tomllib.loads(p.read_text())) and "rotor" not in data
    ),
    ids=lambda p: p.name,
)
def test_every_shipped_case_loads(path):
    case = load_case(path)
    assert case.problem.t_eval.size >= 2
    assert case.to_dict()["settings"]["case"]["name"] == case.name


def test_paper_cases_match_the_figure3_caption():
    """Figure 3 caption (model notes, section 6), mu = 0, 0.01, ..., 0.05 for a ... f."""
    for letter, mu in zip("abcdef", (0.0, 0.01, 0.02, 0.03, 0.04, 0.05), strict=True):
        case = load_case(REPO / "cases" / "paper" / f"fig3{letter}.toml")
        p = case.params
        assert (p.nu, p.eta, p.e, p.K, p.Rp, p.phi0, p.mu) == (
            0.009478,
            0.7818,
            7.52,
            17.6,
            46.16,
            0.0,
            mu,
        )
        assert case.problem.initial == (0.88544, -0.8039, 0.0, 0.0)


def test_physical_units_convert_as_by_hand(tmp_path):
    case = load_case(write(tmp_path, PHYSICAL))
    p, scale = case.params, case.scale
    assert scale == units.PhysicalScale(omega=100.0, clearance=1e-3, k_r=4e4, k_s=8e5)
    assert p.nu == pytest.approx(0.01, rel=1e-14)
    assert p.eta == pytest.approx(0.8, rel=1e-14)
    assert p.K == pytest.approx(20.0, rel=1e-14)  # noqa: SIM300 (K is not a constant)
    assert p.e == pytest.approx(2.0, rel=1e-14)
    assert p.Rp == pytest.approx(50.0, rel=1e-14)
    assert (p.mu, p.phi0) == (0.1, 0.3)
    np.testing.assert_allclose(case.problem.initial, (0.5, -1.0, 1.0, -0.5), rtol=1e-14)
    assert case.problem.t_span[1] == pytest.approx(3 * 2 * math.pi / 0.8, rel=1e-14)


def test_physical_outputs_convert_back_as_by_hand():
    scale = units.PhysicalScale(omega=100.0, clearance=1e-3, k_r=4e4, k_s=8e5)
    assert units.seconds(100.0, scale) == pytest.approx(1.0)
    assert units.metres(0.5, scale) == pytest.approx(5e-4)
    assert units.metres_per_second(1.0, scale) == pytest.approx(0.1)
    assert units.newtons(1.0, scale) == pytest.approx(40.0)  # k_r * clearance
    # normal force K (z - 1) in newtons is k_s (r - clearance): z = 1.5 -> 8e5 * 0.5e-3 = 400 N
    assert units.newtons(20.0 * (1.5 - 1.0), scale) == pytest.approx(400.0)


def test_units_round_trip():
    params, scale = units.nondimensional_params(
        m=2.5, k_r=3e5, d_r=12.0, k_s=7e6, clearance=3e-4, e=1e-4, Omega=200.0, Rp=0.04
    )
    state = units.nondimensional_state(1e-4, -2e-4, 0.03, 0.01, scale)
    back = (
        units.metres(state[0], scale),
        units.metres(state[1], scale),
        units.metres_per_second(state[2], scale),
        units.metres_per_second(state[3], scale),
    )
    np.testing.assert_allclose(back, (1e-4, -2e-4, 0.03, 0.01), rtol=1e-14)
    assert params.K * scale.k_r == pytest.approx(scale.k_s)


def test_forces_map_defaults_and_values(tmp_path):
    case = load_case(write(tmp_path, MINIMAL + "\n[forces_map]\n"))
    fm = case.settings.forces_map
    assert fm.extent == 1.5 and fm.resolution == 201
    assert fm.products == ["forces", "taylor_error", "eigen"]
    assert fm.deltas is None and fm.K_values is None
    np.testing.assert_allclose(fm.resolved_deltas(), np.logspace(-6, -1, 11))
    assert len(DEFAULT_FORCES_MAP_DELTAS) == 11
    assert fm.resolved_K_values() == DEFAULT_FORCES_MAP_K_VALUES == (17.6, 1.76e3, 1.76e5, 1.75e6)
    text = MINIMAL + '\n[forces_map]\nextent = 2\nresolution = 3\nproducts = ["eigen"]\n'
    text += "deltas = [1e-3, 1e-2]\nK_values = [17.6]\n"
    fm = load_case(write(tmp_path, text)).settings.forces_map
    assert (fm.extent, fm.resolution, fm.products) == (2.0, 3, ["eigen"])
    assert fm.resolved_deltas() == (1e-3, 1e-2) and fm.resolved_K_values() == (17.6,)


def test_overrides_are_validated_again(tmp_path):
    case = load_case(write(tmp_path, MINIMAL))
    other = case.with_overrides(methods=["dop853"], periods=0.5, output_dir=tmp_path / "o")
    assert other.methods == ["dop853"]
    assert other.problem.periods == pytest.approx(0.5)
    assert other.output_dir == tmp_path / "o"
    assert case.methods == ["analytic", "rk45"]  # the original is unchanged
    with pytest.raises(CaseError, match=r"time\.periods"):
        case.with_overrides(periods=-1.0)


def test_known_methods_match_the_solver_registry():
    from rubcli.solvers import METHODS

    assert set(KNOWN_METHODS) == set(METHODS)


def test_init_samples_validate():
    from rubcli.samples import SAMPLE_CASE, SAMPLE_PHYSICAL_CASE

    assert load_case_text(SAMPLE_CASE, "sample.toml").scale is None
    assert load_case_text(SAMPLE_PHYSICAL_CASE, "sample.toml").scale is not None


# ---------------------------------------------------------------------- invalid files


@pytest.mark.parametrize(
    ("old", "new", "field", "words"),
    [
        ("K = 17.6", "K = -17.6", "model.K", "greater than 0"),
        ("K = 17.6", "K = 0", "model.K", "greater than 0"),
        ("nu = 0.009478", "nu = -0.1", "model.nu", "greater than or equal to 0"),
        ("e = 7.52", "e = nan", "model.e", "finite"),
        ("eta = 0.7818", "eta = inf", "model.eta", "finite"),
        ("x = 0.88544", "x = -inf", "initial.x", "finite"),
        ("K = 17.6", 'K = "17.6"', "model.K", "valid number"),
        ("K = 17.6", "K = true", "model.K", "valid number"),
        (
            "samples_per_period = 10",
            "samples_per_period = 10.0",
            "time.samples_per_period",
            "integer",
        ),
        ("periods = 2", "periods = 0", "time.periods", "greater than 0"),
        ("periods = 2", "periods = 1e12", "time", "output samples"),
        ('name = "t"', 'name = "a/b"', "case.name", "letters, digits"),
        ("K = 17.6", "K = 17.6\nk = 1.0", "model.k", "unknown key"),
        ("[time]", "[time]\nstep = 0.1", "time.step", "unknown key"),
        ("[case]", "[cases]\nname = 1\n[case]", "cases", "unknown key"),
    ],
)
def test_invalid_value_names_file_and_field(tmp_path, old, new, field, words):
    problems = problems_of(tmp_path, replace(MINIMAL, old, new))
    assert any(f": {field}: " in line and words in line for line in problems), problems


@pytest.mark.parametrize("table", ["case", "initial", "time"])
def test_missing_table(tmp_path, table):
    text = MINIMAL
    start = text.index(f"[{table}]")
    end = text.find("\n[", start + 1)
    text = text[:start] + (text[end + 1 :] if end != -1 else "")
    problems = problems_of(tmp_path, text)
    assert any(f": {table}: missing table [{table}]" in line for line in problems), problems


def test_missing_key(tmp_path):
    problems = problems_of(tmp_path, replace(MINIMAL, "K = 17.6\n", ""))
    assert any(": model.K: missing required key" in line for line in problems), problems


def test_neither_model_nor_physical(tmp_path):
    text = MINIMAL[: MINIMAL.index("[model]")] + MINIMAL[MINIMAL.index("[initial]") :]
    problems = problems_of(tmp_path, text)
    assert any(": model: missing table" in line and "[physical]" in line for line in problems)


def test_both_model_and_physical(tmp_path):
    physical = PHYSICAL[PHYSICAL.index("[physical]") : PHYSICAL.index("[initial]")]
    problems = problems_of(tmp_path, MINIMAL + "\n" + physical)
    assert any(": physical: " in line and "not both" in line for line in problems), problems


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("m = 4.0", "m = 0.0", "physical.m"),
        ("clearance = 1.0e-3", "clearance = -1.0e-3", "physical.clearance"),
        ("Omega = 80.0", "Omega = 0.0", "physical.Omega"),
        ("d_r = 8.0", "d_r = -8.0", "physical.d_r"),
        ("k_s = 8.0e5", "k_s = nan", "physical.k_s"),
    ],
)
def test_invalid_physical_value(tmp_path, old, new, field):
    problems = problems_of(tmp_path, replace(PHYSICAL, old, new))
    assert any(f": {field}: " in line for line in problems), problems


def test_unknown_method(tmp_path):
    text = MINIMAL + '\n[solver]\nmethods = ["rk45", "euler"]\n'
    problems = problems_of(tmp_path, text)
    assert any(": solver.methods[1]: " in line and "'euler'" in line for line in problems)


@pytest.mark.parametrize(
    ("table", "line", "field"),
    [
        ("solver", "methods = []", "solver.methods"),
        ("solver", 'methods = ["rk45", "rk45"]', "solver.methods"),
        ("solver", "rtol = 0", "solver.rtol"),
        ("solver", "steps_per_period = 0", "solver.steps_per_period"),
        ("solver", "max_steps = -5", "solver.max_steps"),
        ("output", 'plots = ["orbit", "phase"]', "output.plots[1]"),
        ("output", 'csv = "yes"', "output.csv"),
        ("forces_map", "extent = 1.0", "forces_map.extent"),
        ("forces_map", "resolution = 2", "forces_map.resolution"),
        ("forces_map", 'products = ["force"]', "forces_map.products[0]"),
        ("forces_map", "deltas = [1e-3, -1e-2]", "forces_map.deltas[1]"),
        ("forces_map", "K_values = [0]", "forces_map.K_values[0]"),
    ],
)
def test_invalid_optional_tables(tmp_path, table, line, field):
    problems = problems_of(tmp_path, f"{MINIMAL}\n[{table}]\n{line}\n")
    assert any(f": {field}: " in p for p in problems), problems


def test_all_problems_are_reported_at_once(tmp_path):
    text = replace(replace(MINIMAL, "K = 17.6", "K = -1"), "x = 0.88544", "x = nan")
    problems = problems_of(tmp_path, text)
    assert len(problems) == 2
    assert str(CaseError(problems)) == "\n".join(problems)


def test_not_toml_names_the_line(tmp_path):
    problems = problems_of(tmp_path, MINIMAL.replace("K = 17.6", "K = = 17.6"))
    assert len(problems) == 1
    assert "not valid TOML" in problems[0] and "line 8" in problems[0]  # K is on line 8


def test_binary_file_is_not_toml(tmp_path):
    path = tmp_path / "case.toml"
    path.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(CaseError, match="not valid TOML"):
        load_case(path)


def test_missing_file(tmp_path):
    with pytest.raises(CaseError, match=r"nope\.toml: file not found"):
        load_case(tmp_path / "nope.toml")


def test_directory_is_not_a_case(tmp_path):
    with pytest.raises(CaseError, match="is a directory"):
        load_case(tmp_path)


def test_schema_alone_rejects_model_and_physical_together():
    """CaseFile keeps the rule even without the loader's friendlier message."""
    raw = {
        "case": {"name": "t"},
        "initial": {"x": 0.0, "y": 0.0},
        "time": {"periods": 1, "samples_per_period": 10},
    }
    with pytest.raises(ValueError, match="exactly one"):
        CaseFile.model_validate(raw)
    with pytest.raises(CaseError, match="missing table"):
        validate_case(raw, "raw")


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"m = 4.0": "m = 1e-320", "k_r = 4.0e4": "k_r = 1e10"}, "converts to eta = 0.0"),
        ({"m = 4.0": "m = 1e300", "k_r = 4.0e4": "k_r = 1e-300"}, "cannot be converted"),
    ],
)
def test_physical_values_that_convert_to_nonsense(tmp_path, changes, words):
    """Each SI value is valid alone, but the converted model is not (under/overflow)."""
    text = PHYSICAL
    for old, new in changes.items():
        text = replace(text, old, new)
    problems = problems_of(tmp_path, text)
    assert any(": physical: " in line and words in line for line in problems), problems


def test_horizon_beyond_floating_point_range(tmp_path):
    problems = problems_of(tmp_path, replace(MINIMAL, "eta = 0.7818", "eta = 1e-310"))
    assert any(": model.eta: must be at least 1e-100" in line for line in problems), problems
    problems = problems_of(tmp_path, replace(MINIMAL, "eta = 0.7818", "eta = 1e-100"))
    assert any(": time.periods: " in line and "beyond 1e+100" in line for line in problems)


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        ("eta = 1e300", "model.eta", "at most 1e+100 in size"),
        ("e = 1e308", "model.e", "at most 1e+100 in size"),
        ("K = 1e300", "model.K", "at most 1e+100 in size"),
        ("K = 1e60", "model.K", "a contact oscillation"),
        ("phi0 = -1e200", "model.phi0", "at most 1e+100 in size"),
    ],
)
def test_model_values_beyond_the_domain_are_refused_like_physical_ones(
    tmp_path, change, field, words
):
    """[model] is checked against the model's domain as a [physical] table's converted
    values are (once [model] eta = 1e300 overflowed in ModelParams.period)."""
    name = change.split(" = ")[0]
    text = MINIMAL if name != "phi0" else replace(MINIMAL, "[model]", "[model]\nphi0 = 0.0")
    lines = [ln for ln in text.splitlines() if not ln.startswith(f"{name} = ")]
    text = "\n".join(lines).replace("[model]", f"[model]\n{change}") + "\n"
    problems = problems_of(tmp_path, text)
    assert any(f": {field}: " in line and words in line for line in problems), problems


def test_physical_table_converting_beyond_the_domain_names_the_value(tmp_path):
    """k_s / k_r = 1e150 is a finite K, valid alone, beyond the domain: named as converted."""
    text = replace(replace(PHYSICAL, "k_r = 4.0e4", "k_r = 1e-100"), "k_s = 8.0e5", "k_s = 1e50")
    problems = problems_of(tmp_path, text)
    assert any(": physical: converts to K = 1e+150: " in line for line in problems), problems


def test_start_state_beyond_the_domain_is_refused(tmp_path):
    problems = problems_of(tmp_path, replace(MINIMAL, "x = 0.88544", "x = 1e150"))
    assert any(": initial.x: must be at most 1e+100" in line for line in problems), problems


def _two_axes(first: str, second: str) -> str:
    return (
        MINIMAL
        + f"""
[[sweep.axes]]
parameter = "{first}"
values = [0.1, 0.2]
[[sweep.axes]]
parameter = "{second}"
values = [0.3, 0.4]
"""
    )


@pytest.mark.parametrize(
    ("first", "second"),
    [
        ("offset", "offset_x"),
        ("offset_y", "offset"),
        ("load", "load_y"),
        ("k_xy", "cross_coupling"),
    ],
)
def test_sweep_axes_that_set_the_same_entry_are_refused(tmp_path, first, second):
    """offset and offset_x together: offset_x overrides the offset's c_x at every point,
    so the offset axis would change nothing (identical rows). Two components are not an
    overlap."""
    (line,) = problems_of(tmp_path, _two_axes(first, second))
    assert "sweep" in line and first in line and second in line and "overrides" in line
    assert load_case(write(tmp_path, _two_axes("offset_x", "offset_y"))).settings.sweep

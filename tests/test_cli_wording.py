"""What the command line says: help texts that show flags as flags and state what --quick
does, tables that fit the width of a pipe, counts that say what the CSV says, tables in
the order of the parameter. No solving: each check runs on the text or on small objects."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from rubcli.cli import orbits, tables
from rubcli.cli.app import app
from rubcli.studies import compare as compare_study
from rubcli.studies import sweep

runner = CliRunner()

COMMANDS = ("run", "compare", "sweep", "orbits", "stress", "forces-map", "validate", "init")


@pytest.mark.parametrize("command", COMMANDS)
def test_help_lists_flags_without_a_value_type(command):
    result = runner.invoke(app, [command, "--help"], env={"COLUMNS": "120"})
    assert result.exit_code == 0
    assert "<bool>" not in result.output  # a flag takes no value
    assert "--help" in result.output


def test_compare_quick_help_and_report_state_the_spans_it_runs():
    result = runner.invoke(app, ["compare", "--help"], env={"COLUMNS": "200"})
    text = " ".join(result.output.split())
    assert "5-period horizon" not in text
    assert f"each orbit over at most {compare_study.QUICK_ORBIT_PERIODS:g}" in text
    assert f"work-precision over at most {compare_study.QUICK_HORIZON_PERIODS:g}" in text
    # report.md states the span the orbits were solved over, not the case's [time] periods
    quick = compare_study.QUICK_ORBIT_PERIODS
    panels = [SimpleNamespace(problem=SimpleNamespace(periods=quick))] * 2
    assert compare_study._orbit_periods(panels) == f"{quick:g}"


ROWS = [
    ["neimark_sacker", "0.01028723043", "yes", "1.23387",
     "1.000000, 1.000000, 0.858691, 0.858691",
     "critical pair 0.619044 +- 0.785357i, angle 51.75 deg, and a long note after it"],
    ["fold", "1.2463288", "yes", "1.37", "1.000000, 0.5", "short"],
]  # fmt: skip


@pytest.mark.parametrize(("columns", "width"), [(None, tables.DEFAULT_WIDTH), ("72", 72)])
def test_tables_fit_the_width_when_stdout_is_not_a_terminal(capsys, monkeypatch, columns, width):
    if columns is None:
        monkeypatch.delenv("COLUMNS", raising=False)
    else:
        monkeypatch.setenv("COLUMNS", columns)
    tables.table("bifurcations along mu", ["kind", "mu", "located", "max z", "|m|", "note"], ROWS)
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert max(len(line.rstrip()) for line in lines) <= width
    for number in ("0.01028723043", "1.2463288", "1.23387"):  # numbers are never cut
        assert number in out
    words = out.split()
    for word in ROWS[0][5].split():  # the note wraps at spaces, no word is lost or cut
        assert word in words


def test_a_table_of_numbers_wider_than_the_width_is_widened_not_cut(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "20")
    tables.table("t", ["a", "b"], [["1.234567890123", "9.876543210987"]])
    out = capsys.readouterr().out
    assert "1.234567890123" in out and "9.876543210987" in out


def _bifurcation(kind: str, value: float):
    point = SimpleNamespace(max_z=1.0, multipliers=np.array([1.0, 0.5]))
    return SimpleNamespace(kind=kind, parameter=value, located=True, point=point, note="")


def test_bifurcation_table_is_in_increasing_order_of_the_parameter():
    # continuation meets them in branch order: up from the start, then down
    found = [_bifurcation("grazing", 1.0378), _bifurcation("fold", 1.2463),
             _bifurcation("grazing", 0.9706), _bifurcation("fold", 0.5)]  # fmt: skip
    rows = orbits.summary_lines(SimpleNamespace(bifurcations=found))
    values = [float(r[1]) for r in rows]
    assert values == sorted(values) == [0.5, 0.9706, 1.0378, 1.2463]


def _classes(codes, lyapunov) -> xr.Dataset:
    n = len(codes)
    return xr.Dataset(
        {
            "status": (("direction", "eta"), np.zeros((1, n), dtype=np.int8)),
            "response_class": (("direction", "eta"), np.array([codes], dtype=float)),
            "lyapunov": (("direction", "eta"), np.array([lyapunov], dtype=float)),
        },
        coords={"direction": ["up"], "eta": np.arange(n, dtype=float)},
    )


def test_sweep_counts_chaos_without_an_exponent_as_unconfirmed():
    nan = float("nan")
    # 0 periodic, 2 chaotic (RESPONSE_CLASSES order): two without an exponent, one with
    lines = dict(sweep.class_lines(_classes([0, 2, 2, 2], [nan, nan, nan, 0.05])))
    assert lines["periodic"] == 1
    assert lines[sweep.UNCONFIRMED] == 2
    assert lines["chaotic (positive Lyapunov exponent)"] == 1
    assert "chaotic" not in lines
    # every chaotic point confirmed: printed as the report counts them
    assert dict(sweep.class_lines(_classes([2], [0.05]))) == {"chaotic": 1}

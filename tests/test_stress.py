"""`rubcli stress --quick` through the real CLI, and the suite's make-up.

Asserted as statuses, never as wall-clock limits: every run of every case ends with a
clean status (``success``, or ``failed`` with a reason: a budget, a switch storm), no
state is non-finite, every case finds a reference, and the files are complete.
"""

from __future__ import annotations

import csv
import math

import pytest
from typer.testing import CliRunner

from rubcli import model
from rubcli.analysis import stress
from rubcli.cli.app import app
from rubcli.solvers import METHODS


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("stress") / "quick"
    result = CliRunner().invoke(app, ["stress", "--quick", "--out", str(out)])
    with open(out / "stress.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    return result, out, rows


def test_quick_suite_ends_cleanly_everywhere(quick_run):
    result, out, rows = quick_run
    assert result.exit_code == 0, result.output
    cases = stress.stress_cases()
    variants = stress.method_variants(METHODS)
    assert len(rows) == len(cases) * len(variants)
    assert {(r["case"], r["method"]) for r in rows} == {
        (c.name, label) for c in cases for label, _, _ in variants
    }
    for row in rows:
        where = f"{row['case']} / {row['method']}: {row['message']}"
        assert row["status"] in ("success", "failed"), where
        assert row["message"], where
        assert row["nan"] == "0", where
        assert float(row["periods"]) <= float(row["target_periods"]) * (1 + 1e-12), where
        if row["status"] == "success":
            assert float(row["periods"]) == pytest.approx(float(row["target_periods"])), where
            assert math.isfinite(float(row["energy_residual"])), where
        else:
            # a budget or the storm guard: a failure that says why, never a hang
            assert "budget exhausted" in row["message"] or "storm" in row["message"], where


def test_quick_suite_measures_every_case_against_a_reference(quick_run):
    _, _, rows = quick_run
    by_case: dict[str, list[dict]] = {}
    for row in rows:
        by_case.setdefault(row["case"], []).append(row)
    for case, case_rows in by_case.items():
        labels = {r["reference"] for r in case_rows if r["reference"]}
        assert len(labels) == 1, case  # one reference per case, named
        if case.startswith("sync") or case == "long-horizon":
            assert labels == {"exact sync rub"}
        if case.startswith("grazing"):
            assert labels == {"exact free flight (touching)"}
    # on exact references dop853 (rtol 1e-8) is accurate where it reports an error; the
    # stiff touch amplifies its rtol-level error to ~3e-6 (a contact its error creates)
    exact_dop853 = [
        r
        for r in rows
        if r["method"] == "dop853" and r["reference"].startswith("exact") and r["error"]
    ]
    assert len(exact_dop853) >= 6
    for row in exact_dop853:
        assert float(row["error"]) < 1e-5, row["case"]


def test_quick_suite_writes_a_readable_table(quick_run):
    _, out, rows = quick_run
    text = (out / "stress.md").read_text()
    assert text.startswith("# rubcli stress (quick)")
    assert "`rubcli stress --quick`" in text
    for case in stress.stress_cases():
        assert f"| {case.name} |" in text
    assert text.count("\n| ") >= len(rows) + len(stress.stress_cases())


def test_suite_covers_the_extremes_of_the_issue():
    cases = stress.stress_cases()
    Ks = {c.params.K for c in cases}
    assert {17.6, 1.76e3, 1.76e5, 1.75e6} <= Ks
    mus = {c.params.mu for c in cases}
    assert min(mus) == 0.0 and max(mus) == 0.1
    assert any(c.params.nu == 0.0 for c in cases)
    assert max(c.periods for c in cases) == 10_000
    assert max(c.params.e for c in cases) >= 46.16
    starts = [math.hypot(c.initial[0], c.initial[1]) for c in cases]
    assert max(starts) >= 2.0  # deep inside the stator
    whip = next(c for c in cases if c.name == "dry-whip")
    assert model.regime_of_state(whip.initial, whip.params) == model.STICK
    assert sum(c.touches for c in cases) == 2
    for c in cases:
        assert c.quick_periods < c.periods


def test_warnings_flag_a_wrong_success():
    run = stress.StressRun("c", "m", "success", "ok", 0.1, 1.0, 1.0)
    assert stress.warning_of(run, exact_reference=True) == ""
    run.energy_residual = 0.2
    assert "energy residual 0.2" in stress.warning_of(run, exact_reference=False)
    run.energy_residual, run.error = 1e-9, 0.5
    assert stress.warning_of(run, exact_reference=False) == ""  # chaos: not a verdict
    assert "error 0.5 against the exact solution" in stress.warning_of(run, exact_reference=True)
    run.status = "failed"
    assert stress.warning_of(run, exact_reference=True) == ""  # already says it failed


def test_unknown_case_or_method_is_invalid_input(tmp_path):
    runner = CliRunner()
    result = runner.invoke(app, ["stress", "--quick", "--case", "nope", "--out", str(tmp_path)])
    assert result.exit_code == 2 and "unknown case" in result.stderr
    result = runner.invoke(app, ["stress", "--quick", "--method", "euler", "--out", str(tmp_path)])
    assert result.exit_code == 2 and "unknown method" in result.stderr
    assert not (tmp_path / "stress.csv").exists()

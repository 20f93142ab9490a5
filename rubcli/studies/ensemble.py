"""An ensemble of runs (``rubcli ensemble``), as a library study: ``ensemble_of(case)``
returns an ``EnsembleStudy``, whose ``write(directory)`` writes ``ensemble.csv``,
``ensemble.png`` and ``report.json`` in one atomic commit (``rubcli.io``). The numerics
are ``rubcli.analysis.ensembles.ensemble``; the table is the case's ``[ensemble]``
(docs/reproduction.md). Along ``[ensemble] parameter`` the study is
``rubcli.studies.basin_stability``'s."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rubcli import io
from rubcli.analysis.ensembles import ensemble as en
from rubcli.case import Case
from rubcli.solvers import wall_time_deadline

FILES = ("ensemble.csv", "ensemble.png", "report.json")
# --quick: a CI run of a few seconds
QUICK = {"runs": 4, "periods": 300, "record_periods": 100, "lyapunov_periods": 50}
COLUMNS = ("run", "method", "rtol", "start_offset", "attractor", "regime", "kind", "settled",
           "settle_period", "contact_fraction", "stick_fraction", "whirl_order", "z_max",
           "lyapunov", "lyapunov_stderr", "contraction_rate", "rotation_number", "ok",
           "message")  # fmt: skip


def settings_of(case: Case, quick: bool = False) -> tuple[dict, list[str]]:
    """The ensemble's settings from the case (and ``quick``), or the problems with it."""
    src, e = case.source, case.settings.ensemble
    if e is None:
        return {}, [f"{src}: ensemble: missing table [ensemble] (docs/reproduction.md)"]
    s = e.model_dump()
    s["periods"] = s["periods"] or int(round(case.problem.periods))
    s["methods"] = s["methods"] or case.methods[:1]
    s["rtols"] = s["rtols"] or [case.settings.solver.rtol]
    if quick:
        s.update({k: min(s[k], v) for k, v in QUICK.items()})
    if not s["record_periods"] < s["periods"]:
        return s, [f"{src}: ensemble.record_periods: {s['record_periods']} must be below "
                   f"the periods run ({s['periods']})"]  # fmt: skip
    return s, []


@dataclass
class EnsembleStudy:
    """An ensemble with what produced it; ``write`` puts it in a directory."""

    case: Case
    settings: dict
    starts: np.ndarray | None  # the box's starts, or None for a cloud about the case's
    result: en.EnsembleResult
    wall_time_s: float

    def report(self, command_line: dict[str, Any]) -> dict[str, Any]:
        return {
            **io.report_envelope("ensemble", command_line, self.case.to_dict()),
            "wall_time_s": self.wall_time_s,
            **self.result.to_dict(),
            "members": [m.to_dict() for m in self.result.members],
        }

    def rows(self) -> list[list[Any]]:
        """One row of ``COLUMNS`` per run."""
        return [[m.index, m.method, m.rtol, m.offset, m.attractor, m.regime, m.kind,
                 m.settled, m.settle_period, m.contact_fraction, m.stick_fraction,
                 m.whirl_order, m.z_max, m.lyapunov, m.lyapunov_stderr, m.contraction_rate,
                 m.rotation_number, m.ok, m.message]
                for m in self.result.members]  # fmt: skip

    def title(self) -> str:
        s, p = self.settings, self.case.params
        if self.starts is None:
            where = f"starts within {s['spread']:g}"
        else:
            box = self.case.settings.ensemble.box()
            where = "starts in a box: " + ", ".join(
                f"{k} in [{v[0]:g}, {v[1]:g}]" for k, v in box.items() if v
            )
        runs = len(self.result.members)
        return (f"{self.case.name}: {runs} runs of {s['periods']} periods, mu = {p.mu:g}, "
                f"eta = {p.eta:g}, e = {p.e:g}, {where}")  # fmt: skip

    def write(
        self, directory: str | Path, plan: io.OutputPlan | None = None,
        command_line: dict[str, Any] | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Write the outputs into ``directory`` as one commit (``plan``: the dir as the
        caller opened and checked it; without one it is opened here); returns the report.
        The figure is drawn only when a run succeeded."""
        report = self.report(command_line or {"out": str(directory)})
        with io.staged_output_dir(directory, plan) as staged:
            io.write_rows_csv(staged.path("ensemble.csv"), COLUMNS, self.rows(), nonfinite="")
            if self.result.good:
                from rubcli.plotting.ensemble import ensemble_figure

                io.save_figure(ensemble_figure(self.result, self.title()),
                               staged.path("ensemble.png"))  # fmt: skip
            report["files"] = staged.names() + ["report.json"]
            staged.write_report(report)
        return report


def ensemble_of(
    case: Case,
    *,
    quick: bool = False,
    workers: int = 1,
    progress: Callable[[int], None] | None = None,
    max_wall_time_s: float | None = None,
) -> EnsembleStudy:
    """The case's ``[ensemble]``: its runs from a cloud (or a box) of starts at every
    setting of its tolerance ladder, each end classified and named (``quick``: at most 4
    runs of 300 periods); ``progress(done)`` after each run. ValueError if the table
    cannot be run (its message names the file and the field).

    The whole is bounded by ``[ensemble] max_wall_time_s`` (``max_wall_time_s``: a budget
    instead of the table's; None in both: no budget but each run's): checked after every
    run, each solve getting at most the time left;
    ``rubcli.analysis.orbits.periodic.WallTimeBudgetError`` once it is spent (TypeError or
    ValueError naming ``max_wall_time_s`` for a budget that is not a number > 0)."""
    s, problems = settings_of(case, quick)
    if problems:
        raise ValueError("\n".join(problems))
    deadline = wall_time_deadline("ensemble_of()", budget_of(case, max_wall_time_s))
    started = time.perf_counter()
    e = case.settings.ensemble
    starts = (en.box_starts(case.problem.initial, e.box(), s["runs"], s["seed"])
              if s["starts"] == "box" else None)  # fmt: skip
    tasks = en.member_tasks(
        case.params, case.problem.initial, runs=s["runs"], spread=s["spread"], seed=s["seed"],
        methods=s["methods"], rtols=s["rtols"], options=case.solver_options,
        periods=s["periods"], samples_per_period=case.settings.time.samples_per_period,
        record_periods=s["record_periods"], lyapunov=s["lyapunov"],
        lyapunov_periods=s["lyapunov_periods"], settle_tolerance=s["settle_tolerance"],
        starts=starts, deadline=deadline,
    )  # fmt: skip
    result = en.run_ensemble(tasks, workers=max(1, min(workers, len(tasks))), progress=progress,
                             settings=s)  # fmt: skip
    return EnsembleStudy(case, s, starts, result, time.perf_counter() - started)


def budget_of(case: Case, max_wall_time_s: float | None = None) -> float | None:
    """The ensemble's wall-time budget: ``max_wall_time_s``, else ``[ensemble]
    max_wall_time_s`` (None: none)."""
    e = case.settings.ensemble
    return e.max_wall_time_s if max_wall_time_s is None and e is not None else max_wall_time_s


def run_count(settings: dict) -> int:
    """The runs an ensemble of these settings makes: its starts at every method and
    tolerance of its ladder."""
    return settings["runs"] * len(settings["methods"]) * len(settings["rtols"])

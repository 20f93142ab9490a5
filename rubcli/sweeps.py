"""``rubcli.sweep(case, ...)``: a case's ``[sweep]`` as an ``xarray.Dataset``.

The Python side of ``rubcli sweep`` (docs/sweeps.md)::

    import rubcli

    ds = rubcli.sweep("cases/examples/run-up.toml", workers=2)
    ds["section_z"].sel(direction="up").plot.line(x="eta", add_legend=False)

The engine is ``rubcli.analysis.sweep``; this module turns a case into its plan.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rubcli import case as case_module
from rubcli.analysis.sweep import SweepPlan, close_client, connect, execute
from rubcli.analysis.sweep.attractors import Recognition
from rubcli.analysis.sweep.plan import INITIAL_AXES, Axis

if TYPE_CHECKING:
    import xarray as xr
    from distributed import Client

# --quick: every axis thinned to at most this many values (its ends kept), short runs.
QUICK_VALUES = 5
QUICK_TRANSIENT_PERIODS = 20
QUICK_RECORD_PERIODS = 16
QUICK_LYAPUNOV_PERIODS = 20


def _thin(values: tuple[float, ...], n: int) -> tuple[float, ...]:
    if len(values) <= n:
        return values
    picks = np.unique(np.round(np.linspace(0, len(values) - 1, n)).astype(int))
    return tuple(values[i] for i in picks)


def plan_from_case(case: case_module.Case, quick: bool = False) -> SweepPlan:
    """The sweep plan of a case with a ``[sweep]`` table (ValueError if it has none)."""
    cfg = case.settings.sweep
    if cfg is None:
        raise ValueError(f"{case.source}: no [sweep] table")
    from rubcli.solvers import options_for

    axes = []
    for axis in cfg.resolved_axes():
        values = tuple(sorted(axis.resolved_values()))
        if quick:
            values = _thin(values, QUICK_VALUES)
        axes.append(Axis(axis.parameter, values))
    transient, record = cfg.transient_periods, cfg.record_periods
    if quick:
        transient = min(transient, QUICK_TRANSIENT_PERIODS)
        record = min(record, QUICK_RECORD_PERIODS)
    options = options_for(cfg.method, case.solver_options)
    basin = axes[0].parameter in INITIAL_AXES
    recognition = None
    if basin and cfg.recognition.enabled:
        recognition = Recognition(**cfg.recognition.model_dump(exclude={"enabled"}))
    return SweepPlan(
        params=case.params,
        initial=case.problem.initial
        + (case.problem.stator_initial if case.params.stator is not None else ()),
        axes=tuple(axes),
        direction=cfg.direction,
        transient_periods=transient,
        record_periods=record,
        samples_per_period=case.settings.time.samples_per_period,
        method=cfg.method,
        options=options,
        energy=cfg.energy,
        spectrum=cfg.spectrum,
        spectrum_max_order=cfg.spectrum_max_order,
        lyapunov=cfg.lyapunov,
        lyapunov_periods=min(cfg.lyapunov_periods, QUICK_LYAPUNOV_PERIODS)
        if quick
        else cfg.lyapunov_periods,
        name=case.name,
        recognition=recognition,
    )


def case_attrs(case: case_module.Case) -> dict:
    """Attributes of the dataset: the case echoed and the package versions."""
    from rubcli import io

    versions = io.environment_info()
    for name in ("xarray", "h5netcdf", "numba"):
        with contextlib.suppress(ImportError):
            versions[name] = __import__(name).__version__
    return {
        "case": json.dumps(case.settings.model_dump(mode="json"), sort_keys=True),
        "versions": json.dumps(versions, sort_keys=True),
        "source": case.source,
    }


def _check_arguments(workers, client, scheduler, quick, store_dir, oversubscribe) -> None:
    """TypeError naming the first of ``sweep``'s arguments of the wrong type (the value of
    ``workers`` is checked where the processes start, ``check_workers``)."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)):
        raise TypeError(f"sweep(): workers must be an int or None, got {type(workers).__name__}")
    for name, value in (("quick", quick), ("oversubscribe", oversubscribe)):
        if not isinstance(value, bool | np.bool_):
            raise TypeError(f"sweep(): {name} must be True or False, got {type(value).__name__}")
    if store_dir is not None and not isinstance(store_dir, str | os.PathLike):
        raise TypeError(
            f"sweep(): store_dir must be a path (a str or a Path) or None, got "
            f"{type(store_dir).__name__}"
        )
    if store_dir is not None and "\0" in str(store_dir):
        raise ValueError("sweep(): store_dir holds a NUL byte (\\0), which no file name may hold")
    if scheduler is not None and not isinstance(scheduler, str):
        raise TypeError(
            f"sweep(): scheduler must be an address (a str) or None, got {type(scheduler).__name__}"
        )
    if client is not None:
        try:
            from distributed import Client
        except ImportError:
            Client = ()  # noqa: N806 (without distributed nothing is a Client)
        if not isinstance(client, Client):
            raise TypeError(
                f"sweep(): client must be a distributed.Client or None, got {type(client).__name__}"
            )


def sweep(
    case: str | Path | case_module.Case,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    client: Client | None = None,
    quick: bool = False,
    store_dir: str | Path | None = None,
    oversubscribe: bool = False,
) -> xr.Dataset:
    """Run the ``[sweep]`` of ``case`` (a path or a loaded Case); returns an xarray.Dataset
    (for a basin grid with recognition, ``basins.build_dataset``'s: one attractor label
    per start).

    ``workers`` local processes (default all cores, 1 = in this process), or a Dask
    ``client`` / ``scheduler`` address (default: ``[sweep] scheduler``). ``store_dir``
    keeps finished points for resumption (none by default: the Python call is one run).
    More ``workers`` than cores is a ValueError unless ``oversubscribe``. An argument of
    the wrong type (``quick="no"``, ``store_dir=5``) is a TypeError naming it.
    """
    from rubcli.analysis.sweep.dataset import build_dataset

    _check_arguments(workers, client, scheduler, quick, store_dir, oversubscribe)
    if not isinstance(case, case_module.Case):
        case = case_module.load_case(case)
    plan = plan_from_case(case, quick)
    cfg = case.settings.sweep
    assert cfg is not None
    if client is None and scheduler is None:
        scheduler = cfg.scheduler
    own = None
    if client is None and scheduler is not None:
        client = own = connect(scheduler, timeout=cfg.scheduler_timeout_s)
    try:
        results, _stats, _where = execute(
            plan, workers=workers, client=client, store_dir=store_dir,
            oversubscribe=oversubscribe, lost_timeout_s=cfg.scheduler_lost_timeout_s,
        )  # fmt: skip
    finally:
        if own is not None:
            close_client(own)
    if plan.recognition is not None:
        from rubcli.analysis.sweep import basins

        return basins.build_dataset(plan, results, case_attrs(case))
    return build_dataset(plan, results, case_attrs(case))

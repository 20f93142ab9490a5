"""The results of a sweep as an ``xarray.Dataset``, and its NetCDF and CSV files.

Dimensions: ``direction`` ("up"/"down", or "independent"), one per swept axis (named after
the parameter; ``x0``, ``y0`` ... for an initial-state grid), ``section`` (the recorded
forcing periods 1 ... record_periods) and, with ``spectrum = true``, ``order`` (the full
spectrum's lines in orders of the running speed).
"""

from __future__ import annotations

import csv
import io as _io
import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rubcli.analysis.sweep.plan import STATE_NAMES, SweepPlan, point_key
from rubcli.analysis.sweep.point import (
    RESPONSE_CLASSES,
    SCALARS,
    WHOLE,
    PointResult,
    spectrum_orders,
)

if TYPE_CHECKING:
    import xarray as xr

STATUS_OK, STATUS_FAILED = 0, 1
SECTION_VARIABLES = ("x", "y", "vx", "vy", "z")


def build_dataset(
    plan: SweepPlan, results: dict[str, PointResult], attrs: dict | None = None
) -> xr.Dataset:
    """All points of ``plan`` (every one must be in ``results``) as an xarray Dataset."""
    import xarray as xr

    directions = plan.directions
    shape = (len(directions), *plan.shape)
    dims = ("direction", *(a.dim for a in plan.axes))
    record = plan.record_periods
    scalars = {name: np.full(shape, np.nan) for name in SCALARS}
    section = np.full((*shape, record, 4), np.nan)
    status = np.full(shape, STATUS_FAILED, dtype=np.int8)
    messages = np.full(shape, "", dtype=object)
    orders = spectrum_orders(record, plan.spectrum_max_order) if plan.spectrum else None
    spectrum = np.full((*shape, orders.size), np.nan) if orders is not None else None
    for d, direction in enumerate(directions):
        for index in np.ndindex(*plan.shape):
            result = results[point_key(direction, index)]
            at = (d, *index)
            status[at] = STATUS_OK if result.ok else STATUS_FAILED
            messages[at] = result.message
            for name in SCALARS:
                scalars[name][at] = result.scalar(name)
            if result.ok and result.section.shape == (record, 4):
                section[at] = result.section
            if spectrum is not None and result.spectrum is not None:
                spectrum[at] = result.spectrum
    coords = {"direction": list(directions), "section": np.arange(1, record + 1)}
    for axis in plan.axes:
        coords[axis.dim] = np.asarray(axis.values)
    data = {}
    for name, values in scalars.items():
        data[name] = (dims, values, {"long_name": SCALARS[name]})
    for i, name in enumerate(STATE_NAMES):
        data[f"section_{name}"] = (
            (*dims, "section"),
            section[..., i],
            {"long_name": f"stroboscopic {name} at the end of each recorded forcing period"},
        )
    data["section_z"] = (
        (*dims, "section"),
        np.hypot(section[..., 0], section[..., 1]),
        {"long_name": "stroboscopic z = |x + i y| at the end of each recorded forcing period"},
    )
    data["status"] = (dims, status, {"long_name": "0 ok, 1 failed"})
    data["message"] = (dims, messages.astype(str), {"long_name": "classifier or failure message"})
    if spectrum is not None:
        coords["order"] = orders
        data["spectrum"] = (
            (*dims, "order"),
            spectrum,
            {"long_name": "full-spectrum amplitude of x + i y (clearances) at each order"},
        )
    ds = xr.Dataset(data, coords=coords)
    ds["response_class"].attrs["flag_meanings"] = " ".join(RESPONSE_CLASSES)
    ds.attrs.update(
        {
            "title": f"rubcli sweep: {plan.name}",
            "plan": json.dumps(plan.to_dict(), sort_keys=True),
            "plan_digest": plan.digest(),
        }
    )
    if attrs:
        ds.attrs.update({k: v if isinstance(v, str) else json.dumps(v) for k, v in attrs.items()})
    return ds


def write_netcdf(ds: xr.Dataset, path: str | Path) -> Path:
    """NetCDF4 through h5netcdf (the caller writes into a staging dir)."""
    ds.to_netcdf(path, engine="h5netcdf")
    return Path(path)


def csv_text(ds: xr.Dataset, plan: SweepPlan) -> str:
    """One row per point and direction: axis values, scalar results, status, message."""
    buffer = _io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    axes = [a.dim for a in plan.axes]
    names = list(SCALARS)
    writer.writerow(["direction", *axes, *names, "status", "message"])
    coords = [ds[a].values for a in axes]
    columns = {name: ds[name].values for name in names}
    status, message = ds["status"].values, ds["message"].values
    for d, direction in enumerate(ds["direction"].values):
        for index in np.ndindex(*plan.shape):
            at = (d, *index)
            row = [str(direction)]
            row += [_number(float(c[i])) for c, i in zip(coords, index, strict=True)]
            for name in names:
                value = float(columns[name][at])
                row.append(_whole(value) if name in WHOLE else _number(value))
            row.append("ok" if int(status[at]) == STATUS_OK else "failed")
            row.append(str(message[at]))
            writer.writerow(row)
    return buffer.getvalue()


def _number(value: float) -> str:
    return "" if not np.isfinite(value) else repr(float(value))  # shortest exact form


def _whole(value: float) -> str:
    return "" if not np.isfinite(value) else str(int(value))

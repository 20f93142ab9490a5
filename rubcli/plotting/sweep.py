"""Figures of a sweep (from its xarray Dataset): bifurcation diagram, summary, full-spectrum
cascade, 2-D maps and basins of attraction. They only draw; the numbers come from
``rubcli.analysis.sweep``. Built on the Agg canvas (no pyplot), saved with io.save_figure.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from rubcli.analysis.sweep.point import RESPONSE_CLASSES

DIRECTION_COLOURS = {"up": "tab:blue", "down": "tab:orange", "independent": "tab:blue"}
# RESPONSE_CLASSES order: periodic ... undecided, converging
CLASS_COLOURS = ("tab:green", "tab:blue", "tab:red", "black", "0.75", "tab:cyan")
WHIRL_COLOURS = {-1: "tab:purple", 0: "0.8", 1: "tab:olive"}
WHIRL_NAMES = {-1: "backward", 0: "no whirl", 1: "forward"}
AXIS_LABELS = {
    "eta": "speed ratio eta = Omega/omega (-)",
    "mu": "friction coefficient mu (-)",
    "K": "stiffness ratio K (-)",
    "e": "unbalance e (clearances)",
    "nu": "damping ratio nu (-)",
    "Rp": "rotor radius Rp (clearances)",
    "phi0": "unbalance phase phi0 (rad)",
    "x0": "start x (clearances)",
    "y0": "start y (clearances)",
    "vx0": "start vx (clearances per unit tau)",
    "vy0": "start vy (clearances per unit tau)",
}


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _class_note(ds) -> str:
    """How the classes were decided: with Lyapunov exponents or the section alone."""
    if np.isfinite(ds["lyapunov"].values).any():
        return ""
    return "\n(no Lyapunov exponents: chaos never claimed; tori from the section's frequencies)"


def _axes_dims(ds) -> list[str]:
    return [d for d in ds["status"].dims if d != "direction"]


def _label(dim: str) -> str:
    return AXIS_LABELS.get(dim, dim)


def _marker_size(n_points: int) -> float:
    return float(np.clip(3000.0 / max(n_points, 1), 0.3, 6.0))


def bifurcation_figure(ds, title: str) -> Figure:
    """Stroboscopic z and x against the swept parameter; up and down in two colours."""
    (dim,) = _axes_dims(ds)
    p = ds[dim].values
    fig = _new_figure(9.0, 7.0)
    axes = fig.subplots(2, 1, sharex=True)
    n_dirs = ds.sizes["direction"]
    size = _marker_size(ds.sizes["section"] * p.size * n_dirs / 20.0)
    for ax, var, ylabel in (
        (axes[0], "section_z", "stroboscopic z = |x + i y| (clearances)"),
        (axes[1], "section_x", "stroboscopic x (clearances)"),
    ):
        for k, direction in enumerate(ds["direction"].values):
            sub = ds[var].sel(direction=direction).values  # (n, section)
            # a small offset keeps the two directions side by side where they coincide
            shift = 0.0 if n_dirs == 1 else (k - 0.5) * 0.15 * np.min(np.diff(p), initial=0.0)
            xs = np.repeat(p + shift, sub.shape[1])
            ax.scatter(
                xs, sub.ravel(), s=size, color=DIRECTION_COLOURS.get(str(direction), "k"),
                alpha=0.8, linewidths=0, label=f"sweep {direction}",
            )  # fmt: skip
        failed = (ds["status"].values != 0).any(axis=0)
        if failed.any():
            lo = np.nanmin(ds[var].values) if np.isfinite(ds[var].values).any() else 0.0
            ax.scatter(p[failed], np.full(failed.sum(), lo), marker="x", color="red", s=30,
                       label="failed point")  # fmt: skip
        if var == "section_z":
            ax.axhline(1.0, color="0.3", linestyle="--", linewidth=0.8, label="clearance z = 1")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), markerscale=3, fontsize=8)
    axes[1].set_xlabel(_label(dim))
    fig.suptitle(title, fontsize=10)
    return fig


def summary_figure(ds, title: str) -> Figure:
    """Contact/stick fraction, z range, whirl order with direction, class, Lyapunov."""
    (dim,) = _axes_dims(ds)
    p = ds[dim].values
    lyap = np.isfinite(ds["lyapunov"].values).any()
    rows = 5 if lyap else 4
    fig = _new_figure(9.0, 2.2 * rows + 0.8)
    axes = fig.subplots(rows, 1, sharex=True)
    for direction in ds["direction"].values:
        d = ds.sel(direction=direction)
        colour = DIRECTION_COLOURS.get(str(direction), "k")
        axes[0].plot(p, d["contact_fraction"], "-", color=colour, label=f"contact, {direction}")
        axes[0].plot(p, d["stick_fraction"], ":", color=colour, label=f"stick, {direction}")
        axes[1].plot(p, d["z_max"], "-", color=colour, label=f"max z, {direction}")
        axes[1].plot(p, d["z_min"], "--", color=colour, label=f"min z, {direction}")
        order = d["whirl_order"].values
        whirl = d["whirl_direction"].values
        axes[2].plot(p, order, "-", color=colour, linewidth=0.6, alpha=0.6)
        for code, marker in ((1, "^"), (-1, "v"), (0, "o")):
            sel = whirl == code
            if sel.any():
                axes[2].scatter(p[sel], order[sel], marker=marker, s=14, color=colour,
                                label=f"{WHIRL_NAMES[code]}, {direction}")  # fmt: skip
        axes[3].scatter(p, d["response_class"], s=14, color=colour, label=str(direction))
        if lyap:
            axes[4].errorbar(p, d["lyapunov"], yerr=d["lyapunov_stderr"], fmt=".", color=colour,
                             label=str(direction))  # fmt: skip
    axes[0].set_ylabel("time fraction (-)")
    axes[0].set_ylim(-0.05, 1.05)
    axes[1].axhline(1.0, color="0.3", linestyle="--", linewidth=0.8, label="clearance")
    axes[1].set_ylabel("z (clearances)")
    axes[2].axhline(0.0, color="0.3", linewidth=0.6)
    axes[2].set_ylabel("dominant whirl (orders of eta)")
    axes[3].set_yticks(range(len(RESPONSE_CLASSES)), RESPONSE_CLASSES)
    axes[3].set_ylim(-0.5, len(RESPONSE_CLASSES) - 0.5)
    axes[3].set_ylabel("response class")
    if _class_note(ds):
        axes[3].set_title(_class_note(ds).strip(), fontsize=8)
    if lyap:
        axes[4].axhline(0.0, color="0.3", linewidth=0.6)
        axes[4].set_ylabel("largest Lyapunov exponent (1/tau)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1].set_xlabel(_label(dim))
    fig.suptitle(title, fontsize=10)
    return fig


def cascade_figure(ds, title: str, floor_db: float = -80.0) -> Figure:
    """Full-spectrum cascade: amplitude (dB of the largest line) by order and parameter."""
    (dim,) = _axes_dims(ds)
    p = ds[dim].values
    dirs = list(ds["direction"].values)
    fig = _new_figure(5.0 * len(dirs) + 1.5, 6.0)
    axes = np.atleast_1d(fig.subplots(1, len(dirs), sharey=True))
    orders = ds["order"].values
    spec = ds["spectrum"].values
    peak = np.nanmax(spec) if np.isfinite(spec).any() else 1.0
    image = None
    for ax, direction in zip(axes, dirs, strict=True):
        amp = ds["spectrum"].sel(direction=direction).values
        db = 20.0 * np.log10(np.maximum(amp / peak, 10 ** (floor_db / 20.0)))
        image = ax.pcolormesh(orders, p, db, shading="nearest", cmap="viridis",
                              vmin=floor_db, vmax=0.0)  # fmt: skip
        ax.set_title(f"sweep {direction}: backward (< 0) | forward (> 0)", fontsize=9)
        ax.set_xlabel("whirl frequency (orders of the running speed, 1X = eta)")
    axes[0].set_ylabel(_label(dim))
    if image is not None:
        fig.colorbar(image, ax=list(axes), label="amplitude of x + i y (dB of the largest line)")
    fig.suptitle(title, fontsize=10)
    return fig


def _categorical(ax, values, x, y, colours, names, title):
    cmap = ListedColormap(colours)
    norm = BoundaryNorm(np.arange(len(colours) + 1) - 0.5, len(colours))
    masked = np.ma.masked_invalid(values)
    ax.pcolormesh(x, y, masked.T, cmap=cmap, norm=norm, shading="nearest")
    present = sorted({int(v) for v in values[np.isfinite(values)]})
    handles = [Patch(color=colours[i], label=names[i]) for i in present]
    if np.isnan(values).any():
        handles.append(Patch(facecolor="white", edgecolor="k", label="failed"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax.set_title(title, fontsize=9)


def map_figure(ds, title: str) -> Figure:
    """A 2-D sweep: response class, whirl direction and max z as colour maps."""
    dim_x, dim_y = _axes_dims(ds)
    x, y = ds[dim_x].values, ds[dim_y].values
    dirs = list(ds["direction"].values)
    fig = _new_figure(16.0, 4.2 * len(dirs) + 0.6)
    grid = fig.subplots(len(dirs), 3, squeeze=False)
    for row, direction in zip(grid, dirs, strict=True):
        d = ds.sel(direction=direction)
        ok = d["status"].values == 0
        cls = np.where(ok, d["response_class"].values, np.nan)
        whirl = np.where(ok, d["whirl_direction"].values + 1.0, np.nan)
        _categorical(row[0], cls, x, y, list(CLASS_COLOURS), list(RESPONSE_CLASSES),
                     f"response class ({direction}){_class_note(ds)}")  # fmt: skip
        codes = (-1, 0, 1)
        _categorical(row[1], whirl, x, y, [WHIRL_COLOURS[c] for c in codes],
                     [WHIRL_NAMES[c] for c in codes], f"whirl direction ({direction})")  # fmt: skip
        zmax = np.where(ok, d["z_max"].values, np.nan)
        image = row[2].pcolormesh(x, y, np.ma.masked_invalid(zmax).T, shading="nearest",
                                  cmap="magma")  # fmt: skip
        fig.colorbar(image, ax=row[2], label="max z (clearances)")
        row[2].set_title(f"largest z ({direction}); white: failed", fontsize=9)
        for ax in row:
            ax.set_xlabel(_label(dim_x))
            ax.set_ylabel(_label(dim_y))
    fig.suptitle(title, fontsize=10)
    return fig


def attractor_labels(ds) -> tuple[np.ndarray, list[str]]:
    """Each point's attractor: class, whirl direction and, for a periodic one, its max z.

    Points that end on the same periodic orbit share class, direction and max z (to two
    decimals); a non-periodic attractor is labelled by class and direction.
    """
    d = ds.isel(direction=0)
    ok = d["status"].values == 0
    labels = np.full(ok.shape, "failed", dtype=object)
    for index in np.ndindex(ok.shape):
        if not ok[index]:
            continue
        cls = RESPONSE_CLASSES[int(d["response_class"].values[index])]
        whirl = WHIRL_NAMES[int(d["whirl_direction"].values[index])]
        if cls == "periodic":
            zmax = float(d["z_max"].values[index])
            period = d["response_period"].values[index]
            text = f"periodic p{int(period)}, {whirl}, max z {zmax:.2f}"
        else:
            text = f"{cls}, {whirl}"
        labels[index] = text
    names = sorted(set(labels.ravel()) - {"failed"})
    if (labels == "failed").any():
        names.append("failed")
    codes = np.vectorize(names.index, otypes=[float])(labels)
    return codes, names


def basins_figure(ds, title: str) -> Figure:
    """Basins of attraction over a grid of start states: one colour per attractor."""
    dims = _axes_dims(ds)
    codes, names = attractor_labels(ds)
    palette = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
               "tab:pink", "tab:olive", "tab:cyan", "0.5"]  # fmt: skip
    colours = [palette[i % len(palette)] for i in range(len(names))]
    if names and names[-1] == "failed":
        colours[-1] = "white"
    fig = _new_figure(9.5, 6.0)
    ax = fig.subplots()
    if len(dims) == 1:
        x = ds[dims[0]].values
        ax.scatter(x, np.zeros_like(x), c=[colours[int(c)] for c in codes], s=40)
        ax.set_yticks([])
        handles = [Patch(color=colours[i], label=n) for i, n in enumerate(names)]
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    else:
        x, y = ds[dims[0]].values, ds[dims[1]].values
        _categorical(ax, codes, x, y, colours, names, "attractor reached from each start")
        ax.set_ylabel(_label(dims[1]))
        if {"x0", "y0"} == set(dims):
            t = np.linspace(0, 2 * np.pi, 200)
            ax.plot(np.cos(t), np.sin(t), color="k", linestyle="--", linewidth=0.8)
            ax.set_aspect("equal")
            ax.set_title("attractor reached from each start (dashed: the clearance z = 1)",
                         fontsize=9)  # fmt: skip
    ax.set_xlabel(_label(dims[0]))
    fig.suptitle(title, fontsize=10)
    return fig

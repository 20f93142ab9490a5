"""Figures of a sweep (from its xarray Dataset): bifurcation diagram, summary, full-spectrum
cascade, 2-D maps and basins of attraction. They only draw; the numbers come from
``rubcli.analysis.sweep``. Built on the Agg canvas (no pyplot), saved with io.save_figure.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from rubcli import model
from rubcli.analysis.sweep.point import RESPONSE_CLASSES
from rubcli.plotting.cascade import DYNAMIC_RANGE_DB

if TYPE_CHECKING:
    import xarray as xr

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
    **model.MACHINE_PARAMETERS,
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


DIRECTION_MARKERS = {"up": "^", "down": "v", "independent": "o"}
OTHER_DIRECTION = "0.78"  # the other direction, drawn behind for comparison


def bifurcation_figure(ds: xr.Dataset, title: str) -> Figure:
    """Stroboscopic z and x against the swept parameter, one column per direction.

    Each column draws its direction in colour over the other direction in light grey, so
    neither hides the other where they coincide and the hysteresis (a jump up on one
    side, down on the other) reads in either column. When the z values fall into two
    groups with an empty gap between them (a dry whip beside a partial rub), the z axis
    is broken into two linear parts (``axes.split_ranges``). Markers are sized to the
    density of points and at least two pixels wide, so a dense section renders as a
    density instead of moire stripes; where they are large enough to tell apart, up and
    down are triangles pointing up and down.
    """
    from rubcli.plotting import axes as ax_tools

    (dim,) = _axes_dims(ds)
    p = ds[dim].values
    dirs = [str(d) for d in ds["direction"].values]
    fig = _new_figure(6.5 * len(dirs) + 2.4, 8.0)
    outer = fig.add_gridspec(2, len(dirs), height_ratios=(1.0, 1.0))
    z_all = np.append(ds["section_z"].values.ravel(), 1.0)  # (the clearance line is drawn)
    ranges = ax_tools.split_ranges(z_all)
    x_range = ax_tools.split_ranges(ds["section_x"].values.ravel(), gap_fraction=2.0)
    panel_px = (6.5 * 0.8 * ax_tools.DPI) * (8.0 * 0.4 * ax_tools.DPI)
    n_points = max(1, int(np.isfinite(ds["section_z"].values[0]).sum()))
    size = ax_tools.point_size(n_points, panel_px)
    columns = []
    share_z = share_x = sharex = None
    for col, direction in enumerate(dirs):
        z_axes = ax_tools.broken_axes(fig, outer[0, col], ranges, sharex=sharex, sharey=share_z)
        sharex = z_axes[0]
        x_axes = ax_tools.broken_axes(fig, outer[1, col], x_range, sharex=sharex,
                                      sharey=share_x)  # fmt: skip
        share_z, share_x = share_z or z_axes, share_x or x_axes
        columns.append((z_axes, x_axes))
        for axes, var in ((z_axes, "section_z"), (x_axes, "section_x")):
            for ax in axes:
                _direction_points(ax, ds, var, direction, dirs, p, size)
                if var == "section_z":
                    ax.axhline(1.0, color="0.3", linestyle="--", linewidth=0.8, zorder=4)
                ax.grid(True, alpha=0.3)
                if col > 0:
                    ax.tick_params(labelleft=False)
        z_axes[0].set_title(_direction_title(direction, len(dirs)), fontsize=10)
        x_axes[-1].set_xlabel(_label(dim))
        for ax in z_axes[:-1] + x_axes[:-1]:
            ax.tick_params(labelbottom=False)
        z_axes[-1].tick_params(labelbottom=False)
    z_axes, x_axes = columns[0]
    _value_label(fig, z_axes, "stroboscopic z = |x + i y| (clearances)", broken=len(ranges) > 1)
    _value_label(fig, x_axes, "stroboscopic x (clearances)", broken=False)
    fig.legend(handles=_direction_handles(ds, dirs), loc="outside right center", fontsize=8)
    fig.suptitle(title, fontsize=10)
    return fig


def _direction_title(direction: str, n_dirs: int) -> str:
    if n_dirs == 1:
        return f"sweep {direction}"
    return f"sweep {direction} (the other direction in grey, behind)"


def _direction_points(ax, ds, var, direction, dirs, p, size) -> None:
    """The stroboscopic samples of ``direction`` in colour over the others in grey, and a
    red cross at the failed points of this direction."""
    for other in dirs:
        sub = ds[var].sel(direction=other).values  # (n, section)
        xs = np.repeat(p, sub.shape[1])
        mine = other == direction
        ax.scatter(
            xs, sub.ravel(), s=size if mine else size * 0.8,
            color=DIRECTION_COLOURS.get(other, "k") if mine else OTHER_DIRECTION,
            marker=DIRECTION_MARKERS.get(other, "o") if size > 10 else "o",
            alpha=0.45 if mine else 0.4, linewidths=0, zorder=3 if mine else 2, rasterized=True,
        )  # fmt: skip
    failed = ds["status"].sel(direction=direction).values != 0
    if failed.any():
        lo = ax.get_ylim()[0]
        ax.scatter(p[failed], np.full(failed.sum(), lo), marker="x", color="red", s=30,
                   zorder=5, clip_on=False)  # fmt: skip


def _value_label(fig, axes, text: str, broken: bool) -> None:
    """One y label for a stack of axes (a broken axis is one axis), on the taller part."""
    tallest = max(axes, key=lambda a: a.get_subplotspec().get_position(fig).height)
    tallest.set_ylabel(text + ("\n(axis broken: two linear parts)" if broken else ""))


def _direction_handles(ds, dirs) -> list:
    from matplotlib.lines import Line2D

    handles = [
        Line2D([], [], ls="", marker=DIRECTION_MARKERS.get(d, "o"), ms=6,
               color=DIRECTION_COLOURS.get(d, "k"), label=f"sweep {d}")
        for d in dirs
    ]  # fmt: skip
    if len(dirs) > 1:
        handles.append(Line2D([], [], ls="", marker="o", ms=5, color=OTHER_DIRECTION,
                              label="the other direction (behind)"))  # fmt: skip
    handles.append(Line2D([], [], color="0.3", ls="--", lw=0.8, label="clearance z = 1"))
    if (ds["status"].values != 0).any():
        handles.append(Line2D([], [], ls="", marker="x", color="red", label="failed point"))
    return handles


def summary_figure(ds: xr.Dataset, title: str) -> Figure:
    """Contact/stick fraction, z range, whirl order with direction, class, Lyapunov; the
    first direction wide and light, the second thin on top, so neither hides the other."""
    (dim,) = _axes_dims(ds)
    p = ds[dim].values
    lyap = np.isfinite(ds["lyapunov"].values).any()
    rows = 5 if lyap else 4
    fig = _new_figure(9.0, 2.2 * rows + 0.8)
    axes = fig.subplots(rows, 1, sharex=True)
    for k, direction in enumerate(ds["direction"].values):
        d = ds.sel(direction=direction)
        colour = DIRECTION_COLOURS.get(str(direction), "k")
        # the first direction wide and light, the second thin on top: where they coincide
        # both show (as overlaid methods in orbit.png)
        lw, alpha, size = (2.6, 0.5, 40) if k == 0 else (1.0, 1.0, 10)
        line = {"color": colour, "lw": lw, "alpha": alpha}
        axes[0].plot(p, d["contact_fraction"], "-", label=f"contact, {direction}", **line)
        axes[0].plot(p, d["stick_fraction"], ":", label=f"stick, {direction}", **line)
        axes[1].plot(p, d["z_max"], "-", label=f"max z, {direction}", **line)
        axes[1].plot(p, d["z_min"], "--", label=f"min z, {direction}", **line)
        order = d["whirl_order"].values
        whirl = d["whirl_direction"].values
        axes[2].plot(p, order, "-", color=colour, linewidth=0.6, alpha=0.6)
        for code, marker in ((1, "^"), (-1, "v"), (0, "o")):
            sel = whirl == code
            if sel.any():
                axes[2].scatter(p[sel], order[sel], marker=marker, s=size, color=colour,
                                alpha=alpha, linewidths=0, zorder=2 + k,
                                label=f"{WHIRL_NAMES[code]}, {direction}")  # fmt: skip
        axes[3].scatter(p, d["response_class"], s=size, color=colour, alpha=alpha,
                        linewidths=0, zorder=2 + k, label=str(direction))  # fmt: skip
        if lyap:
            axes[4].errorbar(p, d["lyapunov"], yerr=d["lyapunov_stderr"], fmt="o", ms=size**0.5,
                             color=colour, alpha=alpha, label=str(direction))  # fmt: skip
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
        if ax.get_legend_handles_labels()[0]:  # a panel of failed points only has none
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1].set_xlabel(_label(dim))
    fig.suptitle(title, fontsize=10)
    return fig


def cascade_figure(
    ds: xr.Dataset, title: str, dynamic_range_db: float = DYNAMIC_RANGE_DB
) -> Figure:
    """Full-spectrum cascade per direction: the lines of x + i y by order and parameter,
    in dB of the largest line of the figure, down to ``dynamic_range_db`` below it
    (``plotting.cascade``: each line a marker, so none drops out of the image)."""
    from rubcli.plotting.cascade import draw_cascade

    (dim,) = _axes_dims(ds)
    p = ds[dim].values
    dirs = list(ds["direction"].values)
    fig = _new_figure(5.0 * len(dirs) + 1.8, 6.4)
    axes = np.atleast_1d(fig.subplots(1, len(dirs), sharey=True))
    orders = ds["order"].values
    spec = ds["spectrum"].values
    reference = float(np.nanmax(spec)) if np.isfinite(spec).any() else 0.0
    artist = None
    for ax, direction in zip(axes, dirs, strict=True):
        amp = ds["spectrum"].sel(direction=direction).values
        drawn = draw_cascade(ax, orders, p, amp, reference=reference,
                             dynamic_range_db=dynamic_range_db)  # fmt: skip
        artist = artist or drawn
        ax.set_title(f"sweep {direction}: backward (< 0, shaded) | forward (> 0)", fontsize=9)
        ax.set_xlabel("whirl frequency (orders of the running speed, 1X = eta)")
        ax.grid(True, alpha=0.25)
    axes[0].set_ylabel(_label(dim))
    if artist is not None:
        fig.colorbar(artist, ax=list(axes), label=f"level of each line of x + i y, dB of the "
                     f"largest ({reference:.3g} clearances)\nlines below -{dynamic_range_db:g} "
                     "dB are not drawn")  # fmt: skip
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


def map_figure(ds: xr.Dataset, title: str) -> Figure:
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


def attractor_labels(ds: xr.Dataset) -> tuple[np.ndarray, list[str]]:
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


def basins_figure(ds: xr.Dataset, title: str) -> Figure:
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


# -------------------------------------------------------- a basin grid with recognition

ATTRACTOR_PALETTE = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple",
                     "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "gold")  # fmt: skip
# the codes below 0 (attractors.UNRECOGNISED, DIVERGED, FAILED)
SPECIAL = {-1: ("0.8", "not recognised (ran to the budget)"), -2: ("black", "diverged"),
           -3: ("white", "failed")}  # fmt: skip


def _grid_image(ax, ds, values, dims, **kwargs):
    """``values`` over the start grid as an image (a million starts draw as fast as a
    hundred); a 1-D grid is a strip."""
    x = ds[dims[0]].values
    if len(dims) == 1:
        image = np.asarray(values)[None, :]
        y = np.array([-0.5, 0.5])
    else:
        image = np.asarray(values).T
        y = ds[dims[1]].values
    dx = (x[-1] - x[0]) / max(1, len(x) - 1) if len(x) > 1 else 1.0
    dy = (y[-1] - y[0]) / max(1, len(y) - 1) if len(y) > 1 else 1.0
    extent = (x[0] - dx / 2, x[-1] + dx / 2, y[0] - dy / 2, y[-1] + dy / 2)
    shown = ax.imshow(image, origin="lower", extent=extent, interpolation="nearest",
                      aspect="auto", **kwargs)  # fmt: skip
    ax.set_xlabel(_label(dims[0]))
    if len(dims) == 1:
        ax.set_yticks([])
    else:
        ax.set_ylabel(_label(dims[1]))
        if {"x0", "y0"} == set(dims):
            if _shows_clearance(extent):
                t = np.linspace(0, 2 * np.pi, 400)
                ax.plot(np.cos(t), np.sin(t), color="k", linestyle="--", linewidth=0.8)
            ax.set_xlim(extent[:2])
            ax.set_ylim(extent[2:])
            ax.set_aspect("equal")
    return shown


def _shows_clearance(extent) -> bool:
    """Whether the clearance circle z = 1 crosses the start grid's extent."""
    t = np.linspace(0, 2 * np.pi, 4000)
    x, y = np.cos(t), np.sin(t)
    return bool(np.any((x >= extent[0]) & (x <= extent[1]) & (y >= extent[2]) & (y <= extent[3])))


def _clearance_drawn(ds, dims) -> bool:
    if {"x0", "y0"} != set(dims):
        return False
    x, y = ds[dims[0]].values, ds[dims[1]].values
    return _shows_clearance((x.min(), x.max(), y.min(), y.max()))


def _basin_dims(ds) -> list[str]:
    return list(ds["attractor_label"].dims)


def recognised_basins_figure(ds: xr.Dataset, title: str) -> Figure:
    """Each start coloured by the attractor it reached, with the attractors' descriptors
    and basin fractions in the legend."""
    dims = _basin_dims(ds)
    label = ds["attractor_label"].values.astype(int)
    n_attr = ds.sizes["attractor"]
    colours = [ATTRACTOR_PALETTE[k % len(ATTRACTOR_PALETTE)] for k in range(n_attr)]
    codes = sorted(SPECIAL) + list(range(n_attr))  # -3 ... n_attr - 1
    palette = [SPECIAL[c][0] for c in sorted(SPECIAL)] + colours
    cmap = ListedColormap(palette)
    norm = BoundaryNorm(np.arange(codes[0], codes[-1] + 2) - 0.5, len(palette))
    fig = _new_figure(11.0, 6.4)
    ax = fig.subplots()
    _grid_image(ax, ds, label, dims, cmap=cmap, norm=norm)
    handles = []
    for k in range(n_attr):
        share = float(ds["basin_fraction"].values[k])
        name = str(ds["attractor_name"].values[k])
        handles.append(Patch(color=colours[k], label=f"A{k}: {name} ({100 * share:.1f} %)"))
    for code in sorted(SPECIAL, reverse=True):
        count = int((label == code).sum())
        if count:
            colour, text = SPECIAL[code]
            share = 100 * count / label.size
            handles.append(Patch(facecolor=colour, edgecolor="k", label=f"{text} ({share:.1f} %)"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8,
              title="attractor (basin share)", title_fontsize=8)  # fmt: skip
    s_b, s_bb = ds.attrs.get("basin_entropy"), ds.attrs.get("boundary_basin_entropy")
    entropy = ""
    if s_b is not None and np.isfinite(s_b):
        entropy = f"; basin entropy {s_b:.3f}, boundary basin entropy {s_bb:.3f}"
    ax.set_title(
        f"attractor reached from each of {label.size} starts{entropy}"
        + ("\n(dashed: the clearance z = 1)" if _clearance_drawn(ds, dims) else ""),
        fontsize=9,
    )
    fig.suptitle(title, fontsize=10)
    return fig


def convergence_figure(ds: xr.Dataset, title: str) -> Figure:
    """When each start reached its attractor, and what it cost (periods integrated), on
    one colour scale."""
    dims = _basin_dims(ds)
    conv = np.ma.masked_invalid(ds["convergence_period"].values.astype(float))
    cost = ds["periods_integrated"].values.astype(float)
    top = float(max(np.nanmax(cost) if cost.size else 1.0, conv.max() if conv.count() else 1.0))
    fig = _new_figure(13.0, 5.6)
    axes = fig.subplots(1, 2, sharex=True, sharey=True)
    cmap = colormaps["viridis"].with_extremes(bad="white")
    shown = _grid_image(axes[0], ds, conv, dims, cmap=cmap, vmin=0, vmax=top)
    _grid_image(axes[1], ds, cost, dims, cmap=cmap, vmin=0, vmax=top)
    fig.colorbar(shown, ax=list(axes), label="forcing periods", shrink=0.9)
    axes[0].set_title("period at which the start reached its attractor\n(white: not known)",
                      fontsize=9)  # fmt: skip
    budget = int(ds["periods_integrated"].values.max()) if cost.size else 0
    axes[1].set_title(
        f"periods integrated before the start was recognised\n(mean {cost.mean():.1f}; "
        f"largest {budget})",
        fontsize=9,
    )
    fig.suptitle(title, fontsize=10)
    return fig

"""The full-spectrum figure (spectrum.png): whirl amplitude against frequency, both signs.

One panel per spectrum (``analysis.response.spectrum.FullSpectrum``, the FFT of w = x + i y over
the steady span): positive frequencies are forward whirl (with the spin), negative ones
backward whirl, drawn left of zero on a shaded half. The frequency axis is in orders of
the running speed (1X = synchronous), with rad/s on the top axis for a ``[physical]``
case; the amplitude is a whirl radius, in clearances (metres for a physical case), on
a log scale so that small lines show beside the dominant one. The dominant line is
marked and stated (order, direction, amplitude). A long record is drawn as the min/max
envelope of its bins within the plotted range (``display.envelope``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from rubcli import units
from rubcli.analysis.response.spectrum import STATIC, FullSpectrum
from rubcli.plotting import display
from rubcli.plotting.run import _message_box, _new_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes

DYNAMIC_RANGE = 1e-6  # lines below this fraction of the largest are not drawn


def order_range(spectrum: FullSpectrum, level: float = 1e-3) -> float:
    """Half-width of the plotted order axis: every line above ``level`` of the largest
    one, the dominant line and +-1X with some room, within the Nyquist order."""
    order = spectrum.order
    amp = spectrum.amplitude
    nyquist = float(np.max(np.abs(order)))
    peak = float(np.max(amp)) if amp.size else 0.0
    strong = np.abs(order[amp >= level * peak]) if peak > 0 else np.zeros(1)
    wanted = max(2.5, 1.3 * abs(spectrum.dominant_order), 1.15 * float(np.max(strong)))
    return min(wanted, nyquist)


def draw_spectrum(
    ax: Axes,
    spectrum: FullSpectrum,
    *,
    scale: units.PhysicalScale | None = None,
    color: str = "C0",
    half: float | None = None,
    limits: tuple[float, float] | None = None,
    overlay: int = 0,
    label: str = "|W(omega)| (Hann window)",
    alone: bool = True,
) -> dict:
    """Draw one full spectrum into ``ax``; returns what was drawn (range, dominant).

    ``half`` (orders) and ``limits`` (amplitudes) set the axes, e.g. ones shared by several
    panels; default from this spectrum. ``overlay``: 0 for the first spectrum of the axes
    (a thick light line, with the frame), 1, 2, ... for each one drawn over it (a thin
    line on top: where two methods agree both stay visible). ``alone``: the only spectrum
    of its axes, drawn as a plain line.
    """
    unit = 1.0 if scale is None else scale.clearance
    half = order_range(spectrum) if half is None else half
    order, amp = spectrum.order, spectrum.amplitude * unit
    inside = np.abs(order) <= half
    peak = float(np.max(amp)) if amp.size else 1.0
    floor, top = limits if limits is not None else _limits(peak)
    oe, ae = display.envelope(order[inside], np.maximum(amp[inside], floor))
    if overlay == 0:
        ax.axvspan(-half, 0.0, color="0.92", zorder=0)
        line = {"lw": 1.0, "alpha": 1.0} if alone else {"lw": 2.0, "alpha": 0.55}
        line["zorder"] = 2
    else:
        line = {"lw": 0.9, "alpha": 1.0, "zorder": 3}
    ax.semilogy(oe, ae, color=color, label=label, **line)
    ax.set_xlim(-half, half)
    ax.set_ylim(floor, top)
    if overlay == 0:
        for sign in (-1.0, 1.0):
            ax.axvline(sign, color="0.5", ls=":", lw=0.8)
        ax.text(0.02, 0.97, "backward (< 0)", transform=ax.transAxes, va="top",
                fontsize="small")  # fmt: skip
        ax.text(0.98, 0.97, "forward (> 0)", transform=ax.transAxes, va="top", ha="right",
                fontsize="small")  # fmt: skip
    if spectrum.direction == STATIC:
        text = f"no whirl: static offset {spectrum.static_offset * unit:.3g}"
    else:
        dom = spectrum.dominant_order
        dom_amp = spectrum.dominant_amplitude * unit
        ax.plot([dom], [dom_amp], "v", color=color, mec="k", ms=8 if overlay == 0 else 5,
                zorder=5)  # fmt: skip
        text = f"dominant {dom:+.3f}X {spectrum.direction}, amplitude {dom_amp:.3g}"
        if scale is not None:
            text += f", {spectrum.dominant_omega * scale.omega:.4g} rad/s"
    if overlay == 0:
        ax.set_xlabel("frequency / running speed (order)")
        ax.set_ylabel("whirl amplitude / clearance" if scale is None else "whirl amplitude (m)")
        if scale is not None:
            factor = spectrum.eta * scale.omega  # rad/s per order
            top_axis = ax.secondary_xaxis(
                "top", functions=(lambda o: o * factor, lambda w: w / factor)
            )
            top_axis.set_xlabel("frequency (rad/s)")
        ax.grid(True, which="major", alpha=0.3)
    return {"half_range": half, "text": text, "points": int(oe.size)}


def _limits(peak: float) -> tuple[float, float]:
    """Amplitude axis of a spectrum: ``DYNAMIC_RANGE`` below its largest line, and room above."""
    if not peak > 0:
        return 1e-300, 1.0
    return peak * DYNAMIC_RANGE, peak * 4.0


def _spectra(entry) -> list[tuple[str, FullSpectrum]]:
    """A panel's spectra as ``[(name, spectrum), ...]`` (one spectrum is named by nothing)."""
    if entry is None:
        return []
    if isinstance(entry, FullSpectrum):
        return [("", entry)]
    return [(name, sp) for name, sp in entry if sp is not None]


def spectrum_figure(
    panels: Sequence[tuple[str, object, str]],
    title: str,
    *,
    scale: units.PhysicalScale | None = None,
) -> Figure:
    """Full spectra, one panel each: ``(label, spectra, note)``, where ``spectra`` is one
    ``FullSpectrum``, a list of ``(method, FullSpectrum)`` drawn over each other (the
    first thick and light, the others thin on top, each in its method's colour), or None.

    Every panel shares one order axis (the widest any spectrum needs) and one amplitude
    axis (``DYNAMIC_RANGE`` below the largest line of all), so lines compare across
    panels. A panel without a spectrum (a failed run, too short a record) shows its note
    in place of a blank plot. Panels stack in one column up to three, else a 3-wide grid.
    """
    from rubcli.plotting.orbit import COLORS

    n = max(1, len(panels))
    cols = 1 if n <= 3 else 3
    rows = math.ceil(n / cols)
    width = 9.0 if cols == 1 else 13.5
    fig = _new_figure(width, 3.3 * rows + 1.2)
    every = [sp for _, entry, _ in panels for _, sp in _spectra(entry)]
    unit = 1.0 if scale is None else scale.clearance
    half = max((order_range(sp) for sp in every), default=None)
    peak = max((float(np.max(sp.amplitude)) * unit for sp in every if sp.amplitude.size),
               default=0.0)  # fmt: skip
    limits = _limits(peak)
    methods: list[str] = []
    for k, (label, entry, note) in enumerate(panels):
        ax = fig.add_subplot(rows, cols, k + 1)
        spectra = _spectra(entry)
        if not spectra:
            ax.set_axis_off()
            _message_box(ax, f"{label}: no spectrum\n{note}".strip())
            continue
        texts = []
        for i, (name, spectrum) in enumerate(spectra):
            if name and name not in methods:
                methods.append(name)
            color = COLORS[methods.index(name) % len(COLORS)] if name else COLORS[k % len(COLORS)]
            info = draw_spectrum(ax, spectrum, scale=scale, color=color, half=half,
                                 limits=limits, overlay=i, label=name or None,
                                 alone=len(spectra) == 1)  # fmt: skip
            texts.append(f"{name}: {info['text']}" if name else info["text"])
        head = f"{label}: " + ("\n".join(texts) if len(texts) > 1 else texts[0])
        ax.set_title(head + (f"\n{note}" if note else ""), fontsize="small")
    if methods:
        from matplotlib.lines import Line2D

        overlaid = any(len(_spectra(entry)) > 1 for _, entry, _ in panels)
        handles = [Line2D([], [], color=COLORS[i % len(COLORS)],
                          lw=2.0 if i == 0 and overlaid else 0.9,
                          alpha=0.55 if i == 0 and overlaid else 1.0, label=name)
                   for i, name in enumerate(methods)]  # fmt: skip
        handles.append(Line2D([], [], ls="", marker="v", color="0.5", mec="k",
                              label="dominant line of each method"))  # fmt: skip
        fig.legend(handles=handles, loc="outside lower center", ncols=len(handles),
                   fontsize="small")  # fmt: skip
    if not panels:
        ax = fig.add_subplot()
        ax.set_axis_off()
        _message_box(ax, "no spectrum: no method produced a solution")
    fig.suptitle(
        f"{title}\nfull spectrum of w = x + i y over the steady span, |W(omega)| (Hann window); "
        "shared axes",
        fontsize="medium",
    )
    return fig

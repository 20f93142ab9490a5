"""The full-spectrum figure (spectrum.png): whirl amplitude against frequency, both signs.

One panel per spectrum (``analysis.spectrum.FullSpectrum``, the FFT of w = x + i y over
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

import numpy as np
from matplotlib.figure import Figure

from rubcli import units
from rubcli.analysis.spectrum import STATIC, FullSpectrum
from rubcli.plotting import display
from rubcli.plotting.run import _message_box, _new_figure

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
    ax, spectrum: FullSpectrum, *, scale: units.PhysicalScale | None = None, color: str = "C0"
) -> dict:
    """Draw one full spectrum into ``ax``; returns what was drawn (range, dominant)."""
    unit = 1.0 if scale is None else scale.clearance
    half = order_range(spectrum)
    order, amp = spectrum.order, spectrum.amplitude * unit
    inside = np.abs(order) <= half
    peak = float(np.max(amp)) if amp.size else 1.0
    floor = peak * DYNAMIC_RANGE if peak > 0 else 1e-300
    oe, ae = display.envelope(order[inside], np.maximum(amp[inside], floor))
    ax.axvspan(-half, 0.0, color="0.92", zorder=0)
    ax.semilogy(oe, ae, color=color, lw=1.0, label="|W(omega)| (Hann window)")
    ax.set_xlim(-half, half)
    ax.set_ylim(floor, peak * 4.0)
    for sign in (-1.0, 1.0):
        ax.axvline(sign, color="0.5", ls=":", lw=0.8)
    ax.text(0.02, 0.97, "backward (< 0)", transform=ax.transAxes, va="top", fontsize="small")
    ax.text(0.98, 0.97, "forward (> 0)", transform=ax.transAxes, va="top", ha="right",
            fontsize="small")  # fmt: skip
    if spectrum.direction == STATIC:
        text = f"no whirl: static offset {spectrum.static_offset * unit:.3g}"
    else:
        dom = spectrum.dominant_order
        dom_amp = spectrum.dominant_amplitude * unit
        ax.plot([dom], [dom_amp], "v", color="k", ms=7, label="dominant line")
        text = f"dominant {dom:+.3f}X {spectrum.direction}, amplitude {dom_amp:.3g}"
        if scale is not None:
            text += f", {spectrum.dominant_omega * scale.omega:.4g} rad/s"
    ax.set_xlabel("frequency / running speed (order)")
    ax.set_ylabel("whirl amplitude / clearance" if scale is None else "whirl amplitude (m)")
    if scale is not None:
        factor = spectrum.eta * scale.omega  # rad/s per order
        top = ax.secondary_xaxis("top", functions=(lambda o: o * factor, lambda w: w / factor))
        top.set_xlabel("frequency (rad/s)")
    ax.grid(True, which="major", alpha=0.3)
    return {"half_range": half, "text": text, "points": int(oe.size)}


def spectrum_figure(
    panels: Sequence[tuple[str, FullSpectrum | None, str]],
    title: str,
    *,
    scale: units.PhysicalScale | None = None,
) -> Figure:
    """Full spectra, one panel each: ``(label, spectrum or None, note)``.

    A panel without a spectrum (a failed run, too short a record) shows its note in
    place of a blank plot. Panels stack in one column up to three, else a 3-wide grid.
    """
    n = max(1, len(panels))
    cols = 1 if n <= 3 else 3
    rows = math.ceil(n / cols)
    width = 9.0 if cols == 1 else 13.5
    fig = _new_figure(width, 3.2 * rows + 1.0)
    for k, (label, spectrum, note) in enumerate(panels):
        ax = fig.add_subplot(rows, cols, k + 1)
        if spectrum is None:
            ax.set_axis_off()
            _message_box(ax, f"{label}: no spectrum\n{note}".strip())
            continue
        info = draw_spectrum(ax, spectrum, scale=scale, color=f"C{k % 10}")
        head = f"{label}: {info['text']}"
        ax.set_title(head + (f"\n{note}" if note else ""), fontsize="small")
    if not panels:
        ax = fig.add_subplot()
        ax.set_axis_off()
        _message_box(ax, "no spectrum: no method produced a solution")
    fig.suptitle(f"{title}\nfull spectrum of w = x + i y over the steady span", fontsize="medium")
    return fig

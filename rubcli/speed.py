"""A speed that changes in time: a prescribed profile eta(tau), piecewise linear.

A profile is a list of knots ``(tau_i, eta_i)``: the speed is linear between knots and
held before the first and after the last (a ramp from ``from`` to ``to`` at ``rate`` is
the two knots ``(0, from)`` and ``((to - from) / rate, to)``). The unbalance phase is the
exact integral ``p(tau) = phi0 + integral_0^tau eta``, and the forcing carries the
tangential inertia term ``e eta' (sin p, -cos p)`` (``model.unbalance_value``).

The solvers run a profile **leg by leg**: on each leg the speed is linear, and the leg is
a ``ModelParams`` whose ``eta``, ``rate``, ``tau0`` and ``phi0`` give that line and the
phase there (``legs``). A leg ends where eta' jumps; the driver restarts the segment
there (``driver.integrate``), as at an event, so no step straddles the kink of the speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from rubcli.model import MAX_MAGNITUDE, FloatOrArray, ModelParams


@dataclass(frozen=True)
class SpeedProfile:
    """Knots ``(tau, eta)`` of a piecewise-linear speed (module docstring), checked on
    construction: ValueError naming the problem."""

    tau: tuple[float, ...]
    eta: tuple[float, ...]
    kind: str = "table"  # "ramp" or "table": how the user gave it (reported)

    def __post_init__(self) -> None:
        tau = tuple(float(t) for t in self.tau)
        eta = tuple(float(v) for v in self.eta)
        if len(tau) != len(eta) or len(tau) < 1:
            raise ValueError(
                f"speed profile: tau and eta must have the same length >= 1 (got {len(tau)} "
                f"and {len(eta)})"
            )
        for name, values in (("tau", tau), ("eta", eta)):
            for i, v in enumerate(values):
                if not (math.isfinite(v) and abs(v) <= MAX_MAGNITUDE):
                    raise ValueError(f"speed profile: {name}[{i}] must be finite (got {v!r})")
        if tau[0] < 0.0:
            raise ValueError(f"speed profile: tau[0] must be >= 0 (got {tau[0]!r})")
        for i in range(1, len(tau)):
            if not tau[i] > tau[i - 1]:
                raise ValueError(
                    f"speed profile: tau must increase (tau[{i}] = {tau[i]!r} after "
                    f"tau[{i - 1}] = {tau[i - 1]!r})"
                )
        for i, v in enumerate(eta):
            if not v >= 1.0 / MAX_MAGNITUDE:
                raise ValueError(
                    f"speed profile: eta[{i}] must be > 0 (got {v!r}): the rotor does not "
                    "stop or turn back in a prescribed profile"
                )
        object.__setattr__(self, "tau", tau)
        object.__setattr__(self, "eta", eta)

    @classmethod
    def ramp(cls, start: float, end: float, rate: float) -> SpeedProfile:
        """From ``start`` at tau = 0 to ``end`` at ``rate`` (d eta / d tau, its sign that of
        end - start), then held."""
        if not (math.isfinite(rate) and rate != 0.0):
            raise ValueError(f"speed ramp: rate must be finite and non-zero (got {rate!r})")
        if start == end:
            raise ValueError(f"speed ramp: from and to are equal ({start!r}): nothing to ramp")
        if (end - start) * rate < 0.0:
            raise ValueError(
                f"speed ramp: rate = {rate!r} goes away from to = {end!r} (from = {start!r}): "
                "its sign must be that of to - from"
            )
        return cls(tau=(0.0, (end - start) / rate), eta=(start, end), kind="ramp")

    @property
    def end(self) -> float:
        """The last knot's time: where the profile's changes end."""
        return self.tau[-1]

    def speed(self, tau: FloatOrArray) -> FloatOrArray:
        """eta(tau), scalars or arrays."""
        out = np.interp(tau, self.tau, self.eta)
        return float(out) if np.ndim(out) == 0 else out

    def rate(self, tau: FloatOrArray) -> FloatOrArray:
        """eta'(tau) (on a knot, the rate of the leg it begins)."""
        starts, _, rates, _ = self._legs()
        i = np.searchsorted(starts, tau, side="right") - 1
        out = rates[i]
        return float(out) if np.ndim(out) == 0 else out

    def phase(self, tau: FloatOrArray, phi0: float) -> FloatOrArray:
        """The unbalance phase phi0 + integral_0^tau eta, scalars or arrays."""
        starts, etas, rates, phases = self._legs(phi0)
        t = np.asarray(tau, dtype=float)
        i = np.searchsorted(starts, t, side="right") - 1
        d = t - np.where(i == 0, 0.0, starts[i])  # the first hold counts from tau = 0
        out = phases[i] + etas[i] * d + 0.5 * rates[i] * d * d
        return float(out) if np.ndim(out) == 0 else out

    def _legs(self, phi0: float = 0.0) -> tuple[np.ndarray, ...]:
        """(start, eta at start, rate, phase at start) of every leg: the hold from tau = 0
        (or -inf) to the first knot, one leg per pair of knots, and the final hold."""
        tau, eta = np.array(self.tau), np.array(self.eta)
        starts = np.concatenate(([-np.inf], tau))
        etas = np.concatenate(([eta[0]], eta))
        rates = np.concatenate(([0.0], np.diff(eta) / np.diff(tau), [0.0]))
        phases = np.empty(starts.size)
        phases[0] = 0.0
        phases[1] = phi0 + eta[0] * tau[0]  # held at eta[0] from tau = 0
        for i in range(2, starts.size):
            d = starts[i] - starts[i - 1]
            phases[i] = phases[i - 1] + etas[i - 1] * d + 0.5 * rates[i - 1] * d * d
        phases[0] = phi0  # the first hold's phase is counted from tau = 0
        return starts, etas, rates, phases

    def legs(self, params: ModelParams, t0: float, t1: float) -> list[tuple[float, ModelParams]]:
        """The legs that cover [t0, t1]: ``(start, params)`` in time order, each ``params``
        the machine with that leg's line of speed (``ModelParams.rate``, ``tau0``) and
        the phase continuous (``phi0`` such that eta tau + phi0 + rate (tau - tau0)^2 / 2
        is the exact integral)."""
        starts, etas, rates, phases = self._legs(params.phi0)
        out: list[tuple[float, ModelParams]] = []
        for i in range(starts.size):
            end = starts[i + 1] if i + 1 < starts.size else math.inf
            if end <= t0 or starts[i] >= t1:
                continue
            if i == 0:  # the hold before the first knot: phase phi0 + eta tau
                leg = replace(params, eta=float(etas[0]), phi0=params.phi0, rate=0.0, tau0=0.0)
            else:
                tau0 = float(starts[i])
                leg = replace(
                    params,
                    eta=float(etas[i]),
                    phi0=float(phases[i] - etas[i] * tau0),
                    rate=float(rates[i]),
                    tau0=tau0,
                )
            out.append((max(float(starts[i]), t0), leg))
        return out

    def text(self) -> str:
        """The profile in a few words (figure titles)."""
        if self.kind == "ramp":
            rate = (self.eta[1] - self.eta[0]) / (self.tau[1] - self.tau[0])
            return f"eta {self.eta[0]:g} to {self.eta[1]:g} at {rate:g} per tau"
        return f"eta by table, {min(self.eta):g} to {max(self.eta):g}"

    def describe(self) -> dict:
        """The profile as report.json gives it."""
        return {"profile": self.kind, "tau": list(self.tau), "eta": list(self.eta)}

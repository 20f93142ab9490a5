"""A machine as the arrays its compiled system reads (``kernels``), built once a run."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rubcli.machine import Machine
from rubcli.machine.contact import LAW_SIZE
from rubcli.system.kernels import GEOMETRY_SIZE, S_LAW, VALUES_SIZE, WORK_ROWS


@dataclass(frozen=True, eq=False)
class SystemArrays:
    """The structure's matrices premultiplied by ``M^-1``, its power terms, the
    unbalances, the stations and the speed's knots as plain arrays."""

    machine: Machine
    Minv: np.ndarray
    MinvK: np.ndarray
    MinvC: np.ndarray
    MinvG: np.ndarray
    C: np.ndarray
    G: np.ndarray
    Kanti: np.ndarray
    facc: np.ndarray
    unbalances: np.ndarray  # (U, 4): x coordinate, y coordinate, m e, phase
    indices: np.ndarray  # (S, 4) int64: rotor x, y; stator x, y (-1: rigid)
    parameters: np.ndarray  # (S, S_LAW + LAW_SIZE): kernels.S_* columns, then the law
    knots: np.ndarray  # (k, 3): speed.knots()

    @classmethod
    def of(cls, machine: Machine) -> SystemArrays:
        st = machine.structure
        Minv = np.linalg.inv(st.M)
        Minv = 0.5 * (Minv + Minv.T)
        unb = np.array(
            [[*u.coordinates, u.magnitude, u.phase] for u in machine.unbalances], dtype=float
        ).reshape(-1, 4)
        indices = np.full((len(machine.stations), 4), -1, dtype=np.int64)
        parameters = np.empty((len(machine.stations), S_LAW + LAW_SIZE))
        for s, station in enumerate(machine.stations):
            indices[s, :2] = station.rotor
            if station.stator is not None:
                indices[s, 2:] = station.stator
            parameters[s, :S_LAW] = (
                *station.offset,
                station.clearance,
                station.mu,
                station.radius,
            )
            parameters[s, S_LAW:] = station.law.record()
        return cls(
            machine=machine,
            Minv=Minv,
            MinvK=Minv @ st.K,
            MinvC=Minv @ st.C,
            MinvG=Minv @ st.G,
            C=np.ascontiguousarray(st.C),
            G=np.ascontiguousarray(st.G),
            Kanti=0.5 * (st.K - st.K.T),
            facc=Minv @ st.static,
            unbalances=unb,
            indices=indices,
            parameters=parameters,
            knots=machine.speed.knots(),
        )

    @property
    def size(self) -> int:
        """The state's size: positions, velocities and the work, 2 n + 1."""
        return 2 * self.Minv.shape[0] + 1

    def context(self, regimes: np.ndarray) -> tuple:
        """The tuple the compiled system takes (``kernels.evaluate``), with its own work
        buffers, around the regimes array ``regimes`` (S,) int64 (the caller changes it in
        place at a switch)."""
        n = self.Minv.shape[0]
        S = self.indices.shape[0]
        return (
            self.Minv,
            self.MinvK,
            self.MinvC,
            self.MinvG,
            self.C,
            self.G,
            self.Kanti,
            self.facc,
            self.unbalances,
            self.indices,
            self.parameters,
            self.knots,
            regimes,
            np.zeros((WORK_ROWS + S, n)),
            np.zeros((S, GEOMETRY_SIZE)),
            np.zeros((S, S)),
            np.zeros((S, S)),
            np.zeros(S),
            np.zeros(S, dtype=np.int64),
            np.zeros((S, VALUES_SIZE)),
        )

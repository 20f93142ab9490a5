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
    Dsym: np.ndarray  # the damping's symmetric part (C's, and Omega G's at a constant speed)
    Gsym: np.ndarray  # G's symmetric part, apart (a speed that changes)
    Kanti: np.ndarray  # K's antisymmetric part
    flags: np.ndarray  # kernels.F_*: which of the terms above are there
    facc: np.ndarray
    unbalances: np.ndarray  # (U, 4): x coordinate, y coordinate, m e, phase
    indices: np.ndarray  # (S, 4) int64: rotor x, y; stator x, y (-1: rigid)
    parameters: np.ndarray  # (S, S_LAW + LAW_SIZE): kernels.S_* columns, then the law
    knots: np.ndarray  # (k, 3): speed.knots()
    table_indices: np.ndarray  # (m,) int64: the speed table's coordinates (none: empty)
    table_speeds: np.ndarray  # (k,)
    table_stiffness: np.ndarray  # (k, m, m)
    table_damping: np.ndarray  # (k, m, m)

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
        constant = machine.speed.is_constant
        omega = machine.speed.values[0]
        # at a constant speed Omega G joins C (one product less a step)
        C = st.C + omega * st.G if constant else st.C
        G = np.zeros_like(st.G) if constant else st.G
        Gsym = 0.5 * (G + G.T)
        Kanti = 0.5 * (st.K - st.K.T)
        flags = np.array([np.any(G != 0.0), np.any(Gsym != 0.0), np.any(Kanti != 0.0)])
        table = st.speed_table
        if table is None:
            table_indices = np.zeros(0, dtype=np.int64)
            table_speeds = np.zeros(1)
            table_stiffness, table_damping = np.zeros((1, 0, 0)), np.zeros((1, 0, 0))
        else:
            table_indices = np.array(table.coordinates, dtype=np.int64)
            table_speeds = np.array(table.speeds)
            table_stiffness, table_damping = np.array(table.K), np.array(table.C)
        return cls(
            machine=machine,
            Minv=Minv,
            MinvK=Minv @ st.K,
            MinvC=Minv @ C,
            MinvG=Minv @ G,
            Dsym=0.5 * (C + C.T),
            Gsym=Gsym,
            Kanti=Kanti,
            flags=flags,
            facc=Minv @ st.static,
            unbalances=unb,
            indices=indices,
            parameters=parameters,
            knots=machine.speed.knots(),
            table_indices=table_indices,
            table_speeds=table_speeds,
            table_stiffness=table_stiffness,
            table_damping=table_damping,
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
        m = self.table_indices.shape[0]
        return (
            self.Minv,
            self.MinvK,
            self.MinvC,
            self.MinvG,
            self.Dsym,
            self.Gsym,
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
            self.flags,
            self.table_indices,
            self.table_speeds,
            self.table_stiffness,
            self.table_damping,
            np.zeros((m, m)),
            np.zeros((m, m)),
            np.zeros(m),
        )

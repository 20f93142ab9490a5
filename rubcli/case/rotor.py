"""A case whose machine is given as matrices (``[rotor] matrices = "rotor.npz"``), in SI.

::

    [case]
    name = "two-seals"

    [rotor]
    matrices = "rotor.npz"   # M, K, C (optional G, number_dof), SI; relative to this file
    speed = 1500.0           # rpm
    number_dof = 6           # coordinates a node (else the file's number_dof)

    [[unbalance]]
    node = 0                 # coordinates number_dof * node + 0 (x), + 1 (y)
    magnitude = 1e-3         # kg m
    phase = 0.0              # rad

    [[station]]
    name = "seal"            # names the station's CSV columns (default station<k>)
    node = 0
    clearance = 2e-4         # m
    contact_stiffness = 1e6  # N/m
    contact_damping = 0.0    # N s/m: the force c z' along the normal in contact
    contact_exponent = 1.0   # Hertzian exponent p: k delta^p
    mu = 0.15
    radius = 0.02            # m: the rotor's surface radius (slip = radius Omega + d' . t)
    offset = [0.0, 0.0]      # the stator's centre, m
    # stator_node = 3        # the stator is this node of the structure (a ring, a casing)

    [time]
    end = 0.4                # s
    samples_per_revolution = 50

Read in three steps as every case (read the TOML, validate the schema, assemble the
machine); every problem a ``CaseError`` line naming the file and the field. The
matrices file is checked before it is loaded: a regular file of at most
``MAX_MATRICES_BYTES``, an ``.npz`` (zip) whose arrays are plain numbers (no pickles),
each named matrix square, of one size, at most ``machine.MAX_COORDINATES`` (read from
the arrays' headers, before their data), finite, ``M`` symmetric positive definite.
"""

from __future__ import annotations

import math
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, ValidationError

from rubcli.case.base import CaseError, _Section
from rubcli.case.casefile import _format_error
from rubcli.case.loading import open_regular_file, read_case_file
from rubcli.case.run import CaseSection
from rubcli.machine import ContactLaw, Machine, Speed, Station, Structure, Unbalance
from rubcli.machine.contact import MAX_EXPONENT
from rubcli.machine.machine import MAX_COORDINATES
from rubcli.problem import MAX_OUTPUT_SAMPLES
from rubcli.system import METHODS

MAX_MATRICES_BYTES = 2 * 1024**3
# A run keeps every sample of every method in memory (the states, the work, a regime a
# station): beyond this a case is refused before it runs.
MAX_RUN_BYTES = 8 * 1024**3
MATRIX_NAMES = ("M", "K", "C", "G")
REQUIRED_MATRICES = ("M", "K", "C")
STATION_NAME_PATTERN = r"^[A-Za-z][A-Za-z0-9_]*$"
MAX_SPEED_RPM = 1e7


class RotorSection(_Section):
    """[rotor]: the structure's matrices file, the speed, the coordinates per node."""

    matrices: str = Field(min_length=1)
    speed: float = Field(gt=0, le=MAX_SPEED_RPM)  # rpm
    number_dof: int | None = Field(default=None, ge=2, le=64)


class UnbalanceSection(_Section):
    node: int = Field(ge=0)
    magnitude: float = Field(ge=0, le=1e6)  # kg m
    phase: float = Field(default=0.0, ge=-1e6, le=1e6)  # rad


class StationSection(_Section):
    name: str | None = Field(default=None, pattern=STATION_NAME_PATTERN, max_length=40)
    node: int = Field(ge=0)
    clearance: float = Field(gt=0, le=1e3)  # m
    contact_stiffness: float = Field(gt=0, le=1e30)  # N/m
    contact_damping: float = Field(default=0.0, ge=0, le=1e30)  # N s/m
    contact_exponent: float = Field(default=1.0, ge=1.0, le=MAX_EXPONENT)
    mu: float = Field(default=0.0, ge=0, le=100)
    radius: float = Field(ge=0, le=1e3)  # m
    offset: list[float] = Field(default_factory=lambda: [0.0, 0.0], min_length=2, max_length=2)
    stator_node: int | None = Field(default=None, ge=0)


class TimeSection(_Section):
    end: float = Field(gt=0, le=1e6)  # s
    samples_per_revolution: int = Field(default=50, gt=0, le=100_000)


class RotorSolverSection(_Section):
    methods: list[str] = Field(default_factory=lambda: ["dop853-jit"], min_length=1)
    rtol: float = Field(default=1e-9, ge=1e-14, lt=1)
    atol: float = Field(default=1e-12, ge=1e-100)  # m (positions), m/s (velocities)
    max_steps: int = Field(default=10_000_000, gt=0)
    max_wall_time_s: float | None = Field(default=None, gt=0)


class RotorOutputSection(_Section):
    dir: str | None = Field(default=None, min_length=1)
    csv: bool = True
    plots: list[str] = Field(default_factory=lambda: ["orbit"])


class RotorCaseFile(_Section):
    case: CaseSection
    rotor: RotorSection
    unbalance: list[UnbalanceSection] = Field(default_factory=list)
    station: list[StationSection] = Field(min_length=1, max_length=64)
    time: TimeSection
    solver: RotorSolverSection = Field(default_factory=RotorSolverSection)
    output: RotorOutputSection = Field(default_factory=RotorOutputSection)


PLOTS = ("orbit",)


@dataclass(frozen=True, eq=False)
class RotorCase:
    """A validated matrices case: the machine (SI), its sample times, the nodes each
    station joins, and the settings as given."""

    name: str
    source: str
    machine: Machine
    t_eval: np.ndarray
    station_names: tuple[str, ...]
    station_nodes: tuple[tuple[int, int | None], ...]  # (rotor node, stator node or None)
    settings: RotorCaseFile
    matrices_path: Path

    @property
    def methods(self) -> list[str]:
        return list(self.settings.solver.methods)

    @property
    def output_dir(self) -> Path:
        return Path(self.settings.output.dir or f"out/{self.name}")

    @property
    def nodes(self) -> list[int]:
        """Every node a station joins, in order, once."""
        found: list[int] = []
        for rotor, stator in self.station_nodes:
            for node in (rotor, stator):
                if node is not None and node not in found:
                    found.append(node)
        return found

    def to_dict(self) -> dict[str, Any]:
        return self.settings.model_dump(mode="json")


def load_rotor_case(path: str | Path) -> RotorCase:
    """Read, validate and assemble a matrices case; CaseError naming file and field."""
    raw = read_case_file(path)
    return assemble_rotor_case(raw, Path(path))


def assemble_rotor_case(raw: dict[str, Any], path: Path) -> RotorCase:
    source = str(path)
    try:
        settings = RotorCaseFile.model_validate(raw)
    except ValidationError as exc:
        raise CaseError([_format_error(source, e) for e in exc.errors()]) from None
    problems: list[str] = []
    unknown = [m for m in settings.solver.methods if m not in METHODS]
    if unknown:
        problems.append(
            f"{source}: solver.methods: {', '.join(map(repr, unknown))} cannot run a machine "
            f"given as matrices; choose from {', '.join(METHODS)}"
        )
    if len(set(settings.solver.methods)) != len(settings.solver.methods):
        problems.append(f"{source}: solver.methods: a method is listed twice")
    bad_plots = [p for p in settings.output.plots if p not in PLOTS]
    if bad_plots:
        problems.append(
            f"{source}: output.plots: unknown plot {', '.join(map(repr, bad_plots))}; "
            f"choose from {', '.join(PLOTS)}"
        )
    names = [s.name or f"station{k}" for k, s in enumerate(settings.station)]
    if len(set(names)) != len(names):
        problems.append(f"{source}: station: two stations have the same name")
    if problems:
        raise CaseError(problems)
    matrices_path = Path(settings.rotor.matrices)
    if not matrices_path.is_absolute():
        matrices_path = path.parent / matrices_path
    arrays = read_matrices(matrices_path, f"{source}: rotor.matrices")
    structure = _structure(arrays, settings, source)
    machine, nodes = _machine(structure, settings, source, names)
    t_eval = _time_grid(settings, source)
    need = len(settings.solver.methods) * t_eval.size * (2 * machine.size + 1 + len(names)) * 8
    if need > MAX_RUN_BYTES:
        raise CaseError(
            [
                f"{source}: time: {t_eval.size:,} samples of {2 * machine.size + 1} states x "
                f"{len(settings.solver.methods)} methods need {need / 1024**3:.3g} GiB, more than "
                f"the {MAX_RUN_BYTES / 1024**3:g} GiB a run may hold: shorten [time] end or take "
                "fewer samples_per_revolution"
            ]  # fmt: skip
        )
    return RotorCase(
        name=settings.case.name,
        source=source,
        machine=machine,
        t_eval=t_eval,
        station_names=tuple(names),
        station_nodes=tuple(nodes),
        settings=settings,
        matrices_path=matrices_path,
    )


def read_matrices(path: Path, where: str) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` file of matrices, checked before they are loaded
    (module docstring); CaseError lines starting with ``where``."""
    shown = f"{where}: {path}"
    fd, info = open_regular_file(path, shown, "matrices file")
    with os.fdopen(fd, "rb") as handle:
        if info.st_size > MAX_MATRICES_BYTES:
            raise CaseError(
                [
                    f"{shown}: is larger than {MAX_MATRICES_BYTES // 1024**3} GiB, the most a "
                    "matrices file may hold"
                ]  # fmt: skip
            )
        try:
            archive = zipfile.ZipFile(handle)
        except (zipfile.BadZipFile, OSError, ValueError):
            raise CaseError(
                [f"{shown}: not an .npz file (numpy.savez: a zip of .npy arrays)"]
            ) from None
        with archive:
            return _arrays(archive, shown)


def _arrays(archive: zipfile.ZipFile, shown: str) -> dict[str, np.ndarray]:
    members = {Path(n).stem: n for n in archive.namelist() if n.endswith(".npy")}
    missing = [m for m in REQUIRED_MATRICES if m not in members]
    if missing:
        have = ", ".join(sorted(members)) or "none"
        raise CaseError(
            [
                f"{shown}: has no matrix {', '.join(missing)} (it needs M, K and C, optionally "
                f"G and number_dof; it holds: {have})"
            ]  # fmt: skip
        )
    out: dict[str, np.ndarray] = {}
    for name in (*MATRIX_NAMES, "number_dof"):
        if name not in members:
            continue
        try:
            with archive.open(members[name]) as member:
                version = np.lib.format.read_magic(member)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(member)
                else:
                    shape, _, dtype = np.lib.format.read_array_header_2_0(member)
                if dtype.hasobject or dtype.kind not in "biuf":
                    raise CaseError([f"{shown}: {name} must hold plain numbers (got {dtype})"])
                if name == "number_dof":
                    if int(np.prod(shape)) != 1:
                        raise CaseError([f"{shown}: number_dof must be one integer"])
                elif len(shape) != 2 or shape[0] != shape[1]:
                    raise CaseError([f"{shown}: {name} must be a square matrix (got {shape})"])
                elif shape[0] > MAX_COORDINATES:
                    raise CaseError(
                        [
                            f"{shown}: {name} has {shape[0]} coordinates, more than "
                            f"{MAX_COORDINATES} (reduce the model)"
                        ]  # fmt: skip
                    )
            with archive.open(members[name]) as member:
                out[name] = np.lib.format.read_array(member, allow_pickle=False)
        except CaseError:
            raise
        except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
            raise CaseError([f"{shown}: {name} cannot be read ({exc})"]) from None
    return out


def _structure(arrays: dict[str, np.ndarray], settings: RotorCaseFile, source: str) -> Structure:
    where = f"{source}: rotor.matrices"
    per_node = settings.rotor.number_dof
    if per_node is None and "number_dof" in arrays:
        value = arrays["number_dof"].reshape(-1)[0]
        if not float(value).is_integer():
            raise CaseError([f"{where}: number_dof must be an integer (got {value})"])
        per_node = int(value)
    n = arrays["M"].shape[0]
    if per_node is None:
        if n != 2:
            raise CaseError(
                [
                    f"{source}: rotor.number_dof: give the coordinates a node (the matrices file "
                    "has no number_dof)"
                ]  # fmt: skip
            )
        per_node = 2
    try:
        return Structure(
            M=arrays["M"], K=arrays["K"], C=arrays["C"], G=arrays.get("G"), dof_per_node=per_node
        )
    except (TypeError, ValueError) as exc:
        raise CaseError([f"{where}: {str(exc).removeprefix('structure: ')}"]) from None


def _machine(
    structure: Structure, settings: RotorCaseFile, source: str, names: list[str]
) -> tuple[Machine, list[tuple[int, int | None]]]:
    problems: list[str] = []

    def node_pair(field: str, node: int) -> tuple[int, int] | None:
        if node >= structure.nodes:
            problems.append(
                f"{source}: {field}: node {node} does not exist (the matrices have "
                f"{structure.nodes} nodes, 0 to {structure.nodes - 1})"
            )
            return None
        return structure.lateral(node)

    unbalances = []
    for k, u in enumerate(settings.unbalance):
        pair = node_pair(f"unbalance[{k}].node", u.node)
        if pair is not None:
            unbalances.append(Unbalance(pair, u.magnitude, u.phase))
    stations, nodes = [], []
    for k, s in enumerate(settings.station):
        rotor = node_pair(f"station[{k}].node", s.node)
        stator = None
        if s.stator_node is not None:
            if s.stator_node == s.node:
                problems.append(f"{source}: station[{k}].stator_node: the station's own node")
                continue
            stator = node_pair(f"station[{k}].stator_node", s.stator_node)
            if stator is None:
                continue
        if rotor is None:
            continue
        law = ContactLaw(s.contact_stiffness, s.contact_damping, s.contact_exponent)
        stations.append(
            Station(rotor, s.clearance, law, s.mu, s.radius, stator, s.offset, names[k])
        )
        nodes.append((s.node, s.stator_node))
    if problems:
        raise CaseError(problems)
    omega = settings.rotor.speed * 2.0 * math.pi / 60.0
    machine = Machine(structure, tuple(stations), Speed.constant(omega), tuple(unbalances))
    return machine, nodes


def _time_grid(settings: RotorCaseFile, source: str) -> np.ndarray:
    revolutions = settings.time.end * settings.rotor.speed / 60.0
    samples = revolutions * settings.time.samples_per_revolution
    if not samples <= MAX_OUTPUT_SAMPLES:
        raise CaseError(
            [
                f"{source}: time: {samples:.3g} samples ({revolutions:.6g} revolutions at "
                f"{settings.time.samples_per_revolution} a revolution), more than "
                f"{MAX_OUTPUT_SAMPLES:,}"
            ]  # fmt: skip
        )
    return np.linspace(0.0, settings.time.end, max(2, int(round(samples)) + 1))

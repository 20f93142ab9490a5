"""A case whose machine is given as matrices (``[rotor] matrices = "rotor.npz"``) or as a
ROSS rotor file (``[rotor] ross = "rotor.toml"``, read through ROSS, the optional extra:
``rubcli.machine.ross``), in SI.

::

    [case]
    name = "two-seals"

    [rotor]
    matrices = "rotor.npz"   # M, K, C (optional G, number_dof, node_xy: each node's x, y
                             # where nodes differ, outer_radius, and the shaft view's
                             # node_position, disk_nodes, bearing_nodes), SI;
                             # relative to this file; or ross = "rotor.toml" (ROSS's
                             # Rotor.save)
    gravity = [0.0, -9.81]   # m/s^2 along x, y: the static load M a (optional)
    speed = 1500.0           # rpm (or a [speed] section: a run-up, a coast-down)
    number_dof = 6           # coordinates a node (else the file's number_dof)
    modes = 0                # > 0: a Craig-Bampton reduction (rubcli.machine.reduction)

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
    radius = 0.02            # m: the rotor's surface radius (slip = radius Omega + d' . t);
                             # default: the shaft's outer radius at the node (ROSS, outer_radius)
    offset = [0.0, 0.0]      # the stator's centre, m
    # stator_node = 3        # the stator is this node of the structure (a ring, a casing)

    [[probe]]                # optional: reads x cos(angle) + y sin(angle), as ROSS's Probe
    name = "probe_de"        # names its CSV column (default probe<k>)
    node = 1
    angle = 0.0              # rad

    # [speed]                # in place of [rotor] speed: the bearings follow the speed
    # profile = "ramp"       # from, to (rpm) and rate (rpm/s); or "table": t (s), speed (rpm)
    # from = 600.0           # (a run-up writes bode.png, polar.png, cascade.png at the
    # to = 3000.0            #  probes: it needs a [[probe]])
    # rate = 800.0

    [time]
    end = 0.4                # s
    samples_per_revolution = 50  # at the fastest speed

    [output]
    plots = ["orbit", "shaft", "time"]  # the shaft view needs the nodes' positions
    shapes = [0.1, 0.35]     # s: the deflected shape at these instants (shape.png,
                             # shapes.csv; needs the nodes' positions too)

Read in three steps as every case (read the TOML, validate the schema, assemble the
machine); every problem a ``CaseError`` line naming the file and the field. The
matrices file is checked before it is loaded: a regular file of at most
``MAX_MATRICES_BYTES``, an ``.npz`` (zip) whose arrays are plain numbers (no pickles),
each named matrix square, of one size, at most ``machine.MAX_COORDINATES`` (read from
the arrays' headers, before their data), finite, ``M`` symmetric positive definite.
"""

from __future__ import annotations

import json
import math
import os
import tomllib
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import ConfigDict, Field, ValidationError, model_validator

from rubcli.case.base import CaseError, _Section
from rubcli.case.casefile import _format_error
from rubcli.case.loading import open_regular_file, read_case_file
from rubcli.case.run import CaseSection
from rubcli.machine import ContactLaw, Machine, Speed, Station, Structure, Unbalance
from rubcli.machine.contact import MAX_EXPONENT
from rubcli.machine.linear import with_gravity
from rubcli.machine.machine import MAX_COORDINATES
from rubcli.machine.reduction import Reduction, reduce_machine
from rubcli.problem import MAX_OUTPUT_SAMPLES
from rubcli.system import METHODS

MAX_MATRICES_BYTES = 2 * 1024**3
MAX_ROSS_FILE_BYTES = 64 * 1024**2
MAX_ROSS_NODES = MAX_COORDINATES // 4  # 4 lateral coordinates a node kept
# A run keeps every sample of every method in memory (the states, the work, a regime a
# station): beyond this a case is refused before it runs.
MAX_RUN_BYTES = 8 * 1024**3
MATRIX_NAMES = ("M", "K", "C", "G")
REQUIRED_MATRICES = ("M", "K", "C")
# the shaft's layout, for its view (``ShaftLayout``): optional in a matrices file
LAYOUT_NAMES = ("node_position", "disk_nodes", "bearing_nodes")
STATION_NAME_PATTERN = r"^[A-Za-z][A-Za-z0-9_]*$"
MAX_SPEED_RPM = 1e7


class RotorSection(_Section):
    """[rotor]: the structure (a matrices file, or a ROSS rotor file), the speed, the
    coordinates per node (matrices only), the gravity (m/s^2 along x, y), and ``modes``:
    the fixed-interface modes of a Craig-Bampton reduction that keeps the stations',
    unbalances' and probes' coordinates physical (``machine.reduction``; 0: the full
    model)."""

    matrices: str | None = Field(default=None, min_length=1)
    ross: str | None = Field(default=None, min_length=1)
    speed: float | None = Field(default=None, gt=0, le=MAX_SPEED_RPM)  # rpm; or [speed]
    number_dof: int | None = Field(default=None, ge=2, le=64)
    gravity: list[float] | None = Field(default=None, min_length=2, max_length=2)
    modes: int = Field(default=0, ge=0, le=MAX_COORDINATES)

    @model_validator(mode="after")
    def _one_structure(self) -> RotorSection:
        if (self.matrices is None) == (self.ross is None):
            raise ValueError("give the structure once: matrices = FILE.npz or ross = FILE.toml")
        if self.ross is not None and self.number_dof is not None:
            raise ValueError("number_dof is for a matrices file (a ROSS rotor gives its own)")
        if self.gravity is not None and not all(abs(g) <= 1e4 for g in self.gravity):
            raise ValueError("gravity must be at most 1e4 m/s^2 in each direction")
        return self


class RotorSpeedSection(_Section):
    """[speed]: a speed that changes (a run-up, a coast-down), in rpm: a ramp from
    ``from`` to ``to`` at ``rate`` rpm/s (its sign that of ``to - from``), held at ``to``
    after; or a table of times ``t`` (s) and speeds ``speed`` (rpm), linear between."""

    model_config = ConfigDict(populate_by_name=True)

    profile: Literal["ramp", "table"]
    start: float | None = Field(default=None, alias="from", gt=0, le=MAX_SPEED_RPM)
    to: float | None = Field(default=None, gt=0, le=MAX_SPEED_RPM)
    rate: float | None = Field(default=None, ge=-1e9, le=1e9)  # rpm/s
    t: list[float] | None = Field(default=None, min_length=2, max_length=100_000)  # s
    speed: list[Annotated[float, Field(gt=0, le=MAX_SPEED_RPM)]] | None = Field(
        default=None, min_length=2, max_length=100_000
    )  # rpm

    @model_validator(mode="after")
    def _complete(self) -> RotorSpeedSection:
        ramp = {"from": self.start, "to": self.to, "rate": self.rate}
        table = {"t": self.t, "speed": self.speed}
        mine, other = (ramp, table) if self.profile == "ramp" else (table, ramp)
        extra = [k for k, v in other.items() if v is not None]
        if extra:
            raise ValueError(f"{', '.join(extra)} do not belong to profile = '{self.profile}'")
        missing = [k for k, v in mine.items() if v is None]
        if missing:
            raise ValueError(f"profile = '{self.profile}' needs {', '.join(missing)}")
        if self.profile == "ramp":
            if self.to == self.start:
                raise ValueError("from and to are the same speed: give [rotor] speed instead")
            if self.rate == 0 or (self.rate > 0) != (self.to > self.start):
                raise ValueError("rate must be nonzero with the sign of to - from (rpm/s)")
        else:
            if len(self.t) != len(self.speed):
                raise ValueError(f"t has {len(self.t)} times and speed {len(self.speed)} speeds")
            if any(not b > a for a, b in zip(self.t, self.t[1:], strict=False)):
                raise ValueError("t must increase")
            if len(set(self.speed)) == 1:
                raise ValueError("every speed of the table is the same: give [rotor] speed")
        return self

    def knots_rpm(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The profile's knots: times (s) and speeds (rpm)."""
        if self.profile == "table":
            return tuple(self.t), tuple(self.speed)
        return (0.0, abs(self.to - self.start) / abs(self.rate)), (self.start, self.to)


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
    radius: float | None = Field(default=None, ge=0, le=1e3)  # m; None: the shaft's
    offset: list[float] = Field(default_factory=lambda: [0.0, 0.0], min_length=2, max_length=2)
    stator_node: int | None = Field(default=None, ge=0)


class ProbeSection(_Section):
    """[[probe]]: a displacement probe as ROSS's ``Probe(node, angle)``: it reads
    ``x cos(angle) + y sin(angle)`` at ``node`` (m)."""

    name: str | None = Field(default=None, pattern=STATION_NAME_PATTERN, max_length=40)
    node: int = Field(ge=0)
    angle: float = Field(ge=-1e3, le=1e3)  # rad


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
    # instants (s) whose deflected shape is drawn (shape.png) and written (shapes.csv)
    shapes: list[Annotated[float, Field(ge=0)]] = Field(default_factory=list, max_length=12)


class RotorCaseFile(_Section):
    case: CaseSection
    rotor: RotorSection
    unbalance: list[UnbalanceSection] = Field(default_factory=list)
    station: list[StationSection] = Field(min_length=1, max_length=64)
    probe: list[ProbeSection] = Field(default_factory=list, max_length=64)
    speed: RotorSpeedSection | None = None
    time: TimeSection
    solver: RotorSolverSection = Field(default_factory=RotorSolverSection)
    output: RotorOutputSection = Field(default_factory=RotorOutputSection)

    @model_validator(mode="after")
    def _one_speed(self) -> RotorCaseFile:
        if (self.rotor.speed is None) == (self.speed is None):
            raise ValueError(
                "give the speed once: [rotor] speed (rpm, constant) or a [speed] section (a "
                "run-up or coast-down)"
            )
        if self.speed is not None and not self.probe:
            raise ValueError(
                "a run-up's Bode, polar and cascade plots read the probes: give at least one "
                "[[probe]]"
            )
        return self

    def speed_knots(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The speed's knots: times (s) and speeds (rad/s); one knot: constant."""
        if self.speed is None:
            return (0.0,), (self.rotor.speed * RPM,)
        times, rpm = self.speed.knots_rpm()
        return times, tuple(v * RPM for v in rpm)


RPM = 2.0 * math.pi / 60.0  # rad/s of one rpm

PLOTS = ("orbit", "shaft", "time")


@dataclass(frozen=True, eq=False)
class ShaftLayout:
    """Where the rotor's nodes are along its axis (m; nan for a node off the shaft), the
    shaft's outer radius at each (m; 0 where unknown), and which nodes carry a disk or a
    bearing: for the shaft view."""

    positions: np.ndarray
    radii: np.ndarray
    disks: tuple[int, ...]
    bearings: tuple[int, ...]


@dataclass(frozen=True)
class Probe:
    """A displacement probe: its name, node and angle (rad from x toward y)."""

    name: str
    node: int
    angle: float


@dataclass(frozen=True, eq=False)
class RotorCase:
    """A validated matrices case: the machine (SI) it runs (the full one, or its
    reduction), its sample times, the nodes each station joins, and the settings as
    given."""

    name: str
    source: str
    machine: Machine
    full_machine: Machine  # machine itself unless reduced
    reduction: Reduction | None
    t_eval: np.ndarray
    station_names: tuple[str, ...]
    station_nodes: tuple[tuple[int, int | None], ...]  # (rotor node, stator node or None)
    probes: tuple[Probe, ...]
    layout: ShaftLayout | None  # None: the rotor's file gives no node positions
    settings: RotorCaseFile
    rotor_file: Path  # the matrices file or the ROSS rotor file

    @property
    def methods(self) -> list[str]:
        return list(self.settings.solver.methods)

    @property
    def output_dir(self) -> Path:
        return Path(self.settings.output.dir or f"out/{self.name}")

    @property
    def nodes(self) -> list[int]:
        """Every node a station joins or a probe reads, in order, once."""
        found: list[int] = []
        every = [n for pair in self.station_nodes for n in pair] + [p.node for p in self.probes]
        for node in every:
            if node is not None and node not in found:
                found.append(node)
        return found

    def lateral(self, node: int) -> tuple[int, int]:
        """The coordinates of ``node``'s x and y in the machine that runs."""
        pair = self.full_machine.structure.lateral(node)
        if self.reduction is None:
            return pair
        return (self.reduction.reduced_index(pair[0]), self.reduction.reduced_index(pair[1]))

    @property
    def runup(self) -> bool:
        """The speed changes ([speed]): the run-up products are written."""
        return self.settings.speed is not None

    @property
    def speed_text(self) -> str:
        """The speed as a title shows it: ``1200 rpm`` or ``600 to 3000 rpm``."""
        if self.settings.speed is None:
            return f"{self.settings.rotor.speed:g} rpm"
        rpm = self.settings.speed.knots_rpm()[1]
        return f"{rpm[0]:g} to {rpm[-1]:g} rpm"

    def to_dict(self) -> dict[str, Any]:
        return self.settings.model_dump(mode="json", by_alias=True)


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
    if settings.speed is not None and "analytic" in settings.solver.methods:
        problems.append(
            f"{source}: solver.methods: 'analytic' needs a constant speed (its free flight is "
            "the closed form of a structure that does not change); a [speed] run-up runs by "
            "dop853-jit or radau"
        )
    bad_plots = [p for p in settings.output.plots if p not in PLOTS]
    if bad_plots:
        problems.append(
            f"{source}: output.plots: unknown plot {', '.join(map(repr, bad_plots))}; "
            f"choose from {', '.join(PLOTS)}"
        )
    names = [s.name or f"station{k}" for k, s in enumerate(settings.station)]
    if len(set(names)) != len(names):
        problems.append(f"{source}: station: two stations have the same name")
    probe_names = [p.name or f"probe{k}" for k, p in enumerate(settings.probe)]
    if len(set(probe_names)) != len(probe_names):
        problems.append(f"{source}: probe: two probes have the same name")
    if set(probe_names) & set(names):
        problems.append(
            f"{source}: probe: {', '.join(sorted(set(probe_names) & set(names)))} is a station's "
            "name too (their CSV columns would clash)"
        )
    if problems:
        raise CaseError(problems)
    field = "matrices" if settings.rotor.matrices is not None else "ross"
    rotor_file = Path(getattr(settings.rotor, field))
    if not rotor_file.is_absolute():
        rotor_file = path.parent / rotor_file
    where = f"{source}: rotor.{field}"
    if field == "matrices":
        arrays = read_matrices(rotor_file, where)
        structure = _structure(arrays, settings, source)
    else:
        structure, arrays = _ross_structure(rotor_file, settings, where)
    radii = arrays.get("outer_radius")
    layout = _layout(arrays, structure, where)
    if "shaft" in settings.output.plots and layout is None:
        raise CaseError(
            [f"{source}: output.plots: 'shaft' needs the nodes' positions, which {rotor_file} "
             "does not give (a matrices file: node_position, as rubcli export-matrices writes)"]
        )  # fmt: skip
    if settings.output.shapes and layout is None:
        raise CaseError(
            [f"{source}: output.shapes: a deflected shape needs the nodes' positions, which "
             f"{rotor_file} does not give (a matrices file: node_position)"]
        )  # fmt: skip
    late = [t for t in settings.output.shapes if t > settings.time.end]
    if late:
        raise CaseError(
            [f"{source}: output.shapes: {', '.join(f'{t:g}' for t in late)} s is after the "
             f"run's end ({settings.time.end:g} s)"]
        )  # fmt: skip
    full, nodes = _machine(structure, settings, source, names, radii)
    bad = [k for k, p in enumerate(settings.probe) if p.node >= structure.nodes]
    if bad:
        raise CaseError(
            [f"{source}: probe[{k}].node: node {settings.probe[k].node} does not exist (the "
             f"rotor has {structure.nodes} nodes, 0 to {structure.nodes - 1})" for k in bad]
        )  # fmt: skip
    probes = tuple(
        Probe(name, p.node, p.angle) for name, p in zip(probe_names, settings.probe, strict=True)
    )
    machine, reduction = full, None
    if settings.rotor.modes > 0:
        keep = tuple(c for p in probes for c in structure.lateral(p.node))
        try:
            machine, reduction = reduce_machine(full, settings.rotor.modes, keep)
        except ValueError as exc:
            raise CaseError([f"{source}: rotor.modes: {exc}"]) from None
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
        full_machine=full,
        reduction=reduction,
        t_eval=t_eval,
        station_names=tuple(names),
        station_nodes=tuple(nodes),
        probes=probes,
        layout=layout,
        settings=settings,
        rotor_file=rotor_file,
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
    for name in (*MATRIX_NAMES, "number_dof", "node_xy", "outer_radius", *LAYOUT_NAMES):
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
                elif name == "node_xy":
                    if len(shape) != 2 or shape[1] != 2 or shape[0] > MAX_COORDINATES:
                        raise CaseError([f"{shown}: node_xy must be a pair of coordinates a node"])
                elif name == "outer_radius" or name in LAYOUT_NAMES:
                    if len(shape) != 1 or shape[0] > MAX_COORDINATES:
                        raise CaseError([f"{shown}: {name} must be a list of numbers a node"])
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
        structure = Structure(
            M=arrays["M"], K=arrays["K"], C=arrays["C"], G=arrays.get("G"),
            dof_per_node=per_node, node_xy=arrays.get("node_xy"),
        )  # fmt: skip
    except (TypeError, ValueError) as exc:
        raise CaseError([f"{where}: {str(exc).removeprefix('structure: ')}"]) from None
    return with_gravity(structure, settings.rotor.gravity)


def check_ross_file(path: Path, where: str) -> None:
    """A ROSS rotor file (``Rotor.save``: TOML or JSON) checked before ROSS reads it: a
    regular file of at most ``MAX_ROSS_FILE_BYTES``, of a known format, with shaft
    elements, whose nodes give at most ``MAX_ROSS_NODES`` nodes; CaseError lines
    starting with ``where``."""
    shown = f"{where}: {path}"
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise CaseError([f"{shown}: a ROSS rotor file is .toml or .json (Rotor.save)"])
    fd, info = open_regular_file(path, shown, "ROSS rotor file")
    with os.fdopen(fd, "rb") as handle:
        if info.st_size > MAX_ROSS_FILE_BYTES:
            raise CaseError(
                [
                    f"{shown}: is larger than {MAX_ROSS_FILE_BYTES // 1024**2} MiB, more than a "
                    "rotor file holds"
                ]  # fmt: skip
            )
        raw = handle.read()
    try:
        text = raw.decode("utf-8")
        data = json.loads(text) if suffix == ".json" else tomllib.loads(text)
    except UnicodeDecodeError:
        raise CaseError([f"{shown}: not a text file (UTF-8)"]) from None
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise CaseError([f"{shown}: not a ROSS rotor file: {exc}"]) from None
    if not isinstance(data, dict):
        raise CaseError([f"{shown}: not a ROSS rotor file (its top level is not a table)"])
    nodes = 0
    for name, element in data.items():
        if name in ("parameters", "ross_version") or name.startswith("_"):
            continue
        if not isinstance(element, dict):
            raise CaseError([f"{shown}: {name}: an element must be a table"])
        n = element.get("n")
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 0):
            raise CaseError([f"{shown}: {name}.n: a node number must be an integer >= 0"])
        if name.startswith("ShaftElement"):
            nodes = max(nodes, (n or 0) + 2)
    if nodes == 0:
        raise CaseError([f"{shown}: not a ROSS rotor file (it has no ShaftElement table)"])
    if nodes > MAX_ROSS_NODES:
        raise CaseError(
            [
                f"{shown}: {nodes} nodes, more than the {MAX_ROSS_NODES} a run holds "
                f"({MAX_COORDINATES} coordinates): reduce the model"
            ]  # fmt: skip
        )


def _ross_structure(
    path: Path, settings: RotorCaseFile, where: str
) -> tuple[Structure, dict[str, np.ndarray]]:
    """The structure of a ROSS rotor file at the case's speed, and the shaft's outer
    radius and layout (``ross.shaft_layout``)."""
    check_ross_file(path, where)
    from rubcli.machine import ross

    try:
        rotor = ross.load_ross_rotor(path)
        speeds = settings.speed_knots()[1]
        gravity = settings.rotor.gravity
        structure = ross.ross_structure(
            rotor,
            speeds[0],
            None if gravity is None else tuple(gravity),
            None if len(speeds) == 1 else (min(speeds), max(speeds)),
        )
    except ross.RossError as exc:
        raise CaseError([f"{where}: {exc}"]) from None
    return structure, ross.shaft_layout(rotor)


def _layout(arrays: dict[str, np.ndarray], structure: Structure, where: str) -> ShaftLayout | None:
    """The shaft's layout from the rotor's arrays (``LAYOUT_NAMES``), checked: a position
    a node (nan: off the shaft, as a bearing's support node), at least two on the shaft,
    not decreasing along it; radii as many as the nodes or fewer (the rest 0); disks and
    bearings at nodes on the shaft."""
    if "node_position" not in arrays:
        return None
    nodes = structure.nodes
    positions = np.asarray(arrays["node_position"], dtype=float)
    shaft = np.isfinite(positions)
    if positions.shape != (nodes,) or np.any(np.isinf(positions)) or shaft.sum() < 2:
        raise CaseError(
            [f"{where}: node_position must be {nodes} positions (m; nan off the shaft), "
             "at least two of them finite"]
        )  # fmt: skip
    if np.any(np.diff(positions[shaft]) < 0.0):
        raise CaseError([f"{where}: node_position must not decrease along the shaft"])
    given = np.asarray(arrays.get("outer_radius", np.zeros(0)), dtype=float).reshape(-1)
    if given.size > nodes or not np.all(np.isfinite(given) & (given >= 0.0)):
        raise CaseError([f"{where}: outer_radius must be at most {nodes} radii >= 0 (m)"])
    radii = np.zeros(nodes)
    radii[: given.size] = given
    marked = {}
    for name in ("disk_nodes", "bearing_nodes"):
        values = np.asarray(arrays.get(name, np.zeros(0)), dtype=float).reshape(-1)
        whole = values == np.round(values)
        if not np.all(whole & (values >= 0) & (values < nodes)) or not np.all(
            shaft[values.astype(np.int64)]
        ):
            raise CaseError([f"{where}: {name} must be nodes on the shaft (0 to {nodes - 1})"])
        marked[name] = tuple(sorted({int(v) for v in values}))
    return ShaftLayout(positions, radii, marked["disk_nodes"], marked["bearing_nodes"])


def _machine(
    structure: Structure,
    settings: RotorCaseFile,
    source: str,
    names: list[str],
    radii: np.ndarray | None,
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
        radius = s.radius
        if radius is None:
            if radii is None or s.node >= radii.size or not radii[s.node] > 0.0:
                problems.append(
                    f"{source}: station[{k}].radius: give the rotor's surface radius at the "
                    "station (m): the rotor's file gives none at this node"
                )
                continue
            radius = float(radii[s.node])
        law = ContactLaw(s.contact_stiffness, s.contact_damping, s.contact_exponent)
        stations.append(Station(rotor, s.clearance, law, s.mu, radius, stator, s.offset, names[k]))
        nodes.append((s.node, s.stator_node))
    if problems:
        raise CaseError(problems)
    times, speeds = settings.speed_knots()
    machine = Machine(structure, tuple(stations), Speed(times, speeds), tuple(unbalances))
    return machine, nodes


def _time_grid(settings: RotorCaseFile, source: str) -> np.ndarray:
    fastest = max(settings.speed_knots()[1]) / RPM
    revolutions = settings.time.end * fastest / 60.0  # at the fastest speed: its sampling
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

"""Case files: the TOML schema (pydantic) and loading a case into a Problem plus settings.

Loading goes in three steps, each a function that can be used alone:

1. ``read_case_file(path)``: read the file and parse TOML (missing file, not TOML -> error);
2. ``validate_case(raw, source)``: validate against the schema (``CaseFile``);
3. ``assemble_case(settings, path)``: fill the defaults, convert physical units once
   (``rubcli.units``) and build the nondimensional ``Problem``.

``load_case(path)`` does all three. Every problem is reported as a ``CaseError`` whose
message has one line per problem, naming the file, the dotted field and what is wrong::

    my.toml: model.K: Input should be greater than 0 (got -1.0)

The key names are a contract with users: add keys, don't rename them. The full
reference is ``docs/cases.md``. The method names come from the registry's data
(``rubcli.solvers.registry``), which loads no solver.

One module per table or close group of tables (``run``: [case], [initial], [time],
[solver], [output]; ``machine``: [model], [physical], [stator]; ``speed``; ``forces_map``;
``compare``: [compare], [analysis]; ``sweep``; ``orbits``; ``ensemble``; ``chart``), the
whole file and its validation (``casefile``), the assembly into a Problem (``assemble``)
and reading a file (``loading``); ``base`` holds what they all share.
"""

from rubcli.case.assemble import Case, assemble_case, paper_machine_problem
from rubcli.case.base import (
    KNOWN_METHODS,
    MAX_CASE_MEMORY_BYTES,
    CaseError,
    run_memory_bytes,
)
from rubcli.case.casefile import CaseFile, validate_case
from rubcli.case.chart import ChartSection
from rubcli.case.compare import AnalysisSection, CompareSection
from rubcli.case.ensemble import EnsembleSection
from rubcli.case.forces_map import (
    DEFAULT_FORCES_MAP_DELTAS,
    DEFAULT_FORCES_MAP_K_VALUES,
    FORCES_MAP_BYTES_PER_POINT,
    ForcesMapSection,
    forces_map_memory_bytes,
    largest_forces_map_resolution,
)
from rubcli.case.loading import (
    MAX_CASE_FILE_BYTES,
    load_case,
    load_case_text,
    parse_case_text,
    read_case_file,
)
from rubcli.case.machine import ModelSection, PhysicalSection, StatorSection
from rubcli.case.orbits import OrbitsSection
from rubcli.case.run import (
    KNOWN_PLOTS,
    CaseSection,
    InitialSection,
    OutputSection,
    SolverSection,
    TimeSection,
)
from rubcli.case.speed import SpeedSection
from rubcli.case.sweep import RecognitionSection, SweepAxis, SweepSection, sweep_memory

__all__ = [
    "DEFAULT_FORCES_MAP_DELTAS",
    "DEFAULT_FORCES_MAP_K_VALUES",
    "FORCES_MAP_BYTES_PER_POINT",
    "KNOWN_METHODS",
    "KNOWN_PLOTS",
    "MAX_CASE_FILE_BYTES",
    "MAX_CASE_MEMORY_BYTES",
    "AnalysisSection",
    "Case",
    "CaseError",
    "CaseFile",
    "CaseSection",
    "ChartSection",
    "CompareSection",
    "EnsembleSection",
    "ForcesMapSection",
    "InitialSection",
    "ModelSection",
    "OrbitsSection",
    "OutputSection",
    "PhysicalSection",
    "RecognitionSection",
    "SolverSection",
    "SpeedSection",
    "StatorSection",
    "SweepAxis",
    "SweepSection",
    "TimeSection",
    "assemble_case",
    "forces_map_memory_bytes",
    "largest_forces_map_resolution",
    "load_case",
    "load_case_text",
    "paper_machine_problem",
    "parse_case_text",
    "read_case_file",
    "run_memory_bytes",
    "sweep_memory",
    "validate_case",
]

"""How far each pinned run of the golden test moves between BLAS kernels.

``python tests/golden/kernel_spread.py`` runs every pinned run (``scenarios.runs``) once
per OpenBLAS kernel (``OPENBLAS_CORETYPE``, each in its own process: the kernel is chosen
when the library loads) and compares each with ``solvers.json``: the largest deviation of
the states and of the event times (relative to max(1, |value|), as the golden test
measures them), and whether the status, the event kinds and regimes, the sample regimes
and each step count are identical. It prints one line per run that moved and writes the
whole table as JSON (``--out``, default ``kernel_spread.json`` beside this file).

The tolerances of ``tests/test_golden.py`` are set from this table (see its docstring).
Kernels this CPU cannot run are reported as skipped by OpenBLAS itself (it falls back to
another one, named in the table). ``--kernels`` picks the kernels; ``--dump FILE`` is the
child's mode (run everything under the current environment, write the records).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))

DEFAULT_KERNELS = ("", "Haswell", "SkylakeX", "Sandybridge", "Prescott")


def _dump(path: Path) -> None:
    from scenarios import record, runs

    from rubcli.solvers import solve

    out: dict = {}
    for name, label, problem, method, options in runs():
        out.setdefault(name, {})[label] = record(solve(problem, method, **options))
    path.write_text(json.dumps(out))


def _kernel_loaded(env: dict) -> str:
    """The kernel OpenBLAS reports for this environment (``OPENBLAS_VERBOSE=2``)."""
    probe = "import numpy; numpy.dot(numpy.ones((8, 8)), numpy.ones((8, 8)))"
    done = subprocess.run(
        [sys.executable, "-c", probe],
        env={**env, "OPENBLAS_VERBOSE": "2"},
        capture_output=True,
        text=True,
        check=False,
    )
    lines = (done.stdout + done.stderr).splitlines()
    cores = [ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("Core:")]
    return cores[0] if cores else "unknown"


def _deviation(a, b) -> float:
    import numpy as np

    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape:
        return float("inf")
    if a.size == 0:
        return 0.0
    return float(np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b))))


def compare(got: dict, pinned: dict) -> dict:
    """Per scenario and label: the deviations from the pins, what is identical, and the
    golden test's tolerance of the run (``test_golden.state_tolerance``)."""
    sys.path.insert(0, str(HERE.parent))
    from scenarios import settings as labelled
    from test_golden import state_tolerance

    options = {**{k: o for k, (_, o) in labelled().items()}, **_python_options()}
    table: dict = {}
    for name, runs_ in pinned.items():
        for label, want in runs_.items():
            have = got[name][label]
            same_events = [e[1:] for e in have["events"]] == [e[1:] for e in want["events"]]
            nsteps = want["stats"]["nsteps"]
            table.setdefault(name, {})[label] = {
                "tolerance": state_tolerance(name, label, options[label], nsteps),
                "states": _deviation(have["states"], want["states"]),
                "event_times": _deviation(
                    [e[0] for e in have["events"]], [e[0] for e in want["events"]]
                )
                if same_events
                else None,
                "t_end": _deviation([have["t_end"]], [want["t_end"]]),
                "status_same": have["status"] == want["status"],
                "events_same": same_events,
                "regimes_same": have["regimes"] == want["regimes"],
                "stats_changed": {
                    k: [want["stats"].get(k), v]
                    for k, v in have["stats"].items()
                    if want["stats"].get(k) != v
                },
            }
    return table


def _python_options() -> dict:
    from scenarios import python_settings

    return {k: o for k, (_, o) in python_settings().items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kernels", nargs="+", default=list(DEFAULT_KERNELS))
    ap.add_argument("--out", type=Path, default=HERE / "kernel_spread.json")
    ap.add_argument("--dump", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.dump:
        _dump(args.dump)
        return
    pinned = json.loads((HERE / "solvers.json").read_text())
    result: dict = {}
    for kernel in args.kernels:
        env = dict(os.environ)
        env.pop("OPENBLAS_CORETYPE", None)
        if kernel:
            env["OPENBLAS_CORETYPE"] = kernel
        loaded = _kernel_loaded(env)
        dump = args.out.with_suffix(f".{kernel or 'default'}.tmp")
        subprocess.run([sys.executable, __file__, "--dump", str(dump)], env=env, check=True)
        table = compare(json.loads(dump.read_text()), pinned)
        dump.unlink()
        result[kernel or "default"] = {"loaded": loaded, "runs": table}
        print(f"== OPENBLAS_CORETYPE={kernel or '(unset)'} (OpenBLAS loaded {loaded})")
        for name, runs_ in table.items():
            for label, row in runs_.items():
                identical = (
                    row["states"] == 0.0
                    and not row["event_times"]
                    and row["events_same"]
                    and row["regimes_same"]
                    and row["status_same"]
                    and not row["stats_changed"]
                )
                if identical:
                    continue
                times = row["event_times"]
                worst = max(row["states"], times or 0.0)
                margin = row["tolerance"] / worst if worst > 0 else float("inf")
                print(
                    f"  {name:22} {label:32} tolerance/spread {margin:9.3g} "
                    f"states {row['states']:.2e} "
                    f"events {'same' if row['events_same'] else 'DIFFER'} "
                    f"times {'-' if times is None else f'{times:.2e}'} "
                    f"regimes {'same' if row['regimes_same'] else 'DIFFER'} "
                    f"stats {row['stats_changed'] or 'same'}"
                )
    args.out.write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

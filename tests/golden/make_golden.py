"""Regenerate tests/golden/solvers.json (see scenarios.py). Review the diff before committing.

``python tests/golden/make_golden.py`` regenerates every entry; with ``--only LABEL ...``
only the runs of those method settings (labels of ``scenarios.settings`` and
``python_settings``, e.g. ``analytic analytic-python``), the others kept as pinned.
"""

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from scenarios import record, runs  # noqa: E402

from rubcli.solvers import solve  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", nargs="+", help="regenerate only these method settings")
    args = ap.parse_args()
    path = Path(__file__).with_name("solvers.json")
    out: dict = json.loads(path.read_text()) if args.only else {}
    for name, label, problem, method, options in runs():
        if args.only and label not in args.only:
            continue
        start = time.perf_counter()
        sol = solve(problem, method, **options)
        out.setdefault(name, {})[label] = record(sol)
        print(
            f"{name:22} {label:32} {sol.status:8} {len(sol.events):4} events "
            f"{time.perf_counter() - start:7.2f} s  {sol.message[:60]}"
        )
    path.write_text(json.dumps(out, indent=0, sort_keys=True) + "\n")
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()

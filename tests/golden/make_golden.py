"""Regenerate tests/golden/solvers.json (see scenarios.py). Review the diff before committing."""

import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from scenarios import record, runs  # noqa: E402

from rubcli.solvers import solve  # noqa: E402


def main() -> None:
    out: dict = {}
    for name, label, problem, method, options in runs():
        start = time.perf_counter()
        sol = solve(problem, method, **options)
        out.setdefault(name, {})[label] = record(sol)
        print(
            f"{name:22} {label:32} {sol.status:8} {len(sol.events):4} events "
            f"{time.perf_counter() - start:7.2f} s  {sol.message[:60]}"
        )
    path = Path(__file__).with_name("solvers.json")
    path.write_text(json.dumps(out, indent=0, sort_keys=True) + "\n")
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()

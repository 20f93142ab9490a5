"""Check the key results of the Figure 3 reproduction from its report.json (used by CI).

    rubcli compare cases/paper/fig3.toml --quick --out out/ci-fig3
    python .ci/check_fig3.py out/ci-fig3/report.json

Asserts what docs/reproduction.md states and the quick run can resolve: at mu = 0 both
the analytic method and rk45 classify as periodic with period 1 (the synchronous full
annular rub, stable); for mu = 0 and 0.01 the two methods agree within 5e-3 clearances
(the analytic method's own error at 400 steps per period is ~1e-3); the synchronous rub
is stable for mu <= 0.01 and unstable from 0.02. Exits non-zero with the reason if not.
"""

import json
import sys
from pathlib import Path

AGREEMENT = 5e-3


def main(path: str) -> int:
    report = json.loads(Path(path).read_text())
    panels = {round(p["mu"], 6): p for p in report["orbits"]}
    problems = []
    for method in ("analytic", "rk45"):
        r = panels[0.0]["methods"][method].get("response") or {}
        if r.get("kind") != "periodic" or r.get("period") != 1:
            problems.append(f"mu = 0, {method}: {r.get('kind')} period {r.get('period')}")
    for mu in (0.0, 0.01):
        diff = panels[mu]["agreement"]["analytic vs rk45"]["max_difference"]
        if not diff < AGREEMENT:
            problems.append(f"mu = {mu}: analytic vs rk45 differ by {diff:.3g} > {AGREEMENT}")
    for mu, stable in ((0.0, True), (0.01, True), (0.02, False), (0.05, False)):
        rubs = panels[mu]["synchronous_rubs"]
        if not rubs or rubs[0]["stable"] != stable:
            problems.append(f"mu = {mu}: synchronous rub stable should be {stable}")
    for line in problems:
        print("FAIL:", line)
    if not problems:
        print(
            "fig3 reproduction: mu = 0 periodic (period 1) with both methods; analytic and "
            "rk45 agree within 5e-3 for mu <= 0.01; synchronous rub stable up to 0.01 only"
        )
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))

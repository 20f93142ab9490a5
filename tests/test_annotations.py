"""Every public function of the package is annotated: each parameter and the return (a
library's signatures are its documentation, and type checkers read them)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "rubcli"


def _unannotated(path: Path) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        if node.name.startswith("_"):
            continue
        a = node.args
        params = [*a.posonlyargs, *a.args, *a.kwonlyargs, *filter(None, (a.vararg, a.kwarg))]
        missing = [p.arg for p in params if p.annotation is None and p.arg not in ("self", "cls")]
        if missing or node.returns is None:
            what = ", ".join(missing) + ("; return" if node.returns is None else "")
            out.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {node.name}: {what}")
    return out


def test_every_public_function_is_annotated():
    missing = [line for path in sorted(PACKAGE.rglob("*.py")) for line in _unannotated(path)]
    assert not missing, "\n".join(missing)

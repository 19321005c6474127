"""viz3d.hydro imports only numpy, scipy, the standard library, viz3d._typing, viz3d.flexible and itself."""

import ast
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "viz3d" / "hydro"
ALLOWED_THIRD_PARTY = {"numpy", "scipy"}
ALLOWED_VIZ3D = ("viz3d._typing", "viz3d.flexible", "viz3d.hydro")


def imported_modules(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            yield node.module
        elif isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)


def test_hydro_imports_only_what_the_layering_allows():
    bad = []
    for path in PACKAGE.rglob("*.py"):
        for module in imported_modules(path):
            top = module.split(".")[0]
            if top == "viz3d":
                ok = any(module == m or module.startswith(m + ".") for m in ALLOWED_VIZ3D)
            else:
                ok = top in ALLOWED_THIRD_PARTY or top in sys.stdlib_module_names or top == "__future__"
            if not ok:
                bad.append(f"{path.name} imports {module}")
    assert not bad, bad

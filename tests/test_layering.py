"""Imports only go downwards: integrators never see bodies; the core never imports the CLI."""

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "viz3d"

FORBIDDEN = {
    "integrators": {"viz3d.bodies", "viz3d.joints", "viz3d.forces", "viz3d.system", "viz3d.dynamics", "viz3d.scene"},
    "rotations.py": {"viz3d.bodies", "viz3d.joints", "viz3d.system"},
    # viewer and recorder consume frames: no integrators, formulations, assembly or dynamics
    "viz": {"viz3d.integrators", "viz3d.formulation", "viz3d.dynamics", "viz3d.scene.build", "viz3d.simulate",
            "viz3d.constraints", "viz3d.stabilization"},
    "*": {"viz3d.cli"},
}


def _imports(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            yield node.module
        elif isinstance(node, ast.Import):
            yield from (a.name for a in node.names)


def test_layering():
    bad = []
    for path in PKG.rglob("*.py"):
        rel = path.relative_to(PKG)
        rules = set(FORBIDDEN["*"]) if rel.name != "cli.py" and rel.name != "__main__.py" else set()
        if rel.parts[0] in ("integrators", "viz"):
            rules |= FORBIDDEN[rel.parts[0]]
        rules |= FORBIDDEN.get(rel.name, set())
        for mod in _imports(path):
            if any(mod == r or mod.startswith(r + ".") for r in rules):
                bad.append(f"{rel} imports {mod}")
    assert not bad, bad

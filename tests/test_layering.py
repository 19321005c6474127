"""Imports only go downwards, and there are no import cycles (imports inside functions count).

Layers, top to bottom (a module may import its own layer and the ones below):

* ``cli``: the command line and the package's public API (``viz3d/__init__.py``);
* ``view``: the viewer and the recorder (``viz/``), which consume frames;
* ``drivers``: scenes, simulation, live driver, studies (``scene/``, ``simulate``, ``realtime``,
  ``bench``, ``stability``, output frames and trajectories);
* ``numerics``: integrators, formulations, stabilization, the compiled kernel, contact event
  stepping; they see generalized vectors and the system's assembled functions, never a scene;
* ``physics``: bodies, material points, joints, force elements, contacts and their laws, flexible
  bars, hydrodynamics, the system and its assembly (mass matrix, forces, constraint rows);
* ``base``: rotations, types, the compiled-piece registry.

Every module of the package must be assigned a layer here: a new module fails until it is.
"""

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "viz3d"
ORDER = ("base", "physics", "numerics", "drivers", "view", "cli")

LAYERS = {
    "base": ["viz3d._typing", "viz3d.rotations", "viz3d.compiled"],
    "physics": ["viz3d.bodies", "viz3d.points", "viz3d.joint_axes", "viz3d.joints", "viz3d.forces", "viz3d.timefunctions",
                "viz3d.geometry", "viz3d.mass", "viz3d.kinematics", "viz3d.coordinates", "viz3d.constraints",
                "viz3d.system", "viz3d.dynamics", "viz3d.contact.*", "viz3d.flexible.*", "viz3d.hydro.*", "viz3d.water", "viz3d.anchoring"],
    "numerics": ["viz3d.integrators.*", "viz3d.formulation", "viz3d.stabilization", "viz3d.ali3p", "viz3d.methods",
                 "viz3d.kernel.*", "viz3d.events", "viz3d.diagnosis", "viz3d.sparsity"],
    "drivers": ["viz3d.scene.*", "viz3d.simulate", "viz3d.realtime", "viz3d.bench", "viz3d.stability", "viz3d.stowage", "viz3d.stowagestudy", "viz3d.hydrostudy",
                "viz3d.studies.*", "viz3d.sweep",
                "viz3d.frames", "viz3d.trajectory", "viz3d.outputs", "viz3d.extras", "viz3d.sink", "viz3d.interrupts", "viz3d.columns",
                "viz3d.departures"],
    "view": ["viz3d.viz.*"],
    "cli": ["viz3d", "viz3d.cli", "viz3d.__main__", "viz3d.process"],  # the package's public API is at the top
}


def modules() -> dict[str, Path]:
    out = {}
    for f in PKG.rglob("*.py"):
        rel = f.relative_to(PKG.parent).with_suffix("")
        out[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = f
    return out


def layer_of(module: str) -> str | None:
    for layer, patterns in LAYERS.items():
        for p in patterns:
            if module == p or (p.endswith(".*") and (module == p[:-2] or module.startswith(p[:-1]))):
                return layer
    return None


def import_graph() -> dict[str, set[str]]:
    """Module -> the package modules it imports anywhere in its source (AST)."""
    mods = modules()
    graph = {}
    for name, path in mods.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                deps.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                deps.add(node.module)
                deps.update(f"{node.module}.{a.name}" for a in node.names)
        graph[name] = {d for d in deps if d in mods and d not in (name, "viz3d")}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_every_module_has_a_layer():
    assert not [m for m in modules() if layer_of(m) is None]


def test_no_upward_imports():
    rank = {layer: i for i, layer in enumerate(ORDER)}
    bad = [f"{m} ({layer_of(m)}) imports {d} ({layer_of(d)})" for m, deps in import_graph().items() for d in deps
           if layer_of(m) and layer_of(d) and rank[layer_of(d)] > rank[layer_of(m)]]
    assert not bad, bad


def test_no_import_cycles():
    assert not cycles(import_graph())


def test_the_checks_can_fail():
    """The checker sees an upward import and a cycle when there are some."""
    graph = {"viz3d.rotations": {"viz3d.cli"}, "viz3d.cli": {"viz3d.rotations"}}
    assert cycles(graph) == [["viz3d.cli", "viz3d.rotations"]]
    assert ORDER.index(layer_of("viz3d.cli")) > ORDER.index(layer_of("viz3d.rotations"))

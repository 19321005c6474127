"""The scene's ``[collision]`` table: collision shapes, groups and pair laws (``viz3d.contact.collision``).

Every rigid body of a group collides with its own shape (mesh shapes as their convex hull unless
listed in ``triangle_meshes``); the ground shapes form the group ``ground``. Each
``[[collision.pairs]]`` entry names two groups and the law acting where they touch.
"""

from __future__ import annotations

from fnmatch import fnmatchcase

import numpy as np

from viz3d.contact import laws as L
from viz3d.contact.collision import Collisions, PairLaw, Shape, convex_hull, support_points
from viz3d.contact.parameters import effective_modulus
from viz3d.geometry import MeshError, shape_mesh
from viz3d.rotations import matrix_from_euler
from viz3d.scene.contacts import DEFAULT_MATERIAL, RIGID, contact_law, friction_law
from viz3d.scene.schema import SceneError

GROUND = "ground"


def build_collisions(scene, n_bodies: int, is_rigid, centers) -> tuple[Collisions, ...]:
    """The ``Collisions`` force element of a scene with a ``[collision]`` table (``scene.build.shape_contacts``
    calls it for those only).

    ``centers[i]``: the centroid of body i's mesh shape in its own frame (vertices are shifted by it).
    """
    spec = scene.data["collision"]
    src, bodies = scene.source(), scene.data["bodies"]
    groups = _groups(src, spec, bodies, is_rigid)
    names = list(groups) + [GROUND]
    shapes = []
    for g, members in enumerate(groups.values()):
        for i in members:
            shapes.append(_body_shape(scene, spec, bodies[i], i, centers[i], g))
    for k, entry in enumerate(spec["ground"]):
        shapes.append(_ground_shape(scene, entry, k, n_bodies, len(names) - 1, spec["rim_points"]))
    if not spec["pairs"]:
        raise SceneError(src, "collision.pairs", "at least one [[collision.pairs]] entry naming two groups that collide")
    pair_law = -np.ones((len(names), len(names)), int)
    laws = []
    for p, entry in enumerate(spec["pairs"]):
        where = f"collision.pairs[{p}]"
        g1, g2 = (_group_index(src, names, g, f"{where}.groups") for g in entry["groups"])
        if names[g1] == names[g2] == GROUND:
            raise SceneError(src, f"{where}.groups", "at most one 'ground' (ground shapes never move)", entry["groups"])
        if pair_law[g1, g2] >= 0:
            raise SceneError(src, f"{where}.groups", "a pair of groups not already given", entry["groups"])
        pair_law[g1, g2] = pair_law[g2, g1] = len(laws)
        laws.append(_pair_law(src, entry, where, [s for s in shapes if s.group in (g1, g2)], names[g1], names[g2]))
    excluded = frozenset()
    if spec["skip_joined"]:
        index = {b["name"]: i for i, b in enumerate(bodies)}
        excluded = frozenset(tuple(sorted((index[j["body1"]], index[j["body2"]]))) for j in scene.data["joints"]
                             if j.get("body2", GROUND) in index and j["body1"] in index)
    element = Collisions(tuple(shapes), tuple(names), pair_law, tuple(laws), n_bodies, excluded,
                         spec["max_contacts"], spec["merge_distance"])
    return (element,)


def _groups(src: str, spec: dict, bodies: list[dict], is_rigid) -> dict[str, list[int]]:
    given = spec["groups"] or {"bodies": [b["name"] for i, b in enumerate(bodies) if is_rigid[i] and "shape" in b]}
    out, owner = {}, {}
    for g, patterns in given.items():
        where = f"collision.groups.{g}"
        if g == GROUND:
            raise SceneError(src, where, "a group name other than 'ground' (the ground shapes' group)")
        members = bodies_matching(src, where, patterns, bodies)
        for i in members:
            b = bodies[i]
            if not is_rigid[i] or "shape" not in b:
                raise SceneError(src, where, f"rigid bodies with a shape (body {b['name']!r} has "
                                 f"{'no shape' if is_rigid[i] else 'a flexible model'})", b["name"])
            if i in owner:
                raise SceneError(src, where, f"bodies in one group only ({b['name']!r} is already in {owner[i]!r})",
                                 b["name"])
            owner[i] = g
        out[g] = members
    return out


def bodies_matching(src: str, where: str, patterns: list[str], bodies: list[dict]) -> list[int]:
    """Indices of the scene bodies whose names match any of ``patterns`` (fnmatch), in first-match
    order; a pattern that matches no body is a ``SceneError`` at ``where``."""
    out: list[int] = []
    for pattern in patterns:
        hit = [i for i, b in enumerate(bodies) if fnmatchcase(b["name"], pattern)]
        if not hit:
            raise SceneError(src, where, "body names or patterns that match a body", pattern)
        out += [i for i in hit if i not in out]
    return out


def _group_index(src: str, names: list[str], g: str, where: str) -> int:
    if g not in names:
        raise SceneError(src, where, f"group names among {names}", g)
    return names.index(g)


def _mesh(scene, shape: dict, where: str):
    try:
        return shape_mesh(shape, scene.base_dir)
    except MeshError as exc:
        raise SceneError(scene.source(), f"{where}.file", f"a readable mesh file ({exc})") from None


def _geometry(scene, shape: dict, where: str, triangles: bool, center, rim_points: int):
    """``(kind, size, vertices, faces, support)`` of a scene shape table in its own axes."""
    kind = shape["type"]
    size, vertices, faces = (), np.zeros((0, 3)), np.zeros((0, 3), int)
    if kind == "sphere":
        size = (shape["radius"],)
    elif kind in ("capsule", "cylinder"):
        size = (shape["radius"], shape["height"])
    elif kind == "box":
        size = tuple(float(x) for x in shape["extents"])
    else:  # mesh
        mesh = _mesh(scene, shape, where)
        vertices, faces = np.asarray(mesh.vertices, float) - np.asarray(center, float), np.asarray(mesh.faces, int)
        if not triangles:
            try:
                vertices, faces = convex_hull(vertices)
            except Exception as exc:  # Qhull errors: flat or degenerate point sets
                raise SceneError(scene.source(), f"{where}.file", f"a mesh with a 3-D convex hull ({exc})") from None
            kind = "convex"
    return kind, size, vertices, faces, support_points(kind, size, vertices, rim_points)


def _body_shape(scene, spec: dict, body: dict, i: int, center, group: int) -> Shape:
    triangles = any(fnmatchcase(body["name"], p) for p in spec["triangle_meshes"])
    kind, size, v, f, support = _geometry(scene, body["shape"], f"bodies[{i}].shape", triangles, center,
                                          spec["rim_points"])
    return Shape(body["name"], i, kind, size, vertices=v, faces=f, support=support, group=group)


def _ground_shape(scene, entry: dict, k: int, n_bodies: int, group: int, rim_points: int) -> Shape:
    name = entry.get("name", f"ground{k}")
    if entry["type"] == "plane":
        n = np.asarray(entry["normal"], float)
        return Shape(name, n_bodies, "plane", B_r=np.asarray(entry["point"], float), group=group,
                     normal=n / np.linalg.norm(n))
    kind, size, v, f, support = _geometry(scene, entry, f"collision.ground[{k}]", not entry.get("convex", False),
                                          np.zeros(3), rim_points)
    R = matrix_from_euler(np.radians(entry["euler_deg"]))
    return Shape(name, n_bodies, kind, size, np.asarray(entry["position"], float), R, v, f, support, group)


def _pair_law(src: str, entry: dict, where: str, shapes: list[Shape], name1: str, name2: str) -> PairLaw:
    cls = L.NORMAL_LAWS[entry["law"]]
    if cls.kind == "elastoplastic":
        raise SceneError(src, f"{where}.law", "a law without contact memory (linear, hertz, or a rate law with "
                         "damping_factor): collision contacts are stepped through, not located", entry["law"])
    if issubclass(cls, L.HysteresisLaw) and "damping_factor" not in entry:
        raise SceneError(src, f"{where}.damping_factor", f"a fixed c [s/m] for the {entry['law']} law (collision "
                         "contacts have no located onset to calibrate a target restitution at)")
    mats = [entry.get(f"material{k}", RIGID if g == GROUND else DEFAULT_MATERIAL) for k, g in ((1, name1), (2, name2))]
    modulus = np.nan
    values = {**entry, "radius": 0.0}
    if "stiffness" not in entry and cls is not L.Linear:
        odd = next((s for s in shapes if s.kind not in ("sphere", "plane")), None)
        if odd is not None:
            raise SceneError(src, f"{where}.stiffness", f"a stiffness [N/m^n] (Hertz from the materials needs spheres "
                             f"and planes; {odd.name!r} is a {odd.kind})")
        modulus = effective_modulus(mats[0]["E"], mats[0]["nu"], mats[1]["E"], mats[1]["nu"])
        values["stiffness"] = 1.0  # replaced per pair of shapes by Hertz's constant
    _, law, _ = contact_law(values, (mats[0], mats[1]), src, where)
    dashpot = 0.0 if cls is L.Linear else entry["damping"]
    # shape contacts keep their stick anchors without located events (viz3d.contact.collision)
    return PairLaw(law, dashpot, friction_law(src, {**entry, "events": True}, where, "law", False), modulus)

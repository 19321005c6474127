"""``Scene`` + ``System`` -> ``SceneVisuals``: display meshes, colours and scales.

A body without a shape is drawn as its equivalent-inertia box (same mass and principal moments),
oriented along its principal axes. A spring whose end is on ground ends on a post standing on the
floor (static geometry), so it visibly ends on something; what hangs from ground joints gets a
reach sphere, so a camera can keep all of its motion in view.
"""

from __future__ import annotations

import json

import numpy as np

from viz3d.forces import SpringDamper
from viz3d.frames import BodyVisual, SceneVisuals, StaticVisual
from viz3d.geometry import display_mesh
from viz3d.scene.build import body_mass_properties
from viz3d.scene.load import Scene
from viz3d.system import System

#: Colours of bodies that give none (Tableau 10).
PALETTE = np.array([[78, 121, 167], [242, 142, 43], [225, 87, 89], [118, 183, 178], [89, 161, 79],
                    [237, 201, 72], [176, 122, 161], [255, 157, 167], [156, 117, 95], [186, 176, 172]], dtype=np.uint8)
G_REFERENCE = 9.81
#: Posts under the ground ends of springs: shaft and knob radii [fraction of the scene's thickness].
POST_RADIUS = 0.25
KNOB_RADIUS = 0.6
POST_COLOR = np.array([110, 110, 110], dtype=np.uint8)


def scene_visuals(scene: Scene, system: System) -> SceneVisuals:
    """Display data of every body, joint and spring of ``scene``."""
    bodies = tuple(_body_visual(scene, system, i) for i in range(system.n_bodies))
    positions = np.array([b["position"] for b in scene.data["bodies"]], float)
    radii = np.array([b.radius for b in bodies])
    g = np.linalg.norm(scene.data["sim"]["gravity"]) or G_REFERENCE
    weight = float(system.bodies.mass.sum() * g)
    springs = tuple(n for e in system.forces if isinstance(e, SpringDamper) for n in e.names)
    thickness = float(np.median([_thickness(b) for b in bodies]))
    lo, hi = (positions - radii[:, None]).min(axis=0), (positions + radii[:, None]).max(axis=0)
    statics = _posts(_spring_ground_points(system), min(0.0, lo[2]), thickness)
    for st in statics:
        lo, hi = np.minimum(lo, st.vertices.min(axis=0)), np.maximum(hi, st.vertices.max(axis=0))
    return SceneVisuals(
        name=scene.name, bodies=bodies, joint_names=system.joint_names, spring_names=springs,
        length_scale=float(np.median(radii)), thickness=thickness, force_scale=weight if weight > 0 else 1.0,
        bounds=np.array([lo, hi]), statics=statics, reach=_reach(system, positions, radii))


def _spring_ground_points(system: System) -> np.ndarray:
    """Distinct world points where springs are attached to ground, shape (k, 3) [m]."""
    ground = system.n_bodies
    points = [e.B_s[e.body == ground] for e in system.forces if isinstance(e, SpringDamper)]
    points = np.concatenate(points) if points else np.zeros((0, 3))
    return np.unique(np.round(points, 12), axis=0)


def _posts(points: np.ndarray, floor: float, thickness: float) -> tuple[StaticVisual, ...]:
    """One mesh of vertical posts from the floor (height ``floor`` [m]) up to each point, each
    topped by a knob; empty without points."""
    import trimesh

    parts = []
    for x, y, z in points:
        parts.append(trimesh.creation.icosphere(subdivisions=2, radius=KNOB_RADIUS * thickness).apply_translation((x, y, z)))
        if z > floor:
            parts.append(trimesh.creation.cylinder(radius=POST_RADIUS * thickness, segment=((x, y, floor), (x, y, z)),
                                                   sections=16))
    if not parts:
        return ()
    mesh = trimesh.util.concatenate(parts)
    return (StaticVisual("posts", np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32), POST_COLOR),)


def _reach(system: System, positions: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Per ground joint, the sphere ``[x, y, z, r]`` [m] about its point that holds every body
    joined to it (through any chain of joints) at any pose: r = the farthest body's distance
    from the point plus its bounding radius. Shape (k, 4)."""
    ground = system.n_bodies
    root = list(range(ground))

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = root[i]
        return i

    anchors = []
    for js in system.joints.joints:
        for (b0, b1), s in zip(js.body, getattr(js, "B_s", np.zeros((len(js.body), 2, 3)))):
            if b0 != ground and b1 != ground:
                root[find(b0)] = find(b1)
            elif b0 != b1:
                anchors.append((s[0] if b0 == ground else s[1], b1 if b0 == ground else b0))
    spheres = []
    for point, body in anchors:
        held = [i for i in range(ground) if find(i) == find(body)]
        spheres.append([*point, float(np.max(np.linalg.norm(positions[held] - point, axis=1) + radii[held]))])
    return np.array(spheres).reshape(-1, 4)


def _body_visual(scene: Scene, system: System, i: int) -> BodyVisual:
    spec = scene.data["bodies"][i]
    color = np.asarray(spec.get("color", PALETTE[i % len(PALETTE)]), dtype=np.uint8)
    if "shape" in spec:
        center = body_mass_properties(scene, i).center if "inertia" not in spec else np.zeros(3)
        mesh = display_mesh(spec["shape"], scene.base_dir, center)
        vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        group = json.dumps([spec["shape"], np.round(center, 12).tolist()], sort_keys=True)
    else:
        vertices, faces = _inertia_box(system.bodies.mass[i], system.bodies.inertia[i])
        group = f"inertia-box:{spec['name']}"
    radius = float(np.max(np.linalg.norm(vertices, axis=1)))
    return BodyVisual(spec["name"], vertices.astype(np.float32), faces.astype(np.int32), color, group, radius)


def _thickness(body: BodyVisual) -> float:
    """Smallest extent of the body's vertices along its principal directions [m]."""
    v = body.vertices - body.vertices.mean(axis=0)
    _, axes = np.linalg.eigh(v.T @ v)
    return float(np.min(np.ptp(v @ axes, axis=0)))


def _inertia_box(mass: float, inertia: np.ndarray):
    """Vertices and faces of the uniform box with the same mass and inertia tensor."""
    import trimesh

    moments, axes = np.linalg.eigh(inertia)
    Ix, Iy, Iz = moments
    ext = np.sqrt(np.maximum(6.0 / mass * np.array([Iy + Iz - Ix, Ix + Iz - Iy, Ix + Iy - Iz]), 1e-12))
    box = trimesh.creation.box(extents=ext)
    return np.asarray(box.vertices) @ axes.T, np.asarray(box.faces)

"""``Scene`` + ``System`` -> ``SceneVisuals``: display meshes, colours and scales.

A body without a shape is drawn as its equivalent-inertia box (same mass and principal moments),
oriented along its principal axes. A spring whose end is on ground ends on a post standing on the
floor (static geometry), so it visibly ends on something; what hangs from ground joints gets a
reach sphere, so a camera can keep all of its motion in view.
"""

from __future__ import annotations

import json
from functools import cache

import numpy as np

from viz3d.flexible.floating_points import material_points
from viz3d.forces import SpringDamper
from viz3d.frames import BodyVisual, DeformableVisual, FlexibleDrawing, SceneVisuals, StaticVisual, surface_stress_rows
from viz3d.geometry import display_mesh
from viz3d.kinematics import Configuration, pose_from, twist_from
from viz3d.scene.build import body_mass_properties, initial_pose
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
PLANE_COLOR = np.array([150, 150, 150], dtype=np.uint8)
#: A flexible bar is drawn as a tube: this many sections along it, this many points round each.
SECTIONS = 41
RING = 12
#: Plates drawn for contact planes on ground: side [multiple of the scene's length scale].
PLANE_SIZE = 20.0


def scene_visuals(scene: Scene, system: System) -> SceneVisuals:
    """Display data of every body, joint, spring, contact plane and flexible body of ``scene``."""
    bodies = tuple(_body_visual(scene, system, i) for i in range(system.n_bodies))
    positions, _ = initial_pose(scene, system.bodies)
    drawings = flexible_drawings(scene, system)
    deformables = _deformables(scene, system, drawings)
    radii = np.array([b.radius for b in bodies])
    for d in deformables:
        radii[d.body] = float(np.max(np.linalg.norm(d.vertices - positions[d.body], axis=1)))
    g = np.linalg.norm(scene.data["sim"]["gravity"]) or G_REFERENCE
    weight = float(system.bodies.mass.sum() * g)
    springs = tuple(n for e in system.forces if isinstance(e, SpringDamper) for n in e.names)
    thickness = float(np.median([_thickness(b) for b in bodies if b.vertices.size] or [_bar_depth(system)]))
    lo, hi = (positions - radii[:, None]).min(axis=0), (positions + radii[:, None]).max(axis=0)
    length_scale = float(np.median(radii))
    statics = (_posts(_spring_ground_points(system), min(0.0, lo[2]), thickness) + _planes(system, PLANE_SIZE * length_scale)
               + _collision_grounds(system, PLANE_SIZE * length_scale))
    for st in statics:
        lo, hi = np.minimum(lo, st.vertices.min(axis=0)), np.maximum(hi, st.vertices.max(axis=0))
    frame_dt = scene.data["display"].get("frame_dt")
    extra = {"display_dt": float(frame_dt)} if frame_dt else {}
    if plot_dt := scene.data["display"].get("plot_dt"):
        extra["plot_dt"] = float(plot_dt)
    if stress_scale := scene.data["display"].get("stress_scale"):
        extra["stress_scale"] = float(stress_scale)
    return SceneVisuals(
        name=scene.name, bodies=bodies, joint_names=system.joint_names, spring_names=springs,
        length_scale=length_scale, thickness=thickness, force_scale=weight if weight > 0 else 1.0,
        bounds=np.array([lo, hi]), deformables=tuple(DeformableVisual(d.name, d.faces, d.vertices, d.color,
                                                                      RING if d.stressed else 0)
                                                     for d in deformables),
        plots=_plots(system), statics=statics, reach=_reach(system, positions, radii), **extra)


def _plots(system: System) -> tuple[tuple[str, str], ...]:
    """The time-series panels the frames feed (title, entity prefix under /plots)."""
    plots = [("Energy [J]", "energy"), ("Constraint violation [m]", "constraint_violation"),
             ("Joint reaction force [N]", "reaction_force")]
    if system.contacts:
        plots.append(("Contact force [N]", "contact"))
    plots += list(dict.fromkeys(out.plot for out in system.outputs))  # (gauges on several bars: one panel)
    if system.driven:
        plots.append(("Drive effort [N or N m]", "drive"))
    for e in system.forces:  # shape contacts, water, joint stops: the element's own series
        for title, key in live_plots(e):
            plots.append((title, key.rsplit("/", 1)[0] if key.startswith("joint/") else key))
    return tuple(plots)


def live_plots(element) -> tuple[tuple[str, str], ...]:
    """``(title, frame scalar)`` of each series a force element shows: its ``live_plot`` (shape
    contacts' normal force, water's buoyancy), or a joint stop's coordinates (the anchor's flukes)."""
    from viz3d.forces import JointStop

    if isinstance(element, JointStop):
        return tuple((f"{name}: {js.names[j]} {js.FREE[c][0]} [{_unit(js.FREE[c][0])}]", f"joint/{js.names[j]}/{js.FREE[c][0]}")
                     for name, js, j, c in zip(element.names, element.joints, element.index, element.free))
    plot = getattr(element, "live_plot", None)
    return (plot,) if plot else ()


def _unit(coordinate: str) -> str:
    """The unit of a joint's relative coordinate by its name (``Joint.FREE``): angles in rad, distances in m."""
    return "rad" if coordinate.startswith("angle") else "m"


def _bar_depth(system: System) -> float:
    return float(min(fb.bar.section.depth for fb in system.bodies.flexible)) if system.bodies.flexible else 0.01


def flexible_drawings(scene: Scene, system: System) -> tuple[FlexibleDrawing, ...]:
    """How each flexible body is drawn: a tube along its deformed axis, ``[display] amplification``
    times its deformation, its vertices carrying the surface bending stress."""
    out = []
    for k, fb in enumerate(system.bodies.flexible):
        name = system.bodies.names[fb.index]
        x = np.linspace(0.0, fb.bar.length, SECTIONS)
        ring = _ring(fb.bar.section)
        out.append(FlexibleDrawing(name, k, fb.index, material_points(fb.bar, x), ring,
                                   scene.data["display"]["amplification"], surface_stress_rows(fb.bar, x, ring)))
    return tuple(out)


class _Deformable:
    def __init__(self, name, body, faces, vertices, color, stressed):
        self.name, self.body, self.faces, self.vertices, self.color = name, body, faces, vertices, color
        self.stressed = stressed


def _deformables(scene: Scene, system: System, drawings) -> list:
    """The undeformed tube of each flexible body, world coordinates."""
    W_r0, R0 = initial_pose(scene, system.bodies)
    pose = pose_from(W_r0, R0)
    zeros = np.zeros_like(W_r0)
    cfg = Configuration(0.0, pose, twist_from(zeros, zeros, pose), tuple(np.zeros(fb.n) for fb in system.bodies.flexible),
                        tuple(np.zeros(fb.n) for fb in system.bodies.flexible))
    out = []
    for d in drawings:
        spec = scene.data["bodies"][d.body]
        color = np.asarray(spec.get("color", PALETTE[d.body % len(PALETTE)]), dtype=np.uint8)
        out.append(_Deformable(d.name, d.body, _tube_faces().astype(np.int32), d.vertices(cfg), color,
                               d.stress_rows is not None))
    return out


def _ring(section) -> np.ndarray:
    """Cross-section outline in body axes (0, depth direction y, width direction z), shape (RING, 3) [m]."""
    half = 0.5 * section.depth
    width = section.area / section.depth
    angle = np.linspace(0.0, 2 * np.pi, RING, endpoint=False) + np.pi / RING
    if abs(section.area - np.pi * half**2) < 1e-9 * section.area:  # circle
        yz = np.column_stack([half * np.cos(angle), half * np.sin(angle)])
    else:
        yz = np.column_stack([np.sign(np.cos(angle)) * half, np.sign(np.sin(angle)) * 0.5 * width])
    return np.column_stack([np.zeros(RING), yz])


@cache
def _tube_faces() -> np.ndarray:
    """Triangles of the tube (shared by every frame: read-only)."""
    faces = []
    for i in range(SECTIONS - 1):
        for j in range(RING):
            a, b = i * RING + j, i * RING + (j + 1) % RING
            faces += [(a, b, b + RING), (a, b + RING, a + RING)]
    for end, flip in ((0, True), ((SECTIONS - 1) * RING, False)):
        for j in range(1, RING - 1):
            tri = (end, end + j, end + j + 1)
            faces.append(tri[::-1] if flip else tri)
    faces = np.array(faces)
    faces.flags.writeable = False
    return faces


def _planes(system: System, size: float) -> tuple[StaticVisual, ...]:
    """One mesh of square plates for the contact planes on ground (at their point, normal to their normal)."""
    import trimesh

    parts, seen = [], set()
    for c in system.contacts:
        for i in np.flatnonzero(c.body[:, 1] == system.n_bodies):
            point, normal = c.sides[1].B_s[i], c.normal[i]
            key = tuple(np.round(np.concatenate([point, normal]), 9))
            if key in seen:
                continue
            seen.add(key)
            plate = trimesh.creation.box(extents=(size, size, 0.005 * size))
            plate.apply_translation((0.0, 0.0, -0.0025 * size))
            plate.apply_transform(trimesh.geometry.align_vectors((0.0, 0.0, 1.0), normal))
            plate.apply_translation(point)
            parts.append(plate)
    if not parts:
        return ()
    mesh = trimesh.util.concatenate(parts)
    return (StaticVisual("planes", np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32), PLANE_COLOR),)


def _collision_grounds(system: System, size: float) -> tuple[StaticVisual, ...]:
    """The ground shapes of shape contacts (``[[collision.ground]]``), one mesh each, in world
    coordinates; a plane as a square plate of side ``size`` [m]."""
    import trimesh

    from viz3d.contact.collision import Collisions

    out = []
    for element in (e for e in system.forces if isinstance(e, Collisions)):
        for s in (s for s in element.shapes if s.body == system.n_bodies):
            if s.kind == "plane":
                mesh = trimesh.creation.box(extents=(size, size, 0.005 * size))
                mesh.apply_translation((0.0, 0.0, -0.0025 * size))
                mesh.apply_transform(trimesh.geometry.align_vectors((0.0, 0.0, 1.0), s.normal))
            elif len(s.faces):
                mesh = trimesh.Trimesh(s.vertices, s.faces, process=False)
            else:
                keys = {"sphere": ("radius",), "capsule": ("radius", "height"), "cylinder": ("radius", "height"),
                        "box": ("extents",)}[s.kind]
                mesh = display_mesh({"type": s.kind, **dict(zip(keys, [list(s.size)] if s.kind == "box" else s.size))},
                                    None, np.zeros(3))
            V = np.asarray(mesh.vertices) @ s.B_R.T + s.B_r
            out.append(StaticVisual(s.name, V.astype(np.float32), np.asarray(mesh.faces, np.int32), PLANE_COLOR))
    return tuple(out)


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
    for js in system.joint_sets:
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
    if spec["type"] == "flexible":  # drawn as a deformable tube (``flexible_drawings``), not as a rigid mesh
        return BodyVisual(spec["name"], np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), color,
                          f"flexible:{spec['name']}", 0.0)
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

"""``Scene`` + ``System`` -> ``SceneVisuals``: display meshes, colours and scales.

A body without a shape is drawn as its equivalent-inertia box (same mass and principal moments),
oriented along its principal axes.
"""

from __future__ import annotations

import json

import numpy as np

from viz3d.forces import SpringDamper
from viz3d.frames import BodyVisual, SceneVisuals
from viz3d.geometry import display_mesh
from viz3d.scene.build import body_mass_properties
from viz3d.scene.load import Scene
from viz3d.system import System

#: Colours of bodies that give none (Tableau 10).
PALETTE = np.array([[78, 121, 167], [242, 142, 43], [225, 87, 89], [118, 183, 178], [89, 161, 79],
                    [237, 201, 72], [176, 122, 161], [255, 157, 167], [156, 117, 95], [186, 176, 172]], dtype=np.uint8)
G_REFERENCE = 9.81


def scene_visuals(scene: Scene, system: System) -> SceneVisuals:
    """Display data of every body, joint and spring of ``scene``."""
    bodies = tuple(_body_visual(scene, system, i) for i in range(system.n_bodies))
    positions = np.array([b["position"] for b in scene.data["bodies"]], float)
    radii = np.array([b.radius for b in bodies])
    g = np.linalg.norm(scene.data["sim"]["gravity"]) or G_REFERENCE
    weight = float(system.bodies.mass.sum() * g)
    springs = tuple(n for e in system.forces if isinstance(e, SpringDamper) for n in e.names)
    return SceneVisuals(
        name=scene.name, bodies=bodies, joint_names=system.joint_names, spring_names=springs,
        length_scale=float(np.median(radii)), thickness=float(np.median([_thickness(b) for b in bodies])),
        force_scale=weight if weight > 0 else 1.0,
        bounds=np.array([(positions - radii[:, None]).min(axis=0), (positions + radii[:, None]).max(axis=0)]))


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

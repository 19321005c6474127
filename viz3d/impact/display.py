"""Drawing an impact: scene visuals (impactor, wall, a deforming bar mesh) and frames.

The bar is a tube of ``SECTIONS`` cross-sections along its axis; each frame moves every section
by the frame motion plus ``amplification`` times the elastic displacement (axial u or deflection
w). The impactor is drawn at its true position (its centre moves along the contact normal): a
sphere, or for ``shape = "flat"`` a short cylinder whose flat face is the contact face.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from viz3d._typing import FloatArray
from viz3d.frames import BodyVisual, DeformableVisual, Frame, SceneVisuals
from viz3d.impact.build import ImpactSetup
from viz3d.impact.engine import Sample
from viz3d.scene.load import Scene

#: Cross-sections along the drawn bar, and vertices around each.
SECTIONS = 80
RING = 12
IMPACT_PLOTS = (("Contact force [N]", "contact/force"), ("Indentation [m]", "contact/penetration"),
                ("Gauge strain [-]", "strain"), ("Energy ledger [J]", "energy"))


@dataclass(frozen=True)
class BarDrawing:
    """What every frame of a bar reuses, computed once per setup.

    Attributes
    ----------
    x : ndarray, shape (SECTIONS,)
        Drawn sections along the bar [m].
    shapes : ndarray, shape (SECTIONS, n)
        Elastic displacement of those sections per unit bar coordinate (``bar.displacement(x)``).
    ring : ndarray, shape (RING, 2)
        Cross-section outline in (axis-normal, bend) coordinates [m].
    gauge_strain : ndarray, shape (ng, n)
        Strain at the gauges per unit bar coordinate (``bar.strain(gauge_x)``).
    """

    x: FloatArray
    shapes: FloatArray
    ring: FloatArray
    gauge_strain: FloatArray


@dataclass(frozen=True)
class ImpactGeometry:
    """World placement of an impact scene.

    Attributes
    ----------
    origin, axis, bend : ndarray, shape (3,)
        Bar end x = 0, unit axis, unit bending direction (orthogonal to the axis).
    d : ndarray, shape (3,)
        Unit deformation direction (axis for rods, bending direction for beams).
    n : ndarray, shape (3,)
        Contact normal, from the impactor into the target.
    surface : ndarray, shape (3,)
        Undeformed contact point on the target's surface [m].
    radius : float
        Impactor radius drawn [m].
    bar : BarDrawing or None
        The bar's per-setup drawing data (None for a wall).
    """

    origin: FloatArray
    axis: FloatArray
    bend: FloatArray
    d: FloatArray
    n: FloatArray
    surface: FloatArray
    radius: float
    bar: BarDrawing | None = None

    def impactor_centre(self, gap: float, z1: float) -> FloatArray:
        return self.surface - (gap + self.radius) * self.n + z1 * self.n


def geometry(scene: Scene, setup: ImpactSetup) -> ImpactGeometry:
    d = scene.data
    radius = d["impactor"].get("radius", 0.01)
    bar = d.get("bar")
    if bar is None:  # wall: the xy plane, impactor from above
        z = np.array([0.0, 0.0, 1.0])
        return ImpactGeometry(np.zeros(3), np.array([1.0, 0.0, 0.0]), z, z, -setup.side * z, np.zeros(3), radius)
    axis = np.asarray(bar["axis"], float)
    axis /= np.linalg.norm(axis)
    bend = np.asarray(bar["bending_direction"], float)
    bend = bend - (bend @ axis) * axis
    bend /= np.linalg.norm(bend)
    rod = bar["theory"] == "rod"
    d_dir = axis if rod else bend
    origin = np.asarray(bar["position"], float)
    surface = origin + setup.x_contact * axis
    if not rod:
        surface = surface + setup.side * 0.5 * setup.bar.section.depth * bend
    return ImpactGeometry(origin, axis, bend, d_dir, -setup.side * d_dir, surface, radius, _bar_drawing(setup))


def _bar_drawing(setup: ImpactSetup) -> BarDrawing:
    bar = setup.bar
    x = np.linspace(0.0, bar.length, SECTIONS)
    gauges = bar.strain(setup.gauge_x) if len(setup.gauge_x) else np.zeros((0, bar.n))
    return BarDrawing(x, bar.displacement(x), _ring(setup), gauges)


def impactor_mesh(shape: str, radius: float, n: FloatArray):
    """The impactor about its centre: a sphere of ``radius``, or for "flat" a cylinder of that
    radius and length whose face at ``+radius`` along the contact normal ``n`` is the contact face
    (where a sphere would touch: the contact point is ``centre + radius n`` for both)."""
    import trimesh

    if shape != "flat":
        return trimesh.creation.icosphere(subdivisions=3, radius=radius)
    body = trimesh.creation.cylinder(radius=radius, height=radius, sections=32)   # axis z, centred
    body.apply_translation((0.0, 0.0, 0.5 * radius))                            # face at z = +radius
    body.apply_transform(trimesh.geometry.align_vectors((0.0, 0.0, 1.0), n))
    return body


def impact_visuals(scene: Scene, setup: ImpactSetup, geo: ImpactGeometry) -> SceneVisuals:
    import trimesh

    d = scene.data
    mesh = impactor_mesh(d["impactor"]["shape"], geo.radius, geo.n)
    bodies = [BodyVisual("impactor", mesh.vertices.astype(np.float32), mesh.faces.astype(np.int32),
                         np.asarray(d["impactor"]["color"], np.uint8), "impactor",
                         float(np.linalg.norm(mesh.vertices, axis=1).max()))]
    deformables = []
    if setup.bar is None:
        size = 20 * geo.radius
        wall = trimesh.creation.box(extents=(size, size, 0.1 * geo.radius))
        wall.apply_translation([0.0, 0.0, -0.05 * geo.radius])
        bodies.append(BodyVisual("wall", wall.vertices.astype(np.float32), wall.faces.astype(np.int32),
                                 np.asarray(d.get("wall", {}).get("color", [150, 150, 150]), np.uint8), "wall",
                                 float(np.linalg.norm(wall.vertices, axis=1).max())))
        extent = size
    else:
        verts, faces = bar_mesh(setup, geo, np.zeros(setup.bar.n + _n_frame(setup)), 1.0)
        deformables.append(DeformableVisual("bar", faces.astype(np.int32), verts.astype(np.float32),
                                            np.asarray(d["bar"]["color"], np.uint8)))
        extent = setup.bar.length
    centre0 = geo.impactor_centre(d["impactor"]["gap"], 0.0)
    pts = np.vstack([centre0, geo.origin, geo.origin + extent * geo.axis])
    lo, hi = pts.min(axis=0) - 2 * geo.radius, pts.max(axis=0) + 2 * geo.radius
    plots = tuple(p for p in IMPACT_PLOTS if setup.bar is not None or p[1] != "strain")
    frame_dt = d["display"].get("frame_dt", d["sim"]["output_dt"])
    thickness = setup.bar.section.depth if setup.bar is not None else geo.radius
    return SceneVisuals(scene.name, tuple(bodies), (), (), length_scale=float(np.max(hi - lo)) / 10,
                        thickness=float(thickness), force_scale=1.0, bounds=np.array([lo, hi]),
                        deformables=tuple(deformables), plots=plots, display_dt=float(frame_dt), kind="impact")


def _n_frame(setup: ImpactSetup) -> int:
    return setup.problem.b2.n - setup.bar.n


def _ring(setup: ImpactSetup) -> FloatArray:
    """Cross-section outline in (axis-normal, bend) coordinates, shape (RING, 2) [m]."""
    sec = setup.bar.section
    half = 0.5 * sec.depth
    width = sec.area / sec.depth
    angle = np.linspace(0.0, 2 * np.pi, RING, endpoint=False) + np.pi / RING
    if abs(sec.area - np.pi * half**2) < 1e-9 * sec.area:  # circle
        return np.column_stack([half * np.cos(angle), half * np.sin(angle)])
    square = np.column_stack([np.sign(np.cos(angle)) * 0.5 * width, np.sign(np.sin(angle)) * half])
    return square


def bar_mesh(setup: ImpactSetup, geo: ImpactGeometry, z2: FloatArray, amplification: float):
    """World vertices (SECTIONS * RING, 3) and faces of the bar at coordinates ``z2``."""
    bar, drawing = setup.bar, geo.bar
    x = drawing.x
    nf = _n_frame(setup)
    elastic = drawing.shapes @ z2[nf:]
    frame = np.zeros_like(x)
    if setup.reference == "free":
        frame = z2[0] + (x * z2[1] if bar.kind == "bending" else 0.0)
    elif setup.reference == "pinned":
        frame = x * z2[0]
    offset = frame + amplification * elastic
    side = np.cross(geo.bend, geo.axis)
    ring = drawing.ring
    centre = geo.origin + x[:, None] * geo.axis + offset[:, None] * geo.d
    verts = centre[:, None, :] + ring[None, :, 0:1] * side + ring[None, :, 1:2] * geo.bend
    return verts.reshape(-1, 3), _tube_faces()


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


def impact_frame(setup: ImpactSetup, geo: ImpactGeometry, sample: Sample, gap: float, amplification: float) -> Frame:
    """A ``Frame`` of the sample (impactor pose, deformed bar, contact and energy scalars)."""
    p = setup.problem
    centre = geo.impactor_centre(gap, float(sample.z1[0]))
    W_r = [centre]
    R = [np.eye(3)]
    W_v = [float(sample.z1d[0]) * geo.n]
    deformed = {}
    if setup.bar is not None:
        verts, _ = bar_mesh(setup, geo, sample.z2, amplification)
        deformed["bar"] = verts.astype(np.float32)
    else:
        W_r.append(np.zeros(3))
        R.append(np.eye(3))
        W_v.append(np.zeros(3))
    led = sample.ledger
    scalars = {"contact/force": sample.force, "contact/penetration": max(sample.alpha, 0.0)}
    scalars.update({f"energy/{k}": v for k, v in led.items() if k != "total_plus_dissipated"})
    scalars["energy/balance_error"] = led["total_plus_dissipated"] - p.initial_energy
    if setup.bar is not None and len(setup.gauge_x):
        strain = geo.bar.gauge_strain @ sample.z2[_n_frame(setup):]
        scalars.update({f"strain/{n}": float(e) for n, e in zip(setup.gauge_names, strain)})
    kinetic = led["impactor_kinetic"] + led["bar_kinetic"]
    zeros = np.zeros((len(W_r), 3))
    points, forces = np.zeros((0, 3)), np.zeros((0, 3))
    if sample.force > 0:  # the contact point on the impactor's surface, the force on the target
        points = (centre + geo.radius * geo.n)[None]
        forces = (sample.force * geo.n)[None]
    return Frame(sample.t, np.array(W_r), np.array(R), np.array(W_v), zeros, np.zeros((0, 3)), np.zeros((0, 3)),
                 np.zeros((0, 2, 3)), kinetic, led["total"] - kinetic, 0.0, scalars, deformed, points, forces)

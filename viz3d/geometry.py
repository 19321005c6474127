"""Body geometry: trimesh meshes for display and mass properties per unit density.

Primitives use closed-form volumes and inertias (exact; a tessellated cylinder is 0.16 % off);
mesh files use trimesh's surface integrals, which are only valid for watertight, outward-oriented
meshes, so anything else is refused. A mesh file's properties are kept on disk, keyed by its
contents (``mesh_cache_dir``): a headless run of a scene with mesh bodies then imports no trimesh.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viz3d._typing import FloatArray

#: Sections and subdivisions of the display meshes of primitives.
CYLINDER_SECTIONS = 48
SPHERE_SUBDIVISIONS = 3


class MeshError(ValueError):
    """A mesh that cannot give mass properties (missing, unreadable, open or inverted)."""


@dataclass(frozen=True)
class UnitMassProperties:
    """Mass properties at density 1 kg/m^3.

    Attributes
    ----------
    volume : float [m^3]
    center : ndarray, shape (3,)
        Centroid in the shape's own frame [m].
    inertia : ndarray, shape (3, 3)
        About the centroid, shape axes, per unit density [m^5].
    """

    volume: float
    center: FloatArray
    inertia: FloatArray


def primitive_properties(shape: dict) -> UnitMassProperties:
    """Closed-form properties of box, cylinder, sphere and capsule (axes along body z)."""
    kind = shape["type"]
    if kind == "box":
        a, b, c = shape["extents"]
        V = a * b * c
        I = V / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    elif kind == "cylinder":
        r, h = shape["radius"], shape["height"]
        V = np.pi * r * r * h
        I = np.diag([V * (3 * r * r + h * h) / 12] * 2 + [V * r * r / 2])
    elif kind == "sphere":
        r = shape["radius"]
        V = 4 / 3 * np.pi * r**3
        I = np.eye(3) * 0.4 * V * r * r
    elif kind == "capsule":
        V, I = _capsule(shape["radius"], shape["height"])
    else:
        raise ValueError(f"not a primitive: {kind}")
    return UnitMassProperties(float(V), np.zeros(3), I)


def _capsule(r: float, h: float) -> tuple[float, FloatArray]:
    """Cylinder of length h plus two hemispheres; hemisphere centroid 3r/8 from its flat face,
    its transverse inertia about the centroid 83/320 m r^2."""
    Vc = np.pi * r * r * h
    Vh = 2 / 3 * np.pi * r**3
    d = h / 2 + 3 * r / 8
    I_axial = Vc * r * r / 2 + 2 * (0.4 * Vh * r * r)
    I_trans = Vc * (h * h / 12 + r * r / 4) + 2 * Vh * (83 / 320 * r * r + d * d)
    return Vc + 2 * Vh, np.diag([I_trans, I_trans, I_axial])


def load_mesh(path: Path, scale: float):
    """Load a mesh file as one ``trimesh.Trimesh`` scaled by ``scale``; raise ``MeshError``."""
    import trimesh

    if not path.is_file():
        raise MeshError(f"mesh file not found: {path}")
    try:
        mesh = trimesh.load_mesh(path)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise MeshError(f"cannot read mesh {path}: {exc}") from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"mesh {path} has no triangles")
    mesh.apply_scale(scale)
    return mesh


def shape_mesh(shape: dict, base_dir: Path):
    """``trimesh.Trimesh`` of a mesh shape table: its ``file`` (relative to ``base_dir``) or its
    ``generator`` with ``params`` (``viz3d.anchoring.MESHES``), scaled by ``scale``; raise ``MeshError``."""
    if "generator" not in shape:
        return load_mesh(base_dir / shape["file"], shape["scale"])
    import trimesh

    from viz3d.anchoring import generated_mesh

    try:
        V, F = generated_mesh(shape["generator"], shape.get("params", {}))
    except ValueError as exc:
        raise MeshError(str(exc)) from None
    mesh = trimesh.Trimesh(V, F, process=False)
    mesh.apply_scale(shape["scale"])
    return mesh


def shape_mesh_properties(shape: dict, base_dir: Path) -> UnitMassProperties:
    """``mesh_properties`` of a mesh shape table (``shape_mesh``); a mesh file's are computed once per
    process and version of the file (its path, size and modification time): a build asks twice
    (mass properties, centroid) and a sweep builds its scene once per run; and once per contents
    and scale on this machine (``mesh_cache_dir``). Raise ``MeshError``."""
    if "generator" in shape:
        return mesh_properties(shape_mesh(shape, base_dir))
    path = base_dir / shape["file"]
    try:
        stat = path.resolve().stat()
    except OSError:  # load_mesh names the missing file
        return mesh_properties(load_mesh(path, shape["scale"]))
    p = _mesh_file_properties(str(path.resolve()), stat.st_size, stat.st_mtime_ns, float(shape["scale"]))
    return UnitMassProperties(p.volume, p.center.copy(), p.inertia.copy())


@functools.lru_cache(maxsize=64)
def _mesh_file_properties(path: str, size: int, mtime_ns: int, scale: float) -> UnitMassProperties:
    """``mesh_properties`` of the mesh file ``path`` scaled by ``scale`` (``size`` [bytes] and
    ``mtime_ns`` key the file's version in this process), from the disk cache when it holds them for
    these contents and scale (``mesh_cache_dir``), else computed and stored there."""
    try:
        key = hashlib.sha256(Path(path).read_bytes() + f"\0{scale!r}\0{MESH_CACHE_FORMAT}".encode()).hexdigest()
    except OSError:  # load_mesh names the file
        return mesh_properties(load_mesh(Path(path), scale))
    found = _cached_properties(key)
    if found is not None:
        return found
    props = mesh_properties(load_mesh(Path(path), scale))
    _store_properties(key, props)
    return props


#: Version of the disk cache's entries (part of their key).
MESH_CACHE_FORMAT = 1


def mesh_cache_dir() -> Path:
    """Where mesh files' mass properties are kept between processes: ``$VIZ3D_CACHE_DIR/mesh_properties``,
    else under the user's cache directory (``$XDG_CACHE_HOME``, else ``~/.cache``) in ``viz3d``.
    Computing them imports trimesh, and with it scipy.spatial, scipy.sparse and scipy.optimize: a run
    of the torque-free T-handle took 0.544 s beyond Python's own start without the cache, 0.282 s with
    it (median of 9 interleaved, 2026-11-29).
    One JSON file per entry, named by the SHA-256 of the mesh file's bytes, the scale and
    ``MESH_CACHE_FORMAT``; a cache that cannot be read or written is computed around."""
    root = os.environ.get("VIZ3D_CACHE_DIR")
    if not root:
        root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "viz3d"
    return Path(root) / "mesh_properties"


def _cached_properties(key: str) -> UnitMassProperties | None:
    """The stored properties of ``key``, or None (absent, unreadable or malformed)."""
    try:
        entry = json.loads((mesh_cache_dir() / f"{key}.json").read_text())
        volume, center, inertia = float(entry["volume"]), np.array(entry["center"], float), np.array(entry["inertia"], float)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if center.shape != (3,) or inertia.shape != (3, 3) or not np.isfinite([volume, *center, *inertia.ravel()]).all():
        return None
    return UnitMassProperties(volume, center, inertia)


def _store_properties(key: str, props: UnitMassProperties) -> None:
    """Store ``props`` under ``key`` (written whole, then renamed: readers see all of it or none); nothing
    where the cache cannot be written."""
    entry = {"volume": props.volume, "center": props.center.tolist(), "inertia": props.inertia.tolist()}
    directory = mesh_cache_dir()
    tmp = directory / f"{key}.{os.getpid()}.tmp"
    try:
        directory.mkdir(parents=True, exist_ok=True)
        tmp.write_text(json.dumps(entry))
        os.replace(tmp, directory / f"{key}.json")
    except OSError:
        with contextlib.suppress(OSError):  # (a part written before the failure)
            tmp.unlink(missing_ok=True)


def mesh_properties(mesh) -> UnitMassProperties:
    """Properties of a watertight, outward-oriented mesh; raise ``MeshError`` otherwise."""
    if not mesh.is_watertight:
        raise MeshError("mesh is not watertight (open edges): its volume and inertia would be wrong")
    if not mesh.is_volume or mesh.volume <= 0:
        raise MeshError("mesh is not a consistently outward-oriented volume (inverted or self-intersecting faces)")
    m = mesh.copy()
    m.density = 1.0
    return UnitMassProperties(float(m.volume), np.asarray(m.center_mass, float), np.asarray(m.moment_inertia, float))


def display_mesh(shape: dict, base_dir: Path, center: FloatArray):
    """``trimesh.Trimesh`` of a shape in body coordinates (mesh files shifted by ``-center``)."""
    import trimesh

    kind = shape["type"]
    if kind == "box":
        return trimesh.creation.box(extents=shape["extents"])
    if kind == "cylinder":
        return trimesh.creation.cylinder(radius=shape["radius"], height=shape["height"], sections=CYLINDER_SECTIONS)
    if kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=shape["radius"])
    if kind == "capsule":
        return trimesh.creation.capsule(height=shape["height"], radius=shape["radius"],
                                        count=[CYLINDER_SECTIONS, CYLINDER_SECTIONS])
    mesh = shape_mesh(shape, base_dir)
    mesh.apply_translation(-np.asarray(center))
    return mesh


def contact_spheres(shape: dict, rim_points: int = 16) -> list[tuple[FloatArray, float]]:
    """The spheres (centre in body axes [m], radius [m]; radius 0: a point) whose contacts with a
    plane are those of the primitive ``shape`` (a scene ``shape`` table): a sphere is itself, a capsule
    its two end spheres, a box its eight corners (exact against a plane: its supporting points), a
    cylinder ``rim_points`` points on each end rim (an approximation that tends to the rim).

    Raises
    ------
    ValueError
        For shapes without such spheres (meshes).
    """
    kind = shape["type"]
    if kind == "sphere":
        return [(np.zeros(3), float(shape["radius"]))]
    if kind == "capsule":
        h = 0.5 * shape["height"]
        return [(np.array([0.0, 0.0, s * h]), float(shape["radius"])) for s in (1.0, -1.0)]
    if kind == "box":
        half = 0.5 * np.asarray(shape["extents"], float)
        return [(half * np.array([sx, sy, sz]), 0.0) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
    if kind == "cylinder":
        r, h = shape["radius"], 0.5 * shape["height"]
        angles = 2 * np.pi * np.arange(rim_points) / rim_points
        return [(np.array([r * np.cos(a), r * np.sin(a), z]), 0.0) for z in (h, -h) for a in angles]
    raise ValueError(f"a sphere, capsule, box or cylinder shape, not {kind!r}")

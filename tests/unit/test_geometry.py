"""Mass properties: closed forms against trimesh's mesh integrals; meshes that cannot give
mass properties are refused with the file and key named."""

import numpy as np
import pytest
import trimesh

import viz3d
from viz3d.bodies import Bodies, InertiaError
from viz3d.geometry import mesh_properties, primitive_properties

PRIMITIVES = [
    ({"type": "box", "extents": [0.3, 0.2, 0.1]}, trimesh.creation.box(extents=(0.3, 0.2, 0.1)), 1e-12),
    ({"type": "cylinder", "radius": 0.1, "height": 0.5}, trimesh.creation.cylinder(radius=0.1, height=0.5, sections=2048), 1e-5),
    ({"type": "sphere", "radius": 0.2}, trimesh.creation.icosphere(subdivisions=7, radius=0.2), 1e-4),
    # trimesh's capsule stops being watertight above count 128; its error there is 8e-4.
    ({"type": "capsule", "radius": 0.05, "height": 0.3},
     trimesh.creation.capsule(height=0.3, radius=0.05, count=[128, 128]), 1e-3),
]


@pytest.mark.parametrize("shape,mesh,rtol", PRIMITIVES, ids=[p[0]["type"] for p in PRIMITIVES])
def test_primitive_closed_forms_match_fine_meshes(shape, mesh, rtol):
    ours, ref = primitive_properties(shape), mesh_properties(mesh)
    assert ours.volume == pytest.approx(ref.volume, rel=rtol)
    np.testing.assert_allclose(ours.inertia, ref.inertia, rtol=rtol, atol=rtol * np.abs(ref.inertia).max())


def test_capsule_tessellation_error_converges_to_the_closed_form():
    """The closed form is the limit: the mesh error falls like 1/count^2."""
    exact = primitive_properties({"type": "capsule", "radius": 0.05, "height": 0.3}).inertia.diagonal()
    err = [np.abs(mesh_properties(trimesh.creation.capsule(height=0.3, radius=0.05, count=[c, c])).inertia.diagonal()
                  / exact - 1).max() for c in (32, 64, 128)]
    assert err[0] / err[1] > 3.5 and err[1] / err[2] > 3.5, err


BODY_WITH_MESH = """
[[bodies]]
name = "part"
shape = {{ type = "mesh", file = "{file}" }}
density = 1000.0
position = [0.0, 0.0, 0.0]
"""


def _box_with(tmp_path, name, edit):
    mesh = trimesh.creation.box(extents=(0.2, 0.1, 0.05))
    mesh = edit(mesh)
    path = tmp_path / name
    mesh.export(path)
    return path


def test_mesh_body_gets_mass_properties_about_its_centroid(tmp_path, write_scene):
    def shift(m):
        m.apply_translation([1.0, 2.0, 3.0])
        return m

    f = _box_with(tmp_path, "box.obj", shift)  # OBJ keeps the digits (STL and PLY store float32)
    system, _ = viz3d.build(viz3d.load_scene(write_scene(BODY_WITH_MESH.format(file=f.name))))
    a, b, c = 0.2, 0.1, 0.05
    m = 1000 * a * b * c
    assert system.bodies.mass[0] == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose(system.bodies.inertia[0], m / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b]),
                               rtol=1e-9, atol=1e-12)  # parallel-axis cancellation from (1, 2, 3)


@pytest.mark.parametrize("name,edit,word", [
    ("open.stl", lambda m: trimesh.Trimesh(m.vertices, m.faces[2:], process=False), "watertight"),
    ("inverted.obj", lambda m: trimesh.Trimesh(m.vertices, m.faces[:, ::-1], process=False), "outward"),
])
def test_bad_meshes_are_refused_naming_file_and_key(tmp_path, write_scene, name, edit, word):
    f = _box_with(tmp_path, name, edit)
    scene = viz3d.load_scene(write_scene(BODY_WITH_MESH.format(file=f.name)))
    with pytest.raises(viz3d.SceneError) as err:
        viz3d.build(scene)
    msg = str(err.value)
    assert "scene.toml" in msg and "bodies[0].shape.file" in msg and word in msg


@pytest.mark.parametrize("fmt", ["stl", "obj", "glb", "ply"])
def test_every_mesh_format_loads_as_one_watertight_volume(tmp_path, write_scene, fmt):
    f = _box_with(tmp_path, f"box.{fmt}", lambda m: m)
    system, _ = viz3d.build(viz3d.load_scene(write_scene(BODY_WITH_MESH.format(file=f.name))))
    assert system.bodies.mass[0] == pytest.approx(1000 * 0.2 * 0.1 * 0.05, rel=1e-6)  # float32 formats: 3e-7


def test_missing_mesh_file(write_scene):
    with pytest.raises(viz3d.SceneError, match=r"bodies\[0\]\.shape\.file.*not found"):
        viz3d.build(viz3d.load_scene(write_scene(BODY_WITH_MESH.format(file="nope.stl"))))


@pytest.mark.parametrize("inertia,word", [
    (np.diag([1.0, 1.0, -1.0]), "positive definite"),
    (np.diag([1.0, 1.0, 3.0]), "I1 \\+ I2 >= I3"),
    (np.array([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), "symmetric"),
])
def test_unphysical_inertia_is_refused(inertia, word):
    with pytest.raises(InertiaError, match=word):
        Bodies(("x",), np.ones(1), inertia[None])


def test_a_mesh_file_is_read_once_per_version(tmp_path, write_scene, monkeypatch):
    """Builds reuse a mesh file's mass properties until the file changes (then they follow it)."""
    import os

    from viz3d import geometry

    f = _box_with(tmp_path, "box.obj", lambda m: m)
    reads = []
    load = geometry.load_mesh
    monkeypatch.setattr(geometry, "load_mesh", lambda path, scale: reads.append(path) or load(path, scale))
    scene = viz3d.load_scene(write_scene(BODY_WITH_MESH.format(file=f.name)))
    first, _ = viz3d.build(scene)
    viz3d.build(scene)
    assert len(reads) == 1
    bigger = trimesh.creation.box(extents=(0.4, 0.1, 0.05))
    bigger.export(f)
    os.utime(f, ns=(f.stat().st_atime_ns, f.stat().st_mtime_ns + 10**9))  # a new version even within one clock tick
    second, _ = viz3d.build(scene)
    assert len(reads) == 2
    assert second.bodies.mass[0] == pytest.approx(2 * first.bodies.mass[0], rel=1e-12)


def test_a_mesh_files_properties_are_kept_on_disk_by_its_contents(tmp_path, write_scene):
    """A build in a fresh process finds a mesh file's mass properties on disk, equal to the computed ones
    to the last bit, without importing trimesh (``viz3d.geometry.mesh_cache_dir``: 0.26 s of such a
    run's start); a damaged entry is computed again and replaced; new contents get their own entry."""
    import json
    import subprocess
    import sys

    from viz3d.geometry import mesh_cache_dir

    f = _box_with(tmp_path, "box.obj", lambda m: m)
    path = write_scene(BODY_WITH_MESH.format(file=f.name))
    probe = ("import sys, viz3d\n"
             f"system, _ = viz3d.build(viz3d.load_scene({str(path)!r}))\n"
             "print(repr(float(system.bodies.mass[0])), repr(system.bodies.inertia[0].tolist()), 'trimesh' in sys.modules)")

    def fresh() -> list[str]:
        out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=600, check=True)
        return out.stdout.strip().rsplit(" ", 1)

    computed, imported = fresh()
    assert imported == "True"
    entries = list(mesh_cache_dir().glob("*.json"))
    assert len(entries) == 1
    assert fresh() == [computed, "False"]
    entries[0].write_text('{"volume": 1.0, "center": [0.0')  # damaged
    assert fresh() == [computed, "True"]
    assert json.loads(entries[0].read_text())["volume"] == pytest.approx(0.2 * 0.1 * 0.05, rel=1e-12)
    trimesh.creation.box(extents=(0.4, 0.1, 0.05)).export(f)
    bigger, imported = fresh()
    assert imported == "True" and len(list(mesh_cache_dir().glob("*.json"))) == 2
    assert float(bigger.split()[0]) == pytest.approx(2 * float(computed.split()[0]), rel=1e-12)

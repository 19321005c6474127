"""Contacts from a body's own shape (``geometry = "body_shape"``): the spheres that meet a plane
where the shape does (``viz3d.geometry.contact_spheres``), expanded when the scene loads."""

from __future__ import annotations

import numpy as np
import pytest

import viz3d
from viz3d.geometry import contact_spheres
from viz3d.scene.schema import SceneError

G = 9.81


def _scene(tmp_path, shape: str, contact_extra: str = "", position=(0.0, 0.0, 0.5), euler="[0.0, 0.0, 0.0]") -> viz3d.Scene:
    path = tmp_path / "s.toml"
    path.write_text(f'[sim]\nt_end = 0.01\ndt = 1e-4\n[[bodies]]\nname = "b"\nshape = {shape}\nmass = 1.0\n'
                    f"position = {list(position)}\neuler_deg = {euler}\n"
                    f'[[contacts]]\nname = "floor"\nbody1 = "b"\ngeometry = "body_shape"\nlaw = "linear"\n'
                    f"stiffness = 1e5\ndamping = 600.0\n{contact_extra}")
    return viz3d.load_scene(path)


def test_box_corners_capsule_ends_and_cylinder_rims(tmp_path):
    scene = _scene(tmp_path, '{ type = "box", extents = [0.2, 0.4, 0.1] }')
    contacts = scene.data["contacts"]
    assert [c["name"] for c in contacts] == [f"floor_{k}" for k in range(8)]
    corners = np.array([c["local1"] for c in contacts])
    np.testing.assert_array_equal(np.unique(np.abs(corners), axis=0), [[0.1, 0.2, 0.05]])
    assert len(np.unique(corners, axis=0)) == 8 and all(c["radius"] == 0.0 for c in contacts)
    caps = contact_spheres({"type": "capsule", "radius": 0.03, "height": 0.2})
    assert [(c.tolist(), r) for c, r in caps] == [([0.0, 0.0, 0.1], 0.03), ([0.0, 0.0, -0.1], 0.03)]
    rim = contact_spheres({"type": "cylinder", "radius": 0.05, "height": 0.01}, rim_points=12)
    pts = np.array([c for c, _ in rim])
    assert len(rim) == 24 and np.allclose(np.hypot(pts[:, 0], pts[:, 1]), 0.05) and set(np.abs(pts[:, 2])) == {0.005}


def test_a_capsule_lying_on_the_floor_rests_on_its_two_end_spheres(tmp_path):
    """Lying along x, the capsule rests on both end spheres: z = r - m g / (2 K)."""
    r, K, m = 0.03, 1e5, 1.0
    scene = _scene(tmp_path, f'{{ type = "capsule", radius = {r}, height = 0.2 }}', position=(0.0, 0.0, r),
                   euler="[90.0, 90.0, 0.0]")
    traj = viz3d.simulate(viz3d.load_scene(scene.path, {"sim.t_end": 0.5}))
    assert traj.status == "ok"
    # critically damped per sphere (c = 2 sqrt(K m / 2) ~ 450 < 600): settled to round-off by 0.5 s
    assert traj.position[-1, 0, 2] == pytest.approx(r - m * G / (2 * K), abs=1e-9)
    assert list(traj.extras["contact_names"]) == ["floor_0", "floor_1"]


@pytest.mark.parametrize("shape, extra, key", [
    ('{ type = "mesh", file = "nope.stl" }', "", "geometry"),
    ('{ type = "box", extents = [0.1, 0.1, 0.1] }', "radius = 0.01\n", "radius"),
    ('{ type = "box", extents = [0.1, 0.1, 0.1] }', "local1 = [0.0, 0.0, 0.0]\n", "local1"),
])
def test_body_shape_refuses_what_it_cannot_use(tmp_path, shape, extra, key):
    with pytest.raises(SceneError, match=rf"contacts\[0\]\.{key}"):
        _scene(tmp_path, shape, extra)

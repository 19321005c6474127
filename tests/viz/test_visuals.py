"""Static display data: posts under springs anchored to ground, the flat impactor's face, the
reach of what hangs from ground joints (issue 8)."""

import numpy as np
import pytest

import viz3d
from viz3d.scene.build import build, initial_pose
from viz3d.scene.visuals import scene_visuals

from conftest import SCENES


def _visuals(name, overrides=None):
    scene = viz3d.load_scene(SCENES / f"{name}.toml", overrides)
    return scene_visuals(scene, build(scene)[0])


def _impactor(name):
    """The impactor's vertices in world axes about its centre (k, 3), its centre, and the contact entry."""
    scene = viz3d.load_scene(SCENES / f"{name}.toml")
    system = build(scene)[0]
    vis = scene_visuals(scene, system)
    i = [b["name"] for b in scene.data["bodies"]].index("impactor")
    positions, rotations = initial_pose(scene, system.bodies)
    return vis.bodies[i].vertices.astype(float) @ rotations[i].T, positions[i], scene.data["contacts"][0]


def test_tendons_anchored_to_ground_end_on_a_post_standing_on_the_floor():
    vis = _visuals("robot_arm")
    posts = {s.name: s for s in vis.statics}["posts"]
    v = posts.vertices.astype(float)
    top = np.array([0.0, 0.0, 1.8])                                   # both mast tendons end here
    assert np.min(np.linalg.norm(v - top, axis=1)) < 0.05, "no post reaches the tendons' ground end"
    assert v[:, 2].min() == pytest.approx(0.0, abs=1e-6)              # stands on the floor (z = 0)
    assert np.all(np.linalg.norm(v[:, :2], axis=1) < 0.05)            # one thin vertical post at x = y = 0
    assert posts.faces.max() < len(v) and posts.faces.shape[1] == 3
    assert np.all(vis.bounds[1] >= top - 1e-9)                         # the post is part of the scene's box


def test_scenes_without_ground_springs_have_no_posts():
    assert not _visuals("double_pendulum").statics


def test_reach_of_a_chain_hanging_from_ground_is_its_length():
    vis = _visuals("chain", ["chain.n=20"])
    (x, y, z, r), = vis.reach
    assert (x, y, z) == pytest.approx((0.0, 0.0, 1.2))
    assert 20 * 0.1 <= r <= 20 * 0.1 + 0.05


def test_flat_impactor_is_drawn_with_a_flat_contact_face():
    v, centre, contact = _impactor("impact_clamped_bar")
    n = np.asarray(contact["normal"])
    radius = 0.02                                                      # impactor.radius of the scene
    along = v @ n
    assert centre + along.min() * n == pytest.approx(contact["point1"], abs=1e-9)  # the face is where the contact is
    face = v[along < along.min() + 1e-6 * radius]
    assert len(face) >= 8, "the contact side is not flat"
    lateral = np.linalg.norm(face - np.outer(face @ n, n), axis=1)
    assert lateral.max() == pytest.approx(radius, rel=1e-3)           # a full disc, not a point


def test_spherical_impactor_stays_a_sphere():
    v, _, contact = _impactor("impact_bronze_ball")
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), contact["radius"], rtol=1e-5)

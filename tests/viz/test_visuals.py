"""Static display data: posts under springs anchored to ground, the flat impactor's face, the
reach of what hangs from ground joints (issue 8)."""

import numpy as np
import pytest

import viz3d
from viz3d.impact.build import build_impact
from viz3d.impact.display import geometry, impact_visuals
from viz3d.scene.build import build
from viz3d.scene.visuals import scene_visuals

from conftest import SCENES


def _visuals(name, overrides=None):
    scene = viz3d.load_scene(SCENES / f"{name}.toml", overrides)
    return scene_visuals(scene, build(scene)[0])


def _impact(name):
    scene = viz3d.load_scene(SCENES / f"{name}.toml")
    setup = build_impact(scene)
    geo = geometry(scene, setup)
    return impact_visuals(scene, setup, geo), geo


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
    vis, geo = _impact("impact_clamped_bar")
    imp = vis.bodies[0]
    assert imp.name == "impactor"
    v = imp.vertices.astype(float)
    along = v @ geo.n
    assert along.max() == pytest.approx(geo.radius, rel=1e-6)         # the face is where the contact is
    face = v[along > along.max() - 1e-6 * geo.radius]
    assert len(face) >= 8, "the contact side is not flat"
    lateral = np.linalg.norm(face - np.outer(face @ geo.n, geo.n), axis=1)
    assert lateral.max() == pytest.approx(geo.radius, rel=1e-3)       # a full disc, not a point


def test_spherical_impactor_stays_a_sphere():
    vis, geo = _impact("impact_bronze_ball")
    r = np.linalg.norm(vis.bodies[0].vertices.astype(float), axis=1)
    np.testing.assert_allclose(r, geo.radius, rtol=1e-5)

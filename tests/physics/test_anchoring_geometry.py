"""The parametric anchoring meshes (viz3d/anchoring.py) and the stowed pose the [ship] generator
writes (viz3d/scene/ship.py), checked against closed forms written here: prismatoid volumes, the
ellipse where a cylinder cuts a plane, the polygon area of the floor, and the stowed anchor lying on
the pocket floor with its shank on the pipe's axis."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from viz3d import anchoring as A
from viz3d.scene.load import load_scene
from viz3d.scene.ship import bend_over, chain_links, shell_axes

EPS = np.finfo(float).eps


def _prismatoid(h, a0, b0, a1, b1):
    """Volume of a solid between two parallel rectangles a0 x b0 and a1 x b1 a height h apart."""
    am, bm = (a0 + a1) / 2, (b0 + b1) / 2
    return h / 6 * (a0 * b0 + a1 * b1 + 4 * am * bm)


@pytest.mark.parametrize("mass", [9300.0, 1200.0])
def test_anchor_meshes_are_closed_convex_solids_of_the_prismatoid_volumes(mass):
    s = (mass / 9300.0) ** (1 / 3)
    cases = {
        "anchor_shank": _prismatoid(s * (A.SHANK_EYE - A.SHANK_TAIL), *(s * np.array([*A.SHANK_CROWN, *A.SHANK_HEAD]))),
        "anchor_flukes": _prismatoid(s * (A.FLUKE_TIP - A.FLUKE_BACK), s * A.FLUKE_THICKNESS[0], s * A.FLUKE_WIDTH[0],
                                     s * A.FLUKE_THICKNESS[1], s * A.FLUKE_WIDTH[1]),
        "anchor_shackle": s**3 * A.SHACKLE[0] * A.SHACKLE[1] * A.SHACKLE[2],
    }
    for name, volume in cases.items():
        m = trimesh.Trimesh(*A.MESHES[name](mass=mass), process=False)
        assert m.is_watertight and m.is_volume, name
        assert m.volume == pytest.approx(volume, rel=1e3 * EPS), name


@pytest.mark.parametrize("gamma", [15.0, 25.0, 30.0])
def test_the_pipe_wall_meets_the_floor_on_the_ellipse_of_its_oblique_cut(gamma):
    r, L = 0.35, 4.0
    V, F = A.hawse_pipe(pipe_radius=r, pipe_angle_deg=gamma, pipe_length=L, sections=40)
    a = A.pipe_axis(gamma)
    radial = V - (V @ a)[:, None] * a
    np.testing.assert_allclose(np.linalg.norm(radial, axis=1), r, rtol=0, atol=1e2 * EPS)
    ring = V[np.abs(V[:, 2]) <= 1e2 * EPS]           # the wall's points on the floor plane n = 0
    assert len(ring) >= 40
    b = r / math.sin(math.radians(gamma))
    np.testing.assert_allclose((ring[:, 0] / r) ** 2 + (ring[:, 1] / b) ** 2, 1.0, atol=1e3 * EPS)
    assert np.max(V @ a) == pytest.approx(L, abs=1e2 * EPS)
    # the floor's opening is the same points: the pipe and the floor share their edge
    Vp, _ = A.pocket(pipe_radius=r, pipe_angle_deg=gamma, sections=40)
    floor_ring = Vp[: len(ring)]
    d = np.linalg.norm(floor_ring[:, None, :] - ring[None], axis=2).min(axis=1)
    assert np.max(d) <= 1e2 * EPS


def test_floor_area_is_the_pocket_rectangle_less_the_opening_polygon():
    W, top, bottom = 2.8, 1.6, 1.4
    V, F = A.pocket(pipe_radius=0.35, pipe_angle_deg=25.0, pocket_width=W, pocket_top=top, pocket_bottom=bottom,
                    depth=0.35, sections=48)
    tri = V[F]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    floor = np.abs(tri[:, :, 2]).max(axis=1) == 0.0
    assert np.all(n[floor, 2] > 0)                     # facing the water side
    inner = V[: floor.sum() // 2]
    x, y = inner[:, 0], inner[:, 1]
    hole = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))   # shoelace
    assert 0.5 * np.linalg.norm(n[floor], axis=1).sum() == pytest.approx(W * (top + bottom) - hole, rel=1e3 * EPS)
    walls = 0.5 * np.linalg.norm(n[~floor], axis=1).sum()
    assert walls == pytest.approx(2 * (W + top + bottom) * 0.35, rel=1e3 * EPS)


def test_link_choice_meets_its_sagitta_tolerance_with_the_fewest_links():
    for d, r, tol in [(0.084, 0.35, 0.05), (0.084, 1.5, 0.05), (0.05, 0.6, 0.1), (0.084, 0.2, 0.001)]:
        k, pitch, mass = chain_links(d, r, tol)
        assert pitch == pytest.approx(4 * d)
        assert k == 1 or (k * pitch) ** 2 / (8 * r) <= tol
        assert ((k + 1) * pitch) ** 2 / (8 * r) > tol


def test_the_chain_starts_tangent_to_the_rim_a_whole_number_of_links_from_the_windlass():
    C = np.array([0.0, -1.2, -1.4])
    a = np.array([0.0, 0.3, 1.0]) / np.linalg.norm([0.0, 0.3, 1.0])
    down, r, ell = np.array([0.0, 0.0, -1.0]), 0.15, 0.336
    Tp, V, m = bend_over(C, 4.0 * a, a, down, r, ell)
    assert np.linalg.norm(V - Tp) == pytest.approx(m * ell, rel=1e-12)
    assert 0.0 <= (Tp - 4.0 * a) @ a < ell
    np.testing.assert_allclose(np.cross(Tp - 4.0 * a, a), 0.0, atol=1e-12)
    for d in ((V - Tp) / np.linalg.norm(V - Tp), down):   # both stretches at distance r from the rim
        w = C - V
        assert np.linalg.norm(w - (w @ d) * d) == pytest.approx(r, rel=1e-9)


@pytest.mark.parametrize("sets", [[], ["ship.heel=7", "ship.trim=-3", "ship.pipe_angle=20", "ship.flare=10"]])
def test_the_stowed_anchor_lies_on_the_pocket_floor_with_its_shank_on_the_pipe_axis(sets, tmp_path):
    path = tmp_path / "hoist.toml"
    path.write_text("[ship]\n")
    data = load_scene(path, sets).data
    ship, st = data["ship"], data["stowage"]
    Rw = _world(ship)
    S = Rw @ shell_axes(ship["flare"])
    g = math.radians(ship["pipe_angle"])
    a = S @ np.array([0.0, math.cos(g), -math.sin(g)])
    bodies = {b["name"]: b for b in data["bodies"]}
    for name, P, R in zip(st["bodies"], np.array(st["position"]), np.array(st["axes"])):
        V, _ = A.MESHES[bodies[name]["shape"]["generator"]](mass=ship["anchor_mass"])
        m = trimesh.Trimesh(V, _, process=False)
        W = (V - m.center_mass) @ R.T + P                  # the mesh at its stowed pose, world
        n_coord = W @ S[:, 2]                             # height above the pocket floor
        if name == "flukes":
            assert n_coord.min() == pytest.approx(0.0, abs=1e-12)      # resting on the floor, not in it
            assert np.linalg.norm(np.cross(R[:, 2], S[:, 1])) < 1e-12 and R[:, 2] @ S[:, 1] > 0   # flat, along u
        else:
            np.testing.assert_allclose(R[:, 2], a, atol=1e-12)         # the shank along the pipe's axis
            axis_point = W.mean(axis=0)
            assert np.linalg.norm(np.cross(axis_point - (axis_point @ a) * a, a)) < ship["pipe_diameter"] / 2


def _world(ship):
    """World from ship axes, from scipy: intrinsic y (trim) then x (heel)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("YX", [ship["trim"], ship["heel"]], degrees=True).as_matrix()


def test_a_slanted_rim_edge_is_cleared_by_the_link_radius_along_both_stretches():
    """With heel or trim the rim's edge is not normal to the chain's plane: the distance between the
    edge's line and each stretch's line (not the vertex's) is at least the radius, and the radius for
    the nearer one (the chain touches the edge, without overlapping it)."""
    C, e = np.array([0.0, -1.2, -1.4]), np.array([0.995, 0.0, 0.0998])
    e /= np.linalg.norm(e)
    a = np.array([0.0, 0.3, 1.0]) / np.linalg.norm([0.0, 0.3, 1.0])
    down, r = np.array([0.0, 0.0, -1.0]), 0.15
    Tp, V, m = bend_over(C, 4.0 * a, a, down, r, 0.336, e)
    dist = []
    for d in ((V - Tp) / np.linalg.norm(V - Tp), down):
        n = np.cross(d, e)
        dist.append(abs((V - C) @ n) / np.linalg.norm(n))
    assert min(dist) == pytest.approx(r, rel=1e-9) and max(dist) >= r
    assert np.linalg.norm(V - Tp) == pytest.approx(m * 0.336, rel=1e-12)


@pytest.mark.parametrize("heel, trim", [(0.0, 0.0), (-5.0, 3.0), (5.0, -3.0), (5.0, 3.0)])
def test_the_generated_ship_starts_without_contact(heel, trim, tmp_path):
    """Nothing overlaps in the initial configuration at any heel and trim: the run starts at rest, not
    with a contact the law cannot resolve (the chain only touches the rim once it sags)."""
    from viz3d.contact.collision import Collisions
    from viz3d.dynamics import body_state
    from viz3d.scene.build import build

    path = tmp_path / "hoist.toml"
    path.write_text("[ship]\n")
    system, state = build(load_scene(path, [f"ship.heel={heel}", f"ship.trim={trim}"]))
    col = next(e for e in system.forces if isinstance(e, Collisions))
    assert col.detect(body_state(system, state.q, state.v, state.chart, 0.0)).m == 0

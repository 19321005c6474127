"""Contacts the collision glue reports (``viz3d.contact.collision``) against closed-form geometry.

References written here, independent of Coal: sphere-sphere and sphere-plane depths, the distance
between two segments (capsules) by minimising over both segment parameters with scipy, the
distance from a point to a box (clamping), a box's lowest corners against a plane; poses drawn from
``scipy.spatial.transform.Rotation``. Tolerance 1e-12 m on unit sizes (round-off) for all: Coal's
sphere, box and capsule pairs are closed forms, and a sphere against a polytope is GJK between the
polytope and a point (finite termination on the exact closest feature) with the radius added. The
scipy segment distance (L-BFGS-B, gtol 1e-12) is checked to the same bound only because the
closest points are interior, where the minimum is a smooth quadratic's.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from viz3d.contact.collision import SMALL_GROUPS, Collisions, PairLaw, Shape, convex_hull, support_points
from viz3d.contact.laws import Linear
from viz3d.kinematics import Configuration, pose_from, twist_from

EXACT = 1e-12
#: Coal 3.0.3's box-box witness points lie 1e-11 m deeper than the exact overlap, whatever its GJK
#: and EPA tolerances (tests/physics/test_collisions.py measured it).
POLYTOPE_OFFSET = 1.01e-11


def _shape(name, body, kind, size=(), group=0, vertices=None, **kw):
    v = np.zeros((0, 3)) if vertices is None else vertices
    faces = np.zeros((0, 3), int)
    if kind == "convex":
        v, faces = convex_hull(vertices)
    return Shape(name, body, kind, tuple(size), vertices=v, faces=faces, support=support_points(kind, size, v),
                 group=group, **kw)


def _world(shapes, n_bodies, groups=("bodies", "ground"), pairs=((0, 0), (0, 1)), excluded=frozenset()):
    G = len(groups)
    pair_law = -np.ones((G, G), int)
    for a, b in pairs:
        pair_law[a, b] = pair_law[b, a] = 0
    return Collisions(tuple(shapes), tuple(groups), pair_law, (PairLaw(Linear(1.0)),), n_bodies, excluded)


def _cfg(W_r, R):
    pose = pose_from(np.asarray(W_r, float).reshape(-1, 3), np.asarray(R, float).reshape(-1, 3, 3))
    n = len(W_r)
    return Configuration(0.0, pose, twist_from(np.zeros((n, 3)), np.zeros((n, 3)), pose))


@pytest.mark.parametrize("seed", range(5))
def test_two_spheres_overlap_by_the_sum_of_radii_minus_the_distance_along_the_centre_line(seed):
    rng = np.random.default_rng(seed)
    r1, r2 = rng.uniform(0.1, 1.0, 2)
    c1 = rng.normal(size=3)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    d = (r1 + r2) * rng.uniform(0.5, 0.99)
    c2 = c1 + d * u
    R = Rotation.random(2, random_state=seed).as_matrix()
    world = _world([_shape("a", 0, "sphere", (r1,)), _shape("b", 1, "sphere", (r2,))], 2)
    tc = world.detect(_cfg([c1, c2], R))
    assert tc.m == 1
    assert tc.depth[0] == pytest.approx(r1 + r2 - d, abs=EXACT)
    np.testing.assert_allclose(tc.n[0], -u, atol=EXACT)  # from B (the second sphere) towards A
    assert tuple(tc.body[0]) == (0, 1)


def test_spheres_apart_do_not_touch_and_ungrouped_pairs_are_never_tested():
    shapes = [_shape("a", 0, "sphere", (0.5,)), _shape("b", 1, "sphere", (0.5,), group=1)]
    apart = _world(shapes, 2, groups=("g0", "g1", "ground"), pairs=((0, 1),))
    assert apart.detect(_cfg([[0, 0, 0], [1.01, 0, 0]], np.tile(np.eye(3), (2, 1, 1)))).m == 0
    assert apart.detect(_cfg([[0, 0, 0], [0.9, 0, 0]], np.tile(np.eye(3), (2, 1, 1)))).m == 1
    separate = _world(shapes, 2, groups=("g0", "g1", "ground"), pairs=((0, 0), (1, 1)))
    assert separate.detect(_cfg([[0, 0, 0], [0.9, 0, 0]], np.tile(np.eye(3), (2, 1, 1)))).m == 0
    joined = _world([_shape("a", 0, "sphere", (0.5,)), _shape("b", 1, "sphere", (0.5,))], 2, excluded={(0, 1)})
    assert joined.detect(_cfg([[0, 0, 0], [0.9, 0, 0]], np.tile(np.eye(3), (2, 1, 1)))).m == 0


def _segment_distance(p0, p1, q0, q1):
    """Distance between segments p0-p1 and q0-q1, minimised over both parameters (scipy, bounded)."""
    f = lambda s: np.linalg.norm(p0 + s[0] * (p1 - p0) - q0 - s[1] * (q1 - q0))  # noqa: E731
    best = min((minimize(f, x0, bounds=[(0, 1), (0, 1)], method="L-BFGS-B", options={"ftol": 1e-15, "gtol": 1e-12})
                for x0 in ([0.5, 0.5], [0.0, 1.0], [1.0, 0.0])), key=lambda r: r.fun)
    return best.fun


@pytest.mark.parametrize("seed", range(5))
def test_crossing_capsules_overlap_by_twice_the_radius_minus_the_axes_distance(seed):
    """Penetrations small against the radius, as a penalty contact keeps them (with the axes nearly
    intersecting, the minimum-translation direction is ill-defined)."""
    rng = np.random.default_rng(100 + seed)
    r, h = 0.1, 1.0
    R = Rotation.random(2, random_state=100 + seed).as_matrix()
    a1, a2 = R[0][:, 2], R[1][:, 2]
    n = np.cross(a1, a2) / np.linalg.norm(np.cross(a1, a2))
    s1, s2 = rng.uniform(-0.35, 0.35, 2) * h
    c1 = rng.normal(size=3)
    c2 = c1 + s1 * a1 + rng.uniform(1.5, 1.99) * r * n - s2 * a2
    d = _segment_distance(c1 - a1 * h / 2, c1 + a1 * h / 2, c2 - a2 * h / 2, c2 + a2 * h / 2)
    world = _world([_shape("a", 0, "capsule", (r, h)), _shape("b", 1, "capsule", (r, h))], 2)
    tc = world.detect(_cfg([c1, c2], R))
    assert tc.m == 1
    assert tc.depth[0] == pytest.approx(2 * r - d, abs=EXACT)


def test_a_box_resting_on_a_ground_box_touches_at_the_corners_of_their_overlap():
    """Coal's contact patch of a box on a box: the four bottom corners of a small box on a large one,
    each at the overlap depth, normals straight up."""
    depth = 0.01
    shapes = [_shape("top", 0, "box", (1.0, 1.0, 1.0)),
              _shape("floor", 1, "box", (4.0, 4.0, 1.0), group=1, B_r=np.array([0.0, 0.0, -0.5]))]
    world = _world(shapes, 1)
    tc = world.detect(_cfg([[0.3, -0.2, 0.5 - depth]], [np.eye(3)]))
    assert tc.m == 4
    np.testing.assert_allclose(tc.depth, depth, atol=EXACT + POLYTOPE_OFFSET)
    np.testing.assert_allclose(tc.n, np.tile([0.0, 0.0, 1.0], (4, 1)), atol=EXACT)
    assert set(map(tuple, tc.body)) == {(0, 1)}


@pytest.mark.parametrize("seed", range(4))
def test_a_tilted_box_meets_a_plane_at_its_corners_below_it(seed):
    R = Rotation.random(random_state=200 + seed).as_matrix()
    extents = np.array([0.4, 0.3, 0.2])
    corners = np.array([[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]) * extents / 2
    lowest = np.min(corners @ R.T, axis=0)[2]
    z = -lowest - 0.02  # the lowest corner 2 cm into the plane z = 0
    shapes = [_shape("box", 0, "box", tuple(extents)),
              _shape("floor", 1, "plane", group=1, normal=np.array([0.0, 0.0, 1.0]))]
    tc = _world(shapes, 1).detect(_cfg([[0.1, 0.2, z]], [R]))
    below = -(corners @ R.T)[:, 2] - z
    expected = np.sort(below[below > 0])[::-1][:4]
    np.testing.assert_allclose(np.sort(tc.depth)[::-1], expected, atol=EXACT)


@pytest.mark.parametrize("seed", range(4))
def test_a_convex_hull_of_a_cube_mesh_meets_a_sphere_at_the_box_distance(seed):
    """Convex polyhedron against a sphere: depth r - |c - clamp(c)| for a centre outside."""
    rng = np.random.default_rng(300 + seed)
    cube = np.array([[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)], float) * 0.5
    R = Rotation.random(random_state=300 + seed).as_matrix()
    r = 0.3
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    local = np.clip(direction * 0.8, -0.5, 0.5) + 0.2 * direction  # a point outside the cube, near a face
    dist = np.linalg.norm(local - np.clip(local, -0.5, 0.5))
    shapes = [_shape("cube", 0, "convex", vertices=cube), _shape("ball", 1, "sphere", (r,))]
    tc = _world(shapes, 2).detect(_cfg([[0, 0, 0], R @ local], [R, np.eye(3)]))
    assert tc.m == 1
    assert tc.depth[0] == pytest.approx(r - dist, abs=EXACT)


def test_a_sphere_on_a_faceted_triangle_mesh_floor_gets_one_contact_at_its_depth():
    """A triangle soup: facets near the lowest point each report a contact; the reduction keeps the
    deepest (the facet under the sphere, normal up) and drops the tilted ones beside it."""
    import trimesh

    slab = trimesh.creation.box(extents=[4, 4, 1]).subdivide().subdivide()
    v = np.asarray(slab.vertices) - [0.0, 0.0, 0.5]
    floor = Shape("floor", 1, "mesh", vertices=v, faces=np.asarray(slab.faces), support=support_points("mesh", (), v),
                  group=1)
    world = _world([_shape("ball", 0, "sphere", (0.5,)), floor], 1)
    for x, y in ((0.1, 0.2), (0.25, 0.0), (0.0, 0.0)):  # inside a facet, on an edge, on a vertex
        tc = world.detect(_cfg([[x, y, 0.49]], [np.eye(3)]))
        assert tc.m == 1, (x, y, tc.depth)
        assert tc.depth[0] == pytest.approx(0.01, abs=EXACT)
        np.testing.assert_allclose(tc.n[0], [0.0, 0.0, 1.0], atol=EXACT)


def test_the_convex_hull_keeps_outward_triangles_and_only_hull_vertices():
    rng = np.random.default_rng(7)
    points = rng.normal(size=(60, 3))
    v, f = convex_hull(points)
    centre = v.mean(axis=0)
    tri = v[f]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("ki,ki->k", normals, tri[:, 0] - centre) > 0)
    # every input point lies inside every face plane
    assert np.all(np.einsum("ki,pi->pk", normals, points) - np.einsum("ki,ki->k", normals, tri[:, 0]) <= 1e-12)


@pytest.mark.parametrize("seed, n", [(0, 30), (1, 120), (2, 400), (3, 400)])
def test_the_broad_phase_proposes_exactly_the_overlapping_bounds_of_colliding_groups(seed, n):
    """Against the brute-force list of all pairs, with all pairs of small groups and a k-d tree per
    large group (over ``SMALL_GROUPS`` pairs): the same set, groups that do not collide and joined
    bodies left out; a ground box proposes the moving shapes its box overlaps."""
    rng = np.random.default_rng(400 + seed)
    radii = rng.uniform(0.02, 0.15, n)
    group = rng.integers(0, 3, n)  # groups a, b, c: a-a, a-b and c-ground collide, b-b and b-c do not
    shapes = [_shape(f"s{i}", i, "sphere", (radii[i],), group=int(group[i])) for i in range(n)]
    shapes.append(_shape("table", n, "box", (1.0, 1.0, 0.2), group=3, B_r=np.array([0.5, 0.5, 0.0])))
    excluded = frozenset({(0, 1), (2, 3)})
    world = _world(shapes, n, groups=("a", "b", "c", "ground"), pairs=((0, 0), (0, 1), (2, 3)), excluded=excluded)
    centres = rng.uniform(0.0, 1.0, (n, 3)) * (n / 120) ** (1 / 3)
    got = {tuple(sorted(p)) for p in world.candidates(np.vstack([centres, [[0.5, 0.5, 0.0]]]))}
    assert (n * n / 9 > SMALL_GROUPS) == (n == 400)  # both paths covered
    colliding = {(0, 0), (0, 1), (1, 0)}
    I, J = np.triu_indices(n, 1)
    overlap = np.linalg.norm(centres[I] - centres[J], axis=1) <= radii[I] + radii[J]
    expected = {(int(i), int(j)) for i, j in zip(I[overlap], J[overlap])
                if (group[i], group[j]) in colliding and (i, j) not in excluded}
    lo, hi = np.array([0.0, 0.0, -0.1]), np.array([1.0, 1.0, 0.1])
    expected |= {(i, n) for i in range(n) if group[i] == 2 and np.all(centres[i] + radii[i] >= lo - 1e-12)
                 and np.all(centres[i] - radii[i] <= hi + 1e-12)}
    assert got == expected
    assert len(expected) < n * (n - 1) / 2 / 20  # what a broad phase is for


def test_segment_distance_matches_the_minimised_distance_including_degenerate_segments():
    from viz3d.contact.narrowphase import segment_distance

    rng = np.random.default_rng(9)
    p0, p1, q0, q1 = (rng.normal(size=(40, 3)) for _ in range(4))
    p1[:5] = p0[:5]  # points against segments
    q1[5:8] = q0[5:8]
    u = np.cross(p1[8:12] - p0[8:12], rng.normal(size=(4, 3)))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    q0[8:12], q1[8:12] = p0[8:12] + u, p1[8:12] + u  # parallel, 1 apart
    got = segment_distance(p0, p1, q0, q1)
    for k in range(40):
        assert got[k] == pytest.approx(_segment_distance(p0[k], p1[k], q0[k], q1[k]), abs=1e-7)
    np.testing.assert_allclose(got[8:12], 1.0, atol=1e-14)

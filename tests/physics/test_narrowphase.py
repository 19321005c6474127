"""Our narrow phase (``viz3d.contact.narrowphase``: shapes on triangle meshes, spheres on spheres and
capsules) against Coal, which nobody here wrote, against closed forms, and its box tree against
visiting every facet.

Tolerances. Coal's GJK and EPA stop at their default tolerance ``TAU = 1e-6`` (Coal 3.0,
``GJK_DEFAULT_TOLERANCE``, ``EPA_DEFAULT_TOLERANCE``; ``GJKSolver::shapeDistance`` documents the
distance as precise up to it), applied as ``TAU (1 + |x|)`` with ``|x|`` in metres: GJK stops when
its distance ``rl`` is within ``TAU (1 + rl)`` of the best lower bound ``alpha`` (``checkConvergence``,
the default criterion), EPA when the support gap is within ``TAU (1 + |w|)``. Hence

* depths agree within ``TAU (1 + L)`` (L: the shape's size, >= every distance and depth here), plus
  ``64 eps L`` for our own round-off;
* where GJK ends (a sphere or capsule whose core stays off the facet, at core distance ``s``): its
  iterate ``x`` and the exact closest vector ``x*`` of the Minkowski difference obey
  ``|x - x*|^2 <= |x|^2 - |x*|^2 <= (rl - alpha)(rl + alpha) <= 2 TAU (1 + s) s``, so the normal
  ``x / |x|`` is within ``sqrt(2 TAU (1 + s) / s)`` and the witness points within
  ``sqrt(2 TAU (1 + s) s)`` (plus the depth tolerance);
* where EPA ends (hulls, cores through the facet) its gap does not bound the normal's angle (a
  nearly flat stretch of the difference's boundary); we allow the same forms with the depth ``d``
  in place of ``s``.

Witness points. Coal's are pinned down by its tolerance only where the contact features are steep:
a capsule whose axis makes an angle ``theta`` with the contact plane may slide its witness by up to
``depth tolerance / sin theta`` along the axis within GJK's stop; a hull's vertex, edge or face
on a facet likewise by the angles of its edges (and a face lying on the facet has no unique witness
at all). So points are compared with Coal's for spheres (unique), for capsules with that slide
added, and for every contact of ours they are checked to lie on both contact features: the witness
on the shape (``point + depth/2 n``) on its surface, the witness on the mesh (``point - depth/2 n``)
on the facet, within the depth tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import viz3d
from viz3d.contact.collision import GEOMETRIES, Collisions, Shape, convex_hull, support_points
from viz3d.contact.narrowphase import MESH_CONTACTS, pack_shapes, pair_contacts

from conftest import ROOT

coal = pytest.importorskip("coal")

TAU = 1e-6
EPS = np.finfo(float).eps


def depth_tol(L: float) -> float:
    """Depth tolerance [m] for shapes of size ``L`` [m] (module docstring)."""
    return TAU * (1.0 + L) + 64 * EPS * L


def normal_tol(s: float) -> float:
    """Normal tolerance at core distance (or depth) ``s`` [m] (module docstring)."""
    return np.sqrt(2.0 * TAU * (1.0 + s) / s) + 64 * EPS


def point_tol(L: float, s: float) -> float:
    """Witness point tolerance [m] (module docstring)."""
    return np.sqrt(2.0 * TAU * (1.0 + s) * s) + depth_tol(L)


def _separation(shape: Shape, depth: float) -> float:
    """The core distance (GJK ends) or the depth (EPA ends) of a contact of ``shape`` [m]."""
    r = shape.size[0] if shape.kind in ("sphere", "capsule") else 0.0
    return r - depth if depth < r else depth


# --- shapes and the two narrow phases -------------------------------------------------------------------


def sphere(radius: float) -> Shape:
    return Shape("sphere", 0, "sphere", (radius,), support=support_points("sphere", (radius,), None))


def capsule(radius: float, length: float) -> Shape:
    return Shape("capsule", 0, "capsule", (radius, length), support=support_points("capsule", (radius, length), None))


def hull(points: np.ndarray) -> Shape:
    v, f = convex_hull(np.asarray(points, float))
    return Shape("hull", 0, "convex", vertices=v, faces=f, support=support_points("convex", (), v))


def mesh(vertices: np.ndarray, faces: np.ndarray) -> Shape:
    return Shape("mesh", 1, "mesh", vertices=np.asarray(vertices, float), faces=np.asarray(faces, int),
                 support=support_points("mesh", (), vertices))


def soup(rng, n: int, size: float = 0.4, spread: float = 1.0) -> Shape:
    """``n`` random triangles of edge ~``size`` in a cube of side ``2 spread``."""
    centre = rng.uniform(-spread, spread, (n, 1, 3))
    v = (centre + rng.normal(0.0, size / 2, (n, 3, 3))).reshape(-1, 3)
    return mesh(v, np.arange(3 * n).reshape(n, 3))


def ours(table, i, j, r, R):
    """Our contacts of shapes i, j: {facet: (point, n, depth)}."""
    P, N, D, F = np.zeros((MESH_CONTACTS, 3)), np.zeros((MESH_CONTACTS, 3)), np.zeros(MESH_CONTACTS), \
        np.zeros(MESH_CONTACTS, np.int64)
    k = pair_contacts(table, i, j, r[i], R[i], r[j], R[j], P, N, D, F)
    return {int(F[m]): (P[m], N[m], D[m]) for m in range(k)}


def coals(shapes, i, j, r, R):
    """Coal's contacts of shapes i, j (as ``Collisions`` asks for them): {facet: (point, n, depth)},
    depth from the witness points, positive ones; None when Coal filled its 32 places."""
    req = coal.CollisionRequest()
    req.enable_contact, req.num_max_contacts = True, MESH_CONTACTS
    res = coal.CollisionResult()
    gi, gj = (GEOMETRIES[shapes[k].kind](shapes[k]) for k in (i, j))
    coal.collide(gi, coal.Transform3s(R[i], r[i]), gj, coal.Transform3s(R[j], r[j]), req, res)
    if res.numContacts() >= MESH_CONTACTS:
        return None
    out = {}
    for c in res.getContacts():
        p_i, p_j, n = np.asarray(c.getNearestPoint1()), np.asarray(c.getNearestPoint2()), np.asarray(c.normal)
        depth = float((p_i - p_j) @ n)
        if depth > 0.0:
            out[int(c.b2 if shapes[j].kind == "mesh" else c.b1)] = (0.5 * (p_i + p_j), n, depth)
    return out


def _closest_on_triangle(x, w):
    """Distance of ``x`` to triangle ``w``: the plane foot if inside, else the nearest edge point."""
    a, b, c = w
    nt = np.cross(b - a, c - a)
    nt /= np.linalg.norm(nt)
    foot = x - ((x - a) @ nt) * nt
    inside = all(np.cross(q - p, foot - p) @ nt >= 0.0 for p, q in ((a, b), (b, c), (c, a)))
    if inside:
        return abs((x - a) @ nt)
    best = np.inf
    for p, q in ((a, b), (b, c), (c, a)):
        t = np.clip((x - p) @ (q - p) / ((q - p) @ (q - p)), 0.0, 1.0)
        best = min(best, np.linalg.norm(x - p - t * (q - p)))
    return best


def on_features(shape, r_s, R_s, mesh_shape, r_m, R_m, f, point, n, depth, tol):
    """Assert the witnesses of a contact (``n`` from the shape to the mesh) lie on the shape's surface
    and on facet ``f``."""
    on_shape, on_mesh = point + 0.5 * depth * n, point - 0.5 * depth * n
    w = r_m + mesh_shape.vertices[mesh_shape.faces[f]] @ R_m.T
    assert _closest_on_triangle(on_mesh, w) <= tol, f"witness off facet {f}"
    local = R_s.T @ (on_shape - r_s)
    if shape.kind == "convex":
        v = shape.vertices[shape.faces]
        nf = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        nf /= np.linalg.norm(nf, axis=1)[:, None]
        assert abs(np.max(np.einsum("ki,ki->k", nf, local - v[:, 0]))) <= tol, "witness off the hull's surface"
    else:
        h = 0.5 * shape.size[1] if shape.kind == "capsule" else 0.0
        core = np.array([0.0, 0.0, np.clip(local[2], -h, h)])
        assert abs(np.linalg.norm(local - core) - shape.size[0]) <= tol, "witness off the surface"


def compare(shapes, table, i, j, r, R, L) -> int:
    """Assert ours equals Coal's for shapes i, j (module docstring); the number of contacts compared."""
    theirs, mine = coals(shapes, i, j, r, R), ours(table, i, j, r, R)
    if theirs is None or len(mine) >= MESH_CONTACTS:
        return 0
    tol = depth_tol(L)
    k_shape, k_mesh = (j, i) if shapes[i].kind == "mesh" else (i, j)
    shape = shapes[k_shape]
    for f in set(theirs) ^ set(mine):
        assert (theirs.get(f) or mine.get(f))[2] <= tol, f"facet {f} touched by one side only"
    for f in set(theirs) & set(mine):
        (p, n, d), (q, m, e) = theirs[f], mine[f]
        s = _separation(shape, e)
        assert abs(d - e) <= tol, f"mismatch: depth on facet {f}: {e} vs Coal's {d}"
        assert np.linalg.norm(n - m) <= normal_tol(s), f"mismatch: normal on facet {f}: {m} vs {n}"
        sign = 1.0 if k_shape == i else -1.0  # n from the shape to the mesh
        on_features(shape, r[k_shape], R[k_shape], shapes[k_mesh], r[k_mesh], R[k_mesh], f, q, sign * m, e, tol)
        if shape.kind == "convex":
            continue
        slide = 0.0
        if shape.kind == "capsule":
            sin_theta = abs(R[k_shape][:, 2] @ n)
            slide = tol / sin_theta if sin_theta > 0.0 else np.inf
        assert np.linalg.norm(p - q) <= point_tol(L, s) + slide, f"mismatch: point on facet {f}: {q} vs {p}"
    return len(set(theirs) & set(mine))


def poses(shapes, rng, near: np.ndarray):
    """Shape 0 at a random rotation and a point within ~0.1 m of ``near``; the mesh (shape 1) at a random
    pose."""
    r, R = np.zeros((2, 3)), np.tile(np.eye(3), (2, 1, 1))
    R[1] = Rotation.random(random_state=rng.integers(2**31)).as_matrix()
    r[1] = rng.normal(0.0, 0.5, 3)
    R[0] = Rotation.random(random_state=rng.integers(2**31)).as_matrix()
    r[0] = r[1] + R[1] @ (near + rng.normal(0.0, 0.1, 3))
    return r, R


# --- against Coal -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["sphere", "capsule", "box", "hull"])
def test_contacts_on_a_random_triangle_soup_are_coals(kind):
    rng = np.random.default_rng(11)
    first = {"sphere": sphere(0.3), "capsule": capsule(0.15, 0.34),
             "box": hull([[x, y, z] for x in (-0.3, 0.3) for y in (-0.2, 0.2) for z in (-0.1, 0.1)]),
             "hull": hull(rng.normal(0.0, 0.3, (12, 3)))}[kind]
    compared = 0
    for _ in range(60):
        shapes = (first, soup(rng, 60))
        table = pack_shapes(shapes, 1)
        L = first.bounding_radius
        for _ in range(10):
            r, R = poses(shapes, rng, shapes[1].vertices[rng.integers(len(shapes[1].vertices))])
            for i, j in ((0, 1), (1, 0)):
                compared += compare(shapes, table, i, j, r, R, L)
    assert compared > 300  # the poses do touch


def _hoist_states():
    from viz3d.kinematics import resting_configurations
    from viz3d.scene.build import build

    scene = viz3d.load_scene(ROOT / "scenes" / "anchor_hoist.toml", ["sim.t_end=0.3", "sim.output_dt=0.05"])
    traj = viz3d.simulate(scene)
    assert traj.status == "ok", traj.status
    system, _ = build(scene)
    col = next(f for f in system.forces if isinstance(f, Collisions))
    return col, resting_configurations(traj.t, traj.position, traj.rotation)


@pytest.fixture(scope="module")
def hoist():
    return _hoist_states()


def test_contacts_along_the_anchor_hoist_are_coals(hoist):
    col, cfgs = hoist
    shapes, table = col.shapes, col._world()["table"]
    rng = np.random.default_rng(5)
    compared = 0
    for cfg in cfgs:
        r, R = col.shape_poses(cfg)
        for i, j in col.candidates(r, R):
            if "mesh" not in (shapes[i].kind, shapes[j].kind):
                continue
            k = j if shapes[i].kind == "mesh" else i  # the shape on the mesh
            L = shapes[k].bounding_radius
            compared += compare(shapes, table, i, j, r, R, L)
            # and the same shape moved by 2 cm and turned a little
            r2, R2 = r.copy(), R.copy()
            r2[k] += rng.normal(0.0, 0.02, 3)
            R2[k] = Rotation.from_rotvec(rng.normal(0.0, 0.05, 3)).as_matrix() @ R[k]
            compared += compare(shapes, table, i, j, r2, R2, L)
    assert compared >= 10


def test_collisions_find_the_same_touches_with_our_narrow_phase_as_with_coals(hoist):
    col, cfgs = hoist
    w = col._world()
    ours_mask = w["ours"].copy()
    L = max(s.bounding_radius for s in col.shapes if s.body != col.n_bodies)
    try:
        for cfg in cfgs:
            w["ours"][:] = False
            theirs = col._detect(cfg)
            w["ours"][:] = ours_mask
            mine = col._detect(cfg)
            assert np.array_equal(theirs.shape, mine.shape), f"t = {cfg.t}: other pairs or counts"
            for k in range(mine.m):
                s = _separation(col.shapes[mine.shape[k, 0]], mine.depth[k])
                assert abs(theirs.depth[k] - mine.depth[k]) <= depth_tol(L), f"t = {cfg.t}: depth {k}"
                assert np.linalg.norm(theirs.n[k] - mine.n[k]) <= normal_tol(s), f"t = {cfg.t}: normal {k}"
                assert np.linalg.norm(theirs.point[k] - mine.point[k]) <= point_tol(L, s), f"t = {cfg.t}: point {k}"
    finally:
        w["ours"][:] = ours_mask


@pytest.mark.parametrize("kinds", [("sphere", "sphere"), ("sphere", "capsule"), ("capsule", "sphere")])
def test_a_sphere_on_a_sphere_or_capsule_is_coals(kinds):
    """Both closed forms (Coal's and ours: closest points of the cores): equal to round-off."""
    rng = np.random.default_rng(29)
    make = {"sphere": lambda: sphere(rng.uniform(0.05, 0.3)), "capsule": lambda: capsule(rng.uniform(0.05, 0.2),
                                                                                          rng.uniform(0.0, 0.6))}
    hits = 0
    for _ in range(300):
        shapes = (make[kinds[0]](), make[kinds[1]]())
        shapes = (shapes[0], Shape(shapes[1].name, 1, shapes[1].kind, shapes[1].size, support=shapes[1].support))
        table = pack_shapes(shapes, 2)
        r = rng.normal(0.0, 0.25, (2, 3))
        R = Rotation.random(2, random_state=rng.integers(2**31)).as_matrix()
        L = max(s.bounding_radius for s in shapes)
        mine = ours(table, 0, 1, r, R)
        res = coal.CollisionResult()
        req = coal.CollisionRequest()
        req.enable_contact = True
        coal.collide(*(x for k in (0, 1) for x in (GEOMETRIES[shapes[k].kind](shapes[k]), coal.Transform3s(R[k], r[k]))),
                     req, res)
        theirs = [(0.5 * (np.asarray(c.getNearestPoint1()) + np.asarray(c.getNearestPoint2())), np.asarray(c.normal),
                   float((np.asarray(c.getNearestPoint1()) - np.asarray(c.getNearestPoint2())) @ np.asarray(c.normal)))
                  for c in res.getContacts()]
        theirs = [t for t in theirs if t[2] > 0.0]
        assert len(theirs) == len(mine)
        for (p, n, d), (q, m, e) in zip(theirs, mine.values()):
            assert abs(d - e) <= 64 * EPS * L and np.linalg.norm(p - q) <= 64 * EPS * L
            core = sum(x.size[0] for x in shapes) - e  # the cores' distance: n = gap / core
            assert np.linalg.norm(n - m) <= 64 * EPS * L / core
            hits += 1
    assert hits > 50


# --- closed forms -----------------------------------------------------------------------------------------

TRIANGLE = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _at(shape: Shape, centre, rotation=None, tri=TRIANGLE, faces=((0, 1, 2),)):
    """Our contacts of ``shape`` at ``centre`` (turned by ``rotation``) with the mesh ``tri``, ``faces``."""
    shapes = (shape, mesh(tri, np.array(faces)))
    r = np.array([centre, [0.0, 0.0, 0.0]], float)
    R = np.array([np.eye(3) if rotation is None else rotation, np.eye(3)], float)
    return ours(pack_shapes(shapes, 1), 0, 1, r, R)


@pytest.mark.parametrize("centre, foot", [((0.2, 0.3, 0.1), (0.2, 0.3, 0.0)),      # above the face
                                          ((0.5, -0.1, 0.05), (0.5, 0.0, 0.0)),   # beside edge 0-1
                                          ((-0.1, -0.1, 0.1), (0.0, 0.0, 0.0))])   # off vertex 0
def test_a_sphere_on_a_triangle_touches_its_nearest_point(centre, foot):
    r = 0.3
    (p, n, d), = _at(sphere(r), centre).values()
    gap = np.subtract(foot, centre)
    dist = np.linalg.norm(gap)
    assert d == pytest.approx(r - dist, abs=64 * EPS)
    assert np.allclose(n, gap / dist, atol=64 * EPS)
    assert np.allclose(p, 0.5 * (np.add(centre, r * gap / dist) + foot), atol=64 * EPS)


def test_a_capsule_lying_on_a_triangle_touches_along_the_middle_of_its_overlap():
    r, length, h = 0.1, 0.6, 0.06
    lying = Rotation.from_euler("y", 90, degrees=True).as_matrix()  # its axis along x
    (p, n, d), = _at(capsule(r, length), (0.2, 0.25, h), lying).values()
    assert d == pytest.approx(r - h, abs=64 * EPS)
    assert np.allclose(n, [0.0, 0.0, -1.0], atol=64 * EPS)
    # the segment x in [-0.1, 0.5] at y = 0.25 over the triangle x + y <= 1, x >= 0: x in [0, 0.5]
    assert np.allclose(p, [0.25, 0.25, 0.5 * (h - r)], atol=64 * EPS)


def test_a_cube_resting_on_a_plane_mesh_sinks_exactly_its_overlap():
    a, delta = 0.5, 0.01
    square = np.array([[-2.0, -2.0, 0.0], [2.0, -2.0, 0.0], [2.0, 2.0, 0.0], [-2.0, 2.0, 0.0]])
    cube = hull([[x, y, z] for x in (-a, a) for y in (-a, a) for z in (-a, a)])
    found = _at(cube, (0.3, -0.2, a - delta), tri=square, faces=((0, 1, 2), (0, 2, 3)))
    assert sorted(found) == [0, 1]  # both triangles under the cube
    for p, n, d in found.values():
        assert d == pytest.approx(delta, abs=64 * EPS * a)
        assert np.allclose(n, [0.0, 0.0, -1.0], atol=64 * EPS)
        assert p[2] == pytest.approx(-0.5 * delta, abs=64 * EPS)
        assert abs(p[0] - 0.3) <= a and abs(p[1] + 0.2) <= a  # under the cube's face


def test_face_on_facet_points_lie_on_both_features():
    """Coal's point is not unique here: ours is checked to lie on both contact features."""
    rng = np.random.default_rng(3)
    a = 0.4
    cube = hull([[x, y, z] for x in (-a, a) for y in (-a, a) for z in (-a, a)])
    tri = np.array([[-1.0, -0.8, 0.0], [1.2, -0.5, 0.0], [0.1, 1.1, 0.0]])
    for _ in range(50):
        turn = Rotation.from_euler("z", rng.uniform(0, 360), degrees=True).as_matrix()
        delta = rng.uniform(0.001, 0.1)
        centre = np.array([*rng.uniform(-0.8, 0.8, 2), a - delta])
        found = _at(cube, centre, turn, tri=tri)
        theirs = coals((cube, mesh(tri, np.array([[0, 1, 2]]))), 0, 1, np.array([centre, np.zeros(3)]),
                       np.array([turn, np.eye(3)]))
        assert set(found) == set(theirs)
        for f, (p, n, d) in found.items():
            assert d == pytest.approx(theirs[f][2], abs=depth_tol(a))
            on_cube, on_facet = p + 0.5 * d * n, p - 0.5 * d * n  # p_i - p_j = d n
            assert abs(on_cube[2] - (centre[2] - a)) <= depth_tol(a)                  # the cube's bottom face
            assert np.all(np.abs(turn.T @ (on_cube - centre))[:2] <= a + depth_tol(a))
            assert abs(on_facet[2]) <= depth_tol(a)                                    # the facet
            u = np.linalg.solve(np.column_stack([tri[1] - tri[0], tri[2] - tri[0], [0, 0, 1]]), on_facet - tri[0])
            assert u[0] >= -depth_tol(a) and u[1] >= -depth_tol(a) and u[0] + u[1] <= 1 + depth_tol(a)


# --- the box tree -----------------------------------------------------------------------------------------


def _every_facet(table, m: int):
    """``table`` with mesh m's tree replaced by a list of leaves with unbounded boxes (every facet)."""
    F = table.f_off[m + 1] - table.f_off[m]
    n0, n1 = table.n_off[m], table.n_off[m + 1]
    lo, hi = np.full((F, 3), -np.inf), np.full((F, 3), np.inf)

    def cut(a, b):
        return np.ascontiguousarray(np.concatenate([a[:n0], b, a[n1:]]))

    n_off = table.n_off.copy()
    n_off[m + 1:] += F - (n1 - n0)
    return table._replace(node_lo=cut(table.node_lo, lo), node_hi=cut(table.node_hi, hi),
                          node_skip=cut(table.node_skip, np.arange(1, F + 1)), node_facet=cut(table.node_facet, np.arange(F)),
                          n_off=n_off)


@pytest.mark.parametrize("kind", ["sphere", "capsule", "hull"])
def test_the_box_tree_finds_the_facets_every_facet_finds(kind):
    rng = np.random.default_rng(23)
    first = {"sphere": sphere(0.25), "capsule": capsule(0.1, 0.5), "hull": hull(rng.normal(0.0, 0.25, (10, 3)))}[kind]
    touched = 0
    for _ in range(20):
        shapes = (first, soup(rng, 300, size=0.3, spread=1.0))
        table = pack_shapes(shapes, 1)
        assert len(table.node_skip) == 2 * 300 - 1
        flat = _every_facet(table, 1)
        for _ in range(20):
            r, R = poses(shapes, rng, rng.uniform(-1.0, 1.0, 3))
            tree, every = ours(table, 0, 1, r, R), ours(flat, 0, 1, r, R)
            if len(every) >= MESH_CONTACTS:
                continue
            assert sorted(tree) == sorted(every)
            touched += len(every)
    assert touched > 100

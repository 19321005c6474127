"""Still water (``[water]``, ``viz3d.water``) on rigid bodies whose shape is a triangle mesh, against
references from trimesh and scipy (volumes, centroids, convex hulls) and Archimedes:

* fully submerged, a mesh feels ``rho g V`` (``V`` trimesh's volume) through its centre of mass: the
  body origin of a mesh given a density; its own origin when its inertia is given;
* a floating mesh box rests at Archimedes' draft ``d = m / (rho A)``, to a bound from its grid;
* a mesh box and the primitive box feel the same buoyancy and moment at any pose (their grids are
  the same grid); a convex mesh's wet volume is scipy's hull of its wet part, to a grid bound;
* the cells of a mesh are the grid centres inside it (scipy's hull for convex meshes, the torus'
  equation for a non-convex one), even where grid columns run through its edges and vertices.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.optimize import brentq
from scipy.spatial import ConvexHull

import viz3d
from viz3d.anchoring import anchor_flukes, anchor_shank
from viz3d.dynamics import body_state
from viz3d.scene.schema import SceneError
from viz3d.water import column_winding, mesh_cells

G, RHO_W = 9.81, 1000.0
BOX = (0.5, 0.375, 0.25)  # binary fractions: exact in an STL file's float32
CELLS = 32768  # for the wet hulls: a bound that says something needs slender pieces many cells across
OFFSET = (1.0, -0.5, 0.25)  # the box mesh file's centroid, away from its origin [m]


def _box_file(tmp_path, extents=BOX, offset=OFFSET, name="box.stl"):
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(offset)
    path = tmp_path / name
    mesh.export(path)
    return path


def _build(tmp_path, text, name="scene"):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return viz3d.build(viz3d.load_scene(path))


def _water(system):
    return next(e for e in system.forces if e.type_name == "water")


def _wrench(system, state, z=None):
    """The water's force (3,) [N] and moment about the body origin (3,) [N m] on body 0, at height z."""
    q = state.q.copy()
    if z is not None:
        system.split_q(q)[0][0, 2] = z
    cfg = body_state(system, q, state.v, state.chart, 0.0)
    F, tau, _ = _water(system).wrench(cfg)
    return F[0], tau[0], cfg


def _body(name, shape, where, extra="density = 7850.0\n"):
    return f'[[bodies]]\nname = "{name}"\nshape = {shape}\n{extra}position = {[float(x) for x in where]}\n'


@pytest.mark.parametrize("given_inertia", [False, True])
def test_a_submerged_mesh_feels_rho_g_V_through_its_centroid(tmp_path, given_inertia):
    """An anchor shank (a tapered bar: its centroid is not its bounding box's centre), tilted, deep
    under water. Its cells' volumes sum to V exactly, so F = rho g V n to round-off. The buoyancy acts
    at the mesh's centroid c (trimesh): with a density the body origin is that centroid (moment 0); with
    a given inertia the origin is the mesh's own, and the moment is (R c) x F."""
    V_mesh, F_mesh = anchor_shank()
    ref = trimesh.Trimesh(V_mesh, F_mesh)
    V, c = ref.volume, ref.center_mass
    extra = "mass = 1000.0\ninertia = [100.0, 100.0, 10.0]\n" if given_inertia else "density = 7850.0\n"
    system, state = _build(tmp_path, _body("shank", '{ type = "mesh", generator = "anchor_shank" }', (0.3, -0.2, -20.0),
                                           extra + "euler_deg = [30.0, 40.0, 10.0]\n")
                           + f"[water]\ndensity = {RHO_W}\n")
    F, tau, cfg = _wrench(system, state)
    B = RHO_W * G * V
    np.testing.assert_allclose(F, [0.0, 0.0, B], rtol=0, atol=1e-12 * B)
    lever = cfg.pose.R_WB[0] @ c if given_inertia else np.zeros(3)
    assert np.linalg.norm(lever) > 0.5 or not given_inertia  # the test would see a wrong origin
    np.testing.assert_allclose(tau, np.cross(lever, F), rtol=0, atol=1e-12 * B * np.ptp(V_mesh, axis=0).max())
    assert _water(system).scalars(cfg)["water/buoyancy"] == pytest.approx(B, rel=1e-12)


def _layer_bound(V, nz, dz, c):
    """Bound on |V_wet(cells) - V_wet| of a level box cut into nz layers dz thick (all its cells inside,
    each of volume V / (nz n_xy), its grid's own: w = dx dy dz). A layer at height z_k under a surface at
    s holds f_k = clip((s - z_k)/c + 1/2, 0, 1) of its volume for the cells, g_k = clip((s - z_k)/dz
    + 1/2, 0, 1) in truth: they differ only where |s - z_k| < max(c, dz)/2 (at most max/dz + 1 layers),
    each by at most (1 - min/max)/2 (two ramps through the same midpoint)."""
    lo, hi = min(c, dz), max(c, dz)
    return V / nz * (np.floor(hi / dz) + 1) * 0.5 * (1 - lo / hi)


@pytest.mark.parametrize("cells", [512, 4096])
def test_a_floating_mesh_box_rests_at_the_archimedes_draft(tmp_path, cells):
    """A box mesh file of density 300 (not half the water's, where symmetry alone would put it right),
    its centroid off the file's origin. Its equilibrium height z* (the water's force on the built
    system equals its weight) is Archimedes' h/2 - d, d = m / (rho A), within the layer bound over A
    (the grid's layers: per axis round(extent / c), c = (V / n)^(1/3)); started there it stays at rest."""
    a, b, h = BOX
    rho = 300.0
    m = rho * a * b * h
    d = m / (RHO_W * a * b)
    path = _box_file(tmp_path)
    text = ("[sim]\nt_end = 0.5\ndt = 1e-3\noutput_dt = 0.1\n\n"
            + _body("box", f'{{ type = "mesh", file = "{path.name}" }}', (0.0, 0.0, 0.0), f"density = {rho}\n")
            + f"[water]\ndensity = {RHO_W}\ncells = {cells}\n")
    system, state = _build(tmp_path, text, f"float{cells}")
    z_star = brentq(lambda z: _wrench(system, state, z)[0][2] - m * G, -h, h, xtol=1e-14)
    c = (a * b * h / cells) ** (1 / 3)
    _, dx = _grid(-0.5 * np.array(BOX), 0.5 * np.array(BOX), c)
    bound = _layer_bound(a * b * h, round(h / dx[2]), dx[2], c) / (a * b)
    assert abs(z_star - (h / 2 - d)) <= bound  # its bottom at -d
    assert bound < 0.1 * d  # the bound says something
    _, tau, _ = _wrench(system, state, z_star)
    np.testing.assert_allclose(tau, 0.0, atol=1e-12 * m * G * a)  # level and symmetric: upright
    (tmp_path / f"rest{cells}.toml").write_text(text.replace("position = [0.0, 0.0, 0.0]", f"position = [0.0, 0.0, {z_star!r}]"))
    traj = viz3d.simulate(viz3d.load_scene(tmp_path / f"rest{cells}.toml"))
    assert traj.status == "ok", traj.status
    assert np.abs(traj.position[:, 0, 2] - z_star).max() < 1e-9


POSES = [((0.0, 0.0, 0.0), 0.03), ((30.0, 20.0, 0.0), 0.0), ((10.0, 75.0, -40.0), -0.06), ((0.0, 90.0, 0.0), 0.1)]


@pytest.mark.parametrize("euler, z", POSES)
def test_a_mesh_box_and_the_primitive_box_feel_the_same_water(tmp_path, euler, z):
    """Same box as a mesh file (centroid off its origin) and as a primitive, at the same tilted pose
    through the surface and moving: the mesh's grid is the primitive's (cell volume V / n over a box
    filling its bounding box), shifted by the centroid, so buoyancy, drag and their moments agree to
    round-off (each pose is partly wet: a wrong grid, frame or volume would show)."""
    path = _box_file(tmp_path)
    where = (0.5, 0.2, z)
    tilt = f"euler_deg = {list(euler)}\ndensity = 500.0\nvelocity = [0.3, -0.2, 0.5]\nomega = [1.0, 2.0, -0.5]\n"
    text = (_body("mesh", f'{{ type = "mesh", file = "{path.name}" }}', where, tilt)
            + _body("prim", f'{{ type = "box", extents = {list(BOX)} }}', where, tilt)
            + f"[water]\ndensity = {RHO_W}\ndrag_coefficient = 0.7\n")
    system, state = _build(tmp_path, text, "pair")
    water = _water(system)
    assert list(water.body) == [0, 1]  # default bodies: the mesh too
    cfg = body_state(system, state.q, state.v, state.chart, 0.0)
    F, tau, _ = water.wrench(cfg)
    B = RHO_W * G * np.prod(BOX)
    assert 0.05 * B < F[1, 2] < 0.95 * B and abs(F[1, 0]) > 1e-5 * B  # through the surface, dragged
    np.testing.assert_allclose(F[0], F[1], rtol=0, atol=1e-12 * B)
    np.testing.assert_allclose(tau[0], tau[1], rtol=0, atol=1e-12 * B * max(BOX))


def _hull_wet_volume(vertices, faces, s):
    """Volume of the part below z = s of a convex mesh: scipy's hull of its vertices below and its
    edges' crossings of the plane."""
    e = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    p, q = vertices[e[:, 0]], vertices[e[:, 1]]
    cross = (p[:, 2] - s) * (q[:, 2] - s) < 0
    t = (s - p[cross, 2]) / (q[cross, 2] - p[cross, 2])
    points = np.vstack([vertices[vertices[:, 2] <= s], p[cross] + t[:, None] * (q[cross] - p[cross])])
    return ConvexHull(points).volume


def _grid(lo, hi, c):
    """The grid the water module's docstring describes: per axis round(extent / c) cells (at least
    one) over the bounding box; centres (m, 3) and spacings (3,)."""
    k = np.maximum(1, np.round((hi - lo) / c)).astype(int)
    dx = (hi - lo) / k
    axes = [lo[i] + (np.arange(k[i]) + 0.5) * dx[i] for i in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3), dx


def _hull_distance(points, vertices):
    """Largest signed distance (m,) of points to the face planes of the convex hull of vertices: < 0
    inside."""
    eq = ConvexHull(vertices).equations
    return (points @ eq[:, :3].T + eq[:, 3]).max(axis=1)


def _cut_boxes(centres, dx, vertices):
    """Which grid boxes (centres (m, 3), sides dx (3,)) the surface of a convex hull may cut: not all
    their corners inside (else the box is inside), and no face plane with all of them outside (else
    it is outside). Conservative: it ignores the edge-edge separations."""
    eq = ConvexHull(vertices).equations
    signs = np.array([[i, j, k] for i in (-0.5, 0.5) for j in (-0.5, 0.5) for k in (-0.5, 0.5)])
    corners = centres[:, None, :] + signs * dx  # (m, 8, 3)
    D = corners @ eq[:, :3].T + eq[:, 3]  # (m, 8, planes)
    inside = (D <= 0).all(axis=2).all(axis=1)
    outside = (D > 0).all(axis=1).any(axis=1)
    return ~inside & ~outside


@pytest.mark.parametrize("generator, mesh", [("anchor_shank", anchor_shank), ("anchor_flukes", anchor_flukes)])
@pytest.mark.parametrize("fraction", [0.3, 0.7])
def test_a_convex_mesh_through_the_surface_displaces_its_wet_hull(tmp_path, generator, mesh, fraction):
    """An upright anchor piece with the surface at ``fraction`` of its height: its buoyancy over rho g
    is the volume of its wet part (scipy's hull), to a grid bound. The cells are the grid's boxes B_i
    (|B| = dx dy dz) whose centres are inside, translated by delta onto the exact centroid: so the
    model is the unshifted grid under a surface at s' = s - delta_z. Against the truth sum_i |B_i cap
    S cap W| it errs by |1 - |B|/w| times its own volume (the cells weigh w = V/m, not |B|), plus at
    most |B| for each box the mesh's surface cuts that may be wet, and for each kept one in the band
    |s' - z_i| < max(c, dz)/2 (elsewhere its wet fraction and the truth are both 0 or both 1)."""
    V, F = mesh()
    ref = trimesh.Trimesh(V, F)
    V = V - ref.center_mass  # body axes: centred on the centre of mass
    lo, hi = V.min(axis=0), V.max(axis=0)
    s = lo[2] + fraction * (hi[2] - lo[2])  # surface height in body axes; the body is at z = -s
    system, state = _build(tmp_path, _body("piece", f'{{ type = "mesh", generator = "{generator}" }}', (0.0, 0.0, -s))
                           + f"[water]\ndensity = {RHO_W}\ncells = {CELLS}\n", generator)
    model = _wrench(system, state)[0][2] / (RHO_W * G)
    c = float((ref.volume / CELLS) ** (1 / 3))
    grid, dx = _grid(lo, hi, c)
    d = _hull_distance(grid, V)
    kept = d < 0
    delta = -grid[kept].mean(axis=0)  # the centroid is the origin
    s1 = s - delta[2]
    box, band = np.prod(dx), 0.5 * max(c, dx[2])
    cut = _cut_boxes(grid, dx, V) & (grid[:, 2] < s1 + band)
    in_band = kept & (np.abs(s1 - grid[:, 2]) < band)
    w = ref.volume / kept.sum()
    bound = abs(1 - box / w) * model + box * (cut | in_band).sum()
    assert abs(model - _hull_wet_volume(V, F, s1)) <= bound
    assert bound < 0.3 * model  # the bound says something


@pytest.mark.parametrize("n", [64, 512, 4096])
def test_mesh_cells_are_the_grid_centres_inside_a_convex_mesh(n):
    """Anchor flukes (a tapered plate): the cells, less one translation onto the exact centroid
    (trimesh's), are the grid centres scipy's hull puts inside (those on a face plane either way).
    The translation is the grid's centroid error: under a cell (0.6 c for this plate 1 to 3 cells
    thick at 64 and 512 cells)."""
    V, F = anchor_flukes()
    ref = trimesh.Trimesh(V, F)
    X, w, c = mesh_cells(V, F, ref.volume, n)
    grid, _ = _grid(V.min(axis=0), V.max(axis=0), c)
    d = _hull_distance(grid, V)
    inside, clear = d < 0, np.abs(d) > 1e-9
    shift = ref.center_mass - grid[inside].mean(axis=0)
    assert np.linalg.norm(shift) < c
    kept = {tuple(np.round(x, 9)) for x in X - shift}
    assert kept >= {tuple(np.round(x, 9)) for x in grid[inside & clear]}
    assert kept <= {tuple(np.round(x, 9)) for x in grid[inside | ~clear]}
    assert w.sum() == pytest.approx(ref.volume, rel=1e-12)
    np.testing.assert_allclose(X.mean(axis=0), ref.center_mass, atol=1e-12)


@pytest.mark.parametrize("k", [7, 8, 33])
def test_the_winding_test_of_a_torus_matches_its_equation(k):
    """A non-convex mesh (trimesh's torus, radii R and r): on a k^3 grid whose columns run through its
    vertices and edges (x = 0 or y = 0 for odd k), points whose distance to the core circle is below
    r - e are inside, above r + e outside; e bounds the facets' deviation from the true torus (sagitta
    of the minor and major polygons)."""
    R, r, m = 0.1, 0.03, 32
    torus = trimesh.creation.torus(R, r, major_sections=m, minor_sections=m)
    assert torus.is_watertight and torus.is_volume
    e = r * (1 - np.cos(np.pi / m)) + (R + r) * (1 - np.cos(np.pi / m))
    x = np.linspace(-R - r, R + r, k)
    z = np.linspace(-r, r, k)
    xy = np.stack(np.meshgrid(x, x, indexing="ij"), axis=-1).reshape(-1, 2)
    W = column_winding(xy, z, torus.vertices, torus.faces)
    core = np.hypot(np.hypot(xy[:, 0], xy[:, 1])[:, None] - R, z[None, :])
    assert set(np.unique(W)) <= {0, 1}
    assert (W[core < r - e] == 1).all() and (W[core > r + e] == 0).all()
    assert (core < r - e).sum() > 0.2 * W.size / 4  # the test sees the inside


def test_default_water_bodies_take_closed_meshes_and_leave_open_ones_dry(tmp_path):
    """Default ``water.bodies``: every rigid body with a shape, open meshes (collision surfaces, given
    their inertia) left out; naming an open mesh or a shapeless body is a SceneError."""
    _box_file(tmp_path)
    open_box = trimesh.creation.box(extents=BOX)
    open_box.update_faces(np.arange(len(open_box.faces)) > 1)  # two triangles missing: open
    open_box.export(tmp_path / "open.stl")
    given = "mass = 1.0\ninertia = [1.0, 1.0, 1.0]\n"
    text = (_body("ball", '{ type = "sphere", radius = 0.1 }', (0, 0, 0))
            + _body("shell", '{ type = "mesh", file = "open.stl" }', (1, 0, 0), given)
            + _body("box", '{ type = "mesh", file = "box.stl" }', (2, 0, 0))
            + _body("point", "{}", (3, 0, 0), given).replace("shape = {}\n", "")
            + f"[water]\ndensity = {RHO_W}\n")
    system, _ = _build(tmp_path, text, "default")
    assert list(_water(system).body) == [0, 2]
    for name, where in (("shell", "bodies[1].shape.file"), ("point", "water.bodies")):
        with pytest.raises(SceneError) as err:
            _build(tmp_path, text + f'bodies = ["{name}"]\n', name)
        assert err.value.path == where


@pytest.mark.parametrize("seed", range(5))
def test_columns_through_edges_cross_the_surface_once(seed):
    """Columns through points of a rotated icosphere's edges (on them to round-off, where the two
    faces' orientation tests could disagree): a point below the sphere has winding number 0 and one at
    its centre 1. The edge test must give the two faces exactly opposite answers."""
    from scipy.spatial.transform import Rotation

    sphere = trimesh.creation.icosphere(2, radius=1.0)
    V = Rotation.random(random_state=seed).apply(sphere.vertices)
    e = sphere.edges_unique
    t = np.random.default_rng(seed).uniform(0.2, 0.8, len(e))[:, None]
    xy = (V[e[:, 0]] * (1 - t) + V[e[:, 1]] * t)[:, :2]
    W = column_winding(xy, np.array([-2.0, 0.0]), V, sphere.faces)
    inradius = np.einsum("fi,fi->f", sphere.face_normals, sphere.triangles[:, 0]).min()
    within = np.hypot(xy[:, 0], xy[:, 1]) < inradius  # then (x, y, 0) is inside
    assert (W[:, 0] == 0).all() and (W[within, 1] == 1).all() and within.sum() > 0.5 * len(e)

"""Contacts between body shapes: broad phase, narrow phase (ours against triangle meshes, Coal's, hpp-fcl's
successor, for the rest), reduction and forces.

Every rigid body with a shape, and every ground shape, is a collision shape. At each evaluation of
the forces the shapes are placed at the bodies' poses; the broad phase proposes the pairs whose
bounding spheres (moving shapes) or boxes (ground shapes) overlap, from a k-d tree per collision
group (``scipy.spatial.cKDTree``: O(N log N) per group, never the O(N^2) pair list), and only for
the pairs of groups the scene declares. The narrow phase then gives each touching pair its normal,
penetration depth and contact points: ours (``viz3d.contact.narrowphase``, compiled) for a sphere,
capsule or convex hull against a triangle mesh and a sphere against a sphere or capsule, Coal's for
every other pair, with its contact patch
(the polygon where the shapes touch, each point with its witness on both surfaces: a box on a box
gets the corners of their overlap). Infinite planes are not in the broad phase: a shape's *support
points* (a sphere's centre with its radius, a capsule's two end spheres, a box's corners, a
cylinder's rim points, a convex or triangle mesh's vertices) are tested against each plane
directly, one contact per point below it, exact for everything but the cylinder's rim
(``rim_points`` chords).

Each contact acts as a penalty contact stepped through (no events located): its pair's normal law
(one without contact memory: linear, Hertz, the rate laws with a fixed ``damping_factor``) plus an
optional linear dashpot that never pulls, and a friction law, at the contact point:

    alpha = penetration depth,   alpha_dot = -n . (v_A(p) - v_B(p)),
    F = max(law(alpha, alpha_dot) + c alpha_dot, 0),   f_A = F n + f_t,   f_B = -f_A,

with ``n`` the unit normal pointing from B towards A (A is pushed along ``+n``) and ``p`` the middle
of the two witness points. Every contact point carries the pair's law. ``potential_energy`` is the
laws' elastic energy; the dashpots', the rate laws' and friction's power is ``nonconservative_power``.

Friction: memoryless laws (``coulomb``, ``stribeck``) act against the slip alone; ``bristle``
(seed 004, eqs. 3.40-3.49, ``viz3d.contact.friction.Bristle``) also on the bristles' deflection
from a stick anchor, a point of B kept per contact in the simulation state (``StickAnchors`` in
``State.element_memory``, fixed during a step). Contacts are found afresh at every evaluation, so
each gets its identity from the last accepted step: a contact of the same two shapes whose point
at that step, carried along as a point of A or as a point of B, lies within half the merge
distance of it (contacts of one pair are farther apart than that distance; of several candidates
the nearest is taken first, each anchor once). A contact without a match has its anchor where it touches
(no deflection). After each accepted step (``memory_after_step``) a matched contact keeps its
anchor, moved by eq. 3.49 when its bristles carry more than ``mu_s F_n``; a new contact plants
one at its point; a contact that ended loses its own.

Triangle meshes are triangle soups: a shape overlapping several facets gets one contact per facet.
Of a pair's contacts we keep the deepest, drop those whose normals differ from it by more than
``COPLANAR`` (a neighbouring facet's view of the same touch), then add the farthest from those kept
until ``max_contacts`` (a well-spread support), merging any closer than ``merge_distance``.

What is ours and what is Coal's (3.0). Ours: the broad phase, the planes, the reduction, and the
narrow phase of sphere, capsule and convex hull against a triangle mesh and of a sphere against a
sphere or capsule (``narrowphase.covered``): the same raw contacts as Coal's triangle-soup test (one
per facet, the same facets, depths and normals to round-off; its module docstring says how, and
which witness point it takes where Coal's is not unique) and closed forms, compiled, so that the
kernel can call it as well. Coal's: every other pair (convex against convex, capsule against
capsule, boxes, cylinders, mesh against mesh) and the contact patches. Coal brings sphere,
capsule, box, cylinder, convex and triangle-mesh geometries, contact patches, and exact depths for
curved shapes (GJK/EPA on the shapes' cores plus the radii): on a sphere against a convex cube its
depth is exact to 1e-16 m where python-fcl 0.7 (libccd's EPA) was off by up to 2 cm on a 0.3 m
sphere. The price is its size: 320 MB with Boost and Assimp.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.contact.narrowphase import MESH_CONTACTS, contacts_of_pairs, covered, pack_shapes, segment_distance
from viz3d.forces import ForceElement
from viz3d.geometry import contact_spheres
from viz3d.kinematics import Configuration
from viz3d.rotations import cross

#: Normals within this angle [rad] of a pair's deepest contact count as the same face.
COPLANAR = 0.05
#: Below this many pairs of two groups' shapes all pairs are tested (vectorised) instead of a k-d tree.
SMALL_GROUPS = 4096
#: Shapes whose contact with anything is a single point, and curved ones (Coal's patches from the
#: curved side first can collapse to one point; the other order is tried then).
POINT_SHAPES, CURVED = ("sphere",), ("sphere", "capsule", "cylinder")


def _coal():
    import coal

    return coal


# --- shapes ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Shape:
    """One collision shape fixed to a body (or to ground).

    Attributes
    ----------
    name : str
    body : int
        Body index; ``nb``: ground.
    kind : str
        A key of ``GEOMETRIES``.
    size : tuple of float
        sphere (r,), capsule (r, h), box (a, b, c), cylinder (r, h), plane (); meshes ().
    B_r : ndarray, shape (3,)
        Shape origin in body axes from the body's frame origin (ground: world) [m].
    B_R : ndarray, shape (3, 3)
        Body-from-shape rotation.
    vertices : ndarray, shape (m, 3)
        Mesh vertices in shape axes [m] (convex: its hull's) (others: empty).
    faces : ndarray of int, shape (f, 3)
        Mesh triangles (others: empty).
    support : ndarray, shape (s, 4)
        Support points against a plane: centre in shape axes [m] and radius [m].
    group : int
        Index into ``Collisions.groups``.
    normal : ndarray, shape (3,)
        Planes: outward normal in shape axes (the plane passes through the shape origin).
    """

    name: str
    body: int
    kind: str
    size: tuple = ()
    B_r: FloatArray = field(default_factory=lambda: np.zeros(3))
    B_R: FloatArray = field(default_factory=lambda: np.eye(3))
    vertices: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    faces: IntArray = field(default_factory=lambda: np.zeros((0, 3), int))
    support: FloatArray = field(default_factory=lambda: np.zeros((0, 4)))
    group: int = 0
    normal: FloatArray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    @property
    def bounding_radius(self) -> float:
        """Radius of a sphere about the shape origin holding the shape [m] (planes: inf)."""
        if self.kind == "plane":
            return np.inf
        if len(self.vertices):
            return float(np.max(np.linalg.norm(self.vertices, axis=1)))
        return float(np.max(np.linalg.norm(self.support[:, :3], axis=1) + self.support[:, 3]))


def _sphere(s: Shape):
    return _coal().Sphere(s.size[0])


def _capsule(s: Shape):
    return _coal().Capsule(s.size[0], s.size[1])


def _box(s: Shape):
    return _coal().Box(*s.size)


def _cylinder(s: Shape):
    return _coal().Cylinder(s.size[0], s.size[1])


def _bvh(s: Shape):
    bvh = _coal().BVHModelOBBRSS()
    bvh.beginModel(len(s.faces), len(s.vertices))
    bvh.addVertices(np.asarray(s.vertices, float))
    bvh.addTriangles(np.asarray(s.faces, np.int64))
    bvh.endModel()
    return bvh


def _convex(s: Shape):
    bvh = _bvh(s)
    bvh.buildConvexHull(True, "Qt")
    return bvh.convex


#: Collision geometries: shape kind -> Coal geometry of a ``Shape`` (planes are handled here, not by Coal).
GEOMETRIES = {"sphere": _sphere, "capsule": _capsule, "box": _box, "cylinder": _cylinder, "convex": _convex,
              "mesh": _bvh, "plane": None}


def support_points(kind: str, size: tuple, vertices: FloatArray, rim_points: int = 16) -> FloatArray:
    """Support points of a shape against a plane (s, 4): centre in shape axes [m] and radius [m]; the
    primitives' are ``viz3d.geometry.contact_spheres``, a mesh's its vertices."""
    if kind in ("convex", "mesh"):
        return np.column_stack([vertices, np.zeros(len(vertices))])
    if kind not in ("sphere", "capsule", "box", "cylinder"):
        return np.zeros((0, 4))
    table = {"type": "box", "extents": list(size)} if kind == "box" else {"type": kind,
                                                                           **dict(zip(("radius", "height"), size))}
    return np.array([[*c, r] for c, r in contact_spheres(table, rim_points)])


def convex_hull(vertices: FloatArray) -> tuple[FloatArray, IntArray]:
    """Vertices and outward triangles of the convex hull of ``vertices`` (m, 3) (scipy's Qhull)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(vertices)
    faces = hull.simplices.copy()
    centre = vertices[hull.vertices].mean(axis=0)
    v = vertices[faces]
    outward = np.einsum("ki,ki->k", np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), v[:, 0] - centre) > 0
    faces[~outward] = faces[~outward][:, ::-1]
    used, inverse = np.unique(faces, return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3)


# --- pair laws ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PairLaw:
    """What acts where two groups touch.

    Attributes
    ----------
    law : NormalLaw
        A law without contact memory (``law.memoryless``); with ``hertz_modulus`` its stiffness is
        replaced per pair of spheres (or sphere and plane) by Hertz's ``4/3 E* sqrt(R)``.
    damping : float
        Linear dashpot added to the law [N s/m] (never pulls).
    friction : FrictionLaw or None
        Tangential law (``viz3d.contact.friction``); a stateful one (``bristle``) keeps stick
        anchors (``StickAnchors``).
    hertz_modulus : float
        ``E*`` [Pa] when the stiffness comes from the shapes' radii; NaN otherwise.
    """

    law: object
    damping: float = 0.0
    friction: object = None
    hertz_modulus: float = np.nan


@dataclass(frozen=True)
class Touches:
    """Contacts found at one configuration (m of them).

    Attributes
    ----------
    shape : ndarray of int, shape (m, 2)
        Shapes A and B.
    body : ndarray of int, shape (m, 2)
    law : ndarray of int, shape (m,)
        Index into ``Collisions.laws``.
    point : ndarray, shape (m, 3)
        Contact point, world [m].
    n : ndarray, shape (m, 3)
        Unit normal from B towards A.
    depth : ndarray, shape (m,)
        Penetration depth ``alpha`` [m]: > 0 where found (``FrozenTouches.at``: any sign, no force
        where <= 0).
    """

    shape: IntArray
    body: IntArray
    law: IntArray
    point: FloatArray
    n: FloatArray
    depth: FloatArray

    @property
    def m(self) -> int:
        return len(self.depth)


@dataclass(frozen=True)
class StickAnchors:
    """The stick anchors of the contacts whose pair law has a stateful friction law (``bristle``): the
    memory ``Collisions`` keeps in ``State.element_memory`` (n contacts, at the last accepted step).

    Attributes
    ----------
    shape : ndarray of int, shape (n, 2)
        Shapes A and B of each contact.
    anchor : ndarray, shape (n, 3)
        Where the bristles are planted: a point of B in B's axes from its frame origin (ground:
        world) [m].
    mark : ndarray, shape (n, 2, 3)
        The contact point as a point of A and as a point of B, each in its body's axes from its frame
        origin [m]: the contact's identity at the next evaluations.
    """

    shape: IntArray
    anchor: FloatArray
    mark: FloatArray

    @property
    def n(self) -> int:
        return len(self.shape)


@dataclass(frozen=True)
class FrozenTouches:
    """The contacts found at one configuration, held fixed for evaluations near it (m of them): the
    memory an implicit step's Newton iteration evaluates the shape contacts with
    (``Collisions.frozen``, ``viz3d.ali3p``), so that their forces are smooth in the iterate. Each
    contact is a material point of A (its witness, the deepest point) against the tangent plane of
    B at B's witness point; at a configuration

        p_A = W_r_A + R_WA A_r,   p_B = W_r_B + R_WB B_r,   n = R_WB B_n,   depth = (p_B - p_A) . n,

    the point their middle. Exact while a vertex or flat face of A stays on the same face of B, to
    second order in the motion for curved ones. Which contacts push is held too (an active set):
    an active one carries its law's force without the clipping at zero (``force_unclipped``: the
    clipped force has a kink where a rate law's damping cancels it), continued as an odd function
    of the depth where it separates (``sign(depth) F(|depth|)``, smooth through 0 for exponents
    >= 1): it may pull, which the iteration's check at its converged point sees; the others carry
    none. The bristles' anchors, and each contact's match among them, are fixed
    as well.

    Attributes
    ----------
    shape, body : ndarray of int, shape (m, 2)
        Shapes and bodies A and B.
    law : ndarray of int, shape (m,)
        Index into ``Collisions.laws``.
    A_r, B_r : ndarray, shape (m, 3)
        The witness points, each in its body's axes from its frame origin (ground: world) [m].
    B_n : ndarray, shape (m, 3)
        The unit normal from B towards A in B's axes.
    match : ndarray of int, shape (m,)
        Each contact's entry in ``anchors`` (``Collisions.match``), -1: none.
    active : ndarray of bool, shape (m,)
        The contacts that push (their clipped force > 0 where they were found).
    anchors : StickAnchors or None
        The element's memory of the step (bristle friction's stick anchors).
    """

    shape: IntArray
    body: IntArray
    law: IntArray
    A_r: FloatArray
    B_r: FloatArray
    B_n: FloatArray
    match: IntArray
    active: np.ndarray
    anchors: StickAnchors | None = None

    def at(self, cfg: Configuration) -> Touches:
        """The contacts at ``cfg`` (depths may be <= 0)."""
        W_r, R = cfg.pose.W_r, cfg.pose.R_WB
        a, b = self.body[:, 0], self.body[:, 1]
        p_A = W_r[a] + np.einsum("kij,kj->ki", R[a], self.A_r)
        p_B = W_r[b] + np.einsum("kij,kj->ki", R[b], self.B_r)
        n = np.einsum("kij,kj->ki", R[b], self.B_n)
        return Touches(self.shape, self.body, self.law, 0.5 * (p_A + p_B), n, np.einsum("ki,ki->k", p_B - p_A, n))


def _world_box(s: Shape) -> tuple[FloatArray, FloatArray]:
    """World axis-aligned box (lower, upper corners) of a ground shape [m], exact but for cylinders
    (the box of their enclosing square prism)."""
    if len(s.vertices):
        centres, radius = s.vertices, np.zeros(len(s.vertices))
    elif s.kind == "cylinder":
        r, h = s.size[0], 0.5 * s.size[1]
        centres = np.array([[x, y, z] for x in (-r, r) for y in (-r, r) for z in (-h, h)])
        radius = np.zeros(8)
    else:
        centres, radius = s.support[:, :3], s.support[:, 3]
    p = s.B_r + centres @ np.asarray(s.B_R).T
    return (p - radius[:, None]).min(axis=0), (p + radius[:, None]).max(axis=0)


def _all_pairs(a: IntArray, b: IntArray, same: bool) -> IntArray:
    """Every pair (k, 2) of an index from ``a`` and one from ``b`` (``same``: a = b, each pair once)."""
    if same:
        x, y = np.triu_indices(len(a), 1)
        return np.column_stack([a[x], a[y]])
    return np.column_stack([np.repeat(a, len(b)), np.tile(b, len(a))])


def _no_touches() -> Touches:
    return Touches(np.zeros((0, 2), int), np.zeros((0, 2), int), np.zeros(0, int), np.zeros((0, 3)), np.zeros((0, 3)),
                   np.zeros(0))


# --- the force element -------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Collisions(ForceElement):
    """Contact forces between every pair of shapes whose groups a scene declares (module docstring).

    Attributes
    ----------
    shapes : tuple of Shape
    groups : tuple of str
    pair_law : ndarray of int, shape (G, G)
        Index into ``laws`` of each pair of groups (symmetric), -1: they do not collide.
    laws : tuple of PairLaw
    n_bodies : int
        Number of bodies (the body index of ground).
    excluded : frozenset of (int, int)
        Body pairs that never collide (lower index first): bodies joined to each other.
    max_contacts : int
        Contacts kept per pair of shapes.
    merge_distance : float
        Contacts of one pair closer than this are one [m]; 0: a tenth of the smaller shape's
        bounding radius.
    """

    type_name: ClassVar[str] = "collisions"
    packed_per_run: ClassVar[bool] = True  # (viz3d.kernel.collisions: scratch and anchors in the packed data)
    dissipative: ClassVar[bool] = True
    #: Frame scalars this element adds (``scalars``), saved as trajectory fields (``viz3d.extras``).
    scalar_names: ClassVar[tuple[str, ...]] = ("collision/contacts", "collision/max_depth", "collision/normal_force")
    #: The live viewer's plot of this element: (title, frame scalar).
    live_plot: ClassVar[tuple[str, str]] = ("Shape contacts: normal force [N]", "collision/normal_force")
    smooth: ClassVar[bool] = False
    branches: ClassVar[bool] = True
    shapes: tuple[Shape, ...]
    groups: tuple[str, ...]
    pair_law: IntArray
    laws: tuple[PairLaw, ...]
    n_bodies: int
    excluded: frozenset = frozenset()
    max_contacts: int = 4
    merge_distance: float = 0.0
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __getstate__(self):  # Coal objects do not pickle: rebuilt on first use
        state = dict(self.__dict__)
        state["_cache"] = {}
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)

    # ------------------------------------------------------------------ the collision scene

    def _world(self) -> dict:
        """Coal geometries and requests, the bounding radii of moving shapes and the world boxes of
        ground shapes, built once."""
        w = self._cache
        if "geometry" in w:
            return w
        coal = _coal()
        w["geometry"] = [None if GEOMETRIES[s.kind] is None else GEOMETRIES[s.kind](s) for s in self.shapes]
        w["radius"] = np.array([s.bounding_radius for s in self.shapes])
        w["moving"] = np.array([s.body != self.n_bodies and s.kind != "plane" for s in self.shapes])
        w["box"] = {i: _world_box(s) for i, s in enumerate(self.shapes) if s.body == self.n_bodies and s.kind != "plane"}
        group = np.array([s.group for s in self.shapes], int)
        w["members"] = [np.flatnonzero(w["moving"] & (group == g)) for g in range(len(self.groups))]
        w["half"] = np.array([0.5 * s.size[1] if s.kind == "capsule" else 0.0 for s in self.shapes])
        w["core"] = np.array([s.size[0] if s.kind in ("sphere", "capsule") else np.nan for s in self.shapes])
        w["excluded"] = np.array(sorted(self.excluded), int).reshape(-1, 2)
        w["body"] = np.array([s.body for s in self.shapes], int)
        w["B_R"] = np.array([s.B_R for s in self.shapes], float)
        w["B_r"] = np.array([s.B_r for s in self.shapes], float)
        w["curvature"] = np.array([1.0 / s.size[0] if s.kind == "sphere" else 0.0 for s in self.shapes])
        w["all_pairs"] = {}
        w["planes"] = []
        for k, P in enumerate(self.shapes):  # per plane: the support points of the shapes it meets
            if P.kind != "plane":
                continue
            meets = [i for i, s in enumerate(self.shapes) if s.body != self.n_bodies and len(s.support)
                     and self.pair_law[s.group, P.group] >= 0]
            owner = np.concatenate([np.full(len(self.shapes[i].support), i) for i in meets]).astype(int) if meets else \
                np.zeros(0, int)
            local = np.vstack([self.shapes[i].support for i in meets]) if meets else np.zeros((0, 4))
            w["planes"].append((k, owner, local))
        for key, n in (("point", 1), ("mesh", MESH_CONTACTS)):
            req = coal.CollisionRequest()
            req.enable_contact, req.num_max_contacts = True, n
            w[key] = req
        w["patch"] = coal.ContactPatchRequest()
        w["table"] = pack_shapes(self.shapes, self.n_bodies)
        kinds = [s.kind for s in self.shapes]
        w["ours"] = np.array([[covered(a, b) for b in kinds] for a in kinds], bool).reshape(len(kinds), len(kinds))
        return w

    def coupled_bodies(self) -> IntArray:
        """Every pair of bodies whose shapes' groups collide (any of them may touch)."""
        body = np.array([s.body for s in self.shapes], int)
        group = np.array([s.group for s in self.shapes], int)
        ij = np.column_stack(np.nonzero(self.pair_law[group[:, None], group[None, :]] >= 0))
        return np.unique(body[ij], axis=0) if len(ij) else np.zeros((0, 2), int)

    def shape_poses(self, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
        """World origins (S, 3) and rotations (S, 3, 3) of every shape."""
        w = self._world()
        R_b, r_b = cfg.pose.R_WB[w["body"]], cfg.pose.W_r[w["body"]]
        return r_b + np.einsum("kij,kj->ki", R_b, w["B_r"]), R_b @ w["B_R"]

    # ------------------------------------------------------------------ detection

    def detect(self, cfg: Configuration) -> Touches:
        """Every contact between shapes of colliding groups at this configuration (``Touches``). The
        last configuration's answer is kept (by identity: a ``Configuration`` is never changed in
        place), so the forces, the ledger's power and the frame scalars of one evaluation detect once."""
        if not self.shapes:
            return _no_touches()
        last = self._cache.get("last")
        if last is not None and last[0] is cfg:
            return last[1]
        touches = self._detect(cfg)
        self._cache["last"] = (cfg, touches)
        return touches

    def _detect(self, cfg: Configuration) -> Touches:
        w = self._world()
        r, R = self.shape_poses(cfg)
        found: dict[tuple[int, int], list] = {}
        self._narrow(w, self.candidates(r, R), r, R, found)
        self._planes(found, r, R)
        return self._reduce(found)

    def candidates(self, r: FloatArray, R: FloatArray | None = None) -> list[tuple[int, int]]:
        """Broad phase: pairs of shapes (i, j) of colliding groups whose bounds overlap at shape origins
        ``r`` (S, 3): bounding spheres of moving shapes from a k-d tree per group, ground shapes' world
        boxes against the moving spheres' boxes; joined and same-body pairs left out. With the
        rotations ``R`` (S, 3, 3), pairs of spheres and capsules whose cores (point or segment plus
        radius) do not overlap are dropped as well: an exact test, vectorised."""
        from scipy.spatial import cKDTree

        w = self._world()
        rho, members = w["radius"], w["members"]
        trees = {}
        pairs: list[IntArray] = []  # (k, 2) blocks of candidate pairs
        G = len(self.groups)
        for g1 in range(G):
            for g2 in range(g1, G):
                if self.pair_law[g1, g2] < 0 or not len(members[g1]) or not len(members[g2]):
                    continue
                if len(members[g1]) * len(members[g2]) <= SMALL_GROUPS:
                    if (g1, g2) not in w["all_pairs"]:
                        w["all_pairs"][g1, g2] = _all_pairs(members[g1], members[g2], g1 == g2)
                    ij = w["all_pairs"][g1, g2]
                else:
                    for g in (g1, g2):
                        if g not in trees:
                            trees[g] = cKDTree(r[members[g]])
                    if g1 == g2:
                        local = trees[g1].query_pairs(2.0 * rho[members[g1]].max(), output_type="ndarray")
                        ij = members[g1][local]
                    else:
                        near = trees[g2].query_ball_point(r[members[g1]], rho[members[g1]] + rho[members[g2]].max())
                        ij = np.array([(i, members[g2][k]) for i, ks in zip(members[g1], near) for k in ks],
                                      int).reshape(-1, 2)
                if len(ij):
                    close = np.linalg.norm(r[ij[:, 0]] - r[ij[:, 1]], axis=1) <= rho[ij[:, 0]] + rho[ij[:, 1]]
                    pairs.append(ij[close])
        for k, (lo, hi) in w["box"].items():
            gk = self.shapes[k].group
            for g in range(G):
                if self.pair_law[g, gk] < 0 or not len(members[g]):
                    continue
                m = members[g]
                hit = np.all((r[m] + rho[m, None] >= lo) & (r[m] - rho[m, None] <= hi), axis=1)
                pairs.append(np.column_stack([m[hit], np.full(hit.sum(), k)]))
        ij = np.vstack(pairs).astype(int) if pairs else np.zeros((0, 2), int)
        ij = ij[self._allowed(ij)]
        if R is not None and len(ij):
            ij = ij[self._cores_overlap(ij, r, R)]
        return [(int(i), int(j)) for i, j in ij]

    def _cores_overlap(self, ij: IntArray, r: FloatArray, R: FloatArray) -> np.ndarray:
        """Mask of the pairs ``ij`` (k, 2) to keep: not both spheres or capsules, or cores overlapping."""
        w = self._world()
        axis = R[:, :, 2] * w["half"][:, None]
        i, j = ij[:, 0], ij[:, 1]
        d = segment_distance(r[i] - axis[i], r[i] + axis[i], r[j] - axis[j], r[j] + axis[j])
        return ~(d > w["core"][i] + w["core"][j])  # NaN core (other shapes): kept

    def _allowed(self, ij: IntArray) -> np.ndarray:
        """Mask of the pairs ``ij`` (k, 2) on two different bodies not joined to each other."""
        body = self._world()["body"][ij] if len(ij) else np.zeros((0, 2), int)
        ok = body[:, 0] != body[:, 1]
        ex = self._world()["excluded"]
        if len(ex) and len(ij):
            lo, hi = body.min(axis=1), body.max(axis=1)
            ok &= ~np.any((lo[:, None] == ex[:, 0]) & (hi[:, None] == ex[:, 1]), axis=1)
        return ok

    def _narrow(self, w: dict, pairs: list[tuple[int, int]], r: FloatArray, R: FloatArray, found: dict) -> None:
        """The raw contacts of the candidate ``pairs`` at shape origins ``r`` (S, 3) and rotations ``R``
        (S, 3, 3), filed by ``_book``: ours (``viz3d.contact.narrowphase``) for the pairs it covers,
        Coal's for the others."""
        ij = np.array(pairs, np.int64).reshape(-1, 2)
        mine = w["ours"][ij[:, 0], ij[:, 1]]
        if mine.any():
            self._ours(w, ij[mine], r, R, found)
        tf = {}
        for i, j in ij[~mine]:
            for k in (i, j):
                if k not in tf:
                    tf[k] = _coal().Transform3s(R[k], r[k])
            self._coal_pair(w, int(i), int(j), tf, found)

    def _ours(self, w: dict, ij: IntArray, r: FloatArray, R: FloatArray, found: dict) -> None:
        """Contacts of the pairs ``ij`` (k, 2) that ``narrowphase.covered`` says are ours."""
        rows = len(ij) * MESH_CONTACTS
        pair, point, n, depth = np.zeros(rows, np.int64), np.zeros((rows, 3)), np.zeros((rows, 3)), np.zeros(rows)
        m = contacts_of_pairs(w["table"], ij, np.ascontiguousarray(r), np.ascontiguousarray(R), pair, point, n, depth)
        for k in range(m):
            i, j = ij[pair[k]]
            self._book(found, int(i), int(j), point[k], n[k], float(depth[k]))

    def _coal_pair(self, w: dict, i: int, j: int, tf: dict, found: dict) -> None:
        """Coal's contacts of shapes i and j, filed by ``_book`` (triangle meshes: one per facet;
        otherwise the contact patch's points with their depths from the witness points)."""
        coal = _coal()
        si, sj = self.shapes[i], self.shapes[j]
        mesh = "mesh" in (si.kind, sj.kind)
        res = coal.CollisionResult()
        coal.collide(w["geometry"][i], tf[i], w["geometry"][j], tf[j], w["mesh" if mesh else "point"], res)
        if not res.isCollision():
            return
        contacts = res.getContacts()
        if mesh or si.kind in POINT_SHAPES or sj.kind in POINT_SHAPES:
            for c in contacts:  # depth from the witness points (Coal's own depth may carry EPA's 1e-11)
                p_i, p_j, n = np.asarray(c.getNearestPoint1()), np.asarray(c.getNearestPoint2()), np.asarray(c.normal)
                self._book(found, i, j, 0.5 * (p_i + p_j), n, float((p_i - p_j) @ n))
            return
        a, b, n, pts = self._patch(w, i, j, tf, res)
        if sj.kind in CURVED and len(pts) <= 1:  # try the patch from the other side
            res2 = coal.CollisionResult()
            coal.collide(w["geometry"][j], tf[j], w["geometry"][i], tf[i], w["point"], res2)
            if res2.isCollision():
                other = self._patch(w, j, i, tf, res2)
                a, b, n, pts = other if len(other[3]) > len(pts) else (a, b, n, pts)
        c = (res if a == i else res2).getContacts()[0]
        exact = float((np.asarray(c.getNearestPoint1()) - np.asarray(c.getNearestPoint2())) @ n)
        depths = [float((p_a - p_b) @ n) for p_a, p_b in pts]
        shift = max(depths) - exact  # the patch's points carry EPA's 1e-11; the witness points do not
        for (p_a, p_b), depth in zip(pts, depths):
            self._book(found, a, b, 0.5 * (p_a + p_b), n, depth - shift)

    def _patch(self, w: dict, i: int, j: int, tf: dict, res) -> tuple[int, int, FloatArray, list]:
        """``(i, j, n, [(witness on i, witness on j), ...])`` of a collision result's contact patch, with
        ``n`` the normal from i to j."""
        coal = _coal()
        c = res.getContacts()[0]
        n = np.asarray(c.normal, float)
        out = coal.ContactPatchResult(w["patch"])
        coal.computeContactPatch(w["geometry"][i], tf[i], w["geometry"][j], tf[j], res, w["patch"], out)
        if out.numContactPatches() == 0:
            return i, j, n, [(np.asarray(c.getNearestPoint1()), np.asarray(c.getNearestPoint2()))]
        patch = out.getContactPatch(0)
        return i, j, n, [(np.asarray(patch.getPointShape1(k)), np.asarray(patch.getPointShape2(k)))
                         for k in range(patch.size())]

    def _book(self, found: dict, i: int, j: int, pos, normal, depth: float) -> None:
        """File one raw contact under its pair, A the moving (or lower-index) shape, ``n`` from B to A."""
        if depth <= 0.0:
            return
        si, sj = self.shapes[i], self.shapes[j]
        n = -np.asarray(normal, float)  # Coal's normal points from shape i to j: j pushes i back along -normal
        if sj.body != self.n_bodies and (si.body == self.n_bodies or j < i):
            i, j, n = j, i, -n
        found.setdefault((i, j), []).append((np.asarray(pos, float), n, float(depth)))

    def _planes(self, found: dict, r: FloatArray, R: FloatArray) -> None:
        """Support points of moving shapes below ground planes of a colliding group."""
        for k, owner, local in self._world()["planes"]:
            if not len(owner):
                continue
            n = R[k] @ self.shapes[k].normal
            centres = r[owner] + np.einsum("kij,kj->ki", R[owner], local[:, :3])
            depth = local[:, 3] - (centres - r[k]) @ n
            for p in np.flatnonzero(depth > 0.0):
                found.setdefault((int(owner[p]), k), []).append((centres[p] - (local[p, 3] - 0.5 * depth[p]) * n, n,
                                                                  float(depth[p])))

    def _reduce(self, found: dict) -> Touches:
        """Per pair: the deepest contact and, among those on its face (``COPLANAR``), the farthest from
        the ones kept until ``max_contacts``, none closer than the merge distance to another."""
        rows = []
        for (i, j) in sorted(found):
            raw = sorted(found[(i, j)], key=lambda c: -c[2])
            merge = self.merge_distance or 0.1 * min(self._world()["radius"][i], self._world()["radius"][j])
            face = [c for c in raw if c[1] @ raw[0][1] >= np.cos(COPLANAR)]
            kept = [face[0]]
            rest = face[1:]
            while rest and len(kept) < self.max_contacts:
                gap = [min(np.linalg.norm(c[0] - k[0]) for k in kept) for c in rest]
                best = int(np.argmax(gap))
                if gap[best] <= merge:
                    break
                kept.append(rest.pop(best))
            law = self.pair_law[self.shapes[i].group, self.shapes[j].group]
            rows += [(i, j, law, p, n, a) for p, n, a in kept]
        if not rows:
            return _no_touches()
        shape = np.array([[r[0], r[1]] for r in rows], int)
        body = np.array([[self.shapes[i].body, self.shapes[j].body] for i, j in shape], int)
        return Touches(shape, body, np.array([r[2] for r in rows], int), np.array([r[3] for r in rows]),
                       np.array([r[4] for r in rows]), np.array([r[5] for r in rows]))

    # ------------------------------------------------------------------ forces

    def _stiffness_scale(self, tc: Touches, mask: np.ndarray, k: int) -> FloatArray | float:
        """Factor on the law's force for the contacts ``mask`` of pair law ``k``: 1, or Hertz's
        ``4/3 E* sqrt(R)`` of each pair of spheres (or sphere and plane; the law's stiffness is 1)."""
        pl = self.laws[k]
        if np.isnan(pl.hertz_modulus):
            return 1.0
        from viz3d.contact.parameters import hertz_stiffness

        return hertz_stiffness(pl.hertz_modulus, 1.0 / self._world()["curvature"][tc.shape[mask]].sum(axis=1))

    def evaluate(self, cfg: Configuration, touches: Touches | None = None,
                 memory: StickAnchors | FrozenTouches | None = None):
        """``(touches, alpha_dot (m,), F (m,), F_el (m,), f (m, 3), v_t (m, 3))``: indentation rates, normal
        forces, their elastic parts, the total force on A and the slip velocities; ``memory``: the stick
        anchors of bristle friction (None: every contact without deflection), or the contacts held
        fixed by ``frozen`` (with their anchors)."""
        if touches is None:  # the forces and the ledger's power of one evaluation: evaluated once
            last = self._cache.get("evaluated")
            if last is not None and last[0] is cfg and last[1] is memory:
                return last[2]
            if isinstance(memory, FrozenTouches):
                out = self._evaluate(cfg, memory.at(cfg), memory.anchors, memory.match, memory.active)
            else:
                out = self._evaluate(cfg, self.detect(cfg), memory)
            self._cache["evaluated"] = (cfg, memory, out)
            return out
        return self._evaluate(cfg, touches, memory)

    def _evaluate(self, cfg: Configuration, tc: Touches, memory: StickAnchors | None, match: IntArray | None = None,
                  active: np.ndarray | None = None):
        """``evaluate`` of the contacts ``tc``; ``match``: their entries in ``memory`` (None: found by
        ``match``); ``active``: an active set (``FrozenTouches``), None: the clipped forces."""
        m = tc.m
        alpha_dot, F, F_el = np.zeros(m), np.zeros(m), np.zeros(m)
        f, v_t = np.zeros((m, 3)), np.zeros((m, 3))
        if m == 0:
            return tc, alpha_dot, F, F_el, f, v_t
        W_r, W_v, W_w = cfg.pose.W_r, cfg.twist.W_v, cfg.twist.W_omega
        a, b = tc.body[:, 0], tc.body[:, 1]
        v_rel = (W_v[a] + cross(W_w[a], tc.point - W_r[a])) - (W_v[b] + cross(W_w[b], tc.point - W_r[b]))
        v_n = np.einsum("ki,ki->k", v_rel, tc.n)
        alpha_dot = -v_n
        v_t = v_rel - v_n[:, None] * tc.n
        f_t = np.zeros((m, 3))
        s = None  # the bristles' deflections, when some law needs them
        for k in np.unique(tc.law):
            on = tc.law == k
            pl = self.laws[k]
            scale = self._stiffness_scale(tc, on, k)
            touching = tc.depth[on] > 0.0  # (all found contacts; held ones may have separated)
            depth = np.where(touching, tc.depth[on], 0.0)
            F_el[on] = scale * pl.law.force(depth, np.zeros(on.sum()), None)
            if active is None:
                F[on] = np.where(touching, np.maximum(scale * pl.law.force(depth, alpha_dot[on], None)
                                                      + pl.damping * alpha_dot[on], 0.0), 0.0)
            else:
                d = tc.depth[on]  # (odd in the depth: an active contact pulls where it separates)
                F[on] = np.where(active[on], scale * np.sign(d) * pl.law.force_unclipped(np.abs(d), alpha_dot[on], None)
                                 + pl.damping * alpha_dot[on], 0.0)
            if pl.friction is not None and pl.friction.stateful:
                s = self.deflection(cfg, tc, memory, match) if s is None else s
                for i in np.flatnonzero(on & (F > 0.0)):
                    f_t[i] = pl.friction.vector(v_t[i], s[i], F[i])
            elif pl.friction is not None:
                speed = np.linalg.norm(v_t[on], axis=1)
                moving = speed > 0.0
                unit = np.divide(v_t[on], speed[:, None], out=np.zeros_like(v_t[on]), where=moving[:, None])
                f_t[on] = -np.asarray(pl.friction.force(speed, F[on]))[:, None] * unit
        f = F[:, None] * tc.n + f_t
        return tc, alpha_dot, F, F_el, f, v_t

    def wrench(self, cfg, memory: StickAnchors | None = None):
        tc, _, _, _, f, _ = self.evaluate(cfg, memory=memory)
        rows = cfg.pose.W_r.shape[0]
        W_F, W_tau = np.zeros((rows, 3)), np.zeros((rows, 3))
        if tc.m:
            a, b = tc.body[:, 0], tc.body[:, 1]
            np.add.at(W_F, a, f)
            np.add.at(W_F, b, -f)
            np.add.at(W_tau, a, cross(tc.point - cfg.pose.W_r[a], f))
            np.add.at(W_tau, b, -cross(tc.point - cfg.pose.W_r[b], f))
        return W_F, W_tau, None

    def potential_energy(self, cfg):
        """Elastic energy of the laws at the current depths [J] (not the bristles': their work is in
        ``nonconservative_power``)."""
        tc = self.detect(cfg)
        U = 0.0
        for k in np.unique(tc.law):
            on = tc.law == k
            U += float(np.sum(self._stiffness_scale(tc, on, k) * self.laws[k].law.elastic_energy(tc.depth[on], None)))
        return U

    @property
    def conservative(self) -> bool:
        return all(not pl.law.dissipative and pl.damping == 0.0 and pl.friction is None for pl in self.laws)

    def nonconservative_power(self, cfg, memory: StickAnchors | None = None):
        """Power of the dashpots, the rate laws' damping and friction on the bodies [W] (<= 0 but for
        the bristles' springs giving back what they stored)."""
        tc, alpha_dot, F, F_el, f, v_t = self.evaluate(cfg, memory=memory)
        if not tc.m:
            return 0.0
        f_t = f - F[:, None] * tc.n
        return float(-np.sum((F - F_el) * alpha_dot) + np.sum(np.einsum("ki,ki->k", f_t, v_t)))

    def contacts(self, cfg: Configuration, memory: StickAnchors | None = None) -> tuple[FloatArray, FloatArray]:
        """Contact points (m, 3) that carry a force, and the force on A there (m, 3), for display."""
        tc, _, F, _, f, _ = self.evaluate(cfg, memory=memory)
        on = F > 0.0
        return tc.point[on], f[on]

    # ------------------------------------------------------------------ stick anchors (bristle friction)

    @property
    def has_memory(self) -> bool:
        """Some pair law's friction keeps stick anchors (``bristle``)."""
        return any(pl.friction is not None and pl.friction.stateful for pl in self.laws)

    def match(self, cfg: Configuration, tc: Touches, memory: StickAnchors | None) -> IntArray:
        """Each contact's entry in ``memory`` (m,), -1 for a new contact: one of the same two shapes whose
        marks, carried by A and by B to ``cfg``, come within half the pair's merge distance of the
        contact point (nearest pairs first, each entry used once)."""
        out = -np.ones(tc.m, int)
        if memory is None or not memory.n or not tc.m:
            return out
        i, j = np.nonzero(np.all(tc.shape[:, None, :] == memory.shape[None, :, :], axis=2))
        if not len(i):
            return out
        w = self._world()
        body = w["body"][memory.shape[j]]  # (k, 2): A and B
        marks = cfg.pose.W_r[body] + np.einsum("kaij,kaj->kai", cfg.pose.R_WB[body], memory.mark[j])
        d = np.linalg.norm(tc.point[i][:, None, :] - marks, axis=2).min(axis=1)
        radius = w["radius"][tc.shape[i]].min(axis=1)
        near = d <= 0.5 * (self.merge_distance or 0.1 * radius)
        i, j, d = i[near], j[near], d[near]
        taken = np.zeros(memory.n, bool)
        for k in np.argsort(d, kind="stable"):
            if out[i[k]] < 0 and not taken[j[k]]:
                out[i[k]], taken[j[k]] = j[k], True
        return out

    def deflection(self, cfg: Configuration, tc: Touches, memory: StickAnchors | None,
                   match: IntArray | None = None) -> FloatArray:
        """The bristles' deflection of each contact, world [m], shape (m, 3): the contact point minus its
        anchor (fixed in B), without its normal part; zero for a contact without one (``match``)."""
        s = np.zeros((tc.m, 3))
        match = self.match(cfg, tc, memory) if match is None else match
        on = match >= 0
        if on.any():
            b = tc.body[on, 1]
            d = tc.point[on] - cfg.pose.W_r[b] - np.einsum("kij,kj->ki", cfg.pose.R_WB[b], memory.anchor[match[on]])
            n = tc.n[on]
            s[on] = d - np.einsum("ki,ki->k", d, n)[:, None] * n
        return s

    def memory_after_step(self, cfg: Configuration, memory: StickAnchors | None) -> StickAnchors:
        """The stick anchors after an accepted step ending at ``cfg``, from those of the step (None: the
        start of a run). A contact that goes on keeps its anchor, moved when its bristles carry more
        than ``mu_s F_n`` so that they carry ``alpha_stick mu_s F_n`` (``Bristle.anchor_update``, eq.
        3.49); a new contact plants one where it touches; one that ended is dropped."""
        tc, _, F, _, _, _ = self.evaluate(cfg)  # (normal forces: the same with any memory)
        laws = [self.laws[k].friction for k in tc.law]
        keep = np.array([law is not None and law.stateful for law in laws], bool)
        match = self.match(cfg, tc, memory)
        s = self.deflection(cfg, tc, memory, match)
        W_r, R = cfg.pose.W_r, cfg.pose.R_WB
        a, b = tc.body[:, 0], tc.body[:, 1]
        anchor = np.einsum("kji,kj->ki", R[b], tc.point - W_r[b])  # new contacts: planted at their point
        for i in np.flatnonzero(keep & (match >= 0)):
            s_i = s[i]
            kept = laws[i].anchor_update(s_i, F[i])
            anchor[i] = memory.anchor[match[i]] if kept is s_i else R[b[i]].T @ (tc.point[i] - kept - W_r[b[i]])
        mark = np.stack([np.einsum("kji,kj->ki", R[c], tc.point - W_r[c]) for c in (a, b)], axis=1)
        return StickAnchors(tc.shape[keep], anchor[keep], mark[keep])

    # ------------------------------------------------------------------ contacts held fixed (implicit steps)

    def frozen(self, cfg: Configuration, memory: StickAnchors | None) -> FrozenTouches:
        """The contacts at ``cfg`` held fixed (``FrozenTouches``), with their anchors and matches in the
        step's ``memory``: the forces near ``cfg`` as a smooth function of the configuration."""
        tc = self.detect(cfg)
        W_r, R = cfg.pose.W_r, cfg.pose.R_WB
        a, b = tc.body[:, 0], tc.body[:, 1]
        half = 0.5 * tc.depth[:, None] * tc.n
        A_r = np.einsum("kji,kj->ki", R[a], tc.point - half - W_r[a])
        B_r = np.einsum("kji,kj->ki", R[b], tc.point + half - W_r[b])
        B_n = np.einsum("kji,kj->ki", R[b], tc.n)
        match = self.match(cfg, tc, memory) if self.has_memory else -np.ones(tc.m, int)
        F = self._evaluate(cfg, tc, memory, match)[2]
        return FrozenTouches(tc.shape, tc.body, tc.law, A_r, B_r, B_n, match, F > 0.0, memory)

    def frozen_change(self, cfg: Configuration, frozen: FrozenTouches, tol: float = 0.0) -> str:
        """What differs at ``cfg`` between the contacts found and those held in ``frozen`` ('' if
        nothing): the pairs of shapes whose number of pushing contacts differs, else the pair whose
        depths differ most (a contact moved to another face, or to other witness points), if by more
        than ``tol`` [m]."""
        live, held = self.detect(cfg), frozen.at(cfg)
        live_on = self.evaluate(cfg, live)[2] > 0.0
        held_on = frozen.active  # (an active contact that separated pulls: it ended)
        pairs = sorted({tuple(p) for p in live.shape[live_on]} | {tuple(p) for p in held.shape[held_on]})
        if not pairs:
            return ""
        count = [(int(np.all(live.shape[live_on] == p, axis=1).sum()),
                  int(np.all(held.shape[held_on] == p, axis=1).sum())) for p in pairs]
        name = [f"{self.shapes[i].name!r}-{self.shapes[j].name!r}" for i, j in pairs]
        changed = [f"{n} {'began' if h == 0 else 'ended' if c == 0 else f'{h} -> {c} contacts'}"
                   for n, (c, h) in zip(name, count) if c != h]
        if changed:
            return "contacts " + ", ".join(changed)
        gap = [abs(live.depth[live_on & np.all(live.shape == p, axis=1)].sum()
                   - held.depth[held_on & np.all(held.shape == p, axis=1)].sum()) for p in pairs]
        k = int(np.argmax(gap))
        return f"contacts {name[k]} moved (depths differ by {gap[k]:.2e} m)" if gap[k] > tol else ""

    def compiled(self, pack):
        """The element packed for the compiled kernel (``viz3d.kernel.collisions``, through the packer:
        the kernel is a layer above)."""
        return pack.collision_items(self)

    def scalars(self, cfg: Configuration) -> dict[str, float]:
        """Frame scalars: number of contacts, deepest penetration [m], total normal force [N]."""
        tc, _, F, _, _, _ = self.evaluate(cfg)
        return {"collision/contacts": float(tc.m), "collision/max_depth": float(tc.depth.max(initial=0.0)),
                "collision/normal_force": float(F.sum())}

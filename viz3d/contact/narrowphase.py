"""Our narrow phase: compiled contact tests of a sphere, capsule or convex polytope against a triangle
mesh, giving the raw contacts Coal gives (``viz3d.contact.collision``).

A triangle mesh is a triangle soup, as in Coal: a shape gets one contact per facet it touches, each
the minimum translation of the shape out of that facet alone (a flat convex set), with

    point = middle of the two witness points,   n = unit normal from shape i to shape j,
    depth = (p_i - p_j) . n > 0                 (p_i on i, p_j on j).

Spheres and capsules are a *core* (a point, a segment along the shape's z axis of length ``h``)
swept by their radius ``r``, as Coal treats them. Per facet:

* core apart from the facet: the closest points of point or segment and triangle (Ericson,
  Real-Time Collision Detection, secs. 5.1.5 and 5.1.9), ``depth = r - distance``, ``n`` along
  them: exact (Coal's sphere-triangle test is this one; its capsule-triangle GJK converges to it);
* core through the facet, and convex polytopes: separating axes. The minimum translation of two
  convex polytopes is the smallest overlap over the normals of the faces of their Minkowski
  difference, and those are among the face normals of each (the facet's two sides, the polytope's
  faces) and the cross products of an edge of each; any other unit axis overlaps more, so the
  smallest overlap over these candidates is exact (Coal's EPA converges to it). Edge pairs within
  ``PARALLEL`` of parallel are skipped (their axis would carry eps / sin of error; the overlap
  along a skipped axis differs from a tested neighbour's by ``L sin``). Of axes overlapping within
  ``FEATURE L`` of each other the first is kept: facet normal, then the polytope's faces, then edges.

Witness points. With ``n`` fixed, the contact features are the vertices of the core within
``FEATURE L`` of its extreme along ``+n`` and those of the facet within it of the extreme along
``-n`` (``L``: the shape's bounding radius). A vertex feature makes the witnesses unique (the vertex
and its projection along ``n``), so does a pair of crossing edges (their closest points). Otherwise
they are not (a face or edge lying on the facet, an edge along an edge), and **we take the mean of
the end points of the overlap's boundary pieces**: each edge of the lower-dimensional feature (of
both, when both are faces) clipped to the other feature's prism along ``n``; two parallel edges give
the middle of their common stretch. It is a point of the overlap of the two features, deterministic
and continuous while the features do not change (not the overlap's area centroid).

A static bounding-volume hierarchy per mesh (an axis-aligned box tree, median split along the
longest axis of the facets' centres, one facet per leaf), built once by ``pack_shapes`` and stored
depth first with skip indices, is walked without a stack, so a shape visits only the facets near its
box. Contacts come out in that walk's order; at most ``out_depth.shape[0]`` per pair (Coal stops at
its request's ``num_max_contacts`` likewise).

Everything compiled here allocates nothing (``viz3d.compiled``: no NRT); vectors are tuples.
Pairs not ``covered`` (convex-convex, boxes, cylinders, meshes against meshes) stay Coal's.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from viz3d.compiled import entry, inline, jit

#: Shape kinds as integer codes (others: ``OTHER``).
SPHERE, CAPSULE, CONVEX, MESH, OTHER = 0, 1, 2, 3, -1
CODES = {"sphere": SPHERE, "capsule": CAPSULE, "convex": CONVEX, "mesh": MESH}
#: Contacts per pair that involves a triangle mesh (one per facet touched), as asked of Coal.
MESH_CONTACTS = 32
#: Relative tolerance (of the shape's bounding radius) of the contact features and of ties between axes.
FEATURE = 1e-9
#: Edge pairs with sin(angle) below this give no separating axis.
PARALLEL = 1e-8
#: Faces of a polytope within this of the contact normal (1 - cos) are its contact face.
FACING = 1e-6
#: Kinds against a mesh that ``pair_contacts`` handles.
_ON_MESH = ("sphere", "capsule", "convex")


class ShapeTable(NamedTuple):
    """Collision shapes packed for compiled code (S shapes; pools with offsets per shape).

    kind : (S,) int64, ``CODES`` (``OTHER``: not handled here); body : (S,) int64;
    radius : (S,) sphere and capsule radius [m]; half : (S,) capsule half length [m];
    scale : (S,) bounding radius about the shape origin [m];
    v_off : (S + 1,) int64 into ``vertices`` (V, 3), shape axes [m] (convex hulls, meshes);
    f_off : (S + 1,) into ``faces`` (F, 3) int64 (indices into the shape's own vertices) and
    ``normals`` (F, 3) unit, ``(b - a) x (c - a)`` (convex: outward);
    e_off : (S + 1,) into ``edges`` (E, 2) int64, each edge of a convex hull's triangles once;
    n_off : (S + 1,) into the meshes' box trees, depth first: ``node_lo``, ``node_hi`` (N, 3) [m],
    ``node_skip`` (N,) int64 (the shape's node after this one's subtree, local), ``node_facet``
    (N,) int64 (a leaf's facet, local; -1 inner);
    n_bodies : int, the body index of ground.
    """

    kind: np.ndarray
    body: np.ndarray
    radius: np.ndarray
    half: np.ndarray
    scale: np.ndarray
    v_off: np.ndarray
    vertices: np.ndarray
    f_off: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    e_off: np.ndarray
    edges: np.ndarray
    n_off: np.ndarray
    node_lo: np.ndarray
    node_hi: np.ndarray
    node_skip: np.ndarray
    node_facet: np.ndarray
    n_bodies: int


def covered(kind_i: str, kind_j: str) -> bool:
    """Whether ``pair_contacts`` handles shapes of these kinds (either order)."""
    return (kind_i == "mesh" and kind_j in _ON_MESH) or (kind_j == "mesh" and kind_i in _ON_MESH)


# --- packing (Python, once) ---------------------------------------------------------------------------


def box_tree(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Box tree of facets with boxes ``lo``, ``hi`` (F, 3): ``(node_lo, node_hi, skip, facet)``,
    2F - 1 nodes depth first (``ShapeTable``); median split along the longest spread of the centres."""
    F = len(lo)
    n = max(2 * F - 1, 0)
    node_lo, node_hi = np.zeros((n, 3)), np.zeros((n, 3))
    skip, facet = np.zeros(n, np.int64), -np.ones(n, np.int64)
    centre = 0.5 * (lo + hi)
    k = 0

    def build(idx: np.ndarray) -> None:
        nonlocal k
        me = k
        k += 1
        node_lo[me], node_hi[me] = lo[idx].min(axis=0), hi[idx].max(axis=0)
        if len(idx) == 1:
            facet[me] = idx[0]
        else:
            c = centre[idx]
            axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
            idx = idx[np.argsort(c[:, axis], kind="stable")]
            build(idx[: len(idx) // 2])
            build(idx[len(idx) // 2:])
        skip[me] = k

    if F:
        build(np.arange(F))
    return node_lo, node_hi, skip, facet


def _edges(faces: np.ndarray) -> np.ndarray:
    """Each edge of the triangles ``faces`` (f, 3) once (e, 2), lower index first."""
    if not len(faces):
        return np.zeros((0, 2), np.int64)
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0).astype(np.int64)


def _normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    if not len(faces):
        return np.zeros((0, 3))
    v = vertices[faces]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n / np.linalg.norm(n, axis=1)[:, None]


def pack_shapes(shapes: tuple, n_bodies: int) -> ShapeTable:
    """The ``ShapeTable`` of ``shapes`` (``Collisions.shapes``, ``viz3d.contact.collision.Shape``);
    ``n_bodies``: ground's body index."""
    kind = np.array([CODES.get(s.kind, OTHER) for s in shapes], np.int64)
    radius = np.array([s.size[0] if s.kind in ("sphere", "capsule") else 0.0 for s in shapes])
    half = np.array([0.5 * s.size[1] if s.kind == "capsule" else 0.0 for s in shapes])
    scale = np.array([s.bounding_radius if s.kind != "plane" else 0.0 for s in shapes])
    pooled = [(np.asarray(s.vertices, float).reshape(-1, 3), np.asarray(s.faces, np.int64).reshape(-1, 3))
              if s.kind in ("convex", "mesh") else (np.zeros((0, 3)), np.zeros((0, 3), np.int64)) for s in shapes]
    edges = [_edges(f) if s.kind == "convex" else np.zeros((0, 2), np.int64) for s, (_, f) in zip(shapes, pooled)]
    trees = []
    for s, (v, f) in zip(shapes, pooled):
        if s.kind == "mesh" and len(f):
            tri = v[f]
            trees.append(box_tree(tri.min(axis=1), tri.max(axis=1)))
        else:
            trees.append((np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)))

    def offsets(sizes):
        return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)

    def stack(parts, shape, dtype=float):
        return np.ascontiguousarray(np.concatenate(parts).astype(dtype)) if parts else np.zeros(shape, dtype)

    return ShapeTable(
        kind=kind, body=np.array([s.body for s in shapes], np.int64), radius=radius, half=half, scale=scale,
        v_off=offsets([len(v) for v, _ in pooled]), vertices=stack([v for v, _ in pooled], (0, 3)),
        f_off=offsets([len(f) for _, f in pooled]), faces=stack([f for _, f in pooled], (0, 3), np.int64),
        normals=stack([_normals(v, f) for v, f in pooled], (0, 3)),
        e_off=offsets([len(e) for e in edges]), edges=stack(edges, (0, 2), np.int64),
        n_off=offsets([len(t[2]) for t in trees]), node_lo=stack([t[0] for t in trees], (0, 3)),
        node_hi=stack([t[1] for t in trees], (0, 3)), node_skip=stack([t[2] for t in trees], (0,), np.int64),
        node_facet=stack([t[3] for t in trees], (0,), np.int64), n_bodies=int(n_bodies))


# --- vectors as tuples ----------------------------------------------------------------------------------


@inline
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@inline
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@inline
def _axpy(a, s, b):
    """``a + s b``."""
    return (a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2])


@inline
def _scale(s, a):
    return (s * a[0], s * a[1], s * a[2])


@inline
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@inline
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@inline
def _row(A, k):
    return (A[k, 0], A[k, 1], A[k, 2])


@inline
def _mv(M, x):
    """``M x`` with ``M`` a tuple of rows."""
    return (_dot(M[0], x), _dot(M[1], x), _dot(M[2], x))


@inline
def _tmv(M, x):
    """``M^T x`` with ``M`` a tuple of rows."""
    return _axpy(_axpy(_scale(x[0], M[0]), x[1], M[1]), x[2], M[2])


@inline
def _relative(r_a, R_a, r_m, R_m):
    """Pose of shape a in shape m's axes: rows of ``R_m^T R_a`` and ``R_m^T (r_a - r_m)``."""
    rows = ((R_m[0, 0], R_m[1, 0], R_m[2, 0]), (R_m[0, 1], R_m[1, 1], R_m[2, 1]), (R_m[0, 2], R_m[1, 2], R_m[2, 2]))
    c0, c1, c2 = (R_a[0, 0], R_a[1, 0], R_a[2, 0]), (R_a[0, 1], R_a[1, 1], R_a[2, 1]), (R_a[0, 2], R_a[1, 2], R_a[2, 2])
    M = ((_dot(rows[0], c0), _dot(rows[0], c1), _dot(rows[0], c2)),
         (_dot(rows[1], c0), _dot(rows[1], c1), _dot(rows[1], c2)),
         (_dot(rows[2], c0), _dot(rows[2], c1), _dot(rows[2], c2)))
    return M, _mv(rows, (r_a[0] - r_m[0], r_a[1] - r_m[1], r_a[2] - r_m[2]))


# --- closest points -------------------------------------------------------------------------------------


@jit
def point_triangle(p, a, b, c):
    """Closest point of triangle abc to ``p`` (Ericson sec. 5.1.5, by Voronoi regions)."""
    ab, ac, ap = _sub(b, a), _sub(c, a), _sub(p, a)
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return a
    bp = _sub(p, b)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return _axpy(a, d1 / (d1 - d3), ab)
    cp = _sub(p, c)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return _axpy(a, d2 / (d2 - d6), ac)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        return _axpy(b, (d4 - d3) / ((d4 - d3) + (d5 - d6)), _sub(c, b))
    denom = 1.0 / (va + vb + vc)
    return _axpy(_axpy(a, vb * denom, ab), vc * denom, ac)


@jit
def segment_segment(p0, p1, q0, q1):
    """Closest points of segments p0-p1 and q0-q1 (Ericson sec. 5.1.9), zero lengths included."""
    d1, d2, r = _sub(p1, p0), _sub(q1, q0), _sub(p0, q0)
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    tiny = 1e-300
    if a <= tiny and e <= tiny:
        return p0, q0
    if a <= tiny:
        return p0, _axpy(q0, min(max(f / e, 0.0), 1.0), d2)
    c = _dot(d1, r)
    if e <= tiny:
        return _axpy(p0, min(max(-c / a, 0.0), 1.0), d1), q0
    b = _dot(d1, d2)
    den = a * e - b * b
    s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > tiny * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t, s = 0.0, min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    return _axpy(p0, s, d1), _axpy(q0, t, d2)


@jit
def segment_triangle(p0, p1, w0, w1, w2, nt):
    """``(distance, x on p0-p1, y on triangle w0 w1 w2)``: closest points; distance 0 where the segment
    meets the triangle (``nt``: its unit normal)."""
    s0, s1 = _dot(nt, _sub(p0, w0)), _dot(nt, _sub(p1, w0))
    if s0 * s1 <= 0.0 and s0 != s1:  # crosses the plane: inside the triangle?
        x = _axpy(p0, s0 / (s0 - s1), _sub(p1, p0))
        if _inside(x, w0, w1, w2, nt):
            return 0.0, x, x
    y = point_triangle(p0, w0, w1, w2)
    best, bx, by = _dot(_sub(p0, y), _sub(p0, y)), p0, y
    y = point_triangle(p1, w0, w1, w2)
    d = _dot(_sub(p1, y), _sub(p1, y))
    if d < best:
        best, bx, by = d, p1, y
    for k in range(3):
        a, b = (w0, w1) if k == 0 else ((w1, w2) if k == 1 else (w2, w0))
        x, y = segment_segment(p0, p1, a, b)
        d = _dot(_sub(x, y), _sub(x, y))
        if d < best:
            best, bx, by = d, x, y
    return np.sqrt(best), bx, by


@inline
def _inside(x, w0, w1, w2, nt):
    """Whether ``x`` (in the triangle's plane) lies in triangle w0 w1 w2 (boundary included)."""
    return (_dot(_cross(_sub(w1, w0), _sub(x, w0)), nt) >= 0.0 and _dot(_cross(_sub(w2, w1), _sub(x, w1)), nt) >= 0.0
            and _dot(_cross(_sub(w0, w2), _sub(x, w2)), nt) >= 0.0)


# --- the shape's core in the mesh's axes ----------------------------------------------------------------


@inline
def _n_core(tb, a):
    """Vertices of shape a's core: a sphere's centre, a capsule's segment ends, a hull's vertices."""
    k = tb.kind[a]
    if k == CONVEX:
        return tb.v_off[a + 1] - tb.v_off[a]
    return 2 if k == CAPSULE else 1


@inline
def _core(tb, a, k, M, t, p0, p1):
    """Vertex k of shape a's core in the mesh's axes (``M``, ``t``: the shape's pose there)."""
    if tb.kind[a] == CONVEX:
        return _add(_mv(M, _row(tb.vertices, tb.v_off[a] + k)), t)
    return p0 if k == 0 else p1


@inline
def _n_edges(tb, a):
    k = tb.kind[a]
    if k == CONVEX:
        return tb.e_off[a + 1] - tb.e_off[a]
    return 1 if k == CAPSULE else 0


@inline
def _edge(tb, a, e):
    """Vertex indices of edge e of shape a's core."""
    if tb.kind[a] == CONVEX:
        return tb.edges[tb.e_off[a] + e, 0], tb.edges[tb.e_off[a] + e, 1]
    return 0, 1


@jit
def _core_range(tb, a, M, t, p0, p1, u):
    """Lowest and highest ``u . x`` over the core's vertices."""
    lo, hi = np.inf, -np.inf
    if tb.kind[a] == CONVEX:
        ua, off = _tmv(M, u), _dot(u, t)
        for k in range(tb.v_off[a], tb.v_off[a + 1]):
            s = _dot(ua, _row(tb.vertices, k)) + off
            lo, hi = min(lo, s), max(hi, s)
        return lo, hi
    s0, s1 = _dot(u, p0), _dot(u, p1)
    return min(s0, s1), max(s0, s1)


@jit
def _overlap(tb, a, M, t, p0, p1, w0, w1, w2, u):
    """``(overlap, n)``: the smaller translation of the core out of the triangle along ``u`` or
    ``-u``, and that direction (from the core towards the triangle); negative: ``u`` separates."""
    lo_a, hi_a = _core_range(tb, a, M, t, p0, p1, u)
    s0, s1, s2 = _dot(u, w0), _dot(u, w1), _dot(u, w2)
    lo_b, hi_b = min(s0, min(s1, s2)), max(s0, max(s1, s2))
    plus, minus = hi_a - lo_b, hi_b - lo_a
    if plus <= minus:
        return plus, u
    return minus, _scale(-1.0, u)


@jit
def _separating(tb, a, M, t, p0, p1, w0, w1, w2, nt, tol):
    """``(depth, n)`` of the core against the triangle by separating axes (module docstring);
    ``depth < 0``: apart."""
    best, bn = _overlap(tb, a, M, t, p0, p1, w0, w1, w2, nt)
    if best < 0.0:
        return best, bn
    if tb.kind[a] == CONVEX:
        for f in range(tb.f_off[a], tb.f_off[a + 1]):
            d, n = _overlap(tb, a, M, t, p0, p1, w0, w1, w2, _mv(M, _row(tb.normals, f)))
            if d < best - tol:
                best, bn = d, n
                if best < 0.0:
                    return best, bn
    for e in range(_n_edges(tb, a)):
        i0, i1 = _edge(tb, a, e)
        de = _sub(_core(tb, a, i1, M, t, p0, p1), _core(tb, a, i0, M, t, p0, p1))
        for k in range(3):
            te = _sub(w1, w0) if k == 0 else (_sub(w2, w1) if k == 1 else _sub(w0, w2))
            u = _cross(de, te)
            uu = _dot(u, u)
            if uu <= PARALLEL * PARALLEL * _dot(de, de) * _dot(te, te) or uu == 0.0:
                continue
            d, n = _overlap(tb, a, M, t, p0, p1, w0, w1, w2, _scale(1.0 / np.sqrt(uu), u))
            if d < best - tol:
                best, bn = d, n
                if best < 0.0:
                    return best, bn
    return best, bn


# --- witness points -------------------------------------------------------------------------------------


@jit
def _clip_triangle(x0, x1, w0, w1, w2, nt, tol):
    """``(found, y0, y1)``: the part of segment x0-x1 in the prism of triangle w0 w1 w2 along its
    normal ``nt`` (widened by ``tol``)."""
    s_lo, s_hi = 0.0, 1.0
    for k in range(3):
        a, b = (w0, w1) if k == 0 else ((w1, w2) if k == 1 else (w2, w0))
        m = _cross(_sub(b, a), nt)
        slack = tol * np.sqrt(_dot(m, m))
        g0, g1 = _dot(m, _sub(x0, a)) - slack, _dot(m, _sub(x1, a)) - slack
        s_lo, s_hi = _cut(g0, g1, s_lo, s_hi)
    d = _sub(x1, x0)
    return s_lo <= s_hi, _axpy(x0, s_lo, d), _axpy(x0, s_hi, d)


@jit
def _clip_face(tb, a, M, t, x0, x1, n, top, tol):
    """``(found, y0, y1)``: the part of segment x0-x1, moved along ``n`` onto the plane ``n . x = top``
    (the convex shape a's contact face), inside shape a (all of its faces' planes, widened by ``tol``,
    but those of the contact face)."""
    y0, y1 = _axpy(x0, top - _dot(n, x0), n), _axpy(x1, top - _dot(n, x1), n)
    s_lo, s_hi = 0.0, 1.0
    for f in range(tb.f_off[a], tb.f_off[a + 1]):
        m = _mv(M, _row(tb.normals, f))
        if _dot(m, n) >= 1.0 - FACING:
            continue
        v = _core(tb, a, tb.faces[f, 0], M, t, x0, x0)
        s_lo, s_hi = _cut(_dot(m, _sub(y0, v)) - tol, _dot(m, _sub(y1, v)) - tol, s_lo, s_hi)
    d = _sub(y1, y0)
    return s_lo <= s_hi, _axpy(y0, s_lo, d), _axpy(y0, s_hi, d)


@inline
def _cut(g0, g1, s_lo, s_hi):
    """Narrow ``[s_lo, s_hi]`` to where ``g0 + s (g1 - g0) <= 0``."""
    if g0 > 0.0 and g1 > 0.0:
        return 1.0, 0.0
    if g0 > 0.0:
        return max(s_lo, g0 / (g0 - g1)), s_hi
    if g1 > 0.0:
        return s_lo, min(s_hi, g0 / (g0 - g1))
    return s_lo, s_hi


@jit
def _two_edges(a0, a1, b0, b1, n):
    """A point where edges a0-a1 and b0-b1 (across ``n``) meet seen along ``n``: their crossing, or
    the middle of their common stretch when parallel."""
    da, db = _sub(a1, a0), _sub(b1, b0)
    den = _dot(_cross(da, db), n)
    if abs(den) > PARALLEL * np.sqrt(_dot(da, da) * _dot(db, db)):
        s = -_dot(_cross(_sub(a0, b0), db), n) / den
        return _axpy(a0, min(max(s, 0.0), 1.0), da)
    la = np.sqrt(_dot(da, da))
    if la == 0.0:
        return a0
    e = _scale(1.0 / la, da)
    sb0, sb1 = _dot(_sub(b0, a0), e), _dot(_sub(b1, a0), e)
    lo, hi = max(0.0, min(sb0, sb1)), min(la, max(sb0, sb1))
    return _axpy(a0, 0.5 * (lo + hi), e)


@jit
def _witness(tb, a, M, t, p0, p1, w0, w1, w2, nt, n, tol):
    """Witness points ``(x on the core, y on the triangle)`` for normal ``n`` (module docstring)."""
    top = -np.inf
    for k in range(_n_core(tb, a)):
        top = max(top, _dot(n, _core(tb, a, k, M, t, p0, p1)))
    s0, s1, s2 = _dot(n, w0), _dot(n, w1), _dot(n, w2)
    bottom = min(s0, min(s1, s2))
    gap = top - bottom
    n_a, first = 0, 0
    for k in range(_n_core(tb, a)):
        if _dot(n, _core(tb, a, k, M, t, p0, p1)) >= top - tol:
            if n_a == 0:
                first = k
            n_a += 1
    on0, on1, on2 = s0 <= bottom + tol, s1 <= bottom + tol, s2 <= bottom + tol
    n_b = int(on0) + int(on1) + int(on2)
    if n_a == 1:
        x = _core(tb, a, first, M, t, p0, p1)
        return x, _axpy(x, -gap, n)
    if n_b == 1:
        y = w0 if on0 else (w1 if on1 else w2)
        return _axpy(y, gap, n), y
    if n_a == 2 and n_b == 2:
        second = first
        for k in range(first + 1, _n_core(tb, a)):
            if _dot(n, _core(tb, a, k, M, t, p0, p1)) >= top - tol:
                second = k
        b0, b1 = (w1, w2) if not on0 else ((w0, w1) if on1 else (w2, w0))
        q = _two_edges(_core(tb, a, first, M, t, p0, p1), _core(tb, a, second, M, t, p0, p1), b0, b1, n)
    else:
        q = _overlap_mean(tb, a, M, t, p0, p1, w0, w1, w2, nt, n, top, tol, n_a, n_b, on0, on1, on2)
    return _axpy(q, top - _dot(n, q), n), _axpy(q, bottom - _dot(n, q), n)


@jit
def _overlap_mean(tb, a, M, t, p0, p1, w0, w1, w2, nt, n, top, tol, n_a, n_b, on0, on1, on2):
    """Mean of the end points of the overlap's boundary pieces of the core's contact feature (``n_a``
    vertices) and the triangle's (``n_b``), one of them a face (module docstring)."""
    total, count = (0.0, 0.0, 0.0), 0
    if n_b == 3:  # the core's feature edges, clipped to the triangle
        for e in range(_n_edges(tb, a)):
            i0, i1 = _edge(tb, a, e)
            x0, x1 = _core(tb, a, i0, M, t, p0, p1), _core(tb, a, i1, M, t, p0, p1)
            if _dot(n, x0) < top - tol or _dot(n, x1) < top - tol:
                continue
            ok, y0, y1 = _clip_triangle(x0, x1, w0, w1, w2, nt, tol)
            if ok:
                total, count = _add(total, _add(y0, y1)), count + 2
    if n_a >= 3:  # the triangle's feature edges, clipped to the core's face
        for k in range(3):
            c0, c1 = (on0, on1) if k == 0 else ((on1, on2) if k == 1 else (on2, on0))
            if not (c0 and c1):
                continue
            x0, x1 = (w0, w1) if k == 0 else ((w1, w2) if k == 1 else (w2, w0))
            ok, y0, y1 = _clip_face(tb, a, M, t, x0, x1, n, top, tol)
            if ok:
                total, count = _add(total, _add(y0, y1)), count + 2
    if count == 0:  # round-off left nothing: the mean of the core's feature
        for k in range(_n_core(tb, a)):
            x = _core(tb, a, k, M, t, p0, p1)
            if _dot(n, x) >= top - tol:
                total, count = _add(total, x), count + 1
    return _scale(1.0 / count, total)


# --- pair tests -----------------------------------------------------------------------------------------


@jit
def _facet_contact(tb, a, M, t, p0, p1, w0, w1, w2, nt, tol):
    """``(depth, point, n)`` of shape a (core + radius) on one triangle, mesh axes, ``n`` from a to
    the triangle; depth <= 0: no contact."""
    r = tb.radius[a]
    if tb.kind[a] != CONVEX:
        if tb.kind[a] == SPHERE:
            y = point_triangle(p0, w0, w1, w2)
            dist, x = np.sqrt(_dot(_sub(y, p0), _sub(y, p0))), p0
        else:
            dist, x, y = segment_triangle(p0, p1, w0, w1, w2, nt)
        if dist >= r:
            return 0.0, x, nt
        if dist > 0.0:
            n = _scale(1.0 / dist, _sub(y, x))
            x, y = _witness(tb, a, M, t, p0, p1, w0, w1, w2, nt, n, tol)
            return r - dist, _scale(0.5, _add(_axpy(x, r, n), y)), n
    depth, n = _separating(tb, a, M, t, p0, p1, w0, w1, w2, nt, tol)
    if depth + r <= 0.0:
        return 0.0, p0, n
    x, y = _witness(tb, a, M, t, p0, p1, w0, w1, w2, nt, n, tol)
    return depth + r, _scale(0.5, _add(_axpy(x, r, n), y)), n


@jit
def _on_mesh(tb, a, m, r_a, R_a, r_m, R_m, sign, out_point, out_n, out_depth, out_facet, facets):
    """Contacts of shape a (sphere, capsule, convex) with mesh m, written with normals ``sign`` times
    from a to m; ``facets``: also write each contact's facet into ``out_facet``."""
    M, t = _relative(r_a, R_a, r_m, R_m)
    h, r = tb.half[a], tb.radius[a]
    axis = (M[0][2], M[1][2], M[2][2])
    p0, p1 = _axpy(t, -h, axis), _axpy(t, h, axis)
    lo = (min(p0[0], p1[0]) - r, min(p0[1], p1[1]) - r, min(p0[2], p1[2]) - r)
    hi = (max(p0[0], p1[0]) + r, max(p0[1], p1[1]) + r, max(p0[2], p1[2]) + r)
    if tb.kind[a] == CONVEX:
        lo, hi = (np.inf, np.inf, np.inf), (-np.inf, -np.inf, -np.inf)
        for k in range(_n_core(tb, a)):
            x = _core(tb, a, k, M, t, p0, p1)
            lo = (min(lo[0], x[0]), min(lo[1], x[1]), min(lo[2], x[2]))
            hi = (max(hi[0], x[0]), max(hi[1], x[1]), max(hi[2], x[2]))
    tol = FEATURE * (tb.scale[a] + r)
    v0, f0, n0, n1 = tb.v_off[m], tb.f_off[m], tb.n_off[m], tb.n_off[m + 1]
    cap, count, k = out_depth.shape[0], 0, n0
    rows = ((R_m[0, 0], R_m[0, 1], R_m[0, 2]), (R_m[1, 0], R_m[1, 1], R_m[1, 2]), (R_m[2, 0], R_m[2, 1], R_m[2, 2]))
    while k < n1 and count < cap:
        if (lo[0] > tb.node_hi[k, 0] or lo[1] > tb.node_hi[k, 1] or lo[2] > tb.node_hi[k, 2]
                or hi[0] < tb.node_lo[k, 0] or hi[1] < tb.node_lo[k, 1] or hi[2] < tb.node_lo[k, 2]):
            k = n0 + tb.node_skip[k]
            continue
        f = tb.node_facet[k]
        k += 1
        if f < 0:
            continue
        g = f0 + f
        w0, w1, w2 = (_row(tb.vertices, v0 + tb.faces[g, 0]), _row(tb.vertices, v0 + tb.faces[g, 1]),
                      _row(tb.vertices, v0 + tb.faces[g, 2]))
        depth, p, n = _facet_contact(tb, a, M, t, p0, p1, w0, w1, w2, _row(tb.normals, g), tol)
        if depth > 0.0:
            pw, nw = _mv(rows, p), _mv(rows, n)
            for c in range(3):
                out_point[count, c] = pw[c] + r_m[c]
                out_n[count, c] = sign * nw[c]
            out_depth[count] = depth
            if facets:
                out_facet[count] = f
            count += 1
    return count


@entry
def pair_contacts(table, i, j, r_i, R_i, r_j, R_j, out_point, out_n, out_depth, out_facet=None):
    """Raw contacts of shapes i and j (a ``covered`` pair) at world origins ``r`` (3,) and rotations
    ``R`` (3, 3): up to ``out_depth.shape[0]`` points (k, 3) [m], unit normals from i to j (k, 3)
    and depths > 0 (k,) [m] written; returns k (0 for pairs not covered). ``out_facet`` (k,) int64,
    optional: the mesh facet of each contact."""
    if out_facet is None:
        return _pair(table, i, j, r_i, R_i, r_j, R_j, out_point, out_n, out_depth, out_depth, False)
    return _pair(table, i, j, r_i, R_i, r_j, R_j, out_point, out_n, out_depth, out_facet, True)


@jit
def _pair(table, i, j, r_i, R_i, r_j, R_j, out_point, out_n, out_depth, out_facet, facets):
    ki, kj = table.kind[i], table.kind[j]
    if kj == MESH and (ki == SPHERE or ki == CAPSULE or ki == CONVEX):
        return _on_mesh(table, i, j, r_i, R_i, r_j, R_j, 1.0, out_point, out_n, out_depth, out_facet, facets)
    if ki == MESH and (kj == SPHERE or kj == CAPSULE or kj == CONVEX):
        return _on_mesh(table, j, i, r_j, R_j, r_i, R_i, -1.0, out_point, out_n, out_depth, out_facet, facets)
    return 0


@entry
def contacts_of_pairs(table, ij, r, R, out_pair, out_point, out_n, out_depth):
    """``pair_contacts`` of every pair ``ij`` (k, 2) at shape origins ``r`` (S, 3) and rotations ``R``
    (S, 3, 3), ``MESH_CONTACTS`` places per pair in the outputs (k * MESH_CONTACTS rows): the
    contacts, each with its row of ``ij`` in ``out_pair``, packed to the front; returns how many."""
    count = 0
    for p in range(ij.shape[0]):
        i, j = ij[p, 0], ij[p, 1]
        k = pair_contacts(table, i, j, r[i], R[i], r[j], R[j], out_point[count:count + MESH_CONTACTS],
                          out_n[count:count + MESH_CONTACTS], out_depth[count:count + MESH_CONTACTS])
        for c in range(count, count + k):
            out_pair[c] = p
        count += k
    return count

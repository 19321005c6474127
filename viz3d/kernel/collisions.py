"""The shape contacts' compiled piece: ``viz3d.contact.collision.Collisions`` in the kernel.

The same computation as the NumPy element, in its order, at every evaluation (its module docstring
describes the model):

    shape poses -> broad phase (allowed pairs, bounding spheres / ground boxes) -> narrow phase
    (``viz3d.contact.narrowphase.pair_contacts``) and support points below ground planes -> per pair
    the reduction (deepest, same face within ``COPLANAR``, farthest first up to ``max_contacts``,
    merge distance) -> per contact the pair law's normal force (its ``normal_force`` piece, Hertz's
    ``4/3 E* sqrt(R)`` factor), the dashpot, friction (``friction_vector``: coulomb, stribeck,
    bristle with its deflection from the stick anchor) -> the wrench on both bodies and the power
    the ledger books as dissipated.

Broad phase: every pair of shapes that may ever touch (colliding groups, two bodies not joined, a
ground shape other than a plane) is listed once when packing, in the orientation the NumPy
element's ``candidates`` gives it, and tested at each evaluation: O(S^2) pairs in the worst case
(every shape in one group), cheap next to the narrow phase while S is at most a few hundred; the
NumPy element's k-d tree per group is what larger scenes need (beyond ``MAX_PAIRS`` they keep the
NumPy path).

Stick anchors (bristle friction; ``StickAnchors``): fixed during a step, in arrays of the packed data
(``a_*``, capacity: every contact the scene can have); ``after_step_piece`` renews them after each
step of the kernel's fixed-step loop as ``Collisions.memory_after_step`` does (match, eq. 3.49, plant,
drop). ``load_anchors`` and ``stored_anchors`` convert them from and to ``StickAnchors`` at the ends
of a compiled call, so frames, the recorder and resumed runs see the same state as on the NumPy path.

The packed data holds its own scratch (raw contacts, contacts, match candidates): a ``KernelData``
belongs to one run (``viz3d.kernel.model.per_run``: packed for each run, not kept with the system).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from viz3d.compiled import (
    CHANGE,
    HOLD,
    RELEASE,
    Items,
    after_step_piece,
    compiled_piece,
    cross3,
    dot3,
    energy_piece,
    force_piece,
    hold_piece,
    jit,
    normal_force,
    registered,
)
from viz3d.contact import narrowphase
from viz3d.contact.collision import COPLANAR, StickAnchors, _all_pairs
from viz3d.contact.friction import FRICTION_PARAMS, friction_vector
from viz3d.contact.laws import Linear, PowerLawElastic
from viz3d.contact.narrowphase import MESH_CONTACTS, pair_contacts
from viz3d.points import rigid_points

try:
    from numba import literal_unroll
except ImportError:  # pragma: no cover
    def literal_unroll(x):
        return x

#: Columns of ``CollisionItems.i`` (per shape): body, group, the body's frame-origin point, plane (1/0).
BODY, GROUP, POINT, PLANE = 0, 1, 2, 3
#: Columns of ``CollisionItems.f`` (per shape): origin B_r (3), rotation B_R (9, row-major), bounding
#: radius [m] (planes: inf), normal in shape axes (3), curvature 1/r of spheres [1/m] (others 0).
B_R0, RADIUS, NORMAL, CURVATURE = 3, 12, 13, 16
#: Columns of ``CollisionItems.law_f`` (per pair law): dashpot [N s/m], E* [Pa] (NaN: no Hertz factor),
#: elastic energy ``c alpha^p`` (c, p), then the friction's ``FRICTION_PARAMS`` (code 0: none).
DAMPING, HERTZ, ENERGY_C, ENERGY_P, FRICTION = 0, 1, 2, 3, 4
#: ``CollisionItems.opts``: max_contacts, some law's friction keeps anchors (1/0), nb (ground's body index).
MAX_CONTACTS, STATEFUL, GROUND = 0, 1, 2
#: ``CollisionItems.count``: raw contacts, contacts, 1 when the contacts are those of the poses in
#: ``last_sr``, ``last_sR`` (``_detect``), contacts held (``h_*``), 1 while they are held (``hold_piece``).
N_RAW, N_TOUCH, KNOWN, N_HELD, HELD = 0, 1, 2, 3, 4
#: Most listed pairs the kernel's all-pairs broad phase takes (beyond it the run keeps the NumPy
#: element's k-d trees): 5e4 pairs cost ~0.1 ms of bound tests per evaluation and their raw-contact
#: scratch ~150 MB.
MAX_PAIRS = 50_000
#: Friction code of ``Bristle`` (``viz3d.contact.friction``): the stateful law.
BRISTLE = 3.0


def _z(*shape, dtype=float) -> np.ndarray:
    return np.zeros(shape, dtype)


class _CollisionFields(NamedTuple):
    """A ``Collisions`` element packed (shapes: S shapes, P listed pairs, M support points against
    planes, L pair laws, G groups, R raw and T contact capacity, A = T anchor capacity).

    i, f : (S, 4) int64, (S, 17)
        Per shape (columns ``BODY``... and ``B_R0``...).
    opts : (3,) int64
    merge : (1,) [m]
    pair_law : (G, G) int64
    pairs : (P, 3) int64
        Shapes i, j (the NumPy broad phase's orientation) and 1 when j is a ground shape (box test).
    box : (S, 2, 3)
        World boxes (lower, upper corner) of ground shapes [m].
    sup_i, sup : (M, 2) int64, (M, 4)
        Plane shape and owner shape of each support point; its centre in shape axes and radius [m].
    law_slot : (L, 2) int64
        Position of each pair law's normal law in ``laws`` and its row there.
    law_f : (L, 4 + FRICTION_PARAMS)
    laws : tuple
        One ``Items`` per registered normal-law class (``viz3d.compiled.normal_force``), parameters from
        column 0.
    table : ShapeTable
        The shapes as the narrow phase reads them (``viz3d.contact.narrowphase``; the NumPy element's).
    The rest is scratch and memory: shape poses, raw contacts, contacts, match, anchors, the contacts
    held within an ALI3-P step (``hold_piece``; while held, the contacts ``t_*`` are those held).
    """

    i: np.ndarray
    f: np.ndarray
    opts: np.ndarray
    merge: np.ndarray
    pair_law: np.ndarray
    pairs: np.ndarray
    box: np.ndarray
    sup_i: np.ndarray
    sup: np.ndarray
    law_slot: np.ndarray
    law_f: np.ndarray
    laws: tuple
    table: narrowphase.ShapeTable
    sr: np.ndarray  # shape origins, world [m]
    sR: np.ndarray  # shape rotations
    last_sr: np.ndarray  # the poses of the last detection
    last_sR: np.ndarray
    raw_key: np.ndarray
    raw_p: np.ndarray
    raw_n: np.ndarray
    raw_d: np.ndarray
    order: np.ndarray
    flag: np.ndarray
    np_p: np.ndarray
    np_n: np.ndarray
    np_d: np.ndarray
    t_shape: np.ndarray
    t_law: np.ndarray
    t_p: np.ndarray
    t_n: np.ndarray
    t_d: np.ndarray
    t_F: np.ndarray
    t_Fel: np.ndarray
    t_ad: np.ndarray
    t_vt: np.ndarray
    t_match: np.ndarray
    cand: np.ndarray
    cand_d: np.ndarray
    taken: np.ndarray
    count: np.ndarray
    a_shape: np.ndarray  # stick anchors (StickAnchors), a_n[0] of them
    a_anchor: np.ndarray
    a_mark: np.ndarray
    a_n: np.ndarray
    b_shape: np.ndarray  # the renewed ones, before they replace them
    b_anchor: np.ndarray
    b_mark: np.ndarray
    v3: np.ndarray  # scratch 3-vectors
    h_shape: np.ndarray  # contacts held (``FrozenTouches``), count[N_HELD] of them: shapes A, B
    h_law: np.ndarray
    h_A: np.ndarray  # A's witness point in A's axes from its frame origin [m]
    h_B: np.ndarray  # B's, in B's
    h_n: np.ndarray  # the normal in B's axes
    h_match: np.ndarray  # its anchor (-1: none)
    h_active: np.ndarray  # 1: it pushes


class CollisionItems(_CollisionFields, Items):
    """``_CollisionFields`` as a compiled piece's data (``viz3d.compiled.Items``: ``i``, ``f`` first),
    in the kernel's tuples only for systems with shape contacts (``present_only``: its 75 arrays,
    passed at every evaluation, would cost systems without them more than their own steps)."""

    __slots__ = ()
    present_only = True


# ---------------------------------------------------------------------------- packing (Python)


def pack_collisions(c, packer) -> CollisionItems:
    """``c`` (a ``Collisions``) packed; ``packer.Unsupported`` names what the compiled piece lacks."""
    nb = c.n_bodies
    flexible = {fb.index for fb in packer.bodies.flexible}
    if any(s.body in flexible for s in c.shapes):
        raise packer.Unsupported("shape contacts on flexible bodies")
    w = c._world()
    pairs = _pairs(c, w)
    if len(pairs) > MAX_PAIRS:
        raise packer.Unsupported(f"{len(pairs)} pairs of shapes that may touch, more than the kernel's all-pairs "
                                 f"broad phase takes ({MAX_PAIRS})")
    _check_narrow(c, pairs, packer.Unsupported)
    frame = packer.points(rigid_points(np.arange(nb + 1), np.zeros((nb + 1, 3))))
    S = len(c.shapes)
    i = np.array([[s.body, s.group, frame[s.body], int(s.kind == "plane")] for s in c.shapes], np.int64).reshape(S, 4)
    f = np.array([[*s.B_r, *np.asarray(s.B_R).ravel(), w["radius"][k], *s.normal, w["curvature"][k]]
                  for k, s in enumerate(c.shapes)], float).reshape(S, 17)
    box = np.zeros((S, 2, 3))
    for k, (lo, hi) in w["box"].items():
        box[k] = lo, hi
    sup_i = np.array([(k, o) for k, owner, _ in w["planes"] for o in owner], np.int64).reshape(-1, 2)
    sup = np.vstack([local for _, _, local in w["planes"]] + [np.zeros((0, 4))])
    law_slot, law_f, laws = _laws(c.laws, packer.Unsupported)
    n_plane_pairs = len({(int(o), int(k)) for k, o in sup_i})
    T = (len(pairs) + n_plane_pairs) * c.max_contacts
    R = len(pairs) * MESH_CONTACTS + len(sup)
    stateful = any(pl.friction is not None and pl.friction.stateful for pl in c.laws)
    A = T if stateful else 0
    opts = np.array([c.max_contacts, int(stateful), nb], np.int64)
    return CollisionItems(
        i, f, opts, np.array([float(c.merge_distance)]), np.ascontiguousarray(c.pair_law, np.int64), pairs, box, sup_i,
        np.ascontiguousarray(sup, float), law_slot, law_f, laws,
        c._world()["table"],
        _z(S, 3), _z(S, 3, 3), _z(S, 3), _z(S, 3, 3), _z(R, 2, dtype=np.int64), _z(R, 3), _z(R, 3), _z(R), _z(R, dtype=np.int64),
        _z(R, dtype=np.int64), _z(MESH_CONTACTS, 3), _z(MESH_CONTACTS, 3), _z(MESH_CONTACTS),
        _z(T, 2, dtype=np.int64), _z(T, dtype=np.int64), _z(T, 3), _z(T, 3), _z(T), _z(T), _z(T), _z(T), _z(T, 3),
        _z(T, dtype=np.int64), _z(T * c.max_contacts, 2, dtype=np.int64), _z(T * c.max_contacts),
        _z(A, dtype=np.int64), _z(5, dtype=np.int64), _z(A, 2, dtype=np.int64), _z(A, 3), _z(A, 2, 3),
        _z(1, dtype=np.int64), _z(A, 2, dtype=np.int64), _z(A, 3), _z(A, 2, 3), _z(12, 3),
        _z(T, 2, dtype=np.int64), _z(T, dtype=np.int64), _z(T, 3), _z(T, 3), _z(T, 3), _z(T, dtype=np.int64),
        _z(T, dtype=np.int64))


def _pairs(c, w) -> np.ndarray:
    """Every pair of shapes the NumPy broad phase may propose (``Collisions.candidates``, in its
    orientation), with 1 where j is a ground shape (box test), (P, 3)."""
    blocks = []
    members, G = w["members"], len(c.groups)
    for g1 in range(G):
        for g2 in range(g1, G):
            if c.pair_law[g1, g2] >= 0 and len(members[g1]) and len(members[g2]):
                ij = _all_pairs(members[g1], members[g2], g1 == g2)
                blocks.append(np.column_stack([ij, np.zeros(len(ij), int)]))
    for k in w["box"]:
        for g in range(G):
            if c.pair_law[g, c.shapes[k].group] >= 0 and len(members[g]):
                m = members[g]
                blocks.append(np.column_stack([m, np.full(len(m), k), np.ones(len(m), int)]))
    ij = np.vstack(blocks).astype(np.int64) if blocks else np.zeros((0, 3), np.int64)
    return np.ascontiguousarray(ij[c._allowed(ij[:, :2])] if len(ij) else ij)


def _check_narrow(c, pairs: np.ndarray, unsupported) -> None:
    """``unsupported`` naming the first pair of shape kinds the compiled narrow phase lacks."""
    kinds = sorted({tuple(c.shapes[int(k)].kind for k in p[:2]) for p in pairs})
    for ki, kj in kinds:
        if not narrowphase.covered(ki, kj):
            raise unsupported(f"shape contacts of {ki!r} and {kj!r} have no compiled narrow phase")


def _laws(pair_laws, unsupported) -> tuple[np.ndarray, np.ndarray, tuple]:
    """``law_slot``, ``law_f`` and the normal laws' ``Items`` of the pair laws."""
    classes = registered(normal_force)
    rows: dict[type, list] = {cls: [] for cls in classes}
    slot, table = [], []
    for pl in pair_laws:
        law = pl.law
        cls = type(law).compiled_items
        if cls is None or cls not in rows:
            raise unsupported(f"normal law {law.name!r} has no compiled piece")
        slot.append((classes.index(cls), len(rows[cls])))
        rows[cls].append(law.params())
        friction = pl.friction.params() if pl.friction is not None else [0.0] * FRICTION_PARAMS
        table.append([pl.damping, pl.hertz_modulus, *_energy_form(law, unsupported), *friction])
    laws = tuple(cls(np.zeros((len(r), 0), np.int64), np.array(r, float).reshape(len(r), -1) if r else np.zeros((0, 0)))
                 for cls, r in rows.items())
    return (np.array(slot, np.int64).reshape(-1, 2), np.array(table, float).reshape(-1, 4 + FRICTION_PARAMS), laws)


def _energy_form(law, unsupported) -> tuple[float, float]:
    """``(c, p)`` of the law's elastic energy ``c alpha^p`` [J] (linear: K/2, 2; power laws K/(n+1), n+1)."""
    if type(law).elastic_energy is Linear.elastic_energy:
        return 0.5 * law.stiffness, 2.0
    if type(law).elastic_energy is PowerLawElastic.elastic_energy:
        return law.stiffness / (law.exponent + 1.0), law.exponent + 1.0
    raise unsupported(f"normal law {law.name!r}: its elastic energy has no compiled form")


def load_anchors(d: CollisionItems, anchors: StickAnchors | None) -> None:
    """Put ``anchors`` (None: none) into ``d``'s anchor arrays."""
    n = 0 if anchors is None else anchors.n
    if n > d.a_shape.shape[0]:
        raise ValueError(f"{n} stick anchors, more than the {d.a_shape.shape[0]} contacts the scene can have")
    d.a_n[0] = n
    if n:
        d.a_shape[:n], d.a_anchor[:n], d.a_mark[:n] = anchors.shape, anchors.anchor, anchors.mark


def stored_anchors(d: CollisionItems) -> StickAnchors:
    """The anchors in ``d``'s arrays as a new ``StickAnchors``."""
    n = int(d.a_n[0])
    return StickAnchors(d.a_shape[:n].copy(), d.a_anchor[:n].copy(), d.a_mark[:n].copy())


# ---------------------------------------------------------------------------- compiled: detection


@jit
def _poses(d, v):
    """World origins and rotations of every shape: ``r_b + R_b B_r``, ``R_b B_R``."""
    for s in range(d.i.shape[0]):
        b, p = d.i[s, BODY], d.i[s, POINT]
        R = v.R[b]
        for a in range(3):
            acc = v.px[p, a]
            for c in range(3):
                acc += R[a, c] * d.f[s, c]
            d.sr[s, a] = acc
            for c in range(3):
                d.sR[s, a, c] = (R[a, 0] * d.f[s, B_R0 + c] + R[a, 1] * d.f[s, B_R0 + 3 + c]
                                 + R[a, 2] * d.f[s, B_R0 + 6 + c])


@jit
def _book(d, i, j, p, normal, depth):
    """File one raw contact of shapes i, j (``Collisions._book``): A the moving (or lower-index)
    shape, the normal from B to A (``normal`` is from i to j)."""
    if not depth > 0.0:
        return
    sign = -1.0
    nb = d.opts[GROUND]
    if d.i[j, BODY] != nb and (d.i[i, BODY] == nb or j < i):
        i, j, sign = j, i, 1.0
    k = d.count[N_RAW]
    d.raw_key[k, 0], d.raw_key[k, 1] = i, j
    for c in range(3):
        d.raw_p[k, c] = p[c]
        d.raw_n[k, c] = sign * normal[c]
    d.raw_d[k] = depth
    d.count[N_RAW] = k + 1


@jit
def _broad(d, i, j, box):
    """The bounds of shapes i and j overlap: bounding spheres, or i's sphere's box and ground shape j's box."""
    rho = d.f[i, RADIUS]
    if box == 1:
        for c in range(3):
            if not (d.sr[i, c] + rho >= d.box[j, 0, c] and d.sr[i, c] - rho <= d.box[j, 1, c]):
                return False
        return True
    s = 0.0
    for c in range(3):
        x = d.sr[i, c] - d.sr[j, c]
        s += x * x
    return math.sqrt(s) <= rho + d.f[j, RADIUS]


@jit
def _narrow(d):
    """The listed pairs whose bounds overlap, through the narrow phase."""
    for p in range(d.pairs.shape[0]):
        i, j = d.pairs[p, 0], d.pairs[p, 1]
        if not _broad(d, i, j, d.pairs[p, 2]):
            continue
        n = pair_contacts(d.table, i, j, d.sr[i], d.sR[i], d.sr[j], d.sR[j], d.np_p, d.np_n, d.np_d)
        for k in range(n):
            _book(d, i, j, d.np_p[k], d.np_n[k], d.np_d[k])


@jit
def _planes(d):
    """Support points below ground planes (``Collisions._planes``): their key (owner, plane)."""
    n, centre = d.v3[0], d.v3[1]
    for q in range(d.sup.shape[0]):
        k, o = d.sup_i[q, 0], d.sup_i[q, 1]
        for a in range(3):
            n[a] = (d.sR[k, a, 0] * d.f[k, NORMAL] + d.sR[k, a, 1] * d.f[k, NORMAL + 1]
                    + d.sR[k, a, 2] * d.f[k, NORMAL + 2])
            centre[a] = d.sr[o, a] + d.sR[o, a, 0] * d.sup[q, 0] + d.sR[o, a, 1] * d.sup[q, 1] + d.sR[o, a, 2] * d.sup[q, 2]
        depth = d.sup[q, 3] - ((centre[0] - d.sr[k, 0]) * n[0] + (centre[1] - d.sr[k, 1]) * n[1]
                               + (centre[2] - d.sr[k, 2]) * n[2])
        if depth > 0.0:
            r = d.count[N_RAW]
            d.raw_key[r, 0], d.raw_key[r, 1] = o, k
            for a in range(3):
                d.raw_p[r, a] = centre[a] - (d.sup[q, 3] - 0.5 * depth) * n[a]
                d.raw_n[r, a] = n[a]
            d.raw_d[r] = depth
            d.count[N_RAW] = r + 1


@jit
def _before(d, x, y):
    """Raw contact x goes before y: by pair (i, j), then deeper first (ties: as filed)."""
    if d.raw_key[x, 0] != d.raw_key[y, 0]:
        return d.raw_key[x, 0] < d.raw_key[y, 0]
    if d.raw_key[x, 1] != d.raw_key[y, 1]:
        return d.raw_key[x, 1] < d.raw_key[y, 1]
    return d.raw_d[x] > d.raw_d[y]


@jit
def _sort_raw(d):
    """``order``: the raw contacts by pair, deepest first, stable (insertion sort: a few hundred)."""
    for k in range(d.count[N_RAW]):
        x = k
        q = k
        while q > 0 and _before(d, x, d.order[q - 1]):
            d.order[q] = d.order[q - 1]
            q -= 1
        d.order[q] = x


@jit
def _dist(a, b):
    s = 0.0
    for c in range(3):
        x = a[c] - b[c]
        s += x * x
    return math.sqrt(s)


@jit
def _keep(d, x):
    """Contact ``x`` of the raw list into the contacts."""
    t = d.count[N_TOUCH]
    i, j = d.raw_key[x, 0], d.raw_key[x, 1]
    d.t_shape[t, 0], d.t_shape[t, 1] = i, j
    d.t_law[t] = d.pair_law[d.i[i, GROUP], d.i[j, GROUP]]
    for c in range(3):
        d.t_p[t, c] = d.raw_p[x, c]
        d.t_n[t, c] = d.raw_n[x, c]
    d.t_d[t] = d.raw_d[x]
    d.count[N_TOUCH] = t + 1


@jit
def _reduce(d):
    """Per pair (``Collisions._reduce``): the deepest contact, then of those on its face the farthest
    from the kept ones until ``max_contacts``, none within the merge distance."""
    m = d.count[N_RAW]
    cos_face = math.cos(COPLANAR)
    a = 0
    while a < m:
        x0 = d.order[a]
        b = a + 1
        while b < m and d.raw_key[d.order[b], 0] == d.raw_key[x0, 0] and d.raw_key[d.order[b], 1] == d.raw_key[x0, 1]:
            b += 1
        i, j = d.raw_key[x0, 0], d.raw_key[x0, 1]
        merge = d.merge[0] if d.merge[0] > 0.0 else 0.1 * min(d.f[i, RADIUS], d.f[j, RADIUS])
        for q in range(a, b):  # 1: on the deepest's face and not kept yet
            d.flag[q] = 1 if dot3(d.raw_n[d.order[q]], d.raw_n[x0]) >= cos_face else 0
        t0 = d.count[N_TOUCH]
        _keep(d, x0)
        d.flag[a] = 0
        while d.count[N_TOUCH] - t0 < d.opts[MAX_CONTACTS]:
            best, gap_best = -1, 0.0
            for q in range(a + 1, b):
                if d.flag[q] == 1:
                    gap = math.inf
                    for t in range(t0, d.count[N_TOUCH]):
                        gap = min(gap, _dist(d.raw_p[d.order[q]], d.t_p[t]))
                    if best < 0 or gap > gap_best:
                        best, gap_best = q, gap
            if best < 0 or gap_best <= merge:
                break
            _keep(d, d.order[best])
            d.flag[best] = 0
        a = b


@jit
def _detect(d, v):
    """The contacts at the kinematics in ``v`` (``Collisions.detect``). They depend on the shapes' poses
    alone: where these equal the last detection's bit for bit, its contacts are kept (the first stage
    of a step finds the shapes where the stick anchors' renewal after the last step found them, and
    so do output samples at a step's end: a fifth of the detections of an RK4 step with bristles)."""
    _poses(d, v)
    if d.count[KNOWN] == 1 and _same_poses(d):
        return
    d.count[N_RAW] = 0
    d.count[N_TOUCH] = 0
    _narrow(d)
    _planes(d)
    _sort_raw(d)
    _reduce(d)
    for s in range(d.sr.shape[0]):
        for a in range(3):
            d.last_sr[s, a] = d.sr[s, a]
            for c in range(3):
                d.last_sR[s, a, c] = d.sR[s, a, c]
    d.count[KNOWN] = 1


@jit
def _same_poses(d):
    for s in range(d.sr.shape[0]):
        for a in range(3):
            if d.sr[s, a] != d.last_sr[s, a]:
                return False
            for c in range(3):
                if d.sR[s, a, c] != d.last_sR[s, a, c]:
                    return False
    return True


# ---------------------------------------------------------------------------- compiled: forces


@jit
def _law_force(laws, slot, row, alpha, alpha_dot, clip):
    """The normal law's force of pair law (``slot``, ``row``) (``normal_force``; memoryless laws), clipped
    at zero or not (``clip``)."""
    F = 0.0
    s = 0
    for ld in literal_unroll(laws):
        if s == slot:
            F = normal_force(ld, row, 0, alpha, alpha_dot, 0.0, 0.0, clip)
        s += 1
    return F


@jit
def _scale(d, t, k):
    """``Collisions._stiffness_scale`` of contact t with pair law k: 1 or Hertz's ``4/3 E* sqrt(R)``."""
    E = d.law_f[k, HERTZ]
    if math.isnan(E):
        return 1.0
    curvature = d.f[d.t_shape[t, 0], CURVATURE] + d.f[d.t_shape[t, 1], CURVATURE]
    return 4.0 / 3.0 * E * math.sqrt(1.0 / curvature)


@jit
def _normal(d, v):
    """Per contact: indentation rate, slip velocity, normal force and its elastic part
    (``Collisions._evaluate``; held contacts, ``count[HELD]``: the active ones' law unclipped, odd in the
    depth, the others none)."""
    vA, vB, lever = d.v3[0], d.v3[1], d.v3[2]
    for t in range(d.count[N_TOUCH]):
        for side in range(2):
            s = d.t_shape[t, side]
            b, p = d.i[s, BODY], d.i[s, POINT]
            out = vA if side == 0 else vB
            for c in range(3):
                lever[c] = d.t_p[t, c] - v.px[p, c]
            cross3(v.wW[b], lever, out)
            for c in range(3):
                out[c] += v.pv[p, c]
        vn = 0.0
        for c in range(3):
            vA[c] -= vB[c]
            vn += vA[c] * d.t_n[t, c]
        for c in range(3):
            d.t_vt[t, c] = vA[c] - vn * d.t_n[t, c]
        alpha_dot = -vn
        k = d.t_law[t]
        scale = _scale(d, t, k)
        slot, row = d.law_slot[k, 0], d.law_slot[k, 1]
        d.t_ad[t] = alpha_dot
        d.t_Fel[t] = scale * _law_force(d.laws, slot, row, d.t_d[t], 0.0, True)
        if d.count[HELD] == 0:
            d.t_F[t] = max(scale * _law_force(d.laws, slot, row, d.t_d[t], alpha_dot, True)
                           + d.law_f[k, DAMPING] * alpha_dot, 0.0)
        elif d.h_active[t] == 1:
            depth = d.t_d[t]
            sign = 1.0 if depth > 0.0 else (-1.0 if depth < 0.0 else 0.0)
            d.t_F[t] = (scale * sign * _law_force(d.laws, slot, row, abs(depth), alpha_dot, False)
                        + d.law_f[k, DAMPING] * alpha_dot)
        else:
            d.t_F[t] = 0.0


@jit
def _match(d, v):
    """Each contact's anchor (``t_match``, -1: none; ``Collisions.match``): of the same two shapes, its
    marks carried by A and B within half the merge distance of the contact point, nearest first."""
    nt, na = d.count[N_TOUCH], d.a_n[0]
    mark = d.v3[3]
    n = 0
    for t in range(nt):
        d.t_match[t] = -1
        for e in range(na):
            if d.a_shape[e, 0] != d.t_shape[t, 0] or d.a_shape[e, 1] != d.t_shape[t, 1]:
                continue
            dist = math.inf
            for side in range(2):
                s = d.a_shape[e, side]
                b, p = d.i[s, BODY], d.i[s, POINT]
                for c in range(3):
                    mark[c] = v.px[p, c] + (v.R[b, c, 0] * d.a_mark[e, side, 0] + v.R[b, c, 1] * d.a_mark[e, side, 1]
                                            + v.R[b, c, 2] * d.a_mark[e, side, 2])
                dist = min(dist, _dist(d.t_p[t], mark))
            i, j = d.t_shape[t, 0], d.t_shape[t, 1]
            radius = min(d.f[i, RADIUS], d.f[j, RADIUS])
            if dist <= 0.5 * (d.merge[0] if d.merge[0] > 0.0 else 0.1 * radius):
                q = n  # insertion by distance, stable
                while q > 0 and dist < d.cand_d[q - 1]:
                    d.cand[q, 0], d.cand[q, 1], d.cand_d[q] = d.cand[q - 1, 0], d.cand[q - 1, 1], d.cand_d[q - 1]
                    q -= 1
                d.cand[q, 0], d.cand[q, 1], d.cand_d[q] = t, e, dist
                n += 1
    for e in range(na):
        d.taken[e] = 0
    for q in range(n):
        t, e = d.cand[q, 0], d.cand[q, 1]
        if d.t_match[t] < 0 and d.taken[e] == 0:
            d.t_match[t] = e
            d.taken[e] = 1


@jit
def _deflection(d, v, t, out):
    """The bristles' deflection of contact t into ``out`` (``Collisions.deflection``): the contact point
    minus its anchor (a point of B), without its normal part; zero without an anchor."""
    e = d.t_match[t]
    for c in range(3):
        out[c] = 0.0
    if e < 0:
        return
    s = d.t_shape[t, 1]
    b, p = d.i[s, BODY], d.i[s, POINT]
    for c in range(3):
        out[c] = d.t_p[t, c] - v.px[p, c] - (v.R[b, c, 0] * d.a_anchor[e, 0] + v.R[b, c, 1] * d.a_anchor[e, 1]
                                              + v.R[b, c, 2] * d.a_anchor[e, 2])
    sn = dot3(out, d.t_n[t])
    for c in range(3):
        out[c] -= sn * d.t_n[t, c]


@jit
def _apply(d, v, t, f):
    """``f`` on A and ``-f`` on B at contact t's point (world forces at the frame origins, torques
    about them)."""
    lever, tq = d.v3[6], d.v3[7]
    for side in range(2):
        s = d.t_shape[t, side]
        b, p = d.i[s, BODY], d.i[s, POINT]
        sign = 1.0 if side == 0 else -1.0
        for c in range(3):
            lever[c] = d.t_p[t, c] - v.px[p, c]
        cross3(lever, f, tq)
        for c in range(3):
            v.F[b, c] += sign * f[c]
            v.tau[b, c] += sign * tq[c]


@compiled_piece(force_piece, CollisionItems)
def _collision_forces(d, t, v, power):
    if d.count[HELD] == 1:
        _held_touches(d, v)
    else:
        _detect(d, v)
    _normal(d, v)
    if d.opts[STATEFUL] == 1 and d.count[HELD] == 0:
        _match(d, v)
    s, ft, f = d.v3[3], d.v3[4], d.v3[5]
    for k in range(d.count[N_TOUCH]):
        law = d.t_law[k]
        code = d.law_f[law, FRICTION]
        F = d.t_F[k]
        for c in range(3):
            ft[c] = 0.0
        if code == BRISTLE:
            if F > 0.0:
                _deflection(d, v, k, s)
                friction_vector(d.law_f[law, FRICTION:], d.t_vt[k], s, F, ft)
        elif code != 0.0:
            friction_vector(d.law_f[law, FRICTION:], d.t_vt[k], s, F, ft)
        for c in range(3):
            f[c] = F * d.t_n[k, c] + ft[c]
        _apply(d, v, k, f)
        # dissipated (the dampers' slot): minus the power of the rate part and of friction on the bodies
        power[power.shape[0] - 2] += (F - d.t_Fel[k]) * d.t_ad[k] - dot3(ft, d.t_vt[k])


@compiled_piece(energy_piece, CollisionItems)
def _collision_energy(d, v, V):
    _detect(d, v)
    for t in range(d.count[N_TOUCH]):
        k = d.t_law[t]
        V[1] += _scale(d, t, k) * d.law_f[k, ENERGY_C] * d.t_d[t] ** d.law_f[k, ENERGY_P]


@compiled_piece(after_step_piece, CollisionItems)
def _collision_after_step(d, t, v):
    """``Collisions.memory_after_step``: matched anchors kept (moved by eq. 3.49 when the bristles carry
    more than ``mu_s F_n``), new contacts' planted at their point, ended ones dropped."""
    if d.opts[STATEFUL] == 0:
        return
    _detect(d, v)
    _normal(d, v)
    _match(d, v)
    s, x = d.v3[3], d.v3[4]
    n = 0
    for k in range(d.count[N_TOUCH]):
        law = d.t_law[k]
        if d.law_f[law, FRICTION] != BRISTLE:
            continue
        e = d.t_match[k]
        kept = False
        if e >= 0:
            _deflection(d, v, k, s)
            p = d.law_f[law, FRICTION:]
            limit, size = p[2] * d.t_F[k], math.sqrt(dot3(s, s))
            if p[6] * size <= limit or size == 0.0:
                for c in range(3):
                    d.b_anchor[n, c] = d.a_anchor[e, c]
                kept = True
            else:
                for c in range(3):
                    s[c] *= p[8] * limit / (p[6] * size)
        else:
            for c in range(3):
                s[c] = 0.0
        for side in range(2):
            sh = d.t_shape[k, side]
            b, pt = d.i[sh, BODY], d.i[sh, POINT]
            d.b_shape[n, side] = sh
            for c in range(3):
                x[c] = d.t_p[k, c] - v.px[pt, c]
            for c in range(3):
                d.b_mark[n, side, c] = v.R[b, 0, c] * x[0] + v.R[b, 1, c] * x[1] + v.R[b, 2, c] * x[2]
            if side == 1 and not kept:
                for c in range(3):
                    x[c] = d.t_p[k, c] - s[c] - v.px[pt, c]
                for c in range(3):
                    d.b_anchor[n, c] = v.R[b, 0, c] * x[0] + v.R[b, 1, c] * x[1] + v.R[b, 2, c] * x[2]
        n += 1
    for q in range(n):
        for side in range(2):
            d.a_shape[q, side] = d.b_shape[q, side]
            for c in range(3):
                d.a_mark[q, side, c] = d.b_mark[q, side, c]
        for c in range(3):
            d.a_anchor[q, c] = d.b_anchor[q, c]
    d.a_n[0] = n


# ---------------------------------------------------------------------------- compiled: contacts held


@jit
def _witness(d, v, e, side, out):
    """Held contact ``e``'s witness point on ``side`` (0: A, 1: B) in world axes [m]."""
    s = d.h_shape[e, side]
    b, p = d.i[s, BODY], d.i[s, POINT]
    x = d.h_A[e] if side == 0 else d.h_B[e]
    for c in range(3):
        out[c] = v.px[p, c] + v.R[b, c, 0] * x[0] + v.R[b, c, 1] * x[1] + v.R[b, c, 2] * x[2]


@jit
def _held_depth(d, v, e, pA, pB, n):
    """Held contact ``e`` at the kinematics in ``v`` (``FrozenTouches.at``): its witness points ``pA``,
    ``pB``, normal ``n`` (world) and depth ``(pB - pA) . n`` [m]."""
    _witness(d, v, e, 0, pA)
    _witness(d, v, e, 1, pB)
    b = d.i[d.h_shape[e, 1], BODY]
    for c in range(3):
        n[c] = v.R[b, c, 0] * d.h_n[e, 0] + v.R[b, c, 1] * d.h_n[e, 1] + v.R[b, c, 2] * d.h_n[e, 2]
    return (pB[0] - pA[0]) * n[0] + (pB[1] - pA[1]) * n[1] + (pB[2] - pA[2]) * n[2]


@jit
def _held_touches(d, v):
    """The contacts ``t_*`` those held, at the kinematics in ``v`` (``FrozenTouches.at``): the point
    their witness points' middle; no longer the last detection's (``KNOWN``)."""
    pA, pB, n = d.v3[8], d.v3[9], d.v3[10]
    for e in range(d.count[N_HELD]):
        depth = _held_depth(d, v, e, pA, pB, n)
        d.t_shape[e, 0], d.t_shape[e, 1] = d.h_shape[e, 0], d.h_shape[e, 1]
        d.t_law[e] = d.h_law[e]
        d.t_match[e] = d.h_match[e]
        d.t_d[e] = depth
        for c in range(3):
            d.t_p[e, c] = 0.5 * (pA[c] + pB[c])
            d.t_n[e, c] = n[c]
    d.count[N_TOUCH] = d.count[N_HELD]
    d.count[KNOWN] = 0


@jit
def _hold(d, v):
    """The contacts at the kinematics in ``v`` held (``Collisions.frozen``): material points of A and B at
    their witness points (the contact point -+ half the depth along the normal), the normal in B's axes,
    their anchors, pushing or not (clipped force > 0)."""
    d.count[HELD] = 0
    _detect(d, v)
    _normal(d, v)
    if d.opts[STATEFUL] == 1:
        _match(d, v)
    x = d.v3[8]
    for t in range(d.count[N_TOUCH]):
        for side in range(2):
            s = d.t_shape[t, side]
            b, p = d.i[s, BODY], d.i[s, POINT]
            half = (0.5 if side == 1 else -0.5) * d.t_d[t]
            for c in range(3):
                x[c] = d.t_p[t, c] + half * d.t_n[t, c] - v.px[p, c]
            out = d.h_A[t] if side == 0 else d.h_B[t]
            for c in range(3):
                out[c] = v.R[b, 0, c] * x[0] + v.R[b, 1, c] * x[1] + v.R[b, 2, c] * x[2]
            d.h_shape[t, side] = s
        b = d.i[d.t_shape[t, 1], BODY]
        for c in range(3):
            d.h_n[t, c] = v.R[b, 0, c] * d.t_n[t, 0] + v.R[b, 1, c] * d.t_n[t, 1] + v.R[b, 2, c] * d.t_n[t, 2]
        d.h_law[t] = d.t_law[t]
        d.h_match[t] = d.t_match[t] if d.opts[STATEFUL] == 1 else -1
        d.h_active[t] = 1 if d.t_F[t] > 0.0 else 0
    d.count[N_HELD] = d.count[N_TOUCH]
    d.count[HELD] = 1


@jit
def _changed(d, v, tol):
    """1 when the contacts found at the kinematics in ``v`` differ from those held (``Collisions.frozen_change``):
    a pair of shapes with another number of pushing contacts, or whose pushing contacts' depths sum to
    more than ``tol`` [m] from the held ones'; else 0. The held contacts stay held."""
    d.count[HELD] = 0
    _detect(d, v)
    _normal(d, v)
    d.count[HELD] = 1
    for t in range(d.count[N_TOUCH]):
        if d.t_F[t] > 0.0 and _pair_differs(d, v, d.t_shape[t, 0], d.t_shape[t, 1], tol):
            return 1
    for e in range(d.count[N_HELD]):
        if d.h_active[e] == 1 and _pair_differs(d, v, d.h_shape[e, 0], d.h_shape[e, 1], -1.0):
            return 1
    return 0


@jit
def _pair_differs(d, v, i, j, tol):
    """The pair of shapes ``(i, j)`` has another number of pushing contacts found (``t_*``) than held, or
    (``tol`` >= 0) their depths' sums differ by more than ``tol`` [m]."""
    pA, pB, n = d.v3[8], d.v3[9], d.v3[10]
    found, held, depth = 0, 0, 0.0
    for t in range(d.count[N_TOUCH]):
        if d.t_F[t] > 0.0 and d.t_shape[t, 0] == i and d.t_shape[t, 1] == j:
            found += 1
            depth += d.t_d[t]
    for e in range(d.count[N_HELD]):
        if d.h_active[e] == 1 and d.h_shape[e, 0] == i and d.h_shape[e, 1] == j:
            held += 1
            depth -= _held_depth(d, v, e, pA, pB, n)
    return found != held or (tol >= 0.0 and abs(depth) > tol)


@compiled_piece(hold_piece, CollisionItems)
def _collision_hold(d, t, v, mode, tol):
    """``Collisions.frozen`` held (``HOLD``), released, or compared (``CHANGE``: 1 if they differ)."""
    if mode == HOLD:
        _hold(d, v)
    elif mode == RELEASE:
        d.count[HELD] = 0
        d.count[KNOWN] = 0
    else:
        return _changed(d, v, tol)
    return 0

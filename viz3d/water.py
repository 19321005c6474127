"""Bodies in still water: buoyancy and quadratic drag on their submerged parts (seed 004's anchor and
chain below the waterline; issue 11).

The water fills the half-space below a plane (``level`` along the unit ``normal``, which points up
out of the water). Each body's shape is cut into cells (``volume_cells``): centres ``x_i`` in body
axes with volumes ``w_i`` summing to the shape's exact volume, cell size ``c``. Primitives (sphere,
capsule, box, cylinder) keep the cells of a grid of about ``n`` over their bounding box whose centres
are inside; a closed, outward mesh (``mesh_cells``) keeps those of a grid of cell volume ``V / n``
over its bounding box whose centres have winding number 1, then shifts them (by the grid's centroid
error, a fraction of a cell) so their centroid is the mesh's exact one, as the primitives' symmetric
grids have theirs. A mesh
body's frame origin is its centre of mass (its vertices come shifted by it). A cell whose centre
lies at depth ``t = level - n . x`` is wet by the fraction ``f(t) = clip(t / c + 1/2, 0, 1)``
(continuous: a cell drains linearly as the surface sweeps through it), so that

    buoyancy on the cell  B_i = rho g w_i f(t_i) n,   at its centre,
    its potential         U_i = rho g w_i H(t_i),   H' = f,   H(t) = 0, (t + c/2)^2 / (2c), t,

below, through and above the band ``|t| < c/2`` (the force is ``-dU/dx``: buoyancy is conservative).
A fully submerged body feels ``rho g V`` exactly, at its cells' centroid: its shape's centroid.

Drag on a body acts at the wet cells' centroid ``p`` against its velocity ``v_p`` through the water:
``D = -1/2 rho C_d A phi |v_p| v_p``, with ``phi`` the wet fraction of the volume and ``A`` the
frontal area of the sphere of the same volume (exact for spheres; an estimate for other shapes).
Its power is booked as work done by non-conservative forces. No added mass, no rotational drag.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.forces import ForceElement
from viz3d.kinematics import Configuration
from viz3d.rotations import cross


def volume_cells(shape: dict, volume: float, n: int = 512,
                 mesh: tuple[FloatArray, IntArray] | None = None) -> tuple[FloatArray, FloatArray, float]:
    """About ``n`` cells of a shape table: centres (m, 3) in body axes [m], volumes (m,) summing to
    ``volume`` [m^3], and the cell size [m]. Primitives (sphere, capsule, box, cylinder; axes along
    body z): a regular grid over the bounding box, its cells whose centres lie inside kept. Meshes:
    ``mesh_cells`` of ``mesh``, its vertices (N, 3) in body axes [m] and outward faces (F, 3).

    Raises
    ------
    ValueError
        For a mesh shape without ``mesh``, or a mesh no cell centre falls inside of.
    """
    kind = shape["type"]
    if kind == "mesh":
        if mesh is None:
            raise ValueError("a mesh shape's cells need its vertices and faces")
        return mesh_cells(*mesh, volume, n)
    if kind == "box":
        half = 0.5 * np.asarray(shape["extents"], float)
    elif kind == "sphere":
        half = np.full(3, shape["radius"])
    elif kind in ("capsule", "cylinder"):
        r = shape["radius"]
        extra = r if kind == "capsule" else 0.0
        half = np.array([r, r, 0.5 * shape["height"] + extra])
    else:
        raise ValueError(f"water acts on spheres, capsules, boxes, cylinders and meshes, not {kind!r}")
    c = float((8 * np.prod(half) / n) ** (1 / 3))
    X = _grid(-half, half, c)
    X = X[_inside(kind, shape, X)]
    return X, np.full(len(X), volume / len(X)), c


def mesh_cells(vertices: FloatArray, faces: IntArray, volume: float, n: int = 512) -> tuple[FloatArray, FloatArray, float]:
    """About ``n`` cells of a closed, outward triangle mesh: vertices (N, 3) [m], faces (F, 3).

    A regular grid of cell size ``c = (V / n)^(1/3)`` over the bounding box; the cells whose centres
    have winding number 1 kept, then translated together (by the grid's centroid error, a fraction of
    ``c``) so their centroid is the mesh's exact one (divergence theorem). Returns centres (m, 3) in
    the vertices' frame [m], volumes (m,) summing to ``volume`` [m^3], and ``c`` [m].

    Raises
    ------
    ValueError
        When no cell centre falls inside (a mesh thinner than its cells everywhere: raise ``n``).
    """
    V = np.asarray(vertices, float)
    c = float((volume / n) ** (1 / 3))
    x, y, z = _axes(V.min(axis=0), V.max(axis=0), c)
    xy = np.stack(np.meshgrid(x, y, indexing="ij"), axis=-1).reshape(-1, 2)
    inside = column_winding(xy, z, V, faces).reshape(-1) == 1
    X = _grid(V.min(axis=0), V.max(axis=0), c)[inside]
    if not len(X):
        raise ValueError(f"no cell centre of size {c:g} m falls inside the mesh: more cells needed")
    X = X + (mesh_centroid(V, faces) - X.mean(axis=0))
    return X, np.full(len(X), volume / len(X)), c


def _axes(lo: FloatArray, hi: FloatArray, c: float) -> list[FloatArray]:
    """Per axis, the centres of a grid over the box ``lo``..``hi`` (3,) [m], about ``c`` apart [m]."""
    out = []
    for a, b in zip(lo, hi):
        k = max(1, int(round((b - a) / c)))
        out.append(a + (np.arange(k) + 0.5) * ((b - a) / k))
    return out


def _grid(lo: FloatArray, hi: FloatArray, c: float) -> FloatArray:
    """Centres (m, 3) [m] of the grid of ``_axes``, z fastest."""
    return np.stack(np.meshgrid(*_axes(lo, hi, c), indexing="ij"), axis=-1).reshape(-1, 3)


def mesh_centroid(vertices: FloatArray, faces: IntArray) -> FloatArray:
    """Centroid (3,) [m] of the solid a closed, outward mesh bounds: its tetrahedra on the origin,
    ``sum v_f (a + b + c) / 4 / sum v_f`` with ``v_f = a . (b x c) / 6``."""
    a, b, c = (np.asarray(vertices, float)[np.asarray(faces)[:, k]] for k in range(3))
    v = np.einsum("ki,ki->k", a, np.cross(b, c)) / 6.0
    return (v @ (a + b + c)) / (4.0 * v.sum())


def column_winding(xy: FloatArray, z: FloatArray, vertices: FloatArray, faces: IntArray,
                   chunk: int = 2**20) -> IntArray:
    """Winding numbers (k, m) of a closed, outward mesh about the points ``(x_i, y_i, z_j)``: columns
    ``xy`` (k, 2) [m], heights ``z`` (m,) [m]; 1 inside, 0 outside.

    Each column's ray up +z crosses faces; a crossing above a point counts the sign of the face's
    normal z (leaving the solid +1, entering -1). A column through a projected edge or vertex is moved
    by the symbolic ``(eps, eps^2)`` (``_edge_sides``), so each crossing is counted once, exactly."""
    V, F = np.asarray(vertices, float), np.asarray(faces)
    W = np.zeros((len(xy), len(z)), int)
    step = max(1, chunk // max(1, len(F)))
    for s in range(0, len(xy), step):
        o, side = _edge_sides(np.asarray(xy[s:s + step], float), V, F)  # (k, F, 3) each: edges bc, ca, ab
        hit = (side[..., 0] == side[..., 1]) & (side[..., 1] == side[..., 2]) & (side[..., 0] != 0)
        col, f = np.nonzero(hit)
        w = o[col, f]
        z_hit = np.einsum("hi,hi->h", w, V[F[f], 2]) / w.sum(axis=1)
        np.add.at(W, s + col, side[col, f, 0][:, None].astype(int) * (z_hit[:, None] > z[None, :]))
    return W


def _edge_sides(xy: FloatArray, vertices: FloatArray, faces: IntArray) -> tuple[FloatArray, FloatArray]:
    """Per column (k, 2) and face (F, 3), its edges' orientations ``(q - p) x (s - p)`` about the
    column ``s`` (edges bc, ca, ab: the barycentric weights of a, b, c) (k, F, 3), then the signs
    (k, F, 3) of those orientations at ``s + (eps, eps^2)``. Each edge is evaluated from its lower
    vertex index, so two faces sharing it see exactly opposite values."""
    i, j = faces[:, [1, 2, 0]], faces[:, [2, 0, 1]]
    lo, hi, flip = np.minimum(i, j), np.maximum(i, j), np.where(i < j, 1.0, -1.0)
    p, d = vertices[lo, :2], vertices[hi, :2] - vertices[lo, :2]  # (F, 3, 2)
    r = xy[:, None, None, :] - p[None]
    o = d[..., 0] * r[..., 1] - d[..., 1] * r[..., 0]
    tie = np.where(d[..., 1] != 0.0, -np.sign(d[..., 1]), np.sign(d[..., 0]))
    side = np.where(o != 0.0, np.sign(o), tie) * flip
    return o * flip, side


def _inside(kind: str, shape: dict, X: FloatArray) -> np.ndarray:
    if kind == "box":
        return np.ones(len(X), dtype=bool)
    r = shape["radius"]
    if kind == "sphere":
        return np.einsum("ki,ki->k", X, X) <= r * r
    if kind == "cylinder":
        return X[:, 0] ** 2 + X[:, 1] ** 2 <= r * r
    h = 0.5 * shape["height"]
    axial = np.clip(X[:, 2], -h, h)
    return X[:, 0] ** 2 + X[:, 1] ** 2 + (X[:, 2] - axial) ** 2 <= r * r


def wet_fraction(t: FloatArray, c: FloatArray) -> FloatArray:
    """``f(t) = clip(t / c + 1/2, 0, 1)`` of cells at depth ``t`` [m], size ``c`` [m]."""
    return np.clip(t / c + 0.5, 0.0, 1.0)


def wet_potential(t: FloatArray, c: FloatArray) -> FloatArray:
    """``H(t)`` [m] with ``H' = f``: 0 above the band, ``(t + c/2)^2 / (2c)`` in it, ``t`` below."""
    return np.where(t <= -0.5 * c, 0.0, np.where(t >= 0.5 * c, t, (t + 0.5 * c) ** 2 / (2.0 * c)))


@dataclass(frozen=True, eq=False)
class Water(ForceElement):
    """Buoyancy and drag of still water on the cells of k bodies (module docstring).

    Attributes
    ----------
    body : ndarray of int, shape (k,)
    cells : tuple of ndarray, each (m_b, 3)
        Cell centres in body axes from the body's frame origin [m].
    weights : tuple of ndarray, each (m_b,)
        Cell volumes [m^3].
    size : ndarray, shape (k,)
        Cell size of each body [m].
    area : ndarray, shape (k,)
        Frontal area for drag [m^2].
    level : float
        Height of the surface along ``normal`` [m].
    normal : ndarray, shape (3,)
        Unit normal of the surface, up out of the water.
    density : float
        [kg/m^3].
    gravity : float
        Magnitude of gravity [m/s^2].
    drag : float
        ``C_d`` [-] (0: no drag).
    """

    type_name: ClassVar[str] = "water"
    dissipative: ClassVar[bool] = True
    #: Frame scalars this element adds (``scalars``), saved as trajectory fields (``viz3d.extras``).
    scalar_names: ClassVar[tuple[str, ...]] = ("water/submerged_volume", "water/buoyancy")
    #: The live viewer's plot of this element: (title, frame scalar).
    live_plot: ClassVar[tuple[str, str]] = ("Water: buoyancy [N]", "water/buoyancy")
    body: IntArray
    cells: tuple
    weights: tuple
    size: FloatArray
    area: FloatArray
    level: float
    normal: FloatArray
    density: float
    gravity: float
    drag: float = 0.0

    def __post_init__(self):  # every body's cells stacked once, for whole-array evaluations
        owner = np.concatenate([np.full(len(c), k) for k, c in enumerate(self.cells)]).astype(int)
        object.__setattr__(self, "_owner", owner)
        object.__setattr__(self, "_X", np.vstack(self.cells).reshape(-1, 3))
        object.__setattr__(self, "_w", np.concatenate(self.weights))
        object.__setattr__(self, "_volume", np.bincount(owner, self._w, minlength=len(self.body)))

    def coupled_bodies(self):
        return np.zeros((0, 2), int)  # each body's water forces depend on its own pose only

    def _cells(self, cfg: Configuration) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Every cell's lever from its body's frame origin, world (M, 3) [m], depth (M,) [m] and wet
        volume (M,) [m^3]."""
        b = self.body[self._owner]
        lever = np.einsum("kij,kj->ki", cfg.pose.R_WB[b], self._X)
        depth = self.level - (cfg.pose.W_r[b] + lever) @ self.normal
        return lever, depth, self._w * wet_fraction(depth, self.size[self._owner])

    def _drag(self, cfg: Configuration, lever: FloatArray, wet: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Drag on each body (k, 3) [N] and its lever from the frame origin, world (k, 3) [m] (zero
        when dry or C_d = 0)."""
        k = len(self.body)
        total = np.bincount(self._owner, wet, minlength=k)
        moment = np.stack([np.bincount(self._owner, wet * lever[:, i], minlength=k) for i in range(3)], axis=1)
        arm = np.divide(moment, total[:, None], out=np.zeros((k, 3)), where=total[:, None] > 0.0)
        if self.drag == 0.0:
            return np.zeros((k, 3)), arm
        v = cfg.twist.W_v[self.body] + cross(cfg.twist.W_omega[self.body], arm)
        phi = total / self._volume
        D = -0.5 * self.density * self.drag * (self.area * phi * np.linalg.norm(v, axis=1))[:, None] * v
        return D, arm

    def wrench(self, cfg):
        rows = cfg.pose.W_r.shape[0]
        F, tau = np.zeros((rows, 3)), np.zeros((rows, 3))
        lever, _, wet = self._cells(cfg)
        B = (self.density * self.gravity * wet)[:, None] * self.normal
        b = self.body[self._owner]
        np.add.at(F, b, B)
        np.add.at(tau, b, cross(lever, B))
        D, arm = self._drag(cfg, lever, wet)
        np.add.at(F, self.body, D)
        np.add.at(tau, self.body, cross(arm, D))
        return F, tau, None

    def potential_energy(self, cfg):
        _, depth, _ = self._cells(cfg)
        return self.density * self.gravity * float(self._w @ wet_potential(depth, self.size[self._owner]))

    @property
    def conservative(self) -> bool:
        return self.drag == 0.0

    def nonconservative_power(self, cfg):
        """The drag's power on the bodies [W] (<= 0); buoyancy's is in ``potential_energy``."""
        lever, _, wet = self._cells(cfg)
        D, arm = self._drag(cfg, lever, wet)
        v = cfg.twist.W_v[self.body] + cross(cfg.twist.W_omega[self.body], arm)
        return float(np.sum(D * v))

    def scalars(self, cfg: Configuration) -> dict[str, float]:
        """Frame scalars: the submerged volume [m^3] and the buoyancy [N] of all bodies."""
        wet = float(self._cells(cfg)[2].sum())
        return {"water/submerged_volume": wet, "water/buoyancy": self.density * self.gravity * wet}

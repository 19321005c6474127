"""Material points on bodies: where joints, springs, loads and contacts attach.

A ``BodyPoints`` holds k points, each fixed in the material of one body (or of ground). On a rigid
body a point is a constant offset ``s`` from the centre of mass (body axes); on a flexible body it
is a section ``x`` of the bar with an offset ``c`` in the section, which moves with the deformation
(``viz3d.flexible.floating_points``). Every element asks its points for the same five things, so
no element needs to know what kind of body it is attached to:

* ``levers`` and ``positions``: world vectors from the frame origins, world positions [m];
* ``velocities`` [m/s];
* ``jacobian``: the velocity Jacobian, as a frame part (k, 3, 6) on the body's twist
  ``[W_v, B_omega]`` and an elastic part (k, 3, n_e) on the stacked ``eta_dot`` of all flexible
  bodies (zero columns except the point's own body);
* ``bias``: the acceleration not proportional to ``v_dot`` (``J_dot v``) [m/s^2];
* ``wrench``: world forces at the points as generalized forces: per body a world force at the frame
  origin and a world torque about it (nb + 1, 3) each, plus the elastic part (n_e,).

See docs/notation.md ("Points on bodies").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.compiled import cross3, inline, jit, matvec3, tmatvec3
from viz3d.flexible import floating_points as fp
from viz3d.kinematics import Configuration
from viz3d.rotations import cross, skew


@dataclass(frozen=True, eq=False)
class FlexPoints:
    """The points of a ``BodyPoints`` that lie on one flexible body.

    Attributes
    ----------
    which : ndarray of int, shape (m,)
        Their indices among the k points.
    flex : int
        Index of the body among ``Bodies.flexible`` (and of its ``eta`` in ``Configuration``).
    offset : int
        Position of the body's ``eta`` in the stacked elastic coordinates.
    material : MaterialPoints
        Sections and offsets, with their shape matrices.
    """

    which: IntArray
    flex: int
    offset: int
    material: fp.MaterialPoints

    @property
    def n(self) -> int:
        return self.material.N.shape[2]


@dataclass(frozen=True, eq=False)
class BodyPoints:
    """k material points, vectorized.

    Attributes
    ----------
    body : ndarray of int, shape (k,)
        Body of each point; ``nb`` is ground.
    B_s : ndarray, shape (k, 3)
        Offset from the body's frame origin in body axes [m] (ground: the world point); for points on
        flexible bodies, the undeformed one.
    flex : tuple of FlexPoints
        The points on flexible bodies, grouped by body.
    n_elastic : int
        Elastic coordinates of the system (columns of the elastic Jacobian part).
    """

    body: IntArray
    B_s: FloatArray
    flex: tuple[FlexPoints, ...] = ()
    n_elastic: int = 0

    @property
    def k(self) -> int:
        return len(self.body)

    def body_positions(self, cfg: Configuration) -> FloatArray:
        """Offsets from the frame origins in body axes, deformed, shape (k, 3) [m]."""
        if not self.flex:
            return self.B_s
        s = self.B_s.copy()
        for g in self.flex:
            s[g.which] = g.material.s0 + g.material.N @ cfg.eta[g.flex]
        return s

    def levers(self, cfg: Configuration) -> FloatArray:
        """World vectors from the frame origins to the points, shape (k, 3) [m]."""
        return np.einsum("kij,kj->ki", cfg.pose.R_WB[self.body], self.body_positions(cfg))

    def positions(self, cfg: Configuration) -> FloatArray:
        """World positions, shape (k, 3) [m]."""
        return cfg.pose.W_r[self.body] + self.levers(cfg)

    def velocities(self, cfg: Configuration, levers: FloatArray | None = None) -> FloatArray:
        """World velocities, shape (k, 3) [m/s]."""
        rho = self.levers(cfg) if levers is None else levers
        v = cfg.twist.point_velocity(self.body, rho)
        for g in self.flex:
            R = cfg.pose.R_WB[self.body[g.which]]
            v[g.which] += np.einsum("kij,kjq,q->ki", R, g.material.N, cfg.eta_dot[g.flex])
        return v

    def jacobian(self, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
        """Velocity Jacobian: frame part (k, 3, 6) ``[I, -R skew(s)]`` on ``[W_v, B_omega]`` and
        elastic part (k, 3, n_e) ``R N``."""
        Jf = np.zeros((self.k, 3, 6))
        Jf[:, :, :3] = np.eye(3)
        Jf[:, :, 3:] = np.einsum("kab,kbc->kac", cfg.pose.R_WB[self.body], -skew(self.body_positions(cfg)))
        Je = np.zeros((self.k, 3, self.n_elastic))
        for g in self.flex:
            R = cfg.pose.R_WB[self.body[g.which]]
            Je[g.which, :, g.offset:g.offset + g.n] = R @ g.material.N
        return Jf, Je

    def bias(self, cfg: Configuration, levers: FloatArray | None = None) -> FloatArray:
        """``J_dot v``, shape (k, 3) [m/s^2]: ``w x (w x rho)`` plus, on flexible bodies, the Coriolis
        term ``2 w x (R N eta_dot)`` (world axes)."""
        rho = self.levers(cfg) if levers is None else levers
        w = cfg.twist.W_omega[self.body]
        a = cross(w, cross(w, rho))
        for g in self.flex:
            R = cfg.pose.R_WB[self.body[g.which]]
            u_dot = np.einsum("kij,kjq,q->ki", R, g.material.N, cfg.eta_dot[g.flex])
            a[g.which] += 2.0 * cross(w[g.which], u_dot)
        return a

    def section_rotations(self, cfg: Configuration) -> FloatArray:
        """Small rotation ``theta = P eta`` of each point's section relative to its body's frame, body
        axes, shape (k, 3) [rad]; zero on rigid bodies and ground (``viz3d.flexible.floating_points``)."""
        theta = np.zeros((self.k, 3))
        for g in self.flex:
            theta[g.which] = g.material.P @ cfg.eta[g.flex]
        return theta

    def section_jacobian(self, cfg: Configuration) -> FloatArray:
        """``R P`` on the stacked elastic velocities, shape (k, 3, n_e): the world rate of the section
        rotation relative to the frame, ``Omega = R P eta_dot``; zero on rigid bodies and ground."""
        G = np.zeros((self.k, 3, self.n_elastic))
        for g in self.flex:
            G[g.which, :, g.offset:g.offset + g.n] = cfg.pose.R_WB[self.body[g.which]] @ g.material.P
        return G

    def subset(self, which: IntArray) -> "BodyPoints":
        """The points ``which`` (m,) (indices into the k points, distinct) as a ``BodyPoints``."""
        which = np.asarray(which, dtype=int)
        groups = []
        for g in self.flex:
            mine = np.flatnonzero(np.isin(which, g.which))
            if mine.size:
                rows = np.searchsorted(g.which, which[mine])
                m = g.material
                material = fp.MaterialPoints(m.x[rows], m.c[rows], m.s0[rows], m.N[rows], m.P[rows])
                groups.append(FlexPoints(mine, g.flex, g.offset, material))
        return BodyPoints(self.body[which], self.B_s[which], tuple(groups), self.n_elastic)

    def wrench(self, cfg: Configuration, W_F: FloatArray, levers: FloatArray | None = None
               ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """World forces ``W_F`` (k, 3) [N] at the points as generalized forces: world forces at the
        frame origins and world torques about them, shapes (nb + 1, 3), and the elastic part (n_e,)."""
        rho = self.levers(cfg) if levers is None else levers
        n = cfg.pose.W_r.shape[0]
        F = scatter(n, self.body, W_F)
        tau = scatter(n, self.body, cross(rho, W_F))
        Qe = np.zeros(self.n_elastic)
        for g in self.flex:
            R = cfg.pose.R_WB[self.body[g.which]]
            F_B = np.einsum("kji,kj->ki", R, W_F[g.which])
            Qe[g.offset:g.offset + g.n] += np.einsum("kiq,ki->q", g.material.N, F_B)
        return F, tau, Qe


def scatter(n_rows: int, body: IntArray, values: FloatArray) -> FloatArray:
    """Sum ``values`` (k, 3) into rows ``body`` (k,) of a zero (n_rows, 3) array."""
    out = np.zeros((n_rows, 3))
    np.add.at(out, body, values)
    return out


def rigid_points(body: IntArray, B_s: FloatArray, n_elastic: int = 0) -> BodyPoints:
    """Points with constant body-frame offsets (rigid bodies and ground)."""
    return BodyPoints(np.asarray(body, dtype=int), np.asarray(B_s, dtype=float).reshape(-1, 3), (), n_elastic)


def body_points(bodies, body: IntArray, B_s: FloatArray, x: FloatArray | None = None) -> BodyPoints:
    """k points of ``bodies`` (a ``viz3d.bodies.Bodies``).

    Parameters
    ----------
    body : ndarray of int, shape (k,)
        Body of each point (``nb`` = ground).
    B_s : ndarray, shape (k, 3)
        Rigid bodies and ground: the offset from the centre of mass, body axes (ground: the world
        point) [m]. Flexible bodies: the offset ``c`` of the point from its section's centroid, body
        axes [m] (e.g. ``(depth / 2) d`` for the surface).
    x : ndarray, shape (k,), optional
        Flexible bodies: the section of each point along the bar [m] (ignored elsewhere).
    """
    body = np.asarray(body, dtype=int)
    B_s = np.asarray(B_s, dtype=float).reshape(-1, 3).copy()
    n_elastic = sum(fb.n for fb in bodies.flexible)
    groups, offset = [], 0
    for i, fb in enumerate(bodies.flexible):
        which = np.flatnonzero(body == fb.index)
        if which.size:
            if x is None:
                raise ValueError(f"points on the flexible body {bodies.names[fb.index]!r} need their sections x")
            material = fp.material_points(fb.bar, np.asarray(x, dtype=float)[which], B_s[which])
            B_s[which] = material.s0
            groups.append(FlexPoints(which, i, offset, material))
        offset += fb.n
    return BodyPoints(body, B_s, tuple(groups), n_elastic)


# ---------------------------------------------------------------------------- compiled kernel pieces
# The kernel (viz3d.kernel) keeps every material point of a system in one table: ``v.pt_i`` (np, 4)
# int [body, offset of its N (3, n) in ``v.pt_N``, n (0: rigid or ground), offset of its body's eta
# in the stacked elastic coordinates] and ``m.pt_s`` (np, 3), the offset s (or s0) in body axes.
# ``kinematics`` fills, per evaluation, the deformed offsets ``v.ps``, levers ``v.prho``,
# positions ``v.px``, velocities ``v.pv`` and elastic velocities ``v.pud = R N eta_dot`` (world) of
# every point, and of its section (``v.pt_P``, the section rotation P (3, n) at the offset of N) the
# small rotation ``v.pth = R P eta`` and its rate relative to the frame ``v.pom = R P eta_dot``
# (world; zero on rigid bodies and ground); elements then read them and act through ``apply_force``,
# ``add_row``, ``add_turn`` and ``bias``, as their NumPy code does through BodyPoints (and
# ``viz3d.joint_axes``). Scratch rows ``v.v3[0:8]`` are these helpers'.


@inline
def kinematics(m, v, w):
    """Every point's deformed offset, lever, position, velocity and elastic velocity, its section's
    rotation and rate (see above)."""
    for p in range(v.pt_i.shape[0]):
        b, off, n, e0 = v.pt_i[p, 0], v.pt_i[p, 1], v.pt_i[p, 2], v.pt_i[p, 3]
        s, ud, th, om = v.ps[p], v.v3[0], v.v3[2], v.v3[3]
        for c in range(3):
            s[c] = m.pt_s[p, c]
            ud[c] = 0.0
            th[c] = 0.0
            om[c] = 0.0
            for q in range(n):
                N, P = v.pt_N[off + c * n + q], v.pt_P[off + c * n + q]
                s[c] += N * w.eta[e0 + q]
                ud[c] += N * w.eta_dot[e0 + q]
                th[c] += P * w.eta[e0 + q]
                om[c] += P * w.eta_dot[e0 + q]
        matvec3(v.R[b], s, v.prho[p])
        matvec3(v.R[b], ud, v.pud[p])
        matvec3(v.R[b], th, v.pth[p])
        matvec3(v.R[b], om, v.pom[p])
        cross3(v.wW[b], v.prho[p], v.v3[1])
        for c in range(3):
            v.px[p, c] = w.r[b, c] + v.prho[p, c]
            v.pv[p, c] = w.vW[b, c] + v.v3[1, c] + v.pud[p, c]


@inline
def apply_pair(v, p1, p2, f):
    """Add ``f`` (3,) [N] at point ``p1`` and ``-f`` at point ``p2`` (an action and its reaction);
    ``f`` is unchanged on return."""
    apply_force(v, p1, f)
    for c in range(3):
        f[c] = -f[c]
    apply_force(v, p2, f)
    for c in range(3):
        f[c] = -f[c]


@inline
def apply_force(v, p, f):
    """Add the world force ``f`` (3,) [N] at point ``p`` to the generalized forces: ``f`` and ``rho x f``
    on its body's frame (world), ``N^T R^T f`` on its elastic coordinates."""
    _apply_force(v.pt_i, v.pt_N, v.R, v.prho, v.F, v.tau, v.Qe, v.v3, p, f)


@jit
def _apply_force(pt_i, pt_N, R, prho, F, tau, Qe, v3, p, f):
    # The arrays, not the View: a compiled call receives every field of every array it is passed
    # (about 180 scalars for the View), which cost more than the arithmetic here.
    b, off, n, e0 = pt_i[p, 0], pt_i[p, 1], pt_i[p, 2], pt_i[p, 3]
    t = v3[2]
    cross3(prho[p], f, t)
    for c in range(3):
        F[b, c] += f[c]
        tau[b, c] += t[c]
    if n > 0:
        fB = v3[3]
        tmatvec3(R[b], f, fB)
        for c in range(3):
            for q in range(n):
                Qe[e0 + q] += pt_N[off + c * n + q] * fB[c]


@inline
def add_row(v, row, side, p, u, sign):
    """Add ``sign u^T J_p`` to side ``side`` of constraint row ``row``: the velocity Jacobian of point
    ``p`` along the world vector ``u`` (3,), i.e. ``[u, s x R^T u]`` on the frame twist and
    ``N^T R^T u`` on the elastic velocities."""
    b, off, n = v.pt_i[p, 0], v.pt_i[p, 1], v.pt_i[p, 2]
    uB, t = v.v3[4], v.v3[5]
    tmatvec3(v.R[b], u, uB)
    cross3(v.ps[p], uB, t)
    for c in range(3):
        v.J[row, side, c] += sign * u[c]
        v.J[row, side, 3 + c] += sign * t[c]
    _add_elastic(v, v.pt_N, row, side, off, n, uB, sign)


@inline
def _add_elastic(v, table, row, side, off, n, uB, sign):
    """Add ``sign table^T uB`` (``table`` a point's (3, n) block at ``off``: ``N`` or ``P``) to the elastic
    part of side ``side`` of constraint row ``row``."""
    j0 = v.row_je[row, side]
    for q in range(n):
        acc = 0.0
        for c in range(3):
            acc += table[off + c * n + q] * uB[c]
        v.Je[j0 + q] += sign * acc


@inline
def add_turn(v, row, side, p, u, u0, sign):
    """Add ``sign`` times the rate of ``d . x`` through the turn of point ``p``'s section to side ``side``
    of constraint row ``row``, for a direction ``d`` fixed in the section (``viz3d.joint_axes``): ``u = d
    x x`` (world) gives ``R^T u`` on ``B_omega`` and ``u0 = d0 x x`` (``d0`` the direction in the
    undeformed section, ``R`` times its body components) gives ``P^T R^T u0`` on the elastic velocities
    (none on rigid bodies)."""
    b, off, n = v.pt_i[p, 0], v.pt_i[p, 1], v.pt_i[p, 2]
    uB = v.v3[4]
    tmatvec3(v.R[b], u, uB)
    for c in range(3):
        v.J[row, side, 3 + c] += sign * uB[c]
    if n > 0:
        tmatvec3(v.R[b], u0, uB)
        _add_elastic(v, v.pt_P, row, side, off, n, uB, sign)


@inline
def bias(v, p, out):
    """``J_dot v`` of point ``p`` (3,) [m/s^2], world: ``w x (w x rho) + 2 w x (R N eta_dot)``."""
    b = v.pt_i[p, 0]
    t = v.v3[6]
    cross3(v.wW[b], v.prho[p], t)
    cross3(v.wW[b], t, out)
    cross3(v.wW[b], v.pud[p], t)
    for c in range(3):
        out[c] += 2.0 * t[c]

"""Holonomic joints, each class a vectorized set of joints of one type.

A joint set of ``nj`` joints with ``n_eq`` equations each provides, at a ``Configuration``,

* ``residual``: the constraint ``C``, shape (nj, n_eq),
* ``jacobian``: ``C_v`` per side, as a frame part (nj, n_eq, 2, 6) on each body's twist
  ``[W_v, B_omega]`` (side 0 = body 1, side 1 = body 2) and an elastic part (nj, n_eq, 2, n_e) on the
  stacked elastic velocities (a side attached to a section of a flexible body),
* ``gamma``: the acceleration right-hand side, shape (nj, n_eq), with ``C_v @ v_dot = gamma``.

The sides are material points (``viz3d.points.BodyPoints``), so a joint attaches to any point of
any body, including a section of a flexible bar. Bodies are indices into the pose arrays; ground is
index ``nb``. See docs/notation.md and docs/extending.md ("Add a joint").
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.compiled import Items, compiled_piece, cross3, dot3, inline, items, row_piece
from viz3d.joint_axes import SideAxes, side_axes, unit
from viz3d.kinematics import Configuration
from viz3d.points import BodyPoints, add_row, add_turn, bias, rigid_points
from viz3d.rotations import cross
from viz3d.timefunctions import profile, profile_value


@dataclass(frozen=True)
class Joint(ABC):
    """Base class of a joint set. Subclasses implement ``residual``, ``jacobian``, ``gamma``.

    Attributes
    ----------
    names : tuple of str, length nj
    body : ndarray of int, shape (nj, 2)
        Body indices of the two sides; ``nb`` means ground.
    """

    type_name: ClassVar[str]
    n_eq: ClassVar[int]
    #: Row providers that are not joints (contact rows, ``viz3d.contact.contacts.ContactRows``) say False.
    is_joint: ClassVar[bool] = True
    #: Rows with an explicit time dependence (``time_rate``; drives) say True.
    rheonomic: ClassVar[bool] = False

    names: tuple[str, ...]
    body: IntArray

    @property
    def n_joints(self) -> int:
        return len(self.names)

    @abstractmethod
    def residual(self, cfg: Configuration) -> FloatArray:
        """Constraint values ``C``, shape (nj, n_eq)."""

    @abstractmethod
    def jacobian(self, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
        """Velocity Jacobian blocks: frame (nj, n_eq, 2, 6) and elastic (nj, n_eq, 2, n_e)."""

    @abstractmethod
    def gamma(self, cfg: Configuration) -> FloatArray:
        """Acceleration right-hand side ``gamma = -C_v_dot @ v``, shape (nj, n_eq)."""

    def rows(self, cfg: Configuration) -> tuple[FloatArray, tuple[FloatArray, FloatArray], FloatArray]:
        """``(residual, jacobian, gamma)`` at ``cfg`` (what the constraint assembly asks of every row
        provider; a provider whose three share work overrides this to do it once)."""
        return self.residual(cfg), self.jacobian(cfg), self.gamma(cfg)

    def time_rate(self, cfg: Configuration) -> FloatArray:
        """``C_t``, shape (nj, n_eq): the part of ``C_dot = C_v v + C_t`` that is not through the
        velocities (``rheonomic`` providers, ``JointDrive``); zero for the scleronomic ones."""
        return np.zeros((self.n_joints, self.n_eq))

    def reaction_force(self, J: FloatArray, lam: FloatArray) -> FloatArray:
        """World force on body 1 of each joint, shape (..., nj, 3) [N], from the frame Jacobian blocks
        (..., nj, n_eq, 2, 6) and the multipliers (..., nj, n_eq) (leading axes: instants).

        The constraint force on the bodies is ``-C_v^T lam`` (docs/notation.md, sign of lambda);
        its translational part on side 0 is this reaction.
        """
        return -np.einsum("...jei,...je->...ji", J[..., 0, :3], lam)


class RowsJoint(Joint):
    """A joint set whose residual, Jacobian and gamma share their work: it implements ``rows`` only."""

    @abstractmethod
    def rows(self, cfg):
        """``(residual, (J, Je), gamma)`` (``Joint.rows``)."""

    def residual(self, cfg):
        return self.rows(cfg)[0]

    def jacobian(self, cfg):
        return self.rows(cfg)[1]

    def gamma(self, cfg):
        return self.rows(cfg)[2]


@dataclass(frozen=True)
class BallJoint(Joint):
    """Ball joint (rotula): point ``p1`` of body 1 coincides with point ``p2`` of body 2.

    ``C = p1 - p2`` (3 equations), as in seed 000; ``C_v = J_p1 - J_p2`` and ``gamma = -(J_dot v)_1 +
    (J_dot v)_2``, the points' velocity Jacobians and bias accelerations (``viz3d.points``): on rigid
    bodies ``C_v = [I, -R1 skew(s1) | -I, R2 skew(s2)]`` and ``gamma = -w1 x (w1 x rho1) + w2 x (w2 x
    rho2)``.

    Attributes
    ----------
    B_s : ndarray, shape (nj, 2, 3)
        The joint point in each body's frame, from its frame origin [m] (ground: the world point;
        a flexible body: the undeformed point).
    sides : tuple of BodyPoints, optional
        The two sides' material points (default: rigid points at ``B_s``).
    """

    type_name = "ball"
    n_eq = 3

    B_s: FloatArray = field(default=None)
    sides: tuple[BodyPoints, BodyPoints] | None = field(default=None)

    def __post_init__(self):
        if self.sides is None:
            sides = tuple(rigid_points(self.body[:, k], self.B_s[:, k]) for k in (0, 1))
            object.__setattr__(self, "sides", sides)

    @property
    def n_elastic(self) -> int:
        return self.sides[0].n_elastic

    def points(self, cfg: Configuration) -> FloatArray:
        """World joint points of side 0 (on body 1), shape (nj, 3) [m]."""
        return self.sides[0].positions(cfg)

    def residual(self, cfg):
        return self.sides[0].positions(cfg) - self.sides[1].positions(cfg)

    def jacobian(self, cfg):
        return point_jacobian(self.sides, cfg)

    def gamma(self, cfg):
        return self.sides[1].bias(cfg) - self.sides[0].bias(cfg)

    def compiled(self, pack) -> Items:
        rows = pack.row_start(self) + 3 * np.arange(self.n_joints)
        i = np.column_stack([rows, pack.points(self.sides[0]), pack.points(self.sides[1])])
        return items(BallItems, i, k=self.n_joints)


class BallItems(Items):
    """Ball joints: i = [first row, point on body 1, point on body 2]."""


@compiled_piece(row_piece, BallItems)
def _ball(d, t, v):
    for k in range(d.i.shape[0]):
        point_rows(v, d.i[k, 0], d.i[k, 1], d.i[k, 2])


@inline
def point_rows(v, r0, p1, p2):
    """Rows ``r0 .. r0 + 2``: point ``p1`` coincides with point ``p2`` (``C = x1 - x2``, world axes)."""
    e, a1, a2 = v.v3[8], v.v3[9], v.v3[10]
    bias(v, p1, a1)
    bias(v, p2, a2)
    for c in range(3):
        e[0], e[1], e[2] = 0.0, 0.0, 0.0
        e[c] = 1.0
        add_row(v, r0 + c, 0, p1, e, 1.0)
        add_row(v, r0 + c, 1, p2, e, -1.0)
        v.C[r0 + c] = v.px[p1, c] - v.px[p2, c]
        v.gam[r0 + c] = a2[c] - a1[c]


def point_jacobian(sides: tuple[BodyPoints, BodyPoints], cfg: Configuration) -> tuple[FloatArray, FloatArray]:
    """``C_v`` of ``C = x1 - x2`` (3 rows per joint): frame (nj, 3, 2, 6) and elastic (nj, 3, 2, n_e) parts."""
    nj, ne = sides[0].k, sides[0].n_elastic
    J = np.zeros((nj, 3, 2, 6))
    Je = np.zeros((nj, 3, 2, ne))
    for k, sign in ((0, 1.0), (1, -1.0)):
        Jf, Jel = sides[k].jacobian(cfg)
        J[:, :, k, :] = sign * Jf
        Je[:, :, k, :] = sign * Jel
    return J, Je




# ---------------------------------------------------------------------------- joints with frames


@dataclass(frozen=True)
class FramedJoint(RowsJoint):
    """A joint with a frame on each side: a point ``p_k`` and orthonormal axes ``a_k = R_k A_k``
    (columns x, y, z) fixed in body k; the scene makes both frames coincide in its initial
    configuration, so every relative coordinate starts at zero. The equations come from three
    primitives (Haug, *Computer-Aided Kinematics and Dynamics*, ch. 9), chosen by the subclass:

    * ``POINT``: ``p1 - p2 = 0``, 3 rows (world axes), as the ball joint;
    * ``PERPENDICULAR`` pairs ``(i, j)``: ``a1_i . a2_j = 0``, one row each, with
      ``C_v = [0, R1^T (a1_i x a2_j) | 0, -R2^T (a1_i x a2_j)]`` and
      ``gamma = -(w1 - w2) . ((w1 x a1_i) x a2_j + a1_i x (w2 x a2_j))``;
    * ``ON_PLANE`` axes ``i``: ``a1_i . (p2 - p1) = 0``, one row each, with
      ``C_v = a1_i^T (J_p2 - J_p1) + [0, R1^T (a1_i x d) | 0]`` and
      ``gamma = -((w1 x (w1 x a1_i)) . d + 2 (w1 x a1_i) . d_dot + a1_i . (b2 - b1))``,
      ``d = p2 - p1``, ``b`` the points' bias accelerations (``viz3d.points``).

    Rows are ordered point, perpendicular, on-plane. A side may be a section of a flexible body: its
    point is the section's material point and its axes turn with the section (``viz3d.joint_axes``:
    ``a = R (A + theta x A)``, ``theta = P eta``), which adds elastic columns to every row and the
    section's rotation rate to the axes' rates; the formulas above are the rigid case (the compiled
    piece ``_framed`` evaluates the general ones, with the sections' rotations from ``viz3d.points``).

    Attributes
    ----------
    B_s : ndarray, shape (nj, 2, 3)
        The joint point in each body's axes, from its centre of mass [m] (ground: world).
    B_A : ndarray, shape (nj, 2, 3, 3)
        Each side's joint axes (columns x, y, z) in its body's axes.
    sides : tuple of BodyPoints, optional
        The two sides' points (default: rigid points at ``B_s``).
    """

    POINT: ClassVar[bool] = True
    PERPENDICULAR: ClassVar[tuple[tuple[int, int], ...]] = ()
    ON_PLANE: ClassVar[tuple[int, ...]] = ()
    #: The relative coordinates the joint leaves free: (name, code of ``COORDINATES``).
    FREE: ClassVar[tuple[tuple[str, int], ...]] = ()

    B_s: FloatArray = field(default=None)
    B_A: FloatArray = field(default=None)
    sides: tuple[BodyPoints, BodyPoints] | None = field(default=None)

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.n_eq = 3 * cls.POINT + len(cls.PERPENDICULAR) + len(cls.ON_PLANE)

    def __post_init__(self):
        if self.sides is None:
            sides = tuple(rigid_points(self.body[:, k], self.B_s[:, k]) for k in (0, 1))
            object.__setattr__(self, "sides", sides)

    def points(self, cfg: Configuration) -> FloatArray:
        """World joint points of side 0 (on body 1), shape (nj, 3) [m]."""
        return self.sides[0].positions(cfg)

    def axes(self, R_WB: FloatArray) -> FloatArray:
        """World joint axes of both sides (columns), shape (..., nj, 2, 3, 3), from every body's
        rotation ``R_WB`` (..., nb + 1, 3, 3) (leading axes: instants)."""
        return R_WB[..., self.body, :, :] @ self.B_A

    def side_axes(self, cfg: Configuration) -> tuple[SideAxes, SideAxes]:
        """Both sides' joint axes at ``cfg`` (``viz3d.joint_axes``: on flexible sections they turn with
        the section)."""
        return side_axes(self.sides[0], self.B_A[:, 0], cfg), side_axes(self.sides[1], self.B_A[:, 1], cfg)

    def rows(self, cfg):
        nj, ne = self.n_joints, self.sides[0].n_elastic
        ax = self.side_axes(cfg)
        x = [s.positions(cfg) for s in self.sides]
        bias_ = [s.bias(cfg) for s in self.sides]
        C, J, Je, g = [], [], [], []
        if self.POINT:
            C.append(x[0] - x[1])
            Jp, Jpe = point_jacobian(self.sides, cfg)
            J.append(Jp)
            Je.append(Jpe)
            g.append(bias_[1] - bias_[0])
        for i, j in self.PERPENDICULAR:
            A, B = ax[0].a[:, :, i], ax[1].a[:, :, j]
            n = cross(A, B)
            Jr, Jre = np.zeros((nj, 1, 2, 6)), np.zeros((nj, 1, 2, ne))
            Jr[:, 0, 0], Jre[:, 0, 0] = ax[0].jacobian(unit(i), B, n)
            Jr[:, 0, 1], Jre[:, 0, 1] = ax[1].jacobian(unit(j), A, -n)
            (A_d, A_b), (B_d, B_b) = ax[0].motion(unit(i)), ax[1].motion(unit(j))
            C.append(_dot(A, B)[:, None])
            J.append(Jr)
            Je.append(Jre)
            g.append(-(_dot(A_b, B) + 2.0 * _dot(A_d, B_d) + _dot(A, B_b))[:, None])
        if self.ON_PLANE:
            d = x[1] - x[0]
            d_dot = self.sides[1].velocities(cfg) - self.sides[0].velocities(cfg)
            (Jf0, Je0), (Jf1, Je1) = (s.jacobian(cfg) for s in self.sides)
        for i in self.ON_PLANE:
            A = ax[0].a[:, :, i]
            Jr, Jre = np.zeros((nj, 1, 2, 6)), np.zeros((nj, 1, 2, ne))
            Jr[:, 0, 0], Jre[:, 0, 0] = ax[0].jacobian(unit(i), d)
            Jr[:, 0, 0] -= np.einsum("ki,kij->kj", A, Jf0)
            Jre[:, 0, 0] -= np.einsum("ki,kiq->kq", A, Je0)
            Jr[:, 0, 1] = np.einsum("ki,kij->kj", A, Jf1)
            Jre[:, 0, 1] = np.einsum("ki,kiq->kq", A, Je1)
            C.append(_dot(A, d)[:, None])
            J.append(Jr)
            Je.append(Jre)
            A_d, A_b = ax[0].motion(unit(i))
            g.append(-(_dot(A_b, d) + 2.0 * _dot(A_d, d_dot) + _dot(A, bias_[1] - bias_[0]))[:, None])
        return np.concatenate(C, axis=1), (np.concatenate(J, axis=1), np.concatenate(Je, axis=1)), np.concatenate(g, axis=1)

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """Names of the relative coordinates the joint leaves free: angles [rad], distances [m]."""
        return tuple(name for name, _ in self.FREE)

    def coordinates(self, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
        """The relative coordinates ``coordinate_names`` and their rates at ``cfg``, shapes (nj, m); on
        flexible sections from the section's axes and point (angle rates to first order in its rotation)."""
        if not self.on_flexible:
            return self.relative(cfg.pose.R_WB, cfg.pose.W_r, cfg.twist.W_v, cfg.twist.W_omega)
        ax = self.side_axes(cfg)
        e = self.sides[0].positions(cfg) - self.sides[1].positions(cfg)
        e_dot = self.sides[0].velocities(cfg) - self.sides[1].velocities(cfg)
        values, rates = [], []
        for _, code in self.FREE:
            q, u = coordinate(code, ax[0].a, ax[1].a, e)
            values.append(q)
            rates.append(_dot(u, e_dot) + _dot(ax[0].motion(unit(2))[0], e) if code == DISTANCE_Z
                         else _dot(ax[0].w + ax[0].Omega - ax[1].w - ax[1].Omega, u))
        shape = (self.n_joints, 0)
        return (np.stack(values, axis=-1) if values else np.zeros(shape),
                np.stack(rates, axis=-1) if rates else np.zeros(shape))

    def relative(self, R_WB: FloatArray, W_r: FloatArray, W_v: FloatArray, W_omega: FloatArray
                 ) -> tuple[FloatArray, FloatArray]:
        """Relative coordinates and rates, shapes (..., nj, m), from every body's pose and twist
        (..., nb + 1, ...), ground last (leading axes: instants): the motion of body 1 relative to
        body 2 (the reference; ground by default), zero in the initial configuration (``COORDINATES``).
        Rates are exact on the constraint manifold."""
        a = self.axes(R_WB)
        rho = (R_WB[..., self.body, :, :] @ self.B_s[..., None])[..., 0]
        p = W_r[..., self.body, :] + rho
        p_dot = W_v[..., self.body, :] + cross(W_omega[..., self.body, :], rho)
        w = W_omega[..., self.body, :]
        e, e_dot = p[..., 0, :] - p[..., 1, :], p_dot[..., 0, :] - p_dot[..., 1, :]
        values, rates = [], []
        for _, code in self.FREE:
            q, u = coordinate(code, a[..., 0, :, :], a[..., 1, :, :], e)
            values.append(q)
            rates.append(_dot(u, e_dot) + _dot(cross(w[..., 0, :], u), e) if code == DISTANCE_Z
                         else _dot(w[..., 0, :] - w[..., 1, :], u))
        shape = a.shape[:-3] + (0,)
        return (np.stack(values, axis=-1) if values else np.zeros(shape),
                np.stack(rates, axis=-1) if rates else np.zeros(shape))

    @property
    def on_flexible(self) -> bool:
        """Some joint of the set has a side on a section of a flexible body."""
        return any(s.flex for s in self.sides)

    def compiled(self, pack) -> Items:
        n = self.n_joints
        rows = pack.row_start(self) + self.n_eq * np.arange(n)
        code = np.zeros((n, 11), np.int64)
        code[:, 0] = self.POINT
        code[:, 1], code[:, 2] = len(self.PERPENDICULAR), len(self.ON_PLANE)
        code[:, 3:3 + 2 * len(self.PERPENDICULAR)] = np.ravel(self.PERPENDICULAR)
        code[:, 9:9 + len(self.ON_PLANE)] = self.ON_PLANE
        i = np.column_stack([rows, pack.points(self.sides[0]), pack.points(self.sides[1]), code])
        return items(FramedItems, i, self.B_A.reshape(n, 18), k=n)


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.einsum("...i,...i->...", a, b)


#: Relative coordinates of body 1 to body 2 by code, from the world joint axes ``x_k, y_k, z_k``
#: of both sides and ``e = p1 - p2``, with the world axis ``u`` they turn about or slide along:
#: ANGLE_Z ``-atan2(x2 . y1, x2 . x1)`` about ``z1``; ANGLE_X1 ``-atan2(y2 . z1, y2 . y1)`` about
#: ``x1``; ANGLE_Y2 ``-atan2(z2 . x1, x2 . x1)`` about ``y2``; DISTANCE_Z ``z1 . e`` along ``z1``.
#: Rates: ``(w1 - w2) . u`` for angles, ``u . e_dot + (w1 x u) . e`` for the distance.
COORDINATES = ANGLE_Z, ANGLE_X1, ANGLE_Y2, DISTANCE_Z = range(4)
#: Each angle as ``q = -atan2(u . e2, u . e1)``: (side a, axis e1, axis e2 of side a, side b, axis u
#: of side b) (axes 0, 1, 2 = x, y, z of each side's joint frame), for the drives (``JointDrive``).
ANGLE_DRIVES = {ANGLE_Z: (0, 0, 1, 1, 0), ANGLE_X1: (0, 1, 2, 1, 1), ANGLE_Y2: (1, 0, 2, 0, 0)}


def coordinate(code: int, a1: FloatArray, a2: FloatArray, e: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Value (...,) and world axis (..., 3) of coordinate ``code`` from both sides' axes (..., 3, 3)
    (columns x, y, z) and ``e = p1 - p2`` (..., 3)."""
    x1, y1, z1 = a1[..., :, 0], a1[..., :, 1], a1[..., :, 2]
    x2, y2, z2 = a2[..., :, 0], a2[..., :, 1], a2[..., :, 2]
    if code == ANGLE_Z:
        return -np.arctan2(_dot(x2, y1), _dot(x2, x1)), z1
    if code == ANGLE_X1:
        return -np.arctan2(_dot(y2, z1), _dot(y2, y1)), x1
    if code == ANGLE_Y2:
        return -np.arctan2(_dot(z2, x1), _dot(x2, x1)), y2
    return _dot(z1, e), z1


@dataclass(frozen=True)
class RevoluteJoint(FramedJoint):
    """Revolute joint (hinge) about the joint z axis: the points coincide and ``z1`` stays normal to
    ``x2`` and ``y2`` (5 equations). Coordinate: ``angle``, the turn of body 1 about the axis."""

    type_name = "revolute"
    PERPENDICULAR = ((2, 0), (2, 1))
    FREE = (("angle", ANGLE_Z),)


@dataclass(frozen=True)
class UniversalJoint(FramedJoint):
    """Universal (Cardan) joint: the points coincide and the first axis ``x1`` (on body 1) stays normal
    to the second axis ``y2`` (on body 2): 4 equations, two relative rotations. Coordinates: ``angle1``
    about ``x1`` and ``angle2`` about ``y2``: body 1's joint frame is body 2's turned by
    ``Ry(angle2) Rx(angle1)`` (axes of body 2's joint frame); the third relative rotation, about
    ``x1 x y2``, is what the constraint removes."""

    type_name = "universal"
    PERPENDICULAR = ((0, 1),)
    FREE = (("angle1", ANGLE_X1), ("angle2", ANGLE_Y2))


@dataclass(frozen=True)
class PrismaticJoint(FramedJoint):
    """Prismatic joint (slider) along the joint z axis: the frames keep their orientation (``z1``
    normal to ``x2``, ``y2``; ``x1`` normal to ``y2``) and ``p2`` stays on the line through ``p1``
    along ``z1`` (5 equations). Coordinate: ``distance`` ``z . (p1 - p2)``, body 1's slide along the axis."""

    type_name = "prismatic"
    POINT = False
    PERPENDICULAR = ((2, 0), (2, 1), (0, 1))
    ON_PLANE = (0, 1)
    FREE = (("distance", DISTANCE_Z),)


@dataclass(frozen=True)
class CylindricalJoint(FramedJoint):
    """Cylindrical joint: turns about and slides along the joint z axis (4 equations: ``z1`` normal to
    ``x2``, ``y2``; ``p2`` on the line through ``p1`` along ``z1``). Coordinates: ``angle``, ``distance``."""

    type_name = "cylindrical"
    POINT = False
    PERPENDICULAR = ((2, 0), (2, 1))
    ON_PLANE = (0, 1)
    FREE = (("angle", ANGLE_Z), ("distance", DISTANCE_Z))


@dataclass(frozen=True)
class FixedJoint(FramedJoint):
    """Fixed joint (weld): the points coincide and the frames keep their orientation (6 equations)."""

    type_name = "fixed"
    PERPENDICULAR = ((2, 0), (2, 1), (0, 1))


class FramedItems(Items):
    """Joints with frames: i = [first row, point 1, point 2, POINT, number of PERPENDICULAR pairs,
    number of ON_PLANE axes, the pairs (3 x 2), the axes (2)]; f = [A1, A2] row-major (18)."""


@inline
def _world_axis(v, f, side, b, i, out):
    """``out = R_b A[:, i]`` with ``A`` of side ``side`` row-major in ``f[9 side:]``."""
    k = 9 * side + i
    for r in range(3):
        out[r] = v.R[b, r, 0] * f[k] + v.R[b, r, 1] * f[k + 3] + v.R[b, r, 2] * f[k + 6]


@inline
def coordinate_of(v, f, code, q1, q2, p1, p2, u):
    """Compiled ``coordinate``: ``(value, rate)`` of coordinate ``code`` of a framed joint whose
    axes are packed in ``f`` (``FramedItems``), bodies ``q1``, ``q2``, points ``p1``, ``p2``; its world
    axis into ``u`` (3,). Scratch: ``v.v3[16:20]``."""
    A, B, e, w = v.v3[16], v.v3[17], v.v3[18], v.v3[19]
    for c in range(3):
        e[c] = v.px[p1, c] - v.px[p2, c]
    if code == DISTANCE_Z:
        _world_axis(v, f, 0, q1, 2, u)
        cross3(v.wW[q1], u, w)
        rate = dot3(w, e)
        for c in range(3):
            rate += u[c] * (v.pv[p1, c] - v.pv[p2, c])
        return dot3(u, e), rate
    if code == ANGLE_Z:  # -atan2(x2 . y1, x2 . x1) about z1
        _world_axis(v, f, 1, q2, 0, B)
        _world_axis(v, f, 0, q1, 1, A)
        sine = dot3(B, A)
        _world_axis(v, f, 0, q1, 0, A)
        _world_axis(v, f, 0, q1, 2, u)
    elif code == ANGLE_X1:  # -atan2(y2 . z1, y2 . y1) about x1
        _world_axis(v, f, 1, q2, 1, B)
        _world_axis(v, f, 0, q1, 2, A)
        sine = dot3(B, A)
        _world_axis(v, f, 0, q1, 1, A)
        _world_axis(v, f, 0, q1, 0, u)
    else:  # ANGLE_Y2: -atan2(z2 . x1, x2 . x1) about y2
        _world_axis(v, f, 0, q1, 0, A)
        _world_axis(v, f, 1, q2, 2, B)
        sine = dot3(B, A)
        _world_axis(v, f, 1, q2, 0, B)
        _world_axis(v, f, 1, q2, 1, u)
    cosine = dot3(B, A)
    rate = 0.0
    for c in range(3):
        rate += (v.wW[q1, c] - v.wW[q2, c]) * u[c]
    return -math.atan2(sine, cosine), rate


@inline
def _section_axis(v, f, side, p, i, alpha, a):
    """Axis ``i`` of side ``side`` (packed in ``f``, ``FramedItems``) at point ``p``: ``alpha = R A[:, i]``
    and ``a = alpha + theta x alpha`` (``theta = R P eta``, world: zero on rigid sides; ``SideAxes.a``)."""
    _world_axis(v, f, side, v.pt_i[p, 0], i, alpha)
    cross3(v.pth[p], alpha, a)
    for c in range(3):
        a[c] += alpha[c]


@inline
def _axis_motion(v, p, a, alpha, rate, acc, s, t):
    """``SideAxes.motion`` of the axis ``a`` (undeformed ``alpha``) at point ``p``: ``rate = w x a + s``
    and ``acc = w x (w x a) + 2 w x s``, ``s = Omega x alpha`` (``s``, ``t``: scratch)."""
    w = v.wW[v.pt_i[p, 0]]
    cross3(w, a, rate)
    cross3(w, rate, acc)
    cross3(v.pom[p], alpha, s)
    cross3(w, s, t)
    for c in range(3):
        rate[c] += s[c]
        acc[c] += 2.0 * t[c]


@compiled_piece(row_piece, FramedItems)
def _framed(d, t, v):
    A, A0, B, B0, n = v.v3[16], v.v3[17], v.v3[18], v.v3[19], v.v3[20]
    A_d, A_b, B_d, B_b, s = v.v3[21], v.v3[22], v.v3[23], v.v3[24], v.v3[25]
    b1, b2, t = v.v3[26], v.v3[27], v.v3[28]
    for k in range(d.i.shape[0]):
        r, p1, p2 = d.i[k, 0], d.i[k, 1], d.i[k, 2]
        f = d.f[k]
        if d.i[k, 3] == 1:
            point_rows(v, r, p1, p2)
            r += 3
        for e in range(d.i[k, 4]):  # a1_i . a2_j = 0
            _section_axis(v, f, 0, p1, d.i[k, 6 + 2 * e], A0, A)
            _section_axis(v, f, 1, p2, d.i[k, 7 + 2 * e], B0, B)
            v.C[r] = dot3(A, B)
            cross3(A, B, n)
            cross3(A0, B, s)
            add_turn(v, r, 0, p1, n, s, 1.0)
            cross3(A, B0, s)
            add_turn(v, r, 1, p2, n, s, -1.0)  # -(A x B) and B0 x A (d/dt of a1_i . a2_j through a2_j)
            _axis_motion(v, p1, A, A0, A_d, A_b, s, t)
            _axis_motion(v, p2, B, B0, B_d, B_b, s, t)
            v.gam[r] = -(dot3(A_b, B) + 2.0 * dot3(A_d, B_d) + dot3(A, B_b))
            r += 1
        if d.i[k, 5] > 0:
            bias(v, p1, b1)
            bias(v, p2, b2)
        for e in range(d.i[k, 5]):  # a1_i . (p2 - p1) = 0
            _section_axis(v, f, 0, p1, d.i[k, 12 + e], A0, A)
            for c in range(3):
                n[c] = v.px[p2, c] - v.px[p1, c]
                B_d[c] = v.pv[p2, c] - v.pv[p1, c]
            add_row(v, r, 0, p1, A, -1.0)
            add_row(v, r, 1, p2, A, 1.0)
            cross3(A, n, B)
            cross3(A0, n, s)
            add_turn(v, r, 0, p1, B, s, 1.0)
            v.C[r] = dot3(A, n)
            _axis_motion(v, p1, A, A0, A_d, A_b, s, t)
            acc = dot3(A_b, n) + 2.0 * dot3(A_d, B_d)
            for c in range(3):
                acc += A[c] * (b2[c] - b1[c])
            v.gam[r] = -acc
            r += 1




# ---------------------------------------------------------------------------- drives


@dataclass(frozen=True)
class JointDrive(RowsJoint):
    """Drives: rheonomic constraints that prescribe a joint coordinate ``q`` (``FramedJoint``, body 1
    relative to body 2) as a profile ``r(t)`` (``viz3d.timefunctions.profile``: the position, or the
    velocity integrated from zero), one row each, ``C`` equal to ``q - r`` to first order:

    * an angle (ANGLE_Z, ANGLE_X1, ANGLE_Y2; ``ANGLE_DRIVES``): the coordinate is
      ``q = -atan2(u . e2, u . e1)`` for two axes ``e1, e2`` of one side (``a``) and an axis ``u`` of
      the other (``b``); ``C = -u . w`` with ``w = cos(r) e2 + sin(r) e1`` turning with the profile, so
      ``C = sin(q - r)`` on the joint's manifold; ``C_v`` is ``R_a^T N`` on side a and ``-R_b^T N``
      on side b (``N = u x w``), ``C_t = r_dot (u . m)`` with ``m = sin(r) e2 - cos(r) e1``;
    * a distance along ``z1`` (DISTANCE_Z): ``C = z1 . (p1 - p2) - r``.

    ``C_dot = C_v v + C_t``; the generalized force the drive exerts on its coordinate (the driving
    torque or force) is ``-lam`` (``effort``).

    Attributes
    ----------
    joints : tuple of FramedJoint, length k
    index, free : ndarray of int, shape (k,)
        The joint within its set and the coordinate within its ``FREE``.
    kind : ndarray of int, shape (k,)
        Time-function kind of the profile (``viz3d.timefunctions.TIME_FUNCTIONS``).
    velocity : ndarray of int, shape (k,)
        1: the profile is the velocity (``r`` its integral from 0); 0: the position.
    table : ndarray, shape (k, 10)
        ``TimeFunctions.table`` rows of the profiles (first component).
    """

    type_name = "drive"
    n_eq = 1
    rheonomic = True

    joints: tuple = ()
    index: IntArray = field(default=None)
    free: IntArray = field(default=None)
    kind: IntArray = field(default=None)
    velocity: IntArray = field(default=None)
    table: FloatArray = field(default=None)


    def profiles(self, t: float) -> FloatArray:
        """``(r, r_dot, r_ddot)`` of every drive at ``t``, shape (k, 3)."""
        return np.array([profile_value(k, v, f, t) for k, v, f in zip(self.kind, self.velocity, self.table)]).reshape(-1, 3)

    def points(self, cfg: Configuration) -> FloatArray:
        """The driven joints' points on body 1, shape (k, 3) [m]."""
        return np.array([js.points(cfg)[j] for js, j in zip(self.joints, self.index)]).reshape(-1, 3)

    def rows(self, cfg):
        return self._rows(cfg)[:3]

    def time_rate(self, cfg):
        return self._rows(cfg)[3]

    def _rows(self, cfg):
        k, ne = len(self.names), self.joints[0].sides[0].n_elastic if self.joints else 0
        C, J, Je, g, C_t = np.zeros((k, 1)), np.zeros((k, 1, 2, 6)), np.zeros((k, 1, 2, ne)), np.zeros((k, 1)), np.zeros((k, 1))
        axes = {id(js): js.side_axes(cfg) for js in self.joints}  # once per joint set
        for i, ((r, r_d, r_dd), js, j, c) in enumerate(zip(self.profiles(cfg.t), self.joints, self.index, self.free)):
            ax = tuple(_joint_axes(a, j) for a in axes[id(js)])
            code = js.FREE[c][1]
            if code != DISTANCE_Z:
                C[i], (J[i, 0], Je[i, 0]), g[i], C_t[i] = _angle_row(ax, ANGLE_DRIVES[code], r, r_d, r_dd)
            else:
                sides = [js.sides[s].subset([j]) for s in (0, 1)]
                C[i], (J[i, 0], Je[i, 0]), g[i], C_t[i] = _distance_row(ax[0], sides, cfg, r, r_d, r_dd)
        return C, (J, Je), g, C_t

    def effort(self, lam: FloatArray) -> FloatArray:
        """The generalized force each drive exerts on its coordinate, ``-lam`` [N m or N], shape (..., k)."""
        return -lam

    def compiled(self, pack) -> Items:
        k = len(self.names)
        rows_i, rows_f = [], []
        for i, (js, j, c) in enumerate(zip(self.joints, self.index, self.free)):
            pts = [pack.points(js.sides[s].subset([j]))[0] for s in (0, 1)]
            code = js.FREE[c][1]
            angle = ANGLE_DRIVES.get(code, (0, 0, 0, 0, 0))
            rows_i.append([pack.row_start(self) + i, pts[0], pts[1], code, self.kind[i], self.velocity[i], *angle])
            rows_f.append([*js.B_A[j].reshape(18), *self.table[i]])
        return items(DriveItems, rows_i, rows_f, k=k)


def _joint_axes(ax: SideAxes, j: int) -> SideAxes:
    """Joint ``j``'s axes of a side (a ``SideAxes`` of one joint)."""
    return SideAxes(*(x[[j]] for x in (ax.a, ax.alpha, ax.R, ax.w, ax.Omega, ax.G)), rigid=ax.rigid)


def _angle_row(ax: tuple[SideAxes, SideAxes], drive: tuple, r: float, r_d: float, r_dd: float):
    """``(C, (J (2, 6), Je (2, n_e)), gamma, C_t)`` of a drive on the angle ``-atan2(u . e2, u . e1)``
    (``ANGLE_DRIVES`` row ``drive``): ``C = -u . w``, ``w = a_a c`` with ``c = cos(r) E_e2 + sin(r) E_e1``,
    ``m = a_a c_m``, ``c_m = sin(r) E_e2 - cos(r) E_e1`` (``dc/dt = -r_d c_m``, ``dc_m/dt = r_d c``)."""
    sa, i1, i2, sb, iu = drive
    A, B = ax[sa], ax[sb]
    c = np.cos(r) * unit(i2) + np.sin(r) * unit(i1)
    c_m = np.sin(r) * unit(i2) - np.cos(r) * unit(i1)
    u, w, m = B.vector(unit(iu))[0], A.vector(c)[0], A.vector(c_m)[0]
    u_d, u_b = (x[0] for x in B.motion(unit(iu)))
    w_d, w_b = (x[0] for x in A.motion(c))
    m_d = A.motion(c_m)[0][0]
    w_d = w_d - r_d * m
    w_bias = w_b - 2.0 * r_d * m_d - r_dd * m - r_d * r_d * w
    J, Je = np.zeros((2, 6)), np.zeros((2, A.G.shape[2]))
    (J[sa], Je[sa]), (J[sb], Je[sb]) = A.jacobian(c, -u[None]), B.jacobian(unit(iu), -w[None])
    gamma = u_b @ w + 2.0 * u_d @ w_d + u @ w_bias
    return -u @ w, (J, Je), gamma, r_d * (u @ m)


def _distance_row(ax: SideAxes, sides: list[BodyPoints], cfg: Configuration, r: float, r_d: float, r_dd: float):
    """``(C, (J (2, 6), Je (2, n_e)), gamma, C_t)`` of a drive on the distance ``z1 . (p1 - p2)``
    (``sides``: the joint's two points, ``ax`` side 1's axes)."""
    z = ax.vector(unit(2))[0]
    e = sides[0].positions(cfg)[0] - sides[1].positions(cfg)[0]
    e_d = sides[0].velocities(cfg)[0] - sides[1].velocities(cfg)[0]
    (J1, Je1), (J2, Je2) = (sd.jacobian(cfg) for sd in sides)
    Jz, Jze = ax.jacobian(unit(2), e[None])
    J = np.stack([z @ J1[0] + Jz[0], -(z @ J2[0])])
    Je = np.stack([z @ Je1[0] + Jze[0], -(z @ Je2[0])])
    b = sides[0].bias(cfg)[0] - sides[1].bias(cfg)[0]
    z_d, z_b = (x[0] for x in ax.motion(unit(2)))
    gamma = r_dd - (z_b @ e + 2.0 * z_d @ e_d + z @ b)
    return z @ e - r, (J, Je), gamma, -r_d


class DriveItems(Items):
    """Drives: i = [row, point 1, point 2, coordinate code, profile kind, velocity profile, the angle's
    ``ANGLE_DRIVES`` row (5)]; f = [A1, A2 (18), ``TimeFunctions.table`` row (10)]."""


@compiled_piece(row_piece, DriveItems)
def _drive(d, t, v):
    e1, e1_0, e2, e2_0, u, u0 = v.v3[16], v.v3[17], v.v3[18], v.v3[19], v.v3[20], v.v3[21]
    w, w0, m, m0, N, s = v.v3[22], v.v3[23], v.v3[24], v.v3[25], v.v3[26], v.v3[27]
    u_d, u_b, w_d, w_b, m_d, m_b, t1 = v.v3[28], v.v3[29], v.v3[30], v.v3[31], v.v3[32], v.v3[33], v.v3[34]
    for k in range(d.i.shape[0]):
        row, p1, p2 = d.i[k, 0], d.i[k, 1], d.i[k, 2]
        f = d.f[k]
        r, r_d, r_dd = profile(d.i[k, 4], d.i[k, 5], f[18:28], t)
        if d.i[k, 3] != DISTANCE_Z:  # _angle_row: axes e1, e2 of side a, u of side b (ANGLE_DRIVES)
            sa, sb = d.i[k, 6], d.i[k, 9]
            pa, pb = (p1, p2) if sa == 0 else (p2, p1)
            _section_axis(v, f, sa, pa, d.i[k, 7], e1_0, e1)
            _section_axis(v, f, sa, pa, d.i[k, 8], e2_0, e2)
            _section_axis(v, f, sb, pb, d.i[k, 10], u0, u)
            cr, sr = math.cos(r), math.sin(r)
            for c in range(3):
                w[c] = cr * e2[c] + sr * e1[c]
                w0[c] = cr * e2_0[c] + sr * e1_0[c]
                m[c] = sr * e2[c] - cr * e1[c]
                m0[c] = sr * e2_0[c] - cr * e1_0[c]
            v.C[row] = -dot3(u, w)
            v.Ct[row] = r_d * dot3(u, m)
            cross3(u, w, N)                                         # N = u x w
            cross3(u, w0, s)
            add_turn(v, row, sa, pa, N, s, 1.0)
            cross3(u0, w, s)
            add_turn(v, row, sb, pb, N, s, -1.0)
            _axis_motion(v, pb, u, u0, u_d, u_b, s, t1)
            _axis_motion(v, pa, w, w0, w_d, w_b, s, t1)
            _axis_motion(v, pa, m, m0, m_d, m_b, s, t1)
            for c in range(3):
                w_d[c] -= r_d * m[c]
                w_b[c] -= 2.0 * r_d * m_d[c] + r_dd * m[c] + r_d * r_d * w[c]
            v.gam[row] = dot3(u_b, w) + 2.0 * dot3(u_d, w_d) + dot3(u, w_b)
        else:  # _distance_row: z1 . (p1 - p2) = r
            _section_axis(v, f, 0, p1, 2, e1_0, e1)                # z1
            for c in range(3):
                N[c] = v.px[p1, c] - v.px[p2, c]                    # e
                m[c] = v.pv[p1, c] - v.pv[p2, c]                    # e_dot
            add_row(v, row, 0, p1, e1, 1.0)
            add_row(v, row, 1, p2, e1, -1.0)
            cross3(e1, N, w)
            cross3(e1_0, N, s)
            add_turn(v, row, 0, p1, w, s, 1.0)
            v.C[row] = dot3(e1, N) - r
            v.Ct[row] = -r_d
            bias(v, p1, e2)
            bias(v, p2, u)
            _axis_motion(v, p1, e1, e1_0, u_d, u_b, s, t1)
            acc = dot3(u_b, N) + 2.0 * dot3(u_d, m)
            for c in range(3):
                acc += e1[c] * (e2[c] - u[c])
            v.gam[row] = r_dd - acc


def relative_coordinates(joints, R_WB: FloatArray, W_r: FloatArray, W_v: FloatArray, W_omega: FloatArray,
                         cfg: Configuration | None = None) -> dict[str, FloatArray]:
    """Every joint's relative coordinates and rates as named values: ``joint/<name>/<coordinate>``
    [rad or m] and ``joint/<name>/<coordinate>_rate`` [rad/s or m/s], each of the leading shape of
    the poses and twists (..., nb + 1, ...) (leading axes: instants), from ``joints`` (joint sets).
    Joints on flexible sections need the deformation: they are reported only when ``cfg`` (the
    configuration of a single instant) is given."""
    out: dict[str, FloatArray] = {}
    for js in joints:
        if not getattr(js, "coordinate_names", ()):
            continue
        if js.on_flexible and cfg is None:
            continue
        values, rates = js.coordinates(cfg) if js.on_flexible else js.relative(R_WB, W_r, W_v, W_omega)
        for j, name in enumerate(js.names):
            for c, free in enumerate(js.coordinate_names):
                out[f"joint/{name}/{free}"] = values[..., j, c]
                out[f"joint/{name}/{free}_rate"] = rates[..., j, c]
    return out


JOINTS: dict[str, type[Joint]] = {cls.type_name: cls for cls in (BallJoint, RevoluteJoint, UniversalJoint,
                                                                 PrismaticJoint, CylindricalJoint, FixedJoint)}
#: Rheonomic row providers (a drive prescribes a joint's coordinate; scene ``[[drives]]``).
DRIVES: dict[str, type[Joint]] = {JointDrive.type_name: JointDrive}


def drive_efforts(joints, row_slices, lam: FloatArray) -> dict[str, FloatArray]:
    """``drive/<name>/effort``: the torque or force each drive exerts on its coordinate [N m or N],
    of the leading shape of ``lam`` (..., n_c) (leading axes: instants), from the row providers
    ``joints`` and their ``row_slices``."""
    out: dict[str, FloatArray] = {}
    for js, sl in zip(joints, row_slices):
        if isinstance(js, JointDrive):
            effort = js.effort(lam[..., sl])
            for k, name in enumerate(js.names):
                out[f"drive/{name}/effort"] = effort[..., k]
    return out

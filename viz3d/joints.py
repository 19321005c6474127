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

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.compiled import Items, compiled_piece, items, row_piece
from viz3d.kinematics import Configuration
from viz3d.points import BodyPoints, add_row, bias, rigid_points


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

    def reaction_force(self, J: FloatArray, lam: FloatArray) -> FloatArray:
        """World force on body 1 of each joint, shape (..., nj, 3) [N], from the frame Jacobian blocks
        (..., nj, n_eq, 2, 6) and the multipliers (..., nj, n_eq) (leading axes: instants).

        The constraint force on the bodies is ``-C_v^T lam`` (docs/notation.md, sign of lambda);
        its translational part on side 0 is this reaction.
        """
        return -np.einsum("...jei,...je->...ji", J[..., 0, :3], lam)


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
        nj, ne = self.n_joints, self.n_elastic
        J = np.zeros((nj, 3, 2, 6))
        Je = np.zeros((nj, 3, 2, ne))
        for k, sign in ((0, 1.0), (1, -1.0)):
            Jf, Jel = self.sides[k].jacobian(cfg)
            J[:, :, k, :] = sign * Jf
            Je[:, :, k, :] = sign * Jel
        return J, Je

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
    e, a1, a2 = v.v3[8], v.v3[9], v.v3[10]
    for k in range(d.i.shape[0]):
        r0, p1, p2 = d.i[k, 0], d.i[k, 1], d.i[k, 2]
        bias(v, p1, a1)
        bias(v, p2, a2)
        for c in range(3):
            e[0], e[1], e[2] = 0.0, 0.0, 0.0
            e[c] = 1.0
            add_row(v, r0 + c, 0, p1, e, 1.0)
            add_row(v, r0 + c, 1, p2, e, -1.0)
            v.C[r0 + c] = v.px[p1, c] - v.px[p2, c]
            v.gam[r0 + c] = a2[c] - a1[c]


JOINTS: dict[str, type[Joint]] = {cls.type_name: cls for cls in (BallJoint,)}

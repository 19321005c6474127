"""Holonomic joints, each class a vectorized set of joints of one type.

A joint set of ``nj`` joints with ``n_eq`` equations each provides, at a pose and twist,

* ``residual``: the constraint ``C``, shape (nj, n_eq),
* ``jacobian``: ``C_v`` per side, shape (nj, n_eq, 2, 6), the derivative of ``C_dot`` with
  respect to each body's velocity ``[W_v, B_omega]`` (side 0 = body 1, side 1 = body 2),
* ``gamma``: the acceleration right-hand side, shape (nj, n_eq), with ``C_v @ v_dot = gamma``.

Bodies are indices into the pose arrays; ground is index ``nb``. See docs/notation.md and
docs/extending.md ("Add a joint").
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.kinematics import Pose, Twist
from viz3d.rotations import cross, skew


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

    names: tuple[str, ...]
    body: IntArray

    @property
    def n_joints(self) -> int:
        return len(self.names)

    @abstractmethod
    def residual(self, pose: Pose) -> FloatArray:
        """Constraint values ``C``, shape (nj, n_eq)."""

    @abstractmethod
    def jacobian(self, pose: Pose) -> FloatArray:
        """Velocity Jacobian blocks, shape (nj, n_eq, 2, 6)."""

    @abstractmethod
    def gamma(self, pose: Pose, twist: Twist) -> FloatArray:
        """Acceleration right-hand side ``gamma = -C_v_dot @ v``, shape (nj, n_eq)."""

    def reaction_force(self, J: FloatArray, lam: FloatArray) -> FloatArray:
        """World force on body 1 of each joint, shape (nj, 3) [N].

        The constraint force on the bodies is ``-C_v^T lam`` (docs/notation.md, sign of lambda);
        its translational part on side 0 is this reaction.
        """
        return -np.einsum("jei,je->ji", J[:, :, 0, :3], lam)


@dataclass(frozen=True)
class BallJoint(Joint):
    """Ball joint (rotula): point ``s1`` of body 1 coincides with point ``s2`` of body 2.

    ``C = W_r1 + R1 s1 - W_r2 - R2 s2`` (3 equations), as in seed 000. With
    ``rho_i = R_i s_i``: ``C_v = [I, -R1 skew(s1) | -I, R2 skew(s2)]`` and
    ``gamma = -w1 x (w1 x rho1) + w2 x (w2 x rho2)`` (world angular velocities ``w``).

    Attributes
    ----------
    B_s : ndarray, shape (nj, 2, 3)
        The joint point in each body's frame, from its centre of mass [m]; for ground, the
        world point.
    """

    type_name = "ball"
    n_eq = 3

    B_s: FloatArray = field(default=None)
    _R_skew_sign: FloatArray = field(init=False, repr=False)
    _J_translation: FloatArray = field(init=False, repr=False)

    def __post_init__(self):
        # -skew(s1) on side 0, +skew(s2) on side 1: the rotational Jacobian is R_i @ this.
        signed = skew(self.B_s) * np.array([-1.0, 1.0])[None, :, None, None]
        object.__setattr__(self, "_R_skew_sign", signed)
        J = np.zeros((self.n_joints, 3, 2, 6))
        J[:, :, 0, :3], J[:, :, 1, :3] = np.eye(3), -np.eye(3)
        object.__setattr__(self, "_J_translation", J)

    def _points(self, pose: Pose) -> tuple[FloatArray, FloatArray]:
        rho = np.einsum("jsab,jsb->jsa", pose.R_WB[self.body], self.B_s)
        return pose.W_r[self.body] + rho, rho

    def residual(self, pose):
        p, _ = self._points(pose)
        return p[:, 0] - p[:, 1]

    def jacobian(self, pose):
        J = self._J_translation.copy()
        J[:, :, :, 3:] = np.einsum("jsab,jsbc->jasc", pose.R_WB[self.body], self._R_skew_sign)
        return J

    def gamma(self, pose, twist):
        _, rho = self._points(pose)
        w = twist.W_omega[self.body]
        centripetal = cross(w, cross(w, rho))
        return centripetal[:, 1] - centripetal[:, 0]


JOINTS: dict[str, type[Joint]] = {cls.type_name: cls for cls in (BallJoint,)}

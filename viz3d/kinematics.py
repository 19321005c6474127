"""Body poses and twists from the state vectors, with ground appended as body index ``nb``, and the
``Configuration`` of a whole system at one instant (poses, twists, elastic coordinates).

Appending ground (identity pose, zero twist, zero inverse mass) lets joints and force elements
address "ground" like any body, so no stage needs a mask. A flexible body's pose is that of its
frame (origin at its undeformed centre of mass); its deformation is in ``Configuration.eta``. See
docs/notation.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.rotations import cross


@dataclass(frozen=True)
class Pose:
    """Positions and orientations of all bodies plus ground (last row).

    Attributes
    ----------
    W_r : ndarray, shape (nb + 1, 3)
        Centre-of-mass positions in world [m]; ground at the origin.
    R_WB : ndarray, shape (nb + 1, 3, 3)
        World-from-body rotations; ground is the identity.
    """

    W_r: FloatArray
    R_WB: FloatArray

    def point(self, body: IntArray, B_s: FloatArray) -> FloatArray:
        """World positions of body-fixed points, shape (k, 3), from ``body`` (k,), ``B_s`` (k, 3) [m]."""
        return self.W_r[body] + self.lever(body, B_s)

    def lever(self, body: IntArray, B_s: FloatArray) -> FloatArray:
        """World vectors from the centre of mass to body-fixed points, shape (k, 3) [m]."""
        return np.einsum("kij,kj->ki", self.R_WB[body], B_s)


@dataclass(frozen=True)
class Twist:
    """Velocities of all bodies plus ground (last row, zero).

    Attributes
    ----------
    W_v : ndarray, shape (nb + 1, 3)
        Centre-of-mass velocities in world [m/s].
    B_omega : ndarray, shape (nb + 1, 3)
        Angular velocities in body axes [rad/s].
    W_omega : ndarray, shape (nb + 1, 3)
        Angular velocities in world axes [rad/s].
    """

    W_v: FloatArray
    B_omega: FloatArray
    W_omega: FloatArray

    def point_velocity(self, body: IntArray, W_rho: FloatArray) -> FloatArray:
        """World velocities of points at world levers ``W_rho`` (k, 3) from their bodies' centres."""
        return self.W_v[body] + cross(self.W_omega[body], W_rho)


def with_ground(x: FloatArray, ground: FloatArray) -> FloatArray:
    """Append ``ground`` (one row) to ``x`` along the first axis."""
    return np.concatenate([x, ground[None]], axis=0)


_ZERO3 = np.zeros(3)
_EYE3 = np.eye(3)


def pose_from(W_r: FloatArray, R_WB: FloatArray) -> Pose:
    """Pose with ground appended, from (nb, 3) positions and (nb, 3, 3) rotations."""
    return Pose(with_ground(W_r, _ZERO3), with_ground(R_WB, _EYE3))


def twist_from(W_v: FloatArray, B_omega: FloatArray, pose: Pose) -> Twist:
    """Twist with ground appended, from (nb, 3) velocities and body angular velocities."""
    W_v = with_ground(W_v, _ZERO3)
    B_omega = with_ground(B_omega, _ZERO3)
    W_omega = np.einsum("bij,bj->bi", pose.R_WB, B_omega)
    return Twist(W_v, B_omega, W_omega)


@dataclass(frozen=True)
class Configuration:
    """Everything position- and velocity-dependent of a system at one instant, computed once per
    evaluation and read by every element.

    Attributes
    ----------
    t : float
        Time [s].
    pose : Pose
        Frames of all bodies plus ground, rows (nb + 1).
    twist : Twist
        Frame velocities of all bodies plus ground, rows (nb + 1) (zero for fixed frames).
    eta, eta_dot : tuple of ndarray
        Elastic coordinates (n_b,) and their rates of each flexible body, in body order.
    """

    t: float
    pose: Pose
    twist: Twist
    eta: tuple = ()
    eta_dot: tuple = ()


def resting_configurations(t: FloatArray, W_r: FloatArray, R_WB: FloatArray) -> list[Configuration]:
    """Configurations at times ``t`` (n,) [s] with the bodies' poses ``W_r`` (n, nb, 3) [m] and
    ``R_WB`` (n, nb, 3, 3) and zero twists (rigid bodies): what geometry alone (contact detection)
    needs of a trajectory's frames."""
    out = []
    for k in range(len(t)):
        pose = pose_from(W_r[k], R_WB[k])
        zero = np.zeros((W_r.shape[1], 3))
        out.append(Configuration(float(t[k]), pose, twist_from(zero, zero, pose)))
    return out

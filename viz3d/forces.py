"""Force elements: everything that contributes applied forces and torques to the bodies.

A force element is a vectorized set (all springs of a scene are one element) with one hook,
``wrench(t, pose, twist) -> (W_F, W_tau)``: world forces at each centre of mass and world
torques about it, shapes (nb + 1, 3) (the last row, ground, is discarded). Conservative elements
also give ``potential_energy``. See docs/extending.md ("Add a force element").
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.kinematics import Pose, Twist
from viz3d.rotations import cross
from viz3d.timefunctions import TimeFunctions

#: Spring lengths below this [m] are treated as zero (direction undefined, force from k * d).
MIN_LENGTH = 1e-12


def scatter(n_rows: int, body: IntArray, values: FloatArray) -> FloatArray:
    """Sum ``values`` (k, 3) into rows ``body`` (k,) of a zero (n_rows, 3) array."""
    out = np.zeros((n_rows, 3))
    np.add.at(out, body, values)
    return out


class ForceElement(ABC):
    """Base class. Subclasses set ``type_name`` and implement ``wrench``."""

    type_name: ClassVar[str]

    @abstractmethod
    def wrench(self, t: float, pose: Pose, twist: Twist) -> tuple[FloatArray, FloatArray]:
        """World forces and torques about the centres of mass, shapes (nb + 1, 3) [N, N m]."""

    def potential_energy(self, t: float, pose: Pose) -> float:
        """Potential energy [J]; zero for non-conservative elements."""
        return 0.0

    @property
    def conservative(self) -> bool:
        """True when the element's forces are minus the gradient of ``potential_energy``."""
        return False


@dataclass(frozen=True)
class Gravity(ForceElement):
    """Uniform gravity ``F = m g`` at every centre of mass; ``V = -sum m g . r``.

    Attributes
    ----------
    mass : ndarray, shape (nb,) [kg]
    g : ndarray, shape (3,) [m/s^2]
    """

    type_name = "gravity"
    mass: FloatArray
    g: FloatArray

    def wrench(self, t, pose, twist):
        F = np.zeros_like(pose.W_r)
        F[:-1] = self.mass[:, None] * self.g
        return F, np.zeros_like(F)

    def potential_energy(self, t, pose):
        return -float(self.mass @ (pose.W_r[:-1] @ self.g))

    @property
    def conservative(self) -> bool:
        return True


@dataclass(frozen=True)
class SpringDamper(ForceElement):
    """Linear spring-dampers between body points (or a body point and ground).

    Tension ``f = k (l - l0) + c l_dot`` acts along the line of the two points: ``+f u`` on
    body 1 and ``-f u`` on body 2, with ``u`` the unit vector from point 1 to point 2.
    ``V = k (l - l0)^2 / 2``.

    Attributes
    ----------
    names : tuple of str, length k
    body : ndarray of int, shape (k, 2)
    B_s : ndarray, shape (k, 2, 3)
        Attachment points in body frames (world for ground) [m].
    stiffness : ndarray, shape (k,) [N/m]
    damping : ndarray, shape (k,) [N s/m]
    rest_length : ndarray, shape (k,) [m]
    """

    type_name = "spring_damper"
    names: tuple[str, ...]
    body: IntArray
    B_s: FloatArray
    stiffness: FloatArray
    damping: FloatArray
    rest_length: FloatArray

    def endpoints(self, pose: Pose) -> tuple[FloatArray, FloatArray]:
        """World attachment points (k, 2, 3) and levers from the centres of mass (k, 2, 3)."""
        rho = np.einsum("ksab,ksb->ksa", pose.R_WB[self.body], self.B_s)
        return pose.W_r[self.body] + rho, rho

    def _geometry(self, pose: Pose):
        p, rho = self.endpoints(pose)
        d = p[:, 1] - p[:, 0]
        length = np.linalg.norm(d, axis=1)
        u = d / np.maximum(length, MIN_LENGTH)[:, None]
        return rho, d, length, u

    def wrench(self, t, pose, twist):
        rho, d, length, u = self._geometry(pose)
        v = twist.W_v[self.body] + cross(twist.W_omega[self.body], rho)
        length_d = np.einsum("ki,ki->k", u, v[:, 1] - v[:, 0])
        # k (l - l0) u written as k (d - l0 u): exact for l0 = 0 even when the points coincide.
        f = self.stiffness[:, None] * (d - self.rest_length[:, None] * u) + (self.damping * length_d)[:, None] * u
        F_pts = np.stack([f, -f], axis=1)
        n = pose.W_r.shape[0]
        flat_b = self.body.ravel()
        F = scatter(n, flat_b, F_pts.reshape(-1, 3))
        tau = scatter(n, flat_b, cross(rho, F_pts).reshape(-1, 3))
        return F, tau

    @property
    def conservative(self) -> bool:
        return not np.any(self.damping > 0)

    def potential_energy(self, t, pose):
        _, _, length, _ = self._geometry(pose)
        return float(0.5 * np.sum(self.stiffness * (length - self.rest_length) ** 2))


@dataclass(frozen=True)
class AppliedForce(ForceElement):
    """Prescribed forces at body points, constant or time functions, in world or body axes.

    Attributes
    ----------
    names : tuple of str, length k
    body : ndarray of int, shape (k,)
    B_s : ndarray, shape (k, 3)
        Point of application from the centre of mass, body axes [m].
    in_body_frame : ndarray of bool, shape (k,)
        Value given in body axes (follows the body) instead of world axes.
    value : TimeFunctions
        ``k`` functions of time [N].
    """

    type_name = "force"
    names: tuple[str, ...]
    body: IntArray
    B_s: FloatArray
    in_body_frame: np.ndarray
    value: TimeFunctions

    def world_value(self, t: float, pose: Pose) -> FloatArray:
        """The prescribed vectors in world axes, shape (k, 3)."""
        val = self.value(t)
        in_body = np.einsum("kij,kj->ki", pose.R_WB[self.body], val)
        return np.where(self.in_body_frame[:, None], in_body, val)

    def wrench(self, t, pose, twist):
        F_k = self.world_value(t, pose)
        n = pose.W_r.shape[0]
        tau_k = cross(pose.lever(self.body, self.B_s), F_k)
        return scatter(n, self.body, F_k), scatter(n, self.body, tau_k)


@dataclass(frozen=True)
class AppliedTorque(AppliedForce):
    """Prescribed torques (couples) on bodies, world or body axes; ``B_s`` is unused (zero)."""

    type_name = "torque"

    def wrench(self, t, pose, twist):
        tau_k = self.world_value(t, pose)
        return np.zeros_like(pose.W_r), scatter(pose.W_r.shape[0], self.body, tau_k)


#: Force elements by scene type. Contact elements (viz3d.contact.element) register themselves
#: here when imported, which viz3d.scene.build does.
FORCES: dict[str, type[ForceElement]] = {
    cls.type_name: cls for cls in (SpringDamper, AppliedForce, AppliedTorque)
}

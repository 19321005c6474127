"""Contact in multibody scenes: a sphere fixed on a body against a fixed plane, as a force element.

Geometry and law are separate: ``SpherePlane`` computes the gap and its rate (the kinematics);
the normal force magnitude comes from a law of ``viz3d.contact.laws`` that needs no contact
memory (``linear``, ``hertz``), plus an optional linear dashpot that never pulls. Laws whose
damping depends on the approach speed at onset need per-contact memory across steps: they are
available in impact scenes (viz3d.impact), not here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.forces import FORCES, ForceElement, scatter
from viz3d.kinematics import Configuration
from viz3d.rotations import cross

#: Laws usable without contact memory.
MEMORYLESS_LAWS = ("linear", "hertz")


@dataclass(frozen=True)
class SpherePlane(ForceElement):
    """Spheres on bodies against fixed planes; force ``F = law(alpha) + c alpha_dot``, clipped at 0.

    ``alpha = r - n . (p_centre - p_plane)`` is the indentation; the force ``F n`` acts on the body
    at the deepest point of the sphere.

    Attributes
    ----------
    names : tuple of str, length k
    body : ndarray of int, shape (k,)
    B_c : ndarray, shape (k, 3)
        Sphere centre from the centre of mass, body axes [m].
    radius : ndarray, shape (k,) [m]
    plane_point : ndarray, shape (k, 3) [m]
    normal : ndarray, shape (k, 3)
        Unit plane normal pointing to the free side.
    laws : tuple of NormalLaw, length k
    damping : ndarray, shape (k,) [N s/m]
    """

    type_name = "contact"
    names: tuple[str, ...]
    body: IntArray
    B_c: FloatArray
    radius: FloatArray
    plane_point: FloatArray
    normal: FloatArray
    laws: tuple
    damping: FloatArray

    def kinematics(self, cfg: Configuration):
        """Indentation (k,) [m], its rate (k,) [m/s], contact points (k, 3) and levers (k, 3)."""
        pose, twist = cfg.pose, cfg.twist
        rho = pose.lever(self.body, self.B_c)
        centre = pose.W_r[self.body] + rho
        alpha = self.radius - np.einsum("ki,ki->k", self.normal, centre - self.plane_point)
        lever = rho - self.radius[:, None] * self.normal
        v = twist.W_v[self.body] + cross(twist.W_omega[self.body], lever)
        alpha_dot = -np.einsum("ki,ki->k", self.normal, v)
        return alpha, alpha_dot, centre - self.radius[:, None] * self.normal, lever

    def magnitudes(self, alpha, alpha_dot) -> FloatArray:
        elastic = np.array([float(law.force(a, 0.0, None)) if a > 0 else 0.0 for law, a in zip(self.laws, alpha)])
        return np.where(alpha > 0, np.maximum(elastic + self.damping * alpha_dot, 0.0), 0.0)

    def wrench(self, cfg):
        alpha, alpha_dot, _, lever = self.kinematics(cfg)
        f = self.magnitudes(alpha, alpha_dot)[:, None] * self.normal
        n = cfg.pose.W_r.shape[0]
        return scatter(n, self.body, f), scatter(n, self.body, cross(lever, f)), None

    def potential_energy(self, cfg):
        pose = cfg.pose
        rho = pose.lever(self.body, self.B_c)
        alpha = self.radius - np.einsum("ki,ki->k", self.normal, pose.W_r[self.body] + rho - self.plane_point)
        return float(sum(float(law.elastic_energy(a, None)) for law, a in zip(self.laws, alpha) if a > 0))

    @property
    def conservative(self) -> bool:
        return not np.any(self.damping > 0)

    def contacts(self, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
        """Active contact points (m, 3) and the forces on the bodies there (m, 3), for display."""
        alpha, alpha_dot, points, _ = self.kinematics(cfg)
        F = self.magnitudes(alpha, alpha_dot)
        on = F > 0
        return points[on], F[on, None] * self.normal[on]


FORCES[SpherePlane.type_name] = SpherePlane

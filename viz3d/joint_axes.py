"""Joint axes on one side of a set of framed joints: fixed in a rigid body (or ground), or in a
section of a flexible body, with their rates, bias accelerations and velocity Jacobians.

A side's axes (columns x, y, z) are ``A`` in its body's axes. On a flexible section they turn with the
section's small rotation ``theta = P eta`` to first order, as the material points of
``viz3d.flexible.floating_points`` do (a direction is the difference of two material points):

    a = R (A + theta x A) = alpha + (R theta) x alpha,        alpha = R A

so every combination ``a c`` of the axes (``c`` (3,) coefficients) moves as

    d(a c)/dt     = w x (a c) + Omega x (alpha c),            Omega = R P eta_dot = G eta_dot
    d2(a c)/dt2   = [v_dot terms] + w x (w x (a c)) + 2 w x (Omega x (alpha c))

(``w`` the frame's world angular velocity). Rigid sides have ``theta = 0``, ``G = 0``, ``a = alpha``.
For a fixed world vector ``x`` the rate of ``(a c) . x`` is ``B_omega . R^T ((a c) x x) + eta_dot .
G^T ((alpha c) x x)``: the ``jacobian``. See docs/notation.md ("Joints with frames").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.kinematics import Configuration
from viz3d.points import BodyPoints
from viz3d.rotations import cross


@dataclass(frozen=True, eq=False)
class SideAxes:
    """The joint axes of one side of nj joints at one configuration.

    Attributes
    ----------
    a : ndarray, shape (nj, 3, 3)
        World axes (columns), turned with the section on flexible sides.
    alpha : ndarray, shape (nj, 3, 3)
        World axes of the undeformed section, ``R A``.
    R : ndarray, shape (nj, 3, 3)
        The side's frame rotation ``R_WB``.
    w : ndarray, shape (nj, 3)
        The frame's world angular velocity [rad/s].
    Omega : ndarray, shape (nj, 3)
        World rate of the section rotation relative to the frame, ``G eta_dot`` [rad/s].
    G : ndarray, shape (nj, 3, n_e)
        ``R P`` on the stacked elastic velocities (zero on rigid sides).
    rigid : bool
        A rigid body's or ground's side: ``a = alpha``, ``Omega = 0``, ``G = 0`` (the terms of the
        section's rotation are skipped, not computed as zeros: the rigid joints' NumPy path).
    """

    a: FloatArray
    alpha: FloatArray
    R: FloatArray
    w: FloatArray
    Omega: FloatArray
    G: FloatArray
    rigid: bool = False

    def vector(self, c: FloatArray) -> FloatArray:
        """``a c`` (nj, 3) for coefficients ``c`` (3,) or (nj, 3)."""
        return _combine(self.a, c)

    def motion(self, c: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``d(a c)/dt`` [1/s] and the part of ``d2(a c)/dt2`` not proportional to ``v_dot`` [1/s^2],
        each (nj, 3): ``w x (a c) + s`` and ``w x (w x (a c)) + 2 w x s``, ``s = Omega x (alpha c)``."""
        rate = cross(self.w, _combine(self.a, c))
        bias = cross(self.w, rate)
        if not self.rigid:
            s = cross(self.Omega, _combine(self.alpha, c))
            rate, bias = rate + s, bias + 2.0 * cross(self.w, s)
        return rate, bias

    def jacobian(self, c: FloatArray, x: FloatArray, n: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
        """Velocity Jacobian of ``(a c) . x`` for world vectors ``x`` (nj, 3) held fixed: frame part
        (nj, 6) on ``[W_v, B_omega]`` and elastic part (nj, n_e); ``n``: ``(a c) x x`` if the caller
        has it (the two sides of a perpendicularity share it, with opposite signs)."""
        Jf = np.zeros((len(self.a), 6))
        Jf[:, 3:] = np.einsum("kji,kj->ki", self.R, cross(_combine(self.a, c), x) if n is None else n)
        if self.rigid:
            return Jf, np.zeros((len(self.a), self.G.shape[2]))
        return Jf, np.einsum("kiq,ki->kq", self.G, cross(_combine(self.alpha, c), x))


def _combine(axes: FloatArray, c: FloatArray) -> FloatArray:
    """``axes c``: (nj, 3) from axes (nj, 3, 3) and coefficients (3,) or (nj, 3)."""
    c = np.asarray(c, dtype=float)
    return axes @ c if c.ndim == 1 else np.einsum("kij,kj->ki", axes, c)


def side_axes(points: BodyPoints, B_A: FloatArray, cfg: Configuration) -> SideAxes:
    """The axes ``B_A`` (nj, 3, 3) (body axes of the undeformed section) of the side whose joint points
    are ``points`` (``viz3d.points.BodyPoints``, k = nj), at ``cfg``."""
    R = cfg.pose.R_WB[points.body]
    alpha = R @ B_A
    G = points.section_jacobian(cfg)
    if not points.flex:
        return SideAxes(alpha, alpha, R, cfg.twist.W_omega[points.body], np.zeros((points.k, 3)), G, rigid=True)
    theta_W = np.einsum("kij,kj->ki", R, points.section_rotations(cfg))
    a = alpha + np.cross(theta_W[:, :, None], alpha, axis=1)
    Omega = np.einsum("kiq,q->ki", G, _stacked(cfg)) if G.shape[2] else np.zeros((points.k, 3))
    return SideAxes(a, alpha, R, cfg.twist.W_omega[points.body], Omega, G)


def _stacked(cfg: Configuration) -> FloatArray:
    """The stacked elastic velocities (n_e,) of ``cfg``."""
    return np.concatenate(cfg.eta_dot) if cfg.eta_dot else np.zeros(0)


def unit(i: int) -> FloatArray:
    """Coefficients of axis ``i`` (0, 1, 2 = x, y, z), shape (3,)."""
    return np.eye(3)[i]

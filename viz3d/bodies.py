"""Rigid-body inertia of all bodies: mass matrix blocks, gyroscopic terms, kinetic energy.

With velocities ``[W_v, B_omega]`` per body the mass matrix is constant and block diagonal,
``M_b = diag(m_b I3, I_b)`` with ``I_b`` the (general, symmetric positive definite) inertia
tensor about the centre of mass in body axes. See docs/notation.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray
from viz3d.rotations import cross


class InertiaError(ValueError):
    """An inertia tensor that no rigid body can have."""


def check_inertia(name: str, mass: float, inertia: FloatArray) -> None:
    """Raise ``InertiaError`` unless ``mass > 0`` and ``inertia`` (3, 3) is symmetric positive
    definite and satisfies the triangle inequalities of its principal moments."""
    if not mass > 0:
        raise InertiaError(f"body {name!r}: mass must be positive, got {mass}")
    I = np.asarray(inertia, dtype=float)
    if not np.allclose(I, I.T, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(I).max())):
        raise InertiaError(f"body {name!r}: inertia tensor is not symmetric: {I.tolist()}")
    p = np.linalg.eigvalsh(I)
    if p[0] <= 0:
        raise InertiaError(f"body {name!r}: inertia tensor is not positive definite (principal moments {p.tolist()})")
    if p[0] + p[1] < p[2] * (1 - 1e-9):
        raise InertiaError(f"body {name!r}: principal moments {p.tolist()} violate I1 + I2 >= I3")


@dataclass(frozen=True)
class Bodies:
    """Inertial data of ``nb`` rigid bodies.

    Attributes
    ----------
    names : tuple of str, length nb
    mass : ndarray, shape (nb,) [kg]
    inertia : ndarray, shape (nb, 3, 3)
        About the centre of mass, body axes [kg m^2].
    M_inv : ndarray, shape (nb + 1, 6, 6)
        Inverse mass-matrix blocks; ground (last) is zero, so it never moves.
    """

    names: tuple[str, ...]
    mass: FloatArray
    inertia: FloatArray
    M_inv: FloatArray = field(init=False, repr=False)

    def __post_init__(self):
        for name, m, I in zip(self.names, self.mass, self.inertia):
            check_inertia(name, float(m), I)
        nb = len(self.names)
        M_inv = np.zeros((nb + 1, 6, 6))
        M_inv[:nb, :3, :3] = np.eye(3) / self.mass[:, None, None]
        M_inv[:nb, 3:, 3:] = np.linalg.inv(self.inertia)
        object.__setattr__(self, "M_inv", M_inv)

    @property
    def n_bodies(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of body ``name``; "ground" is ``nb``."""
        return self.n_bodies if name == "ground" else self.names.index(name)

    def gyroscopic(self, B_omega: FloatArray) -> FloatArray:
        """``B_omega x (I B_omega)`` per body, shape (nb, 3) [N m], from ``B_omega`` (nb, 3)."""
        return cross(B_omega, np.einsum("bij,bj->bi", self.inertia, B_omega))

    def kinetic_energy(self, W_v: FloatArray, B_omega: FloatArray) -> float:
        """Total kinetic energy [J] from (nb, 3) velocities and body angular velocities."""
        trans = self.mass @ np.einsum("bi,bi->b", W_v, W_v)
        rot = np.einsum("bi,bij,bj->", B_omega, self.inertia, B_omega)
        return 0.5 * float(trans + rot)

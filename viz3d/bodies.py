"""The bodies of a system: rigid bodies (6 velocity coordinates) and flexible bodies (their frame's 6,
if it floats, plus n elastic coordinates), with their mass-matrix blocks and energies.

A rigid body's velocities are ``[W_v, B_omega]`` and its mass matrix is the constant
``diag(m I3, I_b)`` with ``I_b`` the (general, symmetric positive definite) inertia tensor about the
centre of mass in body axes. A flexible body is a bar on a floating frame of reference
(``viz3d.flexible.floating``): velocities ``[W_v, B_omega, eta_dot]`` and a configuration-dependent
mass matrix; or a bar whose frame is fixed in the world (a clamped structure): velocities
``eta_dot`` only, constant mass matrix. See docs/notation.md ("Bodies").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible import floating as ffr
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


@dataclass(frozen=True, eq=False)
class FlexibleBody:
    """A flexible bar among the bodies.

    Attributes
    ----------
    index : int
        Its body index.
    bar : FloatingBar
        Fields, inertia invariants, stiffness and damping (``viz3d.flexible.floating``).
    floating : bool
        True: its frame moves (6 frame velocities in ``v``); False: the frame is fixed at
        ``(W_r0, R0)`` and only the elastic coordinates move.
    W_r0 : ndarray, shape (3,)
        Position of the frame origin (the undeformed centre of mass) at t = 0 [m]; the fixed one.
    R0 : ndarray, shape (3, 3)
        Orientation of the frame at t = 0; the fixed one.
    model_choice : str
        How its model was discretized and why (mode count, truncation estimate), for reports.
    ked : bool
        Kineto-elastodynamic (seed 003's model): the frame moves as the rigid body (its mass-matrix
        block has no frame-elastic coupling, its frame forces and joint rows are those of the
        undeformed body) and the elastic equations are driven by that motion without feedback
        (``viz3d.dynamics``; docs/notation.md, "Flexible links"). False: the coupled floating frame.
    M_ee_inv : ndarray, shape (n, n)
        Inverse of the elastic mass matrix (derived; what a fixed frame's body needs).
    """

    index: int
    bar: object
    floating: bool
    W_r0: FloatArray
    R0: FloatArray
    model_choice: str = ""
    ked: bool = False
    M_ee_inv: FloatArray = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "M_ee_inv", np.linalg.inv(self.bar.M_ee) if self.bar.n else np.zeros((0, 0)))

    @property
    def n(self) -> int:
        """Elastic coordinates."""
        return self.bar.n

    @property
    def width(self) -> int:
        """Velocity coordinates of the body: 6 + n floating, n fixed."""
        return self.n + (6 if self.floating else 0)

    def mass_matrix(self, R_WB: FloatArray, eta: FloatArray) -> FloatArray:
        """The body's mass-matrix block, shape (width, width); kineto-elastodynamic (``ked``): the
        undeformed frame block and ``M_ee``, uncoupled."""
        if not self.floating:
            return self.bar.M_ee
        if self.ked:
            M = ffr.mass_matrix(self.bar, R_WB, np.zeros(self.n))
            M[:6, 6:], M[6:, :6] = 0.0, 0.0
            return M
        return ffr.mass_matrix(self.bar, R_WB, eta)


@dataclass(frozen=True)
class Bodies:
    """Inertial data of ``nb`` bodies.

    Attributes
    ----------
    names : tuple of str, length nb
    mass : ndarray, shape (nb,) [kg]
    inertia : ndarray, shape (nb, 3, 3)
        About the centre of mass, body axes [kg m^2] (a flexible body: of its undeformed shape).
    flexible : tuple of FlexibleBody
        The flexible bodies, in body order; every other body is rigid.
    M_inv : ndarray, shape (nb + 1, 6, 6)
        Inverse mass-matrix blocks of the rigid bodies; zero for flexible bodies (their blocks are
        configuration dependent or elastic only) and for ground (last), which never moves.
    is_rigid : ndarray of bool, shape (nb,)
    """

    names: tuple[str, ...]
    mass: FloatArray
    inertia: FloatArray
    flexible: tuple[FlexibleBody, ...] = ()
    M_inv: FloatArray = field(init=False, repr=False)
    is_rigid: np.ndarray = field(init=False, repr=False)
    _rigid_mass_inertia: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        nb = len(self.names)
        rigid = np.ones(nb, dtype=bool)
        for fb in self.flexible:
            rigid[fb.index] = False
        for name, m, I, r in zip(self.names, self.mass, self.inertia, rigid):
            if r:
                check_inertia(name, float(m), I)
        M_inv = np.zeros((nb + 1, 6, 6))
        M_inv[:nb][rigid, :3, :3] = np.eye(3) / self.mass[rigid, None, None]
        M_inv[:nb][rigid, 3:, 3:] = np.linalg.inv(self.inertia[rigid]) if rigid.any() else np.zeros((0, 3, 3))
        object.__setattr__(self, "M_inv", M_inv)
        object.__setattr__(self, "is_rigid", rigid)
        which = None if rigid.all() else np.flatnonzero(rigid)  # rows of the rigid bodies, None: all
        object.__setattr__(self, "_rigid_mass_inertia", (which, self.mass[rigid], self.inertia[rigid]))

    @property
    def n_bodies(self) -> int:
        return len(self.names)

    @property
    def all_rigid(self) -> bool:
        return not self.flexible

    def index(self, name: str) -> int:
        """Index of body ``name``; "ground" is ``nb``."""
        return self.n_bodies if name == "ground" else self.names.index(name)

    def gyroscopic(self, B_omega: FloatArray) -> FloatArray:
        """``B_omega x (I B_omega)`` per body, shape (nb, 3) [N m], from ``B_omega`` (nb, 3) (rigid bodies;
        flexible bodies have their velocity forces, ``viz3d.flexible.floating.velocity_forces``)."""
        return cross(B_omega, np.einsum("bij,bj->bi", self.inertia, B_omega))

    def kinetic_energy(self, W_v: FloatArray, B_omega: FloatArray) -> float:
        """Kinetic energy of the rigid bodies [J] from (nb, 3) velocities and body angular velocities."""
        rigid, mass, inertia = self._rigid_mass_inertia
        if rigid is not None:
            W_v, B_omega = W_v[rigid], B_omega[rigid]
        trans = mass @ np.einsum("bi,bi->b", W_v, W_v)
        rot = np.sum(B_omega * np.matmul(inertia, B_omega[:, :, None])[:, :, 0])
        return 0.5 * float(trans + rot)

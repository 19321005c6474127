"""The frozen model (``System``) and the state value (``State``).

Layout of the state vectors (docs/notation.md):

* ``q`` (n_q,): per body ``[W_r (3) [m], theta (n_rot) [rad or -]]``, bodies in order.
* ``v`` (n_v,): per body ``[W_v (3) [m/s], B_omega (3) [rad/s]]``; ``n_v = 6 nb``.
* ``chart`` (nb, 3, 3): per-body reference rotation of the orientation coordinates.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.bodies import Bodies
from viz3d.constraints import ConstraintLayout
from viz3d.coordinates import RotationCoordinates
from viz3d.forces import ForceElement


@dataclass(frozen=True)
class System:
    """Everything that does not change during a run.

    Attributes
    ----------
    bodies : Bodies
    joints : ConstraintLayout
        Joint sets and the precomputed structure of their constraint rows.
    forces : tuple of ForceElement
        Gravity first (if any), then the scene's force elements.
    rotation : RotationCoordinates
    """

    bodies: Bodies
    joints: ConstraintLayout
    forces: tuple[ForceElement, ...]
    rotation: RotationCoordinates

    @property
    def n_bodies(self) -> int:
        return self.bodies.n_bodies

    @property
    def n_q_body(self) -> int:
        return 3 + self.rotation.n_q

    @property
    def n_q(self) -> int:
        return self.n_bodies * self.n_q_body

    @property
    def n_v(self) -> int:
        return 6 * self.n_bodies

    @property
    def n_c(self) -> int:
        return self.joints.n_rows

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(n for js in self.joints.joints for n in js.names)

    def split_q(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(W_r (nb, 3), theta (nb, n_rot))`` views of ``q``."""
        qb = q.reshape(self.n_bodies, self.n_q_body)
        return qb[:, :3], qb[:, 3:]

    def split_v(self, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(W_v (nb, 3), B_omega (nb, 3))`` views of ``v``."""
        vb = v.reshape(self.n_bodies, 6)
        return vb[:, :3], vb[:, 3:]

    def join_q(self, W_r: FloatArray, theta: FloatArray) -> FloatArray:
        return np.concatenate([W_r, theta], axis=1).reshape(-1)


@dataclass(frozen=True)
class State:
    """Time-varying state of a System (a value: use ``replace`` to make a new one).

    Attributes
    ----------
    t : float
        Time [s].
    q : ndarray, shape (n_q,)
        Positions (see module docstring).
    v : ndarray, shape (n_v,)
        Velocities.
    chart : ndarray, shape (nb, 3, 3)
        Reference rotation of each body's orientation coordinates.
    """

    t: float
    q: FloatArray
    v: FloatArray
    chart: FloatArray

    def replace(self, **changes) -> "State":
        return dataclasses.replace(self, **changes)

    @property
    def y(self) -> FloatArray:
        """``[q, v]`` stacked, shape (n_q + n_v,): what integrators advance."""
        return np.concatenate([self.q, self.v])

"""Rotation parametrizations: how a body's orientation is stored in ``q`` and advanced in time.

The velocity of every body is ``[W_v (3), B_omega (3)]`` whatever the parametrization, so the mass
matrix and the constraint Jacobians never depend on it; a parametrization only provides

* ``matrix(theta, chart)``: rotation ``R_WB`` from the stored coordinates,
* ``rates(theta, B_omega)``: the kinematic equation ``theta_dot = f(theta, B_omega)``,
* ``rechart(theta, chart)``: an optional re-parametrization between steps,
* ``normalize(theta)``: an optional projection onto the coordinates' own constraint (the unit norm
  of Euler parameters), applied between steps,
* ``advance(theta, chart, B_dphi)``: the exact finite rotation ``R_WB exp(skew(B_dphi))`` in the
  same chart (what Lie-group methods, ``gen_alpha`` and ``ali3p``, move positions by),
* ``singular_bodies(theta)``: where the kinematic equation breaks down.

``chart`` is a per-body reference rotation ``R_WC`` (shape (nb, 3, 3)) carried in the state, so that
``R_WB = R_WC @ R(theta)``. See docs/notation.md, "Orientation coordinates".
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray
from viz3d.rotations import (
    cross,
    euler_from_matrix,
    euler_near_gimbal_lock,
    euler_rates_from_body_omega,
    matrix_from_euler,
    matrix_from_quat,
    matrix_from_rotation_vector,
    quat_from_matrix,
)

#: Angles at the centre of a fresh chart: nutation pi/2, as far as possible from 0 and pi.
CHART_CENTRE = np.array([0.0, 0.5 * np.pi, 0.0])
#: Re-chart a body when |sin(theta)| falls below this (theta within 30 deg of 0 or pi); the rate
#: map's condition number then stays below 1/0.5 = 2.
SWITCH_SIN = 0.5
#: Plain Euler angles are declared singular below this |sin(theta)|: the rate map's condition
#: number exceeds 1e8 and the rates lose eight digits.
SINGULAR_SIN = 1e-8
#: Within this |sin(theta)| of the pole, fast Euler-angle rates are diagnosed as the gimbal lock.
NEAR_SINGULAR_SIN = 0.1


class RotationCoordinates(ABC):
    """Orientation coordinates of all bodies, vectorized over bodies.

    Subclasses set ``name`` and ``n_q`` and implement ``matrix``, ``rates`` and ``from_matrix``;
    ``rechart``, ``normalize`` and ``singular_bodies`` default to "never"; ``advance`` (needed by
    the Lie-group methods ``gen_alpha`` and ``ali3p``) raises unless implemented. Register in
    ``ROTATIONS``.
    """

    name: ClassVar[str]
    n_q: ClassVar[int]  # stored coordinates per body
    #: True when explicit Runge-Kutta methods without an error estimate advance these coordinates on
    #: the group (Munthe-Kaas stages through ``advance``; ``viz3d.integrators.explicit_rk``) rather
    #: than as a vector.
    group_stages: ClassVar[bool] = False

    @abstractmethod
    def matrix(self, theta: FloatArray, chart: FloatArray) -> FloatArray:
        """``R_WB``, shape (nb, 3, 3), from ``theta`` (nb, n_q) and ``chart`` (nb, 3, 3)."""

    @abstractmethod
    def rates(self, theta: FloatArray, B_omega: FloatArray) -> FloatArray:
        """``theta_dot``, shape (nb, n_q), from ``theta`` and ``B_omega`` (nb, 3) [rad/s]."""

    @abstractmethod
    def from_matrix(self, R: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Coordinates and chart, shapes (nb, n_q) and (nb, 3, 3), representing ``R`` (nb, 3, 3)."""

    def rechart(self, theta: FloatArray, chart: FloatArray) -> tuple[FloatArray, FloatArray, np.ndarray]:
        """Return ``(theta, chart, switched)``; ``switched`` is a bool mask (nb,). Default: no-op."""
        return theta, chart, np.zeros(theta.shape[0], dtype=bool)

    def singular_bodies(self, theta: FloatArray) -> np.ndarray:
        """Bool mask (nb,) of bodies whose kinematic equation is singular. Default: none."""
        return np.zeros(theta.shape[0], dtype=bool)

    def near_singular(self, theta: FloatArray) -> np.ndarray:
        """Bool mask (nb,) of bodies close to a singular point of these coordinates, where fast
        coordinate rates mean "singular" rather than "step too long" in a diagnosis. Default:
        ``singular_bodies``."""
        return self.singular_bodies(theta)

    def normalize(self, theta: FloatArray) -> FloatArray:
        """``theta`` projected onto the coordinates' own constraint, if any. Default: unchanged."""
        return theta

    def correct(self, theta: FloatArray, B_dphi: FloatArray) -> FloatArray:
        """First-order update of ``theta`` for a small body-frame rotation ``B_dphi`` (nb, 3)."""
        return theta + self.rates(theta, B_dphi)

    def advance(self, theta: FloatArray, chart: FloatArray, B_dphi: FloatArray) -> FloatArray:
        """Coordinates, in the same ``chart``, of ``R_WB @ exp(skew(B_dphi))``: the body turned by
        the finite rotation vector ``B_dphi`` (nb, 3) [rad] about its own axes."""
        raise NotImplementedError(f"rotation coordinates {self.name!r} do not implement advance()")


class EulerZXZ(RotationCoordinates):
    """The seed's ZXZ Euler angles (psi, theta, phi) relative to the world, never re-charted.

    Singular at nutation 0 or pi: the kinematic map divides by sin(theta). Kept to reproduce the
    seed's failure; ``singular_bodies`` reports it so a run stops with a diagnosis.
    """

    name = "euler_zxz"
    n_q = 3

    def matrix(self, theta, chart):
        return chart @ matrix_from_euler(theta)

    def rates(self, theta, B_omega):
        return euler_rates_from_body_omega(theta, B_omega)

    def from_matrix(self, R):
        return euler_from_matrix(R), np.broadcast_to(np.eye(3), R.shape).copy()

    def singular_bodies(self, theta):
        return euler_near_gimbal_lock(theta, SINGULAR_SIN)

    def near_singular(self, theta):
        return euler_near_gimbal_lock(theta, NEAR_SINGULAR_SIN)

    def advance(self, theta, chart, B_dphi):
        new = euler_from_matrix(matrix_from_euler(theta) @ matrix_from_rotation_vector(B_dphi))
        # ZXZ angles have two branches, (psi, theta, phi) and (psi + pi, -theta, phi + pi):
        # keep the one of the old angles, and psi, phi within pi of their old values.
        neg = theta[..., 1] < 0.0
        new[neg] = new[neg] * [1.0, -1.0, 1.0] + [np.pi, 0.0, np.pi]
        turn = new - theta
        turn[..., [0, 2]] = np.mod(turn[..., [0, 2]] + np.pi, 2.0 * np.pi) - np.pi
        return theta + turn


class EulerSwitching(EulerZXZ):
    """ZXZ Euler angles relative to a per-body chart ``R_WC``, re-charted near gimbal lock.

    When a body's nutation comes within 30 deg of 0 or pi, its chart becomes ``R_WB @
    R(CHART_CENTRE)^T`` and its angles ``CHART_CENTRE``: the same orientation, now at theta =
    pi/2. Orientation and angular velocity are unchanged, so the switch is exact; the kinematic
    map's condition number stays below 2 at all times.
    """

    name = "euler_switching"

    def from_matrix(self, R):
        theta, chart = super().from_matrix(R)
        return self.rechart(theta, chart)[:2]

    def rechart(self, theta, chart):
        switched = euler_near_gimbal_lock(theta, SWITCH_SIN)
        if not np.any(switched):
            return theta, chart, switched
        theta, chart = theta.copy(), chart.copy()
        R = self.matrix(theta[switched], chart[switched])
        chart[switched] = R @ matrix_from_euler(CHART_CENTRE).T
        theta[switched] = CHART_CENTRE
        return theta, chart, switched

    def singular_bodies(self, theta):
        return np.zeros(theta.shape[0], dtype=bool)


class Quaternion(RotationCoordinates):
    """Euler parameters ``p = (w, x, y, z)``, scalar first, ``R_WB = R(p)`` (chart: identity).

    Kinematics ``p_dot = 1/2 p (x) (0, B_omega)`` (quaternion product), regular everywhere. The
    flow keeps ``|p|`` constant but a discrete step does not exactly: ``matrix`` normalises, so
    the orientation never depends on ``|p|``, and ``normalize`` (``p / |p|``) projects the
    coordinates back onto ``|p| = 1`` between steps. ``advance`` and ``correct`` multiply by the
    unit quaternion of the rotation vector, which keeps ``|p|``. Fixed-step explicit Runge-Kutta
    methods advance them on the group (``group_stages``: Runge-Kutta-Munthe-Kaas), exact for a
    constant spin, which RK on ``p_dot`` is not.
    """

    name = "quaternion"
    n_q = 4
    group_stages = True

    def matrix(self, theta, chart):
        return chart @ matrix_from_quat(theta)

    def rates(self, theta, B_omega):
        return 0.5 * quat_product(theta, np.concatenate([np.zeros(B_omega.shape[:-1] + (1,)), B_omega], axis=-1))

    def from_matrix(self, R):
        return quat_from_matrix(R), np.broadcast_to(np.eye(3), R.shape).copy()

    def normalize(self, theta):
        return theta / np.linalg.norm(theta, axis=-1, keepdims=True)

    def advance(self, theta, chart, B_dphi):
        return quat_product(theta, quat_from_rotation_vector(B_dphi))

    def correct(self, theta, B_dphi):
        return self.advance(theta, None, B_dphi)


def quat_product(p: FloatArray, q: FloatArray) -> FloatArray:
    """Hamilton product ``p (x) q`` of scalar-first quaternions, shapes (..., 4)."""
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    return np.concatenate([w, pw * qv + qw * pv + cross(pv, qv)], axis=-1)


def quat_from_rotation_vector(phi: FloatArray) -> FloatArray:
    """Unit quaternion ``(cos(a/2), sin(a/2) phi/a)`` of the rotation vector ``phi`` (..., 3), ``a = |phi|``."""
    angle = np.linalg.norm(phi, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(a/2)/a -> 1/2 - a^2/48 as a -> 0 (series below 1e-4 rad: its error a^4/3840 is below 3e-20)
    scale = np.where(angle < 1e-4, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(angle < 1e-4, 1.0, angle))
    return np.concatenate([np.cos(half), scale * phi], axis=-1)


ROTATIONS: dict[str, type[RotationCoordinates]] = {
    cls.name: cls for cls in (EulerSwitching, EulerZXZ, Quaternion)
}

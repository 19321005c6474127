"""Rotation parametrizations: how a body's orientation is stored in ``q`` and advanced in time.

The velocity of every body is ``[W_v (3), B_omega (3)]`` whatever the parametrization, so the mass
matrix and the constraint Jacobians never depend on it; a parametrization only provides

* ``matrix(theta, chart)``: rotation ``R_WB`` from the stored coordinates,
* ``rates(theta, B_omega)``: the kinematic equation ``theta_dot = f(theta, B_omega)``,
* ``rechart(theta, chart)``: an optional re-parametrization between steps,
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
    euler_from_matrix,
    euler_near_gimbal_lock,
    euler_rates_from_body_omega,
    matrix_from_euler,
)

#: Angles at the centre of a fresh chart: nutation pi/2, as far as possible from 0 and pi.
CHART_CENTRE = np.array([0.0, 0.5 * np.pi, 0.0])
#: Re-chart a body when |sin(theta)| falls below this (theta within 30 deg of 0 or pi); the rate
#: map's condition number then stays below 1/0.5 = 2.
SWITCH_SIN = 0.5
#: Plain Euler angles are declared singular below this |sin(theta)|: the rate map's condition
#: number exceeds 1e8 and the rates lose eight digits.
SINGULAR_SIN = 1e-8


class RotationCoordinates(ABC):
    """Orientation coordinates of all bodies, vectorized over bodies.

    Subclasses set ``name`` and ``n_q`` and implement ``matrix``, ``rates`` and ``from_matrix``;
    ``rechart`` and ``singular_bodies`` default to "never". Register in ``ROTATIONS``.
    """

    name: ClassVar[str]
    n_q: ClassVar[int]  # stored coordinates per body

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

    def correct(self, theta: FloatArray, B_dphi: FloatArray) -> FloatArray:
        """First-order update of ``theta`` for a small body-frame rotation ``B_dphi`` (nb, 3)."""
        return theta + self.rates(theta, B_dphi)


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


ROTATIONS: dict[str, type[RotationCoordinates]] = {
    cls.name: cls for cls in (EulerSwitching, EulerZXZ)
}

"""Rotation conversions: ZXZ Euler angles, matrices, quaternions, rate maps.

Pure functions over arrays with any number of leading axes; nothing here knows about bodies.
Conventions (see docs/notation.md):

* ``R_WB`` takes body coordinates to world coordinates: ``W_x = R_WB @ B_x``.
* Euler angles are the intrinsic ZXZ sequence ``(psi, theta, phi)`` = (precession, nutation,
  spin): ``R = Rz(psi) @ Rx(theta) @ Rz(phi)``. This is scipy's ``Rotation.from_euler("ZXZ", ...)``.
* Quaternions are scalar-first ``(w, x, y, z)``.
"""

from __future__ import annotations

import numpy as np

from viz3d._typing import FloatArray

#: Below this |sin(theta)| the ZXZ angles are treated as gimbal-locked by ``euler_from_matrix``.
GIMBAL_EPS = 1e-12


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a x b`` over the last axis (shape (..., 3)); several times faster than ``np.cross``
    for the small arrays of the right-hand side."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def skew(x: FloatArray) -> FloatArray:
    """Cross-product matrix: ``skew(a) @ b == cross(a, b)``.

    Parameters
    ----------
    x : ndarray, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    x = np.asarray(x, dtype=float)
    out = np.zeros(x.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -x[..., 2], x[..., 1]
    out[..., 1, 0], out[..., 1, 2] = x[..., 2], -x[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -x[..., 1], x[..., 0]
    return out


def matrix_from_euler(angles: FloatArray) -> FloatArray:
    """Rotation matrix ``R = Rz(psi) Rx(theta) Rz(phi)`` from ZXZ angles.

    Parameters
    ----------
    angles : ndarray, shape (..., 3)
        ``(psi, theta, phi)`` [rad].

    Returns
    -------
    R : ndarray, shape (..., 3, 3)
        World-from-body rotation.
    """
    angles = np.asarray(angles, dtype=float)
    c = np.cos(angles)
    s = np.sin(angles)
    c1, c2, c3 = c[..., 0], c[..., 1], c[..., 2]
    s1, s2, s3 = s[..., 0], s[..., 1], s[..., 2]
    R = np.empty(angles.shape[:-1] + (3, 3))
    R[..., 0, 0] = c1 * c3 - s1 * c2 * s3
    R[..., 0, 1] = -c1 * s3 - s1 * c2 * c3
    R[..., 0, 2] = s1 * s2
    R[..., 1, 0] = s1 * c3 + c1 * c2 * s3
    R[..., 1, 1] = -s1 * s3 + c1 * c2 * c3
    R[..., 1, 2] = -c1 * s2
    R[..., 2, 0] = s2 * s3
    R[..., 2, 1] = s2 * c3
    R[..., 2, 2] = c2
    return R


def euler_from_matrix(R: FloatArray) -> FloatArray:
    """ZXZ angles ``(psi, theta, phi)`` of a rotation matrix.

    ``theta`` is in [0, pi]; ``psi`` and ``phi`` in (-pi, pi]. At gimbal lock (theta = 0 or pi)
    only ``psi +- phi`` is defined: ``phi`` is set to 0, as scipy does.

    Parameters
    ----------
    R : ndarray, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    R = np.asarray(R, dtype=float)
    s2 = np.hypot(R[..., 0, 2], R[..., 1, 2])
    theta = np.arctan2(s2, R[..., 2, 2])
    regular = s2 > GIMBAL_EPS
    psi = np.arctan2(R[..., 0, 2], -R[..., 1, 2])
    phi = np.arctan2(R[..., 2, 0], R[..., 2, 1])
    if not np.all(regular):  # (the gimbal-lock branch only where some rotation needs it)
        psi = np.where(regular, psi, np.arctan2(R[..., 1, 0], R[..., 0, 0]))
        phi = np.where(regular, phi, 0.0)
    return np.stack([psi, theta, phi], axis=-1)


def frame_with_z(z: FloatArray) -> FloatArray:
    """A rotation matrix (3, 3) whose third column is the unit vector ``z`` (3,) (the other two
    completed from whichever world axis is farther from ``z``)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def euler_near_gimbal_lock(angles: FloatArray, sin_min: float) -> np.ndarray:
    """True where ``|sin(theta)| < sin_min``, i.e. nutation near 0 or pi.

    Parameters
    ----------
    angles : ndarray, shape (..., 3)
    sin_min : float

    Returns
    -------
    ndarray of bool, shape (...)
    """
    return np.abs(np.sin(np.asarray(angles)[..., 1])) < sin_min


def body_rate_matrix_from_euler(angles: FloatArray) -> FloatArray:
    """Matrix ``H`` with ``B_omega = H(angles) @ angles_dot`` for ZXZ angles.

    Columns are the body-frame directions of the three rotation axes:
    ``psi -> (s2 s3, s2 c3, c2)``, ``theta -> (c3, -s3, 0)``, ``phi -> (0, 0, 1)``.
    ``det H = -sin(theta)``: singular at theta = 0 or pi.

    Parameters
    ----------
    angles : ndarray, shape (..., 3)

    Returns
    -------
    H : ndarray, shape (..., 3, 3)
    """
    angles = np.asarray(angles, dtype=float)
    s2, c2 = np.sin(angles[..., 1]), np.cos(angles[..., 1])
    s3, c3 = np.sin(angles[..., 2]), np.cos(angles[..., 2])
    H = np.zeros(angles.shape[:-1] + (3, 3))
    H[..., 0, 0], H[..., 1, 0], H[..., 2, 0] = s2 * s3, s2 * c3, c2
    H[..., 0, 1], H[..., 1, 1] = c3, -s3
    H[..., 2, 2] = 1.0
    return H


def euler_rates_from_body_omega(angles: FloatArray, B_omega: FloatArray) -> FloatArray:
    """Solve ``H(angles) @ angles_dot = B_omega`` in closed form.

    ``psi_dot = (w1 s3 + w2 c3) / s2``, ``theta_dot = w1 c3 - w2 s3``,
    ``phi_dot = w3 - psi_dot c2``. Divides by ``sin(theta)``: callers keep theta away from 0, pi.

    Parameters
    ----------
    angles : ndarray, shape (..., 3)
        ZXZ angles [rad].
    B_omega : ndarray, shape (..., 3)
        Angular velocity in body axes [rad/s].

    Returns
    -------
    ndarray, shape (..., 3)
        ``(psi_dot, theta_dot, phi_dot)`` [rad/s].
    """
    s2, c2 = np.sin(angles[..., 1]), np.cos(angles[..., 1])
    s3, c3 = np.sin(angles[..., 2]), np.cos(angles[..., 2])
    w1, w2, w3 = B_omega[..., 0], B_omega[..., 1], B_omega[..., 2]
    psi_d = (w1 * s3 + w2 * c3) / s2
    out = np.empty(np.broadcast_shapes(angles.shape, B_omega.shape))
    out[..., 0] = psi_d
    out[..., 1] = w1 * c3 - w2 * s3
    out[..., 2] = w3 - psi_d * c2
    return out


def matrix_from_rotation_vector(phi: FloatArray) -> FloatArray:
    """Rodrigues' formula: ``exp(skew(phi))``.

    Parameters
    ----------
    phi : ndarray, shape (..., 3)
        Rotation vector [rad].

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    phi = np.asarray(phi, dtype=float)
    angle = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = angle < 1e-8
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0 - angle**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * (K @ K)


def quat_from_matrix(R: FloatArray) -> FloatArray:
    """Unit quaternion ``(w, x, y, z)`` with ``w >= 0`` from a rotation matrix (Shepperd's method).

    Parameters
    ----------
    R : ndarray, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    R = np.asarray(R, dtype=float)
    tr = np.trace(R, axis1=-2, axis2=-1)
    diag = np.diagonal(R, axis1=-2, axis2=-1)
    cand = np.stack([tr, diag[..., 0], diag[..., 1], diag[..., 2]], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    d = {  # each row: the largest component is computed from the diagonal, the others from pairs
        0: (1 + tr, R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]),
        1: (R[..., 2, 1] - R[..., 1, 2], 1 + 2 * diag[..., 0] - tr, R[..., 0, 1] + R[..., 1, 0], R[..., 0, 2] + R[..., 2, 0]),
        2: (R[..., 0, 2] - R[..., 2, 0], R[..., 0, 1] + R[..., 1, 0], 1 + 2 * diag[..., 1] - tr, R[..., 1, 2] + R[..., 2, 1]),
        3: (R[..., 1, 0] - R[..., 0, 1], R[..., 0, 2] + R[..., 2, 0], R[..., 1, 2] + R[..., 2, 1], 1 + 2 * diag[..., 2] - tr),
    }
    for case, comps in d.items():
        sel = k == case
        if np.any(sel):
            v = np.stack([np.broadcast_to(c, k.shape) for c in comps], axis=-1)[sel]
            q[sel] = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def matrix_from_quat(quat: FloatArray) -> FloatArray:
    """Rotation matrix from a quaternion ``(w, x, y, z)`` (normalised first).

    Parameters
    ----------
    quat : ndarray, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    q = np.asarray(quat, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R

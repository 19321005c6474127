"""Material points of a floating bar (``viz3d.flexible.floating``): positions, velocities, velocity
Jacobians and bias accelerations for constraint rows and contact gaps, the small rotation and
angular velocity of their sections, generalized forces of point forces, and display centrelines.

A material point is a section ``x`` in [0, L] and an offset ``c`` (body axes) rigidly attached to
the section; in B it sits at ``s = s0 + c + N eta`` with ``N = U(x) - skew(c) P(x)`` (3, n). Here
P holds *every* bending field's section rotation (psi = w' for Euler-Bernoulli: the section turns
with the slope even where the model carries no rotary inertia). With ``v = [W_v, B_omega, eta_dot]``:

    W_p          = W_r + R s
    W_p_dot      = J v,        J = [I, -R skew(s), R N]                    (3, 6 + n)
    W_p_ddot     = J v_dot + a_bias,  a_bias = R (w x (w x s) + 2 w x N eta_dot)

so a constraint row ``J v = 0`` has ``gamma = -a_bias``. The section's small rotation is
``theta = P eta`` (body axes; section orientation ``R exp(skew(theta))``), its angular velocity
``W_Omega = R (w + P eta_dot)`` (first order in theta, as the field) with Jacobian ``[0, R, R P]``
and bias ``R (w x P eta_dot)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible.bar import X_RTOL
from viz3d.flexible.floating import E_X, FloatingBar
from viz3d.rotations import cross, skew

#: Sample points of a display centreline (uniform in x, ends included): enough for a smooth curve
#: of the few lowest modes one can see.
DISPLAY_POINTS = 33


@dataclass(frozen=True, eq=False)
class MaterialPoints:
    """k material points of one floating bar, with their shape matrices evaluated once.

    Attributes
    ----------
    x : ndarray, shape (k,)
        Sections [m], 0 <= x <= L.
    c : ndarray, shape (k, 3)
        Offsets from the section's centroid [m], body axes.
    s0 : ndarray, shape (k, 3)
        Undeformed positions in B, ``(x - x_G) e_x + c`` [m].
    N : ndarray, shape (k, 3, n)
        Displacement per unit eta, ``U - skew(c) P`` [m per unit eta].
    P : ndarray, shape (k, 3, n)
        Section rotation per unit eta, body axes [rad per unit eta].
    """

    x: FloatArray
    c: FloatArray
    s0: FloatArray = field(repr=False)
    N: FloatArray = field(repr=False)
    P: FloatArray = field(repr=False)


def material_points(bar: FloatingBar, x: FloatArray, c: FloatArray | None = None) -> MaterialPoints:
    """The material points at sections ``x`` (k,) with offsets ``c`` (k, 3) (default: on the axis)."""
    x = np.atleast_1d(np.asarray(x, dtype=float))
    if x.ndim != 1 or np.any(x < -X_RTOL * bar.length) or np.any(x > (1 + X_RTOL) * bar.length):
        raise ValueError(f"sections x must be a 1-D array in [0, {bar.length}] m")
    x = np.clip(x, 0.0, bar.length)
    c = np.zeros((len(x), 3)) if c is None else np.asarray(c, dtype=float).reshape(len(x), 3)
    U = np.zeros((len(x), 3, bar.n))
    P = np.zeros((len(x), 3, bar.n))
    for model, sl, d in zip(bar.fields, bar.field_slices, bar.directions):
        U[:, :, sl] = d[None, :, None] * model.displacement(x)[:, None, :]
        if model.kind == "bending":
            P[:, :, sl] = cross(E_X, d)[None, :, None] * model.rotation(x)[:, None, :]
    s0 = (x - bar.x_G)[:, None] * E_X[None, :] + c
    return MaterialPoints(x, c, s0, U - skew(c) @ P, P)


def _check(bar: FloatingBar, points: MaterialPoints) -> None:
    if points.N.shape[2] != bar.n:
        raise ValueError(f"points built for a bar with {points.N.shape[2]} elastic coordinates, this one has {bar.n}")


def _body_positions(points: MaterialPoints, eta: FloatArray) -> FloatArray:
    """s (k, 3) in B [m]."""
    return points.s0 + points.N @ eta


def point_positions(bar: FloatingBar, W_r: FloatArray, R_WB: FloatArray, eta: FloatArray, points: MaterialPoints) -> FloatArray:
    """W_p (k, 3) [m]."""
    _check(bar, points)
    return np.asarray(W_r, dtype=float) + _body_positions(points, eta) @ R_WB.T


def point_velocities(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray, points: MaterialPoints, v: FloatArray) -> FloatArray:
    """W_p_dot (k, 3) [m/s] for ``v = [W_v, B_omega, eta_dot]``."""
    _check(bar, points)
    w, eta_dot = v[3:6], v[6:]
    return v[:3] + (cross(w, _body_positions(points, eta)) + points.N @ eta_dot) @ R_WB.T


def point_jacobian(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray, points: MaterialPoints) -> FloatArray:
    """J (k, 3, 6 + n) with ``W_p_dot = J v``: columns ``[I, -R skew(s), R N]``."""
    _check(bar, points)
    k, n = len(points.x), points.N.shape[2]
    J = np.empty((k, 3, 6 + n))
    J[:, :, :3] = np.eye(3)
    J[:, :, 3:6] = -R_WB @ skew(_body_positions(points, eta))
    J[:, :, 6:] = R_WB @ points.N
    return J


def point_bias_accelerations(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray, points: MaterialPoints,
                             v: FloatArray) -> FloatArray:
    """``J_dot v`` (k, 3) [m/s^2], world axes: ``R (w x (w x s) + 2 w x N eta_dot)``; gamma = -this."""
    _check(bar, points)
    w = np.broadcast_to(v[3:6], (len(points.x), 3))
    s = _body_positions(points, eta)
    return (cross(w, cross(w, s)) + 2.0 * cross(w, points.N @ v[6:])) @ R_WB.T


def section_rotations(bar: FloatingBar, eta: FloatArray, points: MaterialPoints) -> FloatArray:
    """theta (k, 3) [rad]: small rotation vector of each point's section relative to B, body axes."""
    _check(bar, points)
    return points.P @ eta


def section_angular_jacobian(bar: FloatingBar, R_WB: FloatArray, points: MaterialPoints) -> FloatArray:
    """(k, 3, 6 + n): ``W_Omega = R (B_omega + P eta_dot)``, columns ``[0, R, R P]``."""
    _check(bar, points)
    k, n = len(points.x), points.P.shape[2]
    J = np.zeros((k, 3, 6 + n))
    J[:, :, 3:6] = R_WB
    J[:, :, 6:] = R_WB @ points.P
    return J


def section_angular_bias(bar: FloatingBar, R_WB: FloatArray, points: MaterialPoints, v: FloatArray) -> FloatArray:
    """(k, 3) [rad/s^2], world axes: the part of d(W_Omega)/dt not proportional to v_dot, ``R (w x P eta_dot)``."""
    _check(bar, points)
    w = np.broadcast_to(v[3:6], (len(points.x), 3))
    return cross(w, points.P @ v[6:]) @ R_WB.T


def point_forces(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray, points: MaterialPoints, W_F: FloatArray) -> FloatArray:
    """Generalized force ``sum_i J_i^T F_i`` (6 + n,) of world forces ``W_F`` (k, 3) [N] at the points:
    ``[sum F, sum s x F_B (body axes) [N m], sum N^T F_B]``, ``F_B = R^T F``."""
    _check(bar, points)
    F_B = np.asarray(W_F, dtype=float).reshape(-1, 3) @ R_WB
    s = _body_positions(points, eta)
    return np.concatenate([F_B.sum(axis=0) @ R_WB.T, cross(s, F_B).sum(axis=0), np.einsum("kiq,ki->q", points.N, F_B)])


def centreline_points(bar: FloatingBar, n_points: int = DISPLAY_POINTS) -> MaterialPoints:
    """``n_points`` material points on the axis, uniform from x = 0 to L (for display)."""
    return material_points(bar, np.linspace(0.0, bar.length, n_points))


def centreline(bar: FloatingBar, W_r: FloatArray, R_WB: FloatArray, eta: FloatArray,
               points: MaterialPoints | None = None) -> FloatArray:
    """World positions (k, 3) [m] of the deformed axis (``eta = 0``: undeformed); pass ``points``
    from ``centreline_points`` to evaluate the shapes once."""
    points = centreline_points(bar) if points is None else points
    return point_positions(bar, W_r, R_WB, eta, points)

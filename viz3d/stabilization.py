"""Mass-orthogonal projections of positions and velocities onto the constraint manifold.

Positions: Newton iterations ``dx = -M^-1 C_v^T (C_v M^-1 C_v^T)^-1 C`` in body-velocity space
(``dx`` per body: ``[dW_r, B_dphi]``), applied as ``W_r += dW_r`` and a small body-frame rotation
``B_dphi``. Velocities: ``v -= M^-1 C_v^T (C_v M^-1 C_v^T)^-1 C_v v`` (one linear step; the joints
are scleronomic, ``C_t = 0``). Both are the minimum-kinetic-metric corrections.
"""

from __future__ import annotations

import numpy as np

from viz3d._typing import FloatArray
from viz3d.constraints import apply_jacobian, apply_jacobian_transpose, constraint_residual, schur_solve
from viz3d.kinematics import pose_from

#: Newton iterations allowed for a position projection.
MAX_ITER = 50


class ProjectionError(RuntimeError):
    """The position projection did not converge."""


def _pose(system, q, chart):
    W_r, theta = system.split_q(q)
    return pose_from(W_r, system.rotation.matrix(theta, chart))


def _jacobian(system, pose) -> FloatArray:
    return np.concatenate([js.jacobian(pose).reshape(-1, 2, 6) for js in system.joints.joints])


def _min_norm_correction(system, J, r) -> FloatArray:
    """``M^-1 C_v^T (C_v M^-1 C_v^T)^-1 r`` per body, shape (nb, 6)."""
    M_inv = system.bodies.M_inv
    lam = schur_solve(system.joints, M_inv, J, r)
    CtL = apply_jacobian_transpose(system.joints, J, lam, M_inv.shape[0])
    return np.einsum("bij,bj->bi", M_inv, CtL)[:-1]


def project_positions(system, q: FloatArray, chart: FloatArray, tol: float = 1e-12,
                      max_iter: int = MAX_ITER) -> tuple[FloatArray, int]:
    """Project ``q`` (n_q,) onto ``C(q) = 0``; return the new ``q`` and the iterations used.

    Raises
    ------
    ProjectionError
        If ``max |C| > tol`` after ``max_iter`` iterations.
    """
    if system.n_c == 0:
        return q, 0
    q = q.copy()
    for it in range(max_iter + 1):
        pose = _pose(system, q, chart)
        C = constraint_residual(system.joints, pose)
        if np.max(np.abs(C)) <= tol:
            return q, it
        dx = -_min_norm_correction(system, _jacobian(system, pose), C)
        W_r, theta = system.split_q(q)
        q = system.join_q(W_r + dx[:, :3], system.rotation.correct(theta, dx[:, 3:]))
    raise ProjectionError(f"position projection left max |C| = {np.max(np.abs(C)):.3e} m after {max_iter} iterations")


def project_velocities(system, q: FloatArray, v: FloatArray, chart: FloatArray) -> FloatArray:
    """Project ``v`` (n_v,) onto ``C_v v = 0``."""
    if system.n_c == 0:
        return v
    pose = _pose(system, q, chart)
    J = _jacobian(system, pose)
    v_body = np.concatenate([v.reshape(-1, 6), np.zeros((1, 6))])
    dv = _min_norm_correction(system, J, apply_jacobian(system.joints, J, v_body))
    return (v.reshape(-1, 6) - dv).reshape(-1)

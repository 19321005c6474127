"""Mass-orthogonal projections of positions and velocities onto the constraint manifold.

Positions: Newton iterations ``dx = -M^-1 C_v^T (C_v M^-1 C_v^T)^-1 C`` in velocity space
(``dx`` per floating frame: ``[dW_r, B_dphi]``; per flexible body also ``d_eta``), applied as
``W_r += dW_r``, a small body-frame rotation ``B_dphi`` and ``eta += d_eta``. Velocities:
``v -= M^-1 C_v^T (C_v M^-1 C_v^T)^-1 (C_v v + C_t)`` (one linear step; ``C_t`` is the drives' explicit
time rate, zero for scleronomic joints). Positions and velocities are projected at the time ``t``
the drives are evaluated at. Both are the minimum-kinetic-metric corrections. Only the rows that act are projected on (the
joints, and kinematic contacts while touching: ``memory``, the state's contact phases).
"""

from __future__ import annotations

import numpy as np

from viz3d._typing import FloatArray
from viz3d.constraints import apply_jacobian_transpose, constraint_rows, schur_solve
from viz3d.dynamics import body_state, flat_velocity, split_velocity, system_mass

#: Newton iterations allowed for a position projection.
MAX_ITER = 50


class ProjectionError(RuntimeError):
    """The position projection did not converge; ``t`` [s] is the time of the state projected."""

    def __init__(self, message: str, t: float):
        super().__init__(message)
        self.t = t


def _min_norm_correction(system, cfg, rows, r) -> FloatArray:
    """``M^-1 C_v^T (C_v M^-1 C_v^T)^-1 r`` in the order of ``v``, shape (n_v,), over the rows that act."""
    mass = system_mass(system, cfg)
    J, Je = rows.J, rows.Je
    lam = schur_solve(system.joints, mass, J, r, Je=Je, inactive=rows.inactive)
    CtL, CtL_e = apply_jacobian_transpose(system.joints, J, lam, system.n_bodies + 1, Je)
    return flat_velocity(system, *mass.solve(CtL, CtL_e))


def project_positions(system, q: FloatArray, chart: FloatArray, tol: float = 1e-12,
                      max_iter: int = MAX_ITER, memory: tuple = (), t: float = 0.0) -> tuple[FloatArray, int]:
    """Project ``q`` (n_q,) onto ``C(q, t) = 0``; return the new ``q`` and the iterations used.

    Raises
    ------
    ProjectionError
        If ``max |C| > tol`` after ``max_iter`` iterations.
    """
    if system.n_c == 0:
        return q, 0
    q = q.copy()
    v0 = np.zeros(system.n_v)
    for it in range(max_iter + 1):
        cfg = body_state(system, q, v0, chart, t)
        rows = constraint_rows(system.joints, cfg, memory)
        C = rows.C
        if np.max(np.abs(C)) <= tol:
            return q, it
        dx = -_min_norm_correction(system, cfg, rows, C)
        W_r, theta = system.split_q(q)
        dW, dphi = system.split_v(dx)
        eta = system.elastic_part(q, system.n_frames * system.n_q_body) + system.elastic_part(dx, 6 * system.n_frames)
        q = system.join_q(W_r + dW, system.rotation.correct(theta, dphi), eta)
    raise ProjectionError(f"position projection left max |C| = {np.max(np.abs(C)):.3e} m after {max_iter} iterations",
                          t)


def project_velocities(system, q: FloatArray, v: FloatArray, chart: FloatArray, memory: tuple = (),
                       t: float = 0.0) -> FloatArray:
    """Project ``v`` (n_v,) onto ``C_v v + C_t = 0`` at time ``t``."""
    if system.n_c == 0:
        return v
    cfg = body_state(system, q, v, chart, t)
    rows = constraint_rows(system.joints, cfg, memory)
    frame, elastic = split_velocity(system, v)
    return v - _min_norm_correction(system, cfg, rows, rows.velocity_residual(system.joints, frame, elastic))

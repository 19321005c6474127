"""Mass-orthogonal projection of a state onto the constraints, in the kernel: what
``viz3d.stabilization.project_positions`` then ``project_velocities`` do (the ``projection``
formulation's ``post_step``), on the field's own rows, mass blocks and banded Schur solve, so O(N)
on chains.

Positions: Newton iterations on ``C(q, t) = 0`` with the correction ``dx = -M^-1 C_v^T (C_v M^-1
C_v^T)^-1 C`` in velocity space, applied as ``W_r += dW_r``, the orientation coordinates moved by the
small body-frame rotation ``B_dphi`` as ``RotationCoordinates.correct`` moves them (Euler angles by its
rates, Euler parameters by ``p (x) exp(B_dphi / 2)``) and ``eta += d_eta``;
until ``max |C| <= tol`` (``Model.projection_tol``) or ``Model.projection_iter`` corrections.
Velocities, at the projected positions: ``v -= M^-1 C_v^T (C_v M^-1 C_v^T)^-1 (C_v v + C_t)``.
"""

from __future__ import annotations

from viz3d.compiled import inline, jit
from viz3d.flexible.floating_kernel import FX_FLOATING, shape_moments
from viz3d.kernel.field import (
    OK,
    PROJECTION,
    SINGULAR,
    coordinate_rates,
    correct,
    factor_blocks,
    fill_rows,
    frames,
    mass_weighted_rows,
    row_times,
    schur_solve,
    turn_quaternion,
    twists,
)
from viz3d.points import kinematics


@jit
def project(t, y, chart, m, v, w, rows):
    """Project the positions, then the velocities, of ``y`` (in place) onto the rows at time ``t``
    [s]; returns ``OK``, ``SINGULAR`` (a mass block or ``C_v M^-1 C_v^T`` not positive definite) or
    ``PROJECTION`` (``max |C| > m.projection_tol`` after ``m.projection_iter`` corrections; ``y``
    then holds the last iterate)."""
    if m.row_body.shape[0] == 0:
        return OK
    for it in range(m.projection_iter + 1):
        if not _rows_at(t, y, chart, m, v, w, rows):
            return SINGULAR
        if _max_abs(v.C) <= m.projection_tol:
            break
        if it == m.projection_iter:
            return PROJECTION
        for r in range(v.C.shape[0]):
            w.lam[r] = v.C[r]
        if not _min_norm_correction(m, v, w):
            return SINGULAR
        _move_positions(m, w, y)
    # the rows and mass blocks of the projected positions are in v, w: the velocity step needs no new ones
    twists(m, w)
    for r in range(m.row_body.shape[0]):
        w.lam[r] = row_times(m.row_body, v.row_je, m.body_kind, m.body_flex, m.fx_i, v.J, v.Je, r, w.tw,
                             w.eta_dot) + v.Ct[r]
    if not _min_norm_correction(m, v, w):
        return SINGULAR
    _move_velocities(m, w, y)
    return OK


@inline
def _rows_at(t, y, chart, m, v, w, rows):
    """Frames, material points, flexible mass blocks (factorized) and rows at ``(t, y)``; False if a
    mass block is not positive definite."""
    frames(m, v, w, y, chart)
    kinematics(m, v, w)
    for fx in range(m.fx_i.shape[0]):  # the floating bars' shape moments at this eta, which the field's
        if m.fx_i[fx, FX_FLOATING] == 1:  # velocity forces leave for the mass blocks (factor): not run here
            shape_moments(m.fx_i, m.fx_pool, m.fx_bij, w.fx_work, fx, w.eta)
    if not factor_blocks(m, v, w):
        return False
    fill_rows(m.row_body, v, t, rows)
    return True


@inline
def _max_abs(x):
    """``max |x|``; nan if an entry is nan (so that a non-finite residual never passes a tolerance)."""
    out = 0.0
    for i in range(x.shape[0]):
        a = abs(x[i])
        if not a <= out:
            if a != a:
                return a
            out = a
    return out


@inline
def _min_norm_correction(m, v, w):
    """``w.a``, ``w.ae`` = ``-M^-1 C_v^T (C_v M^-1 C_v^T)^-1 b`` per body (frame, elastic) for ``b`` in
    ``w.lam`` (the multipliers left there); False if the matrix is not positive definite."""
    for r in range(m.row_body.shape[0]):
        mass_weighted_rows(m, v, w, r)
    if not schur_solve(m, v, w, 0.0):
        return False
    for b in range(m.nb + 1):
        for i in range(6):
            w.a[b, i] = 0.0
    for e in range(w.ae.shape[0]):
        w.ae[e] = 0.0
    correct(m, v, w)
    return True


@inline
def _move_positions(m, w, y):
    """``q`` moved by the velocity-space increment in ``w.a``, ``w.ae``: ``W_r += dW_r``, Euler angles
    by the ZXZ rates of ``B_dphi`` (``viz3d.rotations.euler_rates_from_body_omega``), Euler parameters
    by the finite rotation ``B_dphi`` (``turn_quaternion``), ``eta += d_eta``."""
    nf, nqb = m.frame_body.shape[0], 3 + m.n_rot
    for k in range(nf):
        b = m.frame_body[k]
        q0 = nqb * k
        for i in range(3):
            y[q0 + i] += w.a[b, i]
        if m.n_rot == 4:
            turn_quaternion(y, q0 + 3, w.a[b, 3], w.a[b, 4], w.a[b, 5])
        else:
            d = coordinate_rates(3, y, q0 + 3, w.a[b, 3], w.a[b, 4], w.a[b, 5])
            y[q0 + 3] += d[0]
            y[q0 + 4] += d[1]
            y[q0 + 5] += d[2]
    for e in range(m.n_e):
        y[nqb * nf + e] += w.ae[e]


@inline
def _move_velocities(m, w, y):
    """``v += w.a`` (frames ``[W_v, B_omega]``) and ``eta_dot += w.ae``."""
    nf = m.frame_body.shape[0]
    for k in range(nf):
        b = m.frame_body[k]
        for i in range(6):
            y[m.n_q + 6 * k + i] += w.a[b, i]
    for e in range(m.n_e):
        y[m.n_q + 6 * nf + e] += w.ae[e]

"""Compiled pieces of the floating bar (``viz3d.flexible.floating``) for the kernel: packing, the
mass block's factorization and solves, velocity, elastic and gravity forces.

Same formulas as the NumPy module (whose docstring derives them), evaluated on flat pools. The mass
block is solved by eliminating the elastic coordinates, whose block ``M_ee`` is constant:

    M = [[M_rr(eta, R), M_re(eta, R)], [M_re^T, M_ee]],   X = M_ee^-1 M_re^T   (n, 6),
    Sc = M_rr - M_re X   (6 x 6, factorized per evaluation),
    x_r = Sc^-1 (b_r - M_re M_ee^-1 b_e),   x_e = M_ee^-1 b_e - X x_r,

O(n^2) per evaluation with a dense ``M_ee^-1`` (finite elements) and O(n) with a diagonal one
(modes). A body whose frame is fixed has ``x_e = M_ee^-1 b_e`` only.

Layout (``pack_flexible``): per flexible body a row of ``m.fx_i`` (columns ``FX_*``), a row of
``m.fx_f`` ``[mass, I0 (9)]``, matrices in the pool ``m.fx_pool`` (row-major), the (i, j) indices
of the nonzero blocks of ``B[i, j, :, :]`` in ``m.fx_bij``; scratch of the evaluation in
``w.fx_work`` (``F`` (3, 3, n), ``M_re`` (6, n), ``X`` (n, 6)) and ``w.fx_sc`` (the Cholesky factor
of ``Sc``). Gravity needs nothing here: its compiled piece applies each body's weight at its
centre of mass, a material point with ``N = S / m`` (``viz3d.kernel.model.Packer``).
"""

from __future__ import annotations

import math

import numpy as np

from viz3d.compiled import cross3, inline, jit, matvec3, tmatvec3

FX_BODY, FX_FLOATING, FX_N, FX_E0, FX_S, FX_A, FX_NB, FX_BIJ, FX_B = 0, 1, 2, 3, 4, 5, 6, 7, 8
FX_MINV_KIND, FX_MINV, FX_K_KIND, FX_K, FX_C_KIND, FX_C, FX_WORK = 9, 10, 11, 12, 13, 14, 15
FX_KW_KIND, FX_KW = 16, 17  # geometric stiffening's K_omega (ZERO without it)
#: How a matrix is stored in the pool.
ZERO, DIAGONAL, DENSE = 0, 1, 2
#: A matrix is stored as diagonal when its off-diagonal entries are at most this many times
#: n eps max |diagonal|: the round-off of the quadrature of orthogonal modes, not model content.
DIAGONAL_ROUNDOFF = 10.0


def matrix_kind(A: np.ndarray) -> int:
    """``ZERO``, ``DIAGONAL`` or ``DENSE`` for the square matrix ``A``."""
    n = A.shape[0]
    scale = np.abs(np.diag(A)).max(initial=0.0)
    off = np.abs(A - np.diag(np.diag(A))).max(initial=0.0)
    if scale == 0.0 and off == 0.0:
        return ZERO
    return DIAGONAL if off <= DIAGONAL_ROUNDOFF * n * np.finfo(float).eps * scale else DENSE


def pack_flexible(flexible, e_offsets) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """``(fx_i, fx_f, fx_pool, fx_bij, work size)`` of the flexible bodies (``viz3d.bodies.FlexibleBody``)
    with the offsets of their eta in the stacked elastic coordinates."""
    fx_i = np.zeros((len(flexible), 18), np.int64)
    fx_f = np.zeros((len(flexible), 10))
    pool, bij, size, work = [], [], 0, 0

    def put(a) -> int:
        nonlocal size
        a = np.ascontiguousarray(a, dtype=float).ravel()
        pool.append(a)
        size += a.size
        return size - a.size

    for k, (fb, e0) in enumerate(zip(flexible, e_offsets)):
        bar, n = fb.bar, fb.n
        blocks = [(i, j) for i in range(3) for j in range(3) if np.any(bar.B[i, j])]
        row = fx_i[k]
        row[[FX_BODY, FX_FLOATING, FX_N, FX_E0]] = fb.index, int(fb.floating), n, e0
        row[FX_S], row[FX_A] = put(bar.S), put(bar.A)
        row[FX_NB], row[FX_BIJ] = len(blocks), sum(len(b) for b in bij)
        bij.append(np.array(blocks, np.int64).ravel())
        row[FX_B] = put(np.array([bar.B[i, j] for i, j in blocks]).reshape(-1)) if blocks else size
        K_omega = np.zeros((n, n)) if bar.K_omega is None else bar.K_omega
        for kind_col, col, A in ((FX_MINV_KIND, FX_MINV, fb.M_ee_inv), (FX_K_KIND, FX_K, bar.K), (FX_C_KIND, FX_C, bar.C),
                                 (FX_KW_KIND, FX_KW, K_omega)):
            kind = matrix_kind(A)
            row[kind_col] = kind
            row[col] = put(np.diag(A) if kind == DIAGONAL else A) if kind != ZERO else size
        if fb.floating:
            row[FX_WORK] = work
            work += 21 * n
        fx_f[k, 0] = bar.mass
        fx_f[k, 1:] = bar.I0.ravel()
    fx_pool = np.concatenate(pool) if pool else np.zeros(0)
    fx_bij = np.concatenate(bij) if bij else np.zeros(0, np.int64)
    return fx_i, fx_f, fx_pool, fx_bij.astype(np.int64), work


# ---------------------------------------------------------------------------- matrix helpers


@jit
def _apply(kind, pool, off, n, x, x0, out, o0, alpha):
    """``out[o0:o0+n] += alpha A x[x0:x0+n]`` for a matrix stored as ``kind`` at ``pool[off]``."""
    if kind == DIAGONAL:
        for q in range(n):
            out[o0 + q] += alpha * pool[off + q] * x[x0 + q]
    elif kind == DENSE:
        for p in range(n):
            acc = 0.0
            for q in range(n):
                acc += pool[off + p * n + q] * x[x0 + q]
            out[o0 + p] += alpha * acc


@jit
def _quadratic(kind, pool, off, n, x, x0):
    """``x^T A x`` for a matrix stored as ``kind``."""
    return _bilinear(kind, pool, off, n, x, x0, x, x0)


@jit
def _bilinear(kind, pool, off, n, x, x0, y, y0):
    """``x^T A y`` for a matrix stored as ``kind``."""
    acc = 0.0
    if kind == DIAGONAL:
        for q in range(n):
            acc += x[x0 + q] * pool[off + q] * y[y0 + q]
    elif kind == DENSE:
        for p in range(n):
            for q in range(n):
                acc += x[x0 + p] * pool[off + p * n + q] * y[y0 + q]
    return acc


@jit
def _first_moment(fx_i, pool, fx, x, x0, out):
    """``out = S x[x0:x0+n]`` (3,)."""
    n, S = fx_i[fx, FX_N], fx_i[fx, FX_S]
    for c in range(3):
        acc = 0.0
        for q in range(n):
            acc += pool[S + c * n + q] * x[x0 + q]
        out[c] = acc


@jit
def shape_moments(fx_i, pool, bij, work, fx, eta):
    """``F = A + B . eta`` (3, 3, n) into the body's scratch."""
    n, e0, A, F = fx_i[fx, FX_N], fx_i[fx, FX_E0], fx_i[fx, FX_A], fx_i[fx, FX_WORK]
    for k in range(9 * n):
        work[F + k] = pool[A + k]
    B, ij = fx_i[fx, FX_B], fx_i[fx, FX_BIJ]
    for blk in range(fx_i[fx, FX_NB]):
        i, j = bij[ij + 2 * blk], bij[ij + 2 * blk + 1]
        base = B + blk * n * n
        for p in range(n):
            eta_p = eta[e0 + p]
            if eta_p != 0.0:
                for q in range(n):
                    work[F + (3 * i + j) * n + q] += pool[base + p * n + q] * eta_p


@jit
def _contract(fx_i, work, fx, x, x0, out):
    """``out[i, j] = sum_q F[i, j, q] x_q`` (3, 3) (``F . x``)."""
    n, F = fx_i[fx, FX_N], fx_i[fx, FX_WORK]
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for q in range(n):
                acc += work[F + (3 * i + j) * n + q] * x[x0 + q]
            out[i, j] = acc


@jit
def _inertia(fx_i, fx_f, pool, work, fx, eta, J):
    """``J(eta) = tr(Sigma2) I - Sigma2``, ``Sigma2 = I0 + (A . eta)^T + F . eta`` (3, 3)."""
    n, e0, A = fx_i[fx, FX_N], fx_i[fx, FX_E0], fx_i[fx, FX_A]
    _contract(fx_i, work, fx, eta, e0, J)               # F . eta
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for q in range(n):
                acc += pool[A + (3 * j + i) * n + q] * eta[e0 + q]  # (A . eta)^T
            J[i, j] += fx_f[fx, 1 + 3 * i + j] + acc
    tr = J[0, 0] + J[1, 1] + J[2, 2]
    for i in range(3):
        for j in range(3):
            J[i, j] = (tr if i == j else 0.0) - J[i, j]


# ---------------------------------------------------------------------------- forces


@inline
def body_forces(m, v, w, fx):
    """Elastic forces ``-K eta - C eta_dot`` (into ``v.Qe``) and their damping power (``w.aux``'s
    second last entry); on a floating frame also the velocity forces (centrifugal, Coriolis,
    gyroscopic: ``w.Q`` frame row, body-axes torque, and ``v.Qe``) and the geometric stiffening
    ``-w_perp^2 K_omega eta`` (``viz3d.flexible.floating.velocity_forces``; ``w_perp^2 = |w|^2 - w_x^2``),
    whose power goes to the work in (``w.aux``'s last entry). Leaves ``F`` in the scratch."""
    i = m.fx_i[fx]
    b, n, e0 = i[FX_BODY], i[FX_N], i[FX_E0]
    pool = m.fx_pool
    _apply(i[FX_K_KIND], pool, i[FX_K], n, w.eta, e0, v.Qe, e0, -1.0)
    _apply(i[FX_C_KIND], pool, i[FX_C], n, w.eta_dot, e0, v.Qe, e0, -1.0)
    w.aux[w.aux.shape[0] - 2] += _quadratic(i[FX_C_KIND], pool, i[FX_C], n, w.eta_dot, e0)
    if i[FX_FLOATING] == 1:
        _velocity_forces(m.fx_i, m.fx_f, pool, m.fx_bij, w.fx_work, fx, v.R[b], w.wB[b], w.eta, w.eta_dot,
                         w.Q[b], v.Qe, v.v3, w.m3)
        if i[FX_KW_KIND] != ZERO:
            om = w.wB[b]
            w_perp2 = om[1] * om[1] + om[2] * om[2]  # B_omega^T P_AXIS B_omega, P_AXIS = diag(0, 1, 1)
            _apply(i[FX_KW_KIND], pool, i[FX_KW], n, w.eta, e0, v.Qe, e0, -w_perp2)
            w.aux[w.aux.shape[0] - 1] -= w_perp2 * _bilinear(i[FX_KW_KIND], pool, i[FX_KW], n, w.eta_dot, e0, w.eta, e0)


@jit
def _velocity_forces(fx_i, fx_f, pool, bij, work, fx, R, om, eta, eta_dot, Q, Qe, v3, m3):
    """Add Q_velocity of a floating bar to its frame row ``Q`` (6,) and to ``Qe``."""
    i = fx_i[fx]
    n, e0 = i[FX_N], i[FX_E0]
    shape_moments(fx_i, pool, bij, work, fx, eta)
    sc, scd, t1, t2 = v3[10], v3[11], v3[12], v3[13]
    _first_moment(fx_i, pool, fx, eta, e0, sc)
    _first_moment(fx_i, pool, fx, eta_dot, e0, scd)
    # Q_v = -R (w x (w x s_c) + 2 w x s_c_dot)
    cross3(om, sc, t1)
    cross3(om, t1, t2)
    cross3(om, scd, t1)
    for c in range(3):
        t2[c] += 2.0 * t1[c]
    matvec3(R, t2, t1)
    for c in range(3):
        Q[c] -= t1[c]
    # Q_w = -w x J w - 2 (tr(Y) w - Y w),  Y = (F . eta_dot)^T
    J, Y = m3[0], m3[1]
    _inertia(fx_i, fx_f, pool, work, fx, eta, J)
    matvec3(J, om, t1)
    cross3(om, t1, t2)
    _contract(fx_i, work, fx, eta_dot, e0, Y)           # F . eta_dot = Y^T
    trY = Y[0, 0] + Y[1, 1] + Y[2, 2]
    tmatvec3(Y, om, t1)                                 # Y w
    for c in range(3):
        Q[3 + c] -= t2[c] + 2.0 * (trY * om[c] - t1[c])
    # Q_eta = -sum_ij W_ij F[j, i, :] - 2 sum_ij skew(w)_ij B[i, j] eta_dot
    Wm = m3[2]
    ww = om[0] * om[0] + om[1] * om[1] + om[2] * om[2]
    for r in range(3):
        for c in range(3):
            Wm[r, c] = om[r] * om[c] - (ww if r == c else 0.0)
    F = i[FX_WORK]
    for q in range(n):
        acc = 0.0
        for r in range(3):
            for c in range(3):
                acc += Wm[r, c] * work[F + (3 * c + r) * n + q]
        Qe[e0 + q] -= acc
    B, ij = i[FX_B], i[FX_BIJ]
    for blk in range(i[FX_NB]):
        r, c = bij[ij + 2 * blk], bij[ij + 2 * blk + 1]
        sk = _skew_of(om, r, c)
        if sk == 0.0:
            continue
        base = B + blk * n * n
        for q in range(n):
            acc = 0.0
            for p in range(n):
                acc += pool[base + q * n + p] * eta_dot[e0 + p]
            Qe[e0 + q] -= 2.0 * sk * acc


@jit
def _skew_of(x, r, c):
    """``skew(x)[r, c]``."""
    if r == c:
        return 0.0
    if r == 0:
        return -x[2] if c == 1 else x[1]
    if r == 1:
        return x[2] if c == 0 else -x[0]
    return -x[1] if c == 0 else x[0]


# ---------------------------------------------------------------------------- mass block


@jit
def factor(fx_i, fx_f, pool, work, fx_sc, fx, R, eta, v3, m3):
    """Assemble ``M_re``, ``X = M_ee^-1 M_re^T`` and the Cholesky factor of ``Sc`` of a floating bar
    (after its velocity forces, which leave ``F`` in the scratch). False if ``Sc`` is not positive
    definite."""
    i = fx_i[fx]
    if i[FX_FLOATING] == 0:
        return True
    n, e0 = i[FX_N], i[FX_E0]
    F, Mre, X = i[FX_WORK], i[FX_WORK] + 9 * n, i[FX_WORK] + 15 * n
    S = i[FX_S]
    for q in range(n):  # rows 0-2: R S; rows 3-5: G = eps_kij F[i, j]
        for c in range(3):
            acc = 0.0
            for k in range(3):
                acc += R[c, k] * pool[S + k * n + q]
            work[Mre + c * n + q] = acc
        work[Mre + 3 * n + q] = work[F + 5 * n + q] - work[F + 7 * n + q]
        work[Mre + 4 * n + q] = work[F + 6 * n + q] - work[F + 2 * n + q]
        work[Mre + 5 * n + q] = work[F + 1 * n + q] - work[F + 3 * n + q]
    for c in range(6):  # X[:, c] = M_ee^-1 M_re[c]^T
        _apply_strided(i[FX_MINV_KIND], pool, i[FX_MINV], n, work, Mre + c * n, work, X + c)
    Sc = fx_sc[fx]
    sc, J = v3[10], m3[0]
    _first_moment(fx_i, pool, fx, eta, e0, sc)
    _inertia(fx_i, fx_f, pool, work, fx, eta, J)
    mass = fx_f[fx, 0]
    for r in range(3):
        for c in range(3):
            Sc[r, c] = mass if r == c else 0.0
            Sc[3 + r, 3 + c] = J[r, c]
            acc = 0.0  # M_rr[0:3, 3:6] = -R skew(s_c)
            for k in range(3):
                acc -= R[r, k] * _skew_of(sc, k, c)
            Sc[r, 3 + c] = acc
            Sc[3 + c, r] = acc
    for r in range(6):
        for c in range(6):
            acc = 0.0
            for q in range(n):
                acc += work[Mre + r * n + q] * work[X + q * 6 + c]
            Sc[r, c] -= acc
    return _cholesky6(Sc)


@jit
def _apply_strided(kind, pool, off, n, x, x0, out, o0):
    """``out[o0 + 6 q] = (A x[x0:x0+n])_q`` (a column of an (n, 6) row-major matrix)."""
    for q in range(n):
        out[o0 + 6 * q] = 0.0
    if kind == DIAGONAL:
        for q in range(n):
            out[o0 + 6 * q] = pool[off + q] * x[x0 + q]
    elif kind == DENSE:
        for p in range(n):
            acc = 0.0
            for q in range(n):
                acc += pool[off + p * n + q] * x[x0 + q]
            out[o0 + 6 * p] = acc


@jit
def _cholesky6(A):
    """In place: the lower Cholesky factor of the SPD (6, 6) ``A``; False if not positive definite."""
    for j in range(6):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        A[j, j] = d
        for i in range(j + 1, 6):
            s = A[i, j]
            for k in range(j):
                s -= A[i, k] * A[j, k]
            A[i, j] = s / d
    return True


@jit
def solve(fx_i, pool, work, fx_sc, fx, b6, be, be0, x6, xe, xe0):
    """``[x6; xe] = M^-1 [b6; be]`` for flexible body ``fx``: ``b6`` (6,) frame part (ignored and
    ``x6`` zero on a fixed frame), elastic parts at ``be[be0:]``, ``xe[xe0:]`` (n). Needs ``factor``."""
    i = fx_i[fx]
    n = i[FX_N]
    for q in range(n):
        xe[xe0 + q] = 0.0
    _apply(i[FX_MINV_KIND], pool, i[FX_MINV], n, be, be0, xe, xe0, 1.0)
    if i[FX_FLOATING] == 0:
        for c in range(6):
            x6[c] = 0.0
        return
    Mre, X, L = i[FX_WORK] + 9 * n, i[FX_WORK] + 15 * n, fx_sc[fx]
    for c in range(6):  # r = b_r - M_re y
        acc = b6[c]
        for q in range(n):
            acc -= work[Mre + c * n + q] * xe[xe0 + q]
        x6[c] = acc
    for r in range(6):  # L z = r
        s = x6[r]
        for k in range(r):
            s -= L[r, k] * x6[k]
        x6[r] = s / L[r, r]
    for r in range(5, -1, -1):  # L^T x = z
        s = x6[r]
        for k in range(r + 1, 6):
            s -= L[k, r] * x6[k]
        x6[r] = s / L[r, r]
    for q in range(n):
        acc = 0.0
        for c in range(6):
            acc += work[X + q * 6 + c] * x6[c]
        xe[xe0 + q] -= acc

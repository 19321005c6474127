"""ALI3-P's steps in the compiled kernel: the compiled path of ``viz3d.ali3p``.

``viz3d.ali3p`` holds the method (predictor, Newton iteration, multiplier updates, the switch to
the exact tangent, projections, halvings) on NumPy: the reference. Here one compiled call
(``ali3p_frames``) takes a run's steps from one output frame to the next, each the same attempt(s)
of a step as the reference's (``_attempts``: the same stopping tests, tangents and counts of
evaluations, so the reference's iterates), with what ``viz3d.simulate`` does between steps (health
checks, normalisation, chart switches, the force elements' memory), and stops before a step that
fails: Python takes that one for its diagnosis. A single step that ``viz3d.ali3p`` takes (its
halvings stay there: they call it again) is the same call, one frame of one step without the work
between steps, which Python then does (``KernelALI3P.step``). In the call:

* a trial increment ``dx`` is retracted (``W_r + dW_r``; Euler parameters turned by
  ``turn_quaternion``; ZXZ Euler angles through ``R exp(skew(B_dphi))`` on the branch and turn
  of the old angles, as ``viz3d.coordinates.EulerZXZ.advance``), and forces, gyroscopic terms,
  constraint rows ``C``, ``C_v`` and ``gamma`` are evaluated by the field's own stages
  (``viz3d.kernel.field``);
* matrices over the velocity unknowns are in LAPACK's band storage, the bodies in body order or in
  reverse Cuthill-McKee's where that narrows the band (``_band_order``), of half-bandwidth
  ``bw = 6 d + 5`` where ``d`` is the largest distance in that order of two coupled bodies
  (``viz3d.sparsity.body_adjacency``): 11 on a chain of any length. Column ``j`` of a band
  matrix ``A`` (n, n) is row ``j`` of a C array ``ab`` (n, 3 bw + 1), ``A[i, j] = ab[j, 2 bw + i - j]``
  (Fortran's ``AB`` of ``gbtrf`` with ``LDAB = 3 bw + 1``; the first ``bw`` entries of a column
  room for the LU's fill). ``C_v^T C_v`` is assembled from the rows' (2, 6) blocks, the
  finite-difference tangents (columns grouped as ``viz3d.sparsity.sparse_fd_plan`` groups them)
  are written into the band, and ``T`` (not symmetric once ``K``, ``D`` are in it) is factored by
  LAPACK's banded LU with partial pivoting (``dgbtrf``/``dgbtrs`` of ``scipy.linalg.cython_lapack``,
  called from compiled code): O(N) per step on a chain. (A banded LU with partial pivoting written
  in numba took 1.1-1.4x LAPACK's time at 2-200 links on random band matrices that need pivoting.)

Force elements with branches (joint stops, shape contacts) are held within a step as ``viz3d.ali3p._solve``
holds them: at the predictor (``_branches``, their ``hold_piece``: a stop's side, the shape contacts as
material points against tangent planes with an active set and their anchors' matches, in their packed
data), the fresh force tangents taken there, then checked at the converged point and re-solved from
there (``_solve``, ``MAX_SET_UPDATES``), a cycle of two sets solved between them by bisection on the
blend of their forces (``_filippov``, each blended point holding the branches as at one set, then at
the other: ``_mixed_point``); a step whose set does not settle comes back to Python for the reason
(``viz3d.ali3p.not_settled``, naming what changed). Force elements that remember (the stick
anchors) are loaded at each call and renewed after each step of ``ali3p_frames`` (their
``after_step_piece``), one frame per call so that each state carries its own.

The stages with one call site (``_attempts``, ``_solve``, ``_filippov``, ``_finish``,
``_residual_tangent``) are inlined into their callers
(``viz3d.compiled.inline``), and a single step is a call of ``ali3p_frames``, not an entry of its own:
each compiled function of the kernel's tuples has a cost of its own to compile, more than these
bodies' (README, "The anchor hoist": its signature's compile time). The steps are the same to the bit.

Covered: rigid bodies, every joint and force element with a compiled piece, joint stops and shape
contacts included. Not covered (the run keeps the NumPy path and says why,
``viz3d.kernel.model._check_stepping``): flexible bodies, the law contacts of ``System.contacts``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from viz3d.ali3p import (
    MAX_BISECTIONS,
    MAX_CUTS,
    MAX_ITER,
    MAX_SET_UPDATES,
    NONFINITE_STATE,
    ROUND_OFF_FACTOR,
    SINGULAR_MATRIX,
    SLOW_RATE,
    cycled,
    failure,
    no_convergence,
    not_settled,
    refresh_tangent,
    small_update,
    too_slow,
)
from viz3d.compiled import CHANGE, HOLD, RELEASE, entry, hold_piece, inline, jit, numba, registered
from viz3d.integrators.base import Status
from viz3d.integrators.implicit import FD_REL
from viz3d.kernel.field import NONFINITE, OK, clear, evaluate, fill_rows, force_piece, frames, generalized_forces, turn_quaternion
from viz3d.kernel.stepping import _check_frames, renew, state_ok
from viz3d.points import kinematics
from viz3d.rotations import GIMBAL_EPS
from viz3d.system import State

try:
    from numba import literal_unroll
except ImportError:  # pragma: no cover
    def literal_unroll(x):
        return x

#: Outcomes of a step (``_attempts``): converged (the step is done), the iteration did not converge within
#: ``MAX_ITER``, a trial point was not finite, an iteration matrix was singular, the index-1 field
#: (the ledger's work rates) failed at the new state, the branches held did not settle (``_solve``), the
#: branches held cycled and no boundary between the two sets was found (``_filippov``).
CONVERGED, NOT_CONVERGED, NONFINITE_POINT, SINGULAR_LU, WORK_RATES, NOT_SETTLED, CYCLED = 0, 1, 2, 3, 4, 6, 7


# ---------------------------------------------------------------------------- compiled pieces


@jit
def _advance_euler(y, i0, d1, d2, d3):
    """ZXZ angles ``y[i0:i0 + 3]`` of ``R(angles) exp(skew(d))`` in place, on the branch of the old
    angles and with psi, phi within pi of their old values (``EulerZXZ.advance``)."""
    a0, a1, a2 = y[i0], y[i0 + 1], y[i0 + 2]
    c1, s1, c2, s2, c3, s3 = math.cos(a0), math.sin(a0), math.cos(a1), math.sin(a1), math.cos(a2), math.sin(a2)
    r00, r01, r02 = c1 * c3 - s1 * c2 * s3, -c1 * s3 - s1 * c2 * c3, s1 * s2
    r10, r11, r12 = s1 * c3 + c1 * c2 * s3, -s1 * s3 + c1 * c2 * c3, -c1 * s2
    r20, r21, r22 = s2 * s3, s2 * c3, c2
    # Rodrigues: E = I + a K + b K^2 (matrix_from_rotation_vector, series below 1e-8 rad)
    ang = math.sqrt(d1 * d1 + d2 * d2 + d3 * d3)
    if ang < 1e-8:
        a, b = 1.0 - ang * ang / 6.0, 0.5 - ang * ang / 24.0
    else:
        a, b = math.sin(ang) / ang, (1.0 - math.cos(ang)) / (ang * ang)
    e00, e11, e22 = 1.0 - b * (d2 * d2 + d3 * d3), 1.0 - b * (d1 * d1 + d3 * d3), 1.0 - b * (d1 * d1 + d2 * d2)
    e01, e10 = -a * d3 + b * d1 * d2, a * d3 + b * d1 * d2
    e02, e20 = a * d2 + b * d1 * d3, -a * d2 + b * d1 * d3
    e12, e21 = -a * d1 + b * d2 * d3, a * d1 + b * d2 * d3
    p02 = r00 * e02 + r01 * e12 + r02 * e22
    p12 = r10 * e02 + r11 * e12 + r12 * e22
    p22 = r20 * e02 + r21 * e12 + r22 * e22
    p00 = r00 * e00 + r01 * e10 + r02 * e20
    p10 = r10 * e00 + r11 * e10 + r12 * e20
    p20 = r20 * e00 + r21 * e10 + r22 * e20
    p21 = r20 * e01 + r21 * e11 + r22 * e21
    sn = math.hypot(p02, p12)  # euler_from_matrix
    theta = math.atan2(sn, p22)
    if sn > GIMBAL_EPS:
        psi, phi = math.atan2(p02, -p12), math.atan2(p20, p21)
    else:
        psi, phi = math.atan2(p10, p00), 0.0
    if a1 < 0.0:  # the old angles' branch (psi + pi, -theta, phi + pi)
        psi, theta, phi = psi + math.pi, -theta, phi + math.pi
    y[i0] = a0 + _wrap(psi - a0)
    y[i0 + 1] = theta
    y[i0 + 2] = a2 + _wrap(phi - a2)


@jit
def _wrap(x):
    """``x`` into [-pi, pi) (``np.mod(x + pi, 2 pi) - pi``)."""
    two_pi = 2.0 * math.pi
    r = x + math.pi
    return r - two_pi * math.floor(r / two_pi) - math.pi


@jit
def _retract(m, q0, dx, y):
    """``y[:n_q]`` = ``q0`` moved by the velocity-space increment ``dx`` (n_v,) (``viz3d.dynamics.retract``)."""
    nf, nqb = m.frame_body.shape[0], 3 + m.n_rot
    for i in range(m.n_q):
        y[i] = q0[i]
    for k in range(nf):
        for i in range(3):
            y[nqb * k + i] += dx[6 * k + i]
        d1, d2, d3 = dx[6 * k + 3], dx[6 * k + 4], dx[6 * k + 5]
        if m.n_rot == 4:
            turn_quaternion(y, nqb * k + 3, d1, d2, d3)
        else:
            _advance_euler(y, nqb * k + 3, d1, d2, d3)


@jit
def _forces_and_rows(t, y, chart, m, v, w, forces, rows, Q):
    """Forces (applied and gyroscopic) ``Q`` (n_v,) and the constraint rows (in ``v``) at ``(t, y)``;
    ``NONFINITE`` if one is not finite."""
    frames(m, v, w, y, chart)
    kinematics(m, v, w)
    clear(m, v, w)
    for d in literal_unroll(forces):
        if d.i.shape[0] > 0:
            force_piece(d, t, v, w.aux)
    generalized_forces(m, v, w)
    if m.row_body.shape[0] > 0:
        fill_rows(m.row_body, v, t, rows)
    ok = True
    for k in range(m.frame_body.shape[0]):
        for i in range(6):
            Q[6 * k + i] = w.Q[m.frame_body[k], i]
            ok = ok and math.isfinite(Q[6 * k + i])
    for r in range(v.C.shape[0]):
        ok = ok and math.isfinite(v.C[r])
    return OK if ok else NONFINITE



# ---------------------------------------------------------------------------- LAPACK's banded LU

if numba is not None:
    import llvmlite.binding as _llvm
    from numba import types as _t
    from numba.extending import get_cython_function_address

    # the symbols by name (not ctypes pointers, which numba's disk cache refuses): bound at import,
    # before any cached code that calls them is loaded
    for _name in ("dgbtrf", "dgbtrs"):
        _llvm.add_symbol(f"viz3d_{_name}", get_cython_function_address("scipy.linalg.cython_lapack", _name))
    _p = _t.voidptr
    _dgbtrf = _t.ExternalFunction("viz3d_dgbtrf", _t.void(_p, _p, _p, _p, _p, _p, _p, _p))
    _dgbtrs = _t.ExternalFunction("viz3d_dgbtrs", _t.void(_p, _p, _p, _p, _p, _p, _p, _p, _p, _p, _p))


@jit
def _band_factor(ab, bw, piv, ints):
    """LU of the band matrix ``ab`` (n, 3 bw + 1) in place (``dgbtrf``), row swaps into ``piv`` (n,)
    int32; ``ints`` (5,) int32 scratch for LAPACK's arguments. Returns ``info``: 0, or the first
    zero pivot (1-based: the matrix is singular)."""
    ints[0], ints[1], ints[2], ints[3], ints[4] = ab.shape[0], bw, ab.shape[1], 0, 1
    _dgbtrf(ints.ctypes, ints.ctypes, ints[1:].ctypes, ints[1:].ctypes, ab.ctypes, ints[2:].ctypes, piv.ctypes,
            ints[3:].ctypes)
    return ints[3]


@jit
def _band_solve(s, ab, bw, piv, b):
    """``b = A^-1 b`` (n,) in place from ``_band_factor``'s ``ab``, ``piv`` (``dgbtrs``), ``A`` in the band's
    order (``s.perm``), ``b`` in the unknowns'."""
    ints, bp = s.ints, s.bp
    for i in range(b.shape[0]):
        bp[s.perm[i]] = b[i]
    ints[0], ints[1], ints[2], ints[3], ints[4] = ab.shape[0], bw, ab.shape[1], 0, 1
    _dgbtrs(s.trans.ctypes, ints.ctypes, ints[1:].ctypes, ints[1:].ctypes, ints[4:].ctypes, ab.ctypes, ints[2:].ctypes,
            piv.ctypes, bp.ctypes, ints.ctypes, ints[3:].ctypes)
    for i in range(b.shape[0]):
        b[i] = bp[s.perm[i]]


@jit
def _band_times(s, ab, bw, x, out):
    """``out = A x`` (n,) for ``A`` in band storage in the band's order (``s.perm``), ``x`` and ``out`` in
    the unknowns'."""
    n = x.shape[0]
    for i in range(n):
        out[i] = 0.0
    for j in range(n):
        xj, pj = x[j], s.perm[j]
        for pi in range(max(0, pj - bw), min(n, pj + bw + 1)):
            out[s.inv[pi]] += ab[pj, 2 * bw + pi - pj] * xj


@jit
def _add_gram(col, J, scale, bw, ab):
    """``A += scale C_v^T C_v`` in band storage; ``C_v`` as the rows' blocks ``J`` (n_c, 2, 6) and
    their bodies' first velocity columns ``col`` (n_c, 2) (-1: ground)."""
    for r in range(J.shape[0]):
        for s in range(2):
            ci = col[r, s]
            if ci < 0:
                continue
            for u in range(2):
                cj = col[r, u]
                if cj < 0:
                    continue
                for i in range(6):
                    f = scale * J[r, s, i]
                    for j in range(6):
                        ab[cj + j, 2 * bw + ci + i - cj - j] += f * J[r, u, j]


@jit
def _rows_transposed_times(col, J, lam, out):
    """``out = C_v^T lam`` (n_v,)."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    for r in range(J.shape[0]):
        for s in range(2):
            c = col[r, s]
            if c >= 0:
                for i in range(6):
                    out[c + i] += J[r, s, i] * lam[r]


@jit
def _iteration_matrix(W, col, J, scale, bw, out):
    """``out = W + scale C_v^T C_v`` (band storage)."""
    for j in range(W.shape[0]):
        for i in range(W.shape[1]):
            out[j, i] = W[j, i]
    _add_gram(col, J, scale, bw, out)

# ---------------------------------------------------------------------------- the step


class Scratch(NamedTuple):
    """What ``_attempts`` works in (n = n_v, L = 3 bw + 1; ``n_y = n_q + n_v + n_aux``); the system's
    constant parts first.

    M : (n, L) the mass matrix, band storage [kg, kg m^2]
    col, bcol : (n_c, 2) int64 the rows' bodies' first velocity columns (-1: ground), in the unknowns' and
        in the band's order
    perm, inv : (n,) int64 each unknown's position in the band (``_band_order``) and its inverse
    group_ptr, group_col : (G + 1,), (n,) int64 the columns differenced together (group g:
        ``group_col[group_ptr[g]:group_ptr[g + 1]]``, ``viz3d.sparsity.sparse_fd_plan``)
    row_ptr, row_idx : (n + 1,), int64 the rows each column reaches (column c:
        ``row_idx[row_ptr[c]:row_ptr[c + 1]]``)
    trans : (1,) uint8 'N' for ``dgbtrs``
    W : (n, L) ``M + h/2 D + h^2/4 K``
    lu : (2, n, L), piv : (2, n) int32 the current and a new factorisation; ints : (5,) int32
    y, yp, f, qp : (n_y,) the trial point ``[q1, v1]``, perturbed points, a field evaluation, the
        predictor's point (where the branches are held, ``_attempts``)
    a1, ap, Q, Qp, Q0 : (n,) accelerations and forces at the trial and perturbed points
    dx, ddx, x, res, rp, ma, r1, dx0, last, bp : (n,) the increment, its update, a perturbed one, residuals,
        products, the increment an iteration started from (``_solve``), the line search's last update, a
        right-hand side in the band's order
    before, xa, xb, lo, hi, Qa : (n,) the solution two updates before (``_solve``); where the two sets of a
        cycle were held, the sides of its bisection, forces with the first set (``_filippov``)
    cx, lam_hi, lam_lo : (n_c,) scratch; the multipliers an update started from, those of the
        bisection's low side
    yh : (n_y,) where branches are held for a blend (``_mixed_point``)
    """

    M: np.ndarray
    col: np.ndarray
    bcol: np.ndarray
    perm: np.ndarray
    inv: np.ndarray
    group_ptr: np.ndarray
    group_col: np.ndarray
    row_ptr: np.ndarray
    row_idx: np.ndarray
    trans: np.ndarray
    W: np.ndarray
    lu: np.ndarray
    piv: np.ndarray
    ints: np.ndarray
    y: np.ndarray
    yp: np.ndarray
    f: np.ndarray
    qp: np.ndarray
    a1: np.ndarray
    ap: np.ndarray
    Q: np.ndarray
    Qp: np.ndarray
    Q0: np.ndarray
    dx: np.ndarray
    ddx: np.ndarray
    x: np.ndarray
    res: np.ndarray
    rp: np.ndarray
    ma: np.ndarray
    r1: np.ndarray
    dx0: np.ndarray
    last: np.ndarray
    bp: np.ndarray
    before: np.ndarray
    xa: np.ndarray
    xb: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    Qa: np.ndarray
    cx: np.ndarray
    lam_hi: np.ndarray
    lam_lo: np.ndarray
    yh: np.ndarray


@jit
def _trial_point(t1, q0, v0, a0, dx, h, chart, m, v, w, forces, rows, y, a1, Q):
    """ALI3-P's trial point of the increment ``dx`` (n_v,) from ``(q0, v0, a0)``: ``y = [q1, v1]``,
    ``a1`` (eqs. 3.19, 3.20), forces ``Q`` and the rows at ``t1`` (in ``v``); the status."""
    _retract(m, q0, dx, y)
    n_q = m.n_q
    for i in range(m.n_v):
        y[n_q + i] = 2.0 / h * dx[i] - v0[i]
        a1[i] = 4.0 / (h * h) * (dx[i] - h * v0[i]) - a0[i]
    return _forces_and_rows(t1, y, chart, m, v, w, forces, rows, Q)


@jit
def _mixed_point(t1, q0, v0, a0, dx, h, chart, m, v, w, forces, rows, branches, s, theta, y, a1, Q):
    """``_trial_point`` with the branches as held (``theta < 0``), or with the forces
    ``(1 - theta) Q(A) + theta Q(B)``, the branches held as at the increments ``s.xa`` (A) and ``s.xb``
    (B) (``viz3d.ali3p._Mix``, ``_filippov``; B held on return)."""
    if theta < 0.0:
        return _trial_point(t1, q0, v0, a0, dx, h, chart, m, v, w, forces, rows, y, a1, Q)
    _branches(t1, q0, v0, s.xa, h, chart, m, v, w, branches, s.yh, HOLD, 0.0)
    status = _trial_point(t1, q0, v0, a0, dx, h, chart, m, v, w, forces, rows, y, a1, Q)
    for i in range(Q.shape[0]):
        s.Qa[i] = Q[i]
    _branches(t1, q0, v0, s.xb, h, chart, m, v, w, branches, s.yh, HOLD, 0.0)
    other = _trial_point(t1, q0, v0, a0, dx, h, chart, m, v, w, forces, rows, y, a1, Q)
    for i in range(Q.shape[0]):
        Q[i] = (1.0 - theta) * s.Qa[i] + theta * Q[i]
    return other if status == OK else status


@jit
def _residual(h, alpha, s, bw, J, C, lam, a1, Q, out):
    """Equations of motion at ``t1`` scaled by ``h^2 / 4`` (eq. 3.23; ``viz3d.ali3p._residual``) into
    ``out`` (n_v,) [N s^2], from the point's rows ``J``, ``C``, accelerations ``a1`` and forces ``Q``."""
    for r in range(C.shape[0]):
        s.cx[r] = alpha * C[r] + lam[r]
    _band_times(s, s.M, bw, a1, s.ma)
    _rows_transposed_times(s.col, J, s.cx, out)
    scale = 0.25 * h * h
    for i in range(out.shape[0]):
        out[i] = scale * (s.ma[i] + out[i] - Q[i])


@jit
def _scatter(s, bw, g, step_floor, x0, d, d0, sign, out):
    """The columns of group ``g`` of a forward-difference Jacobian into the band ``out``: column c's
    rows r get ``sign (d[r] - d0[r]) / step_c``, ``step_c = FD_REL max(|x0[c]|, step_floor)``
    (``viz3d.sparsity.grouped_fd_jacobian``'s steps), in the band's order (``s.perm``)."""
    for k in range(s.group_ptr[g], s.group_ptr[g + 1]):
        c = s.group_col[k]
        pc = s.perm[c]
        step = FD_REL * max(abs(x0[c]), step_floor)
        for e in range(s.row_ptr[c], s.row_ptr[c + 1]):
            r = s.row_idx[e]
            out[pc, 2 * bw + s.perm[r] - pc] = sign * ((d[r] - d0[r]) / step)


@jit
def _perturbed(s, g, step_floor, x0, x):
    """``x = x0`` with the columns of group ``g`` moved by their steps (``_scatter``)."""
    for i in range(x0.shape[0]):
        x[i] = x0[i]
    for k in range(s.group_ptr[g], s.group_ptr[g + 1]):
        c = s.group_col[k]
        x[c] = x0[c] + FD_REL * max(abs(x0[c]), step_floor)


@jit
def _force_tangent(t, q0, v0, chart, bw, m, v, w, forces, rows, s, K, D):
    """``K = -dQ/dx`` and ``D = -dQ/dv`` (band storage) at ``(t, q0, v0)`` by grouped forward
    differences (``viz3d.ali3p.force_tangent``): 2 G + 1 force evaluations."""
    n_q, n = m.n_q, m.n_v
    y = s.yp
    for i in range(n_q):
        y[i] = q0[i]
    for i in range(n):
        y[n_q + i] = v0[i]
    _forces_and_rows(t, y, chart, m, v, w, forces, rows, s.Q0)
    K[:, :] = 0.0
    D[:, :] = 0.0
    for i in range(n):
        s.r1[i] = 0.0  # the position increment's origin
    for g in range(s.group_ptr.shape[0] - 1):
        _perturbed(s, g, 1.0, s.r1, s.x)  # FD_REL on the group's columns
        _retract(m, q0, s.x, y)
        _forces_and_rows(t, y, chart, m, v, w, forces, rows, s.Qp)
        _scatter(s, bw, g, 1.0, s.r1, s.Qp, s.Q0, -1.0, K)
    for i in range(n_q):
        y[i] = q0[i]
    for g in range(s.group_ptr.shape[0] - 1):
        _perturbed(s, g, 1.0, v0, y[n_q:n_q + n])
        _forces_and_rows(t, y, chart, m, v, w, forces, rows, s.Qp)
        _scatter(s, bw, g, 1.0, v0, s.Qp, s.Q0, -1.0, D)
    return 2 * (s.group_ptr.shape[0] - 1) + 1


@inline
def _residual_tangent(t1, q0, v0, a0, h, chart, alpha, lam, bw, m, v, w, forces, rows, branches, s, theta, out):
    """``d residual / d dx`` at ``s.dx`` and fixed multipliers (band storage) by grouped forward
    differences (``viz3d.ali3p._residual_tangent``), ``s.res`` the residual at ``s.dx``: G trial points
    (``_mixed_point``'s, ``theta``)."""
    out[:, :] = 0.0
    for g in range(s.group_ptr.shape[0] - 1):
        _perturbed(s, g, 1.0, s.dx, s.x)
        _mixed_point(t1, q0, v0, a0, s.x, h, chart, m, v, w, forces, rows, branches, s, theta, s.yp, s.ap, s.Qp)
        _residual(h, alpha, s, bw, v.J, v.C, lam, s.ap, s.Qp, s.rp)
        _scatter(s, bw, g, 1.0, s.dx, s.rp, s.res, 1.0, out)
    return s.group_ptr.shape[0] - 1


@inline
def _finish(t1, h, alpha, bw, w0, w_dot0, chart, m, v, w, forces, rows, s, y1, a_out, w_dot1):
    """Velocities and accelerations projected (eqs. 3.27, 3.28; ``viz3d.ali3p._finish``) at the
    converged point (``s.y``, ``s.a1``, rows in ``v``) into ``y1 = [q1, v1, w1]`` and ``a_out``; the
    ledger's work rates at the new state into ``w_dot1`` and its work integrals by the trapezoidal
    rule. Returns the outcome."""
    n_q, n, scale = m.n_q, m.n_v, 0.25 * h * h * alpha
    lu, piv = s.lu[0], s.piv[0]
    _iteration_matrix(s.W, s.bcol, v.J, scale, bw, lu)
    if _band_factor(lu, bw, piv, s.ints) != 0:
        return SINGULAR_LU
    for i in range(n_q + n):
        y1[i] = s.y[i]
    _forces_and_rows(t1, y1, chart, m, v, w, forces, rows, s.Qp)  # C_t at (q1, v1)
    _rows_transposed_times(s.col, v.J, v.Ct, s.r1)
    _band_times(s, s.W, bw, s.y[n_q:n_q + n], s.ma)
    for i in range(n):
        s.ma[i] -= scale * s.r1[i]
    _band_solve(s, lu, bw, piv, s.ma)
    for i in range(n):
        y1[n_q + i] = s.ma[i]
    _forces_and_rows(t1, y1, chart, m, v, w, forces, rows, s.Qp)  # gamma at (q1, v)
    _rows_transposed_times(s.col, v.J, v.gam, s.r1)
    _band_times(s, s.W, bw, s.a1, a_out)
    for i in range(n):
        a_out[i] += scale * s.r1[i]
    _band_solve(s, lu, bw, piv, a_out)
    n_aux = w0.shape[0]
    if n_aux:
        for k in range(n_aux):
            y1[n_q + n + k] = w0[k]
        if evaluate(t1, y1, chart, m, v, w, forces, rows, s.f) != OK:
            return WORK_RATES
        for k in range(n_aux):
            w_dot1[k] = s.f[n_q + n + k]
            y1[n_q + n + k] = w0[k] + 0.5 * h * (w_dot0[k] + w_dot1[k])
    return CONVERGED


@jit
def _iterate(t0, h, q0, v0, a0, chart, alpha, tol, bw, exact_ok, search, K, D, m, v, w, forces, rows, branches, s,
             lam, theta):
    """One iteration with the force tangents ``K``, ``D`` from the increment ``s.dx`` and multipliers
    ``lam`` (both in place; ``viz3d.ali3p._iterate``, the same tests in the same order; ``search``: its
    line search on the exact tangent; ``theta``: the forces of ``_mixed_point``):
    ``(outcome, evaluations, last update, max |C|, cur)``; converged,
    the point in ``s.y``, ``s.a1``, ``s.Q`` and the rows in ``v``, its iteration matrix's factors in
    ``s.lu[cur]``."""
    t1, n, n_c = t0 + h, m.n_v, lam.shape[0]
    scale = 0.25 * h * h * alpha
    for j in range(n):
        for i in range(s.W.shape[1]):
            s.W[j, i] = s.M[j, i] + 0.5 * h * D[j, i] + 0.25 * h * h * K[j, i]
    cur, have_lu, step, prev, exact, evals, C_max, cuts, base = 0, False, np.inf, np.inf, False, 0, 0.0, 0, np.inf
    for it in range(MAX_ITER):
        status = _mixed_point(t1, q0, v0, a0, s.dx, h, chart, m, v, w, forces, rows, branches, s, theta, s.y, s.a1,
                              s.Q)
        evals += 1
        if status != OK:
            return NONFINITE_POINT, evals, step, np.nan, cur
        C_max = 0.0
        for r in range(n_c):
            C_max = max(C_max, abs(v.C[r]))
        rate = np.inf
        if it > 0:
            for r in range(n_c):
                lam[r] += alpha * v.C[r]
            rate = step / prev if math.isfinite(prev) else np.inf
            if small_update(step, rate, tol) and C_max <= tol:
                return CONVERGED, evals, step, C_max, cur
        prev = step
        _residual(h, alpha, s, bw, v.J, v.C, lam, s.a1, s.Q, s.res)
        if not have_lu:
            _iteration_matrix(s.W, s.bcol, v.J, scale, bw, s.lu[cur])
            if _band_factor(s.lu[cur], bw, s.piv[cur], s.ints) != 0:
                return SINGULAR_LU, evals, step, C_max, cur
            have_lu = True
        elif (exact_ok and (exact or it >= 3) and rate > SLOW_RATE
              and (exact or too_slow(step, rate, tol, MAX_ITER - it))):
            # slow: Newton on the exact tangent, rebuilt at every iterate while the contraction stays slow
            new = 1 - cur
            evals += _residual_tangent(t1, q0, v0, a0, h, chart, alpha, lam, bw, m, v, w, forces, rows, branches, s,
                                       theta, s.lu[new])
            if _band_factor(s.lu[new], bw, s.piv[new], s.ints) == 0:
                cur, exact = new, True
            else:  # a singular difference tangent: go on with the approximate one
                exact_ok = False
        for i in range(n):
            s.ddx[i] = -s.res[i]
        _band_solve(s, s.lu[cur], bw, s.piv[cur], s.ddx)
        size = _max_abs(s.res)
        if search and exact and size > base and cuts < MAX_CUTS:
            # the update that led here overshot (the residual grew): back half-way along it
            for i in range(n):
                s.ddx[i], s.last[i] = -0.5 * s.last[i], 0.5 * s.last[i]
            cuts += 1
        else:
            for i in range(n):
                s.last[i] = s.ddx[i]
            cuts, base = 0, size
        step = _max_abs(s.ddx)
        for i in range(n):
            s.dx[i] = s.dx[i] + s.ddx[i]
    return NOT_CONVERGED, evals, step, C_max, cur


@jit
def _max_abs(x):
    """``max |x|`` (0 for an empty ``x``)."""
    out = 0.0
    for i in range(x.shape[0]):
        out = max(out, abs(x[i]))
    return out


@jit
def _branches(t1, q0, v0, dx, h, chart, m, v, w, branches, y, mode, tol):
    """``hold_piece`` of the elements with branches, at the trial point of the increment ``dx`` (n_v,)
    (set up in ``y`` and ``v``; not for ``RELEASE``): ``viz3d.ali3p._held`` (``HOLD``), ``_change``
    (``CHANGE``: the number of branches that differ, positions within ``tol`` [m])."""
    if mode != RELEASE:
        _retract(m, q0, dx, y)
        for i in range(m.n_v):
            y[m.n_q + i] = 2.0 / h * dx[i] - v0[i]
        frames(m, v, w, y, chart)
        kinematics(m, v, w)
    changed = 0
    for d in literal_unroll(branches):
        if d.i.shape[0] > 0:
            changed += hold_piece(d, t1, v, mode, tol)
    return changed


@inline
def _solve(t0, h, q0, v0, a0, lam0, chart, alpha, tol, bw, exact_ok, search, K, D, m, v, w, forces, rows, branches,
           s, lam):
    """``viz3d.ali3p._solve`` from the predictor, the branches held there (``search``; none: one
    ``_iterate``): at the converged point the difference of the Newton updates with the forces held and
    found (``s.Q``, ``s.Qp``) within ``tol``, or no branch changed, settles it; else the iteration goes
    on from there with the branches found there, ``MAX_SET_UPDATES`` times at most (then
    ``NOT_SETTLED``, the last update the shift; ``s.dx0``: where the last held branches were taken).
    Returns ``_iterate``'s tuple; converged, the forces are released."""
    t1, n = t0 + h, m.n_v
    for r in range(lam.shape[0]):
        lam[r] = lam0[r]
    _predictor(h, v0, a0, s.dx)
    evals = 0
    for update in range(MAX_SET_UPDATES + 1):
        for i in range(n):
            s.dx0[i] = s.dx[i]
        for r in range(lam.shape[0]):
            s.lam_hi[r] = lam[r]
        outcome, k, step, C_max, cur = _iterate(t0, h, q0, v0, a0, chart, alpha, tol, bw, exact_ok, search, K, D, m, v,
                                                w, forces, rows, branches, s, lam, -1.0)
        evals += k
        if outcome != CONVERGED or not search:
            return outcome, evals, step, C_max, cur
        for i in range(n):
            s.ddx[i] = s.dx[i] - s.dx0[i]
        if update > 0 and _max_abs(s.ddx) <= tol:
            break  # the branches found at the last solution moved it by less than tol
        changed = _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.yp, CHANGE, ROUND_OFF_FACTOR * tol)
        _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.yp, RELEASE, 0.0)
        _trial_point(t1, q0, v0, a0, s.dx, h, chart, m, v, w, forces, rows, s.yp, s.ap, s.Qp)  # (rows: s.dx's)
        evals += 1
        for i in range(n):
            s.r1[i] = 0.25 * h * h * (s.Q[i] - s.Qp[i])
        _band_solve(s, s.lu[cur], bw, s.piv[cur], s.r1)
        shift = _max_abs(s.r1)
        if shift <= tol or changed == 0:
            return CONVERGED, evals, step, C_max, cur
        if update >= 2:
            for i in range(n):
                s.ddx[i] = s.dx[i] - s.before[i]
            if _max_abs(s.ddx) <= ROUND_OFF_FACTOR * tol:  # a cycle: these branches were held for the last solution
                outcome, k, step, C_max, cur = _filippov(t0, h, q0, v0, a0, chart, alpha, tol, bw, exact_ok, K, D, m, v,
                                                         w, forces, rows, branches, s, lam)
                return outcome, evals + k, step, C_max, cur
        if update == MAX_SET_UPDATES:
            return NOT_SETTLED, evals, shift, C_max, cur
        for i in range(n):
            s.before[i] = s.dx0[i]
        _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.yp, HOLD, 0.0)
    _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.yp, RELEASE, 0.0)
    return CONVERGED, evals, step, C_max, cur


@inline
def _filippov(t0, h, q0, v0, a0, chart, alpha, tol, bw, exact_ok, K, D, m, v, w, forces, rows, branches, s, lam):
    """``viz3d.ali3p._filippov`` where ``_solve``'s held branches cycle: held as at ``s.dx0`` (A) the
    iteration converged to ``s.dx`` with multipliers ``lam`` (the low side, theta = 0), where those
    held as at ``s.dx`` (B) are found; ``s.dx0``, ``s.lam_hi``: the solution with B's, where A's are found
    (the high side). Bisection on theta of ``_mixed_point``'s forces until the sides are within
    ``ROUND_OFF_FACTOR * tol``; converged, the low side's point in ``s.dx``, ``lam``, ``s.y``, ``s.a1``
    and the rows in ``v``, the branches released; else ``CYCLED``. Returns ``_iterate``'s tuple."""
    t1, n, n_c = t0 + h, m.n_v, lam.shape[0]
    for i in range(n):
        s.xa[i], s.xb[i], s.lo[i], s.hi[i] = s.dx0[i], s.dx[i], s.dx[i], s.dx0[i]
    for r in range(n_c):
        s.lam_lo[r] = lam[r]
    t_lo, t_hi, evals, step, C_max, cur = 0.0, 1.0, 0, 0.0, 0.0, 0
    for _ in range(MAX_BISECTIONS):
        for i in range(n):
            s.ddx[i] = s.hi[i] - s.lo[i]
        if _max_abs(s.ddx) <= ROUND_OFF_FACTOR * tol:
            _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.yp, RELEASE, 0.0)
            for i in range(n):
                s.dx[i] = s.lo[i]
            for r in range(n_c):
                lam[r] = s.lam_lo[r]
            _trial_point(t1, q0, v0, a0, s.dx, h, chart, m, v, w, forces, rows, s.y, s.a1, s.Q)  # (the low side's)
            return CONVERGED, evals, step, C_max, cur
        theta = 0.5 * (t_lo + t_hi)
        for i in range(n):
            s.dx[i] = 0.5 * (s.lo[i] + s.hi[i])
        for r in range(n_c):
            lam[r] = 0.5 * (s.lam_lo[r] + s.lam_hi[r])
        outcome, k, step, C_max, cur = _iterate(t0, h, q0, v0, a0, chart, alpha, tol, bw, exact_ok, True, K, D, m, v,
                                                w, forces, rows, branches, s, lam, theta)
        evals += k
        if outcome != CONVERGED:
            return outcome, evals, step, C_max, cur
        _branches(t1, q0, v0, s.xb, h, chart, m, v, w, branches, s.yh, HOLD, 0.0)
        if _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.yp, CHANGE, np.inf) == 0:
            t_lo = theta
            for i in range(n):
                s.lo[i] = s.dx[i]
            for r in range(n_c):
                s.lam_lo[r] = lam[r]
            continue
        _branches(t1, q0, v0, s.xa, h, chart, m, v, w, branches, s.yh, HOLD, 0.0)
        if _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.yp, CHANGE, np.inf) != 0:
            return CYCLED, evals, step, C_max, cur
        t_hi = theta
        for i in range(n):
            s.hi[i] = s.dx[i]
        for r in range(n_c):
            s.lam_hi[r] = lam[r]
    return CYCLED, evals, step, C_max, cur


@jit
def _predictor(h, v0, a0, dx):
    """The increment (n_v,) of the trapezoidal rule with ``a1 = a0`` (``viz3d.ali3p._predictor``)."""
    for i in range(dx.shape[0]):
        dx[i] = h * v0[i] + 0.5 * h * h * a0[i]


@inline
def _attempts(t0, h, q0, v0, a0, lam0, w0, w_dot0, chart, alpha, tol, bw, have_K, search, K, D, K_new, D_new, m, v,
              w, forces, rows, branches, s, y1, a_out, lam, w_dot1):
    """One step of ``viz3d.ali3p._one_step``: with the kept force tangents ``K``, ``D`` when ``have_K``,
    then (or else only) with fresh ones written into ``K_new``, ``D_new``; with ``search``, the forces'
    branches held as at the predictor (``_branches``), the fresh tangents taken there. On convergence
    ``y1`` (n_q + n_v + n_aux,) holds the new state, ``a_out`` its accelerations, ``lam`` the
    multipliers, ``w_dot1`` the work rates. Returns ``(outcome, evaluations, evaluations of the last
    attempt, fresh tangents built, last update, max |C|)`` (``NaN`` max |C| when a point was not
    finite; the last update: the shift of ``NOT_SETTLED``). The branches are released on return."""
    t1, n_q, n = t0 + h, m.n_q, m.n_v
    total = 0
    built = False
    outcome, evals, step, C_max = NOT_CONVERGED, 0, np.inf, 0.0
    for attempt in range(2 if have_K else 1):
        fresh = attempt == 1 or not have_K
        if search:
            _predictor(h, v0, a0, s.dx)
            _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.qp, HOLD, 0.0)
        if fresh:
            if search:  # where the branches were taken: a contact that begins within the step has no stiffness at t0
                total += _force_tangent(t1, s.qp[:n_q], s.qp[n_q:n_q + n], chart, bw, m, v, w, forces, rows, s, K_new,
                                        D_new)
            else:
                total += _force_tangent(t0, q0, v0, chart, bw, m, v, w, forces, rows, s, K_new, D_new)
            built = True
        outcome, evals, step, C_max, _ = _solve(t0, h, q0, v0, a0, lam0, chart, alpha, tol, bw, fresh, search,
                                                K_new if fresh else K, D_new if fresh else D, m, v, w, forces, rows,
                                                branches, s, lam)
        total += evals
        if outcome == CONVERGED:
            outcome = _finish(t1, h, alpha, bw, w0, w_dot0, chart, m, v, w, forces, rows, s, y1, a_out, w_dot1)
            break
    if search:
        _branches(t1, q0, v0, s.dx, h, chart, m, v, w, branches, s.qp, RELEASE, 0.0)
    return outcome, total, evals, built, step, C_max


#: ``ali3p_frames``' status when a step's end state fails the health checks (``viz3d.kernel.stepping.state_ok``).
UNHEALTHY = 5


@entry
def ali3p_frames(n_frames, every, n0, t_start, h, y, chart, switches, max_speed, a0, lam, w_dot0, Ks, Ds, carry, alpha,
                 tol, bw, search, m, v, w, forces, rows, branches, memories, s, y1, a1, lam1, w_dot1, Y, charts, after,
                 info):
    """Up to ``n_frames`` times ``every`` steps (``_attempts``) of the state ``y = [q, v, w]`` (n_y,) and
    ``chart`` in place, from step ``n0`` of a run started at ``t_start`` [s], each followed by what
    ``viz3d.simulate.Simulation`` does between steps (health checks, normalised Euler parameters,
    chart switches counted per body in ``switches``, the force elements' memory renewed:
    ``viz3d.kernel.stepping``); the state after frame
    ``f`` into ``Y[f]``, ``charts[f]``. The memory is carried in place: accelerations ``a0``,
    multipliers ``lam``, work rates ``w_dot0``, force tangents ``Ks[carry[0]]``, ``Ds[carry[0]]``
    (the other buffer takes fresh ones), ``carry[1]`` 1 while they are kept, ``carry[2]`` the
    evaluations. Stops before a step that fails (``_attempts``' outcome) or whose end state is not
    healthy (``UNHEALTHY``), state and memory as before it. Without ``after``, none of the work
    between steps (health checks, charts, the elements' memory: the caller's). ``info`` (4,) gets the
    last step's evaluations (its attempts'), 1.0 if it built fresh tangents (into ``Ks[1 - carry[0]]``,
    ``Ds[..]``), its last update [m, rad] and max |C| [m] (``_attempts``). Returns (frames done, steps
    done in the next frame, status: ``CONVERGED`` when all were done)."""
    n_q, n_v, n_y = m.n_q, m.n_v, y.shape[0]
    for f in range(n_frames):
        for k in range(every):
            cur = carry[0]
            t0 = t_start + (n0 + f * every + k) * h
            outcome, evals, last, built, step, C_max = _attempts(
                t0, h, y[:n_q], y[n_q:n_q + n_v], a0, lam, y[n_q + n_v:], w_dot0, chart, alpha, tol, bw, carry[1] == 1,
                search, Ks[cur], Ds[cur], Ks[1 - cur], Ds[1 - cur], m, v, w, forces, rows, branches, s, y1, a1, lam1,
                w_dot1)
            info[0], info[1], info[2], info[3] = evals, 1.0 if built else 0.0, step, C_max
            if outcome != CONVERGED:
                return f, k, outcome
            if after:
                if not state_ok(n_q, n_v, m.n_rot, m.switching, m.frame_body.shape[0], y1, h, max_speed):
                    return f, k, UNHEALTHY
                _check_frames(n_q, m.n_rot, m.switching, m.frame_body, m.centre, m.centre_R, w.m3[3], y1, chart,
                              switches, h, max_speed)
            for i in range(n_y):
                y[i] = y1[i]
            if after and m.remembers == 1:
                renew(t0 + h, m, v, w, y, chart, memories)
            for i in range(n_v):
                a0[i] = a1[i]
            for r in range(lam.shape[0]):
                lam[r] = lam1[r]
            for i in range(w_dot0.shape[0]):
                w_dot0[i] = w_dot1[i]
            if built:
                carry[0] = 1 - cur
            carry[1] = 0 if refresh_tangent(last) else 1
            carry[2] += evals + 1 + (1 if w_dot0.shape[0] else 0)
        for i in range(n_y):
            Y[f, i] = y[i]
        for b in range(chart.shape[0]):
            for i in range(3):
                for j in range(3):
                    charts[f, b, i, j] = chart[b, i, j]
    return n_frames, every, CONVERGED


# ---------------------------------------------------------------------------- from Python


def _band_order(A: np.ndarray, frame_of: np.ndarray, n_frames: int) -> np.ndarray:
    """Each floating frame's position in the band (n_frames,): reverse Cuthill-McKee's order of the
    bodies' adjacency ``A`` (nb, nb) where it narrows the band (a windlass first in body order and joined
    to the chain's last link made the hoist's band full: 131 of 138), else body order; ``frame_of`` (nb,)
    each body's frame."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    i, j = np.nonzero(A)
    keep = (frame_of[i] >= 0) & (frame_of[j] >= 0)
    fi, fj = frame_of[i][keep], frame_of[j][keep]
    F = csr_matrix((np.ones(fi.size), (fi, fj)), shape=(n_frames, n_frames))
    order = np.empty(n_frames, np.int64)
    order[reverse_cuthill_mckee(F, symmetric_mode=True)] = np.arange(n_frames)
    natural = np.arange(n_frames, dtype=np.int64)
    width = lambda o: np.max(np.abs(o[fi] - o[fj]), initial=0)  # noqa: E731
    return order if width(order) < width(natural) else natural


class _Run(NamedTuple):
    """What one ``ali3p_frames`` call left (``KernelALI3P._call``): the state ``y`` and ``chart`` after its
    last step done, the memory's parts (``a0``, ``lam``, ``w_dot0``, tangents ``Ks``, ``Ds`` and ``carry``),
    ``info``, the chart switches per body, the frames' states ``Y``, ``charts``, frames done, steps done in
    the next frame and the status."""

    y: np.ndarray
    chart: np.ndarray
    a0: np.ndarray
    lam: np.ndarray
    w_dot0: np.ndarray
    Ks: np.ndarray
    Ds: np.ndarray
    carry: np.ndarray
    info: np.ndarray
    switches: np.ndarray
    Y: np.ndarray
    charts: np.ndarray
    done: int
    partial: int
    status: int


class Stopped(NamedTuple):
    """Where a batched call (``KernelALI3P.frames``) stopped: the ``state`` before the step that failed
    (its memory: the one ``frames`` returns), ``steps`` steps past the last whole frame; ``failed``: that
    step's attempts, the memory after them (their evaluations, the fresh tangents they built) and their
    failed status, as ``KernelALI3P.step`` returns them (None when the step converged and its end state
    was not healthy, or its work rates failed: ``step`` then takes it for the diagnosis)."""

    state: State
    steps: int
    failed: tuple[object, Status] | None


def _after(memory, run: _Run):
    """``memory`` (an ``ALI3PMemory``) after the steps of ``run``: the kept tangents, or none (rebuilt
    at the next step), and the evaluations counted."""
    kept, cur = run.carry[1] == 1, int(run.carry[0])
    return replace(memory, v_dot=run.a0, lam=run.lam, w_dot=run.w_dot0 if run.w_dot0.size else memory.w_dot,
                   K=run.Ks[cur].copy() if kept else None, D=run.Ds[cur].copy() if kept else None,
                   n_evals=memory.n_evals + int(run.carry[2]))


class KernelALI3P:
    """ALI3-P's steps in the kernel for one packed system (``stepper``: its
    ``viz3d.kernel.KernelStepper``; ``system``: covered, see ``viz3d.kernel.model._check_stepping``),
    held by ``viz3d.ali3p.ALI3PMemory``; the force tangents it keeps there are band matrices
    (n_v, 3 bw + 1)."""

    name = "compiled kernel"

    def __init__(self, system, stepper):
        from viz3d.sparsity import body_adjacency, sparse_fd_plan

        self.stepper, d = stepper, stepper.data
        m = d.model
        self.m, n = m, m.n_v
        self.search = any(e.branches for e in system.forces)
        self.branches = tuple(x for x in d.forces if type(x) in registered(hold_piece))  # (the same arrays)
        A = body_adjacency(system)
        frame_of = m.body_frame[: m.nb]
        order = _band_order(A, frame_of, m.frame_body.shape[0])
        i, j = np.nonzero(A)
        at = np.where(frame_of >= 0, order[np.maximum(frame_of, 0)], frame_of)  # each body's place in the band
        self.bw = bw = int(6 * np.max(np.abs(at[i] - at[j]), initial=0) + 5)
        L, n_c, n_y = 3 * bw + 1, m.row_body.shape[0], m.n_q + m.n_v + m.n_aux
        frame_row = m.body_frame[m.row_body]
        col = np.where(frame_row >= 0, 6 * frame_row, -1).astype(np.int64)
        bcol = np.where(frame_row >= 0, 6 * order[frame_row], -1).astype(np.int64)
        perm = (6 * np.repeat(order, 6) + np.tile(np.arange(6), order.size)).astype(np.int64)
        groups, rows_of = sparse_fd_plan(system)
        ptr = lambda parts: np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)  # noqa: E731
        cat = lambda parts: np.concatenate([np.asarray(p, np.int64) for p in parts] or [np.zeros(0, np.int64)])  # noqa: E731
        z = np.zeros
        self.s = Scratch(self._mass(m, bw, perm), np.ascontiguousarray(col), np.ascontiguousarray(bcol), perm,
                         np.argsort(perm).astype(np.int64), ptr(groups), cat(groups), ptr(rows_of),
                         cat(rows_of), np.frombuffer(b"N", np.uint8).copy(), z((n, L)), z((2, n, L)),
                         z((2, n), np.int32), z(5, np.int32), z(n_y), z(n_y), z(n_y), z(n_y), *(z(n) for _ in range(21)),
                         z(n_c), z(n_c), z(n_c), z(n_y))

    @staticmethod
    def _mass(m, bw: int, perm: np.ndarray) -> np.ndarray:
        """``diag(m I3, I)`` per rigid body (constant), band storage (n_v, 3 bw + 1) in the band's order ``perm``."""
        M = np.zeros((m.n_v, 3 * bw + 1))
        for k, b in enumerate(m.frame_body):
            block = np.zeros((6, 6))
            block[:3, :3] = np.eye(3) / m.mass_inv[b]
            block[3:, 3:] = m.inertia[b]
            p = perm[6 * k]
            for i in range(6):
                for j in range(6):
                    M[p + j, 2 * bw + i - j] = block[i, j]
        return M

    def step(self, system, formulation, state: State, h: float, memory) -> tuple[State, object, Status]:
        """``viz3d.ali3p._one_step`` in one compiled call (``ali3p_frames``: one frame of one step, without
        the work between steps, which ``viz3d.simulate.Simulation`` does): ``(state, memory, status)``."""
        m = self.m
        n_q, n_v = m.n_q, m.n_v
        self.stepper.load(state.element_memory)
        run = self._call(formulation, state, memory, 1, 1, 0, state.t, h, math.inf, False)
        if run.status != CONVERGED:
            if run.status == WORK_RATES:
                raise np.linalg.LinAlgError(f"t = {state.t + h:.6g} s: constraint matrix is not positive definite")
            return (state, *self._failed(system, formulation, state, h, memory, run))
        y = run.y
        new = State(state.t + h, y[:n_q], y[n_q:n_q + n_v], state.chart, element_memory=state.element_memory)
        if m.n_aux:
            new = new.replace(memory=state.memory, w=y[n_q + n_v:])
        return new, _after(memory, run), Status.OK

    def _failed(self, system, formulation, state: State, h: float, memory, run: _Run) -> tuple[object, Status]:
        """The memory after the failed attempts of ``run``'s last step, from ``state`` with ``memory``
        (their evaluations, the fresh tangents they built), and its failed status."""
        fresh = 1 - int(run.carry[0])
        K, D = (run.Ks[fresh], run.Ds[fresh]) if run.info[1] == 1.0 else (memory.K, memory.D)
        step, C_max = float(run.info[2]), float(run.info[3])
        reason = {NONFINITE_POINT: NONFINITE_STATE, SINGULAR_LU: SINGULAR_MATRIX,
                  CYCLED: cycled(state.t + h)}.get(run.status)
        if run.status == NOT_SETTLED:
            reason = not_settled(system, formulation, state, h, self.s.dx0, self.s.dx, step)
        return replace(memory, K=K, D=D, n_evals=memory.n_evals + int(run.info[0])), failure(
            state, h, reason or no_convergence(step, C_max))

    def frames(self, system, formulation, state: State, memory, n_frames: int, every: int, n0: int, t_start: float,
               h: float, max_speed: float):
        """``n_frames`` times ``every`` steps from ``state`` with ``memory`` in one compiled call
        (``ali3p_frames``), from step ``n0`` of a run started at ``t_start`` [s]: ``(states, memory,
        switches, done, stopped)``, the states after each frame done, the memory and chart switches per
        body (n_bodies,) after the last step done, and ``None`` when every frame was done, else where
        the run stopped (``Stopped``: the state before the step that failed, the steps done past the
        last frame, the failed step's outcome, which ``viz3d.ali3p`` takes without redoing it). Inputs
        are copied. With force elements that remember (stick anchors), one call per frame: each state
        carries its own."""
        if not self.stepper.data.anchors:
            return self._frames(system, formulation, state, memory, n_frames, every, n0, t_start, h, max_speed)
        states, switches = [], np.zeros(system.n_bodies, np.int64)
        for f in range(n_frames):
            got, memory, more, done, stopped = self._frames(system, formulation, state, memory, 1, every,
                                                            n0 + f * every, t_start, h, max_speed)
            switches += more
            states += got
            if stopped is not None:
                return states, memory, switches, f, stopped
            state = got[-1]
        return states, memory, switches, n_frames, None

    def _frames(self, system, formulation, state: State, memory, n_frames: int, every: int, n0: int, t_start: float,
                h: float, max_speed: float):
        """``frames`` in one compiled call (the force elements' memory of the last state on all)."""
        n_q, n_v = self.m.n_q, self.m.n_v
        self.stepper._fresh(state.element_memory)
        run = self._call(formulation, state, memory, n_frames, every, n0, t_start, h, max_speed, True)
        elements = self.stepper.stored(state.element_memory)
        Y = run.Y
        states = [State(t_start + (n0 + (f + 1) * every) * h, Y[f, :n_q], Y[f, n_q:n_q + n_v], run.charts[f],
                        Y[f, n_q + n_v:], state.memory, elements) for f in range(run.done)]
        memory = _after(memory, run)
        if run.status == CONVERGED:
            return states, memory, run.switches, run.done, None
        y, k = run.y, run.partial
        at = State(t_start + (n0 + run.done * every + k) * h, y[:n_q], y[n_q:n_q + n_v], run.chart, y[n_q + n_v:],
                   state.memory, elements)
        failed = None if run.status in (UNHEALTHY, WORK_RATES) else self._failed(system, formulation, at, h, memory,
                                                                                 run)
        return states, memory, run.switches, run.done, Stopped(at, k, failed)

    def _call(self, formulation, state: State, memory, n_frames: int, every: int, n0: int, t_start: float, h: float,
              max_speed: float, after: bool) -> "_Run":
        """``ali3p_frames`` from ``state`` and ``memory`` (copied; the elements' memory loaded by the caller),
        with (``after``) or without the work between steps."""
        st, d, m = self.stepper, self.stepper.data, self.m
        n, L = m.n_v, 3 * self.bw + 1
        y, chart = np.array(state.y, dtype=float), np.array(state.chart, dtype=float)
        Ks, Ds = np.empty((2, n, L)), np.empty((2, n, L))
        have_K = memory.K is not None
        if have_K:
            Ks[0], Ds[0] = memory.K, memory.D
        a0, lam = np.array(memory.v_dot, dtype=float), np.array(memory.lam, dtype=float)
        w_dot0 = np.array(memory.w_dot, dtype=float) if m.n_aux else np.zeros(0)
        carry, info = np.array([0, int(have_K), 0], np.int64), np.zeros(4)
        switches = np.zeros(m.nb, np.int64)
        Y, charts = np.empty((n_frames, y.size)), np.empty((n_frames, *chart.shape))
        v, w = st.ws
        done, partial, status = st._call(
            ali3p_frames, n_frames, every, n0, t_start, h, y, chart, switches, float(max_speed), a0, lam, w_dot0, Ks,
            Ds, carry, float(formulation.alpha), float(formulation.tol), self.bw, self.search, d.model, v, w, d.forces,
            d.rows, self.branches, d.memories, self.s, np.empty(y.size), np.empty(n), np.empty(lam.size),
            np.empty(m.n_aux), Y, charts, after, info)
        return _Run(y, chart, a0, lam, w_dot0, Ks, Ds, carry, info, switches, Y, charts, done, partial, status)

    def work_rates(self, system, formulation, state) -> np.ndarray:
        """The ledger's work rates at ``state`` (n_aux,) [W]: the kernel's index-1 field's."""
        out = np.empty(self.m.n_q + self.m.n_v + self.m.n_aux)
        if self.stepper.evaluate(state.t, state.y, state.chart, self.stepper.view(()), out) != OK:
            raise np.linalg.LinAlgError(f"t = {state.t:.6g} s: constraint matrix is not positive definite")
        return out[self.m.n_q + self.m.n_v:].copy()


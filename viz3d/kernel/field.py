"""The compiled vector field ``y_dot = f(t, y)``: the recipe of ``viz3d.dynamics.accelerations``,
generic over the elements, which act through their compiled pieces (``viz3d.compiled``).

    frames (Euler angles in charts or Euler parameters) -> material points -> force elements and
    contacts (pieces) -> generalized forces (gyroscopic, flexible velocity and elastic forces) ->
    free accelerations M^-1 Q -> constraint rows (pieces) -> Schur complement, banded Cholesky ->
    accelerations -> rates

Nothing is allocated during an evaluation (allocation, not arithmetic, dominated the cost of small
systems): ``m``, ``v``, ``w`` are the model, view and workspace of ``viz3d.kernel.model``. Stages
called once are inlined (``viz3d.compiled.inline``); functions called from several places take
the arrays they need (each compiled function taking the whole named tuples costs about a second
to compile).
"""

from __future__ import annotations

import math

import numpy as np

from viz3d.compiled import cross3, entry, force_piece, gap_piece, inline, jit, matvec3, row_piece, tmatvec3
from viz3d.flexible.floating_kernel import FX_BODY, FX_E0, FX_N, body_forces, factor, solve
from viz3d.kernel.model import FIXED_FLEXIBLE, FLOATING_FLEXIBLE, GROUND, RIGID
from viz3d.points import kinematics

try:
    from numba import literal_unroll
except ImportError:  # pragma: no cover
    def literal_unroll(x):
        return x

#: Status codes of ``evaluate``, ``viz3d.kernel.stepping.steps`` and ``viz3d.kernel.projection.project``
#: (``PROJECTION``: the position projection did not reach its tolerance).
OK, NONFINITE, SINGULAR, SPEED, ROTATION, PROJECTION = 0, 1, 2, 3, 4, 5


@jit
def rotation(chart, a, out):
    """``out = chart @ Rz(a0) Rx(a1) Rz(a2)`` (ZXZ Euler angles in a chart, docs/notation.md)."""
    c1, s1 = math.cos(a[0]), math.sin(a[0])
    c2, s2 = math.cos(a[1]), math.sin(a[1])
    c3, s3 = math.cos(a[2]), math.sin(a[2])
    r00, r01, r02 = c1 * c3 - s1 * c2 * s3, -c1 * s3 - s1 * c2 * c3, s1 * s2
    r10, r11, r12 = s1 * c3 + c1 * c2 * s3, -s1 * s3 + c1 * c2 * c3, -c1 * s2
    r20, r21, r22 = s2 * s3, s2 * c3, c2
    _chart_times(chart, r00, r01, r02, r10, r11, r12, r20, r21, r22, out)


@inline
def _chart_times(chart, r00, r01, r02, r10, r11, r12, r20, r21, r22, out):
    """``out = chart @ R`` for the rotation ``R`` given by its entries ``rij`` (3, 3)."""
    for i in range(3):
        x, y, z = chart[i, 0], chart[i, 1], chart[i, 2]
        out[i, 0] = x * r00 + y * r10 + z * r20
        out[i, 1] = x * r01 + y * r11 + z * r21
        out[i, 2] = x * r02 + y * r12 + z * r22


@inline
def quaternion_rotation(chart, p, out):
    """``out = chart @ R(p / |p|)`` (Euler parameters ``p = (w, x, y, z)``, scalar first, normalised
    first as ``viz3d.rotations.matrix_from_quat`` does; docs/notation.md). Inlined: a compiled call
    in ``frames``' branch, even never taken, made every evaluation of Euler-angle systems 0.4 us
    slower (the heavy top's RK4 step 3.4 -> 4.3 us)."""
    n = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3])
    qw, qx, qy, qz = p[0] / n, p[1] / n, p[2] / n, p[3] / n
    r00, r01, r02 = 1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)
    r10, r11, r12 = 2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)
    r20, r21, r22 = 2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)
    _chart_times(chart, r00, r01, r02, r10, r11, r12, r20, r21, r22, out)


@inline
def frame_rotation(n_rot, chart, y, i0, out):
    """``out = R_WB`` of the orientation coordinates ``y[i0:i0 + n_rot]`` in ``chart`` (3, 3): ZXZ
    Euler angles (``n_rot`` 3) or Euler parameters (4)."""
    if n_rot == 4:
        quaternion_rotation(chart, y[i0:i0 + 4], out)
    else:
        rotation(chart, y[i0:i0 + 3], out)


@inline
def coordinate_rates(n_rot, y, i0, w1, w2, w3):
    """``theta_dot`` of the orientation coordinates ``y[i0:i0 + n_rot]`` for ``B_omega = (w1, w2, w3)``
    [rad/s], as a 4-tuple: the ZXZ rates of ``viz3d.rotations.euler_rates_from_body_omega`` (last entry
    0), or ``p_dot = 1/2 p (x) (0, B_omega)`` (Hamilton product, ``viz3d.coordinates.Quaternion.rates``;
    ``p`` as stored, not normalised)."""
    if n_rot == 4:
        pw, px, py, pz = y[i0], y[i0 + 1], y[i0 + 2], y[i0 + 3]
        return (0.5 * -(px * w1 + py * w2 + pz * w3), 0.5 * (pw * w1 + (py * w3 - pz * w2)),
                0.5 * (pw * w2 + (pz * w1 - px * w3)), 0.5 * (pw * w3 + (px * w2 - py * w1)))
    s2, c2 = math.sin(y[i0 + 1]), math.cos(y[i0 + 1])
    s3, c3 = math.sin(y[i0 + 2]), math.cos(y[i0 + 2])
    psi_d = (w1 * s3 + w2 * c3) / s2
    return psi_d, w1 * c3 - w2 * s3, w3 - psi_d * c2, 0.0


@inline
def turn_quaternion(y, i0, d1, d2, d3):
    """``p = y[i0:i0 + 4]`` turned by the body-frame rotation vector ``(d1, d2, d3)`` [rad] in place:
    ``p (x) (cos(a/2), sin(a/2) d / a)``, ``a = |d|`` (``viz3d.coordinates.Quaternion.advance``; below
    1e-4 rad ``sin(a/2) / a`` by its series ``1/2 - a^2/48``). Keeps ``|p|``."""
    a = math.sqrt(d1 * d1 + d2 * d2 + d3 * d3)
    s = 0.5 - a * a / 48.0 if a < 1e-4 else math.sin(0.5 * a) / a
    qw, qx, qy, qz = math.cos(0.5 * a), s * d1, s * d2, s * d3
    pw, px, py, pz = y[i0], y[i0 + 1], y[i0 + 2], y[i0 + 3]
    y[i0] = pw * qw - (px * qx + py * qy + pz * qz)
    y[i0 + 1] = pw * qx + qw * px + (py * qz - pz * qy)
    y[i0 + 2] = pw * qy + qw * py + (pz * qx - px * qz)
    y[i0 + 3] = pw * qz + qw * pz + (px * qy - py * qx)


@inline
def frames(m, v, w, y, chart):
    """Poses and twists of every body (fixed frames and ground at rest) and the elastic coordinates."""
    nf, nqb = m.frame_body.shape[0], 3 + m.n_rot
    for b in range(m.nb + 1):
        k = m.body_frame[b]
        if k < 0:
            for i in range(3):
                w.r[b, i] = m.r0[b, i]
                w.vW[b, i] = 0.0
                w.wB[b, i] = 0.0
                v.wW[b, i] = 0.0
                for j in range(3):
                    v.R[b, i, j] = m.R0[b, i, j]
            continue
        frame_rotation(m.n_rot, chart[k], y, nqb * k + 3, v.R[b])
        for i in range(3):
            w.r[b, i] = y[nqb * k + i]
            w.vW[b, i] = y[m.n_q + 6 * k + i]
            w.wB[b, i] = y[m.n_q + 6 * k + 3 + i]
        matvec3(v.R[b], w.wB[b], v.wW[b])
    for e in range(m.n_e):
        w.eta[e] = y[nqb * nf + e]
        w.eta_dot[e] = y[m.n_q + 6 * nf + e]


@inline
def clear(m, v, w):
    """Zero the generalized forces and the work rates."""
    for b in range(m.nb + 1):
        for i in range(3):
            v.F[b, i] = 0.0
            v.tau[b, i] = 0.0
    for e in range(m.n_e):
        v.Qe[e] = 0.0
    for k in range(w.aux.shape[0]):
        w.aux[k] = 0.0


@inline
def generalized_forces(m, v, w):
    """``Q`` per body: ``[W_F, R^T W_tau]``, rigid bodies minus ``w x I w``; flexible bodies' velocity
    and elastic forces; zero rows for fixed frames and ground."""
    t1, t2 = v.v3[8], v.v3[9]
    for b in range(m.nb + 1):
        kind = m.body_kind[b]
        if kind == GROUND or kind == FIXED_FLEXIBLE:
            for i in range(6):
                w.Q[b, i] = 0.0
            continue
        tmatvec3(v.R[b], v.tau[b], t1)
        for i in range(3):
            w.Q[b, i] = v.F[b, i]
            w.Q[b, 3 + i] = t1[i]
        if kind == RIGID:
            matvec3(m.inertia[b], w.wB[b], t1)
            cross3(w.wB[b], t1, t2)
            for i in range(3):
                w.Q[b, 3 + i] -= t2[i]
    for fx in range(m.fx_i.shape[0]):
        body_forces(m, v, w, fx)


@inline
def _rigid_solve(mass_inv, inertia_inv, b, x, out):
    """``out = M_b^-1 x`` (6,) for a rigid body."""
    for i in range(3):
        out[i] = x[i] * mass_inv[b]
        out[3 + i] = inertia_inv[b, i, 0] * x[3] + inertia_inv[b, i, 1] * x[4] + inertia_inv[b, i, 2] * x[5]


@inline
def factor_blocks(m, v, w):
    """Factorize the flexible bodies' mass blocks at the current frames and elastic coordinates;
    False if a block is not positive definite."""
    for fx in range(m.fx_i.shape[0]):
        if not factor(m.fx_i, m.fx_f, m.fx_pool, w.fx_work, w.fx_sc, fx, v.R[m.fx_i[fx, FX_BODY]], w.eta, v.v3, w.m3):
            return False
    return True


@inline
def free_accelerations(m, v, w):
    """``a = M^-1 Q`` (factorizing the flexible blocks); False if a block is not positive definite."""
    if not factor_blocks(m, v, w):
        return False
    for b in range(m.nb + 1):
        kind = m.body_kind[b]
        if kind == RIGID:
            _rigid_solve(m.mass_inv, m.inertia_inv, b, w.Q[b], w.a[b])
        elif kind == GROUND:
            for i in range(6):
                w.a[b, i] = 0.0
        else:
            fx = m.body_flex[b]
            e0 = m.fx_i[fx, FX_E0]
            solve(m.fx_i, m.fx_pool, w.fx_work, w.fx_sc, fx, w.Q[b], v.Qe, e0, w.a[b], w.ae, e0)
    return True


@inline
def row_times(row_body, row_je, body_kind, body_flex, fx_i, J, Je, row, x6, xe):
    """``C_v[row] . x`` for per-body frame vectors ``x6`` (nb + 1, 6) and elastic ``xe`` (n_e,)."""
    acc = 0.0
    for s in range(2):
        b = row_body[row, s]
        if body_kind[b] == RIGID or body_kind[b] == FLOATING_FLEXIBLE:
            for i in range(6):
                acc += J[row, s, i] * x6[b, i]
        j0 = row_je[row, s]
        if j0 >= 0:
            fx = body_flex[b]
            n, e0 = fx_i[fx, FX_N], fx_i[fx, FX_E0]
            for q in range(n):
                acc += Je[j0 + q] * xe[e0 + q]
    return acc


@inline
def constrain(m, v, w, t, rows):
    """Rows from the pieces, then ``(C M^-1 C^T + compliance I) lam = C a - gamma_s`` and
    ``a -= M^-1 C^T lam``; False if the matrix is not positive definite."""
    fill_rows(m.row_body, v, t, rows)
    twists(m, w)
    _schur_rhs(m, v, w)
    if not schur_solve(m, v, w, m.form[2]):
        return False
    correct(m, v, w)
    return True


@jit
def fill_rows(row_body, v, t, rows):
    """Every constraint row (``row_body`` (n_c, 2)) at time ``t`` from the pieces: ``C``, ``C_v``
    (``J``, ``Je``), ``gamma``, ``C_t`` and the rows that do not act, for the points' kinematics in
    ``v``. Takes ``row_body``, not the model: a compiled call passes its arguments' arrays flattened."""
    for r in range(row_body.shape[0]):
        v.C[r] = 0.0
        v.gam[r] = 0.0
        v.Ct[r] = 0.0
        v.inactive[r] = 0
        for s in range(2):
            for i in range(6):
                v.J[r, s, i] = 0.0
    for k in range(v.Je.shape[0]):
        v.Je[k] = 0.0
    for d in literal_unroll(rows):
        if d.i.shape[0] > 0:
            row_piece(d, t, v)


@inline
def twists(m, w):
    """``w.tw`` (nb + 1, 6) = every body's ``[W_v, B_omega]``: the velocities the rows act on."""
    for b in range(m.nb + 1):
        for i in range(3):
            w.tw[b, i] = w.vW[b, i]
            w.tw[b, 3 + i] = w.wB[b, i]


@inline
def schur_solve(m, v, w, compliance):
    """``(C M^-1 C^T + compliance I) lam = b`` in place (``b`` in ``w.lam``, row order), with ``W = M^-1
    C^T`` in ``w.W6``, ``w.We``; rows that do not act get 1 on the diagonal (their ``b`` is 0, so
    ``lam`` = 0). False if the matrix is not positive definite."""
    n_c = m.row_body.shape[0]
    _schur_matrix(m.row_body, v.row_je, m.body_kind, m.body_flex, m.fx_i, m.pair, v.J, v.Je, w.W6, w.We, w.ab)
    for i in range(n_c):
        w.ab[m.kd * n_c + i] += compliance + (1.0 if v.inactive[m.perm[i]] == 1 else 0.0)
        w.x[i] = w.lam[m.perm[i]]
    if not banded_cholesky_solve(w.ab, n_c, m.kd, w.x):
        return False
    for i in range(n_c):
        w.lam[m.perm[i]] = w.x[i]
    return True


@inline
def mass_weighted_rows(m, v, w, r):
    """``W = M^-1 C^T`` of row ``r``, both sides, into ``w.W6`` (frame) and ``w.We`` (elastic); the
    flexible blocks factorized."""
    for s in range(2):
        b = m.row_body[r, s]
        kind = m.body_kind[b]
        if kind == RIGID:
            _rigid_solve(m.mass_inv, m.inertia_inv, b, v.J[r, s], w.W6[r, s])
        elif kind == GROUND:
            for i in range(6):
                w.W6[r, s, i] = 0.0
        else:
            j0 = v.row_je[r, s]
            solve(m.fx_i, m.fx_pool, w.fx_work, w.fx_sc, m.body_flex[b], v.J[r, s], v.Je, j0, w.W6[r, s], w.We, j0)


@inline
def _schur_rhs(m, v, w):
    """``W = M^-1 C^T`` per (row, side) and ``C a - gamma + 2 damping C_d + frequency^2 C`` into ``w.lam``
    (``C_d = C_v v + C_t``)."""
    for r in range(m.row_body.shape[0]):
        mass_weighted_rows(m, v, w, r)
        Ca = row_times(m.row_body, v.row_je, m.body_kind, m.body_flex, m.fx_i, v.J, v.Je, r, w.a, w.ae)
        if m.form[0] != 0.0:  # velocity feedback (baumgarte, penalty); index1 has none
            C_d = row_times(m.row_body, v.row_je, m.body_kind, m.body_flex, m.fx_i, v.J, v.Je, r, w.tw, w.eta_dot) + v.Ct[r]
            w.lam[r] = Ca - (v.gam[r] - 2.0 * m.form[0] * C_d - m.form[1] ** 2 * v.C[r])
        else:
            w.lam[r] = Ca - (v.gam[r] - m.form[1] ** 2 * v.C[r])


@jit
def _schur_matrix(row_body, row_je, body_kind, body_flex, fx_i, pair, J, Je, W6, We, ab):
    """``C M^-1 C^T`` in band storage from the couplings through shared bodies."""
    for k in range(ab.shape[0]):
        ab[k] = 0.0
    for p in range(pair.shape[0]):
        r, s, k, l = pair[p, 0], pair[p, 1], pair[p, 2], pair[p, 3]
        b = row_body[r, s]
        val = 0.0
        if body_kind[b] == RIGID or body_kind[b] == FLOATING_FLEXIBLE:
            for i in range(6):
                val += W6[r, s, i] * J[k, l, i]
        j0, j1 = row_je[r, s], row_je[k, l]
        if j0 >= 0:
            for q in range(fx_i[body_flex[b], FX_N]):
                val += We[j0 + q] * Je[j1 + q]
        ab[pair[p, 4]] += val


@inline
def correct(m, v, w):
    """``a -= W lam`` (frame and elastic parts)."""
    for r in range(m.row_body.shape[0]):
        lam = w.lam[r]
        for s in range(2):
            b = m.row_body[r, s]
            if m.body_kind[b] == RIGID or m.body_kind[b] == FLOATING_FLEXIBLE:
                for i in range(6):
                    w.a[b, i] -= w.W6[r, s, i] * lam
            j0 = v.row_je[r, s]
            if j0 >= 0:
                fx = m.body_flex[b]
                n, e0 = m.fx_i[fx, FX_N], m.fx_i[fx, FX_E0]
                for q in range(n):
                    w.ae[e0 + q] -= w.We[j0 + q] * lam


@jit
def banded_cholesky_solve(ab, n, kd, b):
    """Solve ``A x = b`` in place (``b``), A SPD in upper band storage ``ab[(kd + i - j) n + j]``;
    False if not positive definite. The factor's diagonal is kept as its reciprocal (multiplies,
    not divisions, in the factorization and both solves)."""
    for j in range(n):
        s = ab[kd * n + j]
        for k in range(max(0, j - kd), j):
            u = ab[(kd + k - j) * n + j]
            s -= u * u
        if not s > 0.0:
            return False
        r = 1.0 / math.sqrt(s)
        ab[kd * n + j] = r
        for i in range(j + 1, min(n, j + kd + 1)):
            s = ab[(kd + j - i) * n + i]
            for k in range(max(0, i - kd), j):
                s -= ab[(kd + k - j) * n + j] * ab[(kd + k - i) * n + i]
            ab[(kd + j - i) * n + i] = s * r
    for i in range(n):  # U^T z = b
        s = b[i]
        for k in range(max(0, i - kd), i):
            s -= ab[(kd + k - i) * n + i] * b[k]
        b[i] = s * ab[kd * n + i]
    for i in range(n - 1, -1, -1):  # U x = z
        s = b[i]
        for k in range(i + 1, min(n, i + kd + 1)):
            s -= ab[(kd + i - k) * n + k] * b[k]
        b[i] = s * ab[kd * n + i]
    return True


@inline
def rates(m, v, w, y, ydot):
    """``y_dot = [W_v, theta_dot(theta, B_omega), eta_dot, v_dot, work rates]``."""
    nf, nqb = m.frame_body.shape[0], 3 + m.n_rot
    n_q = m.n_q
    for k in range(nf):
        b = m.frame_body[k]
        for i in range(3):
            ydot[nqb * k + i] = w.vW[b, i]
            ydot[n_q + 6 * k + i] = w.a[b, i]
            ydot[n_q + 6 * k + 3 + i] = w.a[b, 3 + i]
        d = coordinate_rates(m.n_rot, y, nqb * k + 3, w.wB[b, 0], w.wB[b, 1], w.wB[b, 2])
        ydot[nqb * k + 3], ydot[nqb * k + 4], ydot[nqb * k + 5] = d[0], d[1], d[2]
        if m.n_rot == 4:
            ydot[nqb * k + 6] = d[3]
    for e in range(m.n_e):
        ydot[nqb * nf + e] = w.eta_dot[e]
        ydot[n_q + 6 * nf + e] = w.ae[e]
    for k in range(m.n_aux):
        ydot[n_q + m.n_v + k] = w.aux[k]


@inline
def evaluate(t, y, chart, m, v, w, forces, rows, ydot):
    """``ydot = f(t, y)`` for the charts ``chart`` (nf, 3, 3) and the contacts' memory in ``v.mem``;
    returns ``OK`` or ``SINGULAR`` (a mass block or the constraint matrix not positive definite).

    The first stage of a step (``stages``), which is taken at ``(t, y)`` itself and reads neither the
    tableau nor the stage point: ``ydot`` as a (1, n) stage array and ``y`` stand in for them, with
    the types a step passes: one compiled field for both (the constants compile as their types,
    ``viz3d.compiled._one_signature_per_type``)."""
    k = ydot.reshape((1, ydot.shape[0]))
    return stages(t, 0.0, y, chart, k, ydot, 0, False, m, v, w, forces, rows, k, y)


@entry
def rhs(t, y, chart, m, v, w, forces, rows, ydot):
    """``evaluate``, called from Python."""
    return evaluate(t, y, chart, m, v, w, forces, rows, ydot)


@jit
def stages(t, h, y, chart, ta, tc, first, turns, m, v, w, forces, rows, k, yi):
    """The stages of an explicit Runge-Kutta step of size ``h`` from ``(t, y)`` into ``k`` (stages, n),
    ``first`` to the last (the rows before ``first`` given); the status of the first failed
    evaluation, ``OK`` when none.

    The field's one compiled form, inlined here (``field_kinematics``, the force elements' pieces,
    ``field_rates``): a step's stages take one compiled call, not one per stage (each compiled call
    passes ``m``, ``v``, ``w`` and the elements' data flattened, some 700 words, more than a small
    system's evaluation costs), and every other evaluation is the first stage of a step
    (``evaluate``), so the field is compiled once for a system's types.

    Stage ``i`` is taken at ``t + c_i h`` and ``yi = y + h sum_l a_il k_l`` (``_stage_point``),
    stage 0 (``c_0 = 0``, no ``a_0l``) at ``(t, y)`` itself. ``turns``: the stages of a
    Munthe-Kaas step (``viz3d.integrators.explicit_rk.ExplicitRK``): each frame's Euler parameters at
    stage ``i`` are ``y``'s turned by ``u_i = h sum_l a_il K_l`` (``turn_quaternion``); after the
    evaluation, the frame's ``k[i]`` entries of ``p_dot`` hold ``K_i = dexpinv(u_i, B_omega_i)``
    (``viz3d.dynamics.dexpinv``) and 0 (those of the rows before ``first`` too)."""
    nf = m.frame_body.shape[0] if turns else 0
    for i in range(0 if turns else first, ta.shape[0]):
        t_i, p = t, y
        if i > 0 or turns:
            t_i, p = t + tc[i] * h, yi
            _stage_point(h, y, ta, i, k, yi)
            for f in range(nf):
                i0 = 7 * f + 3
                u1, u2, u3 = rotation_increment(ta[i], i, h, k, i0)
                for c in range(4):
                    yi[i0 + c] = y[i0 + c]
                turn_quaternion(yi, i0, u1, u2, u3)
        if i >= first:
            field_kinematics(m, v, w, p, chart)
            for d in literal_unroll(forces):
                if d.i.shape[0] > 0:  # every registered type is passed (but present_only ones); most are empty
                    force_piece(d, t_i, v, w.aux)
            status = field_rates(t_i, p, m, v, w, rows, k[i])
            if status != OK:
                return status
        for f in range(nf):
            i0, o = 7 * f + 3, m.n_q + 6 * f + 3
            u1, u2, u3 = rotation_increment(ta[i], i, h, k, i0)
            w1, w2, w3 = yi[o], yi[o + 1], yi[o + 2]
            c1, c2, c3 = u2 * w3 - u3 * w2, u3 * w1 - u1 * w3, u1 * w2 - u2 * w1
            k[i, i0] = w1 + 0.5 * c1 + (u2 * c3 - u3 * c2) / 12.0
            k[i, i0 + 1] = w2 + 0.5 * c2 + (u3 * c1 - u1 * c3) / 12.0
            k[i, i0 + 2] = w3 + 0.5 * c3 + (u1 * c2 - u2 * c1) / 12.0
            k[i, i0 + 3] = 0.0
    return OK


@inline
def field_kinematics(m, v, w, y, chart):
    """The field's stages before the force elements: frames, material points, forces cleared."""
    frames(m, v, w, y, chart)
    kinematics(m, v, w)
    clear(m, v, w)


@inline
def field_rates(t, y, m, v, w, rows, ydot):
    """The field's stages after the force elements, to ``ydot``; returns ``OK`` or ``SINGULAR``.
    (The force elements' loop between ``field_kinematics`` and this is written out in ``stages``:
    numba inlines no function that uses ``literal_unroll``.)"""
    generalized_forces(m, v, w)
    if not free_accelerations(m, v, w):
        return SINGULAR
    if m.row_body.shape[0] > 0:
        if not constrain(m, v, w, t, rows):
            return SINGULAR
        if m.n_aux > 0:  # the drives' power lam . C_t, into the work in (viz3d.dynamics.drive_power)
            for r in range(m.row_body.shape[0]):
                w.aux[w.aux.shape[0] - 1] += w.lam[r] * v.Ct[r]
    rates(m, v, w, y, ydot)
    return OK


@inline
def _stage_point(h, y, ta, i, k, yi):
    """``yi = y + h sum_l a_il k_l`` over the stages before ``i`` (zero coefficients skipped)."""
    for j in range(y.shape[0]):
        acc = y[j]
        for l in range(i):
            if ta[i, l] != 0.0:
                acc += h * ta[i, l] * k[l, j]
        yi[j] = acc


@inline
def rotation_increment(coef, s, h, k, i0):
    """``h sum_l coef[l] K_l`` over the first ``s`` stages, ``K_l = k[l, i0:i0 + 3]``: a frame's
    body-frame rotation increment [rad] (``stages`` keeps its ``K`` there)."""
    u1 = u2 = u3 = 0.0
    for l in range(s):
        if coef[l] != 0.0:
            u1 += h * coef[l] * k[l, i0]
            u2 += h * coef[l] * k[l, i0 + 1]
            u3 += h * coef[l] * k[l, i0 + 2]
    return u1, u2, u3


@entry
def gaps(t, y, chart, m, v, w, geometry, out):
    """``out[k] = [alpha, alpha_dot]`` of every contact at ``(t, y)`` (kinematics only: the event
    functions of ``viz3d.events``)."""
    frames(m, v, w, y, chart)
    kinematics(m, v, w)
    for d in literal_unroll(geometry):
        if d.i.shape[0] > 0:
            gap_piece(d, v, out)

"""ALI3-P's evaluations and linear algebra in the kernel: the compiled path of ``viz3d.ali3p``.

``viz3d.ali3p`` holds the method once (predictor, Newton iteration, multiplier updates, the
switch to the exact tangent, projections, halvings); it asks a *path* for what costs: the
positions, forces and constraint rows at a trial increment, the mass matrix, the force tangents
and the factors of its matrices. ``KernelPath`` answers in the kernel:

* a trial increment ``dx`` is retracted (``W_r + dW_r``; Euler parameters turned by
  ``turn_quaternion``; ZXZ Euler angles through ``R exp(skew(B_dphi))`` on the branch and turn
  of the old angles, as ``viz3d.coordinates.EulerZXZ.advance``), and forces, gyroscopic terms,
  constraint rows ``C``, ``C_v`` and ``gamma`` are evaluated by the field's own stages
  (``viz3d.kernel.field``), one compiled call;
* matrices over the velocity unknowns are ``Band``: general band storage in body order, of
  half-bandwidth ``6 d + 5`` where ``d`` is the largest distance in body order of two coupled
  bodies (``viz3d.sparsity.body_adjacency``): 11 on a chain of any length. ``C_v^T C_v``
  is assembled from the rows' (2, 6) blocks, the finite-difference tangents are scattered into
  the band, and ``T`` (not symmetric once ``K``, ``D`` are in it) is factored by LAPACK's banded
  LU with partial pivoting (``gbtrf``/``gbtrs``): O(N) per step on a chain.

Covered: rigid bodies, every joint and force element with a compiled piece. Not covered (the run
keeps the NumPy path and says why, ``viz3d.kernel.model._check_stepping``): flexible bodies, contacts, force elements that
remember (shape contacts' anchors).
"""

from __future__ import annotations

import math

import numpy as np

from viz3d.compiled import entry, jit
from viz3d.kernel import _c
from viz3d.kernel.field import NONFINITE, OK, clear, fill_rows, force_piece, frames, generalized_forces, turn_quaternion
from viz3d.points import kinematics
from viz3d.rotations import GIMBAL_EPS

try:
    from numba import literal_unroll
except ImportError:  # pragma: no cover
    def literal_unroll(x):
        return x


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
        fill_rows(m, v, t, rows)
    ok = True
    for k in range(m.frame_body.shape[0]):
        for i in range(6):
            Q[6 * k + i] = w.Q[m.frame_body[k], i]
            ok = ok and math.isfinite(Q[6 * k + i])
    for r in range(v.C.shape[0]):
        ok = ok and math.isfinite(v.C[r])
    return OK if ok else NONFINITE


@entry
def trial_point(t1, q0, v0, a0, dx, h, chart, m, v, w, forces, rows, y, a1, Q):
    """ALI3-P's trial point of the increment ``dx`` (n_v,) from ``(q0, v0, a0)``: ``y = [q1, v1]``,
    ``a1`` (eqs. 3.19, 3.20), forces ``Q`` and the rows at ``t1`` (in ``v``); the status."""
    _retract(m, q0, dx, y)
    n_q = m.n_q
    for i in range(m.n_v):
        y[n_q + i] = 2.0 / h * dx[i] - v0[i]
        a1[i] = 4.0 / (h * h) * (dx[i] - h * v0[i]) - a0[i]
    return _forces_and_rows(t1, y, chart, m, v, w, forces, rows, Q)


@entry
def state_point(t, y, chart, m, v, w, forces, rows, Q):
    """Forces ``Q`` (n_v,) and the rows (in ``v``) at the state ``y = [q, v]``; the status."""
    return _forces_and_rows(t, y, chart, m, v, w, forces, rows, Q)


@entry
def retracted(m, q0, dx, y):
    """``y[:n_q]`` = ``q0`` moved by ``dx`` (``_retract`` callable from Python)."""
    _retract(m, q0, dx, y)


@entry
def rows_times(col, J, x, out):
    """``out = C_v x`` (n_c,) for the rows' blocks ``J`` (n_c, 2, 6) and their bodies' first velocity
    columns ``col`` (n_c, 2) (-1: ground)."""
    for r in range(J.shape[0]):
        acc = 0.0
        for s in range(2):
            c = col[r, s]
            if c >= 0:
                for i in range(6):
                    acc += J[r, s, i] * x[c + i]
        out[r] = acc


@entry
def rows_transposed_times(col, J, lam, out):
    """``out = C_v^T lam`` (n_v,)."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    for r in range(J.shape[0]):
        for s in range(2):
            c = col[r, s]
            if c >= 0:
                for i in range(6):
                    out[c + i] += J[r, s, i] * lam[r]


@entry
def add_gram(col, J, scale, bw, ab):
    """``A += scale C_v^T C_v`` in the band storage ``ab`` of half-bandwidth ``bw`` (``Band``)."""
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
                        ab[2 * bw + ci + i - cj - j, cj + j] += f * J[r, u, j]


@entry
def band_times(ab, bw, x, out):
    """``out = A x`` for ``A`` in band storage (``Band``)."""
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(max(0, i - bw), min(n, i + bw + 1)):
            acc += ab[2 * bw + i - j, j] * x[j]
        out[i] = acc


# ---------------------------------------------------------------------------- matrices


class Band:
    """A square matrix (n, n) of half-bandwidth ``bw`` in LAPACK's band storage for ``gbtrf``:
    ``ab`` (3 bw + 1, n), ``A[i, j] = ab[2 bw + i - j, j]``, the first ``bw`` rows room for the
    LU's fill. Supports ``A + B``, ``c * A``, ``A @ x`` and ``factor``."""

    __array_ufunc__ = None  # numpy scalars defer to __rmul__

    def __init__(self, ab: np.ndarray, bw: int):
        self.ab, self.bw = ab, bw

    @classmethod
    def zeros(cls, n: int, bw: int) -> "Band":
        return cls(np.zeros((3 * bw + 1, n)), bw)

    @classmethod
    def from_sparse(cls, S, bw: int) -> "Band":
        """The band of the sparse (n, n) ``S``; ``ValueError`` if an entry lies outside it."""
        S = S.tocsr().tocoo()  # duplicates summed: each entry once
        if S.nnz and np.max(np.abs(S.row - S.col)) > bw:
            raise ValueError(f"entry outside the half-bandwidth {bw}")
        out = cls.zeros(S.shape[0], bw)
        out.ab[2 * bw + S.row - S.col, S.col] = S.data
        return out

    def __add__(self, other: "Band") -> "Band":
        return Band(self.ab + other.ab, self.bw)

    def __mul__(self, c: float) -> "Band":
        return Band(float(c) * self.ab, self.bw)

    __rmul__ = __mul__

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        out = np.empty(self.ab.shape[1])
        band_times(self.ab, self.bw, np.ascontiguousarray(x, dtype=float), out)
        return out

    def toarray(self) -> np.ndarray:
        n, bw = self.ab.shape[1], self.bw
        A = np.zeros((n, n))
        for i in range(n):
            for j in range(max(0, i - bw), min(n, i + bw + 1)):
                A[i, j] = self.ab[2 * bw + i - j, j]
        return A

    def factor(self) -> "BandLU":
        return BandLU(self)


class BandLU:
    """LAPACK's banded LU with partial pivoting (``gbtrf``) of a ``Band``, with ``solve(b)``;
    ``RuntimeError`` if the matrix is singular (as SuperLU raises)."""

    def __init__(self, A: Band):
        from scipy.linalg.lapack import dgbtrf

        self.bw = A.bw
        self.lu, self.piv, info = dgbtrf(A.ab, A.bw, A.bw)
        if info != 0:
            raise RuntimeError(f"singular banded matrix (gbtrf info {info})")

    def solve(self, b: np.ndarray) -> np.ndarray:
        from scipy.linalg.lapack import dgbtrs

        x, info = dgbtrs(self.lu, self.bw, self.bw, b, self.piv)
        return x


class BlockRows:
    """``C_v`` (n_c, n_v) as the rows' (2, 6) blocks ``J`` and their bodies' first columns ``col``
    (n_c, 2) (-1: ground): ``C_v @ x``, ``C_v.T @ lam``, ``C_v.T @ C_v`` (a ``Band`` of half-bandwidth
    ``bw``)."""

    def __init__(self, col: np.ndarray, J: np.ndarray, n_v: int, bw: int, transposed: bool = False):
        self.col, self.J, self.n_v, self.bw, self.transposed = col, J, n_v, bw, transposed

    @property
    def T(self) -> "BlockRows":
        return BlockRows(self.col, self.J, self.n_v, self.bw, not self.transposed)

    def __matmul__(self, x):
        if isinstance(x, BlockRows):
            assert self.transposed and not x.transposed
            out = Band.zeros(self.n_v, self.bw)
            add_gram(self.col, self.J, 1.0, self.bw, out.ab)
            return out
        x = np.ascontiguousarray(x, dtype=float)
        if self.transposed:
            out = np.empty(self.n_v)
            rows_transposed_times(self.col, self.J, x, out)
        else:
            out = np.empty(self.J.shape[0])
            rows_times(self.col, self.J, x, out)
        return out


# ---------------------------------------------------------------------------- the path


class KernelPath:
    """What ``viz3d.ali3p`` asks of a path, answered in the kernel for one packed system
    (``stepper``: its ``viz3d.kernel.KernelStepper``; ``system``: covered, see ``viz3d.kernel.model._check_stepping``)."""

    name = "compiled kernel"

    def __init__(self, system, stepper):
        from viz3d.sparsity import body_adjacency

        self.stepper, d = stepper, stepper.data
        m = d.model
        self.m, self.n_v = m, m.n_v
        A = body_adjacency(system)
        frame_of = m.body_frame[: m.nb]
        i, j = np.nonzero(A)
        self.bw = int(6 * np.max(np.abs(frame_of[i] - frame_of[j]), initial=0) + 5)
        self.col = np.where(m.body_frame[m.row_body] >= 0, 6 * m.body_frame[m.row_body], -1).astype(np.int64)
        self.y = np.zeros(m.n_q + m.n_v + m.n_aux)
        self.a1, self.Q = np.zeros(m.n_v), np.zeros(m.n_v)
        self.M = self._mass()

    def _mass(self) -> Band:
        """``diag(m I3, I)`` per rigid body (constant)."""
        m, M = self.m, Band.zeros(self.n_v, self.bw)
        for k, b in enumerate(m.frame_body):
            block = np.zeros((6, 6))
            block[:3, :3] = np.eye(3) / m.mass_inv[b]
            block[3:, 3:] = m.inertia[b]
            for i in range(6):
                for j in range(6):
                    M.ab[2 * self.bw + i - j, 6 * k + j] = block[i, j]
        return M

    def mass_matrix(self, system, state) -> Band:
        return self.M

    def point(self, system, state, a0, dx, h: float, t1: float, M=None):
        """``(q1, v1, a1, C, C_v, Q, M)`` at the trial increment ``dx`` (``viz3d.ali3p._Point``'s
        fields; ``C`` nan where the evaluation is not finite)."""
        st, d = self.stepper, self.stepper.data
        v, w = st.ws
        status = st._call(trial_point, t1, _c(state.q), _c(state.v), _c(a0), _c(dx), h, _c(state.chart), d.model, v, w,
                          d.forces, d.rows, self.y, self.a1, self.Q)
        n_q = self.m.n_q
        C = v.C.copy() if status == OK else np.full(v.C.shape, np.nan)
        return (self.y[:n_q].copy(), self.y[n_q: n_q + self.n_v].copy(), self.a1.copy(), C,
                BlockRows(self.col, v.J.copy(), self.n_v, self.bw), self.Q.copy(), self.M)

    def forces(self, system, t: float, q, v_, chart, elements=()) -> np.ndarray:
        """Applied and gyroscopic forces (n_v,) at ``(t, q, v)``."""
        self._state_point(t, q, v_, chart)
        return self.Q.copy()

    def rows(self, system, q, v_, chart, t: float):
        """``(C_t, gamma)`` (n_c,) at ``(t, q, v)``."""
        self._state_point(t, q, v_, chart)
        vw = self.stepper.ws[0]
        return vw.Ct.copy(), vw.gam.copy()

    def _state_point(self, t, q, v_, chart) -> None:
        st, d = self.stepper, self.stepper.data
        n_q = self.m.n_q
        self.y[:n_q], self.y[n_q: n_q + self.n_v] = q, v_
        st._call(state_point, t, self.y, _c(chart), d.model, *st.ws, d.forces, d.rows, self.Q)

    def retract(self, system, q, dx, chart) -> np.ndarray:
        out = np.empty(self.m.n_q)
        self.stepper._call(retracted, self.m, _c(q), _c(dx), out)
        return out

    def work_rates(self, system, formulation, state) -> np.ndarray:
        """The ledger's work rates at ``state`` (n_aux,) [W]: the kernel's index-1 field's."""
        out = np.empty(self.y.size)
        if self.stepper.evaluate(state.t, state.y, state.chart, self.stepper.view(()), out) != OK:
            raise np.linalg.LinAlgError(f"t = {state.t:.6g} s: constraint matrix is not positive definite")
        return out[self.m.n_q + self.n_v:].copy()

    def matrix(self, S) -> Band:
        """A finite-difference tangent (sparse) as a ``Band``."""
        return Band.from_sparse(S, self.bw)

    @staticmethod
    def factor(A: Band) -> BandLU:
        return A.factor()

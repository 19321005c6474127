"""Constraint rows of all joints and the structured solve of the augmented system.

The augmented system ``[M C_v^T; C_v 0] [v_dot; lam] = [Q; gamma]`` is solved through its Schur
complement: with the constant block-diagonal ``M^-1``,

    A lam = C_v M^-1 Q - gamma,   A = C_v M^-1 C_v^T,   v_dot = M^-1 (Q - C_v^T lam).

``A`` is symmetric positive definite when the joints are independent. Each constraint row touches
at most two bodies, so ``A`` is sparse: two rows couple only through a shared body. At build time
``ConstraintLayout`` lists those couplings, orders the rows by reverse Cuthill-McKee to shrink the
bandwidth, and picks a dense (LAPACK ``dposv``) or banded (LAPACK ``dpbsv``, O(n kd^2)) Cholesky
solve. A chain of N ball joints gives a block-tridiagonal ``A`` with half-bandwidth 5.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee

from viz3d._typing import FloatArray, IntArray
from viz3d.joints import Joint
from viz3d.kinematics import Pose, Twist

#: Use the banded solver when there are at least this many rows ...
BANDED_MIN_ROWS = 24
#: ... and the half-bandwidth is at most this fraction of the row count.
BANDED_MAX_FRACTION = 0.25


class SingularConstraintError(np.linalg.LinAlgError):
    """The constraint Jacobian lost rank (redundant or degenerate joints)."""


@dataclass(frozen=True)
class ConstraintRows:
    """All joints' constraint rows at one state, stacked in joint order.

    Attributes
    ----------
    C : ndarray, shape (n_c,)
        Residuals [m].
    J : ndarray, shape (n_c, 2, 6)
        Velocity-Jacobian blocks of each row on its two bodies.
    gamma : ndarray, shape (n_c,)
        Acceleration right-hand side [m/s^2].
    """

    C: FloatArray
    J: FloatArray
    gamma: FloatArray


@dataclass(frozen=True)
class ConstraintLayout:
    """Build-time structure of the constraint rows (frozen; computed once per system).

    Attributes
    ----------
    joints : tuple of Joint
    row_body : ndarray of int, shape (n_c, 2)
    perm : ndarray of int, shape (n_c,)
        Solve order of the rows (reverse Cuthill-McKee).
    pair_row, pair_side, pair_col, pair_colside : ndarray of int, shape (n_pairs,)
        Couplings ``A[r, k] += W[r, s] . J[k, l]`` through a shared body, upper triangle in solve
        order only.
    pair_slot : ndarray of int, shape (n_pairs,)
        Flat index of each coupling in the dense (n_c, n_c) or banded (kd + 1, n_c) storage.
    kd : int
        Half-bandwidth in solve order.
    banded : bool
    """

    joints: tuple[Joint, ...]
    row_body: IntArray
    perm: IntArray
    pair_row: IntArray
    pair_side: IntArray
    pair_col: IntArray
    pair_colside: IntArray
    pair_slot: IntArray
    kd: int
    banded: bool

    @property
    def n_rows(self) -> int:
        return self.row_body.shape[0]

    @property
    def storage_size(self) -> int:
        n = self.n_rows
        return (self.kd + 1) * n if self.banded else n * n

    def row_slices(self) -> list[slice]:
        """Rows of each joint set, in ``joints`` order."""
        out, start = [], 0
        for js in self.joints:
            stop = start + js.n_joints * js.n_eq
            out.append(slice(start, stop))
            start = stop
        return out


def build_layout(joints: tuple[Joint, ...], n_bodies: int) -> ConstraintLayout:
    """Precompute row couplings, ordering and solver choice for ``joints`` on ``n_bodies`` bodies."""
    row_body = np.concatenate(
        [np.repeat(js.body, js.n_eq, axis=0) for js in joints] or [np.zeros((0, 2), int)]
    ).astype(int)
    n_c = row_body.shape[0]
    r_idx, s_idx, k_idx, l_idx = _shared_body_pairs(row_body, n_bodies)
    perm = _bandwidth_order(r_idx, k_idx, n_c)
    pos = np.empty(n_c, dtype=int)
    pos[perm] = np.arange(n_c)
    upper = pos[r_idx] <= pos[k_idx]
    r_idx, s_idx, k_idx, l_idx = r_idx[upper], s_idx[upper], k_idx[upper], l_idx[upper]
    i, j = pos[r_idx], pos[k_idx]
    kd = int(np.max(j - i)) if n_c else 0
    banded = n_c >= BANDED_MIN_ROWS and kd <= BANDED_MAX_FRACTION * n_c
    slot = (kd + i - j) * n_c + j if banded else i * n_c + j
    return ConstraintLayout(tuple(joints), row_body, perm, r_idx, s_idx, k_idx, l_idx, slot, kd, banded)


def _shared_body_pairs(row_body: IntArray, n_bodies: int):
    """All (row r, side s, row k, side l) with ``row_body[r, s] == row_body[k, l]`` not ground."""
    flat_row = np.repeat(np.arange(row_body.shape[0]), 2)
    flat_side = np.tile([0, 1], row_body.shape[0])
    flat_body = row_body.ravel()
    keep = flat_body < n_bodies
    flat_row, flat_side, flat_body = flat_row[keep], flat_side[keep], flat_body[keep]
    order = np.argsort(flat_body, kind="stable")
    flat_row, flat_side, flat_body = flat_row[order], flat_side[order], flat_body[order]
    starts = np.searchsorted(flat_body, np.arange(n_bodies))
    stops = np.searchsorted(flat_body, np.arange(n_bodies), side="right")
    groups = [np.arange(a, b) for a, b in zip(starts, stops) if b > a]
    a = np.concatenate([np.repeat(g, len(g)) for g in groups] or [np.zeros(0, int)])
    b = np.concatenate([np.tile(g, len(g)) for g in groups] or [np.zeros(0, int)])
    return flat_row[a], flat_side[a], flat_row[b], flat_side[b]


def _bandwidth_order(r_idx: IntArray, k_idx: IntArray, n_c: int) -> IntArray:
    if n_c == 0:
        return np.zeros(0, dtype=int)
    graph = coo_matrix((np.ones(len(r_idx)), (r_idx, k_idx)), shape=(n_c, n_c)).tocsr()
    return np.asarray(reverse_cuthill_mckee(graph, symmetric_mode=True), dtype=int)


def constraint_rows(layout: ConstraintLayout, pose: Pose, twist: Twist) -> ConstraintRows:
    """Residuals, Jacobian blocks and gamma of every joint, stacked (see ``ConstraintRows``)."""
    C, J, gamma = [], [], []
    for js in layout.joints:
        C.append(js.residual(pose).reshape(-1))
        J.append(js.jacobian(pose).reshape(-1, 2, 6))
        gamma.append(js.gamma(pose, twist).reshape(-1))
    if not layout.joints:
        return ConstraintRows(np.zeros(0), np.zeros((0, 2, 6)), np.zeros(0))
    return ConstraintRows(np.concatenate(C), np.concatenate(J), np.concatenate(gamma))


def constraint_jacobian(layout: ConstraintLayout, pose: Pose) -> FloatArray:
    """Jacobian blocks of every joint, stacked, shape (n_c, 2, 6) (see ``ConstraintRows``)."""
    if not layout.joints:
        return np.zeros((0, 2, 6))
    return np.concatenate([js.jacobian(pose).reshape(-1, 2, 6) for js in layout.joints])


def dense_jacobian(layout: ConstraintLayout, J: FloatArray, n_bodies: int) -> FloatArray:
    """``C_v`` as a dense matrix, shape (n_c, 6 n_bodies), from its row blocks ``J`` (n_c, 2, 6)."""
    n_c = J.shape[0]
    dense = np.zeros((n_c, 6 * (n_bodies + 1)))
    cols = layout.row_body[:, :, None] * 6 + np.arange(6)
    np.put_along_axis(dense, cols.reshape(n_c, 12), J.reshape(n_c, 12), axis=1)
    return dense[:, : 6 * n_bodies]


def constraint_residual(layout: ConstraintLayout, pose: Pose) -> FloatArray:
    """Stacked residuals ``C`` only, shape (n_c,) [m]."""
    if not layout.joints:
        return np.zeros(0)
    return np.concatenate([js.residual(pose).reshape(-1) for js in layout.joints])


def apply_jacobian(layout: ConstraintLayout, J: FloatArray, x: FloatArray) -> FloatArray:
    """``C_v @ x`` for per-body vectors ``x`` (nb + 1, 6): shape (n_c,)."""
    return np.einsum("rsi,rsi->r", J, x[layout.row_body])


def apply_jacobian_transpose(layout: ConstraintLayout, J: FloatArray, lam: FloatArray, n_rows: int) -> FloatArray:
    """``C_v^T @ lam`` as per-body vectors, shape (n_rows, 6), with ``n_rows = nb + 1``."""
    out = np.zeros((n_rows, 6))
    np.add.at(out, layout.row_body.ravel(), (J * lam[:, None, None]).reshape(-1, 6))
    return out


def schur_solve(layout: ConstraintLayout, M_inv: FloatArray, J: FloatArray, b: FloatArray,
                shift: float = 0.0) -> FloatArray:
    """Solve ``(C_v M^-1 C_v^T + shift I) lam = b`` for ``lam`` (n_c,), on dense or banded storage
    (``shift > 0``: the compliance of penalty-like formulations, positive definite even for
    redundant joints).

    Raises
    ------
    SingularConstraintError
        If the matrix is not positive definite (the Jacobian lost rank).
    """
    if layout.n_rows == 0:
        return np.zeros(0)
    W = np.einsum("rsi,rsij->rsj", J, M_inv[layout.row_body])
    vals = np.einsum("pi,pi->p", W[layout.pair_row, layout.pair_side], J[layout.pair_col, layout.pair_colside])
    store = np.bincount(layout.pair_slot, vals, minlength=layout.storage_size)
    n = layout.n_rows
    if shift:
        store[layout.kd * n + np.arange(n) if layout.banded else np.arange(n) * (n + 1)] += shift
    rhs = b[layout.perm]
    if layout.banded:
        _, x, info = lapack.dpbsv(store.reshape(layout.kd + 1, n), rhs, lower=0)
    else:
        _, x, info = lapack.dposv(store.reshape(n, n), rhs, lower=0)
    if info != 0:
        what = "C M^-1 C^T" if not shift else f"C M^-1 C^T + {shift:.3g} I"
        raise SingularConstraintError(f"constraint matrix {what} is singular (not positive definite, LAPACK info={info})")
    lam = np.empty(n)
    lam[layout.perm] = x
    return lam

"""Constraint rows of all joints and the structured solve of the augmented system.

The augmented system ``[M C_v^T; C_v 0] [v_dot; lam] = [Q; gamma]`` is solved through its Schur
complement: with ``M^-1`` applied block by block (``viz3d.mass``),

    A lam = C_v M^-1 Q - gamma,   A = C_v M^-1 C_v^T,   v_dot = M^-1 (Q - C_v^T lam).

``A`` is symmetric positive definite when the joints are independent. Each constraint row touches
at most two bodies, so ``A`` is sparse: two rows couple only through a shared body. At build time
``ConstraintLayout`` lists those couplings, orders the rows by reverse Cuthill-McKee to shrink the
bandwidth, and picks a dense (LAPACK ``dposv``) or banded (LAPACK ``dpbsv``, O(n kd^2)) Cholesky
solve. A chain of N ball joints gives a block-tridiagonal ``A`` with half-bandwidth 5. Couplings
through a rigid body use its constant 6 x 6 inverse; the rows touching a flexible body are coupled
through its whole block (frame and elastic velocities), factorized once per evaluation.

Row Jacobians are kept split like every generalized vector: a frame part ``J`` (n_c, 2, 6) on the
twists of the row's two bodies and an elastic part ``Je`` (n_c, 2, n_e) on the stacked elastic
velocities.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.joints import Joint
from viz3d.kinematics import Configuration

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
        Velocity-Jacobian blocks of each row on its two bodies' twists.
    gamma : ndarray, shape (n_c,)
        Acceleration right-hand side [m/s^2].
    Je : ndarray, shape (n_c, 2, n_e)
        Elastic part of each side's Jacobian (zero unless the side is on a flexible body).
    inactive : ndarray of bool, shape (n_c,)
        Rows that do not act now (a kinematic contact that is not touching): zero rows, and a unit
        diagonal in the Schur complement so that their multipliers are zero.
    C_t : ndarray, shape (n_c,), optional
        ``C_dot = C_v v + C_t``: the rows' explicit time rate (drives; None when every row is
        scleronomic).
    """

    C: FloatArray
    J: FloatArray
    gamma: FloatArray
    Je: FloatArray
    inactive: np.ndarray | None = None
    C_t: FloatArray | None = None

    def velocity_residual(self, layout, frame: FloatArray, elastic: FloatArray) -> FloatArray:
        """``C_dot = C_v v + C_t`` (n_c,) for per-body twists ``frame`` (nb + 1, 6) and the elastic
        velocities ``elastic`` (n_e,)."""
        C_d = apply_jacobian(layout, self.J, frame, self.Je, elastic)
        return C_d if self.C_t is None else C_d + self.C_t


@dataclass(frozen=True)
class FlexGroup:
    """The constraint rows touching one flexible body (build time).

    Attributes
    ----------
    flex : int
        Index of the body among ``Bodies.flexible``.
    row, side : ndarray of int, shape (m,)
        The (row, side) entries on the body.
    pair_a, pair_b : ndarray of int, shape (n_pairs,)
        Members coupled through the body, upper triangle in solve order (diagonal included).
    pair_slot : ndarray of int, shape (n_pairs,)
        Their slots in the dense or banded storage of ``A``.
    """

    flex: int
    row: IntArray
    side: IntArray
    pair_a: IntArray
    pair_b: IntArray
    pair_slot: IntArray


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
        Couplings ``A[r, k] += W[r, s] . J[k, l]`` through a shared rigid body, upper triangle in
        solve order only.
    pair_slot : ndarray of int, shape (n_pairs,)
        Flat index of each coupling in the dense (n_c, n_c) or banded (kd + 1, n_c) storage.
    kd : int
        Half-bandwidth in solve order.
    banded : bool
    flex_groups : tuple of FlexGroup
        Couplings through flexible bodies.
    n_elastic : int
        Columns of the elastic Jacobian part.
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
    flex_groups: tuple[FlexGroup, ...] = ()
    n_elastic: int = 0

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

    def slot(self, i: IntArray, j: IntArray) -> IntArray:
        """Storage slots of entries ``(i, j)`` given in solve order with ``i <= j``."""
        n = self.n_rows
        return (self.kd + i - j) * n + j if self.banded else i * n + j


def build_layout(joints: tuple[Joint, ...], bodies, n_elastic: int | None = None) -> ConstraintLayout:
    """Precompute row couplings, ordering and solver choice for ``joints`` on ``bodies`` (a ``Bodies``,
    or the number of rigid bodies)."""
    n_bodies = bodies if isinstance(bodies, (int, np.integer)) else bodies.n_bodies
    flexible = () if isinstance(bodies, (int, np.integer)) else bodies.flexible
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
    flex_body = np.array([fb.index for fb in flexible], dtype=int)
    rigid_pair = ~np.isin(row_body[r_idx, s_idx], flex_body)
    groups = tuple(_flex_group(k, fb.index, row_body, pos, kd, banded) for k, fb in enumerate(flexible)
                   if np.any(row_body == fb.index))
    if n_elastic is None:
        n_elastic = sum(fb.n for fb in flexible)
    return ConstraintLayout(tuple(joints), row_body, perm, r_idx[rigid_pair], s_idx[rigid_pair], k_idx[rigid_pair],
                            l_idx[rigid_pair], slot[rigid_pair], kd, banded, groups, n_elastic)


def _flex_group(k: int, body: int, row_body: IntArray, pos: IntArray, kd: int, banded: bool) -> FlexGroup:
    row, side = np.nonzero(row_body == body)
    a, b = np.meshgrid(np.arange(len(row)), np.arange(len(row)), indexing="ij")
    a, b = a.ravel(), b.ravel()
    upper = pos[row[a]] <= pos[row[b]]  # a row with both sides on the body keeps both cross terms
    a, b = a[upper], b[upper]
    i, j = pos[row[a]], pos[row[b]]
    n_c = row_body.shape[0]
    slot = (kd + i - j) * n_c + j if banded else i * n_c + j
    return FlexGroup(k, row, side, a, b, slot)


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
    """The rows (n_c,) in reverse Cuthill-McKee order of the coupling graph with edges ``(r_idx, k_idx)``
    (symmetric: both directions listed; self-loops allowed).

    Breadth-first from a row of least degree in each connected part (the next unvisited row in
    NumPy's default ``argsort`` of the degrees, int32); each row's unvisited neighbours are appended
    in increasing index, then stably sorted by degree; the whole order is reversed. The degree is
    the number of distinct neighbours, a self-loop counted twice. These are the rules, ties included,
    of ``scipy.sparse.csgraph.reverse_cuthill_mckee(csr, symmetric_mode=True)``, which orders the
    same rows identically (``tests/unit/test_constraints.py``) but imports scipy.sparse and
    scipy.linalg (0.15 s at a run's start; Cuthill and McKee, ACM '69, 157-172).
    """
    key = np.sort(np.asarray(r_idx, np.int64) * n_c + np.asarray(k_idx, np.int64))
    distinct = np.ones(len(key), dtype=bool)  # (``np.unique`` would import numpy.ma: 10 ms of a run's start)
    distinct[1:] = key[1:] != key[:-1]
    key = key[distinct]
    row, col = np.divmod(key, n_c)
    start = np.searchsorted(row, np.arange(n_c + 1))
    degree = (np.diff(start) + np.bincount(row[row == col], minlength=n_c)).astype(np.int32)
    visited = np.zeros(n_c, dtype=bool)
    order: list[int] = []
    for seed in np.argsort(degree).tolist():
        if visited[seed]:
            continue
        visited[seed] = True
        order.append(seed)
        head = len(order) - 1
        while head < len(order):
            r = order[head]
            head += 1
            new = col[start[r]:start[r + 1]]
            new = new[~visited[new]]
            visited[new] = True
            order.extend(new[np.argsort(degree[new], kind="stable")].tolist())
    return np.array(order[::-1], dtype=int)


def constraint_rows(layout: ConstraintLayout, cfg: Configuration, memory: tuple = ()) -> ConstraintRows:
    """Residuals, Jacobian blocks and gamma of every joint (and kinematic contact row active in
    ``memory``, the contact phases of ``State.memory``), stacked (see ``ConstraintRows``)."""
    if not layout.joints:
        return ConstraintRows(np.zeros(0), np.zeros((0, 2, 6)), np.zeros(0), np.zeros((0, 2, layout.n_elastic)))
    C, J, Je, gamma, off, C_t = [], [], [], [], [], []
    for js in layout.joints:
        m = js.n_joints * js.n_eq
        res, (Jf, Jel), gam = js.rows(cfg)
        C.append(res.reshape(-1))
        J.append(Jf.reshape(m, 2, 6))
        Je.append(Jel.reshape(m, 2, layout.n_elastic))
        gamma.append(gam.reshape(-1))
        off.append(np.zeros(m, dtype=bool) if js.is_joint else np.repeat(~js.active(memory), js.n_eq))
        C_t.append(js.time_rate(cfg).reshape(-1) if getattr(js, "rheonomic", False) else np.zeros(m))
    rheonomic = any(getattr(js, "rheonomic", False) for js in layout.joints)
    rows = ConstraintRows(np.concatenate(C), np.concatenate(J), np.concatenate(gamma), np.concatenate(Je),
                          C_t=np.concatenate(C_t) if rheonomic else None)
    inactive = np.concatenate(off)
    if not inactive.any():
        return rows
    keep = ~inactive
    return ConstraintRows(rows.C * keep, rows.J * keep[:, None, None], rows.gamma * keep, rows.Je * keep[:, None, None],
                          inactive, None if rows.C_t is None else rows.C_t * keep)


def constraint_jacobian(layout: ConstraintLayout, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
    """Jacobian blocks of every joint, stacked: frame (n_c, 2, 6) and elastic (n_c, 2, n_e)."""
    return _stacked_jacobian(layout, [js.jacobian(cfg) for js in layout.joints])


def residual_and_jacobian(layout: ConstraintLayout, cfg: Configuration) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``C`` (n_c,) [m] and the Jacobian blocks (``constraint_jacobian``) from one ``Joint.rows`` call
    per joint set (a set whose three share their work computes them once: ``RowsJoint``)."""
    parts = [js.rows(cfg) for js in layout.joints]
    C = np.concatenate([res.reshape(-1) for res, _, _ in parts]) if parts else np.zeros(0)
    return (C, *_stacked_jacobian(layout, [J for _, J, _ in parts]))


def _stacked_jacobian(layout: ConstraintLayout, parts: list) -> tuple[FloatArray, FloatArray]:
    """The joint sets' Jacobian blocks ``(J, Je)`` stacked: (n_c, 2, 6) and (n_c, 2, n_e)."""
    if not parts:
        return np.zeros((0, 2, 6)), np.zeros((0, 2, layout.n_elastic))
    return (np.concatenate([J.reshape(-1, 2, 6) for J, _ in parts]),
            np.concatenate([Je.reshape(js.n_joints * js.n_eq, 2, layout.n_elastic)
                            for js, (_, Je) in zip(layout.joints, parts)]))


def jacobian_entries(system, J: FloatArray, Je: FloatArray) -> tuple[IntArray, IntArray, FloatArray]:
    """``C_v``'s entries as (rows, columns, values) in the order of ``v``, from its blocks: 12 per row
    on the frames of its two bodies (ground's dropped), then the elastic columns (duplicates add)."""
    layout = system.joints
    n_c, nb = J.shape[0], system.n_bodies
    slot = np.full(nb + 1, -1)
    slot[system.frame_body] = np.arange(system.n_frames)
    body_slot = slot[layout.row_body] if n_c else np.zeros((0, 2), int)   # (n_c, 2), -1: ground or no frame
    cols = body_slot[:, :, None] * 6 + np.arange(6)
    rows = np.broadcast_to(np.arange(n_c)[:, None, None], cols.shape)
    keep = np.broadcast_to((body_slot >= 0)[:, :, None], cols.shape)
    r, c, v = rows[keep], cols[keep], J[keep]
    if system.n_elastic:
        Je_sum = Je.sum(axis=1)
        er, ec = np.nonzero(Je_sum)
        r, c, v = (np.concatenate([r, er]), np.concatenate([c, ec + 6 * system.n_frames]),
                   np.concatenate([v, Je_sum[er, ec]]))
    return r, c, v


def sparse_jacobian(system, J: FloatArray, Je: FloatArray):
    """``C_v`` as a sparse CSR matrix, shape (n_c, n_v) (``jacobian_entries``)."""
    import scipy.sparse as sp

    r, c, v = jacobian_entries(system, J, Je)
    return sp.csr_matrix((v, (r, c)), shape=(J.shape[0], system.n_v))


def dense_jacobian(system, J: FloatArray, Je: FloatArray) -> FloatArray:
    """``C_v`` as a dense matrix, shape (n_c, n_v) (``jacobian_entries``)."""
    out = np.zeros((J.shape[0], system.n_v))
    r, c, v = jacobian_entries(system, J, Je)
    np.add.at(out, (r, c), v)
    return out


def constraint_residual(layout: ConstraintLayout, cfg: Configuration) -> FloatArray:
    """Stacked residuals ``C`` only, shape (n_c,) [m]."""
    if not layout.joints:
        return np.zeros(0)
    return np.concatenate([js.residual(cfg).reshape(-1) for js in layout.joints])


def apply_jacobian(layout: ConstraintLayout, J: FloatArray, x: FloatArray, Je: FloatArray | None = None,
                   x_e: FloatArray | None = None) -> FloatArray:
    """``C_v @ x`` for per-body vectors ``x`` (nb + 1, 6) and the elastic part ``x_e`` (n_e,): shape (n_c,)."""
    out = np.einsum("rsi,rsi->r", J, x[layout.row_body])
    if Je is not None and Je.shape[2]:
        out = out + np.einsum("rsi,i->r", Je, x_e)
    return out


def apply_jacobian_transpose(layout: ConstraintLayout, J: FloatArray, lam: FloatArray, n_rows: int,
                             Je: FloatArray | None = None) -> tuple[FloatArray, FloatArray] | FloatArray:
    """``C_v^T @ lam`` as per-body vectors, shape (n_rows, 6), with ``n_rows = nb + 1``; with ``Je``
    also the elastic part (n_e,), returned as a pair."""
    out = np.zeros((n_rows, 6))
    np.add.at(out, layout.row_body.ravel(), (J * lam[:, None, None]).reshape(-1, 6))
    if Je is None:
        return out
    return out, np.einsum("rsi,r->i", Je, lam)


def schur_solve(layout: ConstraintLayout, mass, J: FloatArray, b: FloatArray, shift: float = 0.0,
                Je: FloatArray | None = None, inactive: np.ndarray | None = None) -> FloatArray:
    """Solve ``(C_v M^-1 C_v^T + shift I) lam = b`` for ``lam`` (n_c,), on dense or banded storage
    (``shift > 0``: the compliance of penalty-like formulations, positive definite even for
    redundant joints). ``mass`` is a ``viz3d.mass.MassMatrix`` (or, for rigid bodies only, the
    inverse blocks (nb + 1, 6, 6)).

    Raises
    ------
    SingularConstraintError
        If the matrix is not positive definite (the Jacobian lost rank).
    """
    from scipy.linalg import lapack
    if layout.n_rows == 0:
        return np.zeros(0)
    M_inv = mass if isinstance(mass, np.ndarray) else mass.M_inv
    W = np.einsum("rsi,rsij->rsj", J, M_inv[layout.row_body])
    vals = np.einsum("pi,pi->p", W[layout.pair_row, layout.pair_side], J[layout.pair_col, layout.pair_colside])
    # (float even without rigid couplings: bincount of no weights is an integer array)
    store = np.bincount(layout.pair_slot, vals, minlength=layout.storage_size).astype(float, copy=False)
    for g in layout.flex_groups:
        G = flex_rows(mass, g, J, Je)
        A = G @ mass.solve_block(g.flex, G)
        np.add.at(store, g.pair_slot, A[g.pair_a, g.pair_b])
    n = layout.n_rows
    diagonal = layout.kd * n + np.arange(n) if layout.banded else np.arange(n) * (n + 1)
    if shift:
        store[diagonal] += shift
    if inactive is not None:
        store[diagonal[np.argsort(layout.perm)][inactive]] += 1.0  # rows that do not act: lam = b = 0
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


def flex_rows(mass, group: FlexGroup, J: FloatArray, Je: FloatArray) -> FloatArray:
    """The rows of ``group`` on its flexible body's velocities ``[twist (if floating), eta_dot]``, shape (m, width)."""
    fb = mass.flexible[group.flex]
    elastic = Je[group.row, group.side][:, mass.v_elastic[group.flex]]
    if not fb.floating:
        return elastic
    return np.concatenate([J[group.row, group.side], elastic], axis=1)

"""Which velocity unknowns a system's forces and constraints couple, and finite-difference
Jacobians that use it (Curtis, Powell and Reid's column grouping).

A body's forces depend on its own coordinates and on those of the bodies it is joined to or
shares a force element or contact with (``body_adjacency``). Perturbing one column of each of
several bodies whose neighbourhoods do not overlap changes disjoint sets of rows, so one residual
evaluation gives all their columns: a chain needs 3 groups of bodies whatever its length, so a
Jacobian costs 3 x 6 evaluations instead of 6 N. Elements that do not say which bodies they couple
(``ForceElement.coupled_bodies`` returns None) couple every body with every other: always correct,
only slower.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from viz3d._typing import FloatArray, IntArray


def body_adjacency(system) -> np.ndarray:
    """Bodies (nb, nb) whose forces or constraint rows depend on each other's coordinates, each
    with itself; ground left out."""
    nb = system.n_bodies
    A = np.eye(nb, dtype=bool)
    pairs = [system.joints.row_body] if len(system.joints.row_body) else []
    pairs += [c.body for c in system.contacts]
    for e in system.forces:
        coupled = e.coupled_bodies()
        if coupled is None:
            return np.ones((nb, nb), dtype=bool)
        pairs.append(np.asarray(coupled, int).reshape(-1, 2))
    for p in pairs:
        p = p[(p[:, 0] < nb) & (p[:, 1] < nb)]
        A[p[:, 0], p[:, 1]] = A[p[:, 1], p[:, 0]] = True
    return A


def column_bodies(system) -> IntArray:
    """The body of each velocity unknown, shape (n_v,): 6 per frame, then each flexible body's
    elastic coordinates."""
    out = np.repeat(system.frame_body, 6)
    elastic = [np.full(sl.stop - sl.start, fb.index) for fb, sl in zip(system.bodies.flexible, system.v_elastic)]
    return np.concatenate([out, *elastic]).astype(int)


def column_groups(column_body: IntArray, adjacency: np.ndarray) -> list[IntArray]:
    """Groups of columns that one evaluation can difference together: greedy colouring of the bodies
    so that two of one colour share no neighbour (distance-2), then the k-th column of every body of
    a colour in one group."""
    nb = adjacency.shape[0]
    reach = (adjacency.astype(int) @ adjacency.astype(int)) > 0  # within two steps
    colour = -np.ones(nb, int)
    for b in np.argsort(-adjacency.sum(axis=1), kind="stable"):
        taken = set(colour[reach[b]]) - {-1}
        colour[b] = next(c for c in range(nb) if c not in taken)
    local = np.zeros(len(column_body), int)
    for b in np.unique(column_body):
        idx = np.flatnonzero(column_body == b)
        local[idx] = np.arange(len(idx))
    key = colour[column_body] * (local.max(initial=0) + 1) + local
    return [np.flatnonzero(key == k) for k in np.unique(key)]


def grouped_fd_jacobian(residual: Callable[[FloatArray], FloatArray], x: FloatArray, r0: FloatArray,
                        groups: list[IntArray], rows_of: list[IntArray], step: FloatArray):
    """Sparse forward-difference Jacobian ``d residual / d x`` (CSC, (n, n)): one evaluation per group
    of columns, each column reading only its rows ``rows_of[j]``; ``step`` (n,) the increments."""
    import scipy.sparse as sp

    rows, cols, vals = [], [], []
    for g in groups:
        xp = x.copy()
        xp[g] += step[g]
        d = residual(xp) - r0
        r = np.concatenate([rows_of[j] for j in g])
        c = np.repeat(g, [len(rows_of[j]) for j in g])
        rows.append(r)
        cols.append(c)
        vals.append(d[r] / step[c])
    return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r0.size, x.size))


def sparse_fd_plan(system) -> tuple[list[IntArray], list[IntArray]]:
    """``(groups, rows_of)`` for ``grouped_fd_jacobian`` on a function of the velocity unknowns that
    returns generalized forces (or residuals) in the same order."""
    cb = column_bodies(system)
    A = body_adjacency(system)
    groups = column_groups(cb, A)
    rows_by_body = {b: np.flatnonzero(A[b][cb]) for b in np.unique(cb)}
    return groups, [rows_by_body[b] for b in cb]

"""The system mass matrix at one configuration, kept by blocks, and the products with its inverse.

``M`` is block diagonal over bodies: a rigid body's block ``diag(m I3, I)`` is constant (its inverse
is precomputed in ``Bodies.M_inv``); a flexible body's block (width 6 + n on a floating frame, n on
a fixed one) depends on its configuration and is factorized once per evaluation here. Generalized
vectors (forces, accelerations) are kept in the same split form everywhere: a frame part per body
(nb + 1, 6) ``[W_F, B_tau]`` (ground and fixed frames last / ignored) and an elastic part (n_e,).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.bodies import FlexibleBody
from viz3d.kinematics import Configuration


@dataclass(frozen=True)
class MassMatrix:
    """``M`` at one configuration.

    Attributes
    ----------
    M_inv : ndarray, shape (nb + 1, 6, 6)
        Inverse blocks of the rigid bodies (zero rows elsewhere).
    flexible : tuple of FlexibleBody
    factors : tuple
        ``cho_factor`` of each flexible body's block, in the same order.
    v_elastic : tuple of slice
        Each flexible body's columns in the stacked elastic part.
    """

    M_inv: FloatArray
    flexible: tuple[FlexibleBody, ...] = ()
    factors: tuple = ()
    v_elastic: tuple[slice, ...] = ()

    def body_vector(self, i: int, frame: FloatArray, elastic: FloatArray) -> FloatArray:
        """Flexible body ``i``'s generalized vector ``[frame (6, if floating), eta part]`` from split parts."""
        fb = self.flexible[i]
        part = elastic[..., self.v_elastic[i]]
        return np.concatenate([frame[..., fb.index, :], part], axis=-1) if fb.floating else part

    def solve(self, frame: FloatArray, elastic: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``M^-1 x`` for ``x = (frame (nb + 1, 6), elastic (n_e,))``, in the same split form."""
        from scipy.linalg import cho_solve
        a = np.einsum("bij,bj->bi", self.M_inv, frame)
        a_e = np.zeros_like(elastic)
        for i, fb in enumerate(self.flexible):
            x = cho_solve(self.factors[i], self.body_vector(i, frame, elastic))
            if fb.floating:
                a[fb.index] = x[:6]
                x = x[6:]
            a_e[self.v_elastic[i]] = x
        return a, a_e

    def solve_block(self, i: int, G: FloatArray) -> FloatArray:
        """``M_b^-1 G^T`` for flexible body ``i`` and rows ``G`` (m, width): shape (width, m)."""
        from scipy.linalg import cho_solve
        return cho_solve(self.factors[i], G.T)


def mass_matrix(bodies, v_elastic: tuple[slice, ...], cfg: Configuration) -> MassMatrix:
    """The mass matrix of ``bodies`` at ``cfg`` (factorizes each flexible body's block)."""
    if not bodies.flexible:
        return MassMatrix(bodies.M_inv)
    from scipy.linalg import cho_factor

    factors = tuple(cho_factor(fb.mass_matrix(cfg.pose.R_WB[fb.index], cfg.eta[i]))
                    for i, fb in enumerate(bodies.flexible))
    return MassMatrix(bodies.M_inv, bodies.flexible, factors, v_elastic)


def mass_entries(system, cfg: Configuration) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``M``'s entries as (rows, columns, values) in the order of ``v`` (``viz3d.system``) [kg, kg m^2,
    ...]: ``diag(m I3, I)`` per rigid body, each flexible body's block at its configuration."""
    b = system.bodies
    rows, cols, vals = [np.zeros(0, int)], [np.zeros(0, int)], [np.zeros(0)]
    frame_slot = {int(body): k for k, body in enumerate(system.frame_body)}
    rigid = [k for k, body in enumerate(system.frame_body) if b.is_rigid[body]]
    if rigid:
        blocks = np.zeros((len(rigid), 6, 6))
        bodies = system.frame_body[rigid]
        blocks[:, :3, :3] = b.mass[bodies, None, None] * np.eye(3)
        blocks[:, 3:, 3:] = b.inertia[bodies]
        idx = 6 * np.asarray(rigid)[:, None] + np.arange(6)
        rows.append(np.repeat(idx, 6, axis=1).ravel())
        cols.append(np.tile(idx, (1, 6)).ravel())
        vals.append(blocks.ravel())
    for i, fb in enumerate(b.flexible):
        block = fb.mass_matrix(cfg.pose.R_WB[fb.index], cfg.eta[i])
        idx = np.arange(system.v_elastic[i].start, system.v_elastic[i].stop)
        if fb.floating:
            k = frame_slot[fb.index]
            idx = np.concatenate([np.arange(6 * k, 6 * k + 6), idx])
        rows.append(np.repeat(idx, len(idx)))
        cols.append(np.tile(idx, len(idx)))
        vals.append(np.asarray(block).ravel())
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)


def sparse_mass_matrix(system, cfg: Configuration):
    """``M`` as a sparse CSR matrix (n_v, n_v) (``mass_entries``)."""
    import scipy.sparse as sp

    r, c, v = mass_entries(system, cfg)
    return sp.csr_matrix((v, (r, c)), shape=(system.n_v, system.n_v))


def dense_mass_matrix(system, cfg: Configuration) -> FloatArray:
    """``M`` as a dense (n_v, n_v) matrix (``mass_entries``)."""
    M = np.zeros((system.n_v, system.n_v))
    r, c, v = mass_entries(system, cfg)
    np.add.at(M, (r, c), v)
    return M

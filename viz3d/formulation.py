"""Formulations: how accelerations come out of the constrained equations of motion.

A formulation has two hooks: ``solve(system, Q, rows, twist) -> (a, lam)`` with ``a`` shape
(nb + 1, 6), and ``post_step(system, state) -> state`` (identity unless it stabilizes between
steps). Registry: ``FORMULATIONS``; see docs/extending.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from viz3d.constraints import ConstraintRows, apply_jacobian, apply_jacobian_transpose, schur_solve
from viz3d.kinematics import Twist
from viz3d.stabilization import project_positions, project_velocities
from viz3d.system import State, System


def solve_augmented(system: System, Q, rows: ConstraintRows, gamma):
    """Solve ``[M C_v^T; C_v 0] [a; lam] = [Q; gamma]`` by the Schur complement.

    Returns ``a`` (nb + 1, 6) [m/s^2, rad/s^2] and ``lam`` (n_c,).
    """
    M_inv = system.bodies.M_inv
    a_free = np.einsum("bij,bj->bi", M_inv, Q)
    lam = schur_solve(system.joints, M_inv, rows.J, apply_jacobian(system.joints, rows.J, a_free) - gamma)
    CtL = apply_jacobian_transpose(system.joints, rows.J, lam, Q.shape[0])
    return a_free - np.einsum("bij,bj->bi", M_inv, CtL), lam


@dataclass(frozen=True)
class Index1:
    """The seed's augmented index-1 system, acceleration-level constraints only.

    Constraint drift (|C| and |C_v v|) grows unchecked: the honest baseline.
    """

    name: ClassVar[str] = "index1"

    def solve(self, system: System, Q, rows: ConstraintRows, twist: Twist):
        return solve_augmented(system, Q, rows, rows.gamma)

    def post_step(self, system: System, state: State) -> State:
        return state


@dataclass(frozen=True)
class Baumgarte(Index1):
    """Index-1 with Baumgarte stabilization: ``C_dd + 2 alpha C_d + beta^2 C = 0``.

    Attributes
    ----------
    alpha : float
        Damping rate [1/s].
    beta : float
        Natural frequency [rad/s].

    References
    ----------
    J. Baumgarte, Comput. Methods Appl. Mech. Eng. 1 (1972) 1-16.
    """

    name: ClassVar[str] = "baumgarte"
    alpha: float = 10.0
    beta: float = 10.0

    def solve(self, system, Q, rows, twist):
        C_d = apply_jacobian(system.joints, rows.J, _per_body_twist(twist))
        gamma = rows.gamma - 2.0 * self.alpha * C_d - self.beta**2 * rows.C
        return solve_augmented(system, Q, rows, gamma)


@dataclass(frozen=True)
class Projection(Index1):
    """Index-1 plus mass-orthogonal projection onto ``C = 0`` and ``C_v v = 0`` after each step.

    Attributes
    ----------
    tol : float
        Position tolerance of the Newton projection [m].
    """

    name: ClassVar[str] = "projection"
    tol: float = 1e-12

    def post_step(self, system, state):
        q, _ = project_positions(system, state.q, state.chart, tol=self.tol)
        return state.replace(q=q, v=project_velocities(system, q, state.v, state.chart))


def _per_body_twist(twist: Twist):
    return np.concatenate([twist.W_v, twist.B_omega], axis=1)


FORMULATIONS = {cls.name: cls for cls in (Index1, Baumgarte, Projection)}

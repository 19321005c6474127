"""Equations of motion: from a state to accelerations, reaction multipliers and energies.

The recipe (``accelerations``): body poses and twists -> applied and gyroscopic generalized
forces -> constraint rows (residual, Jacobian, gamma) -> the formulation solves the augmented
system ``[M C_v^T; C_v 0] [v_dot; lam] = [Q; gamma]``. Integrators see only ``vector_field``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.constraints import ConstraintRows, constraint_rows
from viz3d.kinematics import Pose, Twist, pose_from, twist_from
from viz3d.system import State, System


def body_state(system: System, q: FloatArray, v: FloatArray, chart: FloatArray) -> tuple[Pose, Twist]:
    """Poses and twists of all bodies (ground appended) from ``q`` (n_q,), ``v`` (n_v,)."""
    W_r, theta = system.split_q(q)
    pose = pose_from(W_r, system.rotation.matrix(theta, chart))
    W_v, B_omega = system.split_v(v)
    return pose, twist_from(W_v, B_omega, pose)


def generalized_forces(system: System, t: float, pose: Pose, twist: Twist) -> FloatArray:
    """``Q`` per body, shape (nb + 1, 6): ``[W_F, B_tau - B_omega x I B_omega]`` [N, N m].

    Forces are world vectors at the centre of mass; torques are about it, in body axes.
    """
    W_F = np.zeros_like(pose.W_r)
    W_tau = np.zeros_like(pose.W_r)
    for element in system.forces:
        F, tau = element.wrench(t, pose, twist)
        W_F += F
        W_tau += tau
    Q = np.zeros((W_F.shape[0], 6))
    Q[:, :3] = W_F
    Q[:, 3:] = np.einsum("bji,bj->bi", pose.R_WB, W_tau)  # R^T tau: body axes
    Q[:-1, 3:] -= system.bodies.gyroscopic(twist.B_omega[:-1])
    Q[-1] = 0.0  # ground
    return Q


@dataclass(frozen=True)
class Accelerations:
    """Result of the dynamics at one state.

    Attributes
    ----------
    v_dot : ndarray, shape (n_v,)
        ``[W_a, B_alpha]`` per body [m/s^2, rad/s^2].
    lam : ndarray, shape (n_c,)
        Multipliers; the constraint force on the bodies is ``-C_v^T lam`` [N].
    rows : ConstraintRows
    """

    v_dot: FloatArray
    lam: FloatArray
    rows: ConstraintRows


def accelerations(system: System, formulation, t: float, q: FloatArray, v: FloatArray,
                  chart: FloatArray) -> Accelerations:
    """Accelerations and multipliers at ``(t, q, v)`` (the physics recipe)."""
    pose, twist = body_state(system, q, v, chart)
    Q = generalized_forces(system, t, pose, twist)
    rows = constraint_rows(system.joints, pose, twist)
    a, lam = formulation.solve(system, Q, rows, twist)
    return Accelerations(a[:-1].reshape(-1), lam, rows)


def kinematic_rates(system: System, q: FloatArray, v: FloatArray) -> FloatArray:
    """``q_dot`` (n_q,) from the velocities: ``W_r_dot = W_v``, ``theta_dot = f(theta, B_omega)``."""
    _, theta = system.split_q(q)
    W_v, B_omega = system.split_v(v)
    return system.join_q(W_v, system.rotation.rates(theta, B_omega))


def retract(system: System, q: FloatArray, w: FloatArray, chart: FloatArray) -> FloatArray:
    """Positions moved by the velocity-space increment ``w`` (n_v,), in the same charts.

    Per body ``w = [dW_r (3) [m], B_dphi (3) [rad]]``: ``W_r + dW_r`` and ``R_WB @ exp(skew(B_dphi))``
    (the Lie-group update of ``R^3 x SO(3)`` that ``gen_alpha`` and ``ali3p`` advance positions by).
    """
    W_r, theta = system.split_q(q)
    dW_r, B_dphi = system.split_v(w)
    return system.join_q(W_r + dW_r, system.rotation.advance(theta, chart, B_dphi))


class VectorField:
    """``y_dot = f(t, y)`` with ``y = [q, v]``, for a fixed chart; what integrators see.

    Besides ``__call__`` it offers the ``retract`` hook of ``viz3d.integrators.base.Rhs``.

    Attributes
    ----------
    n_q : int
        Length of the position part of ``y`` (partitioned methods split there).
    n_evals : int
        Number of evaluations so far.
    """

    def __init__(self, system: System, formulation, chart: FloatArray):
        self.system, self.formulation, self.chart = system, formulation, chart
        self.n_q = system.n_q
        self.n_evals = 0

    def __call__(self, t: float, y: FloatArray) -> FloatArray:
        self.n_evals += 1
        q, v = y[: self.n_q], y[self.n_q:]
        acc = accelerations(self.system, self.formulation, t, q, v, self.chart)
        return np.concatenate([kinematic_rates(self.system, q, v), acc.v_dot])

    def retract(self, q: FloatArray, w: FloatArray) -> FloatArray:
        """``q`` moved by the velocity-space increment ``w`` (n_v,) [m, rad] (see ``retract``)."""
        return retract(self.system, q, w, self.chart)


def energies(system: System, state: State) -> tuple[float, float]:
    """Kinetic and potential energy [J] of a state (potential of all conservative elements)."""
    pose, twist = body_state(system, state.q, state.v, state.chart)
    T = system.bodies.kinetic_energy(twist.W_v[:-1], twist.B_omega[:-1])
    V = sum(e.potential_energy(state.t, pose) for e in system.forces)
    return T, float(V)

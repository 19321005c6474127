"""Random multibody systems and states for derivative and solver tests (seeded)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from viz3d.bodies import Bodies
from viz3d.constraints import build_layout
from viz3d.coordinates import EulerSwitching
from viz3d.forces import Gravity, SpringDamper
from viz3d.joints import BallJoint
from viz3d.kinematics import pose_from, twist_from
from viz3d.rotations import matrix_from_rotation_vector
from viz3d.system import State, System


def random_inertia(rng, n):
    """SPD inertia tensors with products of inertia that satisfy the triangle inequality."""
    p = rng.uniform(0.5, 1.0, (n, 3)) * 0.01
    p[:, 2] = np.minimum(p[:, 2], p[:, 0] + p[:, 1])
    Q = Rotation.random(n, random_state=rng.integers(1 << 31)).as_matrix()
    return np.einsum("nij,nj,nkj->nik", Q, p, Q)


def ball_joints(rng, pairs, names=None):
    pairs = np.asarray(pairs, dtype=int)
    names = names or tuple(f"j{i}" for i in range(len(pairs)))
    return BallJoint(tuple(names), pairs, rng.normal(scale=0.3, size=(len(pairs), 2, 3)))


def random_system(nb=4, seed=0, extra_pairs=((0, 2),), springs=True):
    """A chain 0-1-...-(nb-1) hung from ground plus ``extra_pairs`` joints, random inertia."""
    rng = np.random.default_rng(seed)
    names = tuple(f"b{i}" for i in range(nb))
    bodies = Bodies(names, rng.uniform(0.5, 2.0, nb), random_inertia(rng, nb))
    pairs = [(0, nb)] + [(i, i - 1) for i in range(1, nb)] + list(extra_pairs)
    joints = (ball_joints(rng, pairs),)
    forces = [Gravity(bodies.mass, np.array([0.0, 0.0, -9.81]))]
    if springs:
        sp = np.array([[0, nb], [nb - 1, 0], [1, 2 % nb]])
        forces.append(SpringDamper(("s0", "s1", "s2"), sp, rng.normal(scale=0.2, size=(3, 2, 3)),
                                   rng.uniform(10, 100, 3), np.zeros(3), rng.uniform(0.1, 0.5, 3)))
    return System(bodies, build_layout(joints, nb), tuple(forces), EulerSwitching())


def random_state(system, seed=1):
    """Random positions, orientations (through a random chart) and velocities."""
    rng = np.random.default_rng(seed)
    nb = system.n_bodies
    chart = Rotation.random(nb, random_state=seed).as_matrix()
    theta = np.column_stack([rng.uniform(-3, 3, nb), rng.uniform(0.7, 2.4, nb), rng.uniform(-3, 3, nb)])
    q = system.join_q(rng.normal(size=(nb, 3)), theta)
    return State(0.0, q, rng.normal(size=6 * nb), chart)


def pose_twist(system, state):
    W_r, theta = system.split_q(state.q)
    pose = pose_from(W_r, system.rotation.matrix(theta, state.chart))
    W_v, B_omega = system.split_v(state.v)
    return pose, twist_from(W_v, B_omega, pose)


def moved_pose(pose, dx, eps):
    """Pose displaced by ``eps * dx`` (dx per body [dW_r, B_dphi], shape (nb, 6))."""
    W_r = pose.W_r[:-1] + eps * dx[:, :3]
    R = pose.R_WB[:-1] @ matrix_from_rotation_vector(eps * dx[:, 3:])
    return pose_from(W_r, R)


def pose_along(pose, twist, acc, t):
    """Pose at time ``t`` under constant accelerations ``acc`` (nb, 6), to second order."""
    v = np.concatenate([twist.W_v[:-1], twist.B_omega[:-1]], axis=1)
    W_r = pose.W_r[:-1] + t * v[:, :3] + 0.5 * t * t * acc[:, :3]
    R = pose.R_WB[:-1] @ matrix_from_rotation_vector(t * v[:, 3:] + 0.5 * t * t * acc[:, 3:])
    return pose_from(W_r, R)

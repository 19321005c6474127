"""Joint Jacobians and gamma against finite differences, for every registered joint type."""

import numpy as np
import pytest

from viz3d.constraints import apply_jacobian, constraint_residual, constraint_rows
from viz3d.joints import JOINTS
from viz3d.kinematics import twist_from

from systems import moved_pose, pose_along, pose_twist, random_state, random_system

#: Central differences of step h err by h^2 |f'''| / 6 (truncation) + eps |f| / h (round-off). Jacobian:
#: h = 1e-6 m or rad on O(1) residuals: ~1e-12 + 2e-10; JAC_TOL [m] is 50x the round-off.
EPS = 1e-6
JAC_TOL = 1e-8
#: gamma (second derivative of C along a motion, via a difference of C_dot): h = 1e-4 s balances the two,
#: ~1e-9 + 2e-12 relative to the largest term; GAMMA_TOL is 500x that.
GAMMA_EPS = 1e-4
GAMMA_TOL = 1e-6

#: How the tests build a system holding each registered joint type. A new joint type must be
#: added here, or ``test_every_registered_joint_type_is_covered`` fails.
SYSTEMS = {"ball": lambda seed: random_system(nb=4, seed=seed)}


def test_every_registered_joint_type_is_covered():
    assert set(JOINTS) == set(SYSTEMS)


@pytest.mark.parametrize("kind", sorted(JOINTS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_jacobian_matches_finite_differences(kind, seed):
    system = SYSTEMS[kind](seed)
    pose, twist = pose_twist(system, random_state(system, seed))
    J = constraint_rows(system.joints, pose, twist).J
    rng = np.random.default_rng(10 + seed)
    for _ in range(3):
        dx = rng.normal(size=(system.n_bodies, 6))
        fd = (constraint_residual(system.joints, moved_pose(pose, dx, EPS))
              - constraint_residual(system.joints, moved_pose(pose, dx, -EPS))) / (2 * EPS)
        dx_g = np.concatenate([dx, np.zeros((1, 6))])
        np.testing.assert_allclose(apply_jacobian(system.joints, J, dx_g), fd, atol=JAC_TOL, err_msg="mismatch: C_v")


@pytest.mark.parametrize("kind", sorted(JOINTS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gamma_matches_second_time_derivative(kind, seed):
    """d/dt (C_v v) along a motion with accelerations a equals C_v a - gamma."""
    system = SYSTEMS[kind](seed)
    pose, twist = pose_twist(system, random_state(system, seed))
    acc = np.random.default_rng(20 + seed).normal(size=(system.n_bodies, 6))
    rows = constraint_rows(system.joints, pose, twist)

    def C_dot(t):
        p = pose_along(pose, twist, acc, t)
        v = np.concatenate([twist.W_v[:-1], twist.B_omega[:-1]], axis=1) + t * acc
        tw = twist_from(v[:, :3], v[:, 3:], p)
        J = constraint_rows(system.joints, p, tw).J
        return apply_jacobian(system.joints, J, np.concatenate([v, np.zeros((1, 6))]))

    fd = (C_dot(GAMMA_EPS) - C_dot(-GAMMA_EPS)) / (2 * GAMMA_EPS)
    acc_g = np.concatenate([acc, np.zeros((1, 6))])
    expected = apply_jacobian(system.joints, rows.J, acc_g) - rows.gamma
    np.testing.assert_allclose(fd, expected, atol=GAMMA_TOL * np.abs(expected).max(), err_msg="mismatch: gamma")


def test_reaction_force_is_minus_lambda_for_ball_joints():
    system = random_system(nb=3, seed=4)
    pose, twist = pose_twist(system, random_state(system, 4))
    js = system.joints.joints[0]
    lam = np.random.default_rng(0).normal(size=(js.n_joints, 3))
    J = js.jacobian(pose)
    np.testing.assert_allclose(js.reaction_force(J, lam), -lam)

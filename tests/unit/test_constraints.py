"""The structured (Schur, dense or banded) solve equals a dense solve of the full augmented
system; redundant joints are detected and named."""

import numpy as np
import pytest

from viz3d.bodies import Bodies
from viz3d.constraints import SingularConstraintError, build_layout, constraint_rows
from viz3d.coordinates import EulerSwitching
from viz3d.diagnosis import redundant_joints
from viz3d.dynamics import generalized_forces
from viz3d.formulation import Index1
from viz3d.system import System

from systems import ball_joints, pose_twist, random_state, random_system

#: Two backward-stable solves of the same system differ by at most ~ p(n) eps cond(A) |x| (Higham,
#: Accuracy and Stability of Numerical Algorithms, 2nd ed., thm. 7.2); p(n) taken as 10 (seen <= 0.5).
SOLVE_SAFETY = 10.0


def dense_augmented(system, rows):
    """[M C^T; C 0] as a dense matrix (test oracle)."""
    nb, n_c = system.n_bodies, system.n_c
    M = np.zeros((6 * nb, 6 * nb))
    for b in range(nb):
        M[6 * b:6 * b + 3, 6 * b:6 * b + 3] = system.bodies.mass[b] * np.eye(3)
        M[6 * b + 3:6 * b + 6, 6 * b + 3:6 * b + 6] = system.bodies.inertia[b]
    C = np.zeros((n_c, 6 * nb))
    for r in range(n_c):
        for s in range(2):
            b = system.joints.row_body[r, s]
            if b < nb:
                C[r, 6 * b:6 * b + 6] += rows.J[r, s]
    return np.block([[M, C.T], [C, np.zeros((n_c, n_c))]])


@pytest.mark.parametrize("nb,extra", [(3, ((0, 2),)), (12, ()), (30, ((5, 17),))])
def test_structured_solve_equals_dense_augmented_solve(nb, extra):
    system = random_system(nb=nb, seed=nb, extra_pairs=extra)
    state = random_state(system, nb)
    pose, twist = pose_twist(system, state)
    Q = generalized_forces(system, 0.0, pose, twist)
    rows = constraint_rows(system.joints, pose, twist)
    a, lam = Index1().solve(system, Q, rows, twist)
    rhs = np.concatenate([Q[:-1].reshape(-1), rows.gamma])
    A = dense_augmented(system, rows)
    sol = np.linalg.solve(A, rhs)
    tol = SOLVE_SAFETY * np.finfo(float).eps * np.linalg.cond(A, np.inf) * np.abs(sol).max()
    np.testing.assert_allclose(a[:-1].reshape(-1), sol[: 6 * nb], rtol=0, atol=tol, err_msg="mismatch: v_dot")
    np.testing.assert_allclose(lam, sol[6 * nb:], rtol=0, atol=tol, err_msg="mismatch: lam")


def test_chain_uses_banded_solver_with_block_tridiagonal_bandwidth():
    system = random_system(nb=40, seed=1, extra_pairs=(), springs=False)
    assert system.joints.banded
    assert system.joints.kd <= 5


def test_shuffled_chain_is_reordered_to_a_narrow_band():
    rng = np.random.default_rng(0)
    nb = 30
    pairs = np.array([(0, nb)] + [(i, i - 1) for i in range(1, nb)])
    perm = rng.permutation(nb)            # joints listed in random order
    layout = build_layout((ball_joints(rng, pairs[perm]),), nb)
    assert layout.banded and layout.kd <= 5


def test_redundant_joints_raise_and_are_named():
    rng = np.random.default_rng(2)
    bodies = Bodies(("a", "b"), np.ones(2), np.stack([np.eye(3) * 0.01] * 2))
    js = ball_joints(rng, [(0, 2), (1, 0), (1, 0)], names=("ground_a", "ab", "ab_again"))
    js = type(js)(js.names, js.body, np.concatenate([js.B_s[:2], js.B_s[1:2]]))  # same point twice
    system = System(bodies, build_layout((js,), 2), (), EulerSwitching())
    state = random_state(system, 3)
    pose, twist = pose_twist(system, state)
    rows = constraint_rows(system.joints, pose, twist)
    with pytest.raises(SingularConstraintError):
        Index1().solve(system, generalized_forces(system, 0.0, pose, twist), rows, twist)
    assert set(redundant_joints(system, rows.J)) == {"ab", "ab_again"}

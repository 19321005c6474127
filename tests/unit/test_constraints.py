"""The structured (Schur, dense or banded) solve equals a dense solve of the full augmented
system; redundant joints are detected and named."""

import numpy as np
import pytest

from viz3d.bodies import Bodies
from viz3d.constraints import SingularConstraintError, build_layout, constraint_rows
from viz3d.coordinates import EulerSwitching
from viz3d.diagnosis import redundant_joints
from viz3d.dynamics import flat_velocity, generalized_forces, system_mass
from viz3d.formulation import Index1
from viz3d.mass import dense_mass_matrix
from viz3d.constraints import dense_jacobian
from viz3d.system import System

from systems import ball_joints, configuration, random_state, random_system

#: Two backward-stable solves of the same system differ by at most ~ p(n) eps cond(A) |x| (Higham,
#: Accuracy and Stability of Numerical Algorithms, 2nd ed., thm. 7.2); p(n) taken as 10 (seen <= 0.5).
SOLVE_SAFETY = 10.0


def dense_augmented(system, cfg, rows):
    """[M C^T; C 0] as a dense matrix (test oracle; the dense C assembled entry by entry here)."""
    n_v, n_c = system.n_v, system.n_c
    M = dense_mass_matrix(system, cfg)
    C = np.zeros((n_c, n_v))
    slot = {int(b): k for k, b in enumerate(system.frame_body)}
    for r in range(n_c):
        for s in range(2):
            b = system.joints.row_body[r, s]
            if b in slot:
                C[r, 6 * slot[b]:6 * slot[b] + 6] += rows.J[r, s]
        C[r, 6 * system.n_frames:] += rows.Je[r].sum(axis=0)
    return np.block([[M, C.T], [C, np.zeros((n_c, n_c))]])


@pytest.mark.parametrize("nb,extra,flexible", [(3, ((0, 2),), False), (12, (), False), (30, ((5, 17),), False),
                                               (3, ((0, 2),), True), (30, ((5, 17),), True)])
def test_structured_solve_equals_dense_augmented_solve(nb, extra, flexible):
    system = random_system(nb=nb, seed=nb, extra_pairs=extra, flexible=flexible)
    state = random_state(system, nb)
    cfg = configuration(system, state)
    Q = generalized_forces(system, cfg)
    rows = constraint_rows(system.joints, cfg)
    (a, a_e), lam = Index1().solve(system, system_mass(system, cfg), Q, rows, cfg)
    rhs = np.concatenate([flat_velocity(system, *Q), rows.gamma])
    A = dense_augmented(system, cfg, rows)
    np.testing.assert_array_equal(A[system.n_v:, :system.n_v], dense_jacobian(system, rows.J, rows.Je))
    sol = np.linalg.solve(A, rhs)
    tol = SOLVE_SAFETY * np.finfo(float).eps * np.linalg.cond(A, np.inf) * np.abs(sol).max()
    np.testing.assert_allclose(flat_velocity(system, a, a_e), sol[: system.n_v], rtol=0, atol=tol, err_msg="mismatch: v_dot")
    np.testing.assert_allclose(lam, sol[system.n_v:], rtol=0, atol=tol, err_msg="mismatch: lam")


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


def scipy_rcm(r_idx, k_idx, n):
    """The oracle: scipy's reverse Cuthill-McKee of the symmetric graph with edges (r_idx, k_idx)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    graph = coo_matrix((np.ones(len(r_idx)), (r_idx, k_idx)), shape=(n, n)).tocsr()
    return np.asarray(reverse_cuthill_mckee(graph, symmetric_mode=True), dtype=int)


@pytest.mark.parametrize("seed", range(40))
def test_row_order_is_scipys_reverse_cuthill_mckee(seed):
    """On random symmetric graphs (disconnected parts, repeated edges, self-loops on some rows,
    many ties in degree, up to 400 rows) the own ordering is scipy's, tie for tie."""
    from viz3d.constraints import _bandwidth_order

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    m = int(rng.integers(0, 3 * n))
    a, b = rng.integers(0, n, m), rng.integers(0, n, m)
    loops = np.nonzero(rng.random(n) < rng.random())[0]
    r, k = np.concatenate([a, b, loops]), np.concatenate([b, a, loops])
    np.testing.assert_array_equal(_bandwidth_order(r, k, n), scipy_rcm(r, k, n))


@pytest.mark.parametrize("nb,extra", [(3, ((0, 2),)), (12, ()), (40, ()), (30, ((5, 17), (2, 25)))])
def test_layout_orders_its_rows_as_scipys_reverse_cuthill_mckee(nb, extra):
    from viz3d.constraints import _shared_body_pairs

    system = random_system(nb=nb, seed=nb, extra_pairs=extra)
    layout = system.joints
    r, _, k, _ = _shared_body_pairs(layout.row_body, system.n_bodies)
    np.testing.assert_array_equal(layout.perm, scipy_rcm(r, k, layout.n_rows))


def test_redundant_joints_raise_and_are_named():
    rng = np.random.default_rng(2)
    bodies = Bodies(("a", "b"), np.ones(2), np.stack([np.eye(3) * 0.01] * 2))
    js = ball_joints(rng, [(0, 2), (1, 0), (1, 0)], names=("ground_a", "ab", "ab_again"))
    js = type(js)(js.names, js.body, np.concatenate([js.B_s[:2], js.B_s[1:2]]))  # same point twice
    system = System(bodies, build_layout((js,), 2), (), EulerSwitching())
    state = random_state(system, 3)
    cfg = configuration(system, state)
    rows = constraint_rows(system.joints, cfg)
    with pytest.raises(SingularConstraintError):
        Index1().solve(system, system_mass(system, cfg), generalized_forces(system, cfg), rows, cfg)
    assert set(redundant_joints(system, rows.J, rows.Je)) == {"ab", "ab_again"}


def test_rows_coupled_only_through_a_flexible_body_solve_like_the_dense_system():
    """A flexible bar pinned to ground: every coupling of the Schur complement goes through the
    bar's whole block (none through a rigid body; a storage once built from integer counts)."""
    from viz3d.bodies import FlexibleBody
    from viz3d.points import body_points

    from systems import flexible_bars

    rng = np.random.default_rng(7)
    bar = flexible_bars(rng)[0][0]
    bodies = Bodies(("bar",), np.array([bar.mass]), bar.J0[None], (FlexibleBody(0, bar, True, np.zeros(3), np.eye(3)),))
    pairs = np.array([[0, 1], [0, 1]])
    B_s = np.zeros((2, 2, 3))
    sides = (body_points(bodies, pairs[:, 0], B_s[:, 0], np.array([0.0, 0.8])),
             body_points(bodies, pairs[:, 1], np.array([[0.0, 0.0, 0.0], [0.8, 0.0, 0.0]]), np.zeros(2)))
    from viz3d.joints import BallJoint

    js = BallJoint(("pin", "tip"), pairs, B_s, sides)
    system = System(bodies, build_layout((js,), bodies), (), EulerSwitching())
    assert not len(system.joints.pair_row) and system.joints.flex_groups
    state = random_state(system, 2)
    cfg = configuration(system, state)
    Q = generalized_forces(system, cfg)
    rows = constraint_rows(system.joints, cfg)
    (a, a_e), lam = Index1().solve(system, system_mass(system, cfg), Q, rows, cfg)
    A = dense_augmented(system, cfg, rows)
    sol = np.linalg.solve(A, np.concatenate([flat_velocity(system, *Q), rows.gamma]))
    tol = SOLVE_SAFETY * np.finfo(float).eps * np.linalg.cond(A, np.inf) * np.abs(sol).max()
    np.testing.assert_allclose(lam, sol[system.n_v:], rtol=0, atol=tol, err_msg="mismatch: lam")

"""Rotation conversions against scipy's Rotation, finite differences and identities."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from viz3d.rotations import (
    body_rate_matrix_from_euler,
    cross,
    euler_from_matrix,
    euler_rates_from_body_omega,
    matrix_from_euler,
    matrix_from_quat,
    matrix_from_rotation_vector,
    quat_from_matrix,
    skew,
)

#: Matrices of O(1) entries from a few trig products and sums: errors of a few eps; 1e-13 is ~450 eps.
TOL = 1e-13
#: Central differences: truncation h^2 |f'''| / 6 ~ 1e-12, round-off eps |f| / h ~ 2e-10 for O(1) f;
#: FD_TOL is 50x the round-off.
FD_STEP = 1e-6
FD_TOL = 1e-8


@pytest.fixture
def angles():
    rng = np.random.default_rng(1)
    a = rng.uniform(-np.pi, np.pi, (200, 3))
    a[:, 1] = rng.uniform(0.0, np.pi, 200)
    return a


def test_matrix_matches_scipy_intrinsic_zxz(angles):
    R = matrix_from_euler(angles)
    assert np.abs(R - Rotation.from_euler("ZXZ", angles).as_matrix()).max() < TOL


def test_matrix_is_proper_orthonormal(angles):
    R = matrix_from_euler(angles)
    assert np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)).max() < TOL
    assert np.abs(np.linalg.det(R) - 1.0).max() < TOL


def test_euler_from_matrix_matches_scipy_away_from_gimbal_lock(angles):
    R = matrix_from_euler(angles)
    ours = euler_from_matrix(R)
    theirs = Rotation.from_matrix(R).as_euler("ZXZ")
    assert np.abs(np.angle(np.exp(1j * (ours - theirs)))).max() < 1e-9


@pytest.mark.parametrize("theta", [0.0, np.pi, 1e-14, np.pi - 1e-14])
def test_euler_from_matrix_round_trips_at_gimbal_lock(theta):
    # At theta = 0 or pi only psi +- phi is defined: compare matrices, not angles.
    for psi, phi in [(0.3, -1.2), (2.9, 0.4), (-3.0, 3.0)]:
        R = matrix_from_euler([psi, theta, phi])
        back = euler_from_matrix(R)
        assert np.abs(matrix_from_euler(back) - R).max() < 1e-12
        assert back[2] == 0.0 or abs(np.sin(theta)) > 1e-12


def test_body_rate_matrix_gives_angular_velocity_of_finite_differences(angles):
    rng = np.random.default_rng(2)
    rates = rng.normal(size=angles.shape)
    keep = np.abs(np.sin(angles[:, 1])) > 0.05
    a, ad = angles[keep], rates[keep]
    R = matrix_from_euler(a)
    R_dot = (matrix_from_euler(a + FD_STEP * ad) - matrix_from_euler(a - FD_STEP * ad)) / (2 * FD_STEP)
    omega_skew = np.swapaxes(R, -1, -2) @ R_dot          # R^T R_dot = skew(B_omega)
    B_omega = np.einsum("nij,nj->ni", body_rate_matrix_from_euler(a), ad)
    assert np.abs(omega_skew - skew(B_omega)).max() < FD_TOL


def test_rate_inverse_and_determinant(angles):
    H = body_rate_matrix_from_euler(angles)
    assert np.allclose(np.linalg.det(H), -np.sin(angles[:, 1]), atol=1e-14)
    keep = np.abs(np.sin(angles[:, 1])) > 1e-3
    w = np.random.default_rng(3).normal(size=(keep.sum(), 3))
    rates = euler_rates_from_body_omega(angles[keep], w)
    assert np.abs(np.einsum("nij,nj->ni", H[keep], rates) - w).max() < 1e-10


def test_quaternions_scalar_first_match_scipy(angles):
    R = matrix_from_euler(angles)
    q = quat_from_matrix(R)
    ref = Rotation.from_matrix(R).as_quat(scalar_first=True)
    ref *= np.where(ref[:, :1] < 0, -1.0, 1.0)
    assert np.abs(q - ref).max() < 1e-12
    assert np.abs(matrix_from_quat(q) - R).max() < TOL * 10


def test_rotation_vector_matches_scipy():
    rng = np.random.default_rng(4)
    phi = np.concatenate([rng.normal(size=(50, 3)), 1e-10 * rng.normal(size=(5, 3)), np.zeros((1, 3))])
    assert np.abs(matrix_from_rotation_vector(phi) - Rotation.from_rotvec(phi).as_matrix()).max() < 1e-14


def test_cross_and_skew_match_numpy():
    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    assert np.allclose(cross(a, b), np.cross(a, b), atol=1e-15)
    assert np.allclose(np.einsum("nij,nj->ni", skew(a), b), np.cross(a, b), atol=1e-15)


def test_euler_from_matrix_of_a_batch_is_that_of_each_rotation():
    # Rotations at gimbal lock and away from it in one call: each row as the rotation alone gives it.
    angles = np.array([[0.3, 1.1, -0.7], [0.3, 0.0, -1.2], [2.9, np.pi, 0.4], [-3.0, 2.0, 3.0]])
    R = matrix_from_euler(angles)
    batch = euler_from_matrix(R)
    assert np.array_equal(batch, np.array([euler_from_matrix(r) for r in R]))
    assert np.array_equal(batch[[0, 3]], euler_from_matrix(R[[0, 3]]))

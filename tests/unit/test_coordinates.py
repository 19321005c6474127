"""Rotation coordinates of every registered parametrization against scipy's ``Rotation``: the
kinematic equation, the exact finite rotation ``advance`` used by Lie-group methods, and the unit
norm of Euler parameters."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from viz3d.coordinates import ROTATIONS
from viz3d.rotations import skew

#: Rotation matrices built from coordinates agree with scipy to round-off.
MATRIX_TOL = 1e-13
#: Central differences of step EPS: truncation EPS^2 ~ 1e-12, round-off 1e-16 / EPS ~ 1e-10.
EPS = 1e-6
RATE_TOL = 1e-8
NB = 6


def _coordinates(rotation, seed=0):
    """Random orientations as coordinates and charts of ``rotation`` (Euler nutation kept away
    from 0 and pi, where the plain angles are singular)."""
    rng = np.random.default_rng(seed)
    R = Rotation.from_euler("ZXZ", np.column_stack([rng.uniform(-3, 3, NB), rng.uniform(0.6, 2.5, NB),
                                                    rng.uniform(-3, 3, NB)])).as_matrix()
    theta, chart = rotation.from_matrix(R)
    return R, theta, chart, rng


@pytest.mark.parametrize("name", sorted(ROTATIONS))
def test_from_matrix_round_trips(name):
    rotation = ROTATIONS[name]()
    R, theta, chart, _ = _coordinates(rotation)
    np.testing.assert_allclose(rotation.matrix(theta, chart), R, atol=MATRIX_TOL)


@pytest.mark.parametrize("name", sorted(ROTATIONS))
def test_rates_turn_the_body_about_its_own_axes(name):
    """``R(theta + eps theta_dot)`` moves like ``R exp(eps skew(B_omega))``: ``R_dot = R skew(B_omega)``."""
    rotation = ROTATIONS[name]()
    R, theta, chart, rng = _coordinates(rotation, seed=1)
    B_omega = rng.normal(size=(NB, 3))
    rates = rotation.rates(theta, B_omega)
    R_dot = (rotation.matrix(theta + EPS * rates, chart) - rotation.matrix(theta - EPS * rates, chart)) / (2 * EPS)
    np.testing.assert_allclose(R_dot, R @ skew(B_omega), atol=RATE_TOL)


@pytest.mark.parametrize("name", sorted(ROTATIONS))
def test_advance_is_the_exact_finite_rotation(name):
    rotation = ROTATIONS[name]()
    R, theta, chart, rng = _coordinates(rotation, seed=2)
    B_dphi = rng.normal(scale=0.4, size=(NB, 3))
    moved = rotation.advance(theta, chart, B_dphi)
    np.testing.assert_allclose(rotation.matrix(moved, chart), R @ Rotation.from_rotvec(B_dphi).as_matrix(), atol=MATRIX_TOL)


def test_quaternions_are_scipys_scalar_first_euler_parameters():
    rotation = ROTATIONS["quaternion"]()
    R, p, chart, rng = _coordinates(rotation, seed=3)
    ref = Rotation.from_matrix(R).as_quat(scalar_first=True)
    np.testing.assert_allclose(np.abs(np.sum(p * ref, axis=1)), 1.0, atol=MATRIX_TOL)   # p = +-ref
    np.testing.assert_array_equal(chart, np.broadcast_to(np.eye(3), (NB, 3, 3)))
    # normalize projects a drifted p back onto |p| = 1 without turning the body
    drifted = p * rng.uniform(0.9, 1.1, (NB, 1))
    np.testing.assert_allclose(np.linalg.norm(rotation.normalize(drifted), axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(rotation.matrix(rotation.normalize(drifted), chart), R, atol=MATRIX_TOL)
    # the kinematic equation keeps |p|: p . p_dot = 0
    np.testing.assert_allclose(np.sum(p * rotation.rates(p, rng.normal(size=(NB, 3))), axis=1), 0.0, atol=1e-15)

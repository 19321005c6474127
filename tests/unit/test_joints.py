"""Joint Jacobians and gamma against finite differences, for every registered joint type."""

import numpy as np
import pytest

from viz3d.constraints import apply_jacobian, constraint_residual, constraint_rows
from viz3d.dynamics import split_velocity
from viz3d.joints import JOINTS

from systems import along, configuration, drive_set, moved, random_state, random_system

#: Central differences of step h err by h^2 |f'''| / 6 (truncation) + eps |f| / h (round-off). Jacobian:
#: h = 1e-6 m or rad on O(1) residuals: ~1e-12 + 2e-10; JAC_TOL [m] is 50x the round-off.
EPS = 1e-6
JAC_TOL = 1e-8
#: gamma (second derivative of C along a motion, via a difference of C_dot): h = 1e-4 s balances the two,
#: ~1e-9 + 2e-12 relative to the largest term; GAMMA_TOL is 500x that.
GAMMA_EPS = 1e-4
GAMMA_TOL = 1e-6

#: How the tests build a system holding each registered joint type (also on sections of flexible
#: bars). A new joint type must be added here, or ``test_every_registered_joint_type_is_covered`` fails.
SYSTEMS = {kind: (lambda seed, flexible, kind=kind: random_system(nb=4, seed=seed, flexible=flexible, kinds=(kind,),
                                                                  framed_on_flexible=flexible))
           for kind in ("ball", "revolute", "universal", "prismatic", "cylindrical", "fixed")}


def _C_v(system, rows, x):
    """``C_v @ x`` for ``x`` in the order of ``v`` (n_v,)."""
    frame, elastic = split_velocity(system, x)
    return apply_jacobian(system.joints, rows.J, frame, rows.Je, elastic)


def test_every_registered_joint_type_is_covered():
    assert set(JOINTS) == set(SYSTEMS)


def _velocity_scales(system):
    """Random increments of order 1 on frames and of about 1 cm of deflection on elastic coordinates."""
    from systems import _mode_scale

    parts = [np.ones(6 * system.n_frames)] + [_mode_scale(fb) for fb in system.bodies.flexible]
    return np.concatenate(parts)


@pytest.mark.parametrize("flexible", [False, True])
@pytest.mark.parametrize("kind", sorted(JOINTS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_jacobian_matches_finite_differences(kind, seed, flexible):
    system = SYSTEMS[kind](seed, flexible)
    state = random_state(system, seed)
    rows = constraint_rows(system.joints, configuration(system, state))
    rng = np.random.default_rng(10 + seed)
    for _ in range(3):
        dx = rng.normal(size=system.n_v) * _velocity_scales(system)
        fd = (constraint_residual(system.joints, moved(system, state, dx, EPS))
              - constraint_residual(system.joints, moved(system, state, dx, -EPS))) / (2 * EPS)
        np.testing.assert_allclose(_C_v(system, rows, dx), fd, atol=JAC_TOL, err_msg="mismatch: C_v")


@pytest.mark.parametrize("flexible", [False, True])
@pytest.mark.parametrize("kind", sorted(JOINTS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gamma_matches_second_time_derivative(kind, seed, flexible):
    """d/dt (C_v v) along a motion with accelerations a equals C_v a - gamma."""
    system = SYSTEMS[kind](seed, flexible)
    state = random_state(system, seed)
    acc = np.random.default_rng(20 + seed).normal(size=system.n_v) * _velocity_scales(system)
    rows = constraint_rows(system.joints, configuration(system, state))

    def C_dot(t):
        r = constraint_rows(system.joints, along(system, state, acc, t))
        return _C_v(system, r, state.v + t * acc)

    fd = (C_dot(GAMMA_EPS) - C_dot(-GAMMA_EPS)) / (2 * GAMMA_EPS)
    expected = _C_v(system, rows, acc) - rows.gamma
    np.testing.assert_allclose(fd, expected, atol=GAMMA_TOL * np.abs(expected).max(), err_msg="mismatch: gamma")


def test_reaction_force_is_minus_lambda_for_ball_joints():
    system = random_system(nb=3, seed=4)
    js = system.joints.joints[0]
    lam = np.random.default_rng(0).normal(size=(js.n_joints, 3))
    J, _ = js.jacobian(configuration(system, random_state(system, 4)))
    np.testing.assert_allclose(js.reaction_force(J, lam), -lam)


def _driven_system(seed, flexible=False):
    """Drives on every coordinate kind; with ``flexible``, the driven joints have sides on sections of
    flexible bars (``random_system(framed_on_flexible=True)``: its last joint of each set is one)."""
    from viz3d.constraints import build_layout
    from viz3d.system import System

    base = random_system(nb=8, seed=seed, kinds=("revolute", "prismatic", "cylindrical", "universal"),
                         flexible=flexible, framed_on_flexible=flexible)
    drives = drive_set(base, seed)
    codes = {js.FREE[c][1] for js, c in zip(drives.joints, drives.free)}
    assert codes == {0, 1, 2, 3} and set(drives.velocity) == {0, 1}  # every coordinate kind, both profile modes
    if flexible:
        assert all(js.on_flexible for js in drives.joints)
    return System(base.bodies, build_layout(base.joints.joints + (drives,), base.bodies), base.forces, base.rotation)


@pytest.mark.parametrize("flexible", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_drive_rows_match_finite_differences_in_time_and_state(seed, flexible):
    """``C_dot = C_v v + C_t`` and ``d/dt (C_v v + C_t) = C_v a - gamma`` along a motion through time
    (the profiles move with it): central differences as the tests above. The drives are the last rows."""
    system = _driven_system(seed, flexible)
    state = random_state(system, seed).replace(t=0.05 + 0.1 * seed)
    acc = np.random.default_rng(30 + seed).normal(size=system.n_v) * _velocity_scales(system)
    rows = constraint_rows(system.joints, configuration(system, state))
    k = len(system.joints.joints[-1].names)
    assert rows.C_t is not None and np.all(rows.C_t[:-k] == 0) and np.any(rows.C_t[-k:] != 0)
    C = lambda t: constraint_rows(system.joints, along(system, state.replace(v=state.v), 0 * acc, t)).C  # noqa: E731
    fd = (C(EPS) - C(-EPS)) / (2 * EPS)
    np.testing.assert_allclose(_C_v(system, rows, state.v) + rows.C_t, fd, atol=JAC_TOL * (1 + np.abs(fd).max()))

    def C_dot(t):
        r = constraint_rows(system.joints, along(system, state, acc, t))
        return _C_v(system, r, state.v + t * acc) + r.C_t

    fd2 = (C_dot(GAMMA_EPS) - C_dot(-GAMMA_EPS)) / (2 * GAMMA_EPS)
    expected = _C_v(system, rows, acc) - rows.gamma
    np.testing.assert_allclose(fd2, expected, atol=GAMMA_TOL * np.abs(expected).max())

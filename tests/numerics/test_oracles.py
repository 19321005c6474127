"""Trajectories against references nobody here wrote: scipy DOP853 at rtol 1e-11 on an
independent quaternion formulation, Jacobi elliptic closed forms, the compound-pendulum period,
statics."""

import numpy as np
import pytest

import viz3d

from conftest import SCENES
from references import fixed_point_body, torque_free_omega

#: RK4 is order 4: halving dt divides its error by 2^4, within this many powers of 2 (the next term of
#: the error expansion is O(h) relative; a lost order is off by >= 1).
ORDER_TOL = 0.4
#: Runs at dt and dt/2 give Richardson's estimate of the dt run's error, (16/15) |y_dt - y_dt/2|. The
#: distance to the independent reference must equal it within this fraction: what is left is the next term
#: of the error expansion, O(h) relative (0.1-1 % seen), and the reference's error; a modelling difference
#: (a wrong term gives ~1e-2) is not.
RICHARDSON_TOL = 0.1
#: Bound on the RK4 error of the top through the vertical, dt = 5e-4, 3 s [m] (one run, no Richardson
#: estimate: its reference costs 20 s). A truncation error [5.4e-7 m, 2026-11-21], falling 16x per halving
#: of dt, so reproduced to several digits on any machine (round-off over 6000 steps < 1e-12 m); the 3x
#: flags a change of the error constant, a wrong term gives ~1e-2.
TTV_POS_TOL = 1.5e-6


def _fixed_point_reference(traj, pivot_local, g=(0.0, 0.0, -9.81)):
    c_B = -np.asarray(pivot_local)
    return fixed_point_body(traj.inertia_body[0], traj.mass[0], c_B, g, traj.rotation[0, 0], traj.omega[0, 0], traj.t)


def _compare_top(traj, pivot_local):
    R_ref, w_ref, rG_ref = _fixed_point_reference(traj, pivot_local)
    pos_err = np.abs(traj.position[:, 0] - rG_ref).max()
    rot_err = np.abs(traj.rotation[:, 0] - R_ref).max()
    return pos_err, rot_err, R_ref


def _richardson_rk4(t_coarse, y_coarse, t_fine, y_fine):
    """(16/15) max |y_dt - y_dt/2| at the coarse run's output times: RK4's estimate of the dt run's error."""
    common = np.isin(np.round(t_fine, 9), np.round(t_coarse, 9))
    assert common.sum() == len(t_coarse)
    return 16 / 15 * np.abs(y_coarse - y_fine[common]).max()


@pytest.mark.parametrize("rotation", ["euler_switching", "quaternion"])
def test_heavy_top_matches_quaternion_reference_and_converges_at_fourth_order(rotation):
    """Both regular parametrizations, in the compiled kernel."""
    runs, errors = [], []
    for dt in (1e-3, 5e-4):
        traj = viz3d.simulate(SCENES / "heavy_top.toml", [f"sim.rotation={rotation}"], t_end=2.0, dt=dt)
        assert traj.ok, traj.status
        assert traj.scene["run"]["kernel"] == "compiled kernel"
        runs.append(traj)
        errors.append(_compare_top(traj, [0.0, 0.0, -0.15])[:2])
    for i, field in enumerate(("position", "rotation")):
        estimate = _richardson_rk4(runs[0].t, getattr(runs[0], field)[:, 0], runs[1].t, getattr(runs[1], field)[:, 0])
        assert abs(errors[0][i] / estimate - 1) < RICHARDSON_TOL, (field, errors[0][i], estimate)
    order = np.log2(errors[0][0] / errors[1][0])
    assert abs(order - 4) < ORDER_TOL, f"halving dt divided the error by 2^{order:.2f}, expected 2^4 (RK4)"


def _vertical_passes(R, deg=1.0):
    """Local minima of the world nutation (angle of the body z axis from world Z) below ``deg``."""
    theta = np.degrees(np.arccos(np.clip(R[:, 2, 2], -1, 1)))
    i = np.flatnonzero((theta[1:-1] < theta[:-2]) & (theta[1:-1] <= theta[2:])) + 1
    return theta[i][theta[i] < deg]


@pytest.mark.parametrize("rotation", ["euler_switching", "quaternion"])
def test_top_through_vertical_matches_reference_across_many_passes(rotation):
    """Both regular parametrizations: re-charted Euler angles and Euler parameters (measured
    4.0e-7 m with quaternions, 2026-11-21); plain angles fail (next test)."""
    traj = viz3d.simulate(SCENES / "top_through_vertical.toml", ["sim.output_dt=5e-4", f"sim.rotation={rotation}"])
    assert traj.ok, traj.status
    pos_err, rot_err, R_ref = _compare_top(traj, [0.0, 0.0, -0.1])
    passes = _vertical_passes(R_ref)
    assert len(passes) >= 12, f"the reference axis passes the vertical only {len(passes)} times"
    assert len(_vertical_passes(traj.rotation[:, 0])) == len(passes)
    assert pos_err < TTV_POS_TOL and rot_err < TTV_POS_TOL / 0.1, (pos_err, rot_err)
    assert traj.chart_switches[0] >= (1 if rotation == "euler_switching" else 0)


def test_top_exactly_through_the_pole():
    """L_z = L_3 exactly: the axis goes through theta = 0 itself; world Euler angles are
    undefined there, the rotation matrices still match the reference."""
    th, w3, d = np.radians(40.0), 80.0, 0.1
    I3, I1p = 0.005, (3 * 0.01 + 0.0016) / 12 + d * d
    psi_d = I3 * w3 * (1 - np.cos(th)) / (I1p * np.sin(th) ** 2)
    k = np.array([0.0, -np.sin(th), np.cos(th)])
    omega = psi_d * np.array([0.0, 0.0, 1.0]) + (w3 - psi_d * np.cos(th)) * k
    velocity = np.cross(omega, d * k)
    traj = viz3d.simulate(SCENES / "top_through_vertical.toml",
                          {"bodies.top.omega": omega.tolist(), "bodies.top.velocity": velocity.tolist(),
                           "sim.output_dt": 5e-4}, t_end=1.0)
    assert traj.ok, traj.status
    pos_err, _, R_ref = _compare_top(traj, [0.0, 0.0, -0.1])
    assert np.degrees(np.arccos(R_ref[:, 2, 2].max())) < 0.05  # passes within 0.05 deg of the pole
    assert pos_err < TTV_POS_TOL


def test_plain_euler_angles_fail_at_the_pole_with_a_diagnosis():
    # index-1: its joint drift carries the axis to 2.4e-3 rad of the pole (see test_bench_stability)
    traj = viz3d.simulate(SCENES / "top_through_vertical.toml", ["sim.rotation=euler_zxz", "sim.formulation=index1"])
    assert not traj.ok
    assert "'top'" in traj.status and "gimbal lock" in traj.status and "t = 0.1" in traj.status, traj.status
    assert 0.05 < traj.t[-1] < 0.12  # frames up to the failure are kept
    assert np.all(np.isfinite(traj.position))


@pytest.mark.parametrize("rotation", ["euler_switching", "quaternion"])
def test_torque_free_body_follows_jacobi_elliptic_solution(rotation):
    """Both regular parametrizations, in the compiled kernel. The distance to the closed form is RK4's
    error (Richardson) and the angular momentum drift is truncation error too (falls like dt^4). Steps 8x
    and 4x the scene's: this run passes close to the separatrix, where omega(t) is ~5e3 times as sensitive
    to its data as |omega|; double-precision evaluations of the closed form (against mpmath) and any
    integrator at any step (dop853 at rtol 1e-12 included) agree with it only to ~3e-8 rad/s. At these
    steps RK4's error (~1e-5 rad/s) is 300x that floor, which RICHARDSON_TOL then covers."""
    runs, errors, drifts = [], [], []
    for dt in (4e-3, 2e-3):
        traj = viz3d.simulate(SCENES / "torque_free.toml", ["sim.output_dt=0.02", f"sim.rotation={rotation}"], t_end=3.0,
                              dt=dt)
        assert traj.ok, traj.status
        assert traj.scene["run"]["kernel"] == "compiled kernel"
        I = traj.inertia_body[0]
        assert np.abs(I - np.diag(np.diag(I))).max() > 1e-6, "the scene should have products of inertia"
        moments, axes = np.linalg.eigh(I)
        B_omega = np.einsum("nji,nj->ni", traj.rotation[:, 0], traj.omega[:, 0])
        w_principal = B_omega @ axes
        ref = torque_free_omega(moments, w_principal[0], traj.t)
        scale = np.linalg.norm(w_principal[0])
        runs.append((traj.t, w_principal))
        errors.append(np.abs(w_principal - ref).max())
        # it does flip: the intermediate-axis component changes sign
        assert w_principal[:, 1].min() < -0.5 * scale < 0.5 * scale < w_principal[:, 1].max()
        # angular momentum is constant in world axes
        L = np.einsum("nij,jk,nlk,nl->ni", traj.rotation[:, 0], I, traj.rotation[:, 0], traj.omega[:, 0])
        drifts.append(np.abs(L - L[0]).max())
    estimate = _richardson_rk4(*runs[0], *runs[1])
    assert abs(errors[0] / estimate - 1) < RICHARDSON_TOL, (errors[0], estimate)
    assert abs(np.log2(errors[0] / errors[1]) - 4) < ORDER_TOL, errors
    assert abs(np.log2(drifts[0] / drifts[1]) - 4) < ORDER_TOL, f"angular momentum drift {drifts}"


HANGING_ROD = """
[sim]
t_end = {t_end}
dt = 1e-3
output_dt = 1e-3

[[bodies]]
name = "rod"
shape = {{ type = "cylinder", radius = 0.02, height = {L} }}
density = 2700.0
position = [0.0, 0.0, {z}]
omega = [{w}, 0.0, 0.0]
velocity = [0.0, {vy}, 0.0]

[[joints]]
name = "pivot"
body1 = "rod"
point = [0.0, 0.0, 0.0]
"""


def test_small_oscillation_period_of_a_compound_pendulum(write_scene):
    L, w = 0.8, 0.01
    path = write_scene(HANGING_ROD.format(t_end=6.0, L=L, z=-L / 2, w=w, vy=w * L / 2))  # v = omega x r
    traj = viz3d.simulate(path)
    assert traj.ok, traj.status
    m, I = traj.mass[0], traj.inertia_body[0]
    expected = 2 * np.pi * np.sqrt((I[0, 0] + m * (L / 2) ** 2) / (m * 9.81 * L / 2))
    y = traj.position[:, 0, 1]
    i = np.flatnonzero((y[:-1] > 0) & (y[1:] <= 0))       # downward zero crossings
    t_cross = traj.t[i] - y[i] * (traj.t[i + 1] - traj.t[i]) / (y[i + 1] - y[i])
    period = np.diff(t_cross).mean()
    assert len(t_cross) >= 3
    assert period == pytest.approx(expected, rel=1e-5)   # amplitude 0.01 rad: correction 6e-6


def test_reaction_of_a_hanging_pendulum_at_rest_is_its_weight(write_scene):
    traj = viz3d.simulate(write_scene(HANGING_ROD.format(t_end=0.5, L=1.0, z=-0.5, w=0.0, vy=0.0)))
    weight = traj.mass[0] * 9.81
    np.testing.assert_allclose(traj.reaction_force[:, 0], np.tile([0.0, 0.0, weight], (len(traj.t), 1)), atol=1e-9 * weight)
    assert np.abs(traj.velocity).max() < 1e-12


def test_reactions_of_a_hanging_double_pendulum():
    scene = viz3d.load_scene(SCENES / "double_pendulum.toml", {
        "bodies.upper.position": [0.0, 0.0, -0.25], "bodies.upper.euler_deg": [0.0, 0.0, 0.0],
        "bodies.lower.position": [0.0, 0.0, -0.75], "bodies.lower.euler_deg": [0.0, 0.0, 0.0],
        "bodies.lower.velocity": [0.0, 0.0, 0.0], "bodies.lower.omega": [0.0, 0.0, 0.0],
        "joints.elbow.point": [0.0, 0.0, -0.5]})
    traj = viz3d.simulate(scene, t_end=0.2)
    m1, m2 = traj.mass
    shoulder, elbow = traj.reaction_force[-1]
    np.testing.assert_allclose(shoulder, [0, 0, (m1 + m2) * 9.81], atol=1e-9)
    np.testing.assert_allclose(elbow, [0, 0, m2 * 9.81], atol=1e-9)  # force on 'lower' (body1) from 'upper'

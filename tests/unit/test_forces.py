"""Force elements: conservative parts are minus the gradient of their potential (power balance),
dampers dissipate, applied loads act where and how the scene says."""

import numpy as np
import pytest

from viz3d.dynamics import generalized_forces
from viz3d.forces import AppliedForce, AppliedTorque, SpringDamper
from viz3d.kinematics import Configuration, pose_from, twist_from
from viz3d.timefunctions import TimeFunctions

from systems import configuration, moved, random_state, random_system

#: Central difference of the potential along the motion: truncation EPS^2 |V'''| / 6, round-off eps |V| / EPS
#: (2e-10 |V|); the power balance below allows 1e-7 relative + 1e-9 W, 500x the round-off for |V| ~ 1 J.
EPS = 1e-6


def _power(cfg, element):
    """Power of one element's generalized forces on the bodies [W]: frame forces and torques on the
    frames' twists, elastic forces on the elastic rates."""
    F, tau, e = element.wrench(cfg)
    P = float(np.sum(F * cfg.twist.W_v) + np.sum(tau * cfg.twist.W_omega))
    if e is not None:
        P += float(e @ np.concatenate(cfg.eta_dot))
    return P


def _cfg(pose, twist, t=0.0):
    return Configuration(t, pose, twist)


@pytest.mark.parametrize("flexible", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_conservative_elements_power_equals_minus_potential_rate(seed, flexible):
    system = random_system(nb=4, seed=seed, flexible=flexible)
    state = random_state(system, seed)
    cfg = configuration(system, state)
    for element in system.forces:  # along the motion's own velocity
        V_rate = (element.potential_energy(moved(system, state, state.v, EPS))
                  - element.potential_energy(moved(system, state, state.v, -EPS))) / (2 * EPS)
        assert _power(cfg, element) == pytest.approx(-V_rate, rel=1e-7, abs=1e-9), type(element).__name__


def test_damper_dissipates_c_times_length_rate_squared():
    rng = np.random.default_rng(3)
    pose = pose_from(rng.normal(size=(2, 3)), np.stack([np.eye(3)] * 2))
    twist = twist_from(rng.normal(size=(2, 3)), rng.normal(size=(2, 3)), pose)
    c = 7.0
    damper = SpringDamper(("d",), np.array([[0, 1]]), rng.normal(scale=0.1, size=(1, 2, 3)), np.zeros(1),
                          np.array([c]), np.zeros(1))
    cfg = _cfg(pose, twist)
    p, rho = damper.endpoints(cfg)
    u = (p[0, 1] - p[0, 0]) / np.linalg.norm(p[0, 1] - p[0, 0])
    vel = twist.point_velocity(damper.body[0], rho[0])
    l_dot = u @ (vel[1] - vel[0])
    P = _power(cfg, damper)
    assert P == pytest.approx(-c * l_dot**2, rel=1e-12)  # a dozen products and sums: ~10 eps; 4500 eps


def _loads(cls, frame_body, value):
    tf = TimeFunctions.from_entries([{"kind": "constant", "offset": value, "amplitude": [0, 0, 0], "frequency": 0.0,
                                      "phase": 0.0, "start": 0.0, "duration": 0.0}])
    return cls(("l",), np.array([0]), np.array([[0.0, 0.2, 0.0]]), np.array([frame_body]), tf)


def test_applied_force_torque_about_centre_of_mass_and_frames():
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z
    pose = pose_from(np.array([[1.0, 2.0, 3.0]]), R[None])
    cfg = _cfg(pose, twist_from(np.zeros((1, 3)), np.zeros((1, 3)), pose))
    F, tau, _ = _loads(AppliedForce, False, [0.0, 0.0, 5.0]).wrench(cfg)
    lever = R @ [0.0, 0.2, 0.0]
    np.testing.assert_allclose(F[0], [0, 0, 5.0])
    np.testing.assert_allclose(tau[0], np.cross(lever, [0, 0, 5.0]))
    F_b, _, _ = _loads(AppliedForce, True, [1.0, 0.0, 0.0]).wrench(cfg)
    np.testing.assert_allclose(F_b[0], R @ [1.0, 0.0, 0.0], atol=1e-15)
    F_t, tau_t, _ = _loads(AppliedTorque, False, [0.0, 0.0, 2.0]).wrench(cfg)
    np.testing.assert_allclose(F_t[0], 0.0)
    np.testing.assert_allclose(tau_t[0], [0, 0, 2.0])


def test_generalized_forces_are_body_torques_minus_gyroscopic():
    system = random_system(nb=3, seed=5, springs=False)
    cfg = configuration(system, random_state(system, 5))
    Q, _ = generalized_forces(system, cfg)
    w = cfg.twist.B_omega[:-1]
    gyro = np.cross(w, np.einsum("bij,bj->bi", system.bodies.inertia, w))
    np.testing.assert_allclose(Q[:-1, 3:], -gyro, atol=1e-12)  # gravity has no torque about G
    np.testing.assert_allclose(Q[:-1, :3], system.bodies.mass[:, None] * [0, 0, -9.81])


def test_time_functions():
    entries = [
        {"kind": k, "offset": [1.0, 0, 0], "amplitude": [2.0, 0, 0], "frequency": 0.5, "phase": 0.1, "start": 1.0,
         "duration": 2.0}
        for k in ("constant", "sine", "step", "ramp", "pulse")
    ]
    tf = TimeFunctions.from_entries(entries)
    for t, expected in [(0.5, [1, 1 + 2 * np.sin(np.pi * 0.5 + 0.1), 1, 1, 1]),
                        (2.0, [1, 1 + 2 * np.sin(np.pi * 2.0 + 0.1), 3, 2, 3]),
                        (3.5, [1, 1 + 2 * np.sin(np.pi * 3.5 + 0.1), 3, 3, 1])]:
        np.testing.assert_allclose(tf(t)[:, 0], expected, err_msg=f"t = {t}")


@pytest.mark.parametrize("seed", [0, 1])
def test_joint_coordinate_forces_have_power_effort_times_rate_off_the_manifold(seed):
    """At random states (joints not satisfied) the stop's and motor's wrench still has power f q_dot
    with ``q_dot`` their rate definition (``viz3d.joints.coordinate``): the distance's moment
    ``f u x e`` on body 1 included."""
    from viz3d.forces import JointMotor, JointStop

    system = random_system(nb=5, seed=seed, kinds=("revolute", "universal", "prismatic", "cylindrical"))
    cfg = configuration(system, random_state(system, seed))
    sets, index, free = [], [], []
    for js in system.joints.joints:
        for c in range(len(js.FREE)):
            sets.append(js)
            index.append(0)
            free.append(c)
    k = len(sets)
    idx, fr = np.array(index), np.array(free)
    q = np.array([js.coordinates(cfg)[0][j, c] for js, j, c in zip(sets, idx, fr)])
    stop = JointStop(tuple(f"s{i}" for i in range(k)), tuple(sets), idx, fr, q + 0.1, q + 0.2, np.full(k, 30.0), np.full(k, 0.5))
    tf = TimeFunctions.from_entries([{"kind": "constant", "offset": [1.0, 0, 0], "amplitude": [0, 0, 0], "frequency": 0.0,
                                      "phase": 0.0, "start": 0.0, "duration": 0.0}] * k)
    motor = JointMotor(tuple(f"m{i}" for i in range(k)), tuple(sets), idx, fr, tf, np.full(k, 3.0), np.full(k, 0.2),
                       np.full(k, np.inf))
    codes = {js.FREE[c][1] for js, c in zip(sets, fr)}
    assert codes == {0, 1, 2, 3}  # every coordinate kind
    for element in (stop, motor):
        q, q_dot = element.coordinates(cfg)
        f, _ = element.effort(0.0, q, q_dot)
        assert np.all(f != 0.0)
        assert _power(cfg, element) == pytest.approx(float(f @ q_dot), rel=1e-12)


def test_forces_on_joint_coordinates_refuse_a_joint_on_a_flexible_section():
    """Stops and motors act through rigid frames' axes (``JointCoordinateForce``): a system built in
    code (scene files refuse it earlier) cannot put one on a joint at a flexible section, and the
    same joints between rigid bodies are accepted."""
    from viz3d.forces import JointMotor, JointStop

    from systems import sections_tree

    js = sections_tree("revolute").joints.joints[0]  # every joint has a side on a section
    one = np.ones(1)
    for j in range(js.n_joints):
        with pytest.raises(ValueError, match="flexible body"):
            JointStop(("stop",), (js,), np.array([j]), np.zeros(1, int), -one, one, one, one)
    rigid = random_system(kinds=("revolute",)).joints.joints[0]
    JointStop(("stop",), (rigid,), np.array([1]), np.zeros(1, int), -one, one, one, one)
    target = TimeFunctions.from_entries([{"kind": "constant", "offset": [0, 0, 0], "amplitude": [0, 0, 0], "frequency": 0.0,
                                         "phase": 0.0, "start": 0.0, "duration": 0.0}])
    with pytest.raises(ValueError, match="joint_motor 'motor'"):
        JointMotor(("motor",), (js,), np.array([2]), np.zeros(1, int), target, one, one, one)

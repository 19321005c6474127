"""Revolute, universal, prismatic, cylindrical and fixed joints in whole runs, against closed-form
motions and scipy's rotations (references nobody here wrote).

Each scene is written to a file and run through ``viz3d.load_scene`` / ``viz3d.simulate`` like a
user's. Tolerances: RK4 at dt = 1e-3 s on motions of angular frequency below 6 rad/s has a global
error of order (omega dt)^4 omega T ~ 1e-9 relative over a few periods; the tests allow 1e-6, and
the checks they guard against (a wrong axis, a lost equation, a wrong lever) are percent-level.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation
from scipy.special import ellipk

import viz3d
from viz3d.scene.schema import SceneError

G = 9.81
#: Relative accuracy asked of the closed-form comparisons (see the module docstring).
RTOL = 1e-6


def _vec(x) -> str:
    return "[" + ", ".join(repr(float(v)) for v in x) + "]"


def _rod(name: str, centre, axis, length: float, mass: float, radius: float = 0.02, omega=(0, 0, 0)) -> str:
    """A rigid rod (cylinder of ``radius``) whose body z axis is ``axis``, with exact mass properties."""
    z = np.asarray(axis, float) / np.linalg.norm(axis)
    helper = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = helper - (helper @ z) * z
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z])
    with warnings.catch_warnings():  # a rod along z is at the ZXZ gimbal lock: any split of the angle is fine
        warnings.simplefilter("ignore", UserWarning)
        euler = Rotation.from_matrix(R).as_euler("ZXZ", degrees=True)
    I_t = mass * (3 * radius**2 + length**2) / 12
    return (f'[[bodies]]\nname = "{name}"\nshape = {{ type = "cylinder", radius = {radius}, height = {length} }}\n'
            f"mass = {mass}\ninertia = {_vec([I_t, I_t, mass * radius**2 / 2])}\nposition = {_vec(centre)}\n"
            f"euler_deg = {_vec(euler)}\nomega = {_vec(omega)}\n")


def _run(tmp_path, text: str, t_end: float, dt: float = 1e-3, name: str = "scene", **sim):
    extra = "".join(f"{k} = {v!r}\n" if not isinstance(v, str) else f'{k} = "{v}"\n' for k, v in sim.items())
    path = tmp_path / f"{name}.toml"
    path.write_text(f"[sim]\nt_end = {t_end}\ndt = {dt}\n{extra}\n{text}")
    traj = viz3d.simulate(viz3d.load_scene(path))
    assert traj.status == "ok", traj.status
    return traj


def _coordinate(traj, name: str) -> tuple[np.ndarray, np.ndarray]:
    k = list(traj.extras["joint_coordinate_names"]).index(name)
    return traj.extras["joint_coordinates"][:, k], traj.extras["joint_coordinate_rates"][:, k]


def _first_return(t, rate, after: float) -> float:
    """Time of the first zero of ``rate`` after ``after`` (cubic interpolation: error O(dt^4))."""
    spline = CubicSpline(t, rate)
    roots = [r for r in spline.roots(extrapolate=False) if r > after]
    return float(roots[0])


def _hinge_scene(alpha: float, theta0: float, length: float, mass: float) -> tuple[str, np.ndarray]:
    """A rod hinged at one end about an axis tilted ``alpha`` from horizontal, released ``theta0``
    from its lowest position in the plane normal to the axis; also the axis."""
    a = np.array([0.0, np.cos(alpha), np.sin(alpha)])
    down = np.array([0.0, np.sin(alpha), -np.cos(alpha)])  # lowest direction normal to a
    u = np.cos(theta0) * down + np.sin(theta0) * np.cross(a, down)
    text = _rod("rod", 0.5 * length * u, u, length, mass)
    text += f'[[joints]]\nname = "hinge"\ntype = "revolute"\nbody1 = "rod"\npoint = [0.0, 0.0, 0.0]\naxis = {_vec(a)}\n'
    return text, a


def _pendulum_period(I_O: float, m: float, d: float, g: float, theta0: float) -> float:
    """Exact period of a compound pendulum of amplitude theta0: 4 sqrt(I_O / (m g d)) K(sin^2(theta0/2))."""
    return 4.0 * np.sqrt(I_O / (m * g * d)) * ellipk(np.sin(theta0 / 2) ** 2)


@pytest.mark.parametrize("alpha", [0.0, np.radians(30)])
def test_revolute_pendulum_has_the_compound_pendulum_period(tmp_path, alpha):
    """A tilted hinge feels g cos(alpha) (a ball joint would swing in the vertical plane)."""
    L, m, r, theta0 = 0.8, 1.3, 0.02, np.radians(60)
    text, _ = _hinge_scene(alpha, theta0, L, m)
    traj = _run(tmp_path, text, t_end=1.5)
    angle, rate = _coordinate(traj, "hinge/angle")
    I_O = m * (3 * r**2 + L**2) / 12 + m * (L / 2) ** 2
    half = _pendulum_period(I_O, m, L / 2, G * np.cos(alpha), theta0) / 2
    assert _first_return(traj.t, rate, 0.05) == pytest.approx(half, rel=RTOL)
    # the far turning point is the mirror image of the start: angle -2 theta0 (energy conserved;
    # the rod turns from +theta0 about the axis towards -theta0)
    assert CubicSpline(traj.t, angle)(half) == pytest.approx(-2 * theta0, rel=RTOL)


@pytest.mark.filterwarnings("ignore::viz3d.scene.build.InitialConditionsWarning")  # the point of the test
def test_revolute_joint_removes_the_other_rotations(tmp_path):
    """An initial spin about the rod and about a horizontal axis normal to the hinge is removed by
    the initial velocity projection (minimum kinetic metric): the rod only turns about the hinge, its
    world angular velocity is the angle rate along the axis."""
    L, m = 0.8, 1.3
    text, a = _hinge_scene(0.0, np.radians(20), L, m)
    text = text.replace("omega = [0.0, 0.0, 0.0]", "omega = [1.0, 0.5, 2.0]")
    traj = _run(tmp_path, text, t_end=0.5)
    _, rate = _coordinate(traj, "hinge/angle")
    w = traj.omega[:, 0]
    np.testing.assert_allclose(w, rate[:, None] * a, atol=1e-9 * (1 + np.abs(w).max()))
    assert abs(rate[0]) > 0.1  # the projection kept a turn about the hinge


@pytest.mark.filterwarnings("ignore::viz3d.scene.build.InitialConditionsWarning")  # spins along the rods removed
def test_universal_chain_keeps_two_relative_rotations(tmp_path):
    """Three rods on universal joints swinging in 3D: each joint's relative rotation (body 2's joint
    frame to body 1's), from scipy, is Ry(angle2) Rx(angle1) with the reported angles and a third
    angle that stays zero to the projection's tolerance."""
    L, m = 0.4, 0.7
    text = ""
    top = np.zeros(3)
    u = np.array([np.sin(0.6), 0.3, -np.cos(0.6)])
    u /= np.linalg.norm(u)
    for i in range(3):
        text += _rod(f"r{i}", top + 0.5 * L * u, u, L, m, omega=(0.5 * i, 1.0, 0.0))
        text += (f'[[joints]]\nname = "u{i}"\ntype = "universal"\nbody1 = "r{i}"\n'
                 + (f'body2 = "r{i - 1}"\n' if i else "") + f"point = {_vec(top)}\naxis1 = [1.0, 0.0, 0.0]\n"
                 f"axis2 = {_vec(np.cross(u, [1.0, 0.0, 0.0]))}\n")
        top = top + L * u
        u = Rotation.from_rotvec([0.0, 0.0, 0.7]).apply(u)
    traj = _run(tmp_path, text, t_end=1.0, formulation="projection")
    system, _ = viz3d.build(viz3d.load_scene(tmp_path / "scene.toml"))
    js = system.joints.joints[0]
    R = np.concatenate([traj.rotation, np.broadcast_to(np.eye(3), (len(traj.t), 1, 3, 3))], axis=1)
    frames = js.axes(R)  # (n, nj, 2, 3, 3): joint axes of both sides, world
    rel = np.einsum("njia,njib->njab", frames[:, :, 1], frames[:, :, 0])  # A2^T R2^T R1 A1
    # intrinsic Y, then X, then the third: Ry(angle2) Rx(angle1) Rz(third)
    yxz = Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_euler("YXZ").reshape(len(traj.t), 3, 3)
    for j in range(3):
        a1, _ = _coordinate(traj, f"u{j}/angle1")
        a2, _ = _coordinate(traj, f"u{j}/angle2")
        np.testing.assert_allclose(yxz[:, j, 1], a1, atol=1e-9)
        np.testing.assert_allclose(yxz[:, j, 0], a2, atol=1e-9)
        assert np.ptp(a1) > 0.1 and np.ptp(a2) > 0.05  # the joints do turn both ways
    # third angle: the projection holds the constraints to projection_tol (1e-12) plus round-off
    assert np.abs(yxz[:, :, 2]).max() < 1e-10


def test_prismatic_slider_on_an_incline(tmp_path):
    """A block on a frictionless prismatic joint to ground along a 25 deg incline: s = g sin(t) t^2 / 2,
    and the joint's reaction is the normal force m g cos(t), normal to the incline."""
    tilt, m = np.radians(25), 2.0
    axis = np.array([np.cos(tilt), 0.0, -np.sin(tilt)])
    text = (f'[[bodies]]\nname = "block"\nshape = {{ type = "box", extents = [0.2, 0.1, 0.1] }}\nmass = {m}\n'
            f"inertia = [0.01, 0.02, 0.02]\nposition = [0.0, 0.0, 0.0]\n"
            f'[[joints]]\nname = "slide"\ntype = "prismatic"\nbody1 = "block"\naxis = {_vec(axis)}\n')
    traj = _run(tmp_path, text, t_end=1.0)
    s, s_dot = _coordinate(traj, "slide/distance")
    np.testing.assert_allclose(s, 0.5 * G * np.sin(tilt) * traj.t**2, atol=RTOL * G)
    np.testing.assert_allclose(s_dot, G * np.sin(tilt) * traj.t, atol=RTOL * G)
    normal = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    np.testing.assert_allclose(traj.reaction_force[:, 0], np.broadcast_to(m * G * np.cos(tilt) * normal, (len(traj.t), 3)),
                               atol=RTOL * m * G)


def test_cylindrical_joint_slides_and_spins(tmp_path):
    """A rod on a vertical cylindrical joint to ground, spun about it: it falls freely along the axis
    and keeps its spin (axis of symmetry): distance -g t^2 / 2, angle omega t."""
    m, spin = 1.0, 3.0
    text = _rod("rod", [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.5, m, omega=(0.0, 0.0, spin))
    text += '[[joints]]\nname = "c"\ntype = "cylindrical"\nbody1 = "rod"\naxis = [0.0, 0.0, 1.0]\n'
    traj = _run(tmp_path, text, t_end=1.0)
    s, _ = _coordinate(traj, "c/distance")
    angle, rate = _coordinate(traj, "c/angle")
    np.testing.assert_allclose(s, -0.5 * G * traj.t**2, atol=RTOL * G)
    np.testing.assert_allclose(rate, spin, atol=RTOL * spin)
    np.testing.assert_allclose(np.unwrap(angle), spin * traj.t, atol=RTOL * spin)


def test_welded_rods_swing_as_one_body(tmp_path):
    """An L of two rods welded by a fixed joint, hinged at one end: the compound-pendulum period of the
    L's combined moment of inertia and centre of mass (small amplitude: the series in theta0^2)."""
    L, m, r, theta0 = 0.6, 1.0, 0.02, np.radians(40)
    text, a = _hinge_scene(0.0, theta0, L, m)
    down = np.array([0.0, 0.0, -1.0])
    u = np.cos(theta0) * down + np.sin(theta0) * np.cross(a, down)
    tip = L * u
    w = np.cross(a, u)  # the second rod, normal to the first in the swing plane
    text += _rod("arm", tip + 0.5 * L * w, w, L, m)
    text += f'[[joints]]\nname = "weld"\ntype = "fixed"\nbody1 = "arm"\nbody2 = "rod"\npoint = {_vec(tip)}\n'
    traj = _run(tmp_path, text, t_end=2.0)
    I_c = m * (3 * r**2 + L**2) / 12
    G1, G2 = 0.5 * L * u, tip + 0.5 * L * w
    I_O = 2 * I_c + m * (G1 @ G1) + m * (G2 @ G2)
    com = 0.5 * (G1 + G2)
    d = np.linalg.norm(com)
    # released at rest: the combined centre of mass starts at angle beta from the vertical
    beta = np.arccos(-com[2] / d)
    half = _pendulum_period(I_O, 2 * m, d, G, beta) / 2
    _, rate = _coordinate(traj, "hinge/angle")
    assert _first_return(traj.t, rate, 0.05) == pytest.approx(half, rel=RTOL)
    angle_weld = [n for n in traj.extras["joint_coordinate_names"] if n.startswith("weld")]
    assert not angle_weld  # a weld has no relative coordinate
    rel = np.einsum("nji,njk->nik", traj.rotation[:, 0], traj.rotation[:, 1])
    np.testing.assert_allclose(rel, np.broadcast_to(rel[0], rel.shape), atol=1e-8)


def test_stops_on_a_joint_at_a_flexible_section_are_refused(tmp_path):
    """Framed joints attach to flexible sections (tests/flexible/test_flexible_joints.py); stops and
    motors act through rigid frames' axes and refuse them, naming the key."""
    path = tmp_path / "flex.toml"
    path.write_text(
        '[sim]\nt_end = 0.01\ndt = 1e-4\n[[bodies]]\nname = "bar"\ntype = "flexible"\nlength = 1.0\n'
        'material = { E = 2e11, rho = 7800.0, nu = 0.3 }\nsection = { type = "circle", diameter = 0.02 }\n'
        'theory = "euler_bernoulli"\nmodes = 3\nposition = [0.0, 0.0, 0.0]\n'
        '[[joints]]\nname = "pin"\ntype = "revolute"\nbody1 = "bar"\npoint = [0.0, 0.0, 0.0]\n'
        '[[forces]]\ntype = "joint_stop"\njoint = "pin"\nupper = 1.0\nstiffness = 1e3\n')
    with pytest.raises(SceneError, match=r"forces\[0\]\.joint.*rigid bodies or ground"):
        viz3d.build(viz3d.load_scene(path))


def test_parallel_universal_axes_are_refused(tmp_path):
    path = tmp_path / "u.toml"
    path.write_text('[sim]\nt_end = 0.01\ndt = 1e-3\n' + _rod("r", [0, 0, -0.2], [0, 0, 1], 0.4, 1.0)
                    + '[[joints]]\ntype = "universal"\nbody1 = "r"\naxis1 = [1.0, 0.0, 0.0]\naxis2 = [2.0, 0.0, 0.0]\n')
    with pytest.raises(SceneError, match=r"joints\[0\]\.axis2.*not parallel to axis1"):
        viz3d.build(viz3d.load_scene(path))


# ---------------------------------------------------------------------------- stops and motors


def _hanging_rod(L: float, m: float, q0: float = 0.0, omega=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0)) -> str:
    """A rod hinged at its top end on ``axis`` (horizontal: a pendulum; vertical: a rotor through
    its end), turned ``q0`` about the axis from hanging straight down."""
    a = np.asarray(axis, float)
    u = Rotation.from_rotvec(q0 * a).apply([0.0, 0.0, -1.0])
    return (_rod("rod", 0.5 * L * u, u, L, m, omega=omega)
            + f'[[joints]]\nname = "hinge"\ntype = "revolute"\nbody1 = "rod"\npoint = [0.0, 0.0, 0.0]\naxis = {_vec(a)}\n')


def test_stop_rebound_and_energy_loss_match_the_damped_oscillator(tmp_path):
    """A horizontal rod spinning about a vertical hinge through its end (no gravity moment about it)
    strikes a 30 deg stop: the stop is I d'' = -k d - c d' while it pushes (the force clipped at
    zero, then the rod leaves), so the rebound speed and the energy lost are those of that 1-DOF
    law, integrated by scipy's solve_ivp at rtol 1e-12 with an event where the force vanishes."""
    from scipy.integrate import solve_ivp

    L, m, r, w0, k, c = 0.5, 0.8, 0.02, 2.0, 400.0, 1.5
    limit = np.radians(30)
    I_O = m * (3 * r**2 + L**2) / 12 + m * (L / 2) ** 2  # about a transverse axis through the end
    text = (_rod("rod", [0.5 * L, 0.0, 0.0], [1.0, 0.0, 0.0], L, m, omega=(0.0, 0.0, w0)).replace(
                "omega =", f"velocity = [0.0, {0.5 * L * w0}, 0.0]\nomega =")
            + '[[joints]]\nname = "hinge"\ntype = "revolute"\nbody1 = "rod"\npoint = [0.0, 0.0, 0.0]\naxis = [0.0, 0.0, 1.0]\n'
            + f'[[forces]]\ntype = "joint_stop"\nname = "stop"\njoint = "hinge"\nlower = {-limit}\nupper = {limit}\n'
            f"stiffness = {k}\ndamping = {c}\n")
    traj = _run(tmp_path, text, t_end=0.5, dt=1e-4, output_dt=1e-4)
    q, rate = _coordinate(traj, "hinge/angle")
    assert rate[0] == pytest.approx(w0, rel=1e-12)

    def law(t, y):
        return [y[1], min(-k * y[0] - c * y[1], 0.0) / I_O]

    def released(t, y):
        return -k * y[0] - c * y[1] if t > 0 else -1.0

    released.terminal, released.direction = True, 1
    ref = solve_ivp(law, (0, 1.0), [0.0, w0], rtol=1e-12, atol=1e-14, events=released)
    w1 = ref.y_events[0][0][1]
    assert -w0 < w1 < 0
    after = traj.t > limit / w0 + 2 * ref.t_events[0][0]  # well after the contact, before the other stop
    assert np.ptp(rate[after]) < 1e-9 * w0  # free rotation again
    # The damper's force jumps from 0 to -c w0 as the rod enters the stop, inside a step (stop entries
    # are not located as events): RK4 is first order across the jump, an error of at most the step's
    # impulse c w0 dt / I_O in the rate (the smooth parts add (omega dt)^4 ~ 3e-8 relative).
    jump = c * w0 * traj.t[1] / I_O
    assert abs(rate[after][0] - w1) < jump
    E = traj.energy_kinetic + traj.energy_potential
    assert abs(E[0] - E[after][0] - 0.5 * I_O * (w0**2 - w1**2)) < I_O * abs(w1) * jump
    assert q.max() > limit  # it did enter the stop


def test_stop_holds_a_pendulum_with_the_static_deflection(tmp_path):
    """A pendulum released at -36 deg falls onto a stop that keeps it below -30 deg and settles
    (critical damping) where the stop's spring balances the weight's moment:
    -k (theta + 30 deg) = m g d sin(theta). Joint coordinates are zero at the start: q = theta + 36 deg."""
    from scipy.optimize import brentq

    L, m, r, k = 0.6, 1.2, 0.02, 60.0
    theta0, stop = np.radians(-36), np.radians(-30)
    I_O = m * (3 * r**2 + L**2) / 12 + m * (L / 2) ** 2
    c = 2 * np.sqrt(k * I_O)
    text = _hanging_rod(L, m, q0=theta0)
    text += (f'[[forces]]\ntype = "joint_stop"\nname = "stop"\njoint = "hinge"\nupper = {stop - theta0}\n'
             f"stiffness = {k}\ndamping = {c}\n")
    traj = _run(tmp_path, text, t_end=4.0)
    q, rate = _coordinate(traj, "hinge/angle")
    d = L / 2
    # the weight's moment about +y is -m g d sin(theta) (theta about +y from hanging)
    theta = brentq(lambda x: -k * (x - stop) - m * G * d * np.sin(x), stop, 0.0)
    assert theta > stop
    # critically damped: e^(-omega_n t) (1 + omega_n t) < 1e-10 by t = 4 s (omega_n = 11 rad/s)
    assert q[-1] + theta0 == pytest.approx(theta, abs=1e-9)
    assert abs(rate[-1]) < 1e-8


def test_motor_holds_a_pendulum_against_gravity(tmp_path):
    """A PD motor tracking 60 deg holds the pendulum where kp (60 deg - q) = m g d sin(q)."""
    from scipy.optimize import brentq

    L, m, kp = 0.6, 1.2, 40.0
    d, target = L / 2, np.radians(60)
    kd = 2 * np.sqrt(kp * m * L**2 / 3)
    text = _hanging_rod(L, m) + (f'[[forces]]\ntype = "joint_motor"\nname = "motor"\njoint = "hinge"\n'
                                 f"kp = {kp}\nkd = {kd}\nvalue = {target}\n")
    traj = _run(tmp_path, text, t_end=6.0)
    q, rate = _coordinate(traj, "hinge/angle")
    expected = brentq(lambda x: kp * (target - x) - m * G * d * np.sin(x), 0.0, target)
    assert q[-1] == pytest.approx(expected, abs=1e-9)
    assert abs(rate[-1]) < 1e-8


def test_saturated_motor_swings_like_a_constant_torque(tmp_path):
    """Capped at half the weight's moment at 60 deg, the motor's effort stays at the cap while the
    pendulum swings up from rest: it turns back where the cap's work equals the weight's,
    tau q_max = m g d (1 - cos q_max)."""
    from scipy.optimize import brentq

    L, m, kp = 0.6, 1.2, 200.0
    d, target = L / 2, np.radians(60)
    cap = 0.5 * m * G * d * np.sin(target)
    text = _hanging_rod(L, m) + (f'[[forces]]\ntype = "joint_motor"\nname = "motor"\njoint = "hinge"\n'
                                 f"kp = {kp}\nvalue = {target}\nmax_effort = {cap}\n")
    traj = _run(tmp_path, text, t_end=1.0)
    q, rate = _coordinate(traj, "hinge/angle")
    q_max = brentq(lambda x: cap * x - m * G * d * (1 - np.cos(x)), 0.1, np.pi / 2)
    assert kp * (target - q_max) > cap  # the demand never drops below the cap on the way up
    t_turn = _first_return(traj.t, rate, 0.05)
    assert CubicSpline(traj.t, q)(t_turn) == pytest.approx(q_max, rel=RTOL)


def _refused(tmp_path, text: str, where: str, sim: str = "") -> None:
    """Building (and running) the scene ``text`` is a SceneError matching ``where``."""
    path = tmp_path / "bad.toml"
    path.write_text(f"[sim]\nt_end = 0.01\ndt = 1e-3\n{sim}" + text)
    with pytest.raises(SceneError, match=where):
        viz3d.simulate(viz3d.load_scene(path))


def test_stop_on_an_unknown_joint_or_coordinate_is_refused(tmp_path):
    base = _hanging_rod(0.5, 1.0) + '[[forces]]\ntype = "joint_stop"\nstiffness = 10.0\n'
    _refused(tmp_path, base + 'joint = "nope"\n', r"forces\[0\]\.joint")
    _refused(tmp_path, base + 'joint = "hinge"\ncoordinate = "distance"\n', r"forces\[0\]\.coordinate.*'angle'")


def test_joint_forces_power_is_effort_times_rate_and_stops_store_their_spring_energy(tmp_path):
    """On a chain holding every kind of joint coordinate, at a state that satisfies the joints (built
    and projected from a scene): each stop's and motor's wrench has power f q_dot (what
    ``nonconservative_power`` and the ledger book), and the stops' potential decreases at the rate
    of their spring parts' power (central difference along the motion, as tests/unit/test_forces.py)."""
    from viz3d.dynamics import body_state

    text, top = "", np.zeros(3)
    kinds = (("revolute", "angle"), ("universal", "angle2"), ("cylindrical", "distance"), ("prismatic", "distance"),
             ("cylindrical", "angle"), ("universal", "angle1"))
    u = np.array([0.3, 0.2, -1.0]) / np.linalg.norm([0.3, 0.2, -1.0])
    for i, (kind, coordinate) in enumerate(kinds):
        text += _rod(f"r{i}", top + 0.25 * u, u, 0.5, 1.0, omega=(0.3 * i, -0.5, 0.2 * i))
        axis = np.cross(u, [1.0, 0.0, 0.0]) + 0.3 * u
        axes = (f"axis1 = [1.0, 0.0, 0.0]\naxis2 = {_vec(axis)}\n" if kind == "universal" else f"axis = {_vec(axis)}\n")
        text += (f'[[joints]]\nname = "j{i}"\ntype = "{kind}"\nbody1 = "r{i}"\n' + (f'body2 = "r{i - 1}"\n' if i else "")
                 + f"point = {_vec(top)}\n" + axes)
        text += (f'[[forces]]\ntype = "joint_stop"\nname = "s{i}"\njoint = "j{i}"\ncoordinate = "{coordinate}"\n'
                 f"upper = -0.01\nstiffness = {50.0 + i}\ndamping = 0.3\n"
                 f'[[forces]]\ntype = "joint_motor"\nname = "m{i}"\njoint = "j{i}"\ncoordinate = "{coordinate}"\n'
                 f'kp = 7.0\nkd = 0.2\nkind = "sine"\namplitude = 0.4\nfrequency = 1.0\n')
        top = top + 0.5 * u
        u = Rotation.from_rotvec([0.0, 0.0, 0.9]).apply(u)
    path = tmp_path / "all.toml"
    path.write_text("[sim]\nt_end = 0.1\ndt = 1e-3\n" + text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the spins are projected onto the joints
        system, state = viz3d.build(viz3d.load_scene(path))
    state = state.replace(t=0.3)
    cfg = body_state(system, state.q, state.v, state.chart, state.t)
    for element in system.forces[1:]:
        F, tau, _ = element.wrench(cfg)
        power = float(np.sum(F * cfg.twist.W_v) + np.sum(tau * cfg.twist.W_omega))
        q, q_dot = element.coordinates(cfg)
        f, f_V = element.effort(state.t, q, q_dot)
        assert np.all(f != 0.0)  # every stop pushes, every motor pulls
        assert power == pytest.approx(float(f @ q_dot), rel=1e-12, abs=1e-14)
        from systems import moved

        h = 1e-6
        V_rate = (element.potential_energy(moved(system, state, state.v, h))
                  - element.potential_energy(moved(system, state, state.v, -h))) / (2 * h)
        # truncation h^2 |V'''| ~ 1e-12, round-off eps |V| / h ~ 1e-11 (|V| ~ 0.1 J)
        assert V_rate == pytest.approx(-float(f_V @ q_dot), abs=1e-8)
        assert element.nonconservative_power(cfg) == pytest.approx(float((f - f_V) @ q_dot), rel=1e-12)


@pytest.mark.filterwarnings("ignore::viz3d.scene.build.InitialConditionsWarning")  # the drive starts the rod
def test_drives_refuse_what_they_cannot_follow(tmp_path):
    """A position profile must have a bounded acceleration (no ramp) and the joint must exist: each is
    an error naming the file and the key."""
    base = _hanging_rod(0.5, 1.0) + "[[drives]]\n"
    _refused(tmp_path, base + 'joint = "hinge"\nmode = "position"\nkind = "ramp"\n', r"drives\[0\]\.kind.*'sine'")
    _refused(tmp_path, base + 'joint = "nope"\n', r"drives\[0\]\.joint")


def test_a_universal_joint_driven_in_both_angles_follows_its_profiles(tmp_path):
    """A rod on a universal joint to ground with angle1 prescribed as a position (sine) and angle2 as a
    velocity (constant): both coordinates follow their profiles to the integration's error, and the
    drives report the torques they take."""
    text = _rod("rod", [0.0, 0.0, -0.25], [0.0, 0.0, 1.0], 0.5, 1.0)
    text += ('[[joints]]\nname = "u"\ntype = "universal"\nbody1 = "rod"\npoint = [0.0, 0.0, 0.0]\n'
             'axis1 = [1.0, 0.0, 0.0]\naxis2 = [0.0, 1.0, 0.0]\n'
             '[[drives]]\nname = "d1"\njoint = "u"\ncoordinate = "angle1"\nmode = "position"\nkind = "sine"\n'
             'amplitude = 0.3\nfrequency = 1.0\n'
             '[[drives]]\nname = "d2"\njoint = "u"\ncoordinate = "angle2"\nvalue = 0.8\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the rod starts at rest: the drives' velocities are projected in
        traj = _run(tmp_path, text, t_end=1.0)
    a1, _ = _coordinate(traj, "u/angle1")
    a2, _ = _coordinate(traj, "u/angle2")
    np.testing.assert_allclose(a1, 0.3 * np.sin(2 * np.pi * traj.t), atol=1e-8)
    np.testing.assert_allclose(a2, 0.8 * traj.t, atol=1e-8)
    assert list(traj.extras["drive_names"]) == ["d1", "d2"] and np.all(np.ptp(traj.extras["drive_effort"], axis=0) > 0.1)

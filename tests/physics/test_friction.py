"""Friction against the closed-form motions of blocks and balls (issue "Joints, drives, stops,
contact geometry and friction"): the incline is a level floor under gravity tilted by theta.

A box rests on four corner contacts (linear law, critically damped); a ball on one. The laws are
regularised (``viz3d.contact.friction``): slip speeds below ``slip_speed`` carry less than the full
friction force, so a held body creeps at ``FrictionLaw.creep_speed`` (stated and checked here), and
a sliding one feels ``mu F_n (1 - 2 exp(-2 s / slip_speed))``: exact to round-off once ``s`` exceeds
a few dozen ``slip_speed``.
"""

from __future__ import annotations

import numpy as np
import pytest

import viz3d
from viz3d.contact.friction import RegularizedCoulomb

G = 9.81
#: Regularisation and contact stiffness: friction's velocity stiffness mu m g / slip_speed and the
#: corners' normal frequency sqrt(4 K / m) both stay well inside RK4's stability limit at DT.
SLIP, K, DT = 1e-3, 1e5, 1e-4


def _vec(x) -> str:
    return "[" + ", ".join(repr(float(v)) for v in x) + "]"


def _contact(name, body, local, radius, mu, law_extra=""):
    return (f'[[contacts]]\nname = "{name}"\nbody1 = "{body}"\nlocal1 = {_vec(local)}\nradius = {radius}\n'
            f'normal = [0.0, 0.0, 1.0]\nlaw = "linear"\nstiffness = {K}\n{law_extra}'
            f'friction = "coulomb"\nmu = {mu}\nslip_speed = {SLIP}\n')


def _run(tmp_path, bodies_and_contacts: str, theta: float, t_end: float, name="scene"):
    g = G * np.array([np.sin(theta), 0.0, -np.cos(theta)])
    path = tmp_path / f"{name}.toml"
    path.write_text(f"[sim]\nt_end = {t_end}\ndt = {DT}\noutput_dt = 0.01\ngravity = {_vec(g)}\n\n{bodies_and_contacts}")
    traj = viz3d.simulate(viz3d.load_scene(path))
    assert traj.status == "ok", traj.status
    return traj


def _box(theta: float, mu: float, v0: float = 0.0, m: float = 1.0) -> str:
    """A 0.2 x 0.2 x 0.1 m box resting on its four bottom corners at their static indentation."""
    a, h = 0.1, 0.05
    alpha0 = m * G * np.cos(theta) / (4 * K)
    damping = np.sqrt(K * m)  # four corners: critical damping of the bounce mode
    text = (f'[[bodies]]\nname = "box"\nshape = {{ type = "box", extents = [0.2, 0.2, 0.1] }}\nmass = {m}\n'
            f"inertia = [{m * (0.2**2 + 0.1**2) / 12}, {m * (0.2**2 + 0.1**2) / 12}, {m * 0.08 / 12}]\n"
            f"position = [0.0, 0.0, {h - alpha0}]\nvelocity = [{v0}, 0.0, 0.0]\n")
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        text += _contact(f"corner{i}", "box", [sx * a, sy * a, -h], 0.0, mu, f"damping = {damping}\n")
    return text


def test_box_slides_down_a_steep_incline_with_the_dynamic_coefficient(tmp_path):
    """tan(theta) > mu: a = g (sin(theta) - mu cos(theta))."""
    theta, mu = np.radians(30), 0.3
    traj = _run(tmp_path, _box(theta, mu), theta, 1.0)
    late = traj.t > 0.1  # after the slip exceeds a few dozen slip_speed (t ~ 100 SLIP / a)
    a = np.polyfit(traj.t[late], traj.velocity[late, 0, 0], 1)[0]
    expected = G * (np.sin(theta) - mu * np.cos(theta))
    # the regularisation's deficit 2 exp(-2 s / SLIP) mu g cos is below 1e-80 by then; what is left is
    # RK4's truncation on the corners' normal oscillation, damped out within ~0.01 s
    assert a == pytest.approx(expected, rel=1e-6)
    assert np.abs(traj.velocity[late, 0, 2]).max() < 1e-9  # no bouncing


def test_box_holds_on_a_gentle_incline_and_creeps_at_the_regularised_speed(tmp_path):
    """tan(theta) < mu: held. A regularised law holds ``m g sin`` only while slipping at the creep speed
    ``slip_speed atanh(tan(theta) / mu)`` (0.70 mm/s here): the box drifts 1.05 mm in 1.5 s. The
    creep is reached within a few ``m slip_speed / (mu m g)`` (0.2 ms) once the corners' critically
    damped bounce (sqrt(4 K / m) = 632 rad/s) has died out, well before 0.5 s."""
    theta, mu = np.radians(20), 0.6
    traj = _run(tmp_path, _box(theta, mu), theta, 1.5)
    creep = RegularizedCoulomb(mu, SLIP).creep_speed(np.tan(theta))
    assert creep == pytest.approx(SLIP * np.arctanh(np.tan(theta) / mu), rel=1e-9)
    late = traj.t > 0.5
    np.testing.assert_allclose(traj.velocity[late, 0, 0], creep, rtol=1e-6)


def test_box_launched_on_a_floor_stops_after_v0_squared_over_2_mu_g(tmp_path):
    """Level floor, v0 = 1 m/s, mu = 0.3: it stops after v0^2 / (2 mu g) in v0 / (mu g). The
    regularisation lets the last ``slip_speed`` of speed decay over ``slip_speed / (mu g)``: the
    stopping distance moves by a few ``slip_speed^2 / (mu g)`` (3e-7 m; 1.5e-6 m measured)."""
    mu, v0 = 0.3, 1.0
    traj = _run(tmp_path, _box(0.0, mu, v0), 0.0, 0.6)
    x = traj.position[:, 0, 0]
    assert x[-1] == pytest.approx(v0**2 / (2 * mu * G), abs=1e-5)
    t_stop = v0 / (mu * G)
    sliding = traj.t < 0.9 * t_stop
    decel = np.polyfit(traj.t[sliding & (traj.t > 0.02)], traj.velocity[sliding & (traj.t > 0.02), 0, 0], 1)[0]
    assert -decel == pytest.approx(mu * G, rel=1e-6)
    assert abs(traj.velocity[-1, 0, 0]) < SLIP


def _ball(theta: float, mu: float, m: float = 1.0, r: float = 0.05) -> str:
    alpha0 = m * G * np.cos(theta) / K
    damping = 2 * np.sqrt(K * m)
    I = 0.4 * m * r * r
    return (f'[[bodies]]\nname = "ball"\nshape = {{ type = "sphere", radius = {r} }}\nmass = {m}\n'
            f"inertia = [{I}, {I}, {I}]\nposition = [0.0, 0.0, {r - alpha0}]\n"
            + _contact("floor", "ball", [0.0, 0.0, 0.0], r, mu, f"damping = {damping}\n"))


@pytest.mark.parametrize("mu", [0.5, 0.05])
def test_ball_rolls_or_slides_down_an_incline(tmp_path, mu):
    """mu >= 2/7 tan(theta): rolls, a = 5/7 g sin(theta), omega = v / r; below: slides with
    a = g (sin - mu cos) and spins up at 5 mu g cos / (2 r)."""
    theta, r = np.radians(20), 0.05
    traj = _run(tmp_path, _ball(theta, mu), theta, 1.0, name=f"ball{mu}")
    late = traj.t > 0.1
    a = np.polyfit(traj.t[late], traj.velocity[late, 0, 0], 1)[0]
    spin = np.polyfit(traj.t[late], traj.omega[late, 0, 1], 1)[0]  # rolling in +x turns about +y
    if mu >= 2 / 7 * np.tan(theta):
        assert a == pytest.approx(5 / 7 * G * np.sin(theta), rel=1e-6)
        assert spin * r == pytest.approx(a, rel=1e-6)
    else:
        assert a == pytest.approx(G * (np.sin(theta) - mu * np.cos(theta)), rel=1e-6)
        assert spin == pytest.approx(5 * mu * G * np.cos(theta) / (2 * r), rel=1e-6)


# ---------------------------------------------------------------------------- bristle stick-slip (seed 004)

K_STICK = 1e4  # bristles per corner [N/m]: tangential frequency sqrt(4 K_STICK / m) = 200 rad/s
C_STICK = 100.0  # critical damping of that mode, shared by the four corners [N s/m]


def _bristle_box(theta: float, mu: float, mu_s: float, v0: float = 0.0) -> str:
    return _box(theta, mu, v0).replace(
        'friction = "coulomb"', f'friction = "bristle"\nmu_static = {mu_s}\nstick_speed = {SLIP}\n'
        f"stick_stiffness = {K_STICK}\nstick_damping = {C_STICK}")


def test_bristles_hold_a_box_without_creep(tmp_path):
    """tan(theta) < mu_s: the bristle springs hold the box with their static deflection
    m g sin(theta) / (4 k_stick) per corner; it does not creep (drift from 0.5 s to 1.5 s below 1e-9 m,
    against 0.70 mm for the regularised Coulomb law of the test above; the bristles' mode, 200 rad/s,
    is critically damped). The centre of mass moves a little
    more: the friction's moment about it (lever h = 0.05 m) pitches the box on its corner springs by
    phi = m g sin(theta) h / (4 K a^2) (a = 0.1 m), adding h phi (statics to first order in phi ~ 4e-5)."""
    theta, m, h, a = np.radians(20), 1.0, 0.05, 0.1
    traj = _run(tmp_path, _bristle_box(theta, 0.5, 0.6), theta, 1.5)
    x = traj.position[:, 0, 0]
    deflection = m * G * np.sin(theta) / (4 * K_STICK)
    phi = m * G * np.sin(theta) * h / (4 * K * a * a)
    # second-order terms (the corners' a (1 - cos phi) ~ a phi^2 / 2) are 2e-6 of the deflection
    assert x[-1] == pytest.approx(deflection + h * phi, rel=1e-5)
    late = traj.t > 0.5
    assert np.ptp(x[late]) < 1e-9


def test_bristles_let_a_box_slide_with_the_dynamic_coefficient(tmp_path):
    """tan(theta) > mu_s: the bristles break away (their anchor follows, eq. 3.49) and the box
    slides at g (sin - mu cos): beta = exp(-(v / v_stick)^2) is below 1e-40 once v > 10 v_stick."""
    theta, mu = np.radians(35), 0.4
    traj = _run(tmp_path, _bristle_box(theta, mu, 0.6), theta, 1.0)
    late = traj.t > 0.1
    a = np.polyfit(traj.t[late], traj.velocity[late, 0, 0], 1)[0]
    assert a == pytest.approx(G * (np.sin(theta) - mu * np.cos(theta)), rel=1e-6)


def test_bristles_stop_a_launched_box_and_hold_it(tmp_path):
    """Level floor, v0 = 1 m/s, mu = 0.3: it stops after v0^2 / (2 mu g) in v0 / (mu g), give or take
    the stick-slip transition (speeds below v_stick: ~ v_stick^2 / (mu g)) and the bristles' deflection
    (at most mu_s m g / (4 k_stick) = 0.15 mm); then it stays put."""
    mu, mu_s, v0 = 0.3, 0.6, 1.0
    traj = _run(tmp_path, _bristle_box(0.0, mu, mu_s, v0), 0.0, 1.0)
    x = traj.position[:, 0, 0]
    assert abs(x[-1] - v0**2 / (2 * mu * G)) < mu_s * G / (4 * K_STICK) + 1e-5
    # the bristles, deflected while sliding, spring back and unload (over ~0.3 s: the stick-slip
    # transition at speeds ~ v_stick and the box's pitch settle with them)
    stopped = traj.t > 2 * v0 / (mu * G)
    assert np.ptp(x[stopped]) < 1e-9 and np.abs(traj.velocity[stopped, 0, 0]).max() < 1e-8

"""The slider-crank scene (a velocity drive on a revolute joint, a ball joint, a universal joint and a
prismatic joint) against its closed-form kinematics and an inverse-dynamics torque derived here with
sympy (Lagrange's equation of the one-degree-of-freedom mechanism), nobody's code but sympy's.

Tolerances: RK4 at dt = 1e-3 s on a motion at 2 pi rad/s has (omega dt)^4 ~ 2e-9 relative error per
unit time; positions are compared to 1e-8 m and the torque to 1e-6 of its largest value.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import viz3d

from conftest import ROOT

SCENE = ROOT / "scenes" / "slider_crank.toml"


def _parameters(scene) -> dict:
    """Lengths, masses and inertias (about the y axis) the scene gives, and the drive's speed."""
    bodies = {b["name"]: b for b in scene.data["bodies"]}
    joints = {j["name"]: j for j in scene.data["joints"]}
    r = joints["crank_pin"]["point"][0] - joints["main_bearing"]["point"][0]
    l = joints["piston_pin"]["point"][0] - joints["crank_pin"]["point"][0]
    return {"r": r, "l": l, "omega": scene.data["drives"][0]["value"], "g": -scene.data["sim"]["gravity"][2],
            **{f"m_{n}": bodies[n]["mass"] for n in ("crank", "rod", "piston")},
            **{f"I_{n}": float(np.asarray(bodies[n]["inertia"]).reshape(-1)[4 if np.size(bodies[n]["inertia"]) == 9 else 1])
               for n in ("crank", "rod")}}


def _inverse_dynamics(p: dict):
    """``tau(theta)``: the torque that turns the crank at constant speed, from Lagrange's equation
    ``d/dt dT/dtheta_dot - dT/dtheta + dV/dtheta = tau`` with ``theta_dd = 0``; and the piston's ``x(theta)``.
    The crank turns about +y: its pin is at ``r (cos theta, -sin theta)`` in the x-z plane."""
    th, thd = sp.symbols("theta theta_dot")
    r, l = p["r"], p["l"]
    pin = sp.Matrix([r * sp.cos(th), -r * sp.sin(th)])
    x_p = r * sp.cos(th) + sp.sqrt(l**2 - r**2 * sp.sin(th) ** 2)
    piston = sp.Matrix([x_p, 0])
    rod_G, crank_G = (pin + piston) / 2, pin / 2
    alpha = sp.atan2(-(piston - pin)[1], (piston - pin)[0])  # the rod's turn about +y

    def rate(expr):
        return sp.diff(expr, th) * thd

    v2 = lambda P: rate(P[0]) ** 2 + rate(P[1]) ** 2  # noqa: E731
    T = sp.Rational(1, 2) * ((p["I_crank"] + p["m_crank"] * (r / 2) ** 2) * thd**2 + p["m_rod"] * v2(rod_G)
                             + p["I_rod"] * rate(alpha) ** 2 + p["m_piston"] * rate(x_p) ** 2)
    V = p["g"] * (p["m_crank"] * crank_G[1] + p["m_rod"] * rod_G[1])
    dT = sp.diff(T, thd)
    tau = sp.diff(dT, th) * thd - sp.diff(T, th) + sp.diff(V, th)  # + dT/dthd_dot * theta_dd (= 0)
    tau = tau.subs(thd, p["omega"])
    return sp.lambdify(th, tau, "numpy"), sp.lambdify(th, x_p, "numpy")


@pytest.fixture(scope="module")
def run():
    scene = viz3d.load_scene(SCENE)
    traj = viz3d.simulate(scene)
    assert traj.status == "ok"
    return scene, traj


def test_piston_follows_the_closed_form_kinematics(run):
    scene, traj = run
    p = _parameters(scene)
    _, x_of = _inverse_dynamics(p)
    theta = p["omega"] * traj.t
    piston = list(traj.body_names).index("piston")
    np.testing.assert_allclose(traj.position[:, piston, 0], x_of(theta), atol=1e-8)
    np.testing.assert_allclose(traj.position[:, piston, 1:], 0.0, atol=1e-8)
    k = list(traj.extras["joint_coordinate_names"]).index("main_bearing/angle")
    angle = np.unwrap(traj.extras["joint_coordinates"][:, k])
    np.testing.assert_allclose(angle, theta, atol=1e-8)  # the drive holds the crank on its profile


def test_driving_torque_equals_the_inverse_dynamics(run):
    scene, traj = run
    tau_of, _ = _inverse_dynamics(_parameters(scene))
    assert list(traj.extras["drive_names"]) == ["motor"]
    effort = traj.extras["drive_effort"][:, 0]
    expected = tau_of(_parameters(scene)["omega"] * traj.t)
    assert np.ptp(expected) > 1.0  # the torque does vary over a turn (gravity and the rod's inertia)
    np.testing.assert_allclose(effort, expected, atol=1e-6 * np.abs(expected).max())

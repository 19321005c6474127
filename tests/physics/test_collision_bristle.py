"""Bristle stick-slip friction (seed 004, eqs. 3.40-3.49) on shape contacts (``[collision]``) against
the statics and dynamics of a block on an incline, with RK4 and with ALI3-P.

A 0.2 x 0.2 x 0.1 m box (m = 1 kg) rests on a ground plane on its four bottom corners (linear law K
per corner, critically damped bounce). The plane is tilted by theta about y (its normal ``(sin, 0,
cos)``), gravity is vertical. Contacts are found afresh at every evaluation; each corner's stick
anchor lives in ``State.element_memory`` and must persist from step to step.

* Below the friction angle (tan theta < mu_s) the bristles hold the box: each corner's deflection is
  ``m g sin / (4 k_stick)`` and the friction's moment about the centre of mass (lever h) pitches the
  box on its normal springs by ``phi = m g sin h / (4 K a^2)``, which moves it by ``h phi`` more
  (statics to first order in phi ~ 4e-5; the same closed form as the sphere-contact test in
  test_friction.py). It does not creep, while regularised Coulomb friction creeps at
  ``slip_speed atanh(tan / mu)`` (``RegularizedCoulomb.creep_speed``).
* Above it the box slides with ``g (sin - mu cos)``: ``beta = exp(-(v / v_stick)^2)`` is below 1e-40
  once ``v > 10 v_stick``, so nothing of the stick law is left.
* A push ramped from 0 to m g on a level plane: the friction force of each contact never exceeds
  ``mu_s F_n`` (no viscous term here), every contact keeps its identity (anchor) from one step to the
  next, and the box breaks away between the pushes ``mu m g`` and ``mu_s m g`` (plus the time the
  cap allows).
* Anchors are planted at touch-down and dropped at lift-off; a box launched on a floor stops after
  ``v0^2 / (2 mu g)`` and stays (its anchors were moved along while it slid, eq. 3.49).
"""

from __future__ import annotations

import numpy as np
import pytest

import viz3d
from viz3d.contact.collision import Collisions
from viz3d.contact.friction import RegularizedCoulomb
from viz3d.dynamics import body_state
from viz3d.scene.build import build, make_formulation, make_integrator_from
from viz3d.simulate import Simulation

G = 9.81
M, A, H = 1.0, 0.1, 0.05  # mass [kg], half length and half height of the box [m]
#: Normal stiffness per corner, bristles per corner (tangential frequency sqrt(4 K_STICK / M) = 200
#: rad/s) with critical damping of that mode shared by the four corners, stick-slip speed.
K, K_STICK, C_STICK, V_STICK = 1e5, 1e4, 100.0, 1e-3
SLIP = 1e-3  # regularised Coulomb's slip speed [m/s]
#: Each method's text and step [s]: RK4 inside its stability limit on the corners' normal mode
#: (sqrt(4 K / M) dt = 0.13 at 2e-4); ALI3-P's trapezoidal rule is A-stable and exact on the steady
#: states and the constant acceleration these tests measure, so it takes 1e-3 (0.63 rad a step). ALI3-P
#: on the NumPy path: compiling its shape-contact steps takes about 2 minutes of CPU, over the default
#: suite's budget (the compiled steps equal these: tests/numerics/test_ali3p_contact_sets.py, slow).
METHODS = {"rk4": ('integrator = "rk4"', 2e-4),
           "ali3p": ('formulation = "ali3p"\nintegrator = "trapezoidal"\ncompiled = false', 1e-3)}


def _vec(x) -> str:
    return "[" + ", ".join(repr(float(v)) for v in x) + "]"


def _friction(kind: str, mu: float, mu_s: float) -> str:
    if kind == "coulomb":
        return f'friction = "coulomb"\nmu = {mu_s}\nslip_speed = {SLIP}'
    return (f'friction = "bristle"\nmu = {mu}\nmu_static = {mu_s}\nstick_speed = {V_STICK}\n'
            f"stick_stiffness = {K_STICK}\nstick_damping = {C_STICK}")


def _scene(theta: float, friction: str, t_end: float, method: str = "rk4", push: float = 0.0, lift: float = 0.0) -> str:
    """The box at its static normal indentation (raised by ``lift``) on a plane tilted by ``theta``;
    ``push``: a force along x at the centre of mass ramped from 0 to ``push`` over 1 s."""
    n = np.array([np.sin(theta), 0.0, np.cos(theta)])
    alpha0 = M * G * np.cos(theta) / (4 * K)
    I = [M * (4 * A * A + 4 * H * H) / 12, M * (4 * A * A + 4 * H * H) / 12, M * 8 * A * A / 12]
    tilt = f"euler_deg = [90.0, {float(np.degrees(theta))!r}, -90.0]" if theta else ""  # (about y)
    load = (f'[[forces]]\ntype = "force"\nbody = "box"\nlocal = [0.0, 0.0, {-H}]\nkind = "ramp"\nduration = 1.0\n'
            f'amplitude = [{push}, 0.0, 0.0]\n' if push else "")
    text, dt = METHODS[method]
    return f"""[sim]\nt_end = {t_end}\ndt = {dt}\noutput_dt = 0.01\n{text}\n
[[bodies]]\nname = "box"\nshape = {{ type = "box", extents = [{2 * A}, {2 * A}, {2 * H}] }}\nmass = {M}
inertia = {_vec(I)}\nposition = {_vec((H - alpha0 + lift) * n)}\n{tilt}\n
{load}
[collision]
[[collision.ground]]\ntype = "plane"\nnormal = {_vec(n)}
[[collision.pairs]]\ngroups = ["bodies", "ground"]\nlaw = "linear"\nstiffness = {K}\ndamping = {np.sqrt(K * M)}
{friction}
"""


def _run(tmp_path, text: str, name: str):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    traj = viz3d.simulate(viz3d.load_scene(path))
    assert traj.status == "ok", traj.status
    return traj


def _down(theta: float) -> np.ndarray:
    return np.array([np.cos(theta), 0.0, -np.sin(theta)])


@pytest.mark.parametrize("method", ["rk4", "ali3p"])
def test_bristles_hold_a_box_below_the_friction_angle_where_coulomb_creeps(tmp_path, method):
    """theta = 20 deg, mu_s = 0.6 (tan = 0.36): held at the bristles' static deflection plus the pitch
    term, within the bound mu_s m g cos / (4 k_stick) (+ h phi), without creep: the drift from 0.5 s
    to 1.5 s stays below 1e-9 m, where regularised Coulomb (mu = 0.6) drifts its creep speed times 1 s
    (0.70 mm)."""
    theta, mu_s = np.radians(20), 0.6
    down = _down(theta)
    traj = _run(tmp_path, _scene(theta, _friction("bristle", 0.5, mu_s), 1.5, method), f"hold_{method}")
    x = traj.position[:, 0] @ down
    deflection = M * G * np.sin(theta) / (4 * K_STICK)
    pitch = H * M * G * np.sin(theta) * H / (4 * K * A * A)
    # Neglected: second order in phi (a phi^2 / 2 ~ 1e-10 m) and the contact point's rise by half the
    # indentation (alpha / 2 = 6e-6 m against h = 0.05 m in the pitch term): below 1e-5 relative.
    assert x[-1] == pytest.approx(deflection + pitch, rel=1e-5)
    assert x[-1] <= mu_s * M * G * np.cos(theta) / (4 * K_STICK) + pitch
    late = traj.t >= 0.5
    assert np.ptp(x[late]) < 1e-9

    coulomb = _run(tmp_path, _scene(theta, _friction("coulomb", 0.5, mu_s), 1.5, method), f"creep_{method}")
    xc = coulomb.position[:, 0] @ down
    creep = RegularizedCoulomb(mu_s, SLIP).creep_speed(np.tan(theta))
    drift = xc[late][-1] - xc[late][0]
    assert drift == pytest.approx(creep * (traj.t[-1] - 0.5), rel=1e-3)
    assert drift > 1e5 * np.ptp(x[late])


@pytest.mark.parametrize("method", ["rk4", "ali3p"])
def test_bristles_let_a_box_slide_above_the_friction_angle_with_the_dynamic_coefficient(tmp_path, method):
    """theta = 35 deg, mu = 0.4, mu_s = 0.6 (tan = 0.70): a = g (sin - mu cos) = 2.412 m/s^2 along the
    slope once v > 10 v_stick (t > 0.01 s); fitted from 0.1 s."""
    theta, mu = np.radians(35), 0.4
    traj = _run(tmp_path, _scene(theta, _friction("bristle", mu, 0.6), 0.6, method), f"slide_{method}")
    late = traj.t > 0.1
    a = np.polyfit(traj.t[late], traj.velocity[late, 0] @ _down(theta), 1)[0]
    assert a == pytest.approx(G * (np.sin(theta) - mu * np.cos(theta)), rel=1e-6)


def _simulation(tmp_path, text: str) -> tuple[Simulation, Collisions, int]:
    path = tmp_path / "sim.toml"
    path.write_text(text)
    scene = viz3d.load_scene(path)
    system, state = build(scene)
    cfg = scene.data["sim"]
    sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"])
    k = next(i for i, e in enumerate(system.forces) if isinstance(e, Collisions))
    return sim, system.forces[k], k


def test_a_pushed_box_keeps_its_anchors_and_friction_never_exceeds_mu_static_f_n(tmp_path):
    """Level plane, push P = m g t / (1 s) at the height of the contacts (no pitch: the four corners
    load alike). After every step, at each contact: |f_t| <= mu_s F_n (the stick force is capped
    there, the slide force is mu F_n, beta blends them; no viscous term), its anchor from the step
    before is found again (identity kept through stick and sliding) and its bristles carry at most
    mu_s F_n (eq. 3.49). Breakaway (slip past 10 v_stick) is bracketed by the law's bounds: not before
    P = mu m g (at that slip the friction is mu F_n, beta < 1e-43), and no later than 0.045 s after
    P = mu_s m g (past it friction <= mu_s F_n leaves at least a = g (t - mu_s) / 1 s, so the slip
    gains 10 v_stick within sqrt(2 * 10 v_stick / g)). Measured: 0.584 s; the blend is velocity
    weakening (mu < mu_s) and breaks away a little before the cap, at the loading's slip speed."""
    mu, mu_s = 0.4, 0.6
    sim, element, k = _simulation(tmp_path, _scene(0.0, _friction("bristle", mu, mu_s), 0.7, push=M * G))
    prev = sim.state
    worst, speed = 0.0, []
    while sim.state.t < 0.7 - 1e-9:
        state = sim.step()
        cfg = body_state(sim.system, state.q, state.v, state.chart, state.t)
        tc, _, F, _, f, _ = element.evaluate(cfg, memory=state.element_memory[k])
        assert tc.m == 4
        f_t = f - F[:, None] * tc.n
        worst = max(worst, float(np.max(np.linalg.norm(f_t, axis=1) / (mu_s * F))))
        assert np.all(element.match(cfg, tc, prev.element_memory[k]) >= 0)
        s = element.deflection(cfg, tc, state.element_memory[k])
        assert np.all(K_STICK * np.linalg.norm(s, axis=1) <= mu_s * F * (1 + 1e-12))
        speed.append((state.t, state.v[0]))
        prev = state
    assert worst <= 1 + 1e-12
    t, v = np.array(speed).T
    t_slide = t[np.argmax(v > 10 * V_STICK)]
    assert mu <= t_slide <= mu_s + np.sqrt(2 * 10 * V_STICK / G)


def test_anchors_are_planted_at_touch_down_and_dropped_at_lift_off(tmp_path):
    """A box dropped from 1 mm: no anchors in the air, four at the corners' touch-down (planted where
    they touch: no deflection then), none again after it bounces off a stiff floor (no damping)."""
    text = _scene(0.0, _friction("bristle", 0.4, 0.6), 0.05, lift=1e-3).replace(f"damping = {np.sqrt(K * M)}",
                                                                                 "damping = 0.0")
    sim, element, k = _simulation(tmp_path, text)
    counts, fresh = [], []
    while sim.state.t < 0.05 - 1e-9:
        prev = sim.state
        state = sim.step()
        cfg = body_state(sim.system, state.q, state.v, state.chart, state.t)
        tc = element.detect(cfg)
        memory = state.element_memory[k]
        counts.append((tc.m, memory.n))
        if memory.n and not prev.element_memory[k].n:  # touch-down: anchors just planted
            fresh.append(np.abs(element.deflection(cfg, tc, memory)).max())
    m, n = np.array(counts).T
    np.testing.assert_array_equal(m, n)
    assert n[0] == 0 and n.max() == 4
    assert fresh and max(fresh) < 1e-15  # round-off of the body-frame round trip
    assert n[np.argmax(n > 0):].min() == 0  # lifted off again: dropped


def test_a_launched_box_stops_after_v0_squared_over_two_mu_g_and_sticks(tmp_path):
    """Level plane, v0 = 1 m/s, mu = 0.3: it stops after v0^2 / (2 mu g) = 0.170 m, give or take the
    stick-slip transition (speeds below v_stick: ~ v_stick^2 / (mu g) = 3e-7 m) and the bristles'
    deflection (at most mu_s m g / (4 k_stick) = 0.15 mm); then the anchors, moved along while it slid
    (eq. 3.49), hold it: no drift after 2 v0 / (mu g)."""
    mu, mu_s, v0 = 0.3, 0.6, 1.0
    text = _scene(0.0, _friction("bristle", mu, mu_s), 0.8).replace("position = ", f"velocity = [{v0}, 0.0, 0.0]\nposition = ")
    traj = _run(tmp_path, text, "launch")
    x = traj.position[:, 0, 0]
    assert abs(x[-1] - v0**2 / (2 * mu * G)) < mu_s * G / (4 * K_STICK) + 1e-6
    stopped = traj.t > 2 * v0 / (mu * G)
    assert np.ptp(x[stopped]) < 1e-9 and np.abs(traj.velocity[stopped, 0, 0]).max() < 1e-8


def test_bristle_on_a_collision_pair_needs_its_stiffness(tmp_path):
    from viz3d.scene.schema import SceneError

    text = _scene(0.0, 'friction = "bristle"\nmu = 0.4', 0.01)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(SceneError) as err:
        viz3d.simulate(viz3d.load_scene(path))
    assert err.value.path == "collision.pairs[0].stick_stiffness"

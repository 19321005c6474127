"""Framed joints (fixed, revolute) on sections of flexible bodies, against references the engine did
not write:

* a free-free quintic FE bar on a floating frame, welded at x = 0 to ground by a ``fixed`` joint, is
  the cantilever: its linearized frequencies are the eigenvalues of the clamped FE model (frame =
  "fixed", supports clamped-free, the same mesh: the welded bar spans the same function space), and
  its static tip deflection under its weight is ``q L^4 / (8 E I)`` (quartic: exact in quintic
  elements);
* a stiff flexible bar on a revolute swings as the rigid compound pendulum ``I_O phi'' = m g d cos
  phi`` (scipy DOP853), its deviation falling as 1 / E.

The Jacobians themselves are checked by finite differences in tests/unit/test_joints.py (every joint
type with sides on flexible sections, drives included).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import eigh

import viz3d
from viz3d.constraints import constraint_residual
from viz3d.dynamics import VectorField, body_state, retract
from viz3d.flexible.floating_points import material_points, point_positions
from viz3d.formulation import Index1

L, E, RHO, WIDTH, DEPTH = 1.0, 2e11, 7800.0, 0.02, 0.001
#: Frequencies: central differences of the vector field (h = 1e-7 on unit-scale coordinates: error
#: ~ h^2 + eps omega_max^2 / omega_1^2 ~ 1e-10) and the rigid frame's section rotary inertia, which
#: the Euler-Bernoulli fields lack: it lowers the frequencies by O(I / (A L^2)) = DEPTH^2 / 12 L^2 =
#: 8.3e-8 (2.3 times that for mode 1, falling as DEPTH^2: -7.5e-7 at 2 mm, -6.8e-9 at 0.2 mm). 1e-6.
FREQ_RTOL = 1e-6
#: Static deflection: the equilibrium of the nonlinear floating-frame model differs from the linear
#: one by O(w / L) = 6e-7 at g = 1e-5 m/s^2 (w = 5.9e-7 m) plus the Newton residual: 1e-6.
STATIC_RTOL = 1e-6
FD_STEP = 1e-7


def _bar(frame: str = "floating", supports=("free", "free"), elements: int = 4, extra: str = "") -> str:
    return (f'[[bodies]]\nname = "bar"\ntype = "flexible"\nlength = {L}\nmaterial = {{ E = {E}, rho = {RHO}, nu = 0.3 }}\n'
            f'section = {{ type = "rectangle", width = {WIDTH}, depth = {DEPTH} }}\ntheory = "euler_bernoulli"\n'
            f'model = "fe"\nelement = "quintic"\nelements = {elements}\nsupports = {list(supports)}\nframe = "{frame}"\n'
            f'position = [0.0, 0.0, 0.0]\naxis = [1.0, 0.0, 0.0]\nbending_direction = [0.0, 0.0, 1.0]\n{extra}')


def _build(tmp_path, text: str, gravity: float):
    path = tmp_path / "scene.toml"
    path.write_text(f"[sim]\nt_end = 0.01\ndt = 1e-4\ngravity = [0.0, 0.0, {-gravity}]\n" + text)
    return viz3d.build(viz3d.load_scene(path))


WELDED = _bar() + '[[joints]]\nname = "clamp"\ntype = "fixed"\nbody1 = "bar"\nx1 = 0.0\n'


def _linear_frequencies(system, state) -> np.ndarray:
    """Positive imaginary parts of the eigenvalues of the vector field's Jacobian at rest [rad/s]
    (the constraint directions give zero eigenvalues: C'' = 0)."""
    f = VectorField(system, Index1(), state.chart)
    y0 = state.y
    A = np.column_stack([(f(0.0, y0 + FD_STEP * e) - f(0.0, y0 - FD_STEP * e)) / (2 * FD_STEP) for e in np.eye(len(y0))])
    lam = np.linalg.eigvals(A)
    return np.sort(lam.imag[(lam.imag > 1.0) & (np.abs(lam.real) < 1e-3 * np.abs(lam))])


def test_welded_bar_has_the_cantilever_frequencies(tmp_path):
    system, state = _build(tmp_path, WELDED, 0.0)
    clamped, _ = _build(tmp_path, _bar("fixed", ("clamped", "free")), 0.0)
    bar = clamped.bodies.flexible[0].bar
    exact = np.sqrt(eigh(bar.K, bar.M_ee, eigvals_only=True))
    omega = _linear_frequencies(system, state)
    assert len(omega) == len(exact)
    np.testing.assert_allclose(omega[:4], exact[:4], rtol=FREQ_RTOL)
    # and the continuous cantilever's (beta L)^2 sqrt(EI / rho A L^4) (the quintic's h^8 error is 1e-9)
    EI, rhoA = E * WIDTH * DEPTH**3 / 12, RHO * WIDTH * DEPTH
    assert omega[0] == pytest.approx(1.8751040687119611**2 * np.sqrt(EI / (rhoA * L**4)), rel=FREQ_RTOL)


def _equilibrium(system, state, iterations: int = 4):
    """Rest configuration: Gauss-Newton on ``[v_dot(q, 0); C(q)] = 0`` over velocity-space increments
    (central-difference Jacobian)."""
    f = VectorField(system, Index1(), state.chart)
    n_q, n_v = system.n_q, system.n_v
    rest = np.zeros(n_v)

    def residual(q):
        acc = f(0.0, np.concatenate([q, rest]))[n_q:]
        cfg = body_state(system, q, rest, state.chart)
        return np.concatenate([acc, constraint_residual(system.joints, cfg)])

    q = state.q
    for _ in range(iterations):
        J = np.column_stack([(residual(retract(system, q, 1e-6 * e, state.chart))
                              - residual(retract(system, q, -1e-6 * e, state.chart))) / 2e-6 for e in np.eye(n_v)])
        q = retract(system, q, -np.linalg.lstsq(J, residual(q), rcond=None)[0], state.chart)
    return q


def _tip(system, q, chart) -> np.ndarray:
    cfg = body_state(system, q, np.zeros(system.n_v), chart)
    fb = system.bodies.flexible[0]
    pts = material_points(fb.bar, np.array([L]))
    return point_positions(fb.bar, cfg.pose.W_r[fb.index], cfg.pose.R_WB[fb.index], cfg.eta[0], pts)[0]


def test_welded_bar_sags_as_the_clamped_cantilever(tmp_path):
    g = 1e-5
    system, state = _build(tmp_path, WELDED, g)
    q = _equilibrium(system, state)
    q_load = RHO * WIDTH * DEPTH * g
    exact = -q_load * L**4 / (8 * E * WIDTH * DEPTH**3 / 12)
    tip = _tip(system, q, state.chart)
    assert tip[2] == pytest.approx(exact, rel=STATIC_RTOL)
    assert abs(tip[0] - L) < 1e-3 * abs(exact) and abs(tip[1]) < 1e-12


# ---------------------------------------------------------------------------- stiff pendulum

PENDULUM_T = 0.3
SAMPLE_DT = 2e-3
#: Stiffness factors of the two runs: the deviation from the rigid swing must fall by their ratio.
FACTORS = (1.0, 10.0)
#: The deviation is the quasi-static slope at the pin plus the vibration excited by the release, both
#: O(1 / E); the next terms are O((omega_pendulum / omega_1)^2) ~ 1e-3 and the integration error
#: (rtol 1e-9) ~ 1e-8 rad against deviations of 1e-3..1e-4 rad: 15 % on the ratio.
RATIO_RTOL = 0.15


def _pendulum(tmp_path, factor: float):
    extra = 'modes = 2\n[[joints]]\nname = "pin"\ntype = "revolute"\nbody1 = "bar"\nx1 = 0.0\naxis = [0.0, 1.0, 0.0]\n'
    text = _bar(elements=2, extra=extra).replace(f"E = {E}", f"E = {E * factor}").replace(f"depth = {DEPTH}", "depth = 0.01")
    path = tmp_path / "pendulum.toml"
    path.write_text(f'[sim]\nt_end = {PENDULUM_T}\ndt = {SAMPLE_DT}\nintegrator = "dopri5"\nrtol = 1e-9\natol = 1e-12\n' + text)
    traj = viz3d.simulate(viz3d.load_scene(path))
    names = list(traj.extras["joint_coordinate_names"])
    return traj.t, traj.extras["joint_coordinates"][:, names.index("pin/angle")]


def _rigid_swing(t: np.ndarray) -> np.ndarray:
    """phi(t) of the rigid bar (mass m, I_O = m (L^2 / 3 + h^2 / 12) about the pin, d = L / 2) released
    horizontal: ``I_O phi'' = m g d cos(phi)``, phi the turn about +y (DOP853, rtol 1e-12)."""
    h, g = 0.01, 9.81
    I_over_m = L**2 / 3 + h**2 / 12
    sol = solve_ivp(lambda _, y: [y[1], g * (L / 2) * np.cos(y[0]) / I_over_m], (0, t[-1]), [0.0, 0.0],
                    method="DOP853", rtol=1e-12, atol=1e-14, t_eval=t)
    return sol.y[0]


@pytest.mark.slow
def test_stiff_flexible_pendulum_on_a_revolute_swings_as_the_rigid_one(tmp_path):
    deviations = []
    for factor in FACTORS:
        t, angle = _pendulum(tmp_path, factor)
        deviations.append(np.sqrt(np.mean((angle - _rigid_swing(t)) ** 2)))
    ratio = deviations[0] / deviations[1]
    assert ratio == pytest.approx(FACTORS[1] / FACTORS[0], rel=RATIO_RTOL), deviations
    assert deviations[1] < 1e-3

"""Fixed-step explicit Runge-Kutta methods advance Euler parameters on the group (Runge-Kutta-Munthe-Kaas,
``viz3d.integrators.explicit_rk.ExplicitRK``, ``viz3d.kernel.field.stages``), against references
nobody here wrote: the closed form of a constant spin, ``p(t) = p0 (x) exp(t B_omega)``, and scipy's
DOP853 on an independent quaternion formulation (``references.fixed_point_body``) for the tumbling
T-handle. The compiled steps take the NumPy path's to round-off: test_kernel_quaternion.py."""

import numpy as np
import pytest
from kernel_runs import EPS, run

import viz3d
from viz3d.dynamics import VectorField
from viz3d.integrators import make_integrator
from viz3d.scene.build import make_formulation

from conftest import SCENES
from references import fixed_point_body

#: Halving dt divides a fourth-order method's error by 2^4, within this many powers of 2 (the next term of
#: the error expansion is O(h) relative; a lost order is off by >= 1). As test_oracles.py.
ORDER_TOL = 0.4
#: The dt run's error must equal Richardson's estimate (16/15) |y_dt - y_dt/2| within this fraction (the
#: next term of the error expansion, O(h) relative, and the reference's error). As test_oracles.py.
RICHARDSON_TOL = 0.1
#: Round-off of one step of a constant spin, in eps: the increment h sum b_i K_i (4 terms, each K_i = omega
#: to a few eps, the dexpinv terms being crosses of parallel vectors), its unit quaternion (sin, cos, a
#: product) and the product with p (four products and three sums per component), then the normalisation.
SPIN_STEP_EPS = 16

SPIN = """
[sim]
t_end = 2.0
dt = 0.05
gravity = [0.0, 0.0, 0.0]
rotation = "quaternion"

[[bodies]]
name = "ball"
shape = {{ type = "sphere", radius = 0.1 }}
density = 1000.0
position = [0.0, 0.0, 0.0]
omega = [{w0}, {w1}, {w2}]
"""


def _quat_mul(p, q):
    return np.concatenate([[p[0] * q[0] - p[1:] @ q[1:]], p[0] * q[1:] + q[0] * p[1:] + np.cross(p[1:], q[1:])])


@pytest.mark.parametrize("compiled", [True, False])
def test_constant_spin_is_exact_to_roundoff(write_scene, compiled):
    """A sphere spinning at 5 rad/s about a skew axis, 40 RK4 steps of h |omega| = 0.25: RK4 on p_dot = 1/2
    p (x) omega is off by ~(h |omega| / 2)^5 / 120 per step (1e-5 here); the group step is exact but for
    round-off: ``SPIN_STEP_EPS`` per step, plus the drift of omega from the rounding of omega x I omega (~eps
    |omega|^2 [rad/s^2], turning p by ~eps |omega|^2 t^2 / 2 by t)."""
    omega = np.array([3.0, -4.0, 0.0]) / 5.0 * 4.0 + np.array([0.0, 0.0, 3.0])  # |omega| = 5 rad/s
    scene = viz3d.load_scene(write_scene(SPIN.format(w0=omega[0], w1=omega[1], w2=omega[2])))
    system, state = viz3d.build(scene)
    n, dt = 40, 0.05
    sim = run(system, state, make_formulation(scene.data["sim"]), n, dt, compiled=compiled)
    assert sim.n_steps == n
    t = n * dt
    p0 = system.split_q(state.q)[1][0]
    a = np.linalg.norm(omega) * t
    closed = _quat_mul(p0, np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * omega / np.linalg.norm(omega)]))
    p = system.split_q(sim.state.q)[1][0]
    bound = (SPIN_STEP_EPS * n + np.linalg.norm(omega) ** 2 * t * t / 2) * EPS
    err = min(np.abs(p - closed).max(), np.abs(p + closed).max())
    assert err <= bound, f"p after {n} steps of a constant spin: {err:.2e} from the closed form > {bound:.2e}"


def test_group_step_keeps_unit_quaternions():
    """One RK4 step of the tumbling T-handle (h |omega| = 0.1) from unit Euler parameters, before any
    normalisation, ten times: |p| stays 1 to the rounding of a product of unit quaternions (4 eps a step),
    where RK4 on p_dot moves it by ~(h |omega| / 2)^5 / 120 (3e-9) a step."""
    scene = viz3d.load_scene(SCENES / "torque_free.toml", ["sim.rotation=quaternion"])
    system, state = viz3d.build(scene)
    field = VectorField(system, make_formulation(scene.data["sim"]), state.chart)
    y = state.y
    for j in range(1, 11):
        y = make_integrator("rk4").step(field, 0.0, y, 4e-3).y
        p = system.split_q(y[: system.n_q])[1][0]
        assert abs(np.linalg.norm(p) - 1.0) <= 4 * EPS * j, f"|p| - 1 = {np.linalg.norm(p) - 1.0:.2e} after {j} steps"


def test_tumbling_body_converges_at_fourth_order_to_dop853():
    """The T-handle flipping about its intermediate axis (omega's direction swings through 180 degrees),
    3 s in the compiled kernel, RK4 at dt 4e-3 and 2e-3 against scipy's DOP853 at rtol 1e-11 on the
    body's free rotation: fourth order, and the error is what Richardson's estimate says."""
    errors, runs = [], []
    for dt in (4e-3, 2e-3):
        traj = viz3d.simulate(SCENES / "torque_free.toml", ["sim.output_dt=0.02", "sim.rotation=quaternion",
                                                            "sim.integrator=rk4"], t_end=3.0, dt=dt)
        assert traj.ok, traj.status
        assert traj.scene["run"]["kernel"] == "compiled kernel"
        R_ref = fixed_point_body(traj.inertia_body[0], traj.mass[0], np.zeros(3), np.zeros(3), traj.rotation[0, 0],
                                 traj.omega[0, 0], traj.t)[0]
        errors.append(np.abs(traj.rotation[:, 0] - R_ref).max())
        runs.append((traj.t, traj.rotation[:, 0]))
    common = np.isin(np.round(runs[1][0], 9), np.round(runs[0][0], 9))
    estimate = 16 / 15 * np.abs(runs[0][1] - runs[1][1][common]).max()
    assert abs(errors[0] / estimate - 1) < RICHARDSON_TOL, (errors[0], estimate)
    assert abs(np.log2(errors[0] / errors[1]) - 4) < ORDER_TOL, errors

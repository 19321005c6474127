"""Convergence order of every registered integrator, energy drift like h^4 for RK4, constraint
drift with and without stabilization, exact chart switches."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

import viz3d
from viz3d.coordinates import CHART_CENTRE, EulerSwitching
from viz3d.dynamics import VectorField
from viz3d.formulation import Index1
from viz3d.integrators import INTEGRATORS, make_integrator
from viz3d.simulate import Simulation

from conftest import SCENES

ORDER_TOL = 0.3
T_ORDER = 0.25  # s of the spatial double pendulum (its charts need no switch before 0.4 s)
#: Coarsest step count per order, so that four halvings stay in the asymptotic range.
COARSEST = {1: 400, 2: 50, 3: 25, 4: 12}


def _pose(system, q, chart):
    W_r, theta = system.split_q(q)
    return W_r, system.rotation.matrix(theta, chart)


@pytest.fixture(scope="module")
def double_pendulum_reference():
    system, state = viz3d.build(viz3d.load_scene(SCENES / "double_pendulum.toml"))
    rhs = VectorField(system, Index1(), state.chart)
    sol = solve_ivp(rhs, (0.0, T_ORDER), state.y, method="DOP853", rtol=1e-13, atol=1e-13)
    assert np.abs(np.sin(sol.y[: system.n_q].reshape(system.n_bodies, 6, -1)[:, 4])).min() > 0.5, "fixed chart went singular"
    return system, state, _pose(system, sol.y[: system.n_q, -1], state.chart)


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_convergence_order_matches_declared_order(name, double_pendulum_reference):
    system, state, (r_ref, R_ref) = double_pendulum_reference
    integrator = make_integrator(name)
    n0 = COARSEST.get(integrator.order, 8)
    steps, errors = [], []
    for n in (n0, 2 * n0, 4 * n0, 8 * n0):
        sim = Simulation(system, state, integrator, Index1(), T_ORDER / n)
        for _ in range(n):
            sim.step()
        r, R = _pose(system, sim.state.q, sim.state.chart)
        steps.append(T_ORDER / n)
        errors.append(max(np.abs(r - r_ref).max(), np.abs(R - R_ref).max()))
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - integrator.order) <= ORDER_TOL, f"{name}: slope {slope:.2f}, errors {errors}"


def test_rk4_energy_drift_falls_like_h4():
    drifts = [viz3d.simulate(SCENES / "spherical_pendulum.toml", t_end=2.0, dt=dt).energy_drift for dt in (4e-3, 2e-3, 1e-3)]
    slope = np.polyfit(np.log([4e-3, 2e-3, 1e-3]), np.log(drifts), 1)[0]
    assert 3.7 < slope < 4.3, f"energy drift {drifts} falls with slope {slope:.2f}"


def test_stabilization_controls_constraint_drift():
    """A 10-link chain at a coarse step: index-1 drifts; Baumgarte holds it; projection removes it."""
    runs = {f: viz3d.simulate(SCENES / "chain.toml", [f"sim.formulation={f}"], t_end=1.0, dt=2e-3)
            for f in ("index1", "baumgarte", "projection")}
    drift = {f: t.max_constraint_violation for f, t in runs.items()}
    assert all(t.ok for t in runs.values()), {f: t.status for f, t in runs.items()}
    assert drift["index1"] > 1e-6, drift                      # visible by design
    assert drift["baumgarte"] < drift["index1"] / 10, drift
    assert drift["projection"] < 1e-11, drift


def test_chart_switch_keeps_orientation_exactly():
    rot = EulerSwitching()
    rng = np.random.default_rng(0)
    chart = Rotation.random(6, random_state=1).as_matrix()
    theta = np.column_stack([rng.uniform(-3, 3, 6), [0.01, 0.2, 3.1, 3.0, 1.0, 2.0], rng.uniform(-3, 3, 6)])
    new_theta, new_chart, switched = rot.rechart(theta, chart)
    np.testing.assert_array_equal(switched, [True, True, True, True, False, False])
    np.testing.assert_allclose(rot.matrix(new_theta, new_chart), rot.matrix(theta, chart), atol=1e-15)
    np.testing.assert_array_equal(new_theta[switched], np.tile(CHART_CENTRE, (4, 1)))


def test_body_starting_exactly_at_zero_nutation():
    """The seed's failure case: a top standing exactly upright (theta = 0) at t = 0."""
    traj = viz3d.simulate(SCENES / "heavy_top.toml", {
        "bodies.top.euler_deg": [0.0, 0.0, 0.0], "bodies.top.position": [0.0, 0.0, 0.15],
        "bodies.top.omega": [0.0, 0.0, 60.0]}, t_end=0.5)
    assert traj.ok, traj.status
    np.testing.assert_allclose(traj.position[:, 0], np.tile([0.0, 0.0, 0.15], (len(traj.t), 1)), atol=1e-12)
    np.testing.assert_allclose(traj.omega[:, 0], np.tile([0.0, 0.0, 60.0], (len(traj.t), 1)), atol=1e-9)

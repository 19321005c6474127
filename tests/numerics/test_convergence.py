"""Convergence order of every registered integrator (and of ALI3-P, which steps itself), energy
drift like h^4 for RK4, constraint drift with and without stabilization (ALI3-P and the penalty
formulation included), exact chart switches."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

import viz3d
from viz3d.coordinates import CHART_CENTRE, EulerSwitching
from viz3d.dynamics import VectorField
from viz3d.formulation import ALI3P, Index1
from viz3d.integrators import INTEGRATORS, make_integrator
from viz3d.simulate import Simulation

from conftest import SCENES

#: Fitted slope of log error against log h, four runs: orders are integers, 0.3 admits the next term of the
#: error expansion on these step ranges (chosen in COARSEST to be asymptotic); a lost order is off by >= 1.
ORDER_TOL = 0.3
T_ORDER = 0.25  # s of the spatial double pendulum (its charts need no switch before 0.4 s)
#: Coarsest step count per order, so that the refinements stay in the asymptotic range.
COARSEST = {1: 400, 2: 50, 3: 25, 4: 12, 5: 6, 8: 5}
#: Horizons other than T_ORDER [s]. Order 5: DOPRI5's leading error coefficient is small on this
#: problem, and over 0.25 s (through the lower rod's slowest turn, |omega| = 1.2 rad/s at 0.2 s)
#: its global error stays in the h^6 regime down to the reference's accuracy (measured slopes
#: 5.5-5.65 for 6 to 96 steps, 2026-11-21); over the first 0.1 s it is asymptotic (5.0).
HORIZON = {5: 0.1}
#: Refinement factor between the four runs where it is not 2. Order 8 gains 256x per halving:
#: from the coarsest step in the asymptotic range (4e-10 with 5 steps of 0.05 s) three halvings
#: would end far below the reference's 1e-13, so the steps shrink by sqrt(2) (5, 7, 10, 14 steps,
#: down to 1.2e-13; measured slope 7.88, 2026-11-21).
REFINE = {8: np.sqrt(2.0)}
#: DOP853 reference tolerance (errors above are at least 1e3 x larger).
REF_TOL = 1e-13
#: Rotation matrices composed of a chart and Euler angles agree to this after a chart switch (20 eps).
MATRIX_ROUNDOFF = 20 * np.finfo(float).eps


def _pose(system, q, chart):
    W_r, theta = system.split_q(q)
    return W_r, system.rotation.matrix(theta, chart)


@pytest.fixture(scope="module")
def double_pendulum_reference():
    """``reference(T)``: system, initial state and the pose at ``T`` from scipy's DOP853."""
    system, state = viz3d.build(viz3d.load_scene(SCENES / "double_pendulum.toml"))
    cache = {}

    def reference(T):
        if T not in cache:
            rhs = VectorField(system, Index1(), state.chart)
            sol = solve_ivp(rhs, (0.0, T), state.y, method="DOP853", rtol=REF_TOL, atol=REF_TOL)
            nutation = sol.y[: system.n_q].reshape(system.n_bodies, 6, -1)[:, 4]
            assert np.abs(np.sin(nutation)).min() > 0.5, "fixed chart went singular"
            cache[T] = _pose(system, sol.y[: system.n_q, -1], state.chart)
        return system, state, cache[T]

    return reference


def _errors(reference, make_sim, T, counts):
    system, state, (r_ref, R_ref) = reference(T)
    errors = []
    for n in counts:
        sim = make_sim(system, state, T / n)
        for _ in range(n):
            sim.step()
        r, R = _pose(system, sim.state.q, sim.state.chart)
        errors.append(max(np.abs(r - r_ref).max(), np.abs(R - R_ref).max()))
    return errors


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_convergence_order_matches_declared_order(name, double_pendulum_reference):
    order = make_integrator(name).order
    T, n0, refine = HORIZON.get(order, T_ORDER), COARSEST.get(order, 8), REFINE.get(order, 2.0)
    counts = [int(round(n0 * refine**k)) for k in range(4)]
    errors = _errors(double_pendulum_reference, lambda system, state, dt: Simulation(
        system, state, make_integrator(name), Index1(), dt), T, counts)
    slope = np.polyfit(np.log(T / np.array(counts)), np.log(errors), 1)[0]
    assert abs(slope - order) <= ORDER_TOL, f"{name}: slope {slope:.2f}, steps {counts}, errors {errors}"


@pytest.mark.parametrize("compiled", [True, False], ids=["kernel", "numpy"])
def test_ali3p_converges_at_second_order(double_pendulum_reference, compiled):
    """ALI3-P steps itself (the trapezoidal rule on R^3 x SO(3)): order 2, like its integrator, on
    both paths (``viz3d.kernel.ali3p`` and the NumPy reference)."""
    counts = [COARSEST[2] * 2**k for k in range(4)]
    sims = []

    def make(system, state, dt):
        sims.append(Simulation(system, state, make_integrator("trapezoidal"), ALI3P(), dt, compiled=compiled))
        return sims[-1]

    errors = _errors(double_pendulum_reference, make, T_ORDER, counts)
    assert all((s.kernel_note == "compiled kernel") == compiled for s in sims)
    slope = np.polyfit(np.log(T_ORDER / np.array(counts)), np.log(errors), 1)[0]
    assert abs(slope - 2) <= ORDER_TOL, f"ali3p: slope {slope:.2f}, errors {errors}"


def test_rk4_energy_drift_falls_like_h4():
    # index-1: RK4's own drift (a projection after each step changes the energy by its own O(h^4) terms)
    drifts = [viz3d.simulate(SCENES / "spherical_pendulum.toml", ["sim.formulation=index1"], t_end=2.0, dt=dt).energy_drift
              for dt in (4e-3, 2e-3, 1e-3)]
    slope = np.polyfit(np.log([4e-3, 2e-3, 1e-3]), np.log(drifts), 1)[0]
    assert abs(slope - 4) < ORDER_TOL, f"energy drift {drifts} falls with slope {slope:.2f}"


def test_stabilization_controls_constraint_drift():
    """A 10-link chain at a coarse step: index-1 drifts; Baumgarte holds it; projection removes it."""
    runs = {f: viz3d.simulate(SCENES / "chain.toml", [f"sim.formulation={f}"], t_end=1.0, dt=2e-3)
            for f in ("index1", "baumgarte", "projection")}
    drift = {f: t.max_constraint_violation for f, t in runs.items()}
    assert all(t.ok for t in runs.values()), {f: t.status for f, t in runs.items()}
    assert drift["index1"] > INDEX1_VISIBLE_C, drift          # visible by design
    assert drift["baumgarte"] < drift["index1"] / 10, drift
    assert drift["projection"] < PROJECTED_MAX_C, drift


#: ALI3-P iterates until max |C| <= sim.projection_tol = 1e-12 m; the test allows 100x that.
ALI3P_MAX_C = 1e-10
#: Projection after each step: max |C| <= sim.projection_tol = 1e-12 m, 10x that.
PROJECTED_MAX_C = 1e-11
#: Index-1 drift on the same run must be visible: at least this [m]. It is RK4's truncation error at
#: dt = 2e-3 [3.7e-6 m, 2026-11-21], a property of the method (round-off is ~1e-13 m); a lower bound below it.
INDEX1_VISIBLE_C = 1e-6


def test_ali3p_holds_the_chain_on_its_joints_where_index1_drifts():
    """10-link chain, dt = 2e-3 s, 1 s: RK4 + index-1 drifts off the joints, ALI3-P does not."""
    runs = {m: viz3d.simulate(SCENES / "chain.toml", over, t_end=1.0, dt=2e-3) for m, over in (
        ("rk4+index1", ["sim.integrator=rk4", "sim.formulation=index1"]),
        ("ali3p", ["sim.integrator=trapezoidal", "sim.formulation=ali3p"]))}
    assert all(t.ok for t in runs.values()), {m: t.status for m, t in runs.items()}
    drift = {m: t.max_constraint_violation for m, t in runs.items()}
    assert drift["rk4+index1"] > INDEX1_VISIBLE_C, drift
    assert drift["ali3p"] < ALI3P_MAX_C, drift
    assert drift["ali3p"] < drift["rk4+index1"] / 1e4, drift


#: |C| stays below its bound max |lam| / (alpha omega^2) (an exact bound, see the test; 0.78 of it seen) ...
PENALTY_BOUND_MARGIN = 1.0
#: ... and is the penalty's compliance, not integration error: at least this fraction of it (the bound
#: is reached when lam holds its maximum for longer than 1 / omega; 0.5 says the compliance dominates).
PENALTY_MIN_FRACTION = 0.5


@pytest.mark.parametrize("alpha", [1e3, 1e4])
def test_penalty_violation_is_bounded_by_its_compliance(alpha):
    """Seed 004 eq. 3.16 with xi = 1: the violation obeys C_dd + 2 omega C_d + omega^2 C = lam /
    alpha, whose impulse response is positive with integral 1 / omega^2, so starting on the joints
    |C| <= max |lam| / (alpha omega^2) (all rows, all times: a weaker, still exact bound)."""
    omega = 10.0
    traj = viz3d.simulate(SCENES / "double_pendulum.toml", [
        "sim.formulation=penalty", f"sim.penalty_alpha={alpha}", f"sim.penalty_omega={omega}", "sim.penalty_xi=1",
        "sim.output_dt=1e-3"], t_end=1.0, dt=1e-3)
    assert traj.ok, traj.status
    bound = np.abs(traj.reaction_force).max() / (alpha * omega**2)
    assert PENALTY_MIN_FRACTION * bound <= traj.max_constraint_violation <= PENALTY_BOUND_MARGIN * bound, \
        (traj.max_constraint_violation, bound)


def test_chart_switch_keeps_orientation_exactly():
    rot = EulerSwitching()
    rng = np.random.default_rng(0)
    chart = Rotation.random(6, random_state=1).as_matrix()
    theta = np.column_stack([rng.uniform(-3, 3, 6), [0.01, 0.2, 3.1, 3.0, 1.0, 2.0], rng.uniform(-3, 3, 6)])
    new_theta, new_chart, switched = rot.rechart(theta, chart)
    np.testing.assert_array_equal(switched, [True, True, True, True, False, False])
    # each matrix is chart @ R(theta): entries <= 1, three products and sums each plus the trig: ~10 eps
    np.testing.assert_allclose(rot.matrix(new_theta, new_chart), rot.matrix(theta, chart), atol=MATRIX_ROUNDOFF)
    np.testing.assert_array_equal(new_theta[switched], np.tile(CHART_CENTRE, (4, 1)))


def test_body_starting_exactly_at_zero_nutation():
    """The seed's failure case: a top standing exactly upright (theta = 0) at t = 0."""
    traj = viz3d.simulate(SCENES / "heavy_top.toml", {
        "bodies.top.euler_deg": [0.0, 0.0, 0.0], "bodies.top.position": [0.0, 0.0, 0.15],
        "bodies.top.omega": [0.0, 0.0, 60.0]}, t_end=0.5)
    assert traj.ok, traj.status
    # the exact motion is a steady spin; 500 steps of round-off, n eps |y|, are 1.7e-14 m and 7e-12 rad/s:
    # 60x and 150x that (a top leaving its axis is off by > 1e-3)
    np.testing.assert_allclose(traj.position[:, 0], np.tile([0.0, 0.0, 0.15], (len(traj.t), 1)), atol=1e-12)
    np.testing.assert_allclose(traj.omega[:, 0], np.tile([0.0, 0.0, 60.0], (len(traj.t), 1)), atol=1e-9)

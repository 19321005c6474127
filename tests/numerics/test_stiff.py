"""Implicit methods on a stiff spring pendulum (scenes/stiff_spring.toml: axial mode at 1000
rad/s under a 1 Hz swing) at a step where RK4 diverges, against scipy's Radau (an implicit
reference nobody here wrote) on the same equations in unit quaternions."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import viz3d
from viz3d.dynamics import VectorField
from viz3d.formulation import Index1
from viz3d.methods import method_overrides

from conftest import SCENES

SCENE = SCENES / "stiff_spring.toml"
T_END = 1.0     # s
DT = 5e-3       # s: h omega = 5 on the axial mode; RK4 is stable below h omega = 2.8 (measured:
                # runs at 2.8 ms, diverges at 3 ms)
#: Reference tolerance; it agrees with rtol 1e-10 to 1.3e-12 m, far below the methods' errors.
REF_RTOL = 1e-8
#: The methods are second order: halving DT divides the position error by 2^2, within this many powers
#: of 2 (the unresolved axial mode barely enters the swing, so the swing's error is asymptotic already).
ORDER_TOL = 0.4
#: Runs at DT and DT/2 give Richardson's estimate of the DT run's error, (4/3) |y_DT - y_DT/2|; the
#: distance to Radau must equal it within this fraction: what is left is the next term of the error
#: expansion, O(h) relative (1e-4 seen), and the reference's error (< 1e-11 m); a modelling difference is not.
RICHARDSON_TOL = 0.1
#: The spring-damper only dissipates: no method may gain more energy than this [J] (of 3.9 J). The
#: trapezoidal updates are not exactly conservative on this nonlinear system (gains 6.6e-8 J trapezoidal,
#: 2.2e-7 J ALI3-P, none gen_alpha: truncation-level, deterministic); a diverging method gains joules.
#: 1e-5 J = 2.6e-6 E separates the two (45x the largest gain seen).
ENERGY_GAIN_TOL = 1e-5


@pytest.fixture(scope="module")
def reference():
    system, state = viz3d.build(viz3d.load_scene(SCENE, ["sim.rotation=quaternion"]))
    rhs = VectorField(system, Index1(), state.chart)
    t = np.round(np.arange(0.0, T_END + 1e-9, 0.01), 10)
    sol = solve_ivp(rhs, (0.0, T_END), state.y, method="Radau", rtol=REF_RTOL, atol=REF_RTOL * 1e-2, t_eval=t)
    assert sol.success, sol.message
    return sol.y[:3].T  # centre of mass [m], the first three coordinates of the one body


def test_rk4_diverges_at_this_step_and_says_so():
    traj = viz3d.simulate(SCENE, ["sim.integrator=rk4"], t_end=T_END, dt=DT)
    assert not traj.ok
    assert "'block'" in traj.status and "sim.dt" in traj.status, traj.status
    assert np.all(np.isfinite(traj.position)) and np.all(np.isfinite(traj.velocity))


@pytest.mark.parametrize("method", ["trapezoidal", "gen_alpha", "ali3p", "gen_alpha+quaternion"])
def test_implicit_methods_run_stably_where_rk4_diverges(method, reference):
    runs = [viz3d.simulate(SCENE, method_overrides(method) + ["sim.output_dt=0.01"], t_end=T_END, dt=dt)
            for dt in (DT, DT / 2)]
    for traj in runs:
        assert traj.ok, traj.status
        E = traj.energy_total
        assert E.max() - E[0] <= ENERGY_GAIN_TOL, E.max() - E[0]
    coarse, fine = (traj.position[:, 0] for traj in runs)
    errors = [np.abs(x - reference[: len(x)]).max() for x in (coarse, fine)]
    estimate = 4 / 3 * np.abs(coarse - fine).max()
    assert abs(errors[0] / estimate - 1) < RICHARDSON_TOL, (errors[0], estimate)
    assert abs(np.log2(errors[0] / errors[1]) - 2) < ORDER_TOL, errors

"""``viz3d bench`` and ``viz3d stability`` against references nobody here wrote: the bench
reference against scipy's DOP853 on an independent quaternion formulation; the largest stable
RK4 step against the closed-form stability limit of RK4 on the linearized stiff force; failure
reasons reproduced deterministically (divergence, gimbal lock, missed contact) and located where
the physics puts them."""

import numpy as np
import pytest

import viz3d
from viz3d.bench import bench, reference_run
from viz3d.stability import GAP_FRACTION, contact_windows, largest_stable_step, reason_of, stability

from conftest import SCENES
from references import fixed_point_body

#: RK4's stability interval on the imaginary axis: |h omega| <= 2 sqrt(2).
RK4_LIMIT = 2.0 * np.sqrt(2.0)


@pytest.fixture(scope="module")
def torque_free_scipy():
    """The bench reference of torque_free (2 s, frames every 0.01 s) and scipy DOP853 at rtol 1e-12
    on the body's free rotation in unit quaternions (its centre moves uniformly, no gravity)."""
    ref = reference_run(SCENES / "torque_free.toml", [], 0.01, 2.0)
    R, W_omega, _ = fixed_point_body(ref.inertia_body[0], ref.mass[0], np.zeros(3), np.zeros(3), ref.rotation[0, 0],
                                     ref.omega[0, 0], ref.t, rtol=1e-12, atol=1e-14)
    return ref, R, W_omega


def test_bench_reference_agrees_with_scipy_dop853_on_the_torque_free_body(torque_free_scipy):
    ref, R, W_omega = torque_free_scipy
    assert ref.ok, ref.status
    w = np.linalg.norm(ref.omega[0, 0])
    assert np.abs(ref.rotation[:, 0] - R).max() < 1e-9  # [measured 6.8e-11; omega 3.2e-11 relative]
    assert np.abs(ref.omega[:, 0] - W_omega).max() < 1e-9 * w
    # the body does flip within the run (the reference is not a trivial steady spin)
    B_omega = np.einsum("nji,nj->ni", R, W_omega)
    assert np.ptp(B_omega, axis=0).max() > w


def test_bench_errors_are_distances_to_that_reference(torque_free_scipy):
    ref, R, _ = torque_free_scipy
    report = bench(SCENES / "torque_free.toml", ["rk4"], dts=[4e-3, 2e-3], t_end=2.0, progress=False)
    assert report.reference_self < 1e-9
    errors = [row.error for row in report.rows]
    assert all(row.status == "ok" for row in report.rows)
    # the same runs measured against scipy's solution instead
    r_g = np.sqrt(np.trace(ref.inertia_body[0]) / (2 * ref.mass[0]))
    for row in report.rows:
        assert row.steps == round(2.0 / float(row.setting.split("=")[1]))
    assert errors[0] > errors[1] > 0
    assert 12 < errors[0] / errors[1] < 20  # RK4: halving the step divides the error by about 16
    scipy_err = r_g * np.abs(ref.rotation[:, 0] - R).max()
    assert scipy_err < 1e-3 * errors[1]  # the reference is far more accurate than any run


def _hertz_rk4_limit(K, m, v):
    """RK4's largest stable step on a Hertz contact F = K delta^1.5 struck at speed v by mass m:
    2 sqrt(2) / omega at the deepest indentation delta_max = (5 m v^2 / (4 K))^(2/5), where the
    linearized contact stiffness 1.5 K delta^0.5 is largest."""
    delta = (5.0 * m * v**2 / (4.0 * K)) ** 0.4
    return RK4_LIMIT / np.sqrt(1.5 * K * np.sqrt(delta) / m)


@pytest.mark.parametrize("K", [1e8, 1e10])
def test_rk4_stable_step_on_stiff_hertz_contact_is_its_linear_stability_limit(K):
    scene = SCENES / "stiff_contact.toml"
    over = ["sim.integrator=rk4", f"forces.floor.stiffness={K:g}"]
    dt, reason, detail = largest_stable_step(scene, over, 0.1)
    m = 7850.0 * 4.0 / 3.0 * np.pi * 0.02**3
    v = np.sqrt(2 * 9.81 * 0.005)  # dropped 5 mm
    limit = _hertz_rk4_limit(K, m, v)
    assert 0.9 * limit < dt < 1.1 * limit, (dt, limit)  # [measured 0.97-0.98 of the limit]
    assert reason == "diverged" and "energy grew" in detail and "'ball'" in detail, detail


def test_rk4_beyond_its_limit_on_a_stiff_contact_is_reported_diverged_and_implicit_methods_are_not():
    scene = SCENES / "stiff_contact.toml"
    dt = 3.0 * _hertz_rk4_limit(2.2e10, 7850.0 * 4.0 / 3.0 * np.pi * 0.02**3, np.sqrt(2 * 9.81 * 0.005))
    traj = viz3d.simulate(scene, ["sim.integrator=rk4"], t_end=0.1, dt=dt)
    assert reason_of(traj)[0] == "diverged", traj.status
    assert "t = 0.03" in traj.status  # at the first impact (the ball falls 5 mm in 32 ms)
    assert np.all(np.isfinite(traj.position)) and traj.t[-1] > 0.03  # frames up to the failure kept
    for method in ("trapezoidal", "gen_alpha"):
        traj = viz3d.simulate(scene, [f"sim.integrator={method}"], t_end=0.1, dt=dt)
        assert traj.ok, traj.status


def test_implicit_methods_lift_rk4s_limit_on_a_stiff_spring():
    """Spring 1e8 N/m on 1 kg: omega = 1e4 rad/s (damping ratio 1e-4), RK4 stable below 2.83e-4 s."""
    scene = SCENES / "stiff_spring.toml"
    dt, reason, _ = largest_stable_step(scene, ["sim.integrator=rk4", "forces.spring.stiffness=1e8"], 0.5)
    assert 0.97 * RK4_LIMIT / 1e4 < dt < 1.03 * RK4_LIMIT / 1e4, dt  # [measured 2.82e-4]
    assert reason in ("diverged", "unresolved rotation")
    for method in ("trapezoidal", "gen_alpha"):
        dt_implicit, *_ = largest_stable_step(scene, [f"sim.integrator={method}", "forces.spring.stiffness=1e8"], 0.5)
        assert dt_implicit > 10 * dt, (method, dt_implicit)  # [measured 36x trapezoidal, 45x gen_alpha]


def test_methods_map_through_theta_zero_finds_the_gimbal_lock_where_the_axis_is_vertical():
    report = stability(SCENES / "top_through_vertical.toml", ["rk4+euler_zxz", "rk4+euler_switching", "rk4+quaternion"],
                       None, 5e-4, 0.3)
    rows = {r.method: r for r in report.rows}
    zxz = rows["rk4+euler_zxz"]
    assert zxz.reason == "singular" and "gimbal lock" in zxz.detail, zxz.detail
    # the reference's axis is nearest the vertical at the first pass, where plain angles fail
    ref = reference_run(SCENES / "top_through_vertical.toml", ["sim.rotation=quaternion"], 5e-4, 0.3)
    theta = np.arccos(np.clip(ref.rotation[:, 0, 2, 2], -1.0, 1.0))
    first_pass = ref.t[np.argmin(np.where(ref.t < 0.2, theta, np.inf))]
    assert abs(zxz.t_fail - first_pass) < 0.01, (zxz.t_fail, first_pass)
    for method in ("rk4+euler_switching", "rk4+quaternion"):
        assert rows[method].reason == "ok", rows[method].detail
        assert rows[method].error < 1e-5  # [5.6e-7 and 4.3e-7 m]


def test_constraint_drift_grows_without_stabilization_and_not_with_it():
    report = stability(SCENES / "chain.toml", ["rk4", "rk4+baumgarte", "rk4+projection", "ali3p"], None, 2e-3, 2.0,
                       overrides=["chain.n=5"])
    C = {r.method: r.constraint for r in report.rows}
    assert all(r.reason == "ok" for r in report.rows), [(r.method, r.detail) for r in report.rows]
    # [measured: rk4 4.5e-5 m, baumgarte 2.2e-6 m, projection 2.2e-13 m, ali3p ~1e-14 m]
    assert C["rk4+projection"] < 1e-10 and C["ali3p"] < 1e-10
    assert C["rk4"] > 10 * C["rk4+baumgarte"] and C["rk4"] > 1e4 * max(C["rk4+projection"], C["ali3p"])
    t, drift, _ = report.histories["rk4"]
    assert drift[-1] > drift[len(t) // 4]  # it grows along the run


def test_impact_map_misses_the_second_contact_with_too_few_modes():
    """Clamped bar, beta = 1 (thesis 4.5): the exact solution separates at 1.534 T, touches again
    at 2.125 T and leaves for good at 2.163 T (T = 2 L / c). One mode misses the second contact;
    enough modes find both where the exact solution has them."""
    scene = SCENES / "impact_clamped_bar.toml"
    report = stability(scene, [], "bar.modes=1,16,60", None, None)
    rows = {r.value: r for r in report.rows}
    assert rows["1"].reason == "missed contact" and rows["1"].extra["contacts"] == 1, rows["1"].detail
    assert rows["16"].reason == "ok" and rows["60"].reason == "ok"
    finest = viz3d.simulate(scene, ["bar.modes=60"])
    c = finest.extras["contacts"]
    windows = contact_windows(c, GAP_FRACTION * (np.nanmax(c[:, [0, 2]]) - c[0, 0]))
    T = 2 * 0.3 / np.sqrt(210e9 / 7900)  # L = 0.3 m, steel
    assert len(windows) == 2
    np.testing.assert_allclose(np.array(windows) / T, [[0.0, 1.534], [2.125, 2.163]], atol=0.03)

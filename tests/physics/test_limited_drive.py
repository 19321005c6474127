"""A limited drive (``[[drives]]`` with ``servo_gain``: ``viz3d.forces.DriveServo``) hauling a mass up
a vertical prismatic joint, against closed forms written here from ``m x'' = f - m g`` with
``f = clip(g_s (v0 - x'), -F, F)``:

* below its capacity (``g_s v0 < F``, weight ``m g < F``) the speed rises as
  ``x'(t) = v_ss (1 - exp(-t / tau))``, ``tau = m / g_s``, to ``v_ss = v0 - m g / g_s`` (the tracking
  error is the weight over the gain), ``x(t) = v_ss (t - tau (1 - exp(-t / tau)))``, and the effort
  ``g_s (v0 - x')`` falls from ``g_s v0`` to ``m g``;
* with a weight above its capacity it stalls: the effort is ``F`` and the mass falls with the constant
  net force, ``x(t) = (F / m - g) t^2 / 2``;
* the effort never exceeds the capacity; the energy ledger (work in = the drive's ``f x'``) closes;
* kernel and NumPy paths give the same run; a run whose drive stays at its capacity for
  ``capacity_time`` ends there cleanly (status ok), the ``CapacityWatch``'s rule for a drive that
  stalls.

Tolerances. RK4 on the servo's pole ``z = -h / tau``: its local error on the decaying transient is
``|exp(z) - R(z)| <= |z|^5 / 120`` of it per step, summed over the ``tau / h = 1 / |z|`` steps in which
it matters: at most ``|z|^4 / 120 v_ss`` in the speed (and ``tau`` times that in the position); the
saturated motion is a quadratic, which RK4 integrates exactly (round-off: 1e-12 relative).
"""

from __future__ import annotations

import numpy as np
import pytest

import viz3d

G = 9.81


def _scene(m: float, gain: float, v0: float, capacity: float, capacity_time: float = 10.0) -> str:
    """The hoist; ``capacity_time`` beyond the runs' ends unless given (at the capacity that long, a
    run ends: ``CapacityWatch``)."""
    return f"""
[sim]
gravity = [0.0, 0.0, {-G}]

[[bodies]]
name = "load"
mass = {m}
inertia = [0.1, 0.1, 0.1]
position = [0.0, 0.0, 0.0]

[[joints]]
name = "guide"
type = "prismatic"
body1 = "load"
axis = [0.0, 0.0, 1.0]

[[drives]]
name = "hoist"
joint = "guide"
mode = "velocity"
value = {v0}
servo_gain = {gain}
capacity = {capacity}
capacity_time = {capacity_time}
"""


def _run(tmp_path, text: str, t_end: float, dt: float, compiled: bool = True, output_dt: float = 0.01):
    path = tmp_path / "hoist.toml"
    path.write_text(text)
    scene = viz3d.load_scene(path, [f"sim.t_end={t_end}", f"sim.dt={dt}", f"sim.output_dt={output_dt}",
                                    f"sim.compiled={str(compiled).lower()}"])
    traj = viz3d.simulate(scene)
    assert traj.status == "ok", traj.status
    k = list(traj.extras["joint_coordinate_names"]).index("guide/distance")
    x, v = traj.extras["joint_coordinates"][:, k], traj.extras["joint_coordinate_rates"][:, k]
    effort = traj.extras["drive_effort"][:, list(traj.extras["drive_names"]).index("hoist")]
    return traj, x, v, effort


M, GAIN, V0, DT = 10.0, 1e4, 0.05, 1e-4     # tau = 1 ms, z = -0.1; g_s v0 = 500 N, m g = 98.1 N


@pytest.mark.parametrize("compiled", [True, False], ids=["kernel", "numpy"])
def test_below_its_capacity_it_tracks_the_speed_less_the_weight_over_the_gain(tmp_path, compiled):
    F = 1000.0
    traj, x, v, effort = _run(tmp_path, _scene(M, GAIN, V0, F), t_end=0.02, dt=DT, compiled=compiled,
                              output_dt=DT * 10)
    t, tau = traj.t, M / GAIN
    v_ss = V0 - M * G / GAIN
    z = DT / tau
    tol_v = 10 * z**4 / 120 * v_ss
    np.testing.assert_allclose(v, v_ss * (1 - np.exp(-t / tau)), rtol=0, atol=tol_v)
    np.testing.assert_allclose(x, v_ss * (t - tau * (1 - np.exp(-t / tau))), rtol=0, atol=tol_v * tau + 1e-15)
    assert v[-1] == pytest.approx(v_ss, abs=tol_v)                    # the tracking error m g / g_s
    np.testing.assert_allclose(effort, GAIN * (V0 - v), rtol=1e-12)    # unsaturated: the servo law
    assert effort[-1] == pytest.approx(M * G, rel=1e-6)
    assert np.abs(effort).max() < F
    _ledger_closes(traj)


@pytest.mark.parametrize("compiled", [True, False], ids=["kernel", "numpy"])
def test_with_a_weight_above_its_capacity_it_stalls_and_gives_way_under_the_net_force(tmp_path, compiled):
    F = 0.5 * M * G
    traj, x, v, effort = _run(tmp_path, _scene(M, GAIN, V0, F), t_end=0.5, dt=1e-3, compiled=compiled)
    t = traj.t
    a = F / M - G                                                      # constant net force, downward
    np.testing.assert_allclose(x, 0.5 * a * t**2, rtol=0, atol=1e-12 * abs(a))
    np.testing.assert_allclose(v, a * t, rtol=0, atol=1e-12 * abs(a))
    assert np.all(effort == F)                                          # at its capacity, never over
    _ledger_closes(traj)


def test_kernel_and_numpy_runs_agree(tmp_path):
    """Across the knee (the effort starts saturated, g_s v0 > F, then drops below it as the speed
    rises): the same run on both paths to the round-off of its own arithmetic."""
    F = 300.0
    runs = [_run(tmp_path, _scene(M, GAIN, V0, F), t_end=0.02, dt=DT, compiled=c, output_dt=DT * 10) for c in (True, False)]
    (_, x1, v1, e1), (_, x2, v2, e2) = runs
    assert e1[0] == F and e1[-1] < F                                   # saturated, then tracking
    np.testing.assert_allclose(v1, v2, rtol=0, atol=1e-12 * V0)
    np.testing.assert_allclose(x1, x2, rtol=0, atol=1e-12 * V0 * 0.02)
    np.testing.assert_allclose(e1, e2, rtol=0, atol=1e-9 * F)


def test_a_drive_held_at_its_capacity_ends_the_run_cleanly(tmp_path):
    """The stalled hoist (weight above capacity) with capacity_time = 0.1 s: the run ends, status ok, at
    the first frame that has been at the capacity for 0.1 s, announcing the stall."""
    F = 0.5 * M * G
    traj, x, v, effort = _run(tmp_path, _scene(M, GAIN, V0, F, capacity_time=0.1), t_end=1.0, dt=1e-3)
    assert traj.t[-1] == pytest.approx(0.1)
    assert np.all(effort == F)


def _ledger_closes(traj, rel: float = 1e-6) -> None:
    """Work in (the drive's power integrated) = kinetic + potential change, to ``rel`` of the work in
    (the step's error)."""
    x = traj.extras
    work = x["energy_work_in"]
    assert np.abs(work).max() > 0.0
    assert np.abs(x["energy_balance_error"]).max() <= rel * np.abs(work).max()


@pytest.mark.parametrize("compiled", [True, False], ids=["kernel", "numpy"])
def test_a_gain_beyond_the_steps_stability_limit_stops_on_the_energy_ledger(tmp_path, compiled):
    """RK4 is stable on the servo's pole ``z = -g_s h / m`` for ``|z| < 2.785`` (the real-axis end of
    its stability region, where ``|R(z)| = 1``). At ``|z| = 2.9`` each step multiplies the velocity
    error by ``|R(z)| = 1.19``: the run stops at its first frame with the ledger's diagnosis (its
    work in no longer matches the energy it gave), long before any speed limit, and keeps that frame;
    at ``|z| = 1`` the same run balances."""
    dt, frame = 1e-3, 0.01
    path = tmp_path / "hoist.toml"
    for z, ok in ((2.9, False), (1.0, True)):
        path.write_text(_scene(M, z * M / dt, V0, 1e9))
        scene = viz3d.load_scene(path, ["sim.t_end=0.1", f"sim.dt={dt}", f"sim.output_dt={frame}",
                                        f"sim.compiled={str(compiled).lower()}"])
        traj = viz3d.simulate(scene)
        if ok:
            assert traj.status == "ok", traj.status
            # the ledger's error is RK4's on the start's transient, |z|^4 / 120 = 8e-3 of its kinetic energy
            # m v_ss^2 / 2 = 8e-3 J, against the work m g v_ss t_end = 0.39 J in 0.1 s: 2e-4 of it (5x margin)
            _ledger_closes(traj, 1e-3)
        else:
            assert traj.status.startswith(f"t = {frame:g} s: the energy ledger does not balance"), traj.status
            assert traj.t[-1] == pytest.approx(frame)

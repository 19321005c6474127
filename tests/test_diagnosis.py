"""Runs that cannot go on stop with a diagnosis (body, joint, time, quantity) and keep what
was computed; they never return a NaN trajectory."""

import numpy as np

import viz3d

STIFF = """
[sim]
t_end = 1.0
dt = {dt}
gravity = [0.0, 0.0, 0.0]

[[bodies]]
name = "bob"
shape = {{ type = "sphere", radius = 0.05 }}
density = 1000.0
position = [0.1, 0.0, 0.0]

[[bodies]]
name = "arm"
shape = {{ type = "box", extents = [0.2, 0.02, 0.02] }}
density = 1000.0
position = [0.0, 0.0, -0.5]

[[joints]]
name = "hinge"
body1 = "arm"
point = [-0.1, 0.0, -0.5]

[[forces]]
type = "spring_damper"
name = "very_stiff"
body1 = "bob"
point2 = [0.0, 0.0, 0.0]
local1 = [0.0, 0.0, 0.0]
stiffness = 1e7
rest_length = 0.0
"""


def test_divergence_names_body_time_and_quantity(write_scene):
    # bob: m = 0.524 kg on k = 1e7 N/m, omega = 4370 rad/s; omega h = 4.4 > 2 sqrt(2), beyond RK4 stability
    traj = viz3d.simulate(write_scene(STIFF.format(dt=1e-3)))
    assert not traj.ok
    assert "'bob'" in traj.status and "t = " in traj.status
    assert any(word in traj.status for word in ("speed", "non-finite"))
    assert len(traj.t) >= 1 and np.all(np.isfinite(traj.position))


def test_same_scene_with_a_small_step_is_fine(write_scene):
    traj = viz3d.simulate(write_scene(STIFF.format(dt=1e-5)), t_end=0.01)
    assert traj.ok, traj.status


def test_redundant_joints_are_named(write_scene):
    text = STIFF.format(dt=1e-3) + '\n[[joints]]\nname = "hinge_again"\nbody1 = "arm"\npoint = [-0.1, 0.0, -0.5]\n'
    try:
        viz3d.simulate(write_scene(text))
    except viz3d.SceneError as exc:
        assert "'hinge', 'hinge_again' are redundant" in str(exc) and "scene.toml: joints:" in str(exc)
    else:
        raise AssertionError("redundant joints were not reported")


def test_a_failing_adaptive_step_is_quoted_at_its_own_time_not_the_next_sample():
    """Adaptive steps end between the output samples (here 0.01 s apart, steps of a few ms at rtol
    1e-9): a projection that cannot reach its tolerance (1e-16 m, below the round-off of |C|) stops
    the run at the time of the step it failed on (after the last frame; the step may end past the
    next sample, which it had to reach first), not at the next sample's time, on the compiled path
    and on NumPy's."""
    import re

    from conftest import SCENES

    for compiled in ("true", "false"):
        traj = viz3d.simulate(SCENES / "chain.toml", ["chain.n=3", "sim.formulation=projection", "sim.integrator=dopri5",
                                                      "sim.dt=0.01", "sim.rtol=1e-9", "sim.atol=1e-12",
                                                      "sim.projection_tol=1e-16", "sim.t_end=1.0",
                                                      f"sim.compiled={compiled}"])
        assert "position projection left" in traj.status, traj.status
        t_fail = float(re.match(r"t = (\S+) s: ", traj.status).group(1))
        sample = traj.t[-1] + 0.01
        assert traj.t[-1] < t_fail < sample + 0.01 and abs(t_fail - sample) > 1e-6, (traj.status, traj.t[-1])


def _ledger_frames(t, T, V, work, dissipated, balance):
    """Frame columns of one body at rest in the world axes with the given ledger (arrays over t)."""
    from viz3d.columns import FrameColumns

    n = len(t)
    z = np.zeros((n, 1, 3))
    return FrameColumns(t=np.asarray(t, float), W_r=z, R_WB=np.tile(np.eye(3), (n, 1, 1, 1)), W_v=z, W_omega=z,
                        energy_kinetic=np.asarray(T, float), energy_potential=np.asarray(V, float),
                        constraint_violation=np.zeros(n), reaction_force=np.zeros((n, 0, 3)),
                        scalars={"energy/work_in": np.asarray(work, float),
                                 "energy/dissipated": np.asarray(dissipated, float),
                                 "energy/balance_error": np.asarray(balance, float)})


def _watch():
    from types import SimpleNamespace

    from viz3d.diagnosis import EnergyWatch

    bodies = SimpleNamespace(mass=np.ones(1), inertia=np.eye(3)[None], names=("bob",))
    return EnergyWatch(SimpleNamespace(bodies=bodies), 0.5, conservative=False)


def test_a_ledger_that_stops_balancing_stops_the_run_at_that_frame_in_any_chunks():
    """A driven run (not conservative, with a ledger): a balance error within blowup_energy (0.5) of
    the energy that moved passes, whatever the potential's datum; the first frame beyond it fails,
    whether the frames come in one chunk or one at a time (the energy that moved is carried over)."""
    import pytest

    from viz3d.diagnosis import EnergyFailure

    t = np.arange(6) * 0.1
    work = np.array([0.0, 10.0, 20.0, 20.0, 20.0, 20.0])        # 20 J in, then nothing more
    balance = np.array([0.0, 1.0, 2.0, 9.0, 11.0, 50.0])        # 11 J > 0.5 x 20 J at frame 4
    V = 1e6 + work - balance                                    # a large datum: the ledger's own terms
    frames = _ledger_frames(t, np.zeros(6), V, work, np.zeros(6), balance)
    for chunks in ([slice(0, 6)], [slice(i, i + 1) for i in range(6)]):
        watch = _watch()
        with pytest.raises(EnergyFailure, match=r"t = 0\.4 s: the energy ledger does not balance") as failed:
            for sl in chunks:
                watch.check(frames.take(np.arange(6)[sl]))
        assert failed.value.frame == (4 if len(chunks) == 1 else 0)


def test_a_ledger_within_rounding_of_its_datum_passes_before_anything_moved():
    """Before anything moves, a balance error at the rounding of the potential's datum
    (sqrt(eps) of it, ``LEDGER_ROUNDOFF``) is not a failure; a NaN is."""
    import pytest

    from viz3d.diagnosis import LEDGER_ROUNDOFF, EnergyFailure

    t, E = np.array([0.0, 0.1]), 4e5
    _watch().check(_ledger_frames(t, [0.0, 0.0], [E, E], [0.0, 0.0], [0.0, 0.0], [0.0, 0.5 * LEDGER_ROUNDOFF * E]))
    with pytest.raises(EnergyFailure):
        _watch().check(_ledger_frames(t, [0.0, 0.0], [E, E], [0.0, 0.0], [0.0, 0.0], [0.0, np.nan]))

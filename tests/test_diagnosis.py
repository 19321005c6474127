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

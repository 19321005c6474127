"""Rerun recordings read back with rerun.chunk.RrdReader: same energies and poses as the
trajectory, on the same sim_time timeline; blueprint embedded; interrupted runs stay readable."""

import numpy as np
import pytest
from rerun.chunk import RrdReader

import viz3d
from viz3d.cli import main
from viz3d.viz.recorder_rerun import RerunRecorder
from viz3d.sink import NullSink

from conftest import SCENES
from departing import HAUL
from recording import entities, read_column, read_scalars

FLOAT32_POS_TOL = 1e-6  # rerun stores translations as float32 (ECOSYSTEM pitfall 6); positions < 2 m


def test_recording_matches_the_trajectory(tmp_path):
    path = tmp_path / "dp.rrd"
    traj = viz3d.simulate(SCENES / "double_pendulum.toml", ["sim.output_dt=5e-4"], t_end=0.3, sinks=[RerunRecorder(path)])
    reader = RrdReader(path)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1
    # energies at full rate: every step (dt = 5e-4) -> 601 samples; the trajectory's frames are a subset
    t, E = read_scalars(path, "/plots/energy/total")
    assert len(t) == 601 and np.allclose(np.diff(t), 5e-4, atol=1e-9)
    np.testing.assert_allclose(t, traj.t, atol=1e-9)
    idx = np.arange(len(t))
    # the recorder's frames are rows of the trajectory's columns: the same numbers
    np.testing.assert_array_equal(E[idx, 0], traj.energy_total)
    _, C = read_scalars(path, "/plots/constraint_violation")
    np.testing.assert_array_equal(C[idx, 0], traj.constraint_violation)  # the same kernel rows
    _, F = read_scalars(path, "/plots/reaction_force/shoulder")
    np.testing.assert_array_equal(F[idx], traj.reaction_force[:, 0])
    # poses at 30 Hz on the same timeline
    tp, xyz = read_column(path, "/world/bodies/lower", "Transform3D:translation")
    assert 9 <= len(tp) <= 12 and np.all(np.diff(tp[:-1]) >= 1 / 30 - 1e-9)
    assert tp[-1] == pytest.approx(0.3)                                # the last state is always logged
    k = np.searchsorted(traj.t, tp - 1e-9)
    np.testing.assert_allclose(traj.t[k], tp, atol=1e-9)              # on the trajectory's timeline
    np.testing.assert_allclose(xyz.reshape(-1, 3), traj.position[k, traj.body("lower")], atol=FLOAT32_POS_TOL)


def test_a_recording_at_every_step_holds_the_trajectory_at_its_output_instants(tmp_path):
    """Plot samples every step (dt = 1 ms), trajectory frames every 10 ms: at the trajectory's times
    the recording holds the trajectory's numbers."""
    path = tmp_path / "top.rrd"
    traj = viz3d.simulate(SCENES / "heavy_top.toml", t_end=0.3, sinks=[RerunRecorder(path)])
    t, E = read_scalars(path, "/plots/energy/total")
    assert len(t) == 301 and len(traj.t) == 31
    k = np.searchsorted(t, traj.t - 1e-9)
    np.testing.assert_allclose(t[k], traj.t, atol=1e-9)  # (sim_time is stored in nanoseconds)
    np.testing.assert_array_equal(E[k, 0], traj.energy_total)
    _, F = read_scalars(path, "/plots/reaction_force/tip")
    np.testing.assert_array_equal(F[k], traj.reaction_force[:, 0])


def test_joints_and_reactions_are_recorded_at_the_poses(tmp_path):
    """Joint points and reaction arrows (sent as columns with the body poses) are the drawn frames'."""
    path, frames = tmp_path / "dp.rrd", []

    class Keep(NullSink):
        frame_dt = 0.0

        def log(self, frame):
            frames.append(frame)

    viz3d.simulate(SCENES / "double_pendulum.toml", t_end=0.3, sinks=[RerunRecorder(path), Keep()])
    by_t = {round(f.t, 9): f for f in frames}
    tp, _ = read_column(path, "/world/bodies/lower", "Transform3D:translation")
    tj, points = read_column(path, "/world/joints", "Points3D:positions")
    ta, arrows = read_column(path, "/world/reactions", "Arrows3D:vectors")
    np.testing.assert_allclose(tj, tp, atol=1e-9)
    np.testing.assert_allclose(ta, tp, atol=1e-9)
    for t, p, a in zip(tj, points, arrows):
        f = by_t[round(t, 9)]
        np.testing.assert_allclose(p.reshape(-1, 3), f.joint_points, atol=FLOAT32_POS_TOL)
        scale = np.abs(f.reaction_force).max()
        np.testing.assert_allclose(a.reshape(-1, 3) / np.abs(a).max(), f.reaction_force / scale, atol=1e-6)


def test_recording_layout_and_no_wall_clock(tmp_path):
    path = tmp_path / "arm.rrd"
    viz3d.simulate(SCENES / "robot_arm.toml", t_end=0.05, sinks=[RerunRecorder(path)])
    ents = entities(path)
    for e in ("/world/bodies/upper_arm/mesh", "/world"):
        assert (e, True) in ents
    for e in ("/world/bodies/hand", "/world/springs", "/world/joints", "/world/reactions", "/events"):
        assert (e, False) in ents
    for chunk in RrdReader(path).stream().to_chunks():
        assert "log_time" not in chunk.to_record_batch().schema.names
    _, text = read_column(path, "/events", "TextLog:text")
    assert "status: ok" in str(text[-1])


class _Interrupt(NullSink):
    frame_dt = 0.0

    def __init__(self, after):
        self.after, self.n = after, 0

    def log(self, frame):
        self.n += 1
        if self.n == self.after:
            raise KeyboardInterrupt


def test_interrupted_run_leaves_a_readable_recording(tmp_path):
    path = tmp_path / "int.rrd"
    traj = viz3d.simulate(SCENES / "chain.toml", t_end=1.0, sinks=[RerunRecorder(path), _Interrupt(200)])
    assert traj.status.startswith("interrupted")
    t, _ = read_scalars(path, "/plots/energy/kinetic")
    assert len(t) >= 199 and t[-1] == pytest.approx(traj.t[-1], abs=0.011)
    _, text = read_column(path, "/events", "TextLog:text")
    assert "interrupted" in str(text[-1])


def test_cli_run_record_and_replay_prints_the_command(tmp_path, capsys, monkeypatch):
    path = tmp_path / "sp.rrd"
    assert main(["run", str(SCENES / "spherical_pendulum.toml"), "--t-end", "0.05", "--out", str(tmp_path / "sp.npz"),
                 "--record", str(path)]) == 0
    assert path.is_file() and "recorded" in capsys.readouterr().out
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["replay", str(path)]) == 0
    out = capsys.readouterr().out
    assert "rerun" in out and str(path) in out and "0.41.0" in out
    assert main(["replay", str(tmp_path / "missing.rrd")]) == 2


def test_ctrl_c_on_the_command_line_leaves_a_readable_recording(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    from conftest import ROOT

    # The same command, short, first: it compiles and caches every kernel the run needs. With a cold
    # numba cache the interrupted run would otherwise still be compiling when the signal comes (tens
    # of seconds; seen with pytest-xdist on a fresh clone), and a signal then is lost or breaks the
    # compiler (see the closing note of stop 17).
    def command(t_end, name):
        return [sys.executable, "-m", "viz3d", "run", str(SCENES / "chain.toml"), "--t-end", t_end,
                "--record", str(tmp_path / f"{name}.rrd"), "--out", str(tmp_path / f"{name}.npz"), "--no-progress"]

    warm = subprocess.run(command("0.05", "warm"), cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert warm.returncode == 0, warm.stderr
    path = tmp_path / "sigint.rrd"
    # SIGINT back to its default in the child: a suite started as a background job (`cmd &` in a script)
    # hands its children SIGINT ignored, and Python then never raises KeyboardInterrupt
    proc = subprocess.Popen(command("100", "sigint"), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 60
    while not path.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1 and "interrupted at t =" in out, (out, err)
    t, _ = read_scalars(path, "/plots/energy/total")
    assert len(t) > 100
    traj = viz3d.Trajectory.load(tmp_path / "sigint.npz")
    assert traj.t[-1] == pytest.approx(t[-1], abs=0.011)


def test_posts_are_recorded_as_static_geometry(tmp_path):
    path = tmp_path / "arm.rrd"
    viz3d.simulate(SCENES / "robot_arm.toml", t_end=0.01, sinks=[RerunRecorder(path)])
    assert ("/world/posts", True) in entities(path)


def test_shape_contacts_are_recorded_as_arrows_and_plots(tmp_path):
    """Collision-library contacts: their count, deepest penetration and total normal force as plots
    (equal to the trajectory's fields), and their points and forces as /world/contacts arrows."""
    path = tmp_path / "ramp.rrd"
    traj = viz3d.simulate(SCENES / "shapes_on_a_ramp.toml", t_end=0.4, sinks=[RerunRecorder(path)])
    t, n = read_scalars(path, "/plots/collision/contacts")
    k = np.searchsorted(t, traj.t - 1e-9)
    np.testing.assert_array_equal(n[k, 0], traj.extras["collision_contacts"])
    assert traj.extras["collision_contacts"].max() >= 1
    _, F = read_scalars(path, "/plots/collision/normal_force")
    np.testing.assert_array_equal(F[k, 0], traj.extras["collision_normal_force"])
    chunks = [c.to_record_batch() for c in RrdReader(path).stream().to_chunks()
              if c.entity_path == "/world/contacts" and not c.is_static]  # arrows, or a Clear when none act
    batches = [np.asarray(v, float) for rb in chunks if "Arrows3D:origins" in rb.schema.names
               for v in rb.column("Arrows3D:origins").to_pylist() if v is not None]
    assert batches and all(1 <= len(b) <= traj.extras["collision_contacts"].max() for b in batches)
    assert all(np.all(np.isfinite(b)) for b in batches)



def test_plot_dt_thins_the_plot_samples_and_keeps_the_last(tmp_path):
    """``[display] plot_dt``: plot samples at most every plot_dt (of a dt = 5e-4 run, every 20th
    step for 0.01 s) on the trajectory's timeline, the last state always among them."""
    path = tmp_path / "dp_thin.rrd"
    traj = viz3d.simulate(SCENES / "double_pendulum.toml", ["sim.output_dt=5e-4", "display.plot_dt=0.01"], t_end=0.3,
                          sinks=[RerunRecorder(path)])
    t, E = read_scalars(path, "/plots/energy/total")
    assert len(t) == 31 and np.allclose(np.diff(t), 0.01, atol=1e-9) and t[-1] == pytest.approx(0.3)
    k = np.searchsorted(traj.t, t - 1e-9)
    np.testing.assert_allclose(traj.t[k], t, atol=1e-9)
    scale = np.max(np.abs(traj.energy_kinetic) + np.abs(traj.energy_potential))
    np.testing.assert_allclose(E[:, 0], traj.energy_total[k], rtol=0, atol=16 * np.finfo(float).eps * scale)


def test_a_recording_shows_a_link_until_it_leaves_and_at_scale_zero_after(write_scene, tmp_path):
    path = tmp_path / "haul.rrd"
    tr = viz3d.simulate(viz3d.load_scene(write_scene(HAUL)), sinks=[RerunRecorder(path)])
    gone = np.isnan(tr.position[:, list(tr.body_names).index("link0"), 0])
    left, before = tr.t[np.argmax(gone)], tr.t[np.argmax(gone) - 1]  # (output frames bracketing its departure)
    t, scale = read_column(path, "/world/bodies/link0", "Transform3D:scale")
    scale = scale.reshape(len(t), 3)
    # poses are recorded at display rate: the first one after the departure is at scale 0, and the last
    assert scale[-1].tolist() == [0.0, 0.0, 0.0] and before < t[-1] < left + 0.05
    assert (scale[:-1] == 1.0).all() and t[-2] <= left  # drawn at full size until then
    t_pose, xyz = read_column(path, "/world/bodies/link0", "Transform3D:translation")
    assert t_pose.max() == t[-1] and np.isfinite(xyz).all()
    t2, _ = read_column(path, "/world/bodies/link5", "Transform3D:translation")
    assert t2.max() > tr.t[-1] - 0.05  # a link that stays is posed to the end

"""Sinks get their frames from the run's columns (``viz3d.columns.StateLog`` with ``emit``): a sink
changes nothing in the trajectory, its frames at the output instants are the trajectory's rows,
frames and events arrive in time order, every step's frame reaches a sink with ``frame_dt = 0``,
and a frame's drawing is evaluated only when a sink reads it."""

from dataclasses import fields

import numpy as np
import pytest

import viz3d
from viz3d import columns
from viz3d.sink import NullSink
from viz3d.viz.recorder_rerun import RerunRecorder

from conftest import SCENES

#: (scene, overrides): the kernel's batched fixed steps (heavy top, robot arm with springs), adaptive
#: steps with contact events (bouncing sphere), flexible bodies drawn deformed (four-bar), the NumPy
#: path (shape contacts: no compiled piece).
CASES = [("heavy_top", ["sim.t_end=0.3"]), ("robot_arm", ["sim.t_end=0.1"]), ("bouncing_sphere", ["sim.t_end=0.6"]),
         ("flexible_four_bar", ["sim.t_end=0.01"]), ("shapes_on_a_ramp", ["sim.t_end=0.1"])]
NOT_COMPARED = {"wall_time"}


class Everything(NullSink):
    """Every step's frame (drawing read), and the events, in arrival order."""

    frame_dt = 0.0

    def __init__(self):
        self.frames, self.arrivals = [], []

    def log(self, frame):
        frame.joint_points, frame.deformed  # the drawing is evaluated
        self.frames.append(frame)
        self.arrivals.append(("frame", frame.t))

    def event(self, t, text, level="info"):
        self.arrivals.append((text, t))


def _equal(name, a, b):
    if isinstance(a, dict):
        assert a.keys() == b.keys(), name
        for k in a:
            _equal(f"{name}[{k}]", a[k], b[k])
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=name)
    else:
        assert a == b, name


@pytest.mark.parametrize("name, over", CASES, ids=[c[0] for c in CASES])
def test_a_sink_changes_nothing_in_the_trajectory_and_gets_its_rows(name, over):
    bare = viz3d.simulate(SCENES / f"{name}.toml", over)
    sink = Everything()
    seen = viz3d.simulate(SCENES / f"{name}.toml", over, sinks=[sink])
    assert bare.status == "ok", bare.status
    for f in fields(bare):
        if f.name not in NOT_COMPARED:
            _equal(f.name, getattr(bare, f.name), getattr(seen, f.name))
    times = [t for _, t in sink.arrivals]
    assert np.all(np.diff(times) >= 0), "frames and events out of time order"
    scene = viz3d.load_scene(SCENES / f"{name}.toml", over)
    dt = scene.data["sim"]["dt"]
    steps = np.array([f.t for f in sink.frames])
    assert np.all(np.isin(np.round(np.arange(0, bare.t[-1] + dt / 2, dt) / dt), np.round(steps / dt))), "a step's frame missing"
    by_t = {f.t: f for f in sink.frames}
    for i, t in enumerate(bare.t):  # the output instants' frames are the trajectory's rows
        f = by_t[t]
        np.testing.assert_array_equal(f.W_r, bare.position[i])
        np.testing.assert_array_equal(f.R_WB, bare.rotation[i])
        np.testing.assert_array_equal(f.reaction_force, bare.reaction_force[i])
        assert (f.energy_total, f.constraint_violation) == (bare.energy_total[i], bare.constraint_violation[i])


def test_a_frame_is_drawn_only_when_a_sink_reads_its_drawing(monkeypatch, tmp_path):
    calls = []
    drawing_of = columns.drawing_of
    monkeypatch.setattr(columns, "drawing_of", lambda *a: calls.append(a[1].t) or drawing_of(*a))

    class Plots(NullSink):  # every step's frame, plotted, never drawn
        frame_dt = 0.0
        n = 0

        def log(self, frame):
            self.n += 1
            frame.energy_total, dict(frame.scalars)

    plots = Plots()
    viz3d.simulate(SCENES / "robot_arm.toml", ["sim.t_end=0.2"], sinks=[plots])
    assert plots.n == 201 and not calls  # dt = 1 ms
    path = tmp_path / "arm.rrd"
    viz3d.simulate(SCENES / "robot_arm.toml", ["sim.t_end=0.2"], sinks=[RerunRecorder(path)])
    # the recorder draws a pose every display_dt (1/30 s: at 0, 34, 68, 102, 136, 170 ms of the 1-ms
    # steps) and the last state: 7 of the 201 frames
    assert len(calls) == 7 and calls[-1] == pytest.approx(0.2)


def test_a_sink_at_the_output_rate_gets_the_output_frames_only():
    class Outputs(NullSink):
        def __init__(self):
            self.t = []

        def log(self, frame):
            self.t.append(frame.t)

    sink = Outputs()
    traj = viz3d.simulate(SCENES / "heavy_top.toml", ["sim.t_end=0.3"], sinks=[sink])
    np.testing.assert_array_equal(sink.t, traj.t)


def test_the_live_driver_hands_sinks_the_frames_they_ask_for():
    """The live viewer's driver: a sink with ``frame_dt = 0`` gets every step's frame, one with
    ``frame_dt = 10 ms`` every tenth; both are the headless run's frames at those times."""
    import math
    import queue

    from viz3d.realtime import make_driver

    class Keep(NullSink):
        def __init__(self, frame_dt):
            self.frame_dt, self.frames = frame_dt, []

        def log(self, frame):
            self.frames.append(frame)

    every, tenth = Keep(0.0), Keep(0.01)
    scene = viz3d.load_scene(SCENES / "heavy_top.toml", ["sim.t_end=0.05", "sim.output_dt=1e-3"])
    driver = make_driver(scene, [every, tenth])
    driver.advance(0.05 - 1e-9, math.inf, queue.Queue())
    traj = viz3d.simulate(scene)
    assert [f.t for f in every.frames] == list(traj.t[1:])
    assert [f.t for f in tenth.frames] == list(traj.t[10::10])
    for f, i in zip(every.frames, range(1, len(traj.t))):
        np.testing.assert_array_equal(f.W_r, traj.position[i])
        assert f.energy_total == traj.energy_total[i]


def test_a_sink_that_fails_ends_the_run_with_the_frames_it_got():
    class Fails(NullSink):
        frame_dt = 0.0

        def __init__(self):
            self.t = []

        def log(self, frame):
            if frame.t > 0.2 + 1e-9:
                raise RuntimeError("disk full")
            self.t.append(frame.t)

    sink = Fails()
    traj = viz3d.simulate(SCENES / "heavy_top.toml", ["sim.t_end=0.3"], sinks=[sink])
    assert traj.status.startswith("stopped by an internal error") and "RuntimeError: disk full" in traj.status
    assert "at t = 0.2 s:" in traj.status, traj.status  # its last frame's time, not the state's a chunk later
    assert traj.t[-1] == pytest.approx(0.2) and sink.t[-1] == pytest.approx(0.2)  # the frames up to the failure

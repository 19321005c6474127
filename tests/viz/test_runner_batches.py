"""The live runner's cost: steps in batches (``viz3d.realtime.Driver.advance`` through
``Simulation.output_states``, the headless run's batched path) give the same states and sink frames as
one step at a time; a run that lags behind publishes fewer frames (``SimRunner._frame_interval``)."""

import math
import queue

import numpy as np
import pytest

import viz3d
from viz3d.realtime import make_driver

from conftest import SCENES

#: Wall-clock targets the runner might be handed [s]: off the step grid, one within a step.
TARGETS = (0.0131, 0.05, 0.0502, 0.2)


class FrameLog:
    """A sink that asks for a frame every 25 steps of 0.5 ms and keeps what it gets."""

    frame_dt = 0.0125

    def __init__(self):
        self.frames = []

    def log(self, frame):
        self.frames.append(frame)


def _advanced(batched: bool):
    sink = FrameLog()
    driver = make_driver(viz3d.load_scene(SCENES / "chain.toml", ["chain.n=5"]), sinks=[sink])
    assert driver.sim.batches_frames and driver.sim.dt == 5e-4
    calls = []
    take = driver.sim.output_states
    driver.sim.output_states = lambda n_frames, every: calls.append(every) or take(n_frames, every)
    if not batched:  # the per-step path the batches replace
        driver._batch = lambda *args: 1
    for t in TARGETS:
        driver.advance(t, math.inf, queue.Queue())
    return driver, sink, calls


def test_batched_steps_give_the_states_and_frames_of_single_steps():
    batched, b_sink, calls = _advanced(True)
    single, s_sink, single_calls = _advanced(False)
    assert not single_calls
    assert len(calls) <= 2 * (len(TARGETS) + len(s_sink.frames)), "the steps did not go in batches"
    assert batched.sim.n_samples == single.sim.n_samples == math.ceil(TARGETS[-1] / 5e-4 - 1e-9)
    np.testing.assert_array_equal(batched.sim.state.y, single.sim.state.y)
    assert [f.t for f in b_sink.frames] == [f.t for f in s_sink.frames]
    assert len(s_sink.frames) == math.floor(TARGETS[-1] / FrameLog.frame_dt + 1e-9)
    for a, b in zip(b_sink.frames, s_sink.frames):
        np.testing.assert_array_equal(a.W_r, b.W_r, err_msg=f"W_r at t = {a.t}")


def test_a_lagging_run_publishes_frames_within_their_share_of_the_wall_time():
    """While the simulation lags behind, frames come no more often than their cost over
    FRAME_SHARE allows, never fewer than MIN_FRAME_RATE; on time, at the display rate."""
    from viz3d.realtime import FRAME_SHARE, MIN_FRAME_RATE, SimRunner

    runner = SimRunner(viz3d.load_scene(SCENES / "chain.toml", ["chain.n=5"]), display_rate=60.0)
    try:
        runner._frame_cost = 0.2 * FRAME_SHARE / MIN_FRAME_RATE  # a fifth of what the floor allows
        assert runner._frame_interval() == 1.0 / 60.0
        runner._behind = True
        assert runner._frame_interval() == pytest.approx(max(1.0 / 60.0, 0.2 / MIN_FRAME_RATE), rel=1e-12)
        runner._frame_cost = 3.0 * FRAME_SHARE / MIN_FRAME_RATE
        assert runner._frame_interval() == 1.0 / MIN_FRAME_RATE
    finally:
        runner.stop()

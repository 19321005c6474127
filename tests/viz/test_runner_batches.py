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


class _Clock:
    """A wall clock the test moves (``perf_counter``, ``sleep``) [s]; each reading costs 10 us."""

    def __init__(self):
        self.now = 100.0

    def perf_counter(self):
        self.now += 1e-5
        return self.now

    def sleep(self, seconds):
        self.now += seconds


class _Stalling:
    """A simulation that steps ``capacity`` times faster than real time but once, at ``t_stall`` [s]
    of simulated time, takes ``stall`` [s] of wall time for one 1-ms step (a failed step's attempts and
    halvings)."""

    t_end = 100.0

    def __init__(self, clock, capacity, t_stall, stall):
        self.clock, self.capacity, self.t_stall, self.stall, self.t = clock, capacity, t_stall, stall, 0.0

    def advance(self, t_target, deadline, commands):
        while self.t < t_target and self.clock.now < deadline:
            if self.stall and self.t >= self.t_stall:
                self.clock.now += self.stall
                self.t, self.stall = self.t + 1e-3, 0.0
                continue
            span = min(t_target - self.t, (deadline - self.clock.now) * self.capacity)
            self.t += span
            self.clock.now += span / self.capacity


@pytest.mark.parametrize("stall", [0.6, 3.0])
def test_a_stall_within_max_lag_is_won_back_and_a_longer_one_is_dropped(monkeypatch, stall):
    """At speed 1, a run with spare speed (capacity 1.5x) that stalls once for 0.6 s (the anchor hoist
    stalls 0.4 s at its flukes' stop) is level with the wall clock again a few seconds later (before:
    the backlog over 0.25 s was dropped and the run stayed behind for good, 0.94x over 20 s). A stall
    longer than MAX_LAG is dropped: the run then stays that far behind, as it cannot win it back."""
    from viz3d import realtime
    from viz3d.realtime import MAX_LAG, SimRunner

    assert 0.6 < MAX_LAG < 3.0
    clock = _Clock()
    monkeypatch.setattr(realtime, "time", clock)
    runner = SimRunner(viz3d.load_scene(SCENES / "chain.toml", ["chain.n=5"]), speed=1.0, display_rate=60.0)
    try:
        runner.driver = _Stalling(clock, 1.5, 1.0, stall)
        runner._publish = lambda force: None
        runner._rebase()
        start = clock.now
        while clock.now - start < 10.0:
            runner._advance()
        behind = (clock.now - start) - runner.driver.t
        if stall < MAX_LAG:  # caught up: within a display interval of the wall clock
            assert 0.0 <= behind <= 1.0 / 60.0, behind
        else:  # what the runner could not win back: the stall, less the lag it had when it dropped it
            assert stall - MAX_LAG - 1e-3 <= behind <= stall + 1.0 / 60.0, behind
    finally:
        runner.stop()


def test_a_driver_whose_links_leave_gives_the_frames_of_a_headless_run(write_scene):
    """Departures (``viz3d.departures``) are checked at fixed instants, whatever the driver's batches:
    the live driver, batched or one step at a time, reaches the headless run's state, with the links that
    left drawn as NaN (the viewer shows them at scale 0)."""
    from departing import HAUL

    path = write_scene(HAUL)
    headless = viz3d.simulate(viz3d.load_scene(path))
    ends = []
    for batched in (True, False):
        sink = FrameLog()
        sink.frame_dt = 0.01
        driver = make_driver(viz3d.load_scene(path), sinks=[sink])
        if not batched:
            driver._batch = lambda *args: 1
        for t in (0.3, 0.5137, 0.9, 1.2):
            driver.advance(t, math.inf, queue.Queue())
        assert [t for t, _ in driver.sim.departures.log] == pytest.approx([0.51, 0.91])
        last = sink.frames[-1]
        assert last.t == pytest.approx(headless.t[-1])
        np.testing.assert_array_equal(np.isnan(last.W_r), np.isnan(headless.position[-1]))
        np.testing.assert_allclose(last.W_r, headless.position[-1], rtol=0, atol=1e-12)
        assert np.isnan(last.joint_points).any(axis=1).sum() == 2  # the joints of the two links that left
        ends.append(driver.sim.state.y)
    np.testing.assert_array_equal(ends[0], ends[1])

"""The haul's verdict (viz3d/stowage.py) on synthetic frames whose answer is known by construction:
a body that approaches its stowed pose and stays (seated, and when), a drive at or over its
capacity (jammed, and when), a body that stops moving while the drive hauls (jammed), and one still on
its way (not reached); pose errors against scipy's rotation angles."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from viz3d.stowage import pose_errors, verdict

T = np.linspace(0.0, 10.0, 101)
R_STOW = Rotation.from_euler("ZXZ", [0.3, 0.4, -0.2]).as_matrix()
P_STOW = np.array([1.0, -2.0, 0.5])
SPEC = {"bodies": ["anchor"], "position": [P_STOW.tolist()], "axes": [R_STOW.tolist()], "tolerance": 0.1,
        "angle_tolerance": 5.0, "stall_time": 2.0, "stall_distance": 0.02}


def _approach(t_arrive: float, stop_short: float = 0.0):
    """A body moving along x at 1 m/s toward P_STOW, arriving at ``t_arrive`` (then resting
    ``stop_short`` m short), turning about a fixed axis from 40 deg off to the stowed orientation."""
    s = np.clip((t_arrive - T), stop_short, None)
    P = P_STOW + s[:, None] * np.array([1.0, 0.0, 0.0])
    angle = np.radians(40.0) * np.clip((t_arrive - T) / t_arrive, 0.0, None)
    R = np.einsum("tij,jk->tik", Rotation.from_rotvec(angle[:, None] * np.array([0.0, 0.6, 0.8])).as_matrix(), R_STOW)
    return P[:, None, :], R[:, None]


def test_pose_errors_are_distance_and_rotation_angle():
    P, R = _approach(6.0)
    dist, ang = pose_errors(SPEC, P, R, [0])
    np.testing.assert_allclose(dist, np.clip(6.0 - T, 0.0, None), atol=1e-12)
    ref = np.degrees((Rotation.from_matrix(R[:, 0]) * Rotation.from_matrix(R_STOW).inv()).magnitude())
    np.testing.assert_allclose(ang, ref, atol=1e-6)


def test_a_body_that_reaches_its_stowed_pose_and_stays_is_seated_from_when_it_entered_the_tolerance():
    P, R = _approach(6.0)
    v = verdict(SPEC, T, P, R, ["anchor"], np.full(T.size, 2e5), 4.5e5, np.ones(T.size, bool))
    assert v.outcome == "seated"
    assert v.time == pytest.approx(5.9)              # 0.1 m away at t = 5.9 s, 4 deg off then (< 5)
    assert v.peak_force == 2e5 and v.position_error == 0.0


def test_a_drive_over_its_capacity_is_a_jam_at_the_first_frame_over_it():
    P, R = _approach(6.0)
    effort = np.where(T >= 3.0, 5e5, 2e5)
    v = verdict(SPEC, T, P, R, ["anchor"], effort, 4.5e5, np.ones(T.size, bool))
    assert v.outcome == "jammed" and v.time == pytest.approx(3.0) and v.peak_force == 5e5


def test_a_body_stuck_short_of_its_pose_while_the_drive_hauls_is_jammed_else_not_reached():
    P, R = _approach(6.0, stop_short=0.5)
    hauling = np.ones(T.size, bool)
    stuck = verdict(SPEC, T, P, R, ["anchor"], np.full(T.size, 1e5), None, hauling)
    assert stuck.outcome == "jammed" and stuck.time == pytest.approx(8.0)
    done = verdict(SPEC, T, P, R, ["anchor"], np.full(T.size, 1e5), None, T < 6.0)   # the drive stopped
    assert done.outcome == "not reached" and done.position_error == pytest.approx(0.5)
    P, R = _approach(20.0)                                                            # still on its way
    assert verdict(SPEC, T, P, R, ["anchor"], np.full(T.size, 1e5), None, hauling).outcome == "not reached"


@pytest.mark.parametrize("chunk", [1, 7, 101])
def test_the_windlass_stops_once_the_anchor_has_stayed_seated_for_settle_time(chunk):
    """seated_stop on the synthetic approach, its frames given in chunks of any length: the body
    enters the tolerance (0.1 m, and 5 deg: the angle is 40 deg (6 - t) / 6, under 5 deg from
    t = 5.25 s; the distance from t = 5.9 s) at t = 5.9 s; with settle_time 1.5 s the run ends at the
    frame of t = 7.4 s (kept: the check names it); a body that leaves the tolerance restarts the clock."""
    from types import SimpleNamespace

    from viz3d.diagnosis import RunComplete
    from viz3d.stowage import seated_stop

    P, R = _approach(6.0)
    check = seated_stop({**SPEC, "settle_time": 1.5}, ["anchor"])
    with pytest.raises(RunComplete) as done:
        for a in range(0, T.size, chunk):
            check(SimpleNamespace(t=T[a:a + chunk], W_r=P[a:a + chunk], R_WB=R[a:a + chunk]), None)
    assert T[a + done.value.frame] == pytest.approx(7.4)
    assert "seated since t = 5.9 s" in str(done.value)
    assert seated_stop(SPEC, ["anchor"]) is None                   # no settle_time: haul to t_end
    away = P.copy()
    away[66, 0, 0] += 0.5                                          # out of tolerance at t = 6.6 s
    check = seated_stop({**SPEC, "settle_time": 1.5}, ["anchor"])
    with pytest.raises(RunComplete) as done:
        check(SimpleNamespace(t=T, W_r=away, R_WB=R), None)
    assert T[done.value.frame] == pytest.approx(8.2)               # 6.7 s + 1.5 s


@pytest.mark.parametrize("chunk", [1, 7, 101])
def test_the_windlass_stops_once_it_has_hauled_its_limit(chunk):
    """seated_stop with ``haul_limit`` 4 m on a windlass coordinate hauled at 0.5 m/s (a body that never
    seats): the run ends at the frame of t = 8 s, the first at the limit, in chunks of any length."""
    from types import SimpleNamespace

    from viz3d.diagnosis import RunComplete
    from viz3d.stowage import seated_stop

    P, R = _approach(20.0)
    x = 0.5 * T
    check = seated_stop({**SPEC, "haul_limit": 4.0}, ["anchor"], "joint/guide/distance")
    with pytest.raises(RunComplete) as done:
        for a in range(0, T.size, chunk):
            check(SimpleNamespace(t=T[a:a + chunk], W_r=P[a:a + chunk], R_WB=R[a:a + chunk],
                                  scalars={"joint/guide/distance": x[a:a + chunk]}), None)
    assert T[a + done.value.frame] == pytest.approx(8.0)
    assert "hauled its limit 4" in str(done.value)


@pytest.mark.parametrize("depth0", [0.0, 0.011])
def test_a_jam_from_a_starting_overlap_says_so(depth0):
    """run_verdict: a drive over its capacity is a jam either way; when the shapes already overlapped at
    t = 0 (the trimmed ship that started 11 mm into the rim 'jammed' at 677 MN), the reason says so."""
    from types import SimpleNamespace

    from viz3d.stowage import run_verdict

    P, R = _approach(6.0)
    data = {"stowage": SPEC | {"drive": "windlass"}, "drives": [{"name": "windlass", "joint": "guide", "capacity": 4e5}],
            "joints": [{"name": "guide"}]}
    effort = np.where(T > 0.2, 7e8, 0.0)
    depth = np.zeros(T.size)
    depth[:3] = depth0
    class Cols(SimpleNamespace):
        def __len__(self):
            return T.size

    cols = Cols(t=T, W_r=P, R_WB=R, scalars={"drive/windlass/effort": effort, "collision/max_depth": depth})
    v = run_verdict(data, cols, ["anchor"])
    assert v.outcome == "jammed" and v.time == pytest.approx(0.3)
    assert ("already overlapped by 0.011 m" in v.reason) == (depth0 > 0)


def test_a_spike_shorter_than_capacity_time_is_no_jam_but_a_held_overload_is():
    """A drive with ``capacity_time`` 0.25 s (frames every 0.1 s): one frame at 7e5 N over its 4.5e5 N
    capacity (an impact's spike) leaves the anchor seated, with peak force 2e5 N held and 7e5 N
    transient; 5e5 N from t = 3 s on is a jam at 3 s, decided once held from 3.0 to 3.3 s."""
    P, R = _approach(6.0)
    spike = np.where(np.isclose(T, 3.0), 7e5, 2e5)
    v = verdict(SPEC, T, P, R, ["anchor"], spike, 4.5e5, np.ones(T.size, bool), capacity_time=0.25)
    assert v.outcome == "seated" and v.peak_force == 2e5 and v.peak_transient == 7e5
    assert verdict(SPEC, T, P, R, ["anchor"], spike, 4.5e5, np.ones(T.size, bool)).outcome == "jammed"  # 0 s
    held = np.where(T >= 3.0, 5e5, 2e5)
    v = verdict(SPEC, T, P, R, ["anchor"], held, 4.5e5, np.ones(T.size, bool), capacity_time=0.25)
    assert v.outcome == "jammed" and v.time == pytest.approx(3.0) and v.peak_force == 5e5
    assert "for 0.3 s" in v.reason


def test_held_effort_is_the_least_effort_over_the_window():
    from viz3d.diagnosis import held_effort

    t = np.arange(8) * 0.1
    e = np.array([1.0, -5.0, 4.0, 6.0, -7.0, 2.0, 9.0, 8.0])
    np.testing.assert_array_equal(held_effort(t, e, 0.0), np.abs(e))
    np.testing.assert_array_equal(held_effort(t, e, 0.2), [np.nan, np.nan, 1.0, 4.0, 4.0, 2.0, 2.0, 2.0])
    np.testing.assert_array_equal(held_effort(t, e, 0.25)[3:], [1.0, 4.0, 2.0, 2.0, 2.0])


@pytest.mark.parametrize("chunk", [1, 3, 101])
def test_the_capacity_watch_stops_a_run_once_the_overload_is_held_in_chunks_of_any_length(chunk):
    """CapacityWatch over frames given in chunks: a spike passes; an overload from t = 3 s stops the
    run at the frame of t = 3.3 s (held 0.25 s at frames 0.1 s apart), saying since when."""
    from viz3d.diagnosis import CapacityWatch, SimulationFailure

    effort = np.where(T >= 3.0, 5e5, 2e5)
    effort[10] = 9e5                                                # a spike at t = 1 s
    watch = CapacityWatch({"windlass": (4.5e5, 0.25, False)})
    with pytest.raises(SimulationFailure) as failed:
        for a in range(0, T.size, chunk):
            watch.check(T[a:a + chunk], {"drive/windlass/effort": effort[a:a + chunk]})
    assert T[a + failed.value.frame] == pytest.approx(3.3)
    assert "since t = 3 s" in str(failed.value) and "'windlass'" in str(failed.value)


@pytest.mark.parametrize("chunk", [1, 3, 101])
def test_a_limited_drive_held_at_its_capacity_ends_the_run_as_stalled(chunk):
    """The same rule for a limited drive (servo_gain), whose effort is exactly its capacity when it
    stalls: a spike to the capacity passes; at the capacity from t = 3 s the run ends at the frame of
    3.3 s with ``RunComplete`` (status ok: the model still holds), saying it stalled and since when;
    just under the capacity it goes on."""
    from viz3d.diagnosis import CapacityWatch, RunComplete

    effort = np.where(T >= 3.0, 4.5e5, 2e5)
    effort[10] = 4.5e5
    watch = CapacityWatch({"windlass": (4.5e5, 0.25, True)})
    with pytest.raises(RunComplete) as done:
        for a in range(0, T.size, chunk):
            watch.check(T[a:a + chunk], {"drive/windlass/effort": effort[a:a + chunk]})
    assert T[a + done.value.frame] == pytest.approx(3.3)
    assert "stalled at its capacity" in str(done.value) and "since t = 3 s" in str(done.value)
    watch = CapacityWatch({"windlass": (4.5e5, 0.25, True)})
    watch.check(T, {"drive/windlass/effort": np.minimum(effort, np.nextafter(4.5e5, 0.0))})


def test_a_drive_held_at_exactly_its_capacity_is_a_jam():
    """A limited drive's effort at a stall is its capacity itself (the servo's clip): held for
    capacity_time it is a jam, from when it reached it; a hair under, it is not."""
    P, R = _approach(6.0, stop_short=0.5)
    at = np.where(T >= 3.0, 4.5e5, 2e5)
    v = verdict(SPEC, T, P, R, ["anchor"], at, 4.5e5, T < 3.4, capacity_time=0.25)
    assert v.outcome == "jammed" and v.time == pytest.approx(3.0) and v.peak_force == 4.5e5
    under = np.minimum(at, np.nextafter(4.5e5, 0.0))
    assert verdict(SPEC, T, P, R, ["anchor"], under, 4.5e5, T < 3.4, capacity_time=0.25).outcome == "not reached"


def test_a_run_that_fails_while_its_drive_is_over_capacity_jammed():
    """A wedged anchor on a rigid drive: the effort passes the capacity at t = 3.0 s and the run
    diverges before capacity_time (its frames end at 3.1 s): jammed since 3.0 s. The same frames
    of a run that did not fail, or one that failed with its drive under capacity, are not a jam."""
    P, R = _approach(6.0)
    n = 32                                                          # frames to t = 3.1 s
    effort = np.where(T[:n] >= 3.0, 4e7, 2e5)
    args = (SPEC, T[:n], P[:n], R[:n], ["anchor"])
    v = verdict(*args, effort, 4.5e5, np.ones(n, bool), capacity_time=0.25, stopped=True)
    assert v.outcome == "jammed" and v.time == pytest.approx(3.0) and "when the run failed" in v.reason
    assert verdict(*args, effort, 4.5e5, np.ones(n, bool), capacity_time=0.25).outcome == "not reached"
    calm = np.full(n, 2e5)
    assert verdict(*args, calm, 4.5e5, np.ones(n, bool), capacity_time=0.25, stopped=True).outcome == "not reached"


def test_a_goal_reached_in_frames_before_a_failing_step_ends_the_run_there():
    """A step that fails (no frame of its own) after frames not yet checked: if those frames reached the
    goal (a stalled windlass, a seated anchor) the run ended there: ``RunComplete``, not the failure and
    not an exception escaping the run (a member of the stowage ensemble, 2026-11-28, did)."""
    from viz3d.diagnosis import RunComplete, SimulationFailure
    from viz3d.simulate import _earliest_failure

    class Log:
        def flush(self):
            raise RunComplete("stalled at its capacity", 3)

    got = _earliest_failure(Log(), SimulationFailure("t = 39.2 s: the step did not converge"))
    assert isinstance(got, RunComplete) and "stalled" in str(got)

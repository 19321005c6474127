"""The haul's verdict (viz3d/stowage.py) on synthetic frames whose answer is known by construction:
a body that approaches its stowed pose and stays (seated, and when), a drive over its capacity
(jammed, and when), a body that stops moving while the drive hauls (jammed), and one still on
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

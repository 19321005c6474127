"""The cycloidal ramp (``kind = "smooth_ramp"``): as a velocity profile its integral is Kane, Ryan &
Banerjee's spin-up angle; rate and acceleration agree with central differences of the angle."""

from __future__ import annotations

import numpy as np

from viz3d.timefunctions import TimeFunctions, profile_value

W_S, T_S = 4.0, 15.0
ROW = np.array([0.0, 0.0, 0.0, W_S, 0.0, 0.0, 0.0, 0.0, 0.0, T_S])   # packed: amplitude w_s, start 0, duration T_s
SMOOTH = 5


def spin_up_angle(t: float) -> float:
    """theta(t) of Kane, Ryan & Banerjee (1987) [rad]."""
    if t < T_S:
        return W_S / T_S * (t**2 / 2 + (T_S / (2 * np.pi)) ** 2 * (np.cos(2 * np.pi * t / T_S) - 1))
    return W_S * (t - T_S / 2)


def test_velocity_profile_integrates_to_the_spin_up_angle_with_consistent_derivatives():
    h = 1e-4
    for t in (0.3, 4.0, 7.5, 14.9, 15.0, 22.0):
        r, r_dot, r_ddot = profile_value(SMOOTH, 1, ROW, t)
        assert abs(r - spin_up_angle(t)) <= 1e-12 * max(1.0, abs(r))
        # central differences: O(h^2 theta''') ~ 1e-8 * 2 pi w_s / T_s^2
        assert abs(r_dot - (spin_up_angle(t + h) - spin_up_angle(t - h)) / (2 * h)) <= 1e-7
        rate = [profile_value(SMOOTH, 1, ROW, s)[1] for s in (t - h, t + h)]
        assert abs(r_ddot - (rate[1] - rate[0]) / (2 * h)) <= 1e-6


def test_time_function_shape_runs_from_zero_to_one_with_no_overshoot():
    tf = TimeFunctions.from_entries([{"kind": "smooth_ramp", "offset": [0, 0, 0], "amplitude": [1, 0, 0],
                                      "frequency": 0.0, "phase": 0.0, "start": 1.0, "duration": 2.0}])
    values = np.array([tf(t)[0, 0] for t in np.linspace(0.0, 4.0, 81)])
    assert values[0] == 0.0 and values[-1] == 1.0
    assert np.all(np.diff(values) >= 0.0)
    np.testing.assert_allclose(tf(2.0)[0, 0], 0.5, atol=1e-15)   # symmetric about its middle

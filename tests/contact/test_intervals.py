"""Contacts as the physics defines them (viz3d.contact.intervals), on hand-made interval lists."""

import numpy as np

from viz3d.contact.intervals import impacts, physical_contacts

TAU = 1.0  # time resolution of the made-up model [s]


def rows(*spans):
    """Contact rows from (start, end) pairs: approach speed 1 + start, separation speed 2 + end."""
    return np.array([[a, 1 + a, b, 2 + b] for a, b in spans], float)


def test_gaps_shorter_than_the_resolution_are_closed():
    c = physical_contacts(rows((0, 5), (5.5, 9), (9.2, 12), (20, 25)), TAU)
    np.testing.assert_array_equal(c.rows, [[0, 1, 12, 14], [20, 21, 25, 27]])  # first approach, last separation
    np.testing.assert_array_equal(c.breaks, [2, 0])
    assert c.count == 2 and c.unresolved_breaks == 2 and len(c.touches) == 0


def test_short_recontacts_are_touches_but_an_impact_opener_is_a_contact():
    c = physical_contacts(rows((0, 0.5), (3, 3), (5, 5.4), (5.8, 5.9), (10, 12)), TAU)
    np.testing.assert_array_equal(c.rows[:, [0, 2]], [[0, 0.5], [10, 12]])  # the first is short but opens the impact
    np.testing.assert_array_equal(c.touches[:, [0, 2]], [[3, 3], [5, 5.9]])
    assert c.touch_breaks == 1 and c.unresolved_breaks == 1
    opened = physical_contacts(rows((0, 4), (6, 6.5)), TAU, opens_impact=[True, True])
    assert opened.count == 2  # a new impact (the loads turned the bodies round) is a contact


def test_zero_resolution_keeps_every_interval_and_an_unfinished_contact_is_kept():
    spans = rows((0, 1e-9), (1e-9 + 1e-12, 2e-9))
    assert physical_contacts(spans, 0.0).count == 2
    c = physical_contacts(np.array([[0, 1, 4, 2], [4.5, 1, np.nan, np.nan]]), TAU)
    assert c.count == 1 and np.isnan(c.rows[0, 2])
    c = physical_contacts(np.array([[0, 1, 4, 2], [9, 1, np.nan, np.nan]]), TAU)
    assert c.count == 2


def test_impacts_start_only_where_the_loads_turned_the_rigid_motion_round():
    # bouncing ball: leaves each contact receding, comes back approaching
    assert impacts([0.63, 0.52, 0.43], [-0.52, -0.43, -0.36]) == [[0], [1], [2]]
    # impactor on a clamped bar: still receding when the bar end catches up with it
    assert impacts([1.0, -0.69], [-0.69, -0.70]) == [[0, 1]]
    # mass riding a cantilever tip: still approaching in rigid terms when the tip comes back
    assert impacts([1.0, 0.9, 0.7], [0.9, 0.7, -0.8]) == [[0, 1, 2]]

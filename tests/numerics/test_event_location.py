"""Event location inside one step (``viz3d.integrators.adaptive.first_event``): a crossing and its
return inside the step are found, a tangency is not, and the cubic extrema both paths take
(``viz3d.integrators.adaptive.hermite_extrema``, compiled) are its source's run by Python to the bit.

The event function here is ``x`` of a point under a constant acceleration ``A`` (``y = [x, v]``,
``f = [v, A]``), the rate of ``x`` its ``v``: the state's cubic Hermite interpolant is the motion
itself (a quadratic), so the located root is off by ``brentq``'s tolerance (``EVENT_XTOL`` of the
step plus ``EVENT_RTOL`` of the time) and the rounding of ``x`` near it over the speed there.
"""

import math

import numpy as np
import pytest

from viz3d.compiled import numba
from viz3d.integrators import adaptive
from viz3d.integrators.adaptive import (CUBIC_ROUNDOFF, EPS, EVENT_RTOL, EVENT_XTOL, ROUNDING, Event, first_event,
                                        hermite_extrema)

#: Acceleration of the point [m/s^2] and length of the step [s].
A, H = 2.0, 1.0


def _parabola_step(c: float, d: float):
    """``x(t) = (t - c)^2 + d`` (``A = 2``) over the step [0, H]: (y0, f0, y1, f1)."""
    x = lambda t: (t - c) * (t - c) + d
    v = lambda t: 2.0 * (t - c)
    y0, y1 = np.array([x(0.0), v(0.0)]), np.array([x(H), v(H)])
    return y0, np.array([y0[1], A]), y1, np.array([y1[1], A])


def _rounding(y0, f0, y1, f1) -> float:
    """Rounding of ``x`` on the interpolant [m]: the Hermite form's (``CUBIC_ROUNDOFF``)."""
    return CUBIC_ROUNDOFF * EPS * (abs(y0[0]) + H * abs(f0[0]) + abs(y1[0]) + H * abs(f1[0]))


def _first(c: float, d: float, direction: int = -1):
    """``first_event`` of ``x`` (falling through 0 for ``direction`` -1) with its rate ``v``."""
    ev = Event("x", lambda t, y: y[0], direction, lambda t, y: y[1])
    y0, f0, y1, f1 = _parabola_step(c, d)
    return first_event([ev], [y0[0]], [y0[1]], 0.0, y0, f0, H, y1, f1)


@pytest.mark.parametrize("c, depth", [(0.5, 1e-6), (0.3, 1e-2), (0.71, 1e-9)])
def test_a_crossing_and_its_return_inside_one_step_are_found(c, depth):
    """``x`` positive at both ends of the step, below zero by ``depth`` in between (the flight of a
    ball through the plate in one step): the event is the first root ``c - sqrt(depth)``."""
    hit = _first(c, -depth)
    assert hit is not None, "the crossing inside the step was not found"
    root, speed = c - math.sqrt(depth), 2.0 * math.sqrt(depth)
    bound = EVENT_XTOL * H + EVENT_RTOL * root + _rounding(*_parabola_step(c, -depth)) / speed
    assert abs(hit[1] - root) <= bound, f"{hit[1] - root:.3g} s"


def test_a_rising_event_through_a_bump_inside_one_step():
    """The mirror case: ``-x`` rising through 0 (a gap's onset) and back inside the step."""
    ev = Event("onset", lambda t, y: -y[0], +1, lambda t, y: -y[1])
    c, depth = 0.4, 1e-4
    y0, f0, y1, f1 = _parabola_step(c, -depth)
    hit = first_event([ev], [-y0[0]], [-y0[1]], 0.0, y0, f0, H, y1, f1)
    assert hit is not None, "the crossing inside the step was not found"
    root, speed = c - math.sqrt(depth), 2.0 * math.sqrt(depth)
    assert abs(hit[1] - root) <= EVENT_XTOL * H + EVENT_RTOL * root + _rounding(y0, f0, y1, f1) / speed


@pytest.mark.parametrize("d", [0.0, 1e-12, 1e-3])
def test_a_dip_to_zero_or_above_it_is_no_event(d):
    """A minimum at zero (a tangency) or above it crosses nothing."""
    assert _first(0.5, d) is None


def test_a_minimum_at_round_off_below_zero_is_no_event():
    """Tangencies whose cubic rounds below zero at its minimum, by less than ``CUBIC_ROUNDOFF`` eps
    of its scale: no event (without the tolerance, these would stop the run)."""
    below = []
    for c in np.linspace(0.05, 0.95, 181):
        y0, f0, y1, f1 = _parabola_step(c, 0.0)
        m0, m1 = H * y0[1], H * y1[1]
        p = adaptive._cubic(c, y0[0], m0, y1[0], m1)
        tol = CUBIC_ROUNDOFF * EPS * (abs(y0[0]) + abs(m0) + abs(y1[0]) + abs(m1))
        assert abs(p) <= tol  # the rounding bound holds
        if p < 0.0:
            below.append(c)
        assert _first(c, 0.0) is None, f"c = {c}: a tangency located as an event"
    assert below, "no tangency rounded below zero: the case is not exercised"


def test_an_event_without_a_rate_sees_the_ends_only():
    """No rate (a multiplier, a gap rate): only the signs at the ends, as before."""
    ev = Event("x", lambda t, y: y[0], -1)
    y0, f0, y1, f1 = _parabola_step(0.5, -1e-2)
    assert first_event([ev], [y0[0]], [np.nan], 0.0, y0, f0, H, y1, f1) is None


def test_a_fresh_event_whose_excursion_falls_between_the_probes():
    """An event just handled at ``t0`` (value zero) whose whole armed excursion and return lie
    between two of the ``FRESH_PROBES`` points (a ball's next flight in the step after its bounce):
    found at the root after the cubic's armed extremum."""
    # x(t) = (t - c)^2 - c^2: zero at 0, below zero (armed for a rising event) until 2c, then above
    c = 0.3 / adaptive.FRESH_PROBES
    ev = Event("onset", lambda t, y: y[0], +1, lambda t, y: y[1])
    y0, f0, y1, f1 = _parabola_step(c, -c * c)
    assert y0[0] == 0.0
    hit = first_event([ev], [0.0], [y0[1]], 0.0, y0, f0, H, y1, f1, fresh=("onset",))
    assert hit is not None, "the excursion between two probes was missed"
    assert abs(hit[1] - 2 * c) <= EVENT_XTOL * H + EVENT_RTOL * 2 * c + _rounding(y0, f0, y1, f1) / (2 * c)


@pytest.mark.skipif(numba is None, reason="numba is not installed")
def test_the_compiled_extrema_are_the_python_ones_to_the_bit(monkeypatch):
    """``hermite_extrema`` compiled, called from compiled code (the compiled adaptive driver) and from
    Python (the Python loop), against its source run by Python (``py_func``, with ``_cubic``'s: what
    runs without numba) on random cubics, tangencies and degenerate ones (no cubic term, no slope,
    nan slopes)."""

    @numba.njit
    def call(g0, m0, g1, m1):
        return hermite_extrema(g0, m0, g1, m1, ROUNDING)

    rng = np.random.default_rng(7)
    cases = [tuple(x) for x in rng.standard_normal((2000, 4)) * 10.0 ** rng.integers(-8, 3, (2000, 1))]
    cases += [(0.25, -1.0, 0.25, 1.0), (1.0, 0.0, 1.0, 0.0), (1.0, 0.0, 2.0, 2.0), (0.0, 0.0, 0.0, 0.0),
              (1.0, np.nan, 1.0, 1.0), (1.0, -1.0, 1.0, np.nan)]
    for c in np.linspace(0.05, 0.95, 19):
        y0, _, y1, _ = _parabola_step(c, 0.0)
        cases.append((y0[0], y0[1], y1[0], y1[1]))
    compiled = [(call(*case), hermite_extrema(*case, ROUNDING)) for case in cases]
    monkeypatch.setattr(adaptive, "_cubic", adaptive._cubic.py_func)
    for case, (from_compiled, from_python) in zip(cases, compiled, strict=True):
        interpreted = hermite_extrema.py_func(*case, ROUNDING)
        assert from_compiled == interpreted and from_python == interpreted, case

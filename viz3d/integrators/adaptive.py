"""Adaptive time stepping with error control, dense output and event location.

Separate pieces, as in diffrax: a method with an embedded error estimate (an ``ExplicitRK`` on an
embedded tableau such as ``DOPRI5``), a step-size ``Controller`` with ``accepted_step`` (step
rejection and the next step's proposal), cubic Hermite dense output, and ``first_event``, which
locates the first sign change of scalar functions ``g(t, y)`` inside a step, also where ``g``
crosses zero and comes back within the step (``hermite_extrema``). The driver owns the
loop between steps (``viz3d.simulate`` re-charts, projects and handles events between accepted
steps). Nothing here knows what ``y`` describes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from viz3d._typing import FloatArray
from viz3d.compiled import entry
from viz3d.integrators.base import Integrator, StepResult

#: Controller defaults (Hairer, Norsett & Wanner, Solving ODEs I, sec. II.4).
SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 5.0
#: Event times are located to this relative precision of the step (``brentq``'s ``xtol``), with
#: ``brentq``'s least relative tolerance (4 eps, its default) and its default iteration limit; the
#: compiled adaptive driver (``viz3d.kernel.adaptive``) locates events with the same three.
EVENT_XTOL = 1e-12
EVENT_RTOL = 4 * np.finfo(float).eps
EVENT_MAXITER = 100
#: Rounding of ``hermite_extrema``'s cubic at a point of [0, 1], in units of eps times the sum of the
#: magnitudes of its end values and end slopes: each Hermite basis function is rounded at most 4
#: times (those of the values are at most 1, those of the slopes at most 4/27), then one product
#: and three sums, each within eps of the sum of the terms' magnitudes.
CUBIC_ROUNDOFF = 8.0
EPS = float(np.finfo(float).eps)
#: ``hermite_extrema``'s ``rounding``: ``CUBIC_ROUNDOFF`` eps.
ROUNDING = CUBIC_ROUNDOFF * EPS


class StepSizeUnderflow(RuntimeError):
    """The controller asked for a step below ``min_step``."""


@dataclass(frozen=True)
class Controller:
    """Integral step-size control on the weighted RMS norm of the local error estimate.

    ``norm = rms(err / (atol + rtol max(|y0|, |y1|)))``; a step is accepted when ``norm <= 1``
    and the next step is ``h * clip(SAFETY * norm**(-1 / (q + 1)), FAC_MIN, FAC_MAX)`` with
    ``q`` the order of the embedded estimate.

    Attributes
    ----------
    rtol, atol : float
    max_step, min_step : float [s]
    """

    rtol: float = 1e-6
    atol: float = 1e-9
    max_step: float = np.inf
    min_step: float = 0.0

    def error_norm(self, err: FloatArray, y0: FloatArray, y1: FloatArray) -> float:
        scale = self.atol + self.rtol * np.maximum(np.abs(y0), np.abs(y1))
        return float(np.sqrt(np.mean((err / scale) ** 2)))

    def next_step(self, h: float, norm: float, error_order: int) -> float:
        factor = FAC_MAX if norm == 0.0 else SAFETY * norm ** (-1.0 / (error_order + 1))
        return h * min(FAC_MAX, max(FAC_MIN, factor))

    def first_step(self, rhs, t: float, y: FloatArray, f0: FloatArray, order: int) -> float:
        """Initial step from the scale of ``y`` and ``f`` (Hairer et al., II.4, 'starting step')."""
        scale = self.atol + self.rtol * np.abs(y)
        d0, d1 = np.sqrt(np.mean((y / scale) ** 2)), np.sqrt(np.mean((f0 / scale) ** 2))
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        f1 = rhs(t + h0, y + h0 * f0)
        d2 = np.sqrt(np.mean(((f1 - f0) / scale) ** 2)) / h0
        h1 = max(1e-6, h0 * 1e-3) if max(d1, d2) <= 1e-15 else (0.01 / max(d1, d2)) ** (1.0 / (order + 1))
        return min(100 * h0, h1, self.max_step)


@dataclass(frozen=True)
class FixedSteps:
    """Fixed steps as the compiled driver takes them (``viz3d.kernel.adaptive``'s ``ctrl[FIXED]``)
    for a run with contact events and no controller, as ``Simulation._event_step`` takes them:
    ``dt`` [s] within ``max_step`` [s] (the contacts' step bound) and within the rest to the next
    sample (``step_to_try``), the last one ending on it (``step_end``). No error test.

    Attributes
    ----------
    dt, max_step : float [s]
    """

    dt: float
    max_step: float = np.inf


@dataclass(frozen=True)
class Event:
    """A scalar function of the state whose sign change stops the integration.

    Attributes
    ----------
    name : str
    g : callable (t, y) -> float
    direction : int
        +1: only rising crossings (g from < 0 to >= 0); -1: only falling; 0: both.
    rate : callable (t, y) -> float, optional
        ``dg/dt`` along the solution at ``(t, y)`` (for ``g(y)``: its gradient times the vector
        field). With it a crossing and its return inside one step are found (``first_event``);
        None where it is not known (then only the signs at the ends, and a fresh event's probes).
    """

    name: str
    g: Callable[[float, FloatArray], float]
    direction: int = 0
    rate: Callable[[float, FloatArray], float] | None = None

    def crosses(self, g0: float, g1: float) -> bool:
        return crosses(self.direction, g0, g1)


@entry
def crosses(direction: int, g0: float, g1: float) -> bool:
    """An event of ``direction`` (``Event.direction``) crosses from the value ``g0`` to ``g1``.
    Compiled: the compiled adaptive driver (``viz3d.kernel.adaptive``) calls it too, as the other
    event-location helpers (``armed``, ``hermite_extrema``), so both paths decide alike."""
    rising = g0 < 0.0 <= g1
    falling = g0 > 0.0 >= g1
    if direction > 0:
        return rising
    if direction < 0:
        return falling
    return rising or falling


@entry
def armed(direction: int, g: float) -> bool:
    """An event of ``direction`` at the value ``g`` is on a side it crosses from. Compiled, as ``crosses``."""
    if direction > 0:
        return g < 0.0
    if direction < 0:
        return g > 0.0
    return g != 0.0


def hermite(t0, y0, f0, t1, y1, f1, t):
    """Cubic Hermite interpolant between two steps, at ``t`` (scalar or (m,) array). Squares are
    products (numpy's scalar ``** 2`` calls ``pow``, which may round otherwise), so the compiled
    adaptive driver's ``hermite_state`` gives the same bits."""
    h = t1 - t0
    s = (np.asarray(t, float) - t0) / h
    s = s[..., None] if np.ndim(s) else s
    u2 = (1 - s) * (1 - s)
    h00, h10 = (1 + 2 * s) * u2, s * u2
    h01, h11 = s * s * (3 - 2 * s), s * s * (s - 1)
    return h00 * y0 + h10 * h * f0 + h01 * y1 + h11 * h * f1


def first_event(events, g0, r0, t0, y0, f0, t1, y1, f1, fresh: tuple[str, ...] = ()):
    """Earliest (name, time) of an event crossing inside (t0, t1], located on the interpolant.

    ``g0`` and ``r0`` are the events' values and rates (``Event.rate``; nan where unknown) at ``t0``.
    The sign of an event function is looked at in order at the step's start, at the interior
    extrema of its cubic Hermite (``hermite_extrema``: from its values and rates at the ends, where
    it lies off zero by more than its rounding) and at the step's end: the first crossing lies
    between the last point on the side the event crosses from and the first point after it on the
    other side (``_bracket``), and is located there on the interpolant. So an event that crosses
    and comes back inside one step is found (a ball's whole flight in one step of a method exact in
    free flight, the plate ahead of it at both ends), and a tangency is not. The extrema are looked
    at on the cubic first: only where its signs show a crossing is the event function evaluated
    on the interpolant, at them, and the crossing taken where its signs there show one too.

    ``fresh`` names events that start at a root: an event just handled at ``t0`` (its function
    is zero to round-off there, of either sign), or one armed by it (the separation of a contact
    that just began). The sign at ``t0`` says nothing about such an event: it crosses when its
    interpolant is on its armed side (before the crossing) at one of the points after ``t0`` and on
    the other side later: the cubic's extrema and, unless the step ends armed, ``FRESH_PROBES``
    points of the step (for events without a rate). So a contact that begins and ends inside one
    step ends inside it, and an event that just fired does not fire again at once.
    """
    best = None
    for ev, g_start, r_start in zip(events, g0, r0):
        g_end = ev.g(t1, y1)
        r_end = ev.rate(t1, y1) if ev.rate is not None else np.nan
        h = t1 - t0
        extrema = hermite_extrema(float(g_start), float(h * r_start), float(g_end), float(h * r_end), ROUNDING)

        def g_of(t, ev=ev):
            return ev.g(t, hermite(t0, y0, f0, t1, y1, f1, t))

        if ev.name in fresh:
            points = _fresh_points(ev, g_of, t0, t1, g_end, extrema)
        elif _bracket(ev.direction, [(t0, g_start), *_interior(t0, t1, extrema), (t1, g_end)]) is None:
            continue  # (the cubic's signs show no crossing)
        else:
            points = [(t0, g_start), *((t, g_of(t)) for t, _ in _interior(t0, t1, extrema)), (t1, g_end)]
        pair = _bracket(ev.direction, points)
        t_ev = None if pair is None else _locate(g_of, t0, t1, pair[0], *pair[1])
        if t_ev is not None and (best is None or t_ev < best[1]):
            best = (ev.name, t_ev)
    return best


#: Points on which a fresh event's interpolant is searched for its armed side (see ``first_event``).
FRESH_PROBES = 32


@entry
def hermite_extrema(g0: float, m0: float, g1: float, m1: float, rounding: float) -> tuple[float, float, float, float]:
    """The interior extrema of the cubic Hermite ``p`` on [0, 1] with ``p(0) = g0``, ``p'(0) = m0``,
    ``p(1) = g1``, ``p'(1) = m1`` at which ``|p|`` exceeds its rounding ``rounding (|g0| + |m0| +
    |g1| + |m1|)`` (``ROUNDING``): ``(s_lo, p_lo, s_hi, p_hi)``, ``s_lo < s_hi``, ``s = -1`` (and
    ``p = 0``) for none; none when a slope is nan (an event without a rate). Compiled: the compiled
    adaptive driver calls it too (``crosses``).

    For an event function over a step of length ``h``: ``g0``, ``g1`` its values and ``m0``, ``m1``
    ``h`` times its rates at the ends, ``s = (t - t0) / h``. Why this test: it needs only what
    every step has (the event function and its rate at the ends; the rate of a gap is its gap rate,
    evaluated with it) and works for any event function with a rate on any dense output, at a few
    operations per event and step. A step bound from a closing speed would shorten every step of a
    flight (cost), needs a bound on the acceleration too (the speed is zero at the top) and serves
    one kind of event function. The cubic is the event function on the state's cubic Hermite
    interpolant where it is linear in the state (a sphere on a plane), and within that
    interpolant's ``O(h^4)`` otherwise: its points are checked on the interpolant
    (``first_event``). An extremum at zero or within rounding of it (a tangency) is no point: it
    crosses nothing. The extrema are the roots of ``p'``, a quadratic, in closed form (the form
    without cancellation).
    """
    tol = rounding * (abs(g0) + abs(m0) + abs(g1) + abs(m1))
    s_lo, p_lo, s_hi, p_hi = -1.0, 0.0, -1.0, 0.0
    a = 2.0 * (g0 - g1) + m0 + m1                    # p(s) = g0 + m0 s + b s^2 + a s^3
    b = 3.0 * (g1 - g0) - 2.0 * m0 - m1
    disc = b * b - 3.0 * a * m0                      # p'(s) = 3 a s^2 + 2 b s + m0
    if not disc >= 0.0:                              # (no real root, or a nan slope)
        return s_lo, p_lo, s_hi, p_hi
    q = -(b + math.copysign(math.sqrt(disc), b))
    if q == 0.0:                                     # b = 0 and a m0 = 0: p' = 3 a s^2 or constant
        return s_lo, p_lo, s_hi, p_hi
    r1 = m0 / q
    r2 = q / (3.0 * a) if a != 0.0 else -1.0
    for s in (min(r1, r2), max(r1, r2)):
        p = _cubic(s, g0, m0, g1, m1) if 0.0 < s < 1.0 else 0.0
        if abs(p) > tol:
            if s_lo < 0.0:
                s_lo, p_lo = s, p
            else:
                s_hi, p_hi = s, p
    return s_lo, p_lo, s_hi, p_hi


@entry
def _cubic(s: float, g0: float, m0: float, g1: float, m1: float) -> float:
    """``hermite_extrema``'s cubic at ``s`` in the Hermite basis (compiled, as it)."""
    u2 = (1.0 - s) * (1.0 - s)
    h00, h10 = (1.0 + 2.0 * s) * u2, s * u2
    h01, h11 = s * s * (3.0 - 2.0 * s), s * s * (s - 1.0)
    return h00 * g0 + h10 * m0 + h01 * g1 + h11 * m1


def _interior(t0: float, t1: float, extrema) -> list[tuple[float, float]]:
    """(time, cubic's value) of the ``hermite_extrema`` of the step ``[t0, t1]``."""
    s_lo, p_lo, s_hi, p_hi = extrema
    return [(t0 + s * (t1 - t0), p) for s, p in ((s_lo, p_lo), (s_hi, p_hi)) if s >= 0.0]


def _bracket(direction: int, points) -> tuple[float, tuple[float, float]] | None:
    """``(t_a, (t_b, g_b))``: the first pair of (time, value) ``points`` (in time order) across which
    an event of ``direction`` crosses, from the last point before ``t_b`` on a side it crosses from;
    None when there is none."""
    last = t_a = None
    for t, g in points:
        if last is not None and crosses(direction, last, g):
            return t_a, (t, g)
        if armed(direction, g):
            t_a, last = t, g
    return None


def _locate(g_of, t0: float, t1: float, t_a: float, t_b: float, g_b: float) -> float:
    """Root of ``g_of`` in (t_a, t_b] bracketed by a sign change (``t_b`` if the interpolant
    disagrees at ``t_a`` or ``t_b`` is the root), to ``EVENT_XTOL`` of the step ``[t0, t1]``."""
    from scipy.optimize import brentq
    lo_val = g_of(t_a)
    if g_b == 0.0 or (np.sign(lo_val) == np.sign(g_b)):
        return t_b
    return float(brentq(g_of, t_a, t_b, xtol=EVENT_XTOL * (t1 - t0) + 1e-300, rtol=EVENT_RTOL, maxiter=EVENT_MAXITER))


def _fresh_points(ev, g_of, t0: float, t1: float, g_end: float, extrema) -> list[tuple[float, float]]:
    """(time, value on the interpolant) of a fresh event after ``t0``, in time order: the cubic's
    extrema, and ``FRESH_PROBES`` points of the step unless the step ends on the armed side (then
    only its end)."""
    ends_armed = armed(ev.direction, g_end) if ev.direction != 0 else False
    times = [t for t, _ in _interior(t0, t1, extrema)]
    times += [t1] if ends_armed else list(np.linspace(t0, t1, FRESH_PROBES + 1)[1:])
    return [(t, g_end if t == t1 else g_of(t)) for t in sorted(times)]


@dataclass(frozen=True)
class Accepted:
    """The step ``accepted_step`` settled on.

    Attributes
    ----------
    res : StepResult
    h : float
        Step taken [s].
    h_next : float
        Step the controller proposes next [s].
    n_rejected : int
        Trial steps rejected before this one.
    """

    res: StepResult
    h: float
    h_next: float
    n_rejected: int


@entry
def step_to_try(h: float, max_step: float, t: float, t_end: float) -> float:
    """The step [s] to try from ``t``: the proposal ``h`` within ``max_step`` and the rest of the run
    to ``t_end`` (inf: unbounded), so no step goes past the run's end (``scipy.integrate.solve_ivp``
    clips its steps to ``t_bound`` so). Compiled: the compiled adaptive driver
    (``viz3d.kernel.adaptive``) calls it too."""
    return min(h, max_step, t_end - t)


@entry
def step_end(t: float, h: float, t_end: float) -> float:
    """The end [s] of the accepted step of length ``h`` from ``t``: ``t_end`` itself when the step is
    the rest of the run (``step_to_try`` clipped it to ``t_end - t`` and it was accepted so; ``t +
    h`` may round to either side of ``t_end``), so the run's last step ends exactly there; else ``t
    + h``, which is then at most ``t_end`` (``h`` is less than ``t_end - t``, and ``t_end`` is a
    float: ``t + h`` cannot round past it). Compiled, as ``step_to_try``."""
    return t_end if h == t_end - t else t + h


def error_order(method: Integrator) -> int:
    """Order of ``method``'s embedded error estimate (the controller's exponent uses it)."""
    return method.tableau.estimate_order


def accepted_step(rhs, t: float, y: FloatArray, f: FloatArray, h: float, method: Integrator,
                  controller: Controller) -> Accepted:
    """Try steps of ``method`` from ``(t, y)`` (``f = rhs(t, y)``), shrinking ``h`` until the
    error test of ``controller`` passes.

    A trial step with a non-finite error (the vector field blew up inside it), or one whose stage
    state the field cannot be evaluated at (``LinAlgError``: e.g. a flexible body deformed so far
    that its mass block is no longer positive definite), is rejected like a too-large one, with the
    smallest allowed factor.

    Raises
    ------
    StepSizeUnderflow
        If the step falls below ``controller.min_step`` or no longer changes ``t``.
    """
    order, n_rejected, failed = error_order(method), 0, None
    while True:
        try:
            res = method.step(rhs, t, y, h, f0=f)
        except np.linalg.LinAlgError as exc:  # a stage state outside the field's domain
            res, failed = None, exc
        with np.errstate(all="ignore"):
            norm = np.inf if res is None else controller.error_norm(res.error, y, res.y)
        if norm <= 1.0:
            return Accepted(res, h, controller.next_step(h, norm, order), n_rejected)
        n_rejected += 1
        h = controller.next_step(h, norm, order) if np.isfinite(norm) else FAC_MIN * h
        if h < controller.min_step or t + h == t:
            why = "" if failed is None else f"; a stage's evaluation failed: {failed}"
            raise StepSizeUnderflow(f"t = {t:.9g} s: adaptive step {h:.3g} s below min_step {controller.min_step:.3g} s "
                                    f"({n_rejected} rejections in a row{why})")

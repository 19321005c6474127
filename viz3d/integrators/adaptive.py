"""Adaptive time stepping with error control, dense output and event location.

Separate pieces, as in diffrax: a method with an embedded error estimate (an ``ExplicitRK`` on an
embedded tableau such as ``DOPRI5``), a step-size ``Controller`` with ``accepted_step`` (step
rejection and the next step's proposal), cubic Hermite dense output, and ``first_event``, which
locates the first sign change of scalar functions ``g(t, y)`` inside a step. The driver owns the
loop between steps (``viz3d.simulate`` re-charts, projects and handles events between accepted
steps). Nothing here knows what ``y`` describes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from viz3d._typing import FloatArray
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
class Event:
    """A scalar function of the state whose sign change stops the integration.

    Attributes
    ----------
    name : str
    g : callable (t, y) -> float
    direction : int
        +1: only rising crossings (g from < 0 to >= 0); -1: only falling; 0: both.
    """

    name: str
    g: Callable[[float, FloatArray], float]
    direction: int = 0

    def crosses(self, g0: float, g1: float) -> bool:
        rising = g0 < 0.0 <= g1
        falling = g0 > 0.0 >= g1
        return {1: rising, -1: falling, 0: rising or falling}[self.direction]


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


def first_event(events, g0, t0, y0, f0, t1, y1, f1, fresh: tuple[str, ...] = ()):
    """Earliest (name, time) of an event crossing inside (t0, t1], located on the interpolant.

    ``fresh`` names events that start at a root: an event just handled at ``t0`` (its function
    is zero to round-off there, of either sign), or one armed by it (the separation of a contact
    that just began). The sign at ``t0`` says nothing about such an event: it crosses when its
    interpolant is on its armed side (before the crossing) at one of ``FRESH_PROBES`` points of
    the step and on the other side later, so a contact that begins and ends inside one step ends
    inside it, and an event that just fired does not fire again at once.
    """
    best = None
    for ev, g_start in zip(events, g0):
        g_end = ev.g(t1, y1)

        def g_of(t, ev=ev):
            return ev.g(t, hermite(t0, y0, f0, t1, y1, f1, t))

        if ev.name in fresh:
            t_ev = _fresh_crossing(ev, g_of, t0, t1, g_end)
        elif not ev.crosses(g_start, g_end):
            continue
        else:
            t_ev = _locate(g_of, t0, t1, g_end)
        if t_ev is not None and (best is None or t_ev < best[1]):
            best = (ev.name, t_ev)
    return best


#: Points on which a fresh event's interpolant is searched for its armed side (see ``first_event``).
FRESH_PROBES = 32


def _locate(g_of, t0: float, t1: float, g_end: float) -> float:
    """Root of ``g_of`` in (t0, t1] bracketed by a sign change (the step end if the interpolant
    disagrees with the step at ``t0`` or the end is the root)."""
    from scipy.optimize import brentq
    lo_val = g_of(t0)
    if g_end == 0.0 or (np.sign(lo_val) == np.sign(g_end)):
        return t1
    return float(brentq(g_of, t0, t1, xtol=EVENT_XTOL * (t1 - t0) + 1e-300, rtol=EVENT_RTOL, maxiter=EVENT_MAXITER))


def _fresh_crossing(ev, g_of, t0: float, t1: float, g_end: float) -> float | None:
    """First crossing of a fresh event after its interpolant is on the armed side at one of the
    ``FRESH_PROBES`` points of the step (None if it never is, or ends there)."""
    from scipy.optimize import brentq
    side = -1.0 if ev.direction > 0 else 1.0            # armed: below 0 for a rising event, above for falling
    if side * g_end > 0.0:
        return None
    armed = None
    for t in np.linspace(t0, t1, FRESH_PROBES + 1)[1:]:
        if side * g_of(t) > 0.0:
            armed = t
        elif armed is not None:
            return float(brentq(g_of, armed, t, xtol=EVENT_XTOL * (t1 - t0) + 1e-300, rtol=EVENT_RTOL,
                                maxiter=EVENT_MAXITER))
    return None


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

"""Adaptive time stepping with error control, dense output and event location.

Three separate pieces, as in diffrax: a method with an embedded error estimate (an
``ExplicitRK`` on an embedded tableau such as ``DOPRI5``), a step-size ``Controller``, and
``integrate``, which drives them over an interval, samples output through cubic Hermite dense
output and stops exactly at the first event (a sign change of a scalar function ``g(t, y)``).
``accepted_step`` (step rejection and the next step's proposal) serves ``integrate`` and the
drivers that own the loop between steps (``viz3d.simulate`` re-charts and projects between
accepted steps). Nothing here knows what ``y`` describes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.optimize import brentq

from viz3d._typing import FloatArray
from viz3d.integrators.base import Integrator, StepResult

#: Controller defaults (Hairer, Norsett & Wanner, Solving ODEs I, sec. II.4).
SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 5.0
#: Event times are located to this relative precision of the step.
EVENT_XTOL = 1e-12


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


@dataclass
class Outcome:
    """Where ``integrate`` stopped and what it cost.

    Attributes
    ----------
    t : float
    y : ndarray, shape (n_y,)
    f : ndarray, shape (n_y,)
        ``rhs(t, y)``.
    event : str or None
        Name of the event that stopped it, ``None`` at ``t_end``.
    h : float
        Step the controller proposes next.
    n_accepted, n_rejected, n_rhs : int
    """

    t: float
    y: FloatArray
    f: FloatArray
    event: str | None
    h: float
    n_accepted: int = 0
    n_rejected: int = 0
    n_rhs: int = 0


def hermite(t0, y0, f0, t1, y1, f1, t):
    """Cubic Hermite interpolant between two steps, at ``t`` (scalar or (m,) array)."""
    h = t1 - t0
    s = (np.asarray(t, float) - t0) / h
    s = s[..., None] if np.ndim(s) else s
    h00, h10 = (1 + 2 * s) * (1 - s) ** 2, s * (1 - s) ** 2
    h01, h11 = s * s * (3 - 2 * s), s * s * (s - 1)
    return h00 * y0 + h10 * h * f0 + h01 * y1 + h11 * h * f1


class _Counted:
    def __init__(self, rhs):
        self.rhs, self.n = rhs, 0

    def __call__(self, t, y):
        self.n += 1
        return self.rhs(t, y)


def integrate(rhs, t0: float, y0: FloatArray, t_end: float, method: Integrator, controller: Controller,
              events: tuple[Event, ...] = (), h: float | None = None, f0: FloatArray | None = None,
              on_step: Callable | None = None, disarmed: tuple[str, ...] = ()) -> Outcome:
    """Integrate ``y' = rhs(t, y)`` from ``t0`` until ``t_end`` or the first event.

    Parameters
    ----------
    method : Integrator
        With an embedded error estimate (``StepResult.error`` not None).
    h : float, optional
        First step to try (default: estimated).
    on_step : callable (t0, y0, f0, t1, y1, f1) -> None, optional
        Called after every accepted step (including the final partial step to an event), e.g. to
        sample output through ``hermite``.
    disarmed : tuple of str
        Events that just fired at ``t0`` (their function is zero to round-off there): they are
        ignored during the first accepted step, so a root at the start is not found again.

    Raises
    ------
    StepSizeUnderflow
        If the controller needs a step below ``controller.min_step``.
    """
    rhs = _Counted(rhs)
    t, y = t0, np.asarray(y0, float)
    f = rhs(t, y) if f0 is None else f0
    h = controller.first_step(rhs, t, y, f, error_order(method)) if h is None else h
    g = [0.0 if ev.name in disarmed else ev.g(t, y) for ev in events]
    out = Outcome(t, y, f, None, h)
    while t < t_end:
        acc = accepted_step(rhs, t, y, f, min(h, t_end - t, controller.max_step), method, controller)
        res, h = acc.res, acc.h
        out.n_rejected += acc.n_rejected
        t1 = t + h
        f1 = res.f1 if res.f1 is not None else rhs(t1, res.y)
        hit = first_event(events, g, t, y, f, t1, res.y, f1)
        if hit is not None:
            name, t_ev = hit
            res_ev = method.step(rhs, t, y, t_ev - t, f0=f)  # the method's own solution at the event
            f_ev = res_ev.f1 if res_ev.f1 is not None else rhs(t_ev, res_ev.y)
            if on_step:
                on_step(t, y, f, t_ev, res_ev.y, f_ev)
            out.n_accepted += 1
            out.t, out.y, out.f, out.event, out.h = t_ev, res_ev.y, f_ev, name, h
            out.n_rhs = rhs.n
            return out
        if on_step:
            on_step(t, y, f, t1, res.y, f1)
        out.n_accepted += 1
        g = [ev.g(t1, res.y) for ev in events]
        t, y, f = t1, res.y, f1
        h = acc.h_next
    out.t, out.y, out.f, out.h, out.n_rhs = t, y, f, h, rhs.n
    return out


def first_event(events, g0, t0, y0, f0, t1, y1, f1):
    """Earliest (name, time) of an event crossing inside (t0, t1], located on the interpolant."""
    best = None
    for ev, g_start in zip(events, g0):
        g_end = ev.g(t1, y1)
        if not ev.crosses(g_start, g_end):
            continue
        def g_of(t, ev=ev):
            return ev.g(t, hermite(t0, y0, f0, t1, y1, f1, t))
        lo_val = g_of(t0)
        if np.sign(lo_val) == np.sign(g_end) and g_end != 0.0:
            t_ev = t1  # interpolant disagrees at the start: take the step end
        elif g_end == 0.0:
            t_ev = t1
        else:
            t_ev = brentq(g_of, t0, t1, xtol=EVENT_XTOL * (t1 - t0) + 1e-300)
        if best is None or t_ev < best[1]:
            best = (ev.name, t_ev)
    return best


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
    return method.tableau.error_order or method.order - 1


def accepted_step(rhs, t: float, y: FloatArray, f: FloatArray, h: float, method: Integrator,
                  controller: Controller) -> Accepted:
    """Try steps of ``method`` from ``(t, y)`` (``f = rhs(t, y)``), shrinking ``h`` until the
    error test of ``controller`` passes.

    A trial step with a non-finite error (the vector field blew up inside it) is rejected like a
    too-large one, with the smallest allowed factor.

    Raises
    ------
    StepSizeUnderflow
        If the step falls below ``controller.min_step`` or no longer changes ``t``.
    """
    order, n_rejected = error_order(method), 0
    while True:
        res = method.step(rhs, t, y, h, f0=f)
        with np.errstate(all="ignore"):
            norm = controller.error_norm(res.error, y, res.y)
        if norm <= 1.0:
            return Accepted(res, h, controller.next_step(h, norm, order), n_rejected)
        n_rejected += 1
        h = controller.next_step(h, norm, order) if np.isfinite(norm) else FAC_MIN * h
        if h < controller.min_step or t + h == t:
            raise StepSizeUnderflow(f"t = {t:.9g} s: adaptive step {h:.3g} s below min_step {controller.min_step:.3g} s "
                                    f"({n_rejected} rejections in a row)")

"""One accepted step of an embedded method under an ``adaptive.Controller`` (step rejection and
step-size proposal), for drivers that own the loop between steps (``viz3d.simulate`` re-charts
and projects between accepted steps); ``adaptive.integrate`` is the driver for a single interval.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.integrators.adaptive import FAC_MIN, Controller, StepSizeUnderflow
from viz3d.integrators.base import Integrator, StepResult


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

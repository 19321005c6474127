"""The one generic explicit Runge-Kutta stepper; methods are tableaus (tableaus.py)."""

from __future__ import annotations

from typing import Callable

import numpy as np

from viz3d._typing import FloatArray
from viz3d.integrators.adaptive import hermite
from viz3d.integrators.base import Integrator, StepResult
from viz3d.integrators.tableaus import ButcherTableau


class ExplicitRK(Integrator):
    """Explicit Runge-Kutta method given by a Butcher tableau.

    Order: ``tableau.order``. Stages: ``tableau.stages`` evaluations per step (one fewer with
    FSAL when ``f0`` is passed). Explicit, not symplectic. Error estimate when the tableau has an
    embedded solution (``b_hat``). Dense output: the tableau's continuous extension if it has one
    (``interpolant``), else cubic Hermite. No solver state. Zero coefficients are skipped.
    """

    def __init__(self, tableau: ButcherTableau):
        self.tableau = tableau
        self.name = tableau.name
        self.order = tableau.order
        # Nonzero (index, coefficient) pairs of each row of a, and of b.
        self._a = [[(j, a) for j, a in enumerate(row[:i]) if a != 0.0] for i, row in enumerate(tableau.a)]
        self._b = [(j, b) for j, b in enumerate(tableau.b) if b != 0.0]

    @property
    def embedded(self) -> bool:
        return self.tableau.embedded

    def step(self, rhs, t, y, h, f0=None, state=None):
        tab = self.tableau
        compiled = getattr(rhs, "rk_step", None)  # a field that steps in compiled code (viz3d.kernel)
        if compiled is not None:
            done = compiled(tab, t, y, h, f0)
            if done is not None:
                y_new, error, stages = done
                return StepResult(y_new, error, f0=stages[0], f1=stages[-1] if tab.fsal else None, stages=stages)
        k = []
        for i, ci in enumerate(tab.c):
            if i == 0 and f0 is not None:
                k.append(f0)
                continue
            yi = y
            for j, a in self._a[i]:
                yi = yi + (h * a) * k[j]
            k.append(rhs(t + ci * h, yi))
        y_new = y.copy()
        for j, b in self._b:
            y_new += (h * b) * k[j]
        stages = np.asarray(k)
        error = h * np.tensordot(tab.error_weights, stages, axes=1) if tab.embedded else None
        return StepResult(y_new, error, f0=k[0], f1=k[-1] if tab.fsal else None, stages=stages)

    def interpolant(self, rhs, t: float, y: FloatArray, h: float, res: StepResult,
                    f1: FloatArray) -> Callable[[float], FloatArray]:
        """``y(t_s)`` for ``t <= t_s <= t + h`` inside the step that produced ``res``.

        Uses the tableau's continuous extension (evaluating its extra stages now, e.g. three for
        DOP853), else cubic Hermite on ``(y, f0)`` and ``(res.y, f1)``; ``f1 = rhs(t + h, res.y)``.
        """
        dense = self.tableau.dense
        if dense is None or res.stages is None:
            return lambda ts: hermite(t, y, res.f0, t + h, res.y, f1, ts)
        K = list(res.stages)
        for c, row in zip(dense.c_extra, dense.a_extra):
            if c == 1.0 and np.array_equal(row[: len(self.tableau.b)], self.tableau.b) and not np.any(row[len(self.tableau.b):]):
                K.append(f1)  # the stage at the step's end: f(t + h, y1), known already
                continue
            K.append(rhs(t + c * h, y + h * np.tensordot(row[: len(K)], np.asarray(K), axes=1)))
        Q = h * (dense.P.T @ np.asarray(K))                # (degree, n_y)
        powers = np.arange(1, dense.P.shape[1] + 1)
        return lambda ts: y + ((ts - t) / h) ** powers @ Q

    def __repr__(self):
        return f"ExplicitRK({self.tableau.name})"

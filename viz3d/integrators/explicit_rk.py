"""The one generic explicit Runge-Kutta stepper; methods are tableaus (tableaus.py)."""

from __future__ import annotations

import numpy as np

from viz3d.integrators.base import Integrator, StepResult
from viz3d.integrators.tableaus import ButcherTableau


class ExplicitRK(Integrator):
    """Explicit Runge-Kutta method given by a Butcher tableau.

    Order: ``tableau.order``. Stages: ``tableau.stages`` evaluations per step (one fewer with
    FSAL when ``f0`` is passed). Explicit, not symplectic. Error estimate when the tableau has an
    embedded solution (``b_hat``). Zero coefficients are skipped.
    """

    def __init__(self, tableau: ButcherTableau):
        self.tableau = tableau
        self.name = tableau.name
        self.order = tableau.order
        # Nonzero (index, coefficient) pairs of each row of a, and of b.
        self._a = [[(j, a) for j, a in enumerate(row[:i]) if a != 0.0] for i, row in enumerate(tableau.a)]
        self._b = [(j, b) for j, b in enumerate(tableau.b) if b != 0.0]

    def step(self, rhs, t, y, h, f0=None):
        tab = self.tableau
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
        error = h * np.tensordot(tab.b - tab.b_hat, np.asarray(k), axes=1) if tab.embedded else None
        return StepResult(y_new, error, f0=k[0], f1=k[-1] if tab.fsal else None)

    def __repr__(self):
        return f"ExplicitRK({self.tableau.name})"

"""The one generic explicit Runge-Kutta stepper; methods are tableaus (tableaus.py)."""

from __future__ import annotations

from functools import cached_property
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

    Positions on a group: when ``rhs`` has a ``dexpinv`` hook (``viz3d.integrators.base``) and the
    tableau has no error estimate (the fixed-step methods), the step is the tableau's
    Runge-Kutta-Munthe-Kaas method: stage positions ``retract(q0, u_i)``, ``u_i = h sum_j a_ij K_j``,
    ``K_j = dexpinv(u_j, v_j)``, end positions ``retract(q0, h sum_j b_j K_j)``, the rest of ``y`` as
    usual. Same order (the hook's truncation suffices up to order 4), exact for motions of constant
    velocity, and positions stay on the group. Methods with an error estimate keep linear stages
    (their error estimate and continuous extension combine the stages linearly).
    """

    def __init__(self, tableau: ButcherTableau):
        self.tableau = tableau
        self.name = tableau.name
        self.order = tableau.order

    @cached_property
    def _a(self) -> list[list[tuple[int, float]]]:
        """Nonzero ``(j, a_ij)`` pairs of each row ``i`` of ``a`` (made on the first NumPy step: runs
        whose steps the compiled kernel takes need none)."""
        return [[(j, a) for j, a in enumerate(row[:i]) if a != 0.0] for i, row in enumerate(self.tableau.a)]

    @cached_property
    def _b(self) -> list[tuple[int, float]]:
        """Nonzero ``(j, b_j)`` pairs of ``b``."""
        return [(j, b) for j, b in enumerate(self.tableau.b) if b != 0.0]

    @property
    def embedded(self) -> bool:
        return self.tableau.embedded

    def step(self, rhs, t, y, h, f0=None, state=None):
        tab = self.tableau
        compiled = getattr(rhs, "rk_step", None)  # a field that steps in compiled code (viz3d.kernel), group
        if compiled is not None:                  # steps included
            done = compiled(tab, t, y, h, f0)
            if done is not None:
                y_new, error, stages = done
                return StepResult(y_new, error, f0=stages[0], f1=stages[-1] if tab.fsal else None, stages=stages)
        if not tab.embedded and getattr(rhs, "dexpinv", None) is not None:
            return self._group_step(rhs, t, y, h, f0)
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

    def _group_step(self, rhs, t, y, h, f0):
        """The Munthe-Kaas step (class docstring); ``stages`` are the rates ``rhs`` gave (s, n_y)."""
        n_q, n_v = rhs.n_q, rhs.n_v
        q0 = y[:n_q]
        k, K = [], []
        for i, ci in enumerate(self.tableau.c):
            u, yi = np.zeros(n_v), y
            for j, a in self._a[i]:
                u = u + (h * a) * K[j]
                yi = yi + (h * a) * k[j]
            yi = np.concatenate([rhs.retract(q0, u), yi[n_q:]])
            k.append(f0 if i == 0 and f0 is not None else rhs(t + ci * h, yi))
            K.append(rhs.dexpinv(u, yi[n_q:n_q + n_v]))
        u, y_new = np.zeros(n_v), y.copy()
        for j, b in self._b:
            u += (h * b) * K[j]
            y_new += (h * b) * k[j]
        y_new[:n_q] = rhs.retract(q0, u)
        return StepResult(y_new, None, f0=k[0], f1=None, stages=np.asarray(k))

    def interpolant(self, rhs, t: float, y: FloatArray, h: float, res: StepResult,
                    f1: FloatArray) -> Callable[[float], FloatArray]:
        """``y(t_s)`` for ``t <= t_s <= t + h`` inside the step that produced ``res``.

        Uses the tableau's continuous extension (``DenseInterpolant``, evaluating its extra stages
        now, e.g. three for DOP853), else cubic Hermite on ``(y, f0)`` and ``(res.y, f1)``;
        ``f1 = rhs(t + h, res.y)``.
        """
        if self.tableau.dense is None or res.stages is None:
            return lambda ts: hermite(t, y, res.f0, t + h, res.y, f1, ts)
        return DenseInterpolant(t, y, h, self.dense_coefficients(rhs, t, y, h, res.stages, f1))

    def dense_coefficients(self, rhs, t: float, y: FloatArray, h: float, stages: FloatArray,
                           f1: FloatArray) -> FloatArray:
        """``Q = h P^T K`` (degree, n_y) of the continuous extension of the step of ``stages``
        (s, n_y) from ``(t, y)``: the extra stages ``K_{s+i}`` evaluated now (the one at the step's
        end is ``f1``, known already)."""
        dense = self.tableau.dense
        K = list(stages)
        for c, row in zip(dense.c_extra, dense.a_extra):
            if is_end_stage(self.tableau, row):
                K.append(f1)
                continue
            K.append(rhs(t + c * h, y + h * np.tensordot(row[: len(K)], np.asarray(K), axes=1)))
        return h * (dense.P.T @ np.asarray(K))

    def __repr__(self):
        return f"ExplicitRK({self.tableau.name})"


def is_end_stage(tableau: ButcherTableau, row: FloatArray) -> bool:
    """True when the extra stage of ``row`` (of ``tableau.dense.a_extra``) is ``f(t + h, y1)``."""
    s = len(tableau.b)
    return bool(np.array_equal(row[:s], tableau.b) and not np.any(row[s:]))


class DenseInterpolant:
    """``y(t_s) = y0 + sum_d ((t_s - t0) / h)^(d + 1) Q[d]``: a step's continuous extension.

    Attributes
    ----------
    t0, h : float
        The step's start and length [s].
    y0 : ndarray, shape (n_y,)
    Q : ndarray, shape (degree, n_y)
        ``h P^T K`` (``ExplicitRK.dense_coefficients``).
    """

    def __init__(self, t0: float, y0: FloatArray, h: float, Q: FloatArray):
        self.t0, self.y0, self.h, self.Q = t0, y0, h, Q
        self._powers = np.arange(1, Q.shape[0] + 1)

    def __call__(self, ts):
        return self.y0 + ((ts - self.t0) / self.h) ** self._powers @ self.Q

"""Butcher tableaus of explicit Runge-Kutta methods, validated on construction."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Tolerance of the tableau consistency checks.
TABLEAU_TOL = 1e-14


@dataclass(frozen=True)
class ButcherTableau:
    """Explicit Runge-Kutta coefficients.

    Attributes
    ----------
    name : str
    order : int
    c : ndarray, shape (s,)
    a : ndarray, shape (s, s), strictly lower triangular
    b : ndarray, shape (s,)

    Raises ``ValueError`` unless ``a`` is strictly lower triangular, ``sum(b) = 1`` and the rows of
    ``a`` sum to ``c``.
    """

    name: str
    order: int
    c: np.ndarray
    a: np.ndarray
    b: np.ndarray

    def __post_init__(self):
        for key in ("c", "a", "b"):
            object.__setattr__(self, key, np.asarray(getattr(self, key), dtype=float))
        s = len(self.b)
        if self.a.shape != (s, s) or self.c.shape != (s,):
            raise ValueError(f"{self.name}: inconsistent stage count")
        if np.any(np.triu(self.a) != 0):
            raise ValueError(f"{self.name}: a must be strictly lower triangular (explicit method)")
        if abs(self.b.sum() - 1) > TABLEAU_TOL:
            raise ValueError(f"{self.name}: sum(b) = {self.b.sum()} != 1")
        if np.max(np.abs(self.a.sum(axis=1) - self.c)) > TABLEAU_TOL:
            raise ValueError(f"{self.name}: rows of a do not sum to c")

    @property
    def stages(self) -> int:
        return len(self.b)


EULER = ButcherTableau("euler", 1, c=[0.0], a=[[0.0]], b=[1.0])
HEUN = ButcherTableau("heun", 2, c=[0.0, 1.0], a=[[0.0, 0.0], [1.0, 0.0]], b=[0.5, 0.5])
RK4 = ButcherTableau(
    "rk4", 4,
    c=[0.0, 0.5, 0.5, 1.0],
    a=[[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
    b=[1 / 6, 1 / 3, 1 / 3, 1 / 6],
)

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
    b_hat : ndarray, shape (s,), optional
        Weights of the embedded lower-order solution; ``error = h sum (b - b_hat) k``.
    error_order : int, optional
        Order of the embedded solution (the controller's exponent uses it).
    fsal : bool
        First stage of the next step equals the last stage of this one ("first same as last").

    Raises ``ValueError`` unless ``a`` is strictly lower triangular, ``sum(b) = 1`` (and
    ``sum(b_hat) = 1``) and the rows of ``a`` sum to ``c``.
    """

    name: str
    order: int
    c: np.ndarray
    a: np.ndarray
    b: np.ndarray
    b_hat: np.ndarray | None = None
    error_order: int | None = None
    fsal: bool = False

    def __post_init__(self):
        for key in ("c", "a", "b"):
            object.__setattr__(self, key, np.asarray(getattr(self, key), dtype=float))
        if self.b_hat is not None:
            object.__setattr__(self, "b_hat", np.asarray(self.b_hat, dtype=float))
            if abs(self.b_hat.sum() - 1) > TABLEAU_TOL or self.b_hat.shape != self.b.shape:
                raise ValueError(f"{self.name}: b_hat must have the shape of b and sum to 1")
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

    @property
    def embedded(self) -> bool:
        return self.b_hat is not None


EULER = ButcherTableau("euler", 1, c=[0.0], a=[[0.0]], b=[1.0])
HEUN = ButcherTableau("heun", 2, c=[0.0, 1.0], a=[[0.0, 0.0], [1.0, 0.0]], b=[0.5, 0.5])
RK4 = ButcherTableau(
    "rk4", 4,
    c=[0.0, 0.5, 0.5, 1.0],
    a=[[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
    b=[1 / 6, 1 / 3, 1 / 3, 1 / 6],
)

# Dormand & Prince (1980), the pair behind MATLAB's ode45 and scipy's RK45: 5th-order solution,
# 4th-order embedded estimate, 7 stages with FSAL (6 evaluations per accepted step).
DOPRI5 = ButcherTableau(
    "dopri5", 5,
    c=[0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0],
    a=[[0, 0, 0, 0, 0, 0, 0],
       [1 / 5, 0, 0, 0, 0, 0, 0],
       [3 / 40, 9 / 40, 0, 0, 0, 0, 0],
       [44 / 45, -56 / 15, 32 / 9, 0, 0, 0, 0],
       [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0, 0],
       [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0, 0],
       [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0]],
    b=[35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0],
    b_hat=[5179 / 57600, 0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40],
    error_order=4, fsal=True,
)

"""Exact Euler-Bernoulli references for the beam-element tests and benchmarks/bench_beam_elements.py,
written without any viz3d code.

* Natural frequencies omega_i = (lambda_i L)^2 sqrt(EI / rho A) / L^2 with lambda_i L the roots of
  the classical frequency equations (Blevins, Formulas for Natural Frequency and Mode Shape, 1979,
  Table 8-1), solved here to full double precision with brentq:
  clamped-free  cos x cosh x = -1, free-free  cos x cosh x = 1 (elastic modes), pinned-pinned
  sin x = 0 (x = i pi). Each equation is divided by cosh x, so it reads cos x -/+ 1/cosh x = 0:
  O(1) and well conditioned; its i-th root lies within pi/4 of (i - 1/2) pi (clamped-free) or
  (i + 1/2) pi (free-free), where cos x = +-sqrt(2)/2 exceeds 1/cosh x in size.
* Hermite shape functions on [0, h] (sympy), from their interpolation conditions alone.
* The round-off floor of a result computed from a stiffness matrix K (static solve or eigenvalue):
  the computed result is exact for a problem perturbed by about n eps relative (backward
  stability of LU and of the symmetric eigensolvers, with the factor n of Wilkinson's bounds),
  which moves a relative result by at most that times the condition number of K. Nodal dofs
  carry different units (w, w', w''), so the condition number is taken after symmetric Jacobi
  scaling (within a factor n of the best diagonal scaling: van der Sluis, Numer. Math. 14, 1969),
  over the non-null eigenvalues (an unsupported beam has rigid modes).
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp
from scipy.optimize import brentq

EPS = np.finfo(float).eps
#: Relative tolerance of the roots: brentq's floor, 4 eps.
ROOT_RTOL = 4 * EPS

_EQUATIONS = {
    ("clamped", "free"): (lambda x: np.cos(x) + 1.0 / np.cosh(x), -0.5),
    ("free", "free"): (lambda x: np.cos(x) - 1.0 / np.cosh(x), 0.5),
}


def eb_roots(supports: tuple[str, str], n_modes: int) -> np.ndarray:
    """lambda_i L (n_modes,) of the lowest elastic modes of a uniform Euler-Bernoulli beam."""
    supports = tuple(supports)
    if supports == ("pinned", "pinned"):
        return np.pi * np.arange(1, n_modes + 1)
    f, shift = _EQUATIONS[supports]
    centres = (np.arange(1, n_modes + 1) + shift) * np.pi
    return np.array([brentq(f, c - np.pi / 4, c + np.pi / 4, xtol=1e-300, rtol=ROOT_RTOL) for c in centres])


def eb_frequencies(supports, n_modes, length, E, I, rho, A) -> np.ndarray:
    """omega_i (n_modes,) [rad/s] of the lowest elastic modes."""
    return eb_roots(supports, n_modes) ** 2 * np.sqrt(E * I / (rho * A)) / length**2


@functools.cache
def hermite_shapes(n_derivatives: int, x: sp.Symbol, h: sp.Expr) -> tuple:
    """The 2 n Hermite shapes on [0, h] of degree 2 n - 1 (n = ``n_derivatives``): derivative d < n
    of shape (end, d) is 1 at that end and every other condition is 0.
    Order [N_0, N_0', ..., N_h, N_h', ...] (cubic: n = 2, quintic: n = 3)."""
    degree = 2 * n_derivatives - 1
    conditions = [(end, d) for end in (0, h) for d in range(n_derivatives)]
    V = sp.Matrix([[sp.diff(x**k, x, d).subs(x, end) for k in range(degree + 1)] for end, d in conditions])
    coefficients = V.inv()  # column i: coefficients of shape i
    return tuple(sp.expand(sum(coefficients[k, i] * x**k for k in range(degree + 1))) for i in range(len(conditions)))


def roundoff_floor(K: np.ndarray, n_null: int = 0) -> float:
    """n eps kappa_J(K) (module docstring): K (n, n) symmetric positive semi-definite with ``n_null``
    zero eigenvalues."""
    d = 1.0 / np.sqrt(np.diag(K))
    ev = np.linalg.eigvalsh(d[:, None] * K * d[None, :])
    return K.shape[0] * EPS * ev[-1] / ev[n_null]

"""Butcher tableaus of explicit Runge-Kutta methods and their continuous extensions, validated on
construction (row sums, weights, and every order condition up to the declared order)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.polynomial import polynomial as npoly

#: Tolerance of the tableau consistency checks.
TABLEAU_TOL = 1e-14
#: Tolerance of the order conditions ``b . Phi(t) = 1 / gamma(t)``: the coefficients of DOP853
#: (up to 43 in magnitude, given to about 30 digits) satisfy them to 1e-15 in double precision.
ORDER_TOL = 1e-12


@lru_cache(maxsize=None)
def rooted_trees(n: int) -> tuple:
    """All rooted trees with ``n`` nodes, each a sorted tuple of its subtrees (the leaf is ``()``).

    Their numbers for n = 1, 2, ... are 1, 1, 2, 4, 9, 20, 48, 115 (OEIS A000081): one order
    condition each (Hairer, Norsett & Wanner, Solving ODEs I, sec. II.2).
    """
    if n == 1:
        return ((),)

    def forests(m, bound):
        """Multisets of trees of total size ``m``, members in non-increasing ``(size, tree)`` order."""
        if m == 0:
            yield ()
            return
        for k in range(min(m, bound[0]), 0, -1):
            for t in rooted_trees(k):
                if (k, t) <= bound:
                    for rest in forests(m - k, (k, t)):
                        yield (t,) + rest

    return tuple(sorted({tuple(sorted(f)) for f in forests(n - 1, (n, ()))}))


def _tree_density(t: tuple) -> int:
    """``gamma(t)``: the tree's size times the densities of its subtrees."""
    return _tree_size(t) * int(np.prod([_tree_density(c) for c in t]))


def _tree_size(t: tuple) -> int:
    return 1 + sum(_tree_size(c) for c in t)


def order_defects(a: np.ndarray, b: np.ndarray, order: int) -> np.ndarray:
    """``b . Phi(t) - 1 / gamma(t)`` for every rooted tree ``t`` with at most ``order`` nodes.

    ``Phi(t)`` is the stage vector of the tree: ones for the leaf, the elementwise product of
    ``a @ Phi(child)`` over the children otherwise (row-sum condition ``c = a 1`` assumed). A
    method has order ``p`` exactly when all defects up to ``p`` vanish.
    """

    def phi(t):
        v = np.ones(len(b))
        for child in t:
            v = v * (a @ phi(child))
        return v

    return np.array([b @ phi(t) - 1.0 / _tree_density(t) for n in range(1, order + 1) for t in rooted_trees(n)])


@dataclass(frozen=True)
class DenseOutput:
    """Continuous extension of a Runge-Kutta step (data; ``ExplicitRK.interpolant`` evaluates it).

    ``y(t0 + x h) = y0 + h sum_j K_j P_j(x)``, ``P_j(x) = sum_d P[j, d] x^(d + 1)``, over the
    method's ``s`` stages followed by ``m`` extra stages
    ``K_{s+i} = f(t0 + c_extra[i] h, y0 + h sum_j a_extra[i, j] K_j)``.

    Attributes
    ----------
    order : int
        Order of the interpolant (its local error is ``O(h^(order + 1))``).
    P : ndarray, shape (s + m, degree)
    c_extra : ndarray, shape (m,)
    a_extra : ndarray, shape (m, s + m), strictly lower triangular in its stage index
    """

    order: int
    P: np.ndarray
    c_extra: np.ndarray = field(default_factory=lambda: np.zeros(0))
    a_extra: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    def __post_init__(self):
        for key in ("P", "c_extra", "a_extra"):
            object.__setattr__(self, key, np.asarray(getattr(self, key), dtype=float))


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
    dense : DenseOutput, optional
        Continuous extension; without it dense output is cubic Hermite.

    Raises ``ValueError`` unless ``a`` is strictly lower triangular, ``sum(b) = 1`` (and
    ``sum(b_hat) = 1``), the rows of ``a`` sum to ``c``, and ``b`` (``b_hat``) satisfies every
    order condition up to ``order`` (``error_order``) to ``ORDER_TOL``.
    """

    name: str
    order: int
    c: np.ndarray
    a: np.ndarray
    b: np.ndarray
    b_hat: np.ndarray | None = None
    error_order: int | None = None
    fsal: bool = False
    dense: DenseOutput | None = None

    def __post_init__(self):
        for key in ("c", "a", "b"):  # C order: the compiled step's signature (one for every tableau)
            object.__setattr__(self, key, np.ascontiguousarray(getattr(self, key), dtype=float))
        if self.b_hat is not None:
            object.__setattr__(self, "b_hat", np.ascontiguousarray(self.b_hat, dtype=float))
            if abs(self.b_hat.sum() - 1) > TABLEAU_TOL or self.b_hat.shape != self.b.shape:
                raise ValueError(f"{self.name}: b_hat must have the shape of b and sum to 1")
        s = len(self.b)
        object.__setattr__(self, "_error_weights", self.b - self.b_hat if self.b_hat is not None else np.zeros(s))
        if self.a.shape != (s, s) or self.c.shape != (s,):
            raise ValueError(f"{self.name}: inconsistent stage count")
        if np.any(np.triu(self.a) != 0):
            raise ValueError(f"{self.name}: a must be strictly lower triangular (explicit method)")
        if abs(self.b.sum() - 1) > TABLEAU_TOL:
            raise ValueError(f"{self.name}: sum(b) = {self.b.sum()} != 1")
        if np.max(np.abs(self.a.sum(axis=1) - self.c)) > TABLEAU_TOL:
            raise ValueError(f"{self.name}: rows of a do not sum to c")
        for weights, order, what in ((self.b, self.order, "b"), (self.b_hat, self.error_order, "b_hat")):
            if weights is not None and order is not None:
                worst = np.max(np.abs(order_defects(self.a, weights, order)))
                if worst > ORDER_TOL:
                    raise ValueError(f"{self.name}: {what} violates an order condition of order <= {order} by {worst:.2e}")

    @property
    def stages(self) -> int:
        return len(self.b)

    @property
    def embedded(self) -> bool:
        return self.b_hat is not None

    @property
    def estimate_order(self) -> int:
        """Order of the error estimate the controller's exponent uses: ``error_order``, else
        ``order - 1``."""
        return self.error_order or self.order - 1

    @property
    def error_weights(self) -> np.ndarray:
        """``b - b_hat`` (s,): the step's error estimate is ``h sum (b - b_hat)_i k_i`` (zeros without
        an embedded solution)."""
        return self._error_weights


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
    # Shampine's fourth-order continuous extension (Hairer et al., Solving ODEs I, sec. II.6; the
    # coefficients of scipy's RK45.P), free: it uses the seven stages only.
    dense=DenseOutput(4, np.array([
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])),
)


def _dop853() -> ButcherTableau:
    """Hairer's DOP853: the 8th-order 12-stage pair of Dormand & Prince (1980) with a 5th-order
    embedded estimate and a 7th-order continuous extension (Hairer, Norsett & Wanner, Solving ODEs
    I, sec. II.10). The coefficients are taken as data from scipy
    (``scipy.integrate._ivp.dop853_coefficients``, transcribed from Hairer's Fortran code) and
    validated here against all 200 order conditions up to order 8.

    The error estimate is the 5th-order one (``E5``) alone; Hairer's code tempers it with a
    3rd-order one (``E3``), which makes its steps longer at the same tolerance. The continuous
    extension needs ``f(t + h, y1)`` (extra stage 13) and three more evaluations (stages 14-16);
    its weights are scipy's ``D`` and nested Horner form rewritten as polynomials in ``x``.
    """
    from scipy.integrate._ivp import dop853_coefficients as coef

    s, n_ext = coef.N_STAGES, coef.N_STAGES_EXTENDED
    b = np.zeros(n_ext)
    b[:s] = coef.B
    # scipy evaluates y(x) = y0 + F0 w0(x) + ... + F6 w6(x), with F_i = h G_i . K:
    G = np.zeros((7, n_ext))
    G[0] = b                                            # y1 - y0
    G[1] = -b
    G[1, 0] += 1.0                                      # h f0 - (y1 - y0)
    G[2] = 2.0 * b
    G[2, [0, s]] -= 1.0                                 # 2 (y1 - y0) - h (f1 + f0)
    G[3:] = coef.D
    # ... and w_i from its nested evaluation, alternately multiplied by x and (1 - x):
    w = [np.zeros(1) for _ in range(7)]
    for i, idx in enumerate(range(6, -1, -1)):
        w[idx] = npoly.polyadd(w[idx], [1.0])
        w = [npoly.polymul(wi, [0.0, 1.0] if i % 2 == 0 else [1.0, -1.0]) for wi in w]
    W = np.zeros((7, coef.INTERPOLATOR_POWER + 1))
    for i, wi in enumerate(w):
        W[i, : len(wi)] = wi
    P = (G.T @ W)[:, 1:]                                # no constant term: y(0) = y0
    dense = DenseOutput(7, P, c_extra=coef.C[s:], a_extra=coef.A[s:, :])
    return ButcherTableau("dop853", 8, c=coef.C[:s], a=coef.A[:s, :s], b=coef.B, b_hat=coef.B - coef.E5[:s],
                          error_order=5, fsal=False, dense=dense)


def __getattr__(name: str):
    """``DOP853``, built on first use: its coefficients come from scipy.integrate, whose import (0.3 s)
    a run with another method does not pay for (tests/test_startup.py)."""
    if name != "DOP853":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = globals()["DOP853"] = _dop853()
    return value

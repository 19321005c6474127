"""Independent reference for the spin-up beam (tests/flexible/test_spin_up_beam.py), written without
viz3d: the classical linear equation of a cantilever on a hub turned by a prescribed angle theta(t),
with the centrifugal tension's geometric stiffness (Kane, Ryan & Banerjee 1987, eq. for the "correct"
linearization; Simo & Vu-Quoc 1987):

    rho A (w_tt + theta_dd x - theta_d^2 w) + EI w'''' - (N(x) w')' = 0,   N = rho A theta_d^2 (L^2 - x^2) / 2,

w(0) = w'(0) = 0, a free end at L (w relative to the rotating frame; the axial field is quasi-static,
its Coriolis coupling neglected). Ritz with the polynomials ``(x / L)^(k + 1)``, k = 1..n, whose Gram
matrices are exact (polynomial integrals), integrated by scipy's DOP853.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import eigh


def _poly_integral(c: np.ndarray, L: float) -> float:
    """int_0^L p(x) dx for p with coefficients c in powers of x / L."""
    return float(L * np.sum(c / (np.arange(len(c)) + 1.0)))


def ritz_matrices(L: float, EI: float, rhoA: float, n: int) -> tuple[np.ndarray, ...]:
    """Mass M, bending stiffness K, tension stiffness per theta_d^2 G, load per theta_dd f (rho A x
    weighted), all (n, n) or (n,), for the shapes ``(x / L)^(k + 1)``, and their values at the tip (n,)."""
    P = np.polynomial.polynomial
    shapes = [np.eye(k + 2)[-1] for k in range(1, n + 1)]           # coefficients in xi = x / L
    d1 = [P.polyder(c) / L for c in shapes]
    d2 = [P.polyder(c, 2) / L**2 for c in shapes]
    tension = 0.5 * rhoA * L**2 * np.array([1.0, 0.0, -1.0])         # (L^2 - x^2) rho A / 2 in xi
    M = np.array([[rhoA * _poly_integral(P.polymul(a, b), L) for b in shapes] for a in shapes])
    K = np.array([[EI * _poly_integral(P.polymul(a, b), L) for b in d2] for a in d2])
    G = np.array([[_poly_integral(P.polymul(tension, P.polymul(a, b)), L) for b in d1] for a in d1])
    f = np.array([-rhoA * L * _poly_integral(P.polymul([0.0, 1.0], a), L) for a in shapes])
    return M, K, G, f, np.ones(n)


def spin_up_tip(L: float, EI: float, rhoA: float, omega_s: float, T_s: float, t_eval: np.ndarray,
                n: int = 8, stiffening: bool = True) -> np.ndarray:
    """Tip deflection w(L, t) [m] at ``t_eval`` for the spin-up theta_d = omega_s / T_s (t - T_s / 2 pi
    sin(2 pi t / T_s)) up to T_s, omega_s after."""
    M, K, G, f, tip = ritz_matrices(L, EI, rhoA, n)
    omega2, V = eigh(K, M)                     # mass-normalised Ritz modes: V^T M V = I (M is ill-conditioned)
    G_p, f_p, tip_p = V.T @ G @ V, V.T @ f, tip @ V

    def rates(t):
        if t >= T_s:
            return omega_s, 0.0
        a = 2.0 * np.pi / T_s
        return omega_s / T_s * (t - np.sin(a * t) / a), omega_s / T_s * (1.0 - np.cos(a * t))

    def rhs(t, y):
        w, wd = rates(t)
        p, pd = y[:n], y[n:]
        stiff = np.diag(omega2) + w * w * ((G_p if stiffening else 0.0) - np.eye(n))
        return np.concatenate([pd, wd * f_p - stiff @ p])

    sol = solve_ivp(rhs, (0.0, float(t_eval[-1])), np.zeros(2 * n), method="DOP853", t_eval=t_eval,
                    rtol=1e-10, atol=1e-13, max_step=T_s / 200)
    return tip_p @ sol.y[:n]

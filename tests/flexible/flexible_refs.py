"""Independent references for tests/flexible, written without any viz3d code.

* The thesis's "standard" data set and the numbers printed in the thesis or recomputed in its
  digest (/work/shared/seeds/002_digest.md, sections 2 and 5, cases V8, V13, V14, V19, V20).
* Frequency equations as the textbooks print them (explicit transcendental functions), and
  Blevins' table of Euler-Bernoulli roots (R. D. Blevins, Formulas for Natural Frequency and Mode
  Shape, 1979, Table 8-1, nine significant figures).
* The simply supported Timoshenko beam, whose modes are sin(k x) exactly: frequencies from the 2x2
  determinant of the field equations (Timoshenko 1921; Han, Benaroya & Wei, JSV 225, 1999).
* Przemieniecki's consistent mass matrix of the beam element with shear deformation and rotary
  inertia (J. S. Przemieniecki, Theory of Matrix Structural Analysis, 1968, ch. 11).
"""

from __future__ import annotations

import numpy as np

# ---- the thesis's standard data set (digest section 2) -----------------------------------------
L_STD = 0.3            # m
SIDE_STD = 0.03        # m, square section 3 cm x 3 cm
E_STD = 210e9          # Pa
RHO_EB = 7900.0        # kg/m^3, used for the Euler-Bernoulli numbers
RHO_TIMO = 7850.0      # kg/m^3, used by the digest's Timoshenko check
NU_STD = 0.3
K_SHEAR_STD = 5.0 / 6.0
AREA_STD = 9e-4        # m^2 (digest: "A = 9e-4 m^2, I = 6.75e-8 m^4 derived")
I_STD = 6.75e-8        # m^4
M_BAR_STD = 2.133      # kg, bar mass (= impactor mass, beta = 1)
C_T_STD = 44.65        # m^2/s, sqrt(EI / rho A) as printed by the digest (4 figures)

# ---- V13, thesis Table 8.3 and the digest's checks ----------------------------------------------
EB_CANTILEVER_LAMBDA_L = (1.8751, 4.6941, 7.8548, 10.9955, 14.1372, 17.2788)   # 4 decimals
EB_CANTILEVER_OMEGA_7900 = (1744, 10932, 30609, 59982, 99154, 148119)         # rad/s, [check]
EB_CANTILEVER_OMEGA_7850 = (1750, 10966, 30706, 60172, 99469, 148589)         # rad/s, [check]
TIMO_CANTILEVER_OMEGA_7850 = (1736, 10405, 27367, 49644, 75571, 103861)       # [check], 3000 linear elements
TIMO_CANTILEVER_OMEGA_7900 = (1731, 10372, 27281, 49486, 75332, 103532)       # [check], 3000 linear elements
# Table 8.3 as printed; its column labels are swapped (the digest's erratum 17):
TABLE_8_3_PRINTED_EB = (1736, 10423, 27480, 49979, 76266, 105040)           # actually Timoshenko
TABLE_8_3_PRINTED_TIMOSHENKO = (1747, 10959, 30687, 60134, 99406, 148495)   # actually Euler-Bernoulli

# ---- V8: composite "clamped bar + end mass" roots of k L tan k L = m2 / m1 at beta = 1 ----------
COMPOSITE_CLAMPED_BETA1_KL = (0.8603, 3.4256, 6.4373, 9.5293, 12.6453)

# ---- V14: cantilever with a tip mass equal to the bar's ------------------------------------------
TIP_MASS_BETA1_LAMBDA_L = 1.2479
TIP_MASS_BETA1_OMEGA1 = 772.6          # rad/s
TIP_MASS_BETA1_HALF_PERIOD = 4.066e-3  # s

# ---- V19: rotating axial bar ---------------------------------------------------------------------
ROTATING_OMEGA_CR_STD = 26996.0  # rad/s, c pi / (2 L) for the standard bar (rho = 7900)

# ---- Blevins, Table 8-1: lambda_i L ---------------------------------------------------------------
BLEVINS_LAMBDA_L = {
    ("clamped", "free"): (1.87510407, 4.69409113, 7.85475744, 10.9955407, 14.1371683),
    ("free", "free"): (4.73004074, 7.85320462, 10.9956078, 14.1371655, 17.2787597),
    ("clamped", "clamped"): (4.73004074, 7.85320462, 10.9956078, 14.1371655, 17.2787597),
    ("pinned", "free"): (3.92660231, 7.06858275, 10.2101761, 13.3517688, 16.4933614),
    ("pinned", "pinned"): tuple(i * np.pi for i in range(1, 6)),
}


# ---- frequency equations as printed (x = dimensionless root) -------------------------------------
def eb_frequency_equation(supports, x):
    """Classical EB frequency functions, divided by cosh x so they stay O(1) (Blevins Table 8-1)."""
    c, s, ch = np.cos(x), np.sin(x), np.cosh(x)
    return {
        ("clamped", "free"): c + 1.0 / ch,                 # cos cosh = -1 (thesis 8.8)
        ("free", "free"): c - 1.0 / ch,                    # cos cosh = 1
        ("clamped", "clamped"): c - 1.0 / ch,
        ("pinned", "free"): s - c * np.tanh(x),            # tan = tanh (thesis 10.9)
        ("pinned", "pinned"): s,
    }[tuple(supports)]


def eb_tip_mass_equation(x, beta):
    """Thesis (5.36): x (sin x cosh x - sinh x cos x) / (1 + cos x cosh x) - m2/m1, with beta = m2/m1."""
    c, s, ch, sh = np.cos(x), np.sin(x), np.cosh(x), np.sinh(x)
    return x * (s * ch - sh * c) / (1.0 + c * ch) - beta


def rod_clamped_mass_equation(x, beta):
    """Thesis (5.11): x tan x - m2/m1."""
    return x * np.tan(x) - beta


def rod_free_mass_equation(x, beta):
    """Corrected (9.19): tan x + (m1/m2) x = 0, i.e. -tan(x)/x = m1/m2 = 1/beta."""
    return np.tan(x) + x / beta


def rod_free_mass_equation_as_printed(x, beta):
    """(9.19) as printed: -tan(x)/x = m2/m1 = beta."""
    return np.tan(x) + beta * x


def blevins_cantilever_shape(x_over_L, lam):
    """Blevins' cantilever mode cosh - cos - sigma (sinh - sin), sigma = (sinh l - sin l)/(cosh l + cos l)."""
    sigma = (np.sinh(lam) - np.sin(lam)) / (np.cosh(lam) + np.cos(lam))
    z = lam * x_over_L
    return np.cosh(z) - np.cos(z) - sigma * (np.sinh(z) - np.sin(z))


# ---- Timoshenko simply supported -------------------------------------------------------------------
def timoshenko_ss_frequencies(E, G, rho, A, I, kappa, L, n_wave):
    """Both branches omega (2 n_wave,) sorted, for w = W sin(k x), psi = P cos(k x), k = i pi / L:
    det [[kGA k^2 - rho A w^2, -kGA k], [-kGA k, EI k^2 + kGA - rho I w^2]] = 0."""
    kGA, out = kappa * G * A, []
    for i in range(1, n_wave + 1):
        k = i * np.pi / L
        a = rho * A * rho * I
        b = -(rho * A * (E * I * k**2 + kGA) + rho * I * kGA * k**2)
        c = (kGA * k**2) * (E * I * k**2 + kGA) - (kGA * k) ** 2
        out += list(np.sqrt(np.roots([a, b, c]).real))
    return np.sort(out)


# ---- Przemieniecki's beam element with shear deformation -------------------------------------------
def przemieniecki_timoshenko_mass(rhoA, rhoI, h, phi):
    """Consistent mass (4, 4) for dofs [w1, psi1, w2, psi2], phi = 12 EI / (k G A h^2)."""
    f = phi
    t11, t13 = 13 / 35 + 7 * f / 10 + f * f / 3, 9 / 70 + 3 * f / 10 + f * f / 6
    t12, t14 = (11 / 210 + 11 * f / 120 + f * f / 24) * h, -(13 / 420 + 3 * f / 40 + f * f / 24) * h
    t22, t24 = (1 / 105 + f / 60 + f * f / 120) * h * h, -(1 / 140 + f / 60 + f * f / 120) * h * h
    T = np.array([[t11, t12, t13, t14], [t12, t22, -t14, t24], [t13, -t14, t11, -t12], [t14, t24, -t12, t22]])
    r12, r22, r24 = (1 / 10 - f / 2) * h, (2 / 15 + f / 6 + f * f / 3) * h * h, (-1 / 30 - f / 6 + f * f / 6) * h * h
    R = np.array([[6 / 5, r12, -6 / 5, r12], [r12, r22, -r12, r24], [-6 / 5, -r12, 6 / 5, -r12], [r12, r24, -r12, r22]])
    return rhoA * h / (1 + f) ** 2 * T + rhoI / (h * (1 + f) ** 2) * R


# ---- round-off of the symmetric-definite eigenproblem ----------------------------------------------
EPS = float(np.finfo(float).eps)


def eigenvalue_roundoff(K, M):
    """Approximate error bound of the computed eigenvalues of ``K v = lam M v``, relative to each |lam_i| (n,).

    LAPACK Users' Guide (3rd ed., 1999), sec. 4.7.1: a symmetric eigensolver returns eigenvalues within
    about EPSMCH ||A||_2 of the exact ones (EERRBD) and eigenvector angles within EPSMCH ||A||_2 / gap_i
    (ZERRBD). The symmetric-definite drivers solve A = L^-1 K L^-T (M = L L^T), whose norm is lam_max,
    so the relative bound of lam_i is eps lam_max / |lam_i|: eps times the eigenvalue's condition number.
    (Exact zeros - rigid modes - give inf; their absolute bound is eps lam_max.)
    """
    from scipy.linalg import eigh

    lam = eigh(K, M, eigvals_only=True)
    with np.errstate(divide="ignore"):
        return EPS * np.abs(lam).max() / np.abs(lam)


# ---- uniform meshes of linear rod elements: exact discrete dispersion ------------------------------
def rod_chain_omega(k, h, c, lumped=False):
    """omega_h(k) of a uniform chain of 2-node rod elements (element length h, wave speed c) for u_j = sin(k x_j).

    Consistent mass: omega^2 = (6 c^2 / h^2) (1 - cos kh) / (2 + cos kh); lumped: omega = (2 c / h) sin(kh / 2).
    On a clamped-free uniform mesh with k = (2 i - 1) pi / (2 L) these are the FE eigenvalues exactly:
    sin(k x) is symmetric about x = L, so the half-element equation of the free end is half an interior
    one (mirror image). Series: omega_h / omega - 1 = (kh)^2 / 24 + O(h^4) (consistent), -(kh)^2 / 24 (lumped).
    """
    k = np.asarray(k, dtype=float)
    if lumped:
        return 2 * c / h * np.sin(k * h / 2)
    return c / h * np.sqrt(6 * (1 - np.cos(k * h)) / (2 + np.cos(k * h)))


def rod_end_mass_chain_omegas(L, c, rhoA, n_elements, end_mass, n_roots):
    """First ``n_roots`` omega of a clamped rod of ``n_elements`` consistent linear elements with a mass at x = L.

    Inside the mesh u_j = sin(k x_j) with omega = rod_chain_omega(k); k is fixed by the equation of the end
    node, (EA / h)(u_N - u_N-1) = omega^2 [(rho A h / 6)(2 u_N + u_N-1) + m u_N] (the discrete form of
    k L tan k L = rho A L / m); one root per interval (i pi, i pi + pi / 2) of k L.
    """
    from scipy.optimize import brentq

    h = L / n_elements

    def end_equation(kL):
        k = kL / L
        w2 = rod_chain_omega(k, h, c) ** 2
        u_N, u_N1 = np.sin(kL), np.sin(kL - k * h)
        return rhoA * c**2 / h * (u_N - u_N1) - w2 * (rhoA * h / 6 * (2 * u_N + u_N1) + end_mass * u_N)

    tiny = 1e-9
    kL = [brentq(end_equation, i * np.pi + tiny, i * np.pi + np.pi / 2 - tiny, xtol=1e-15, rtol=4 * EPS)
          for i in range(n_roots)]
    return rod_chain_omega(np.array(kL) / L, h, c)


# ---- uniform meshes of Hermite cubic beam elements -----------------------------------------------
def hermite_chain_error(kh):
    """Leading relative frequency error omega_h / omega - 1 = (kh)^4 / 1440 of Hermite cubic beam elements.

    Bloch waves on a uniform chain of consistent-mass Hermite elements: omega_h^2 / omega^2 =
    1 + (kh)^4 / 720 - (kh)^6 / 25200 + O(h^8) (the 2x2 determinant of the element's stiffness and mass
    matrices, expanded with sympy). Supports add a relative correction of the same order (kh)^2 as the
    next chain term.
    """
    return np.asarray(kh, dtype=float) ** 4 / 1440

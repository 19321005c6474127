"""Contact-law parameters from material data or from a target coefficient of restitution.

Hertz constants (seed 002 eqs 3.27, 7.6), first-yield and fully-plastic indentations (7.7, 7.26),
the power-plastic constants (7.34) and damping parameters that give a requested restitution (the
restitution a law really gives in a one-degree-of-freedom impact: ``single_impact.achieved_restitution``).
Sign conventions and units as in ``viz3d.contact.laws``; SI throughout.

Moduli. ``E' = E / (1 - nu^2)`` is the plane-strain modulus of one body and ``E*`` the effective
modulus of a pair, ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``; the Hertz constant is
``K_h = 4/3 E* sqrt(R*)``, ``1/R* = 1/R1 + 1/R2``. The thesis's chapter-7 formulas (7.6), (7.7) and
(7.26) are written with ``E*`` = ``E'/2``, i.e. a sphere and a flat *of the same material*, although
the text says "rigid sphere" (digest Appendix A item 14); the ``*_thesis`` functions keep that form.
"""

from __future__ import annotations

import numpy as np

#: Peak Hertz pressure at first yield, p0 / sigma_Y, for nu ~ 0.3 (von Mises; Johnson 1985, sec. 6.2).
#: It gives the thesis's 25.27 = (1.6 pi)^2 in (7.26).
YIELD_PRESSURE_RATIO = 1.6
#: Yigit & Christoforou's (Tresca) yield factor: alpha_Y = 2.72 pi^2 R (sigma_Y / E')^2 (thesis eq. 7.7).
YIGIT_YIELD_FACTOR = 2.72
#: Tabor: a E' / (R sigma_Y) at the start of the fully plastic regime (thesis eq. 7.19, 7.26).
TABOR_FULLY_PLASTIC_X = 80.0
#: Tabor: a E' / (R sigma_Y) at the end of the elastic regime (thesis eq. 7.19).
TABOR_ELASTIC_X = 5.0
#: Tabor's mean pressure p_m / sigma_f at those two points (thesis eq. 7.19).
TABOR_ELASTIC_PRESSURE = 1.1
TABOR_FULLY_PLASTIC_PRESSURE = 2.8
#: Johnson's fully plastic slope, F / F_Y = 5.5 alpha / alpha_Y (thesis eq. 7.31, "Cr.J.").
JOHNSON_PLASTIC_SLOPE = 5.5
#: Bracket for the power-plastic exponent n in (7.34): between the linear and the cubic law.
POWER_EXPONENT_BRACKET = (1.0 + 1e-9, 3.0)
#: Below this |x|, x - ln(1 + x) is summed as a series (20 terms: error < 0.1^22 relative).
SERIES_LIMIT = 0.1
SERIES_TERMS = 20
#: Largest hysteresis factor searched when inverting the exact restitution relation (e -> 0 needs chi -> inf).
MAX_HYSTERESIS_FACTOR = 1e8
#: Largest damping ratio searched for the linear law (its restitution tends to 0 as zeta -> inf).
MAX_DAMPING_RATIO = 1e8


# --- moduli, radii, Hertz constants ----------------------------------------------------------------


def plane_strain_modulus(E: float, nu: float) -> float:
    """``E' = E / (1 - nu^2)`` [Pa]."""
    return E / (1.0 - nu**2)


def effective_modulus(E1: float, nu1: float, E2: float = np.inf, nu2: float = 0.0) -> float:
    """Effective modulus ``E* = 1 / (sigma1 + sigma2)``, ``sigma = (1 - nu^2) / E`` [Pa].

    ``E2 = inf`` (default) is a rigid second body.
    """
    return 1.0 / ((1.0 - nu1**2) / E1 + (1.0 - nu2**2) / E2)


def effective_radius(R1: float, R2: float = np.inf) -> float:
    """``R* = R1 R2 / (R1 + R2)`` [m]; ``R2 = inf`` (default) is a flat (half-space)."""
    return 1.0 / (1.0 / R1 + 1.0 / R2)


def hertz_stiffness(E_star: float, R_star: float) -> float:
    """Hertz constant ``K_h = 4/3 E* sqrt(R*)`` [N/m^1.5], ``F = K_h alpha^1.5``.

    References
    ----------
    Johnson, *Contact Mechanics* (1985), eq. 4.23; seed 002 eq. 3.27.
    """
    return 4.0 / 3.0 * E_star * np.sqrt(R_star)


def hertz_stiffness_spheres(R1: float, E1: float, nu1: float, R2: float, E2: float, nu2: float) -> float:
    """Hertz constant of two spheres (thesis eq. 3.27) [N/m^1.5]."""
    return hertz_stiffness(effective_modulus(E1, nu1, E2, nu2), effective_radius(R1, R2))


def hertz_stiffness_sphere_plane(R: float, E_sphere: float, nu_sphere: float, E_plane: float, nu_plane: float) -> float:
    """Hertz constant of a sphere on a flat half-space, ``4/3 sqrt(R) / (sigma_sph + sigma_pln)`` (seed 004)."""
    return hertz_stiffness(effective_modulus(E_sphere, nu_sphere, E_plane, nu_plane), R)


def hertz_stiffness_thesis(R: float, E: float, nu: float) -> float:
    """Thesis eq. 7.6, ``K_h = 2/3 E' sqrt(R)``: a sphere on a flat of the *same* material.

    Equal to ``hertz_stiffness_sphere_plane(R, E, nu, E, nu)``; a truly rigid sphere gives twice this.
    """
    return 2.0 / 3.0 * plane_strain_modulus(E, nu) * np.sqrt(R)


# --- elastoplastic thresholds (thesis sec. 7.3.3-7.3.5) --------------------------------------------


def yield_indentation(R_star: float, E_star: float, sigma_Y: float, pressure_ratio: float = YIELD_PRESSURE_RATIO) -> float:
    """Indentation at first yield, peak Hertz pressure ``p0 = pressure_ratio sigma_Y`` [m].

    ``p0 = 2 E* a / (pi R*)`` and ``a^2 = alpha R*`` give ``alpha_Y = R* (pi p0 / (2 E*))^2``.
    """
    return R_star * (np.pi * pressure_ratio * sigma_Y / (2.0 * E_star)) ** 2


def yield_indentation_yigit(R: float, E: float, nu: float, sigma_Y: float) -> float:
    """Yigit & Christoforou, thesis eq. 7.7: ``alpha_Y = 2.72 pi^2 R (sigma_Y / E')^2`` [m]."""
    return YIGIT_YIELD_FACTOR * np.pi**2 * R * (sigma_Y / plane_strain_modulus(E, nu)) ** 2


def yield_indentation_thesis(R: float, E: float, nu: float, sigma_Y: float) -> float:
    """Power-plastic model, thesis eq. 7.26: ``(1.6 pi)^2 R (sigma_Y/E')^2 = 25.27 R (sigma_Y/E')^2`` [m].

    ``yield_indentation`` with ``E* = E'/2`` (same-material convention of chapter 7).
    """
    return yield_indentation(R, plane_strain_modulus(E, nu) / 2.0, sigma_Y)


def fully_plastic_indentation(R: float, E: float, nu: float, sigma_Y: float) -> float:
    """Start of the fully plastic regime, thesis eq. 7.26: ``3200 R (sigma_Y/E')^2`` [m].

    From Tabor's ``a E' / (R sigma_Y) = 80`` and the plastic contact radius ``a^2 = 2 alpha R`` (7.23).
    The middle expression printed in (7.26) has a spurious pi (digest Appendix A item 15).
    """
    return TABOR_FULLY_PLASTIC_X**2 / 2.0 * R * (sigma_Y / plane_strain_modulus(E, nu)) ** 2


def yield_force(K_h: float, alpha_Y: float) -> float:
    """Hertz force at first yield, ``F_Y = K_h alpha_Y^1.5`` [N]."""
    return K_h * alpha_Y**1.5


def yigit_plastic_stiffness(K_h: float, alpha_Y: float) -> float:
    """Slope of the Hertz curve at yield, ``K_Y = 3/2 K_h alpha_Y^0.5`` (eq. 7.8, "Cr.Y.") [N/m]."""
    return 1.5 * K_h * np.sqrt(alpha_Y)


def johnson_plastic_stiffness(K_h: float, alpha_Y: float) -> float:
    """Johnson's fully plastic slope ``K_J = 5.5 F_Y / alpha_Y`` (eq. 7.31, "Cr.J.") [N/m]."""
    return JOHNSON_PLASTIC_SLOPE * yield_force(K_h, alpha_Y) / alpha_Y


def power_plastic_constants(K_h: float, alpha_Y: float, alpha_fp: float) -> tuple[float, float]:
    """``(K_hY, n)`` of the plastic loading ``F = K_hY (alpha^n - alpha_Y^n) + F_Y`` (thesis eq. 7.34).

    Tangent at ``alpha_Y`` equal to ``yigit_plastic_stiffness`` and secant from ``alpha_Y`` to
    ``alpha_fp`` equal to ``johnson_plastic_stiffness``. Dividing the two conditions leaves one
    equation in ``n``, ``(r^n - 1) / (n (r - 1)) = K_J / K_Y`` with ``r = alpha_fp / alpha_Y``.

    Returns
    -------
    K_hY : float [N/m^n]
    n : float
    """
    from scipy.optimize import brentq
    r = alpha_fp / alpha_Y
    ratio = johnson_plastic_stiffness(K_h, alpha_Y) / yigit_plastic_stiffness(K_h, alpha_Y)
    n = brentq(lambda n: (r**n - 1.0) / (n * (r - 1.0)) - ratio, *POWER_EXPONENT_BRACKET, xtol=1e-15)
    K_hY = yigit_plastic_stiffness(K_h, alpha_Y) / (n * alpha_Y ** (n - 1.0))
    return float(K_hY), float(n)


def tabor_parabola() -> tuple[float, float, float]:
    """Coefficients ``(A, B, C)`` of ``p_m / sigma_f = A (log10 x)^2 + B log10 x + C`` (thesis eq. 7.17-7.19).

    Solved from Tabor's two points and the maximum at full plasticity. The thesis prints
    ``(-1.18, 4.49, -1.47)`` (7.20); the exact solution of its own conditions is ``(-1.172, 4.463, -1.446)``.
    """
    l5, l80 = np.log10(TABOR_ELASTIC_X), np.log10(TABOR_FULLY_PLASTIC_X)
    M = np.array([[l5**2, l5, 1.0], [l80**2, l80, 1.0], [2.0 * l80, 1.0, 0.0]])
    A, B, C = np.linalg.solve(M, [TABOR_ELASTIC_PRESSURE, TABOR_FULLY_PLASTIC_PRESSURE, 0.0])
    return float(A), float(B), float(C)


# --- damping from a target coefficient of restitution ----------------------------------------------


def hunt_crossley_factor(e: float) -> float:
    """Hunt & Crossley's estimate ``chi = 3 (1 - e) / 2`` (``lambda = chi K / alpha_dot_0``).

    References
    ----------
    Hunt & Crossley, J. Appl. Mech. 42 (1975); Marhefka & Orin, IEEE SMC-A 29 (1999).
    """
    return 1.5 * (1.0 - e)


def lankarani_nikravesh_factor(e: float) -> float:
    """Lankarani & Nikravesh's ``chi = 3 (1 - e^2) / 4``.

    References
    ----------
    Lankarani & Nikravesh, J. Mech. Des. 112 (1990) 369-376.
    """
    return 0.75 * (1.0 - e**2)


def flores_factor(e: float) -> float:
    """Flores et al.'s ``chi = 8 (1 - e) / (5 e)`` (seed 004).

    References
    ----------
    Flores, Machado, Silva & Martins, Multibody Syst. Dyn. 25 (2011) 357-375.
    """
    return 8.0 * (1.0 - e) / (5.0 * e)


def hysteresis_restitution(chi: float) -> float:
    """Exact restitution of ``F = K alpha^n (1 + chi alpha_dot / alpha_dot_0)`` in a free 1-DOF impact.

    ``m w dw/dalpha = -K alpha^n (1 + chi w / w0)`` separates; integrating from entry
    (``alpha = 0, w = w0``) to exit (``alpha = 0, w = -e w0``) gives, for any ``n``, ``K``, ``m``, ``w0``,

        chi - ln(1 + chi) = -chi e - ln(1 - chi e),

    whose root with ``0 < chi e < 1`` is returned (``e = 1`` for ``chi = 0``). Solved for
    ``y = -ln(1 - chi e) > 0``: ``y - (1 - exp(-y)) = chi - ln(1 + chi)``, monotonic in ``y``.
    """
    from scipy.optimize import brentq
    if chi == 0.0:
        return 1.0
    target = _x_minus_log1p(chi)
    y = brentq(lambda y: _y_minus_one_minus_exp(y) - target, 0.0, target + 1.0, xtol=1e-300, rtol=4 * np.finfo(float).eps)
    return float(-np.expm1(-y) / chi)


def _y_minus_one_minus_exp(y: float) -> float:
    """``y - (1 - exp(-y))`` = ``u - ln(1 + u)`` at ``u = exp(-y) - 1``."""
    return _x_minus_log1p(np.expm1(-y)) if y < SERIES_LIMIT else float(y + np.expm1(-y))


def _x_minus_log1p(x: float) -> float:
    """``x - ln(1 + x)`` without cancellation for small ``|x|`` (series ``x^2/2 - x^3/3 + ...``)."""
    if abs(x) > SERIES_LIMIT:
        return float(x - np.log1p(x))
    k = np.arange(2, SERIES_TERMS + 2)
    return float(np.sum((-1.0) ** k * x**k / k))


def hysteresis_factor_exact(e: float) -> float:
    """Hysteresis factor ``chi`` whose exact restitution is ``e`` (inverse of ``hysteresis_restitution``)."""
    from scipy.optimize import brentq
    _check_restitution(e)
    if e == 1.0:
        return 0.0
    return float(brentq(lambda chi: hysteresis_restitution(chi) - e, 0.0, MAX_HYSTERESIS_FACTOR, xtol=1e-300, rtol=1e-14))


def linear_restitution(zeta: float) -> float:
    """Exact restitution of the no-tension Kelvin-Voigt contact ``F = max(K alpha + D alpha_dot, 0)``.

    ``zeta = D / (2 sqrt(K m))``. The force vanishes (and the bodies separate) when
    ``K alpha + D alpha_dot = 0``; along the damped-oscillator solution that happens at
    ``omega_d t = pi - 2 asin(zeta)`` (``zeta < 1``; ``2 acosh(zeta)`` on the hyperbolic branch),
    where ``alpha_dot = -v0 exp(-zeta omega t)``. Hence ``e = exp(-zeta phi / sqrt|1 - zeta^2|)``;
    ``e(1) = exp(-2)``. The textbook ``exp(-zeta pi / sqrt(1 - zeta^2))`` assumes a tensile force at
    the end of contact and overestimates the loss.
    """
    if zeta == 1.0:
        return float(np.exp(-2.0))
    if zeta < 1.0:
        phase = 2.0 * np.arccos(zeta)  # = pi - 2 asin(zeta), accurate near zeta = 1
    else:
        phase = 2.0 * np.arccosh(zeta)
    return float(np.exp(-zeta * phase / np.sqrt(abs(1.0 - zeta**2))))


def linear_damping(stiffness: float, m_eff: float, e: float) -> float:
    """Dashpot ``D`` [N s/m] giving restitution ``e`` to the no-tension linear law (see ``linear_restitution``)."""
    from scipy.optimize import brentq
    _check_restitution(e)
    if e == 1.0:
        return 0.0
    zeta = brentq(lambda z: linear_restitution(z) - e, 0.0, MAX_DAMPING_RATIO, xtol=1e-15, rtol=1e-14)
    return float(2.0 * zeta * np.sqrt(stiffness * m_eff))


def _check_restitution(e: float) -> None:
    if not 0.0 < e <= 1.0:
        raise ValueError(f"coefficient of restitution must be in (0, 1], got {e}")

"""Contact parameters from material data: Hertz constants, yield indentations, Table 7.1 (V15)."""

import numpy as np
import pytest
from law_examples import NU, SIGMA_Y, E, R

from viz3d.contact.laws import PowerPlastic
from viz3d.contact.parameters import (
    effective_modulus,
    fully_plastic_indentation,
    hertz_stiffness_sphere_plane,
    hertz_stiffness_spheres,
    hertz_stiffness_thesis,
    johnson_plastic_stiffness,
    plane_strain_modulus,
    power_plastic_constants,
    tabor_parabola,
    yield_indentation,
    yield_indentation_thesis,
    yield_indentation_yigit,
    yigit_plastic_stiffness,
)

#: Formula against its re-typed form: rounding only.
FORMULA_RTOL = 1e-13
#: Table 7.1 prints n = 1.33: half a unit of its last digit.
N_PRINTED_TOL = 0.005
#: The brief (and digest V15): K_hY within 20 % of the printed 3.78e9 (inputs inferred, n sensitive).
K_HY_RTOL = 0.20
#: "Cr.Y. = 8e7" has one significant digit: +-0.5e7.
CR_Y_ATOL = 0.5e7
#: "Cr.J. = 2.95e8": half a unit of the last digit (0.17 %) plus sigma_Y = 0.64 GPa known to two
#: digits (0.8 %; Cr.J is proportional to sigma_Y): 1 %.
CR_J_RTOL = 0.01
#: Digest [check] solution of (7.17)-(7.19), printed to 3 decimals.
TABOR_CHECK = (-1.172, 4.463, -1.446)
TABOR_CHECK_TOL = 5e-4


def test_hertz_constant_of_two_spheres_is_eq_3_27():
    R1, E1, nu1, R2, E2, nu2 = 0.01, 210e9, 0.3, 0.03, 70e9, 0.33
    k1, k2 = (1 - nu1**2) / E1, (1 - nu2**2) / E2
    K = 4.0 / 3.0 / (k1 + k2) * np.sqrt(R1 * R2 / (R1 + R2))
    assert hertz_stiffness_spheres(R1, E1, nu1, R2, E2, nu2) == pytest.approx(K, rel=FORMULA_RTOL)


def test_sphere_on_plane_is_the_infinite_radius_limit_and_seed_004_form():
    K = hertz_stiffness_sphere_plane(R, E, NU, 70e9, 0.33)
    assert K == pytest.approx(hertz_stiffness_spheres(R, E, NU, 1e12, 70e9, 0.33), rel=1e-12)
    sigma = (1 - NU**2) / E + (1 - 0.33**2) / 70e9
    assert K == pytest.approx(4.0 / 3.0 * np.sqrt(R) / sigma, rel=FORMULA_RTOL)


def test_thesis_eq_7_6_is_a_sphere_on_a_flat_of_the_same_material():
    """(7.6) K_h = 2/3 E' sqrt(R): the same-material pair; a rigid sphere is twice as stiff (digest note)."""
    same = hertz_stiffness_sphere_plane(R, E, NU, E, NU)
    rigid_sphere = hertz_stiffness_sphere_plane(R, np.inf, 0.0, E, NU)
    assert hertz_stiffness_thesis(R, E, NU) == pytest.approx(same, rel=FORMULA_RTOL)
    assert rigid_sphere == pytest.approx(2.0 * same, rel=FORMULA_RTOL)
    assert effective_modulus(E, NU, E, NU) == pytest.approx(plane_strain_modulus(E, NU) / 2.0, rel=FORMULA_RTOL)


def test_yield_indentation_factors():
    """Y&C's 2.72 pi^2 (7.7); the power model's (1.6 pi)^2 = 25.27 (7.26) and 3200 from x = 80."""
    scale = R * (SIGMA_Y / plane_strain_modulus(E, NU)) ** 2
    assert yield_indentation_yigit(R, E, NU, SIGMA_Y) / scale == pytest.approx(2.72 * np.pi**2, rel=FORMULA_RTOL)
    assert yield_indentation_thesis(R, E, NU, SIGMA_Y) / scale == pytest.approx(25.27, abs=0.005)
    assert fully_plastic_indentation(R, E, NU, SIGMA_Y) / scale == pytest.approx(3200.0, rel=FORMULA_RTOL)


def test_yield_indentation_is_where_the_hertz_peak_pressure_reaches_1_6_sigma_Y():
    """Johnson (1985) eqs. 4.22-4.23: a^3 = 3 F R / (4 E*), p0 = 3 F / (2 pi a^2)."""
    E_star, R_star = effective_modulus(E, NU, 70e9, 0.33), 0.01
    alpha = yield_indentation(R_star, E_star, SIGMA_Y)
    F = 4.0 / 3.0 * E_star * np.sqrt(R_star) * alpha**1.5
    a = (3.0 * F * R_star / (4.0 * E_star)) ** (1.0 / 3.0)
    assert 3.0 * F / (2.0 * np.pi * a**2) == pytest.approx(1.6 * SIGMA_Y, rel=1e-12)


def test_table_7_1_power_plastic_constants():
    """V15: solving (7.34) for R = 25 mm, E = 210 GPa, nu = 0.3, sigma_Y = 0.64 GPa."""
    K_h = hertz_stiffness_thesis(R, E, NU)
    a_Y = yield_indentation_thesis(R, E, NU, SIGMA_Y)
    a_fp = fully_plastic_indentation(R, E, NU, SIGMA_Y)
    K_hY, n = power_plastic_constants(K_h, a_Y, a_fp)
    cr_y, cr_j = yigit_plastic_stiffness(K_h, a_Y), johnson_plastic_stiffness(K_h, a_Y)
    assert n == pytest.approx(1.33, abs=N_PRINTED_TOL)
    assert K_hY == pytest.approx(3.78e9, rel=K_HY_RTOL)
    assert cr_y == pytest.approx(8e7, abs=CR_Y_ATOL)
    assert cr_j == pytest.approx(2.95e8, rel=CR_J_RTOL)
    # both criteria hold exactly for the solved constants (the "New eq." column: K_Yt = Cr.Y, secant = Cr.J)
    assert n * K_hY * a_Y ** (n - 1) == pytest.approx(cr_y, rel=1e-10)
    assert K_hY * (a_fp**n - a_Y**n) / (a_fp - a_Y) == pytest.approx(cr_j, rel=1e-10)


def test_power_plastic_from_material_uses_the_solved_constants():
    law = PowerPlastic.from_material(R, E, NU, SIGMA_Y)
    assert (law.K_hY, law.n) == pytest.approx(power_plastic_constants(law.K_h, law.alpha_Y, law.alpha_fp), rel=1e-14)
    assert law.E_star == pytest.approx(effective_modulus(E, NU, E, NU), rel=FORMULA_RTOL)


def test_tabor_parabola_solves_its_three_conditions():
    """(7.17)-(7.19); the thesis prints (-1.18, 4.49, -1.47) for the exact (-1.172, 4.463, -1.446)."""
    A, B, C = tabor_parabola()

    def y(x):
        return A * np.log10(x) ** 2 + B * np.log10(x) + C

    assert y(5.0) == pytest.approx(1.1, rel=1e-12) and y(80.0) == pytest.approx(2.8, rel=1e-12)
    assert 2 * A * np.log10(80.0) + B == pytest.approx(0.0, abs=1e-12)
    assert (A, B, C) == pytest.approx(TABOR_CHECK, abs=TABOR_CHECK_TOL)

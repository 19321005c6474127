"""Analytic mode sets against the thesis, its digest, Blevins' tables and the printed frequency
equations (validation cases V8, V13, V14, V19, V20 of the digest)."""

import flexible_refs as ref
import numpy as np
import pytest
from scipy.optimize import brentq

from viz3d.flexible import MODE_SETS, Material, Section, analytic_modes, mode_set

#: Modal integrals and orthogonality: machine precision (digest V20 asks 1e-10); quadrature of the
#: closed-form shapes reaches ~1e-14 for 10 modes, 5e-12 for 40.
ORTHO_TOL = 1e-10
#: The digest prints roots lambda L, k L to 4 decimals: half a unit of the last digit (+ round-off).
DIGITS4_TOL = 0.5e-4 + 1e-12
#: Blevins tabulates 9 significant figures.
BLEVINS_RTOL = 1e-8
#: Residual of a printed frequency equation at our roots, relative to its O(1) terms (brentq to
#: 4 eps in the root; the equations amplify it by at most ~100).
FREQ_EQ_TOL = 1e-11
#: The digest's [check] frequencies are integers (rounding 0.5 rad/s); its Timoshenko ones come
#: from 3000 linear elements, whose O(h^2) error is ~(k h)^2 / 12 <= 1e-5 for the 6th mode.
CHECK_ABS_TOL = 0.5 + 1e-9
CHECK_TIMO_RTOL = 1e-5
#: Digest V13 tolerances on the thesis's own Table 8.3: EB 0.5 %, Timoshenko 1.5 % (shear
#: coefficient and density uncertain).
THESIS_EB_RTOL = 0.005
THESIS_TIMO_RTOL = 0.015
#: Digest V19: steady centrifugal elongation to 0.5 %.
ROTATING_RTOL = 0.005
#: Digest prints omega_1 = 772.6 rad/s and the half period 4.066 ms (4 figures).
TIP_OMEGA_TOL = 0.05 + 1e-9
TIP_HALF_PERIOD_TOL = 0.5e-6


def _steel(rho=ref.RHO_EB):
    return Material(ref.E_STD, rho, ref.NU_STD)


SECTION = Section.rectangle(ref.SIDE_STD, ref.SIDE_STD, ref.K_SHEAR_STD)


def _lambda_L(model):
    """Dimensionless EB roots from the model's frequencies (from its integrated M and K)."""
    c_t = np.sqrt(model.material.E * model.section.second_moment / (model.material.rho * model.section.area))
    return np.sqrt(model.frequencies() / c_t) * model.length


def _build(name, n, rho=ref.RHO_EB, **kw):
    kwargs = {"tip_mass": ref.M_BAR_STD} if MODE_SETS[name].with_tip_mass else {}
    kwargs.update(kw)
    return MODE_SETS[name](ref.L_STD, _steel(rho), SECTION, n, **kwargs)


# ---- the standard data set -----------------------------------------------------------------------
def test_standard_section_and_mass_match_the_digest():
    assert SECTION.area == pytest.approx(ref.AREA_STD, rel=1e-14, abs=0)  # abs=0: approx adds 1e-12 otherwise
    assert SECTION.second_moment == pytest.approx(ref.I_STD, rel=1e-14, abs=0)
    model = _build("bending_cantilever", 1)
    assert model.bar_mass == pytest.approx(ref.M_BAR_STD, abs=5e-4)
    c_t = np.sqrt(ref.E_STD * ref.I_STD / (ref.RHO_EB * ref.AREA_STD))
    assert c_t == pytest.approx(ref.C_T_STD, abs=0.005)


# ---- orthogonality and end conditions of every registered set (digest V20) -------------------------
@pytest.mark.parametrize("name", sorted(MODE_SETS))
def test_every_mode_set_is_orthogonal_and_matches_its_frequency_roots(name):
    model = _build(name, 10)
    omega = model.basis.omega
    assert np.abs(model.M - np.eye(10)).max() < ORTHO_TOL, "mismatch: M != I"
    assert np.abs(model.K - np.diag(omega**2)).max() < ORTHO_TOL * omega.max() ** 2, "mismatch: K != diag(omega^2)"
    assert np.abs(model.frequencies() / omega - 1).max() < ORTHO_TOL, "mismatch: eig(K, M) vs roots"
    assert np.all(np.diff(omega) > 0)


@pytest.mark.parametrize("name", sorted(MODE_SETS))
def test_every_mode_set_satisfies_its_end_conditions(name):
    model = _build(name, 6)
    L, omega = model.length, model.basis.omega
    scale = np.abs(model.displacement(np.linspace(0, L, 50))).max(axis=0)
    for x, support in zip((0.0, L), model.supports):
        u = model.displacement([x])[0]
        m_end = sum(pm.mass for pm in model.point_masses if pm.x == x)
        sign = 1.0 if x == L else -1.0  # an end mass is driven by the end force: m u_tt = -sign (N or V)
        if model.kind == "axial":
            N = model.axial_force([x])[0]
            checks = {"free": [(N - sign * m_end * omega**2 * u) * L / (model.material.E * model.section.area)]}
        else:
            EI = model.material.E * model.section.second_moment
            M_ = model.bending_moment([x])[0] * L**2 / EI
            V = model.shear_force([x])[0]
            checks = {"clamped": [model.rotation([x])[0] * L], "pinned": [M_],
                      "free": [M_, (V - sign * m_end * omega**2 * u) * L**3 / EI]}
        if support != "free":
            assert np.abs(u / scale).max() < ORTHO_TOL, f"{support} end at x = {x}: displacement"
        for value in checks.get(support, []):
            assert np.abs(value / scale).max() < 1e3 * ORTHO_TOL, f"{support} end at x = {x}"


def test_unknown_mode_set_names_the_valid_ones():
    with pytest.raises(KeyError, match="bending_cantilever"):
        mode_set("cantilever")


def test_tip_mass_sets_require_a_tip_mass_and_others_refuse_one():
    with pytest.raises(ValueError):
        MODE_SETS["axial_free_mass"](ref.L_STD, _steel(), SECTION, 3)
    with pytest.raises(ValueError):
        MODE_SETS["bending_cantilever"](ref.L_STD, _steel(), SECTION, 3, tip_mass=1.0)
    with pytest.raises(ValueError, match="free end"):
        analytic_modes("rod", ref.L_STD, _steel(), SECTION, 3, ("clamped", "free"), end_masses=(1.0, 0.0))


# ---- V20: axial modal integrals in the thesis's scaling --------------------------------------------
def test_axial_free_free_modes_have_zero_momentum_and_thesis_modal_data():
    model = _build("axial_free_free", 8, normalization="unit")
    m2, EA, L, i = model.bar_mass, ref.E_STD * SECTION.area, ref.L_STD, np.arange(1, 9)
    assert np.abs(np.diag(model.M) / (m2 / 2) - 1).max() < ORTHO_TOL          # (9.27)
    assert np.abs(np.diag(model.K) / (EA * i**2 * np.pi**2 / (2 * L)) - 1).max() < ORTHO_TOL  # (9.28)
    assert np.abs(model.S1).max() < ORTHO_TOL * m2                            # (9.29): no elastic momentum
    assert np.abs(model.S2).max() > 0.01 * m2 * L  # odd modes carry angular momentum: a real check, not a zero


def test_axial_cantilever_modes_carry_momentum_2m_over_2i_minus_1_pi():
    model = _build("axial_clamped_free", 8, normalization="unit")
    m2, EA, L, i = model.bar_mass, ref.E_STD * SECTION.area, ref.L_STD, np.arange(1, 9)
    tip = model.displacement([L])[0]  # our shapes are positive at the tip; the thesis's sin() alternates
    thesis_sign = np.sin((2 * i - 1) * np.pi / 2)
    assert np.abs(tip - 1).max() < ORTHO_TOL
    assert np.abs(np.diag(model.M) / (m2 / 2) - 1).max() < ORTHO_TOL                          # (10.2)
    assert np.abs(np.diag(model.K) / (EA * (2 * i - 1) ** 2 * np.pi**2 / (8 * L)) - 1).max() < ORTHO_TOL
    expected = 2 * m2 / ((2 * i - 1) * np.pi) * thesis_sign
    assert np.abs(model.S1 - expected).max() < ORTHO_TOL * m2


def test_composite_free_bar_modes_decouple_the_reference_coordinate():
    """(9.20): rho A int phi + m1 phi(L) = 0 for the free bar + end mass, for beta != 1 too."""
    for beta in (0.25, 1.0, 4.0):
        m1 = ref.M_BAR_STD / beta
        model = MODE_SETS["axial_free_mass"](ref.L_STD, _steel(), SECTION, 8, tip_mass=m1)
        assert np.abs(model.S1).max() < ORTHO_TOL * np.sqrt(model.mass), f"beta = {beta}"
        kL = model.basis.omega * ref.L_STD / model.material.wave_speed
        res = ref.rod_free_mass_equation(kL, model.bar_mass / m1) * np.cos(kL)  # x cos: O(1), no pole
        assert np.abs(res).max() < FREQ_EQ_TOL * 10, f"beta = {beta}: corrected (9.19) not satisfied"


def test_printed_equation_9_19_would_not_decouple_the_reference_coordinate():
    """Erratum check: with m2/m1 on the right of (9.19) (beta = 4), cos(k x) modes carry momentum."""
    beta, L = 4.0, ref.L_STD
    m2 = _build("axial_free_free", 1).bar_mass
    m1 = m2 / beta
    x_printed = brentq(lambda x: np.sin(x) + beta * x * np.cos(x), np.pi / 2 + 1e-9, np.pi - 1e-9)
    # to the last bits (brentq's default xtol, 2e-12, is the size of the tolerance below)
    x_ours = brentq(lambda x: np.sin(x) + x / beta * np.cos(x), np.pi / 2 + 1e-9, np.pi - 1e-9, xtol=1e-15,
                    rtol=4 * np.finfo(float).eps)
    momentum = lambda x: m2 * np.sin(x) / x + m1 * np.cos(x)  # noqa: E731  rho A int cos(kx) + m1 cos(kL)
    model = MODE_SETS["axial_free_mass"](L, _steel(), SECTION, 1, tip_mass=m1, normalization="unit")
    assert model.basis.omega[0] * L / model.material.wave_speed == pytest.approx(x_ours, rel=1e-12)
    assert abs(momentum(x_ours)) < ORTHO_TOL * m2
    assert abs(momentum(x_printed)) > 0.1 * m1


# ---- V8: composite "clamped bar + impactor" contact modes -----------------------------------------
def test_composite_clamped_bar_roots_for_beta_1():
    model = _build("axial_clamped_mass", 5)
    kL = model.frequencies() * ref.L_STD / model.material.wave_speed
    assert np.abs(kL - ref.COMPOSITE_CLAMPED_BETA1_KL).max() < DIGITS4_TOL
    res = ref.rod_clamped_mass_equation(kL, model.bar_mass / ref.M_BAR_STD) * np.cos(kL)
    assert np.abs(res).max() < FREQ_EQ_TOL * 10


def test_composite_contact_modes_are_orthogonal_with_the_end_mass_5_13():
    model = _build("axial_clamped_mass", 6, normalization="unit")
    x_in = np.linspace(0, ref.L_STD, 7)[1:-1]
    assert np.abs(model.M - np.diag(np.diag(model.M))).max() < ORTHO_TOL * np.abs(model.M).max()
    rhoA = model.material.rho * model.section.area
    without_mass = rhoA * model.integrate(lambda x: np.einsum("pi,pj->pij", model.displacement(x), model.displacement(x)))
    # without the end mass the shapes are not orthogonal: the mass term is what makes (5.13) hold
    assert np.abs(without_mass - np.diag(np.diag(without_mass))).max() > 0.01 * np.abs(model.M).max()
    assert np.all(np.abs(model.displacement(x_in)) <= 1 + 1e-12)


# ---- V13: Euler-Bernoulli and Timoshenko cantilever frequencies -------------------------------------
def test_eb_cantilever_roots_and_frequencies_of_the_standard_bar():
    model = _build("bending_cantilever", 6)
    assert np.abs(_lambda_L(model) - ref.EB_CANTILEVER_LAMBDA_L).max() < DIGITS4_TOL
    assert np.abs(model.frequencies() - ref.EB_CANTILEVER_OMEGA_7900).max() < CHECK_ABS_TOL
    other = _build("bending_cantilever", 6, rho=ref.RHO_TIMO)
    assert np.abs(other.frequencies() - ref.EB_CANTILEVER_OMEGA_7850).max() < CHECK_ABS_TOL
    # the thesis's column printed "Timoshenko" is the EB one (erratum 17)
    assert np.abs(model.frequencies() / ref.TABLE_8_3_PRINTED_TIMOSHENKO - 1).max() < THESIS_EB_RTOL


def test_timoshenko_cantilever_frequencies_of_the_standard_bar():
    for rho, check in ((ref.RHO_TIMO, ref.TIMO_CANTILEVER_OMEGA_7850), (ref.RHO_EB, ref.TIMO_CANTILEVER_OMEGA_7900)):
        omega = _build("timoshenko_cantilever", 6, rho=rho).frequencies()
        assert np.all(np.abs(omega - check) < CHECK_ABS_TOL + CHECK_TIMO_RTOL * omega), f"rho = {rho}: {omega}"
    omega = _build("timoshenko_cantilever", 6, rho=ref.RHO_TIMO).frequencies()
    # the thesis's column printed "E-B" is the Timoshenko one (erratum 17)
    assert np.abs(omega / ref.TABLE_8_3_PRINTED_EB - 1).max() < THESIS_TIMO_RTOL
    eb = _build("bending_cantilever", 6, rho=ref.RHO_TIMO).frequencies()
    assert np.all(omega < eb), "Timoshenko frequencies must lie below Euler-Bernoulli's"


def test_timoshenko_pinned_pinned_matches_the_closed_form_including_the_second_spectrum():
    steel = _steel(ref.RHO_TIMO)
    model = MODE_SETS["timoshenko_pinned_pinned"](ref.L_STD, steel, SECTION, 16)
    expected = ref.timoshenko_ss_frequencies(steel.E, steel.shear_modulus, steel.rho, SECTION.area,
                                             SECTION.second_moment, SECTION.shear_coefficient, ref.L_STD, 16)[:16]
    cutoff = np.sqrt(SECTION.shear_coefficient * steel.shear_modulus * SECTION.area / (steel.rho * SECTION.second_moment))
    assert expected[-1] > cutoff, "the check must reach above the cut-off frequency"
    assert np.abs(model.basis.omega / expected - 1).max() < 1e3 * np.finfo(float).eps


def test_timoshenko_tends_to_euler_bernoulli_for_a_slender_bar():
    """(r/L)^2 effect: L/h = 1000 leaves a relative difference ~ (pi^2/12)(1 + E/kG) 1e-6 ~ 3e-6 on mode 1."""
    slender = 1000 * ref.SIDE_STD
    timo = analytic_modes("timoshenko", slender, _steel(), SECTION, 3, ("clamped", "free")).frequencies()
    eb = analytic_modes("euler_bernoulli", slender, _steel(), SECTION, 3, ("clamped", "free")).frequencies()
    assert 0 < 1 - timo[0] / eb[0] < 1e-5


# ---- Euler-Bernoulli sets against Blevins and the printed frequency equations ----------------------
@pytest.mark.parametrize("supports", sorted(ref.BLEVINS_LAMBDA_L))
def test_eb_roots_match_blevins_and_the_frequency_equation(supports):
    model = analytic_modes("euler_bernoulli", ref.L_STD, _steel(), SECTION, 5, supports)
    lam = _lambda_L(model)
    assert np.abs(lam / ref.BLEVINS_LAMBDA_L[supports] - 1).max() < BLEVINS_RTOL
    lam_roots = np.sqrt(model.basis.omega / np.sqrt(ref.E_STD * SECTION.second_moment / (ref.RHO_EB * SECTION.area))) * ref.L_STD
    assert np.abs(ref.eb_frequency_equation(supports, lam_roots)).max() < FREQ_EQ_TOL


def test_eb_cantilever_shapes_are_blevins_tip_normalised_with_thesis_modal_mass():
    model = _build("bending_cantilever", 4, normalization="unit")
    x = np.linspace(0, ref.L_STD, 31)
    lam = _lambda_L(model)
    for i in range(4):
        blevins = ref.blevins_cantilever_shape(x / ref.L_STD, lam[i])
        # cosh - sigma sinh cancels: round-off eps e^lambda ~ 1e-11 for mode 4 (lambda = 11)
        assert np.abs(model.displacement(x)[:, i] - blevins / blevins[-1]).max() < 1e-9, f"mode {i + 1}"
    m_p = model.bar_mass
    assert np.abs(np.diag(model.M) / (m_p / 4) - 1).max() < ORTHO_TOL                      # (9.58)
    assert np.abs(np.diag(model.K) / (model.frequencies() ** 2 * m_p / 4) - 1).max() < ORTHO_TOL  # (9.59)


def test_free_free_and_pinned_free_modes_satisfy_the_mean_axis_conditions():
    """Free-free: no elastic linear or angular momentum; pinned-free: none about the pin (10.10)."""
    for theory in ("euler_bernoulli", "timoshenko"):
        free = analytic_modes(theory, ref.L_STD, _steel(), SECTION, 8, ("free", "free"))
        scale = np.sqrt(free.mass) * ref.L_STD
        assert np.abs(free.S1).max() < ORTHO_TOL * scale, theory
        assert np.abs(free.S2 + free.S_psi).max() < ORTHO_TOL * scale, theory
        pinned = analytic_modes(theory, ref.L_STD, _steel(), SECTION, 8, ("pinned", "free"))
        assert np.abs(pinned.S2 + pinned.S_psi).max() < ORTHO_TOL * scale, theory
        assert np.abs(pinned.S1).max() > 0.01 * np.sqrt(pinned.mass), "pinned-free modes do carry linear momentum"
    timo = analytic_modes("timoshenko", ref.L_STD, _steel(), SECTION, 8, ("free", "free"))
    assert np.abs(timo.S_psi).max() > 1e-3 * np.abs(timo.S2).max(), "rotary inertia is part of the balance"


# ---- V14: cantilever with a tip mass ----------------------------------------------------------------
def test_cantilever_with_tip_mass_equal_to_the_bar():
    model = _build("bending_cantilever_mass", 4)
    lam = _lambda_L(model)
    assert abs(lam[0] - ref.TIP_MASS_BETA1_LAMBDA_L) < DIGITS4_TOL
    omega1 = model.frequencies()[0]
    assert abs(omega1 - ref.TIP_MASS_BETA1_OMEGA1) < TIP_OMEGA_TOL
    assert abs(np.pi / omega1 - ref.TIP_MASS_BETA1_HALF_PERIOD) < TIP_HALF_PERIOD_TOL
    beta = model.bar_mass / ref.M_BAR_STD
    lam_roots = lam * np.sqrt(model.basis.omega / model.frequencies())
    residual = ref.eb_tip_mass_equation(lam_roots, beta) * (1 + np.cos(lam_roots) * np.cosh(lam_roots)) / np.cosh(lam_roots)
    assert np.abs(residual).max() < FREQ_EQ_TOL * 10


# ---- V19: rotating axial bar (uses S2 and M as a floating frame would) -------------------------------
def test_rotating_axial_bar_elongation_frequencies_and_critical_speed():
    n = 30
    model = _build("axial_clamped_free", n)
    c, L = model.material.wave_speed, ref.L_STD
    omega_cr = c * np.pi / (2 * L)
    assert model.frequencies()[0] == pytest.approx(omega_cr, rel=1e-12)
    assert abs(omega_cr - ref.ROTATING_OMEGA_CR_STD) < 0.5
    Omega = 0.5 * omega_cr
    q = np.linalg.solve(model.K - Omega**2 * model.M, Omega**2 * model.S2)  # centrifugal load, spin softening
    x = np.linspace(0, L, 11)[1:]
    u = model.displacement(x) @ q
    k = (2 * np.arange(1, n + 1) - 1) * np.pi / (2 * L)
    eta = Omega / (c * k)
    series = np.sum(2 * (-1.0) ** np.arange(n) * np.sin(np.outer(x, k)) / ((1 / eta**2 - 1) * k**2 * L), axis=1)  # (5.54)
    assert np.abs(u / series - 1).max() < 1e-10  # a solve with cond ~ (omega_30 / omega_1)^2 / (1 - eta^2) ~ 5e3
    kappa = Omega / c
    closed = np.sin(kappa * x) / (kappa * np.cos(kappa * L)) - x  # c^2 u'' + Omega^2 u = -Omega^2 x, u(0) = u'(L) = 0
    assert np.abs(u / closed - 1).max() < ROTATING_RTOL
    rotating = np.sqrt(np.linalg.eigvalsh(model.K - Omega**2 * model.M))  # M = I
    assert np.abs(rotating / (k * c * np.sqrt(1 - eta**2)) - 1).max() < ORTHO_TOL  # (5.48)


def test_impact_initial_conditions_reproduce_the_thesis_modal_amplitudes_5_22_and_9_22():
    """A rigid mass at v joins the end x = L of a bar at rest: projecting that velocity field on the
    composite modes (q_dot_i = m1 v phi_i(L) / M_ii) gives u(x, t) = sum C_i phi_i(x) sin(omega_i t) with
    the thesis's closed-form C_i, for the clamped (5.22, sin) and the free (9.22, cos) far end."""
    v, L, m1 = 1.0, ref.L_STD, ref.M_BAR_STD
    x = np.linspace(0, L, 9)
    for name, f, sign in (("axial_clamped_mass", np.sin, -1.0), ("axial_free_mass", np.cos, 1.0)):
        model = _build(name, 8)
        omega = model.basis.omega
        k = omega / model.material.wave_speed
        qd0 = m1 * v * model.displacement([L])[0] / np.diag(model.M)
        ours = model.displacement(x) * (qd0 / omega)
        rhoA = model.material.rho * model.section.area
        C = v * f(k * L) / (omega * (rhoA / m1 * (L / 2 + sign * np.sin(2 * k * L) / (4 * k)) + f(k * L) ** 2))
        thesis = f(np.outer(x, k)) * C
        assert np.abs(ours - thesis).max() < ORTHO_TOL * np.abs(thesis).max(), name


@pytest.mark.parametrize("order", [0, 1, 2, 3, 4])
def test_elementary_at_one_point_equals_the_vectorized_form(order):
    """The end conditions evaluate the elementary functions at one point with scalar math; it must
    give the array form's values (both are the same libm functions: a few ulps of the result)."""
    from viz3d.flexible.modes import COS, EXP_LEFT, EXP_RIGHT, SIN, elementary

    rng = np.random.default_rng(order)
    types = np.array([COS, SIN, EXP_LEFT, EXP_RIGHT, COS, SIN])
    rates = rng.uniform(0.1, 40.0, 6)
    length = 1.3
    for x in (0.0, length, rng.uniform(0, length)):
        point = elementary(types, rates, np.array([x]), order, length)
        X = np.array([x, 0.5 * length])  # two points: the array form
        array = elementary(types, rates, X, order, length)[:1]
        scale = np.abs(array) + rates**order * np.finfo(float).tiny
        assert np.all(np.abs(point - array) <= 8 * np.finfo(float).eps * scale * (1 + rates * x))

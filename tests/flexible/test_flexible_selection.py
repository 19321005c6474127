"""The mode-count helper: band from the contact duration, residual flexibility against closed forms,
and the Euler-Bernoulli validity flag."""

import flexible_refs as ref
import numpy as np
import pytest

from viz3d.flexible import Material, Section, analytic_modes, contact_band, fe_model, select_modes
from viz3d.flexible.selection import CONTACT_BAND_FACTOR

#: The flexibilities are sums of phi_i^2 / omega_i^2 over the FE modes, led by the first: their round-off is
#: that of the first elastic eigenpair, eps lam_max / lam_1 (flexible_refs.eigenvalue_roundoff), times this
#: (LAPACK's p(n), as in test_flexible_fe). NB: pytest.approx adds abs=1e-12 unless told, which is 1000x
#: these flexibilities [m/N]: every comparison of one says abs=0.
EIG_SAFETY = 10.0
#: Residual flexibility of a rod from 400 linear elements vs the analytic series: the modes above
#: n differ from the analytic ones by (k h)^2 / 24 ~ 1e-4 for the first omitted ones.
RESIDUAL_RTOL = 1e-3

STEEL = Material(ref.E_STD, ref.RHO_EB, ref.NU_STD)
SECTION = Section.rectangle(ref.SIDE_STD, ref.SIDE_STD, ref.K_SHEAR_STD)
L = ref.L_STD
EA = STEEL.E * SECTION.area
EI = STEEL.E * SECTION.second_moment


@pytest.fixture(scope="module")
def eb_cantilever():
    return fe_model("euler_bernoulli", L, STEEL, SECTION, 120, ("clamped", "free"))


def test_contact_band_is_the_documented_multiple_of_the_contact_frequency():
    assert contact_band(1e-3) == pytest.approx(CONTACT_BAND_FACTOR * 2 * np.pi / 1e-3, rel=1e-15)
    with pytest.raises(ValueError):
        contact_band(0.0)


def test_shorter_contacts_need_more_modes(eb_cantilever):
    """Thesis N7/V14: whole transverse impact ~4 ms, first contact 67 us; then a 10 us contact."""
    counts = [select_modes(eb_cantilever, L, omega_max=contact_band(t_c)).n_modes for t_c in (4e-3, 67e-6, 10e-6)]
    assert counts[0] < counts[1] < counts[2], counts
    s = select_modes(eb_cantilever, L, omega_max=contact_band(67e-6))
    assert s.omega[-1] <= contact_band(67e-6) < s.omega_next
    assert not s.reference_exhausted


def test_euler_bernoulli_is_flagged_beyond_its_validity(eb_cantilever):
    long = select_modes(eb_cantilever, L, omega_max=contact_band(4e-3))
    short = select_modes(eb_cantilever, L, omega_max=contact_band(67e-6))
    assert long.eb_valid and long.wavelength > 10 * SECTION.depth
    assert not short.eb_valid and short.wavelength < 10 * SECTION.depth
    assert short.eb_frequency_error > 0.1 > long.eb_frequency_error >= 0
    axial = select_modes(fe_model("rod", L, STEEL, SECTION, 50, ("clamped", "free")), L, omega_max=contact_band(67e-6))
    assert axial.eb_valid is None and axial.eb_frequency_error is None


def test_eb_frequency_error_is_the_simply_supported_timoshenko_ratio():
    """Pinned-pinned modes are sin(i pi x / L) in both theories, so at the i-th wavenumber the EB error
    estimate must equal the exact EB / Timoshenko frequency ratio of mode i."""
    model = analytic_modes("euler_bernoulli", L, STEEL, SECTION, 12, ("pinned", "pinned"))
    timo = ref.timoshenko_ss_frequencies(STEEL.E, STEEL.shear_modulus, STEEL.rho, SECTION.area, SECTION.second_moment,
                                         SECTION.shear_coefficient, L, 12)
    for i in (2, 5):
        s = select_modes(model, 0.3 * L, omega_max=model.frequencies()[i - 1] * (1 + 1e-9))
        assert s.n_modes == i
        assert s.wavelength == pytest.approx(2 * L / i, rel=1e-12)
        k = i * np.pi / L
        omega_eb = np.sqrt(EI / (STEEL.rho * SECTION.area)) * k**2
        omega_t = np.sort(timo)[i - 1]  # below the cut-off the lower branch of mode i is the i-th value
        assert s.eb_frequency_error == pytest.approx(omega_eb / omega_t - 1, rel=1e-9, abs=0)


def test_residual_flexibility_of_a_rod_cantilever_matches_the_series():
    """G = L / EA; the first n analytic modes carry 8 L / (EA pi^2 (2i - 1)^2) each."""
    reference = fe_model("rod", L, STEEL, SECTION, 400, ("clamped", "free"))
    s = select_modes(reference, L, tol=0.02)
    i = np.arange(1, s.n_modes + 1)
    roundoff = EIG_SAFETY * ref.eigenvalue_roundoff(reference.K, reference.M)[0]
    assert s.flexibility == pytest.approx(L / EA, rel=roundoff, abs=0), "nodal statics are exact"
    expected = L / EA * (1 - np.sum(8 / (np.pi**2 * (2 * i - 1) ** 2)))
    assert s.residual_flexibility == pytest.approx(expected, rel=RESIDUAL_RTOL, abs=0)
    assert s.truncation_error <= 0.02
    fewer = s.n_modes - 1
    assert 1 - np.sum(8 / (np.pi**2 * (2 * np.arange(1, fewer + 1) - 1) ** 2)) > 0.02, "n is the smallest meeting tol"


def test_inertia_relief_flexibility_of_a_free_rod_end_is_L_over_3EA():
    """The continuum's L / 3EA; the consistent-mass mesh of n elements gives L / 3EA (1 - 1 / (4 n^2)), its
    inertia-relief load (M times the rigid acceleration) being the mesh's, not the continuum's (seen to
    round-off for n = 10 to 200)."""
    n = 200
    free = fe_model("rod", L, STEEL, SECTION, n, ("free", "free"))
    s = select_modes(free, 0.0, tol=0.05)
    roundoff = EIG_SAFETY * ref.eigenvalue_roundoff(free.K, free.M)[1]  # [0] is the rigid mode
    assert s.flexibility == pytest.approx(L / (3 * EA) * (1 - 1 / (4 * n**2)), rel=roundoff, abs=0)
    assert s.truncation_error <= 0.05


def test_tolerance_and_band_combine_by_taking_the_larger_count(eb_cantilever):
    tight = select_modes(eb_cantilever, L, tol=1e-4)
    loose = select_modes(eb_cantilever, L, tol=1e-2)
    assert tight.n_modes > loose.n_modes and tight.truncation_error <= 1e-4 < loose.truncation_error
    band = select_modes(eb_cantilever, L, omega_max=contact_band(4e-3))
    both = select_modes(eb_cantilever, L, omega_max=contact_band(4e-3), tol=1e-4)
    assert both.n_modes == max(band.n_modes, tight.n_modes)


def test_a_coarse_reference_is_reported_exhausted():
    coarse = fe_model("euler_bernoulli", L, STEEL, SECTION, 4, ("clamped", "free"))
    assert select_modes(coarse, L, omega_max=contact_band(10e-6)).reference_exhausted


def test_select_modes_needs_a_band_or_a_tolerance(eb_cantilever):
    with pytest.raises(ValueError, match="omega_max"):
        select_modes(eb_cantilever, L)

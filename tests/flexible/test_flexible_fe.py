"""Finite elements: element matrices, nodal statics against closed forms, convergence orders to the
analytic modes, point masses, and modal reduction."""

import flexible_refs as ref
import numpy as np
import pytest

from viz3d.flexible import MODE_SETS, Material, PointMass, Section, analytic_modes, fe_model, reduce
from viz3d.flexible.bar import rayleigh_ritz
from viz3d.flexible.fe import ELEMENTS

#: Round-off of assembled / integrated element matrices and of static solves on small meshes.
ROUNDOFF = 1e-12
#: Observed convergence order of frequencies on three meshes (each twice as fine) must be within this of the
#: theoretical one (rod 2, Hermite 4; Friedman-Kosmatka 2 because its shear strain is constant per
#: element: the energy error in k G A gamma^2 is O(h^2)). Measured 1.99-2.01, 3.93-4.00, 2.00-2.02.
ORDER_TOL = 0.1
#: Rounded mesh-convergence data: frequency errors (relative) on the finest meshes used below,
#: measured on 2026-11-21 and given ~2x headroom; a wrong mass or stiffness term gives O(1e-2).
ROD_64_RTOL = 1e-4          # [2.5e-5 mode 1, 64 linear elements]
HERMITE_32_RTOL = 2e-8      # [8.2e-9 mode 1, 32 Hermite elements]
FK_64_RTOL = 1e-6           # [3.2e-7 mode 1, 64 FK elements]
TIP_MASS_32_RTOL = 5e-6     # [1.7e-6 mode 3, EB tip mass, 32 Hermite elements]
FK_FREE_64_RTOL = 1.2e-3    # [6.0e-4 mode 4, free-free, 64 FK elements]
FK_STUBBY_128_RTOL = 1.6e-3  # [8.1e-4 mode 10, L = 2 depths, 128 FK elements]
TIP_MASS_SHAPE_RTOL = 1e-5  # [2.4e-6 mode 3, mass-normalised shapes, relative to the peak]
#: Leading dispersion error of linear consistent-mass rod elements, omega_h / omega - 1 = (k h)^2 / 24
#: (uniform mesh); measured 0.98-0.99 of it with the end mass, bound with 10 % margin.
ROD_DISPERSION_FACTOR = 1.1
#: FE eigen round-off: eigenvalues computed twice (with and without vectors) agree to ~1e-11 on
#: mode 1, elastic eigenvectors of a free bar are orthogonal to the rigid ones to ~2e-11.
EIG_ROUNDOFF = 1e-10

STEEL = Material(ref.E_STD, ref.RHO_EB, ref.NU_STD)
SECTION = Section.rectangle(ref.SIDE_STD, ref.SIDE_STD, ref.K_SHEAR_STD)
L = ref.L_STD
EA = STEEL.E * SECTION.area
EI = STEEL.E * SECTION.second_moment
KGA = SECTION.shear_coefficient * STEEL.shear_modulus * SECTION.area
ANALYTIC = {"rod": "axial_clamped_free", "euler_bernoulli": "bending_cantilever", "timoshenko": "timoshenko_cantilever"}


def _cantilever(theory, n, **kw):
    return fe_model(theory, L, STEEL, SECTION, n, ("clamped", "free"), **kw)


# ---- element matrices ------------------------------------------------------------------------------
@pytest.mark.parametrize("theory", sorted(ELEMENTS))
def test_assembled_matrices_are_the_energy_of_the_interpolation(theory):
    """The typed element matrices agree with quadrature of the typed shape functions (with a point mass
    between nodes), so Phi(x) and (M, K) describe the same model."""
    pm = (PointMass(0.37 * L, 1.3),)
    model = fe_model(theory, L, STEEL, SECTION, 5, ("pinned", "free") if theory != "rod" else ("clamped", "free"),
                     point_masses=pm)
    M, K = rayleigh_ritz(theory, STEEL, SECTION, model.basis, pm)
    assert np.abs(model.T.T @ M @ model.T - model.M).max() < ROUNDOFF * np.abs(model.M).max(), "mismatch: M"
    assert np.abs(model.T.T @ K @ model.T - model.K).max() < ROUNDOFF * np.abs(model.K).max(), "mismatch: K"


def test_timoshenko_element_mass_is_przemienieckis():
    el = ELEMENTS["timoshenko"]
    for h in (0.3, 0.05, 0.01):
        phi = 12 * EI / (KGA * h * h)
        expected = ref.przemieniecki_timoshenko_mass(STEEL.rho * SECTION.area, STEEL.rho * SECTION.second_moment, h, phi)
        got = el.mass(h, STEEL, SECTION, lumped=False)
        assert np.abs(got - expected).max() < ROUNDOFF * np.abs(expected).max(), f"h = {h}"


def test_timoshenko_shape_functions_solve_the_static_equations():
    """Friedman-Kosmatka shapes: shear strain constant per element and EI psi'' + k G A gamma = 0."""
    model = fe_model("timoshenko", L, STEEL, SECTION, 3, ("free", "free"))
    x = np.linspace(0.01, 0.09, 9)  # inside the first element
    gamma = model.shape(x, "u", 1) - model.shape(x, "psi", 0)
    assert np.abs(gamma - gamma[0]).max() < ROUNDOFF * np.abs(gamma).max()
    assert np.abs(EI * model.shape(x, "psi", 2) + KGA * gamma).max() < ROUNDOFF * KGA * np.abs(gamma).max()


# ---- statics ------------------------------------------------------------------------------------
@pytest.mark.parametrize("n_elements", [1, 3, 10])
@pytest.mark.parametrize("length", [L, 1000 * ref.SIDE_STD])  # stubby and very slender (shear locking shows there)
def test_cantilever_tip_deflection_is_exact(n_elements, length):
    P = 1000.0
    expected = {"rod": P * length / EA, "euler_bernoulli": P * length**3 / (3 * EI),
                "timoshenko": P * length**3 / (3 * EI) + P * length / KGA}
    for theory, tip in expected.items():
        model = fe_model(theory, length, STEEL, SECTION, n_elements, ("clamped", "free"))
        q = np.linalg.solve(model.K, model.point_force(length, P))
        got = (model.displacement([length]) @ q)[0]
        assert got == pytest.approx(tip, rel=1e-10), theory  # ~1e-14 at L/h = 10; cond(K) ~ (L/h)^4 at 1000


def test_static_end_load_gives_uniform_axial_strain():
    F = 2.0e4
    model = _cantilever("rod", 7)
    q = np.linalg.solve(model.K, model.point_force(L, F))
    x = np.linspace(0, L, 29)
    assert np.abs(model.strain(x) @ q / (F / EA) - 1).max() < ROUNDOFF
    assert np.abs(model.axial_force(x) @ q / F - 1).max() < ROUNDOFF


@pytest.mark.parametrize("theory", ["euler_bernoulli", "timoshenko"])
def test_static_tip_load_gives_surface_strain_minus_M_c_over_EI(theory):
    P = 1000.0
    model = _cantilever(theory, 6)
    q = np.linalg.solve(model.K, model.point_force(L, P))
    x = np.linspace(0, L, 31)
    M = P * (L - x)
    expected = -M * (SECTION.depth / 2) / EI
    assert np.abs(model.strain(x) @ q - expected).max() < ROUNDOFF * np.abs(expected).max()
    assert np.abs(model.bending_moment(x) @ q - M).max() < ROUNDOFF * P * L
    assert np.abs(model.shear_force(x) @ q / P - 1).max() < 1e-10  # EB: w''' of cubics, round-off ~1e-13


# ---- convergence to the analytic modes -----------------------------------------------------------
def _errors(theory, meshes, n_modes=3, **kw):
    analytic = MODE_SETS[ANALYTIC[theory]](L, STEEL, SECTION, n_modes).basis.omega
    return np.array([_cantilever(theory, n, **kw).frequencies()[:n_modes] / analytic - 1 for n in meshes])


@pytest.mark.parametrize("theory,order,finest_rtol", [("rod", 2, ROD_64_RTOL), ("euler_bernoulli", 4, HERMITE_32_RTOL),
                                                     ("timoshenko", 2, FK_64_RTOL)])
def test_frequencies_converge_at_the_expected_order(theory, order, finest_rtol):
    meshes = (8, 16, 32) if theory == "euler_bernoulli" else (16, 32, 64)  # Hermite: 64 hits eigen round-off
    err = _errors(theory, meshes)
    assert np.all(err > 0), "consistent mass: Rayleigh-Ritz bounds from above"
    slopes = np.log2(err[:-1] / err[1:])
    assert np.abs(slopes - order).max() < ORDER_TOL, f"{theory}: observed orders {slopes}"
    assert err[-1, 0] < finest_rtol


def test_lumped_rod_converges_from_below_at_second_order():
    err = _errors("rod", (16, 32, 64), mass_matrix="lumped")
    assert np.all(err < 0)
    slopes = np.log2(err[:-1] / err[1:])
    assert np.abs(slopes - 2).max() < ORDER_TOL, slopes


def test_lumped_mass_is_refused_for_beams():
    with pytest.raises(ValueError, match="rod"):
        _cantilever("euler_bernoulli", 4, mass_matrix="lumped")


def test_fe_with_tip_mass_matches_the_analytic_tip_mass_modes():
    tip = (PointMass(L, ref.M_BAR_STD),)
    analytic = MODE_SETS["bending_cantilever_mass"](L, STEEL, SECTION, 3, tip_mass=ref.M_BAR_STD)
    fe = reduce(_cantilever("euler_bernoulli", 32, point_masses=tip), 3)
    assert np.abs(fe.frequencies() / analytic.basis.omega - 1).max() < TIP_MASS_32_RTOL
    x = np.linspace(0, L, 13)
    shapes = analytic.displacement(x)  # both mass-normalised (tip mass included), positive at the peak
    assert np.abs(fe.displacement(x) - shapes).max() < TIP_MASS_SHAPE_RTOL * np.abs(shapes).max()


def test_fe_bar_plus_impactor_matches_the_composite_roots():
    model = fe_model("rod", L, STEEL, SECTION, 100, ("clamped", "free"), point_masses=(PointMass(L, ref.M_BAR_STD),))
    kL = model.frequencies()[:5] * L / STEEL.wave_speed
    digest = np.array(ref.COMPOSITE_CLAMPED_BETA1_KL)
    dispersion = ROD_DISPERSION_FACTOR * digest * (digest / 100) ** 2 / 24
    assert np.all(np.abs(kL - digest) < 0.5e-4 + dispersion), kL
    analytic = MODE_SETS["axial_clamped_mass"](L, STEEL, SECTION, 5, tip_mass=ref.M_BAR_STD).basis.omega
    kL_exact = analytic * L / STEEL.wave_speed
    assert np.all(0 < kL / kL_exact - 1) and np.all(kL / kL_exact - 1 < ROD_DISPERSION_FACTOR * (kL_exact / 100) ** 2 / 24)


# ---- reduction ----------------------------------------------------------------------------------
def test_reduce_keeps_the_lowest_modes_mass_normalised():
    full = _cantilever("timoshenko", 20)
    red = reduce(full, 5)
    assert red.n == 5 and np.array_equal(red.M, np.eye(5))
    assert np.abs(red.frequencies() / full.frequencies()[:5] - 1).max() < EIG_ROUNDOFF
    M, K = rayleigh_ritz("timoshenko", STEEL, SECTION, red.basis)
    assert np.abs(red.T.T @ M @ red.T - np.eye(5)).max() < 1e-10, "FE interpolation x eigenvectors is mass-normalised"
    assert np.abs(red.T.T @ K @ red.T - red.K).max() < 1e-10 * red.K.max()
    peaks = red.displacement(np.linspace(0, L, 200))
    assert np.all(peaks[np.argmax(np.abs(peaks), axis=0), range(5)] > 0), "each mode positive at its peak"


def test_reduce_drops_rigid_modes_of_a_free_bar_and_leaves_mean_axis_modes():
    for theory in ("rod", "euler_bernoulli", "timoshenko"):
        free = fe_model(theory, L, STEEL, SECTION, 24, ("free", "free"))
        n_rigid = 1 if theory == "rod" else 2
        assert np.abs(free.frequencies()[:n_rigid]).max() < 1e-3 * free.frequencies()[n_rigid]
        elastic = reduce(free, 6, drop_rigid=True)
        assert elastic.frequencies()[0] > 1e-3 * elastic.frequencies()[-1]
        scale = np.sqrt(free.mass) * L
        assert np.abs(elastic.S1).max() < EIG_ROUNDOFF * scale, theory
        if theory != "rod":  # an axial displacement carries no angular momentum: S2 is no condition there
            assert np.abs(elastic.S2 + elastic.S_psi).max() < EIG_ROUNDOFF * scale, theory


def test_reduced_fe_timoshenko_free_free_approaches_the_analytic_set():
    analytic = analytic_modes("timoshenko", L, STEEL, SECTION, 4, ("free", "free")).basis.omega
    fe = reduce(fe_model("timoshenko", L, STEEL, SECTION, 64, ("free", "free")), 4, drop_rigid=True).frequencies()
    assert np.all(fe > analytic) and np.abs(fe / analytic - 1).max() < FK_FREE_64_RTOL


def test_timoshenko_fe_and_analytic_modes_agree_above_the_cutoff_frequency():
    """A stubby cantilever (L = 2 depths): 7 of its first 10 modes lie above omega_c = sqrt(kGA / rho I),
    where the analytic shapes switch to cos/sin of the second wavenumber. The FE model, which knows
    nothing of that switch, converges to them at its order 2."""
    stubby = 2 * ref.SIDE_STD
    analytic = analytic_modes("timoshenko", stubby, STEEL, SECTION, 10, ("clamped", "free"))
    omega_c = np.sqrt(KGA / (STEEL.rho * SECTION.second_moment))
    assert np.count_nonzero(analytic.basis.omega > omega_c) >= 5
    assert np.abs(analytic.M - np.eye(10)).max() < 1e-10
    err = np.array([fe_model("timoshenko", stubby, STEEL, SECTION, n, ("clamped", "free")).frequencies()[:10]
                    / analytic.basis.omega - 1 for n in (64, 128)])
    assert np.all(err > 0)
    assert np.abs(np.log2(err[0] / err[1]) - 2).max() < ORDER_TOL
    assert err[1].max() < FK_STUBBY_128_RTOL

"""Finite elements: element matrices, nodal statics against closed forms, convergence orders to the
analytic modes, point masses, and modal reduction."""

import flexible_refs as ref
import numpy as np
import pytest

from viz3d.flexible import MODE_SETS, Material, PointMass, Section, analytic_modes, fe_model, reduce
from viz3d.flexible.bar import rayleigh_ritz
from viz3d.flexible.fe import ELEMENTS

#: Round-off of assembled / integrated element matrices and of shape-function evaluations: sums over
#: <= 2 elements x a few Gauss points of O(1) polynomial products (~100 eps); 1e-12 is ~4500 eps.
ROUNDOFF = 1e-12
#: Observed convergence order log2(e_h / e_h/2) of the frequencies must be within this of the theoretical
#: one (rod 2, Hermite 4; Friedman-Kosmatka 2 because its shear strain is constant per element: the energy
#: error in k G A gamma^2 is O(h^2)), plus the share of the eigenvalue round-off (see _assert_order).
#: Orders are integers; 0.1 admits the O(h^2)-relative next term of the error expansion on the pair used
#: (a property of the discretisation, the same on every machine).
ORDER_TOL = 0.1
#: Meshes of the convergence tests, each twice as fine; each mode uses the finest pair whose eigenvalue
#: round-off leaves its observed order within ORDER_TOL (Hermite: mode 1 on 4 -> 8 elements, whose eigen
#: round-off bound at 16 is already 1/6 of its error; modes 2-3 on 16 -> 32; rod and FK on 32 -> 64).
MESHES = (4, 8, 16, 32, 64)
#: Hermite cubic, next term of omega_h / omega - 1 relative to the leading (kh)^4 / 1440: the uniform chain's
#: own is -(kh)^2 / 35 (flexible_refs.hermite_chain_error); the supports add one of the same order and sign
#: (a property of the discretisation, -0.05 to -0.11 (kh)^2 on these modes). Bound: (kh)^2 / 4.
HERMITE_NEXT_TERM = 0.25
#: Friedman-Kosmatka (no closed-form dispersion here): errors of the finest meshes used below, which are
#: properties of the discretisation (>= 600 times the eigenvalue round-off bound, so every machine gets
#: the same three digits); the bounds (2-3x) flag a change of the element's error constant, a wrong
#: mass or stiffness term gives O(1e-2).
FK_64_RTOL = 1e-6           # [3.2e-7 mode 1, 64 FK elements]
FK_FREE_64_RTOL = 1.2e-3    # [6.0e-4 mode 4, free-free, 64 FK elements]
FK_STUBBY_128_RTOL = 1.6e-3  # [8.1e-4 mode 10, L = 2 depths, 128 FK elements]
#: Mass-normalised shapes of the EB tip-mass cantilever, 32 elements, relative to the peak: an O(h^4)
#: property of the discretisation [2.4e-6 mode 3, ~1.4 (kh)^4 / 1440], far above round-off; 4x.
TIP_MASS_SHAPE_RTOL = 1e-5
#: Static solves: a backward-stable solve of K q = f is within ~ p(n) eps cond(K) of q (Higham, Accuracy and
#: Stability of Numerical Algorithms, 2nd ed., thm. 7.2), with cond that of the diagonally scaled K
#: (Cholesky's rounding does not see the scaling of w against theta dofs: van der Sluis); p(n) taken as 10.
SOLVE_SAFETY = 10.0
#: Eigenvalue and eigenvector round-off bounds (EERRBD, ZERRBD: flexible_refs.eigenvalue_roundoff) times
#: this: LAPACK's p(n), "a modestly growing function of n", taken as 1 in the Users' Guide's approximate
#: bounds; 10 for the n <= 260 here (errors seen: 0.03-0.2 of the p(n) = 1 bound).
EIG_SAFETY = 10.0

STEEL = Material(ref.E_STD, ref.RHO_EB, ref.NU_STD)
SECTION = Section.rectangle(ref.SIDE_STD, ref.SIDE_STD, ref.K_SHEAR_STD)
L = ref.L_STD
EA = STEEL.E * SECTION.area
EI = STEEL.E * SECTION.second_moment
KGA = SECTION.shear_coefficient * STEEL.shear_modulus * SECTION.area
ANALYTIC = {"rod": "axial_clamped_free", "euler_bernoulli": "bending_cantilever", "timoshenko": "timoshenko_cantilever"}


def _cantilever(theory, n, **kw):
    return fe_model(theory, L, STEEL, SECTION, n, ("clamped", "free"), **kw)


def _solve_roundoff(K):
    """Relative round-off bound of a solve with K: SOLVE_SAFETY eps cond(D K D), D = diag(K)^(-1/2)."""
    d = 1 / np.sqrt(np.diag(K))
    return SOLVE_SAFETY * ref.EPS * np.linalg.cond(d[:, None] * K * d)


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
        assert got == pytest.approx(tip, rel=_solve_roundoff(model.K), abs=0), theory


def test_static_end_load_gives_uniform_axial_strain():
    F = 2.0e4
    model = _cantilever("rod", 7)
    q = np.linalg.solve(model.K, model.point_force(L, F))
    x = np.linspace(0, L, 29)
    tol = ROUNDOFF + _solve_roundoff(model.K)
    assert np.abs(model.strain(x) @ q / (F / EA) - 1).max() < tol
    assert np.abs(model.axial_force(x) @ q / F - 1).max() < tol


@pytest.mark.parametrize("theory", ["euler_bernoulli", "timoshenko"])
def test_static_tip_load_gives_surface_strain_minus_M_c_over_EI(theory):
    P = 1000.0
    model = _cantilever(theory, 6)
    q = np.linalg.solve(model.K, model.point_force(L, P))
    x = np.linspace(0, L, 31)
    M = P * (L - x)
    expected = -M * (SECTION.depth / 2) / EI
    tol = ROUNDOFF + _solve_roundoff(model.K)
    assert np.abs(model.strain(x) @ q - expected).max() < tol * np.abs(expected).max()
    assert np.abs(model.bending_moment(x) @ q - M).max() < tol * P * L
    assert np.abs(model.shear_force(x) @ q / P - 1).max() < 1e-10  # EB: w''' of cubics, round-off ~1e-13


# ---- convergence to the analytic modes -----------------------------------------------------------
def _errors(theory, meshes=MESHES, n_modes=3, **kw):
    """Relative frequency errors (n_meshes, n_modes) against the analytic modes and their round-off bounds
    (EIG_SAFETY x half the eigenvalue's relative bound, as omega = sqrt(lam))."""
    analytic = MODE_SETS[ANALYTIC[theory]](L, STEEL, SECTION, n_modes).basis.omega
    models = [_cantilever(theory, n, **kw) for n in meshes]
    err = np.array([m.frequencies()[:n_modes] / analytic - 1 for m in models])
    floor = np.array([EIG_SAFETY * ref.eigenvalue_roundoff(m.K, m.M)[:n_modes] / 2 for m in models])
    return err, floor


def _assert_order(err, floor, order, what):
    """Per mode, the finest pair of MESHES whose round-off share of log2(e_h / e_h/2), (d_h / e_h + d_h/2 / e_h/2)
    / ln 2, stays below ORDER_TOL shows the order within ORDER_TOL plus that share."""
    slopes = np.log2(np.abs(err[:-1] / err[1:]))
    share = (floor[:-1] / np.abs(err[:-1]) + floor[1:] / np.abs(err[1:])) / np.log(2)
    for mode in range(err.shape[1]):
        usable = np.flatnonzero(share[:, mode] < ORDER_TOL)
        assert usable.size, f"{what}, mode {mode + 1}: no pair of {MESHES} rises above the eigenvalue round-off"
        i = usable[-1]
        assert abs(slopes[i, mode] - order) < ORDER_TOL + share[i, mode], \
            f"{what}, mode {mode + 1}, {MESHES[i]} -> {MESHES[i + 1]} elements: observed order {slopes[i, mode]:.3f}"


def _wavenumbers(theory, n_modes=3):
    """Analytic wavenumbers k_i [1/m]: omega / c (rod), (omega / c_t)^(1/2) (beam), for the mesh's kh."""
    omega = MODE_SETS[ANALYTIC[theory]](L, STEEL, SECTION, n_modes).basis.omega
    return omega / STEEL.wave_speed if theory == "rod" else np.sqrt(omega / np.sqrt(EI / (STEEL.rho * SECTION.area)))


@pytest.mark.parametrize("theory,order", [("rod", 2), ("euler_bernoulli", 4), ("timoshenko", 2)])
def test_frequencies_converge_at_the_expected_order(theory, order):
    err, floor = _errors(theory)
    assert np.all(err > -floor), "consistent mass: Rayleigh-Ritz bounds from above (up to round-off)"
    _assert_order(err, floor, order, theory)
    k, h = _wavenumbers(theory)[None, :], L / np.array(MESHES)[:, None]
    kh = k * h
    if theory == "rod":  # the clamped-free uniform mesh reproduces the chain's dispersion exactly
        chain = ref.rod_chain_omega(k, h, STEEL.wave_speed) / (k * STEEL.wave_speed)
        assert np.all(np.abs((1 + err) / chain - 1) <= floor), "mismatch: rod dispersion"
    elif theory == "euler_bernoulli":
        lead, resolved = ref.hermite_chain_error(kh), kh < 1
        bound = HERMITE_NEXT_TERM * kh**2 * lead + floor
        assert np.all(np.abs(err - lead)[resolved] <= bound[resolved]), (err / lead - 1) / kh**2
    else:
        assert err[MESHES.index(64), 0] < FK_64_RTOL


def test_lumped_rod_converges_from_below_at_second_order():
    err, floor = _errors("rod", mass_matrix="lumped")
    assert np.all(err < floor)
    _assert_order(err, floor, 2, "lumped rod")
    k, h = _wavenumbers("rod")[None, :], L / np.array(MESHES)[:, None]
    chain = ref.rod_chain_omega(k, h, STEEL.wave_speed, lumped=True) / (k * STEEL.wave_speed)
    assert np.all(np.abs((1 + err) / chain - 1) <= floor), "mismatch: lumped rod dispersion"


def test_lumped_mass_is_refused_for_beams():
    with pytest.raises(ValueError, match="rod"):
        _cantilever("euler_bernoulli", 4, mass_matrix="lumped")


def test_fe_with_tip_mass_matches_the_analytic_tip_mass_modes():
    """32 Hermite elements and a tip mass equal to the bar's: frequency errors at most the uniform chain's
    leading (kh)^4 / 1440 (+ its next term), since the point mass itself is represented exactly."""
    tip = (PointMass(L, ref.M_BAR_STD),)
    analytic = MODE_SETS["bending_cantilever_mass"](L, STEEL, SECTION, 3, tip_mass=ref.M_BAR_STD)
    model = _cantilever("euler_bernoulli", 32, point_masses=tip)
    fe = reduce(model, 3)
    err = fe.frequencies() / analytic.basis.omega - 1
    floor = EIG_SAFETY * ref.eigenvalue_roundoff(model.K, model.M)[:3] / 2
    kh = np.sqrt(analytic.basis.omega / np.sqrt(EI / (STEEL.rho * SECTION.area))) * L / 32
    assert np.all(-floor < err) and np.all(err < (1 + HERMITE_NEXT_TERM * kh**2) * ref.hermite_chain_error(kh) + floor), err
    x = np.linspace(0, L, 13)
    shapes = analytic.displacement(x)  # both mass-normalised (tip mass included), positive at the peak
    assert np.abs(fe.displacement(x) - shapes).max() < TIP_MASS_SHAPE_RTOL * np.abs(shapes).max()


def test_fe_bar_plus_impactor_matches_the_composite_roots():
    """100 linear elements and an end mass equal to the bar's: the FE frequencies are the roots of the
    mesh's own frequency equation (flexible_refs.rod_end_mass_chain_omegas) to round-off, and lie above the
    continuum's (k L tan k L = 1, digest V8) by the dispersion (kh)^2 / 24 to leading order."""
    n, c = 100, STEEL.wave_speed
    model = fe_model("rod", L, STEEL, SECTION, n, ("clamped", "free"), point_masses=(PointMass(L, ref.M_BAR_STD),))
    omega = model.frequencies()[:5]
    floor = EIG_SAFETY * ref.eigenvalue_roundoff(model.K, model.M)[:5] / 2
    chain = ref.rod_end_mass_chain_omegas(L, c, STEEL.rho * SECTION.area, n, ref.M_BAR_STD, 5)
    assert np.all(np.abs(omega / chain - 1) <= floor), omega / chain - 1
    kL = MODE_SETS["axial_clamped_mass"](L, STEEL, SECTION, 5, tip_mass=ref.M_BAR_STD).basis.omega * L / c
    assert np.abs(kL - ref.COMPOSITE_CLAMPED_BETA1_KL).max() < 0.5e-4, "the digest's 4 decimals"
    dispersion = (kL / n) ** 2 / 24
    assert np.all(0 < omega * L / c / kL - 1) and np.all(omega * L / c / kL - 1 < dispersion * (1 + (kL / n) ** 2)), \
        "below the leading dispersion plus its next term"


# ---- reduction ----------------------------------------------------------------------------------
def test_reduce_keeps_the_lowest_modes_mass_normalised():
    full = _cantilever("timoshenko", 20)
    red = reduce(full, 5)
    lam_max = np.abs(full.frequencies()[-1]) ** 2
    floor = EIG_SAFETY * ref.eigenvalue_roundoff(full.K, full.M)[:5] / 2
    assert red.n == 5 and np.array_equal(red.M, np.eye(5))
    assert np.all(np.abs(red.frequencies() / full.frequencies()[:5] - 1) <= 2 * floor), "two solves, each within floor"
    M, K = rayleigh_ritz("timoshenko", STEEL, SECTION, red.basis)
    # V^T M V = I up to eps cond(M) (M = L L^T, V = L^-T W), V^T K V = diag(omega^2) up to eps lam_max
    mass_tol = EIG_SAFETY * ref.EPS * np.linalg.cond(full.M)
    assert np.abs(red.T.T @ M @ red.T - np.eye(5)).max() < mass_tol, "FE interpolation x eigenvectors is mass-normalised"
    assert np.abs(red.T.T @ K @ red.T - red.K).max() < EIG_SAFETY * ref.EPS * lam_max
    peaks = red.displacement(np.linspace(0, L, 200))
    assert np.all(peaks[np.argmax(np.abs(peaks), axis=0), range(5)] > 0), "each mode positive at its peak"


def test_reduce_drops_rigid_modes_of_a_free_bar_and_leaves_mean_axis_modes():
    """Rigid eigenvalues are 0 within eps lam_max; elastic eigenvectors make angles of at most
    eps lam_max / lam_i with the rigid ones (the gap is lam_i), so S1 = r^T M v_i (r the unit translation,
    |r|_M = sqrt(mass)) is at most that times sqrt(mass); S2 + S_psi likewise with the rotation about x = 0,
    |r|_M = sqrt(I_0) <= sqrt(mass) L."""
    for theory in ("rod", "euler_bernoulli", "timoshenko"):
        free = fe_model(theory, L, STEEL, SECTION, 24, ("free", "free"))
        n_rigid = 1 if theory == "rod" else 2
        omega = free.frequencies()
        lam_max = omega[-1] ** 2
        assert np.all(omega[:n_rigid] <= np.sqrt(EIG_SAFETY * ref.EPS * lam_max)), (theory, omega[:n_rigid])
        elastic = reduce(free, 6, drop_rigid=True)
        angle = EIG_SAFETY * ref.eigenvalue_roundoff(free.K, free.M)[n_rigid:n_rigid + 6]
        assert np.all(np.abs(elastic.frequencies() / omega[n_rigid:n_rigid + 6] - 1) <= angle), "the elastic modes"
        assert np.all(np.abs(elastic.S1) <= angle * np.sqrt(free.mass)), theory
        if theory != "rod":  # an axial displacement carries no angular momentum: S2 is no condition there
            assert np.all(np.abs(elastic.S2 + elastic.S_psi) <= angle * np.sqrt(free.mass) * L), theory


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
    models = [fe_model("timoshenko", stubby, STEEL, SECTION, n, ("clamped", "free")) for n in (64, 128)]
    err = np.array([m.frequencies()[:10] / analytic.basis.omega - 1 for m in models])
    floor = np.array([EIG_SAFETY * ref.eigenvalue_roundoff(m.K, m.M)[:10] / 2 for m in models])
    assert np.all(err > floor), "Rayleigh-Ritz bounds from above, by more than round-off"
    share = (floor[0] / err[0] + floor[1] / err[1]) / np.log(2)
    assert np.all(np.abs(np.log2(err[0] / err[1]) - 2) < ORDER_TOL + share)
    assert err[1].max() < FK_STUBBY_128_RTOL

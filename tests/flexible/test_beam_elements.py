"""Cubic and quintic Hermite Euler-Bernoulli elements: shapes and element matrices derived with
sympy, the seed's printed matrices (Hossne 2007) entry by entry, statics against beam theory, the
curvature dof, and frequency / stress convergence orders against exact beam solutions.

Exactness is asserted to the round-off floor ``n eps kappa_J(K)`` and orders only on meshes whose
error is well above it (``beam_exact.roundoff_floor``).
"""

from __future__ import annotations

import functools
from pathlib import Path

import beam_exact as exact
import numpy as np
import pytest
import seed003_printed as printed
import sympy as sp

from viz3d.flexible import ELEMENT_TYPES, Material, PointMass, Section, fe_model, node_bending_stress, node_curvature
from viz3d.flexible.bar import rayleigh_ritz, rigid_mode_count

EPS = np.finfo(float).eps
#: Exact rational entries times powers of h, computed in floating point: each entry is a product
#: of at most 8 rounded factors (scaling D K D, EI, h^-3, 1/70), relative error <= 8 eps.
ENTRY_RTOL = 8 * EPS
#: Orders are asserted only where the discretisation error exceeds this multiple of the round-off
#: floor, so that round-off changes a fitted slope by less than ~0.01.
FLOOR_MARGIN = 100.0
#: ... and in the asymptotic range: at least four elements per wavelength, k h <= pi / 2 (k = lambda_i / L).
KH_MAX = np.pi / 2
#: Errors of symmetric elements on uniform meshes expand in even powers of h, so an order other
#: than the theoretical one would be >= 2 away; 0.5 identifies it and leaves room for the next term.
ORDER_TOL = 0.5
#: Theoretical orders: eigenvalue error h^(2(p - 1)) for degree p (Strang & Fix, An Analysis of the
#: Finite Element Method, 1973, ch. 6), and the H^2 (curvature) error h^(p - 1).
FREQUENCY_ORDER = {"hermite": 4, "quintic": 8}
CURVATURE_ORDER = {"hermite": 2, "quintic": 4}
N_MODES = 3
MESHES = {"hermite": (2, 3, 4, 5, 6, 8, 10, 12, 16, 24, 32), "quintic": tuple(range(1, 13))}
STATIC_MESHES = {"hermite": (2, 4, 8, 16, 32, 64), "quintic": (1, 2, 4, 8, 16, 32)}
SUPPORT_CASES = [("clamped", "free"), ("pinned", "pinned"), ("free", "free")]

STEEL = Material(210e9, 7900.0, 0.3)
SECTION = Section.rectangle(0.03, 0.03)
L = 0.3
EI = STEEL.E * SECTION.second_moment
RHO_A = STEEL.rho * SECTION.area
C_FIBRE = SECTION.depth / 2
DOCS = Path(__file__).resolve().parents[2] / "docs" / "seed003_element.md"


def _beam(element, n, supports=("clamped", "free"), **kw):
    return fe_model("euler_bernoulli", L, STEEL, SECTION, n, supports, element=element, **kw)


roundoff_floor = exact.roundoff_floor


# ---- sympy: shapes and element matrices ---------------------------------------------------------
x, h = sp.symbols("x h", positive=True)


def hermite_shapes(n_derivatives: int) -> tuple:
    return exact.hermite_shapes(n_derivatives, x, h)


@functools.cache
def exact_matrices(n_derivatives: int) -> tuple[sp.Matrix, sp.Matrix]:
    """int N''^T N'' dx and int N^T N dx over [0, h] (multiply by EI, rho A)."""
    N = hermite_shapes(n_derivatives)
    K = sp.Matrix(len(N), len(N), lambda i, j: sp.integrate(sp.diff(N[i], x, 2) * sp.diff(N[j], x, 2), (x, 0, h)))
    M = sp.Matrix(len(N), len(N), lambda i, j: sp.integrate(N[i] * N[j], (x, 0, h)))
    return K, M


DERIVATIVES = {"hermite": 2, "quintic": 3}


@pytest.mark.parametrize("name", ["hermite", "quintic"])
def test_shape_polynomials_are_the_hermite_interpolants(name):
    element, shapes = ELEMENT_TYPES[name], hermite_shapes(DERIVATIVES[name])
    xi = sp.symbols("xi")
    for hv in (0.3, 0.01, 7.0):
        C = element.polynomials(hv, STEEL, SECTION)["u"]
        for i, N in enumerate(shapes):
            poly = sp.Poly(sp.expand(N.subs(x, xi * h).subs(h, sp.Rational(hv))), xi)
            expected = np.array([float(poly.coeff_monomial(xi**k)) for k in range(C.shape[1])])
            assert np.abs(C[i] - expected).max() <= ENTRY_RTOL * np.abs(expected).max(), f"{name} shape {i}, h = {hv}"


@pytest.mark.parametrize("name", ["hermite", "quintic"])
def test_element_matrices_are_the_exact_integrals_of_the_shapes(name):
    element = ELEMENT_TYPES[name]
    K_exact, M_exact = exact_matrices(DERIVATIVES[name])
    for hv in (0.3, 0.01, 7.0):
        hr = sp.Rational(hv)  # the exact value of the float
        K_ref = np.array(K_exact.subs(h, hr).evalf(30).tolist(), dtype=float) * EI
        M_ref = np.array(M_exact.subs(h, hr).evalf(30).tolist(), dtype=float) * RHO_A
        for key, got, ref in (("K", element.stiffness(hv, STEEL, SECTION), K_ref),
                              ("M", element.mass(hv, STEEL, SECTION, False), M_ref)):
            assert np.all(np.abs(got - ref) <= ENTRY_RTOL * np.abs(ref) + 1e-300), f"mismatch: {name} {key}, h = {hv}"


# ---- the seed's printed formulas ----------------------------------------------------------------
def _seed_derived() -> dict[str, sp.Matrix]:
    """The seed's eqs. 34, 38, 45-51, 56 derived from the Hermite shapes, in its dof order."""
    Lq = printed.L
    Nw = [N.subs(h, Lq).subs(x, printed.x) for N in hermite_shapes(3)]
    Nu = [1 - printed.x / Lq, printed.x / Lq]
    X = printed.x
    Su = sp.Matrix([[Nu[0], 0, 0, 0, Nu[1], 0, 0, 0]])
    Sw = sp.Matrix([[0, *Nw[:3], 0, *Nw[3:]]])

    def integral(expr):
        return expr.applyfunc(lambda f: sp.integrate(f, (X, 0, Lq)))

    basis = sp.Matrix([[0, 1, X, X**2, 0, X**3, X**4, X**5]]), sp.Matrix([[1, 0, 0, 0, X, 0, 0, 0]])
    # [C]: S = C A with A = (B0, A0, A1, A2, B1, A3, A4, A5), from the end values of u = basis_u A, w = basis_w A
    rows = [basis[1].subs(X, 0), basis[0].subs(X, 0), sp.diff(basis[0], X).subs(X, 0), sp.diff(basis[0], X, 2).subs(X, 0),
            basis[1].subs(X, Lq), basis[0].subs(X, Lq), sp.diff(basis[0], X).subs(X, Lq), sp.diff(basis[0], X, 2).subs(X, Lq)]
    C = sp.Matrix.vstack(*rows)
    Bu = sp.diff(Su, X)
    Bw = sp.diff(Sw, X, 2)
    return {
        "eq34": sp.Matrix([[Nw[0], Nw[1], Nw[2], Nw[3], Nw[4], Nw[5]]]),
        "eq38": sp.simplify(C.inv()),
        "eq45": integral(Su), "eq47": integral(Sw), "eq48": integral(X * Su), "eq49": integral(X * Sw),
        "eq46": integral(Su.T * Su), "eq50": integral(Su.T * Sw), "eq51": integral(Sw.T * Sw),
        "eq56": integral(printed.EA * Bu.T * Bu + printed.EI * Bw.T * Bw),
    }


def _seed_printed() -> dict[str, sp.Matrix]:
    p = printed
    return {"eq34": sp.Matrix([[p.EQ34[k] for k in ("phi2", "phi3", "phi4", "phi6", "phi7", "phi8")]]),
            "eq38": p.EQ38, "eq45": p.EQ45_E, "eq47": p.EQ47_G, "eq48": p.EQ48_N, "eq49": p.EQ49_L,
            "eq46": p.EQ46_B, "eq50": p.EQ50_A, "eq51": p.EQ51, "eq56": p.EQ56}


#: ids of ``printed.ERRATA`` for the matrix entries (row, column in the seed's numbering).
_ENTRY_IDS = {("eq34", 0, 5): "eq34 phi8", ("eq38", 7, 6): "eq38 [A5, q7]", ("eq48", 0, 0): "eq48 N[q1]",
              ("eq48", 0, 4): "eq48 N[q5]", ("eq50", 4, 2): "eq50 A[q5, q3]"}


def test_seed_printed_matrices_differ_from_the_derivation_only_in_the_recorded_errata():
    derived, seen = _seed_derived(), _seed_printed()
    differing = set()
    for eq, D in derived.items():
        P = seen[eq]
        assert P.shape == D.shape, eq
        for i in range(D.rows):
            for j in range(D.cols):
                if sp.simplify(P[i, j] - D[i, j]) != 0:
                    differing.add(_ENTRY_IDS.get((eq, i, j), f"{eq} [{i + 1}, {j + 1}] (unrecorded)"))
    recorded = {k for k in printed.ERRATA if not k.startswith("eq44")}
    assert differing == recorded, f"printed entries differing: {sorted(differing)}"


def test_seed_eq51_and_eq56_are_the_quintic_element_matrices():
    """Eq. 51 is int N_w^T N_w (no rho A: T = m/2 [...]) and eq. 56 the stiffness; both equal the
    element's typed matrices (axial part: the rod element's)."""
    el = ELEMENT_TYPES["quintic"]
    idx = [1, 2, 3, 5, 6, 7]
    for hv in (0.3, 0.01):
        subs = {printed.L: sp.Rational(hv), printed.EI: sp.Float(EI, 30), printed.EA: sp.Float(STEEL.E * SECTION.area, 30)}
        M51 = np.array(printed.EQ51.subs(subs).evalf(30).tolist(), dtype=float)[np.ix_(idx, idx)] * RHO_A
        K56 = np.array(printed.EQ56.subs(subs).evalf(30).tolist(), dtype=float)
        assert np.all(np.abs(el.mass(hv, STEEL, SECTION, False) - M51) <= ENTRY_RTOL * np.abs(M51)), "mismatch: M"
        K56_w = K56[np.ix_(idx, idx)]
        assert np.all(np.abs(el.stiffness(hv, STEEL, SECTION) - K56_w) <= ENTRY_RTOL * np.abs(K56_w)), "mismatch: K"
        rod = ELEMENT_TYPES["rod2"].stiffness(hv, STEEL, SECTION)
        assert np.all(np.abs(rod - K56[np.ix_([0, 4], [0, 4])]) <= ENTRY_RTOL * np.abs(rod)), "mismatch: EA/L"


def test_every_erratum_is_recorded_in_the_docs():
    text = DOCS.read_text()
    for key, (was, right) in printed.ERRATA.items():
        assert key in text and was in text and right in text, f"docs/seed003_element.md lacks erratum {key}"


# ---- the model: choice of element, interpolation, curvature dof ----------------------------------
def test_element_choice():
    assert fe_model("euler_bernoulli", L, STEEL, SECTION, 4, ("clamped", "free")).basis.element.name == "hermite"
    quintic = _beam("quintic", 4)
    assert quintic.basis.element.name == "quintic" and quintic.n == 3 * 5 - 2, "clamped: w and w' fixed, w'' free"
    assert _beam("quintic", 4, ("pinned", "pinned")).n == 3 * 5 - 2, "pinned: only w fixed at each end"
    assert _beam("quintic", 4, ("free", "free")).n == 3 * 5
    with pytest.raises(ValueError, match="quintic"):
        fe_model("euler_bernoulli", L, STEEL, SECTION, 4, ("clamped", "free"), element="cubic")
    with pytest.raises(ValueError, match="rod2"):
        fe_model("rod", L, STEEL, SECTION, 4, ("clamped", "free"), element="quintic")


def test_quintic_model_matrices_are_the_energy_of_its_interpolation():
    """Typed matrices == quadrature of the typed shapes (with a point mass between nodes)."""
    pm = (PointMass(0.37 * L, 1.3),)
    model = _beam("quintic", 5, ("pinned", "free"), point_masses=pm)
    M, K = rayleigh_ritz("euler_bernoulli", STEEL, SECTION, model.basis, pm)
    for key, A, B in (("M", model.T.T @ M @ model.T, model.M), ("K", model.T.T @ K @ model.T, model.K)):
        # quadrature sums ~ 2 x 12 points x 6 shapes of terms no larger than max |B|
        assert np.abs(A - B).max() < 100 * EPS * np.abs(B).max() * model.n, f"mismatch: {key}"


def _curvature_evaluation_bound(model, q) -> float:
    """Round-off of evaluating w'' = sum_i N_i'' q_i from the monomials at the end of an element:
    a few eps times sum_i sum_k |c_ik| k (k - 1) |q_i| / h^2 (the monomials cancel to the result)."""
    el, d = model.basis.element, model.basis.element.dofs_per_node
    h = np.diff(model.basis.nodes)[0]
    k = np.arange(6)
    a = np.abs(el.polynomials(h, STEEL, SECTION)["u"]) @ (k * (k - 1)) / h**2
    qa = np.abs(model.T @ q)
    return 16 * EPS * max(a @ qa[e * d: e * d + 2 * d] for e in range(len(model.basis.nodes) - 1))


def test_curvature_dof_is_the_interpolated_curvature():
    model = _beam("quintic", 5)
    q = np.random.default_rng(3).normal(size=model.n)
    nodes = model.basis.nodes
    bound = _curvature_evaluation_bound(model, q)
    assert np.abs(node_curvature(model, q) - model.shape(nodes, "psi", 1) @ q).max() <= bound
    stress = node_bending_stress(model, q)
    assert np.abs(stress - STEEL.E * model.strain(nodes) @ q).max() <= bound * STEEL.E * C_FIBRE


# ---- statics --------------------------------------------------------------------------------------
def _static(model, F):
    return np.linalg.solve(model.K, F), roundoff_floor(model.K)


@pytest.mark.parametrize("name", ["hermite", "quintic"])
@pytest.mark.parametrize("n", [1, 3, 10])
def test_tip_load_deflection_and_clamp_stress_are_exact(name, n):
    """w = P x^2 (3 L - x) / 6 EI is cubic, in both spaces: tip PL^3/3EI, clamp stress -P L c / I,
    free-end stress 0 (the natural condition, not imposed)."""
    P = 1000.0
    model = _beam(name, n)
    q, floor = _static(model, model.point_force(L, P))
    assert abs((model.displacement([L]) @ q)[0] / (P * L**3 / (3 * EI)) - 1) <= floor
    sigma = node_bending_stress(model, q)
    sigma_clamp = -P * L * C_FIBRE / SECTION.second_moment
    assert abs(sigma[0] / sigma_clamp - 1) <= floor, "clamp stress"
    assert abs(sigma[-1] / sigma_clamp) <= floor, "free end: M = 0"


def test_end_moment_curvature_is_reached_because_the_free_end_curvature_is_natural():
    """A moment M0 at the free end bends the cantilever to constant curvature M0 / EI: the quintic
    nodal w'' equals it at every node, the free end included. Imposing w'' = 0 there would be wrong."""
    M0 = 50.0
    model = _beam("quintic", 4)
    q, floor = _static(model, M0 * model.slope([L])[0])
    kappa = node_curvature(model, q)
    assert np.abs(kappa / (M0 / EI) - 1).max() <= floor


@pytest.mark.parametrize("n", [1, 2, 5, 12])
def test_weight_clamp_stress_quintic_exact_cubic_off_by_h2_over_6L2(n):
    """Own weight (uniform load rho A g, consistent load vector S1 g): w is quartic, inside the quintic
    space, so the quintic clamp stress is exact. The cubic's nodal values are exact (its shapes
    contain the homogeneous solutions), so on the first element it is the Hermite interpolant of w;
    the interpolation error (w''''/24) x^2 (x - h)^2 has second derivative q h^2 / (12 EI) at x = 0,
    and the clamp moment is q L^2 / 2: relative error -h^2 / (6 L^2) = -1 / (6 n^2)."""
    g = 9.81
    sigma_clamp = -RHO_A * g * L**2 / 2 * C_FIBRE / SECTION.second_moment
    for name, expected in (("quintic", 0.0), ("hermite", -1.0 / (6 * n * n))):
        model = _beam(name, n)
        q, floor = _static(model, g * model.S1)
        ratio = node_bending_stress(model, q)[0] / sigma_clamp - 1
        assert abs(ratio - expected) <= floor, f"{name}: {ratio} vs {expected}"


def _cosine_load_clamp_stress() -> float:
    """q(s) = q0 cos(pi s / 2L): clamp moment int_0^L q s ds (sympy), stress -M c / I."""
    s = sp.symbols("s")
    M0 = sp.integrate(sp.cos(sp.pi * s / (2 * sp.Rational(L))) * s, (s, 0, sp.Rational(L)))
    return -float(M0) * Q0 * C_FIBRE / SECTION.second_moment


Q0 = 1.0e4  # N/m


@functools.cache
def stress_study(name: str) -> tuple:
    """(n, n_dof, relative clamp-stress error, round-off floor) under the cosine load, per mesh."""
    exact_sigma, out = _cosine_load_clamp_stress(), []
    for n in STATIC_MESHES[name]:
        model = _beam(name, n)
        F = model.integrate(lambda xx: Q0 * np.cos(np.pi * xx / (2 * L))[:, None] * model.displacement(xx))
        q, floor = _static(model, F)
        out.append((n, model.n, node_bending_stress(model, q)[0] / exact_sigma - 1, floor))
    return tuple(out)


@pytest.mark.parametrize("name", ["hermite", "quintic"])
def test_clamp_stress_under_a_cosine_load_converges_at_the_curvature_order(name):
    """A load whose deflection is no polynomial: the clamp stress converges as h^(p - 1)."""
    usable = [(n, abs(e)) for n, _, e, floor in stress_study(name) if abs(e) > FLOOR_MARGIN * floor]
    assert len(usable) >= 3, f"{name}: meshes above the round-off floor: {usable}"
    n, e = np.array(usable).T
    slope = -np.polyfit(np.log(n), np.log(e), 1)[0]
    assert abs(slope - CURVATURE_ORDER[name]) < ORDER_TOL, f"{name}: observed order {slope:.2f}"


# ---- frequencies ----------------------------------------------------------------------------------
@functools.cache
def frequency_study(supports: tuple[str, str], name: str) -> tuple:
    """(n, n_dof, relative errors of the lowest N_MODES elastic frequencies, round-off floor) per mesh."""
    omega = exact.eb_frequencies(supports, N_MODES, L, STEEL.E, SECTION.second_moment, STEEL.rho, SECTION.area)
    n_rigid = rigid_mode_count("bending", supports)
    out = []
    for n in MESHES[name]:
        model = _beam(name, n, supports)
        got = model.frequencies()[n_rigid:n_rigid + N_MODES]
        if len(got) == N_MODES:
            out.append((n, model.n, got / omega - 1, roundoff_floor(model.K, n_rigid)))
    return tuple(out)


@pytest.mark.parametrize("supports", SUPPORT_CASES)
@pytest.mark.parametrize("name", ["hermite", "quintic"])
def test_frequencies_converge_at_the_theoretical_order(supports, name):
    """Exact frequencies from the characteristic equations; consistent mass bounds them from above."""
    study, lam = frequency_study(supports, name), exact.eb_roots(supports, N_MODES)
    for mode in range(N_MODES):
        usable = [(n, e[mode]) for n, _, e, floor in study if e[mode] > FLOOR_MARGIN * floor and lam[mode] / n <= KH_MAX]
        assert len(usable) >= 2, f"{name} {supports} mode {mode + 1}: meshes in range: {usable}"
        above = [e[mode] for _, _, e, floor in study if abs(e[mode]) > FLOOR_MARGIN * floor]
        assert min(above) > 0, "Rayleigh-Ritz: upper bounds"
        n, e = np.array(usable).T
        slope = -np.polyfit(np.log(n), np.log(e), 1)[0]
        assert abs(slope - FREQUENCY_ORDER[name]) < ORDER_TOL, f"{name} {supports} mode {mode + 1}: order {slope:.2f}"

"""Planar beams on a floating frame (viz3d.flexible.planar) against sympy: the shape integrals and
element matrices integrated exactly, the mass matrix, velocity and gravity forces from the seed's
position vector (eq. 21) by the virtual work of d'Alembert's inertia forces, the seed's kinetic
energy (eq. 44) term by term, and the linear model with the frame held against the FE bar models.
"""

from __future__ import annotations

import functools

import beam_exact as exact
import numpy as np
import pytest
import seed003_printed as printed
import sympy as sp
from scipy.linalg import eigh

from viz3d.flexible import Material, Section, fe_model, planar_beam
from viz3d.flexible.planar import (
    PLANAR_ELEMENTS,
    gravity_forces,
    mass_matrix,
    potential_energy,
    quadratic_velocity_forces,
    reference_conditions,
    world_positions,
)

EPS = np.finfo(float).eps
#: Gauss sums, assembly and matrix-vector products add at most ~60 rounded terms no larger than the
#: largest entry (Higham's gamma_n for recursive summation).
SUM_RTOL = 64 * EPS
STEEL = Material(210e9, 7900.0, 0.3)
SECTION = Section.rectangle(0.03, 0.03)
L = 0.3
RHO_A = STEEL.rho * SECTION.area
CASES = [("planar8_quintic", 1), ("planar8_quintic", 2), ("planar6_cubic", 2)]
X = sp.Symbol("X")     # coordinate inside an element, 0 <= X <= h


def _rational(v: float) -> sp.Rational:
    return sp.Rational(v)  # the exact value of the float


def pieces(name: str, n_elements: int):
    """Per element: (x_a, h, N_u, N_w) with N_u, N_w lists over the beam's n_s dofs (sympy, in X).

    Axial u = (1 - X/h) u_a + (X/h) u_b; transverse: the Hermite shapes from their interpolation
    conditions (beam_exact.hermite_shapes), dofs node by node [u, w, w', (w'')] as the seed orders them."""
    d = PLANAR_ELEMENTS[name].dofs_per_node
    h = _rational(L) / n_elements
    Nw_local = exact.hermite_shapes(d - 1, X, h)
    n_s = (n_elements + 1) * d
    out = []
    for e in range(n_elements):
        Nu, Nw = [sp.Integer(0)] * n_s, [sp.Integer(0)] * n_s
        Nu[e * d], Nu[e * d + d] = 1 - X / h, X / h
        for k in range(d - 1):
            Nw[e * d + 1 + k], Nw[e * d + d + 1 + k] = Nw_local[k], Nw_local[d - 1 + k]
        out.append((e * h, h, Nu, Nw))
    return out


def _integrate(expr, h):
    """int_0^h expr dX of a polynomial in X, exactly."""
    antiderivative = sp.Poly(expr, X).integrate()
    return antiderivative.eval(h) - antiderivative.eval(0)


@functools.cache
def symbolic_integrals(name: str, n_elements: int) -> dict:
    mu = _rational(RHO_A)
    out = {}
    parts = pieces(name, n_elements)
    n_s = len(parts[0][2])
    for key, f in (("S_u", lambda xa, Nu, Nw, i: Nu[i]), ("S_w", lambda xa, Nu, Nw, i: Nw[i]),
                   ("xS_u", lambda xa, Nu, Nw, i: (xa + X) * Nu[i]), ("xS_w", lambda xa, Nu, Nw, i: (xa + X) * Nw[i])):
        out[key] = np.array([float(mu * sum(_integrate(f(xa, Nu, Nw, i), h) for xa, h, Nu, Nw in parts)) for i in range(n_s)])
    for key, f in (("M_uu", lambda Nu, Nw, i, j: Nu[i] * Nu[j]), ("M_uw", lambda Nu, Nw, i, j: Nu[i] * Nw[j]),
                   ("M_ww", lambda Nu, Nw, i, j: Nw[i] * Nw[j])):
        out[key] = np.array([[float(mu * sum(_integrate(f(Nu, Nw, i, j), h) for _, h, Nu, Nw in parts))
                              for j in range(n_s)] for i in range(n_s)])
    EA, EI = _rational(STEEL.E * SECTION.area), _rational(STEEL.E * SECTION.second_moment)
    out["K"] = np.array([[float(sum(_integrate(EA * sp.diff(Nu[i], X) * sp.diff(Nu[j], X)
                                               + EI * sp.diff(Nw[i], X, 2) * sp.diff(Nw[j], X, 2), h)
                                    for _, h, Nu, Nw in parts)) for j in range(n_s)] for i in range(n_s)])
    return out


@pytest.mark.parametrize("name,n_elements", CASES)
def test_shape_integrals_and_matrices_are_the_exact_integrals(name, n_elements):
    beam, ref = planar_beam(name, L, STEEL, SECTION, n_elements), symbolic_integrals(name, n_elements)
    for key, expected in ref.items():
        got = getattr(beam, key)
        assert np.abs(got - expected).max() <= SUM_RTOL * np.abs(expected).max(), f"mismatch: {key}"
    assert beam.mass == pytest.approx(RHO_A * L, rel=SUM_RTOL)
    assert beam.static_moment == pytest.approx(RHO_A * L**2 / 2, rel=SUM_RTOL)
    assert beam.inertia == pytest.approx(RHO_A * L**3 / 3, rel=SUM_RTOL)


# ---- dynamics from the position vector (seed eq. 21) -----------------------------------------------
#: Gauss points per element: the integrands below are polynomials in X of degree <= 10 (products of
#: two quintic fields), which 6 points integrate exactly.
GAUSS_POINTS = 6


@functools.cache
def symbolic_kinematics(name: str, n_elements: int) -> list:
    """Per element (x_a, h, J(p, X), a_v(p, pd, X)) as numeric functions, from sympy derivatives of
    W_R(x) = (X1, Y1) + R(theta) (x + u, w): J = dW_R/dp (2, n) and the velocity-dependent
    acceleration a_v = d(J pd)/dp pd (2,)."""
    parts = pieces(name, n_elements)
    n_s = len(parts[0][2])
    p, pd = sp.symbols(f"p0:{3 + n_s}"), sp.symbols(f"pd0:{3 + n_s}")
    th, s = p[2], p[3:]
    out = []
    for xa, h, Nu, Nw in parts:
        u = sum(Nu[i] * s[i] for i in range(n_s))
        w = sum(Nw[i] * s[i] for i in range(n_s))
        R = sp.Matrix([p[0] + sp.cos(th) * (xa + X + u) - sp.sin(th) * w,
                       p[1] + sp.sin(th) * (xa + X + u) + sp.cos(th) * w])
        J = R.jacobian(p)
        a_v = (J * sp.Matrix(pd)).jacobian(p) * sp.Matrix(pd)
        out.append((float(xa), float(h), sp.lambdify([p, X], J, "numpy"), sp.lambdify([p, pd, X], a_v, "numpy")))
    return out


def reference_dynamics(name: str, n_elements: int, p, pd, g):
    """M = int mu J^T J dx, Q_v = -int mu J^T a_v dx, Q_g = int mu J^T g dx: the virtual work of the
    inertia and gravity forces (equal to Lagrange's equations for T = 1/2 int mu |dW_R/dt|^2)."""
    xs, wq = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    n = len(p)
    M, Qv, Qg = np.zeros((n, n)), np.zeros(n), np.zeros(n)
    for _, h, J_f, a_f in symbolic_kinematics(name, n_elements):
        for xi, wi in zip(0.5 * h * (xs + 1), 0.5 * h * wq):
            J, a_v = np.array(J_f(p, xi), dtype=float), np.array(a_f(p, pd, xi), dtype=float).ravel()
            M += RHO_A * wi * J.T @ J
            Qv -= RHO_A * wi * J.T @ a_v
            Qg += RHO_A * wi * J.T @ g
    return M, Qv, Qg


def _state(n: int, seed: int):
    """A random state: frame at ~0.1 m, any angle, elastic coordinates of a few mm / mrad, rates ~1."""
    rng = np.random.default_rng(seed)
    p = np.concatenate([rng.normal(size=2) * 0.1, [rng.uniform(-np.pi, np.pi)], rng.normal(size=n - 3) * 3e-3])
    return p, rng.normal(size=n)


@pytest.mark.parametrize("name,n_elements", CASES)
def test_mass_matrix_and_velocity_forces_are_the_virtual_work_of_the_inertia_forces(name, n_elements):
    beam = planar_beam(name, L, STEEL, SECTION, n_elements)
    g = np.array([0.3, -9.81])
    for seed in range(3):
        p, pd = _state(3 + beam.n_s, seed)
        M, Qv, Qg = reference_dynamics(name, n_elements, p, pd, g)
        for key, got, expected in (("M", mass_matrix(beam, p), M), ("Q_v", quadratic_velocity_forces(beam, p, pd), Qv),
                                   ("Q_g", gravity_forces(beam, p, g), Qg)):
            assert np.abs(got - expected).max() <= SUM_RTOL * np.abs(expected).max(), f"mismatch: {key}, seed {seed}"


@pytest.mark.parametrize("name", sorted(PLANAR_ELEMENTS))
def test_positions_and_potential_energy(name):
    """Nodes at (X1, Y1) + R(theta) (x + u, w) (eq. 21); V = 1/2 s^T K s - int mu g . W_R dx, the
    integral by 12-point Gauss quadrature of world_positions (exact: W_R is of degree <= 5 in x)."""
    beam = planar_beam(name, L, STEEL, SECTION, 3)
    p, _ = _state(3 + beam.n_s, 7)
    s, c, sn = p[3:], np.cos(p[2]), np.sin(p[2])
    u, w = s[beam.dofs("u")], s[beam.dofs("w")]
    expected = p[:2] + np.stack([c * (beam.nodes + u) - sn * w, sn * (beam.nodes + u) + c * w], axis=1)
    got = world_positions(beam, p, beam.nodes)
    assert np.abs(got - expected).max() <= SUM_RTOL * np.abs(expected).max()
    g = np.array([0.4, -9.81])
    xs, wq = np.polynomial.legendre.leggauss(12)
    V_g = 0.0
    for a, b in zip(beam.nodes[:-1], beam.nodes[1:]):
        xq = 0.5 * (a + b) + 0.5 * (b - a) * xs
        V_g -= RHO_A * 0.5 * (b - a) * wq @ (world_positions(beam, p, xq) @ g)
    strain = 0.5 * s @ beam.K @ s
    assert potential_energy(beam, p, g) - strain == pytest.approx(V_g, rel=SUM_RTOL, abs=SUM_RTOL * strain)


# ---- the seed's kinetic energy, eq. 44 -------------------------------------------------------------
def test_seed_eq44_holds_with_the_factor_two_on_the_xd1_thd_G_term():
    """T = m/2 int |v|^2 dx with v the rotating-frame velocity of eq. 25, expanded, against eq. 44 with
    the shape integrals (45)-(51) derived here. Only the printed coefficient of xd1 thd G.S is off."""
    Lq, m, x = printed.L, sp.Symbol("m"), printed.x
    Nw = exact.hermite_shapes(3, x, Lq)
    Su = sp.Matrix([[1 - x / Lq, 0, 0, 0, x / Lq, 0, 0, 0]])
    Sw = sp.Matrix([[0, *Nw[:3], 0, *Nw[3:]]])
    S, Sd = sp.Matrix(sp.symbols("q1:9")), sp.Matrix(sp.symbols("qd1:9"))
    xd1, yd1, thd = sp.symbols("xd1 yd1 thd")
    u, w, ud, wd = (Su * S)[0], (Sw * S)[0], (Su * Sd)[0], (Sw * Sd)[0]
    T = m / 2 * sp.integrate(sp.expand((xd1 + ud - w * thd) ** 2 + (yd1 + (x + u) * thd + wd) ** 2), (x, 0, Lq))

    def I(expr):
        return expr.applyfunc(lambda f: sp.integrate(f, (x, 0, Lq)))

    E, G, N, Lv = I(Su), I(Sw), I(x * Su), I(x * Sw)
    B, A, Mw = I(Su.T * Su), I(Su.T * Sw), I(Sw.T * Sw)
    terms = {
        "xd1^2 L": xd1**2 * Lq, "yd1^2 L": yd1**2 * Lq, "yd1 thd L^2": yd1 * thd * Lq**2, "thd^2 L^3/3": thd**2 * Lq**3 / 3,
        "xd1 E.Sd": xd1 * (E * Sd)[0], "Sd.B.Sd": (Sd.T * B * Sd)[0], "thd Sd.A.S": thd * (Sd.T * A * S)[0],
        "xd1 thd G.S": xd1 * thd * (G * S)[0], "thd^2 S.M.S": thd**2 * (S.T * Mw * S)[0],
        "yd1 thd E.S": yd1 * thd * (E * S)[0], "yd1 G.Sd": yd1 * (G * Sd)[0], "thd^2 N.S": thd**2 * (N * S)[0],
        "thd L.Sd": thd * (Lv * Sd)[0], "thd^2 S.B.S": thd**2 * (S.T * B * S)[0], "thd S.A.Sd": thd * (S.T * A * Sd)[0],
        "Sd.M.Sd": (Sd.T * Mw * Sd)[0],
    }
    corrected = dict(printed.EQ44_COEFFICIENTS)
    for key in printed.ERRATA:
        if key.startswith("eq44 "):
            corrected[key[5:]] = int(printed.ERRATA[key][1])

    def eq44(coefficients):
        return m / 2 * sum(coefficients[k] * t for k, t in terms.items())

    assert sp.expand(T - eq44(corrected)) == 0
    assert sp.expand(T - eq44(printed.EQ44_COEFFICIENTS)) != 0


# ---- the linear model with the frame held ------------------------------------------------------------
@pytest.mark.parametrize("name,fe_element", [("planar8_quintic", "quintic"), ("planar6_cubic", "hermite")])
def test_held_frame_with_tangent_conditions_is_a_cantilever_in_bending_and_tension(name, fe_element):
    """Frame fixed, u = w = w' = 0 at x = 0: the spectrum is the union of the FE cantilever's bending and
    axial spectra (same elements; no coupling in the linear model)."""
    n = 6
    beam = planar_beam(name, L, STEEL, SECTION, n)
    T = reference_conditions(beam, "tangent")
    K = T.T @ beam.K @ T
    omega = np.sqrt(eigh(K, T.T @ beam.M_ss @ T, eigvals_only=True))
    bending = fe_model("euler_bernoulli", L, STEEL, SECTION, n, ("clamped", "free"), element=fe_element).frequencies()
    axial = fe_model("rod", L, STEEL, SECTION, n, ("clamped", "free")).frequencies()
    expected = np.sort(np.concatenate([bending, axial]))
    assert np.abs(omega / expected - 1).max() <= exact.roundoff_floor(K)


def _rank(A: np.ndarray) -> int:
    """Numerical rank of a symmetric positive semi-definite A after Jacobi scaling (the dofs' units differ)."""
    d = 1.0 / np.sqrt(np.diag(A))
    ev = np.linalg.eigvalsh(d[:, None] * A * d[None, :])
    return int(np.sum(ev > len(A) * EPS * ev[-1]))


@pytest.mark.parametrize("kind", ["tangent", "chord"])
@pytest.mark.parametrize("name", sorted(PLANAR_ELEMENTS))
def test_reference_conditions_make_the_free_beam_mass_matrix_definite(name, kind):
    """Undeformed, the frame's three rigid motions are also motions of s (nullity 3); deformed, only the
    translations are (a linear field cannot rotate rigidly). Three reference conditions remove them."""
    beam = planar_beam(name, L, STEEL, SECTION, 3)
    p, _ = _state(3 + beam.n_s, 1)
    undeformed = np.concatenate([p[:3], np.zeros(beam.n_s)])
    assert _rank(mass_matrix(beam, undeformed)) == 3 + beam.n_s - 3
    assert _rank(mass_matrix(beam, p)) == 3 + beam.n_s - 2
    Tp = np.zeros((3 + beam.n_s, beam.n_s))
    Tp[:3, :3], Tp[3:, 3:] = np.eye(3), reference_conditions(beam, kind)
    for q in (undeformed, p):
        assert _rank(Tp.T @ mass_matrix(beam, q) @ Tp) == beam.n_s

"""The flexible bar on a floating frame (viz3d.flexible.floating, floating_points) against references
it did not write: sympy's exact volume integral of the kinetic energy and Hamel's equations
(floating_refs.py), the rigid box's closed-form inertia, conservation of momentum and energy in free
flight integrated by scipy's DOP853, the BarModels' own S1, S2, S_psi and M (mean axes, tangent
frame), the impact engine's linear "free" frame, seed 003's planar beam (viz3d.flexible.planar)
through the change of coordinates, and finite differences of the point kinematics.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from floating_refs import X, PolyBasis, SympyBar, frame_mass_matrix, hamel_velocity_forces, world_mass_matrix
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from viz3d.flexible import BarModel, Material, PointMass, Section, fe_model, mode_set, planar_beam
from viz3d.flexible import planar
from viz3d.flexible.bar import rayleigh_ritz
from viz3d.flexible.floating import (
    E_X,
    angular_momentum,
    elastic_forces,
    floating_bar,
    floating_bar_from_fields,
    gravity_forces,
    gravity_potential,
    kinetic_energies,
    kinetic_energy,
    linear_momentum,
    mass_matrix,
    rigid_bar,
    rotation_coupling,
    strain_energy,
    velocity_forces,
)
from viz3d.flexible.floating_points import (
    centreline,
    material_points,
    point_bias_accelerations,
    point_forces,
    point_jacobian,
    point_positions,
    point_velocities,
    section_angular_bias,
    section_angular_jacobian,
    section_rotations,
)
from viz3d.rotations import matrix_from_quat, matrix_from_rotation_vector

EPS = np.finfo(float).eps
#: Round-off of the invariants and of M, Q: each entry is a Gauss sum or contraction of at most a few
#: hundred rounded products (Higham's gamma_n, n <= 500), none larger than ~2x the entry's
#: Cauchy-Schwarz scale sqrt(M_ii M_jj) (the rigid inertia about G subtracts m x_G^2 from L^2/3).
ROUNDOFF = 1000 * EPS
#: Modal integrals of the analytic modes (S1 = 0, S2 + S_psi = 0) hold to the mode sets' own accuracy,
#: the bound test_flexible_modes.py uses (quadrature of closed-form shapes: ~1e-14 for 10 modes).
MODES_TOL = 1e-10
#: DOP853 keeps every local error below atol + rtol |y| (RMS over the state); after N steps the error
#: of a smooth invariant is at most N times that, times |dI/dy| |y| / |I| <= 2 for the quadratic ones
#: and sqrt(len(y)) <= 5 for the RMS norm: 10.
CONSERVATION_FACTOR = 10.0
RTOL = 1e-11
E_Y, E_Z = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
RNG = np.random.default_rng(20240611)

# ---- the polynomial bar of the sympy checks (rational data, exact in sympy and in floats' round-off) ----
L_S = sp.Rational(9, 10)
RHO_S, WIDTH_S, DEPTH_S = sp.Integer(1200), sp.Rational(6, 100), sp.Rational(1, 10)
POINT_MASSES_S = [(L_S, sp.Rational(2, 5)), (sp.Rational(3, 10), sp.Rational(1, 5))]
TIMO_U = [(X / L_S) ** 2, (X / L_S) ** 3 - X / (2 * L_S)]
TIMO_PSI = [2 * X / L_S**2 + sp.Rational(1, 5), 3 * X**2 / L_S**3 - sp.Rational(1, 2)]   # psi != w': shear
AXIAL_U = [X / L_S - sp.Rational(1, 3)]
EB_U = [(X / L_S) ** 2 * (X / L_S - 1)]


def _f(r) -> float:
    return float(r)


def poly_model(kind, theory, u, psi=None, point_masses=POINT_MASSES_S) -> BarModel:
    """A BarModel with explicit polynomial shapes on the sympy bar (its M, K by Rayleigh-Ritz)."""
    material = Material(7.0e9, _f(RHO_S), 0.3)
    section = Section.rectangle(_f(WIDTH_S), _f(DEPTH_S))
    basis = PolyBasis(_f(L_S), u, psi)
    pms = tuple(PointMass(_f(x), _f(m)) for x, m in point_masses)
    M, K = rayleigh_ritz(theory, material, section, basis, pms)
    return BarModel(kind, theory, _f(L_S), material, section, ("free", "free"), basis, np.eye(len(u)), M, K, pms, "poly")


CASES = {
    # seed 003's planar element: axial + Euler-Bernoulli bending in x-y, no point masses
    "planar": ([((1, 0, 0), AXIAL_U, None, "axial", "rod"), ((0, 1, 0), EB_U, None, "bending", "euler_bernoulli")], []),
    # 3D: Timoshenko in x-y (rotary inertia), axial, Euler-Bernoulli in x-z, two point masses
    "3d": ([((0, 1, 0), TIMO_U, TIMO_PSI, "bending", "timoshenko"), ((1, 0, 0), AXIAL_U, None, "axial", "rod"),
            ((0, 0, 1), EB_U, None, "bending", "euler_bernoulli")], POINT_MASSES_S),
}


@functools.lru_cache(maxsize=None)
def sympy_case(name):
    """(FloatingBar, SympyBar) of a case; the Euler-Bernoulli field along z uses the rectangle turned
    a quarter turn (its depth is the width), as the body's section requires."""
    spec, pms = CASES[name]
    fields = []
    for d, u, psi, kind, theory in spec:
        model = poly_model(kind, theory, u, psi, pms)
        if d == (0, 0, 1):
            material = model.material
            turned = Section.rectangle(_f(DEPTH_S), _f(WIDTH_S))
            M, K = rayleigh_ritz(theory, material, turned, model.basis, model.point_masses)
            model = BarModel(kind, theory, model.length, material, turned, model.supports, model.basis, model.T, M, K,
                             model.point_masses, "poly turned")
        fields.append((np.array(d, dtype=float), model))
    bar = floating_bar_from_fields(fields)
    ref = SympyBar(L_S, RHO_S, WIDTH_S, DEPTH_S, [(d, u, psi) for d, u, psi, _, _ in spec], pms)
    return bar, ref


def random_state(n, scale_eta=0.1, planar_motion=False):
    R = Rotation.random(random_state=RNG.integers(1 << 31)).as_matrix()
    v = RNG.normal(size=6 + n)
    eta = scale_eta * RNG.normal(size=n)
    if planar_motion:
        R = matrix_from_rotation_vector(np.array([0.0, 0.0, RNG.uniform(-3, 3)]))
        v[2] = v[3] = v[4] = 0.0
    return R, v, eta


def scaled_error(A, B, M):
    """max |A - B| entrywise in the unit-free scaling D^-1/2 (.) D^-1/2, D = diag(M)."""
    d = 1.0 / np.sqrt(np.diag(M))
    return np.abs(d[:, None] * (A - B) * d[None, :]).max()


def metric_norm(Q, M):
    """||Q||_{M^-1} = sqrt(Q^T M^-1 Q): a unit-consistent size of a generalized force."""
    return float(np.sqrt(Q @ np.linalg.solve(M, Q)))


# ---- sympy: the mass matrix, velocity and gravity forces of the exact kinetic energy ------------------
@pytest.mark.parametrize("name", list(CASES))
def test_mass_matrix_and_velocity_forces_match_sympy_and_hamel(name):
    bar, ref = sympy_case(name)
    M_B, dM_B = ref.numeric
    assert bar.mass == pytest.approx(float(ref.mass), rel=ROUNDOFF)
    for _ in range(4):
        R, v, eta = random_state(bar.n, planar_motion=(name == "planar"))
        M_ref = world_mass_matrix(np.asarray(M_B(eta), dtype=float), R)
        M = mass_matrix(bar, R, eta)
        assert scaled_error(M, M_ref, M_ref) < ROUNDOFF
        Q_ref = hamel_velocity_forces(np.asarray(M_B(eta), dtype=float), dM_B(eta), R, v)
        Q = velocity_forces(bar, R, v[3:6], eta, v[6:])
        assert metric_norm(Q - Q_ref, M_ref) < ROUNDOFF * metric_norm(Q_ref, M_ref)
        if name == "planar":   # planar motion of a planar body stays planar
            assert np.abs(Q[[2, 3, 4]]).max() < ROUNDOFF * np.abs(Q).max()
        g = np.array([0.3, -1.2, -9.81])
        G_ref = ref.gravity_forces(R, g, eta)
        assert metric_norm(gravity_forces(bar, R, eta, g) - G_ref, M_ref) < ROUNDOFF * metric_norm(G_ref, M_ref)
        W_r = RNG.normal(size=3)
        V_ref = -g @ (float(ref.mass) * W_r + R @ ref.numeric_first_moment(eta))
        assert gravity_potential(bar, W_r, R, eta, g) == pytest.approx(V_ref, rel=ROUNDOFF)


def test_elastic_mass_matrix_is_the_fields_mass_matrices_counted_once():
    """Diagonal blocks of M_ee = each BarModel.M (Timoshenko's rho I psi^2 included once, Euler-Bernoulli
    without rotary inertia); fields in orthogonal directions do not couple in M_ee."""
    bar, _ = sympy_case("3d")
    for model, sl in zip(bar.fields, bar.field_slices):
        assert scaled_error(bar.M_ee[sl, sl], model.M, model.M) < ROUNDOFF
        assert np.abs(bar.S_psi[sl] - model.S_psi).max() <= ROUNDOFF * np.abs(model.S2).max()
    assert np.abs(bar.M_ee[:2, 2:]).max() == 0.0


# ---- rigid limit --------------------------------------------------------------------------------------
def test_rigid_bar_is_a_box_with_point_masses():
    """n = 0: M = diag(m I, J0) with J0 the box's m/12 diag(h^2 + w^2, L^2 + w^2, L^2 + h^2) about its
    centre plus the point masses by Steiner; Q_velocity = [0, -w x J0 w]."""
    L, w, h, rho = 0.9, 0.06, 0.1, 1200.0
    pms = (PointMass(L, 0.4), PointMass(0.3, 0.2))
    bar = rigid_bar(L, Material(7e9, rho, 0.3), Section.rectangle(w, h), pms)
    m_box = rho * w * h * L
    m = m_box + 0.6
    x_G = (m_box * L / 2 + 0.4 * L + 0.2 * 0.3) / m
    J_box = m_box / 12 * np.diag([h**2 + w**2, L**2 + w**2, L**2 + h**2])
    steiner = m_box * (L / 2 - x_G) ** 2 + 0.4 * (L - x_G) ** 2 + 0.2 * (0.3 - x_G) ** 2
    J0 = J_box + steiner * np.diag([0.0, 1.0, 1.0])
    R, v, eta = random_state(0)
    M = mass_matrix(bar, R, eta)
    expected = np.zeros((6, 6))
    expected[:3, :3], expected[3:, 3:] = m * np.eye(3), J0
    assert scaled_error(M, expected, expected) < ROUNDOFF
    Q = velocity_forces(bar, R, v[3:6], eta, v[6:])
    assert np.abs(Q[:3]).max() == 0.0
    assert np.abs(Q[3:] + np.cross(v[3:6], J0 @ v[3:6])).max() < ROUNDOFF * np.abs(J0).max() * (v[3:6] @ v[3:6])


def test_undeformed_flexible_bar_has_the_rigid_inertia():
    """eta = eta_dot = 0: the frame rows of M and Q_velocity are the rigid body's."""
    bar, _ = sympy_case("3d")
    rigid = rigid_bar(bar.length, bar.material, bar.section, bar.point_masses)
    R, v, _ = random_state(bar.n)
    zero = np.zeros(bar.n)
    M, M_r = mass_matrix(bar, R, zero)[:6, :6], mass_matrix(rigid, R, zero[:0])
    assert scaled_error(M, M_r, M_r) < ROUNDOFF
    Q, Q_r = velocity_forces(bar, R, v[3:6], zero, zero)[:6], velocity_forces(rigid, R, v[3:6], zero[:0], zero[:0])
    assert np.abs(Q - Q_r).max() < ROUNDOFF * np.abs(Q_r).max()


# ---- free flight: conservation --------------------------------------------------------------------------
#: Soft and stubby enough that the axial mode (~100 rad/s) does not dictate thousands of steps, while
#: the lowest bending mode (~5 rad/s) is slow enough to couple with the spin.
SOFT = Material(4.0e6, 1000.0, 0.3)
SQUARE = Section.rectangle(0.08, 0.08)


def soft_bar():
    """A spinning soft bar on a tangent frame (clamped-free modes: no mean axes, all couplings on):
    Timoshenko bending in x-y (2 modes), Euler-Bernoulli in x-z (1), axial (1)."""
    L = 1.0
    fields = [(E_Y, mode_set("timoshenko_cantilever")(L, SOFT, SQUARE, 2)),
              (E_Z, mode_set("bending_cantilever")(L, SOFT, SQUARE, 1)),
              (E_X, mode_set("axial_clamped_free")(L, SOFT, SQUARE, 1))]
    return floating_bar_from_fields(fields)


def test_free_flight_conserves_momentum_and_energy():
    bar = soft_bar()
    n = bar.n

    def rhs(t, y):
        quat, eta, v = y[3:7], y[7:7 + n], y[7 + n:]
        R = matrix_from_quat(quat)
        w = v[3:6]
        quat_dot = 0.5 * np.array([-quat[1:] @ w, *(quat[0] * w + np.cross(quat[1:], w))])
        Q = velocity_forces(bar, R, w, eta, v[6:])
        Q[6:] += elastic_forces(bar, eta, v[6:])
        return np.concatenate([v[:3], quat_dot, v[6:], np.linalg.solve(mass_matrix(bar, R, eta), Q)])

    omega1 = bar.fields[0].frequencies()[0]
    eta0 = np.array([0.04, 0.004, -0.03, 1e-4]) * np.sqrt(bar.mass)
    v0 = np.concatenate([[0.3, -0.2, 0.1], [0.4, 0.25 * omega1, -0.2 * omega1], omega1 * np.array([0.02, -0.01, 0.03, 0.0])])
    y0 = np.concatenate([[0.1, 0.2, -0.3], Rotation.from_euler("zyx", [0.3, -0.5, 1.1]).as_quat(scalar_first=True), eta0, v0])
    sol = solve_ivp(rhs, (0.0, 1.0), y0, method="DOP853", rtol=RTOL, atol=1e-14)
    assert sol.success
    invariants = []
    for y in sol.y.T:
        R, eta, v = matrix_from_quat(y[3:7]), y[7:7 + n], y[7 + n:]
        M = mass_matrix(bar, R, eta)
        L_W = linear_momentum(bar, R, eta, v)
        H_W = angular_momentum(bar, y[:3], R, eta, v)
        E = kinetic_energy(bar, R, eta, v) + strain_energy(bar, eta)
        L_scale = np.abs(M[:3] * v).sum()
        H_scale = np.linalg.norm(y[:3]) * L_scale + np.abs(M[3:6] * v).sum()
        invariants.append((L_W, H_W, E, L_scale, H_scale))
    L_W, H_W, E, L_s, H_s = (np.array(a) for a in zip(*invariants))
    bound = CONSERVATION_FACTOR * (len(sol.t) - 1) * RTOL
    assert np.abs(L_W - L_W[0]).max() < bound * L_s.max()
    assert np.abs(H_W - H_W[0]).max() < bound * H_s.max()
    assert np.abs(E - E[0]).max() < bound * E.max()
    # the run is a real test: the bar deforms and exchanges energy between frame and modes
    strain = np.array([strain_energy(bar, y[7:7 + n]) for y in sol.y.T])
    assert strain.max() - strain.min() > 0.05 * E[0]


# ---- mean axes and tangent frames ---------------------------------------------------------------------
def test_free_free_modes_are_mean_axes_and_clamped_free_modes_are_not():
    L, steel, sec = 0.3, Material(210e9, 7850.0, 0.3), Section.rectangle(0.03, 0.03)
    for bend, axial in (("timoshenko_free_free", "axial_free_free"), ("bending_free_free", "axial_free_free"),
                        ("timoshenko_cantilever", "axial_clamped_free"), ("bending_cantilever", "axial_clamped_free")):
        b, a = mode_set(bend)(L, steel, sec, 4), mode_set(axial)(L, steel, sec, 2)
        bar = floating_bar(b, E_Z, second=(E_X, a))
        R, _, eta = random_state(bar.n, scale_eta=0.01)
        M = mass_matrix(bar, R, eta)
        S1 = np.concatenate([b.S1, a.S1])
        D = np.hstack([np.outer(E_Z, np.ones(4)), np.outer(E_X, np.ones(2))])
        # the translational rows are R skew(...)(D S1 eta) and R D S1: nothing else
        s_c = D @ (S1 * eta)
        expected = np.hstack([-R @ np.array([[0, -s_c[2], s_c[1]], [s_c[2], 0, -s_c[0]], [-s_c[1], s_c[0], 0]]), R @ (D * S1)])
        scale = np.sqrt(bar.mass) * L
        assert np.abs(M[:3, 3:] - expected).max() < ROUNDOFF * scale
        # rotational coupling at eta = 0 about b = e_x x e_z = -e_y: S2 about G, plus S_psi
        G0 = rotation_coupling(bar, np.zeros(bar.n))
        b_axis = np.cross(E_X, E_Z)
        assert np.abs(b_axis @ G0[:, :4] - (b.S2 - bar.x_G * b.S1 + b.S_psi)).max() < ROUNDOFF * scale
        if "free_free" in bend:
            assert np.abs(M[:3, 3:]).max() < MODES_TOL * scale                         # decoupled
            assert np.abs(G0).max() < MODES_TOL * scale                                # mean axes
        else:
            assert np.abs(M[:3, 6:]).max() > 0.1 * np.sqrt(bar.mass)                 # coupled
            assert np.abs(G0).max() > 0.01 * scale


# ---- the linear (small-rotation) frame of thesis ch. 6 and 10 ---------------------------------------------------------------------
@pytest.mark.parametrize("name", ["bending_cantilever", "timoshenko_cantilever", "bending_free_free",
                                  "bending_cantilever_mass", "axial_clamped_free", "axial_free_mass"])
def test_small_rotation_limit_is_the_linear_free_frame(name):
    """At R = I, eta = 0 the planar block of M in (v_d, w_b, eta_dot) is the impact engine's
    ``frame_mass_matrix(model, "free")`` in z = [Y, Theta, q] (Y, Theta about x = 0) after the change of
    origin v_d = Y_dot + x_G Theta_dot, w_b = Theta_dot: M_free = T^T M T. The impact engine counts the
    section's rotary inertia rho I L only for Timoshenko bars; this body always has it (a rigid section's
    inertia), so for Euler-Bernoulli the Theta-Theta entries differ by exactly rho I L."""
    steel, sec, L = Material(210e9, 7850.0, 0.3), Section.rectangle(0.03, 0.02), 0.3
    kw = {"tip_mass": 0.7} if name.endswith("_mass") else {}
    model = mode_set(name)(L, steel, sec, 3, **kw)
    d = E_X if model.kind == "axial" else E_Y
    bar = floating_bar(model, d)
    M = mass_matrix(bar, np.eye(3), np.zeros(bar.n))
    M_free = frame_mass_matrix(model, "free")
    if model.kind == "axial":
        rows = [0] + list(range(6, 6 + bar.n))
        T = np.eye(1 + bar.n)
    else:
        b = np.cross(E_X, d)
        rows = [1, 5] + list(range(6, 6 + bar.n))                        # v_y and w_z (b = e_z)
        assert b[2] == 1.0
        T = np.eye(2 + bar.n)
        T[0, 1] = bar.x_G
    mapped = T.T @ M[np.ix_(rows, rows)] @ T
    if model.kind == "bending" and model.theory == "euler_bernoulli":
        mapped[1, 1] -= steel.rho * sec.second_moment * L
    assert scaled_error(mapped, M_free, M_free) < ROUNDOFF


# ---- seed 003's planar beam -------------------------------------------------------------------------------
def test_planar_beam_equations_follow_by_the_change_of_coordinates():
    """viz3d.flexible.planar (p = [X1, Y1, theta, s], frame at x = 0, nodal dofs [u, w, w'] node by node)
    against this body with an axial and an Euler-Bernoulli field of the same elements: with
    v = Gamma(p) p_dot (W_v = [X1_dot, Y1_dot, 0] + theta_dot e_z x R x_G e_x, w = theta_dot e_z,
    eta_dot = permuted s_dot), Gamma^T M Gamma = M_p + rho I L e_theta e_theta^T (the section's own
    inertia, absent from the line model), Gamma^T (Q_velocity - M Gamma_dot p_dot) = Q_v,p and
    Gamma^T Q_gravity = Q_g,p, Gamma^T Q_elastic = -K_p s; positions agree."""
    L, steel, sec, n_el = 0.6, Material(70e9, 2700.0, 0.33), Section.rectangle(0.02, 0.03), 3
    beam = planar_beam("planar6_cubic", L, steel, sec, n_el)
    axial = fe_model("rod", L, steel, sec, n_el, ("free", "free"))
    bending = fe_model("euler_bernoulli", L, steel, sec, n_el, ("free", "free"), element="hermite")
    bar = floating_bar(bending, E_Y, second=(E_X, axial))     # eta = [w0, w0', w1, w1', ..., u0, u1, ...]
    nodes = n_el + 1
    perm = [3 * i + k for i in range(nodes) for k in (1, 2)] + [3 * i for i in range(nodes)]
    n_s = beam.n_s
    for _ in range(3):
        theta, thd = RNG.uniform(-3, 3), RNG.normal()
        s, sd = 1e-2 * RNG.normal(size=n_s), RNG.normal(size=n_s)
        p = np.concatenate([RNG.normal(size=2), [theta], s])
        pd = np.concatenate([RNG.normal(size=2), [thd], sd])
        R = matrix_from_rotation_vector(np.array([0.0, 0.0, theta]))
        r_G = R @ (bar.x_G * E_X)
        Gamma = np.zeros((6 + bar.n, 3 + n_s))
        Gamma[0, 0] = Gamma[1, 1] = 1.0
        Gamma[:3, 2] = np.cross(E_Z, r_G)
        Gamma[5, 2] = 1.0
        Gamma[6:, 3:] = np.eye(n_s)[perm]
        v, eta = Gamma @ pd, s[perm]
        Gamma_dot_pd = np.concatenate([-thd**2 * r_G, np.zeros(3 + bar.n)])
        M = mass_matrix(bar, R, eta)
        M_p = planar.mass_matrix(beam, p)
        M_p_sec = M_p.copy()
        M_p_sec[2, 2] += steel.rho * sec.second_moment * L
        assert scaled_error(Gamma.T @ M @ Gamma, M_p_sec, M_p_sec) < ROUNDOFF
        Q = Gamma.T @ (velocity_forces(bar, R, v[3:6], eta, v[6:]) - M @ Gamma_dot_pd)
        Q_p = planar.quadratic_velocity_forces(beam, p, pd)
        d = np.sqrt(np.diag(M_p_sec))                          # M_p is singular: scale row by row
        assert np.abs((Q - Q_p) / d).max() < ROUNDOFF * np.abs(Q_p / d).max()
        g = np.array([1.5, -9.81])
        Q_g = Gamma.T @ gravity_forces(bar, R, eta, np.append(g, 0.0))
        Q_gp = planar.gravity_forces(beam, p, g)
        assert np.abs((Q_g - Q_gp) / d).max() < ROUNDOFF * np.abs(Q_gp / d).max()
        Q_e = Gamma.T @ np.concatenate([np.zeros(6), elastic_forces(bar, eta, np.zeros(bar.n))])
        assert np.all(np.abs(Q_e - planar.elastic_forces(beam, p))[3:] <= ROUNDOFF * (np.abs(beam.K) @ np.abs(s)))
        x = np.linspace(0.0, L, 7)
        W_r = np.append(p[:2], 0.0) + r_G
        W_p = point_positions(bar, W_r, R, eta, material_points(bar, x))
        W_p_ref = planar.world_positions(beam, p, x)
        assert np.abs(W_p[:, :2] - W_p_ref).max() < ROUNDOFF * (L + np.abs(p[:2]).max())
        assert np.abs(W_p[:, 2]).max() == 0.0


# ---- material points: the field itself, sign conventions, finite differences -----------------------------
def test_material_points_are_the_documented_field_and_follow_the_bar_conventions():
    """Positions = sympy's s(x, y, z) (plus the Euler-Bernoulli slope turning c, which the kinetic energy
    leaves out); section rotations = b psi (Timoshenko) and b w' (Euler-Bernoulli), b = e_x x d; the
    surface fibre at c = (depth/2) d stretches by BarModel.strain (-(depth/2) psi')."""
    bar, ref = sympy_case("3d")
    y, z = sp.symbols("y z")
    x = np.array([0.0, 0.17, 0.5, _f(L_S)])
    c = np.array([[0.0, 0.05, 0.0], [0.0, -0.02, 0.03], [0.0, 0.0, -0.03], [0.0, 0.05, 0.03]])
    pts = material_points(bar, x, c)
    eta = 0.1 * RNG.normal(size=bar.n)
    s = point_positions(bar, np.zeros(3), np.eye(3), eta, pts)
    w_eb = sp.lambdify(X, sp.diff(EB_U[0], X))
    for k in range(len(x)):
        s_ref = np.array(ref.position(y, z).subs({X: x[k], y: c[k, 1], z: c[k, 2], **dict(zip(ref.eta, eta))}),
                         dtype=float).ravel()
        theta_eb = np.cross(E_X, E_Z) * w_eb(x[k]) * eta[3]
        assert np.abs(s[k] - s_ref - np.cross(theta_eb, c[k])).max() < ROUNDOFF * _f(L_S)
    theta = section_rotations(bar, eta, pts)
    psi = np.array([[float(e.subs(X, xk)) for e in TIMO_PSI] for xk in x]) @ eta[:2]
    expected = np.cross(E_X, E_Y)[None] * psi[:, None] + np.cross(E_X, E_Z)[None] * (w_eb(x) * eta[3])[:, None]
    assert np.abs(theta - expected).max() < ROUNDOFF * np.abs(expected).max()
    # the surface fibre on the +w side: d s_x / dx - 1 (axial part removed) = BarModel.strain
    timo = bar.fields[0]
    half = 0.5 * timo.section.depth
    fibre = ref.position(y, z)[0].subs({y: half, z: 0})
    strain = sp.diff(fibre, X) - 1 - sp.diff(AXIAL_U[0], X) * ref.eta[2]
    for xk in x:
        model_strain = timo.strain([xk])[0] @ eta[:2]
        assert float(strain.subs({X: xk, **dict(zip(ref.eta, eta))})) == pytest.approx(model_strain, rel=ROUNDOFF)


#: Rounding of one evaluated position or rotation: a dozen rounded products and sums, relative.
EVAL_ROUNDING = 16 * EPS


def central_difference_bounds(f_scale, d3, d4):
    """Step sizes and error bounds of the central first and second differences of f(t), |f| <= f_scale,
    third and fourth derivatives bounded by d3, d4: truncation h^2 d3 / 6 (h^2 d4 / 12) plus rounding
    EVAL_ROUNDING f_scale / h (4 EVAL_ROUNDING f_scale / h^2), each at its minimizing h."""
    r = EVAL_ROUNDING * f_scale
    h1 = (3 * r / d3) ** (1 / 3)
    h2 = (24 * r / d4) ** (1 / 4)
    return h1, h1**2 / 6 * d3 + r / h1, h2, h2**2 / 12 * d4 + 4 * r / h2**2


def test_point_jacobian_and_bias_are_the_derivatives_of_positions():
    """Along the motion with constant v (W_r + t W_v, R exp(t skew(w)), eta + t eta_dot) the point velocity
    is J v and the acceleration is the bias alone. Derivative bounds: s(t) is linear in t, so
    |d^k/dt^k (R(t) s(t))| <= |w|^k |s| + k |w|^(k-1) |s_dot|."""
    bar = soft_bar()
    x = np.linspace(0.0, bar.length, 5)
    c = np.array([[0.0, 0.04, 0.0], [0.0, 0.0, -0.04], [0.0, 0.04, 0.04], [0.0, -0.02, 0.01], [0.0, 0.0, 0.0]])
    pts = material_points(bar, x, c)
    for _ in range(3):
        R0, v, eta0 = random_state(bar.n, scale_eta=0.05)
        W_r0 = RNG.normal(size=3)

        def positions(t):
            return point_positions(bar, W_r0 + t * v[:3], R0 @ matrix_from_rotation_vector(t * v[3:6]), eta0 + t * v[6:], pts)

        s = np.linalg.norm(pts.s0 + pts.N @ eta0, axis=1).max() * 1.01   # covers the few-h window
        sd = np.linalg.norm(pts.N @ v[6:], axis=1).max()
        w = np.linalg.norm(v[3:6])
        p_scale = np.abs(positions(0.0)).max()
        h1, err1, h2, err2 = central_difference_bounds(p_scale, w**3 * s + 3 * w**2 * sd, w**4 * s + 4 * w**3 * sd)
        J = point_jacobian(bar, R0, eta0, pts)
        velocity_fd = (positions(h1) - positions(-h1)) / (2 * h1)
        assert np.abs(J @ v - velocity_fd).max() < err1
        assert np.abs(point_velocities(bar, R0, eta0, pts, v) - J @ v).max() < ROUNDOFF * np.abs(J @ v).max()
        accel_fd = (positions(h2) - 2 * positions(0.0) + positions(-h2)) / h2**2
        assert np.abs(point_bias_accelerations(bar, R0, eta0, pts, v) - accel_fd).max() < err2


def test_section_angular_velocity_and_bias_are_the_derivatives_of_the_section_orientation():
    """At eta = 0 the section orientation R exp(skew(theta)) turns with W_Omega = R (w + P eta_dot)
    exactly (the first-order field is exact there); along constant v, d W_Omega / dt is the bias."""
    bar = soft_bar()
    pts = material_points(bar, np.array([0.0, 0.3, 1.0]))
    R0, v, _ = random_state(bar.n)

    def orientations(t):
        R = R0 @ matrix_from_rotation_vector(t * v[3:6])
        return R[None] @ matrix_from_rotation_vector(section_rotations(bar, t * v[6:], pts))

    rate = np.linalg.norm(v[3:6]) + np.linalg.norm(pts.P @ v[6:], axis=1).max()
    h1, err1, _, _ = central_difference_bounds(1.0, rate**3, rate**4)
    dR = (orientations(h1) - orientations(-h1)) / (2 * h1) @ np.swapaxes(orientations(0.0), 1, 2)
    Omega_fd = 0.5 * np.stack([dR[:, 2, 1] - dR[:, 1, 2], dR[:, 0, 2] - dR[:, 2, 0], dR[:, 1, 0] - dR[:, 0, 1]], axis=1)
    assert np.abs(section_angular_jacobian(bar, R0, pts) @ v - Omega_fd).max() < err1

    def angular_velocities(t):
        return section_angular_jacobian(bar, R0 @ matrix_from_rotation_vector(t * v[3:6]), pts) @ v

    w = np.linalg.norm(v[3:6])
    scale = np.linalg.norm(angular_velocities(0.0), axis=1).max()
    h1, err1, _, _ = central_difference_bounds(scale, w**3 * scale, w**4 * scale)
    bias_fd = (angular_velocities(h1) - angular_velocities(-h1)) / (2 * h1)
    assert np.abs(section_angular_bias(bar, R0, pts, v) - bias_fd).max() < err1


def test_point_forces_are_the_transposed_jacobian_with_body_torques():
    """Q = sum J_i^T F_i: [sum F, sum s x R^T F (body axes, as a rigid body's B_tau), sum N^T R^T F]; its
    power v . Q is the forces' power sum F . W_p_dot."""
    bar = soft_bar()
    pts = material_points(bar, np.array([0.1, 0.7, 1.0]), np.array([[0.0, 0.04, 0.0], [0.0, 0.0, 0.04], [0.0, 0.0, 0.0]]))
    R, v, eta = random_state(bar.n, scale_eta=0.05)
    F = RNG.normal(size=(3, 3))
    J = point_jacobian(bar, R, eta, pts)
    Q = point_forces(bar, R, eta, pts, F)
    assert np.abs(Q - np.einsum("kir,ki->r", J, F)).max() < ROUNDOFF * np.abs(J).max() * np.abs(F).sum()
    s = pts.s0 + pts.N @ eta
    assert np.abs(Q[3:6] - np.cross(s, F @ R).sum(axis=0)).max() < ROUNDOFF * np.abs(s).max() * np.abs(F).sum()
    power = np.sum(F * point_velocities(bar, R, eta, pts, v))
    assert v @ Q == pytest.approx(power, rel=ROUNDOFF, abs=ROUNDOFF * np.abs(v) @ np.abs(Q))


# ---- damping, display, validation ----------------------------------------------------------------------
def test_modal_damping_gives_each_mode_its_ratio():
    """Mass-normalised analytic modes (M_ee = I, K = diag(omega^2) to the modes' accuracy): C =
    diag(2 zeta omega). An unsupported FE bar keeps its rigid modes, which get no damping."""
    L, steel, sec = 0.3, Material(210e9, 7850.0, 0.3), Section.rectangle(0.03, 0.03)
    model = mode_set("bending_free_free")(L, steel, sec, 4)
    bar = floating_bar(model, modal_damping=0.02, second=(E_X, mode_set("axial_free_free")(L, steel, sec, 2)))
    omega = np.concatenate([f.frequencies() for f in bar.fields])
    assert np.abs(bar.C - np.diag(2 * 0.02 * omega)).max() < MODES_TOL * 2 * 0.02 * omega.max()
    eta, eta_dot = RNG.normal(size=bar.n), RNG.normal(size=bar.n)
    assert np.array_equal(elastic_forces(bar, eta, eta_dot), -bar.K @ eta - bar.C @ eta_dot)
    assert strain_energy(bar, eta) == pytest.approx(0.5 * eta @ bar.K @ eta, rel=ROUNDOFF)
    fe = floating_bar(fe_model("euler_bernoulli", L, steel, sec, 4, ("free", "free")), modal_damping=0.02)
    nodes = np.linspace(0.0, L, 5)
    for rigid in (np.tile([1.0, 0.0], 5), np.stack([nodes, np.ones(5)], axis=1).ravel()):
        # w = 1, w' = 0 (translation); w = x, w' = 1 (rotation): no damping force
        assert np.abs(fe.C @ rigid).max() < ROUNDOFF * np.abs(fe.C).max() * np.abs(rigid).sum()


def test_undeformed_centreline_is_the_segment_through_the_centre_of_mass():
    bar, _ = sympy_case("3d")
    R, _, _ = random_state(bar.n)
    W_r = RNG.normal(size=3)
    line = centreline(bar, W_r, R, np.zeros(bar.n))
    x = np.linspace(0.0, bar.length, len(line))
    assert np.abs(line - (W_r + np.outer(x - bar.x_G, R @ E_X))).max() < ROUNDOFF * (bar.length + np.abs(W_r).max())


def test_fields_must_share_one_bar():
    L, steel, sec = 0.3, Material(210e9, 7850.0, 0.3), Section.rectangle(0.02, 0.03)
    bend = mode_set("bending_cantilever")(L, steel, sec, 2)
    with pytest.raises(ValueError, match="normal to the bar"):
        floating_bar(bend, np.array([0.6, 0.8, 0.0]))
    with pytest.raises(ValueError, match="axial field"):
        floating_bar(mode_set("axial_free_free")(L, steel, sec, 2), E_Y)
    with pytest.raises(ValueError, match="share the bar"):
        floating_bar(bend, second=(E_X, mode_set("axial_free_free")(2 * L, steel, sec, 2)))
    with pytest.raises(ValueError, match="second moment"):       # a rectangle bends differently about z
        floating_bar_from_fields([(E_Y, bend), (E_Z, bend)])


@pytest.mark.parametrize("name", ["soft", *CASES])
def test_kinetic_energies_of_many_states_are_each_states_kinetic_energy(name):
    """``kinetic_energies`` (the blocks of M over N states) against ``kinetic_energy`` (1/2 v^T M v
    with M formed) of each, at large deformations (every coupling of M on): a sum of (6 + n)^2
    products, so within (6 + n) eps of 1/2 |v|^T |M| |v| (the sum of the products' magnitudes), times 4."""
    bar = soft_bar() if name == "soft" else sympy_case(name)[0]
    states = [random_state(bar.n, scale_eta=0.3) for _ in range(6)]
    R, v, eta = (np.array(x) for x in zip(*states))
    T = kinetic_energies(bar, R, eta, v)
    for i in range(len(states)):
        M = mass_matrix(bar, R[i], eta[i])
        bound = 4 * (6 + bar.n) * EPS * 0.5 * np.abs(v[i]) @ np.abs(M) @ np.abs(v[i])
        assert abs(T[i] - kinetic_energy(bar, R[i], eta[i], v[i])) <= bound

"""The pressure series against closed forms and printed numbers nobody here wrote (hydro_refs).

Tolerances: a printed number's rounding (half a unit in its last digit), plus the truncation bound
each result carries (``SeriesResult.bound``), plus machine epsilon times a small count of
operations; closed-form remainders where a Taylor expansion is compared (see each test).
"""

from __future__ import annotations

import numpy as np
import pytest
from hydro_refs import (
    BASE_PRESSURE_COEFFICIENT,
    CHOPRA_FORCE_COEFFICIENT,
    SEED_C,
    SEED_DEPTH,
    SEED_FIRST_CUTOFF,
    SEED_RHO,
    WESTERGAARD_BASE,
    ZETA3,
    ZETA5,
    ZETA7,
    half_unit,
)

from viz3d.hydro import dam as D
from viz3d.hydro.reservoir import (
    SEED_EXAMPLE,
    Reservoir,
    added_mass,
    dynamic_stiffness,
    pressure,
    westergaard_pressure,
)
from viz3d.hydro.shapes import SampledShapes, SmoothShapes, uniform

EPS = np.finfo(float).eps
RHO, H, C = SEED_RHO, SEED_DEPTH, SEED_C
INCOMPRESSIBLE = Reservoir(RHO, H)
ABSORBING = Reservoir(RHO, H, C, reflection=0.5)
UNIFORM = uniform(H)
#: Accumulated rounding of a series of ~1e3 terms of size <= the scale, relative to the scale.
ROUNDING = 1e4 * EPS


def dam_modes(depth: float = H) -> SmoothShapes:
    """The example dam's five modes on the wetted height, as a smooth multi-shape."""
    bar = D.cantilever_dam().bar
    return SmoothShapes.from_function(lambda y: bar.displacement(y), depth)


def kinked_shape() -> SampledShapes:
    """A sampled shape with kinks and phi(h) != 0 (a measured profile, say)."""
    y = np.linspace(0.0, H, 41)
    rng = np.random.default_rng(7)
    return SampledShapes(y, 0.3 + y / H + 0.05 * rng.standard_normal(y.size))


# ----------------------------------------------------------------------------------------------
# incompressible rigid wall: Chopra, Catalan, Westergaard
# ----------------------------------------------------------------------------------------------
def test_rigid_wall_force_is_chopras_0_5428():
    A = added_mass(INCOMPRESSIBLE, UNIFORM, 0.0)
    coefficient = A.value[0, 0, 0] / (RHO * H**2)
    assert coefficient.imag == 0.0
    tol = half_unit(CHOPRA_FORCE_COEFFICIENT, 4) + A.bound / (RHO * H**2) + ROUNDING
    assert abs(coefficient.real - CHOPRA_FORCE_COEFFICIENT) <= tol


def test_base_pressure_is_eight_catalan_over_pi_squared():
    p = pressure(INCOMPRESSIBLE, UNIFORM, 0.0, [0.0])
    coefficient = p.value[0, 0] / (RHO * H)
    assert abs(coefficient - BASE_PRESSURE_COEFFICIENT) <= p.bound / (RHO * H) + ROUNDING


def test_westergaard_parabola_lies_above_the_exact_pressure():
    """Westergaard's (7/8) rho a sqrt(h (h - y)) is conservative over the whole face (docs/hydro.md
    states by how much: 17.9 % at the base, 7.5 % on the force)."""
    y = np.linspace(0.0, H, 201)[:-1]
    p = pressure(INCOMPRESSIBLE, UNIFORM, 0.0, y)
    assert np.all(westergaard_pressure(INCOMPRESSIBLE, y) >= p.value[0].real - p.bound)
    base_excess = WESTERGAARD_BASE / BASE_PRESSURE_COEFFICIENT - 1.0
    assert abs(westergaard_pressure(INCOMPRESSIBLE, [0.0])[0] / p.value[0, 0].real - 1.0 - base_excess) <= 1e-8


# ----------------------------------------------------------------------------------------------
# the accelerated series against the plain one
# ----------------------------------------------------------------------------------------------
def plain_series(omega: float, x: float, y: np.ndarray, n_terms: int) -> tuple[np.ndarray, float]:
    """Chopra's series for phi = 1 summed term by term (no acceleration), and a bound of its tail.

    Terms (2 rho / h) sin(l (h - y)) exp(-kappa x) / (l kappa), l = (2n - 1) pi / 2h; beyond the
    cut-offs |term| <= (2 rho / h) / (s l^2), sum_{n>N} l^-2 <= (2h/pi)^2 / (2 (2N - 1)).
    """
    k = omega / C
    total = np.zeros(y.size, dtype=complex)
    for start in range(1, n_terms + 1, 20000):
        n = np.arange(start, min(n_terms, start + 19999) + 1)
        lam = (2 * n - 1) * np.pi / (2 * H)
        kappa = np.where(lam > k, np.sqrt(np.abs(lam**2 - k**2)), 1j * np.sqrt(np.abs(k**2 - lam**2)))
        terms = np.sin(np.outer(lam, H - y)) * np.exp(-np.outer(kappa, np.full(y.size, x))) / (lam * kappa)[:, None]
        total += 2 * RHO / H * terms.sum(axis=0)
    s = np.sqrt(1 - (k / ((2 * n_terms + 1) * np.pi / (2 * H))) ** 2)
    return total, 2 * RHO / H * (2 * H / np.pi) ** 2 / (2 * (2 * n_terms - 1)) / s


@pytest.mark.parametrize("omega, x", [(0.0, 0.0), (20.0, 0.0), (80.0, 0.0), (20.0, 30.0), (80.0, 150.0)])
def test_accelerated_series_equals_the_plain_sum(omega, x):
    y = np.array([0.0, 17.0, 50.0, 83.0, 99.0])
    reference, tail = plain_series(omega, x, y, 200_000)
    p = pressure(SEED_EXAMPLE, UNIFORM, omega, y, x)
    assert np.abs(p.value[0] - reference).max() <= tail + p.bound + ROUNDING * RHO * H


# ----------------------------------------------------------------------------------------------
# compressible -> incompressible as omega -> 0 and c -> infinity
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("omega, c", [(2.0, C), (5.0, C), (10.0, C), (20.0, 1e4), (20.0, 1e5)])
def test_added_mass_expansion_in_omega_h_over_c(omega, c):
    """A(omega) / (rho h^2) = 14 zeta(3)/pi^3 + 31 zeta(5)/pi^5 (omega h / c)^2 + R, where, from
    1/kappa = (1/l)(1 - u)^-1/2, u = (omega / c l)^2, Taylor's remainder gives
    0 <= R <= (3/4) (2/pi)^7 (127/128) zeta(7) (omega h / c)^4 (1 - u_1)^-5/2."""
    eps_h = omega * H / c
    u1 = (eps_h * 2 / np.pi) ** 2
    A = added_mass(Reservoir(RHO, H, c), UNIFORM, omega)
    coefficient = A.value[0, 0, 0].real / (RHO * H**2)
    expansion = 14 * ZETA3 / np.pi**3 + 31 * ZETA5 / np.pi**5 * eps_h**2
    remainder = 0.75 * (2 / np.pi) ** 7 * (127 / 128) * ZETA7 * eps_h**4 / (1 - u1) ** 2.5
    slack = A.bound / (RHO * H**2) + ROUNDING
    assert -slack <= coefficient - expansion <= remainder + slack


@pytest.mark.parametrize("omega, c", [(1.0, C), (10.0, C), (20.0, 1e5)])
def test_pressure_profile_tends_to_incompressible(omega, c):
    """|p_c - p_inc| <= sum (2 rho/h) |1/kappa - 1/l| / l <= rho k^2 h^3 / (3 s (1 + s)), k = omega/c,
    s = sqrt(1 - (k/l_1)^2) (sum l^-4 = (2h/pi)^4 (15/16) zeta(4) = h^4 / 6)."""
    y = np.linspace(0.0, H, 51)
    k = omega / c
    s = np.sqrt(1 - (k * 2 * H / np.pi) ** 2)
    pc = pressure(Reservoir(RHO, H, c), UNIFORM, omega, y)
    pi = pressure(INCOMPRESSIBLE, UNIFORM, omega, y)
    bound = RHO * k**2 * H**3 / (3 * s * (1 + s))
    assert np.abs(pc.value - pi.value).max() <= bound + pc.bound + pi.bound


# ----------------------------------------------------------------------------------------------
# cut-off frequencies, radiation, energy
# ----------------------------------------------------------------------------------------------
def test_first_cutoff_is_the_seeds_23_45():
    assert abs(SEED_EXAMPLE.cutoff_frequencies(1)[0] - SEED_FIRST_CUTOFF) <= half_unit(SEED_FIRST_CUTOFF, 2)


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_rigid_wall_response_is_unbounded_at_the_cutoff(side):
    """Near omega_1 the first term is (2 rho/h) c / (l_1^2 sqrt((omega_1^2 - omega^2))) (times -j above):
    A sqrt|omega_1^2 - omega^2| -> K0 = (2 rho / h) c / l_1^2, the rest bounded by
    0.5428 rho h^2 / s_2 (s_2 = sqrt(1 - (omega_1 / omega_2)^2) = sqrt(8/9)) times the root."""
    omega_1 = SEED_EXAMPLE.cutoff_frequencies(1)[0]
    lam_1 = np.pi / (2 * H)
    K0 = 2 * RHO / H * C / lam_1**2
    for delta in (1e-4, 1e-8):
        omega = omega_1 * (1 + side * delta)
        root = np.sqrt(abs(omega_1**2 - omega**2))
        A = added_mass(SEED_EXAMPLE, UNIFORM, omega)
        scaled = A.value[0, 0, 0] * root * (1j if side > 0 else 1.0)
        tol = CHOPRA_FORCE_COEFFICIENT * RHO * H**2 / np.sqrt(8 / 9) * root + A.bound * root + ROUNDING * K0
        assert abs(scaled - K0) <= tol
        assert abs(A.value[0, 0, 0]) > 0.5 * K0 / root  # grows without bound as delta -> 0


def shape_sets():
    yield "uniform", UNIFORM
    yield "dam modes", dam_modes()
    yield "kinked", kinked_shape()


@pytest.mark.parametrize("reservoir", [SEED_EXAMPLE, ABSORBING], ids=["rigid bottom", "alpha 0.5"])
@pytest.mark.parametrize("name, shapes", list(shape_sets()), ids=[n for n, _ in shape_sets()])
def test_energy_leaves_the_dam(reservoir, name, shapes):
    """Im S(omega) is positive semi-definite for omega > 0 (power (omega/2) q^H Im S q >= 0), zero
    below the first cut-off over a rigid bottom, positive there over an absorbing one; and
    S(-omega) = conj S(omega) (a real time response)."""
    omega = np.array([5.0, 15.0, 23.0, 24.0, 50.0, 75.0])
    S = dynamic_stiffness(reservoir, shapes, omega)
    scale = np.abs(S.value).max()
    lowest = np.linalg.eigvalsh(S.value.imag).min(axis=1)
    assert np.all(lowest >= -(S.bound + ROUNDING * scale))
    below = omega < reservoir.cutoff_frequencies(1)[0]
    if reservoir.rigid_bottom:
        assert np.all(S.value[below].imag == 0.0)
        assert np.all(np.diagonal(S.value[~below].imag, axis1=1, axis2=2) > 0)
    else:
        assert np.all(np.diagonal(S.value.imag, axis1=1, axis2=2) > 0)
    S_neg = dynamic_stiffness(reservoir, shapes, -omega)
    assert np.abs(S_neg.value - np.conj(S.value)).max() <= 1e-11 * scale


@pytest.mark.parametrize("shape", [UNIFORM, SampledShapes(np.array([0.0, H]), np.array([0.0, 1.0]))],
                         ids=["uniform", "linear"])
def test_power_radiated_far_upstream_equals_power_done_by_the_wall(shape):
    """Far upstream only the propagating terms remain, p = sum P_n sin(l_n (h - y)) exp(-j k_n x); each
    carries (h k_n / (4 omega rho)) |P_n|^2 per unit width (displacement amplitudes). The wall does
    (omega / 2) Im S per unit displacement. P_n is read off the computed far field by projection."""
    omega, x_far = 80.0, 3000.0  # two propagating terms; the third decays like exp(-0.057 x)
    k = omega / C
    nodes, weights = np.polynomial.legendre.leggauss(64)
    y = 0.5 * H * (nodes + 1)
    p = pressure(SEED_EXAMPLE, shape, omega, y, x_far)
    lam = (2 * np.arange(1, 3) - 1) * np.pi / (2 * H)
    P = (2 / H) * (np.sin(np.outer(lam, H - y)) * (0.5 * H * weights)) @ p.value[0] * omega**2  # displacement
    k_n = np.sqrt(k**2 - lam**2)
    radiated = (H * k_n / (4 * omega * RHO) * np.abs(P) ** 2).sum()
    S = dynamic_stiffness(SEED_EXAMPLE, shape, omega)
    wall = 0.5 * omega * S.value[0, 0, 0].imag
    dP = 2 * p.bound * omega**2
    tol = (H * k_n / (4 * omega * RHO) * (2 * np.abs(P) * dP + dP**2)).sum() + 0.5 * omega * S.bound + ROUNDING * wall
    assert abs(radiated - wall) <= tol


# ----------------------------------------------------------------------------------------------
# truncation: the reported bound holds, terms follow the tolerance
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("reservoir", [INCOMPRESSIBLE, SEED_EXAMPLE, ABSORBING],
                         ids=["incompressible", "seed", "alpha 0.5"])
@pytest.mark.parametrize("name, shapes", list(shape_sets()), ids=[n for n, _ in shape_sets()])
def test_truncation_error_is_within_the_reported_bound(reservoir, name, shapes):
    omega = np.array([0.0, 20.0, 60.0])
    coarse, fine = (added_mass(reservoir, shapes, omega, rtol=r) for r in (1e-4, 1e-9))
    assert coarse.n_terms <= fine.n_terms
    assert np.abs(coarse.value - fine.value).max() <= coarse.bound + fine.bound
    if isinstance(shapes, SampledShapes):
        first = SampledShapes(shapes.y, shapes.values[:, 0])
    else:
        first = SmoothShapes.from_function(lambda y: shapes(y)[:, 0], H)
    y = np.linspace(0.0, H, 21)
    coarse, fine = (pressure(reservoir, first, omega, y, 10.0, rtol=r) for r in (1e-3, 1e-8))
    assert coarse.n_terms <= fine.n_terms
    assert np.abs(coarse.value - fine.value).max() <= coarse.bound + fine.bound


# ----------------------------------------------------------------------------------------------
# moments of the shapes
# ----------------------------------------------------------------------------------------------
MU = np.array([0.013, 0.2, 3.7, 0.05 + 0.02j, 1.1 - 0.3j])


def test_moments_of_a_linear_shape_are_exact_in_both_representations():
    """phi = y: I(mu) = int_0^h y sin(mu (h - y)) dy = h / mu - sin(mu h) / mu^2 (any complex mu)."""
    exact = H / MU - np.sin(MU * H) / MU**2
    sampled = SampledShapes(np.array([0.0, H]), np.array([0.0, H])).moments(MU)[:, 0]
    smooth = SmoothShapes.from_function(lambda y: y, H).moments(MU)[:, 0]
    scale = H**2 * np.exp(np.abs(MU.imag) * H)
    assert np.all(np.abs(sampled - exact) <= 1e3 * EPS * scale)
    assert np.all(np.abs(smooth - exact) <= 1e3 * EPS * scale)


def test_sampled_quadratic_is_off_by_its_interpolation_error_only():
    """phi = y^2: I = h^2/mu - 2 (1 - cos mu h)/mu^3. Its piecewise-linear interpolant on a grid of step d
    differs by (y - y_k)(y_k+1 - y) >= 0, whose integral is h d^2 / 6: |I_PL - I| <= h d^2 / 6 (real mu)."""
    mu = MU[:3]
    exact = H**2 / mu - 2 * (1 - np.cos(mu * H)) / mu**3
    for n in (10, 40):
        y = np.linspace(0.0, H, n + 1)
        error = np.abs(SampledShapes(y, y**2).moments(mu)[:, 0] - exact)
        assert np.all(error <= H * (H / n) ** 2 / 6 * (1 + 1e-12))
    smooth = SmoothShapes.from_function(lambda y: y**2, H).moments(mu)[:, 0]
    assert np.all(np.abs(smooth - exact) <= 1e3 * EPS * H**3)


def test_moments_near_the_rigid_wavenumbers_match_direct_quadrature():
    """The Taylor path (absorbing bottom) against direct evaluation at the same complex wavenumbers."""
    shapes = dam_modes()
    lam = (2 * np.arange(1, 41) - 1) * np.pi / (2 * H)
    delta = np.random.default_rng(3).uniform(-1, 1, (5, lam.size)) * 1.5 / H * (1 + 1j) / np.arange(1, 41)
    direct = shapes.moments(lam[None, :] + delta)
    near = shapes.moments_near(lam, delta)
    assert np.abs(near - direct).max() <= 1e-12 * np.abs(direct).max()


# ----------------------------------------------------------------------------------------------
# inputs
# ----------------------------------------------------------------------------------------------
def test_shape_inputs_agree_and_bad_inputs_are_refused():
    y = np.linspace(0.0, H, 3)
    by_tuple = pressure(SEED_EXAMPLE, (y, 1 + y / H), 20.0, y).value
    by_callable = pressure(SEED_EXAMPLE, lambda z: 1 + z / H, 20.0, y).value
    assert np.abs(by_tuple - by_callable).max() <= 1e-8 * RHO * H  # both within rtol = 1e-8 of the truth
    pair = [lambda z: np.ones_like(z), lambda z: z / H]
    listed = added_mass(SEED_EXAMPLE, pair, 20.0).value
    stacked = added_mass(SEED_EXAMPLE, lambda z: np.column_stack([np.ones_like(z), z / H]), 20.0).value
    assert np.array_equal(listed, stacked)
    sampled = added_mass(SEED_EXAMPLE, [SampledShapes(y, np.ones(3)), SampledShapes(y, y / H)], 20.0).value
    assert np.abs(sampled - stacked).max() <= 2e-8 * RHO * H**2
    with pytest.raises(ValueError, match="reservoir is 100.0 m deep"):
        pressure(SEED_EXAMPLE, uniform(50.0), 20.0, y)
    with pytest.raises(ValueError, match="one shape"):
        pressure(SEED_EXAMPLE, dam_modes(), 20.0, y)
    with pytest.raises(ValueError, match="0 <= y"):
        pressure(SEED_EXAMPLE, UNIFORM, 20.0, [H + 1.0])
    with pytest.raises(ValueError, match="reflection"):
        Reservoir(RHO, H, C, reflection=1.5)
    with pytest.raises(ValueError, match="compressible"):
        Reservoir(RHO, H, reflection=0.5)

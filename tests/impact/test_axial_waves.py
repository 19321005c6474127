"""V6 and V7: rigid mass on a free or clamped elastic bar (thesis sec. 4.4-4.7).

References: the thesis's own closed forms and printed numbers (eqs. 4.9-4.47), the digest's
independent [check] values, and a characteristic-grid solver written for these tests
(``wave_grid_oracle``), a different discretisation from the closed-form recursion under test.
"""

import numpy as np
import pytest
from scipy.integrate import simpson
from wave_grid_oracle import grid_impact

from viz3d.contact.exact import clamped_bar_rigid_mass, rigid_mass_on_bar, saint_venant_free_bar

# Standard data set of the thesis (digest sec. 2): steel bar 0.3 m, 3 cm x 3 cm, impactor of equal mass.
E, RHO, A, L, M1, V = 210e9, 7900.0, 9e-4, 0.3, 2.133, 1.0
C = np.sqrt(E / RHO)
IMPEDANCE = A * np.sqrt(E * RHO)
T = 2.0 * L / C
BETA_STD = RHO * A * L / M1

#: Half a unit of the last printed digit of a thesis number (3 decimals).
THESIS_3_DECIMALS = 5e-4
#: Half a unit of the last digit of the digest's 4-decimal [check] values.
CHECK_4_DECIMALS = 5e-5
#: The digest's 4-decimal beta = 0.1 values differ from ours, and from the grid oracle, by 6-7e-5
#: (ours 4.77053 T, -0.94913, -0.96984; digest 4.7706 T, -0.9492, -0.9699); one unit of the last
#: digit is allowed for them (the 3-decimal ones pass at half a unit anyway).
CHECK_BETA_01_TOL = 1e-4
#: Closed form against closed form: rounding (exponentials and polynomial roots of degree <= 3).
EXACT_RTOL = 1e-10
#: Oracle with 20000 steps per T: event times within two steps, velocities within 1e-6 (measured
#: convergence: 4e-9 at 8000 steps).
ORACLE_STEPS = 20_000
ORACLE_TIME_TOL = 2.0 / ORACLE_STEPS
ORACLE_VELOCITY_TOL = 1e-6
#: Simpson's rule on 2001 points of a smooth exp-polynomial piece.
SIMPSON_RTOL = 1e-9


def _clamped(beta=BETA_STD, t=(0.0,)):
    return clamped_bar_rigid_mass(beta, V, C, L, np.asarray(t, dtype=float), IMPEDANCE)


def _integral_of_force(beta, a, b, n=2001):
    """Impulse on ``(a, b)`` [N s], Simpson on a grid inside one smooth piece."""
    t = np.linspace(a, b, n)
    t[0], t[-1] = a + 1e-13 * T, b - 1e-13 * T  # stay on the side of the jump that belongs to the piece
    return simpson(_clamped(beta, t).force, x=t)


# --- V6: free bar ------------------------------------------------------------------------------------


def test_saint_venant_beta_1_numbers():
    """Digest V6 [check]: v1+ = 0.1353 v, v2+ = 0.8647 v, e = 0.7293, t_MC = 0.3466 T."""
    sv = saint_venant_free_bar(1.0, V, C, L, IMPEDANCE)
    assert sv.v1_plus == pytest.approx(0.1353 * V, abs=CHECK_4_DECIMALS)
    assert sv.v2_plus == pytest.approx(0.8647 * V, abs=CHECK_4_DECIMALS)
    assert sv.restitution == pytest.approx(0.7293, abs=CHECK_4_DECIMALS)
    assert sv.time_max_compression / T == pytest.approx(0.3466, abs=CHECK_4_DECIMALS)
    assert sv.separation_time == pytest.approx(T, rel=1e-15)


@pytest.mark.parametrize("beta", [0.25, 1.0, 4.0])
def test_recursion_with_a_free_far_end_is_saint_venant(beta):
    """The d'Alembert recursion (free far end) against eqs. 4.9-4.16: one contact, abrupt at T."""
    sv = saint_venant_free_bar(beta, V, C, L, IMPEDANCE)
    t = np.linspace(0.0, 4.0 * T, 4001)
    r = rigid_mass_on_bar(beta, V, C, L, t, IMPEDANCE, far_end="free")
    assert len(r.contact_intervals) == 1 and r.contact_intervals[0][0] == 0.0
    assert r.contact_intervals[0][1] == pytest.approx(T, rel=EXACT_RTOL)
    assert r.final_velocity == pytest.approx(sv.v1_plus, rel=EXACT_RTOL)
    inside = (t > 0) & (t < T)
    np.testing.assert_allclose(r.force[inside], sv.force(t[inside]), rtol=EXACT_RTOL)
    assert np.all(r.force[t > T] == 0.0)
    bar_velocity = (V - r.final_velocity) / beta  # momentum: m1 (v - v1+) = m2 v2+
    assert bar_velocity == pytest.approx(sv.v2_plus, rel=EXACT_RTOL)
    assert sv.restitution == pytest.approx((sv.v2_plus - sv.v1_plus) / V, rel=EXACT_RTOL)


@pytest.mark.parametrize("beta", [0.25, 1.0, 4.0])
def test_saint_venant_restitution_is_the_impulse_ratio(beta):
    """e_D of eq. 4.39: impulse after the common-velocity instant over the impulse before it."""
    sv = saint_venant_free_bar(beta, V, C, L, IMPEDANCE)
    before = simpson(sv.force(t := np.linspace(1e-15, sv.time_max_compression, 4001)), x=t)
    after = simpson(sv.force(t := np.linspace(sv.time_max_compression, T * (1 - 1e-15), 4001)), x=t)
    assert after / before == pytest.approx(sv.restitution, rel=SIMPSON_RTOL)
    m1 = IMPEDANCE * T / (2.0 * beta)  # the impactor mass that makes this beta
    assert before == pytest.approx(m1 * (V - V / (1.0 + beta)), rel=SIMPSON_RTOL)  # eq. 4.38: v1(t_MC) = v/(1+beta)


# --- V7: clamped bar -----------------------------------------------------------------------------------


def test_clamped_bar_matches_the_thesis_numbers():
    """Thesis eqs. 4.25, 4.26, 4.31, 4.35-4.37, 4.41 and the digest's peak (2 + e^-2) A sqrt(E rho) v."""
    r = _clamped()
    (t0, t1), (t2, t3) = r.contact_intervals
    assert t0 == 0.0 and t1 / T == pytest.approx(1.534, abs=THESIS_3_DECIMALS)
    assert r.separation_velocities[0] / V == pytest.approx(-0.688, abs=THESIS_3_DECIMALS)
    assert t2 / T == pytest.approx(2.125, abs=THESIS_3_DECIMALS)
    assert t3 / T == pytest.approx(2.163, abs=THESIS_3_DECIMALS)
    # eq. 4.36 prints t_c2 = 0.037 T, but its own 2.163 - 2.125 is 0.038 T (exact 0.0382 T): erratum
    assert (t3 - t2) / T == pytest.approx(2.1628 - 2.1246, abs=2 * CHECK_4_DECIMALS)
    assert r.final_velocity / V == pytest.approx(-0.698, abs=0.001)
    assert r.final_velocity / V == pytest.approx(-0.6989, abs=0.001)
    assert r.velocity_zero_time / T == pytest.approx(1.034, abs=THESIS_3_DECIMALS)
    assert r.peak_force == pytest.approx((2.0 + np.exp(-2.0 * BETA_STD)) * IMPEDANCE * V, rel=EXACT_RTOL)
    assert r.peak_force_time == pytest.approx(T, rel=EXACT_RTOL)
    assert r.peak_force == pytest.approx(78.3e3, abs=50.0)


def test_clamped_bar_matches_the_digest_check_values():
    """Digest Appendix B, exact recursion: 1.5338 T, -0.6876, 2.1246 T, 2.1628 T, -0.6989, 78 277 N, 1.0338 T."""
    r = _clamped()
    (_, t1), (t2, t3) = r.contact_intervals
    assert (t1 / T, t2 / T, t3 / T) == pytest.approx((1.5338, 2.1246, 2.1628), abs=CHECK_4_DECIMALS)
    assert np.array(r.separation_velocities) / V == pytest.approx((-0.6876, -0.6989), abs=CHECK_4_DECIMALS)
    assert r.peak_force == pytest.approx(78_277.0, abs=0.5)
    assert r.velocity_zero_time / T == pytest.approx(1.0338, abs=CHECK_4_DECIMALS)
    # stress at the start of the 2nd contact: digest 0.305 (the thesis's 0.299, eq. 4.34, is not reproduced)
    assert r.onset_forces[1] / (IMPEDANCE * V) == pytest.approx(0.305, abs=THESIS_3_DECIMALS)


B01 = CHECK_BETA_01_TOL


@pytest.mark.parametrize(
    ("beta", "events", "velocities"),
    [
        (0.1, [(4.7706, B01), (5.057, THESIS_3_DECIMALS), (5.258, THESIS_3_DECIMALS)], [(-0.9492, B01), (-0.9699, B01)]),
        (0.5, [(2.354, THESIS_3_DECIMALS)], [(-0.925, THESIS_3_DECIMALS)]),
        (2.0, [(1.252, THESIS_3_DECIMALS)], [(-0.729, THESIS_3_DECIMALS)]),
    ],
)
def test_clamped_bar_other_mass_ratios_match_the_digest(beta, events, velocities):
    """Digest Appendix B: separation, recontact and final separation times [T] and velocities [v]."""
    r = _clamped(beta)
    (_, first), *later = r.contact_intervals
    times = [first, *[x for interval in later for x in interval]]
    assert len(times) == len(events) and len(r.separation_velocities) == len(velocities)
    for ours, (ref, tol) in zip(np.array(times) / T, events):
        assert ours == pytest.approx(ref, abs=tol)
    for ours, (ref, tol) in zip(np.array(r.separation_velocities) / V, velocities):
        assert ours == pytest.approx(ref, abs=tol)


def test_beta_01_peak_force_ratio():
    """Digest: F_max = 4.07 A sqrt(E rho) v for beta = 0.1."""
    assert _clamped(0.1).peak_force / (IMPEDANCE * V) == pytest.approx(4.07, abs=0.005)


@pytest.mark.parametrize("beta", [0.1, 1.0, 2.0])
def test_clamped_bar_against_the_characteristic_grid(beta):
    r = _clamped(beta)
    events, v_final = grid_impact(beta, ORACLE_STEPS, r.contact_intervals[-1][1] / T + 0.5)
    ours = [r.contact_intervals[0][1]] + [x for a, b in r.contact_intervals[1:] for x in (a, b)]
    assert len(events) == len(ours), events
    for (kind, t_grid, _), t_ours in zip(events, ours):
        assert t_grid == pytest.approx(t_ours / T, abs=ORACLE_TIME_TOL), kind
    assert v_final == pytest.approx(r.final_velocity / V, abs=ORACLE_VELOCITY_TOL)
    seps = [vel for kind, _, vel in events if kind == "separation"]
    assert seps == pytest.approx(np.array(r.separation_velocities) / V, abs=ORACLE_VELOCITY_TOL)


def test_first_contact_force_is_eqs_4_12_4_23_and_4_27():
    """F = A s0 on (0, T); F = A [s1(t) + s0(t - T)] on (T, t_c), s1 from (4.23)."""
    b = 0.7  # any beta with a single first contact longer than T
    r = _clamped(b)
    t = np.linspace(0.0, r.contact_intervals[0][1], 3001)[1:-1]
    t = t[np.abs(t - T) > 1e-9 * T]
    x = t / T

    def s0(x):
        return np.where(x > 0, np.exp(-2 * b * x), 0.0)

    s1 = s0(x) + np.exp(-2 * b * (x - 1)) * (1 + 4 * b * (1 - x))
    thesis = IMPEDANCE * V * np.where(x < 1, s0(x), s1 + s0(x - 1))
    np.testing.assert_allclose(_clamped(b, t).force, thesis, rtol=EXACT_RTOL)


def test_second_contact_outgoing_wave_is_eq_4_33():
    """s2 = 436.785 s0 e^{-2 beta t/T} (t/T - 2.979)(t/T - 2.089), recovered from the force and (4.23)."""
    r = _clamped()
    a, b = r.contact_intervals[1]
    t = np.linspace(a, b, 41)[1:-1]
    x = t / T
    s1_delayed = np.exp(-2 * (x - 1)) + np.exp(-2 * (x - 2)) * (1 + 4 * (2 - x))  # s1(t - T), beta = 1
    s2 = _clamped(1.0, t).force / (IMPEDANCE * V) - s1_delayed
    coef = np.polyfit(x, s2 * np.exp(2 * x), 2)
    assert coef[0] == pytest.approx(436.785, abs=THESIS_3_DECIMALS)
    assert sorted(np.roots(coef).real) == pytest.approx([2.089, 2.979], abs=THESIS_3_DECIMALS)


def test_model_b_restitution_is_the_impulse_ratio():
    """Eqs. 4.41-4.43: e_D = impulse after the impactor stops / impulse before = -v1(t_c)/v = 0.688."""
    r = _clamped()
    t_mc, t_c = r.velocity_zero_time, r.contact_intervals[0][1]
    before = _integral_of_force(BETA_STD, 0.0, T) + _integral_of_force(BETA_STD, T, t_mc)
    after = _integral_of_force(BETA_STD, t_mc, t_c)
    assert before == pytest.approx(M1 * V, rel=SIMPSON_RTOL)
    assert after / before == pytest.approx(-r.separation_velocities[0] / V, rel=SIMPSON_RTOL)
    assert after / before == pytest.approx(0.688, abs=THESIS_3_DECIMALS)


def test_separation_is_gentle_and_the_last_one_final():
    """Local restitution 0 at each separation (eq. 4.47); after the last one the gap never closes."""
    r0 = _clamped()
    t_sep = np.array([b for _, b in r0.contact_intervals])
    at = _clamped(BETA_STD, t_sep * (1 - 1e-12))
    np.testing.assert_allclose(at.end_velocity, at.velocity, atol=1e-9 * V)
    t = np.linspace(t_sep[-1] * (1 + 1e-6), 20 * T, 20001)
    after = _clamped(BETA_STD, t)
    assert np.all(after.impactor_displacement < after.end_displacement)
    assert np.all(after.velocity == r0.final_velocity) and np.all(after.force == 0.0)


def test_history_is_consistent():
    """No tension; displacements agree in contact, the impactor leads out of it; momentum balance."""
    t = np.linspace(0.0, 3.0 * T, 30001)
    r = _clamped(BETA_STD, t)
    assert np.all(r.force >= 0.0) and np.all(r.force[~r.in_contact] == 0.0)
    np.testing.assert_allclose(r.impactor_displacement[r.in_contact], r.end_displacement[r.in_contact], atol=1e-12 * V * T)
    np.testing.assert_allclose(r.velocity[r.in_contact], r.end_velocity[r.in_contact], atol=1e-12 * V)
    (a1, b1), (a2, b2) = r.contact_intervals
    second = _integral_of_force(BETA_STD, a2, b2)
    assert M1 * (r.separation_velocities[0] - r.final_velocity) == pytest.approx(second, rel=SIMPSON_RTOL)

"""V1-V5: rigid-body restitution, Hertz and structural quasi-static impacts, bar-on-bar waves.

References: the thesis's formulas in their own (beta) form, re-typed here; Euler's Beta function;
scipy's ODE solver; and the digest's numbers for the standard bar.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import beta as beta_function

from viz3d.contact.laws import Hertz
from viz3d.contact.single_impact import achieved_restitution
from viz3d.contact.exact import (
    bar_bar_impact,
    goldsmith_hertz_approximation,
    hertz_impact,
    pendulum_equivalent_mass,
    quasi_static_bar_impact,
    quasi_static_equal_bars,
    rigid_central_impact,
)

E, RHO, A, L, M1, V = 210e9, 7900.0, 9e-4, 0.3, 2.133, 1.0
M2 = RHO * A * L
C = np.sqrt(E / RHO)
T = 2.0 * L / C
IMPEDANCE = A * np.sqrt(E * RHO)

#: V1: machine precision (digest: <= 1e-12 relative).
MACHINE_RTOL = 1e-12
#: Half a unit of the last printed digit.
HALF_UNIT_4 = 5e-5
HALF_UNIT_3 = 5e-4
#: DOP853 at rtol 1e-12 as the independent reference for the Hertz impact.
ODE_RTOL = 1e-8


# --- V1 ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("beta", [0.25, 1.0, 4.0])
@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_rigid_impact_is_eqs_3_9_to_3_11(beta, e):
    m1, v = 1.7, 2.3
    r = rigid_central_impact(m1, beta * m1, v, e)
    assert r.v2_plus == pytest.approx((1 + e) / (1 + beta) * v, rel=MACHINE_RTOL, abs=0)
    assert r.v1_plus == pytest.approx((1 - e * beta) / (1 + beta) * v, rel=MACHINE_RTOL, abs=MACHINE_RTOL * v)
    loss = 0.5 * m1 * v**2 * beta / (1 + beta) * (1 - e**2)
    assert r.energy_lost == pytest.approx(loss, rel=MACHINE_RTOL, abs=MACHINE_RTOL * m1 * v**2)
    assert r.impulse_restitution == pytest.approx(e * r.impulse_compression, rel=MACHINE_RTOL, abs=0.0)
    assert m1 * r.v1_plus + beta * m1 * r.v2_plus == pytest.approx(m1 * v, rel=MACHINE_RTOL, abs=0)
    assert r.v2_plus - r.v1_plus == pytest.approx(e * v, rel=MACHINE_RTOL, abs=MACHINE_RTOL * v)


def test_rigid_pendulum_is_a_free_mass_I_over_Lp_squared():
    """Eqs. 9.2-9.4: omega+ = (I0 - e m2 Lp^2) / (I0 + m2 Lp^2) omega-."""
    I0, Lp, m2, omega, e = 0.12, 0.19, 4.0, -10.6, 0.6
    r = rigid_central_impact(pendulum_equivalent_mass(I0, Lp), m2, Lp * omega, e)
    assert r.v1_plus / Lp == pytest.approx((I0 - e * m2 * Lp**2) / (I0 + m2 * Lp**2) * omega, rel=MACHINE_RTOL, abs=0)
    assert r.v2_plus == pytest.approx(I0 * (1 + e) / (I0 + m2 * Lp**2) * Lp * omega, rel=MACHINE_RTOL, abs=0)


# --- V2 ------------------------------------------------------------------------------------------------


def test_hertz_contact_time_factor_is_2_9433():
    """Digest V2: t_c = 2.9433 alpha_MC / v from the quadrature; Goldsmith's pi/1.068 = 2.9416."""
    h = hertz_impact(1e10, 1.0, 2.0, 1.0)
    assert h.time_factor == pytest.approx(2.9433, abs=HALF_UNIT_4)
    assert h.time_factor == pytest.approx(0.8 * beta_function(0.4, 0.5), rel=1e-12)  # 2 * (2/5) B(2/5, 1/2)
    _, t_goldsmith = goldsmith_hertz_approximation(1.0, 2.0, 1.0, h.alpha_max)
    assert t_goldsmith * h.v / h.alpha_max == pytest.approx(2.9416, abs=HALF_UNIT_4)


def test_hertz_impact_against_direct_integration():
    """alpha_MC (3.33), F_max and t_c against DOP853 of alpha'' = -r alpha^1.5 (3.31), two unequal spheres."""
    K_h, m1, m2, v = 3.2e9, 0.11, 0.45, 2.03
    h = hertz_impact(K_h, m1, m2, v)
    r = K_h * (m1 + m2) / (m1 * m2)

    def rhs(t, y):
        return [y[1], -r * max(y[0], 0.0) ** 1.5]

    def leave(t, y):
        return y[0]

    leave.terminal, leave.direction = True, -1
    sol = solve_ivp(rhs, (0, 1.0), [0.0, v], method="DOP853", rtol=1e-12, atol=1e-16, events=leave, dense_output=True)
    t = np.linspace(0.0, sol.t_events[0][0], 2001)
    alpha = sol.sol(t)[0]
    assert h.alpha_max == pytest.approx(((1.25 * v**2) / r) ** 0.4, rel=MACHINE_RTOL, abs=0)
    assert h.alpha_max == pytest.approx(alpha.max(), rel=ODE_RTOL, abs=0)
    assert h.contact_time == pytest.approx(sol.t_events[0][0], rel=ODE_RTOL, abs=0)
    assert h.force_max == pytest.approx(K_h * alpha.max() ** 1.5, rel=ODE_RTOL, abs=0)
    np.testing.assert_allclose(h.history(t)[0], alpha, rtol=1e-6, atol=1e-9 * h.alpha_max)
    assert -sol.y_events[0][0][1] == pytest.approx(v, rel=ODE_RTOL, abs=0)  # e = 1


def test_hertz_impact_agrees_with_the_contact_law_module():
    """The same impact through ``viz3d.contact`` (Hertz law, 1-DOF integration)."""
    K_h, m1, m2, v = 3.2e9, 0.11, 0.45, 2.03
    h = hertz_impact(K_h, m1, m2, v)
    out = achieved_restitution(Hertz(K_h), h.mu, v)
    assert out.duration == pytest.approx(h.contact_time, rel=ODE_RTOL, abs=0)
    assert out.peak_force == pytest.approx(h.force_max, rel=ODE_RTOL, abs=0)
    assert out.peak_indentation == pytest.approx(h.alpha_max, rel=ODE_RTOL, abs=0)


def test_goldsmith_amplitude_needs_m1_plus_m2():
    """(3.34) prints 1.14 v^2 m2 m1 / ((m2 - m1) alpha_MC); F = mu alpha'' and 1.068^2 = 1.14 give (m1 + m2)."""
    m1, m2, v, a = 0.3, 0.7, 1.5, 2e-5
    amplitude, _ = goldsmith_hertz_approximation(m1, m2, v, a)
    assert amplitude == pytest.approx(1.14 * v**2 * m1 * m2 / ((m1 + m2) * a), rel=0.001)  # 1.068^2 = 1.1406


# --- V3 ------------------------------------------------------------------------------------------------


def test_quasi_static_structural_standard_bar():
    """Digest V3/N6 [check]: F_max = A sqrt(E rho) v = 36.66 kN, t_c = 1.571 T for beta = 1; 4.97 T for beta = 0.1."""
    q = quasi_static_bar_impact(M1, E, A, L, V)
    assert q.force_max / 1e3 == pytest.approx(36.66, abs=0.005)
    assert q.contact_time / T == pytest.approx(1.571, abs=HALF_UNIT_3)
    assert q.x_max == pytest.approx(np.sqrt(M1 * L / (E * A)) * V, rel=MACHINE_RTOL, abs=0)
    assert q.time_max_compression == pytest.approx(0.5 * q.contact_time, rel=MACHINE_RTOL, abs=0)
    assert q.v_out == -V
    assert quasi_static_bar_impact(10 * M2, E, A, L, V).contact_time / T == pytest.approx(4.97, abs=0.005)


@pytest.mark.parametrize("beta", [0.1, 1.0, 3.0])
def test_bar_mass_reduces_the_force_by_kappa(beta):
    """Eq. 3.20: with the bar's mass, force and deflection times kappa = 1/sqrt(1 + beta/3), t_c / kappa."""
    m2 = beta * M1
    rigid, heavy = quasi_static_bar_impact(M1, E, A, L, V), quasi_static_bar_impact(M1, E, A, L, V, m2=m2)
    kappa = 1.0 / np.sqrt(1.0 + beta / 3.0)
    assert heavy.kappa == pytest.approx(kappa, rel=MACHINE_RTOL, abs=0)
    assert heavy.force_max == pytest.approx(kappa * rigid.force_max, rel=MACHINE_RTOL, abs=0)
    assert heavy.x_max == pytest.approx(kappa * rigid.x_max, rel=MACHINE_RTOL, abs=0)
    assert heavy.contact_time == pytest.approx(rigid.contact_time / kappa, rel=MACHINE_RTOL, abs=0)


# --- V4 / V5 -------------------------------------------------------------------------------------------


def test_equal_bars():
    """Constant force A v sqrt(E rho) for 2L/c; impulse = each bar's momentum change 2 m v; reversed velocities."""
    r = bar_bar_impact(E, RHO, A, L, L, V, -V)
    assert r.contact_force == pytest.approx(IMPEDANCE * V, rel=MACHINE_RTOL, abs=0)
    assert r.contact_time == pytest.approx(T, rel=MACHINE_RTOL, abs=0)
    assert r.stress == pytest.approx(V * np.sqrt(E * RHO), rel=MACHINE_RTOL, abs=0)
    assert r.contact_force * r.contact_time == pytest.approx(2 * M2 * V, rel=MACHINE_RTOL, abs=0)
    assert (r.v1_plus, r.v2_plus) == pytest.approx((-V, V), rel=MACHINE_RTOL, abs=0)


def test_quasi_static_equal_bars_contact_time_ratio():
    """Digest Appendix A item 2: model (3.21) gives 0.99 of 2L/c (the thesis's 1.82 is not reproduced)."""
    q = quasi_static_equal_bars(M2, E, A, L, V)
    assert q.contact_time / T == pytest.approx(0.99, abs=0.005)


def test_unequal_bars_l2_equal_3_5_l1():
    """Eqs. 4.4-4.7, Fig. 4.8: section x = 2 l1 of bar 2 sees a two-level square wave of period 2 l2 / c."""
    l1, l2, v1, v2 = 0.2, 0.7, 1.3, 0.2
    m1, m2 = RHO * A * l1, RHO * A * l2
    r = bar_bar_impact(E, RHO, A, l1, l2, v1, v2)
    assert r.contact_time == pytest.approx(2 * l1 / C, rel=MACHINE_RTOL, abs=0)
    assert r.stress == pytest.approx(0.5 * (v1 - v2) * np.sqrt(E * RHO), rel=MACHINE_RTOL, abs=0)
    assert m1 * r.v1_plus + m2 * r.v2_plus == pytest.approx(m1 * v1 + m2 * v2, rel=MACHINE_RTOL, abs=0)
    assert r.contact_force * r.contact_time == pytest.approx(m1 * (v1 - r.v1_plus), rel=MACHINE_RTOL, abs=0)
    period, n_periods, n = r.vibration_period, 40, 400_000
    t = r.contact_time + np.arange(n) * (n_periods * period / n)
    u = r.section_velocity(2 * l1, t)
    assert set(np.unique(u)) == {v2, r.v_interface}
    np.testing.assert_array_equal(r.section_velocity(2 * l1, t[:10_000] + period), u[:10_000])
    # time average = centre-of-mass velocity; a grid mean misplaces each of the 4 jumps per period by < dt
    dt_bound = 4 * n_periods * (n_periods * period / n) * (r.v_interface - v2) / (n_periods * period)
    assert u.mean() == pytest.approx(r.v2_plus, abs=dt_bound)

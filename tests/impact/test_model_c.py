"""V10: event-driven "model C" (free mass on a mass-spring) with a constant restitution (thesis sec. 4.6).

References: the thesis's Fig. 4.20 numbers (2 digits) and the digest's reproduction (Appendix B, 3 digits).
"""

import numpy as np
import pytest

from viz3d.contact.exact import model_c_impacts

E, RHO, A, L, M1, V = 210e9, 7900.0, 9e-4, 0.3, 2.133, 1.0
M_EQ = RHO * A * L / 3.0  # the bar's mass lumped by the static deformed shape
K = E * A / L

#: Thesis values carry 2 digits (velocities in m/s, losses in %): half a unit.
THESIS_VELOCITY_TOL = 0.005
THESIS_LOSS_TOL = 0.005
#: Digest reproduction, 3 digits (velocities) and 0.1 % (losses): half a unit.
CHECK_VELOCITY_TOL = 5e-4
CHECK_LOSS_TOL = 5e-4


@pytest.mark.parametrize(
    ("e", "n_balances", "thesis_v", "thesis_loss", "check_v", "check_loss"),
    [
        (1.0, 3, -0.89, 0.0, -0.891, 0.0),
        (0.9, 3, -0.67, 0.20, -0.674, 0.200),
        (0.8, 4, -0.74, 0.35, -0.739, 0.353),
        (0.688, 7, None, None, -0.662, 0.424),
    ],
)
def test_model_c_balances(e, n_balances, thesis_v, thesis_loss, check_v, check_loss):
    r = model_c_impacts(M1, M_EQ, K, V, e)
    assert r.n_balances == n_balances
    if thesis_v is not None:
        assert r.final_velocity == pytest.approx(thesis_v, abs=THESIS_VELOCITY_TOL)
        assert r.energy_lost_fraction == pytest.approx(thesis_loss, abs=THESIS_LOSS_TOL)
    assert r.final_velocity == pytest.approx(check_v, abs=CHECK_VELOCITY_TOL)
    assert r.energy_lost_fraction == pytest.approx(check_loss, abs=CHECK_LOSS_TOL)


def test_first_balance_with_e_1_is_eq_4_44():
    r = model_c_impacts(M1, M_EQ, K, V, 1.0)
    assert r.velocities[0] == pytest.approx((0.5 * V, 1.5 * V), rel=1e-12)


@pytest.mark.parametrize("e", [1.0, 0.9, 0.8, 0.688])
def test_energy_ledger(e):
    """Initial energy = free mass + oscillator after the last balance + the sum of balance losses."""
    r = model_c_impacts(M1, M_EQ, K, V, e)
    final = 0.5 * M1 * r.final_velocity**2 + r.oscillator_energy + r.energy_lost
    assert final == pytest.approx(0.5 * M1 * V**2, rel=1e-12)


def test_rebound_is_not_monotonic_in_e():
    """The thesis's point: |v1+| for e = 0.9 is below both e = 1 and e = 0.8."""
    v = {e: abs(model_c_impacts(M1, M_EQ, K, V, e).final_velocity) for e in (1.0, 0.9, 0.8)}
    assert v[0.9] < v[0.8] < v[1.0]


def test_results_do_not_depend_on_the_time_scale():
    """Only the mass ratio and e matter: a 100x stiffer spring changes times, not velocities."""
    soft, stiff = model_c_impacts(M1, M_EQ, K, V, 0.8), model_c_impacts(M1, M_EQ, 100 * K, V, 0.8)
    assert stiff.final_velocity == pytest.approx(soft.final_velocity, rel=1e-9)
    np.testing.assert_allclose(np.array(stiff.balance_times) * 10, soft.balance_times, rtol=1e-9, atol=1e-15)

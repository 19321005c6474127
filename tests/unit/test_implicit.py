"""Implicit integrators against closed forms: the trapezoidal rule's stability function, the
generalized-alpha method's spectral radius at infinity (Chung & Hulbert 1993), and failures that
come back as a status, never as NaN."""

import numpy as np
import pytest

from viz3d.integrators import GeneralizedAlpha, Trapezoidal
from viz3d.integrators.implicit import AlphaState

#: Agreement with the closed forms; the Newton iteration stops at an update of 1e-11 of the state.
CLOSED_FORM_RTOL = 1e-9
#: Spectral radius measured at h omega = 1e6 against its limit rho_inf: the three roots meet at
#: -rho_inf (a defective triple root), approached like (h omega)^(-2/3) = 1e-4.
RHO_TOL = 1e-3


class Field:
    """A plain vector field with the ``n_q`` split integrators read."""

    def __init__(self, fun, n_q):
        self.fun, self.n_q = fun, n_q

    def __call__(self, t, y):
        return self.fun(t, y)


def test_trapezoidal_matches_its_stability_function_on_a_stiff_decay():
    lam, h = -1e6, 0.01
    res = Trapezoidal().step(Field(lambda t, y: lam * y, 0), 0.0, np.array([1.0]), h)
    z = h * lam
    assert res.status.ok
    np.testing.assert_allclose(res.y, [(1 + z / 2) / (1 - z / 2)], rtol=CLOSED_FORM_RTOL)


def test_trapezoidal_keeps_the_energy_of_an_unresolved_oscillator():
    """|R(i h omega)| = 1: at h omega = 100 the amplitude neither grows (as RK4's would) nor decays."""
    omega, h = 1e4, 1e-2
    rhs = Field(lambda t, y: np.array([y[1], -omega**2 * y[0]]), 1)
    y, state, method = np.array([1.0, 0.0]), None, Trapezoidal()
    for k in range(100):
        res = method.step(rhs, k * h, y, h, state=state)
        y, state = res.y, res.state
    # each of the 100 steps is exact to the Newton tolerance (1e-11 of the state): ~1e-9 accumulated; 1e3x
    # the one-step tolerance leaves 1e3 x that. RK4 would have grown the amplitude by |R(100 i)|^100.
    np.testing.assert_allclose(y[0] ** 2 + (y[1] / omega) ** 2, 1.0, rtol=1e3 * CLOSED_FORM_RTOL)


def _amplification_matrix(method, omega, h):
    """One step's linear map (q, v, a) -> (q1, v1, a1) on q'' = -omega^2 q (v_dot consistent with q)."""
    rhs = Field(lambda t, y: np.array([y[1], -omega**2 * y[0]]), 1)
    columns = []
    for q, v, a in np.eye(3):
        res = method.step(rhs, 0.0, np.array([q, v]), h, state=AlphaState(np.array([-omega**2 * q]), np.array([a])))
        assert res.status.ok, res.status.message
        columns.append([res.y[0], res.y[1], res.state.a[0]])
    return np.array(columns).T


@pytest.mark.parametrize("rho_inf", [0.0, 0.5, 0.8, 1.0])
def test_gen_alpha_spectral_radius_is_rho_inf_at_infinity_and_one_at_zero(rho_inf):
    method = GeneralizedAlpha(rho_inf)
    far = np.max(np.abs(np.linalg.eigvals(_amplification_matrix(method, 1e3, 1e3))))       # h omega = 1e6
    near = np.abs(np.linalg.eigvals(_amplification_matrix(method, 1.0, 1e-3)))            # h omega = 1e-3
    assert far == pytest.approx(rho_inf, abs=RHO_TOL)
    assert np.sort(near)[-2:] == pytest.approx([1.0, 1.0], abs=RHO_TOL)   # the two physical roots


def test_newton_failure_comes_back_as_a_status():
    """A vector field that is non-finite away from the start: no NaN state, a message instead."""
    rhs = Field(lambda t, y: np.array([np.nan if t > 0 else -y[0]]), 0)
    for method in (Trapezoidal(), GeneralizedAlpha()):
        two = Field(lambda t, y: np.array([y[1], np.nan if t > 0 else -y[0]]), 1)
        res = method.step(rhs if isinstance(method, Trapezoidal) else two, 0.0,
                          np.array([1.0]) if isinstance(method, Trapezoidal) else np.array([1.0, 0.0]), 0.1)
        assert not res.status.ok
        assert "did not converge" in res.status.message and "sim.dt" in res.status.message
        assert np.all(np.isfinite(res.y))


def test_gen_alpha_needs_positions_and_velocities():
    with pytest.raises(ValueError, match="q_dot = v"):
        GeneralizedAlpha().init(Field(lambda t, y: -y, 1), 0.0, np.ones(3))


def test_rho_inf_outside_the_unit_interval_is_refused():
    with pytest.raises(ValueError, match="rho_inf"):
        GeneralizedAlpha(1.5)

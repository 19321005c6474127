"""The dam coupled to its reservoir: natural frequencies, resonance, cut-offs, time response.

References: the finite-element reservoir of helmholtz_fe (added masses of the dam's modes),
scipy's DOP853 integrating the modal equations directly (time response), the Rayleigh-Ritz and
Loewner-order arguments written out in each test.
"""

from __future__ import annotations

from dataclasses import replace

import helmholtz_fe as fe
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import eigh

from viz3d.flexible import Section, analytic_modes
from viz3d.hydro import dam as D
from viz3d.hydro.records import GroundMotion
from viz3d.hydro.reservoir import SEED_EXAMPLE, Reservoir

RHO, H, C = 1000.0, 100.0, 1493.0
INCOMPRESSIBLE = Reservoir(RHO, H)
ABSORBING = Reservoir(RHO, H, C, reflection=0.5)
DAM = D.cantilever_dam()
#: Integrator tolerances of the reference time integration (global error ~1e-8 of the peak, three
#: orders below the FFT's designed wrap-around), and a two-mode dam to keep it quick.
ODE_RTOL, ODE_ATOL = 1e-10, 1e-13
DAM_2 = D.cantilever_dam(n_modes=2)


def test_example_dam_is_below_the_first_cutoff():
    assert DAM.omega[0] < SEED_EXAMPLE.cutoff_frequencies(1)[0]


def test_fundamental_frequency_drops_with_water():
    """Chopra: water lowers the dam's fundamental frequency; compressible water, whose added mass grows
    towards the first cut-off, lowers it further (A_c(omega) - A_inc is positive semi-definite below
    omega_1: sum_n (2 rho / h) (I_n . q)^2 (1/kappa_n - 1/lambda_n) >= 0, and the Rayleigh quotient is
    monotone in the mass)."""
    empty, water, compressible = (D.fundamental_frequency(DAM, r) for r in (None, INCOMPRESSIBLE, SEED_EXAMPLE))
    assert compressible < water < empty
    for omega in (5.0, 15.0, 23.0):
        A_c = D.hydrodynamic_terms(DAM, SEED_EXAMPLE, omega)[0][0]
        A_i = D.hydrodynamic_terms(DAM, INCOMPRESSIBLE, omega)[0][0]
        assert np.all(A_c.imag == 0.0)
        assert np.linalg.eigvalsh((A_c - A_i).real).min() >= -1e-8 * np.abs(A_i).max()


def test_incompressible_fundamental_frequency_matches_finite_elements():
    """Added-mass matrix of the modes from the FE reservoir (omega = 0, Laplace) on two grids; the
    series' natural frequency must lie within the grids' difference of the fine one (margin 3 over
    Richardson's estimate) and the coarse grid must be farther."""
    phi = DAM.bar.displacement

    def fe_frequency(n_y):
        A = np.zeros((DAM.n_modes, DAM.n_modes))
        for j in range(DAM.n_modes):
            y, p = fe.solve(RHO, H, np.inf, 0.0, lambda z: phi(z)[:, j], n_y=n_y)
            A[:, j] = np.trapezoid(phi(y) * p.real[:, None], y, axis=0)
        A = 0.5 * (A + A.T) * DAM.width
        return float(np.sqrt(eigh(DAM.bar.K, np.eye(DAM.n_modes) + A, eigvals_only=True)[0]))

    coarse, fine = fe_frequency(20), fe_frequency(40)
    series = D.fundamental_frequency(DAM, INCOMPRESSIBLE)
    assert abs(series - fine) <= abs(coarse - fine)
    assert abs(series - coarse) >= 2 * abs(series - fine)


def test_ritz_frequencies_decrease_with_more_modes():
    """Rayleigh-Ritz: the coupled fundamental frequency from n modes is an upper bound, decreasing in n."""
    material, section = DAM.bar.material, DAM.bar.section
    values = []
    for n in (1, 2, 3, 5):
        bar = analytic_modes("timoshenko", H, material, section, n, ("clamped", "free"))
        values.append(D.fundamental_frequency(D.Dam(bar), INCOMPRESSIBLE))
    assert np.all(np.diff(values) <= 1e-9 * values[0])
    single = D.hydrodynamic_terms(D.Dam(analytic_modes("timoshenko", H, material, section, 1, ("clamped", "free"))),
                                  INCOMPRESSIBLE, 0.0)[0][0, 0, 0].real
    assert abs(values[0] - DAM.omega[0] / np.sqrt(1 + single)) <= 1e-12 * values[0]


@pytest.mark.parametrize("reservoir", [None, INCOMPRESSIBLE, SEED_EXAMPLE], ids=["empty", "incompressible", "seed"])
def test_undamped_response_is_unbounded_at_the_natural_frequency(reservoir):
    """Near a simple pole H = R / (omega - omega_c) + regular: (omega - omega_c) H -> R, the regular
    part contributing O(delta) relative (delta = 1e-7, 1e-9 of omega_c)."""
    undamped = replace(DAM, damping_ratio=0.0)
    omega_c = D.fundamental_frequency(undamped, reservoir)
    deltas = np.array([1e-7, 1e-9]) * omega_c
    response = D.frequency_response(undamped, reservoir, omega_c + deltas).crest_displacement
    residues = response * deltas
    assert abs(residues[0] - residues[1]) <= 1e-5 * abs(residues[1])
    assert abs(response[1]) > 1e6 * abs(D.frequency_response(undamped, reservoir, 0.0).crest_displacement[0])


def test_flexible_dam_stays_bounded_at_the_cutoff_where_a_rigid_one_does_not():
    """At omega_1 = pi c / 2h the rigid-wall force grows like |omega - omega_1|^-1/2; the flexible dam's
    response tends to one finite value from both sides (the water's singular term is rank one and the
    dam's motion annuls its projection), with a difference of order sqrt(delta)."""
    omega_1 = SEED_EXAMPLE.cutoff_frequencies(1)[0]
    gaps, forces = [], []
    for delta in (1e-4, 1e-8):
        r = D.frequency_response(DAM, SEED_EXAMPLE, omega_1 * np.array([1 - delta, 1 + delta]))
        gaps.append(abs(r.crest_acceleration[0] - r.crest_acceleration[1]))
        forces.append(abs(D.hydrodynamic_terms(DAM, SEED_EXAMPLE, omega_1 * (1 - delta))[2][0]))
    assert gaps[1] <= 2.0 * gaps[0] * np.sqrt(1e-8 / 1e-4)
    assert forces[1] >= 0.5 * forces[0] * np.sqrt(1e-4 / 1e-8)
    at = D.frequency_response(DAM, SEED_EXAMPLE, omega_1).crest_acceleration[0]
    near = D.frequency_response(DAM, SEED_EXAMPLE, omega_1 * (1 + 1e-8)).crest_acceleration[0]
    assert np.isfinite(at) and abs(at - near) <= gaps[1]


# ----------------------------------------------------------------------------------------------
# time response
# ----------------------------------------------------------------------------------------------
def pulse(t, t0=8.0, sigma=0.5, omega_0=12.0):
    """A smooth, band-limited ground acceleration [m/s^2]: its spectrum falls like
    exp(-(sigma (omega - omega_0))^2 / 4), below 1e-150 at the Nyquist frequency of dt = 0.02 s for
    the sigma and omega_0 used here."""
    return np.exp(-(((t - t0) / sigma) ** 2)) * np.cos(omega_0 * t)


def modal_integration(dam, reservoir, t):
    """Crest displacement from (I + A) q'' + C q' + K q = -(L + A_q0) a_g (constant added mass:
    empty or incompressible reservoir) by DOP853."""
    n = dam.n_modes
    if reservoir is None:
        A, B = np.zeros((n, n)), np.zeros(n)
    else:
        A_qq, A_q0, _, _ = D.hydrodynamic_terms(dam, reservoir, 0.0)
        A, B = A_qq[0].real, A_q0[0].real
    M_inv = np.linalg.inv(np.eye(n) + A)
    C = np.diag(2 * dam.damping_ratio * dam.omega)

    def rhs(time, y):
        q, v = y[:n], y[n:]
        return np.concatenate([v, M_inv @ (-(dam.participation + B) * pulse(time) - C @ v - dam.bar.K @ q)])

    sol = solve_ivp(rhs, (t[0], t[-1]), np.zeros(2 * n), method="DOP853", t_eval=t, rtol=ODE_RTOL, atol=ODE_ATOL)
    return dam.bar.displacement([dam.height])[0] @ sol.y[:n]


@pytest.mark.parametrize("reservoir", [None, INCOMPRESSIBLE], ids=["empty", "incompressible"])
def test_fft_time_response_matches_direct_integration(reservoir):
    """Tolerance: the padding leaves a free vibration of at most PAD_DECAY of its starting amplitude to
    wrap around (each mode decays at least as fast as the first); x10 for the sum over modes."""
    dt = 0.02
    t = np.arange(0.0, 20.0, dt)
    record = GroundMotion(dt, pulse(t))
    u = D.time_response(DAM_2, reservoir, record).crest_displacement
    reference = modal_integration(DAM_2, reservoir, t)
    assert np.abs(u - reference).max() <= 10 * D.PAD_DECAY * np.abs(reference).max()


@pytest.mark.parametrize("reservoir", [SEED_EXAMPLE, ABSORBING], ids=["rigid bottom", "alpha 0.5"])
def test_time_response_is_causal_and_free_of_wrap_around(reservoir):
    """A pulse centred on 22 rad/s, next to the first cut-off (23.45 rad/s). Before it arrives
    (t < t0 - 6 sigma, where it is below exp(-36)) the crest is at rest, up to the wrap-around the
    exponential window allows (PAD_DECAY of the peak; x10 for rounding amplified by the window). Over a
    rigid bottom the response then decays only algebraically, and plain zero padding wraps 1.5e-2 of the
    peak into this interval; a radiation condition of the wrong sign would make the water answer before
    it is pushed. Doubling the padding must not change the response by more than the same amount."""
    dt, t0, sigma = 0.02, 8.0, 0.3
    t = np.arange(0.0, 20.0, dt)
    record = GroundMotion(dt, pulse(t, t0, sigma, omega_0=22.0))
    u = D.time_response(DAM, reservoir, record).crest_displacement
    peak = np.abs(u).max()
    assert np.abs(u[t < t0 - 6 * sigma]).max() <= 10 * D.PAD_DECAY * peak
    longer = D.time_response(DAM, reservoir, record, pad=2 * max(D.padding(DAM), record.duration)).crest_displacement
    assert np.abs(u - longer).max() <= 20 * D.PAD_DECAY * peak


def test_dam_inputs_are_checked():
    bar = analytic_modes("timoshenko", H, DAM.bar.material, Section.rectangle(1.0, 40.0), 2, ("clamped", "free"),
                         normalization="unit")
    with pytest.raises(ValueError, match="mass normalised"):
        D.Dam(bar)
    with pytest.raises(ValueError, match="within the dam height"):
        D.frequency_response(D.cantilever_dam(height=80.0), SEED_EXAMPLE, 10.0)
    with pytest.raises(ValueError, match="absorbing bottom"):
        D.fundamental_frequency(DAM, ABSORBING)

"""Exact and closed-form impact solutions of seed 002 (Escalona 2000), as references for the simulator.

Every function computes its result from the inputs (no thesis numbers are stored here). Digest
validation cases: V1 ``rigid_central_impact``; V2 ``hertz_impact``; V3 ``quasi_static_bar_impact``;
V4/V5 ``bar_bar_impact``; V6 ``saint_venant_free_bar``; V7 ``clamped_bar_rigid_mass`` (and
``rigid_mass_on_bar`` for either far end); V10 ``model_c_impacts``.

Axial waves (thesis ch. 4). A bar of length ``L``, wave speed ``c = sqrt(E/rho)``, impedance
``A sqrt(E rho)`` [N s/m], ``T = 2 L / c``; the impactor (mass ``m1``, ``beta = rho A L / m1``) hits the
end ``x = 0`` at speed ``v`` along ``+x``. Compression is positive. At any section the stress is
``s_out(t - x/c) + s_in(t + x/c)``, the waves running away from and towards the impact end, and the
particle velocity is ``(s_out - s_in) / Z``, ``Z = sqrt(E rho)``. The far end reflects
``s_in(t) = r s_out(t - T)``: ``r = +1`` clamped (zero velocity), ``r = -1`` free (zero stress). At the
impact end, in contact the end moves with the impactor, ``m1 V' = -A (Z V + 2 s_in)``; out of contact
the end is stress free, ``s_out = -s_in``. Between breakpoints every stress is
``exp(-2 beta t/T) P(t)`` with ``P`` a polynomial (the thesis's ``s_n``, eq. 4.20-4.23), so each step
of the d'Alembert recursion is closed form; separations are polynomial roots (eq. 4.24) and
recontacts roots of the closed-form gap (eq. 4.31).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.polynomial import Polynomial

from viz3d._typing import FloatArray

#: Times closer than this (in units of T) are the same breakpoint of the wave recursion.
TIME_EPS = 1e-12
#: Slack (in units of v) when comparing the impactor speed with the bar end's mean speed.
SPEED_EPS = 1e-12
#: Reflection of the wave at the far end: s_in(t) = r s_out(t - T).
FAR_END_REFLECTION = {"clamped": 1.0, "free": -1.0}
#: Samples per recursion step when scanning a force or gap function for its first sign change.
N_SCAN = 2001
#: Samples per free-flight period when searching the next model-C balance.
N_SCAN_PERIOD = 4001
#: Give up after this many recursion steps or balances (a run that does not settle is a bug).
MAX_STEPS = 10_000
#: Goldsmith's constant in alpha = alpha_MC sin(1.068 v t / alpha_MC) (thesis eq. 3.34).
GOLDSMITH_FREQUENCY_FACTOR = 1.068


# --- V1: rigid bodies, Newton's restitution (thesis sec. 3.2) ---------------------------------------


@dataclass(frozen=True)
class RigidImpact:
    """Central impact of two rigid bodies.

    Attributes
    ----------
    v1_plus, v2_plus : float
        Velocities after the impact [m/s].
    v_common : float
        Common velocity at maximum compression, ``v_bar`` [m/s].
    impulse_compression, impulse_restitution : float
        ``I_C`` and ``I_E = e I_C`` on body 2 [N s].
    energy_lost : float
        ``T- - T+`` [J].
    """

    v1_plus: float
    v2_plus: float
    v_common: float
    impulse_compression: float
    impulse_restitution: float
    energy_lost: float


def rigid_central_impact(m1: float, m2: float, v1: float, e: float, v2: float = 0.0) -> RigidImpact:
    """Newton/Poisson impact of ``m1`` at ``v1`` on ``m2`` at ``v2`` (thesis eqs. 3.5-3.11).

    Parameters
    ----------
    m1, m2 : float
        Masses [kg]; ``m2 = inf`` is a fixed wall.
    v1, v2 : float
        Velocities before, along the line of centres, ``v1 > v2`` [m/s].
    e : float
        Coefficient of restitution in [0, 1].
    """
    mu = 1.0 / (1.0 / m1 + 1.0 / m2)
    I_C = mu * (v1 - v2)
    v_bar = v1 - I_C / m1
    return RigidImpact(
        v1_plus=v1 - (1.0 + e) * I_C / m1,
        v2_plus=v2 + (1.0 + e) * I_C / m2,
        v_common=v_bar,
        impulse_compression=I_C,
        impulse_restitution=e * I_C,
        energy_lost=0.5 * mu * (1.0 - e**2) * (v1 - v2) ** 2,
    )


def pendulum_equivalent_mass(I_O: float, L_p: float) -> float:
    """Free mass equivalent to a rigid pendulum struck at distance ``L_p`` from its pivot, ``I_O / L_p^2`` (eq. 9.4)."""
    return I_O / L_p**2


# --- V2: Hertz quasi-static impact (thesis sec. 3.4) ------------------------------------------------


@dataclass(frozen=True)
class HertzImpact:
    """Elastic Hertz impact of two bodies, ``mu alpha_ddot = -K_h alpha^1.5``.

    Attributes
    ----------
    alpha_max : float
        Maximum approach ``alpha_MC`` [m] (eq. 3.33).
    force_max : float
        ``K_h alpha_MC^1.5`` [N].
    contact_time : float
        Duration [s], by quadrature of ``dt = d alpha / alpha_dot``.
    time_factor : float
        ``contact_time v / alpha_MC`` (dimensionless; Goldsmith's approximation gives pi / 1.068).
    K_h, mu, v : float
        Inputs: Hertz constant [N/m^1.5], reduced mass [kg], approach speed [m/s].
    """

    alpha_max: float
    force_max: float
    contact_time: float
    time_factor: float
    K_h: float
    mu: float
    v: float

    def history(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Approach ``alpha(t)`` [m] and force [N] at times ``t`` [s] (zero outside the contact).

        ``t(x) = alpha_MC / v * 2/5 B(x^2.5; 2/5, 1/2)`` for ``x = alpha / alpha_MC`` (incomplete beta),
        inverted with ``betaincinv``; symmetric about maximum compression.
        """
        from scipy.special import betaincinv
        t = np.asarray(t, dtype=float)
        half = 0.5 * self.contact_time
        tau = np.clip(np.where(t <= half, t, self.contact_time - t), 0.0, half) / half
        x = betaincinv(0.4, 0.5, tau) ** 0.4
        alpha = np.where((t > 0.0) & (t < self.contact_time), self.alpha_max * x, 0.0)
        return alpha, self.K_h * alpha**1.5


def hertz_impact(K_h: float, m1: float, m2: float, v: float) -> HertzImpact:
    """Hertz impact of ``m1`` at ``v`` on ``m2`` at rest (thesis eqs. 3.28-3.33; ``m2 = inf``: half-space).

    The contact time is ``2 alpha_MC / v * integral_0^1 dx / sqrt(1 - x^2.5)``, evaluated by quadrature
    with the endpoint singularity as an algebraic weight.
    """
    from scipy.integrate import quad
    mu = 1.0 / (1.0 / m1 + 1.0 / m2)
    r = K_h / mu
    alpha_max = (1.25 * v**2 / r) ** 0.4
    half, _ = quad(_hertz_regular_part, 0.0, 1.0, weight="alg", wvar=(0.0, -0.5), epsabs=0.0, epsrel=1e-13)
    factor = 2.0 * half
    return HertzImpact(alpha_max, K_h * alpha_max**1.5, factor * alpha_max / v, factor, K_h, mu, v)


def _hertz_regular_part(x: float) -> float:
    """``sqrt((1 - x) / (1 - x^2.5))``, smooth on [0, 1] (limit ``sqrt(1/2.5)`` at 1): the integrand of the
    contact time without the ``(1 - x)^-1/2`` singularity, which quad takes as its weight."""
    return float(np.sqrt((1.0 - x) / (1.0 - x**2.5))) if x < 1.0 else float(np.sqrt(0.4))


def goldsmith_hertz_approximation(m1: float, m2: float, v: float, alpha_max: float) -> tuple[float, float]:
    """Goldsmith's sine approximation (thesis eq. 3.34): ``(force amplitude [N], contact time [s])``.

    ``alpha = alpha_MC sin(1.068 v t / alpha_MC)``, ``F = mu alpha_ddot``; the amplitude is
    ``1.068^2 v^2 m1 m2 / ((m1 + m2) alpha_MC)``. The thesis prints ``(m2 - m1)`` in the denominator:
    erratum (digest Appendix A item 1).
    """
    mu = 1.0 / (1.0 / m1 + 1.0 / m2)
    omega = GOLDSMITH_FREQUENCY_FACTOR * v / alpha_max
    return mu * alpha_max * omega**2, np.pi / omega


# --- V3: quasi-static structural approximation (thesis sec. 3.3) ------------------------------------


@dataclass(frozen=True)
class SpringImpact:
    """Mass on a linear spring: ``x(t) = (v0/omega) sin(omega t)`` while in contact.

    Attributes
    ----------
    omega : float [rad/s]
    x_max : float [m]
    force_max : float [N]
    contact_time : float [s]
    time_max_compression : float [s]
    v_out : float
        Impactor velocity after contact (negative: rebound) [m/s].
    kappa : float
        Force reduction ``1 / sqrt(1 + beta/3)`` from the bar's own mass (eq. 3.20).
    """

    omega: float
    x_max: float
    force_max: float
    contact_time: float
    time_max_compression: float
    v_out: float
    kappa: float


def quasi_static_bar_impact(m1: float, E: float, A: float, L: float, v: float, m2: float = 0.0) -> SpringImpact:
    """Mass ``m1`` at ``v`` on the free end of a clamped bar seen as a spring ``EA/L`` (eqs. 3.13-3.20).

    ``m2 > 0`` adds the bar's mass with a linear velocity profile: a lumped ``m2/3`` at the tip, set
    moving by an impulsive balance at ``t = 0`` (eq. 3.19), which reduces the force by ``kappa``.
    """
    k = E * A / L
    m_eff = m1 + m2 / 3.0
    v0 = m1 * v / m_eff
    omega = np.sqrt(k / m_eff)
    x_max = v0 / omega
    return SpringImpact(omega, x_max, k * x_max, np.pi / omega, 0.5 * np.pi / omega, -v0, np.sqrt(m1 / m_eff))


def quasi_static_equal_bars(m1: float, E: float, A: float, L: float, v: float) -> SpringImpact:
    """Two equal free bars at ``+-v``: one bar on a wall, clamped-bar uniform-load shape (eqs. 3.21-3.23).

    ``(128/135) m1 x'' + (64/27) (EA/L) x = 0`` for the mid-section displacement; force ``(8 EA / 3L) x``.
    """
    omega = np.sqrt((64.0 / 27.0) / (128.0 / 135.0) * E * A / (L * m1))
    x_max = v / omega
    return SpringImpact(omega, x_max, 8.0 * E * A / (3.0 * L) * x_max, np.pi / omega, 0.5 * np.pi / omega, -v, 1.0)


# --- V4/V5: bar on bar (thesis sec. 4.3) ------------------------------------------------------------


@dataclass(frozen=True)
class BarBarImpact:
    """Axial impact of two bars of the same material and section, ``l1 <= l2``.

    Attributes
    ----------
    contact_force : float
        Constant force during contact [N].
    contact_time : float
        ``2 l1 / c`` [s].
    stress : float
        Compressive stress behind the fronts, ``|v1 - v2| sqrt(E rho) / 2`` [Pa].
    v_interface : float
        ``(v1 + v2) / 2`` [m/s].
    v1_plus : float
        Bar 1 after separation: uniform, stress free, ``= v2`` [m/s].
    v2_plus : float
        Bar 2 centre-of-mass velocity, ``(v1 - v2) l1 / l2 + v2`` [m/s] (eq. 4.7).
    vibration_period : float
        ``2 l2 / c`` [s].
    c, l1, l2, v2 : float
        Wave speed [m/s], lengths [m], initial velocity of bar 2 [m/s].
    """

    contact_force: float
    contact_time: float
    stress: float
    v_interface: float
    v1_plus: float
    v2_plus: float
    vibration_period: float
    c: float
    l1: float
    l2: float
    v2: float

    def section_velocity(self, x: float, t: FloatArray) -> FloatArray:
        """Particle velocity of bar 2 at ``0 < x <= l2`` (from the impact end) [m/s] for ``t >= 0`` [s].

        The pulse injected during contact (velocity jump ``v_interface - v2``, length ``2 l1``) runs
        back and forth between the free ends; unfolding the bar into a ring of length ``2 l2``, the
        section ``x`` sees it at the ring points ``x`` and ``2 l2 - x`` (eq. 4.6, Fig. 4.8).
        """
        t = np.asarray(t, dtype=float)
        front = self.c * t
        tail = np.maximum(front - 2.0 * self.l1, 0.0)
        count = _images_inside(x, tail, front, self.l2) + _images_inside(2.0 * self.l2 - x, tail, front, self.l2)
        return self.v2 + (self.v_interface - self.v2) * count


def _images_inside(s: float, lo: FloatArray, hi: FloatArray, l2: float) -> FloatArray:
    """Number of ring points ``s + 2 l2 j`` (integer ``j``) in ``(lo, hi]``."""
    period = 2.0 * l2
    return np.floor((hi - s) / period) - np.floor((lo - s) / period)


def bar_bar_impact(E: float, rho: float, A: float, l1: float, l2: float, v1: float, v2: float = 0.0) -> BarBarImpact:
    """Bar 1 (length ``l1``) at ``v1`` hits bar 2 (``l2 >= l1``) at ``v2 < v1``; thesis eqs. 4.3-4.7.

    Equal bars at ``+-v`` are ``l1 = l2``, ``v1 = v``, ``v2 = -v`` (force ``A v sqrt(E rho)``, ``t_c = 2L/c``).
    """
    if l2 < l1:
        raise ValueError(f"bar 2 must be the longer one: l1={l1}, l2={l2}")
    c, Z = np.sqrt(E / rho), np.sqrt(E * rho)
    stress = 0.5 * abs(v1 - v2) * Z
    return BarBarImpact(A * stress, 2.0 * l1 / c, stress, 0.5 * (v1 + v2), v2, (v1 - v2) * l1 / l2 + v2,
                        2.0 * l2 / c, c, l1, l2, v2)


# --- V6: rigid mass on a free bar, closed form (thesis sec. 4.4, 4.6) ------------------------------


@dataclass(frozen=True)
class SaintVenantFreeBar:
    """Saint-Venant's rigid mass on a free bar: single contact of duration ``T``.

    Attributes
    ----------
    separation_time : float
        ``T = 2L/c`` [s]; the force drops abruptly to zero.
    v1_plus : float
        Impactor after contact, ``v exp(-2 beta)`` (never rebounds) [m/s] (eq. 4.13).
    v2_plus : float
        Bar centre of mass, ``v (1 - exp(-2 beta)) / beta`` [m/s] (eq. 4.16).
    end_velocity_at_separation : float
        Contact section at ``T``, ``v (1 + exp(-2 beta))`` [m/s] (eq. 4.14): the limit from inside the
        bar at ``t = T``, so the relative separation speed equals the approach speed (local
        restitution 1, eq. 4.46). Once the arriving front has reflected at the now stress-free end,
        the end moves at ``2 v`` (twice the incident particle velocity).
    restitution : float
        ``(v2+ - v1+) / v = (1 - (1 + beta) exp(-2 beta)) / beta`` (eqs. 4.39-4.40).
    time_max_compression : float
        Equal centre-of-mass velocities, ``T ln(1 + beta) / (2 beta)`` [s] (eq. 4.38).
    force_initial : float
        ``A sqrt(E rho) v`` [N]; ``F(t) = force_initial exp(-2 beta t/T)`` for ``0 < t < T`` (eq. 4.12).
    beta, T : float
    """

    separation_time: float
    v1_plus: float
    v2_plus: float
    end_velocity_at_separation: float
    restitution: float
    time_max_compression: float
    force_initial: float
    beta: float
    T: float

    def force(self, t: FloatArray) -> FloatArray:
        """Contact force [N] at ``t`` [s] (0 outside ``0 < t < T``)."""
        t = np.asarray(t, dtype=float)
        inside = (t > 0.0) & (t < self.T)
        return np.where(inside, self.force_initial * np.exp(-2.0 * self.beta * t / self.T), 0.0)


def saint_venant_free_bar(beta: float, v: float, c: float, L: float, impedance: float) -> SaintVenantFreeBar:
    """Closed form of the rigid mass (``beta = m_bar / m1``) hitting a free bar at ``v`` (thesis sec. 4.4).

    ``impedance`` is ``A sqrt(E rho)`` [N s/m].
    """
    T = 2.0 * L / c
    decay = np.exp(-2.0 * beta)
    return SaintVenantFreeBar(
        separation_time=T,
        v1_plus=v * decay,
        v2_plus=v * (1.0 - decay) / beta,
        end_velocity_at_separation=v * (1.0 + decay),
        restitution=(1.0 - (1.0 + beta) * decay) / beta,
        time_max_compression=T * np.log1p(beta) / (2.0 * beta),
        force_initial=impedance * v,
        beta=beta,
        T=T,
    )


# --- V7: rigid mass on a bar, exact characteristic recursion (thesis sec. 4.5) ----------------------


@dataclass(frozen=True)
class _Piece:
    """``exp(-k (t - t0)) P(t - t0) + Q(t - t0)``, times in units of T."""

    t0: float
    k: float
    P: Polynomial
    Q: Polynomial

    def __call__(self, t):
        tau = np.asarray(t, dtype=float) - self.t0
        return np.exp(-self.k * tau) * self.P(tau) + self.Q(tau)

    def rebased(self, a: float) -> _Piece:
        """The same function written about the origin ``a``."""
        h = a - self.t0
        shift = Polynomial([h, 1.0])
        return _Piece(a, self.k, np.exp(-self.k * h) * self.P(shift), self.Q(shift))

    def scaled(self, factor: float) -> _Piece:
        return replace(self, P=factor * self.P, Q=factor * self.Q)

    def integral(self, t):
        """``integral from t0 to t`` (closed form: ``R' - k R = P`` gives ``d(exp(-k tau) R) = exp(-k tau) P``)."""
        R = -sum((self.P.deriv(j) / self.k ** (j + 1) for j in range(self.P.degree() + 1)), Polynomial([0.0]))
        tau = np.asarray(t, dtype=float) - self.t0
        return np.exp(-self.k * tau) * R(tau) - R(0.0) + self.Q.integ()(tau)


def _exp_poly(t0: float, k: float, P: Polynomial) -> _Piece:
    return _Piece(t0, k, P, Polynomial([0.0]))


@dataclass(frozen=True)
class _Step:
    """One interval of the recursion (times in T, velocities in v, stresses in Z v, lengths in v T)."""

    t0: float
    t1: float
    contact: bool
    V: _Piece        # impactor velocity
    s_in: _Piece     # wave arriving at the impact end
    s_out: _Piece    # wave leaving it
    X0: float        # impactor displacement at t0
    u0: float        # end displacement at t0

    def end_velocity(self, t):
        return self.V(t) if self.contact else -2.0 * self.s_in(t)

    def stress(self, t):
        return self.V(t) + 2.0 * self.s_in(t) if self.contact else 0.0 * np.asarray(t)

    def X(self, t):
        return self.X0 + self.V.integral(t)

    def u(self, t):
        return self.X(t) if self.contact else self.u0 - 2.0 * self.s_in.integral(t)


@dataclass(frozen=True)
class AxialImpact:
    """Rigid mass on an elastic bar by the exact d'Alembert recursion, sampled on a time grid.

    Attributes
    ----------
    t : ndarray, shape (n,) [s]
    velocity : ndarray, shape (n,)
        Impactor velocity [m/s].
    force : ndarray, shape (n,)
        Contact force [N], >= 0.
    impactor_displacement, end_displacement : ndarray, shape (n,)
        Displacements of the impactor and of the bar's impact end from ``t = 0`` [m].
    end_velocity : ndarray, shape (n,)
        Particle velocity of the impact end [m/s].
    in_contact : ndarray of bool, shape (n,)
    contact_intervals : tuple of (float, float)
        Start and end of every contact [s].
    separation_velocities : tuple of float
        Impactor velocity at the end of each contact [m/s].
    onset_forces : tuple of float
        Force just after the start of each contact [N].
    final_velocity : float
        Impactor velocity after the last contact [m/s] (proved final: see ``rigid_mass_on_bar``).
    peak_force, peak_force_time : float
        Largest contact force [N] and when (right after a jump: the jump instant) [s].
    velocity_zero_time : float
        First instant the impactor stops [s] (nan if it never does).
    T : float
        ``2L/c`` [s].
    """

    t: FloatArray
    velocity: FloatArray
    force: FloatArray
    impactor_displacement: FloatArray
    end_displacement: FloatArray
    end_velocity: FloatArray
    in_contact: np.ndarray
    contact_intervals: tuple[tuple[float, float], ...]
    separation_velocities: tuple[float, ...]
    onset_forces: tuple[float, ...]
    final_velocity: float
    peak_force: float
    peak_force_time: float
    velocity_zero_time: float
    T: float


def clamped_bar_rigid_mass(beta: float, v: float, c: float, L: float, t: FloatArray, impedance: float) -> AxialImpact:
    """Rigid mass on a bar clamped at the far end, with every contact and recontact (thesis sec. 4.5, V7).

    Parameters
    ----------
    beta : float
        Bar mass over impactor mass, ``rho A L / m1``.
    v : float
        Impact speed [m/s], > 0.
    c : float
        Bar wave speed ``sqrt(E / rho)`` [m/s].
    L : float
        Bar length [m].
    t : array_like, shape (n,)
        Output times [s], ``>= 0``.
    impedance : float
        ``A sqrt(E rho)`` [N s/m].
    """
    return rigid_mass_on_bar(beta, v, c, L, t, impedance, far_end="clamped")


def rigid_mass_on_bar(beta: float, v: float, c: float, L: float, t: FloatArray, impedance: float,
                      far_end: str = "clamped") -> AxialImpact:
    """Rigid mass on a bar whose far end is ``"clamped"`` or ``"free"``, exact d'Alembert recursion.

    Arguments as ``clamped_bar_rigid_mass``. The recursion runs until the last requested time and
    until the last separation is proved final: after one full period of the free end's motion
    (``2T`` clamped, ``T`` free) without recontact, with the impactor no faster than the end's mean
    velocity over that period, the gap can only grow.
    """
    if far_end not in FAR_END_REFLECTION:
        raise ValueError(f"far_end must be one of {sorted(FAR_END_REFLECTION)}, got {far_end!r}")
    reflection = FAR_END_REFLECTION[far_end]
    T = 2.0 * L / c
    t = np.asarray(t, dtype=float)
    if np.any(t < 0.0):
        raise ValueError("output times must be >= 0")
    steps = _recursion(2.0 * beta, reflection, float(t.max(initial=0.0)) / T)
    return _sample(steps, t / T, T, v, impedance)


def _recursion(k: float, reflection: float, tau_end: float) -> list[_Step]:
    """Steps of the recursion in normalized units (``k = 2 beta``) until ``tau_end`` and finality."""
    period = 2.0 if reflection > 0 else 1.0
    steps: list[_Step] = []
    t, contact, V, X, u = 0.0, True, 1.0, 0.0, 0.0
    t_sep, u_sep, final = None, None, False
    for _ in range(MAX_STEPS):
        if final and t >= tau_end:
            return steps
        s_in, b = _incoming(steps, t, k, reflection)
        step, switched = (_contact_step if contact else _flight_step)(t, b, V, X, u, s_in, k)
        if step.t1 > step.t0:
            steps.append(step)
        t, V, X, u = step.t1, float(step.V(step.t1)), float(step.X(step.t1)), float(step.u(step.t1))
        if switched:
            contact = not contact
            t_sep, u_sep = (t, u) if not contact else (None, None)
        if t_sep is not None and not final and t >= t_sep + period - TIME_EPS:
            final = V <= (u - u_sep) / (t - t_sep) + SPEED_EPS
    raise RuntimeError(f"axial impact recursion did not settle in {MAX_STEPS} steps")


def _incoming(steps: list[_Step], t: float, k: float, reflection: float) -> tuple[_Piece, float]:
    """``s_in`` about ``t`` and the end of its current piece: the reflected ``s_out`` of one period ago."""
    if t < 1.0 - TIME_EPS:
        return _exp_poly(t, k, Polynomial([0.0])), 1.0
    for step in steps:
        if step.t1 + 1.0 > t + TIME_EPS:
            return _delayed(step.s_out, t, reflection), step.t1 + 1.0
    raise RuntimeError("wave history shorter than one period")


def _delayed(s_out: _Piece, t: float, reflection: float) -> _Piece:
    """``reflection * s_out(tau - 1)`` written about the origin ``t``."""
    shifted = replace(s_out, t0=s_out.t0 + 1.0)
    return shifted.rebased(t).scaled(reflection)


def _contact_step(a, b, V_a, X_a, u_a, s_in, k):
    """Impactor and end move together: ``V' = -k (V + 2 s_in)``; stops where the stress turns negative.

    Stresses are pure ``exp(-k tau) P(tau)`` pieces (their ``Q`` is zero), so ``V`` is one as well.
    """
    P_V = Polynomial([V_a]) - 2.0 * k * s_in.P.integ()
    stress = P_V + 2.0 * s_in.P  # stress = exp(-k tau) * this polynomial
    tau = _first_sign_change(stress, b - a)
    end = b if tau is None else a + tau
    V = _exp_poly(a, k, P_V)
    s_out = _exp_poly(a, k, P_V + s_in.P)
    return _Step(a, end, True, V, s_in, s_out, X_a, X_a), tau is not None


def _flight_step(a, b, V_a, X_a, u_a, s_in, k):
    """Free impactor, stress-free end (``s_out = -s_in``); stops where the gap closes."""
    V = _Piece(a, k, Polynomial([0.0]), Polynomial([V_a]))
    step = _Step(a, b, False, V, s_in, s_in.scaled(-1.0), X_a, u_a)
    tau = _first_sign_change(lambda x: step.u(a + x) - step.X(a + x), b - a)
    if tau is None:
        return step, False
    return replace(step, t1=a + tau), True


def _first_sign_change(f, length: float) -> float | None:
    """First ``x`` in ``(0, length]`` where ``f`` (positive just after 0) becomes <= 0, else None."""
    from scipy.optimize import brentq
    if length <= TIME_EPS:
        return None
    if f(0.0) < 0.0:
        return 0.0  # jump to a tensile stress at a breakpoint: abrupt separation
    x = np.linspace(0.0, length, N_SCAN)
    y = np.asarray(f(x), dtype=float)
    bad = np.nonzero(y[1:] <= 0.0)[0]
    if bad.size == 0:
        return None
    i = bad[0] + 1
    lo = x[i - 1] if y[i - 1] > 0.0 else _positive_point(f, x[1])
    if lo is None:
        return 0.0
    if y[i] == 0.0:
        return float(x[i])
    return float(brentq(f, lo, x[i], xtol=1e-15, rtol=4 * np.finfo(float).eps))


def _positive_point(f, x1: float) -> float | None:
    """A point of ``(0, x1)`` where ``f > 0`` (``f`` leaves 0 from exactly zero, e.g. a gap that just opened)."""
    for j in range(1, 60):
        if f(x1 * 0.5**j) > 0.0:
            return x1 * 0.5**j
    return None


def _sample(steps: list[_Step], tau: FloatArray, T: float, v: float, impedance: float) -> AxialImpact:
    """Evaluate the recursion on the grid and collect its events, back in SI units."""
    starts = np.array([s.t0 for s in steps])
    idx = np.clip(np.searchsorted(starts, tau, side="right") - 1, 0, len(steps) - 1)
    cols = np.zeros((6, tau.size))
    for i in np.unique(idx):
        s, sel = steps[i], idx == i
        x = tau[sel]
        cols[:, sel] = [s.V(x), s.stress(x), s.X(x), s.u(x), s.end_velocity(x), np.full(x.shape, s.contact)]
    intervals, seps, onsets = _contact_events(steps)
    peak, peak_t = _peak_stress(steps)
    return AxialImpact(
        t=tau * T, velocity=v * cols[0], force=impedance * v * np.maximum(cols[1], 0.0),
        impactor_displacement=v * T * cols[2], end_displacement=v * T * cols[3], end_velocity=v * cols[4],
        in_contact=cols[5].astype(bool),
        contact_intervals=tuple((a * T, b * T) for a, b in intervals),
        separation_velocities=tuple(v * s for s in seps),
        onset_forces=tuple(impedance * v * f for f in onsets),
        final_velocity=v * seps[-1], peak_force=impedance * v * peak, peak_force_time=peak_t * T,
        velocity_zero_time=T * _velocity_zero(steps), T=T,
    )


def _contact_events(steps: list[_Step]):
    """Contact intervals, impactor velocity at each separation, stress at each onset (normalized)."""
    intervals, seps, onsets = [], [], []
    for i, s in enumerate(steps):
        if not s.contact:
            continue
        if i == 0 or not steps[i - 1].contact:
            intervals.append([s.t0, s.t1])
            onsets.append(float(s.stress(s.t0)))
        intervals[-1][1] = s.t1
        if i == len(steps) - 1 or not steps[i + 1].contact:
            seps.append(float(s.V(s.t1)))
    return [tuple(i) for i in intervals], seps, onsets


def _peak_stress(steps: list[_Step]) -> tuple[float, float]:
    """Largest contact stress: step ends and the roots of ``P' - k P`` inside contact steps."""
    best, when = -np.inf, 0.0
    for s in (s for s in steps if s.contact):
        P = s.V.P + 2.0 * s.s_in.P
        roots = (P.deriv() - s.V.k * P).roots() if P.degree() > 0 else []
        crit = [r.real for r in roots if abs(r.imag) < 1e-12 and 0.0 < r.real < s.t1 - s.t0]
        for x in [0.0, s.t1 - s.t0, *crit]:
            val = float(s.stress(s.t0 + x))
            if val > best:
                best, when = val, s.t0 + x
    return best, when


def _velocity_zero(steps: list[_Step]) -> float:
    """First time the impactor velocity reaches zero (normalized), nan if never."""
    for s in (s for s in steps if s.contact):
        tau = _first_sign_change(lambda x, s=s: s.V(s.t0 + x), s.t1 - s.t0)
        if tau is not None:
            return s.t0 + tau
    return float("nan")


# --- V10: event-driven "model C" (thesis sec. 4.6, eq. 4.44) ----------------------------------------


@dataclass(frozen=True)
class ModelC:
    """Free mass on a mass-spring (``m_eq`` on a spring ``k`` to a wall) with instantaneous balances.

    Attributes
    ----------
    balance_times : tuple of float
        Instants of the impulse balances [s].
    velocities : tuple of (float, float)
        ``(v1, v2)`` just after each balance [m/s].
    final_velocity : float
        Free mass after the last balance [m/s].
    energy_lost : float
        Sum of the balance losses ``mu (1 - e^2) v_rel^2 / 2`` [J].
    energy_lost_fraction : float
        ``energy_lost`` over the initial kinetic energy.
    oscillator_energy : float
        Energy left in the mass-spring after the last balance [J].
    """

    balance_times: tuple[float, ...]
    velocities: tuple[tuple[float, float], ...]
    final_velocity: float
    energy_lost: float
    energy_lost_fraction: float
    oscillator_energy: float

    @property
    def n_balances(self) -> int:
        """Number of impulse balances."""
        return len(self.balance_times)


def model_c_impacts(m1: float, m_eq: float, k: float, v: float, e: float) -> ModelC:
    """Mass ``m1`` at ``v`` hits ``m_eq`` (at rest on a spring ``k`` to a wall), restitution ``e > 0``.

    Exact free flight between balances (``m1`` straight, ``m_eq`` harmonic); the next balance is the
    first closing of the gap, searched over one oscillator period (a grazing contact shorter than
    1/4000 of a period could be missed). Final once a period passes without contact while ``m1``
    moves away. Thesis model C: ``m_eq = m_bar/3``, ``k = EA/L``.
    """
    if not 0.0 < e <= 1.0:
        raise ValueError(f"restitution must be in (0, 1], got {e}")
    omega = np.sqrt(k / m_eq)
    t, x1, x2, v1, v2 = 0.0, 0.0, 0.0, v, 0.0
    times, vels, lost = [], [], 0.0
    for _ in range(MAX_STEPS):
        hit = rigid_central_impact(m1, m_eq, v1, e, v2)
        v1, v2, lost = hit.v1_plus, hit.v2_plus, lost + hit.energy_lost
        times.append(t)
        vels.append((v1, v2))
        tau = _next_balance(x1, x2, v1, v2, omega)
        if tau is None:
            osc = 0.5 * m_eq * v2**2 + 0.5 * k * x2**2
            return ModelC(tuple(times), tuple(vels), v1, lost, lost / (0.5 * m1 * v**2), osc)
        c, s = np.cos(omega * tau), np.sin(omega * tau)
        t, x1, x2, v2 = t + tau, x1 + v1 * tau, x2 * c + v2 / omega * s, -x2 * omega * s + v2 * c
    raise RuntimeError(f"model C did not settle in {MAX_STEPS} balances")


def _next_balance(x1, x2, v1, v2, omega) -> float | None:
    """Time to the next closing of the gap ``x2 - x1``, or None if the masses never meet again."""
    from scipy.optimize import brentq
    period = 2.0 * np.pi / omega

    def gap(tau):
        return x2 * np.cos(omega * tau) + v2 / omega * np.sin(omega * tau) - x1 - v1 * tau

    for n in range(MAX_STEPS):
        x = np.linspace(n * period, (n + 1) * period, N_SCAN_PERIOD)
        y = gap(x)
        closing = np.nonzero(y[1:] <= 0.0)[0]
        if closing.size:
            i = closing[0] + 1
            return float(brentq(gap, x[i - 1], x[i], xtol=1e-16 * period)) if y[i - 1] > 0.0 else float(x[i])
        if v1 <= 0.0:
            return None
    raise RuntimeError("model C: no balance found although the free mass keeps approaching")

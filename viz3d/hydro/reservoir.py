"""Hydrodynamic pressure in a semi-infinite reservoir in front of a vertical dam face (Chopra 1967).

The reservoir occupies x >= 0, 0 <= y <= h (y up from the bottom, x upstream from the dam face).
The face moves horizontally with acceleration ``ddot u(y, t) = phi(y) exp(j omega t)``; the
pressure ``p(x, y) exp(j omega t)`` solves

    Helmholtz     p_xx + p_yy + (omega / c)^2 p = 0
    free surface  p(x, h) = 0
    bottom        p_y(x, 0) = j omega q p(x, 0),   q = (1 - alpha) / ((1 + alpha) c)   (q = 0: rigid)
    dam face      p_x(0, y) = -rho phi(y)
    far field     outgoing or decaying waves only (Sommerfeld), as x -> infinity.

Separation of variables gives (docs/hydro.md has the derivation and the seed's errata)

    p(x, y) = sum_n P_n Y_n(y) exp(-kappa_n x),     Y_n = sin(mu_n (h - y)),
    P_n = rho I_n / (kappa_n N_n),   I_n = int_0^h phi Y_n dy,   N_n = int_0^h Y_n^2 dy,
    kappa_n = sqrt(mu_n^2 - (omega / c)^2),  Re kappa_n >= 0,  and kappa_n = j sign(omega) k_n
              for the propagating terms of a rigid bottom,

with ``mu_n = lambda_n = (2n - 1) pi / (2h)`` for a rigid bottom (N_n = h / 2) and the roots of
``mu cos(mu h) + j omega q sin(mu h) = 0`` next to them for an absorbing one. A term radiates above
its cut-off frequency ``omega_n = c lambda_n``; at omega_n (rigid bottom) it is unbounded.

Series are summed to a number of terms chosen from a relative tolerance, after subtracting the
slowly convergent part that every shape shares (Kummer's method): the leading term of I_n is
``phi(h) / lambda_n``, whose incompressible series has the closed form

    sum_n (2 / h) sin(lambda_n (h - y)) exp(-lambda_n x) / lambda_n^2 = (8 h / pi^2) Im chi_2(z),
    z = exp(-pi x / 2h) exp(j pi (h - y) / 2h),

chi_2 Legendre's chi function. The remainder decays like n^-3 (pressure) or n^-4 (added mass);
its tail is bounded a priori (``tail_bound``), and the bound is reported with the result.

Conventions (SI units, docs/notation.md): time factor exp(j omega t); p is the hydrodynamic
pressure (positive = compression) per unit amplitude of wall *acceleration* [Pa / (m/s^2)];
``added_mass`` A_ij = int_0^h phi_i p_j dy (force on the water per unit width along phi_i, per unit
acceleration of shape j) and ``dynamic_stiffness`` S = -omega^2 A, so that the force the wall
exerts on the water is S q for a wall displacement sum_j phi_j q_j exp(j omega t). Re S < 0 is
inertia (added mass), Im S > 0 is energy leaving the dam (radiation, bottom absorption).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.hydro.shapes import BLOCK_ELEMENTS, WallShapes, as_shapes

#: Default relative tolerance of the truncated series (see ``choose_terms`` for what it is relative to).
DEFAULT_RTOL = 1e-8
#: Largest number of series terms ``choose_terms`` will use.
MAX_TERMS = 1 << 20
#: Westergaard's (1933) parabola p = (7/8) rho a sqrt(h (h - y)).
WESTERGAARD_COEFFICIENT = 7.0 / 8.0
#: Apery's constant zeta(3) (``scipy.special.zeta(3.0)`` to the last bit; a literal, so that importing
#: this module does not import scipy.special, 0.3 s: tests/test_startup.py).
ZETA_3 = 1.2020569031595942
#: sum_{n>=1} 1 / (2n - 1)^3 = (7/8) zeta(3): the series of a rigid wall's incompressible force.
ODD_ZETA_3 = 7.0 / 8.0 * ZETA_3
#: Total force on a rigid wall, incompressible water, per unit acceleration: RIGID_FORCE_COEFFICIENT rho h^2
#: = (16 / pi^3) sum 1 / (2n - 1)^3 = 14 zeta(3) / pi^3 = 0.5427...
RIGID_FORCE_COEFFICIENT = 16.0 / np.pi**3 * ODD_ZETA_3
#: Newton iterations per continuation step, and the last step (relative to |mu h|) accepted, for the
#: eigenvalues of an absorbing bottom (Newton converges quadratically: the error is far below the step).
NEWTON_ITERATIONS = 50
NEWTON_RTOL = 1e-13
#: Continuation steps in beta = omega q h: at most this increment per step (root spacing is pi), for the
#: roots z0_n = (2n - 1) pi / 2 below CONTINUATION_RATIO |beta|; the others start from their asymptote.
CONTINUATION_STEP = np.pi / 16.0
CONTINUATION_RATIO = 4.0
#: Safety factor on the tail estimate of an absorbing bottom, whose bound is asymptotic, not rigorous.
ABSORBING_TAIL_SAFETY = 2.0


@dataclass(frozen=True)
class Reservoir:
    """Water of a semi-infinite reservoir of constant depth.

    Attributes
    ----------
    density : float
        rho [kg/m^3].
    depth : float
        h [m].
    sound_speed : float
        c [m/s]; ``numpy.inf`` for incompressible water (Westergaard's case).
    reflection : float
        alpha, wave reflection coefficient of the reservoir bottom for vertically incident
        pressure waves, -1 < alpha <= 1; 1 is a rigid bottom (the seed's model), 0 absorbs
        vertically incident waves completely. Needs a finite ``sound_speed``.
    """

    density: float
    depth: float
    sound_speed: float = np.inf
    reflection: float = 1.0

    def __post_init__(self):
        if not (self.density > 0 and self.depth > 0 and self.sound_speed > 0):
            raise ValueError(f"reservoir needs density, depth and sound speed > 0; got {self}")
        if not -1.0 < self.reflection <= 1.0:
            raise ValueError(f"bottom reflection coefficient must be in (-1, 1], got {self.reflection}")
        if self.reflection < 1.0 and not np.isfinite(self.sound_speed):
            raise ValueError("an absorbing bottom (reflection < 1) needs compressible water (finite sound_speed)")

    @property
    def compressible(self) -> bool:
        return bool(np.isfinite(self.sound_speed))

    @property
    def rigid_bottom(self) -> bool:
        return self.reflection == 1.0

    @property
    def admittance(self) -> float:
        """q = (1 - alpha) / ((1 + alpha) c) [s/m]: bottom condition p_y = j omega q p."""
        return 0.0 if self.rigid_bottom else (1.0 - self.reflection) / ((1.0 + self.reflection) * self.sound_speed)

    def cutoff_frequencies(self, n_terms: int) -> FloatArray:
        """omega_n = c lambda_n = (2n - 1) pi c / (2h), n = 1..n_terms [rad/s] (rigid bottom; inf if incompressible)."""
        return self.sound_speed * rigid_wavenumbers(self.depth, n_terms)


#: The seed's example (chapter 4): rho = 1000 kg/m^3, h = 100 m, c = 1493 m/s, rigid bottom.
SEED_EXAMPLE = Reservoir(density=1000.0, depth=100.0, sound_speed=1493.0)


@dataclass(frozen=True)
class SeriesResult:
    """A truncated series and what its truncation costs.

    Attributes
    ----------
    value : ndarray
        The sum (shape documented by the function that returns it).
    n_terms : int
        Terms summed.
    bound : float
        Bound on |truncation error| of every entry, in the units of ``value`` (a priori for a rigid
        bottom; an asymptotic estimate with a safety factor for an absorbing one).
    rtol : float
        The tolerance ``n_terms`` was chosen for.
    """

    value: np.ndarray
    n_terms: int
    bound: float
    rtol: float


# ----------------------------------------------------------------------------------------------
# the depth functions: eigenvalues, decay rates, norms
# ----------------------------------------------------------------------------------------------
def rigid_wavenumbers(depth: float, n_terms: int) -> FloatArray:
    """lambda_n = (2n - 1) pi / (2h), n = 1..n_terms, shape (n_terms,) [1/m]."""
    return (2.0 * np.arange(1, n_terms + 1) - 1.0) * np.pi / (2.0 * depth)


def _newton(z: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Newton's method on f(z) = z cos z + j b sin z from ``z`` until every step is below NEWTON_RTOL |z|."""
    for _ in range(NEWTON_ITERATIONS):
        c, s = np.cos(z), np.sin(z)
        step = (z * c + 1j * b * s) / (c - z * s + 1j * b * c)
        z = z - step
        if np.all(np.abs(step) <= NEWTON_RTOL * np.abs(z)):
            return z
    raise ArithmeticError(f"bottom eigenvalues did not converge (beta up to {np.abs(b).max():.4g})")


def _absorbing_roots(beta: FloatArray, n_terms: int) -> np.ndarray:
    """Roots z_n(beta) of z cos z + j beta sin z = 0 next to z0_n = (2n - 1) pi / 2: beta (w,) -> (w, n_terms).

    For z0_n >= CONTINUATION_RATIO max|beta| Newton starts from the first-order root z0 + j beta / z0
    (its error is O(beta^2 / z0^3)); the lower roots are continued in beta from 0 in steps of at most
    CONTINUATION_STEP, so that every root stays on its own branch.
    """
    z0 = (2.0 * np.arange(1, n_terms + 1) - 1.0) * np.pi / 2.0
    b = np.asarray(beta)[:, None]
    z = _newton(z0[None, :] + 1j * b / z0[None, :], b)
    near = z0 < CONTINUATION_RATIO * np.abs(b).max(initial=0.0)
    if np.any(near):
        zn = np.broadcast_to(z0[near], (b.size, int(near.sum()))).astype(complex)
        n_steps = max(1, int(np.ceil(np.abs(b).max() / CONTINUATION_STEP)))
        for step in range(1, n_steps + 1):
            zn = _newton(zn, b * step / n_steps)
        z[:, near] = zn
    if n_terms > 1 and np.any(np.diff(z.real, axis=1) <= 0.0):
        raise ArithmeticError("two bottom eigenvalues merged; lower the continuation step")
    return z


def depth_wavenumbers(reservoir: Reservoir, omega: FloatArray, n_terms: int) -> np.ndarray:
    """mu_n of the depth functions Y_n = sin(mu_n (h - y)): shape (1, n_terms) real for a rigid bottom,
    (len(omega), n_terms) complex for an absorbing one [1/m]."""
    lam = rigid_wavenumbers(reservoir.depth, n_terms)
    if reservoir.rigid_bottom:
        return lam[None, :]
    beta = np.asarray(omega) * reservoir.admittance * reservoir.depth
    return _absorbing_roots(beta, n_terms) / reservoir.depth


def decay_rates(mu: np.ndarray, omega: FloatArray, sound_speed: float) -> np.ndarray:
    """kappa_n = sqrt(mu_n^2 - (omega / c)^2) on the physical branch: shape (len(omega), n) complex [1/m].

    Re kappa >= 0 (decaying into the reservoir). Where kappa^2 is real and negative (a propagating
    term of a rigid bottom, real omega), kappa = j sign(omega) k: the wave exp(j (omega t - k x)) travels
    upstream for either sign of omega, the limit of a causal (omega -> omega - j0) response. For complex
    omega (Im omega < 0, ``viz3d.hydro.dam.time_response``) the principal root is that continuation.
    """
    omega = np.asarray(omega)[:, None]
    kappa2 = (np.asarray(mu) ** 2 - (omega / sound_speed) ** 2).astype(complex)
    kappa = np.sqrt(kappa2)
    lossless_propagating = (kappa2.imag == 0.0) & (kappa2.real < 0.0)
    return np.where(lossless_propagating, 1j * np.sign(omega.real) * np.sqrt(np.abs(kappa2.real)), kappa)


def modal_norms(mu: np.ndarray, depth: float) -> np.ndarray:
    """N_n = int_0^h sin^2(mu_n (h - y)) dy = h/2 - sin(2 mu_n h) / (4 mu_n) (h/2 for a rigid bottom) [m]."""
    return depth / 2.0 - np.sin(2.0 * mu * depth) / (4.0 * mu)


def legendre_chi2(z) -> np.ndarray:
    """Legendre's chi function chi_2(z) = sum_{k>=0} z^(2k+1) / (2k+1)^2 = (Li_2(z) - Li_2(-z)) / 2, |z| <= 1."""
    from scipy.special import spence
    z = np.asarray(z, dtype=complex)
    return 0.5 * (spence(1.0 - z) - spence(1.0 + z))


def rigid_wall_series(depth: float, x, y) -> FloatArray:
    """(8h / pi^2) Im chi_2(exp(-pi x/2h) exp(j pi (h - y)/2h)) = sum_n (2/h) sin(lambda_n (h - y)) exp(-lambda_n x) / lambda_n^2.

    The incompressible pressure of a rigid wall per unit acceleration and unit density [m]; the part
    of every series that is summed in closed form. Shape: broadcast of x and y.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    z = np.exp(-np.pi * x / (2.0 * depth)) * np.exp(1j * np.pi * (depth - y) / (2.0 * depth))
    return 8.0 * depth / np.pi**2 * np.imag(legendre_chi2(z))


def westergaard_pressure(reservoir: Reservoir, y) -> FloatArray:
    """Westergaard's parabola (7/8) rho sqrt(h (h - y)) per unit acceleration [Pa / (m/s^2)], shape of y."""
    h = reservoir.depth
    return WESTERGAARD_COEFFICIENT * reservoir.density * np.sqrt(h * np.clip(h - np.asarray(y, float), 0.0, None))


# ----------------------------------------------------------------------------------------------
# how many terms
# ----------------------------------------------------------------------------------------------
def odd_power_tail(depth: float, n_terms: int, power: int) -> float:
    """sum_{n > n_terms} lambda_n^-power, exactly, by the Hurwitz zeta function [m^power].

    sum_{n>N} (2n - 1)^-p = 2^-p zeta(p, N + 1/2).
    """
    from scipy.special import zeta
    return float((depth / np.pi) ** power * zeta(float(power), n_terms + 0.5))


def _reach(reservoir: Reservoir, omega_max: float, n_terms: int) -> float:
    """s_N = sqrt(1 - (omega_max / omega_{N+1})^2): every omitted term has kappa_n >= s_N lambda_n (0 if one radiates)."""
    if not reservoir.compressible:
        return 1.0
    ratio = omega_max / (reservoir.sound_speed * rigid_wavenumbers(reservoir.depth, n_terms + 1)[-1])
    return float(np.sqrt(max(0.0, 1.0 - ratio**2)))


@dataclass(frozen=True)
class DecayConstants:
    """What the truncation bound needs of k shapes, read once (``decay_constants``).

    Attributes
    ----------
    top : ndarray, shape (k,)
        a = |phi(h)|: the moments' leading coefficient, I_n ~ phi(h) / lambda_n.
    variation : ndarray, shape (k,)
        W with |I_n - phi(h) / lambda_n| <= W / lambda_n^2: ``slope_variation`` for a rigid bottom, plus
        |omega q| (|phi(0)| + |phi(h)|) for an absorbing one (its eigenvalues and cos(mu_n h) are
        O(omega q / lambda_n) away from the rigid ones).
    sup : ndarray, shape (k,)
        max |phi|, the scale ``rtol`` is relative to.
    """

    top: FloatArray
    variation: FloatArray
    sup: FloatArray


def decay_constants(reservoir: Reservoir, shapes: WallShapes, omega_max: float) -> DecayConstants:
    """The ``DecayConstants`` of ``shapes`` for frequencies up to ``omega_max`` [rad/s]."""
    a, w = np.abs(shapes.top), shapes.slope_variation
    if not reservoir.rigid_bottom:
        w = w + abs(omega_max * reservoir.admittance) * (np.abs(shapes.bottom) + a)
    return DecayConstants(a, w, shapes.sup)


def tail_bound(reservoir: Reservoir, constants: DecayConstants, omega_max: float, n_terms: int, kind: str) -> np.ndarray:
    """Bound on the truncation error after ``n_terms`` terms, per shape (pressure) or pair (added mass).

    With s = ``_reach``, e = (omega/c)^2, T_p = sum_{n>N} lambda_n^-p (``odd_power_tail``), a and W
    from ``constants`` (docs/hydro.md, "Truncation"):

    * pressure: (2 rho / h) [W T_3 / s + (1 + 1/e_) a e T_4 / s^2], e_ = exp(1), at any x >= 0;
    * added mass: (2 rho / h) [(a_i W_j + a_j W_i) T_4 + (W_i W_j + a_i a_j e) T_5] / s.

    Returns ``inf`` if a term beyond ``n_terms`` still radiates at ``omega_max``. Shape (k,) or (k, k).
    """
    a, w = constants.top, constants.variation
    s = _reach(reservoir, omega_max, n_terms)
    if s == 0.0:
        return np.full((a.size,) * (1 if kind == "pressure" else 2), np.inf)
    h, rho = reservoir.depth, reservoir.density
    e = (omega_max / reservoir.sound_speed) ** 2
    T = {p: odd_power_tail(h, n_terms, p) for p in (3, 4, 5)}
    if kind == "pressure":
        out = 2.0 * rho / h * (w * T[3] / s + (1.0 + 1.0 / np.e) * a * e * T[4] / s**2)
    elif kind == "added_mass":
        cross = np.outer(a, w) + np.outer(w, a)
        out = 2.0 * rho / h * (cross * T[4] + (np.outer(w, w) + e * np.outer(a, a)) * T[5]) / s
    else:
        raise ValueError(f"kind must be 'pressure' or 'added_mass', got {kind!r}")
    return out if reservoir.rigid_bottom else ABSORBING_TAIL_SAFETY * out


def _scale(reservoir: Reservoir, sup: FloatArray, kind: str) -> np.ndarray:
    """What ``rtol`` is relative to: rho h max|phi| (pressure, (k,)) or rho h^2 max|phi_i| max|phi_j| ((k, k))."""
    h, rho = reservoir.depth, reservoir.density
    return rho * h * sup if kind == "pressure" else rho * h**2 * np.outer(sup, sup)


def choose_terms(reservoir: Reservoir, shapes: WallShapes, omega_max: float, rtol: float, kind: str) -> tuple[int, float]:
    """Smallest number of terms N whose ``tail_bound`` is within ``rtol`` times ``_scale``; returns (N, bound).

    The bound decreases with N, so doubling then bisection finds N. Raises if MAX_TERMS do not do.
    """
    if not rtol > 0:
        raise ValueError(f"rtol must be positive, got {rtol}")
    constants = decay_constants(reservoir, shapes, omega_max)
    target = rtol * _scale(reservoir, constants.sup, kind)

    def ok(n: int) -> bool:
        return bool(np.all(tail_bound(reservoir, constants, omega_max, n, kind) <= target))

    low = 1
    if reservoir.compressible:  # every radiating term must be summed
        low = max(1, int(np.floor(omega_max * reservoir.depth / (np.pi * reservoir.sound_speed) + 0.5)) + 1)
    high = low
    while not ok(high):
        if high >= MAX_TERMS:
            raise ValueError(f"rtol = {rtol:g} needs more than {MAX_TERMS} series terms")
        low, high = high, min(MAX_TERMS, 2 * high)
    while high - low > 1:
        mid = (low + high) // 2
        low, high = (low, mid) if ok(mid) else (mid, high)
    n = low if ok(low) else high
    return n, float(tail_bound(reservoir, constants, omega_max, n, kind).max())


# ----------------------------------------------------------------------------------------------
# the series
# ----------------------------------------------------------------------------------------------
def _omegas(omega) -> np.ndarray:
    """Frequencies as a 1-D array: real, or complex with Im omega <= 0 (where causal responses are analytic)."""
    omega = np.atleast_1d(np.asarray(omega))
    if omega.ndim != 1 or not np.all(np.isfinite(omega)):
        raise ValueError("omega must be a finite scalar or 1-D array [rad/s]")
    if np.iscomplexobj(omega):
        if np.any(omega.imag > 0):
            raise ValueError("complex frequencies must have Im omega <= 0 (exp(j omega t) decaying backwards in time)")
        if np.all(omega.imag == 0):
            return omega.real.astype(float)
        return omega.astype(complex)
    return omega.astype(float)


def _terms(reservoir: Reservoir, shapes: WallShapes, omega: FloatArray, n_terms: int):
    """mu (w|1, N), kappa (w, N), moments I (w|1, N, k) and rho / (kappa N_n) (w, N)."""
    mu = depth_wavenumbers(reservoir, omega, n_terms)
    kappa = decay_rates(mu, omega, reservoir.sound_speed)
    if reservoir.rigid_bottom:
        moments = shapes.moments(mu)
    else:  # eigenvalues next to the rigid ones: Taylor's series about them
        lam = rigid_wavenumbers(reservoir.depth, n_terms)
        moments = shapes.moments_near(lam, mu - lam[None, :])
    with np.errstate(divide="ignore", invalid="ignore"):  # kappa = 0 exactly at a cut-off: unbounded
        weight = reservoir.density / (kappa * modal_norms(mu, reservoir.depth))
    return mu, kappa, moments, weight


def pressure(reservoir: Reservoir, shape, omega, y, x=0.0, *, rtol: float = DEFAULT_RTOL,
             combination=None) -> SeriesResult:
    """Hydrodynamic pressure p(x, y, omega) per unit amplitude of wall acceleration.

    Parameters
    ----------
    reservoir : Reservoir
    shape : callable, (y, values) pair or wall shapes object
        One wall-acceleration shape phi on [0, h] (``viz3d.hydro.shapes.as_shapes``), or k shapes
        with ``combination``.
    combination : ndarray, shape (w, k), optional
        Accelerations c_wj of k shapes: the wall moves as sum_j c_wj phi_j at frequency w (a dam's modes
        responding), and the pressure is the same combination of the shapes' pressures, summed once.
        ``bound`` is then max_w sum_j |c_wj| (bound of shape j).
    omega : float or ndarray, shape (w,)
        Circular frequencies [rad/s], either sign.
    y : ndarray, shape (p,)
        Heights above the bottom [m], 0 <= y <= h.
    x : float or ndarray, shape (p,)
        Distance upstream from the dam face [m], x >= 0 (0: on the face).
    rtol : float
        Truncation error at most rtol * rho h max|phi| (``choose_terms``).

    Returns
    -------
    SeriesResult
        ``value`` complex, shape (w, p) [Pa / (m/s^2) per unit phi].
    """
    h = reservoir.depth
    shapes = as_shapes(shape, h)
    omega = _omegas(omega)
    c = _combination(combination, shapes.n_shapes, omega.size)
    x, y = np.broadcast_arrays(np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(y, float)))
    if x.ndim != 1 or np.any(x < 0) or np.any(y < 0) or np.any(y > h):
        raise ValueError(f"points need x >= 0 and 0 <= y <= {h} m (1-D arrays)")
    n, _ = choose_terms(reservoir, shapes, float(np.abs(omega).max()), rtol, "pressure")
    constants = decay_constants(reservoir, shapes, float(np.abs(omega).max()))
    bound = float((np.abs(c) @ tail_bound(reservoir, constants, float(np.abs(omega).max()), n, "pressure")).max())
    mu, kappa, moments, weight = _terms(reservoir, shapes, omega, n)
    coef = weight * np.einsum("wnk,wk->wn", np.broadcast_to(moments, (omega.size,) + moments.shape[1:]), c)  # P_n
    lam = rigid_wavenumbers(h, n)
    a = (c @ shapes.top)[:, None]  # phi(h) of the combination, (w, 1)
    # closed form of a * (incompressible rigid-wall series) minus its first N terms
    kummer_partial = (2.0 / h) * (np.sin(np.outer(lam, h - y)) * np.exp(-np.outer(lam, x)) / lam[:, None] ** 2).sum(axis=0)
    if mu.shape[0] == 1 and not np.any(x):  # rigid bottom, on the face: one matrix product
        value = coef @ np.sin(np.outer(mu[0], h - y))
    else:
        value = np.empty((omega.size, y.size), dtype=complex)
        rows_per_block = max(1, BLOCK_ELEMENTS // max(1, n * y.size))
        for start in range(0, omega.size, rows_per_block):
            b = slice(start, start + rows_per_block)
            mu_b = mu if mu.shape[0] == 1 else mu[b]
            depth_fn = np.sin(mu_b[:, :, None] * (h - y)[None, None, :]) * np.exp(-kappa[b][:, :, None] * x[None, None, :])
            value[b] = np.einsum("wn,wnp->wp", coef[b], depth_fn)
    value = value + reservoir.density * a * (rigid_wall_series(h, x, y) - kummer_partial)[None, :]
    return SeriesResult(value, n, bound, rtol)


def _combination(combination, n_shapes: int, n_omega: int) -> np.ndarray:
    """The (w, k) accelerations of ``pressure``'s shapes: ones for one shape without a combination."""
    if combination is None:
        if n_shapes != 1:
            raise ValueError(f"pressure takes one shape, or k shapes with a combination; got {n_shapes} shapes")
        return np.ones((n_omega, 1))
    c = np.asarray(combination)
    if c.shape != (n_omega, n_shapes):
        raise ValueError(f"combination must have shape (frequencies, shapes) = {(n_omega, n_shapes)}, got {c.shape}")
    return c


def added_mass(reservoir: Reservoir, shapes, omega, *, rtol: float = DEFAULT_RTOL) -> SeriesResult:
    """A_ij(omega) = int_0^h phi_i p_j dy: force on the water along phi_i per unit acceleration of shape j.

    ``A = sum_n rho I_ni I_nj / (kappa_n N_n)``, the leading part ``(2 rho / h) phi_i(h) phi_j(h) / lambda_n^3``
    of each term summed exactly (``odd_power_tail``). Real and frequency independent for incompressible
    water: the added-mass matrix; complex symmetric in general.

    Parameters
    ----------
    reservoir : Reservoir
    shapes : callable, (y, values) pair or wall shapes object
        k shapes on [0, h].
    omega : float or ndarray, shape (w,)
        [rad/s].
    rtol : float
        Truncation error at most rtol * rho h^2 max|phi_i| max|phi_j|.

    Returns
    -------
    SeriesResult
        ``value`` complex, shape (w, k, k) [kg/m per unit phi_i phi_j: per metre of dam width].
    """
    h = reservoir.depth
    shapes = as_shapes(shapes, h)
    omega = _omegas(omega)
    n, bound = choose_terms(reservoir, shapes, float(np.abs(omega).max()), rtol, "added_mass")
    _, _, moments, weight = _terms(reservoir, shapes, omega, n)
    k = shapes.n_shapes
    if moments.shape[0] == 1:  # rigid bottom: sum_n weight_wn (I_n I_n^T) as one matrix product
        products = moments[0][:, :, None] * moments[0][:, None, :]
        value = (weight @ products.reshape(n, k * k)).reshape(omega.size, k, k)
    else:
        value = np.swapaxes(weight[..., None] * moments, 1, 2) @ moments
    a = shapes.top
    value = value + 2.0 * reservoir.density / h * odd_power_tail(h, n, 3) * np.outer(a, a)[None]
    return SeriesResult(value, n, bound, rtol)


def dynamic_stiffness(reservoir: Reservoir, shapes, omega, *, rtol: float = DEFAULT_RTOL) -> SeriesResult:
    """S_ij(omega) = -omega^2 A_ij(omega): force on the water along phi_i per unit displacement of shape j.

    The seed's eq. (8) with its sign fixed (docs/hydro.md): Re S < 0 is added mass, Im S > 0
    (omega > 0) is power leaving the dam, (omega / 2) q^H Im(S) q per unit width. Shape (w, k, k)
    [N/m per metre of width, per unit phi_i phi_j]; ``bound`` scaled by max omega^2.
    """
    omega = _omegas(omega)
    A = added_mass(reservoir, shapes, omega, rtol=rtol)
    return SeriesResult(-(omega**2)[:, None, None] * A.value, A.n_terms, A.bound * float(np.max(omega**2)), rtol)

"""Analytic vibration modes of uniform bars: rods, Euler-Bernoulli and Timoshenko beams.

Every mode is a closed-form combination of four (two for rods) elementary solutions of the
field equation at its frequency,

    rod:      u = a1 cos kx + a2 sin kx,                               omega = c k
    bending:  w = a1 cos bx + a2 sin bx + a3 exp(-a x) + a4 exp(-a (L - x))

(exponentials scaled so that none overflows, so high modes keep full precision; above the
Timoshenko cut-off frequency the last two become cos a'x, sin a'x). Imposing the two end
conditions at each end gives a 2x2 (rod) or 4x4 (beam) matrix B(omega); the frequency equation
is det B = 0, solved numerically (scan for sign changes, then Brent), and the coefficients a are
the null vector of B at the root. Mass and stiffness matrices are then integrated from the
shapes (``bar.rayleigh_ritz``), so their diagonality is a check of the roots and shapes, not an
assumption. Supports and the conventions are those of ``viz3d.flexible``.

Frequency equations that come out (x = 0 is the first support, x = L the second; beta = m_bar / m
for an end mass m at x = L):

==========================  ===================================================  ==========
set                         frequency equation                                   thesis
==========================  ===================================================  ==========
rod free-free               sin kL = 0 (k = i pi / L, rigid i = 0 excluded)       (9.26)
rod clamped-free            cos kL = 0 (k = (2i - 1) pi / 2L)                     (5.25)
rod clamped-clamped         sin kL = 0
rod clamped + mass at L     kL tan kL = beta                                      (5.11)
rod free + mass at L        tan kL = -kL / beta (phi = cos kx)                    (9.19)*
EB cantilever               cos lL cosh lL = -1                                   (8.8)
EB free-free                cos lL cosh lL = 1 (two rigid modes excluded)
EB pinned-pinned            sin lL = 0
EB pinned-free              tan lL = tanh lL (rigid rotation excluded)            (10.9)
EB cantilever + tip mass    1 + cos cosh + (lL / beta)(cos sinh - sin cosh) = 0   (5.36)
Timoshenko                  det B(omega) = 0 with the shapes of Huang (1961)      (8.10-12)
==========================  ===================================================  ==========

(*) the thesis prints ``-(c / (omega L)) tan(omega L / c) = m2 / m1``; the right-hand side must be
m1 / m2 (impactor over bar), as the end condition m1 u_tt(L) = -EA u_x(L) gives and as the
zero-momentum property (9.20) requires (digest, Appendix A item 19). The two agree only at
beta = 1. With the printed form the modes are not orthogonal with the end mass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.flexible.bar import BarModel, Material, PointMass, Section, peak_points, rayleigh_ritz, shear_stiffness

#: Elementary function codes: cos(s x), sin(s x), exp(-s x), exp(-s (L - x)).
COS, SIN, EXP_LEFT, EXP_RIGHT = 0, 1, 2, 3

#: First scan point of the dimensionless wavenumber (kL, lambda L or beta L); excludes the rigid
#: root 0 while admitting end masses up to ~1e5 bar masses (rod root kL ~ sqrt(m_bar / m)).
SCAN_START = 1.0e-3 * np.sqrt(2.0)  # irrational offset: grid points never land on i pi exactly
#: Largest end mass / bar mass whose first root lies above SCAN_START (rod: kL ~ sqrt(m_bar / m)).
MAX_END_MASS_RATIO = 1.0e5
#: Scan steps per pi of the dimensionless wavenumber; roots of one family are ~pi apart, so
#: this resolves roots closer than pi / 32 (Timoshenko's two spectra interleave above cut-off).
SCAN_STEPS_PER_PI = 32
#: Stop scanning (and raise) after this many multiples of pi beyond n_modes.
SCAN_EXTRA_PI = 50
#: Half-width (relative) of the window skipped around the Timoshenko cut-off frequency, where
#: the exponential solutions degenerate into polynomials.
CUTOFF_GAP = 1.0e-9
#: A root whose boundary matrix keeps sigma_min / sigma_max above this did not converge.
NULL_SPACE_RTOL = 1.0e-8
#: Quadrature panels span at most this phase of the fastest elementary function.
PANEL_PHASE = np.pi / 2.0
#: At least this many quadrature panels.
MIN_PANELS = 4
#: Normalizations of analytic shapes: unit generalized mass, or unit peak displacement.
NORMALIZATIONS = ("mass", "unit")


# ----------------------------------------------------------------------------------------------
# the basis: closed-form shapes as sums of elementary functions
# ----------------------------------------------------------------------------------------------
def elementary(types: IntArray, rates: FloatArray, x: FloatArray, order: int, length: float) -> FloatArray:
    """d^order/dx^order of the elementary functions at ``x`` (p,); ``types``, ``rates`` (...): (p, ...)."""
    if x.size == 1 and rates.ndim == 1 and rates.size <= 8:  # one point (end conditions): scalar math, 10x faster
        return _elementary_at(types.tolist(), rates.tolist(), float(x.reshape(-1)[0]), order, length)[None]
    X = x.reshape((-1,) + (1,) * rates.ndim)
    s = rates[None]
    c, sn = np.cos(s * X), np.sin(s * X)
    d_cos = (c, -sn, -c, sn)[order % 4]
    d_sin = (sn, c, -sn, -c)[order % 4]
    e_left = (-1.0) ** order * np.exp(-s * X)
    e_right = np.exp(-s * (length - X))
    t = types[None]
    f = np.where(t == COS, d_cos, np.where(t == SIN, d_sin, np.where(t == EXP_LEFT, e_left, e_right)))
    return f * s**order


def _elementary_at(types: list, rates: list, x: float, order: int, length: float) -> FloatArray:
    """``elementary`` at one point ``x`` for (m,) types and rates, with scalar math."""
    k = order % 4
    out = np.empty(len(rates))
    for j, (t, s) in enumerate(zip(types, rates)):
        if t == COS or t == SIN:
            c, sn = math.cos(s * x), math.sin(s * x)
            f = (c, -sn, -c, sn)[k] if t == COS else (sn, c, -sn, -c)[k]
        elif t == EXP_LEFT:
            f = (-1.0) ** order * math.exp(-s * x)
        else:
            f = math.exp(-s * (length - x))
        out[j] = f * s**order
    return out


@dataclass(frozen=True)
class TrigExpBasis:
    """Analytic mode shapes, row i: ``u_i(x) = sum_j u_coef[i, j] f(types[i, j], rates[i, j], x)``.

    Attributes
    ----------
    length : float
        L [m].
    omega : ndarray, shape (n,)
        Root of the frequency equation of each shape [rad/s].
    types : ndarray of int, shape (n, m)
        Elementary function codes (COS, SIN, EXP_LEFT, EXP_RIGHT) of the displacement terms.
    rates : ndarray, shape (n, m)
        Their wavenumbers [1/m].
    u_coef : ndarray, shape (n, m)
        Displacement coefficients [units of u per unit q].
    psi_types, psi_coef : ndarray, shape (n, m), or None
        Section-rotation terms (same rates) for bending bases; None for rods.
    """

    length: float
    omega: FloatArray
    types: IntArray
    rates: FloatArray
    u_coef: FloatArray
    psi_types: IntArray | None = None
    psi_coef: FloatArray | None = None

    @property
    def n_basis(self) -> int:
        return self.u_coef.shape[0]

    def evaluate(self, x: FloatArray, field: str, order: int) -> FloatArray:
        """Derivative ``order`` of ``field`` ("u" or "psi") of every shape at ``x`` (p,): (p, n)."""
        if field == "u":
            types, coef = self.types, self.u_coef
        elif field == "psi" and self.psi_coef is not None:
            types, coef = self.psi_types, self.psi_coef
        else:
            raise ValueError(f"field {field!r} not available in this basis")
        return np.einsum("pij,ij->pi", elementary(types, self.rates, np.asarray(x, float), order, self.length), coef)

    def breakpoints(self) -> FloatArray:
        """Uniform panels, each at most a quarter wavelength of the fastest term."""
        n_panels = max(MIN_PANELS, int(np.ceil(self.rates.max() * self.length / PANEL_PHASE)))
        return np.linspace(0.0, self.length, n_panels + 1)

    def scaled(self, factor: FloatArray) -> TrigExpBasis:
        """The same shapes multiplied by ``factor`` (n,)."""
        psi = None if self.psi_coef is None else self.psi_coef * factor[:, None]
        return TrigExpBasis(self.length, self.omega, self.types, self.rates, self.u_coef * factor[:, None], self.psi_types, psi)


@dataclass(frozen=True)
class Columns:
    """The elementary solutions at one frequency: (m,) arrays, as in ``TrigExpBasis`` rows."""

    types: IntArray
    rates: FloatArray
    u_coef: FloatArray
    psi_types: IntArray | None = None
    psi_coef: FloatArray | None = None

    def values(self, x: float, field: str, order: int, length: float) -> FloatArray:
        """Derivative ``order`` of ``field`` of each column at the point ``x``: (m,)."""
        types, coef = (self.types, self.u_coef) if field == "u" else (self.psi_types, self.psi_coef)
        return elementary(types, self.rates, np.array([x]), order, length)[0] * coef


def _bending_columns(beta: float, alpha2: float, g_beta: float, g_alpha: float) -> Columns:
    """w: cos bx, sin bx and exp(-a x), exp(-a (L - x)) (alpha2 > 0) or cos a'x, sin a'x (alpha2 < 0);
    psi = g_beta (-sin, cos) and g_alpha (-exp, exp) or g_alpha (-sin, cos) of the same arguments."""
    alpha = np.sqrt(abs(alpha2))
    if alpha2 > 0:
        types, psi_types = [COS, SIN, EXP_LEFT, EXP_RIGHT], [SIN, COS, EXP_LEFT, EXP_RIGHT]
    else:
        types, psi_types = [COS, SIN, COS, SIN], [SIN, COS, SIN, COS]
    return Columns(
        np.array(types), np.array([beta, beta, alpha, alpha]), np.ones(4),
        np.array(psi_types), np.array([-g_beta, g_beta, -g_alpha, g_alpha]),
    )


# ----------------------------------------------------------------------------------------------
# the three theories: frequency of a scan parameter, elementary solutions, end conditions
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rod:
    """Elementary rod, ``rho A u_tt = EA u_xx``: non-dispersive, omega = c k (thesis 4.1, 5.2)."""

    length: float
    material: Material
    section: Section
    name = "rod"
    kind = "axial"

    def omega(self, s: float) -> float:
        """Frequency [rad/s] at the dimensionless wavenumber s = kL."""
        return self.material.wave_speed * s / self.length

    def cutoff(self) -> float | None:
        return None

    def columns(self, omega: float) -> Columns:
        k = omega / self.material.wave_speed
        return Columns(np.array([COS, SIN]), np.array([k, k]), np.ones(2))

    def end_rows(self, cols: Columns, x: float, normal: float, support: str, mass: float, omega: float) -> list:
        """Fixed: u = 0. Free with end mass m: normal EA u' - m omega^2 u = 0 (m u_tt = -normal N)."""
        u = cols.values(x, "u", 0, self.length)
        if support in ("clamped", "pinned"):
            return [u]
        EA = self.material.E * self.section.area
        return [normal * EA * cols.values(x, "u", 1, self.length) - mass * omega**2 * u]


@dataclass(frozen=True)
class _Beam:
    """End conditions shared by the two beam theories (w deflection, psi section rotation)."""

    length: float
    material: Material
    section: Section
    kind = "bending"

    def end_rows(self, cols: Columns, x: float, normal: float, support: str, mass: float, omega: float) -> list:
        """Clamped: w = psi = 0. Pinned: w = 0, M = 0. Free with end mass m: M = 0 and
        -normal V + m omega^2 w = 0 (the mass is driven by the shear force V = -dM/dx)."""
        L = self.length
        w, psi, dpsi = cols.values(x, "u", 0, L), cols.values(x, "psi", 0, L), cols.values(x, "psi", 1, L)
        if support == "clamped":
            return [w, psi]
        if support == "pinned":
            return [w, dpsi]
        return [dpsi, -normal * self.shear(cols, x) + mass * omega**2 * w]


@dataclass(frozen=True)
class EulerBernoulli(_Beam):
    """``rho A w_tt + EI w_xxxx = 0``: omega = c_t lambda^2, c_t = sqrt(EI / rho A) (thesis 5.5-5.8)."""

    name = "euler_bernoulli"

    @property
    def c_t(self) -> float:
        return float(np.sqrt(self.material.E * self.section.second_moment / (self.material.rho * self.section.area)))

    def omega(self, s: float) -> float:
        """Frequency [rad/s] at s = lambda L."""
        return self.c_t * (s / self.length) ** 2

    def cutoff(self) -> float | None:
        return None

    def columns(self, omega: float) -> Columns:
        lam = np.sqrt(omega / self.c_t)
        return _bending_columns(lam, lam**2, lam, lam)  # psi = w'

    def shear(self, cols: Columns, x: float) -> FloatArray:
        return -self.material.E * self.section.second_moment * cols.values(x, "psi", 2, self.length)


@dataclass(frozen=True)
class Timoshenko(_Beam):
    """Shear-deformable beam with rotary inertia (Huang 1961; thesis 8.10-8.12):

        rho A w_tt = k G A (w'' - psi'),     rho I psi_tt = EI psi'' + k G A (w' - psi).

    With ``w, psi ~ exp(s x)``: ``s^4 + omega^2 (rho/E + rho/kG) s^2 - (rho A omega^2 / EI)(1 - omega^2 / omega_c^2) = 0``,
    ``omega_c = sqrt(k G A / rho I)`` the cut-off; ``psi = (s + rho A omega^2 / (k G A s)) w`` per root.
    Below omega_c one pair s = +-a is real and one s = +-i b imaginary; above, both are imaginary.
    The scan parameter is s = b L on the lower (flexural) branch, whose omega(b) is monotonic.
    """

    name = "timoshenko"

    @property
    def _kGA(self) -> float:
        return shear_stiffness(self.material, self.section)

    def cutoff(self) -> float | None:
        """Dimensionless b L at the cut-off frequency omega_c."""
        rho, E, kG = self.material.rho, self.material.E, self._kGA / self.section.area
        return float(np.sqrt(self._omega_c2 * (rho / E + rho / kG)) * self.length)

    def omega(self, s: float) -> float:
        """Lower-branch frequency [rad/s] at s = b L (the stable root of a quadratic in omega^2)."""
        rho, E, kG = self.material.rho, self.material.E, self._kGA / self.section.area
        rhoA_EI = rho * self.section.area / (E * self.section.second_moment)
        b2 = (s / self.length) ** 2
        a1 = (rho / E + rho / kG) * b2 + rhoA_EI
        a2 = rho**2 / (E * kG)
        return float(np.sqrt(2.0 * b2**2 / (a1 + np.sqrt(a1**2 - 4.0 * a2 * b2**2))))

    def columns(self, omega: float) -> Columns:
        rho, E, kG = self.material.rho, self.material.E, self._kGA / self.section.area
        a = omega**2 * (rho / E + rho / kG)
        c = rho * self.section.area * omega**2 / (E * self.section.second_moment) * (1.0 - omega**2 / self._omega_c2)
        root = np.sqrt(a**2 + 4.0 * c)
        beta2, alpha2 = 0.5 * (a + root), 2.0 * c / (a + root)  # s^2 = -beta2 and s^2 = alpha2
        beta, alpha = np.sqrt(beta2), np.sqrt(abs(alpha2))
        r = rho * omega**2 / kG  # rho A omega^2 / (k G A)
        g_alpha = alpha + r / alpha if alpha2 > 0 else alpha - r / alpha
        return _bending_columns(beta, alpha2, beta - r / beta, g_alpha)

    @property
    def _omega_c2(self) -> float:
        return self._kGA / (self.material.rho * self.section.second_moment)

    def shear(self, cols: Columns, x: float) -> FloatArray:
        L = self.length
        return self._kGA * (cols.values(x, "u", 1, L) - cols.values(x, "psi", 0, L))


THEORY_CLASSES = {"rod": Rod, "euler_bernoulli": EulerBernoulli, "timoshenko": Timoshenko}


# ----------------------------------------------------------------------------------------------
# frequency equation: det of the (row-normalised) boundary matrix, scanned and bracketed
# ----------------------------------------------------------------------------------------------
def boundary_matrix(theory, omega: float, supports: tuple[str, str], end_masses: tuple[float, float]) -> FloatArray:
    """B(omega): end conditions (rows, each scaled to unit norm) on the elementary solutions (columns)."""
    cols = theory.columns(omega)
    rows = []
    for x, normal, support, mass in zip((0.0, theory.length), (-1.0, 1.0), supports, end_masses):
        rows += theory.end_rows(cols, x, normal, support, mass, omega)
    B = np.array(rows)
    return B / np.linalg.norm(B, axis=1, keepdims=True)


def _scan_intervals(theory, s_max: float) -> list[tuple[float, float]]:
    """Consecutive scan points up to ``s_max``, minus a small window around the cut-off."""
    grid = np.arange(SCAN_START, s_max, np.pi / SCAN_STEPS_PER_PI)
    s_c = theory.cutoff()
    if s_c is None or s_c >= s_max:
        return list(zip(grid[:-1], grid[1:]))
    lo, hi = s_c * (1 - CUTOFF_GAP), s_c * (1 + CUTOFF_GAP)
    grid = np.sort(np.concatenate([grid[(grid < lo) | (grid > hi)], [lo, hi]]))
    return [(a, b) for a, b in zip(grid[:-1], grid[1:]) if (a, b) != (lo, hi)]


def frequency_roots(theory, n_modes: int, supports, end_masses) -> FloatArray:
    """The lowest ``n_modes`` non-zero roots omega (n_modes,) [rad/s] of det B(omega) = 0.

    Scans the dimensionless wavenumber for sign changes of det B (rows normalised, so det B is a
    continuous function without poles on each side of the cut-off) and refines each by Brent.
    """
    from scipy.optimize import brentq

    def det(s: float) -> float:
        return float(np.linalg.det(boundary_matrix(theory, theory.omega(s), supports, end_masses)))

    roots: list[float] = []
    s_max = (n_modes + SCAN_EXTRA_PI) * np.pi
    b_prev, f_prev = None, None
    for a, b in _scan_intervals(theory, s_max):
        fa = f_prev if a == b_prev else det(a)  # consecutive intervals share their end point
        fb = det(b)
        b_prev, f_prev = b, fb
        if fa == 0.0:
            roots.append(a)
        elif fa * fb < 0:
            roots.append(brentq(det, a, b, xtol=1e-15, rtol=4 * np.finfo(float).eps))
        if len(roots) == n_modes:
            return np.array([theory.omega(s) for s in roots])
    raise RuntimeError(f"found {len(roots)} of {n_modes} roots below s = {s_max:.1f}")


def _null_vector(theory, omega: float, supports, end_masses) -> FloatArray:
    _, sigma, Vh = np.linalg.svd(boundary_matrix(theory, omega, supports, end_masses))
    if sigma[-1] > NULL_SPACE_RTOL * sigma[0]:
        raise RuntimeError(f"boundary matrix not singular at omega = {omega} (sigma {sigma})")
    return Vh[-1]


def modal_basis(theory, omegas: FloatArray, supports, end_masses) -> TrigExpBasis:
    """Closed-form shapes (unnormalised) at the roots ``omegas``: elementary solutions times null vectors."""
    cols = [theory.columns(omega) for omega in omegas]
    a = np.array([_null_vector(theory, omega, supports, end_masses) for omega in omegas])
    types, rates = np.array([c.types for c in cols]), np.array([c.rates for c in cols])
    u_coef = a * np.array([c.u_coef for c in cols])
    if cols[0].psi_coef is None:
        return TrigExpBasis(theory.length, np.asarray(omegas), types, rates, u_coef)
    psi_types, psi_coef = np.array([c.psi_types for c in cols]), a * np.array([c.psi_coef for c in cols])
    return TrigExpBasis(theory.length, np.asarray(omegas), types, rates, u_coef, psi_types, psi_coef)


def peak_amplitudes(basis: TrigExpBasis) -> FloatArray:
    """Signed value of each shape's displacement at its largest |u| on [0, L] (n,), refined locally."""
    from scipy.optimize import minimize_scalar
    x = peak_points(basis)
    U = basis.evaluate(x, "u", 0)
    out = np.empty(basis.n_basis)
    for i, j in enumerate(np.argmax(np.abs(U), axis=0)):
        u_i = _shape_function(basis, i)
        lo, hi = x[max(j - 1, 0)], x[min(j + 1, len(x) - 1)]
        res = minimize_scalar(lambda t, u=u_i: -abs(u(t)), bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-12 * basis.length})
        out[i] = u_i(res.x if -res.fun > abs(U[j, i]) else x[j])
    return out


def _shape_function(basis: TrigExpBasis, i: int):
    """x -> u_i(x) for one scalar x."""
    return lambda t: float(basis.evaluate(np.array([t]), "u", 0)[0, i])


# ----------------------------------------------------------------------------------------------
# public constructors and the registry
# ----------------------------------------------------------------------------------------------
def analytic_modes(
    theory: str,
    length: float,
    material: Material,
    section: Section,
    n_modes: int,
    supports: tuple[str, str],
    *,
    end_masses: tuple[float, float] = (0.0, 0.0),
    normalization: str = "mass",
) -> BarModel:
    """The lowest ``n_modes`` elastic modes of a uniform bar as a ``BarModel`` (q = modal amplitudes).

    Parameters
    ----------
    theory : str
        "rod", "euler_bernoulli" or "timoshenko".
    length : float
        L [m].
    material, section : Material, Section
    n_modes : int
        Number of elastic modes (zero-frequency rigid modes are never included).
    supports : tuple of str
        End conditions at x = 0 and x = L ("free", "clamped", "pinned").
    end_masses : tuple of float
        Point masses [kg] joined to the ends x = 0 and x = L; only free ends may carry one.
    normalization : str
        "mass": generalized mass 1 (``M = I``, ``K = diag(omega^2)`` up to quadrature round-off;
        Phi in 1/sqrt(kg), q in m sqrt(kg)). "unit": peak |u| on [0, L] equal to 1 (Phi
        dimensionless, q in m), the thesis's scaling (sin, cos of unit amplitude; tip-normalised
        cantilever shapes, eq. 9.55). Each shape is positive at its peak.

    Returns
    -------
    BarModel
        With ``basis`` a ``TrigExpBasis`` (``basis.omega`` holds the roots), ``T = I``.
    """
    if normalization not in NORMALIZATIONS:
        raise ValueError(f"normalization {normalization!r}; valid: {NORMALIZATIONS}")
    m_bar = material.rho * section.area * length
    for support, mass in zip(supports, end_masses):
        if mass != 0.0 and support != "free":
            raise ValueError(f"an end mass needs a free end, not {support!r}")
        if not 0.0 <= mass <= MAX_END_MASS_RATIO * m_bar:
            raise ValueError(f"end mass {mass} kg outside [0, {MAX_END_MASS_RATIO:g} x bar mass]")
    model = THEORY_CLASSES[theory](length, material, section)
    omegas = frequency_roots(model, n_modes, supports, end_masses)
    basis = modal_basis(model, omegas, supports, end_masses)
    point_masses = tuple(PointMass(x, m) for x, m in zip((0.0, length), end_masses) if m > 0)
    M, K = rayleigh_ritz(theory, material, section, basis, point_masses)
    if normalization == "mass":
        scale = np.sign(peak_amplitudes(basis)) / np.sqrt(np.diag(M))
    else:
        scale = 1.0 / peak_amplitudes(basis)
    basis = basis.scaled(scale)
    M, K = scale[:, None] * M * scale[None, :], scale[:, None] * K * scale[None, :]
    label = f"{theory} {supports[0]}-{supports[1]}" + (f", end masses {end_masses} kg" if any(end_masses) else "")
    return BarModel(model.kind, theory, length, material, section, tuple(supports), basis, np.eye(n_modes), M, K,
                    point_masses, f"{label}, {n_modes} analytic modes ({normalization})")


@dataclass(frozen=True)
class ModeSet:
    """A registered analytic mode family: a theory, the supports and whether a mass sits at x = L.

    Call it as ``mode_set(length, material, section, n_modes, tip_mass=..., normalization=...)``.
    """

    theory: str
    supports: tuple[str, str]
    with_tip_mass: bool = False

    def __call__(self, length: float, material: Material, section: Section, n_modes: int, *,
                 tip_mass: float = 0.0, normalization: str = "mass") -> BarModel:
        if self.with_tip_mass != (tip_mass > 0):
            raise ValueError("this mode set needs tip_mass > 0" if self.with_tip_mass else "this mode set has no tip mass")
        return analytic_modes(self.theory, length, material, section, n_modes, self.supports,
                              end_masses=(0.0, tip_mass), normalization=normalization)


#: name -> analytic mode set. "..._mass" sets carry a rigid mass at x = L (a joined impactor);
#: the composite rod sets are the thesis's "contact modes" (5.11, clamped far end) and the
#: free-bar composite body (9.17-9.20, free far end).
MODE_SETS = {
    "axial_free_free": ModeSet("rod", ("free", "free")),
    "axial_clamped_free": ModeSet("rod", ("clamped", "free")),
    "axial_clamped_clamped": ModeSet("rod", ("clamped", "clamped")),
    "axial_clamped_mass": ModeSet("rod", ("clamped", "free"), with_tip_mass=True),
    "axial_free_mass": ModeSet("rod", ("free", "free"), with_tip_mass=True),
    "bending_cantilever": ModeSet("euler_bernoulli", ("clamped", "free")),
    "bending_free_free": ModeSet("euler_bernoulli", ("free", "free")),
    "bending_pinned_pinned": ModeSet("euler_bernoulli", ("pinned", "pinned")),
    "bending_pinned_free": ModeSet("euler_bernoulli", ("pinned", "free")),
    "bending_clamped_clamped": ModeSet("euler_bernoulli", ("clamped", "clamped")),
    "bending_cantilever_mass": ModeSet("euler_bernoulli", ("clamped", "free"), with_tip_mass=True),
    "timoshenko_cantilever": ModeSet("timoshenko", ("clamped", "free")),
    "timoshenko_pinned_pinned": ModeSet("timoshenko", ("pinned", "pinned")),
    "timoshenko_free_free": ModeSet("timoshenko", ("free", "free")),
    "timoshenko_cantilever_mass": ModeSet("timoshenko", ("clamped", "free"), with_tip_mass=True),
}


def mode_set(name: str) -> ModeSet:
    """The registered mode set ``name`` (KeyError lists the valid names)."""
    try:
        return MODE_SETS[name]
    except KeyError:
        raise KeyError(f"unknown mode set {name!r}; valid: {', '.join(MODE_SETS)}") from None

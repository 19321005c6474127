"""The common linear model of a straight flexible bar: material, section, ``BarModel``, reduction.

A ``BarModel`` is a basis of shape functions (analytic modes or finite-element interpolation)
times a matrix ``T`` that maps the generalized coordinates ``q`` to the basis coefficients, plus
the mass and stiffness matrices in ``q``. Conventions (axes, signs, units) are in the docstring
of ``viz3d.flexible``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from viz3d._typing import FloatArray

#: Deformation kinds and the beam/rod theories each admits.
THEORIES = {"axial": ("rod",), "bending": ("euler_bernoulli", "timoshenko")}
#: End conditions; for an axial bar "pinned" and "clamped" both fix the displacement.
SUPPORTS = ("free", "clamped", "pinned")

#: Timoshenko's shear coefficient of a rectangle (the thesis uses it, Ch. 8.4.1); Cowper (1966)
#: gives 10(1 + nu)/(12 + 11 nu) = 0.850 at nu = 0.3.
SHEAR_COEFFICIENT_RECTANGLE = 5.0 / 6.0
#: Solid circle, Timoshenko/Mindlin's value; Cowper (1966) gives 6(1 + nu)/(7 + 6 nu) = 0.886 at nu = 0.3.
SHEAR_COEFFICIENT_CIRCLE = 9.0 / 10.0

#: Gauss-Legendre points per quadrature panel. Bases choose panels so that 12 points integrate
#: their products to round-off (exact for the FE polynomials, degree <= 7; a quarter wavelength of
#: the fastest analytic mode per panel).
QUAD_POINTS = 12
#: Relative asymmetry of M or K above which a model is rejected (they are built symmetric to round-off).
SYMMETRY_RTOL = 1e-10
#: Points closer than this to [0, L] (relative to L) are clipped onto the bar; farther ones are errors.
X_RTOL = 1e-12
#: Displacement constraints each support imposes: (axial, bending).
SUPPORT_CONSTRAINTS = {"free": (0, 0), "pinned": (1, 1), "clamped": (1, 2)}
#: Samples per quadrature panel (a quarter wavelength or one element) when locating the peak of a
#: shape (its sign, and "unit" normalization, which then refines the peak locally).
PEAK_SAMPLES = 8


@dataclass(frozen=True)
class Material:
    """Linear elastic isotropic material.

    Attributes
    ----------
    E : float
        Young's modulus [Pa].
    rho : float
        Density [kg/m^3].
    nu : float
        Poisson's ratio [-]; enters only through the shear modulus.
    """

    E: float
    rho: float
    nu: float

    def __post_init__(self):
        if not (self.E > 0 and self.rho > 0 and -1.0 < self.nu < 0.5):
            raise ValueError(f"material needs E > 0, rho > 0, -1 < nu < 0.5; got {self}")

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)) [Pa]."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def wave_speed(self) -> float:
        """Axial (bar) wave speed c = sqrt(E / rho) [m/s]."""
        return float(np.sqrt(self.E / self.rho))


@dataclass(frozen=True)
class Section:
    """Cross-section of a bar.

    Attributes
    ----------
    area : float
        A [m^2].
    second_moment : float
        I about the neutral axis normal to the bending plane [m^4].
    depth : float
        Depth in the bending plane [m]; the extreme fibre is at depth / 2.
    shear_coefficient : float
        Timoshenko shear coefficient k [-] (shear area k A).
    """

    area: float
    second_moment: float
    depth: float
    shear_coefficient: float = SHEAR_COEFFICIENT_RECTANGLE

    def __post_init__(self):
        if not (self.area > 0 and self.second_moment > 0 and self.depth > 0 and self.shear_coefficient > 0):
            raise ValueError(f"section needs positive area, second moment, depth and shear coefficient; got {self}")

    @classmethod
    def rectangle(cls, width: float, depth: float, shear_coefficient: float = SHEAR_COEFFICIENT_RECTANGLE) -> Section:
        """``width`` x ``depth`` rectangle [m], bending in the ``depth`` direction: I = width depth^3 / 12."""
        return cls(width * depth, width * depth**3 / 12.0, depth, shear_coefficient)

    @classmethod
    def circle(cls, diameter: float, shear_coefficient: float = SHEAR_COEFFICIENT_CIRCLE) -> Section:
        """Solid circle of ``diameter`` [m]: A = pi d^2 / 4, I = pi d^4 / 64."""
        return cls(np.pi * diameter**2 / 4.0, np.pi * diameter**4 / 64.0, diameter, shear_coefficient)

    @property
    def radius_of_gyration(self) -> float:
        """r = sqrt(I / A) [m]."""
        return float(np.sqrt(self.second_moment / self.area))


def shear_stiffness(material: Material, section: Section) -> float:
    """Timoshenko shear stiffness ``k G A`` [N]."""
    return section.shear_coefficient * material.shear_modulus * section.area


@dataclass(frozen=True)
class PointMass:
    """A rigid point mass attached to the bar (an impactor joined to it, a tip mass).

    Attributes
    ----------
    x : float
        Position along the bar [m], 0 <= x <= L.
    mass : float
        [kg], > 0. Only its translation (along u for axial bars, w for bending) has inertia.
    """

    x: float
    mass: float

    def __post_init__(self):
        if not self.mass > 0:
            raise ValueError(f"point mass must be positive, got {self.mass}")


class ShapeBasis(Protocol):
    """Shape functions of a bar; ``BarModel`` combines them with its matrix ``T``.

    Implementations: ``viz3d.flexible.modes.TrigExpBasis`` (analytic modes) and
    ``viz3d.flexible.fe.FEBasis`` (finite-element interpolation).
    """

    length: float
    n_basis: int

    def evaluate(self, x: FloatArray, field: str, order: int) -> FloatArray:
        """Derivative ``order`` (>= 0, d/dx) of ``field`` at ``x`` (m,): shape (m, n_basis).

        ``field`` is "u" (axial displacement or transverse deflection) or "psi" (section rotation,
        bending only; ``w'`` for Euler-Bernoulli bases).
        """
        ...

    def breakpoints(self) -> FloatArray:
        """Quadrature panel edges from 0 to ``length`` (element nodes, or a mode-dependent grid)."""
        ...


def gauss_points(breakpoints: FloatArray, n_points: int = QUAD_POINTS) -> tuple[FloatArray, FloatArray]:
    """Composite Gauss-Legendre rule on the panels ``breakpoints`` (p + 1,): points and weights (p n,)."""
    xi, wi = np.polynomial.legendre.leggauss(n_points)
    a, b = np.asarray(breakpoints[:-1]), np.asarray(breakpoints[1:])
    half = 0.5 * (b - a)
    x = (0.5 * (a + b))[:, None] + half[:, None] * xi[None, :]
    return x.ravel(), (half[:, None] * wi[None, :]).ravel()


def rayleigh_ritz(
    theory: str, material: Material, section: Section, basis: ShapeBasis, point_masses: tuple[PointMass, ...] = ()
) -> tuple[FloatArray, FloatArray]:
    """Mass and stiffness matrices of the basis functions, from the energy functionals by quadrature.

    ``T = 1/2 qd^T M qd``, ``U = 1/2 q^T K q`` with

    * rod: ``T = 1/2 int rho A ud^2 + ...``, ``U = 1/2 int EA u'^2``;
    * Euler-Bernoulli: ``T = 1/2 int rho A wd^2``, ``U = 1/2 int EI w''^2`` (no rotary inertia);
    * Timoshenko: ``T = 1/2 int (rho A wd^2 + rho I psid^2)``, ``U = 1/2 int (EI psi'^2 + k G A (w' - psi)^2)``

    (thesis eqs. 8.9, 8.12), plus ``1/2 m ud(x_m)^2`` per point mass.

    Returns
    -------
    M : ndarray, shape (n_basis, n_basis) [kg, in the units of the basis]
    K : ndarray, shape (n_basis, n_basis) [N/m, likewise]
    """
    x, wq = gauss_points(basis.breakpoints())
    rhoA, rhoI = material.rho * section.area, material.rho * section.second_moment
    U = basis.evaluate(x, "u", 0)
    M = rhoA * (U.T * wq) @ U
    if theory == "rod":
        D = basis.evaluate(x, "u", 1)
        K = material.E * section.area * (D.T * wq) @ D
    elif theory == "euler_bernoulli":
        D = basis.evaluate(x, "u", 2)
        K = material.E * section.second_moment * (D.T * wq) @ D
    elif theory == "timoshenko":
        P, dP = basis.evaluate(x, "psi", 0), basis.evaluate(x, "psi", 1)
        gamma = basis.evaluate(x, "u", 1) - P
        kGA = shear_stiffness(material, section)
        M = M + rhoI * (P.T * wq) @ P
        K = material.E * section.second_moment * (dP.T * wq) @ dP + kGA * (gamma.T * wq) @ gamma
    else:
        raise ValueError(f"unknown theory {theory!r}; valid: rod, euler_bernoulli, timoshenko")
    for pm in point_masses:
        phi = basis.evaluate(np.array([pm.x]), "u", 0)
        M = M + pm.mass * phi.T @ phi
    return _symmetric(M), _symmetric(K)


def _symmetric(A: FloatArray) -> FloatArray:
    return 0.5 * (A + A.T)


def _frozen(a) -> FloatArray:
    out = np.array(a, dtype=float)
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class BarModel:
    """Linear model of a straight bar in one deformation kind, with coordinates ``q`` (n,).

    The field is ``u(x, t) = Phi(x) q(t)`` with ``Phi(x) = basis(x) @ T``. See ``viz3d.flexible``
    for the axes, sign conventions and units.

    Attributes
    ----------
    kind : str
        "axial" (displacement u along the bar) or "bending" (deflection w in the plane of
        ``section.depth``).
    theory : str
        "rod" for axial bars; "euler_bernoulli" or "timoshenko" for bending.
    length : float
        L [m]; x runs from 0 (the reference end) to L.
    material : Material
    section : Section
    supports : tuple of str, length 2
        End conditions at x = 0 and x = L, each in ``SUPPORTS``.
    basis : ShapeBasis
        Shape functions (n_basis of them).
    T : ndarray, shape (n_basis, n)
        Basis coefficients per coordinate.
    M : ndarray, shape (n, n)
        Mass matrix [kg when q is in metres; see ``viz3d.flexible`` for modal units]. Includes
        ``point_masses``.
    K : ndarray, shape (n, n)
        Stiffness matrix, same units over s^2.
    point_masses : tuple of PointMass
        Rigid masses joined to the bar (a composite "bar + impactor" body).
    label : str
        Human-readable description (mode set or mesh).
    """

    kind: str
    theory: str
    length: float
    material: Material
    section: Section
    supports: tuple[str, str]
    basis: ShapeBasis = field(repr=False)
    T: FloatArray = field(repr=False)
    M: FloatArray = field(repr=False)
    K: FloatArray = field(repr=False)
    point_masses: tuple[PointMass, ...] = ()
    label: str = ""

    def __post_init__(self):
        if self.theory not in THEORIES.get(self.kind, ()):
            raise ValueError(f"kind {self.kind!r} with theory {self.theory!r}; valid: {THEORIES}")
        if len(self.supports) != 2 or any(s not in SUPPORTS for s in self.supports):
            raise ValueError(f"supports must be two of {SUPPORTS}, got {self.supports}")
        for key in ("T", "M", "K"):
            object.__setattr__(self, key, _frozen(getattr(self, key)))
        n = self.T.shape[1] if self.T.ndim == 2 else -1
        if self.T.shape != (self.basis.n_basis, n) or self.M.shape != (n, n) or self.K.shape != (n, n):
            raise ValueError(f"shapes: T {self.T.shape}, M {self.M.shape}, K {self.K.shape}, n_basis {self.basis.n_basis}")
        for key in ("M", "K"):
            A = getattr(self, key)
            if np.abs(A - A.T).max() > SYMMETRY_RTOL * max(np.abs(A).max(), 1e-300):
                raise ValueError(f"{key} is not symmetric")
        for pm in self.point_masses:
            if not -X_RTOL * self.length <= pm.x <= self.length * (1 + X_RTOL):
                raise ValueError(f"point mass at x = {pm.x} m is off the bar [0, {self.length}]")

    # ---- sizes and rigid data -------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of generalized coordinates."""
        return self.T.shape[1]

    @property
    def bar_mass(self) -> float:
        """rho A L [kg] (without point masses)."""
        return self.material.rho * self.section.area * self.length

    @property
    def mass(self) -> float:
        """Rigid mass of the body, bar plus point masses [kg]."""
        return self.bar_mass + sum(pm.mass for pm in self.point_masses)

    @property
    def static_moment(self) -> float:
        """int rho A x dx + sum m x_m [kg m], about x = 0."""
        return self.bar_mass * self.length / 2.0 + sum(pm.mass * pm.x for pm in self.point_masses)

    @property
    def inertia_origin(self) -> float:
        """int rho A x^2 dx + sum m x_m^2 [kg m^2]: rigid moment of inertia about x = 0 (slender bar,
        section rotary inertia rho I L excluded)."""
        return self.bar_mass * self.length**2 / 3.0 + sum(pm.mass * pm.x**2 for pm in self.point_masses)

    # ---- fields -----------------------------------------------------------------------------
    def _x(self, x) -> FloatArray:
        x = np.atleast_1d(np.asarray(x, dtype=float))
        tol = X_RTOL * self.length
        if x.ndim != 1 or np.any(x < -tol) or np.any(x > self.length + tol):
            raise ValueError(f"x must be a 1-D array of points in [0, {self.length}] m")
        return np.clip(x, 0.0, self.length)

    def shape(self, x, field: str = "u", order: int = 0) -> FloatArray:
        """Derivative ``order`` of the shape functions of ``field`` ("u" or "psi") at ``x`` (m,): (m, n)."""
        if field == "psi" and self.kind != "bending":
            raise ValueError("psi (section rotation) exists only for bending models")
        return self.basis.evaluate(self._x(x), field, order) @ self.T

    def displacement(self, x) -> FloatArray:
        """Phi(x), shape (m, n): u(x) = Phi q, axial displacement or deflection w [m]."""
        return self.shape(x, "u", 0)

    def slope(self, x) -> FloatArray:
        """w'(x) shape functions (m, n) [rad] (bending only)."""
        self._require("bending", "slope")
        return self.shape(x, "u", 1)

    def rotation(self, x) -> FloatArray:
        """Section rotation psi(x) (m, n) [rad]; equals the slope w' for Euler-Bernoulli (bending only)."""
        self._require("bending", "rotation")
        return self.shape(x, "psi", 0)

    def strain(self, x) -> FloatArray:
        """Strain shape functions (m, n) [-].

        Axial: u'(x). Bending: surface strain at the fibre z = +depth/2 (on the +w side),
        ``-(depth/2) psi'(x)``, i.e. ``-(depth/2) w''`` for Euler-Bernoulli.
        """
        if self.kind == "axial":
            return self.shape(x, "u", 1)
        return -0.5 * self.section.depth * self.shape(x, "psi", 1)

    def axial_force(self, x) -> FloatArray:
        """N(x) = EA u'(x) shape functions (m, n) [N] (axial only; tension positive)."""
        self._require("axial", "axial_force")
        return self.material.E * self.section.area * self.shape(x, "u", 1)

    def bending_moment(self, x) -> FloatArray:
        """M(x) = EI psi'(x) shape functions (m, n) [N m] (bending only)."""
        self._require("bending", "bending_moment")
        return self.material.E * self.section.second_moment * self.shape(x, "psi", 1)

    def shear_force(self, x) -> FloatArray:
        """V(x) = -dM/dx shape functions (m, n) [N]: k G A (w' - psi) (Timoshenko), -EI w''' (Euler-Bernoulli)."""
        self._require("bending", "shear_force")
        if self.theory == "timoshenko":
            return shear_stiffness(self.material, self.section) * (self.shape(x, "u", 1) - self.shape(x, "psi", 0))
        return -self.material.E * self.section.second_moment * self.shape(x, "u", 3)

    def point_force(self, x: float, force: float) -> FloatArray:
        """Generalized force (n,) of a point force [N] along u (axial) or w (bending) at ``x``: Phi(x)^T F."""
        return force * self.displacement([x])[0]

    def _require(self, kind: str, what: str) -> None:
        if self.kind != kind:
            raise ValueError(f"{what} is defined for {kind} models, this one is {self.kind}")

    # ---- spectra and inertia integrals ------------------------------------------------------
    def frequencies(self) -> FloatArray:
        """Natural frequencies omega (n,) [rad/s], ascending, from ``K v = omega^2 M v``; rigid modes give 0."""
        from scipy.linalg import eigh
        omega2 = eigh(self.K, self.M, eigvals_only=True)
        return np.sqrt(np.clip(omega2, 0.0, None))

    def integrate(self, integrand) -> FloatArray:
        """int_0^L integrand(x) dx by the basis's quadrature; ``integrand`` maps (m,) points to (m, ...)."""
        x, w = gauss_points(self.basis.breakpoints())
        return np.tensordot(w, integrand(x), axes=(0, 0))

    @property
    def S1(self) -> FloatArray:
        """int rho A Phi dx + sum m Phi(x_m), shape (n,) [kg per unit q]: elastic linear momentum per qd."""
        rhoA = self.material.rho * self.section.area
        return rhoA * self.integrate(self.displacement) + self._point_sum(lambda pm: 1.0)

    @property
    def S2(self) -> FloatArray:
        """int rho A x Phi dx + sum m x_m Phi(x_m), shape (n,) [kg m per unit q], about x = 0.

        For bending: angular momentum about x = 0 per qd carried by the deflection. Timoshenko
        bars add the section rotary inertia ``S_psi``.
        """
        rhoA = self.material.rho * self.section.area
        return rhoA * self.integrate(lambda x: x[:, None] * self.displacement(x)) + self._point_sum(lambda pm: pm.x)

    @property
    def S_psi(self) -> FloatArray:
        """int rho I psi dx, shape (n,) [kg m per unit q]; zero unless Timoshenko (EB neglects rotary inertia)."""
        if self.theory != "timoshenko":
            return np.zeros(self.n)
        return self.material.rho * self.section.second_moment * self.integrate(self.rotation)

    def _point_sum(self, weight) -> FloatArray:
        out = np.zeros(self.n)
        for pm in self.point_masses:
            out += pm.mass * weight(pm) * self.displacement([pm.x])[0]
        return out


def peak_points(basis: ShapeBasis) -> FloatArray:
    """Sample points on the bar used to locate the peak of each shape (ends included)."""
    edges = basis.breakpoints()
    t = np.linspace(0.0, 1.0, PEAK_SAMPLES, endpoint=False)
    x = (edges[:-1, None] + np.diff(edges)[:, None] * t[None, :]).ravel()
    return np.append(x, edges[-1])


def peak_signs(basis: ShapeBasis, T: FloatArray) -> FloatArray:
    """+1 or -1 per column of ``T`` so that each displacement shape is positive at its sampled peak."""
    U = basis.evaluate(peak_points(basis), "u", 0) @ T
    peak = U[np.argmax(np.abs(U), axis=0), np.arange(U.shape[1])]
    return np.where(peak < 0, -1.0, 1.0)


def rigid_mode_count(kind: str, supports: tuple[str, str]) -> int:
    """Zero-frequency modes of a bar: 1 (axial) or 2 (bending) minus the constraints of the supports, at least 0."""
    col = 0 if kind == "axial" else 1
    free_motions = 1 if kind == "axial" else 2
    return max(0, free_motions - sum(SUPPORT_CONSTRAINTS[s][col] for s in supports))


def reduce(model: BarModel, n_modes: int, *, drop_rigid: bool = False) -> BarModel:
    """Modal reduction: keep the lowest ``n_modes`` of ``K v = omega^2 M v``, mass-normalised.

    The result has ``M = I``, ``K = diag(omega^2)`` and ``Phi(x) = model.Phi(x) @ V`` (for a FE
    model, the FE interpolation times the eigenvectors). Each mode is signed so that its largest
    sampled displacement is positive.

    Parameters
    ----------
    model : BarModel
    n_modes : int
        Modes kept, 1 <= n_modes <= model.n (after dropping rigid modes).
    drop_rigid : bool
        Leave out the ``rigid_mode_count(model)`` zero-frequency modes, as a floating frame of
        reference carries the rigid motion itself.

    Returns
    -------
    BarModel
        With n = n_modes coordinates, the modal amplitudes [m sqrt(kg)].
    """
    from scipy.linalg import eigh
    omega2, V = eigh(model.K, model.M)
    if drop_rigid:
        n_rigid = rigid_mode_count(model.kind, model.supports)
        omega2, V = omega2[n_rigid:], V[:, n_rigid:]
    if not 1 <= n_modes <= len(omega2):
        raise ValueError(f"n_modes = {n_modes}: the model has {len(omega2)} modes to keep")
    omega2, V = np.clip(omega2[:n_modes], 0.0, None), V[:, :n_modes]
    V = V * peak_signs(model.basis, model.T @ V)
    return replace(
        model, T=model.T @ V, M=np.eye(n_modes), K=np.diag(omega2), label=f"{model.label}, {n_modes} modes (mass-normalised)"
    )

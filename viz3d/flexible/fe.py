"""Finite-element models of uniform bars: 2-node rod, Hermite Euler-Bernoulli and locking-free
Friedman-Kosmatka Timoshenko elements, assembled into a ``BarModel`` in nodal coordinates.

Nodal coordinates per node: rod ``[u]`` [m]; Euler-Bernoulli ``[w, theta = w']`` [m, rad];
Timoshenko ``[w, psi]`` [m, rad]. ``q`` holds the unconstrained ones, node by node, in order;
supports remove the constrained ones (``BarModel.T`` selects them). Conventions: ``viz3d.flexible``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible.bar import BarModel, Material, PointMass, Section, gauss_points, shear_stiffness

#: Gauss points per element for the Timoshenko consistent mass: products of its cubic shape
#: functions are of degree 6, integrated exactly by 4 points (degree 7).
MASS_GAUSS_POINTS = 4
#: Mass matrix options (lumped only for the rod element).
MASS_MATRICES = ("consistent", "lumped")


def _poly_derivative(C: FloatArray, order: int) -> FloatArray:
    """Coefficients (..., p) of a polynomial in ascending powers after ``order`` d/dxi."""
    for _ in range(order):
        p = C.shape[-1]
        C = C[..., 1:] * np.arange(1, p) if p > 1 else np.zeros_like(C)
    return C


class Element:
    """A 2-node element type. Subclasses give the shape polynomials and element matrices.

    Hooks: ``polynomials(h, material, section) -> {field: (n_dof_e, p)}`` coefficients of the shape
    functions in ascending powers of xi = (x - x_a) / h ("psi" may be absent: then psi = u');
    ``stiffness(h, material, section)`` and ``mass(h, material, section, lumped)``, (n_dof_e, n_dof_e);
    ``constrained(support) -> local dof indices of a node`` fixed by that support.
    """

    name: ClassVar[str]
    theory: ClassVar[str]
    dofs_per_node: ClassVar[int]

    def polynomials(self, h: float, material: Material, section: Section) -> dict[str, FloatArray]:
        raise NotImplementedError

    def stiffness(self, h: float, material: Material, section: Section) -> FloatArray:
        raise NotImplementedError

    def mass(self, h: float, material: Material, section: Section, lumped: bool) -> FloatArray:
        raise NotImplementedError

    def constrained(self, support: str) -> list[int]:
        raise NotImplementedError


class Rod2(Element):
    """Linear 2-node rod element: u = (1 - xi) u1 + xi u2.

    Exact nodal static solution for end loads; frequencies converge as O(h^2) (consistent mass from
    above, lumped mass from below). Reference: R. D. Cook et al., Concepts and Applications of
    Finite Element Analysis, 4th ed. (2002), the bar element and its mass matrices.
    """

    name, theory, dofs_per_node = "rod2", "rod", 1

    def polynomials(self, h, material, section):
        return {"u": np.array([[1.0, -1.0], [0.0, 1.0]])}

    def stiffness(self, h, material, section):
        return material.E * section.area / h * np.array([[1.0, -1.0], [-1.0, 1.0]])

    def mass(self, h, material, section, lumped):
        m = material.rho * section.area * h
        return m / 2.0 * np.eye(2) if lumped else m / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])

    def constrained(self, support):
        return [] if support == "free" else [0]  # "pinned" = "clamped" = fixed u


class HermiteBeam(Element):
    """Cubic Hermite Euler-Bernoulli element, nodal dofs [w, theta = w'].

    Exact nodal statics for point loads and moments; frequencies converge as O(h^4); consistent
    mass without rotary inertia. Reference: J. S. Przemieniecki, Theory of Matrix Structural
    Analysis (1968), the uniform beam element (stiffness) and its consistent mass matrix.
    """

    name, theory, dofs_per_node = "hermite", "euler_bernoulli", 2

    def polynomials(self, h, material, section):
        return {"u": np.array([[1.0, 0.0, -3.0, 2.0], [0.0, h, -2.0 * h, h], [0.0, 0.0, 3.0, -2.0], [0.0, 0.0, -h, h]])}

    def stiffness(self, h, material, section):
        EI = material.E * section.second_moment
        return EI / h**3 * np.array([
            [12.0, 6 * h, -12.0, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
            [-12.0, -6 * h, 12.0, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])

    def mass(self, h, material, section, lumped):
        if lumped:
            raise ValueError("lumped mass is offered for the rod element only")
        m = material.rho * section.area * h
        return m / 420.0 * np.array([
            [156.0, 22 * h, 54.0, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
            [54.0, 13 * h, 156.0, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])

    def constrained(self, support):
        return {"free": [], "pinned": [0], "clamped": [0, 1]}[support]


class FKTimoshenkoBeam(Element):
    """Friedman-Kosmatka 2-node Timoshenko element, nodal dofs [w, psi]: interdependent cubic w and
    quadratic psi that solve the homogeneous static equations, so the element is free of shear
    locking and exact for nodal statics (tip load: PL^3/3EI + PL/kGA). Consistent mass with
    translational and rotary inertia, integrated exactly. phi = 12 EI / (k G A h^2).

    Reference: Z. Friedman, J. B. Kosmatka, "An improved two-node Timoshenko beam finite element",
    Computers & Structures 47(3), 473-481 (1993). The mass equals Przemieniecki's (1968) matrix for
    the beam with shear deformation and rotary inertia (checked in tests/flexible). Frequencies
    converge as O(h^2), not O(h^4): the shear strain is constant per element.
    """

    name, theory, dofs_per_node = "timoshenko_fk", "timoshenko", 2

    @staticmethod
    def _phi(h, material, section) -> float:
        return 12.0 * material.E * section.second_moment / (shear_stiffness(material, section) * h * h)

    def polynomials(self, h, material, section):
        phi = self._phi(h, material, section)
        f = 1.0 / (1.0 + phi)
        w = f * np.array([
            [1.0 + phi, -phi, -3.0, 2.0],
            [0.0, h * (1.0 + phi / 2), -h * (2.0 + phi / 2), h],
            [0.0, phi, 3.0, -2.0],
            [0.0, -h * phi / 2, -h * (1.0 - phi / 2), h]])
        psi = f * np.array([
            [0.0, -6.0 / h, 6.0 / h, 0.0],
            [1.0 + phi, -(4.0 + phi), 3.0, 0.0],
            [0.0, 6.0 / h, -6.0 / h, 0.0],
            [0.0, -(2.0 - phi), 3.0, 0.0]])
        return {"u": w, "psi": psi}

    def stiffness(self, h, material, section):
        phi = self._phi(h, material, section)
        EI = material.E * section.second_moment
        return EI / ((1.0 + phi) * h**3) * np.array([
            [12.0, 6 * h, -12.0, 6 * h], [6 * h, (4 + phi) * h * h, -6 * h, (2 - phi) * h * h],
            [-12.0, -6 * h, 12.0, -6 * h], [6 * h, (2 - phi) * h * h, -6 * h, (4 + phi) * h * h]])

    def mass(self, h, material, section, lumped):
        if lumped:
            raise ValueError("lumped mass is offered for the rod element only")
        polys = self.polynomials(h, material, section)
        xi, wq = gauss_points(np.array([0.0, 1.0]), MASS_GAUSS_POINTS)
        powers = xi[:, None] ** np.arange(4)[None, :]
        W, P = powers @ polys["u"].T, powers @ polys["psi"].T
        rhoA, rhoI = material.rho * section.area, material.rho * section.second_moment
        return h * (rhoA * (W.T * wq) @ W + rhoI * (P.T * wq) @ P)

    def constrained(self, support):
        return {"free": [], "pinned": [0], "clamped": [0, 1]}[support]


#: theory -> element used by ``fe_model``.
ELEMENTS = {"rod": Rod2(), "euler_bernoulli": HermiteBeam(), "timoshenko": FKTimoshenkoBeam()}


@dataclass(frozen=True)
class FEBasis:
    """Finite-element interpolation on a mesh: all nodal dofs (constrained ones included).

    Attributes
    ----------
    element : Element
    nodes : ndarray, shape (n_nodes,)
        Node positions [m], increasing, from 0 to L.
    material, section : Material, Section
    """

    element: Element
    nodes: FloatArray
    material: Material
    section: Section
    _polys: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        h = np.diff(self.nodes)
        if np.any(h <= 0):
            raise ValueError("nodes must be strictly increasing")
        per = [self.element.polynomials(he, self.material, self.section) for he in h]
        polys = {key: np.stack([p[key] for p in per]) for key in per[0]}
        object.__setattr__(self, "_polys", polys)

    @property
    def length(self) -> float:
        return float(self.nodes[-1] - self.nodes[0])

    @property
    def n_basis(self) -> int:
        return len(self.nodes) * self.element.dofs_per_node

    def breakpoints(self) -> FloatArray:
        return np.asarray(self.nodes, dtype=float)

    def evaluate(self, x: FloatArray, field: str, order: int) -> FloatArray:
        """Shape functions of every nodal dof at ``x`` (p,): (p, n_basis). At an interior node the
        element on its left is used (derivatives of C0 fields jump there)."""
        if field == "psi" and "psi" not in self._polys:
            if self.element.theory == "rod":
                raise ValueError("a rod has no section rotation")
            field, order = "u", order + 1  # Euler-Bernoulli: psi = w'
        x = np.asarray(x, dtype=float)
        n_el = len(self.nodes) - 1
        e = np.clip(np.searchsorted(self.nodes, x, side="left") - 1, 0, n_el - 1)
        h = np.diff(self.nodes)[e]
        xi = (x - self.nodes[e]) / h
        C = _poly_derivative(self._polys[field][e], order)  # (p, n_dof_e, deg + 1 - order)
        local = np.einsum("pjk,pk->pj", C, xi[:, None] ** np.arange(C.shape[-1])[None, :]) / h[:, None] ** order
        d = self.element.dofs_per_node
        out = np.zeros((len(x), self.n_basis))
        cols = (e * d)[:, None] + np.arange(2 * d)[None, :]
        np.put_along_axis(out, cols, local, axis=1)
        return out


def assemble(basis: FEBasis, lumped: bool) -> tuple[FloatArray, FloatArray]:
    """Global mass and stiffness over all nodal dofs: (n_basis, n_basis) each."""
    el, d = basis.element, basis.element.dofs_per_node
    M, K = np.zeros((basis.n_basis,) * 2), np.zeros((basis.n_basis,) * 2)
    for e, h in enumerate(np.diff(basis.nodes)):
        idx = slice(e * d, e * d + 2 * d)
        M[idx, idx] += el.mass(h, basis.material, basis.section, lumped)
        K[idx, idx] += el.stiffness(h, basis.material, basis.section)
    return M, K


def free_dofs(basis: FEBasis, supports: tuple[str, str]) -> FloatArray:
    """Selection matrix T (n_basis, n_free) of the dofs left free by the end supports."""
    d, last = basis.element.dofs_per_node, len(basis.nodes) - 1
    fixed = [j for j in basis.element.constrained(supports[0])]
    fixed += [last * d + j for j in basis.element.constrained(supports[1])]
    keep = [i for i in range(basis.n_basis) if i not in fixed]
    return np.eye(basis.n_basis)[:, keep]


def fe_model(
    theory: str,
    length: float,
    material: Material,
    section: Section,
    n_elements: int,
    supports: tuple[str, str],
    *,
    point_masses: tuple[PointMass, ...] = (),
    mass_matrix: str = "consistent",
) -> BarModel:
    """A uniform mesh of ``n_elements`` elements of ``ELEMENTS[theory]`` as a ``BarModel``.

    Parameters
    ----------
    theory : str
        "rod" (2-node linear), "euler_bernoulli" (Hermite cubic) or "timoshenko" (Friedman-Kosmatka).
    length : float
        L [m].
    material, section : Material, Section
    n_elements : int
    supports : tuple of str
        End conditions at x = 0 and x = L.
    point_masses : tuple of PointMass
        Rigid masses joined to the bar, added as ``m N(x)^T N(x)`` (a nodal mass at a node).
    mass_matrix : str
        "consistent" or "lumped" (rod only).

    Returns
    -------
    BarModel
        q = free nodal dofs [m, rad]; ``basis`` an ``FEBasis``.
    """
    if mass_matrix not in MASS_MATRICES:
        raise ValueError(f"mass_matrix {mass_matrix!r}; valid: {MASS_MATRICES}")
    element = ELEMENTS[theory]
    basis = FEBasis(element, np.linspace(0.0, length, n_elements + 1), material, section)
    M, K = assemble(basis, mass_matrix == "lumped")
    for pm in point_masses:
        N = basis.evaluate(np.array([pm.x]), "u", 0)
        M += pm.mass * N.T @ N
    T = free_dofs(basis, supports)
    kind = "axial" if theory == "rod" else "bending"
    label = f"{element.name} FE, {n_elements} elements, {supports[0]}-{supports[1]}, {mass_matrix} mass"
    return BarModel(kind, theory, length, material, section, tuple(supports), basis, T, T.T @ M @ T, T.T @ K @ T,
                    tuple(point_masses), label)

"""Finite-element models of uniform bars: 2-node rod, cubic and quintic Hermite Euler-Bernoulli and
locking-free Friedman-Kosmatka Timoshenko elements, assembled into a ``BarModel`` in nodal coordinates.

Nodal coordinates per node: rod ``[u]`` [m]; cubic Euler-Bernoulli ``[w, theta = w']`` [m, rad];
quintic Euler-Bernoulli ``[w, w', w'']`` [m, rad, 1/m]; Timoshenko ``[w, psi]`` [m, rad]. ``q`` holds
the unconstrained ones, node by node, in order; supports remove the constrained ones
(``BarModel.T`` selects them). ``ELEMENTS`` maps each theory to its default element,
``ELEMENT_TYPES`` every element by name (the choice ``fe_model(..., element=name)``).
Conventions: ``viz3d.flexible``; the quintic element: docs/seed003_element.md.
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

#: Quintic Hermite element in the scaled nodal dofs [w1, h w1', h^2 w1'', w2, h w2', h^2 w2'']:
#: stiffness K = EI / h^3 * QUINTIC_STIFFNESS_70 / 70 and consistent mass M = rho A h *
#: QUINTIC_MASS_55440 / 55440 (exact rationals: int EI w''^2 and int rho A w^2 of the shapes of
#: ``QuinticBeam``; derived with sympy in tests/flexible/test_beam_elements.py; Hossne 2007 eqs. 51, 56).
QUINTIC_STIFFNESS_70 = np.array([
    [1200, 600, 30, -1200, 600, -30],
    [600, 384, 22, -600, 216, -8],
    [30, 22, 6, -30, 8, 1],
    [-1200, -600, -30, 1200, -600, 30],
    [600, 216, 8, -600, 384, -22],
    [-30, -8, 1, 30, -22, 6]], dtype=float)
QUINTIC_MASS_55440 = np.array([
    [21720, 3732, 281, 6000, -1812, 181],
    [3732, 832, 69, 1812, -532, 52],
    [281, 69, 6, 181, -52, 5],
    [6000, 1812, 181, 21720, -3732, 281],
    [-1812, -532, -52, -3732, 832, -69],
    [181, 52, 5, 281, -69, 6]], dtype=float)


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
    Class attributes: ``name`` (key in ``ELEMENT_TYPES``), ``theory``, ``dofs_per_node``, and
    ``curvature_dof``, the local index of w'' (or psi') among a node's dofs, None if it is not a dof.
    To add an element: subclass, implement the four hooks, add an instance to ``ELEMENT_TYPES``.
    """

    name: ClassVar[str]
    theory: ClassVar[str]
    dofs_per_node: ClassVar[int]
    curvature_dof: ClassVar[int | None] = None

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


class QuinticBeam(Element):
    """Quintic Hermite Euler-Bernoulli element, nodal dofs [w, w', w''] (C2 deflection).

    Order: frequencies converge as O(h^8) (eigenvalue error h^(2(p - 1)), p = 5), against O(h^4) for
    the cubic element. Exact nodal deflection and slope for any load with consistent loads (the
    cubic homogeneous solutions are in the space); statics with polynomial solutions up to degree 5
    (tip load, uniform load) exact everywhere. Consistent mass without rotary inertia.
    Curvature: w'' is a nodal dof, so the bending moment EI w'' and the surface stress are read at
    the nodes without differentiating, and are continuous across elements.
    Supports: only w (pinned) and w, w' (clamped) are essential; M = EI w'' = 0 at a free or pinned
    end is a natural condition, so the curvature dof stays free there (an end moment or an attached
    mass may make it non-zero; the exact solution's w'' = 0 is reached as the mesh is refined).

    Reference: A. G. Hossne, "Lagrangiano de un elemento finito plano elástico dinámico con ocho
    grados de libertad", Ingeniería 11(1), 25-36 (2007), eqs. 34, 51, 56 (seed 003; errata in
    docs/seed003_element.md); W. L. Cleghorn, R. G. Fenton, B. Tabarrok, Mech. Mach. Theory 16(4),
    1981 (the same quintic element, axially rigid).
    """

    name, theory, dofs_per_node, curvature_dof = "quintic", "euler_bernoulli", 3, 2

    @staticmethod
    def _scale(h: float) -> FloatArray:
        """diag(1, h, h^2, 1, h, h^2): physical dofs from the scaled ones of the tabulated matrices."""
        return np.tile([1.0, h, h * h], 2)

    def polynomials(self, h, material, section):
        D = self._scale(h)[:, None]
        return {"u": D * np.array([
            [1.0, 0.0, 0.0, -10.0, 15.0, -6.0],
            [0.0, 1.0, 0.0, -6.0, 8.0, -3.0],
            [0.0, 0.0, 0.5, -1.5, 1.5, -0.5],
            [0.0, 0.0, 0.0, 10.0, -15.0, 6.0],
            [0.0, 0.0, 0.0, -4.0, 7.0, -3.0],
            [0.0, 0.0, 0.0, 0.5, -1.0, 0.5]])}

    def stiffness(self, h, material, section):
        D = self._scale(h)
        return material.E * section.second_moment / h**3 * (D[:, None] * QUINTIC_STIFFNESS_70 * D[None, :]) / 70.0

    def mass(self, h, material, section, lumped):
        if lumped:
            raise ValueError("lumped mass is offered for the rod element only")
        D = self._scale(h)
        return material.rho * section.area * h * (D[:, None] * QUINTIC_MASS_55440 * D[None, :]) / 55440.0

    def constrained(self, support):
        return {"free": [], "pinned": [0], "clamped": [0, 1]}[support]


#: Every element by name: the finite-element choices of ``fe_model(..., element=name)``.
ELEMENT_TYPES = {el.name: el for el in (Rod2(), HermiteBeam(), QuinticBeam(), FKTimoshenkoBeam())}
#: theory -> element ``fe_model`` uses when no element is named.
ELEMENTS = {"rod": ELEMENT_TYPES["rod2"], "euler_bernoulli": ELEMENT_TYPES["hermite"],
            "timoshenko": ELEMENT_TYPES["timoshenko_fk"]}


def element_for(theory: str, element: str | None = None) -> Element:
    """The element named ``element`` (or the theory's default), checked to implement ``theory``."""
    if theory not in ELEMENTS:
        raise ValueError(f"unknown theory {theory!r}; valid: {sorted(ELEMENTS)}")
    if element is None:
        return ELEMENTS[theory]
    valid = sorted(name for name, el in ELEMENT_TYPES.items() if el.theory == theory)
    if element not in valid:
        raise ValueError(f"element {element!r} for theory {theory!r}; valid: {valid}")
    return ELEMENT_TYPES[element]


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
    element: str | None = None,
) -> BarModel:
    """A uniform mesh of ``n_elements`` elements of ``element`` (default ``ELEMENTS[theory]``) as a ``BarModel``.

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
    element : str, optional
        A key of ``ELEMENT_TYPES`` implementing ``theory``: "rod2"; "hermite" (cubic) or "quintic"
        for "euler_bernoulli"; "timoshenko_fk". None: the theory's default in ``ELEMENTS``.

    Returns
    -------
    BarModel
        q = free nodal dofs [m, rad]; ``basis`` an ``FEBasis``.
    """
    if mass_matrix not in MASS_MATRICES:
        raise ValueError(f"mass_matrix {mass_matrix!r}; valid: {MASS_MATRICES}")
    element = element_for(theory, element)
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


def node_curvature(model: BarModel, q: FloatArray) -> FloatArray:
    """Bending curvature psi' (= w'' for Euler-Bernoulli) at the mesh nodes [1/m].

    With a curvature dof (``QuinticBeam``) the nodal value is read from the coordinates, continuous
    across elements. Otherwise it is psi' of the element on the node's left (the first element at
    x = 0), which jumps between elements.

    Parameters
    ----------
    model : BarModel
        A bending FE model (``fe_model``).
    q : ndarray, shape (n,) or (n, k)
        Coordinates of the model [m, rad, 1/m].

    Returns
    -------
    kappa : ndarray, shape (n_nodes,) or (n_nodes, k)
    """
    if model.kind != "bending" or not isinstance(model.basis, FEBasis):
        raise ValueError("node_curvature needs a bending finite-element model")
    element = model.basis.element
    if element.curvature_dof is not None:
        return (model.T @ q)[element.curvature_dof::element.dofs_per_node]
    return model.shape(model.basis.nodes, "psi", 1) @ q


def node_bending_stress(model: BarModel, q: FloatArray) -> FloatArray:
    """Bending stress at the nodes on the fibre z = +depth/2 (the +w side) [Pa]: -E (depth/2) psi'.

    Same sign as ``BarModel.strain``: a tip load P (+w) on a cantilever gives -P L (depth/2) / I at
    the clamp. Shapes as ``node_curvature``.
    """
    return -model.material.E * 0.5 * model.section.depth * node_curvature(model, q)

"""Planar beams on a floating frame: seed 003's 8-DOF element (linear axial + quintic transverse)
and the classic 6-DOF element (linear axial + cubic transverse), their element matrices, the shape
integrals of the kinetic energy and the generalized inertia, elastic and gravity forces.

Conventions (Hossne 2007, eqs. 19-25; derivation and errata in docs/seed003_element.md; SI units):

* **Frame.** The beam's frame B has its origin at the reference end x = 0, at world position
  ``W_r_B = (X1, Y1)``, and is turned by ``theta`` about +Z: ``R_WB = [[cos, -sin], [sin, cos]]``.
  A point at x on the undeformed axis is displaced to ``B_r(x) = (x + u(x), w(x))`` and sits at
  ``W_R(x) = W_r_B + R_WB B_r(x)`` (eq. 21). Axial u along +x, deflection w along +y of B.
* **Elastic coordinates** ``s`` (n_s,), node by node: ``[u, w, w']`` ("planar6_cubic") or
  ``[u, w, w', w'']`` ("planar8_quintic"; for one element the seed's q1..q8) [m, m, rad, 1/m];
  ``u = N_u(x) s``, ``w = N_w(x) s``.
* **Generalized coordinates** ``p = [X1, Y1, theta, s]`` (3 + n_s,) [m, m, rad, ...]. All of s is
  free here, so the rigid motions appear twice (frame and s) and the mass matrix is singular until
  three reference conditions fix the frame to the beam (``reference_conditions``) or a joint does.
* **Equations of motion** ``M(p) pdd = Q_v(p, pd) + Q_e(p) + Q_g(p) + Q_applied`` with
  T = 1/2 int rho A |d W_R / dt|^2 dx (eq. 26; no rotary inertia, Euler-Bernoulli) and
  V = 1/2 s^T K s - int rho A g . W_R dx (eqs. 27, 36, with the elastic part of gravity the seed drops).
  Linear elasticity: no geometric (centrifugal) stiffening.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible.bar import Material, Section
from viz3d.flexible.fe import ELEMENT_TYPES, Element

#: Gauss-Legendre points per element for the shape integrals computed by quadrature (x N_u, x N_w,
#: N_u^T N_w: degree <= 6; N_w^T N_w, were it needed: 10), exact up to degree 11.
SHAPE_GAUSS_POINTS = 6
#: Reference conditions that tie the frame to the beam (three per beam, they remove its rigid modes).
REFERENCE_CONDITIONS = ("tangent", "chord")
#: The quarter-turn in the plane, Omega @ r = e_z x r.
OMEGA = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass(frozen=True)
class PlanarElement:
    """A planar beam element: linear axial field plus a transverse Euler-Bernoulli element.

    Attributes
    ----------
    name : str
        Key in ``PLANAR_ELEMENTS``.
    transverse : Element
        "hermite" (cubic, dofs [w, w']) or "quintic" (dofs [w, w', w'']) from ``ELEMENT_TYPES``.
    axial : Element
        The 2-node linear rod (dof [u]).
    """

    name: str
    transverse: Element
    axial: Element = field(default_factory=lambda: ELEMENT_TYPES["rod2"])

    @property
    def dofs_per_node(self) -> int:
        """1 axial + the transverse element's: 3 (cubic) or 4 (quintic)."""
        return self.axial.dofs_per_node + self.transverse.dofs_per_node

    def axial_local(self) -> list[int]:
        """Local indices (2,) of u1, u2 in the element's dof vector (seed order)."""
        return [0, self.dofs_per_node]

    def transverse_local(self) -> list[int]:
        """Local indices (2 d_w,) of the transverse dofs [w, w', (w'')] of both nodes."""
        d = self.dofs_per_node
        return list(range(1, d)) + list(range(d + 1, 2 * d))


#: The seed's 8-DOF element and the classic 6-DOF one (Midha et al. 1978), by name.
PLANAR_ELEMENTS = {
    "planar8_quintic": PlanarElement("planar8_quintic", ELEMENT_TYPES["quintic"]),
    "planar6_cubic": PlanarElement("planar6_cubic", ELEMENT_TYPES["hermite"]),
}


@dataclass(frozen=True)
class PlanarBeam:
    """A uniform straight beam of ``n_elements`` planar elements, x from 0 (frame origin) to L.

    Every array is over the elastic coordinates s (n_s = n_nodes * dofs_per_node,), node by node.
    The seed's symbols (eq. 44, where T = m/2 [...] with m = rho A) are the ones here over rho A.

    Attributes
    ----------
    element : PlanarElement
    material, section : Material, Section
    nodes : ndarray, shape (n_nodes,)
        Node positions [m].
    mass : float
        int rho A dx [kg].
    static_moment : float
        int rho A x dx [kg m].
    inertia : float
        int rho A x^2 dx [kg m^2], about x = 0 (no section rotary inertia).
    S_u, S_w : ndarray, shape (n_s,)
        int rho A N_u dx, int rho A N_w dx [kg] (seed E, G).
    xS_u, xS_w : ndarray, shape (n_s,)
        int rho A x N_u dx, int rho A x N_w dx [kg m] (seed N, L).
    M_uu, M_uw, M_ww : ndarray, shape (n_s, n_s)
        int rho A N_u^T N_u, N_u^T N_w, N_w^T N_w dx [kg] (seed B, A, M). The element mass matrix
        of s is ``M_uu + M_ww``.
    K : ndarray, shape (n_s, n_s)
        Stiffness, int EA u'^2 + EI w''^2 as s^T K s [N/m in the units of s] (seed eq. 56).
    """

    element: PlanarElement
    material: Material
    section: Section
    nodes: FloatArray = field(repr=False)
    mass: float
    static_moment: float
    inertia: float
    S_u: FloatArray = field(repr=False)
    S_w: FloatArray = field(repr=False)
    xS_u: FloatArray = field(repr=False)
    xS_w: FloatArray = field(repr=False)
    M_uu: FloatArray = field(repr=False)
    M_uw: FloatArray = field(repr=False)
    M_ww: FloatArray = field(repr=False)
    K: FloatArray = field(repr=False)

    @property
    def n_s(self) -> int:
        """Number of elastic coordinates."""
        return len(self.S_u)

    @property
    def length(self) -> float:
        return float(self.nodes[-1] - self.nodes[0])

    @property
    def M_ss(self) -> FloatArray:
        """Mass matrix of s alone, M_uu + M_ww, shape (n_s, n_s) [kg]."""
        return self.M_uu + self.M_ww

    def dofs(self, kind: str) -> FloatArray:
        """Indices in s of one kind of nodal dof, one per node: "u", "w", "slope" or "curvature"."""
        local = {"u": 0, "w": 1, "slope": 2, "curvature": 3}[kind]
        d = self.element.dofs_per_node
        if local >= d:
            raise ValueError(f"{self.element.name} has no {kind} dof")
        return np.arange(local, len(self.nodes) * d, d)


# ---- element level ----------------------------------------------------------------------------
def element_matrices(element: PlanarElement, h: float, material: Material, section: Section) -> tuple[FloatArray, FloatArray]:
    """Consistent mass and stiffness of one element in its seed-ordered dofs (2 d, 2 d) each.

    ``M = M_uu + M_ww`` (seed eqs. 46 + 51) [kg], ``K`` (seed eq. 56) [N/m, N, N m].
    """
    n_e = 2 * element.dofs_per_node
    M, K = np.zeros((n_e, n_e)), np.zeros((n_e, n_e))
    for part, idx in ((element.axial, element.axial_local()), (element.transverse, element.transverse_local())):
        M[np.ix_(idx, idx)] = part.mass(h, material, section, False)
        K[np.ix_(idx, idx)] = part.stiffness(h, material, section)
    return M, K


def element_shapes(element: PlanarElement, h: float, material: Material, section: Section, xi: FloatArray
                   ) -> tuple[FloatArray, FloatArray]:
    """Axial and transverse shape functions at xi = (x - x_a) / h (p,): N_u, N_w, each (p, 2 d) [-, m/dof]."""
    n_e, powers = 2 * element.dofs_per_node, xi[:, None] ** np.arange(6)[None, :]
    N_u, N_w = np.zeros((len(xi), n_e)), np.zeros((len(xi), n_e))
    for part, idx, N in ((element.axial, element.axial_local(), N_u), (element.transverse, element.transverse_local(), N_w)):
        C = part.polynomials(h, material, section)["u"]
        N[:, idx] = powers[:, : C.shape[1]] @ C.T
    return N_u, N_w


# ---- the beam ---------------------------------------------------------------------------------
def planar_beam(element: str, length: float, material: Material, section: Section, n_elements: int) -> PlanarBeam:
    """A uniform mesh of ``n_elements`` elements ``PLANAR_ELEMENTS[element]`` on [0, length].

    Element matrices are scattered node by node; the shape integrals are Gauss quadratures exact
    for the polynomials (``SHAPE_GAUSS_POINTS``). ``n_elements = 1`` gives the seed's single element.
    """
    if element not in PLANAR_ELEMENTS:
        raise ValueError(f"unknown planar element {element!r}; valid: {sorted(PLANAR_ELEMENTS)}")
    el = PLANAR_ELEMENTS[element]
    nodes = np.linspace(0.0, length, n_elements + 1)
    d, rhoA = el.dofs_per_node, material.rho * section.area
    n_s = len(nodes) * d
    vec = {k: np.zeros(n_s) for k in ("S_u", "S_w", "xS_u", "xS_w")}
    mat = {k: np.zeros((n_s, n_s)) for k in ("M_uu", "M_uw", "M_ww", "K")}
    xi, wq = np.polynomial.legendre.leggauss(SHAPE_GAUSS_POINTS)
    xi, wq = 0.5 * (xi + 1.0), 0.5 * wq
    for e, (x_a, h) in enumerate(zip(nodes[:-1], np.diff(nodes))):
        idx = np.arange(e * d, e * d + 2 * d)
        N_u, N_w = element_shapes(el, h, material, section, xi)
        w, x = rhoA * h * wq, x_a + h * xi
        vec["S_u"][idx] += w @ N_u
        vec["S_w"][idx] += w @ N_w
        vec["xS_u"][idx] += (w * x) @ N_u
        vec["xS_w"][idx] += (w * x) @ N_w
        M_e, K_e = element_matrices(el, h, material, section)
        ax, tr = el.axial_local(), el.transverse_local()
        mat["M_uu"][np.ix_(idx[ax], idx[ax])] += M_e[np.ix_(ax, ax)]
        mat["M_ww"][np.ix_(idx[tr], idx[tr])] += M_e[np.ix_(tr, tr)]
        mat["M_uw"][np.ix_(idx, idx)] += (N_u.T * w) @ N_w
        mat["K"][np.ix_(idx, idx)] += K_e
    m = rhoA * length
    return PlanarBeam(el, material, section, nodes, m, m * length / 2.0, m * length**2 / 3.0, **vec, **mat)


def reference_conditions(beam: PlanarBeam, kind: str) -> FloatArray:
    """Selection T (n_s, n_s - 3) of the elastic coordinates left free by three reference conditions.

    "tangent": u = w = w' = 0 at x = 0 (the frame is the tangent at the reference end; in it the
    beam is a cantilever). "chord": u = w = 0 at x = 0 and w = 0 at x = L (the frame's x axis
    through both ends). Either removes the beam's three rigid motions from s, so that
    ``T_p^T M T_p`` with ``T_p = blockdiag(I_3, T)`` is positive definite.
    """
    if kind not in REFERENCE_CONDITIONS:
        raise ValueError(f"reference conditions {kind!r}; valid: {REFERENCE_CONDITIONS}")
    u, w = beam.dofs("u"), beam.dofs("w")
    fixed = [u[0], w[0], beam.dofs("slope")[0]] if kind == "tangent" else [u[0], w[0], w[-1]]
    keep = [i for i in range(beam.n_s) if i not in fixed]
    return np.eye(beam.n_s)[:, keep]


# ---- kinematics and energies --------------------------------------------------------------------
def rotation(theta: float) -> FloatArray:
    """R_WB (2, 2) of the frame turned by ``theta`` [rad] about +Z."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def _split(beam: PlanarBeam, p: FloatArray) -> tuple[FloatArray, float, FloatArray]:
    p = np.asarray(p, dtype=float)
    if p.shape != (3 + beam.n_s,):
        raise ValueError(f"p must have shape ({3 + beam.n_s},), got {p.shape}")
    return p[:2], float(p[2]), p[3:]


def first_moment(beam: PlanarBeam, s: FloatArray) -> FloatArray:
    """int rho A B_r dx = (static_moment + S_u s, S_w s), shape (2,) [kg m], in the frame B."""
    return np.array([beam.static_moment + beam.S_u @ s, beam.S_w @ s])


def world_positions(beam: PlanarBeam, p: FloatArray, x: FloatArray) -> FloatArray:
    """W_R(x) (m, 2) [m] of the axis points x (m,) in [0, L] (seed eq. 21)."""
    W_r_B, theta, s = _split(beam, p)
    x = np.atleast_1d(np.asarray(x, dtype=float))
    N_u, N_w = shape_functions(beam, x)
    B_r = np.stack([x + N_u @ s, N_w @ s], axis=1)
    return W_r_B[None, :] + B_r @ rotation(theta).T


def shape_functions(beam: PlanarBeam, x: FloatArray) -> tuple[FloatArray, FloatArray]:
    """N_u(x), N_w(x), each (m, n_s), at points x (m,) in [0, L]; at an interior node the left element."""
    el, d = beam.element, beam.element.dofs_per_node
    e = np.clip(np.searchsorted(beam.nodes, x, side="left") - 1, 0, len(beam.nodes) - 2)
    h = np.diff(beam.nodes)[e]
    N_u, N_w = np.zeros((len(x), beam.n_s)), np.zeros((len(x), beam.n_s))
    for i, (ei, hi) in enumerate(zip(e, h)):
        nu, nw = element_shapes(el, hi, beam.material, beam.section, np.array([(x[i] - beam.nodes[ei]) / hi]))
        N_u[i, ei * d: ei * d + 2 * d], N_w[i, ei * d: ei * d + 2 * d] = nu[0], nw[0]
    return N_u, N_w


def mass_matrix(beam: PlanarBeam, p: FloatArray) -> FloatArray:
    """M(p) (3 + n_s, 3 + n_s) of T = 1/2 pd^T M pd, p = [X1, Y1, theta, s] [kg, kg m, kg m^2]."""
    _, theta, s = _split(beam, p)
    R, n = rotation(theta), beam.n_s
    W = beam.M_uw - beam.M_uw.T  # int rho A (N_u^T N_w - N_w^T N_u): the Coriolis coupling of u and w
    M = np.zeros((3 + n, 3 + n))
    M[:2, :2] = beam.mass * np.eye(2)
    M[:2, 2] = R @ OMEGA @ first_moment(beam, s)
    M[:2, 3:] = R @ np.stack([beam.S_u, beam.S_w])
    M[2, 2] = beam.inertia + 2.0 * beam.xS_u @ s + s @ beam.M_ss @ s
    M[2, 3:] = beam.xS_w - W @ s
    M[3:, 3:] = beam.M_ss
    M[2:, :2] = M[:2, 2:].T
    M[3:, 2] = M[2, 3:]
    return M


def quadratic_velocity_forces(beam: PlanarBeam, p: FloatArray, pd: FloatArray) -> FloatArray:
    """Q_v(p, pd) (3 + n_s,): centrifugal and Coriolis forces, -int rho A (dR/dp)^T R_WB (2 thd Omega B_rd - thd^2 B_r) dx.

    Independent of the frame's translation rates. Units: [N] for X1, Y1, [N m] for theta, [N / unit s] for s.
    """
    _, theta, s = _split(beam, p)
    _, thd, sd = _split(beam, pd)
    W = beam.M_uw - beam.M_uw.T
    rd_bar = np.array([beam.S_u @ sd, beam.S_w @ sd])       # int rho A B_rd dx
    spin = beam.xS_u + beam.M_ss @ s                        # int rho A Phi^T B_r dx (Phi = [N_u; N_w])
    return np.concatenate([
        rotation(theta) @ (thd**2 * first_moment(beam, s) - 2.0 * thd * OMEGA @ rd_bar),
        [-2.0 * thd * spin @ sd],
        thd**2 * spin + 2.0 * thd * W @ sd,
    ])


def elastic_forces(beam: PlanarBeam, p: FloatArray) -> FloatArray:
    """Q_e = -dV_elastic/dp = [0, 0, 0, -K s] (3 + n_s,)."""
    _, _, s = _split(beam, p)
    return np.concatenate([np.zeros(3), -beam.K @ s])


def gravity_forces(beam: PlanarBeam, p: FloatArray, g: FloatArray) -> FloatArray:
    """Q_g = int rho A (dW_R/dp)^T g dx (3 + n_s,) for the uniform field ``g`` (2,) [m/s^2], world axes.

    The elastic part ``S_u g_B,x + S_w g_B,y`` (g_B = R_WB^T g) is the consistent load of the beam's
    weight; the seed's eq. 36 keeps only the rigid part.
    """
    _, theta, s = _split(beam, p)
    g_B = rotation(theta).T @ np.asarray(g, dtype=float)
    return np.concatenate([beam.mass * np.asarray(g, dtype=float), [(OMEGA @ first_moment(beam, s)) @ g_B],
                           beam.S_u * g_B[0] + beam.S_w * g_B[1]])


def kinetic_energy(beam: PlanarBeam, p: FloatArray, pd: FloatArray) -> float:
    """T = 1/2 pd^T M(p) pd [J] (seed eq. 44)."""
    pd = np.asarray(pd, dtype=float)
    return 0.5 * float(pd @ mass_matrix(beam, p) @ pd)


def potential_energy(beam: PlanarBeam, p: FloatArray, g: FloatArray) -> float:
    """V = 1/2 s^T K s - g . (mass W_r_B + R_WB int rho A B_r dx) [J] (seed eqs. 52-55 plus the elastic part of gravity)."""
    W_r_B, theta, s = _split(beam, p)
    g = np.asarray(g, dtype=float)
    return 0.5 * float(s @ beam.K @ s) - float(g @ (beam.mass * W_r_B + rotation(theta) @ first_moment(beam, s)))

"""A flexible bar on a floating frame of reference (FFR) in 3D: inertia invariants, the exact mass
matrix, quadratic velocity, elastic and gravity forces, energies and momenta.

Conventions (SI units; rotations, frames and velocity names as in docs/notation.md; bar axes and
modal units as in ``viz3d.flexible``):

* **Body frame B.** Origin at the centre of mass G of the *undeformed* body (bar plus point
  masses), ``B_x`` along the bar: the section at ``x`` in [0, L] sits at ``s0(x) = (x - x_G) e_x``
  with ``x_G = static_moment / mass``. World pose ``(W_r, R_WB)``; a body point ``s`` is at
  ``W_p = W_r + R_WB s``. B is a floating frame: what ties it to the material (mean axes, tangent
  frame, ...) is the choice of shapes, i.e. the supports of the fields' ``BarModel``s (free-free
  modes: mean axes; clamped-free: the tangent frame at x = 0; pinned-pinned: the chord through both
  ends).
* **Fields.** One or more pairs ``(d_k, model_k)`` on the same bar (same length, material, area
  and point masses). An axial field has ``d = e_x``; a bending field a unit ``d`` normal to ``e_x``
  (the direction of positive deflection w), its section rotation psi turning about
  ``b = e_x x d``. ``eta`` is the concatenation of the fields' coordinates (each in its model's
  units), and the centreline displacement is ``u(x) = U(x) eta``, ``U = [d_1 Phi_1, d_2 Phi_2, ...]``
  (3, n). The small section rotation (body axes) is ``theta(x) = P(x) eta``,
  ``P = [b_k psi_k]`` over the bending fields (psi = w' for Euler-Bernoulli); axial fields do not
  rotate sections and nothing twists (no torsion field).
* **Material points.** The point at section ``x`` with a fixed offset ``c`` (body axes, normally in
  the section plane, e.g. the surface ``c = (depth / 2) d``) is at
  ``s = s0(x) + c + U(x) eta + theta(x) x c = s0 + c + N(x, c) eta``, ``N = U - skew(c) P``: the
  section turned by theta to first order. Positions are linear in eta.
* **Inertia.** ``T = 1/2 int rho |W_p_dot|^2 dV`` over the bar's volume plus ``1/2 m_j
  |W_p_dot(x_j)|^2`` per point mass (on the axis, translation only), with the material points placed
  by the linear field above except that the section rotation turning ``c`` is that of the Timoshenko
  fields only (``N = U - skew(c) P_T``): their ``BarModel.M`` holds ``rho I psi_dot^2``, while
  Euler-Bernoulli neglects rotary inertia (its sections translate with the axis in T, so its modes
  stay mean axes and its ``M`` is unchanged). The volume integral over a section reduces to
  ``rho A`` and the section's second moments ``Sigma = rho int c c^T dA`` (per unit length, body
  axes). The rigid section inertia ``L (tr Sigma I - Sigma)`` (torsion ``rho (I_y + I_z)`` about e_x,
  rotation about the transverse axes) is thus always in ``J0``: without it a line model has no
  inertia about its own axis. Section second moments: ``Section.second_moment`` is about the axis
  normal to the depth direction (the first bending field's d, or ``depth_axis``, else e_y); the
  other one is exact for a rectangle (recognised by ``I = A depth^2 / 12``: ``A width^2 / 12``),
  assumed equal to it for any other section (circle, square, tube), or given as
  ``lateral_second_moment``.
* **Velocities** ``v = [W_v (3), B_omega (3), eta_dot (n)]`` [m/s, rad/s, units of eta per s].
  Equations of motion, all generalized forces on the right:

      M(R_WB, eta) v_dot = Q_applied + Q_elastic + Q_gravity + Q_velocity

  with ``Q_velocity`` the centrifugal, Coriolis and gyroscopic terms (``-w x J0 w`` for a rigid
  body) and torques in body axes: ``Q = [W_F, B_tau, Q_eta]``.
* **Geometric stiffening** (optional, ``with_geometric_stiffening``; docs/notation.md, "Geometric
  stiffening"): the centrifugal tension of the frame's rotation ``w_perp^2 n(x)`` (``w_perp^2 =
  |w|^2 - (e_x . w)^2``, ``n(x) = int rho A |xi - x_s| dxi`` from x away from the stiffening centre
  ``x_s``, the supported end or else G, to the bar's end, plus point masses) acting on the slopes: the
  motion-induced geometric stiffness ``Q_eta -= w_perp^2 K_w eta``, ``K_w = int n U_perp'^T U_perp' dx``
  (Banerjee & Dickens 1990, its centrifugal load case; the first-order effect of Kane, Ryan & Banerjee's
  foreshortening). It depends on the frame's motion, so it is not a potential: the frame feels no
  foreshortening (as kineto-elastodynamics), and its power ``-w_perp^2 eta_dot^T K_w eta`` is booked
  with the work in of the energy ledger. Exact for a support at rest (the spin-up beam); the
  support's acceleration and gravity's axial load are left out.
* **Not modelled.** Torsion, the sections' rotation beyond first order. Given the linear field, T and
  everything below are exact (no further approximation).

Inertia invariants (``FloatingBar``; n elastic coordinates, N the inertial field above, dm over
the bar's line mass and point masses): ``m``; ``S = int U dm`` (3, n); ``I0 = int s0 s0^T dV`` (3, 3);
``A[i, j, q] = int s0_i N_jq dV`` (3, 3, n); ``B[i, j, p, q] = int N_ip N_jq dV`` (3, 3, n, n).
With ``F(eta) = A + B . eta`` (``F[i, j, q] = int s_i N_jq dV``) the mass matrix is

    M = [[ m I,           -R skew(S eta),  R S   ],
         [ (.)^T,          J(eta),         G(eta)],
         [ (.)^T,          (.)^T,          M_ee  ]]

``J = tr(Sigma2) I - Sigma2``, ``Sigma2 = int s s^T dV = I0 + A . eta + (A . eta)^T + B : eta eta``,
``G[k, q] = eps_kij F[i, j, q]`` (``G eta_dot = int s x s_dot dV``), ``M_ee[p, q] = B[i, i, p, q]``.
By Kane's method with partial velocities ``I``, ``-R skew(s)``, ``R N`` and the body-axes bias
acceleration ``a = w x (w x s) + 2 w x N eta_dot`` of every material point,
``Q_velocity = -[R int a dV, int s x a dV, int N^T a dV]``:

    Q_v   = -R (w x (w x S eta) + 2 w x S eta_dot)
    Q_w   = -w x J w - 2 (tr(Y) w - Y w),     Y = int s_dot s^T dV = (F . eta_dot)^T
    Q_eta = -sum_ij (W_ij F[j, i, :] + 2 skew(w)_ij B[i, j] eta_dot),   W = skew(w)^2
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible.bar import BarModel, Material, PointMass, Section, gauss_points
from viz3d.rotations import cross, skew

E_X = np.array([1.0, 0.0, 0.0])
#: Projection normal to the bar's axis, ``I - e_x e_x^T``.
P_AXIS = np.diag([0.0, 1.0, 1.0])
#: Default depth direction of the section (the bending plane of a single bending field is x-y).
E_Y = np.array([0.0, 1.0, 0.0])
#: Directions are unit vectors and bending directions normal to e_x to this tolerance (they are
#: typed in or built from unit vectors: a few rounding errors).
DIRECTION_TOL = 1e-12
#: Fields on "the same bar" agree in length, area and second moments to this relative tolerance
#: (they are built from the same numbers; 1e-9 admits a rectangle rebuilt with swapped sides).
SAME_BAR_RTOL = 1e-9
#: eigh returns the zero-frequency (rigid) modes of an unsupported FE model with |omega^2| up to about
#: n eps max(omega^2) (backward stability); below 100 times that they count as rigid and get no damping
#: (the square root would turn round-off into a damping rate of sqrt(eps) omega_max).
RIGID_EIGENVALUE_FACTOR = 100.0
#: Breakpoints of different fields closer than this (relative to L) are merged: a sliver panel
#: would only repeat Gauss points.
BREAKPOINT_RTOL = 1e-12


@dataclass(frozen=True, eq=False)
class FloatingBar:
    """A flexible bar on a floating frame: fields, inertia invariants, stiffness and damping.

    Build it with ``floating_bar``, ``floating_bar_from_fields`` or ``rigid_bar``; conventions and
    formulas in the module docstring. n is the number of elastic coordinates. Compared (and hashed)
    by identity: it holds arrays.

    Attributes
    ----------
    length : float
        L [m].
    material : Material
    section : Section
        The section of the first field (its ``depth`` is measured along ``depth_axis``).
    point_masses : tuple of PointMass
        On the axis, shared by every field.
    fields : tuple of BarModel
        The deformation fields, in the order of their coordinates in eta.
    names : tuple of str
        One name per field.
    directions : ndarray, shape (n_fields, 3)
        d_k, body axes.
    mass : float
        m [kg].
    x_G : float
        Position of the undeformed centre of mass along the bar [m] (the origin of B).
    J0 : ndarray, shape (3, 3)
        Rigid inertia tensor about the origin of B, body axes [kg m^2] (line, point and section masses).
    Sigma : ndarray, shape (3, 3)
        Section second moments per unit length, ``rho int c c^T dA`` [kg m], body axes.
    D : ndarray, shape (3, n)
        Direction d of each coordinate's field.
    Bxi : ndarray, shape (3, n)
        Rotation axis b of each coordinate's section rotation (zero for axial fields).
    rotary : ndarray of bool, shape (n,)
        Coordinates whose section rotation carries inertia (Timoshenko fields).
    S1 : ndarray, shape (n,)
        ``int Phi dm`` [kg per unit eta] (``BarModel.S1`` per field).
    S2 : ndarray, shape (n,)
        ``int (x - x_G) Phi dm`` [kg m per unit eta]: ``BarModel.S2 - x_G S1``, about G.
    S_psi : ndarray, shape (n,)
        ``int rho I psi dx`` on Timoshenko coordinates [kg m per unit eta], zero elsewhere.
    Phi_Phi : ndarray, shape (n, n)
        ``int Phi_p Phi_q dm`` over all coordinates, cross-field blocks included [kg per unit eta^2].
    Psi_Psi : ndarray, shape (n, n)
        ``int psi_p psi_q dx`` on Timoshenko coordinates [m per unit eta^2] (zero elsewhere).
    S : ndarray, shape (3, n)
        ``int U dm = D S1`` [kg per unit eta].
    I0 : ndarray, shape (3, 3)
        ``int s0 s0^T dV`` [kg m^2].
    A : ndarray, shape (3, 3, n)
        ``int s0_i N_jq dV`` [kg m per unit eta].
    B : ndarray, shape (3, 3, n, n)
        ``int N_ip N_jq dV`` [kg per unit eta^2].
    M_ee : ndarray, shape (n, n)
        Elastic mass matrix ``B[i, i]``; its diagonal blocks are the fields' ``BarModel.M``.
    K : ndarray, shape (n, n)
        Block-diagonal stiffness of the fields [N/m per unit eta^2].
    C : ndarray, shape (n, n)
        Damping: ``modal_damping`` ratio on every mode of (K, M_ee); zero by default.
    K_omega : ndarray, shape (n, n), or None
        Centrifugal geometric stiffness per unit ``w_perp^2`` [kg m^2 per unit eta^2]
        (``with_geometric_stiffening``); None: no stiffening.
    x_s : float
        Stiffening centre [m] (where the foreshortening is measured from).
    """

    length: float
    material: Material
    section: Section
    point_masses: tuple[PointMass, ...]
    fields: tuple[BarModel, ...] = field(repr=False)
    names: tuple[str, ...]
    directions: FloatArray = field(repr=False)
    mass: float
    x_G: float
    J0: FloatArray = field(repr=False)
    Sigma: FloatArray = field(repr=False)
    D: FloatArray = field(repr=False)
    Bxi: FloatArray = field(repr=False)
    rotary: FloatArray = field(repr=False)
    S1: FloatArray = field(repr=False)
    S2: FloatArray = field(repr=False)
    S_psi: FloatArray = field(repr=False)
    Phi_Phi: FloatArray = field(repr=False)
    Psi_Psi: FloatArray = field(repr=False)
    S: FloatArray = field(repr=False)
    I0: FloatArray = field(repr=False)
    A: FloatArray = field(repr=False)
    B: FloatArray = field(repr=False)
    M_ee: FloatArray = field(repr=False)
    K: FloatArray = field(repr=False)
    C: FloatArray = field(repr=False)
    K_omega: FloatArray | None = field(default=None, repr=False)
    x_s: float = 0.0

    @property
    def n(self) -> int:
        """Number of elastic coordinates."""
        return self.D.shape[1]

    @property
    def field_slices(self) -> tuple[slice, ...]:
        """The slice of eta holding each field's coordinates."""
        ends = np.cumsum([0] + [f.n for f in self.fields])
        return tuple(slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:]))

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """``"<field>[i]"`` for each elastic coordinate."""
        return tuple(f"{name}[{i}]" for name, f in zip(self.names, self.fields) for i in range(f.n))


# ---- construction ------------------------------------------------------------------------------
def floating_bar(model: BarModel, direction: FloatArray | None = None, *, second: tuple[FloatArray, BarModel] | None = None,
                 depth_axis: FloatArray | None = None, lateral_second_moment: float | None = None,
                 modal_damping: float = 0.0) -> FloatingBar:
    """A floating bar with the field ``model`` along ``direction`` (default e_x for axial models,
    e_y for bending) and optionally a ``second`` field ``(direction, model)`` (e.g. seed 003's
    axial + bending planar element). Keywords as in ``floating_bar_from_fields``."""
    if direction is None:
        direction = E_X if model.kind == "axial" else E_Y
    fields = [(direction, model)] + ([second] if second is not None else [])
    return floating_bar_from_fields(fields, depth_axis=depth_axis, lateral_second_moment=lateral_second_moment,
                                    modal_damping=modal_damping)


def floating_bar_from_fields(fields: Sequence[tuple[FloatArray, BarModel]], names: Sequence[str] | None = None, *,
                             depth_axis: FloatArray | None = None, lateral_second_moment: float | None = None,
                             modal_damping: float = 0.0) -> FloatingBar:
    """A floating bar with the deformation fields ``[(d_k, model_k), ...]`` on one bar.

    Parameters
    ----------
    fields : sequence of (ndarray (3,), BarModel)
        At least one; all models with the same length, material, area and point masses.
    names : sequence of str, optional
        One per field; default ``"axial"``, ``"bending_y"``, ``"bending_z"``, ... from kind and d.
    depth_axis : ndarray, shape (3,), optional
        Direction in which ``Section.depth`` is measured (normal to e_x). Default: the first bending
        field's d, else e_y.
    lateral_second_moment : float, optional
        Second moment of area about ``depth_axis`` [m^4] (the section's other one); default as in
        the module docstring.
    modal_damping : float
        Damping ratio of every elastic mode, >= 0.
    """
    if not fields:
        raise ValueError("at least one field; use rigid_bar for a bar without deformation")
    dirs = [_unit(d) for d, _ in fields]
    models = [m for _, m in fields]
    first = models[0]
    for d, model in zip(dirs, models):
        _check_field(first, model, d)
    if depth_axis is None:
        bending = [d for d, m in zip(dirs, models) if m.kind == "bending"]
        depth_axis = bending[0] if bending else E_Y
    if names is None:
        names = _default_names(dirs, models)
    if len(names) != len(models) or len(set(names)) != len(names):
        raise ValueError(f"need {len(models)} distinct field names, got {names}")
    return _assemble(first.length, first.material, first.section, first.point_masses, tuple(models), tuple(names),
                     np.array(dirs), depth_axis, lateral_second_moment, modal_damping)


def rigid_bar(length: float, material: Material, section: Section, point_masses: tuple[PointMass, ...] = (), *,
              depth_axis: FloatArray | None = None, lateral_second_moment: float | None = None) -> FloatingBar:
    """The same body without deformation fields (n = 0): a rigid bar."""
    return _assemble(length, material, section, tuple(point_masses), (), (), np.zeros((0, 3)),
                     E_Y if depth_axis is None else depth_axis, lateral_second_moment, 0.0)


def with_geometric_stiffening(bar: FloatingBar) -> FloatingBar:
    """``bar`` with centrifugal geometric stiffening (module docstring): ``K_omega`` about the
    stiffening centre, the first supported end of its bending fields (x = 0, else L), else G."""
    bending = [m for m in bar.fields if m.kind == "bending"]
    if not bending:
        raise ValueError("geometric stiffening needs a bending field")
    supports = bending[0].supports
    x_s = 0.0 if supports[0] != "free" else (bar.length if supports[1] != "free" else bar.x_G)
    x, w = _quadrature(bar.fields, bar.length)
    U1 = _columns([m.shape(x, "u", 1) for m in bar.fields], len(x))[:, None, :] * bar.D[None]   # (m, 3, n)
    U1 -= E_X[None, :, None] * np.einsum("i,miq->mq", E_X, U1)[:, None, :]                     # normal part
    K_omega = np.einsum("m,miq,mip->qp", w * _tension_per_omega2(bar, x, x_s), U1, U1)
    return replace(bar, K_omega=_symmetric(K_omega), x_s=float(x_s))


def _tension_per_omega2(bar: FloatingBar, x: FloatArray, x_s: float) -> FloatArray:
    """``n(x) = int rho A |xi - x_s| dxi + sum m_j |x_j - x_s|`` from x away from x_s to the bar's end
    (m,) [kg m]: the centrifugal tension per unit ``w_perp^2`` of a bar turning about ``x_s``."""
    rhoA = bar.material.rho * bar.section.area
    end = np.where(x >= x_s, bar.length, 0.0)
    n = 0.5 * rhoA * ((end - x_s) ** 2 - (x - x_s) ** 2)
    for pm in bar.point_masses:
        beyond = np.where(x >= x_s, pm.x >= x, pm.x <= x) & (np.sign(pm.x - x_s) == np.sign(x - x_s))
        n += pm.mass * abs(pm.x - x_s) * beyond
    return n


def _unit(d) -> FloatArray:
    d = np.asarray(d, dtype=float)
    if d.shape != (3,) or abs(np.linalg.norm(d) - 1.0) > DIRECTION_TOL:
        raise ValueError(f"a field direction must be a unit 3-vector, got {d}")
    return d


def _check_field(first: BarModel, model: BarModel, d: FloatArray) -> None:
    if model.kind == "axial" and np.abs(d - E_X).max() > DIRECTION_TOL:
        raise ValueError(f"an axial field has d = e_x, got {d}")
    if model.kind == "bending" and abs(d[0]) > DIRECTION_TOL:
        raise ValueError(f"a bending direction must be normal to the bar (e_x), got {d}")
    same = (abs(model.length - first.length) <= SAME_BAR_RTOL * first.length and model.material == first.material
            and abs(model.section.area - first.section.area) <= SAME_BAR_RTOL * first.section.area
            and set(model.point_masses) == set(first.point_masses))
    if not same:
        raise ValueError(f"fields must share the bar (length, material, area, point masses): {first.label!r} vs {model.label!r}")


def _default_names(dirs, models) -> list[str]:
    names = []
    for d, m in zip(dirs, models):
        axis = "xyz"[int(np.argmax(np.abs(d)))] if np.abs(d).max() > 1 - DIRECTION_TOL else "d"
        name = "axial" if m.kind == "axial" else f"bending_{axis}"
        names.append(name if name not in names else f"{name}{len(names)}")
    return names


def section_second_moments(section: Section, lateral_second_moment: float | None = None) -> tuple[float, float]:
    """``(I_d, I_w)`` [m^4]: about the axis normal to the depth direction (``second_moment``) and about
    the depth direction itself (a rectangle's ``A width^2 / 12``; otherwise ``lateral_second_moment``
    or, assumed, ``second_moment`` as for a circle or a square)."""
    I_d, A, h = section.second_moment, section.area, section.depth
    if lateral_second_moment is not None:
        return I_d, float(lateral_second_moment)
    if abs(I_d - A * h**2 / 12.0) <= SAME_BAR_RTOL * I_d:
        return I_d, A * (A / h) ** 2 / 12.0
    return I_d, I_d


def _section_tensor(material: Material, section: Section, depth_axis, lateral_second_moment) -> FloatArray:
    """Sigma = rho int c c^T dA (3, 3) [kg m] in body axes."""
    e_d = _unit(np.asarray(depth_axis, dtype=float))
    if abs(e_d[0]) > DIRECTION_TOL:
        raise ValueError(f"depth_axis must be normal to the bar, got {e_d}")
    e_w = cross(E_X, e_d)
    I_d, I_w = section_second_moments(section, lateral_second_moment)
    return material.rho * (I_d * np.outer(e_d, e_d) + I_w * np.outer(e_w, e_w))


def _quadrature(models: Sequence[BarModel], length: float) -> tuple[FloatArray, FloatArray]:
    """Gauss points and weights on the union of the fields' panels (or [0, L])."""
    edges = np.unique(np.concatenate([[0.0, length]] + [m.basis.breakpoints() for m in models]))
    edges = edges[np.concatenate([[True], np.diff(edges) > BREAKPOINT_RTOL * length])]
    edges[-1] = length
    return gauss_points(edges)


def _assemble(length, material, section, point_masses, models, names, dirs, depth_axis, lateral_second_moment,
              modal_damping) -> FloatingBar:
    """The FloatingBar: rigid data, section tensor, shape integrals, then the invariants S, I0, A, B."""
    rhoA = material.rho * section.area
    mass, x_G, I_line = _rigid_line(length, rhoA, point_masses)
    Sigma = _section_tensor(material, section, depth_axis, lateral_second_moment)
    _check_second_moments(models, dirs, Sigma, material.rho)
    D, Bxi, rotary = _coordinate_axes(models, dirs)
    S1, S2, Phi_Phi, psi_bar, Psi_Psi = _shape_integrals(models, rotary, length, rhoA, x_G, point_masses)
    J_s = np.trace(Sigma) * np.eye(3) - Sigma
    S_psi = np.einsum("iq,ij,jq->q", Bxi, J_s, Bxi) * psi_bar
    I0 = I_line * np.outer(E_X, E_X) + length * Sigma
    J0 = np.trace(I0) * np.eye(3) - I0
    b_skew = skew(Bxi.T)                                     # (n, 3, 3)
    # line: s0 = (x - x_G) e_x, N = D Phi; section (rotary coordinates): c, N = psi skew(b) c
    A = np.einsum("i,jq,q->ijq", E_X, D, S2) + np.einsum("ia,qja,q->ijq", Sigma, b_skew, psi_bar)
    B = np.einsum("ip,jq,pq->ijpq", D, D, Phi_Phi) + np.einsum("pia,ab,qjb,pq->ijpq", b_skew, Sigma, b_skew, Psi_Psi)
    M_ee = _symmetric(np.einsum("iipq->pq", B))
    K = _block_diagonal([m.K for m in models])
    C = modal_damping_matrix(M_ee, K, modal_damping)
    return FloatingBar(length, material, section, tuple(point_masses), models, names, dirs, float(mass), float(x_G),
                       J0, Sigma, D, Bxi, rotary, S1, S2, S_psi, Phi_Phi, Psi_Psi, D * S1, I0, A, B, M_ee, K, C)


def _rigid_line(length: float, rhoA: float, point_masses) -> tuple[float, float, float]:
    """Mass m [kg], centre of mass x_G [m] and int (x - x_G)^2 dm [kg m^2] of the line and point masses."""
    m_pm = np.array([pm.mass for pm in point_masses])
    x_pm = np.array([pm.x for pm in point_masses])
    mass = rhoA * length + m_pm.sum()
    x_G = (rhoA * length**2 / 2.0 + m_pm @ x_pm) / mass
    return mass, x_G, rhoA * length**3 / 3.0 + m_pm @ x_pm**2 - mass * x_G**2


def _check_second_moments(models, dirs, Sigma: FloatArray, rho: float) -> None:
    """Each bending field's second moment must be the body section's about its bending axis."""
    for d, model in zip(dirs, models):
        own, body = rho * model.section.second_moment, d @ Sigma @ d
        if model.kind == "bending" and abs(body - own) > SAME_BAR_RTOL * own:
            raise ValueError(f"field {model.label!r} along {d}: its second moment {model.section.second_moment} "
                             f"differs from the body's section about that axis, {body / rho}")


def _coordinate_axes(models, dirs) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per coordinate: direction d (3, n), section-rotation axis b (3, n; zero for axial fields) and
    whether the rotation carries inertia (n,) (Timoshenko)."""
    n_k = [m.n for m in models]
    axes = [cross(E_X, d) if m.kind == "bending" else np.zeros(3) for d, m in zip(dirs, models)]
    D = np.repeat(np.reshape(dirs, (-1, 3)), n_k, axis=0).T
    Bxi = np.repeat(np.reshape(axes, (-1, 3)), n_k, axis=0).T
    rotary = np.repeat(np.array([m.theory == "timoshenko" for m in models], dtype=bool), n_k)
    return D, Bxi, rotary


def _shape_integrals(models, rotary, length, rhoA, x_G, point_masses):
    """S1 (n,), S2 about G (n,), Phi_Phi (n, n), int psi dx (n,), Psi_Psi (n, n) over all fields."""
    x, w = _quadrature(models, length)
    x_pm = np.array([pm.x for pm in point_masses])
    m_pm = np.array([pm.mass for pm in point_masses])
    Phi = _columns([m.displacement(x) for m in models], len(x))
    Phi_pm = _columns([m.displacement(x_pm) for m in models], len(x_pm)) if len(x_pm) else np.zeros((0, len(rotary)))
    Psi = _columns([m.rotation(x) if m.theory == "timoshenko" else np.zeros((len(x), m.n)) for m in models], len(x))
    S1 = rhoA * (w @ Phi) + m_pm @ Phi_pm
    S2 = rhoA * ((w * (x - x_G)) @ Phi) + (m_pm * (x_pm - x_G)) @ Phi_pm
    Phi_Phi = rhoA * (Phi.T * w) @ Phi + (Phi_pm.T * m_pm) @ Phi_pm
    return S1, S2, _symmetric(Phi_Phi), w @ Psi, _symmetric((Psi.T * w) @ Psi)


def _columns(blocks, rows: int) -> FloatArray:
    return np.hstack(blocks) if blocks else np.zeros((rows, 0))


def _symmetric(a: FloatArray) -> FloatArray:
    return 0.5 * (a + a.T)


def _block_diagonal(blocks: Sequence[FloatArray]) -> FloatArray:
    n = sum(b.shape[0] for b in blocks)
    out, i = np.zeros((n, n)), 0
    for b in blocks:
        out[i:i + b.shape[0], i:i + b.shape[0]] = b
        i += b.shape[0]
    return out


def modal_damping_matrix(M: FloatArray, K: FloatArray, zeta: float) -> FloatArray:
    """``C = M V diag(2 zeta omega) V^T M`` (n, n) with ``K V = M V diag(omega^2)``, ``V^T M V = I``:
    damping ratio ``zeta`` on every mode, none on rigid (zero-frequency) ones."""
    from scipy.linalg import eigh
    if zeta < 0:
        raise ValueError(f"modal damping ratio must be >= 0, got {zeta}")
    if zeta == 0 or M.shape[0] == 0:
        return np.zeros_like(M)
    omega2, V = eigh(K, M)
    rigid = omega2 < RIGID_EIGENVALUE_FACTOR * len(omega2) * np.finfo(float).eps * omega2.max()
    omega = np.where(rigid, 0.0, np.sqrt(np.abs(omega2)))
    return M @ V @ np.diag(2.0 * zeta * omega) @ V.T @ M


# ---- configuration-dependent inertia ------------------------------------------------------------
def shape_moments(bar: FloatingBar, eta: FloatArray) -> FloatArray:
    """``F[i, j, q] = int s_i N_jq dV = A + B . eta`` (3, 3, n) [kg m per unit eta] at the deformation eta."""
    return bar.A + np.einsum("ijpq,p->ijq", bar.B, eta)


def second_moment(bar: FloatingBar, eta: FloatArray) -> FloatArray:
    """``Sigma2 = int s s^T dV`` (3, 3) [kg m^2], about the origin of B."""
    return _second_moment(bar, shape_moments(bar, eta), eta)


def _second_moment(bar: FloatingBar, F: FloatArray, eta: FloatArray) -> FloatArray:
    """``int s s^T = int s s0^T + int s (N eta)^T = I0 + (A . eta)^T + F . eta``."""
    return bar.I0 + (bar.A @ eta).T + F @ eta


def inertia_tensor(bar: FloatingBar, eta: FloatArray) -> FloatArray:
    """J(eta) (3, 3) [kg m^2]: inertia of the deformed body about the origin of B, body axes."""
    return _inertia(_second_moment(bar, shape_moments(bar, eta), eta))


def _inertia(Sigma2: FloatArray) -> FloatArray:
    return np.trace(Sigma2) * np.eye(3) - Sigma2


def rotation_coupling(bar: FloatingBar, eta: FloatArray) -> FloatArray:
    """G(eta) (3, n) [kg m per unit eta]: ``G eta_dot = int s x s_dot dV``, the elastic angular momentum."""
    return _eps_contract(shape_moments(bar, eta))


def _eps_contract(F: FloatArray) -> FloatArray:
    """``eps_kij F[i, j, ...]`` for F of shape (3, 3, ...)."""
    return np.stack([F[1, 2] - F[2, 1], F[2, 0] - F[0, 2], F[0, 1] - F[1, 0]])


def mass_matrix(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray) -> FloatArray:
    """The FFR mass matrix M (6 + n, 6 + n) in ``v = [W_v, B_omega, eta_dot]`` (module docstring).

    Parameters
    ----------
    R_WB : ndarray, shape (3, 3)
    eta : ndarray, shape (n,)

    Returns
    -------
    M : ndarray, shape (6 + n, 6 + n) [kg, kg m, kg m^2, ... per unit eta]
    """
    n = bar.n
    F = shape_moments(bar, eta)
    M = np.empty((6 + n, 6 + n))
    M[:3, :3] = bar.mass * np.eye(3)
    M[:3, 3:6] = -R_WB @ skew(bar.S @ eta)
    M[:3, 6:] = R_WB @ bar.S
    M[3:6, 3:6] = _inertia(_second_moment(bar, F, eta))
    M[3:6, 6:] = _eps_contract(F)
    M[6:, 6:] = bar.M_ee
    M[3:, :3] = M[:3, 3:].T
    M[6:, 3:6] = M[3:6, 6:].T
    return M


# ---- generalized forces -------------------------------------------------------------------------
def velocity_forces(bar: FloatingBar, R_WB: FloatArray, B_omega: FloatArray, eta: FloatArray,
                    eta_dot: FloatArray) -> FloatArray:
    """Q_velocity (6 + n,): centrifugal, Coriolis and gyroscopic forces, on the right-hand side of
    ``M v_dot = Q``; ``[W_F [N], B_tau [N m], Q_eta]``. Independent of W_v (module docstring)."""
    w = B_omega
    F = shape_moments(bar, eta)
    s_c, s_c_dot = bar.S @ eta, bar.S @ eta_dot
    J = _inertia(_second_moment(bar, F, eta))
    Y = (F @ eta_dot).T                                      # int s_dot s^T dV
    W = np.outer(w, w) - (w @ w) * np.eye(3)                 # skew(w)^2
    Q_v = -R_WB @ (cross(w, cross(w, s_c)) + 2.0 * cross(w, s_c_dot))
    Q_w = -cross(w, J @ w) - 2.0 * (np.trace(Y) * w - Y @ w)
    Q_eta = -np.einsum("ij,jiq->q", W, F) - 2.0 * np.einsum("ij,ijqp,p->q", skew(w), bar.B, eta_dot)
    if bar.K_omega is not None:
        Q_eta -= stiffening_rate(bar, w) * (bar.K_omega @ eta)
    return np.concatenate([Q_v, Q_w, Q_eta])


def stiffening_rate(bar: FloatingBar, B_omega: FloatArray) -> float:
    """``w_perp^2 = B_omega^T P B_omega`` [rad^2/s^2]: the squared rate of turning about axes normal to the bar."""
    return float(B_omega @ P_AXIS @ B_omega)


def stiffening_power(bar: FloatingBar, B_omega: FloatArray, eta: FloatArray, eta_dot: FloatArray) -> float:
    """Power of the geometric stiffness force, ``-w_perp^2 eta_dot^T K_w eta`` [W] (0 without it): not a
    potential's, it goes with the ledger's work in."""
    if bar.K_omega is None:
        return 0.0
    return -stiffening_rate(bar, B_omega) * float(eta_dot @ bar.K_omega @ eta)


def elastic_forces(bar: FloatingBar, eta: FloatArray, eta_dot: FloatArray) -> FloatArray:
    """Q_elastic = -K eta - C eta_dot (n,); the frame rows are zero (internal forces)."""
    return -bar.K @ eta - bar.C @ eta_dot


def gravity_forces(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray, W_g: FloatArray) -> FloatArray:
    """Q_gravity (6 + n,) of the uniform field ``W_g`` (3,) [m/s^2]: ``[m g, s_c x g_B, S^T g_B]``,
    ``s_c = S eta`` the first moment of the deformed body about the origin of B, ``g_B = R_WB^T g``:
    the weight, its moment about the undeformed centre of mass, the consistent elastic load."""
    W_g = np.asarray(W_g, dtype=float)
    g_B = R_WB.T @ W_g
    return np.concatenate([bar.mass * W_g, cross(bar.S @ eta, g_B), bar.S.T @ g_B])


# ---- energies and momenta -----------------------------------------------------------------------
def kinetic_energy(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray, v: FloatArray) -> float:
    """T = 1/2 v^T M v [J]."""
    return 0.5 * float(v @ mass_matrix(bar, R_WB, eta) @ v)


def kinetic_energies(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray, v: FloatArray) -> FloatArray:
    """``kinetic_energy`` of N states at once: ``R_WB`` (N, 3, 3), ``eta`` (N, n), ``v`` (N, 6 + n) ->
    T (N,) [J], from the blocks of M (``mass_matrix``) without forming it."""
    W_v, w, eta_dot = v[:, :3], v[:, 3:6], v[:, 6:]
    F = bar.A + np.einsum("ijpq,np->nijq", bar.B, eta)                         # (N, 3, 3, n)
    Sigma2 = bar.I0 + np.einsum("ijq,nq->nji", bar.A, eta) + np.einsum("nijq,nq->nij", F, eta)
    J = np.trace(Sigma2, axis1=1, axis2=2)[:, None, None] * np.eye(3) - Sigma2
    G = np.stack([F[:, 1, 2] - F[:, 2, 1], F[:, 2, 0] - F[:, 0, 2], F[:, 0, 1] - F[:, 1, 0]], axis=1)  # (N, 3, n)
    B_v = np.einsum("nji,nj->ni", R_WB, W_v)                                   # W_v in body axes
    s_c = eta @ bar.S.T
    return (0.5 * bar.mass * np.einsum("ni,ni->n", W_v, W_v)
            + np.einsum("ni,ni->n", B_v, np.cross(w, s_c) + eta_dot @ bar.S.T)
            + 0.5 * np.einsum("ni,nij,nj->n", w, J, w)
            + np.einsum("ni,niq,nq->n", w, G, eta_dot)
            + 0.5 * np.einsum("ni,ij,nj->n", eta_dot, bar.M_ee, eta_dot))


def strain_energy(bar: FloatingBar, eta: FloatArray) -> float:
    """U = 1/2 eta^T K eta [J]."""
    return 0.5 * float(eta @ bar.K @ eta)


def gravity_potential(bar: FloatingBar, W_r: FloatArray, R_WB: FloatArray, eta: FloatArray, W_g: FloatArray) -> float:
    """V = -W_g . (m W_r + R_WB S eta) [J] (zero at the world origin)."""
    return -float(np.asarray(W_g, dtype=float) @ (bar.mass * np.asarray(W_r, dtype=float) + R_WB @ (bar.S @ eta)))


def linear_momentum(bar: FloatingBar, R_WB: FloatArray, eta: FloatArray, v: FloatArray) -> FloatArray:
    """W_L = int W_p_dot dm (3,) [kg m/s], world axes: the first three rows of M v."""
    return mass_matrix(bar, R_WB, eta)[:3] @ v


def angular_momentum(bar: FloatingBar, W_r: FloatArray, R_WB: FloatArray, eta: FloatArray, v: FloatArray) -> FloatArray:
    """W_H (3,) [kg m^2/s] about the world origin, world axes: ``W_r x W_L + R_WB (M v)[3:6]``
    (``(M v)[3:6] = dT/dB_omega`` is the angular momentum about the origin of B in body axes)."""
    Mv = mass_matrix(bar, R_WB, eta) @ v
    return cross(np.asarray(W_r, dtype=float), Mv[:3]) + R_WB @ Mv[3:6]

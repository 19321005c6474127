"""Flexible bars for impact simulations: linear models of straight bars (analytic modes, finite
elements, modal reduction) and the choice of how many modes to keep.

Conventions (every module here follows them; SI units as in docs/notation.md):

* **Axis.** A bar of length L lies along its local x axis, 0 <= x <= L, measured from the
  *reference end* x = 0 (where a floating frame of reference is attached, or the contact end of
  the thesis's free-bar models). ``supports = (at x = 0, at x = L)``, each "free", "clamped" or
  "pinned"; for an axial bar "pinned" = "clamped" = fixed displacement. End masses and
  "tip" masses sit at x = L.
* **One deformation kind per model.** ``kind = "axial"``: displacement u(x) along +x (elementary
  rod theory, no lateral inertia). ``kind = "bending"``: planar deflection w(x) along the local
  axis in which ``Section.depth`` is measured, with section rotation psi(x) (positive in the sense
  of w' : psi = w' for Euler-Bernoulli, psi = w' - gamma for Timoshenko, gamma the shear strain).
* **Fields.** ``u(x) = Phi(x) q``; ``BarModel.displacement(x)`` returns Phi (len(x), n).
  ``strain`` is u' (axial) or the surface strain -(depth/2) psi' at the fibre on the +w side
  (bending). Bending moment M = EI psi'; shear force V = -dM/dx (= k G A gamma; -EI w''' for EB).
  A static tip load P (+w) on a cantilever gives M(x) = P (L - x), surface strain -M c / EI.
* **Coordinates and units.** FE models: q = free nodal dofs [m, rad]. Modal models: q = modal
  amplitudes; with ``normalization="mass"`` (the default, and ``reduce``'s) M = I, K = diag(omega^2),
  Phi in 1/sqrt(kg) and q in m sqrt(kg); with ``"unit"`` the peak |u| of each shape is 1 (Phi
  dimensionless, q in m, M in kg). Either way Phi q is in metres and M is the kinetic-energy
  matrix in q (T = 1/2 qd^T M qd).
* **Floating-frame integrals.** ``S1 = int rho A Phi dx`` and ``S2 = int rho A x Phi dx`` (both
  plus the attached point masses) are the elastic linear and angular (about x = 0) momenta per
  unit qd; Timoshenko bars add the section rotary inertia ``S_psi = int rho I psi dx`` to the
  angular one. ``mass``, ``static_moment``, ``inertia_origin`` are the rigid ones. Free-free and
  free-with-end-mass elastic modes have S1 = 0, free-free and pinned-free bending modes
  S2 + S_psi = 0 (mean-axis conditions, thesis 9.20 and 10.10), so in a floating frame their reference
  coordinates decouple from the elastic ones.
* **Rigid modes.** Analytic free-free and pinned-free sets contain only elastic modes: the rigid
  translation / rotation is the motion of the floating frame itself (its reference coordinates).
  FE models of unsupported bars keep their zero-frequency modes; ``reduce(..., drop_rigid=True)``
  removes them.

Modules: ``bar`` (Material, Section, PointMass, BarModel, reduce), ``modes`` (analytic mode sets,
registry ``MODE_SETS``), ``fe`` (finite elements, ``fe_model``, element choice ``ELEMENT_TYPES``,
nodal curvature and stress), ``planar`` (planar beams on a floating frame: seed 003's 8-DOF
element and the 6-DOF cubic one), ``selection`` (mode count).
Source: J. L. Escalona, *Análisis dinámico de impactos en barras flexibles*, PhD thesis, Sevilla
2000 (seed 002); its digest lists the errata these modules correct.
"""

import importlib

#: The package's names and the module of each, imported on first use (a rigid run imports ``floating``
#: and ``bar`` only; the mode sets, planar elements and mode selection are 8 ms of a run's start).
_MODULE_OF = {
    **dict.fromkeys(("BarModel", "Material", "PointMass", "Section", "reduce"), "bar"),
    **dict.fromkeys(("ELEMENT_TYPES", "ELEMENTS", "fe_model", "node_bending_stress", "node_curvature"), "fe"),
    **dict.fromkeys(("MODE_SETS", "analytic_modes", "mode_set"), "modes"),
    **dict.fromkeys(("PLANAR_ELEMENTS", "PlanarBeam", "planar_beam"), "planar"),
    **dict.fromkeys(("ModeSelection", "contact_band", "select_modes"), "selection"),
}

__all__ = list(_MODULE_OF)


def __getattr__(name: str):
    if name not in _MODULE_OF:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_MODULE_OF[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

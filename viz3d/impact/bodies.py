"""Flexible bars as ``LinearBody``s: elastic coordinates plus the motion of a floating frame.

A bar model (``viz3d.flexible.BarModel``) gives ``u(x) = Phi(x) q`` relative to its frame. The
frame itself may be (thesis ch. 6 and 10)

* ``fixed``: clamped structure, ``z = q``;
* ``free``: it translates along the deformation direction, ``z = [X, q]`` (axial) or
  ``z = [Y, Theta, q]`` (bending: translation and small rotation about x = 0);
* ``pinned``: it rotates about x = 0 (a pendulum), ``z = [Theta, q]`` (bending only).

Displacement of a bar point along the deformation direction: ``X + u(x)`` (axial),
``Y + x Theta + w(x)`` (bending). The mass matrix couples frame and elastic coordinates through
``S1 = int rho A Phi`` and ``S2 = int rho A x Phi`` (+ ``S_psi`` for Timoshenko); with free-free
or pinned-free modes those vanish (mean axes) and the blocks decouple. Rotations are small: the
contact lasts microseconds to milliseconds.
"""

from __future__ import annotations

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible import BarModel
from viz3d.impact.engine import LinearBody

REFERENCES = ("fixed", "free", "pinned")


def frame_columns(model: BarModel, reference: str) -> int:
    """Number of frame coordinates for ``reference``."""
    if reference not in REFERENCES:
        raise ValueError(f"reference must be one of {REFERENCES}, got {reference!r}")
    if reference == "pinned" and model.kind != "bending":
        raise ValueError("a pinned (rotating) frame needs a bending model")
    return {"fixed": 0, "free": 1 if model.kind == "axial" else 2, "pinned": 1}[reference]


def frame_mass_matrix(model: BarModel, reference: str) -> FloatArray:
    """Mass matrix of ``z = [frame coordinates, q]``."""
    m = model
    rot_inertia = m.inertia_origin + (m.material.rho * m.section.second_moment * m.length
                                      if m.theory == "timoshenko" else 0.0)
    if reference == "fixed":
        blocks, coupling = np.zeros((0, 0)), np.zeros((0, m.n))
    elif m.kind == "axial":
        blocks, coupling = np.array([[m.mass]]), m.S1[None]
    elif reference == "free":
        blocks = np.array([[m.mass, m.static_moment], [m.static_moment, rot_inertia]])
        coupling = np.vstack([m.S1, m.S2 + m.S_psi])
    else:  # pinned
        blocks, coupling = np.array([[rot_inertia]]), (m.S2 + m.S_psi)[None]
    return np.block([[blocks, coupling], [coupling.T, m.M]])


def point_row(model: BarModel, reference: str, x: float) -> FloatArray:
    """Displacement of bar point ``x`` along the deformation direction per unit ``z``, shape (n_z,)."""
    frame = {"fixed": [], "free": [1.0] if model.kind == "axial" else [1.0, x], "pinned": [x]}[reference]
    return np.concatenate([frame, model.displacement([x])[0]])


def centre_of_mass_row(model: BarModel, reference: str) -> FloatArray:
    """Displacement of the bar's centre of mass along the deformation direction per unit ``z``, (n_z,).

    ``(1/m) int rho A (frame motion + u(x)) dx``: the frame's translation (1 per unit), its small
    rotation about x = 0 (the static moment over the mass per radian) and the elastic mean
    displacement ``S1 q / m``. The velocity of the centre of mass is the same row times ``zd``.
    """
    frame = {"fixed": [], "free": [model.mass] if model.kind == "axial" else [model.mass, model.static_moment],
             "pinned": [model.static_moment]}[reference]
    return np.concatenate([frame, model.S1]) / model.mass


def modal_time_resolution(model: BarModel) -> float:
    """Period of the highest mode the model retains [s] (``T/N`` for N axial modes of a bar):
    nothing shorter is resolved. 0 for a model without elastic frequencies (nothing rings)."""
    omega = model.frequencies()
    return 2.0 * np.pi / omega.max() if omega.max() > 0.0 else 0.0


def bar_body(name: str, model: BarModel, reference: str, x_contact: float, sign: float,
             frame_velocity: FloatArray | None = None, modal_damping: float = 0.0) -> LinearBody:
    """A bar hit at ``x_contact`` whose contact normal is ``sign`` times its deformation direction.

    Parameters
    ----------
    frame_velocity : ndarray, optional
        Initial velocities of the frame coordinates (e.g. a pendulum's angular velocity [rad/s]).
    modal_damping : float
        Damping ratio applied to every elastic mode (0: undamped, as in the thesis).
    """
    nf = frame_columns(model, reference)
    M = frame_mass_matrix(model, reference)
    K = np.zeros_like(M)
    K[nf:, nf:] = model.K
    C = np.zeros_like(M)
    if modal_damping > 0:
        C[nf:, nf:] = _stiffness_proportional_damping(model, modal_damping)
    zd0 = np.zeros(M.shape[0])
    if frame_velocity is not None:
        zd0[:nf] = frame_velocity
    rigid = np.arange(M.shape[0]) < nf
    r = sign * point_row(model, reference, x_contact)
    return LinearBody(name, M, C, K, r, np.zeros(M.shape[0]), np.zeros(M.shape[0]), zd0, rigid)


def _stiffness_proportional_damping(model: BarModel, zeta: float) -> FloatArray:
    """Modal damping ratio ``zeta`` on every mode: ``C = M V diag(2 zeta omega) V^T M``."""
    from scipy.linalg import eigh

    w2, V = eigh(model.K, model.M)
    omega = np.sqrt(np.clip(w2, 0.0, None))
    return model.M @ V @ np.diag(2 * zeta * omega) @ V.T @ model.M

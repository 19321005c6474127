"""Equations of motion: from a state to accelerations, reaction multipliers and energies.

The recipe (``accelerations``): body configuration (frames, twists, elastic coordinates) -> mass
matrix blocks -> applied, gyroscopic, velocity and elastic generalized forces -> constraint rows
(residual, Jacobian, gamma) -> the formulation solves the augmented system
``[M C_v^T; C_v 0] [v_dot; lam] = [Q; gamma]``. Integrators see only ``vector_field``.

Generalized vectors are split per body (``viz3d.mass``): a frame part (nb + 1, 6) ``[W_F, B_tau]``
and an elastic part (n_e,).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from viz3d._typing import FloatArray
from viz3d.constraints import ConstraintRows, constraint_rows
from viz3d.flexible import floating as ffr
from viz3d.kinematics import Configuration, Pose, Twist, pose_from, twist_from
from viz3d.mass import MassMatrix, mass_matrix
from viz3d.rotations import cross
from viz3d.system import State, System


def body_state(system: System, q: FloatArray, v: FloatArray, chart: FloatArray, t: float = 0.0) -> Configuration:
    """The ``Configuration`` of all bodies (ground appended) from ``q`` (n_q,), ``v`` (n_v,)."""
    W_r, theta = system.split_q(q)
    R = system.rotation.matrix(theta, chart)
    W_v, B_omega = system.split_v(v)
    if system.all_frames_float:
        pose = pose_from(W_r, R)
        twist = twist_from(W_v, B_omega, pose)
    else:
        pose, twist = _with_fixed_frames(system, W_r, R, W_v, B_omega)
    return Configuration(t, pose, twist, system.elastic_q(q), system.elastic_v(v))


def _with_fixed_frames(system: System, W_r, R, W_v, B_omega) -> tuple[Pose, Twist]:
    """Pose and twist rows for every body when some frames are fixed (at their initial pose, at rest)."""
    nb = system.n_bodies
    W_r_all, R_all = np.zeros((nb, 3)), np.broadcast_to(np.eye(3), (nb, 3, 3)).copy()
    v_all, w_all = np.zeros((nb, 3)), np.zeros((nb, 3))
    for fb in system.bodies.flexible:
        W_r_all[fb.index], R_all[fb.index] = fb.W_r0, fb.R0
    W_r_all[system.frame_body], R_all[system.frame_body] = W_r, R
    v_all[system.frame_body], w_all[system.frame_body] = W_v, B_omega
    pose = pose_from(W_r_all, R_all)
    return pose, twist_from(v_all, w_all, pose)


def generalized_forces(system: System, cfg: Configuration, memory: tuple = (),
                       elements: tuple = ()) -> tuple[FloatArray, FloatArray]:
    """``Q``: frame part (nb + 1, 6) ``[W_F, B_tau - gyroscopic]`` [N, N m] and elastic part (n_e,).

    Forces are world vectors at the frame origins; torques are about them, in body axes. Rigid
    bodies add ``-B_omega x I B_omega``; flexible bodies their velocity forces (centrifugal,
    Coriolis, gyroscopic) and elastic forces ``-K eta - C eta_dot``; contacts their law forces,
    given their phases in ``memory`` (``State.memory``); force elements with memory theirs in
    ``elements`` (``State.element_memory``). Rows of ground and of fixed frames are zero (their
    reactions are not unknowns).
    """
    pose, twist = cfg.pose, cfg.twist
    W_F = np.zeros_like(pose.W_r)
    W_tau = np.zeros_like(pose.W_r)
    Q_e = np.zeros(system.n_elastic)
    for i, element in enumerate(system.forces):
        F, tau, e = element.wrench(cfg) if not elements or elements[i] is None else element.wrench(cfg, elements[i])
        W_F += F
        W_tau += tau
        if e is not None:
            Q_e += e
    for k, contacts in enumerate(system.contacts):
        F, tau, e = contacts.wrench(cfg, memory[k] if memory else contacts.initial_phases())
        W_F += F
        W_tau += tau
        Q_e += e
    Q = np.zeros((W_F.shape[0], 6))
    Q[:, :3] = W_F
    Q[:, 3:] = np.einsum("bji,bj->bi", pose.R_WB, W_tau)  # R^T tau: body axes
    rigid = system.bodies.is_rigid
    if system.bodies.all_rigid:
        Q[:-1, 3:] -= system.bodies.gyroscopic(twist.B_omega[:-1])
    else:
        Q[:-1][rigid, 3:] -= system.bodies.gyroscopic(twist.B_omega[:-1])[rigid]
        _flexible_forces(system, cfg, Q, Q_e)
    Q[-1] = 0.0  # ground
    return Q, Q_e


def _flexible_forces(system: System, cfg: Configuration, Q: FloatArray, Q_e: FloatArray) -> None:
    """Add the flexible bodies' velocity and elastic forces; zero the rows of fixed frames."""
    for i, fb in enumerate(system.bodies.flexible):
        sl = system.v_elastic[i]
        eta, eta_dot = cfg.eta[i], cfg.eta_dot[i]
        Q_e[_local(system, sl)] += ffr.elastic_forces(fb.bar, eta, eta_dot)
        if not fb.floating:
            Q[fb.index] = 0.0
            continue
        Q_v = ffr.velocity_forces(fb.bar, cfg.pose.R_WB[fb.index], cfg.twist.B_omega[fb.index], eta, eta_dot)
        Q[fb.index] += Q_v[:6]
        Q_e[_local(system, sl)] += Q_v[6:]


def _local(system: System, sl: slice) -> slice:
    """A body's slice of ``v`` as a slice of the stacked elastic part."""
    n0 = 6 * system.n_frames
    return slice(sl.start - n0, sl.stop - n0)


def elastic_slices(system: System) -> tuple[slice, ...]:
    """Each flexible body's slice of the stacked elastic part (n_e,)."""
    return tuple(_local(system, sl) for sl in system.v_elastic)


def system_mass(system: System, cfg: Configuration) -> MassMatrix:
    """The mass matrix blocks at ``cfg``."""
    return mass_matrix(system.bodies, elastic_slices(system), cfg)


@dataclass(frozen=True)
class Accelerations:
    """Result of the dynamics at one state.

    Attributes
    ----------
    v_dot : ndarray, shape (n_v,)
        ``[W_a, B_alpha]`` per floating frame, then ``eta_ddot`` [m/s^2, rad/s^2, ...].
    lam : ndarray, shape (n_c,)
        Multipliers; the constraint force on the bodies is ``-C_v^T lam`` [N].
    rows : ConstraintRows
    cfg : Configuration
        The configuration they were computed at.
    """

    v_dot: FloatArray
    lam: FloatArray
    rows: ConstraintRows
    cfg: Configuration


def accelerations(system: System, formulation, t: float, q: FloatArray, v: FloatArray,
                  chart: FloatArray, memory: tuple = (), cfg: Configuration | None = None,
                  elements: tuple = ()) -> Accelerations:
    """Accelerations and multipliers at ``(t, q, v)`` with the contact phases ``memory`` and the force
    elements' memory ``elements`` (the physics recipe); ``cfg``: the configuration at that point if
    the caller has it."""
    cfg = body_state(system, q, v, chart, t) if cfg is None else cfg
    if any(fb.ked for fb in system.bodies.flexible):
        return kineto_elastodynamic(system, formulation, cfg, memory, elements)
    mass = system_mass(system, cfg)
    Q = generalized_forces(system, cfg, memory, elements)
    rows = constraint_rows(system.joints, cfg, memory)
    (a, a_e), lam = formulation.solve(system, mass, Q, rows, cfg)
    return Accelerations(flat_velocity(system, a, a_e), lam, rows, cfg)


def kineto_elastodynamic(system: System, formulation, cfg: Configuration, memory: tuple = (),
                         elements: tuple = ()) -> Accelerations:
    """``accelerations`` with the flexible bodies marked ``ked`` (seed 003's kineto-elastodynamics):
    the mechanism moves as if they were rigid — their frame forces, mass blocks and joint rows are
    those of the undeformed body (``undeformed``), without elastic columns — and their elastic
    equations are loaded by that rigid motion only: ``M_ee eta_ddot = Q_e(rigid) - K eta - C eta_dot
    - M_ef(0) a_frame``, ``Q_e(rigid)`` the loads on the undeformed body at elastic rest (velocity
    forces, gravity, applied). Neither the feedback on the frame nor the motion-dependent terms in
    eta (centrifugal softening, Coriolis, Euler, geometric stiffening) are kept (docs/notation.md)."""
    rigid = undeformed(system, cfg)
    Q, Q_e = generalized_forces(system, cfg, memory, elements)
    Q_r, Q_e_r = generalized_forces(system, rigid, memory, elements)
    ked = [(i, fb) for i, fb in enumerate(system.bodies.flexible) if fb.ked]
    slices = elastic_slices(system)
    for i, fb in ked:
        Q[fb.index] = Q_r[fb.index]
        Q_e[slices[i]] = Q_e_r[slices[i]] + ffr.elastic_forces(fb.bar, cfg.eta[i], cfg.eta_dot[i])
    rows = constraint_rows(system.joints, rigid, memory)
    Je = rows.Je.copy()
    for i, _ in ked:
        Je[:, :, slices[i]] = 0.0
    rows = dataclasses.replace(rows, Je=Je)
    (a, a_e), lam = formulation.solve(system, system_mass(system, cfg), (Q, Q_e), rows, rigid)
    for i, fb in ked:
        if fb.floating:
            M_ef = ffr.mass_matrix(fb.bar, cfg.pose.R_WB[fb.index], np.zeros(fb.n))[6:, :6]
            a_e[slices[i]] -= fb.M_ee_inv @ (M_ef @ a[fb.index])
    return Accelerations(flat_velocity(system, a, a_e), lam, rows, cfg)


def undeformed(system: System, cfg: Configuration) -> Configuration:
    """``cfg`` with the kineto-elastodynamic bodies undeformed and at elastic rest (their rigid motion)."""
    eta = tuple(np.zeros_like(e) if fb.ked else e for fb, e in zip(system.bodies.flexible, cfg.eta))
    eta_dot = tuple(np.zeros_like(e) if fb.ked else e for fb, e in zip(system.bodies.flexible, cfg.eta_dot))
    return dataclasses.replace(cfg, eta=eta, eta_dot=eta_dot)


def flat_velocity(system: System, frame: FloatArray, elastic: FloatArray) -> FloatArray:
    """A split generalized vector (frame (nb + 1, 6), elastic (n_e,)) in the order of ``v`` (n_v,)."""
    if system.all_frames_float:
        f = frame[:-1].reshape(-1)
    else:
        f = frame[system.frame_body].reshape(-1)
    return np.concatenate([f, elastic]) if elastic.size else f


def split_velocity(system: System, x: FloatArray) -> tuple[FloatArray, FloatArray]:
    """A vector in the order of ``v`` (n_v,) as split parts (frame (nb + 1, 6), elastic (n_e,))."""
    frame = np.zeros((system.n_bodies + 1, 6))
    frame[system.frame_body] = x[: 6 * system.n_frames].reshape(-1, 6)
    return frame, x[6 * system.n_frames:]


def kinematic_rates(system: System, q: FloatArray, v: FloatArray) -> FloatArray:
    """``q_dot`` (n_q,) from the velocities: ``W_r_dot = W_v``, ``theta_dot = f(theta, B_omega)``,
    ``eta_dot`` as is."""
    _, theta = system.split_q(q)
    W_v, B_omega = system.split_v(v)
    return system.join_q(W_v, system.rotation.rates(theta, B_omega), system.elastic_part(v, 6 * system.n_frames))


def retract(system: System, q: FloatArray, w: FloatArray, chart: FloatArray) -> FloatArray:
    """Positions moved by the velocity-space increment ``w`` (n_v,), in the same charts.

    Per floating frame ``w = [dW_r (3) [m], B_dphi (3) [rad]]``: ``W_r + dW_r`` and ``R_WB @
    exp(skew(B_dphi))`` (the Lie-group update of ``R^3 x SO(3)`` that ``gen_alpha`` and ``ali3p``
    advance positions by); elastic coordinates ``eta + d_eta``.
    """
    W_r, theta = system.split_q(q)
    dW_r, B_dphi = system.split_v(w)
    n_f = system.n_frames * system.n_q_body
    eta = system.elastic_part(q, n_f) + system.elastic_part(w, 6 * system.n_frames)
    return system.join_q(W_r + dW_r, system.rotation.advance(theta, chart, B_dphi), eta)


def dexpinv(system: System, u: FloatArray, v: FloatArray) -> FloatArray:
    """The rate ``u_dot`` (n_v,) of the velocity-space increment ``u`` (n_v,) for which ``retract(q,
    u)`` moves at the velocities ``v`` (n_v,).

    Per floating frame ``B_omega + 1/2 B_u x B_omega + 1/12 B_u x (B_u x B_omega)`` [rad/s]: the
    inverse differential of ``R exp(skew(B_u))`` for body angular velocities (``dexp^-1`` at ``-B_u``),
    truncated after the terms a fourth-order Munthe-Kaas method needs (the next is O(|B_u|^4));
    translations and elastic coordinates move on vector spaces: their ``v`` as is.
    """
    out = np.array(v[: system.n_v], dtype=float)
    B_u, B_omega = system.split_v(u)[1], system.split_v(v)[1]
    c = cross(B_u, B_omega)
    system.split_v(out)[1][:] = B_omega + 0.5 * c + cross(B_u, c) / 12.0
    return out


def aux_rates(system: System, cfg: Configuration, memory: tuple, elements: tuple = (),
              drives: float = 0.0) -> FloatArray:
    """Rates of the work integrals ``w`` of the energy ledger (``System.n_aux``, ``viz3d.events``): per
    contact ``F alpha_dot``; the power taken by dampers: the flexible bodies' damping and the
    non-potential power of dissipative force elements (``ForceElement.dissipative``: dampers, stops,
    drag, shape contacts' damping and friction); the work in: the power of the other elements'
    non-conservative forces (``ForceElement.nonconservative_power``: motors, applied loads) and of the
    flexible bodies' geometric stiffening (``viz3d.flexible.floating.stiffening_power``) plus ``drives``,
    the drives' power (``drive_power``) [W]."""
    parts = [c.power(cfg, memory[k] if memory else c.initial_phases()) for k, c in enumerate(system.contacts)]
    # (called only when the system keeps a ledger: some contact set is located, or a drive works)
    damping = stiffening = 0.0
    for i, fb in enumerate(system.bodies.flexible):
        damping += float(cfg.eta_dot[i] @ fb.bar.C @ cfg.eta_dot[i])
        if fb.floating and not fb.ked:  # (kineto-elastodynamics leaves the stiffening out)
            stiffening += ffr.stiffening_power(fb.bar, cfg.twist.B_omega[fb.index], cfg.eta[i], cfg.eta_dot[i])
    power_in = stiffening + drives
    for i, element in enumerate(system.forces):
        power = (element.nonconservative_power(cfg) if not elements or elements[i] is None
                 else element.nonconservative_power(cfg, elements[i]))
        if element.dissipative:
            damping -= power
        else:
            power_in += power
    return np.concatenate(parts + [[damping, power_in]])


def drive_power(lam: FloatArray, C_t: FloatArray | None) -> float:
    """Power of the drives on the bodies, ``lam . C_t`` [W]: a drive row's force ``-C_v^T lam`` does
    ``-lam C_v v`` and a drive holds ``C_v v = -C_t`` (0 without drives, ``C_t`` None)."""
    return 0.0 if C_t is None else float(lam @ C_t)


def element_memory(system: System, state: State) -> tuple:
    """``State.element_memory`` after an accepted step that ends at ``state`` (or at the start of a
    run): each force element with memory renews its own (``ForceElement.memory_after_step``) from
    the one it carried during the step; () when no element keeps one."""
    if not any(e.has_memory for e in system.forces):
        return ()
    cfg = body_state(system, state.q, state.v, state.chart, state.t)
    old = state.element_memory or (None,) * len(system.forces)
    return tuple(e.memory_after_step(cfg, m) if e.has_memory else None for e, m in zip(system.forces, old))


class VectorField:
    """``y_dot = f(t, y)`` with ``y = [q, v, w]``, for a fixed chart, contact phases and force elements'
    memory; what integrators see (``w``: the ledger's work integrals, present with contacts).

    Besides ``__call__`` it offers the ``retract`` hook of ``viz3d.integrators.base.Rhs``, and its
    ``dexpinv`` hook when the rotation coordinates advance on the group in explicit Runge-Kutta steps
    (``RotationCoordinates.group_stages``; None otherwise).

    Attributes
    ----------
    n_q : int
        Length of the position part of ``y`` (partitioned methods split there).
    n_evals : int
        Number of evaluations so far.
    """

    def __init__(self, system: System, formulation, chart: FloatArray, memory: tuple = (), elements: tuple = ()):
        self.system, self.formulation, self.chart, self.memory = system, formulation, chart, memory
        self.elements = elements
        self.n_q, self.n_v = system.n_q, system.n_v
        self.n_evals = 0
        self.dexpinv = self._dexpinv if system.rotation.group_stages else None

    def __call__(self, t: float, y: FloatArray) -> FloatArray:
        self.n_evals += 1
        q, v = y[: self.n_q], y[self.n_q:self.n_q + self.n_v]
        acc = accelerations(self.system, self.formulation, t, q, v, self.chart, self.memory, elements=self.elements)
        parts = [kinematic_rates(self.system, q, v), acc.v_dot]
        if self.system.n_aux:
            parts.append(aux_rates(self.system, acc.cfg, self.memory, self.elements, drive_power(acc.lam, acc.rows.C_t)))
        return np.concatenate(parts)

    def retract(self, q: FloatArray, w: FloatArray) -> FloatArray:
        """``q`` moved by the velocity-space increment ``w`` (n_v,) [m, rad] (see ``retract``;
        entries beyond n_v, the work integrals' increments, do not move positions)."""
        return retract(self.system, q, w[: self.n_v], self.chart)

    def _dexpinv(self, u: FloatArray, v: FloatArray) -> FloatArray:
        """``u_dot`` (n_v,) of the increment ``u`` (n_v,) at the velocities ``v`` (n_v,) (``dexpinv``)."""
        return dexpinv(self.system, u, v)


def energies(system: System, state: State, cfg: Configuration | None = None, gaps: tuple = ()) -> tuple[float, float]:
    """Kinetic and potential energy [J] of a state (potential of all conservative elements, plus the
    strain energy of flexible bodies and the energy stored in contacts); ``cfg``: its configuration,
    ``gaps``: each contact set's ``gap(cfg)``, if the caller has them."""
    e = energy_terms(system, state, cfg, gaps)
    return e.kinetic, float(sum(e.potentials) + sum(e.strain) + sum(float(U.sum()) for U in e.contact_elastic))


class EnergyTerms(NamedTuple):
    """The energies of a state term by term [J]: ``kinetic`` (all bodies), ``potentials`` (one per
    force element, in ``System.forces`` order), ``strain`` (one per flexible body) and
    ``contact_elastic`` (per contact set, (k,))."""

    kinetic: float
    potentials: list
    strain: list
    contact_elastic: list


def energy_terms(system: System, state: State, cfg: Configuration | None = None, gaps: tuple = ()) -> EnergyTerms:
    """Every energy term of a state, each computed once (``energies`` sums them; the ledger of
    ``viz3d.events`` splits them); ``cfg`` and ``gaps`` as in ``energies``."""
    cfg = body_state(system, state.q, state.v, state.chart, state.t) if cfg is None else cfg
    T = system.bodies.kinetic_energy(cfg.twist.W_v[:-1], cfg.twist.B_omega[:-1])
    strain = []
    for i, fb in enumerate(system.bodies.flexible):
        T += flexible_kinetic(fb, cfg, i)
        strain.append(float(ffr.strain_energy(fb.bar, cfg.eta[i])))
    U = []
    for k, c in enumerate(system.contacts):
        phases = state.memory[k] if state.memory else c.initial_phases()
        U.append(c.elastic_energy(cfg, phases, gaps[k] if gaps else None))
    return EnergyTerms(float(T), [e.potential_energy(cfg) for e in system.forces], strain, U)


def flexible_kinetic(fb, cfg: Configuration, i: int) -> float:
    """Kinetic energy [J] of flexible body ``fb`` (the ``i``-th) at ``cfg``: frame and deformation."""
    if not fb.floating:
        return 0.5 * float(cfg.eta_dot[i] @ fb.bar.M_ee @ cfg.eta_dot[i])
    v = np.concatenate([cfg.twist.W_v[fb.index], cfg.twist.B_omega[fb.index], cfg.eta_dot[i]])
    return ffr.kinetic_energy(fb.bar, cfg.pose.R_WB[fb.index], cfg.eta[i], v)


def flexible_kinetics(fb, s, sl: slice) -> FloatArray:
    """``flexible_kinetic`` of flexible body ``fb`` at N states at once (N,) [J], from kernel samples
    ``s`` (``viz3d.kernel.Samples``; ``sl`` the body's slice of their elastic coordinates)."""
    eta_dot = s.eta_dot[:, sl]
    if not fb.floating:
        return 0.5 * np.einsum("ni,ij,nj->n", eta_dot, fb.bar.M_ee, eta_dot)
    b = fb.index
    return ffr.kinetic_energies(fb.bar, s.R[:, b], s.eta[:, sl], np.concatenate([s.vW[:, b], s.wB[:, b], eta_dot], axis=1))


def centres_of_mass(system: System, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
    """World positions and velocities of the bodies' centres of mass, shapes (nb, 3) [m, m/s]: the
    frame origins, shifted on flexible bodies by their deflection ``R S eta / m``."""
    W_G, W_v = cfg.pose.W_r[:-1], cfg.twist.W_v[:-1]
    if not system.bodies.flexible:
        return W_G, W_v
    W_G, W_v = W_G.copy(), W_v.copy()
    for i, fb in enumerate(system.bodies.flexible):
        R, b = cfg.pose.R_WB[fb.index], fb.index
        shift = R @ (fb.bar.S @ cfg.eta[i]) / fb.bar.mass
        W_G[b] += shift
        W_v[b] += cross(cfg.twist.W_omega[b], shift) + R @ (fb.bar.S @ cfg.eta_dot[i]) / fb.bar.mass
    return W_G, W_v

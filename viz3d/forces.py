"""Force elements: everything that contributes applied forces and torques to the bodies.

A force element is a vectorized set (all springs of a scene are one element) with one hook,
``wrench(cfg) -> (W_F, W_tau, Q_e)``: world forces at each frame origin and world torques about it,
shapes (nb + 1, 3) (the last row, ground, is discarded), and the generalized forces on the stacked
elastic coordinates (n_e,). Elements attach through material points (``viz3d.points``), so the same
spring or load acts on a rigid body or on a section of a flexible one. Conservative elements also
give ``potential_energy``. See docs/extending.md ("Add a force element").
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.compiled import (HOLD, RELEASE, Items, compiled_piece, cross3, dot3, energy_piece, force_piece, hold_piece,
                            inline, items, matvec3)
from viz3d.joints import DISTANCE_Z, coordinate, coordinate_of
from viz3d.kinematics import Configuration
from viz3d.points import BodyPoints, apply_force, apply_pair, rigid_points, scatter
from viz3d.timefunctions import TimeFunctions, value

#: Spring lengths below this [m] are treated as zero (direction undefined, force from k * d).
MIN_LENGTH = 1e-12

__all__ = ["FORCES", "AppliedForce", "AppliedTorque", "DriveServo", "ForceElement", "Gravity", "JointMotor",
           "JointStop", "SpringDamper", "scatter"]


class ForceElement(ABC):
    """Base class. Subclasses set ``type_name`` and implement ``wrench``; those with a compiled
    piece (``viz3d.compiled``) also ``compiled(pack)``, returning their packed ``Items``.

    An element with memory (``has_memory``: shape contacts with bristle friction keep their stick
    anchors) keeps it in ``State.element_memory``, fixed during a step: its ``wrench`` then takes
    it as a second argument, ``wrench(cfg, memory)``, and ``memory_after_step`` renews it after
    each accepted step (``viz3d.dynamics.element_memory``)."""

    type_name: ClassVar[str]
    #: Forces smooth in the positions (False: shape contacts, whose contact sets change between
    #: nearby configurations, so a difference tangent across a change misleads Newton; ``viz3d.ali3p``
    #: holds their contact sets fixed within a step's iteration with ``frozen``).
    smooth: ClassVar[bool] = True
    #: Its force has branches (a contact touching or not, a stop engaged or not) with a kink or a jump
    #: between them; ``frozen`` holds them for an implicit step's iteration (``viz3d.ali3p``).
    branches: ClassVar[bool] = False
    #: Its non-potential power is a loss (dampers, stops, drag, contact damping and friction): the
    #: energy ledger books it as dissipated, not as (negative) work in (``viz3d.dynamics.aux_rates``).
    dissipative: ClassVar[bool] = False
    #: Its packed data (``compiled``) holds what a run writes (shape contacts: narrow-phase scratch,
    #: stick anchors), so the kernel packs it for each run instead of once per system
    #: (``viz3d.kernel.model.per_run``).
    packed_per_run: ClassVar[bool] = False

    @abstractmethod
    def wrench(self, cfg: Configuration) -> tuple[FloatArray, FloatArray, FloatArray | None]:
        """World forces at the frame origins and world torques about them, shapes (nb + 1, 3)
        [N, N m], and the elastic generalized forces (n_e,) (``None`` when the element has none)."""

    def potential_energy(self, cfg: Configuration) -> float:
        """Potential energy [J]; zero for non-conservative elements."""
        return 0.0

    @property
    def has_memory(self) -> bool:
        """True when the element's forces depend on a memory kept in ``State.element_memory``."""
        return False

    def memory_after_step(self, cfg: Configuration, memory):
        """The element's memory after an accepted step that ends at ``cfg``, from the one it carried
        during the step (None at the start of a run); elements without memory: None."""
        return None

    def frozen(self, cfg: Configuration, memory):
        """The memory to evaluate this element with near ``cfg`` with its ``branches`` held as they
        are at ``cfg`` (``viz3d.ali3p``: one step's Newton iteration), so that its force is smooth
        there; ``memory``: the element's own (``State.element_memory``). Elements with branches
        override it (shape contacts: which contacts push, their faces and anchors; stops: which are
        engaged); the others evaluate with their ``memory`` unchanged."""
        return memory

    def frozen_change(self, cfg: Configuration, frozen, tol: float = 0.0) -> str:
        """What differs at ``cfg`` between the element's own branches and those held in ``frozen``
        (from ``self.frozen``), beyond positions within ``tol`` [m]; '' when nothing does."""
        return ""

    def coupled_bodies(self) -> IntArray | None:
        """Pairs of bodies (k, 2) whose coordinates each other's forces from this element depend on
        (``viz3d.sparsity``; ground may appear); None: not known, every body with every other."""
        return None

    @property
    def conservative(self) -> bool:
        """True when the element's forces are minus the gradient of ``potential_energy``."""
        return False

    def nonconservative_power(self, cfg: Configuration) -> float:
        """Power [W] of the forces that ``potential_energy`` does not account for (the energy
        ledger's work in): none for a conservative element, all of them by default."""
        if self.conservative:
            return 0.0
        F, tau, e = self.wrench(cfg)
        power = float(np.sum(F * cfg.twist.W_v) + np.sum(tau * cfg.twist.W_omega))
        return power + (float(e @ np.concatenate(cfg.eta_dot)) if e is not None else 0.0)


@dataclass(frozen=True)
class Gravity(ForceElement):
    """Uniform gravity ``F = m g`` at every centre of mass; ``V = -sum m g . r``. A flexible body's
    deflection moves its centre of mass by ``R S eta / m``: its weight then has a moment about the
    frame origin and a consistent elastic load ``S^T R^T g`` (``viz3d.flexible.floating``).

    Attributes
    ----------
    mass : ndarray, shape (nb,) [kg]
    g : ndarray, shape (3,) [m/s^2]
    flexible : tuple of FlexibleBody
    n_elastic : int
    """

    type_name = "gravity"
    mass: FloatArray
    g: FloatArray
    flexible: tuple = ()
    n_elastic: int = 0

    def coupled_bodies(self):
        return np.zeros((0, 2), int)  # each body's weight depends on its own configuration only

    def wrench(self, cfg):
        F = np.zeros_like(cfg.pose.W_r)
        F[:-1] = self.mass[:, None] * self.g
        tau = np.zeros_like(F)
        if not self.flexible:
            return F, tau, None
        Qe = np.zeros(self.n_elastic)
        offset = 0
        for i, fb in enumerate(self.flexible):
            R = cfg.pose.R_WB[fb.index]
            tau[fb.index] = np.cross(R @ (fb.bar.S @ cfg.eta[i]), self.g)
            Qe[offset:offset + fb.n] = fb.bar.S.T @ (R.T @ self.g)
            offset += fb.n
        return F, tau, Qe

    def potential_energy(self, cfg):
        V = -float(self.mass @ (cfg.pose.W_r[:-1] @ self.g))
        for i, fb in enumerate(self.flexible):
            V -= float(self.g @ (cfg.pose.R_WB[fb.index] @ (fb.bar.S @ cfg.eta[i])))
        return V

    @property
    def conservative(self) -> bool:
        return True

    def compiled(self, pack) -> Items:
        """Each body's weight at its centre of mass (``Packer.centres_of_mass``: on a flexible body a
        point that moves with ``S eta / m``, whose generalized force is exactly the one above)."""
        nb = len(self.mass)
        if self.flexible not in ((), pack.bodies.flexible) or nb != pack.bodies.n_bodies:
            raise pack.Unsupported("gravity on a subset of the bodies")
        if not self.flexible and pack.bodies.flexible:
            raise pack.Unsupported("gravity without the flexible bodies' deflection")
        weights = self.mass[:, None] * self.g[None, :]
        return items(GravityItems, pack.centres_of_mass()[:, None], weights, k=nb)


class GravityItems(Items):
    """i: [centre-of-mass point]; f: [weight m g (3)] [N]."""


@compiled_piece(force_piece, GravityItems)
def _gravity(d, t, v, power):
    for k in range(d.i.shape[0]):
        apply_force(v, d.i[k, 0], d.f[k])


@compiled_piece(energy_piece, GravityItems)
def _gravity_energy(d, v, V):
    for k in range(d.i.shape[0]):
        V[0] -= dot3(d.f[k], v.px[d.i[k, 0]])


@dataclass(frozen=True)
class SpringDamper(ForceElement):
    """Linear spring-dampers between body points (or a body point and ground).

    Tension ``f = k (l - l0) + c l_dot`` acts along the line of the two points: ``+f u`` on
    body 1 and ``-f u`` on body 2, with ``u`` the unit vector from point 1 to point 2.
    ``V = k (l - l0)^2 / 2``.

    Attributes
    ----------
    names : tuple of str, length k
    body : ndarray of int, shape (k, 2)
    B_s : ndarray, shape (k, 2, 3)
        Attachment points in body frames (world for ground) [m].
    stiffness : ndarray, shape (k,) [N/m]
    damping : ndarray, shape (k,) [N s/m]
    rest_length : ndarray, shape (k,) [m]
    sides : tuple of BodyPoints, optional
        The two ends' material points (default: rigid points at ``B_s``).
    """

    type_name = "spring_damper"
    dissipative = True
    names: tuple[str, ...]
    body: IntArray
    B_s: FloatArray
    stiffness: FloatArray
    damping: FloatArray
    rest_length: FloatArray
    sides: tuple[BodyPoints, BodyPoints] | None = field(default=None)

    def __post_init__(self):
        if self.sides is None:
            object.__setattr__(self, "sides", tuple(rigid_points(self.body[:, k], self.B_s[:, k]) for k in (0, 1)))

    def endpoints(self, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
        """World attachment points (k, 2, 3) and levers from the frame origins (k, 2, 3)."""
        rho = np.stack([side.levers(cfg) for side in self.sides], axis=1)
        return cfg.pose.W_r[self.body] + rho, rho

    def _geometry(self, cfg: Configuration):
        p, rho = self.endpoints(cfg)
        d = p[:, 1] - p[:, 0]
        length = np.linalg.norm(d, axis=1)
        u = d / np.maximum(length, MIN_LENGTH)[:, None]
        return rho, d, length, u

    def wrench(self, cfg):
        rho, d, length, u = self._geometry(cfg)
        v = [side.velocities(cfg, rho[:, k]) for k, side in enumerate(self.sides)]
        length_d = np.einsum("ki,ki->k", u, v[1] - v[0])
        # k (l - l0) u written as k (d - l0 u): exact for l0 = 0 even when the points coincide.
        f = self.stiffness[:, None] * (d - self.rest_length[:, None] * u) + (self.damping * length_d)[:, None] * u
        F1, tau1, Qe1 = self.sides[0].wrench(cfg, f, rho[:, 0])
        F2, tau2, Qe2 = self.sides[1].wrench(cfg, -f, rho[:, 1])
        return F1 + F2, tau1 + tau2, (Qe1 + Qe2) if Qe1.size else None

    @property
    def conservative(self) -> bool:
        return not np.any(self.damping > 0)

    def nonconservative_power(self, cfg):
        """The dashpots' power on the bodies, ``-sum c l_dot^2`` [W] (the springs' is in ``potential_energy``)."""
        rho, _, _, u = self._geometry(cfg)
        v = [side.velocities(cfg, rho[:, k]) for k, side in enumerate(self.sides)]
        length_d = np.einsum("ki,ki->k", u, v[1] - v[0])
        return -float(np.sum(self.damping * length_d**2))

    def potential_energy(self, cfg):
        _, _, length, _ = self._geometry(cfg)
        return float(0.5 * np.sum(self.stiffness * (length - self.rest_length) ** 2))

    def coupled_bodies(self):
        return self.body

    def compiled(self, pack) -> Items:
        i = np.column_stack([pack.points(self.sides[0]), pack.points(self.sides[1])])
        return items(SpringItems, i, np.column_stack([self.stiffness, self.damping, self.rest_length]), k=len(self.names))


class SpringItems(Items):
    """i: [point 1, point 2]; f: [stiffness [N/m], damping [N s/m], rest length [m]]."""


@compiled_piece(force_piece, SpringItems)
def _spring(d, t, v, power):
    dv, f = v.v3[8], v.v3[9]
    for k in range(d.i.shape[0]):
        p1, p2 = d.i[k, 0], d.i[k, 1]
        for c in range(3):
            f[c] = v.px[p2, c] - v.px[p1, c]
            dv[c] = v.pv[p2, c] - v.pv[p1, c]
        length = math.sqrt(dot3(f, f))
        inv = 1.0 / max(length, MIN_LENGTH)
        length_d = dot3(f, dv) * inv
        K, D, l0 = d.f[k, 0], d.f[k, 1], d.f[k, 2]
        for c in range(3):
            f[c] = K * (f[c] - l0 * f[c] * inv) + D * length_d * f[c] * inv
        apply_pair(v, p1, p2, f)
        power[power.shape[0] - 2] += D * length_d * length_d  # (dissipated: the dampers' slot)


@compiled_piece(energy_piece, SpringItems)
def _spring_energy(d, v, V):
    for k in range(d.i.shape[0]):
        p1, p2 = d.i[k, 0], d.i[k, 1]
        s = 0.0
        for c in range(3):
            x = v.px[p2, c] - v.px[p1, c]
            s += x * x
        stretch = math.sqrt(s) - d.f[k, 2]
        V[1] += 0.5 * d.f[k, 0] * stretch * stretch


@dataclass(frozen=True)
class AppliedForce(ForceElement):
    """Prescribed forces at body points, constant or time functions, in world or body axes.

    Attributes
    ----------
    names : tuple of str, length k
    body : ndarray of int, shape (k,)
    B_s : ndarray, shape (k, 3)
        Point of application from the frame origin, body axes [m].
    in_body_frame : ndarray of bool, shape (k,)
        Value given in body axes (follows the body) instead of world axes.
    value : TimeFunctions
        ``k`` functions of time [N].
    points : BodyPoints, optional
        The points of application (default: rigid points at ``B_s``).
    """

    type_name = "force"
    names: tuple[str, ...]
    body: IntArray
    B_s: FloatArray
    in_body_frame: np.ndarray
    value: TimeFunctions
    points: BodyPoints | None = field(default=None)

    def __post_init__(self):
        if self.points is None:
            object.__setattr__(self, "points", rigid_points(self.body, self.B_s))

    def coupled_bodies(self):
        return np.zeros((0, 2), int)  # on one body each

    def world_value(self, cfg: Configuration) -> FloatArray:
        """The prescribed vectors in world axes, shape (k, 3)."""
        val = self.value(cfg.t)
        in_body = np.einsum("kij,kj->ki", cfg.pose.R_WB[self.body], val)
        return np.where(self.in_body_frame[:, None], in_body, val)

    def wrench(self, cfg):
        F, tau, Qe = self.points.wrench(cfg, self.world_value(cfg))
        return F, tau, Qe if Qe.size else None

    def compiled(self, pack) -> Items:
        kind, table = self.value.table()
        i = np.column_stack([pack.points(self.points), kind, self.in_body_frame.astype(np.int64)])
        return items(ForceItems, i, table, k=len(self.names))


class ForceItems(Items):
    """i: [point, time-function kind, in body axes]; f: ``TimeFunctions.table`` row (10)."""


@inline
def _prescribed(d, k, t, R, out, tmp):
    """Item ``k``'s prescribed vector at ``t`` into ``out`` (3,), in world axes (``R``: its body's
    rotation, used when the value is given in body axes; ``tmp`` (3,) scratch)."""
    value(d.i[k, 1], d.f[k], t, out)
    if d.i[k, 2] == 1:
        matvec3(R, out, tmp)
        for c in range(3):
            out[c] = tmp[c]


@compiled_piece(force_piece, ForceItems)
def _force(d, t, v, power):
    f = v.v3[8]
    for k in range(d.i.shape[0]):
        p = d.i[k, 0]
        _prescribed(d, k, t, v.R[v.pt_i[p, 0]], f, v.v3[9])
        apply_force(v, p, f)
        power[power.shape[0] - 1] += dot3(f, v.pv[p])


@dataclass(frozen=True)
class AppliedTorque(AppliedForce):
    """Prescribed torques (couples) on bodies' frames, world or body axes; ``B_s`` is unused (zero)."""

    type_name = "torque"

    def wrench(self, cfg):
        tau_k = self.world_value(cfg)
        return np.zeros_like(cfg.pose.W_r), scatter(cfg.pose.W_r.shape[0], self.body, tau_k), None

    def compiled(self, pack) -> Items:
        kind, table = self.value.table()
        i = np.column_stack([self.body, kind, self.in_body_frame.astype(np.int64)])
        return items(TorqueItems, i, table, k=len(self.names))


class TorqueItems(Items):
    """i: [body, time-function kind, in body axes]; f: ``TimeFunctions.table`` row (10)."""


@compiled_piece(force_piece, TorqueItems)
def _torque(d, t, v, power):
    tau = v.v3[8]
    for k in range(d.i.shape[0]):
        b = d.i[k, 0]
        _prescribed(d, k, t, v.R[b], tau, v.v3[9])
        for c in range(3):
            v.tau[b, c] += tau[c]
        power[power.shape[0] - 1] += dot3(tau, v.wW[b])




# ---------------------------------------------------------------------------- forces on joint coordinates


@dataclass(frozen=True)
class JointCoordinateForce(ForceElement):
    """Base of elements that act on joints' relative coordinates (``viz3d.joints.FramedJoint``): a
    generalized force ``f`` on coordinate ``q`` of body 1 relative to body 2 - a torque ``+f u`` on
    body 1 and ``-f u`` on body 2 about the coordinate's axis ``u``, or for a distance a force ``+f u``
    at body 1's joint point and ``-f u`` at body 2's (with the moment ``f u x e`` on body 1,
    ``e = p1 - p2``), so that its power is exactly ``f q_dot`` (``viz3d.joints.coordinate``).
    Subclasses give ``effort(t, q, q_dot) -> (f, f_potential)``: the force and the part of it that
    ``potential_energy`` accounts for.

    Attributes
    ----------
    names : tuple of str, length k
    joints : tuple of FramedJoint, length k
        The joint set of each item.
    index : ndarray of int, shape (k,)
        The joint within its set.
    free : ndarray of int, shape (k,)
        The coordinate within the joint's ``FREE``.
    """

    names: tuple[str, ...]
    joints: tuple
    index: IntArray
    free: IntArray

    def __post_init__(self):
        for name, js, j in zip(self.names, self.joints, self.index):
            if _on_section(js, int(j)):
                raise ValueError(f"{self.type_name} {name!r}: its joint has a side on a section of a flexible body; "
                                 "forces on joint coordinates act through rigid frames' axes (drives take such joints)")

    def _code(self, k: int) -> int:
        return self.joints[k].FREE[self.free[k]][1]

    def coupled_bodies(self):
        return np.array([js.body[j] for js, j in zip(self.joints, self.index)], int).reshape(-1, 2)

    def coordinates(self, cfg: Configuration) -> tuple[FloatArray, FloatArray]:
        """Each item's coordinate and rate, shapes (k,) [rad or m, per s]."""
        q, q_dot = np.zeros(len(self.names)), np.zeros(len(self.names))
        per_set = {id(js): js.coordinates(cfg) for js in self.joints}  # once per joint set
        for k, (js, j, c) in enumerate(zip(self.joints, self.index, self.free)):
            values, rates = per_set[id(js)]
            q[k], q_dot[k] = values[j, c], rates[j, c]
        return q, q_dot

    def wrench(self, cfg, memory=None):
        """(``ForceElement.wrench``; ``memory``: branches held by ``frozen``, when the element has them.)"""
        q, q_dot = self.coordinates(cfg)
        f, _ = self.effort(cfg.t, q, q_dot) if memory is None else self.held_effort(q, q_dot, memory)
        F, tau = np.zeros_like(cfg.pose.W_r), np.zeros_like(cfg.pose.W_r)
        axes = {id(js): js.axes(cfg.pose.R_WB) for js in self.joints}  # once per joint set
        for k, (js, j) in enumerate(zip(self.joints, self.index)):
            b1, b2 = js.body[j]
            a = axes[id(js)][j]
            rho = np.einsum("kij,kj->ki", cfg.pose.R_WB[js.body[j]], js.B_s[j])
            e = cfg.pose.W_r[b1] + rho[0] - cfg.pose.W_r[b2] - rho[1]
            _, u = coordinate(self._code(k), a[0], a[1], e)
            if self._code(k) == DISTANCE_Z:
                F[b1] += f[k] * u
                F[b2] -= f[k] * u
                tau[b1] += np.cross(rho[0], f[k] * u) + f[k] * np.cross(u, e)
                tau[b2] -= np.cross(rho[1], f[k] * u)
            else:
                tau[b1] += f[k] * u
                tau[b2] -= f[k] * u
        return F, tau, None

    def nonconservative_power(self, cfg):
        """``(f - f_potential) q_dot`` summed [W]."""
        q, q_dot = self.coordinates(cfg)
        f, f_V = self.effort(cfg.t, q, q_dot)
        return float(np.sum((f - f_V) * q_dot))

    def effort(self, t: float, q: FloatArray, q_dot: FloatArray) -> tuple[FloatArray, FloatArray]:
        raise NotImplementedError

    def _pack(self, pack, cls, i_extra, f_extra) -> Items:
        """``cls`` items: i = [point 1, point 2, coordinate code, *i_extra], f = [A1, A2 (18), *f_extra]."""
        rows_i, rows_f = [], []
        for k, (js, j) in enumerate(zip(self.joints, self.index)):
            p = [pack.points(rigid_points(js.body[[j], s], js.B_s[[j], s]))[0] for s in (0, 1)]
            rows_i.append([p[0], p[1], self._code(k), *i_extra[k]])
            rows_f.append([*js.B_A[j].reshape(18), *f_extra[k]])
        return items(cls, rows_i, rows_f, k=len(self.names))


def _on_section(js, j: int) -> bool:
    """Joint ``j`` of set ``js`` has a side on a section of a flexible body."""
    return any(j in g.which for side in js.sides for g in side.flex)


@inline
def _coordinate_force(v, d, k, F, u, t1):
    """Apply the generalized force ``F`` of item ``k`` of ``d`` along its axis ``u`` (``JointCoordinateForce``)."""
    p1, p2 = d.i[k, 0], d.i[k, 1]
    q1, q2 = v.pt_i[p1, 0], v.pt_i[p2, 0]
    if d.i[k, 2] == DISTANCE_Z:
        for c in range(3):
            t1[c] = F * u[c]
        apply_pair(v, p1, p2, t1)
        for c in range(3):
            t1[c] = v.px[p1, c] - v.px[p2, c]
        cross3(u, t1, v.v3[20])
        for c in range(3):
            v.tau[q1, c] += F * v.v3[20, c]
    else:
        for c in range(3):
            v.tau[q1, c] += F * u[c]
            v.tau[q2, c] -= F * u[c]


@dataclass(frozen=True)
class JointStop(JointCoordinateForce):
    """Stops (limits) on joint coordinates: a piecewise spring-damper, zero inside ``[lower, upper]``
    and ``-k (q - q_lim) - c q_dot`` outside (seed 004, eq. 3.50), never pulling the joint back into
    the stop (the force is clipped to push out of it only). ``V = k (q - q_lim)^2 / 2`` outside; the
    damper's power and the clipping are the non-conservative part (the ledger's work in).

    Attributes (beyond ``JointCoordinateForce``)
    ----------
    lower, upper : ndarray, shape (k,) [rad or m]
    stiffness : ndarray, shape (k,) [N m/rad or N/m]
    damping : ndarray, shape (k,) [N m s/rad or N s/m]
    """

    type_name = "joint_stop"
    dissipative = True
    branches = True
    lower: FloatArray = field(default=None)
    upper: FloatArray = field(default=None)
    stiffness: FloatArray = field(default=None)
    damping: FloatArray = field(default=None)

    def frozen(self, cfg, memory) -> IntArray:
        """The stops engaged at ``cfg`` (k,): +1 on ``upper``, -1 on ``lower``, 0 none (those whose
        clipped force is not zero): ``held_effort`` then gives their spring-damper unclipped, smooth
        across the limit and the clipping."""
        q, q_dot = self.coordinates(cfg)
        f, _ = self.effort(cfg.t, q, q_dot)
        return np.sign(self._penetration(q)).astype(int) * (f != 0.0)

    def held_effort(self, q: FloatArray, q_dot: FloatArray, side: IntArray) -> tuple[FloatArray, FloatArray]:
        """``effort`` with the stops engaged on ``side`` (``frozen``): ``-k (q - q_lim) - c q_dot`` there,
        pulling too, zero elsewhere."""
        delta = q - np.where(side > 0, self.upper, self.lower)
        spring = np.where(side != 0, -self.stiffness * delta, 0.0)
        return spring - self.damping * q_dot * (side != 0), spring

    def frozen_change(self, cfg, side, tol: float = 0.0) -> str:
        now = self.frozen(cfg, None)
        moved = [f"{n!r} {'released' if b == 0 else 'engaged'}" for n, a, b in zip(self.names, side, now) if a != b]
        return ("stops " + ", ".join(moved)) if moved else ""

    def _penetration(self, q: FloatArray) -> FloatArray:
        """``q - upper`` above, ``q - lower`` below, zero inside."""
        return np.where(q > self.upper, q - self.upper, np.where(q < self.lower, q - self.lower, 0.0))

    def effort(self, t, q, q_dot):
        delta = self._penetration(q)
        spring = -self.stiffness * delta
        f = spring - self.damping * q_dot * (delta != 0)
        f = np.where(delta > 0, np.minimum(f, 0.0), np.where(delta < 0, np.maximum(f, 0.0), 0.0))
        return f, spring

    def potential_energy(self, cfg):
        q, _ = self.coordinates(cfg)
        return float(0.5 * np.sum(self.stiffness * self._penetration(q) ** 2))

    def compiled(self, pack) -> Items:
        n = len(self.names)
        return self._pack(pack, JointStopItems, np.full((n, 1), NOT_HELD),
                          np.column_stack([self.lower, self.upper, self.stiffness, self.damping]))


#: ``JointStopItems.i[:, 3]`` of a stop whose side is not held (``effort``); held: the side of ``frozen``.
NOT_HELD = 2


class JointStopItems(Items):
    """i: [point 1, point 2, coordinate code, held side (``frozen``: +1, -1, 0; ``NOT_HELD``)];
    f: [A1, A2 (18), lower, upper, stiffness, damping]."""


@inline
def _stop_effort(f, q, q_dot, side):
    """``(force, spring force)`` of ``JointStop.effort`` for one item (its row ``f``), or of
    ``held_effort`` with the stop held on ``side`` (not ``NOT_HELD``)."""
    if side != NOT_HELD:
        if side == 0:
            return 0.0, 0.0
        spring = -f[20] * (q - (f[19] if side > 0 else f[18]))
        return spring - f[21] * q_dot, spring
    if q > f[19]:
        delta = q - f[19]
    elif q < f[18]:
        delta = q - f[18]
    else:
        return 0.0, 0.0
    spring = -f[20] * delta
    force = spring - f[21] * q_dot
    if delta > 0.0:
        force = min(force, 0.0)
    else:
        force = max(force, 0.0)
    return force, spring


@compiled_piece(force_piece, JointStopItems)
def _joint_stop(d, t, v, power):
    u = v.v3[24]
    for k in range(d.i.shape[0]):
        p1, p2 = d.i[k, 0], d.i[k, 1]
        q, q_dot = coordinate_of(v, d.f[k], d.i[k, 2], v.pt_i[p1, 0], v.pt_i[p2, 0], p1, p2, u)
        force, spring = _stop_effort(d.f[k], q, q_dot, d.i[k, 3])
        if force != 0.0 or spring != 0.0:
            _coordinate_force(v, d, k, force, u, v.v3[25])
            power[power.shape[0] - 2] -= (force - spring) * q_dot  # (dissipated: the dampers' slot)


@compiled_piece(energy_piece, JointStopItems)
def _joint_stop_energy(d, v, V):
    u = v.v3[24]
    for k in range(d.i.shape[0]):
        p1, p2 = d.i[k, 0], d.i[k, 1]
        q, _ = coordinate_of(v, d.f[k], d.i[k, 2], v.pt_i[p1, 0], v.pt_i[p2, 0], p1, p2, u)
        _, spring = _stop_effort(d.f[k], q, 0.0, NOT_HELD)
        if d.f[k, 20] > 0.0:
            V[1] += 0.5 * spring * spring / d.f[k, 20]


@compiled_piece(hold_piece, JointStopItems)
def _joint_stop_hold(d, t, v, mode, tol):
    """``JointStop.frozen`` (the sides of the stops whose clipped force is not zero) held (``HOLD``),
    released, or the stops whose side differs from the held one counted (``frozen_change``)."""
    u, changed = v.v3[24], 0
    for k in range(d.i.shape[0]):
        if mode == RELEASE:
            d.i[k, 3] = NOT_HELD
            continue
        p1, p2 = d.i[k, 0], d.i[k, 1]
        q, q_dot = coordinate_of(v, d.f[k], d.i[k, 2], v.pt_i[p1, 0], v.pt_i[p2, 0], p1, p2, u)
        force, _ = _stop_effort(d.f[k], q, q_dot, NOT_HELD)
        side = 0 if force == 0.0 else (1 if q > d.f[k, 19] else -1)
        if mode == HOLD:
            d.i[k, 3] = side
        elif side != d.i[k, 3]:
            changed += 1
    return changed


@dataclass(frozen=True)
class JointMotor(JointCoordinateForce):
    """Motors on joint coordinates: PD tracking of a profile ``q_ref(t)`` with a saturation,
    ``f = clip(kp (q_ref(t) - q) - kd q_dot, -max_effort, max_effort)`` [N m or N]. The profile is a
    time function (``viz3d.timefunctions``; first component). Non-conservative: its power is the
    ledger's work in.

    Attributes (beyond ``JointCoordinateForce``)
    ----------
    target : TimeFunctions
        ``q_ref`` in the first component [rad or m].
    kp, kd, max_effort : ndarray, shape (k,)
    """

    type_name = "joint_motor"
    target: TimeFunctions = field(default=None)
    kp: FloatArray = field(default=None)
    kd: FloatArray = field(default=None)
    max_effort: FloatArray = field(default=None)

    def effort(self, t, q, q_dot):
        f = np.clip(self.kp * (self.target(t)[:, 0] - q) - self.kd * q_dot, -self.max_effort, self.max_effort)
        return f, np.zeros_like(f)

    def compiled(self, pack) -> Items:
        kind, table = self.target.table()
        return self._pack(pack, JointMotorItems, kind[:, None],
                          np.column_stack([self.kp, self.kd, self.max_effort, table]))


class JointMotorItems(Items):
    """i: [point 1, point 2, coordinate code, time-function kind]; f: [A1, A2 (18), kp, kd, max_effort,
    ``TimeFunctions.table`` row (10)]."""


@compiled_piece(force_piece, JointMotorItems)
def _joint_motor(d, t, v, power):
    u, ref = v.v3[24], v.v3[26]
    for k in range(d.i.shape[0]):
        p1, p2 = d.i[k, 0], d.i[k, 1]
        row = d.f[k]
        q, q_dot = coordinate_of(v, row, d.i[k, 2], v.pt_i[p1, 0], v.pt_i[p2, 0], p1, p2, u)
        value(d.i[k, 3], row[21:31], t, ref)
        force = min(max(row[18] * (ref[0] - q) - row[19] * q_dot, -row[20]), row[20])
        _coordinate_force(v, d, k, force, u, v.v3[25])
        power[power.shape[0] - 1] += force * q_dot


@dataclass(frozen=True)
class DriveServo(JointCoordinateForce):
    """Limited drives (scene ``[[drives]]`` with a ``servo_gain``): velocity servos with a force range,
    ``f = clip(g (r(t) - q_dot), -F_max, F_max)`` [N or N m] on a joint coordinate ``q``, ``r`` the
    drive's velocity profile (a time function, first component), ``g`` the gain [N s/m or N m s/rad]
    and ``F_max`` the drive's capacity. MuJoCo's velocity actuator with ``forcerange``.

    Why a servo and not a rigid drive (``viz3d.joints.JointDrive``) whose multiplier is bounded: a
    force element needs no change of any formulation (index-1, projection, ALI3-P, the kernel's
    Schur solve), keeps no state (no integral of the speed error: after a stall the drive resumes
    its profile's speed, it does not catch up the distance it lost, as a speed-controlled windlass
    does) and is a stiff term only below its range: on the coordinate's effective mass ``m``
    (the bodies the drive moves through the joints) its pole is ``-g / m``, so an explicit
    method's step ``h`` needs ``g h / m`` inside its real stability interval (RK4: 2.785). Below
    the range it tracks the profile with the speed error ``F / g`` at load ``F`` (a motor's droop);
    at the range it gives ``+-F_max`` and the coordinate follows the net force, so a jammed
    mechanism stalls instead of being pulled through. Its power ``f q_dot`` is the ledger's work in.
    Its effort is the frame scalar ``drive/<name>/effort`` (as a rigid drive's).

    Attributes (beyond ``JointCoordinateForce``)
    ----------
    profile : TimeFunctions
        ``r``, the velocity profile, in the first component [m/s or rad/s].
    gain, capacity : ndarray, shape (k,)
        ``g`` [N s/m or N m s/rad] and ``F_max`` [N or N m].
    """

    type_name = "drive_servo"
    is_drive: ClassVar[bool] = True  # (``System.drive_names``)
    profile: TimeFunctions = field(default=None)
    gain: FloatArray = field(default=None)
    capacity: FloatArray = field(default=None)

    def effort(self, t, q, q_dot):
        f = np.clip(self.gain * (self.profile(t)[:, 0] - q_dot), -self.capacity, self.capacity)
        return f, np.zeros_like(f)

    def scalars(self, cfg: Configuration) -> dict[str, float]:
        """``drive/<name>/effort`` [N or N m] at ``cfg``."""
        q, q_dot = self.coordinates(cfg)
        f, _ = self.effort(cfg.t, q, q_dot)
        return {f"drive/{n}/effort": float(x) for n, x in zip(self.names, f)}

    def compiled(self, pack) -> Items:
        kind, table = self.profile.table()
        return self._pack(pack, DriveServoItems, kind[:, None], np.column_stack([self.gain, self.capacity, table]))


class DriveServoItems(Items):
    """i: [point 1, point 2, coordinate code, time-function kind]; f: [A1, A2 (18), gain, capacity,
    ``TimeFunctions.table`` row (10)]."""


@compiled_piece(force_piece, DriveServoItems)
def _drive_servo(d, t, v, power):
    u, ref = v.v3[24], v.v3[26]
    for k in range(d.i.shape[0]):
        p1, p2 = d.i[k, 0], d.i[k, 1]
        row = d.f[k]
        q, q_dot = coordinate_of(v, row, d.i[k, 2], v.pt_i[p1, 0], v.pt_i[p2, 0], p1, p2, u)
        value(d.i[k, 3], row[20:30], t, ref)
        force = min(max(row[18] * (ref[0] - q_dot), -row[19]), row[19])
        _coordinate_force(v, d, k, force, u, v.v3[25])
        power[power.shape[0] - 1] += force * q_dot


#: Force elements by scene type (contacts are not force elements: ``viz3d.contact.contacts``).
FORCES: dict[str, type[ForceElement]] = {
    cls.type_name: cls for cls in (SpringDamper, AppliedForce, AppliedTorque, JointStop, JointMotor)
}

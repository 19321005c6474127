"""Contacts between bodies: geometry, a normal law or a rigid treatment, and their memory.

A ``ContactSet`` holds k contacts. Each is a sphere of radius ``r`` (``r = 0``: a point or a flat
face) centred on a material point ``a`` of body A, against a surface through a material point ``b``
of body B (or ground) whose outward normal ``n`` is fixed in B (``viz3d.points``: either point may
sit on a section of a flexible bar). The gap and the indentation are

    g = n . (a - b) - r,    alpha = -g,

so ``alpha > 0`` means overlap, and ``alpha_dot = J_alpha v`` with the rows of ``rows``. What acts
at the contact is chosen per contact (``model``):

* ``"law"``: a continuous normal law of ``viz3d.contact.laws`` (plus an optional linear dashpot
  that never pulls) gives ``F >= 0``; A is pushed along ``+n``, B along ``-n`` at the contact;
* ``"rigid"``: kinematic contact: a plastic impulse at onset, then ``alpha = 0`` held by a
  multiplier while it stays compressive (a constraint row that is active while touching);
* ``"restitution"``: an instantaneous impulse (Newton: separation speed ``e`` times the approach
  speed; Poisson: restitution impulse ``e`` times the compression impulse) at every touch.

Each contact's history is a ``ContactPhase`` value kept in the simulation state: whether it is
touching, its law's memory, the energy its impulses took and what its current contact started
with. Onset, maximum indentation and separation are events the stepper locates in time
(``viz3d.events``); with ``located = False`` a law contact acts whenever ``alpha > 0`` without any
event (a penalty contact stepped through, as in the stiff-contact stability study).

Sign of the multiplier of a rigid contact row: ``lambda >= 0`` is compressive (the row is
``alpha``, and the constraint force on the bodies is ``-C_v^T lambda``, docs/notation.md).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.compiled import (
    Items,
    compiled_piece,
    cross3,
    inline,
    dot3,
    force_piece,
    gap_piece,
    items,
    jit,
    matvec3,
    normal_force,
    replant_piece,
    row_piece,
    tmatvec3,
)
from viz3d.contact.friction import FRICTION_PARAMS, Bristle, friction_vector
from viz3d.contact.laws import NORMAL_LAWS, ContactMemory, NormalLaw
from viz3d.kinematics import Configuration, Pose
from viz3d.points import BodyPoints, add_row, apply_pair, bias
from viz3d.rotations import cross

#: Contact treatments.
MODELS = ("law", "rigid", "restitution")
#: Restitution hypotheses of impulses.
HYPOTHESES = ("newton", "poisson")


@dataclass(frozen=True)
class Onset:
    """What a contact started with, for its step bound and its checks (``viz3d.events``).

    Attributes
    ----------
    number : int
        1-based count of this contact's touches.
    t : float
        Onset time [s].
    speed : float
        Approach speed ``alpha_dot`` [m/s].
    memory : ContactMemory or None
        The law's memory before the touch.
    energy : float
        Mechanical energy of the system at onset [J].
    signed_potential : float
        Potential energies that may become negative (gravity, loads) at onset [J].
    balance : float
        Energy-ledger balance error at onset [J].
    dissipated : float
        Energy dissipated by the system so far at onset [J].
    time_scale : float
        The contact's time scale [s] (``viz3d.contact.resolution.contact_time_scale``).
    work_in : float
        Work done by non-conservative force elements since t = 0, at onset [J].
    n_steps : int
        Accepted steps taken while touching.
    velocity_error : float
        Sum over those steps of the magnitude of the error estimate of the relative normal
        velocity ``alpha_dot`` [m/s] (adaptive steps; 0 for fixed ones).
    energy_error : float
        Sum over those steps of the energy the numerics may have created [J]: the change of the
        ledger's balance error between the step's two embedded solutions (adaptive steps), or the
        change measured over the step (fixed steps, which have no estimate).
    balance_now : float
        Balance error after the last step taken while touching (at onset: ``balance``) [J].
    """

    number: int
    t: float
    speed: float
    memory: ContactMemory | None
    energy: float
    signed_potential: float
    balance: float
    dissipated: float
    time_scale: float
    work_in: float = 0.0
    n_steps: int = 0
    velocity_error: float = 0.0
    energy_error: float = 0.0
    balance_now: float = np.nan


@dataclass(frozen=True)
class ContactPhase:
    """The history of one contact (a value; handlers return new ones).

    Attributes
    ----------
    touching : bool
    memory : ContactMemory or None
        The normal law's memory (None before the first touch).
    impulse_loss : float
        Kinetic energy taken by its impulses so far [J].
    touches : int
        Touches so far.
    onset : Onset or None
        The current (or last) touch's start.
    anchor : tuple of 3 float, or None
        Stick anchor of a stateful friction law (``viz3d.contact.friction.Bristle``): the point of B
        where the bristles are planted, in B's axes from its frame origin (ground: world) [m].
    """

    touching: bool = False
    memory: ContactMemory | None = None
    impulse_loss: float = 0.0
    touches: int = 0
    onset: Onset | None = None
    anchor: tuple | None = None


@dataclass(frozen=True)
class Gap:
    """Contact kinematics at one configuration (k contacts).

    Attributes
    ----------
    alpha, alpha_dot : ndarray, shape (k,)
        Indentation [m] and its rate [m/s].
    n : ndarray, shape (k, 3)
        World normal of B's surface, pointing to A's side.
    d : ndarray, shape (k, 3)
        ``a - b``, world [m].
    point : ndarray, shape (k, 3)
        Contact point: A's sphere surface point nearest to B, ``a - r n`` [m].
    """

    alpha: FloatArray
    alpha_dot: FloatArray
    n: FloatArray
    d: FloatArray
    point: FloatArray


@dataclass(frozen=True)
class ContactSet:
    """k contacts between material points and surfaces (see the module docstring).

    Attributes
    ----------
    names : tuple of str, length k
    body : ndarray of int, shape (k, 2)
        Bodies A and B of each contact (``nb`` = ground).
    sides : tuple of BodyPoints
        Sphere centres on A and surface points on B.
    normal : ndarray, shape (k, 3)
        B's outward unit normal in B's axes (ground: world) [-].
    radius : ndarray, shape (k,)
        A's sphere radius [m] (0: a point or a flat face).
    models : tuple of str, length k
        ``MODELS``.
    laws : tuple of NormalLaw or None, length k
        The normal law of each ``"law"`` contact.
    restitution : ndarray, shape (k,)
        ``e`` of ``"restitution"`` contacts.
    hypotheses : tuple of str, length k
        ``HYPOTHESES``.
    damping : ndarray, shape (k,)
        Linear dashpot added to a law's force [N s/m] (never pulls).
    friction : tuple of FrictionLaw or None, length k
        Tangential law of each ``"law"`` contact (``viz3d.contact.friction``), acting at the contact
        point against the slip; rigid bodies and ground only.
    located : bool
        Events (onset, separation, maximum indentation) located in time and the law active only
        while touching; False: a law acts whenever ``alpha > 0`` (memoryless laws only).
    """

    names: tuple[str, ...]
    body: IntArray
    sides: tuple[BodyPoints, BodyPoints]
    normal: FloatArray
    radius: FloatArray
    models: tuple[str, ...]
    laws: tuple[NormalLaw | None, ...]
    restitution: FloatArray = field(default=None)
    hypotheses: tuple[str, ...] = field(default=None)
    damping: FloatArray = field(default=None)
    located: bool = True
    friction: tuple = None

    def __post_init__(self):
        k = len(self.names)
        if self.friction is None:
            object.__setattr__(self, "friction", (None,) * k)
        for i, law in enumerate(self.friction):
            if law is not None and (self.models[i] != "law" or any(g.which.size for s in self.sides for g in s.flex
                                                                   if i in g.which)):
                raise ValueError(f"contact {self.names[i]!r}: friction needs a force law between rigid bodies (or ground)")
        if self.restitution is None:
            object.__setattr__(self, "restitution", np.ones(k))
        if self.hypotheses is None:
            object.__setattr__(self, "hypotheses", ("newton",) * k)
        if self.damping is None:
            object.__setattr__(self, "damping", np.zeros(k))
        if not self.located and any(m != "law" for m in self.models):
            raise ValueError("contacts without located events must use a force law")

    @property
    def k(self) -> int:
        return len(self.names)

    @property
    def n_elastic(self) -> int:
        return self.sides[0].n_elastic

    @property
    def conservative(self) -> bool:
        """Forces that derive from a potential: stepped-through elastic laws without dashpots or friction."""
        return (not self.located and all(law is not None and not law.dissipative for law in self.laws)
                and not np.any(self.damping > 0) and all(f is None for f in self.friction))

    def initial_phases(self) -> tuple[ContactPhase, ...]:
        return tuple(ContactPhase() for _ in self.names)

    def rigid_rows(self) -> IntArray:
        """Indices of the contacts with a kinematic (constraint-row) treatment."""
        return np.array(self.rigid_indices, dtype=int)

    @functools.cached_property
    def rigid_indices(self) -> tuple[int, ...]:
        """``rigid_rows`` as a tuple, computed once."""
        return tuple(i for i, m in enumerate(self.models) if m == "rigid")

    # ------------------------------------------------------------------ kinematics

    def _normals(self, cfg: Configuration) -> FloatArray:
        return np.einsum("kij,kj->ki", cfg.pose.R_WB[self.body[:, 1]], self.normal)

    def gap(self, cfg: Configuration) -> Gap:
        """Indentations, their rates, normals and contact points (see ``Gap``)."""
        A, B = self.sides
        rho_a, rho_b = A.levers(cfg), B.levers(cfg)
        a = cfg.pose.W_r[self.body[:, 0]] + rho_a
        b = cfg.pose.W_r[self.body[:, 1]] + rho_b
        n = self._normals(cfg)
        d = a - b
        g = np.einsum("ki,ki->k", n, d) - self.radius
        w_b = cfg.twist.W_omega[self.body[:, 1]]
        d_dot = A.velocities(cfg, rho_a) - B.velocities(cfg, rho_b)
        g_dot = np.einsum("ki,ki->k", cross(w_b, n), d) + np.einsum("ki,ki->k", n, d_dot)
        return Gap(-g, -g_dot, n, d, a - self.radius[:, None] * n)

    def rows(self, cfg: Configuration) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Rows of ``alpha``: residual (k,), frame Jacobian (k, 2, 6), elastic Jacobian (k, 2, n_e) and
        gamma (k,) with ``J_alpha v_dot = gamma`` while ``alpha`` is held constant.

        ``g_dot = n . (v_a - v_b) + (w_B x n) . d``, so on A ``n^T J_a``, on B ``-n^T J_b + (n x d)^T
        [0, R_B]``; ``gamma_alpha = g_ddot - J_g v_dot``, the velocity-product terms ``(w x (w x n)) .
        d + 2 (w x n) . d_dot + n . (bias_a - bias_b)``.
        """
        A, B = self.sides
        gp = self.gap(cfg)
        Jf_a, Je_a = A.jacobian(cfg)
        Jf_b, Je_b = B.jacobian(cfg)
        J = np.zeros((self.k, 2, 6))
        J[:, 0] = -np.einsum("ki,kij->kj", gp.n, Jf_a)
        J[:, 1] = np.einsum("ki,kij->kj", gp.n, Jf_b)
        R_b = cfg.pose.R_WB[self.body[:, 1]]
        J[:, 1, 3:] -= np.einsum("ki,kij->kj", cross(gp.n, gp.d), R_b)
        Je = np.stack([-np.einsum("ki,kij->kj", gp.n, Je_a), np.einsum("ki,kij->kj", gp.n, Je_b)], axis=1)
        w = cfg.twist.W_omega[self.body[:, 1]]
        rho_a, rho_b = A.levers(cfg), B.levers(cfg)
        d_dot = A.velocities(cfg, rho_a) - B.velocities(cfg, rho_b)
        wn = cross(w, gp.n)
        bias = (np.einsum("ki,ki->k", cross(w, wn), gp.d) + 2.0 * np.einsum("ki,ki->k", wn, d_dot)
                + np.einsum("ki,ki->k", gp.n, A.bias(cfg, rho_a) - B.bias(cfg, rho_b)))
        return gp.alpha, J, Je, bias

    # ------------------------------------------------------------------ forces

    def active(self, phases: tuple[ContactPhase, ...], gp: Gap) -> np.ndarray:
        """Contacts whose law acts now (touching, or overlapping when events are not located)."""
        if not self.located:
            return gp.alpha > 0.0
        return np.array([p.touching and m == "law" for p, m in zip(phases, self.models)], dtype=bool)

    def magnitudes(self, gp: Gap, phases: tuple[ContactPhase, ...]) -> FloatArray:
        """Normal force of each law contact that acts [N] (0 elsewhere)."""
        on = self.active(phases, gp)
        F = np.zeros(self.k)
        for i in np.flatnonzero(on):
            law = self.laws[i]
            memory = phases[i].memory if self.located else None
            elastic = float(law.force(gp.alpha[i], gp.alpha_dot[i], memory)) if gp.alpha[i] > 0.0 else 0.0
            F[i] = max(elastic + self.damping[i] * gp.alpha_dot[i], 0.0) if gp.alpha[i] > 0.0 else 0.0
        return F

    def slip(self, cfg: Configuration, gp: Gap) -> FloatArray:
        """Tangential slip velocity of A on B at the contact points, world [m/s], shape (k, 3): the
        velocity of A's material at ``point`` minus B's, without its normal part."""
        A, B = self.sides
        rho_a, rho_b = A.levers(cfg), B.levers(cfg)
        to_point = -self.radius[:, None] * gp.n
        v = (A.velocities(cfg, rho_a) + cross(cfg.twist.W_omega[self.body[:, 0]], to_point)
             - B.velocities(cfg, rho_b) - cross(cfg.twist.W_omega[self.body[:, 1]], gp.d + to_point))
        return v - np.einsum("ki,ki->k", v, gp.n)[:, None] * gp.n

    def deflection(self, pose: Pose, gp: Gap, phases: tuple[ContactPhase, ...],
                   anchors: FloatArray | None = None) -> FloatArray:
        """Bristle deflection of the contacts with a stick anchor, world [m], shape (k, 3): the contact
        point minus the anchor (fixed in B), without its normal part; zero elsewhere. ``pose``: the
        bodies' (``Configuration.pose``). Of N states at once for ``pose`` and ``gp`` with a leading
        axis: shape (N, k, 3), their stick anchors ``anchors`` (N, k, 3) (default: ``anchor_table``)."""
        A = self.anchor_table(phases) if anchors is None else anchors
        has = ~np.isnan(A[..., :1])
        b = self.body[:, 1]
        d = gp.point - pose.W_r[..., b, :] - (pose.R_WB[..., b, :, :] @ np.where(has, A, 0.0)[..., None])[..., 0]
        s = d - (gp.n[..., None, :] @ d[..., :, None])[..., 0] * gp.n
        return np.where(has, s, 0.0)

    def anchor_table(self, phases: tuple[ContactPhase, ...]) -> FloatArray:
        """The stick anchors of ``phases`` (B's axes [m]), shape (k, 3), NaN where a contact has none."""
        A = np.full((self.k, 3), np.nan)
        for i, phase in enumerate(phases):
            if phase.anchor is not None:
                A[i] = phase.anchor
        return A

    def anchor_at(self, cfg: Configuration, gp: Gap, i: int, s: FloatArray) -> tuple:
        """The anchor (B's axes, ``ContactPhase.anchor``) that gives contact ``i`` the deflection ``s`` (3,)."""
        b = self.body[i, 1]
        return tuple(float(x) for x in cfg.pose.R_WB[b].T @ (gp.point[i] - s - cfg.pose.W_r[b]))

    def friction_forces(self, cfg: Configuration, gp: Gap, F: FloatArray, phases: tuple[ContactPhase, ...]) -> FloatArray:
        """Friction force on A at each contact point [N], shape (k, 3), from the normal forces ``F``
        (``magnitudes``), the slip and the bristles' deflection (``viz3d.contact.friction``); zero
        without a law."""
        f = np.zeros((self.k, 3))
        which = [i for i, law in enumerate(self.friction) if law is not None and F[i] > 0.0]
        if not which:
            return f
        v_t, s = self.slip(cfg, gp), self.deflection(cfg.pose, gp, phases)
        for i in which:
            f[i] = self.friction[i].vector(v_t[i], s[i], F[i])
        return f

    def wrench(self, cfg: Configuration, phases: tuple[ContactPhase, ...]) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Generalized forces of the law contacts: ``F`` along ``+n`` on A at its sphere centre, along
        ``-n`` on B at its material point plus the couple ``F (n x d)`` (the force acts at A's point);
        friction ``f_t`` on A at the contact point (at A's centre plus the couple ``-r n x f_t``) and
        ``-f_t`` on B (at its point plus ``-(d - r n) x f_t``); shapes (nb + 1, 3), (nb + 1, 3), (n_e,)."""
        gp = self.gap(cfg)
        F = self.magnitudes(gp, phases)
        f_t = self.friction_forces(cfg, gp, F, phases)
        f = F[:, None] * gp.n + f_t
        Fa, ta, Qa = self.sides[0].wrench(cfg, f)
        Fb, tb, Qb = self.sides[1].wrench(cfg, -f)
        n_rows = cfg.pose.W_r.shape[0]
        couple = np.zeros((n_rows, 3))
        np.add.at(couple, self.body[:, 1], F[:, None] * cross(gp.n, gp.d) - cross(gp.d, f_t))
        np.add.at(couple, self.body[:, 0], -self.radius[:, None] * cross(gp.n, f_t))
        np.add.at(couple, self.body[:, 1], self.radius[:, None] * cross(gp.n, f_t))
        return Fa + Fb, ta + tb + couple, Qa + Qb

    def power(self, cfg: Configuration, phases: tuple[ContactPhase, ...]) -> FloatArray:
        """Power the bodies do on each contact [W], shape (k,): on its law, ``F alpha_dot``, and on its
        friction, ``-f_t . v_t >= 0`` (dissipated)."""
        gp = self.gap(cfg)
        F = self.magnitudes(gp, phases)
        P = F * gp.alpha_dot
        if any(law is not None for law in self.friction):
            P = P - np.einsum("ki,ki->k", self.friction_forces(cfg, gp, F, phases), self.slip(cfg, gp))
        return P

    def elastic_energy(self, cfg: Configuration | None, phases: tuple[ContactPhase, ...], gp: Gap | None = None,
                       pose: Pose | None = None, anchors: FloatArray | None = None) -> FloatArray:
        """Recoverable energy stored in each acting law contact [J], shape (k,); ``gp``: ``gap(cfg)``
        if the caller has it, ``pose``: ``cfg.pose`` (bristles' deflection; with both, ``cfg`` may be None).
        Of N states sharing ``phases`` at once for ``gp`` and ``pose`` with a leading axis (N,): shape
        (N, k), their stick anchors ``anchors`` (N, k, 3) (``deflection``)."""
        gp = self.gap(cfg) if gp is None else gp
        on = self.active(phases, gp) & (gp.alpha > 0.0)
        U = np.zeros(gp.alpha.shape)
        acting = np.flatnonzero(on.reshape(-1, self.k).any(axis=0))
        for i in acting:
            memory = phases[i].memory if self.located else None
            U[..., i] = np.where(on[..., i], self.laws[i].elastic_energy(gp.alpha[..., i], memory), 0.0)
        if any(f is not None and f.stateful for f in self.friction):
            s = self.deflection(cfg.pose if pose is None else pose, gp, phases, anchors)
            for i in acting:
                if self.friction[i] is not None and self.friction[i].stateful:
                    U[..., i] += np.where(on[..., i], self.friction[i].energy(s[..., i, :]), 0.0)
        return U

    def contacts(self, cfg: Configuration, phases: tuple[ContactPhase, ...]) -> tuple[FloatArray, FloatArray]:
        """Contact points (m, 3) of the contacts that carry a law force and that force on A, friction
        included (m, 3), for display."""
        gp = self.gap(cfg)
        F = self.magnitudes(gp, phases)
        on = F > 0.0
        f = F[:, None] * gp.n + self.friction_forces(cfg, gp, F, phases)
        return gp.point[on], f[on]

    def compiled(self, pack) -> list[Items]:
        """The geometry of every contact (``ContactGeometry``) and the law contacts per law class
        (``law_contacts``): i = [point a, point b, body B, global contact index, located], f = [B's
        normal (3), radius, dashpot, friction (``FRICTION_PARAMS``), the law's ``params()``]."""
        a, b, k0 = pack.points(self.sides[0]), pack.points(self.sides[1]), pack.contact_start(self)
        geometry = items(ContactGeometry, np.column_stack([a, b, self.body[:, 1], k0 + np.arange(self.k)]),
                         np.column_stack([self.normal, self.radius]), k=self.k)
        groups: dict[type, list] = {}
        for j, (model, law) in enumerate(zip(self.models, self.laws)):
            if model != "law":
                continue
            cls = pack.law_items(law)
            row_i = [a[j], b[j], self.body[j, 1], k0 + j, int(self.located)]
            friction = self.friction[j].params() if self.friction[j] is not None else [0.0] * FRICTION_PARAMS
            row_f = [*self.normal[j], self.radius[j], self.damping[j], *friction, *law.params()]
            groups.setdefault(cls, []).append((row_i, row_f))
        return [geometry] + [items(cls, [r[0] for r in rows], [r[1] for r in rows], k=len(rows))
                             for cls, rows in groups.items()]


@dataclass(frozen=True)
class ContactRows:
    """The kinematic contacts of a ``ContactSet`` as constraint rows (``alpha``, one per contact),
    active only while touching: a row provider beside the joint sets of a ``ConstraintLayout``.

    Attributes
    ----------
    contacts : ContactSet
    which : ndarray of int, shape (m,)
        The rigid contacts of the set.
    set_index : int
        Position of the set among ``System.contacts`` (its phases in ``State.memory``).
    """

    contacts: ContactSet
    which: IntArray
    set_index: int
    is_joint = False
    n_eq = 1

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.contacts.names[i] for i in self.which)

    @property
    def body(self) -> IntArray:
        return self.contacts.body[self.which]

    @property
    def n_joints(self) -> int:
        return len(self.which)

    def active(self, memory: tuple) -> np.ndarray:
        """Rows that act now, shape (m,) (touching kinematic contacts)."""
        phases = memory[self.set_index] if memory else self.contacts.initial_phases()
        return np.array([phases[i].touching for i in self.which], dtype=bool)

    def _rows(self, cfg):
        alpha, J, Je, gamma = self.contacts.rows(cfg)
        w = self.which
        return alpha[w], J[w], Je[w], gamma[w]

    def rows(self, cfg):
        """Residual, Jacobian and gamma from one evaluation of the contact geometry."""
        alpha, J, Je, gamma = self._rows(cfg)
        return alpha[:, None], (J[:, None], Je[:, None]), gamma[:, None]

    def residual(self, cfg):
        return self._rows(cfg)[0][:, None]

    def jacobian(self, cfg):
        _, J, Je, _ = self._rows(cfg)
        return J[:, None], Je[:, None]

    def gamma(self, cfg):
        return self._rows(cfg)[3][:, None]

    def compiled(self, pack) -> Items:
        c = self.contacts
        a, b, k0 = pack.points(c.sides[0]), pack.points(c.sides[1]), pack.contact_start(c)
        w = self.which
        i = np.column_stack([pack.row_start(self) + np.arange(len(w)), a[w], b[w], c.body[w, 1], k0 + w])
        return items(RigidContactItems, i, np.column_stack([c.normal[w], c.radius[w]]), k=len(w))


#: Columns of ``memory_rows``.
MEMORY_COLUMNS = 7


def memory_rows(phases: tuple[ContactPhase, ...]) -> FloatArray:
    """The contacts' memory as the compiled pieces read it, shape (k, ``MEMORY_COLUMNS``): ``[touching,
    approach speed [m/s], largest indentation [m], has an anchor, the stick anchor in B's axes (3) [m]]``."""
    out = np.zeros((len(phases), MEMORY_COLUMNS))
    for j, p in enumerate(phases):
        out[j, 0] = float(p.touching)
        if p.memory is not None:
            out[j, 1], out[j, 2] = p.memory.approach_speed, p.memory.alpha_max
        if p.anchor is not None:
            out[j, 3] = 1.0
            out[j, 4:7] = p.anchor
    return out


# ---------------------------------------------------------------------------- compiled pieces
# Memory rows ``w.mem`` (``memory_rows``) and the power slots of the ledger are indexed by the
# global contact index (contacts of all sets in order).

#: Columns of the friction and the law parameters in ``LawContacts.f``.
FRICTION_COLUMN = 5
LAW_COLUMN = FRICTION_COLUMN + FRICTION_PARAMS


class ContactGeometry(Items):
    """Every contact's geometry: i = [point a, point b, body B, global index]; f = [normal (3), radius]."""


class RigidContactItems(Items):
    """Kinematic contacts: i = [row, point a, point b, body B, global index]; f = [normal (3), radius]."""


@jit
def _gap(v, pa, pb, bB, normal, radius, n, d):
    """Indentation and its rate of one contact; its world normal and ``a - b`` into ``n``, ``d``."""
    matvec3(v.R[bB], normal, n)
    for c in range(3):
        d[c] = v.px[pa, c] - v.px[pb, c]
    t = v.v3[14]
    cross3(v.wW[bB], n, t)
    g_dot = dot3(t, d)
    for c in range(3):
        g_dot += n[c] * (v.pv[pa, c] - v.pv[pb, c])
    return radius - dot3(n, d), -g_dot


@compiled_piece(gap_piece, ContactGeometry)
def _contact_gaps(d, v, out):
    n, dv = v.v3[8], v.v3[9]
    for k in range(d.i.shape[0]):
        alpha, alpha_dot = _gap(v, d.i[k, 0], d.i[k, 1], d.i[k, 2], d.f[k, 0:3], d.f[k, 3], n, dv)
        row = out[d.i[k, 3]]
        row[0], row[1] = alpha, alpha_dot
        for c in range(3):  # the rest of Gap: n, d, point = a - r n
            row[2 + c] = n[c]
            row[5 + c] = dv[c]
            row[8 + c] = v.px[d.i[k, 0], c] - d.f[k, 3] * n[c]


@inline
def _magnitude(d, k, kg, v, alpha, alpha_dot):
    """Normal force [N] of law contact ``k`` of ``d`` (global index ``kg``) at indentation ``alpha`` > 0
    and its rate: its law's (memory in ``v.mem``) plus its dashpot, clipped at zero (``ContactSet.magnitudes``)."""
    elastic = normal_force(d, k, LAW_COLUMN, alpha, alpha_dot, v.mem[kg, 1], v.mem[kg, 2], True)
    return max(elastic + d.f[k, 4] * alpha_dot, 0.0)


@inline
def _deflection(v, pa, pb, bB, kg, r, n, a, s):
    """Bristle deflection of contact ``kg`` into ``s`` (3,): its contact point ``a - r n`` minus its stick
    anchor (``v.mem[kg, 4:7]``, B's axes; B's frame origin ``r_B = x_b - rho_b``), without its normal part
    (``ContactSet.deflection``); ``a`` (3,) scratch."""
    matvec3(v.R[bB], v.mem[kg, 4:7], a)
    for c in range(3):
        s[c] = v.px[pa, c] - r * n[c] - (v.px[pb, c] - v.prho[pb, c]) - a[c]
    sn = dot3(s, n)
    for c in range(3):
        s[c] -= sn * n[c]


def _law_contacts(d, t, v, power):
    n, dv, f = v.v3[8], v.v3[9], v.v3[10]
    for k in range(d.i.shape[0]):
        pa, pb, bB, kg = d.i[k, 0], d.i[k, 1], d.i[k, 2], d.i[k, 3]
        alpha, alpha_dot = _gap(v, pa, pb, bB, d.f[k, 0:3], d.f[k, 3], n, dv)
        acting = v.mem[kg, 0] == 1.0 if d.i[k, 4] == 1 else alpha > 0.0
        if not acting or alpha <= 0.0:
            continue
        F = _magnitude(d, k, kg, v, alpha, alpha_dot)
        for c in range(3):
            f[c] = F * n[c]
        apply_pair(v, pa, pb, f)
        cross3(n, dv, f)
        for c in range(3):
            v.tau[bB, c] += F * f[c]
        power[kg] += F * alpha_dot
        if d.f[k, FRICTION_COLUMN] != 0.0 and F > 0.0:
            power[kg] += _friction(d, k, v, pa, pb, bB, kg, F, n, dv)


@jit
def _friction(d, k, v, pa, pb, bB, kg, F, n, dv):
    """Apply contact ``k``'s friction (normal force ``F``, world normal ``n``, ``dv = a - b``) at its
    contact point ``a - r n``: ``f_t`` on A, ``-f_t`` on B (``ContactSet.wrench``); returns the power
    the bodies do on it, ``-f_t . v_t``."""
    r = d.f[k, 3]
    bA = v.pt_i[pa, 0]
    vt, t1, t2, sb, ft = v.v3[11], v.v3[12], v.v3[13], v.v3[15], v.v3[26]
    for c in range(3):
        t1[c] = -r * n[c]                      # contact point from a
        t2[c] = dv[c] - r * n[c]               # contact point from b
    cross3(v.wW[bA], t1, vt)
    for c in range(3):
        vt[c] += v.pv[pa, c] - v.pv[pb, c]
    cross3(v.wW[bB], t2, t1)
    for c in range(3):
        vt[c] -= t1[c]
    vn = dot3(vt, n)
    for c in range(3):
        vt[c] -= vn * n[c]
        sb[c] = 0.0
    if v.mem[kg, 3] == 1.0:  # bristles
        _deflection(v, pa, pb, bB, kg, r, n, t1, sb)
    friction_vector(d.f[k, FRICTION_COLUMN:FRICTION_COLUMN + FRICTION_PARAMS], vt, sb, F, ft)
    P = -dot3(ft, vt)
    apply_pair(v, pa, pb, ft)                  # f_t on A at a, -f_t on B at b
    cross3(n, ft, t1)
    for c in range(3):
        v.tau[bA, c] -= r * t1[c]              # -r n x f_t: the force acts at a - r n
        v.tau[bB, c] += r * t1[c]
    cross3(dv, ft, t1)
    for c in range(3):
        v.tau[bB, c] -= t1[c]                  # -(d) x f_t (with the r n part above)
    return P


#: ``Bristle.code`` as the packed friction parameters hold it.
BRISTLE = float(Bristle.code)


def _replant(d, t, v):
    """``ContactStepping._replant`` after an accepted step (its kinematics in ``v``): the stick anchor
    (``v.mem[kg, 4:7]``, B's axes) of every touching located contact with bristles whose deflection
    carries more than ``mu_s F_n`` moved to leave it ``alpha mu_s F_n / k`` (``Bristle.anchor_update``,
    seed 004 eq. 3.49); the deflection and ``F_n`` as ``_friction`` and ``_law_contacts`` make them."""
    n, dv, s, a = v.v3[8], v.v3[9], v.v3[10], v.v3[11]
    for k in range(d.i.shape[0]):
        pa, pb, bB, kg = d.i[k, 0], d.i[k, 1], d.i[k, 2], d.i[k, 3]
        p = d.f[k, FRICTION_COLUMN:FRICTION_COLUMN + FRICTION_PARAMS]
        if p[0] != BRISTLE or d.i[k, 4] != 1 or v.mem[kg, 0] != 1.0 or v.mem[kg, 3] != 1.0:
            continue
        alpha, alpha_dot = _gap(v, pa, pb, bB, d.f[k, 0:3], d.f[k, 3], n, dv)
        F = _magnitude(d, k, kg, v, alpha, alpha_dot) if alpha > 0.0 else 0.0
        r = d.f[k, 3]
        _deflection(v, pa, pb, bB, kg, r, n, a, s)
        limit, size = p[2] * F, math.sqrt(dot3(s, s))
        if p[6] * size <= limit or size == 0.0:
            continue
        keep = p[8] * limit / (p[6] * size)
        for c in range(3):  # the anchor that leaves the deflection s keep: R^T (point - s keep - r_B)
            a[c] = v.px[pa, c] - r * n[c] - s[c] * keep - (v.px[pb, c] - v.prho[pb, c])
        tmatvec3(v.R[bB], a, s)
        for c in range(3):
            v.mem[kg, 4 + c] = s[c]


_LAW_CONTACTS: dict[type, type[Items]] = {}


def law_contacts(items_cls: type[Items]) -> type[Items]:
    """The packed data class of law contacts (``ContactSet.compiled``) whose law has the compiled data
    class ``items_cls``: a subclass of it (the law's piece reads its parameters), created and
    registered as a force piece (and a replant piece: ``_replant``) on first use."""
    if items_cls not in _LAW_CONTACTS:
        cls = type(f"Contacts{items_cls.__name__}", (items_cls,), {"__module__": __name__})
        globals()[cls.__name__] = cls  # importable by name: numba's cache pickles types by reference
        compiled_piece(force_piece, cls)(_law_contacts)
        compiled_piece(replant_piece, cls)(_replant)
        _LAW_CONTACTS[items_cls] = cls
    return _LAW_CONTACTS[items_cls]


@compiled_piece(row_piece, RigidContactItems)
def _rigid_contacts(d, t, v):
    n, dv, a1, a2 = v.v3[8], v.v3[9], v.v3[10], v.v3[11]
    for k in range(d.i.shape[0]):
        row, pa, pb, bB, kg = d.i[k, 0], d.i[k, 1], d.i[k, 2], d.i[k, 3], d.i[k, 4]
        if v.mem[kg, 0] != 1.0:
            v.inactive[row] = 1
            continue
        alpha, _ = _gap(v, pa, pb, bB, d.f[k, 0:3], d.f[k, 3], n, dv)
        add_row(v, row, 0, pa, n, -1.0)
        add_row(v, row, 1, pb, n, 1.0)
        cross3(n, dv, a1)
        tmatvec3(v.R[bB], a1, a2)
        for c in range(3):
            v.J[row, 1, 3 + c] -= a2[c]
        # gamma = (w x (w x n)) . d + 2 (w x n) . d_dot + n . (bias_a - bias_b)
        om = v.wW[bB]
        cross3(om, n, a1)
        cross3(om, a1, a2)
        g = dot3(a2, dv)
        for c in range(3):
            g += 2.0 * a1[c] * (v.pv[pa, c] - v.pv[pb, c])
        bias(v, pa, a1)
        bias(v, pb, a2)
        for c in range(3):
            g += n[c] * (a1[c] - a2[c])
        v.C[row] = alpha
        v.gam[row] = g


for _law in NORMAL_LAWS.values():  # one data class per law known now: the kernel's types do not depend on run order
    if _law.compiled_items is not None:
        law_contacts(_law.compiled_items)

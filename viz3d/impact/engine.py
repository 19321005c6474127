"""Impact engine: two linear bodies that touch at one point each, integrated event by event.

Each body is linear in its own generalized coordinates ``z`` (a rigid impactor has one, a
flexible bar its reference coordinates plus modal or nodal ones)::

    M z_dd + C z_d + K z = f + s F r                                    (per body)

where ``r`` maps ``z`` to the displacement of the body's contact point along the contact normal
``n`` (which points from body 1 into body 2), ``f`` is a constant load (e.g. gravity), ``F >= 0``
is the contact force and ``s = -1`` for body 1, ``+1`` for body 2. The local indentation is
``alpha = r1.z1 - r2.z2 - gap`` (positive when the surfaces overlap). Contact models:

* a continuous normal law ``F(alpha, alpha_dot, memory)`` (viz3d.contact.laws), resolved in time:
  onset, maximum indentation (elastoplastic memory) and separation are located as events;
* ``rigid``: kinematic contact. At onset the normal velocities are equalised by a plastic impulse,
  then ``alpha = 0`` is kept by a multiplier ``F`` while ``F > 0``; separation when ``F`` reaches 0;
* ``restitution``: instantaneous Newton impulses with coefficient ``e`` at every touch (the
  thesis's generalized impulse-momentum balance, ch. 6).

The state integrated by the adaptive method is ``y = [z1, z2, z1_d, z2_d, W]`` with ``W`` the
work done on the contact, ``int F alpha_dot dt``; the energy ledger is then
``dissipated = W - elastic_energy(alpha) + impulse losses`` and the balance error is what the
numerics created or destroyed.

A law contact is resolved, not stepped over: from its onset no step is longer than
``STEP_FRACTION`` of the contact's time scale (``viz3d.contact.resolution.contact_time_scale``
from the law, the effective mass ``1 / (r1^T M1^-1 r1 + r2^T M2^-1 r2)``, the approach speed and
the loads). Two checks stop a run (status naming the contact, the time and the quantity) when a
contact was nevertheless not resolved: after every step, the indentation's recoverable energy may
not exceed the energy available to the contact (kinetic, strain and contact energy at onset plus
the work of the loads since, plus what the numerics created, read from the ledger): exact for any
bodies; at every separation, the contact's restitution may not be negative (a located separation
has the surfaces receding) and, between rigid bodies, must be the law's own free-impact value
within the loads' effect and the integration error.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from viz3d._typing import FloatArray
from viz3d.contact.resolution import (
    STEP_FRACTION,
    contact_time_scale,
    free_impact_restitution,
    indentation_diagnosis,
    integration_restitution_slack,
    load_restitution_slack,
    restitution_diagnosis,
)
from viz3d.integrators import ExplicitRK
from viz3d.integrators.adaptive import Controller, Event, hermite, integrate
from viz3d.integrators.tableaus import DOPRI5

#: A kinematic contact needing less tension than this [N] (round-off) is kept at onset.
RIGID_TENSION_TOL = 1e-9
#: At most this many events per run (guards against Zeno sequences of impacts).
MAX_EVENTS = 100_000


@dataclass(frozen=True)
class LinearBody:
    """One body of an impact, linear in its coordinates.

    Attributes
    ----------
    name : str
    M, C, K : ndarray, shape (n, n)
        Mass [kg-consistent], damping and stiffness matrices.
    r : ndarray, shape (n,)
        Contact-point displacement along the contact normal per unit ``z`` [m].
    f : ndarray, shape (n,)
        Constant generalized load (e.g. gravity) [N-consistent].
    z0, zd0 : ndarray, shape (n,)
        Initial coordinates and velocities.
    rigid : ndarray of bool, shape (n,)
        Coordinates that are rigid-body (reference) motion, for the ledger's kinetic split.
    M_inv : ndarray, shape (n, n)
        ``M^-1`` (derived).
    M_inv_r : ndarray, shape (n,)
        ``M^-1 r`` [1/kg-consistent]: coordinate accelerations per unit contact force (derived).
    mobility : float
        ``r^T M^-1 r`` [1/kg]: contact-point velocity change per unit impulse (derived).
    """

    name: str
    M: FloatArray
    C: FloatArray
    K: FloatArray
    r: FloatArray
    f: FloatArray
    z0: FloatArray
    zd0: FloatArray
    rigid: np.ndarray
    M_inv: FloatArray = field(init=False, repr=False)
    M_inv_r: FloatArray = field(init=False, repr=False)
    mobility: float = field(init=False, repr=False)

    def __post_init__(self):
        M_inv = np.linalg.inv(self.M) if self.n else np.zeros((0, 0))
        object.__setattr__(self, "M_inv", M_inv)
        object.__setattr__(self, "M_inv_r", M_inv @ self.r)
        object.__setattr__(self, "mobility", float(self.r @ M_inv @ self.r) if self.n else 0.0)

    @property
    def n(self) -> int:
        return len(self.r)

    def kinetic(self, zd: FloatArray) -> tuple[float, float]:
        """Kinetic energy of the rigid and of the elastic coordinates [J] (their coupling term
        is counted with the elastic part)."""
        total = 0.5 * float(zd @ self.M @ zd)
        zr = np.where(self.rigid, zd, 0.0)
        rigid = 0.5 * float(zr @ self.M @ zr)
        return rigid, total - rigid

    def strain(self, z: FloatArray) -> float:
        return 0.5 * float(z @ self.K @ z)

    @property
    def elastic(self) -> bool:
        """True when the body deforms (it has elastic coordinates)."""
        return not bool(self.rigid.all())

    @property
    def rigid_mobility(self) -> float:
        """``r_r^T M_rr^-1 r_r`` [1/kg]: the rigid (frame) motion's share of the contact mobility;
        an impulse P changes the rigid normal velocity of the contact point by ``P`` times this."""
        if not self.rigid.any():
            return 0.0
        rr = self.r[self.rigid]
        return float(rr @ np.linalg.solve(self.M[np.ix_(self.rigid, self.rigid)], rr))

    def rigid_normal_velocity(self, zd: FloatArray) -> float:
        """Normal velocity of the contact point due to the rigid (frame) motion, with the frame
        velocity taken from the rigid part of the momentum, ``M_rr^-1 (M zd)_r`` (so elastic
        motion does not count: for a translating frame, the centre-of-mass velocity) [m/s]."""
        if not self.rigid.any():
            return 0.0
        v_frame = np.linalg.solve(self.M[np.ix_(self.rigid, self.rigid)], (self.M @ zd)[self.rigid])
        return float(self.r[self.rigid] @ v_frame)

    def load_potential(self, z: FloatArray) -> float:
        return -float(self.f @ z)


def fixed_body(name: str = "ground") -> LinearBody:
    """A body that cannot move (a rigid stop)."""
    e = np.zeros(0)
    return LinearBody(name, np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0)), e, e, e, e, np.zeros(0, bool))


def rigid_mass(name: str, mass: float, velocity: float, gap: float = 0.0, force: float = 0.0) -> LinearBody:
    """A rigid body moving along the contact normal: one coordinate, ``z`` along ``n``.

    ``velocity`` [m/s] is along ``n`` (positive = towards body 2 when it is body 1).
    """
    one = np.ones(1)
    return LinearBody(name, mass * np.eye(1), np.zeros((1, 1)), np.zeros((1, 1)), one, force * one,
                      np.zeros(1), velocity * one, np.ones(1, bool))


@dataclass(frozen=True)
class Contact:
    """How the two bodies interact.

    Attributes
    ----------
    model : str
        "law", "rigid" or "restitution".
    law : NormalLaw or None
        For ``model == "law"``.
    restitution : float
        For ``model == "restitution"``.
    hypothesis : str
        "newton" or "poisson" (``model == "restitution"``; see ``ImpactProblem.impulse``).
    gap : float
        Initial distance between the surfaces along ``n`` [m].
    """

    model: str
    law: object = None
    restitution: float = 1.0
    gap: float = 0.0
    hypothesis: str = "newton"


@dataclass
class Sample:
    """Everything recorded at one output time (SI units)."""

    t: float
    z1: FloatArray
    z2: FloatArray
    z1d: FloatArray
    z2d: FloatArray
    alpha: float
    alpha_dot: float
    force: float
    in_contact: bool
    ledger: dict


@dataclass
class ImpactRun:
    """Result of ``run_impact``: samples, events, per-contact speeds and cost.

    ``contacts`` holds one (t_start, approach speed, t_end, separation speed) per contact [s, m/s]
    (normal relative speeds of the contact points; t_end and separation speed are nan for a
    contact still going on at the end); ``contact_rigid`` one (before, after) per contact: the
    bodies' rigid relative normal velocity (approaching > 0) just before it starts (before any
    impulse) and when it ends [m/s]; ``impulses`` one (t, P) per instantaneous impulse [s, N s].
    """

    samples: list[Sample]
    events: list[tuple[float, str]]
    n_accepted: int
    n_rejected: int
    n_rhs: int
    status: str = "ok"
    contacts: list = field(default_factory=list)
    contact_rigid: list = field(default_factory=list)
    impulses: list = field(default_factory=list)


class ImpactProblem:
    """Two bodies and a contact; builds the vector field of each contact phase."""

    def __init__(self, body1: LinearBody, body2: LinearBody, contact: Contact):
        self.b1, self.b2, self.contact = body1, body2, contact
        self.n1, self.n2 = body1.n, body2.n
        self.n = self.n1 + self.n2
        #: Mechanical energy at t = 0 [J] (the reference of the balance error).
        self.initial_energy = self.ledger(self.initial_state(), None, 0.0, False)["total"]

    # ------------------------------------------------------------------ state layout

    def split(self, y: FloatArray):
        n1, n = self.n1, self.n
        return y[:n1], y[n1:n], y[n:n + n1], y[n + n1:2 * n], y[2 * n]

    def join(self, z1, z2, z1d, z2d, W) -> FloatArray:
        return np.concatenate([z1, z2, z1d, z2d, [W]])

    def initial_state(self) -> FloatArray:
        return self.join(self.b1.z0, self.b2.z0, self.b1.zd0, self.b2.zd0, 0.0)

    def indentation(self, y: FloatArray) -> tuple[float, float]:
        """``(alpha, alpha_dot)`` [m, m/s]."""
        z1, z2, z1d, z2d, _ = self.split(y)
        alpha = float(self.b1.r @ z1 - self.b2.r @ z2) - self.contact.gap
        return alpha, float(self.b1.r @ z1d - self.b2.r @ z2d)

    @property
    def effective_mass(self) -> float:
        """``1 / (r1^T M1^-1 r1 + r2^T M2^-1 r2)`` [kg]: impulse per unit change of ``alpha_dot``."""
        return 1.0 / (self.b1.mobility + self.b2.mobility)

    @property
    def load_acceleration(self) -> float:
        """``alpha_dd`` the constant loads alone give [m/s^2] (exact for rigid bodies)."""
        a1 = float(self.b1.r @ self.b1.M_inv @ self.b1.f) if self.n1 else 0.0
        a2 = float(self.b2.r @ self.b2.M_inv @ self.b2.f) if self.n2 else 0.0
        return a1 - a2

    @property
    def rigid_bodies(self) -> bool:
        """True when neither body deforms: the relative normal motion is then one degree of freedom."""
        return not (self.b1.elastic or self.b2.elastic)

    def rigid_relative_velocity(self, y: FloatArray) -> float:
        """Relative normal velocity of the bodies' rigid motions (approaching > 0) [m/s]."""
        _, _, z1d, z2d, _ = self.split(y)
        v1 = self.b1.rigid_normal_velocity(z1d) if self.n1 else 0.0
        v2 = self.b2.rigid_normal_velocity(z2d) if self.n2 else 0.0
        return v1 - v2

    def load_potential(self, y: FloatArray) -> float:
        """Potential of the constant loads [J]."""
        z1, z2, _, _, _ = self.split(y)
        return (self.b1.load_potential(z1) if self.n1 else 0.0) + (self.b2.load_potential(z2) if self.n2 else 0.0)

    # ------------------------------------------------------------------ dynamics

    def free_accelerations(self, y):
        z1, z2, z1d, z2d, _ = self.split(y)
        a1 = self.b1.M_inv @ (self.b1.f - self.b1.C @ z1d - self.b1.K @ z1) if self.n1 else np.zeros(0)
        a2 = self.b2.M_inv @ (self.b2.f - self.b2.C @ z2d - self.b2.K @ z2) if self.n2 else np.zeros(0)
        return a1, a2

    def rhs_law(self, memory):
        """Vector field with the continuous law active at the given memory."""
        law = self.contact.law

        def rhs(t, y):
            z1, z2, z1d, z2d, _ = self.split(y)
            alpha, alpha_dot = self.indentation(y)
            F = float(law.force(alpha, alpha_dot, memory)) if alpha > 0 else 0.0
            a1, a2 = self.free_accelerations(y)
            if self.n1:
                a1 = a1 - F * self.b1.M_inv_r
            if self.n2:
                a2 = a2 + F * self.b2.M_inv_r
            return np.concatenate([z1d, z2d, a1, a2, [F * alpha_dot]])

        return rhs

    def rhs_free(self, t, y):
        z1, z2, z1d, z2d, _ = self.split(y)
        a1, a2 = self.free_accelerations(y)
        return np.concatenate([z1d, z2d, a1, a2, [0.0]])

    def rigid_force(self, y, free=None) -> float:
        """Multiplier keeping ``alpha_dd = 0``: ``F = (r1 a1_free - r2 a2_free) / (m1' + m2')``.

        ``free``: ``free_accelerations(y)`` when the caller already has them.
        """
        a1, a2 = self.free_accelerations(y) if free is None else free
        num = (self.b1.r @ a1 if self.n1 else 0.0) - (self.b2.r @ a2 if self.n2 else 0.0)
        return float(num / (self.b1.mobility + self.b2.mobility))

    def rhs_rigid(self, t, y):
        z1, z2, z1d, z2d, _ = self.split(y)
        a1, a2 = free = self.free_accelerations(y)
        F = self.rigid_force(y, free)
        if self.n1:
            a1 = a1 - F * self.b1.M_inv_r
        if self.n2:
            a2 = a2 + F * self.b2.M_inv_r
        return np.concatenate([z1d, z2d, a1, a2, [0.0]])

    def impulse(self, y: FloatArray, e: float, hypothesis: str = "newton") -> tuple[FloatArray, float, float]:
        """Instantaneous impact; returns (y, P [N s], energy lost [J]).

        ``newton``: the normal separation speed is ``e`` times the approach speed,
        ``P = (1 + e) alpha_dot / (m1' + m2')``. ``poisson``: a compression impulse ``P_c`` that
        stops the approach, then a restitution impulse ``e P_c``. With one frictionless contact
        between linear bodies both give the same ``P`` (they differ with friction or several
        simultaneous contacts); both are kept to say which hypothesis a run used.
        """
        z1, z2, z1d, z2d, W = self.split(y)
        _, alpha_dot = self.indentation(y)
        mobility = self.b1.mobility + self.b2.mobility
        if hypothesis == "poisson":
            P_c = alpha_dot / mobility
            P = P_c + e * P_c
        else:
            P = (1.0 + e) * alpha_dot / mobility
        T0 = self.kinetic(y)
        z1d = z1d - P * self.b1.M_inv_r if self.n1 else z1d
        z2d = z2d + P * self.b2.M_inv_r if self.n2 else z2d
        y_new = self.join(z1, z2, z1d, z2d, W)
        return y_new, P, T0 - self.kinetic(y_new)

    def kinetic(self, y) -> float:
        z1, z2, z1d, z2d, _ = self.split(y)
        return sum(sum(b.kinetic(zd)) for b, zd in ((self.b1, z1d), (self.b2, z2d)) if b.n)

    def ledger(self, y, memory, impulse_loss: float, in_contact: bool) -> dict:
        """Energy ledger [J] at state ``y`` (keys are the recorded names)."""
        z1, z2, z1d, z2d, W = self.split(y)
        alpha, _ = self.indentation(y)
        k1 = self.b1.kinetic(z1d) if self.n1 else (0.0, 0.0)
        k2 = self.b2.kinetic(z2d) if self.n2 else (0.0, 0.0)
        elastic = 0.0
        if in_contact and self.contact.model == "law" and alpha > 0:
            elastic = float(self.contact.law.elastic_energy(alpha, memory))
        dissipated = W - elastic + impulse_loss
        strain = (self.b1.strain(z1) if self.n1 else 0.0) + (self.b2.strain(z2) if self.n2 else 0.0)
        loads = (self.b1.load_potential(z1) if self.n1 else 0.0) + (self.b2.load_potential(z2) if self.n2 else 0.0)
        total = sum(k1) + sum(k2) + strain + loads + elastic
        return {"impactor_kinetic": sum(k1), "bar_kinetic": sum(k2), "bar_strain": strain,
                "contact_elastic": elastic, "load_potential": loads, "dissipated": dissipated,
                "total": total, "total_plus_dissipated": total + dissipated}


def run_impact(problem: ImpactProblem, t_end: float, output_dt: float, controller: Controller,
               on_sample=None, step_fraction: float = STEP_FRACTION) -> ImpactRun:
    """Integrate ``problem`` to ``t_end``, sampling every ``output_dt`` and at every event.

    ``on_sample(sample)`` is called for each sample as it is produced (sinks, progress).
    ``step_fraction``: longest step during a law contact, as a fraction of its time scale
    (``inf`` removes the bound; for tests of the checks).
    """
    stepper = ImpactStepper(problem, output_dt, controller, on_sample, step_fraction)
    stepper.advance(t_end)
    return stepper.result()


class _Unresolved(Exception):
    """A check found a contact the integration did not resolve (the message is the diagnosis)."""

    def __init__(self, message: str, t: float, y: FloatArray):
        super().__init__(message)
        self.t, self.y = t, y


class ImpactStepper:
    """Resumable event-driven integration of an ``ImpactProblem`` (used headless and live).

    ``advance(t_stop)`` integrates from the current time to ``t_stop``, emitting samples on the
    ``output_dt`` grid and at every event; it can be called again to go further. A failed check
    (see the module docstring) stops it with ``status`` set to the diagnosis; the samples up to
    then are kept.
    """

    def __init__(self, problem: ImpactProblem, output_dt: float, controller: Controller, on_sample=None,
                 step_fraction: float = STEP_FRACTION):
        self.problem, self.output_dt, self.controller, self.on_sample = problem, output_dt, controller, on_sample
        self.method = ExplicitRK(DOPRI5)
        self.state = _PhaseState(problem, controller, step_fraction)
        self.t, self.y, self.h = 0.0, problem.initial_state(), None
        self.samples: list[Sample] = []
        self.events: list[tuple[float, str]] = []
        self.stats = [0, 0, 0]
        self.status = "ok"
        self._emit(0.0, self.y)
        self.next_out = output_dt
        self.y = self.state.start(self.t, self.y, self.events)

    @property
    def last_sample(self) -> Sample:
        return self.samples[-1]

    def _emit(self, t, y) -> None:
        sample = self.state.sample(t, y)
        self.samples.append(sample)
        if self.on_sample:
            self.on_sample(sample)

    def _on_step(self, t0, y0, f0, t1, y1, f1) -> None:
        while self.next_out <= t1 + 1e-15 * max(1.0, t1) and self.next_out <= self.t_stop:
            if self.next_out >= t0:
                t = self.next_out
                self._emit(t, hermite(t0, y0, f0, t1, y1, f1, t) if t < t1 else y1)
            self.next_out += self.output_dt
        self.state.after_step(t1, y1)

    def advance(self, t_stop: float) -> None:
        """Integrate to ``t_stop`` (no-op if already there or stopped)."""
        self.t_stop = t_stop
        state = self.state
        while self.t < t_stop and self.status == "ok":
            if len(self.events) > MAX_EVENTS:
                self.status = f"stopped at t = {self.t:.6g} s: more than {MAX_EVENTS} contact events (Zeno sequence?)"
                break
            bound = state.step_bound()
            controller = replace(self.controller, max_step=bound) if bound < self.controller.max_step else self.controller
            h = None if self.h is None else min(self.h, controller.max_step)
            try:
                out = integrate(state.rhs(), self.t, self.y, t_stop, self.method, controller, events=state.events(),
                                h=h, on_step=self._on_step, disarmed=(state.fired,) if state.fired else ())
            except _Unresolved as exc:
                self.status, self.t, self.y = str(exc), exc.t, exc.y
                break
            self.stats[0] += out.n_accepted
            self.stats[1] += out.n_rejected
            self.stats[2] += out.n_rhs
            self.t, self.y, self.h = out.t, out.y, out.h
            if out.event is None:
                break
            state.fired = out.event
            self.y = state.handle(out.event, self.t, self.y, self.events)
            self._emit(self.t, self.y)
            if state.diagnosis:
                self.status = state.diagnosis
        if self.samples[-1].t < self.t - 1e-12 * max(1.0, self.t):
            self._emit(self.t, self.y)  # the final state, when t_stop is not on the output grid

    def result(self) -> ImpactRun:
        s = self.state
        return ImpactRun(self.samples, self.events, *self.stats, self.status, s.contacts, s.contact_rigid, s.impulses)


@dataclass
class _Onset:
    """What a law contact started with, for its step bound and its checks.

    Attributes
    ----------
    index : int
        1-based number of the contact.
    t : float
        Onset time [s].
    speed : float
        Approach speed [m/s].
    memory : ContactMemory or None
        Law memory before the contact.
    total, load_potential, balance, dissipated : float
        Ledger total, load potential, balance error and dissipated energy at onset [J].
    time_scale : float
        ``contact_time_scale`` [s].
    n_steps : int
        Accepted steps taken in contact so far.
    """

    index: int
    t: float
    speed: float
    memory: object
    total: float
    load_potential: float
    balance: float
    dissipated: float
    time_scale: float
    n_steps: int = 0


#: Relative round-off of sums of energies, allowed on top of the ledger's balance error.
ENERGY_ROUNDOFF = 1e-12


class _PhaseState:
    """Which contact phase is active, the law memory, the impulse losses so far and the checks."""

    def __init__(self, problem: ImpactProblem, controller: Controller, step_fraction: float = STEP_FRACTION):
        self.p, self.controller, self.step_fraction = problem, controller, step_fraction
        self.in_contact = False
        self.memory = None
        self.impulse_loss = 0.0
        self.contacts: list[list[float]] = []
        self.contact_rigid: list[list[float]] = []
        self.impulses: list[tuple[float, float]] = []
        self.onset: _Onset | None = None
        self.diagnosis: str | None = None

    def start(self, t, y, events) -> FloatArray:
        """Bodies that start touching and approaching (or overlapping) start in contact."""
        self.fired = None
        alpha, alpha_dot = self.p.indentation(y)
        if alpha > 0 or (alpha == 0 and alpha_dot > 0):
            return self.handle("onset", t, y, events)
        return y

    def rhs(self):
        model = self.p.contact.model
        if model == "law":
            return self.p.rhs_law(self.memory) if self.in_contact else self.p.rhs_free
        if model == "rigid" and self.in_contact:
            return self.p.rhs_rigid
        return self.p.rhs_free

    def step_bound(self) -> float:
        """Longest step allowed now [s]: a fraction of the time scale of a law contact under way."""
        if self.in_contact and self.onset is not None:
            return self.step_fraction * self.onset.time_scale
        return np.inf

    def crater(self) -> float:
        """Indentation at which the surfaces touch: the residual (plastic) indentation left by the
        contacts so far (kept in the contact memory), 0 for elastic and rate laws [m]."""
        if self.memory is None or self.p.contact.model != "law" or not self.p.contact.law.dissipative:
            return 0.0
        return self.memory.alpha_residual

    def events(self) -> tuple[Event, ...]:
        p, model = self.p, self.p.contact.model
        if not self.in_contact:
            floor = self.crater()
            return (Event("onset", lambda t, y: p.indentation(y)[0] - floor, +1),)
        if model == "rigid":
            return (Event("separation", lambda t, y: p.rigid_force(y), -1),)
        law = p.contact.law
        floor = self.crater()
        evs = [Event("separation", lambda t, y: p.indentation(y)[0] - floor, -1)]
        if law.kind == "elastoplastic":  # the turning point sets alpha_max
            evs.append(Event("max_indentation", lambda t, y: p.indentation(y)[1], -1))
        return tuple(evs)

    def handle(self, name: str, t: float, y: FloatArray, events: list) -> FloatArray:
        p, model = self.p, self.p.contact.model
        alpha, alpha_dot = p.indentation(y)
        if name == "onset":
            events.append((t, f"contact start (approach speed {alpha_dot:.4g} m/s)"))
            self.contacts.append([t, alpha_dot, np.nan, np.nan])
            self.contact_rigid.append([p.rigid_relative_velocity(y), np.nan])
            if model == "restitution":
                y, P, loss = p.impulse(y, p.contact.restitution, p.contact.hypothesis)
                self._impulse(t, P, loss)
                self._end(t, y, -p.indentation(y)[1])
                events.append((t, f"impulse {P:.4g} N s, e = {p.contact.restitution:g}: contact end"))
                return y
            if model == "rigid":
                y, P, loss = p.impulse(y, 0.0)
                self._impulse(t, P, loss)
                # Complementarity: stay in contact unless holding alpha = 0 needs tension. F = 0 exactly
                # (an undeformed target) counts as compressive: the force grows from zero.
                self.in_contact = p.rigid_force(y) >= -RIGID_TENSION_TOL
                if not self.in_contact:
                    self._end(t, y, -p.indentation(y)[1])
                    events.append((t, "contact end (plastic impulse only: holding contact would need tension)"))
                return y
            self._law_onset(t, y, alpha_dot)
            return y
        if name == "max_indentation":
            self.memory = p.contact.law.update(self.memory, alpha, alpha_dot)
            events.append((t, f"maximum indentation {alpha:.4g} m"))
            return y
        if name == "separation":
            if model == "law":
                self.memory = p.contact.law.update(self.memory, max(alpha, 0.0), alpha_dot)
            self.in_contact = False
            self._end(t, y, -alpha_dot)
            events.append((t, f"contact end (separation speed {-alpha_dot:.4g} m/s)"))
            if model == "law":
                self.diagnosis = self._restitution_check(t, -alpha_dot)
            return y
        raise ValueError(name)

    def _impulse(self, t: float, P: float, loss: float) -> None:
        self.impulse_loss += loss
        self.impulses.append((t, P))

    def _end(self, t: float, y: FloatArray, separation_speed: float) -> None:
        self.contacts[-1][2:] = [t, separation_speed]
        self.contact_rigid[-1][1] = self.p.rigid_relative_velocity(y)

    def _law_onset(self, t: float, y: FloatArray, alpha_dot: float) -> None:
        """Start a law contact: memory, time scale (the step bound) and the energy it may use."""
        p, law = self.p, self.p.contact.law
        before = self.memory
        self.in_contact = True
        self.memory = law.onset(max(alpha_dot, 0.0), before)
        led = p.ledger(y, self.memory, self.impulse_loss, True)
        pressing = max(p.rigid_force(y), 0.0)  # what the loads and the bodies' strain press with
        t_c = contact_time_scale(law, p.effective_mass, max(alpha_dot, 0.0), before, pressing)
        self.onset = _Onset(len(self.contacts), t, alpha_dot, before, led["total"], p.load_potential(y),
                            led["total_plus_dissipated"] - p.initial_energy, led["dissipated"], t_c)

    def after_step(self, t: float, y: FloatArray) -> None:
        """Indentation check after an accepted step (law contacts); raises ``_Unresolved``.

        The recoverable energy of the indentation cannot exceed what the contact can have been
        given since its onset: the bodies' energy then (``total``, with the load potential) less
        the load potential now, plus what the numerics created since (the ledger's balance error
        and any negative dissipation). Inside a contact this holds by the ledger's construction;
        it fails when the bodies overlap without a contact force (a separation that was not one).
        """
        o = self.onset
        if o is None:
            return
        if self.in_contact:
            o.n_steps += 1
        p, law = self.p, self.p.contact.law
        alpha = p.indentation(y)[0]
        need = float(law.elastic_energy(alpha, self.memory)) if alpha > 0 else 0.0
        available = o.total - p.load_potential(y)
        if need <= available:
            return
        led = p.ledger(y, self.memory, self.impulse_loss, self.in_contact)
        created = (abs(led["total_plus_dissipated"] - p.initial_energy - o.balance)
                   + max(0.0, o.dissipated - led["dissipated"]))
        if need <= available + created + ENERGY_ROUNDOFF * abs(o.total):
            return
        detail = (f"{o.total - o.load_potential:.3g} J in the bodies at onset, work of the loads "
                  f"{o.load_potential - p.load_potential(y):.3g} J, created by the numerics {created:.3g} J")
        raise _Unresolved(indentation_diagnosis(o.index, t, alpha, law, available + created, self.memory, detail), t, y)

    def _restitution_check(self, t: float, separation: float) -> str | None:
        """Diagnosis if the restitution of the law contact just ended is outside what the law allows.

        Any bodies: not below 0 (a located separation has the surfaces receding). Rigid bodies:
        the law's free-impact value (the relative motion is then one degree of freedom), within
        what the loads and the integration can change.
        """
        o, p, law = self.onset, self.p, self.p.contact.law
        if o is None or o.speed <= 0.0:
            return None
        c = self.controller
        slack = integration_restitution_slack(o.n_steps, 2 * p.n + 1, c.rtol, c.atol, o.speed)
        low, high = -slack, np.inf
        if p.rigid_bodies:
            slack += load_restitution_slack(p.load_acceleration, t - o.t, o.speed)
            if slack < 1.0:  # else the loads decide more than the law (a ball coming to rest)
                e_law = free_impact_restitution(law, p.effective_mass, o.speed, o.memory)
                low, high = e_law - slack, e_law + slack
        return restitution_diagnosis(o.index, t, separation / o.speed, low, high, law, o.speed, separation)

    def sample(self, t, y) -> Sample:
        p = self.p
        z1, z2, z1d, z2d, _ = p.split(y)
        alpha, alpha_dot = p.indentation(y)
        F = 0.0
        if self.in_contact and p.contact.model == "law" and alpha > 0:
            F = float(p.contact.law.force(alpha, alpha_dot, self.memory))
        elif self.in_contact and p.contact.model == "rigid":
            F = p.rigid_force(y)
        return Sample(t, z1.copy(), z2.copy(), z1d.copy(), z2d.copy(), alpha, alpha_dot, F, self.in_contact,
                      p.ledger(y, self.memory, self.impulse_loss, self.in_contact))

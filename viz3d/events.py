"""Contacts in the one stepper: work integrals of the energy ledger, event functions of every
contact, what happens at each event, the step bound while a law contact lasts, and the checks that
each contact was resolved.

* **Ledger.** With contacts, the state carries work integrals ``w`` (``System.n_aux``): per contact
  the work the bodies did on its law, ``int F alpha_dot dt``; the energy dissipated by the damping of
  flexible bodies; the work of non-conservative force elements. Then ``dissipated = sum (W_i - U_i)
  + impulse losses + damping`` and the balance error ``E(t) + dissipated - W_in - E(0)`` measures
  what the numerics created or destroyed (``ledger``).
* **Events** (``ContactStepping.events``): onset (``alpha - crater`` rising through 0), separation
  (falling through 0; for kinematic contacts the multiplier falling through 0, i.e. tension),
  maximum indentation (``alpha_dot`` falling through 0, elastoplastic laws). The stepper locates
  them on the step's cubic Hermite interpolant (``brentq``), those on ``alpha`` also where it
  crosses and comes back inside one step (its rate ``alpha_dot`` is ``Event.rate``: a ball's whole
  flight in one step; ``viz3d.integrators.adaptive.hermite_extrema``), and redoes the step to the event
  (``viz3d.simulate``); the compiled adaptive driver does the same in the kernel
  (``viz3d.kernel.adaptive``, the event functions as data: ``event_rows``).
* **Handlers** (``ContactStepping.handle``): law onset (memory, time scale of the contact), plastic
  impulse of a kinematic contact and its activation while compressive, restitution impulses
  (Newton or Poisson) with the generalized impulse-momentum balance: the impulse that gives the
  contact its target normal velocity while every joint keeps its velocity constraint.
* **Who steps**: runs with the compiled driver (``viz3d.kernel.adaptive``: adaptive steps, or fixed
  ones as ``FixedSteps``): in flight and while kinematic or law contacts touch, the driver (it checks
  the signs of the event functions); during law contacts its steps are bounded by ``step_bound`` and
  recorded, with the stick anchors of bristle friction it moves after each step (``_replant``'s rule,
  compiled: ``viz3d.contact.contacts._replant``), and ``after_steps`` keeps the books and checks on
  the records after the call. The driver also locates each event and cuts its step there; handling
  the event (``handle``: memory, impulses) and the step after it (its events start at a root) are Python's.
* **Checks** (``ContactStepping.after_step``, at separation): while a law contact lasts, the
  numerics create no more energy than the error estimates of its steps allow (and its indentation
  stores no more than the energy available since onset); a law contact separates with the surfaces
  receding, and between rigid bodies with the restitution its law allows, within what the loads
  and the error estimates of its normal velocity can change (``viz3d.contact.resolution``).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from viz3d._typing import FloatArray
from viz3d.constraints import apply_jacobian, apply_jacobian_transpose, constraint_rows, schur_solve
from viz3d.contact.contacts import ContactPhase, ContactRows, Gap, Onset
from viz3d.contact.resolution import (
    STEP_FRACTION,
    contact_time_scale,
    free_impact_restitution,
    energy_diagnosis,
    indentation_diagnosis,
    integration_restitution_slack,
    load_restitution_slack,
    restitution_diagnosis,
)
from viz3d.diagnosis import SimulationFailure
from viz3d.dynamics import (accelerations, body_state, flat_velocity, flexible_kinetics, split_velocity,
                            system_mass)
from viz3d.forces import AppliedForce, Gravity
from viz3d.integrators.adaptive import Event
from viz3d.kinematics import Pose
from viz3d.system import State, System

#: A kinematic contact needing less tension than this [N] (round-off) is kept at onset.
RIGID_TENSION_TOL = 1e-9
#: Relative round-off of sums of energies, allowed on top of the ledger's balance error.
ENERGY_ROUNDOFF = 1e-12


# ---------------------------------------------------------------------------- the ledger


@dataclass(frozen=True)
class Ledger:
    """The energies of a state [J].

    Attributes
    ----------
    kinetic : float
        Of every body (flexible ones: frame and deformation).
    potential : float
        Of the conservative force elements (gravity, springs, constant loads).
    strain : float
        Elastic energy of the flexible bodies.
    contact_elastic : float
        Recoverable energy stored in the contacts.
    signed_potential : float
        The part of ``potential`` that may be negative (gravity, loads).
    dissipated : float
        Taken by contact laws (work minus what they store), impulses and damping since t = 0.
    work_in : float
        Done on the bodies by non-conservative force elements since t = 0.
    """

    kinetic: float
    potential: float
    strain: float
    contact_elastic: float
    signed_potential: float
    dissipated: float
    work_in: float

    @property
    def total(self) -> float:
        """Mechanical energy ``kinetic + potential + strain + contact_elastic``."""
        return self.kinetic + self.potential + self.strain + self.contact_elastic


def ledger(system: System, state: State, cfg=None, gaps: tuple = ()) -> Ledger:
    """The energy ledger of ``state`` (see ``Ledger``); ``cfg`` and ``gaps`` (its configuration and
    each contact set's ``gap(cfg)``) if the caller has them."""
    from viz3d.dynamics import energy_terms

    cfg = body_state(system, state.q, state.v, state.chart, state.t) if cfg is None else cfg
    gaps = gaps or tuple(c.gap(cfg) for c in system.contacts)
    e = energy_terms(system, state, cfg, gaps)
    signed = sum(V for f, V in zip(system.forces, e.potentials) if isinstance(f, (Gravity, AppliedForce)))
    U = np.concatenate(e.contact_elastic) if e.contact_elastic else np.zeros(0)
    return ledger_of(e.kinetic, float(sum(e.potentials)), float(signed), float(sum(e.strain)), U,
                     work_integrals(system, state), impulse_loss(system, state))


def ledger_of(kinetic, potential, signed, strain, U, w, losses) -> Ledger:
    """The ledger from its terms, of one state or of n (arrays over instants on the leading axis):
    ``U`` (..., k) every contact's stored energy, ``w`` (..., k + 2) the work integrals (the contact
    laws' work, then the energy taken by dampers and the work in, ``System.n_aux``), ``losses`` (...)
    the kinetic energy taken by impulses [J]."""
    k = U.shape[-1]
    dissipated = (w[..., :k] - U).sum(axis=-1) + losses + w[..., -2]
    return Ledger(kinetic, potential, strain, U.sum(axis=-1), signed, dissipated, w[..., -1])


def work_integrals(system: System, state: State) -> FloatArray:
    """``state.w`` (n_aux,) [J], zeros before the run has started them."""
    return state.w if state.w.size else np.zeros(sum(c.k for c in system.contacts) + 2)


def impulse_loss(system: System, state: State) -> float:
    """Kinetic energy taken by every contact's impulses so far [J]."""
    return memory_loss(state.memory or tuple(c.initial_phases() for c in system.contacts))


def memory_loss(memory: tuple) -> float:
    """Kinetic energy taken by the impulses recorded in the contacts' ``memory`` [J]."""
    return float(sum(p.impulse_loss for phases in memory for p in phases))


# ---------------------------------------------------------------------------- contact records


@dataclass
class ContactRecord:
    """One touch of one contact, as the stepper saw it (output, not state).

    Attributes
    ----------
    contact : str
        Name of the contact.
    t_start, approach, t_end, separation : float
        Onset time [s], approach speed [m/s], end time [s] and separation speed [m/s] of the contact
        points (nan while it lasts).
    rigid_start, rigid_end : float
        Relative normal velocity of the two bodies' centres of mass (momentum-based, so elastic
        vibration does not count) at onset and end [m/s].
    """

    contact: str
    t_start: float
    approach: float
    t_end: float = np.nan
    separation: float = np.nan
    rigid_start: float = np.nan
    rigid_end: float = np.nan


# ---------------------------------------------------------------------------- the stepping


@dataclass(frozen=True)
class EventRow:
    """One contact event function as data: ``kind`` "gap" (``alpha - floor`` of contact ``index``,
    over all sets), "gap_rate" (its ``alpha_dot``) or "multiplier" (of constraint row ``index``)
    [m, m/s or N]; ``direction`` as ``Event.direction``."""

    name: str
    kind: str
    index: int
    floor: float
    direction: int


class ContactStepping:
    """Events, handlers, step bound and checks of a system's contacts (one per run).

    Parameters
    ----------
    system : System
    formulation
        The run's formulation (multipliers of kinematic contacts come from it).
    step_fraction : float
        Longest step during a law contact, as a fraction of its time scale (``inf`` removes the
        bound; for tests of the checks).
    kernel : viz3d.kernel.KernelStepper, optional
        Evaluates the event functions (indentations, their rates, multipliers) compiled; the NumPy
        path without it.

    Attributes
    ----------
    log : list of (float, str)
        Events with their time, in order.
    records : list of ContactRecord
    impulses : list of (float, str, float)
        Time, contact and impulse [N s] of every impulse.
    """

    def __init__(self, system: System, formulation, step_fraction: float = STEP_FRACTION, kernel=None):
        self.system, self.formulation, self.kernel = system, formulation, kernel
        self.step_fraction = step_fraction
        self._k0 = np.cumsum([0] + [c.k for c in system.contacts])
        self._probed: tuple | None = None
        self.log: list[tuple[float, str]] = []
        self.records: list[ContactRecord] = []
        self.impulses: list[tuple[float, str, float]] = []
        self._open: dict[tuple[int, int], ContactRecord] = {}
        self.E0: float | None = None

    # ------------------------------------------------------------------ state plumbing

    def with_phase(self, state: State, k: int, i: int, phase: ContactPhase) -> State:
        memory = list(state.memory)
        phases = list(memory[k])
        phases[i] = phase
        memory[k] = tuple(phases)
        return state.replace(memory=tuple(memory))

    def ledger(self, state: State) -> Ledger:
        """The energy ledger of ``state`` (``ledger``), its configuration and gaps from the compiled
        kernel when the run has one."""
        if self.kernel is None:
            return ledger(self.system, state)
        return ledger(self.system, state, *self.kernel.configuration(state.t, state.y, state.chart))

    def state_at(self, t: float, y: FloatArray, like: State) -> State:
        """The state with ``y = [q, v, w]`` at ``t``, in ``like``'s chart, contact phases and force
        elements' memory."""
        s = self.system
        n_q, n_v = s.n_q, s.n_v
        return State(t, y[:n_q], y[n_q:n_q + n_v], like.chart, y[n_q + n_v:], like.memory, like.element_memory)

    def _gap(self, state: State, k: int):
        return self.system.contacts[k].gap(body_state(self.system, state.q, state.v, state.chart, state.t))

    def _crater(self, state: State, k: int, i: int) -> float:
        c, phase = self.system.contacts[k], state.memory[k][i]
        if c.models[i] != "law" or phase.memory is None or not c.laws[i].dissipative:
            return 0.0
        return float(phase.memory.alpha_residual)

    # ------------------------------------------------------------------ events

    def events(self, state: State) -> tuple[Event, ...]:
        """The event functions of every located contact in its current phase (functions of ``(t, y)``)."""
        out = []
        for k, c in enumerate(self.system.contacts):
            if not c.located:
                continue
            for i in range(c.k):
                out += self._contact_events(state, k, i)
        return tuple(out)

    def _contact_events(self, state: State, k: int, i: int) -> list[Event]:
        out = []
        for row in self._event_rows(state, k, i):
            if row.kind == "multiplier":
                out.append(Event(row.name, lambda t, y, k=k, i=i: self._probe(t, y, state, k, i), row.direction))
            else:
                column = 0 if row.kind == "gap" else 1
                rate = (lambda t, y, r=row: self._probe(t, y, state)[r.index, 1]) if row.kind == "gap" else None
                out.append(Event(row.name, lambda t, y, r=row, c=column: self._probe(t, y, state)[r.index, c] - r.floor,
                                 row.direction, rate))
        return out

    def event_rows(self, state: State) -> tuple["EventRow", ...]:
        """What ``events`` evaluates, as data (the compiled adaptive driver checks their signs)."""
        return tuple(row for k, c in enumerate(self.system.contacts) if c.located
                     for i in range(c.k) for row in self._event_rows(state, k, i))

    def _event_rows(self, state: State, k: int, i: int) -> list["EventRow"]:
        c, phase = self.system.contacts[k], state.memory[k][i]
        at = int(self._k0[k] + i)
        if not phase.touching:
            return [EventRow(f"onset:{k}:{i}", "gap", at, self._crater(state, k, i), +1)]
        if c.models[i] == "rigid":
            return [EventRow(f"separation:{k}:{i}", "multiplier", _row_index(self.system, k, i), 0.0, -1)]
        out = [EventRow(f"separation:{k}:{i}", "gap", at, self._crater(state, k, i), -1)]
        if c.laws[i].kind == "elastoplastic":
            out.append(EventRow(f"max_indentation:{k}:{i}", "gap_rate", at, 0.0, -1))
        return out

    def law_contact_under_way(self, state: State) -> bool:
        """True while a law contact touches (``after_step`` and ``step_bound`` may act then)."""
        return any(phase.touching and c.models[i] == "law"
                   for k, c in enumerate(self.system.contacts) for i, phase in enumerate(state.memory[k]))

    @functools.cached_property
    def replants(self) -> bool:
        """True when a located law contact has stateful friction (bristles: its stick anchor moves
        after each step, ``_replant``)."""
        return any(c.located and m == "law" and f is not None and f.stateful
                   for c in self.system.contacts for m, f in zip(c.models, c.friction))

    @staticmethod
    def anchors_moved(before: State, after: State) -> bool:
        """True when a stick anchor of ``after``'s contact memory is not ``before``'s (``_replant``
        moved it: the vector field is another)."""
        return any(p.anchor is not q.anchor for a, b in zip(before.memory, after.memory) for p, q in zip(a, b))

    def _probe(self, t: float, y: FloatArray, like: State, k: int = -1, i: int = -1):
        """Event-function values at ``(t, y)`` (``like``'s chart and phases): ``_gap_values``, or with
        ``(k, i)`` the multiplier of that kinematic contact. Compiled when the run has a kernel; the
        last result is reused for the same ``(t, y)`` (the events of one step are evaluated at the
        same points)."""
        key = (t, y.tobytes(), k, i, id(like.memory))
        if self._probed is not None and self._probed[0] == key:
            return self._probed[1]
        if k < 0:
            value = self._gap_values(t, y, like.chart)
        elif self.kernel is not None:
            value = float(self.kernel.multipliers(t, y, like.chart, like.memory)[_row_index(self.system, k, i)])
        else:
            value = self.multiplier(self.state_at(t, y, like), k, i)
        self._probed = (key, value)
        return value

    def step_bound(self, state: State) -> float:
        """Longest step allowed now [s]: a fraction of the time scale of every law contact under way."""
        bound = np.inf
        for k, c in enumerate(self.system.contacts):
            for i, phase in enumerate(state.memory[k] if state.memory else ()):
                if phase.touching and c.models[i] == "law" and phase.onset is not None:
                    bound = min(bound, self.step_fraction * phase.onset.time_scale)
        return bound

    # ------------------------------------------------------------------ contact mechanics

    def _contact_row(self, state: State, k: int, i: int):
        cfg = body_state(self.system, state.q, state.v, state.chart, state.t)
        alpha, J, Je, gamma = self.system.contacts[k].rows(cfg)
        return cfg, J[i], Je[i], gamma[i]

    def response(self, state: State, k: int, i: int) -> tuple[FloatArray, float]:
        """Velocity change per unit impulse at contact ``(k, i)`` with every active row held
        (``u``, shape (n_v,)) and the contact's constrained mobility ``J_alpha u`` [1/kg]."""
        s = self.system
        cfg, J, Je, _ = self._contact_row(state, k, i)
        mass = system_mass(s, cfg)
        rows_i = _single_row(s, k, i)
        Fu, Fu_e = apply_jacobian_transpose(rows_i, J[None], np.ones(1), s.n_bodies + 1, Je[None])
        u, u_e = mass.solve(Fu, Fu_e)
        rows = constraint_rows(s.joints, cfg, state.memory)
        if s.n_c:
            mu = schur_solve(s.joints, mass, rows.J, apply_jacobian(s.joints, rows.J, u, rows.Je, u_e), Je=rows.Je,
                             inactive=rows.inactive)
            CtL, CtL_e = apply_jacobian_transpose(s.joints, rows.J, mu, s.n_bodies + 1, rows.Je)
            d, d_e = mass.solve(CtL, CtL_e)
            u, u_e = u - d, u_e - d_e
        mobility = float(apply_jacobian(rows_i, J[None], u, Je[None], u_e)[0])
        return flat_velocity(s, u, u_e), mobility

    def multiplier(self, state: State, k: int, i: int) -> float:
        """Multiplier of kinematic contact ``(k, i)`` (its row active in ``state``) [N]; >= 0 compressive."""
        acc = accelerations(self.system, self.formulation, state.t, state.q, state.v, state.chart, state.memory,
                            elements=state.element_memory)
        return float(acc.lam[_row_index(self.system, k, i)])

    def pressing_force(self, state: State, k: int, i: int) -> float:
        """Multiplier that would keep ``alpha_dd = 0`` at contact ``(k, i)`` given everything else [N]
        (what the loads press the surfaces together with, if > 0)."""
        acc = accelerations(self.system, self.formulation, state.t, state.q, state.v, state.chart, state.memory,
                            elements=state.element_memory)
        cfg, J, Je, gamma = self._contact_row(state, k, i)
        frame, elastic = split_velocity(self.system, acc.v_dot)
        alpha_dd = float(apply_jacobian(_single_row(self.system, k, i), J[None], frame, Je[None], elastic)[0]) - gamma
        _, mobility = self.response(state, k, i)
        return alpha_dd / mobility

    def impulse(self, state: State, k: int, i: int, e: float, hypothesis: str = "newton") -> tuple[State, float, float]:
        """Impact at contact ``(k, i)``: returns the state after it, the impulse [N s] and the kinetic
        energy lost [J].

        Newton: the normal separation speed is ``e`` times the approach speed, ``P = (1 + e)
        alpha_dot / mobility``; Poisson: a compression impulse ``P_c = alpha_dot / mobility`` that
        stops the approach, then a restitution impulse ``e P_c``. With one frictionless contact both
        give the same ``P``; both are kept to say which hypothesis a run used.
        """
        gp = self._gap(state, k)
        u, mobility = self.response(state, k, i)
        approach = float(gp.alpha_dot[i])
        P_c = approach / mobility
        P = (1.0 + e) * P_c if hypothesis == "poisson" else (1.0 + e) * approach / mobility
        T0 = self.ledger(state).kinetic
        new = state.replace(v=state.v - P * u)
        return new, P, T0 - self.ledger(new).kinetic

    def effective_mass(self, state: State, k: int, i: int) -> float:
        """``1 / (J_alpha u)`` [kg]: the inverse of the contact's constrained mobility (``response``); inf
        when the joints hold the bodies along its normal. The mobility is a quadratic form, >= 0; held,
        it is zero up to the round-off of ``J M^-1 J^T`` less its projection, of either sign (a random
        tree: -6e-14 1/kg, an effective mass of -1.7e13 kg)."""
        mobility = self.response(state, k, i)[1]
        return 1.0 / mobility if mobility > 0.0 else np.inf

    def rigid_velocity(self, state: State, k: int, i: int | None = None) -> FloatArray | float:
        """Relative normal velocity of each contact's bodies' rigid motion at the contact point (k,)
        [m/s], positive approaching, or of contact ``i`` alone (a float): of each body, the rigid
        motion with its momentum (linear and angular, about its centre of mass), so elastic vibration
        does not count; a flexible body on a fixed frame has none."""
        cfg = body_state(self.system, state.q, state.v, state.chart, state.t)
        c = self.system.contacts[k]
        gp = c.gap(cfg)
        out = np.empty(c.k)
        for j in range(c.k) if i is None else (i,):
            va = rigid_point_velocity(self.system, cfg, int(c.body[j, 0]), gp.point[j])
            vb = rigid_point_velocity(self.system, cfg, int(c.body[j, 1]), gp.point[j])
            out[j] = -float(gp.n[j] @ (va - vb))
        return out if i is None else float(out[i])

    # ------------------------------------------------------------------ handlers

    def start(self, state: State) -> State:
        """Contacts touching and approaching (or overlapping) at the start begin at once. The ledger's
        initial total ``E0`` is the energy before them plus what contacts overlapping at the start
        store (``_book_stored_energy``: the work integrals they start with)."""
        E0, w0 = self.ledger(state).total, state.w.copy()
        self.E0 = None  # the start's onsets balance by definition
        for k, c in enumerate(self.system.contacts):
            if not c.located:
                continue
            gp = self._gap(state, k)
            for i in range(c.k):
                if gp.alpha[i] > 0.0 or (gp.alpha[i] == 0.0 and gp.alpha_dot[i] > 0.0):
                    state = self.handle(f"onset:{k}:{i}", state)
        self.E0 = E0 + (float(np.sum(state.w - w0)) if w0.size else 0.0)
        return state

    def handle(self, name: str, state: State) -> State:
        """The state after event ``name`` at ``state.t`` (velocities, contact phases); logs it."""
        kind, k, i = name.split(":")
        k, i = int(k), int(i)
        return getattr(self, f"_{kind}")(state, k, i)

    def _onset(self, state: State, k: int, i: int) -> State:
        c = self.system.contacts[k]
        gp = self._gap(state, k)
        approach = float(gp.alpha_dot[i])
        self.log.append((state.t, f"{c.names[i]}: contact start (approach speed {approach:.4g} m/s)"))
        record = ContactRecord(c.names[i], state.t, approach, rigid_start=self.rigid_velocity(state, k, i))
        self.records.append(record)
        self._open[(k, i)] = record
        phase = state.memory[k][i]
        phase = dataclasses.replace(phase, touches=phase.touches + 1)
        model = c.models[i]
        if model == "restitution":
            state, P, loss = self.impulse(state, k, i, float(c.restitution[i]), c.hypotheses[i])
            state = self.with_phase(state, k, i, dataclasses.replace(phase, impulse_loss=phase.impulse_loss + loss))
            self.impulses.append((state.t, c.names[i], P))
            self.log.append((state.t, f"{c.names[i]}: impulse {P:.4g} N s, e = {c.restitution[i]:g}: contact end"))
            return self._close(state, k, i)
        if model == "rigid":
            state, P, loss = self.impulse(state, k, i, 0.0)
            self.impulses.append((state.t, c.names[i], P))
            phase = dataclasses.replace(phase, impulse_loss=phase.impulse_loss + loss, touching=True)
            state = self.with_phase(state, k, i, phase)
            # Complementarity: stay in contact unless holding alpha = 0 needs tension. lam = 0
            # exactly (an undeformed target) counts as compressive: the force grows from zero.
            if self.multiplier(state, k, i) >= -RIGID_TENSION_TOL:
                return state
            state = self.with_phase(state, k, i, dataclasses.replace(phase, touching=False))
            self.log.append((state.t, f"{c.names[i]}: contact end (plastic impulse only: holding contact would need tension)"))
            return self._close(state, k, i)
        return self._law_onset(state, k, i, phase, approach)

    def _law_onset(self, state: State, k: int, i: int, phase: ContactPhase, approach: float) -> State:
        """Start a law contact: memory, time scale (the step bound) and the energy it may use."""
        c = self.system.contacts[k]
        law, before = c.laws[i], phase.memory
        memory = law.onset(max(approach, 0.0), before)
        pressing = max(self.pressing_force(state, k, i), 0.0)
        t_c = contact_time_scale(law, self.effective_mass(state, k, i), max(approach, 0.0), before, pressing)
        anchor = None
        if c.friction[i] is not None and c.friction[i].stateful:  # bristles planted where the contact starts
            cfg = body_state(self.system, state.q, state.v, state.chart, state.t)
            gp = c.gap(cfg)
            anchor = c.anchor_at(cfg, gp, i, np.zeros(3))
        phase = dataclasses.replace(phase, anchor=anchor)
        touching = self.with_phase(state, k, i, dataclasses.replace(phase, touching=True, memory=memory))
        touching = self._book_stored_energy(touching, k, i)
        led = self.ledger(touching)
        balance = self.balance(led)
        onset = Onset(phase.touches, state.t, approach, before, led.total, led.signed_potential,
                      balance, led.dissipated, t_c, led.work_in, balance_now=balance)
        return self.with_phase(touching, k, i, dataclasses.replace(phase, touching=True, memory=memory, onset=onset))

    def _book_stored_energy(self, state: State, k: int, i: int) -> State:
        """Add the energy contact ``i`` of set ``k`` stores at its onset to its work integral: zero for a
        touch that starts at ``alpha = 0``; for a contact that starts overlapping (a body resting at its
        static indentation at t = 0) the work done on it before the run, so the ledger closes."""
        c = self.system.contacts[k]
        U = float(c.elastic_energy(body_state(self.system, state.q, state.v, state.chart, state.t), state.memory[k])[i])
        if U == 0.0 or not state.w.size:
            return state
        w = state.w.copy()
        w[sum(cs.k for cs in self.system.contacts[:k]) + i] += U
        return state.replace(w=w)

    def _max_indentation(self, state: State, k: int, i: int) -> State:
        c, phase = self.system.contacts[k], state.memory[k][i]
        gp = self._gap(state, k)
        memory = c.laws[i].update(phase.memory, float(gp.alpha[i]), float(gp.alpha_dot[i]))
        self.log.append((state.t, f"{c.names[i]}: maximum indentation {gp.alpha[i]:.4g} m"))
        return self.with_phase(state, k, i, dataclasses.replace(phase, memory=memory))

    def _separation(self, state: State, k: int, i: int) -> State:
        c, phase = self.system.contacts[k], state.memory[k][i]
        gp = self._gap(state, k)
        separation = -float(gp.alpha_dot[i])
        if c.models[i] == "law":
            phase = dataclasses.replace(phase, memory=c.laws[i].update(phase.memory, max(float(gp.alpha[i]), 0.0),
                                                                        float(gp.alpha_dot[i])))
        state = self.with_phase(state, k, i, dataclasses.replace(phase, touching=False, anchor=None))
        self.log.append((state.t, f"{c.names[i]}: contact end (separation speed {separation:.4g} m/s)"))
        state = self._close(state, k, i)
        if c.models[i] == "law":
            diagnosis = self._restitution_check(state, k, i, separation)
            if diagnosis:
                raise SimulationFailure(diagnosis)
        return state

    def _close(self, state: State, k: int, i: int) -> State:
        record = self._open.pop((k, i), None)
        if record is not None:
            record.t_end = state.t
            record.separation = -float(self._gap(state, k).alpha_dot[i])
            record.rigid_end = self.rigid_velocity(state, k, i)
        return state

    # ------------------------------------------------------------------ checks

    def balance(self, led: Ledger) -> float:
        return led.total + led.dissipated - led.work_in - (self.E0 if self.E0 is not None else led.total)

    def after_step(self, state: State, error: FloatArray | None = None, replanted: bool = False) -> State:
        """Count the step of every law contact under way, add the step's error estimate of its
        normal velocity, and check its indentation; raises ``SimulationFailure`` with the diagnosis.

        ``error`` is the step's embedded error estimate of ``y = [q, v, w]`` (None for fixed steps).
        The recoverable energy of the indentation cannot exceed what the contact can have been given
        since onset: the system's energy then, less the potential energies that may be negative now
        (gravity, loads; every other stored energy is >= 0), plus the work of the non-conservative
        loads since, plus what the numerics may have created since (``Onset.energy_error``: what
        the error estimates allow, so a run that creates more energy than its tolerance admits
        stops; and any dissipation that went backwards). ``replanted``: the stick anchors of
        ``state`` are after the step's ``_replant`` already (the compiled driver moved them).
        """
        under_way = self._under_way(state)
        if not under_way:
            return state
        if not replanted:
            state = self._replant(state, under_way)
        led = self.ledger(state)
        balance = self.balance(led)
        low = None if error is None else self.balance(self.ledger(self.state_at(state.t, state.y - error, state)))
        dvs = None if error is None else self._normal_velocity_errors(state, error)
        return self._book_step(state, under_way, led, balance, low, dvs)

    def after_steps(self, like: State, ts: FloatArray, Y: FloatArray, charts: FloatArray,
                    errors: FloatArray | None, mems: FloatArray) -> tuple[Sequence[tuple], int | None]:
        """``after_step`` on N steps in order, ending at ``(ts[r], Y[r], charts[r])`` (N,), (N, n_y),
        (N, nf, 3, 3) with error estimates ``errors`` (N, n_y; None for fixed steps) and the contacts'
        memory rows ``mems`` (N, n_contacts, 7) after each (the stick anchors the compiled driver moved
        there), from ``like``'s
        memory on: the contacts' memory after each step (of those before the first that fails), and
        the index of the first step whose check fails (None when none does). With the kernel (the
        memory then changes only in the onsets' books and the recorded anchors between events), the
        ledgers of all steps come from two kernel samples and the books and checks of all steps from
        array sums (``_StepBooks``; a step's memory is built when asked for)."""
        under_way = self._under_way(like)
        if not under_way or self.kernel is None or ts.shape[0] == 0:
            return self._steps_one_by_one(like, ts, Y, charts, errors, mems)
        anchored = mems if self.replants else None  # (bristles: their stick anchors after each step)
        try:
            led = self.ledgers(ts, Y, charts, like.memory, anchored)
            low = None if errors is None else self.balance(self.ledgers(ts, Y - errors, charts, like.memory, anchored))
        except np.linalg.LinAlgError:
            return self._steps_one_by_one(like, ts, Y, charts, errors, mems)
        balance = self.balance(led)
        dvs = None if errors is None else np.array([self._normal_velocity_errors(
            self.state_at(float(ts[r]), Y[r], like.replace(chart=charts[r])), errors[r]) for r in range(ts.shape[0])])
        books = _StepBooks(like.memory, under_way, self._k0, balance, low, dvs, anchored)
        r = self._first_failed_check(books, under_way, led, balance)
        if r is None:
            return books, None
        memory = books[r - 1] if r else like.memory
        memory = memory if anchored is None else with_anchors(memory, anchored[r], self._k0)
        state = self.state_at(float(ts[r]), Y[r], like.replace(chart=charts[r], memory=memory))
        led_r = Ledger(*(float(getattr(led, f.name)[r]) for f in dataclasses.fields(Ledger)))
        try:  # (the per-step books raise the diagnosis of the step that fails, as after_step would)
            self._book_step(state, under_way, led_r, float(balance[r]), None if low is None else float(low[r]),
                            None if dvs is None else dvs[r])
        except SimulationFailure:
            return books.before(r), r
        raise AssertionError(f"the energy check of step {r} passed one by one, failed over the steps")

    def _first_failed_check(self, books: "_StepBooks", under_way: list, led: Ledger, balance: FloatArray) -> int | None:
        """The first step of ``books`` whose energy check (``_energy_exceeded``) fails for any law
        contact under way, None when none does."""
        first = None
        for j in range(len(under_way)):
            bad = np.flatnonzero(_energy_exceeded(books.onset0[j], led, balance, books.energy_error[j]))
            if bad.size and (first is None or bad[0] < first):
                first = int(bad[0])
        return first

    def _steps_one_by_one(self, like: State, ts, Y, charts, errors, mems) -> tuple[list[tuple], int | None]:
        """``after_steps`` one ``after_step`` call at a time (the stick anchors from ``mems``)."""
        memories, state = [], like
        for r in range(ts.shape[0]):
            state = self.state_at(float(ts[r]), Y[r], state.replace(chart=charts[r]))
            state = state.replace(memory=with_anchors(state.memory, mems[r], self._k0))
            try:
                state = self.after_step(state, None if errors is None else errors[r], replanted=True)
            except SimulationFailure:
                return memories, r
            memories.append(state.memory)
        return memories, None

    def ledgers(self, ts: FloatArray, Y: FloatArray, charts: FloatArray, memory: tuple,
                mems: FloatArray | None = None) -> Ledger:
        """The ledgers of N states sharing the contacts' ``memory`` (fields (N,)), but for the stick
        anchors of memory rows ``mems`` (N, n_contacts, 7) when given, from one kernel sample
        (``KernelStepper.sample``: rigid kinetic and force elements' potential energies, gaps, poses)
        and the flexible bodies' energies over all states at once."""
        s, data = self.system, self.kernel.data
        smp = self.kernel.sample(ts, Y, charts, memory)
        T, strain = smp.T.copy(), np.zeros(ts.shape[0])
        for k, fb in enumerate(s.bodies.flexible):
            sl = data.elastic_slices[k]
            T += flexible_kinetics(fb, smp, sl)
            strain += 0.5 * np.einsum("ni,ij,nj->n", smp.eta[:, sl], fb.bar.K, smp.eta[:, sl])
        U = np.zeros((ts.shape[0], data.n_contacts))
        rs = np.flatnonzero((smp.gap[:, :, 0] > 0.0).any(axis=1) | any(p.touching for ph in memory for p in ph))
        if rs.size:
            pose = Pose(smp.r[rs], smp.R[rs])
            for c, x, phases in zip(s.contacts, data.contact_slices, memory):
                g = smp.gap[rs, x]
                anchors = None if mems is None else anchor_rows(c.anchor_table(phases), mems[rs, x])
                U[rs, x] = c.elastic_energy(None, phases, Gap(g[..., 0], g[..., 1], g[..., 2:5], g[..., 5:8], g[..., 8:11]),
                                            pose, anchors)
        W = Y[:, s.n_q + s.n_v:] if Y.shape[1] > s.n_q + s.n_v else np.zeros((ts.shape[0], U.shape[1] + 2))
        losses = np.full(ts.shape[0], memory_loss(memory))
        return ledger_of(T, smp.V[:, 0] + smp.V[:, 1], smp.V[:, 0], strain, U, W, losses)

    def _under_way(self, state: State) -> list[tuple[int, int]]:
        """The law contacts under way at ``state``: (set, contact) pairs."""
        return [(k, i) for k, c in enumerate(self.system.contacts) if c.located
                for i, phase in enumerate(state.memory[k])
                if phase.touching and c.models[i] == "law" and phase.onset is not None]

    def _book_step(self, state: State, under_way: list, led: Ledger, balance: float, low: float | None,
                   dvs: FloatArray | None) -> State:
        """``after_step``'s books and checks of the law contacts ``under_way`` after a step ending at
        ``state``: its ledger ``led`` and balance, the balance ``low`` at ``y - error`` and the normal
        velocity errors ``dvs`` (None for fixed steps)."""
        for k, i in under_way:
            o = state.memory[k][i].onset
            dv = 0.0 if dvs is None else float(dvs[self._k0[k] + i])
            dE = abs(balance - (o.balance_now if low is None else low))
            state = self.with_phase(state, k, i, dataclasses.replace(state.memory[k][i], onset=dataclasses.replace(
                o, n_steps=o.n_steps + 1, velocity_error=o.velocity_error + dv, energy_error=o.energy_error + dE,
                balance_now=balance)))
            self._energy_check(state, k, i, led, balance)
        return state

    def _replant(self, state: State, under_way: list) -> State:
        """Move the stick anchors whose bristles carry more than ``mu_s F_n`` after the step
        (``viz3d.contact.friction.Bristle.anchor_update``, seed 004 eq. 3.49)."""
        stateful = [(k, i) for k, i in under_way if (law := self.system.contacts[k].friction[i]) is not None and law.stateful]
        if not stateful:
            return state
        cfg = body_state(self.system, state.q, state.v, state.chart, state.t)
        for k in {k for k, _ in stateful}:
            c, phases = self.system.contacts[k], state.memory[k]
            gp = c.gap(cfg)
            F, s = c.magnitudes(gp, phases), c.deflection(cfg.pose, gp, phases)
            for kk, i in stateful:
                if kk != k:
                    continue
                deflection = s[i]
                kept = c.friction[i].anchor_update(deflection, F[i])
                if kept is not deflection:
                    state = self.with_phase(state, k, i, dataclasses.replace(state.memory[k][i],
                                                                             anchor=c.anchor_at(cfg, gp, i, kept)))
        return state

    def _gap_values(self, t: float, y: FloatArray, chart: FloatArray) -> FloatArray:
        """``alpha`` [m] and ``alpha_dot`` [m/s] of every contact at ``(t, y)``: columns 0 and 1 of an
        (n_contacts, 2 or more) array (compiled when the run has a kernel)."""
        if self.kernel is not None:
            return self.kernel.gaps(t, y, chart)
        cfg = body_state(self.system, *self.system.split_y(y)[:2], chart, t)
        return np.concatenate([np.column_stack([g.alpha, g.alpha_dot]) for g in (c.gap(cfg) for c in self.system.contacts)])

    def _normal_velocity_errors(self, state: State, error: FloatArray) -> FloatArray:
        """``|J_alpha e_v|`` of every contact (n_contacts,) [m/s]: the error estimate ``error`` of ``y``
        seen by the normal velocities. ``alpha_dot = J_alpha v`` is linear in ``v`` at fixed
        positions, so it is the gap rate at ``state``'s positions with ``v = e_v``."""
        s = self.system
        y = state.y.copy()
        y[s.n_q:s.n_q + s.n_v] = error[s.n_q:s.n_q + s.n_v]
        return np.abs(self._gap_values(state.t, y, state.chart)[:, 1])

    def _energy_check(self, state: State, k: int, i: int, led: Ledger, balance: float) -> None:
        """Stop if the numerics created more energy since the contact's onset than the error
        estimates of its steps allow (``Onset.energy_error``), naming the indentation when it is
        deeper than the energy available then pays for."""
        c, phase = self.system.contacts[k], state.memory[k][i]
        o, law = phase.onset, c.laws[i]
        if not _energy_exceeded(o, led, balance, o.energy_error):
            return
        work = led.work_in - o.work_in
        roundoff = _energy_roundoff(o, led)
        created = balance - o.balance
        alpha = float(self._gap(state, k).alpha[i])
        need = float(law.elastic_energy(alpha, phase.memory)) if alpha > 0 else 0.0
        loads = o.signed_potential - led.signed_potential + work
        allowed = o.energy - o.signed_potential + loads + o.energy_error + max(0.0, o.dissipated - led.dissipated)
        if need > allowed + roundoff:
            detail = (f"{o.energy - o.signed_potential:.3g} J in the system at onset, work of gravity and loads "
                      f"{loads:.3g} J, what the step error estimates allow the numerics {o.energy_error:.3g} J")
            raise SimulationFailure(f"{c.names[i]}: " + indentation_diagnosis(
                o.number, state.t, alpha, law, allowed, phase.memory, detail))
        raise SimulationFailure(f"{c.names[i]}: " + energy_diagnosis(o.number, state.t, created, o.energy_error, o.n_steps))

    def _restitution_check(self, state: State, k: int, i: int, separation: float) -> str | None:
        """Diagnosis if the restitution of the law contact just ended is outside what the law allows.

        Any bodies: not below 0 (a located separation has the surfaces receding). Two rigid bodies
        (or one and ground): the law's free-impact value, within what the loads and the integration
        can change.
        """
        c, phase = self.system.contacts[k], state.memory[k][i]
        o, law = phase.onset, c.laws[i]
        if o is None or o.speed <= 0.0:
            return None
        slack = integration_restitution_slack(o.velocity_error, o.speed)
        low, high = -slack, np.inf
        if self._rigid_pair(k, i):
            acc = self._load_acceleration(state, k, i)
            slack += load_restitution_slack(acc, state.t - o.t, o.speed)
            if slack < 1.0:  # else the loads decide more than the law (a ball coming to rest)
                e_law = free_impact_restitution(law, self.effective_mass(state, k, i), o.speed, o.memory)
                low, high = e_law - slack, e_law + slack
        diagnosis = restitution_diagnosis(o.number, state.t, separation / o.speed, low, high, law, o.speed, separation)
        return None if diagnosis is None else f"{c.names[i]}: {diagnosis}"

    def _rigid_pair(self, k: int, i: int) -> bool:
        """Both bodies of the contact rigid or ground, no joint on either, no friction at the contact
        and no other contact on either body: the relative motion along the normal is one degree of
        freedom (friction and other contacts turn the bodies and feed the normal motion)."""
        s = self.system
        pair = s.contacts[k].body[i]
        moving = pair[pair < s.n_bodies]
        rigid = all(b == s.n_bodies or s.bodies.is_rigid[b] for b in pair)
        jointed = any(np.isin(js.body, moving).any() for js in s.joint_sets)
        others = sum(int(np.isin(c.body, moving).any(axis=1).sum()) for c in s.contacts) > 1
        return rigid and not jointed and not others and s.contacts[k].friction[i] is None

    def _load_acceleration(self, state: State, k: int, i: int) -> float:
        """Relative normal acceleration the loads give the contact's bodies, free of the contact [m/s^2]."""
        return self.pressing_force(state, k, i) * self.response(state, k, i)[1]


def rigid_point_velocity(system: System, cfg, body: int, point: FloatArray) -> FloatArray:
    """Velocity of ``point`` [m] carried by the rigid motion of ``body`` with the body's linear and
    angular momentum [m/s] (rigid bodies: their motion; flexible bodies on a fixed frame, ground: 0)."""
    if body == system.n_bodies:
        return np.zeros(3)
    flexible = {fb.index: (i, fb) for i, fb in enumerate(system.bodies.flexible)}
    if body not in flexible:
        return cfg.twist.W_v[body] + np.cross(cfg.twist.W_omega[body], point - cfg.pose.W_r[body])
    i, fb = flexible[body]
    if not fb.floating:
        return np.zeros(3)
    from viz3d.flexible import floating as ffr

    R, W_r, eta = cfg.pose.R_WB[body], cfg.pose.W_r[body], cfg.eta[i]
    v = np.concatenate([cfg.twist.W_v[body], cfg.twist.B_omega[body], cfg.eta_dot[i]])
    L = ffr.linear_momentum(fb.bar, R, eta, v)
    c = R @ (fb.bar.S @ eta) / fb.bar.mass                     # centre of mass from the frame origin
    G = W_r + c
    H_G = ffr.angular_momentum(fb.bar, W_r, R, eta, v) - np.cross(G, L)
    J_O = R @ ffr.inertia_tensor(fb.bar, eta) @ R.T
    J_G = J_O - fb.bar.mass * ((c @ c) * np.eye(3) - np.outer(c, c))
    omega = np.linalg.solve(J_G, H_G)
    return L / fb.bar.mass + np.cross(omega, point - G)


def _single_row(system: System, k: int, i: int):
    """A one-row layout stand-in for applying contact ``(k, i)``'s row: ``row_body`` only."""
    return _RowBody(system.contacts[k].body[i:i + 1])


@dataclass(frozen=True)
class _RowBody:
    row_body: np.ndarray


def _row_index(system: System, k: int, i: int) -> int:
    """Row of kinematic contact ``(k, i)`` among the system's constraint rows."""
    for provider, sl in zip(system.joints.joints, system.joints.row_slices()):
        if isinstance(provider, ContactRows) and provider.set_index == k:
            return sl.start + int(np.flatnonzero(provider.which == i)[0])
    raise KeyError(f"contact ({k}, {i}) has no constraint row (not kinematic)")


def contact_forces(system: System, state: State, lam: FloatArray, gaps: tuple = ()) -> list[FloatArray]:
    """Normal force of every contact [N], per set (k,): the law's, or a kinematic contact's
    multiplier ``lam`` (the state's multipliers, ``Accelerations.lam``) while it touches; ``gaps``:
    each set's ``gap`` at ``state`` if the caller has them."""
    if not gaps:
        cfg = body_state(system, state.q, state.v, state.chart, state.t)
        gaps = tuple(c.gap(cfg) for c in system.contacts)
    out = []
    for k, c in enumerate(system.contacts):
        phases = state.memory[k] if state.memory else c.initial_phases()
        F = c.magnitudes(gaps[k], phases)
        for i in c.rigid_indices:
            if phases[i].touching:
                F[i] = max(float(lam[_row_index(system, k, i)]), 0.0)
        out.append(F)
    return out


def with_anchors(memory: tuple, rows: FloatArray, k0) -> tuple:
    """The contacts' ``memory`` with the stick anchors of memory rows ``rows`` (n_contacts, 7;
    ``viz3d.contact.contacts.memory_rows``, set ``k``'s first at ``k0[k]``) where it has one (the
    same phases where they are equal)."""
    out = []
    for k, phases in enumerate(memory):
        new = list(phases)
        for i, p in enumerate(phases):
            row = rows[k0[k] + i]
            if p.anchor is not None and row[3] == 1.0 and tuple(row[4:7]) != p.anchor:
                new[i] = dataclasses.replace(p, anchor=tuple(float(x) for x in row[4:7]))
        out.append(tuple(new))
    return tuple(out)


def anchor_rows(anchors: FloatArray, rows: FloatArray) -> FloatArray:
    """A contact set's stick anchors ``anchors`` (k, 3; ``ContactSet.anchor_table``, NaN: none) with
    those of its memory rows ``rows`` (N, k, 7) where it has one (``with_anchors``' rule): (N, k, 3)."""
    moved = (rows[..., 3:4] == 1.0) & ~np.isnan(anchors)
    return np.where(moved, rows[..., 4:7], anchors)


def _energy_exceeded(o: Onset, led: Ledger, balance, energy_error):
    """True where the numerics created more energy since onset ``o`` than ``energy_error`` [J] allows
    (with ``_energy_roundoff``): the test of ``ContactStepping._energy_check``, of one step (floats)
    or of several (arrays over the steps of ``led``, ``balance`` and ``energy_error``)."""
    return ~(balance - o.balance <= energy_error + _energy_roundoff(o, led))


def _energy_roundoff(o: Onset, led: Ledger):
    """Round-off [J] of the ledger's sums since onset ``o`` (``ENERGY_ROUNDOFF`` of the energies in
    play), of one ledger or elementwise over several."""
    return ENERGY_ROUNDOFF * (abs(o.energy) + abs(led.work_in - o.work_in) + abs(o.signed_potential - led.signed_potential))


class _StepBooks:
    """The contacts' memory after each of N steps while law contacts are under way, as
    ``ContactStepping._book_step`` leaves it step by step (the same sums, added in the same order),
    built for a step when asked (a sequence of N memories: ``after_steps``'s first result).

    ``memory``: the contacts' memory before the steps; ``under_way``: the law contacts (set, contact)
    whose onset records are kept, ``k0`` each set's first global contact index; ``balance`` (N,) the
    ledger's balance after each step [J], ``low`` (N,) that at ``y - error`` (None: fixed steps, whose
    energy error is the change of the balance over the step), ``dvs`` (N, n_contacts) the normal velocity
    errors [m/s] (None: fixed steps), ``mems`` (N, n_contacts, 7) the memory rows with the stick anchors
    after each step (None: anchors that do not move)."""

    def __init__(self, memory: tuple, under_way: list, k0, balance: FloatArray, low: FloatArray | None,
                 dvs: FloatArray | None, mems: FloatArray | None = None, n: int | None = None):
        self.memory, self.under_way, self.balance, self.k0, self.mems = memory, under_way, balance, k0, mems
        self.n = balance.shape[0] if n is None else n
        self._built: dict[int, tuple] = {}  # (step -> its memory: one object however often asked for)
        self.onset0 = [memory[k][i].onset for k, i in under_way]
        self.velocity_error, self.energy_error = [], []
        for (k, i), o in zip(under_way, self.onset0):
            dv = np.zeros(balance.shape[0]) if dvs is None else dvs[:, k0[k] + i]
            prev = np.concatenate([[o.balance_now], balance[:-1]]) if low is None else low
            self.velocity_error.append(np.add.accumulate(np.concatenate([[o.velocity_error], dv]))[1:])
            self.energy_error.append(np.add.accumulate(np.concatenate([[o.energy_error], np.abs(balance - prev)]))[1:])

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, r: int) -> tuple:
        if r < 0:
            r += self.n
        if not 0 <= r < self.n:
            raise IndexError(r)
        if r not in self._built:
            self._built[r] = self._build(r)
        return self._built[r]

    def _build(self, r: int) -> tuple:
        memory = [list(phases) for phases in self.memory]
        for j, ((k, i), o) in enumerate(zip(self.under_way, self.onset0)):
            memory[k][i] = dataclasses.replace(memory[k][i], onset=dataclasses.replace(
                o, n_steps=o.n_steps + r + 1, velocity_error=float(self.velocity_error[j][r]),
                energy_error=float(self.energy_error[j][r]), balance_now=float(self.balance[r])))
        memory = tuple(tuple(phases) for phases in memory)
        return memory if self.mems is None else with_anchors(memory, self.mems[r], self.k0)

    def before(self, r: int) -> "_StepBooks":
        """The books of the first ``r`` steps."""
        out = object.__new__(_StepBooks)
        out.__dict__.update(self.__dict__, n=r)
        return out

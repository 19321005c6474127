"""Running a system in time: ``Simulation`` (one fixed step at a time) and ``simulate`` (a whole
headless run into a ``Trajectory``).

A run that fails stops at once with a diagnosis in ``Trajectory.status``; the frames computed so
far are kept. Ctrl-C likewise ends the run with status "interrupted ..." and keeps the frames.
"""

from __future__ import annotations

import collections.abc
import json
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from viz3d._typing import IntArray
from viz3d.columns import CHUNK, FrameColumns, StateLog, chunk_length
from viz3d.constraints import SingularConstraintError, constraint_rows
from viz3d.departures import Departures
from viz3d.diagnosis import (
    CapacityWatch,
    EnergyFailure,
    EnergyWatch,
    RunComplete,
    SimulationFailure,
    check_chart,
    check_state,
    check_violation,
    redundant_joints,
)
from viz3d.dynamics import VectorField, body_state, element_memory
from viz3d.extras import element_fields, joint_fields, ledger_fields, run_extras
from viz3d.frames import Frame, frame_from_state
from viz3d.integrators import Integrator
from viz3d.integrators.base import StepResult
from viz3d.integrators.explicit_rk import DenseInterpolant
from viz3d.integrators.adaptive import (Controller, FixedSteps, StepSizeUnderflow, accepted_step, error_order,
                                        first_event, hermite, step_end, step_to_try)
from viz3d.interrupts import InterruptGuard
from viz3d.methods import MethodError, check_combination
from viz3d.rotations import euler_from_matrix
from viz3d.scene.build import build, make_controller, make_formulation, make_integrator_from
from viz3d.scene.load import Scene, load_scene, with_sim
from viz3d.scene.schema import SceneError
from viz3d.sink import Sink, frame_due
from viz3d.stabilization import ProjectionError
from viz3d.stowage import drive_coordinate, run_events, run_verdict, seated_stop, verdict_fields
from viz3d.system import State, States, System, state_size
from viz3d.trajectory import Trajectory

#: Output interval when the scene gives none [s].
DEFAULT_OUTPUT_DT = 0.01
#: A run that may end at a goal (``[stowage] settle_time``) checks its frames this often [s of
#: simulated time]: the steps it computes past the goal.
GOAL_CHECK_INTERVAL = 0.5
#: Show a progress bar when a run is projected to take longer than this [s] of wall time.
PROGRESS_AFTER = 2.0
#: Largest change of an orientation coordinate in one adaptive step [rad]: a chart is re-centred
#: when its nutation comes within 30 deg (0.52 rad) of the singular one, and only between steps,
#: so no step may turn the angles further than that.
ADAPTIVE_MAX_TURN = 0.5
#: Steps the compiled adaptive driver records in one call during a law contact (doubled whenever a
#: frame needs more): their contact bookkeeping runs in Python after the call.
STEP_RECORDS = 256
#: Most state entries (samples x coordinates) a driver call with contacts returns (``output_states``).
SAMPLES_PER_CALL = 1 << 21


@dataclass(frozen=True, eq=False)
class FrameSource:
    """What the frames of one generation's states are computed with (``viz3d.columns.chunk_frames``):
    its system, formulation, compiled kernel (None: the NumPy path) and the energy ledger's reference
    [J] (None without a ledger)."""

    system: System
    formulation: object
    kernel: object
    reference_energy: float | None

    def solved_rows(self, state: State) -> tuple | None:
        """``(lam, C, J)`` at ``state`` from the compiled kernel (``KernelStepper.solved_rows``), for
        frames; None without constraint rows or kernel (or where the kernel cannot evaluate: the
        NumPy path then says why)."""
        if self.kernel is None or not self.system.n_c:
            return None
        try:
            return self.kernel.solved_rows(state.t, state.y, state.chart, state.memory, state.element_memory)
        except np.linalg.LinAlgError:
            return None

    def kernel_sampler(self):
        """The compiled kernel's stepper when output frames can be sampled in it (``viz3d.columns``;
        every force element's potential energy has a compiled piece), else None."""
        k = self.kernel
        return k if k is not None and k.data.energy_gap is None else None

    def frame(self, state: State, drawings: tuple = ()) -> Frame:
        """The output frame of ``state`` (``viz3d.frames.frame_from_state``), with the multipliers,
        configuration and gaps from the compiled kernel when the run has one."""
        kinematics = None
        if self.kernel is not None:
            kinematics = self.kernel.configuration(state.t, state.y, state.chart)
        return frame_from_state(self.system, self.formulation, state, drawings, self.reference_energy,
                                self.solved_rows(state), kinematics)


class Simulation:
    """Advance a ``System`` from a ``State`` by fixed intervals; used by ``simulate`` and the viewer.

    Each ``step`` returns the state ``dt`` later. How it gets there:

    * fixed steps (default): one step of ``integrator`` (with its solver state and, for FSAL
      methods, the derivative carried over while nothing changed ``y`` in between);
    * adaptive steps (``controller`` given; the integrator needs an embedded error estimate): as
      many accepted steps as ``adaptive.Controller`` chooses, the state at ``t0 + n dt`` sampled
      from the last step's dense output (the tableau's continuous extension, else cubic Hermite);
      none past ``t_end``, where the last one ends (``adaptive.step_to_try``, ``adaptive.step_end``);
    * a formulation that steps itself (``ALI3P``): its own ``step`` with its memory (in the compiled
      kernel when it covers the system, several steps a call: ``steps``, ``output_states``).

    Between accepted steps, always in this order: ``formulation.post_step`` (projections), the
    health check, ``rotation.normalize`` (unit quaternions), ``rotation.rechart`` (per-body
    chart switch) and the force elements' memory (``viz3d.dynamics.element_memory``: shape
    contacts' stick anchors, planted here at the start too).

    Parameters
    ----------
    system, state : System, State
    integrator : Integrator
    formulation : a formulation of ``viz3d.formulation.FORMULATIONS``
    dt : float
        Interval between returned states [s]: the step itself unless ``controller`` is given.
    blowup_speed : float
        Speed [m/s] above which the run is declared diverged.
    controller : adaptive.Controller, optional
        Error control of adaptive steps.
    t_end : float
        Time [s] no adaptive step goes past (``run`` sets it to the run's last sample; inf: none),
        so no event, state or frame of the run is after it.
    departures : viz3d.departures.Departures, optional
        Bodies that leave the run (a chain hauled in): checked every ``rule.every`` samples from the
        start, where every call of ``steps`` and ``output_states`` ends or stops, so the run goes on
        with the next generation of the system (``system`` and ``state`` change; frames keep the first
        generation's bodies and joints: ``viz3d.columns.chunk_frames``).
    compiled : bool
        Evaluate the vector field, and take explicit Runge-Kutta steps (fixed, or adaptive with
        their dense output: ``viz3d.kernel.adaptive``), in the compiled kernel (``viz3d.kernel``)
        when it covers the system and formulation; the NumPy path otherwise (``kernel_note`` says
        which, and why). Fixed steps with contact events go through the compiled adaptive driver
        too (``FixedSteps``: the steps ``_event_step`` takes, no error test). The compiled driver
        locates contact events and cuts its step at them
        (Python applies the event's handler); the step after each event and the steps of systems
        with force elements that remember are taken in Python; during law contacts the compiled
        driver takes them (and moves the stick anchors of bristle friction after each) and Python
        keeps the contacts' books on its step records afterwards.

    Raises
    ------
    MethodError
        If the integrator, formulation, rotation and controller cannot run together.

    Attributes
    ----------
    state : State
        Current state.
    chart_switches : ndarray of int, shape (nb,)
    kernel_note : str
        "compiled kernel", or "NumPy path, ..." with the reason.
    n_steps, n_rejected, n_rhs : int
        Accepted and rejected integration steps, vector-field evaluations so far.
    """

    def __init__(self, system: System, state: State, integrator: Integrator, formulation, dt: float,
                 blowup_speed: float = 1e4, controller: Controller | None = None, compiled: bool = True,
                 t_end: float = math.inf, departures: Departures | None = None):
        check_combination(integrator, formulation, system.rotation, None if controller is None else controller.rtol)
        self.system, self.state = system, state
        self.departures, self._compile = departures, compiled
        self._past: dict[int, FrameSource] = {}  # earlier generations' frame sources, by their n_q
        self._left_switches = np.zeros(system.n_bodies, dtype=int)  # chart switches of the bodies that left
        self.integrator, self.formulation, self.dt, self.t_end = integrator, formulation, dt, t_end
        self.blowup_speed, self.controller = blowup_speed, controller
        self.chart_switches = np.zeros(system.n_bodies, dtype=int)
        self.t0, self.n_steps, self.n_rejected, self.n_rhs, self.n_samples = state.t, 0, 0, 0, 0
        self._f = None          # vector field at the current (inner) state, when known
        self._solver = None     # the integrator's solver state
        self._memory = None     # the memory of a formulation that steps itself
        self._stopped = None    # where its batched call stopped (viz3d.kernel.ali3p.Stopped), the state then
        self._inner = state     # adaptive: state at the last accepted step (may be ahead of .state)
        self._span = None       # adaptive: the last accepted step, for dense output
        self._h = None          # adaptive: next step to try [s]
        self._carry = None      # adaptive: the kernel's carry while the kernel owns the adaptive state (else None)
        self._span_memory = None  # adaptive, kernel: the contacts' memory at the carry's last step's start (None: the inner's)
        self._records, self._capacity = None, STEP_RECORDS  # adaptive, kernel: steps recorded during law contacts
        self._fields: list[VectorField] = []
        self._kernel, self.kernel_note = (_compiled(system, integrator, formulation) if compiled
                                          else (None, "NumPy path (compiled = false)"))
        self._contacts = None   # contact events (systems with contacts): viz3d.events.ContactStepping
        self._remembers = any(e.has_memory for e in system.forces)  # force elements with memory
        if self._remembers and not state.element_memory:
            self.state = self._inner = state = state.replace(element_memory=element_memory(system, state))
        self._fired = None      # the event handled last: its contact's events start at a root next step
        self._pending = None    # the event the compiled driver cut its last step at, not handled yet
        #: States right after contact events, not yet taken by ``drain_events`` (frames at events).
        self.event_states: list[State] = []
        self._E0 = None         # the ledger's initial total [J] (drives without contacts)
        if system.contacts:
            self._start_contacts(state)
        elif system.n_aux:
            if state.w.size != system.n_aux:
                self.state = self._inner = state = state.replace(w=np.zeros(system.n_aux))
            from viz3d.events import ledger

            self._E0 = ledger(system, state).total

    def _start_contacts(self, state: State) -> None:
        from viz3d.events import ContactStepping

        if state.w.size != self.system.n_aux or len(state.memory) != len(self.system.contacts):
            state = state.replace(w=np.zeros(self.system.n_aux), memory=tuple(c.initial_phases() for c in self.system.contacts))
        self._contacts = ContactStepping(self.system, self.formulation, kernel=self._kernel)
        self.state = self._inner = self._contacts.start(state)

    def source(self, state=None) -> "FrameSource":
        """What the frames of ``state`` (a ``State`` or ``States``; default: the current one) are computed
        with: its generation's system, kernel and ledger reference (``FrameSource``)."""
        if state is not None and self._past and state_size(state) != self.system.n_q:
            return self._past[state_size(state)]
        return FrameSource(self.system, self.formulation, self._kernel, self.reference_energy)

    def solved_rows(self, state: State) -> tuple | None:
        """``FrameSource.solved_rows`` of ``state``'s generation."""
        return self.source(state).solved_rows(state)

    def kernel_sampler(self):
        """``FrameSource.kernel_sampler`` of the current generation."""
        return self.source().kernel_sampler()

    def frame(self, state: State, drawings: tuple = ()) -> Frame:
        """``FrameSource.frame`` of ``state``'s generation."""
        return self.source(state).frame(state, drawings)

    @property
    def layout_chart_switches(self) -> IntArray:
        """``chart_switches`` per body of ``layout`` (those of the bodies that left, up to then)."""
        if self.departures is None:
            return self.chart_switches
        out = self._left_switches.copy()
        out[self.departures.current.bodies] += self.chart_switches
        return out

    @property
    def layout(self) -> System:
        """The system whose bodies and joints the run's frames are given in: the first generation's
        (``departures``), else ``system``."""
        return self.departures.layout if self.departures is not None else self.system

    @property
    def reference_energy(self) -> float | None:
        """The energy ledger's initial total [J] (None without a ledger, or before the contacts'
        start has set it)."""
        return self._contacts.E0 if self._contacts is not None else self._E0

    @property
    def contacts(self):
        """The run's ``viz3d.events.ContactStepping`` (None without contacts)."""
        return self._contacts

    def drain_events(self, until: float = np.inf) -> list[State]:
        """The states right after the contact events not taken yet, up to time ``until`` (adaptive
        steps may run ahead of the returned state), in time order."""
        out = [s for s in self.event_states if s.t <= until]
        self.event_states = [s for s in self.event_states if s.t > until]
        return out

    def step(self) -> State:
        """Return the state ``dt`` later; raise ``SimulationFailure`` with a diagnosis if the run
        cannot go on."""
        self._step()
        self._depart()
        return self.state

    def _step(self) -> State:
        while True:  # the compiled adaptive driver, and the Python loop where it stops, until the sample
            if self._adaptive_kernel_covers():
                states = self._kernel_samples(1, 1)
                if states:
                    return states[0]
            new = self._python_step()
            if new is not None:
                return new

    def _python_step(self) -> State | None:
        """``step`` through the Python loop; None when it hands the rest of the sample back to the
        compiled adaptive driver (after the steps at a contact event)."""
        self._to_python()
        target = self.t0 + (self.n_samples + 1) * self.dt
        check_chart(self.system, self._inner if self.controller is not None else self.state)
        try:
            if self.formulation.integrator is not None:
                new = self._own_step(target)
            elif self._contacts is not None:
                new = self._event_steps(target)
                if new is None:
                    return None
            elif self.controller is None:
                new = self._fixed_step(target)
            else:
                new = self._adaptive_samples(target)
        except SingularConstraintError:
            raise SimulationFailure(self._singular_message(self.state)) from None
        except ProjectionError as exc:  # at the failing step's time: adaptive steps end between the samples
            raise SimulationFailure(f"t = {exc.t:.6g} s: {exc}") from None
        except StepSizeUnderflow as exc:  # (its message quotes the step's time)
            raise SimulationFailure(str(exc)) from None
        finally:
            self.n_rhs += sum(f.n_evals for f in self._fields)
            self._fields.clear()
        self.state = new
        self.n_samples += 1
        return new

    def steps(self, n: int) -> State:
        """``n`` calls of ``step`` (the same states, diagnoses and counters); fixed explicit RK
        steps and the steps of a formulation that steps itself through the compiled kernel go in
        one call, free of per-step Python overhead, and the compiled adaptive driver takes the
        samples left as ``output_states`` asks for one frame of them (with contacts, one call up to
        the next event, whose handler ``step`` takes, keeping the samples before it)."""
        goal = self.n_samples + n
        while self.n_samples < goal:  # (to each departure check, where the run may change its system)
            self._steps(min(goal - self.n_samples, self._to_check()))
            self._depart()
        return self.state

    def _steps(self, n: int) -> None:
        goal = self.n_samples + n
        if n > 1 and self._kernel_ready():
            self._kernel_steps(n)
        elif n > 1 and self._own_kernel_ready():
            self._own_frames(1, n)
        while self.n_samples < goal:
            left = goal - self.n_samples
            if left > 1 and self._adaptive_kernel_covers() and (self.output_states(1, left) or self.n_samples == goal):
                continue
            self._step()

    # ------------------------------------------------------------------ departures

    def _to_check(self) -> int:
        """Samples to the next departure check (no limit without departures)."""
        return self.departures.steps_to_check(self.n_samples) if self.departures is not None else sys.maxsize

    def _depart(self) -> None:
        """At a departure check, go on with the next generation of the system for each body that
        leaves now (``viz3d.departures``): the same instant, the state moved onto it, the ledger's
        reference lowered by the energy the body carried out; the kernel, the formulation's memory and
        the integrator's state start afresh, as at the start of a run."""
        d = self.departures
        if d is None or self.n_samples % d.rule.every:
            return
        while (moved := d.next(self.state)) is not None:
            gen, state = moved
            before = d.generations[-2]
            self._past[self.system.n_q] = self.source()
            if self._E0 is not None:
                from viz3d.events import ledger

                new, old = ledger(gen.system, state), ledger(self.system, self.state)
                self._E0 += (new.total + new.dissipated) - (old.total + old.dissipated)  # (the link's energy)
            kept = np.isin(before.bodies, gen.bodies)
            self._left_switches[before.bodies[~kept]] += self.chart_switches[~kept]
            self.chart_switches = self.chart_switches[kept]
            self.system, self.state, self._inner = gen.system, state, state
            self._kernel, self.kernel_note = (_compiled(gen.system, self.integrator, self.formulation) if self._compile
                                              else (None, "NumPy path (compiled = false)"))
            self._f = self._solver = self._memory = self._stopped = self._span = self._carry = None

    # ------------------------------------------------------------------ the three ways to step

    def _fixed_step(self, target: float) -> State:
        s, system = self.state, self.system
        if self._kernel_ready():
            new = self._kernel_step(target)
            if new is not None:
                return new
        rhs = self._field(s.chart, s.memory, s.element_memory)
        if self._solver is None:
            self._solver = self.integrator.init(rhs, s.t, s.y)
        with np.errstate(all="ignore"):
            res = self.integrator.step(rhs, s.t, s.y, self.dt, f0=self._f, state=self._solver)
        if not res.status.ok:
            raise SimulationFailure(res.status.message)
        self._solver = res.state
        raw = _state_at(system, target, res.y, s)
        return self._accept(raw, res.f1, self.dt)

    def _kernel_ready(self) -> bool:
        """Fixed explicit RK steps the kernel covers (a formulation that steps itself gets a stepper
        without tableau from ``_compiled``); not with contacts, whose events the driver's ``FixedSteps`` locate
        inside the steps (``_adaptive_kernel_covers``)."""
        return (self._kernel is not None and self._kernel.tableau is not None and self.controller is None
                and self._contacts is None)

    def _kernel_step(self, target: float) -> State | None:
        """The step through the compiled kernel, which also makes the health checks and the chart
        switch; None when it reports a failure (the NumPy path then redoes the step and raises
        the detailed diagnosis)."""
        y, chart, _, ok = self._kernel_run(1)
        if not ok:
            return None
        return _state_at(self.system, target, y, self.state.replace(chart=chart, element_memory=self._kernel_elements()))

    def _kernel_elements(self) -> tuple:
        """The force elements' memory after the kernel's last steps from the current state."""
        return self._kernel.stored(self.state.element_memory)

    def _kernel_steps(self, n: int) -> None:
        """Up to ``n`` kernel steps in one call; on a failure at step k, the k - 1 good steps are
        kept (redone from the start: the kernel is deterministic) and ``step`` takes the failing
        one to raise the diagnosis."""
        y, chart, done, ok = self._kernel_run(n)
        if not ok:
            y, chart, done, _ = self._kernel_run(done)
        self.n_samples += done
        self.state = _state_at(self.system, self.t0 + self.n_samples * self.dt, y,
                               self.state.replace(chart=chart, element_memory=self._kernel_elements()))

    @property
    def batches_frames(self) -> bool:
        """True when ``output_states`` can take several output frames in one kernel call: fixed
        explicit RK steps the kernel covers, no contacts; adaptive ones the kernel covers
        (``_adaptive_kernel_covers``); those of a formulation that steps itself (``_own_kernel_ready``)."""
        return self._kernel_ready() or self._adaptive_kernel_covers() or self._own_kernel_ready()

    def output_states(self, n_frames: int, every: int) -> States | list[State]:
        """Up to ``n_frames`` states ``every`` steps apart, through the kernel in one call: the same
        states, counters and chart switches as ``n_frames`` calls of ``steps(every)``. On a failure
        the states before the failing frame are returned (``state`` is the last, or, for a formulation
        that steps itself, the one before the failing step, inside that frame: ``n_samples`` says);
        ``steps`` then takes the rest of that frame and raises its diagnosis. Adaptive runs: ``_kernel_samples`` (no
        states while Python takes the steps, e.g. at a contact event); with contacts, the samples
        one a frame of the driver's call, every ``every``-th returned: a call cut at an event keeps
        the samples before it, so the run may stand inside a frame after it (``n_samples``)."""
        if self.departures is not None:  # (each call ends at or before the next departure check)
            n_frames = min(n_frames, self._to_check() // every)
            if n_frames < 1:
                return []
        states = self._output_states(n_frames, every)
        self._depart()
        return states

    def _output_states(self, n_frames: int, every: int) -> States | list[State]:
        from viz3d.kernel import OK

        if self._contacts is not None:  # (the driver's, fixed steps with contacts too)
            room = max(1, SAMPLES_PER_CALL // (every * self.state.y.shape[0]))
            states = self._kernel_samples(min(n_frames, room) * every, 1) or []
            return (states if every == 1 else states[every - 1::every]) if states else []
        if self.controller is not None:
            return self._kernel_samples(n_frames, every) or []
        if self._own_kernel_ready():
            return self._own_frames(n_frames, every)
        states, done, status = self._frames_run(n_frames, every)
        if status != OK and done:  # keep the good frames (redone: the kernel is deterministic)
            states, done, status = self._frames_run(done, every)
        return states

    def _frames_run(self, n_frames: int, every: int) -> tuple[States | list[State], int, int]:
        """``output_states``'s kernel call from the current state: (the frames' states, frames done,
        status); the states (none on a failure), counters and chart switches move only when every
        frame succeeded. Force elements with memory: one call per frame (each state carries its own
        memory), the good frames kept and 0 frames done reported on a failure."""
        from viz3d.kernel import OK

        if not self._kernel.data.anchors:
            return self._frames_call(n_frames, every)
        parts: list[States] = []
        for _ in range(n_frames):
            got, _, status = self._frames_call(1, every)
            if status != OK:
                return (States.join(parts) if parts else []), 0, status
            parts.append(got)
        return States.join(parts), n_frames, OK

    def _frames_call(self, n_frames: int, every: int) -> tuple[States | list[State], int, int]:
        """``_frames_run`` in one kernel call."""
        from viz3d.kernel import OK, SINGULAR

        s, system = self.state, self.system
        y, chart = s.y, s.chart.copy()  # (State.y is a new array)
        switches = np.zeros(system.n_bodies, np.int64)
        anchors = bool(self._kernel.data.anchors)  # (sampled after the call, with each state's anchors)
        Y, charts, done, partial, status, samples = self._kernel.frames(
            n_frames, every, self.n_samples, self.t0, self.dt, y, chart, switches, self.blowup_speed,
            s.element_memory, self.kernel_sampler() is not None and not anchors)
        if status != OK:  # the failed frame's evaluations count (a singular step stops inside its stages)
            self.n_rhs += (done * every + partial + (status == SINGULAR)) * self._kernel.tableau.stages
            return [], done, status
        self.n_rhs += done * every * self._kernel.tableau.stages
        n0 = self.n_samples
        elements = self._kernel_elements()  # (one frame when it changes: _frames_run)
        ts = self.t0 + (n0 + every * np.arange(1, done + 1)) * self.dt  # (each as the kernel's: the same float ops)
        states = States.alike(ts, Y, charts, system.n_q, system.n_v, s.replace(element_memory=elements), samples)
        self.state = states[-1]
        self.n_samples += done * every
        self.n_steps += done * every
        self.chart_switches += switches
        self._f = None
        return states, done, OK

    def _own_kernel_ready(self) -> bool:
        """Steps of a formulation that steps itself (ALI3-P) that the kernel takes, several in one
        call (never with the law contacts of ``System.contacts``: the kernel does not cover them)."""
        return self.formulation.integrator is not None and self._kernel is not None and self._contacts is None

    def _own_memory(self):
        """The memory of a formulation that steps itself, made at the first step (its evaluations counted)."""
        if self._memory is None:
            self._memory = self.formulation.init_memory(self.system, self.state, self._kernel)
            self.n_rhs += self._memory.n_evals
        return self._memory

    def _own_frames(self, n_frames: int, every: int) -> list[State]:
        """Up to ``n_frames`` states ``every`` steps apart of a formulation that steps itself, in one
        kernel call (``viz3d.kernel.ali3p.KernelALI3P.frames``): the same states, memory and counters
        as ``steps(every)`` ``n_frames`` times. On a failure the states of the frames before it are
        returned and the run stands before the failing step (``state``, maybe inside a frame); that
        step's attempts are kept for ``step``, which goes on from them (halvings, or the diagnosis)
        instead of redoing them, and no call is made while it stands there."""
        if self._stopped is not None and self._stopped[1] is self.state:
            return []
        kernel = self._own_memory().kernel
        states, memory, switches, done, stopped = kernel.frames(self.system, self.formulation, self.state,
                                                                self._memory, n_frames, every, self.n_samples,
                                                                self.t0, self.dt, self.blowup_speed)
        steps = done * every + (stopped.steps if stopped is not None else 0)
        if steps:
            self.state = states[-1] if stopped is None else stopped.state
            self.n_samples += steps
            self.n_steps += steps
            self.chart_switches += switches
            self._f = None
        self.n_rhs += memory.n_evals - self._memory.n_evals
        self._memory = memory
        if stopped is not None and stopped.failed is not None:
            self._stopped = (stopped.failed, self.state)
        return states

    def _kernel_run(self, n: int) -> tuple[np.ndarray, np.ndarray, int, bool]:
        """Up to ``n`` kernel steps from the current state: ``(y, chart, good steps, ok)``. The
        evaluations are counted (a failed step's too); steps and chart switches only when all
        ``n`` succeed. The FSAL value of the NumPy path is dropped (the state moves past it)."""
        from viz3d.kernel import OK, SINGULAR

        s = self.state
        y, chart = s.y.copy(), s.chart.copy()
        switches = np.zeros(self.system.n_bodies, np.int64)
        done, status = self._kernel.step(s.t, self.dt, y, chart, switches, self.blowup_speed, n, s.element_memory)
        failed_inside = status == SINGULAR  # a singular step stops inside its stages: not counted in done
        self.n_rhs += (done + failed_inside) * self._kernel.tableau.stages
        if status != OK:
            return y, chart, done if failed_inside else done - 1, False
        self.chart_switches += switches
        self.n_steps += done
        self._f = None
        return y, chart, done, True

    def _event_steps(self, target: float) -> State | None:
        """Steps to ``target`` with contact events located on each step (``viz3d.events``): fixed
        steps land on ``target`` (shortened by the contact step bound and by events), adaptive ones
        are sampled there by dense output. None when the compiled adaptive driver may take the
        next step (it takes the rest to ``target``)."""
        if self._pending is not None:  # the compiled driver's step cut at an event: handled as the loop's own
            name, self._pending = self._pending, None
            self._inner = self._handle_event(name, self._inner)
        s = self._inner
        slack = 1e-12 * max(abs(target), self.dt)  # round-off of times, relative to the run's own scale
        end = target - slack
        while s.t < end and (self.controller is None or self._span is None or self._span.t1 < target):
            s = self._event_step(s, target)
            self._inner = s
            if self._adaptive_kernel_covers() and self._adaptive_kernel_now():
                return None
        if self.controller is None or abs(s.t - target) <= slack:
            return s.replace(t=target) if self.controller is None else s
        sample = self._span.sample(target)
        W_r, theta = self.system.split_q(sample.q)
        normal = self.system.rotation.normalize(theta)
        return sample if normal is theta else sample.replace(q=self.system.with_frames(sample.q, W_r, normal))

    def _event_step(self, s: State, target: float) -> State:
        """One accepted step from ``s``, cut at the first contact event inside it (then handled)."""
        system, method, contacts = self.system, self.integrator, self._contacts
        rhs = self._field(s.chart, s.memory, s.element_memory)
        f0 = rhs(s.t, s.y) if self._f is None else self._f
        bound = contacts.step_bound(s)
        with np.errstate(all="ignore"):
            if self.controller is None:  # (as the compiled driver's FixedSteps)
                h = step_to_try(self.dt, bound, s.t, target)
                res = method.step(rhs, s.t, s.y, h, f0=f0, state=self._solver)
                if not res.status.ok:
                    raise SimulationFailure(res.status.message)
                solver, t1 = res.state, step_end(s.t, h, target)
            else:
                ctrl = self._step_controller(s)
                if self._h is None:
                    self._h = min(ctrl.first_step(rhs, s.t, s.y, f0, error_order(method)), self._turn_limit(f0))
                h = step_to_try(self._h, ctrl.max_step, s.t, self.t_end)
                acc = accepted_step(rhs, s.t, s.y, f0, h, method, ctrl)
                self.n_rejected += acc.n_rejected
                res, h, solver = acc.res, acc.h, None
                t1 = step_end(s.t, h, self.t_end)
                self._h = acc.h_next
            f1 = res.f1 if res.f1 is not None else rhs(t1, res.y)
        events = contacts.events(s)
        touched = self._fired.partition(":")[2] if self._fired else None      # "k:i" of the contact handled last
        fresh = tuple(ev.name for ev in events if ev.name.partition(":")[2] == touched)
        g0 = [0.0 if ev.name in fresh else ev.g(s.t, s.y) for ev in events]
        r0 = [np.nan if ev.rate is None else ev.rate(s.t, s.y) for ev in events]
        hit = first_event(events, g0, r0, s.t, s.y, f0, t1, res.y, f1, fresh)
        if hit is None:
            self._solver = solver
            self._span = self._rk_span(rhs, s, t1, h, res, f1) if self.controller is not None else None
            accepted = self._accept(_state_at(system, t1, res.y, s), f1, h)
            new = contacts.after_step(accepted, res.error)
            if contacts.anchors_moved(accepted, new):
                self._f = None  # (f1 was evaluated with the anchors before)
            self._fired = None
            if self.controller is not None:
                self._h = min(self._h, self._turn_limit(f1))
            return new
        name, t_ev = hit
        with np.errstate(all="ignore"):
            res_ev = method.step(rhs, s.t, s.y, t_ev - s.t, f0=f0, state=self._solver)
        if not res_ev.status.ok:
            raise SimulationFailure(res_ev.status.message)
        self._solver = res_ev.state
        f_ev = res_ev.f1 if res_ev.f1 is not None else rhs(t_ev, res_ev.y)
        self._span = _Span(s.t, t_ev, s, system, lambda: hermite_interpolant(s.t, s.y, f0, t_ev, res_ev.y, f_ev),
                           h=t_ev - s.t) if self.controller is not None else None
        reached = contacts.after_step(self._accept(_state_at(system, t_ev, res_ev.y, s), None, t_ev - s.t), res_ev.error)
        return self._handle_event(name, reached)

    def _handle_event(self, name: str, reached: State) -> State:
        """The state after contact event ``name`` (``ContactStepping.handle``) at ``reached``, the end
        of the step cut at it (by ``_event_step`` or the compiled driver); the next step's events of
        that contact start at a root (``_fired``)."""
        new = self._contacts.handle(name, reached)
        self._fired, self._f = name, None
        self.event_states.append(new)
        return new

    def _own_step(self, target: float) -> State:
        s = self.state
        self._own_memory()
        failed = self._stopped[0] if self._stopped is not None and self._stopped[1] is s else None
        self._stopped = None
        new, memory, status = self.formulation.step(self.system, s, self.dt, self._memory, failed=failed)
        self.n_rhs += memory.n_evals - self._memory.n_evals
        if not status.ok:
            raise SimulationFailure(status.message)
        self._memory = memory
        return self._accept(new.replace(t=target), None, self.dt, post_step=False)

    def _adaptive_samples(self, target: float) -> State:
        while self._span is None or self._span.t1 < target:
            self._adaptive_step()
        sample = self._post_step(self._span.sample(target))
        check_state(self.system, sample, self.blowup_speed, self._span.t1 - self._span.t0)
        W_r, theta = self.system.split_q(sample.q)
        return sample.replace(q=self.system.with_frames(sample.q, W_r, self.system.rotation.normalize(theta)))

    def _adaptive_step(self) -> None:
        s, system, method = self._inner, self.system, self.integrator
        rhs = self._field(s.chart, s.memory, s.element_memory)
        f = rhs(s.t, s.y) if self._f is None else self._f
        if self._h is None:
            self._h = min(self.controller.first_step(rhs, s.t, s.y, f, error_order(method)), self._turn_limit(f))
        with np.errstate(all="ignore"):
            h = step_to_try(self._h, self.controller.max_step, s.t, self.t_end)
            acc = accepted_step(rhs, s.t, s.y, f, h, method, self.controller)
            t1 = step_end(s.t, acc.h, self.t_end)
            f1 = acc.res.f1 if acc.res.f1 is not None else rhs(t1, acc.res.y)
        self.n_rejected += acc.n_rejected
        self._span = self._rk_span(rhs, s, t1, acc.h, acc.res, f1)
        raw = _state_at(system, t1, acc.res.y, s)
        self._inner = self._accept(raw, f1, acc.h)
        self._h = min(acc.h_next, self._turn_limit(f1))

    # ------------------------------------------------------------------ adaptive steps in the kernel

    def _adaptive_kernel_covers(self) -> bool:
        """Runs whose steps the kernel's driver takes (``viz3d.kernel.adaptive``): adaptive ones of an
        explicit RK method with a continuous extension, and fixed explicit RK steps with contact
        events (its ``FixedSteps``: fixed steps without contacts go in ``_kernel_steps``); no force
        element with memory (updated in Python between steps)."""
        k = self._kernel
        if k is None or k.tableau is None or self._remembers:
            return False
        return k.tableau.dense is not None if self.controller is not None else self._contacts is not None

    def _adaptive_kernel_now(self) -> bool:
        """The kernel may take the next samples: the last step was not cut at an event (its span is
        an RK step's; the event is handled, ``_pending``), and with contacts, no event was just
        handled (the next step's events start at a root)."""
        if self._carry is not None:
            return True
        if self._pending is not None or (self._span is not None and self._span.stages is None):
            return False
        return self._fired is None

    def _kernel_samples(self, n_frames: int, every: int) -> list[State] | None:
        """Up to ``n_frames`` output states ``every`` samples apart, the adaptive steps and dense
        output in one kernel call: the states, counters, chart switches and contact memory of as
        many ``step`` calls. None when the kernel cannot take the next sample now; fewer states when
        it cut a step at a contact event (the event's handler is then ``_event_steps``'s, which takes
        the rest of the sample), when it stopped at a step that needs Python (a failure, an event it
        cannot locate: the Python path then redoes that step from the same state and raises the
        diagnosis or locates the event), when its step records were full, or before a recorded step
        whose contact check fails (the Python path redoes that step and raises the diagnosis). Fixed
        steps during law contacts: no more frames than their steps' records hold. With contacts the
        callers ask for one sample a frame (``steps``, ``output_states``): a frame of several samples
        that such a stop cuts is redone for the frames before it."""
        from viz3d.kernel import EVENT, FULL, OK
        from viz3d.kernel.adaptive import CUT, EVALS, REJECTED, STEPS, T

        if not self._adaptive_kernel_now():
            return None
        like = self._inner
        try:
            carry = self._to_kernel()
            records = self._step_records()
            if records is not None and self.controller is None:  # fixed steps: as many frames as their records take
                n_frames = max(1, min(n_frames, records.capacity // (every * self._fixed_steps_per_sample())))
            start = carry.copy() if every > 1 or records is not None else None
            Ts, Y, charts, done, partial, status = self._adaptive_call(carry, n_frames, every, records)
            memories, failed = self._contact_steps(records, like)
            keep = done if failed is None else self._frames_before(records, failed, float(start.times[T]), done, every)
            if start is not None and (failed is not None or (status != OK and partial)):  # the good frames only
                carry = start
                Ts, Y, charts, done, partial, status = self._adaptive_call(carry, keep, every, records)
                memories, _ = self._contact_steps(records, like)
        finally:
            self.n_rhs += sum(f.n_evals for f in self._fields)
            self._fields.clear()
        self._carry = carry  # (the counters of the last call only: a redone call's first try is not a step taken)
        self.n_rhs += int(carry.counts[EVALS])
        self.n_steps += int(carry.counts[STEPS])
        self.n_rejected += int(carry.counts[REJECTED])
        self.chart_switches += carry.switches
        if memories:
            self._span_memory = memories[-2] if len(memories) > 1 else like.memory
            self._inner = like.replace(memory=memories[-1])
        elif carry.counts[STEPS]:
            self._span_memory = None
        states = States(Ts, Y, charts, self.system.n_q, self.system.n_v,
                        self._memories_at(Ts[:done], records, memories, like.memory),
                        (like.element_memory,) * done)
        self.n_samples += done * every
        if states:
            self.state = states[-1]
        if status == FULL:
            self._capacity *= 2  # the next call records more steps (its frame needs them)
        elif status != OK or failed is not None:  # the Python loop takes the step (and raises its diagnosis),
            # or the event the driver cut its step at (its handler, the rest of the sample)
            row = int(carry.flags[CUT]) - 1
            self._to_python()
            if status == EVENT and failed is None:  # (the cut step's end is the inner state now)
                self._pending = self._contacts.event_rows(like)[row].name
        return states

    def _fixed_steps_per_sample(self) -> int:
        """Fixed steps to the next sample within the contacts' step bound (``FixedSteps``; events add
        the step cut at them, which ends the driver's call)."""
        bound = self._contacts.step_bound(self._inner)
        return 1 if bound >= self.dt else math.ceil(self.dt / bound)

    def _step_records(self):
        """The kernel's step records (emptied) when a law contact acts at the inner state (its steps'
        bookkeeping is ``ContactStepping.after_step``'s, after the call), else None."""
        from viz3d.kernel import StepRecords

        c = self._contacts
        if c is None or not c.law_contact_under_way(self._inner):
            return None
        if self._records is None or self._records.capacity != self._capacity:
            self._records = StepRecords.empty(self._capacity, self._inner.y.shape[0], self._inner.chart.shape[0],
                                              self._kernel.data.n_contacts)
        self._records.n[0] = 0
        return self._records

    def _contact_steps(self, records, like: State) -> tuple[list[tuple], int | None]:
        """``ContactStepping.after_steps`` on the recorded steps in order, as the Python loop runs ``after_step``
        after each step: the contacts' memory after each step, and the index of the first step whose
        check fails (None when none does)."""
        if records is None:
            return [], None
        n = int(records.n[0])
        errors = records.err[:n] if self.controller is not None else None  # (fixed steps have no error estimate)
        return self._contacts.after_steps(like, records.t[:n], records.y[:n], records.chart[:n], errors, records.mem[:n])

    def _frames_before(self, records, r: int, t_call: float, done: int, every: int) -> int:
        """How many of the ``done`` frames of a call started at ``t_call`` [s] the Python loop outputs
        before it takes recorded step ``r`` (each frame's last sample at or before the step's start)."""
        t_start = float(records.t[r - 1]) if r > 0 else t_call
        keep = 0
        for f in range(done):
            target = self.t0 + (self.n_samples + (f + 1) * every) * self.dt
            if target > t_start + 1e-12 * max(abs(target), self.dt):
                break
            keep += 1
        return keep

    @staticmethod
    def _memories_at(ts: np.ndarray, records, memories: Sequence[tuple], memory: tuple) -> Sequence[tuple]:
        """The contacts' memory of each sample at ``ts`` (N,) [s]: after the last recorded step ending
        by its time (``memory``, that at the call's start, before the first), each built when indexed."""
        if not memories:
            return (memory,) * ts.shape[0]
        return _SampleMemories(np.searchsorted(records.t[: len(memories)], ts, side="right").tolist(), memories, memory)

    def _adaptive_call(self, carry, n_frames: int, every: int, records=None) -> tuple:
        """The kernel's ``adaptive`` call from ``carry`` (its counters and ``records`` emptied first)."""
        carry.counts[:], carry.switches[:] = 0, 0
        if records is not None:
            records.n[0] = 0
        s, contacts = self._inner, self._contacts
        events = contacts.event_rows(s) if contacts is not None else ()
        return self._kernel.adaptive(carry, n_frames, every, self.n_samples, self.t0, self.dt, self.t_end,
                                     self._step_controller(s), events, s.memory, contacts is not None,
                                     self.blowup_speed, ADAPTIVE_MAX_TURN, records,
                                     contacts is not None and contacts.replants)

    def _step_controller(self, s: State) -> Controller | FixedSteps:
        """The controller of the steps from ``s`` (fixed steps: ``FixedSteps`` of ``dt``): ``max_step``
        within the contacts' step bound (``ContactStepping.step_bound``)."""
        bound = self._contacts.step_bound(s) if self._contacts is not None else np.inf
        if self.controller is None:
            return FixedSteps(self.dt, bound)
        return self.controller if bound >= self.controller.max_step else replace(self.controller, max_step=bound)

    def _to_kernel(self):
        """The adaptive state as the kernel's carry (the first step chosen here, as the Python path
        does, when the run has none yet)."""
        from viz3d.kernel import AdaptiveCarry
        from viz3d.kernel.adaptive import DENSE, H, HAS_F, SPAN, SPAN_H, T, T0, T1

        if self._carry is not None:
            return self._carry
        s = self._inner
        if self._h is None and self.controller is None:
            self._h = self.dt
        if self._h is None:
            rhs = self._field(s.chart, s.memory, s.element_memory)
            self._f = rhs(s.t, s.y) if self._f is None else self._f
            self._h = min(self._step_controller(s).first_step(rhs, s.t, s.y, self._f, error_order(self.integrator)),
                          self._turn_limit(self._f))
        self._span_memory = None if self._span is None else self._span.start.memory
        c = AdaptiveCarry.empty(s.y.shape[0], s.chart.shape[0], self.system.n_bodies, self._kernel.tableau)
        c.y[:], c.chart[:], c.times[T], c.times[H] = s.y, s.chart, s.t, self._h
        if self._f is not None:
            c.f[:], c.flags[HAS_F] = self._f, 1
        span = self._span
        if span is not None:
            c.times[T0], c.times[T1], c.times[SPAN_H] = span.t0, span.t1, span.h
            c.y0[:], c.chart0[:] = span.start.y, span.start.chart
            c.K[: span.stages.shape[0]], c.f1[:], c.flags[SPAN] = span.stages, span.f1, 1
            if isinstance(span.interpolant, DenseInterpolant):
                c.Q[:], c.flags[DENSE] = span.interpolant.Q, 1
        return c

    def _to_python(self) -> None:
        """Hand the adaptive state from the kernel's carry back to the Python path (no-op when it
        has it)."""
        from viz3d.kernel.adaptive import CUT, DENSE, H, HAS_F, SPAN, SPAN_H, T, T0, T1

        c, self._carry = self._carry, None
        if c is None:
            return
        like, system = self._inner, self.system
        self._inner = _state_at(system, float(c.times[T]), c.y.copy(), like.replace(chart=c.chart.copy()))
        self._f = c.f.copy() if c.flags[HAS_F] else None
        self._h = float(c.times[H])
        if not c.flags[SPAN] or self.controller is None:  # (fixed steps sample no span)
            return
        t0, t1 = float(c.times[T0]), float(c.times[T1])
        memory = like.memory if self._span_memory is None else self._span_memory
        start = _state_at(system, t0, c.y0.copy(), like.replace(chart=c.chart0.copy(), memory=memory))
        if c.flags[CUT]:  # a step cut at an event: sampled by cubic Hermite, as _event_step's
            f0, y1, f1 = c.K[0].copy(), c.y_cut.copy(), c.f1.copy()
            self._span = _Span(t0, t1, start, system, lambda: hermite_interpolant(t0, start.y, f0, t1, y1, f1),
                               h=float(c.times[SPAN_H]))
            return
        stages, h = c.K[: len(self._kernel.tableau.b)].copy(), float(c.times[SPAN_H])
        rhs = self._field(start.chart, start.memory, start.element_memory)
        self._span = self._rk_span(rhs, start, t1, h, StepResult(None, f0=stages[0], stages=stages), c.f1.copy())
        if c.flags[DENSE]:
            self._span.interpolant = DenseInterpolant(t0, start.y, h, c.Q.copy())

    def _rk_span(self, rhs, s: State, t1: float, h: float, res: StepResult, f1: np.ndarray) -> "_Span":
        """The span of an accepted step ``res`` of length ``h`` from ``s`` to ``t1`` (its interpolant
        built on first use)."""
        method = self.integrator
        return _Span(s.t, t1, s, self.system, lambda: method.interpolant(rhs, s.t, s.y, h, res, f1), res.stages, f1)

    # ------------------------------------------------------------------ between steps

    def _accept(self, raw: State, f1, h: float, post_step: bool = True) -> State:
        """An integration step's end state after projections, checks, normalization, re-charting and
        the force elements' new memory; keeps ``f1`` (the vector field at ``raw``) for the next step
        while ``raw`` and that memory are unchanged."""
        new = self._settle(raw, f1, h, post_step)
        if not self._remembers:
            return new
        self._f = None  # f1 was evaluated with the step's memory
        return new.replace(element_memory=element_memory(self.system, new))

    def _post_step(self, raw: State) -> State:
        """``formulation.post_step`` of ``raw``: the ``projection`` formulation's projections in the
        kernel when it covers the system (for the steps the kernel does not take itself: implicit
        methods, adaptive steps at contacts), else, or when the compiled projection fails, the NumPy
        path (which raises the diagnosis)."""
        k = self._kernel
        if k is not None and k.data.model.projects == 1:
            y, ok = k.project(raw.t, raw.y, raw.chart, raw.memory)
            if ok:
                return _state_at(self.system, raw.t, y, raw)
        return self.formulation.post_step(self.system, raw)

    def _settle(self, raw: State, f1, h: float, post_step: bool) -> State:
        """``_accept`` but for the force elements' memory."""
        new = self._post_step(raw) if post_step else raw
        if self._kernel is None or not self._kernel.state_ok(new.y, h, self.blowup_speed):
            check_state(self.system, new, self.blowup_speed, h)
        W_r, theta0 = self.system.split_q(new.q)
        normal = self.system.rotation.normalize(theta0)
        theta, chart, switched = self.system.rotation.rechart(normal, new.chart)
        self.chart_switches[self.system.frame_body] += switched
        self.n_steps += 1
        if new is raw and normal is theta0 and not np.any(switched):
            self._f = f1
            return new
        self._f = None
        return new.replace(q=self.system.with_frames(new.q, W_r, theta), chart=chart)

    def _turn_limit(self, f: np.ndarray) -> float:
        """Longest adaptive step [s] that turns no orientation coordinate by more than
        ``ADAPTIVE_MAX_TURN`` at the rates in ``f`` (charts are only switched between steps)."""
        rates = self.system.split_q(f[: self.system.n_q])[1]
        fastest = np.max(np.abs(rates), initial=0.0)
        return ADAPTIVE_MAX_TURN / fastest if fastest > 0.0 else np.inf

    def _field(self, chart, memory: tuple = (), elements: tuple = ()) -> VectorField:
        rhs = VectorField(self.system, self.formulation, chart, memory, elements)
        self._fields.append(rhs)
        if self._kernel is not None:  # evaluations in the compiled kernel (same interface)
            from viz3d.kernel import CompiledField

            return CompiledField(rhs, self._kernel)
        return rhs

    def _singular_message(self, s: State) -> str:
        rows = constraint_rows(self.system.joints, body_state(self.system, s.q, s.v, s.chart, s.t))
        names = redundant_joints(self.system, rows.J, rows.Je)
        who = f"joints {', '.join(map(repr, names))} are redundant or degenerate" if names else "constraint matrix lost rank"
        return f"t = {s.t:.6g} s: singular constraint Jacobian: {who}"


def hermite_interpolant(t0, y0, f0, t1, y1, f1) -> Callable:
    """The cubic Hermite interpolant of a step, as a function of ``t``."""
    return lambda t: hermite(t0, y0, f0, t1, y1, f1, t)


def _state_at(system: System, t: float, y: np.ndarray, like: State) -> State:
    """The state with ``y = [q, v, w]`` at ``t``, in ``like``'s chart, contact phases and force
    elements' memory."""
    q, v, w = system.split_y(y)
    return State(t, q, v, like.chart, w, like.memory, like.element_memory)


class _Span:
    """One accepted adaptive step ``[t0, t1]`` of length ``h`` from ``start`` (its chart and contact
    phases); its interpolant is built on first use (a continuous extension may cost extra
    evaluations, e.g. three for DOP853). ``stages`` (s, n) and ``f1`` (n,): the step's RK stages
    and the field at its end, which the kernel's adaptive driver takes over (None for a step cut
    at an event, sampled by cubic Hermite)."""

    def __init__(self, t0: float, t1: float, start: State, system: System, make_interpolant: Callable,
                 stages: np.ndarray | None = None, f1: np.ndarray | None = None, h: float | None = None):
        self.t0, self.t1, self.start, self.system = t0, t1, start, system
        self.h = t1 - t0 if h is None else h
        self.stages, self.f1 = stages, f1
        self._make, self.interpolant = make_interpolant, None

    @property
    def chart(self) -> np.ndarray:
        return self.start.chart

    def sample(self, t: float) -> State:
        """The interpolated state at ``t0 <= t <= t1`` (chart and phases of the step)."""
        if self.interpolant is None:
            with np.errstate(all="ignore"):
                self.interpolant = self._make()
        return _state_at(self.system, t, self.interpolant(t), self.start)


def _compiled(system, integrator, formulation):
    """``(KernelStepper, "compiled kernel")`` when the kernel covers this system and formulation, else
    ``(None, "NumPy path, not covered by the compiled kernel: <why>")``. Its whole-step path serves
    fixed explicit RK steps; its right-hand side serves every method; a formulation that steps
    itself (ALI3-P) takes its steps through it (``viz3d.kernel.ali3p``)."""
    from viz3d.kernel import KernelStepper, kernel_coverage

    data, why = kernel_coverage(system, formulation)
    if data is None:
        return None, f"NumPy path, not covered by the compiled kernel: {why}"
    tableau = None if formulation.integrator is not None else getattr(integrator, "tableau", None)
    return KernelStepper(data, tableau), "compiled kernel"


def _trajectory(system: System, cols: FrameColumns, status: str, scene_json: str, chart_switches,
                extras: dict | None = None, **cost) -> Trajectory:
    """The run's ``Trajectory`` from its frames as columns."""
    b = system.bodies
    return Trajectory(
        t=cols.t, body_names=np.array(b.names), mass=b.mass.copy(), inertia_body=b.inertia.copy(),
        position=cols.W_r, rotation=cols.R_WB, euler=euler_from_matrix(cols.R_WB), velocity=cols.W_v,
        omega=cols.W_omega, energy_kinetic=cols.energy_kinetic, energy_potential=cols.energy_potential,
        energy_total=cols.energy_kinetic + cols.energy_potential, constraint_violation=cols.constraint_violation,
        joint_names=np.array(system.joint_names, dtype=str), reaction_force=cols.reaction_force,
        chart_switches=np.asarray(chart_switches, int), status=status, scene_json=scene_json, extras=extras or {},
        **cost)


def simulate(scene: Scene | str | Path, overrides=None, *, t_end: float | None = None, dt: float | None = None,
             progress: bool = False, sinks: Sequence[Sink] = ()) -> Trajectory:
    """Run a scene headless and return its ``Trajectory``.

    Parameters
    ----------
    scene : Scene, or a path to a scene file
    overrides : "key.path=value" strings or mapping (only with a path)
    t_end, dt : float, optional
        Override ``sim.t_end`` and ``sim.dt`` [s] (on adaptive runs ``dt`` is the interval between
        returned states and frames), validated as the scene keys are (``SceneError`` otherwise).
    progress : bool
        Draw a progress bar on stderr when the run is projected to take over 2 s.
    sinks : sequence of Sink
        Consumers of the run's frames (e.g. ``RerunRecorder``); opened and closed here.
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene, overrides)
    elif overrides:
        raise ValueError("overrides apply when loading: use load_scene(path, overrides)")
    scene = with_sim(scene, t_end=t_end, dt=dt)
    return simulate_built(scene, *build(scene), progress=progress, sinks=sinks)


def simulate_built(scene: Scene, system: System, state: State, progress: bool = False,
                   sinks: Sequence[Sink] = ()) -> Trajectory:
    """``simulate`` of ``scene`` once it is built (``system, state = build(scene)``): the simulation,
    its run, frames and ``Trajectory`` (what ``benchmarks/bench_peers.py`` times, as the peers' clocks
    start once their models are built)."""
    sim_cfg = scene.data["sim"]
    try:
        sim = Simulation(system, state, make_integrator_from(sim_cfg), make_formulation(sim_cfg), sim_cfg["dt"],
                         sim_cfg["blowup_speed"], make_controller(sim_cfg), compiled=sim_cfg["compiled"],
                         departures=Departures.of(scene, system))
    except MethodError as exc:
        raise SceneError(scene.source(), exc.key, exc.expected, exc.got) from None
    return run(sim, scene, progress, sinks)


def check_methods(scene: Scene) -> None:
    """Refuse a scene whose integrator, formulation, rotation coordinates and tolerance cannot run
    together (``viz3d.methods.check_combination``): ``SceneError`` naming the key, before anything
    is built or announced."""
    sim = scene.data["sim"]
    try:
        check_combination(sim["integrator"], sim["formulation"], sim["rotation"], sim.get("rtol"))
    except MethodError as exc:
        raise SceneError(scene.source(), exc.key, exc.expected, exc.got) from None


def run_checks(sim: Simulation, scene: Scene) -> tuple[Callable, bool]:
    """The checks of a run's output frames, ``check(cols, states)`` (``cols``: their
    ``FrameColumns``): constraint violation, energy growth of a conservative run, rigid drives over
    their capacity (``SimulationFailure``), limited drives stalled at it and the goal of a ``[stowage]``
    table with ``settle_time`` (``RunComplete``); and whether the run may end so. The live viewer
    applies the same checks."""
    cfg = scene.data["sim"]
    energy = EnergyWatch(sim.system, cfg["blowup_energy"], sim.system.conservative)
    limits = {d["name"]: (d["capacity"], d["capacity_time"], "servo_gain" in d) for d in scene.data["drives"]
              if "capacity" in d}
    capacity = CapacityWatch(limits)
    goal = None
    if "stowage" in scene.data:
        keys = [f"joint/{n}/{c}" for js in sim.system.joints.joints for n in js.names
                for c in getattr(js, "coordinate_names", ())]
        goal = seated_stop(scene.data["stowage"], sim.system.bodies.names, drive_coordinate(scene.data, keys))

    def check(cols, states):
        check_violation(lambda state: sim.source(state).system, states, cols.constraint_violation,
                        cfg["blowup_violation"])
        capacity.check(cols.t, cols.scalars)
        energy.check(cols)
        if goal is not None:
            goal(cols, states)

    return check, goal is not None or any(limited for _, _, limited in limits.values())


class _SampleMemories(collections.abc.Sequence):
    """``Simulation._memories_at``: sample ``i``'s contact memory is ``memories[rs[i] - 1]`` (``memory``
    where ``rs[i]`` is 0), looked up when indexed (a call's samples that no one reads build none)."""

    def __init__(self, rs: list[int], memories: Sequence[tuple], memory: tuple):
        self.rs, self.memories, self.memory = rs, memories, memory

    def __len__(self) -> int:
        return len(self.rs)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return tuple(self[k] for k in range(len(self))[i])
        r = self.rs[i]
        return self.memories[r - 1] if r else self.memory


def run(sim: Simulation, scene: Scene, progress: bool = False, sinks: Sequence[Sink] = ()) -> Trajectory:
    """Drive ``sim`` to ``sim.t_end``: the states every ``output_dt`` into the trajectory, and to the
    ``sinks`` the frames of the finer instants they ask for (``Sink.frame_dt``) and the events, in
    time order. The states come from the kernel in batched calls when it takes them
    (``Simulation.output_states``), at the finest interval anyone needs; their frames are computed
    a chunk at a time (``viz3d.columns.StateLog``) and checked before the sinks get them."""
    cfg = scene.data["sim"]
    n_steps = max(1, math.ceil(cfg["t_end"] / cfg["dt"] - 1e-9))
    every = max(1, round(cfg.get("output_dt", max(DEFAULT_OUTPUT_DT, cfg["dt"])) / cfg["dt"]))
    sim.t_end = min(sim.t_end, sim.t0 + (sim.n_samples + n_steps) * sim.dt)  # the last sample's time, as stepped to
    bar = ProgressBar(n_steps) if progress else None
    status, wall0, internal, failure = "ok", time.perf_counter(), None, None
    check, has_goal = run_checks(sim, scene)
    with InterruptGuard() as guard:
        emitter = _Emitter(sim, sinks, guard)
        log = emitter.start(check)
        try:
            emitter.open(scene)
            fine = emitter.interval(every, cfg["dt"])  # steps between the instants anyone needs (divides every)
            if has_goal:  # a run that may end at a goal checks its frames every GOAL_CHECK_INTERVAL of simulated time
                log.chunk = max(1, round(GOAL_CHECK_INTERVAL / (fine * cfg["dt"])))
            else:
                log.chunk = chunk_length(sim.system, fine)
            log.record(sim.state)
            n, n0 = 0, sim.n_samples
            while n < n_steps:  # to the next instant in one call, or as many instants as fit the chunk
                if sim.batches_frames and n % fine == 0 and n_steps - n >= fine:
                    want = min((n_steps - n) // fine, log.room)
                    states = sim.output_states(want, fine)
                    ns = n + fine * np.arange(1, len(states) + 1)
                    n = sim.n_samples - n0  # (with contacts, maybe inside the next instant's interval: the samples of a call cut at an event)
                    log.record_all(States.of(states), (ns % every == 0) | (ns == n_steps))  # (may compute and check the chunk)
                    if bar is not None:
                        bar.update(n)
                    if len(states) == want:
                        continue  # else the failing instant below, one step at a time, for its diagnosis
                k = min(fine - n % fine, n_steps - n)
                sim.steps(k)
                n += k
                emitter.events()
                log.record(sim.state, n % every == 0 or n == n_steps)
                if bar is not None:
                    bar.update(n)
            emitter.events(last=True)
            log.flush()
        except SimulationFailure as exc:
            failure = _earliest_failure(log, exc)
            if isinstance(failure, RunComplete):  # the goal came first: the run ended there, status ok
                emitter.announce([(log.parts[-1].t[-1], str(failure))])
                failure = None
            else:
                status = str(failure)
        except RunComplete as done:  # the goal reached: frames up to it kept, status ok
            emitter.announce([(log.parts[-1].t[-1], str(done))])
        except KeyboardInterrupt:
            status = "interrupted"
        except Exception as exc:  # a defect, not an input error: keep the frames and report it loudly
            import traceback

            traceback.print_exc()
            status, internal = "internal error", f"{type(exc).__name__}: {exc}"
        finally:
            if bar is not None:
                bar.close()
            with guard.held(deliver=False):  # the run ends here anyway: an interrupt now cuts no file
                if status != "ok":  # the frames of events before the stop, unchecked (the run has stopped)
                    log.check = None
                    emitter.events(last=True)
                cols = log.columns(check=False)  # (the instants computed before the stop, to the sinks too)
                t_stop = cols.t[-1] if len(cols) else sim.state.t  # (the state may be a chunk ahead of its frames)
                if status == "interrupted":
                    status = f"interrupted at t = {t_stop:.6g} s"
                elif internal is not None:
                    status = f"stopped by an internal error at t = {t_stop:.6g} s: {internal}"
                verdict = _verdict(scene, cols, sim.layout.bodies.names, failure)
                emitter.announce(run_events(scene.data, cols) + (sim.departures.log if sim.departures else [])
                                 + ([(verdict.time, f"{verdict.outcome}: {verdict.reason}")] if verdict else []))
                emitter.close(status, t_stop)  # (events after the last returned state are not on the trajectory)
    wall = time.perf_counter() - wall0
    extras = run_extras(sim, scene, cols) if sim.system.contacts or sim.system.outputs else None
    if joints := {**ledger_fields(sim.layout, cols), **joint_fields(sim.layout, cols), **element_fields(sim.layout, cols)}:
        extras = {**(extras or {}), **joints}
    if verdict is not None:
        tension = cols.scalars.get("stowage/hawse_tension")
        extras = {**(extras or {}), **verdict_fields(verdict, scene.data["stowage"], tension)}
    return _trajectory(sim.layout, cols, status, scene_json(scene, sim), sim.layout_chart_switches, extras, wall_time=wall,
                       n_steps=sim.n_steps, n_rhs=sim.n_rhs)


def _verdict(scene: Scene, cols, body_names, failure: SimulationFailure | None):
    """The run's ``viz3d.stowage.Verdict`` (None without a ``[stowage]`` table). A run that failed has
    one only if its drive jammed before it failed (``stopped``): it neither seated nor fell short; and
    none at all if it failed on its energy (``EnergyFailure``: its frames' numbers are wrong)."""
    if isinstance(failure, EnergyFailure):
        return None
    verdict = run_verdict(scene.data, cols, body_names, failure is not None)
    return verdict if failure is None or verdict is None or verdict.outcome == "jammed" else None


def _earliest_failure(log: StateLog, exc: SimulationFailure) -> SimulationFailure | RunComplete:
    """The earliest failure (its diagnosis is ``str``): a step that failed (``exc.frame`` None) may
    follow frames, not yet checked, whose check fails first, or whose goal was reached (``RunComplete``:
    a limited drive stalled, an anchor seated; the run ended there, before the step failed)."""
    if exc.frame is None:
        try:
            log.flush()
        except (SimulationFailure, RunComplete) as earlier:
            return earlier
    return exc


class _Emitter:
    """Opens and closes the run's sinks and hands them, through the trajectory's ``StateLog``, the
    frames of the instants they need and the events, in time order."""

    def __init__(self, sim, sinks, guard: InterruptGuard):
        self.sim, self.sinks, self.guard = sim, list(sinks), guard
        self.opened: list[Sink] = []
        self.logged = 0
        self.log: StateLog | None = None
        self.last_t: dict[int, float] = {}  # the time of each sink's last frame [s]

    def open(self, scene: Scene) -> None:
        if self.sinks:
            from viz3d.scene.visuals import flexible_drawings, scene_visuals

            visuals = scene_visuals(scene, self.sim.system)
            self.log.drawings = flexible_drawings(scene, self.sim.system)
            for s in self.sinks:
                s.open(visuals)
                self.opened.append(s)

    def interval(self, every: int, dt: float) -> int:
        """Steps between the instants the run computes frames of: the greatest common divisor of
        the output interval ``every`` and each opened sink's ``frame_dt`` (in steps of ``dt``)."""
        fine = every
        for s in self.opened:
            if s.frame_dt is not None:
                fine = math.gcd(fine, max(1, round(s.frame_dt / dt)))
        return fine

    def start(self, check) -> StateLog:
        """The run's ``StateLog``, emitting to the sinks when there are any."""
        emit = self._emit if self.sinks else None
        self.log = StateLog(self.sim, check, CHUNK, emit, self.guard.held)
        return self.log

    def events(self, last: bool = False) -> None:
        """The states at the contact events up to the current state (every sink gets them; they are
        on the trajectory), and their texts (adaptive steps may have run ahead: later ones wait for
        their time, unless this is the ``last`` call)."""
        t = self.sim.state.t
        for state in self.sim.drain_events(t):
            self.log.record(state)
        contacts = self.sim.contacts
        if contacts is not None:
            while self.logged < len(contacts.log) and (last or contacts.log[self.logged][0] <= t):
                self.log.note(*contacts.log[self.logged])
                self.logged += 1

    def _emit(self, notes: list, frame: Frame | None, output: bool) -> None:
        """``StateLog``'s ``emit``: the texts, then the frame to every sink that wants it (an output
        instant's to all; else to those whose ``frame_dt`` has passed since their last frame)."""
        for t, text in notes:
            for s in self.opened:
                s.event(t, text)
        if frame is None:
            return
        for k, s in enumerate(self.opened):
            if output or frame_due(s, frame.t, self.last_t.get(k, -np.inf)):
                self.last_t[k] = frame.t
                s.log(frame)

    def announce(self, events: list[tuple[float, str]]) -> None:
        """Milestones found after the run (``viz3d.stowage.run_events``, the verdict) to every sink."""
        for t, text in sorted(events):
            for s in self.opened:
                s.event(t, text)

    def close(self, status: str, t: float) -> None:
        """The run's ``status`` to every sink at time ``t`` [s], then close them."""
        for s in self.opened:
            try:
                s.event(t, f"status: {status}", "info" if status == "ok" else "error")
            finally:
                s.close()


def scene_json(scene: Scene, sim: Simulation) -> str:
    """The resolved scene plus what produced the run (version, integrator, step, source):
    ``json.dumps({"scene": scene.data, "run": meta}, sort_keys=True)``, the scene's part as the scene
    keeps it (``Scene.json_text``)."""
    from viz3d import __version__

    cfg = scene.data["sim"]
    meta = {"viz3d_version": __version__, "integrator": cfg["integrator"], "dt": cfg["dt"],
            "formulation": cfg["formulation"], "rotation": cfg["rotation"], "source": str(scene.path),
            "overrides": list(scene.overrides),
            "conservative": sim.system.conservative, "kernel": sim.kernel_note}
    return f'{{"run": {json.dumps(meta, sort_keys=True)}, "scene": {scene.json_text}}}'


class ProgressBar:
    """A one-line stderr progress bar that appears only for runs projected to exceed 2 s."""

    def __init__(self, total: int, stream=None):
        self.total, self.stream = total, stream or sys.stderr
        self.enabled = stream is not None or self.stream.isatty()  # no bar in logs and pipes
        self.start = time.perf_counter()
        self.shown, self.last = False, 0.0

    def update(self, n: int) -> None:
        now = time.perf_counter()
        if not self.enabled or now - self.last < 0.2:
            return
        self.last = now
        elapsed = now - self.start
        eta = elapsed / n * (self.total - n)
        if not self.shown and elapsed + eta < PROGRESS_AFTER:
            return
        self.shown = True
        frac = n / self.total
        bar = "#" * int(30 * frac)
        self.stream.write(f"\r[{bar:<30}] {100 * frac:5.1f}%  {elapsed:6.1f} s elapsed, {eta:6.1f} s left")
        self.stream.flush()

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()

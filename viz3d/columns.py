"""A run's output frames as columns, computed many states at a time.

The trajectory needs, per output instant, what a ``viz3d.frames.Frame`` holds minus the drawing
(centres of mass, rotations, velocities, energies, constraint violation, joint reactions and the
named scalars: contact forces and indentations, the energy ledger, gauges). ``StateLog`` keeps the
states of a run's output instants and turns them into ``FrameColumns`` a chunk at a time:

* with the compiled kernel (``viz3d.kernel.KernelStepper.sample``), one call per chunk evaluates
  every state's kinematics, multipliers, gaps, rigid kinetic and force-element potential energies;
  the rest is array arithmetic, plus per-state NumPy only where the kernel has nothing to offer:
  states with a contact acting (its law's elastic energy and force), flexible bodies' energies,
  the coordinates of joints on flexible sections, and output elements (gauges);
* without it, each state's ``Frame`` from ``frame_from_state`` (the NumPy reference).

A run with sinks logs, besides its output instants, the finer ones its sinks ask for; the sinks get
each instant's ``Frame`` built from its row of the columns (``frame_of``: the scalars read from the
columns when asked for, the drawing evaluated only for the frames a sink draws).
"""

from __future__ import annotations

import itertools
import operator
from collections.abc import Mapping, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field, fields, replace
from typing import Callable, Iterator

import numpy as np

from viz3d._typing import FloatArray
from viz3d.dynamics import flexible_kinetics
from viz3d.contact.contacts import Gap
from viz3d.departures import expand
from viz3d.frames import Frame, drawing_of, ledger_scalars
from viz3d.joints import drive_efforts, relative_coordinates
from viz3d.kinematics import Configuration, Pose, Twist
from viz3d.system import State, States, System, state_size

#: States turned into columns at a time, at least (the run's health checks on energy and constraint
#: violation see frames in chunks this long; ``chunk_length``).
CHUNK = 256
#: ... and more while a chunk's arrays (the kernel's samples, the states, the columns) stay within
#: this many bytes: each chunk costs about 0.1 ms of Python (a kernel call, its columns and checks),
#: 0.8 ms of the torque-free body's 2000 frames in chunks of 256 (256 frames of a 50-link chain hold
#: about 11 MB: large systems keep ``CHUNK``) ...
CHUNK_BYTES = 2**22
#: ... and take no more steps than this (Ctrl-C waits for a kernel call to end, and a chunk whose
#: frame fails is stepped again up to it): about 35 ms of the torque-free body, 0.3 s of a 10-link chain.
CHUNK_STEPS = 2**14


def chunk_length(system: System, steps: int) -> int:
    """States per chunk of ``system``'s run, ``steps`` steps (or adaptive samples) apart: ``CHUNK``, or
    as many as take at most ``CHUNK_STEPS`` and hold at most ``CHUNK_BYTES`` of the kernel's samples
    (``viz3d.kernel.Samples``: 21 floats per body and the ground, 14 per constraint row, 11 per
    contact, 3 more), the states (``y``, 9 per chart, the time) and the columns (18 per body; 3 per
    row: the joints' reactions, coordinates and rates; 2 per contact; 10 more: energies, violation
    and the energy ledger). With flexible bodies, ``CHUNK``: their columns take matrix
    products over a chunk's states (``_centres_of_mass``), whose rounding depends on the chunk's
    length (by 3e-17 m/s at one frame of ``impact_clamped_bar`` in chunks of 1327 against 256)."""
    if system.bodies.flexible:
        return CHUNK
    n_y = system.n_q + system.n_v + system.n_aux
    k = sum(c.k for c in system.contacts)
    floats = 21 * (system.n_bodies + 1) + 18 * system.n_bodies + 17 * system.n_c + 13 * k + n_y + 9 * system.n_frames + 14
    return max(CHUNK, min(CHUNK_BYTES // (8 * floats), CHUNK_STEPS // steps))


@dataclass
class FrameColumns:
    """Output frames as arrays over n instants (nb bodies, nj joints).

    Attributes
    ----------
    t : (n,) [s]
    W_r, W_v, W_omega : (n, nb, 3)
        Centres of mass [m], their velocities [m/s], angular velocities [rad/s], world.
    R_WB : (n, nb, 3, 3)
    energy_kinetic, energy_potential, constraint_violation : (n,) [J, J, m]
    reaction_force : (n, nj, 3) [N]
    scalars : dict of str -> (n,)
        ``Frame.scalars`` as columns (nan where a frame lacks the key).
    """

    t: FloatArray
    W_r: FloatArray
    R_WB: FloatArray
    W_v: FloatArray
    W_omega: FloatArray
    energy_kinetic: FloatArray
    energy_potential: FloatArray
    constraint_violation: FloatArray
    reaction_force: FloatArray
    scalars: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return self.t.shape[0]

    @classmethod
    def from_frames(cls, frames: list[Frame], nb: int, nj: int) -> "FrameColumns":
        """Columns of ``frames`` (the NumPy path)."""
        n = len(frames)

        def stack(key, shape):
            return np.array([getattr(f, key) for f in frames], dtype=float).reshape((n,) + shape)

        keys = list(dict.fromkeys(k for f in frames for k in f.scalars))
        return cls(stack("t", ()), stack("W_r", (nb, 3)), stack("R_WB", (nb, 3, 3)), stack("W_v", (nb, 3)),
                   stack("W_omega", (nb, 3)), stack("energy_kinetic", ()), stack("energy_potential", ()),
                   stack("constraint_violation", ()), stack("reaction_force", (nj, 3)),
                   {k: np.array([f.scalars.get(k, np.nan) for f in frames], float) for k in keys})

    @classmethod
    def join(cls, parts: list["FrameColumns"], nb: int, nj: int) -> "FrameColumns":
        """One set of columns from consecutive ones (scalars missing in a part are nan there; one
        part is returned as it is)."""
        if not parts:
            return cls.from_frames([], nb, nj)
        if len(parts) == 1:
            return parts[0]
        keys = list(dict.fromkeys(k for p in parts for k in p.scalars))
        arrays = {f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(cls) if f.name != "scalars"}
        scalars = {k: np.concatenate([p.scalars.get(k, np.full(len(p), np.nan)) for p in parts]) for k in keys}
        return cls(**arrays, scalars=scalars)

    def head(self, n: int) -> "FrameColumns":
        """The first ``n`` frames."""
        return self.take(slice(0, n))

    def take(self, rows) -> "FrameColumns":
        """The frames ``rows`` (a slice or an index array)."""
        arrays = {f.name: getattr(self, f.name)[rows] for f in fields(self) if f.name != "scalars"}
        return FrameColumns(**arrays, scalars={k: v[rows] for k, v in self.scalars.items()})


class ColumnRow(Mapping):
    """One frame's scalars read from the columns on access (``Frame.scalars`` of sampled frames:
    a frame whose scalars nobody reads does not copy them)."""

    def __init__(self, scalars: dict, i: int):
        self._scalars, self._i = scalars, i

    def __getitem__(self, key: str) -> float:
        return float(self._scalars[key][self._i])

    def __iter__(self) -> Iterator[str]:
        return iter(self._scalars)

    def __len__(self) -> int:
        return len(self._scalars)


class StateLog:
    """The states of a run's output instants, turned into ``FrameColumns`` a chunk at a time; with
    ``emit``, also the finer instants the run's sinks ask for, whose frames (and the texts noted
    between them) are handed on in time order once their chunk is computed and checked.

    Parameters
    ----------
    sim : viz3d.simulate.Simulation
        The run (its system, formulation, compiled kernel and contact stepping).
    check : callable, optional
        ``check(columns, states)`` on the output instants of every chunk as it is computed (the
        run's health checks); it may raise.
    chunk : int
        States (all instants) per chunk.
    emit : callable, optional
        ``emit(notes, frame, output)``: the texts ``(t, text)`` noted before an instant, then its
        ``Frame`` and whether it is an output instant (``frame`` None: texts noted after the last
        instant); called inside ``hold()``.
    hold : callable, optional
        A context manager no interrupt cuts (``viz3d.interrupts.InterruptGuard.held``): an instant is
        handed on and kept in the trajectory, or neither.
    drawings : tuple of FlexibleDrawing
        The flexible bodies drawn in the emitted frames.
    """

    def __init__(self, sim, check=None, chunk: int = CHUNK, emit: Callable | None = None, hold: Callable | None = None,
                 drawings: tuple = ()):
        self.sim, self.check, self.chunk = sim, check, chunk
        self.emit, self.hold, self.drawings = emit, hold or nullcontext, drawings
        self.pieces: list[States] = []                   # the instants kept, in batches
        self.outputs: list[np.ndarray] = []              # per batch: which are output instants
        self.kept = 0                                    # instants kept
        self.notes: list[tuple[int, float, str]] = []   # (instant it precedes, t, text)
        self.handed = 0                                  # instants of the chunk being flushed handed on
        self.parts: list[FrameColumns] = []
        system = sim.system
        self.nb, self.nj = system.n_bodies, len(system.joint_names)

    @property
    def room(self) -> int:
        """Instants that can be recorded before the chunk is computed (at least 1)."""
        return max(1, self.chunk - self.kept)

    def record(self, state: State, output: bool = True) -> None:
        """Keep ``state`` (an output instant, else one only the sinks get); compute the chunk when
        it is full."""
        self.record_all(States.of([state]), np.array([output]))

    def record_all(self, states: States, outputs: np.ndarray) -> None:
        """``record`` of each of ``states`` (``outputs`` (N,) bool: which are output instants) in one
        call: the kernel's batches of frames without a ``State`` each."""
        if self.emit is None and not outputs.all():
            states, outputs = states[outputs], outputs[outputs]
        if not len(states):
            return
        self.pieces.append(states)
        self.outputs.append(outputs)
        self.kept += len(states)
        if self.kept >= self.chunk:
            self.flush()

    def note(self, t: float, text: str) -> None:
        """A text for the sinks at time ``t`` [s], handed on after the instants recorded so far."""
        if self.emit is not None:
            self.notes.append((self.kept, t, text))

    def flush(self, check: bool = True) -> None:
        """Turn the instants kept so far into columns, check the output ones, hand the frames on;
        a check that fails at output frame ``i`` of the chunk (its exception's ``frame``) keeps (and
        hands on) the instants up to that frame only. An interrupt (inside ``hold``) leaves the
        instants not handed on yet pending (before the check) or drops them (after it)."""
        if not self.kept and not self.notes:
            return
        states = joined(self._sampled_pieces()) if self.pieces else None
        outputs = np.concatenate(self.outputs) if self.outputs else np.zeros(0, bool)
        cols, frame_at = self._columns(states) if states is not None else (None, None)
        out = np.flatnonzero(outputs)
        part = None if cols is None else cols if out.size == len(states) else cols.take(out)
        limit, failure = len(states), None
        with self.hold():
            try:
                if check and self.check is not None and part is not None:
                    self.check(part, states if out.size == len(states) else states[out])
            except Exception as exc:
                failure = exc
                if getattr(exc, "frame", None) is not None:
                    limit = int(out[exc.frame]) + 1
        notes, self.handed = self.notes, 0
        try:
            with self.hold():  # (without sinks the chunk is taken and kept at once)
                self.pieces, self.outputs, self.notes, self.kept = [], [], [], 0
                if self.emit is None:
                    self.handed = limit
            self._hand_on(notes, frame_at, outputs, limit)
        finally:
            if part is not None:
                self.parts.append(part.head(int(np.searchsorted(out, self.handed))))
        if failure is not None:
            raise failure

    def _sampled_pieces(self) -> list[States]:
        """The pieces kept, those without the kernel's samples (the run's first state, instants
        stepped in Python) sampled here when another piece has them: joined, the chunk keeps its
        samples instead of being sampled again whole (``chunk_frames``). Unchanged when the kernel
        does not sample or fails to (the chunk then takes the NumPy path there)."""
        pieces = self.pieces
        if all(p.samples is not None for p in pieces) or not any(p.samples is not None for p in pieces):
            return pieces
        steppers = [self.sim.source(p).kernel_sampler() for p in pieces]  # (each piece's generation's)
        if any(st is None for st in steppers):
            return pieces
        try:
            return [p if p.samples is not None else replace(p, samples=kernel_samples(st, p))
                    for p, st in zip(pieces, steppers)]
        except np.linalg.LinAlgError:
            return pieces

    def _hand_on(self, notes: list, frame_at, outputs: np.ndarray, limit: int) -> None:
        """Emit the first ``limit`` of the chunk's instants (``outputs``: which are output instants)
        with the notes before them (and the notes after the last one when all are emitted), counting
        them in ``handed`` (an exception, e.g. an interrupt, may stop it early: the instants handed
        on are kept)."""
        if self.emit is None:
            return
        k = 0
        for i in range(limit):
            with self.hold():
                k1 = k
                while k1 < len(notes) and notes[k1][0] <= i:
                    k1 += 1
                self.emit([x[1:] for x in notes[k:k1]], frame_at(i), bool(outputs[i]))
                k, self.handed = k1, i + 1
        if limit == len(outputs) and k < len(notes):
            with self.hold():
                self.emit([x[1:] for x in notes[k:]], None, False)

    def columns(self, check: bool = True) -> FrameColumns:
        """Every frame recorded, as columns (flushes first)."""
        self.flush(check)
        return FrameColumns.join(self.parts, self.nb, self.nj)

    # ------------------------------------------------------------------ the two paths

    def _columns(self, states: States) -> tuple[FrameColumns, Callable[[int], Frame]]:
        return chunk_frames(self.sim, states, self.drawings)


class Runs(Sequence):
    """Consecutive ``States`` of different generations of a run's system (``viz3d.departures``), as one
    sequence of ``State``; indexed by an array or a slice, a list of them."""

    def __init__(self, runs: list[States]):
        self.runs = runs
        self._start = np.cumsum([0] + [len(r) for r in runs])

    def __len__(self) -> int:
        return int(self._start[-1])

    def __getitem__(self, i):
        if isinstance(i, (slice, np.ndarray, list)):
            return [self[k] for k in np.arange(len(self))[i]]
        i = i + len(self) if i < 0 else i
        r = int(np.searchsorted(self._start, i, side="right")) - 1
        return self.runs[r][i - int(self._start[r])]


def generation_runs(states) -> list[States]:
    """``states`` (``States``, ``Runs`` or a sequence of ``State``) as runs of one generation each."""
    if not isinstance(states, (States, Runs)):
        states = joined([States.of([st]) for st in states]) if len(states) else States.of([])
    return states.runs if isinstance(states, Runs) else [states]


def joined(pieces: list[States]) -> States | Runs:
    """``pieces`` joined: one ``States`` where they are of one generation, else ``Runs`` of each's."""
    runs: list[list[States]] = []
    for p in pieces:
        if runs and state_size(runs[-1][-1]) == state_size(p):
            runs[-1].append(p)
        else:
            runs.append([p])
    return States.join(runs[0]) if len(runs) == 1 else Runs([States.join(r) for r in runs])


def chunk_frames(sim, states, drawings: tuple = ()) -> tuple[FrameColumns, Callable[[int], Frame]]:
    """The ``FrameColumns`` of ``states`` (a sequence of ``State``, ``States`` or ``Runs``) and the
    ``Frame`` of each, by index (drawing the flexible bodies of ``drawings``): from the kernel's
    samples in one call (``frame_of``) when it covers the run, else each state's NumPy frame
    (``FrameSource.frame``). A run whose bodies leave it (``viz3d.departures``) has its frames in its
    first generation's bodies and joints (NaN for those that have left)."""
    runs = generation_runs(states)
    parts = [_generation_frames(sim, r, drawings) for r in runs]
    if len(parts) == 1:
        return parts[0]
    start = np.cumsum([0] + [len(r) for r in runs])
    layout = sim.departures.layout
    cols = FrameColumns.join([c for c, _ in parts], layout.n_bodies, len(layout.joint_names))

    def frame_at(i: int) -> Frame:
        r = int(np.searchsorted(start, i, side="right")) - 1
        return parts[r][1](i - int(start[r]))

    return cols, frame_at


def _generation_frames(sim, states: States, drawings: tuple) -> tuple[FrameColumns, Callable[[int], Frame]]:
    """``chunk_frames`` of states of one generation, in the first generation's bodies and joints."""
    cols, frame_at = _source_frames(sim.source(states) if len(states) else sim.source(), states, drawings)
    departures = getattr(sim, "departures", None)
    gen = departures.generation_of(states) if departures is not None and len(states) else None
    if gen is None or gen is departures.generations[0]:
        return cols, frame_at
    nb, nj = departures.layout.n_bodies, len(departures.layout.joint_names)
    b, j = gen.bodies, gen.joints
    cols = replace(cols, W_r=expand(cols.W_r, b, nb), R_WB=expand(cols.R_WB, b, nb), W_v=expand(cols.W_v, b, nb),
                   W_omega=expand(cols.W_omega, b, nb), reaction_force=expand(cols.reaction_force, j, nj))

    def expanded(i: int) -> Frame:
        f = frame_at(i)

        def draw():
            d = f.drawing
            return replace(d, joint_points=expand(d.joint_points, j, nj, axis=0))

        return replace(f, W_r=cols.W_r[i], R_WB=cols.R_WB[i], W_v=cols.W_v[i], W_omega=cols.W_omega[i],
                       reaction_force=cols.reaction_force[i], draw=draw)

    return cols, expanded


def _source_frames(source, states: States, drawings: tuple) -> tuple[FrameColumns, Callable[[int], Frame]]:
    """``chunk_frames`` of states of the generation ``source`` (``viz3d.simulate.FrameSource``), in its
    own bodies and joints."""
    stepper = source.kernel_sampler()
    if stepper is not None:
        try:
            cols, s = _sampled(source, stepper, states)
            return cols, lambda i: frame_of(source.system, states[i], cols, s, i, stepper.data, drawings)
        except np.linalg.LinAlgError:  # the NumPy path raises the detailed error
            pass
    frames = [source.frame(s, drawings) for s in states]
    return FrameColumns.from_frames(frames, source.system.n_bodies, len(source.system.joint_names)), frames.__getitem__


def frame_of(system: System, state: State, cols: FrameColumns, s, i: int, data, drawings: tuple = ()) -> Frame:
    """The ``Frame`` of instant ``i`` of ``cols`` (``state``, its kernel samples ``s``): its row of the
    columns; the drawing from the samples, evaluated when read (``viz3d.frames.drawing_of``)."""
    def draw():
        cfg = _configuration(data, cols.t[i], s, i)
        gaps = tuple(Gap(s.gap[i, x, 0], s.gap[i, x, 1], s.gap[i, x, 2:5], s.gap[i, x, 5:8], s.gap[i, x, 8:11])
                     for x in data.contact_slices)
        return drawing_of(system, state, cfg, gaps, s.lam[i], drawings)

    return Frame(cols.t[i], cols.W_r[i], cols.R_WB[i], cols.W_v[i], cols.W_omega[i], cols.reaction_force[i],
                 cols.energy_kinetic[i], cols.energy_potential[i], cols.constraint_violation[i],
                 ColumnRow(cols.scalars, i), draw)


def _groups(memory: tuple, elements: tuple) -> list[tuple[int, int]]:
    """Runs ``[a, b)`` of consecutive states sharing one contact memory object and one force elements'
    memory object (``memory``, ``elements``: each state's)."""
    if _one_object(memory) and _one_object(elements):
        return [(0, len(memory))] if memory else []
    out, a = [], 0
    for i in range(1, len(memory) + 1):
        if i == len(memory) or memory[i] is not memory[a] or elements[i] is not elements[a]:
            out.append((a, i))
            a = i
    return out


def _one_object(objects: tuple) -> bool:
    """Every entry of ``objects`` is one and the same object (by identity; true of none)."""
    return not objects or all(map(operator.is_, objects, itertools.repeat(objects[0])))


def kernel_samples(stepper, states: States):
    """The kernel's samples of ``states`` (``KernelStepper.sample``, one call per run of states sharing
    their memories); raises ``LinAlgError`` where an evaluation fails."""
    ts, Y, charts = states.t, states.Y, states.chart  # charts (N, nf, 3, 3), nf may be 0
    samples = [stepper.sample(ts[a:b], Y[a:b], charts[a:b], states.memory[a], states.element_memory[a])
               for a, b in _groups(states.memory, states.element_memory)]
    return samples[0] if len(samples) == 1 else type(samples[0])(*(np.concatenate(x) for x in zip(*samples)))


def _sampled(sim, stepper, states: States) -> tuple[FrameColumns, object]:
    """Columns of ``states`` from the kernel's samples (see the module docstring), and the samples."""
    system = sim.system
    nb = system.n_bodies
    ts = states.t
    s = states.samples  # (taken with the states by the kernel's batched stepping)
    if s is None:
        s = kernel_samples(stepper, states)
    W_G, W_v = _centres_of_mass(system, stepper.data, s)
    T, strain = s.T.copy(), np.zeros(len(states))
    measured = [e for e in system.forces if hasattr(e, "scalars")]  # (shape contacts: counts, depth, force)
    cfgs = _configurations(stepper.data, ts, s) if (system.bodies.flexible or system.outputs or measured) else None
    for k, fb in enumerate(system.bodies.flexible):
        sl = stepper.data.elastic_slices[k]
        T += flexible_kinetics(fb, s, sl)
        strain += 0.5 * np.einsum("ni,ij,nj->n", s.eta[:, sl], fb.bar.K, s.eta[:, sl])
    V = s.V[:, 0] + s.V[:, 1] + strain
    scalars: dict[str, FloatArray] = {}
    violation, reactions = _rows(system, s)
    for out in system.outputs:
        values = [out.values(cfg, r) for cfg, r in zip(cfgs, reactions)]
        for key in values[0] if values else ():
            scalars[key] = np.array([v[key] for v in values], float)
    for e in measured:  # the force elements' own scalars, evaluated on NumPy per state (as frame_from_state)
        values = [e.scalars(cfg) for cfg in cfgs]
        for key in values[0] if values else ():
            scalars[key] = np.array([v[key] for v in values], float)
    scalars.update(relative_coordinates(system.joints.joints, s.R, s.r, s.vW, s.wW))
    scalars.update(_section_coordinates(system.joints.joints, cfgs))
    scalars.update(drive_efforts(system.joints.joints, system.joints.row_slices(), s.lam))
    if system.contacts:
        U = _contact_columns(sim, stepper.data, states, s, scalars)
        V = V + U.sum(axis=1)
    if system.has_ledger:
        _ledger_columns(sim, states, T, s.V, strain, U if system.contacts else np.zeros((len(states), 0)), scalars)
    return FrameColumns(ts, W_G, s.R[:, :nb], W_v, s.wW[:, :nb], T, V, violation, reactions, scalars), s


def _centres_of_mass(system: System, data, s) -> tuple[FloatArray, FloatArray]:
    """Centres of mass and their velocities (n, nb, 3): the frame origins, shifted on flexible
    bodies by ``R S eta / m`` (``viz3d.dynamics.centres_of_mass``)."""
    nb = system.n_bodies
    W_G, W_v = s.r[:, :nb].copy(), s.vW[:, :nb].copy()
    for k, fb in enumerate(system.bodies.flexible):
        b, sl, bar = fb.index, data.elastic_slices[k], fb.bar
        shift = np.einsum("nij,nj->ni", s.R[:, b], s.eta[:, sl] @ bar.S.T) / bar.mass
        W_G[:, b] += shift
        W_v[:, b] += np.cross(s.wW[:, b], shift) + np.einsum("nij,nj->ni", s.R[:, b], s.eta_dot[:, sl] @ bar.S.T) / bar.mass
    return W_G, W_v


def _section_coordinates(joints, cfgs: list[Configuration] | None) -> dict[str, FloatArray]:
    """The relative coordinates (n,) of the joint sets with a joint on a flexible section, which need
    each state's deformation (``viz3d.joints.relative_coordinates`` with its ``cfg``): one state at a time."""
    sets = tuple(js for js in joints if getattr(js, "coordinate_names", ()) and js.on_flexible)
    if not sets:
        return {}
    values = [relative_coordinates(sets, c.pose.R_WB, c.pose.W_r, c.twist.W_v, c.twist.W_omega, c) for c in cfgs]
    return {key: np.array([v[key] for v in values], float) for key in values[0]}


def _configurations(data, ts: FloatArray, s) -> list[Configuration]:
    """Each state's ``Configuration`` from the samples (for the NumPy-only quantities)."""
    return [_configuration(data, ts[i], s, i) for i in range(len(ts))]


def _configuration(data, t: float, s, i: int) -> Configuration:
    """State ``i``'s ``Configuration`` from the samples ``s``."""
    sl = data.elastic_slices
    return Configuration(t, Pose(s.r[i], s.R[i]), Twist(s.vW[i], s.wB[i], s.wW[i]), tuple(s.eta[i, x] for x in sl),
                         tuple(s.eta_dot[i, x] for x in sl))


def _rows(system: System, s) -> tuple[FloatArray, FloatArray]:
    """Constraint violation max |C| over the joints' rows (n,) [m] and each joint's reaction on
    body 1 (n, nj, 3) [N] (a kinematic contact's row is its indentation, not a violation)."""
    n = s.T.shape[0]
    joints = [(js, sl) for js, sl in zip(system.joints.joints, system.joints.row_slices()) if js.is_joint]
    if not joints:
        return np.zeros(n), np.zeros((n, 0, 3))
    rows = np.concatenate([np.arange(system.n_c)[sl] for _, sl in joints])
    violation = np.max(np.abs(s.C[:, rows]), axis=1)
    reactions = [js.reaction_force(s.J[:, sl].reshape(n, js.n_joints, js.n_eq, 2, 6),
                                   s.lam[:, sl].reshape(n, js.n_joints, js.n_eq)) for js, sl in joints]
    return violation, np.concatenate(reactions, axis=1)


def _contact_columns(sim, data, states: States, s, scalars: dict) -> FloatArray:
    """The contacts' scalars (force, indentation per contact) into ``scalars``; returns each contact's
    elastic energy (n, k) [J]. A contact's law force and stored energy are zero unless it overlaps
    or touches: only such states are evaluated one by one."""
    from viz3d.events import contact_forces

    system = sim.system
    n = len(states)
    k_all = data.n_contacts
    U, F = np.zeros((n, k_all)), np.zeros((n, k_all))
    alpha = s.gap[:, :, 0]
    touching = np.array([any(p.touching for phases in mem for p in phases) for mem in states.memory], dtype=bool)
    for i in np.flatnonzero((alpha > 0.0).any(axis=1) | touching):
        st = states[i]
        g = s.gap[i]
        gaps = tuple(Gap(g[x, 0], g[x, 1], g[x, 2:5], g[x, 5:8], g[x, 8:11]) for x in data.contact_slices)
        cfg = None
        if any(f is not None and f.stateful for c in system.contacts for f in c.friction):  # bristles: the pose
            cfg = _configuration(data, st.t, s, i)
        for k, (c, x, gp) in enumerate(zip(system.contacts, data.contact_slices, gaps)):
            U[i, x] = c.elastic_energy(cfg, st.memory[k] if st.memory else c.initial_phases(), gp)
        F[i] = np.concatenate(contact_forces(system, st, s.lam[i], gaps))
    names = [nm for c in system.contacts for nm in c.names]
    for j, nm in enumerate(names):
        scalars[f"contact/{nm}/force"] = F[:, j]
        scalars[f"contact/{nm}/indentation"] = np.maximum(alpha[:, j], 0.0)
    return U


def _ledger_columns(sim, states: States, T, V_forces, strain, U, scalars: dict) -> None:
    """The energy ledger's scalars (``viz3d.frames.ledger_scalars``) into ``scalars``: kinetic ``T``,
    the force elements' potentials ``V_forces`` (n, 2) (signed, others), ``strain`` (n,) and the
    contacts' stored energies ``U`` (n, k) [J]."""
    from viz3d.events import impulse_loss, ledger_of, work_integrals

    W = np.array([work_integrals(sim.system, st) for st in states])
    losses = np.array([impulse_loss(sim.system, st) for st in states])
    led = ledger_of(T, V_forces[:, 0] + V_forces[:, 1], V_forces[:, 0], strain, U, W, losses)
    scalars.update(ledger_scalars(led, sim.reference_energy))

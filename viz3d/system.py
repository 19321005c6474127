"""The frozen model (``System``) and the state value (``State``).

Layout of the state vectors (docs/notation.md, "State layout"):

* ``q`` (n_q,): first the frame coordinates of every body whose frame floats (rigid bodies and
  flexible bodies on a floating frame), ``[W_r (3) [m], theta (n_rot) [rad or -]]`` each, in body
  order; then the elastic coordinates ``eta`` of every flexible body, in body order.
* ``v`` (n_v,): the frame twists ``[W_v (3) [m/s], B_omega (3) [rad/s]]`` of the same bodies, then the
  elastic velocities ``eta_dot``. A system of rigid bodies has ``n_v = 6 nb``.
* ``chart`` (nf, 3, 3): per floating frame, the reference rotation of its orientation coordinates.

Bodies whose frame is fixed (a clamped bar) have no frame coordinates: their frame pose is constant.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.bodies import Bodies
from viz3d.constraints import ConstraintLayout
from viz3d.coordinates import RotationCoordinates
from viz3d.forces import ForceElement


@dataclass(frozen=True)
class System:
    """Everything that does not change during a run.

    Attributes
    ----------
    bodies : Bodies
    joints : ConstraintLayout
        Joint sets and the precomputed structure of their constraint rows.
    forces : tuple of ForceElement
        Gravity first (if any), then the scene's force elements.
    rotation : RotationCoordinates
        Orientation coordinates of every floating frame.
    contacts : tuple of ContactSet
        Contacts between bodies (``viz3d.contact.contacts``); their kinematic rows, if any, are also
        row providers of ``joints``.
    outputs : tuple of Output
        What a run reports without acting (``viz3d.outputs``: strain gauges).
    frame_body : ndarray of int, shape (nf,)
        Body index of each floating frame, in ``q`` order (derived).
    q_elastic, v_elastic : tuple of slice
        Where each flexible body's ``eta`` and ``eta_dot`` sit in ``q`` and ``v`` (derived).
    derived : dict
        What other layers derive from the system alone and keep with it, by their key (its packing
        for the compiled kernel: ``viz3d.kernel.kernel_coverage``), so each run of the system reuses
        it: the system does not change, so neither does what is derived from it. Nothing a run
        writes to is kept here.
    """

    bodies: Bodies
    joints: ConstraintLayout
    forces: tuple[ForceElement, ...]
    rotation: RotationCoordinates
    contacts: tuple = ()
    outputs: tuple = ()
    frame_body: IntArray = field(init=False, repr=False)
    q_elastic: tuple[slice, ...] = field(init=False, repr=False)
    v_elastic: tuple[slice, ...] = field(init=False, repr=False)
    derived: dict = field(init=False, repr=False, compare=False, default_factory=dict)

    def __post_init__(self):
        floating = np.ones(self.bodies.n_bodies, dtype=bool)
        for fb in self.bodies.flexible:
            floating[fb.index] = fb.floating
        object.__setattr__(self, "frame_body", np.flatnonzero(floating))
        q0, v0 = len(self.frame_body) * self.n_q_body, 6 * len(self.frame_body)
        q_sl, v_sl = [], []
        for fb in self.bodies.flexible:
            q_sl.append(slice(q0, q0 + fb.n))
            v_sl.append(slice(v0, v0 + fb.n))
            q0, v0 = q0 + fb.n, v0 + fb.n
        object.__setattr__(self, "q_elastic", tuple(q_sl))
        object.__setattr__(self, "v_elastic", tuple(v_sl))

    @property
    def n_bodies(self) -> int:
        return self.bodies.n_bodies

    @property
    def n_frames(self) -> int:
        """Floating frames (bodies with frame coordinates)."""
        return len(self.frame_body)

    @property
    def all_frames_float(self) -> bool:
        """Every body has frame coordinates (no fixed-frame body): frame index = body index."""
        return self.n_frames == self.n_bodies

    @property
    def n_q_body(self) -> int:
        """Coordinates of one floating frame."""
        return 3 + self.rotation.n_q

    @property
    def n_elastic(self) -> int:
        return sum(fb.n for fb in self.bodies.flexible)

    @property
    def n_q(self) -> int:
        return self.n_frames * self.n_q_body + self.n_elastic

    @property
    def n_v(self) -> int:
        return 6 * self.n_frames + self.n_elastic

    @property
    def n_c(self) -> int:
        return self.joints.n_rows

    @property
    def joint_sets(self) -> tuple:
        """The joint sets among the row providers (not the contact rows)."""
        return tuple(js for js in self.joints.joints if js.is_joint)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(n for js in self.joint_sets for n in js.names)

    @property
    def conservative(self) -> bool:
        """True when the total energy is a constant of the motion: every force element and contact
        conservative and no drive (it works on the bodies)."""
        return (all(e.conservative for e in self.forces) and all(c.conservative for c in self.contacts)
                and not self.driven)

    @property
    def driven(self) -> bool:
        """True when the scene has a drive (a rheonomic constraint or a limited drive: they work on the
        bodies)."""
        return bool(self.drive_names)

    @property
    def drive_names(self) -> tuple[str, ...]:
        """The drives, each with the frame scalar ``drive/<name>/effort``: the rigid ones (rheonomic row
        providers, ``viz3d.joints.JointDrive``), then the limited ones (force elements that are drives,
        ``viz3d.forces.DriveServo``)."""
        rigid = [n for js in self.joints.joints if getattr(js, "rheonomic", False) for n in js.names]
        return tuple(rigid + [n for e in self.forces if getattr(e, "is_drive", False) for n in e.names])

    @property
    def has_ledger(self) -> bool:
        """True when frames carry the energy ledger (``viz3d.events.Ledger``): with contacts or drives."""
        return bool(self.contacts) or self.driven

    @property
    def n_aux(self) -> int:
        """Work integrals carried in the state (``State.w``; ``viz3d.events``): with located contacts or
        drives, one per contact, one for the damping of flexible bodies (and the kinetic energy taken by the
        joints of departures, ``viz3d.departures.velocities_held``) and one for the work in (the drives' and the
        non-conservative force elements'); none otherwise (no energy ledger)."""
        if not (self.driven or any(c.located for c in self.contacts)):
            return 0
        return sum(c.k for c in self.contacts) + 2

    def split_q(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(W_r (nf, 3), theta (nf, n_rot))`` views of the frame coordinates of ``q``."""
        qb = q[: self.n_frames * self.n_q_body].reshape(self.n_frames, self.n_q_body)
        return qb[:, :3], qb[:, 3:]

    def split_v(self, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(W_v (nf, 3), B_omega (nf, 3))`` views of the frame twists of ``v``."""
        vb = v[: 6 * self.n_frames].reshape(self.n_frames, 6)
        return vb[:, :3], vb[:, 3:]

    def elastic_q(self, q: FloatArray) -> tuple[FloatArray, ...]:
        """``eta`` of each flexible body (views of ``q``)."""
        return tuple(q[sl] for sl in self.q_elastic)

    def elastic_v(self, v: FloatArray) -> tuple[FloatArray, ...]:
        """``eta_dot`` of each flexible body (views of ``v``)."""
        return tuple(v[sl] for sl in self.v_elastic)

    def join_q(self, W_r: FloatArray, theta: FloatArray, eta: FloatArray | None = None) -> FloatArray:
        """``q`` from frame coordinates (nf, 3), (nf, n_rot) and the stacked elastic ones (n_e,)."""
        frames = np.concatenate([W_r, theta], axis=1).reshape(-1)
        if not self.n_elastic:
            return frames
        return np.concatenate([frames, np.zeros(self.n_elastic) if eta is None else eta])

    def with_frames(self, q: FloatArray, W_r: FloatArray, theta: FloatArray) -> FloatArray:
        """``q`` with its frame coordinates replaced, the elastic ones kept."""
        return self.join_q(W_r, theta, self.elastic_part(q, self.n_frames * self.n_q_body))

    def split_y(self, y: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(q, v, w)`` views of an integrator's ``y = [q, v, w]``."""
        n_q, n_v = self.n_q, self.n_v
        return y[:n_q], y[n_q:n_q + n_v], y[n_q + n_v:]

    def elastic_part(self, x: FloatArray, n_frame: int) -> FloatArray:
        """The stacked elastic entries (n_e,) of a ``q``- or ``v``-like vector whose frame part has
        ``n_frame`` entries."""
        return x[n_frame:n_frame + self.n_elastic]


@dataclass(frozen=True)
class State:
    """Time-varying state of a System (a value: use ``replace`` to make a new one).

    Attributes
    ----------
    t : float
        Time [s].
    q : ndarray, shape (n_q,)
        Positions (see module docstring).
    v : ndarray, shape (n_v,)
        Velocities.
    chart : ndarray, shape (nf, 3, 3)
        Reference rotation of each floating frame's orientation coordinates.
    w : ndarray, shape (n_aux,)
        Work integrals of the energy ledger [J] (``System.n_aux``; empty without located contacts or drives).
    memory : tuple
        Per contact set of ``System.contacts``, the tuple of its contacts' ``ContactPhase``.
    element_memory : tuple
        Per force element of ``System.forces``, the memory of those that keep one
        (``ForceElement.has_memory``: shape contacts' stick anchors), None for the others; empty when
        no element keeps one. Fixed during a step, renewed after each accepted step
        (``viz3d.dynamics.element_memory``).
    """

    t: float
    q: FloatArray
    v: FloatArray
    chart: FloatArray
    w: FloatArray = field(default_factory=lambda: np.zeros(0))
    memory: tuple = ()
    element_memory: tuple = ()

    def replace(self, **changes) -> "State":
        return dataclasses.replace(self, **changes)

    @property
    def y(self) -> FloatArray:
        """``[q, v, w]`` stacked, shape (n_q + n_v + n_aux,): what integrators advance."""
        return np.concatenate([self.q, self.v, self.w]) if self.w.size else np.concatenate([self.q, self.v])


@dataclass(frozen=True, eq=False)
class States:
    """The states of a run at N instants as arrays (a sequence of ``State``, each built when indexed):
    what the kernel returns for a batch of output frames, without a ``State`` per frame.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Times [s].
    Y : ndarray, shape (N, n_q + n_v + n_aux)
        Each state's ``State.y``.
    chart : ndarray, shape (N, nf, 3, 3)
    n_q, n_v : int
        Where ``q`` and ``v`` end in a row of ``Y``.
    memory, element_memory : sequence, length N
        Each state's ``State.memory`` and ``State.element_memory`` (a tuple, or a sequence that builds
        each when indexed: ``viz3d.simulate._SampleMemories``).
    samples : viz3d.kernel.Samples, optional
        Their output samples when the kernel took them with the states (``KernelStepper.frames``).
    """

    t: FloatArray
    Y: FloatArray
    chart: FloatArray
    n_q: int
    n_v: int
    memory: Sequence
    element_memory: Sequence
    samples: object = None

    @classmethod
    def alike(cls, t: FloatArray, Y: FloatArray, chart: FloatArray, n_q: int, n_v: int, like: State,
              samples=None) -> "States":
        """States whose contact and element memory are ``like``'s."""
        n = t.shape[0]
        return cls(t, Y, chart, n_q, n_v, (like.memory,) * n, (like.element_memory,) * n, samples)

    @classmethod
    def of(cls, states) -> "States":
        """``states`` (a sequence of ``State`` or a ``States``, all of one system) as one ``States``."""
        if isinstance(states, States):
            return states
        if not states:
            return cls(np.zeros(0), np.zeros((0, 0)), np.zeros((0, 0, 3, 3)), 0, 0, (), ())
        s0 = states[0]
        return cls(np.array([s.t for s in states], float), np.array([s.y for s in states]),
                   np.stack([s.chart for s in states]), s0.q.shape[0], s0.v.shape[0],
                   tuple(s.memory for s in states), tuple(s.element_memory for s in states))

    @classmethod
    def join(cls, parts: list["States"]) -> "States":
        """Consecutive ``parts`` as one ``States`` (with samples when every part has them)."""
        if len(parts) == 1:
            return parts[0]
        p0 = parts[0]
        samples = None
        if all(p.samples is not None for p in parts):
            samples = type(p0.samples)(*(np.concatenate(x) for x in zip(*(p.samples for p in parts))))
        return cls(np.concatenate([p.t for p in parts]), np.concatenate([p.Y for p in parts]),
                   np.concatenate([p.chart for p in parts]), p0.n_q, p0.n_v,
                   _chained(p.memory for p in parts), _chained(p.element_memory for p in parts), samples)

    def __len__(self) -> int:
        return self.t.shape[0]

    def __getitem__(self, i):
        """State ``i`` (its ``q``, ``v``, ``w`` views of ``Y[i]``), or the ``States`` of a slice or an
        index array."""
        if isinstance(i, np.ndarray) and i.dtype == bool and i.all():
            return self
        if isinstance(i, (slice, np.ndarray, list)):
            idx = np.arange(len(self))[i]
            samples = None if self.samples is None else type(self.samples)(*(a[i] for a in self.samples))
            return States(self.t[i], self.Y[i], self.chart[i], self.n_q, self.n_v,
                          tuple(self.memory[k] for k in idx), tuple(self.element_memory[k] for k in idx), samples)
        y, n_q, n_v = self.Y[i], self.n_q, self.n_v
        return State(float(self.t[i]), y[:n_q], y[n_q:n_q + n_v], self.chart[i], y[n_q + n_v:], self.memory[i],
                     self.element_memory[i])

    def __iter__(self):
        return (self[i] for i in range(len(self)))


def _chained(tuples) -> tuple:
    """The entries of ``tuples`` one after another, as one tuple."""
    return tuple(itertools.chain.from_iterable(tuples))


def state_size(state: "State | States") -> int:
    """``n_q`` of a ``State`` or ``States``: which generation of a run's system it belongs to
    (``viz3d.departures``: each departure removes a floating body's coordinates)."""
    return state.q.shape[0] if isinstance(state, State) else state.n_q

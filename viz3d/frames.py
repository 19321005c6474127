"""What viewers, recorders and trajectory files consume: ``SceneVisuals`` (sent once) and
``Frame`` (one instant). Nothing that consumes frames needs the System, integrators or
formulations; conversions to a back-end's conventions (quaternion order) happen in the back-end.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray
from viz3d.dynamics import accelerations, body_state, energies
from viz3d.forces import SpringDamper
from viz3d.system import State, System


@dataclass(frozen=True)
class BodyVisual:
    """Display geometry of one body, in body coordinates (origin at the centre of mass).

    Attributes
    ----------
    name : str
    vertices : ndarray, shape (V, 3), float32 [m]
    faces : ndarray, shape (F, 3), int32
    color : ndarray, shape (3,), uint8
    group : str
        Bodies with the same ``group`` share the same vertices and faces (drawn as one batch).
    radius : float
        Bounding radius about the centre of mass [m].
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    color: np.ndarray
    group: str
    radius: float


@dataclass(frozen=True)
class DeformableVisual:
    """A mesh whose vertices every frame gives in world coordinates (a deforming bar).

    Attributes
    ----------
    name : str
    faces : ndarray, shape (F, 3), int32
    vertices : ndarray, shape (V, 3), float32
        Initial world positions [m].
    color : ndarray, shape (3,), uint8
    """

    name: str
    faces: np.ndarray
    vertices: np.ndarray
    color: np.ndarray


@dataclass(frozen=True)
class StaticVisual:
    """Fixed geometry drawn with the scene, in world coordinates (e.g. the posts that hold the
    ground ends of springs).

    Attributes
    ----------
    name : str
    vertices : ndarray, shape (V, 3), float32
        World positions [m].
    faces : ndarray, shape (F, 3), int32
    color : ndarray, shape (3,), uint8
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    color: np.ndarray


@dataclass(frozen=True)
class SceneVisuals:
    """Everything static a viewer or recorder draws.

    Attributes
    ----------
    name : str
        Scene name.
    bodies : tuple of BodyVisual, length nb
    joint_names, spring_names : tuple of str
    length_scale : float
        Typical body size [m] (frame axes and arrows are drawn relative to it).
    thickness : float
        Typical smallest body dimension [m] (joint markers and lines are drawn relative to it).
    force_scale : float
        Force drawn as an arrow of length ``length_scale`` [N] (the total weight, or 1 N).
    bounds : ndarray, shape (2, 3)
        Lower and upper corners of the initial scene [m] (bodies and static geometry).
    deformables : tuple of DeformableVisual
    plots : tuple of (str, str)
        (title, entity prefix under /plots) of the time-series panels recorders lay out.
    display_dt : float
        Simulated time between drawn frames in recordings [s].
    kind : str
        "rigid" or "impact".
    statics : tuple of StaticVisual
        Fixed world geometry (posts under the ground ends of springs).
    reach : ndarray, shape (k, 4)
        Spheres ``[x, y, z, radius]`` [m] that bodies held by ground joints cannot leave (one per
        ground joint: its point and the farthest reach of the bodies hanging from it); with
        ``bounds``, what a camera must keep in view.
    """

    name: str
    bodies: tuple[BodyVisual, ...]
    joint_names: tuple[str, ...]
    spring_names: tuple[str, ...]
    length_scale: float
    thickness: float
    force_scale: float
    bounds: FloatArray
    deformables: tuple[DeformableVisual, ...] = ()
    plots: tuple[tuple[str, str], ...] = (("Energy [J]", "energy"), ("Constraint violation [m]", "constraint_violation"),
                                          ("Joint reaction force [N]", "reaction_force"))
    display_dt: float = 1.0 / 30.0
    kind: str = "rigid"
    statics: tuple[StaticVisual, ...] = ()
    reach: FloatArray = field(default_factory=lambda: np.zeros((0, 4)))


@dataclass(frozen=True)
class Frame:
    """The state of a scene at one instant, as consumers need it.

    Attributes
    ----------
    t : float [s]
    W_r : ndarray, shape (nb, 3)
        Centres of mass, world [m].
    R_WB : ndarray, shape (nb, 3, 3)
        World-from-body rotations.
    W_v, W_omega : ndarray, shape (nb, 3)
        Velocities [m/s] and angular velocities [rad/s], world.
    joint_points : ndarray, shape (nj, 3)
        Joint points (on body 1), world [m].
    reaction_force : ndarray, shape (nj, 3)
        World force on body 1 of each joint [N].
    springs : ndarray, shape (ns, 2, 3)
        Spring end points, world [m].
    energy_kinetic, energy_potential : float [J]
    constraint_violation : float
        max |C| [m].
    scalars : dict of str -> float
        Further named quantities (for plots), in SI units; keys are plot paths ("contact/force").
    deformed : dict of str -> ndarray (V, 3)
        World vertices of each deformable mesh [m].
    contact_points, contact_forces : ndarray, shape (k, 3)
        Active contacts: world points [m] and the force on the struck body there [N].
    """

    t: float
    W_r: FloatArray
    R_WB: FloatArray
    W_v: FloatArray
    W_omega: FloatArray
    joint_points: FloatArray
    reaction_force: FloatArray
    springs: FloatArray
    energy_kinetic: float
    energy_potential: float
    constraint_violation: float
    scalars: dict = field(default_factory=dict)
    deformed: dict = field(default_factory=dict)
    contact_points: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    contact_forces: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def energy_total(self) -> float:
        return self.energy_kinetic + self.energy_potential


def frame_from_state(system: System, formulation, state: State) -> Frame:
    """Evaluate everything a ``Frame`` holds at ``state`` (costs about one right-hand side)."""
    cfg = body_state(system, state.q, state.v, state.chart, state.t)
    T, V = energies(system, state)
    acc = accelerations(system, formulation, state.t, state.q, state.v, state.chart)
    reactions, points = [], []
    for js, sl in zip(system.joints.joints, system.joints.row_slices()):
        J = acc.rows.J[sl].reshape(js.n_joints, js.n_eq, 2, 6)
        reactions.append(js.reaction_force(J, acc.lam[sl].reshape(js.n_joints, js.n_eq)))
        points.append(js.points(cfg))
    springs = [e.endpoints(cfg)[0] for e in system.forces if isinstance(e, SpringDamper)]
    contacts = [e.contacts(cfg) for e in system.forces if hasattr(e, "contacts")]
    W_G, W_v = centres_of_mass(system, cfg)
    return Frame(
        t=state.t, W_r=W_G, R_WB=cfg.pose.R_WB[:-1], W_v=W_v, W_omega=cfg.twist.W_omega[:-1],
        joint_points=_stack(points, (0, 3)), reaction_force=_stack(reactions, (0, 3)),
        springs=_stack(springs, (0, 2, 3)), energy_kinetic=T, energy_potential=V,
        constraint_violation=float(np.max(np.abs(acc.rows.C))) if system.n_c else 0.0,
        contact_points=_stack([c[0] for c in contacts], (0, 3)), contact_forces=_stack([c[1] for c in contacts], (0, 3)))


def centres_of_mass(system: System, cfg) -> tuple[FloatArray, FloatArray]:
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
        W_v[b] += np.cross(cfg.twist.W_omega[b], shift) + R @ (fb.bar.S @ cfg.eta_dot[i]) / fb.bar.mass
    return W_G, W_v


def _stack(parts: list, empty_shape: tuple) -> FloatArray:
    return np.concatenate(parts) if parts else np.zeros(empty_shape)

"""What viewers, recorders and trajectory files consume: ``SceneVisuals`` (sent once) and
``Frame`` (one instant). Nothing that consumes frames needs the System, integrators or
formulations; conversions to a back-end's conventions (quaternion order) happen in the back-end.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Callable

import numpy as np

from viz3d._typing import FloatArray
from viz3d.dynamics import accelerations, body_state, centres_of_mass, energies
from viz3d.forces import SpringDamper
from viz3d.joints import drive_efforts, relative_coordinates
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
    ring : int
        A tube that carries its surface bending stress (``Frame.stress``; a ``FlexibleDrawing`` of a
        bar that bends): points per section, vertex ``i * ring + j`` the ``j``-th point of section
        ``i``; 0: a mesh drawn in its colour only.
    """

    name: str
    faces: np.ndarray
    vertices: np.ndarray
    color: np.ndarray
    ring: int = 0


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
    plot_dt : float
        Simulated time between plot samples in recordings [s] (0: every frame).
    statics : tuple of StaticVisual
        Fixed world geometry (posts under the ground ends of springs).
    reach : ndarray, shape (k, 4)
        Spheres ``[x, y, z, radius]`` [m] that bodies held by ground joints cannot leave (one per
        ground joint: its point and the farthest reach of the bodies hanging from it); with
        ``bounds``, what a camera must keep in view.
    stress_scale : float
        Surface stress drawn at the ends of the deformables' colour map [Pa] (``[display]
        stress_scale``); 0: each sink's running maximum of |stress| (``viz3d.viz.colors``).
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
    plot_dt: float = 0.0
    statics: tuple[StaticVisual, ...] = ()
    reach: FloatArray = field(default_factory=lambda: np.zeros((0, 4)))
    stress_scale: float = 0.0


@dataclass(frozen=True)
class Drawing:
    """What a frame draws beyond the bodies' poses (evaluated only for the frames a sink draws).

    Attributes
    ----------
    joint_points : ndarray, shape (nj, 3)
        Joint points (on body 1), world [m].
    springs : ndarray, shape (ns, 2, 3)
        Spring end points, world [m].
    deformed : dict of str -> ndarray (V, 3)
        World vertices of each deformable mesh [m].
    stress : dict of str -> ndarray (V,)
        Surface bending stress at each vertex of each deformable mesh, float32 [Pa] (tension > 0).
    contact_points, contact_forces : ndarray, shape (k, 3)
        Active contacts: world points [m] and the force on the struck body there [N].
    """

    joint_points: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    springs: FloatArray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    deformed: dict = field(default_factory=dict)
    stress: dict = field(default_factory=dict)
    contact_points: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    contact_forces: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))


@dataclass(frozen=True)
class Frame:
    """The state of a scene at one instant, as consumers need it.

    The drawing (``Drawing``: joint points, springs, contacts, deformed meshes and their stress) is
    evaluated when a consumer first reads one of its attributes, by ``draw`` (a pure function of the
    frame's state): a sink that plots a frame without drawing it does not pay for it.

    Attributes
    ----------
    t : float [s]
    W_r : ndarray, shape (nb, 3)
        Centres of mass, world [m].
    R_WB : ndarray, shape (nb, 3, 3)
        World-from-body rotations.
    W_v, W_omega : ndarray, shape (nb, 3)
        Velocities [m/s] and angular velocities [rad/s], world.
    reaction_force : ndarray, shape (nj, 3)
        World force on body 1 of each joint [N].
    energy_kinetic, energy_potential : float [J]
    constraint_violation : float
        max |C| [m].
    scalars : dict of str -> float
        Further named quantities (for plots), in SI units; keys are plot paths ("contact/force").
    draw : callable () -> Drawing
        Evaluates the drawing (default: nothing to draw).
    """

    t: float
    W_r: FloatArray
    R_WB: FloatArray
    W_v: FloatArray
    W_omega: FloatArray
    reaction_force: FloatArray
    energy_kinetic: float
    energy_potential: float
    constraint_violation: float
    scalars: dict = field(default_factory=dict)
    draw: Callable[[], Drawing] = field(default=Drawing, repr=False, compare=False)

    @property
    def energy_total(self) -> float:
        return self.energy_kinetic + self.energy_potential

    @cached_property
    def drawing(self) -> Drawing:
        """The frame's ``Drawing``, evaluated on first use (``cached_property`` writes the instance's
        ``__dict__``, which a frozen dataclass allows)."""
        return self.draw()

    joint_points = property(lambda self: self.drawing.joint_points, doc="``Drawing.joint_points``")
    springs = property(lambda self: self.drawing.springs, doc="``Drawing.springs``")
    deformed = property(lambda self: self.drawing.deformed, doc="``Drawing.deformed``")
    stress = property(lambda self: self.drawing.stress, doc="``Drawing.stress``")
    contact_points = property(lambda self: self.drawing.contact_points, doc="``Drawing.contact_points``")
    contact_forces = property(lambda self: self.drawing.contact_forces, doc="``Drawing.contact_forces``")


@dataclass(frozen=True, eq=False)
class FlexibleDrawing:
    """How a flexible body is drawn: a tube of rings along its deformed axis, deformation amplified,
    each vertex carrying the surface bending stress of its fibre (not amplified).

    The stress at ring point c of section x is that of the fibre through it: ``sigma = -E sum_k (c .
    d_k) psi_k'(x) eta_k`` over the bending fields k (direction d_k; psi' = w'' for Euler-Bernoulli,
    the curvature, which the quintic element carries as a nodal coordinate): ``E c kappa`` with c
    the fibre's distance from the neutral axis on the +w side, the sign of ``BarModel.strain``
    (tension > 0). Axial fields add no bending stress.

    Attributes
    ----------
    name : str
        The ``DeformableVisual`` it updates.
    flex : int
        The body among ``Bodies.flexible``.
    body : int
        Its body index.
    points : MaterialPoints
        Sections of the axis (``viz3d.flexible.floating_points``).
    ring : ndarray, shape (m, 3)
        Outline of a section, body axes, from the axis [m].
    amplification : float
        Deformation drawn this many times larger.
    stress_rows : ndarray, shape (sections * m, n), or None
        Vertex stress per unit elastic coordinate [Pa per unit eta] (``surface_stress_rows``); None:
        a bar without bending (no stress drawn).
    """

    name: str
    flex: int
    body: int
    points: object
    ring: FloatArray
    amplification: float = 1.0
    stress_rows: FloatArray | None = field(default=None, repr=False)

    def vertices(self, cfg) -> FloatArray:
        """World vertices (sections * m, 3), float32 [m]."""
        R = cfg.pose.R_WB[self.body]
        axis = self.points.s0 + self.amplification * (self.points.N @ cfg.eta[self.flex])
        local = axis[:, None, :] + self.ring[None, :, :]
        return (cfg.pose.W_r[self.body] + local.reshape(-1, 3) @ R.T).astype(np.float32)

    def stresses(self, cfg) -> FloatArray:
        """Surface bending stress at each vertex (sections * m,), float32 [Pa] (a bar that bends)."""
        return (self.stress_rows @ cfg.eta[self.flex]).astype(np.float32)


def surface_stress_rows(bar, x: FloatArray, ring: FloatArray) -> FloatArray | None:
    """Bending stress per unit eta at the fibres through ``ring`` (m, 3) (body axes, from the axis)
    of sections ``x`` (k,), shape (k * m, n) [Pa per unit eta]: ``-E (c . d) psi'(x)`` per bending
    field of ``bar`` (a ``FloatingBar``; see ``FlexibleDrawing``); None without a bending field."""
    if not any(model.kind == "bending" for model in bar.fields):
        return None
    rows = np.zeros((len(x), len(ring), bar.n))
    for model, sl, d in zip(bar.fields, bar.field_slices, bar.directions):
        if model.kind == "bending":
            curvature = model.shape(x, "psi", 1)                         # (k, n_field) [1/m per unit eta]
            rows[:, :, sl] = -model.material.E * (ring @ d)[None, :, None] * curvature[:, None, :]
    return rows.reshape(len(x) * len(ring), bar.n)


def frame_from_state(system: System, formulation, state: State, drawings: tuple = (),
                     reference_energy: float | None = None, solved: tuple | None = None,
                     kinematics: tuple | None = None) -> Frame:
    """Evaluate everything a ``Frame`` holds at ``state`` (costs about one right-hand side; the
    drawing only when it is read): the NumPy reference of ``viz3d.columns``' frames.

    ``drawings``: the ``FlexibleDrawing`` of each flexible body to draw deformed; with contacts,
    ``reference_energy`` (the ledger's initial total) gives the scalar ``energy/balance_error``;
    ``solved``: ``(lam, C, J)`` at ``state`` if the caller has them (the compiled kernel's
    multipliers (n_c,), residuals (n_c,) and Jacobian blocks (n_c, 2, 6)), else they are solved for
    here; ``kinematics``: the ``Configuration`` at ``state`` and each contact set's ``Gap`` if the
    caller has them (``viz3d.kernel.KernelStepper.configuration``).
    """
    if kinematics is None:
        cfg = body_state(system, state.q, state.v, state.chart, state.t)
        gaps = tuple(c.gap(cfg) for c in system.contacts)
    else:
        cfg, gaps = kinematics
    if system.has_ledger:
        from viz3d.events import ledger

        led = ledger(system, state, cfg, gaps)
        T, V = led.kinetic, led.potential + led.strain + led.contact_elastic
    else:
        T, V = energies(system, state, cfg, gaps)
    reactions, violation = [], 0.0
    joints = [(js, sl) for js, sl in zip(system.joints.joints, system.joints.row_slices()) if js.is_joint]
    lam = C = J = None
    if solved is not None:
        lam, C, J = solved
    elif system.n_c:  # multipliers: joint reactions, kinematic contact forces
        acc = accelerations(system, formulation, state.t, state.q, state.v, state.chart, state.memory, cfg,
                            state.element_memory)
        lam, C, J = acc.lam, acc.rows.C, acc.rows.J
    lam = np.zeros(0) if lam is None else lam
    if joints:  # (a kinematic contact's row is its indentation, not a violation)
        violation = float(max(np.max(np.abs(C[sl])) for _, sl in joints))
        for js, sl in joints:
            reactions.append(js.reaction_force(J[sl].reshape(js.n_joints, js.n_eq, 2, 6),
                                               lam[sl].reshape(js.n_joints, js.n_eq)))
    scalars: dict[str, float] = {}
    reaction_force = _stack(reactions, (0, 3))
    for out in system.outputs:
        scalars.update(out.values(cfg, reaction_force))
    for e in system.forces:
        if hasattr(e, "scalars"):
            scalars.update(e.scalars(cfg))
    joint_values = relative_coordinates(system.joints.joints, cfg.pose.R_WB, cfg.pose.W_r, cfg.twist.W_v, cfg.twist.W_omega,
                                        cfg)
    joint_values.update(drive_efforts(system.joints.joints, system.joints.row_slices(), lam))
    scalars.update({k: float(x) for k, x in joint_values.items()})
    if system.contacts:
        scalars.update(_contact_scalars(system, state, gaps, lam))
    if system.has_ledger:
        scalars.update(ledger_scalars(led, reference_energy))
    W_G, W_v = centres_of_mass(system, cfg)
    return Frame(
        t=state.t, W_r=W_G, R_WB=cfg.pose.R_WB[:-1], W_v=W_v, W_omega=cfg.twist.W_omega[:-1],
        reaction_force=reaction_force, energy_kinetic=T, energy_potential=V, constraint_violation=violation,
        scalars=scalars, draw=lambda: drawing_of(system, state, cfg, gaps, lam, drawings))


def drawing_of(system: System, state: State, cfg, gaps: tuple, lam: FloatArray, drawings: tuple = ()) -> Drawing:
    """The ``Drawing`` of ``state`` from its ``Configuration`` ``cfg``, each contact set's ``Gap`` and
    the multipliers ``lam`` (n_c,); ``drawings``: the ``FlexibleDrawing`` of each flexible body to
    draw deformed."""
    points = [js.points(cfg) for js in system.joints.joints if js.is_joint]
    springs = [e.endpoints(cfg)[0] for e in system.forces if isinstance(e, SpringDamper)]
    memories = state.element_memory or (None,) * len(system.forces)
    contacts = [e.contacts(cfg) if m is None else e.contacts(cfg, m)
                for e, m in zip(system.forces, memories) if hasattr(e, "contacts")]
    if system.contacts:
        contacts += _contact_arrows(system, state, gaps, lam)
    return Drawing(
        joint_points=_stack(points, (0, 3)), springs=_stack(springs, (0, 2, 3)),
        deformed={d.name: d.vertices(cfg) for d in drawings},
        stress={d.name: d.stresses(cfg) for d in drawings if d.stress_rows is not None},
        contact_points=_stack([c[0] for c in contacts], (0, 3)), contact_forces=_stack([c[1] for c in contacts], (0, 3)))


def _contact_scalars(system: System, state: State, gaps: tuple, lam) -> dict:
    """Force and indentation of every contact of every contact set (plot scalars)."""
    from viz3d.events import contact_forces

    out = {}
    for c, gp, F in zip(system.contacts, gaps, contact_forces(system, state, lam, gaps)):
        for i, name in enumerate(c.names):
            out[f"contact/{name}/force"] = float(F[i])
            out[f"contact/{name}/indentation"] = float(max(gp.alpha[i], 0.0))
    return out


def _contact_arrows(system: System, state: State, gaps: tuple, lam) -> list:
    """Points and forces of the contacts that carry a force, per contact set (for display)."""
    from viz3d.events import contact_forces

    out = []
    for gp, F in zip(gaps, contact_forces(system, state, lam, gaps)):
        on = F > 0.0
        if on.any():
            out.append((gp.point[on], F[on, None] * gp.n[on]))
    return out


def ledger_scalars(led, reference_energy: float | None) -> dict:
    """The ledger's plot scalars (``energy/...``), floats or arrays over instants as ``led`` holds;
    ``energy/balance_error`` against ``reference_energy`` (the ledger's initial total) if given."""
    out = {"energy/kinetic": led.kinetic, "energy/potential": led.potential, "energy/strain": led.strain,
           "energy/contact_elastic": led.contact_elastic, "energy/dissipated": led.dissipated,
           "energy/work_in": led.work_in}
    if reference_energy is not None:
        out["energy/balance_error"] = led.total + led.dissipated - led.work_in - reference_energy
    return out


def _stack(parts: list, empty_shape: tuple) -> FloatArray:
    return np.concatenate(parts) if parts else np.zeros(empty_shape)

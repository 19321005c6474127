"""A system packed for the compiled kernel: the model ``Model`` (frozen, per system), the workspace
``Work`` (written by every evaluation) and the elements' packed data, one entry per registered
compiled piece (``viz3d.compiled``).

Packing asks every force element, row provider and contact set for its ``compiled(pack)`` data;
``Packer`` gives them global indices: material points (one table for the whole system), the first
constraint row of a row provider, the first global index of a contact set (its memory rows and its
power slots in the ledger). An element without a compiled piece makes ``pack`` raise
``Unsupported`` naming it: the run then takes the NumPy path and says so.

Layout of ``y = [q, v, w]`` as in ``viz3d.system``: nf floating frames ``[W_r, theta (n_rot)]`` (ZXZ
Euler angles in a chart, n_rot = 3, or Euler parameters, n_rot = 4) and ``[W_v, B_omega]``, then the
stacked elastic coordinates and rates, then the ledger's work integrals.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from viz3d.compiled import (
    Items,
    after_step_piece,
    concat,
    energy_piece,
    force_piece,
    gap_piece,
    hold_piece,
    replant_piece,
    items,
    registered,
    row_piece,
    target_of,
)
from viz3d.coordinates import CHART_CENTRE, EulerSwitching, EulerZXZ, Quaternion
from viz3d.flexible.floating_kernel import pack_flexible
from viz3d.rotations import matrix_from_euler

#: ``Model.body_kind`` codes.
RIGID, FLOATING_FLEXIBLE, FIXED_FLEXIBLE, GROUND = 0, 1, 2, 3
#: The rotation of the Euler charts' centre (``Model``'s, copied into each).
_CHART_CENTRE_R = matrix_from_euler(CHART_CENTRE)
#: Formulations the kernel evaluates, and their ``Model.form`` = [damping, frequency, compliance]:
#: ``gamma - 2 damping C_d - frequency^2 C`` and ``compliance`` added to the Schur diagonal.
FORMULATIONS = {
    "index1": lambda f: (0.0, 0.0, 0.0),
    "baumgarte": lambda f: (f.alpha, f.beta, 0.0),
    "penalty": lambda f: (f.xi * f.omega, f.omega, 1.0 / f.alpha),
    "projection": lambda f: (0.0, 0.0, 0.0),  # index1's field; positions and velocities projected after each step
    "ali3p": lambda f: (0.0, 0.0, 0.0),  # steps itself (viz3d.kernel.ali3p); its field (output frames) is index1's
}
#: Formulations that step themselves whose steps the kernel takes (``viz3d.kernel.ali3p``).
STEPPING = ("ali3p",)
#: Formulations whose ``post_step`` the kernel makes after each step (``viz3d.kernel.projection``).
PROJECTING = ("projection",)
#: Rows of scratch 3-vectors in ``View.v3``: 0-7 for viz3d.points, 8-15 for pieces and bodies, 16-34 for
#: pieces that call the ball joint's rows (``viz3d.joints``).
N_V3 = 35


class Unsupported(Exception):
    """The kernel does not cover something in the system (the message says what)."""


class Model(NamedTuple):
    """What the compiled functions know of a system (shapes: nb bodies, nf floating frames, nx
    flexible bodies, np material points, n_c constraint rows, n_e elastic coordinates)."""

    nb: int
    body_kind: np.ndarray     # (nb + 1,) int: RIGID, FLOATING_FLEXIBLE, FIXED_FLEXIBLE, GROUND
    body_frame: np.ndarray    # (nb + 1,) int: floating-frame index, -1
    body_flex: np.ndarray     # (nb + 1,) int: flexible index, -1
    mass_inv: np.ndarray      # (nb + 1,) [1/kg] of the rigid bodies (0 elsewhere), as Bodies.M_inv
    inertia: np.ndarray       # (nb + 1, 3, 3) rigid bodies [kg m^2]
    inertia_inv: np.ndarray   # (nb + 1, 3, 3)
    r0: np.ndarray            # (nb + 1, 3) frame origins of fixed frames (and ground) [m]
    R0: np.ndarray            # (nb + 1, 3, 3) their orientations
    frame_body: np.ndarray    # (nf,) int
    n_q: int
    n_v: int
    n_e: int
    fx_i: np.ndarray          # flexible bodies (viz3d.flexible.floating_kernel)
    fx_f: np.ndarray
    fx_pool: np.ndarray
    fx_bij: np.ndarray
    pt_s: np.ndarray          # (np, 3) points' offsets in body axes [m] (viz3d.points)
    row_body: np.ndarray      # (n_c, 2) int
    perm: np.ndarray          # (n_c,) int: solve order of the rows
    pair: np.ndarray          # (n_pairs, 5) int: row, side, row, side, slot in Work.ab
    kd: int                   # half-bandwidth of the Schur complement in solve order
    form: np.ndarray          # (3,): damping, frequency, compliance (FORMULATIONS)
    n_rot: int                # orientation coordinates per floating frame: 3 (ZXZ Euler angles), 4 (Euler parameters)
    switching: int            # Euler charts re-centred near gimbal lock
    centre: np.ndarray        # (3,) chart centre angles
    centre_R: np.ndarray      # (3, 3) its rotation
    n_aux: int                # work integrals in y
    projects: int             # 1: project positions and velocities after each step (PROJECTING)
    projection_tol: float     # its position tolerance, max |C| [m]
    projection_iter: int      # its Newton corrections allowed
    remembers: int            # 1: force elements renew a memory after each step (``after_step_piece``)


class View(NamedTuple):
    """What the compiled pieces see (``viz3d.compiled``): material points (tables and, per
    evaluation, kinematics), the frames' rotations and world angular velocities, the generalized
    forces, the constraint rows, scratch vectors and the contacts' memory."""

    pt_i: np.ndarray          # (np, 4) int: body, N offset, n, eta offset (viz3d.points)
    pt_N: np.ndarray          # pool of the points' N (3, n)
    pt_P: np.ndarray          # pool of their sections' P (3, n), at the offsets of N (viz3d.points)
    R: np.ndarray             # (nb + 1, 3, 3)
    wW: np.ndarray            # (nb + 1, 3) [rad/s]
    ps: np.ndarray            # (np, 3) deformed offsets, body axes [m]
    prho: np.ndarray          # (np, 3) levers, world [m]
    px: np.ndarray            # (np, 3) positions [m]
    pv: np.ndarray            # (np, 3) velocities [m/s]
    pud: np.ndarray           # (np, 3) elastic velocities R N eta_dot [m/s]
    pth: np.ndarray           # (np, 3) sections' small rotations R P eta, world [rad]
    pom: np.ndarray           # (np, 3) their rates relative to the frame R P eta_dot, world [rad/s]
    F: np.ndarray             # (nb + 1, 3) world forces at the frame origins [N]
    tau: np.ndarray           # (nb + 1, 3) world torques about them [N m]
    Qe: np.ndarray            # (n_e,) elastic generalized forces
    row_je: np.ndarray        # (n_c, 2) int: offset of the side's elastic Jacobian in Je, -1
    J: np.ndarray             # (n_c, 2, 6) frame Jacobian blocks
    Je: np.ndarray            # elastic Jacobian parts (pool)
    C: np.ndarray             # (n_c,) residuals
    gam: np.ndarray           # (n_c,) gamma
    Ct: np.ndarray            # (n_c,) explicit time rate of C (drives; C_dot = C_v v + C_t)
    inactive: np.ndarray      # (n_c,) int: rows that do not act now
    v3: np.ndarray            # (N_V3, 3) scratch
    mem: np.ndarray           # (n_contacts, 7) contacts' memory (viz3d.contact.contacts.memory_rows)


class Work(NamedTuple):
    """Scratch of the generic stages of one evaluation (see ``workspace``)."""

    r: np.ndarray
    vW: np.ndarray
    wB: np.ndarray
    eta: np.ndarray
    eta_dot: np.ndarray
    Q: np.ndarray
    a: np.ndarray
    ae: np.ndarray
    tw: np.ndarray
    fx_work: np.ndarray
    fx_sc: np.ndarray
    W6: np.ndarray
    We: np.ndarray
    lam: np.ndarray
    x: np.ndarray
    ab: np.ndarray
    aux: np.ndarray
    m3: np.ndarray


@dataclass(frozen=True, eq=False)
class KernelData:
    """A packed system: model, the elements' data per registered piece, workspace sizes."""

    model: Model
    forces: tuple
    rows: tuple
    geometry: tuple
    n_contacts: int
    work_sizes: tuple
    pt_i: np.ndarray
    pt_N: np.ndarray
    pt_P: np.ndarray
    row_je: np.ndarray
    elastic_slices: tuple     # each flexible body's slice of the stacked elastic coordinates
    contact_slices: tuple     # each contact set's slice of the contacts (global contact indices)
    energies: tuple           # the force elements' data per registered energy piece
    energy_gap: str | None    # why output frames cannot take their energies from the kernel (None: they can)
    memories: tuple | None    # the force elements' data per registered after-step piece (their memory; None: none)
    replants: tuple           # the law contacts' data per registered replant piece (the adaptive driver's)
    anchors: tuple            # (index in System.forces, CollisionItems) of shape contacts with stick anchors
    #: Compiled entries of the kernel's functions for this data's argument types, by dispatcher
    #: (``viz3d.kernel.KernelStepper._call``); a copy made by ``dataclasses.replace`` starts empty.
    entries: dict = field(init=False, repr=False, compare=False, default_factory=dict)
    #: numba's fingerprints of its tuples the compiled calls take, by field name (``viz3d.kernel.type_prints``).
    prints: dict = field(init=False, repr=False, compare=False, default_factory=dict)


class Packer:
    """Global indices handed to the elements while they pack themselves (see module docstring)."""

    Unsupported = Unsupported

    def __init__(self, system):
        self.system, self.bodies = system, system.bodies
        self._pt_i: list = []
        self._pt_s: list = []
        self._pt_N: list = []
        self._pt_P: list = []
        self._N_size = 0
        starts = [s.start for s in system.joints.row_slices()]
        self._row_start = {id(js): start for js, start in zip(system.joints.joints, starts)}
        k0 = np.cumsum([0] + [c.k for c in system.contacts])
        self._contact_start = {id(c): int(k) for c, k in zip(system.contacts, k0)}

    @property
    def n_points(self) -> int:
        return len(self._pt_i)

    def points(self, bp) -> np.ndarray:
        """Register the material points of ``bp`` (``viz3d.points.BodyPoints``); their global indices (k,)."""
        NP_of: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for g in bp.flex:
            for j, p in enumerate(g.which):
                NP_of[int(p)] = g.material.N[j], g.material.P[j]
        e0 = self._elastic_offsets()
        return np.array([self._add(int(bp.body[p]), bp.B_s[p], *NP_of.get(p, (None, None)), e0.get(int(bp.body[p]), 0))
                         for p in range(bp.k)], dtype=np.int64)

    def centres_of_mass(self) -> np.ndarray:
        """A point at every body's centre of mass, (nb,): the frame origin of a rigid body; on a
        flexible body the deflected centre of mass ``S eta / m`` (N = S / m; no section: P = 0)."""
        e0 = self._elastic_offsets()
        bar = {fb.index: fb.bar for fb in self.bodies.flexible}
        return np.array([self._add(b, np.zeros(3), *((bar[b].S / bar[b].mass, np.zeros_like(bar[b].S)) if b in bar
                                                      else (None, None)), e0.get(b, 0))
                         for b in range(self.bodies.n_bodies)], dtype=np.int64)

    def _elastic_offsets(self) -> dict[int, int]:
        offsets = np.cumsum([0] + [fb.n for fb in self.bodies.flexible])
        return {fb.index: int(o) for fb, o in zip(self.bodies.flexible, offsets)}

    def _add(self, body: int, s, N, P, e0: int) -> int:
        """A point with offset ``s`` (3,), on a flexible body its ``N`` and ``P`` (3, n) (else None)."""
        off, n = self._N_size, 0
        if N is not None:
            N = np.ascontiguousarray(N, dtype=float)
            n = N.shape[1]
            self._pt_N.append(N.ravel())
            self._pt_P.append(np.ascontiguousarray(P, dtype=float).ravel())
            self._N_size += N.size
        self._pt_i.append((body, off, n, e0 if n else 0))
        self._pt_s.append(np.asarray(s, dtype=float))
        return len(self._pt_i) - 1

    def row_start(self, provider) -> int:
        """First constraint row of a row provider of ``System.joints``."""
        return self._row_start[id(provider)]

    def contact_start(self, contact_set) -> int:
        """Global index of the first contact of a set of ``System.contacts``."""
        return self._contact_start[id(contact_set)]

    def law_items(self, law) -> type[Items]:
        """The packed data class of contacts with ``law`` (its compiled piece), or ``Unsupported``."""
        from viz3d.contact.contacts import law_contacts

        if type(law).compiled_items is None:
            raise Unsupported(f"normal law {law.name!r} has no compiled piece")
        return law_contacts(type(law).compiled_items)

    def collision_items(self, collisions):
        """The packed data of shape contacts (``viz3d.kernel.collisions``), or ``Unsupported``."""
        from viz3d.kernel.collisions import pack_collisions

        return pack_collisions(collisions, self)

    def tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(pt_i, pt_s, pt_N, pt_P)`` of the registered points (``View``, ``Model``)."""
        pt_i = np.array(self._pt_i, np.int64).reshape(-1, 4)
        pt_s = np.array(self._pt_s, float).reshape(-1, 3)
        pool = lambda parts: np.concatenate(parts) if parts else np.zeros(0)  # noqa: E731
        return pt_i, pt_s, pool(self._pt_N), pool(self._pt_P)


def _register_pieces() -> None:
    """Import viz3d's modules with compiled pieces: the kernel's argument types (one ``Items`` per
    registered class, ``registered``) must not depend on what the caller happened to import (a
    system built without the contact modules left the contact tables empty, and ``sample`` failed to
    compile over the empty tuple). Not the shape contacts' (``viz3d.kernel.collisions``, 6 ms of a
    run's start): their data is in the tuples only where the system has them (``present_only``), and
    packing them imports the module (``Packer.collision_items``)."""
    import viz3d.contact.contacts  # noqa: F401
    import viz3d.contact.laws  # noqa: F401
    import viz3d.forces  # noqa: F401
    import viz3d.joints  # noqa: F401


def pack(system, formulation) -> KernelData:
    """``system`` and ``formulation`` packed for the kernel; ``Unsupported`` names what it lacks."""
    _register_pieces()
    _check(system, formulation)
    packer = Packer(system)
    parts, classes = _parts(list(system.forces) + list(system.contacts) + list(system.joints.joints), packer)
    if sum(getattr(e, "type_name", None) == "collisions" for e in system.forces) > 1:
        raise Unsupported("more than one shape-contact element")
    if formulation.name in STEPPING:
        _check_held(system.forces, classes)
    forces, rows, geometry, energies, memories, replants = (_by_class(target, parts) for target in (
        force_piece, row_piece, gap_piece, energy_piece, after_step_piece, replant_piece))
    memories = memories or None  # (numba unrolls no empty tuple; the kernel skips None)
    pt_i, pt_s, pt_N, pt_P = packer.tables()
    model, sizes, row_je = _model(system, formulation, pt_s)
    return KernelData(model, forces, rows, geometry, sum(c.k for c in system.contacts), sizes, pt_i, pt_N, pt_P, row_je,
                      _slices([fb.n for fb in system.bodies.flexible]), _slices([c.k for c in system.contacts]),
                      energies, _energy_gap(system.forces, classes), memories, replants, _anchors(system.forces, parts))


def per_run(system, formulation) -> bool:
    """True when ``system``'s packed data for ``formulation`` holds what a run writes, so that each run
    needs its own packing: a force element's ``packed_per_run`` (shape contacts' scratch and stick
    anchors), or, under a formulation that steps itself (ALI3-P), the branches it holds within each
    step in their elements' data (``hold_piece``: joint stops' sides)."""
    return any(e.packed_per_run or (e.branches and formulation.name in STEPPING) for e in system.forces)


def _anchors(forces, parts: dict[type, list]) -> tuple:
    """``KernelData.anchors``: each shape-contact element with stick anchors and its packed data."""
    shapes = [(k, e) for k, e in enumerate(forces) if getattr(e, "type_name", None) == "collisions"]
    if not shapes:  # (their module is imported where they are packed: ``Packer.collision_items``)
        return ()
    from viz3d.kernel.collisions import CollisionItems

    return tuple((k, d) for (k, e), d in zip(shapes, parts[CollisionItems]) if e.has_memory)


def _energy_gap(forces, classes: dict[int, list[type]]) -> str | None:
    """Why the kernel cannot give the force elements' potential energy (an element with its own
    ``potential_energy`` whose data has no ``energy_piece``), or None; ``classes``: the data classes
    each element packed itself into, by ``id``."""
    from viz3d.forces import ForceElement

    with_piece = registered(energy_piece)
    for e in forces:
        if type(e).potential_energy is not ForceElement.potential_energy and not all(
                issubclass(c, with_piece) for c in classes[id(e)]):
            return f"{getattr(e, 'type_name', type(e).__name__)!r} has no compiled energy piece"
    return None


def _slices(sizes: list[int]) -> tuple[slice, ...]:
    """Consecutive slices of the given sizes."""
    ends = np.cumsum([0] + sizes)
    return tuple(slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:]))


def _check(system, formulation) -> None:
    if formulation.name not in FORMULATIONS or (getattr(formulation, "integrator", None) is not None
                                                and formulation.name not in STEPPING):
        raise Unsupported(f"formulation {formulation.name!r}")
    if formulation.name in STEPPING:
        _check_stepping(system)
    if type(system.rotation) not in (EulerSwitching, EulerZXZ, Quaternion):
        raise Unsupported(f"orientation coordinates {system.rotation.name!r}")
    if any(fb.ked for fb in system.bodies.flexible):
        raise Unsupported("kineto-elastodynamic flexible bodies (coupling = 'ked')")


def _check_stepping(system) -> None:
    """What the compiled ALI3-P steps (``viz3d.kernel.ali3p``) leave to the NumPy path."""
    if system.n_elastic or system.bodies.flexible:
        raise Unsupported("ALI3-P with flexible bodies")
    if system.contacts:
        raise Unsupported("ALI3-P with contacts")


def _check_held(forces, classes: dict[int, list[type]]) -> None:
    """Every force element with branches can hold them in the compiled ALI3-P (a ``hold_piece``)."""
    for e in forces:
        if e.branches and not any(c in registered(hold_piece) for c in classes.get(id(e), [])):
            raise Unsupported(f"ALI3-P with {e.type_name!r}: its branches have no compiled hold_piece")


def _parts(elements, packer) -> tuple[dict[type, list], dict[int, list[type]]]:
    """Every element's packed data (``compiled(packer)``) grouped by data class, and the classes of
    each element's data (by ``id``)."""
    found: dict[type, list] = {}
    classes: dict[int, list[type]] = {}
    for e in elements:
        if not hasattr(e, "compiled"):
            what = getattr(e, "type_name", type(e).__name__)
            raise Unsupported(f"{what!r} has no compiled piece")
        out = e.compiled(packer)
        for part in out if isinstance(out, list) else [out]:
            if target_of(type(part)) is None:
                raise Unsupported(f"{type(part).__name__} is not registered for a compiled target")
            found.setdefault(type(part), []).append(part)
            classes.setdefault(id(e), []).append(type(part))
    return found, classes


def _by_class(target, found: dict[type, list]) -> tuple:
    """One ``Items`` per registered data class of ``target``, in canonical order (empty where the
    system has none), except classes with ``present_only`` where the system has none."""
    return tuple(concat(cls, found[cls]) if cls in found else items(cls) for cls in registered(target)
                 if cls in found or not cls.present_only)


def _model(system, formulation, pt_s) -> tuple[Model, tuple, np.ndarray]:
    b = system.bodies
    nb = b.n_bodies
    kind = np.full(nb + 1, RIGID, np.int64)
    kind[nb] = GROUND
    flex = np.full(nb + 1, -1, np.int64)
    r0, R0 = np.zeros((nb + 1, 3)), np.broadcast_to(np.eye(3), (nb + 1, 3, 3)).copy()
    for k, fb in enumerate(b.flexible):
        kind[fb.index] = FLOATING_FLEXIBLE if fb.floating else FIXED_FLEXIBLE
        flex[fb.index] = k
        r0[fb.index], R0[fb.index] = fb.W_r0, fb.R0
    frame = np.full(nb + 1, -1, np.int64)
    frame[system.frame_body] = np.arange(system.n_frames)
    inertia = np.zeros((nb + 1, 3, 3))
    inertia_inv = np.zeros((nb + 1, 3, 3))
    inertia[:nb][b.is_rigid] = b.inertia[b.is_rigid]
    inertia_inv[:nb] = b.M_inv[:nb, 3:, 3:]
    e_offsets = np.cumsum([0] + [fb.n for fb in b.flexible])[:-1]
    fx_i, fx_f, fx_pool, fx_bij, fx_work = pack_flexible(b.flexible, e_offsets)
    row_body, row_je, n_je, perm, pair, kd = _rows(system, flex)
    form = np.array(FORMULATIONS[formulation.name](formulation), dtype=float)
    mass_inv = np.append(b.M_inv[:nb, 0, 0], 0.0).astype(float)
    model = Model(nb, kind, frame, flex, mass_inv, inertia, inertia_inv, r0, R0, system.frame_body.astype(np.int64),
                  system.n_q, system.n_v, system.n_elastic, fx_i, fx_f, fx_pool, fx_bij, pt_s,
                  row_body, perm, pair, kd, form, system.rotation.n_q, int(isinstance(system.rotation, EulerSwitching)),
                  CHART_CENTRE.copy(), _CHART_CENTRE_R.copy(), system.n_aux, *_projection(formulation),
                  int(any(e.has_memory for e in system.forces)))
    n_contacts = sum(c.k for c in system.contacts)
    return model, (nb, len(b.flexible), pt_s.shape[0], system.n_elastic, fx_work, row_body.shape[0], n_je, kd,
                   max(system.n_aux, n_contacts + 2), n_contacts), row_je


def _projection(formulation) -> tuple[int, float, int]:
    """``Model.projects``, ``projection_tol`` [m], ``projection_iter`` of ``formulation`` (what its
    ``post_step`` passes to ``viz3d.stabilization.project_positions``)."""
    from viz3d.stabilization import MAX_ITER

    if formulation.name not in PROJECTING:
        return 0, 0.0, 0
    return 1, float(formulation.tol), MAX_ITER


def _rows(system, flex) -> tuple:
    """Row bodies, elastic-Jacobian offsets, solve order and every coupling of two (row, side)
    entries through a shared body, with its slot in band storage of half-width kd (a dense
    layout is a band of half-width n_c - 1)."""
    lay = system.joints
    n_c = lay.n_rows
    row_body = lay.row_body.astype(np.int64).reshape(n_c, 2)
    width = {fb.index: fb.n for fb in system.bodies.flexible}
    row_je = np.full((n_c, 2), -1, np.int64)
    n_je = 0
    for r in range(n_c):
        for s in range(2):
            if int(row_body[r, s]) in width:
                row_je[r, s] = n_je
                n_je += width[int(row_body[r, s])]
    entries = [np.column_stack([lay.pair_row, lay.pair_side, lay.pair_col, lay.pair_colside])]
    for g in lay.flex_groups:
        entries.append(np.column_stack([g.row[g.pair_a], g.side[g.pair_a], g.row[g.pair_b], g.side[g.pair_b]]))
    pair = np.concatenate(entries).astype(np.int64) if n_c else np.zeros((0, 4), np.int64)
    kd = lay.kd if lay.banded else max(n_c - 1, 0)
    pos = np.empty(n_c, dtype=np.int64)
    pos[lay.perm] = np.arange(n_c)
    i, j = pos[pair[:, 0]], pos[pair[:, 2]]
    assert np.all(i <= j), "couplings must be in the upper triangle of the solve order"
    slot = (kd + i - j) * n_c + j
    return row_body, row_je, n_je, lay.perm.astype(np.int64), np.column_stack([pair, slot]).astype(np.int64), int(kd)


def workspace(data: KernelData) -> tuple[View, Work]:
    """Fresh scratch arrays for ``data`` (contacts' memory zero: nothing touching)."""
    nb, nx, n_p, n_e, fx_work, n_c, n_je, kd, n_power, n_contacts = data.work_sizes
    z3 = lambda n: np.zeros((n, 3))  # noqa: E731
    view = View(data.pt_i, data.pt_N, data.pt_P, np.zeros((nb + 1, 3, 3)), z3(nb + 1), z3(n_p), z3(n_p), z3(n_p),
                z3(n_p), z3(n_p), z3(n_p), z3(n_p), z3(nb + 1), z3(nb + 1), np.zeros(n_e), data.row_je,
                np.zeros((n_c, 2, 6)), np.zeros(n_je),
                np.zeros(n_c), np.zeros(n_c), np.zeros(n_c), np.zeros(n_c, np.int64), np.zeros((N_V3, 3)),
                np.zeros((n_contacts, 7)))
    work = Work(z3(nb + 1), z3(nb + 1), z3(nb + 1), np.zeros(n_e), np.zeros(n_e), np.zeros((nb + 1, 6)),
                np.zeros((nb + 1, 6)), np.zeros(n_e), np.zeros((nb + 1, 6)), np.zeros(fx_work), np.zeros((nx, 6, 6)),
                np.zeros((n_c, 2, 6)), np.zeros(n_je), np.zeros(n_c), np.zeros(n_c), np.zeros((kd + 1) * n_c),
                np.zeros(n_power), np.zeros((4, 3, 3)))
    return view, work

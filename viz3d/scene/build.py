"""``Scene`` -> frozen ``System`` and a consistent initial ``State``.

Mass properties come from the scene (given, or shape x density); joint and spring points given
in world coordinates are converted to body coordinates at the initial pose; then the initial
positions and velocities are projected onto the constraints, with a warning stating the size of
the correction.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from viz3d._typing import FloatArray
from viz3d.bodies import Bodies, InertiaError
from viz3d.constraints import SingularConstraintError, build_layout, constraint_jacobian, constraint_rows
from viz3d.contact.contacts import ContactRows, ContactSet
from viz3d.coordinates import ROTATIONS
from viz3d.diagnosis import redundant_joints
from viz3d.dynamics import body_state
from viz3d.forces import AppliedForce, AppliedTorque, DriveServo, Gravity, JointMotor, JointStop, SpringDamper
from viz3d.formulation import ALI3P, Baumgarte, Index1, Penalty, Projection
from viz3d.geometry import MeshError, primitive_properties, shape_mesh, shape_mesh_properties
from viz3d.integrators import GeneralizedAlpha, Integrator, make_integrator
from viz3d.integrators.adaptive import Controller
from viz3d.joints import JOINTS, BallJoint, JointDrive
from viz3d.kinematics import Configuration, pose_from, twist_from
from viz3d.outputs import GAUGES
from viz3d.points import body_points
from viz3d.rotations import matrix_from_euler
from viz3d.scene.bars import flexible_body
from viz3d.scene.contacts import contact_law, friction_law
from viz3d.scene.contacts import materials as contact_materials
from viz3d.scene.load import Scene
from viz3d.scene.schema import SceneError
from viz3d.stabilization import MAX_ITER, ProjectionError, project_positions, project_velocities
from viz3d.system import State, System
from viz3d.timefunctions import PROFILE_KINDS, TimeFunctions

#: Initial-condition corrections larger than this are reported [m, m/s].
REPORT_CORRECTION = 1e-9
#: Adaptive runs fail (with a diagnosis) rather than take steps below this [s].
ADAPTIVE_MIN_STEP = 1e-12


class InitialConditionsWarning(UserWarning):
    """The scene's initial positions or velocities were moved onto the constraints."""


@dataclass(frozen=True)
class MassProperties:
    """Per body: mass [kg], inertia about the centre of mass (3, 3) [kg m^2], and the shape's
    centroid in its own frame (3,) [m] (mesh vertices are shifted by it)."""

    mass: float
    inertia: FloatArray
    center: FloatArray


def build(scene: Scene) -> tuple[System, State]:
    """Frozen system and projected initial state of a scene.

    Raises
    ------
    SceneError
        For mass properties, meshes or joints that cannot be used (naming file and key).
    """
    sim = scene.data["sim"]
    system = build_system(scene)
    W_r0, R0 = initial_pose(scene, system.bodies)
    frames = system.frame_body
    theta, chart = system.rotation.from_matrix(R0[frames])
    q = system.join_q(W_r0[frames], theta)
    v = initial_velocities(scene, R0, system)
    state = State(0.0, q, v, chart, np.zeros(system.n_aux), tuple(c.initial_phases() for c in system.contacts))
    formulation = make_formulation(sim) if sim["compiled"] else None
    return system, consistent_state(system, state, scene.source(), sim["projection_tol"], formulation)


def build_system(scene: Scene) -> System:
    """The frozen system of a scene (``build`` without the initial state); packed for the compiled
    kernel too when the scene runs there (``viz3d.kernel.keep_packed``)."""
    bodies, _ = build_bodies(scene)
    sim = scene.data["sim"]
    rotation = ROTATIONS[sim["rotation"]]()
    W_r0, R0 = initial_pose(scene, bodies)
    pose0 = pose_from(W_r0, R0)
    joints = build_joints(scene, bodies, pose0)
    drives = build_drives(scene, joints)
    contacts = build_contacts(scene, bodies, pose0)
    rows = joints + drives + tuple(ContactRows(c, c.rigid_rows(), k) for k, c in enumerate(contacts) if len(c.rigid_rows()))
    n_e = sum(fb.n for fb in bodies.flexible)
    gravity = Gravity(bodies.mass, np.asarray(sim["gravity"], float), bodies.flexible, n_e)
    forces = (gravity,) + build_forces(scene, bodies, pose0, joints) + build_servos(scene, joints) + shape_contacts(
        scene, bodies) + build_water(scene, bodies)
    outputs = build_gauges(scene, bodies) + build_stowage_outputs(scene, bodies, joints, W_r0)
    system = System(bodies, build_layout(rows, bodies), forces, rotation, contacts, outputs)
    formulation = make_formulation(sim) if sim["compiled"] else None
    if formulation is not None:  # the model packed for the compiled kernel too, kept with it for its runs
        from viz3d.kernel import keep_packed

        keep_packed(system, formulation)
    return system


def build_bodies(scene: Scene) -> tuple[Bodies, tuple[str, ...]]:
    """The scene's bodies, and per flexible body how its model was chosen."""
    src = scene.source()
    specs = scene.data["bodies"]
    mass, inertia, flexible, choices = [], [], [], []
    for i, b in enumerate(specs):
        if b["type"] == "flexible":
            fb, choice = flexible_body(i, b, src, f"bodies[{i}]")
            flexible.append(fb)
            choices.append(choice)
            mass.append(fb.bar.mass)
            inertia.append(fb.bar.J0)
        else:
            p = body_mass_properties(scene, i)
            mass.append(p.mass)
            inertia.append(p.inertia)
    try:
        bodies = Bodies(tuple(b["name"] for b in specs), np.array(mass, float), np.array(inertia, float).reshape(-1, 3, 3),
                        tuple(flexible))
    except InertiaError as exc:
        raise SceneError(src, "bodies", f"physical mass properties ({exc})") from None
    return bodies, tuple(choices)


def make_formulation(sim: dict):
    """Formulation object named by ``sim.formulation`` with its scene parameters."""
    name = sim["formulation"]
    if name == "baumgarte":
        return Baumgarte(sim["baumgarte_alpha"], sim["baumgarte_beta"])
    if name == "projection":
        return Projection(sim["projection_tol"])
    penalty = Penalty(sim["penalty_alpha"], sim["penalty_xi"], sim["penalty_omega"])
    if name == "penalty":
        return penalty
    if name == "ali3p":
        return ALI3P(sim["ali3p_alpha"], sim["projection_tol"], start=penalty)
    return Index1()


def make_integrator_from(sim: dict) -> Integrator:
    """Integrator named by ``sim.integrator`` with its scene parameters (``sim.rho_inf``)."""
    if sim["integrator"] == "gen_alpha":
        return GeneralizedAlpha(sim["rho_inf"])
    return make_integrator(sim["integrator"])


def make_controller(sim: dict) -> Controller | None:
    """Step-size controller of an adaptive run (``sim.rtol`` given), else ``None`` (fixed steps)."""
    if "rtol" not in sim:
        return None
    return Controller(sim["rtol"], sim["atol"], sim.get("max_step", np.inf), ADAPTIVE_MIN_STEP)


# ---------------------------------------------------------------- bodies


def body_mass_properties(scene: Scene, i: int) -> MassProperties:
    """Mass properties of body ``i``: given, or from its shape and density (or shape and mass)."""
    b = scene.data["bodies"][i]
    where = f"bodies[{i}]"
    if "inertia" in b:
        return MassProperties(b["mass"], np.asarray(b["inertia"], float), np.zeros(3))
    unit = shape_unit_properties(scene, b["shape"], f"{where}.shape")
    if not unit.volume > 0.0:  # sizes so small that the volume underflows (fuzzing found 1e-135 m radii)
        raise SceneError(scene.source(), f"{where}.shape", "a shape whose volume is a positive number (its sizes "
                         f"give {unit.volume:g} m^3)", b["shape"])
    density = b["density"] if "density" in b else b["mass"] / unit.volume
    return MassProperties(density * unit.volume, density * unit.inertia, unit.center)


def build_water(scene: Scene, bodies: Bodies) -> tuple:
    """The ``Water`` element of a scene's ``[water]`` table (none without one, or when disabled).

    Its bodies: those ``water.bodies`` names (rigid, with a shape; a mesh one closed and outward), or
    every rigid body with a primitive shape or a closed, outward mesh (open meshes, collision surfaces
    given their inertia, stay dry). A mesh body's cells are cut in its frame: the mesh shifted by its
    centroid, unless its inertia is given (``body_mass_properties``, ``shape_centers``)."""
    spec, src = scene.data.get("water"), scene.source()
    if spec is None or not spec["enabled"]:
        return ()
    from viz3d.scene.collisions import bodies_matching
    from viz3d.water import Water, volume_cells

    specs = scene.data["bodies"]

    def unit(i: int):  # unit mass properties of body i's shape; SceneError if shapeless or an open mesh
        if not bodies.is_rigid[i] or "shape" not in specs[i]:
            raise SceneError(src, "water.bodies", f"rigid bodies with a shape (body {specs[i]['name']!r})",
                             specs[i]["name"])
        return shape_unit_properties(scene, specs[i]["shape"], f"bodies[{i}].shape")

    def closed(i: int):  # the default's test: None for an open mesh
        try:
            return unit(i)
        except SceneError:
            return None

    def cells(i: int, u) -> tuple:  # centres (m, 3) in body axes [m], volumes (m,) [m^3], cell size [m]
        shape, mesh = specs[i]["shape"], None
        if shape["type"] == "mesh":
            m = shape_mesh(shape, scene.base_dir)
            center = u.center if "inertia" not in specs[i] else np.zeros(3)
            mesh = (np.asarray(m.vertices, float) - center, np.asarray(m.faces, int))
        try:
            return volume_cells(shape, u.volume, spec["cells"], mesh)
        except ValueError as exc:
            raise SceneError(src, "water.cells", f"cells enough to fill body {specs[i]['name']!r} ({exc})",
                             spec["cells"]) from None

    if spec["bodies"]:
        chosen = [(i, unit(i)) for i in bodies_matching(src, "water.bodies", spec["bodies"], specs)]
    else:
        chosen = [(i, u) for i in range(len(specs)) if bodies.is_rigid[i] and "shape" in specs[i] and (u := closed(i))]
    if not chosen:
        return ()
    X, w, c = zip(*(cells(i, u) for i, u in chosen))
    V = np.array([u.volume for _, u in chosen])
    g = np.asarray(scene.data["sim"]["gravity"], float)
    normal = np.asarray(spec["normal"], float) if "normal" in spec else -g
    if not np.linalg.norm(normal) > 0.0:
        raise SceneError(src, "water.normal", "a normal, or a sim.gravity that gives one", spec.get("normal"))
    return (Water(np.array([i for i, _ in chosen], int), X, w, np.array(c), np.pi * (3 * V / (4 * np.pi)) ** (2 / 3),
                  float(spec["level"]), normal / np.linalg.norm(normal), float(spec["density"]),
                  float(np.linalg.norm(g)), float(spec["drag_coefficient"])),)


def shape_contacts(scene: Scene, bodies: Bodies) -> tuple:
    """The shape contacts of a scene's ``[collision]`` table (``viz3d.scene.collisions``, imported only
    for a scene with one: with ``viz3d.contact.collision`` it is 9 ms of a run's start)."""
    if scene.data.get("collision") is None:
        return ()
    from viz3d.scene.collisions import build_collisions

    return build_collisions(scene, bodies.n_bodies, bodies.is_rigid, shape_centers(scene, bodies))


def shape_centers(scene: Scene, bodies: Bodies) -> list:
    """Per body, its mesh shape's centroid in the mesh's own frame (mesh vertices are shifted by it;
    zero for primitives, flexible bodies and given inertias) [m]."""
    out = []
    for i, b in enumerate(scene.data["bodies"]):
        mesh = bodies.is_rigid[i] and b.get("shape", {}).get("type") == "mesh" and "inertia" not in b
        out.append(body_mass_properties(scene, i).center if mesh else np.zeros(3))
    return out


def shape_unit_properties(scene: Scene, shape: dict, where: str):
    if shape["type"] != "mesh":
        return primitive_properties(shape)
    try:
        return shape_mesh_properties(shape, scene.base_dir)
    except MeshError as exc:
        raise SceneError(scene.source(), f"{where}.file", f"a watertight, outward-oriented mesh file ({exc})") from None


def initial_pose(scene: Scene, bodies: Bodies | None = None) -> tuple[FloatArray, FloatArray]:
    """Initial frame origins (nb, 3) and rotations (nb, 3, 3): rigid bodies' centres of mass, flexible
    bodies' undeformed centres of mass."""
    W_r, R = [], []
    flexible = {fb.index: fb for fb in (bodies.flexible if bodies is not None else ())}
    for i, b in enumerate(scene.data["bodies"]):
        if i in flexible:
            W_r.append(flexible[i].W_r0)
            R.append(flexible[i].R0)
            continue
        angles = np.radians(b["euler_deg"]) if "euler_deg" in b else np.asarray(b.get("euler", [0.0, 0.0, 0.0]))
        W_r.append(b["position"])
        R.append(matrix_from_euler(angles))
    return np.asarray(W_r, float).reshape(-1, 3), np.asarray(R).reshape(-1, 3, 3)


def initial_velocities(scene: Scene, R0: FloatArray, system: System | None = None) -> FloatArray:
    """``v`` (n_v,) from the scene's world velocities and world angular velocities (elastic rates 0)."""
    W_v = np.array([b["velocity"] for b in scene.data["bodies"]], float).reshape(-1, 3)
    W_omega = np.array([b["omega"] for b in scene.data["bodies"]], float).reshape(-1, 3)
    B_omega = np.einsum("bji,bj->bi", R0, W_omega)
    frames = np.arange(len(W_v)) if system is None else system.frame_body
    v = np.concatenate([W_v[frames], B_omega[frames]], axis=1).reshape(-1)
    n_e = 0 if system is None else system.n_elastic
    return np.concatenate([v, np.zeros(n_e)]) if n_e else v


# ---------------------------------------------------------------- joints and forces


def _local_point(pose, body: int, entry: dict, point_key: str, local_key: str) -> FloatArray:
    """Body-frame point from a world point at the initial pose, or the given local point."""
    if local_key in entry:
        return np.asarray(entry[local_key], float)
    return pose.R_WB[body].T @ (np.asarray(entry[point_key], float) - pose.W_r[body])


def _side(bodies: Bodies, pose, body: int, entry: dict, side: str, point_key: str, local_key: str,
          default=None) -> tuple[FloatArray, float]:
    """One side's attachment: ``(B_s (3,), x)``. Rigid bodies and ground: the point in body axes
    (``x`` unused). Flexible bodies: the section ``x`` (given as ``x<side>``, or the world point's
    projection on the undeformed axis) and the offset of the point from the section centroid."""
    fb = next((f for f in bodies.flexible if f.index == body), None)
    if fb is None:
        if point_key not in entry and local_key not in entry:
            return np.zeros(3) if default is None else np.asarray(default, float), 0.0
        return _local_point(pose, body, entry, point_key, local_key), 0.0
    x_key = f"x{side}"
    if x_key in entry:
        return np.asarray(entry.get(local_key, [0.0, 0.0, 0.0]), float), float(entry[x_key])
    if point_key in entry:
        s = pose.R_WB[body].T @ (np.asarray(entry[point_key], float) - pose.W_r[body])
        x = float(np.clip(s[0] + fb.bar.x_G, 0.0, fb.bar.length))
        return s - (x - fb.bar.x_G) * np.array([1.0, 0.0, 0.0]), x
    return np.zeros(3), fb.bar.x_G


def _points(bodies: Bodies, pose, body: np.ndarray, entries: list[dict], side: str, point_key: str, local_key: str,
            default=None):
    """``(B_s (k, 3), BodyPoints)`` of one side of ``entries``."""
    sides = [_side(bodies, pose, int(b), e, side, point_key, local_key, default) for b, e in zip(body, entries)]
    B_s = np.array([s for s, _ in sides], float).reshape(-1, 3)
    x = np.array([x for _, x in sides], float)
    return B_s, body_points(bodies, body, B_s, x)


def build_joints(scene: Scene, bodies: Bodies, pose0) -> tuple:
    """One joint set per joint type present, in the order of ``JOINT_BUILDERS``."""
    groups: dict[str, list[dict]] = {}
    paths: dict[str, list[str]] = {}
    for i, j in enumerate(scene.data["joints"]):
        groups.setdefault(j["type"], []).append(j)
        paths.setdefault(j["type"], []).append(f"joints[{i}]")
    return tuple(make(groups[kind], bodies, pose0, scene.source(), paths[kind])
                 for kind, make in JOINT_BUILDERS.items() if kind in groups)


def _ball_joints(entries: list[dict], bodies: Bodies, pose0, source: str, paths: list[str]) -> BallJoint:
    body = np.array([[bodies.index(j["body1"]), bodies.index(j["body2"])] for j in entries], dtype=int)
    s1, p1 = _points(bodies, pose0, body[:, 0], entries, "1", "point", "local1")
    s2, p2 = _points(bodies, pose0, body[:, 1], entries, "2", "point", "local2")
    return BallJoint(tuple(j["name"] for j in entries), body, np.stack([s1, s2], axis=1), (p1, p2))


def _frame_axes(entry: dict) -> FloatArray:
    """The joint frame in world axes (columns x, y, z) in the initial configuration: ``axis`` is z;
    a universal joint's ``axis1`` is x and ``axis2``, made normal to it, y."""
    if "axis1" in entry:
        x = np.asarray(entry["axis1"], float)
        x = x / np.linalg.norm(x)
        y = np.asarray(entry["axis2"], float)
        y = y - (y @ x) * x
        if np.linalg.norm(y) < 1e-6 * np.linalg.norm(entry["axis2"]):
            raise ValueError("axis2", "a direction not parallel to axis1")
        y = y / np.linalg.norm(y)
        return np.column_stack([x, y, np.cross(x, y)])
    z = np.asarray(entry.get("axis", [0.0, 0.0, 1.0]), float)
    z = z / np.linalg.norm(z)
    helper = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = helper - (helper @ z) * z
    x = x / np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _framed_joints(kind: str):
    """Builder of a ``FramedJoint`` set of type ``kind``: each side's point and axes in its body's axes,
    the two frames coinciding in the initial pose ``pose0``. A side on a flexible body is the section
    ``x<side>`` (or the section nearest ``point``), its axes those of the undeformed section."""

    def make(entries: list[dict], bodies: Bodies, pose0, source: str, paths: list[str]):
        body = np.array([[bodies.index(j["body1"]), bodies.index(j["body2"])] for j in entries], dtype=int)
        nj = len(entries)
        B_A = np.zeros((nj, 2, 3, 3))
        located = [{**entry, "point": _framed_point(bodies, pose0, int(body[k, 0]), entry)} for k, entry in enumerate(entries)]
        sides = [_points(bodies, pose0, body[:, s], located, str(s + 1), "point", f"local{s + 1}") for s in (0, 1)]
        for k, (entry, path) in enumerate(zip(entries, paths)):
            if _on_each_body(entry, source, path):
                B_A[k] = entry["frame1"], entry["frame2"]
                continue
            _check_coincident(bodies, pose0, sides, k, source, path, entry)
            try:
                W_A = _frame_axes(entry)
            except ValueError as exc:
                key, expected = exc.args
                raise SceneError(source, f"{path}.{key}", expected, entry[key]) from None
            for side in (0, 1):
                B_A[k, side] = pose0.R_WB[body[k, side]].T @ W_A
        B_s = np.stack([sides[0][1].B_s, sides[1][1].B_s], axis=1)
        return JOINTS[kind](tuple(j["name"] for j in entries), body, B_s, B_A, (sides[0][1], sides[1][1]))

    return make


def _on_each_body(entry: dict, source: str, path: str) -> bool:
    """True for a framed joint given on each body (``frame1``, ``frame2``, ``local1``, ``local2``: its
    point and frame in each side's axes, not in the initial configuration); refuses a partial one."""
    keys = ("frame1", "frame2", "local1", "local2")
    given = [k for k in keys if k in entry]
    if "frame1" not in entry and "frame2" not in entry:
        return False
    if len(given) < len(keys):
        missing = next(k for k in keys if k not in entry)
        raise SceneError(source, f"{path}.{missing}", "given with the other three of frame1, frame2, local1, local2 "
                         "(a joint on each body)")
    return True


def _framed_point(bodies: Bodies, pose0, body1: int, entry: dict) -> FloatArray:
    """The world joint point of a framed joint in the initial configuration: ``point``, else body 1's
    section ``x1`` (flexible) or its centre of mass."""
    if "point" in entry:
        return np.asarray(entry["point"], float)
    fb = next((f for f in bodies.flexible if f.index == body1), None)
    if fb is None or "x1" not in entry:
        return pose0.W_r[body1]
    s = (float(entry["x1"]) - fb.bar.x_G) * np.array([1.0, 0.0, 0.0]) + np.asarray(entry.get("local1", np.zeros(3)), float)
    return pose0.W_r[body1] + pose0.R_WB[body1] @ s


#: Both sides of a framed joint given as sections must meet within this distance relative to the
#: bodies' size (typed-in numbers; a mismatch is a wrong section, not round-off).
COINCIDENCE_RTOL = 1e-9


def _rest_configuration(bodies: Bodies, pose0) -> Configuration:
    """The configuration at the pose ``pose0``, at rest and undeformed."""
    zeros = tuple(np.zeros(fb.n) for fb in bodies.flexible)
    rest = np.zeros_like(pose0.W_r[:-1])
    return Configuration(0.0, pose0, twist_from(rest, rest, pose0), zeros, zeros)


def _check_coincident(bodies: Bodies, pose0, sides, k: int, source: str, path: str, entry: dict) -> None:
    """Both sides' points of joint ``k`` coincide in the initial configuration (they may be given as
    sections ``x1``, ``x2`` of flexible bodies)."""
    cfg0 = _rest_configuration(bodies, pose0)
    p = [sd.subset([k]).positions(cfg0)[0] for _, sd in sides]
    scale = 1.0 + float(np.abs(pose0.W_r).max())
    if np.linalg.norm(p[0] - p[1]) > COINCIDENCE_RTOL * scale:
        raise SceneError(source, f"{path}.x2", f"a section at the joint point {p[0].round(9).tolist()} (side 2 is at "
                         f"{p[1].round(9).tolist()})", entry.get("x2"))


#: Joint type (scene ``type``) -> builder of its joint set from the resolved scene entries.
JOINT_BUILDERS = {"ball": _ball_joints,
                  **{kind: _framed_joints(kind) for kind in ("revolute", "universal", "prismatic", "cylindrical", "fixed")}}


def build_forces(scene: Scene, bodies: Bodies, pose0, joints: tuple = ()) -> tuple:
    """One force element per type present; ``joints``: the joint sets (for forces on joint coordinates)."""
    groups: dict[str, list[dict]] = {}
    paths: dict[str, list[str]] = {}
    for i, f in enumerate(scene.data["forces"]):
        groups.setdefault(f["type"], []).append(f)
        paths.setdefault(f["type"], []).append(f"forces[{i}]")
    out = []
    if "spring_damper" in groups:
        out.append(_springs(groups["spring_damper"], bodies, pose0))
    for kind, cls in (("force", AppliedForce), ("torque", AppliedTorque)):
        if kind in groups:
            out.append(_loads(cls, groups[kind], bodies, pose0))
    for kind in ("joint_stop", "joint_motor"):
        if kind in groups:
            out.append(_joint_forces(kind, groups[kind], paths[kind], joints, scene.source()))
    return tuple(out)


def _joint_coordinates(entries: list[dict], paths: list[str], joints: tuple, source: str) -> tuple:
    """``(joint sets, index in the set, coordinate index)`` of each entry's ``joint`` and ``coordinate``."""
    where = {n: (js, j) for js in joints if js.is_joint for j, n in enumerate(js.names)}
    sets, index, free = [], [], []
    for entry, path in zip(entries, paths):
        js, j = where.get(entry["joint"], (None, None))
        names = getattr(js, "coordinate_names", ())
        if not names:
            known = sorted(n for n, (s, _) in where.items() if getattr(s, "coordinate_names", ()))
            raise SceneError(source, f"{path}.joint", "the name of a joint with a relative coordinate "
                             f"({', '.join(known) or 'none in this scene'})", entry["joint"])
        c = entry.get("coordinate", names[0])
        if c not in names:
            raise SceneError(source, f"{path}.coordinate", f"one of {list(names)} (joint {entry['joint']!r})", c)
        sets.append(js)
        index.append(j)
        free.append(names.index(c))
    return tuple(sets), np.array(index, int), np.array(free, int)


def build_drives(scene: Scene, joints: tuple) -> tuple:
    """The scene's rigid drives (those without ``servo_gain``) as one ``JointDrive`` set (none
    without such ``[[drives]]``)."""
    entries, paths = _drive_entries(scene, limited=False)
    if not entries:
        return ()
    sets, index, free = _joint_coordinates(entries, paths, joints, scene.source())
    kind, table = _profiles(entries).table()
    body = np.array([js.body[j] for js, j in zip(sets, index)], int).reshape(-1, 2)
    return (JointDrive(tuple(f["name"] for f in entries), body, sets, index, free, kind,
                       np.array([f["mode"] == "velocity" for f in entries], np.int64), table),)


def build_servos(scene: Scene, joints: tuple) -> tuple:
    """The scene's limited drives (``servo_gain``) as one ``DriveServo`` element (none without)."""
    entries, paths = _drive_entries(scene, limited=True)
    if not entries:
        return ()
    source = scene.source()
    for entry, path in zip(entries, paths):
        if entry["mode"] != "velocity":
            raise SceneError(source, f"{path}.mode", "'velocity' for a limited drive (servo_gain: a velocity servo)",
                             entry["mode"])
        if "capacity" not in entry:
            raise SceneError(source, f"{path}.capacity", "a capacity for a limited drive (servo_gain: its force range)")
    sets, index, free = _joint_coordinates(entries, paths, joints, source)
    for js, entry, path in zip(sets, entries, paths):
        if js.on_flexible:
            raise SceneError(source, f"{path}.joint", "a joint between rigid bodies or ground for a limited drive (it "
                             "acts through the frames' axes)", entry["joint"])
    return (DriveServo(tuple(f["name"] for f in entries), sets, index, free, _profiles(entries),
                       np.array([f["servo_gain"] for f in entries], float),
                       np.array([f["capacity"] for f in entries], float)),)


def _drive_entries(scene: Scene, limited: bool) -> tuple[list[dict], list[str]]:
    """The ``[[drives]]`` entries that are limited (``servo_gain``) or rigid, and their paths; their
    profile kinds checked."""
    chosen = [(f, f"drives[{i}]") for i, f in enumerate(scene.data["drives"]) if ("servo_gain" in f) == limited]
    for entry, path in chosen:
        if entry["kind"] not in PROFILE_KINDS[entry["mode"]]:
            raise SceneError(scene.source(), f"{path}.kind", f"one of {list(PROFILE_KINDS[entry['mode']])} for a "
                             f"{entry['mode']} profile (its derivative must stay bounded)", entry["kind"])
    return [f for f, _ in chosen], [p for _, p in chosen]


def _profiles(entries: list[dict]) -> TimeFunctions:
    """The drives' profiles ``value + amplitude f(t)`` in the first component."""
    return TimeFunctions.from_entries([{**f, "offset": [f["value"], 0.0, 0.0], "amplitude": [f["amplitude"], 0.0, 0.0]}
                                       for f in entries])


def _joint_forces(kind: str, entries: list[dict], paths: list[str], joints: tuple, source: str):
    sets, index, free = _joint_coordinates(entries, paths, joints, source)
    for js, entry, path in zip(sets, entries, paths):
        if js.on_flexible:
            raise SceneError(source, f"{path}.joint", f"a joint between rigid bodies or ground (a {kind} acts through "
                             "the frames' axes; drives take joints on flexible sections)", entry["joint"])
    names = tuple(f["name"] for f in entries)
    if kind == "joint_stop":
        lower = np.array([f.get("lower", -np.inf) for f in entries], float)
        upper = np.array([f.get("upper", np.inf) for f in entries], float)
        for path, lo, hi in zip(paths, lower, upper):
            if lo > hi:
                raise SceneError(source, f"{path}.upper", f"at least lower = {lo:g}", hi)
        return JointStop(names, sets, index, free, lower, upper, np.array([f["stiffness"] for f in entries], float),
                         np.array([f["damping"] for f in entries], float))
    target = TimeFunctions.from_entries([{**f, "offset": [f["value"], 0.0, 0.0], "amplitude": [f["amplitude"], 0.0, 0.0]}
                                         for f in entries])
    return JointMotor(names, sets, index, free, target, np.array([f["kp"] for f in entries], float),
                      np.array([f["kd"] for f in entries], float),
                      np.array([f.get("max_effort", np.inf) for f in entries], float))


def _springs(entries: list[dict], bodies: Bodies, pose0) -> SpringDamper:
    body = np.array([[bodies.index(f["body1"]), bodies.index(f["body2"])] for f in entries], dtype=int)
    s1, p1 = _points(bodies, pose0, body[:, 0], entries, "1", "point1", "local1")
    s2, p2 = _points(bodies, pose0, body[:, 1], entries, "2", "point2", "local2")
    B_s = np.stack([s1, s2], axis=1)
    cfg0 = _rest_configuration(bodies, pose0)
    ends = np.stack([p1.positions(cfg0), p2.positions(cfg0)], axis=1)
    length0 = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    rest = np.array([f.get("rest_length", length0[k]) for k, f in enumerate(entries)])
    return SpringDamper(tuple(f["name"] for f in entries), body, B_s,
                        np.array([f["stiffness"] for f in entries]), np.array([f["damping"] for f in entries]), rest, (p1, p2))


def _loads(cls, entries: list[dict], bodies: Bodies, pose0):
    body = np.array([bodies.index(f["body"]) for f in entries], dtype=int)
    B_s, points = _points(bodies, pose0, body, [{**f, "x1": f["x"]} if "x" in f else f for f in entries], "1",
                          "point", "local")
    funcs = TimeFunctions.from_entries([{**f, "offset": f["value"]} for f in entries])
    in_body = np.array([f["frame"] == "body" for f in entries])
    return cls(tuple(f["name"] for f in entries), body, B_s, in_body, funcs, points)


def build_contacts(scene: Scene, bodies: Bodies, pose0) -> tuple[ContactSet, ...]:
    """The scene's contacts: one set of the located ones, one of those stepped through."""
    src, entries = scene.source(), scene.data["contacts"]
    sets = []
    for located in (True, False):
        chosen = [(i, c) for i, c in enumerate(entries) if c["events"] == located]
        if chosen:
            sets.append(_contact_set(src, [c for _, c in chosen], [i for i, _ in chosen], bodies, pose0, scene))
    return tuple(sets)


def _contact_set(src: str, entries: list[dict], index: list[int], bodies: Bodies, pose0, scene: Scene) -> ContactSet:
    body = np.array([[bodies.index(c["body1"]), bodies.index(c["body2"])] for c in entries], dtype=int)
    _, pa = _points(bodies, pose0, body[:, 0], entries, "1", "point1", "local1")
    _, pb = _points(bodies, pose0, body[:, 1], entries, "2", "point2", "local2")
    normal = np.array([c["normal"] for c in entries], float)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.einsum("kji,kj->ki", pose0.R_WB[body[:, 1]], normal)  # world -> body 2 axes at t = 0
    models, laws = [], []
    for k, (c, i) in enumerate(zip(entries, index)):
        model, law, _ = contact_law(c, contact_materials(c, scene.data["bodies"]), src, f"contacts[{i}]",
                                    _reduced_mass(bodies, body[k]))
        if not c["events"] and (model != "law" or not law.memoryless):
            raise SceneError(src, f"contacts[{i}].events", f"true for the {c['law']} law as given (it needs contact "
                             "memory; without events only laws without one act: linear, hertz, and the rate laws with "
                             "a fixed damping_factor)")
        models.append(model)
        laws.append(law)
    # the linear law carries its own dashpot; any other law gets it added (never pulling)
    dashpot = np.array([0.0 if (law is not None and law.name == "linear") else c["damping"] for c, law in zip(entries, laws)])
    friction = tuple(friction_law(src, c, f"contacts[{i}]", model,
                                  any(b < bodies.n_bodies and not bodies.is_rigid[b] for b in body[k]))
                     for k, (c, i, model) in enumerate(zip(entries, index, models)))
    return ContactSet(tuple(c["name"] for c in entries), body, (pa, pb), normal,
                      np.array([c["radius"] for c in entries], float), tuple(models), tuple(laws),
                      np.array([c.get("restitution", 1.0) for c in entries], float),
                      tuple(c["hypothesis"] for c in entries), dashpot, entries[0]["events"], friction)


def _reduced_mass(bodies: Bodies, pair) -> float | None:
    """``m1 m2 / (m1 + m2)`` of two rigid bodies (ground: infinite) [kg]; None with a flexible one."""
    inverse = 0.0
    for b in pair:
        if b < bodies.n_bodies:
            if not bodies.is_rigid[b]:
                return None
            inverse += 1.0 / bodies.mass[b]
    return 1.0 / inverse if inverse > 0.0 else None


def build_gauges(scene: Scene, bodies: Bodies) -> tuple:
    """Gauges on flexible bodies, one output element per body and quantity (``viz3d.outputs.GAUGES``)."""
    src, entries = scene.source(), scene.data["gauges"]
    groups: dict[tuple[int, str], list] = {}
    for i, g in enumerate(entries):
        flex = [k for k, fb in enumerate(bodies.flexible) if "body" not in g or bodies.names[fb.index] == g["body"]]
        if len(flex) != 1:
            raise SceneError(src, f"gauges[{i}].body", "the name of a flexible body (required when there are several)",
                             g.get("body"))
        fb = bodies.flexible[flex[0]]
        if g["x"] > fb.bar.length:
            raise SceneError(src, f"gauges[{i}].x", f"a section in [0, {fb.bar.length}] m", g["x"])
        if g["quantity"] == "deflection" and not any(m.kind == "bending" for m in fb.bar.fields):
            raise SceneError(src, f"gauges[{i}].quantity", "strain on a bar without bending (a rod has no deflection)",
                             g["quantity"])
        groups.setdefault((flex[0], g["quantity"]), []).append(g)
    return tuple(GAUGES[quantity](tuple(g["name"] for g in gs), k, np.array([g["x"] for g in gs], float),
                                  bodies.flexible[k].bar)
                 for (k, quantity), gs in groups.items())


def build_stowage_outputs(scene: Scene, bodies: Bodies, joints: tuple, W_r0: FloatArray) -> tuple:
    """The chain's tension at the hawse of a ``[stowage]`` table (``viz3d.stowage.hawse_output``), if
    it names one; ``joints``: the scene's joint sets (their names in ``System.joint_names`` order)."""
    from viz3d.stowage import hawse_output

    if "stowage" not in scene.data:
        return ()
    names = [n for js in joints if js.is_joint for n in js.names]
    out = hawse_output(scene.data["stowage"], bodies.names, names, W_r0)
    return (out,) if out is not None else ()


# ---------------------------------------------------------------- initial conditions


def consistent_state(system: System, state: State, source: str, tol: float, formulation=None) -> State:
    """Project ``state`` onto ``C = 0`` (to ``max |C| <= tol`` [m]) and ``C_v v + C_t = 0`` (drives included,
    at ``state.t``); warn with the size of the corrections. With the run's ``formulation`` (None: a run on
    the NumPy path, ``sim.compiled = false``) the projection is the compiled kernel's when the kernel covers
    the system, as the run's steps will be, and the system is rigid (``kernel_projection``); else, or when
    that fails, NumPy's, which raises the diagnosis."""
    if system.n_c == 0:
        return state
    projected = None if formulation is None else kernel_projection(system, state, tol, formulation)
    try:
        if projected is None:
            q, _ = project_positions(system, state.q, state.chart, tol=tol, memory=state.memory, t=state.t)
            v = project_velocities(system, q, state.v, state.chart, state.memory, t=state.t)
        else:
            q, v = projected.q, projected.v
    except SingularConstraintError:
        names = redundant_joints(system, *constraint_jacobian(system.joints, _configuration(system, state)))
        who = f"joints {', '.join(map(repr, names))} are redundant or degenerate" if names else "the joints lose rank"
        raise SceneError(source, "joints", f"independent joints ({who})") from None
    except np.linalg.LinAlgError as exc:  # a body's mass block (e.g. a bar with absurd dimensions)
        raise SceneError(source, "bodies", f"bodies whose mass matrices are positive definite (here: {exc})") from None
    except ProjectionError as exc:
        raise SceneError(source, "joints", f"joints that can all be satisfied at once ({exc})") from None
    dq = _max_position_change(system, state.q, q)
    dv = float(np.max(np.abs(v - state.v)))
    if dq > REPORT_CORRECTION or dv > REPORT_CORRECTION:
        C0 = constraint_rows(system.joints, _configuration(system, state), state.memory).C
        warnings.warn(InitialConditionsWarning(
            f"{source}: initial conditions projected onto the joints: positions moved by up to {dq:.3g} m "
            f"(initial max |C| = {np.max(np.abs(C0)):.3g}: m, or the sine of an angle for axis rows and angle drives), "
            f"velocities changed by up to {dv:.3g} m/s or rad/s"),
            stacklevel=2)
    return state.replace(q=q, v=v)


def kernel_projection(system: System, state: State, tol: float, formulation) -> State | None:
    """``state`` projected as ``project_positions`` (to ``max |C| <= tol`` [m], at most ``MAX_ITER``
    corrections) then ``project_velocities`` do, in the compiled kernel (``viz3d.kernel.projection``: the
    same Newton corrections and velocity step, its own banded Cholesky solves, no LAPACK), when the kernel
    covers ``system`` with ``formulation``; None when it does not, when the projection fails, and for
    systems with flexible bodies (not yet compared with NumPy's from their initial states: the kernel's
    correction on floating bars lacked their rotation-elastic coupling until it computed the bars' shape
    moments itself, ``tests/numerics/test_kernel_projection.py``)."""
    from viz3d.kernel import KernelStepper, kernel_for

    data = None if system.bodies.flexible else kernel_for(system, formulation)
    if data is None:
        return None
    model = data.model._replace(projection_tol=float(tol), projection_iter=MAX_ITER)
    y, ok = KernelStepper(replace(data, model=model), None).project(state.t, state.y, state.chart, state.memory)
    if not ok:
        return None
    q, v, _ = system.split_y(y)
    return state.replace(q=q, v=v)


def _configuration(system, state):
    return body_state(system, state.q, state.v, state.chart, state.t)


def _max_position_change(system, q0, q1) -> float:
    return float(np.max(np.abs(system.split_q(q1)[0] - system.split_q(q0)[0])))

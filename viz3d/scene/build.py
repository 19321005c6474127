"""``Scene`` -> frozen ``System`` and a consistent initial ``State``.

Mass properties come from the scene (given, or shape x density); joint and spring points given
in world coordinates are converted to body coordinates at the initial pose; then the initial
positions and velocities are projected onto the constraints, with a warning stating the size of
the correction.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.bodies import Bodies, InertiaError
from viz3d.constraints import SingularConstraintError, build_layout, constraint_jacobian, constraint_residual
from viz3d.contact.element import SpherePlane
from viz3d.coordinates import ROTATIONS
from viz3d.diagnosis import redundant_joints
from viz3d.dynamics import body_state
from viz3d.forces import AppliedForce, AppliedTorque, Gravity, SpringDamper
from viz3d.formulation import ALI3P, Baumgarte, Index1, Penalty, Projection
from viz3d.geometry import MeshError, load_mesh, mesh_properties, primitive_properties
from viz3d.integrators import GeneralizedAlpha, Integrator, make_integrator
from viz3d.integrators.adaptive import Controller
from viz3d.joints import BallJoint
from viz3d.kinematics import pose_from
from viz3d.rotations import matrix_from_euler
from viz3d.scene.load import Scene
from viz3d.scene.schema import SceneError
from viz3d.stabilization import ProjectionError, project_positions, project_velocities
from viz3d.system import State, System
from viz3d.timefunctions import TimeFunctions

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
    src = scene.source()
    props = [body_mass_properties(scene, i) for i in range(len(scene.data["bodies"]))]
    names = tuple(b["name"] for b in scene.data["bodies"])
    try:
        bodies = Bodies(names, np.array([p.mass for p in props]), np.array([p.inertia for p in props]))
    except InertiaError as exc:
        raise SceneError(src, "bodies", f"physical mass properties ({exc})") from None
    sim = scene.data["sim"]
    rotation = ROTATIONS[sim["rotation"]]()
    W_r0, R0 = initial_pose(scene)
    pose0 = pose_from(W_r0, R0)
    joints = build_joints(scene, bodies, pose0)
    forces = (Gravity(bodies.mass, np.asarray(sim["gravity"], float)),) + build_forces(scene, bodies, pose0)
    system = System(bodies, build_layout(joints, bodies), forces, rotation)
    theta, chart = rotation.from_matrix(R0)
    q = system.join_q(W_r0, theta)
    v = initial_velocities(scene, R0)
    return system, consistent_state(system, State(0.0, q, v, chart), src, sim["projection_tol"])


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
    density = b["density"] if "density" in b else b["mass"] / unit.volume
    return MassProperties(density * unit.volume, density * unit.inertia, unit.center)


def shape_unit_properties(scene: Scene, shape: dict, where: str):
    if shape["type"] != "mesh":
        return primitive_properties(shape)
    try:
        return mesh_properties(load_mesh(scene.base_dir / shape["file"], shape["scale"]))
    except MeshError as exc:
        raise SceneError(scene.source(), f"{where}.file", f"a watertight, outward-oriented mesh file ({exc})") from None


def initial_pose(scene: Scene) -> tuple[FloatArray, FloatArray]:
    """Initial centres of mass (nb, 3) and rotations (nb, 3, 3)."""
    W_r, R = [], []
    for b in scene.data["bodies"]:
        angles = np.radians(b["euler_deg"]) if "euler_deg" in b else np.asarray(b.get("euler", [0.0, 0.0, 0.0]))
        W_r.append(b["position"])
        R.append(matrix_from_euler(angles))
    return np.asarray(W_r, float), np.asarray(R)


def initial_velocities(scene: Scene, R0: FloatArray) -> FloatArray:
    """``v`` (n_v,) from the scene's world velocities and world angular velocities."""
    W_v = np.array([b["velocity"] for b in scene.data["bodies"]], float)
    W_omega = np.array([b["omega"] for b in scene.data["bodies"]], float)
    B_omega = np.einsum("bji,bj->bi", R0, W_omega)
    return np.concatenate([W_v, B_omega], axis=1).reshape(-1)


# ---------------------------------------------------------------- joints and forces


def _local_point(pose, body: int, entry: dict, point_key: str, local_key: str) -> FloatArray:
    """Body-frame point from a world point at the initial pose, or the given local point."""
    if local_key in entry:
        return np.asarray(entry[local_key], float)
    return pose.R_WB[body].T @ (np.asarray(entry[point_key], float) - pose.W_r[body])


def build_joints(scene: Scene, bodies: Bodies, pose0) -> tuple:
    """One joint set per joint type present, in the order of ``JOINT_BUILDERS``."""
    groups: dict[str, list[dict]] = {}
    for j in scene.data["joints"]:
        groups.setdefault(j["type"], []).append(j)
    return tuple(make(groups[kind], bodies, pose0) for kind, make in JOINT_BUILDERS.items() if kind in groups)


def _ball_joints(entries: list[dict], bodies: Bodies, pose0) -> BallJoint:
    body = np.array([[bodies.index(j["body1"]), bodies.index(j["body2"])] for j in entries], dtype=int)
    B_s = np.array([[_local_point(pose0, body[k, 0], j, "point", "local1"),
                     _local_point(pose0, body[k, 1], j, "point", "local2")] for k, j in enumerate(entries)])
    return BallJoint(tuple(j["name"] for j in entries), body, B_s)


#: Joint type (scene ``type``) -> builder of its joint set from the resolved scene entries.
JOINT_BUILDERS = {"ball": _ball_joints}


def build_forces(scene: Scene, bodies: Bodies, pose0) -> tuple:
    groups: dict[str, list[dict]] = {}
    for f in scene.data["forces"]:
        groups.setdefault(f["type"], []).append(f)
    out = []
    if "spring_damper" in groups:
        out.append(_springs(groups["spring_damper"], bodies, pose0))
    for kind, cls in (("force", AppliedForce), ("torque", AppliedTorque)):
        if kind in groups:
            out.append(_loads(cls, groups[kind], bodies, pose0))
    if "contact" in groups:
        out.append(_contacts(groups["contact"], bodies, pose0))
    return tuple(out)


def _contacts(entries: list[dict], bodies: Bodies, pose0) -> SpherePlane:
    from viz3d.contact.laws import Hertz, Linear

    body = np.array([bodies.index(f["body"]) for f in entries], dtype=int)
    B_c = np.array([_local_point(pose0, body[k], f, "point", "local") if ("point" in f or "local" in f)
                    else np.zeros(3) for k, f in enumerate(entries)]).reshape(-1, 3)
    normal = np.array([f["plane_normal"] for f in entries], float)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    laws = tuple(Hertz(f["stiffness"], f["exponent"]) if f["law"] == "hertz" else Linear(f["stiffness"], 0.0)
                 for f in entries)
    return SpherePlane(tuple(f["name"] for f in entries), body, B_c, np.array([f["radius"] for f in entries]),
                       np.array([f["plane_point"] for f in entries], float), normal, laws,
                       np.array([f["damping"] for f in entries]))


def _springs(entries: list[dict], bodies: Bodies, pose0) -> SpringDamper:
    body = np.array([[bodies.index(f["body1"]), bodies.index(f["body2"])] for f in entries], dtype=int)
    B_s = np.array([[_local_point(pose0, body[k, 0], f, "point1", "local1"),
                     _local_point(pose0, body[k, 1], f, "point2", "local2")] for k, f in enumerate(entries)])
    ends = pose0.W_r[body] + np.einsum("ksab,ksb->ksa", pose0.R_WB[body], B_s)
    length0 = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    rest = np.array([f.get("rest_length", length0[k]) for k, f in enumerate(entries)])
    return SpringDamper(tuple(f["name"] for f in entries), body, B_s,
                        np.array([f["stiffness"] for f in entries]), np.array([f["damping"] for f in entries]), rest)


def _loads(cls, entries: list[dict], bodies: Bodies, pose0):
    body = np.array([bodies.index(f["body"]) for f in entries], dtype=int)
    B_s = np.array([_local_point(pose0, body[k], f, "point", "local") if ("point" in f or "local" in f)
                    else np.zeros(3) for k, f in enumerate(entries)]).reshape(-1, 3)
    funcs = TimeFunctions.from_entries([{**f, "offset": f["value"]} for f in entries])
    in_body = np.array([f["frame"] == "body" for f in entries])
    return cls(tuple(f["name"] for f in entries), body, B_s, in_body, funcs)


# ---------------------------------------------------------------- initial conditions


def consistent_state(system: System, state: State, source: str, tol: float) -> State:
    """Project ``state`` onto ``C = 0`` and ``C_v v = 0``; warn with the size of the corrections."""
    if system.n_c == 0:
        return state
    try:
        q, _ = project_positions(system, state.q, state.chart, tol=tol)
        v = project_velocities(system, q, state.v, state.chart)
    except SingularConstraintError:
        names = redundant_joints(system, *constraint_jacobian(system.joints, _configuration(system, state)))
        who = f"joints {', '.join(map(repr, names))} are redundant or degenerate" if names else "the joints lose rank"
        raise SceneError(source, "joints", f"independent joints ({who})") from None
    except ProjectionError as exc:
        raise SceneError(source, "joints", f"joints that can all be satisfied at once ({exc})") from None
    dq = _max_position_change(system, state.q, q)
    dv = float(np.max(np.abs(v - state.v)))
    if dq > REPORT_CORRECTION or dv > REPORT_CORRECTION:
        C0 = constraint_residual(system.joints, _configuration(system, state))
        warnings.warn(InitialConditionsWarning(
            f"{source}: initial conditions projected onto the joints: positions moved by up to {dq:.3g} m "
            f"(initial max |C| = {np.max(np.abs(C0)):.3g} m), velocities changed by up to {dv:.3g} m/s or rad/s"),
            stacklevel=2)
    return state.replace(q=q, v=v)


def _configuration(system, state):
    return body_state(system, state.q, state.v, state.chart, state.t)


def _max_position_change(system, q0, q1) -> float:
    return float(np.max(np.abs(system.split_q(q1)[0] - system.split_q(q0)[0])))

"""viz3d's rigid-body models in peer simulators (benchmarks only; bench_mujoco.py, bench_peers.py).

A ``RigidTree`` is read from a viz3d scene and the first frame of one of its runs: the bodies'
masses and inertias, their initial poses and velocities, and the ball joints that connect them
(a body without a joint floats free). ``mujoco_run``, ``exudyn_run`` and ``pinocchio_run`` build the
same tree in MuJoCo, Exudyn and Pinocchio, run it at a fixed step and return the bodies' ``markers``
on a grid of output frames (recorded during the run, as viz3d's are). Each peer is optional: its import raises
ImportError when it is not installed (``pip install -e '.[peers]'``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from viz3d.rotations import quat_from_matrix

#: A body's parent when it hangs on a joint to the ground, and when it has no joint.
GROUND, FREE = -1, -2
#: Marker points of every body, body axes [m]: its centre of mass and a point 0.1 m along each axis
#: (a torque-free body's centre does not move; its markers do).
MARKERS = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1]])


#: Exudyn solves with its sparse LU above this many bodies (measured: its default dense solver is
#: 20 % faster at 1-2 bodies, 10 % slower at 5, 1.6x at 10 and 25x at 50).
SPARSE_ABOVE = 4


def markers(r: np.ndarray, R: np.ndarray) -> np.ndarray:
    """World positions of the ``MARKERS`` of bodies at ``r`` (..., 3) [m], turned by ``R`` (..., 3, 3):
    shape (..., 4, 3) [m]."""
    return r[..., None, :] + np.einsum("...ij,mj->...mi", R, MARKERS)


@dataclass(frozen=True)
class RigidTree:
    """Rigid bodies on ball joints (a tree), at t = 0; nb bodies, world axes, SI units.

    mass (nb,) [kg]; inertia (nb, 3, 3) about the centre of mass, body axes [kg m^2];
    r (nb, 3) centres of mass [m]; R (nb, 3, 3) world-from-body rotations; v (nb, 3) [m/s] and
    w (nb, 3) [rad/s] velocities and angular velocities; parent (nb,) the body each body's joint
    connects it to (``GROUND``, ``FREE``, or an index lower than its own); point (nb, 3) that
    joint's centre [m]; gravity (3,) [m/s^2].
    """

    mass: np.ndarray
    inertia: np.ndarray
    r: np.ndarray
    R: np.ndarray
    v: np.ndarray
    w: np.ndarray
    parent: np.ndarray
    point: np.ndarray
    gravity: np.ndarray


def rigid_tree(scene, traj) -> RigidTree:
    """The tree of ``scene`` (ball joints only) in the state of ``traj``'s first frame."""
    names = [str(n) for n in traj.body_names]
    r, R = traj.position[0], traj.rotation[0]
    parent, point = np.full(len(names), FREE), np.zeros((len(names), 3))
    for j in scene.data["joints"]:
        if j.get("type", "ball") != "ball":
            raise ValueError(f"joint {j['name']!r}: only ball joints have a peer model here")
        child = names.index(j["body1"])
        other = j.get("body2", "ground")
        parent[child] = GROUND if other == "ground" else names.index(other)
        point[child] = j["point"] if "point" in j else r[child] + R[child] @ np.asarray(j["local1"], float)
    if np.any(parent >= np.arange(len(names))):
        raise ValueError("a joint's second body must come before its first in the scene")
    return RigidTree(traj.mass.copy(), traj.inertia_body.copy(), r.copy(), R.copy(), traj.velocity[0].copy(),
                     traj.omega[0].copy(), parent, point, np.asarray(scene.data["sim"]["gravity"], float))


@dataclass(frozen=True)
class PeerRun:
    """One run of a peer: the bodies' ``markers`` at the output frames (n, nb, 4, 3) [m], the wall time
    of the run with its frames [s] and the number of steps."""

    position: np.ndarray
    wall: float
    steps: int


def _steps_per_frame(dt: float, output_dt: float) -> int:
    k = round(output_dt / dt)
    if k < 1 or abs(k * dt - output_dt) > 1e-9 * output_dt:
        raise ValueError(f"the step {dt:g} s must divide the output interval {output_dt:g} s")
    return k


# ---------------------------------------------------------------------------- MuJoCo


def mujoco_xml(tree: RigidTree, dt: float, integrator: str = "RK4") -> str:
    """MJCF of ``tree``: nested bodies in their t = 0 poses (the reference configuration), each on a
    ball joint at its joint's centre or on a free joint; explicit inertials, no geoms, no contacts."""
    def body(i: int, r_p: np.ndarray, R_p: np.ndarray) -> str:
        pos = R_p.T @ (tree.r[i] - r_p)
        quat = quat_from_matrix(R_p.T @ tree.R[i])  # (w, x, y, z), as MuJoCo's
        if tree.parent[i] == FREE:
            joint = '<freejoint/>'
        else:
            joint = f'<joint type="ball" pos="{_v(tree.R[i].T @ (tree.point[i] - tree.r[i]))}" damping="0"/>'
        I = tree.inertia[i]
        inertial = (f'<inertial pos="0 0 0" mass="{float(tree.mass[i])!r}" '
                    f'fullinertia="{_v([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])}"/>')
        kids = "".join(body(k, tree.r[i], tree.R[i]) for k in np.flatnonzero(tree.parent == i))
        return f'<body name="b{i}" pos="{_v(pos)}" quat="{_v(quat)}">{joint}{inertial}{kids}</body>'

    roots = np.flatnonzero(tree.parent < 0)
    world = "".join(body(i, np.zeros(3), np.eye(3)) for i in roots)
    return (f'<mujoco><option integrator="{integrator}" timestep="{dt!r}" gravity="{_v(tree.gravity)}"/>'
            f"<worldbody>{world}</worldbody></mujoco>")


def mujoco_model(tree: RigidTree, dt: float, integrator: str = "RK4"):
    """``(mujoco, model, data)`` of ``tree`` in its initial state (``mujoco_reset``)."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(mujoco_xml(tree, dt, integrator))
    data = mujoco.MjData(model)
    mujoco_reset(tree, model, data)
    return mujoco, model, data


def mujoco_reset(tree: RigidTree, model, data) -> None:
    """Initial state: reference configuration; ball joints turn at the relative angular velocity
    in the child's axes, free joints move at the world velocity and turn at the body-axes rate."""
    import mujoco

    mujoco.mj_resetData(model, data)
    for j in range(model.njnt):
        i, a = int(model.body(model.jnt_bodyid[j]).name[1:]), model.jnt_dofadr[j]
        w_p = tree.w[tree.parent[i]] if tree.parent[i] >= 0 else np.zeros(3)
        if tree.parent[i] == FREE:
            data.qvel[a:a + 6] = np.concatenate([tree.v[i], tree.R[i].T @ tree.w[i]])
        else:
            data.qvel[a:a + 3] = tree.R[i].T @ (tree.w[i] - w_p)
    mujoco.mj_forward(model, data)


def mujoco_run(tree: RigidTree, dt: float, t_end: float, output_dt: float) -> PeerRun:
    """Run ``tree`` in MuJoCo (RK4, step ``dt``) to ``t_end``, recording the centres of mass every
    ``output_dt`` [s]; the model is built before the clock starts."""
    mujoco, model, data = mujoco_model(tree, dt)
    k, n = _steps_per_frame(dt, output_dt), round(t_end / output_dt)
    ids = np.array([model.body(f"b{i}").id for i in range(len(tree.mass))])
    r, R = np.empty((n + 1, len(ids), 3)), np.empty((n + 1, len(ids), 9))
    t0 = time.perf_counter()
    r[0], R[0] = data.xpos[ids], data.xmat[ids]
    for f in range(1, n + 1):
        mujoco.mj_step(model, data, nstep=k)
        mujoco.mj_kinematics(model, data)  # the poses of the state reached, as viz3d's frames give
        r[f], R[f] = data.xpos[ids], data.xmat[ids]
    return PeerRun(markers(r, R.reshape(n + 1, len(ids), 3, 3)), time.perf_counter() - t0, n * k)


# ---------------------------------------------------------------------------- Exudyn


def exudyn_run(tree: RigidTree, dt: float, t_end: float, output_dt: float, solver: str | None = None) -> PeerRun:
    """Run ``tree`` in Exudyn to ``t_end`` at step ``dt``, its bodies' centres recorded every
    ``output_dt`` by sensors at the ``MARKERS``. ``solver``: Exudyn's ``DynamicSolverType`` name; default RK44 for a
    tree without joints (explicit solvers take no constraints), else GeneralizedAlpha with Exudyn's
    defaults (index 3, spectral radius 0.9; at 1, no damping, its Newton iteration stalls at a
    relative residual of 1e-8 on the heavy top and the run stops)."""
    import exudyn as exu
    from exudyn.rigidBodyUtilities import RigidBodyInertia

    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    ground = mbs.CreateGround()
    explicit = bool(np.all(tree.parent == FREE))
    solver = solver or exudyn_solver(tree)
    node = exu.NodeType.RotationRotationVector if explicit else exu.NodeType.RotationEulerParameters
    bodies, sensors = [], []
    for i in range(len(tree.mass)):
        bodies.append(mbs.CreateRigidBody(
            inertia=RigidBodyInertia(float(tree.mass[i]), tree.inertia[i]), referencePosition=tree.r[i].tolist(),
            referenceRotationMatrix=tree.R[i], initialVelocity=tree.v[i].tolist(),
            initialAngularVelocity=tree.w[i].tolist(), gravity=tree.gravity.tolist(),
            nodeType=node))
        if tree.parent[i] != FREE:
            other = ground if tree.parent[i] == GROUND else bodies[tree.parent[i]]
            mbs.CreateSphericalJoint(bodyNumbers=[other, bodies[i]], position=tree.point[i].tolist())
        sensors += [mbs.AddSensor(exu.itemInterface.SensorBody(
            bodyNumber=bodies[i], localPosition=m.tolist(), storeInternal=True,
            outputVariableType=exu.OutputVariableType.Position)) for m in MARKERS]
    mbs.Assemble()
    steps = round(t_end / dt)
    _steps_per_frame(dt, output_dt)
    settings = _exudyn_settings(exu, steps, t_end, output_dt)
    if len(tree.mass) > SPARSE_ABOVE:
        settings.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    t0 = time.perf_counter()
    mbs.SolveDynamic(settings, solverType=getattr(exu.DynamicSolverType, solver))
    wall = time.perf_counter() - t0
    pos = np.stack([mbs.GetSensorStoredData(s)[:, 1:4] for s in sensors], axis=1)
    n = round(t_end / output_dt) + 1
    return PeerRun(pos[:n].reshape(n, len(tree.mass), len(MARKERS), 3), wall, steps)


def exudyn_solver(tree: RigidTree) -> str:
    """``exudyn_run``'s default solver for ``tree``: RK44 without joints (explicit solvers take no
    constraints), else GeneralizedAlpha."""
    return "RK44" if bool(np.all(tree.parent == FREE)) else "GeneralizedAlpha"


def _exudyn_settings(exu, steps: int, t_end: float, output_dt: float):
    s = exu.SimulationSettings()
    s.timeIntegration.numberOfSteps = steps
    s.timeIntegration.endTime = t_end
    s.timeIntegration.verboseMode = 0
    s.solutionSettings.writeSolutionToFile = False
    s.solutionSettings.sensorsWritePeriod = output_dt
    s.displayComputationTime = False
    s.displayStatistics = False
    return s


# ---------------------------------------------------------------------------- Pinocchio


def pinocchio_model(tree: RigidTree):
    """``(pinocchio, model, q0, v0, lever)`` of ``tree``: a spherical joint (or a free flyer) per body,
    each joint frame at its joint's centre turned as the body starts (so q0 is the identity rotation),
    the body's inertia about its centre at ``lever`` (nb, 3) in joint axes [m]."""
    import pinocchio as pin

    model = pin.Model()
    model.gravity = pin.Motion(np.asarray(tree.gravity, float), np.zeros(3))
    nb = len(tree.mass)
    origin = np.where((tree.parent == FREE)[:, None], tree.r, tree.point)  # each joint frame's origin
    lever, joint = np.zeros((nb, 3)), np.zeros(nb, int)
    q0, v0 = [], []
    for i in range(nb):
        p = int(tree.parent[i])
        R_p, o_p = (tree.R[p], origin[p]) if p >= 0 else (np.eye(3), np.zeros(3))
        placement = pin.SE3(R_p.T @ tree.R[i], R_p.T @ (origin[i] - o_p))
        w_rel = tree.R[i].T @ (tree.w[i] - (tree.w[p] if p >= 0 else 0.0))
        if p == FREE:
            jm = pin.JointModelFreeFlyer()
            q0 += [np.zeros(3), [0.0, 0.0, 0.0, 1.0]]
            v0 += [tree.R[i].T @ tree.v[i], tree.R[i].T @ tree.w[i]]
        else:
            jm = pin.JointModelSpherical()
            q0 += [[0.0, 0.0, 0.0, 1.0]]
            v0 += [w_rel]
        joint[i] = model.addJoint(int(joint[p]) if p >= 0 else 0, jm, placement, f"j{i}")
        lever[i] = tree.R[i].T @ (tree.r[i] - origin[i])
        model.appendBodyToJoint(int(joint[i]), pin.Inertia(float(tree.mass[i]), lever[i], tree.inertia[i]),
                                pin.SE3.Identity())
    return pin, model, np.concatenate(q0), np.concatenate(v0), lever, joint


#: Pinocchio's forward dynamics used by ``pinocchio_run``: the articulated-body algorithm ``aba``, or
#: ``crba``: the mass matrix (``crba``), ``nonLinearEffects`` and Pinocchio's sparse Cholesky solve.
PINOCCHIO_DYNAMICS = ("aba", "crba")


def pinocchio_run(tree: RigidTree, dt: float, t_end: float, output_dt: float, dynamics: str = "aba") -> PeerRun:
    """Run ``tree`` with Pinocchio's forward ``dynamics`` (``PINOCCHIO_DYNAMICS``) and classic RK4
    written here (Pinocchio has no time integrator: this is how a user steps it), quaternions
    advanced by ``q_dot = q (x) (omega/2, 0)`` as plain ODE coordinates and normalised after each
    step (and, for the dynamics, at each stage: ``crba`` reads a quaternion that is not a unit one
    otherwise than ``aba`` does, 10x the error on a 2-link chain at a 5 ms step); poses read by
    ``forwardKinematics`` every ``output_dt``. The model is built before the clock starts.

    On ball-joint chains of 50 links and more ``aba`` is not usable: its accelerations let each
    link's spin about its own axis (zero in the exact motion: the joint forces act on the axis) grow
    from round-off, exponentially (the top link's, about 45/s on 50 links: 1e-15 rad/s at 0.1 s,
    7e-7 at 0.6 s, 7e-3 at 0.8 s), whatever the step and whether the rotations are integrated as
    here or by ``pin.integrate``; non-finite at 100 and 200 links. ``computeMinverse`` (the same
    recursion) is non-finite from 50 links. ``crba`` on the same model agrees with MuJoCo to 4e-10 m
    (50 links) and 2e-10 m (100 links, before the stages' normalisation) over the first second at a
    1 ms step, where ``aba`` departs by 4e-4 m."""
    if dynamics not in PINOCCHIO_DYNAMICS:
        raise ValueError(f"dynamics must be one of {PINOCCHIO_DYNAMICS}, not {dynamics!r}")
    pin, model, q, v, lever, joint = pinocchio_model(tree)
    data = model.createData()
    free = tree.parent == FREE
    # index arrays of each joint's quaternion (x, y, z, w) and angular-velocity entries, and free flyers' positions
    qi = np.array([model.joints[int(j)].idx_q + (3 if f else 0) for j, f in zip(joint, free)])
    vi = np.array([model.joints[int(j)].idx_v + (3 if f else 0) for j, f in zip(joint, free)])
    quat = qi[:, None] + np.arange(4)
    omega = vi[:, None] + np.arange(3)
    pos = np.array([model.joints[int(j)].idx_q for j in joint[free]], int)[:, None] + np.arange(3)
    lin = np.array([model.joints[int(j)].idx_v for j in joint[free]], int)[:, None] + np.arange(3)
    tau = np.zeros(model.nv)

    def q_dot(q, v):
        x, y, z, w = (q[quat[:, k]] for k in range(4))
        wx, wy, wz = (v[omega[:, k]] for k in range(3))
        out = np.zeros_like(q)
        out[quat[:, 0]] = 0.5 * (w * wx + y * wz - z * wy)
        out[quat[:, 1]] = 0.5 * (w * wy + z * wx - x * wz)
        out[quat[:, 2]] = 0.5 * (w * wz + x * wy - y * wx)
        out[quat[:, 3]] = -0.5 * (x * wx + y * wy + z * wz)
        if pos.size:
            if dynamics != "aba":  # aba has just computed the joints' placements at q
                pin.forwardKinematics(model, data, q)
            for n, j in enumerate(joint[free]):
                out[pos[n]] = data.oMi[int(j)].rotation @ v[lin[n]]
        return out

    def acceleration(q, v):
        if dynamics == "aba":
            return pin.aba(model, data, q, v, tau).copy()
        b = tau - pin.nonLinearEffects(model, data, q, v)
        pin.crba(model, data, q)
        pin.cholesky.decompose(model, data)
        return pin.cholesky.solve(model, data, b)

    def f(q, v):
        unit = q.copy()  # a stage's quaternions are not unit ones: the dynamics sees the rotations they stand for
        unit[quat] /= np.linalg.norm(q[quat], axis=1, keepdims=True)
        return q_dot(q, v), acceleration(unit, v)

    k, n = _steps_per_frame(dt, output_dt), round(t_end / output_dt)
    r, R = np.empty((n + 1, len(joint), 3)), np.empty((n + 1, len(joint), 3, 3))

    def poses(f_):
        pin.forwardKinematics(model, data, q)
        for b, j in enumerate(joint):
            M = data.oMi[int(j)]
            R[f_, b] = M.rotation
            r[f_, b] = M.translation + M.rotation @ lever[b]

    t0 = time.perf_counter()
    poses(0)
    for fr in range(1, n + 1):
        for _ in range(k):
            dq1, a1 = f(q, v)
            dq2, a2 = f(q + 0.5 * dt * dq1, v + 0.5 * dt * a1)
            dq3, a3 = f(q + 0.5 * dt * dq2, v + 0.5 * dt * a2)
            dq4, a4 = f(q + dt * dq3, v + dt * a3)
            q = q + dt / 6.0 * (dq1 + 2.0 * dq2 + 2.0 * dq3 + dq4)
            v = v + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            q[quat] /= np.linalg.norm(q[quat], axis=1, keepdims=True)
        poses(fr)
    return PeerRun(markers(r, R), time.perf_counter() - t0, n * k)


# ---------------------------------------------------------------------------- helpers


def _v(x) -> str:
    return " ".join(repr(float(a)) for a in np.ravel(x))

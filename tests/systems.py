"""Random multibody systems and states for derivative and solver tests (seeded).

``random_system(flexible=True)`` adds flexible bars (two on floating frames with bending and axial
fields, one clamped in the world) joined to the rigid chain at sections of the bars, so every
derivative test also exercises points on flexible bodies.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from viz3d.bodies import Bodies, FlexibleBody
from viz3d.constraints import build_layout
from viz3d.coordinates import EulerSwitching, Quaternion
from viz3d.dynamics import body_state, retract
from viz3d.flexible import Material, Section, analytic_modes, fe_model, reduce
from viz3d.flexible.floating import floating_bar, with_geometric_stiffening
from viz3d.forces import Gravity, SpringDamper
from viz3d.joints import JOINTS, BallJoint
from viz3d.points import body_points
from viz3d.system import State, System

#: A steel-like bar for the flexible bodies: soft enough that deflections are visible in the tests.
BAR_LENGTH = 0.8
BAR_MATERIAL = Material(2e9, 2000.0, 0.3)
BAR_SECTION = Section.rectangle(0.03, 0.02)


def random_inertia(rng, n):
    """SPD inertia tensors with products of inertia that satisfy the triangle inequality."""
    p = rng.uniform(0.5, 1.0, (n, 3)) * 0.01
    p[:, 2] = np.minimum(p[:, 2], p[:, 0] + p[:, 1])
    Q = Rotation.random(n, random_state=rng.integers(1 << 31)).as_matrix()
    return np.einsum("nij,nj,nkj->nik", Q, p, Q)


def ball_joints(rng, pairs, names=None):
    pairs = np.asarray(pairs, dtype=int)
    names = names or tuple(f"j{i}" for i in range(len(pairs)))
    return BallJoint(tuple(names), pairs, rng.normal(scale=0.3, size=(len(pairs), 2, 3)))


def flexible_bars(rng, stiffened=False):
    """Three bars: a free-free bending + axial bar and a pinned-free bending bar on floating frames,
    and a clamped-free FE bar on a fixed frame (modal units differ: both kinds are exercised); with
    ``stiffened``, the floating ones with geometric stiffening (``with_geometric_stiffening``)."""
    bend = analytic_modes("euler_bernoulli", BAR_LENGTH, BAR_MATERIAL, BAR_SECTION, 3, ("free", "free"))
    axial = analytic_modes("rod", BAR_LENGTH, BAR_MATERIAL, BAR_SECTION, 2, ("free", "free"))
    pinned = analytic_modes("timoshenko", BAR_LENGTH, BAR_MATERIAL, BAR_SECTION, 2, ("pinned", "free"))
    clamped = reduce(fe_model("euler_bernoulli", BAR_LENGTH, BAR_MATERIAL, BAR_SECTION, 6, ("clamped", "free")), 3)
    bars = [floating_bar(bend, np.array([0.0, 0.0, 1.0]), second=(np.array([1.0, 0.0, 0.0]), axial)),
            floating_bar(pinned, np.array([0.0, 1.0, 0.0])),
            floating_bar(clamped, np.array([0.0, 0.6, 0.8]))]
    if stiffened:
        bars[:2] = [with_geometric_stiffening(bar) for bar in bars[:2]]
    return bars, (True, True, False)


def random_system(nb=4, seed=0, extra_pairs=((0, 2),), springs=True, flexible=False, kinds=("ball",),
                  framed_on_flexible=False, stiffened=False):
    """A chain 0-1-...-(nb-1) hung from ground plus ``extra_pairs`` joints, random inertia; with
    ``flexible``, three flexible bars after the rigid bodies, joined to the chain (and to each other)
    at random sections by ball joints (by the types ``kinds`` too with ``framed_on_flexible``). The
    joints between rigid bodies (and ground) cycle through the joint types ``kinds``
    (``viz3d.joints.JOINTS``), with random joint frames. ``stiffened``: see ``flexible_bars``."""
    rng = np.random.default_rng(seed)
    names = tuple(f"b{i}" for i in range(nb))
    mass, inertia, flex = rng.uniform(0.5, 2.0, nb), random_inertia(rng, nb), ()
    if flexible:
        bars, floats = flexible_bars(rng, stiffened)
        names += ("f0", "f1", "f2")
        R0 = Rotation.random(3, random_state=seed + 7).as_matrix()
        flex = tuple(FlexibleBody(nb + i, bar, fl, rng.normal(size=3), R0[i]) for i, (bar, fl) in enumerate(zip(bars, floats)))
        mass = np.concatenate([mass, [b.mass for b in bars]])
        inertia = np.concatenate([inertia, [b.J0 for b in bars]])
    n_all = len(names)
    bodies = Bodies(names, mass, inertia, flex)
    pairs = [(0, n_all)] + [(i, i - 1) for i in range(1, nb)] + list(extra_pairs)
    if flexible:
        pairs += [(nb, nb - 1), (nb + 1, nb), (nb + 2, nb + 1), (nb + 1, 0)]
    joints = _joints_of_kinds(rng, bodies, pairs, kinds, nb, framed_on_flexible)
    forces = [Gravity(bodies.mass, np.array([0.0, 0.0, -9.81]), flex, sum(fb.n for fb in flex))]
    if springs:
        sp = [[0, n_all], [nb - 1, 0], [1, 2 % nb]] + ([[nb, n_all], [nb + 2, 1]] if flexible else [])
        forces.append(_springs(rng, bodies, np.array(sp)))
    return System(bodies, build_layout(joints, bodies), tuple(forces), EulerSwitching())


def sections_tree(kind, seed=0):
    """Joints of type ``kind`` on sections of the bars of ``flexible_bars``, in a tree (no loop: the
    rows are independent at any state): ground - f0 (side 0 on a section), f0 - f1 (both sides on
    sections of bars on floating frames), f1 - r0 (side 1 on a section), f2 (a bar on a fixed frame)
    - r1 (side 1); rigid bodies r0, r1, gravity. Random sections, section offsets and joint frames."""
    rng = np.random.default_rng(seed)
    bars, floats = flexible_bars(rng)
    R0 = Rotation.random(3, random_state=seed + 7).as_matrix()
    flex = tuple(FlexibleBody(2 + i, bar, fl, rng.normal(size=3), R0[i]) for i, (bar, fl) in enumerate(zip(bars, floats)))
    bodies = Bodies(("r0", "r1", "f0", "f1", "f2"), np.concatenate([rng.uniform(0.5, 2.0, 2), [b.mass for b in bars]]),
                    np.concatenate([random_inertia(rng, 2), [b.J0 for b in bars]]), flex)
    joints = (_joints(rng, bodies, [(2, 5), (3, 2), (0, 3), (1, 4)], kind),)
    gravity = Gravity(bodies.mass, np.array([0.0, 0.0, -9.81]), flex, sum(fb.n for fb in flex))
    return System(bodies, build_layout(joints, bodies), (gravity,), EulerSwitching())


def _sides(rng, bodies, pairs):
    """Random attachment points of both sides: offsets on rigid bodies, sections (and small section
    offsets) on flexible ones."""
    k = len(pairs)
    B_s = rng.normal(scale=0.3, size=(k, 2, 3))
    x = rng.uniform(0.0, BAR_LENGTH, size=(k, 2))
    for fb in bodies.flexible:
        on = pairs == fb.index
        B_s[on] = rng.normal(scale=0.005, size=(int(on.sum()), 3)) * [0.0, 1.0, 1.0]  # in the section plane
    return B_s, tuple(body_points(bodies, pairs[:, s], B_s[:, s], x[:, s]) for s in (0, 1))


def _joints(rng, bodies, pairs, kind="ball", first=0):
    pairs = np.asarray(pairs, dtype=int)
    B_s, sides = _sides(rng, bodies, pairs)
    names = tuple(f"j{first + i}" for i in range(len(pairs)))
    if kind == "ball":
        return BallJoint(names, pairs, B_s, sides)
    B_A = Rotation.random(2 * len(pairs), random_state=rng.integers(1 << 31)).as_matrix().reshape(len(pairs), 2, 3, 3)
    return JOINTS[kind](names, pairs, B_s, B_A, sides)


def _joints_of_kinds(rng, bodies, pairs, kinds, nb, framed_on_flexible=False):
    """Joint sets for ``pairs``: pairs of rigid bodies (or ground) take the types ``kinds`` in turn,
    pairs with a flexible body ball joints (or, ``framed_on_flexible``, the types ``kinds`` too)."""
    n_all = bodies.n_bodies
    kind_of = []
    for a, b in pairs:
        rigid = framed_on_flexible or all(x < nb or x == n_all for x in (a, b))
        kind_of.append(kinds[len(kind_of) % len(kinds)] if rigid else "ball")
    sets = []
    for kind in dict.fromkeys(kind_of):
        which = [k for k, x in enumerate(kind_of) if x == kind]
        sets.append(_joints(rng, bodies, [pairs[k] for k in which], kind, first=len(sets) * 100))
    return tuple(sets)


def _springs(rng, bodies, pairs):
    B_s, sides = _sides(rng, bodies, pairs)
    k = len(pairs)
    return SpringDamper(tuple(f"s{i}" for i in range(k)), pairs, B_s, rng.uniform(10, 100, k), np.zeros(k),
                        rng.uniform(0.1, 0.5, k), sides)


def random_state(system, seed=1):
    """Random positions, orientations (through a random chart), elastic coordinates and velocities."""
    rng = np.random.default_rng(seed)
    nf = system.n_frames
    chart = Rotation.random(nf, random_state=seed).as_matrix()
    theta = np.column_stack([rng.uniform(-3, 3, nf), rng.uniform(0.7, 2.4, nf), rng.uniform(-3, 3, nf)])
    eta = _elastic_amplitudes(system, rng)
    q = system.join_q(rng.normal(size=(nf, 3)), theta, eta)
    v = rng.normal(size=system.n_v)
    v[6 * nf:] *= np.concatenate([_mode_scale(fb) for fb in system.bodies.flexible] or [np.zeros(0)]) * 20.0
    return State(0.0, q, v, chart)


def _mode_scale(fb):
    """Elastic coordinates of about 1 cm deflection for each coordinate (modal units vary)."""
    return 0.01 / np.sqrt(np.diag(fb.bar.M_ee) / fb.bar.mass)


def _elastic_amplitudes(system, rng):
    parts = [rng.normal(size=fb.n) * _mode_scale(fb) for fb in system.bodies.flexible]
    return np.concatenate(parts) if parts else np.zeros(0)


def with_quaternions(system, state, seed: int = 0):
    """``(system, state)`` in Euler parameters (``sim.rotation = "quaternion"``): every frame's
    ``R_WB`` as a quaternion times a random norm in [0.5, 2] (``R(p)`` must normalise, the kinematics
    take ``p`` as stored), charts the identity; positions, elastic coordinates, velocities unchanged."""
    rng = np.random.default_rng(seed)
    W_r, theta = system.split_q(state.q)
    R = system.rotation.matrix(theta, state.chart)
    p = Rotation.from_matrix(R).as_quat(scalar_first=True) * rng.uniform(0.5, 2.0, (len(R), 1))
    quat = dataclasses.replace(system, rotation=Quaternion())
    q = quat.join_q(W_r, p, system.elastic_part(state.q, system.n_frames * system.n_q_body))
    return quat, state.replace(q=q, chart=np.broadcast_to(np.eye(3), state.chart.shape).copy())


def configuration(system, state):
    """The ``Configuration`` of ``state``."""
    return body_state(system, state.q, state.v, state.chart, state.t)


def pose_twist(system, state):
    cfg = configuration(system, state)
    return cfg.pose, cfg.twist


def moved(system, state, dx, eps):
    """``state``'s configuration with positions moved by the velocity-space increment ``eps * dx`` (n_v,)."""
    return body_state(system, retract(system, state.q, eps * dx, state.chart), state.v, state.chart, state.t)


def along(system, state, acc, t):
    """Configuration at time ``t`` under constant velocity-space accelerations ``acc`` (n_v,), to
    second order: positions ``retract(q, t v + t^2 / 2 acc)``, velocities ``v + t acc``."""
    q = retract(system, state.q, t * state.v + 0.5 * t * t * acc, state.chart)
    return body_state(system, q, state.v + t * acc, state.chart, state.t + t)


def drive_set(system, seed: int = 0, pick: dict | None = None):
    """A ``JointDrive`` on every relative coordinate (angles about and distances along joint axes) of ``system``'s framed
    joints (of each set the joint ``pick[type_name]``, default the last: a drive on a joint that closes a
    loop of ``random_system`` can make its rows redundant), cycling through position and velocity
    profiles of every allowed kind."""
    from viz3d.joints import JointDrive
    from viz3d.timefunctions import PROFILE_KINDS, TimeFunctions

    rng = np.random.default_rng(seed)
    sets, index, free = [], [], []
    for js in system.joints.joints:
        for c in range(len(getattr(js, "FREE", ()))):
            sets.append(js)
            index.append((pick or {}).get(js.type_name, js.n_joints - 1))
            free.append(c)
    modes = [("position", k) for k in PROFILE_KINDS["position"]] + [("velocity", k) for k in PROFILE_KINDS["velocity"]]
    chosen = [modes[i % len(modes)] for i in range(len(sets))]
    funcs = TimeFunctions.from_entries([{"kind": kind, "offset": [rng.normal(), 0, 0], "amplitude": [rng.normal(), 0, 0],
                                         "frequency": rng.uniform(0.5, 2), "phase": rng.uniform(0, 6),
                                         "start": rng.uniform(-0.1, 0.1), "duration": rng.uniform(0.2, 0.5)}
                                        for _, kind in chosen])
    kind, table = funcs.table()
    body = np.array([js.body[j] for js, j in zip(sets, index)])
    return JointDrive(tuple(f"d{i}" for i in range(len(sets))), body, tuple(sets), np.array(index), np.array(free), kind,
                      np.array([m == "velocity" for m, _ in chosen], np.int64), table)


#: A rod (mass [kg], length [m], radius [m]) hinged at its top on the y axis, released at rest THETA0
#: [rad] from hanging (``rod_on_a_stop``).
ROD_M, ROD_L, ROD_R, THETA0 = 1.2, 0.6, 0.02, np.radians(-36.0)
#: Its moment of inertia about the hinge [kg m^2] (a solid cylinder's about its centre, then Steiner).
ROD_I_O = ROD_M * (3 * ROD_R**2 + ROD_L**2) / 12 + ROD_M * (ROD_L / 2) ** 2


def rod_on_a_stop(tmp_path, upper: float, stiffness: float, damping: float, t_end: float, dt: float):
    """The rod on ALI3-P with the trapezoidal rule, its hinge's ``joint_stop`` at ``upper`` [rad] from the
    start (``stiffness`` [N m/rad], ``damping`` [N m s/rad]): ``(system, state, formulation, I_O)``,
    ``I_O`` its moment of inertia about the hinge [kg m^2]."""
    import viz3d
    from viz3d.scene.build import make_formulation

    I_t = ROD_M * (3 * ROD_R**2 + ROD_L**2) / 12
    u = np.array([-np.sin(THETA0), 0.0, -np.cos(THETA0)])  # the rod's axis from the hinge, R_y(THETA0) (0, 0, -1)
    vec = lambda x: "[" + ", ".join(repr(float(c)) for c in x) + "]"  # noqa: E731
    path = tmp_path / "rod_on_a_stop.toml"
    path.write_text(  # body z along the rod: ZXZ (90, THETA0, -90) deg is R_y(THETA0)
        f'[sim]\nt_end = {t_end}\ndt = {dt}\nformulation = "ali3p"\nintegrator = "trapezoidal"\n'
        f'[[bodies]]\nname = "rod"\nshape = {{ type = "cylinder", radius = {ROD_R}, height = {ROD_L} }}\n'
        f"mass = {ROD_M}\ninertia = {vec([I_t, I_t, ROD_M * ROD_R**2 / 2])}\nposition = {vec(0.5 * ROD_L * u)}\n"
        f"euler_deg = {vec([90.0, np.degrees(THETA0), -90.0])}\n"
        '[[joints]]\nname = "hinge"\ntype = "revolute"\nbody1 = "rod"\npoint = [0.0, 0.0, 0.0]\naxis = [0.0, 1.0, 0.0]\n'
        f'[[forces]]\ntype = "joint_stop"\nname = "stop"\njoint = "hinge"\nupper = {upper}\n'
        f"stiffness = {stiffness}\ndamping = {damping}\n")
    scene = viz3d.load_scene(path)
    system, state = viz3d.build(scene)
    return system, state, make_formulation(scene.data["sim"]), ROD_I_O


#: The anchor hoist (scenes/anchor_hoist.toml) on RK4 with Baumgarte's drift control at the step its links'
#: Hertz contact on the rim allows (its default until 2026-11-28; ALI3-P since), set explicitly by the tests
#: of RK4's own behaviour there (its ledger against the step, the compiled RK4 against NumPy).
HOIST_RK4 = ("sim.formulation=baumgarte", "sim.integrator=rk4", "sim.dt=5e-4")

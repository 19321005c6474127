"""The compiled kernel against the NumPy reference on a random system holding every registered element.

Registry-driven: the system below is built from the registries (force elements, joints, normal
laws, contact treatments, time functions, body kinds), and ``test_the_system_exercises_every_piece``
fails when a registered compiled piece has no item in it, so a new element type must be added
here (one line in ``ELEMENT_BUILDERS`` or in the contact table). The right-hand sides (positions,
velocities, accelerations, the ledger's work rates) must agree to the computation's round-off at
several times (every branch of every time function) and for every formulation the kernel covers,
with the frames' orientations in re-charted Euler angles and in Euler parameters (every test of the
module runs on both: ``setup``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from contact.law_examples import EXAMPLES
from kernel_runs import ROUNDOFF_FACTOR, step_roundoff

from viz3d import compiled
from viz3d import kernel as K
from viz3d.constraints import build_layout
from viz3d.contact.collision import Collisions, PairLaw, Shape, support_points
from viz3d.contact.contacts import ContactPhase, ContactRows, ContactSet
from viz3d.contact.friction import Bristle, RegularizedCoulomb, Stribeck
from viz3d.contact.laws import NORMAL_LAWS, Hertz, HuntCrossley, Linear
from viz3d.dynamics import VectorField, body_state, flexible_kinetic
from viz3d.forces import AppliedForce, AppliedTorque, DriveServo, ForceElement, JointMotor, JointStop, SpringDamper
from viz3d.formulation import ALI3P, Baumgarte, Index1, Penalty, Projection
from viz3d.joints import JOINTS, FramedJoint
from viz3d.kernel.model import FORMULATIONS
from viz3d.system import System
from viz3d.timefunctions import TIME_FUNCTIONS, TimeFunctions

from systems import _sides, configuration, drive_set, random_state, random_system, sections_tree, with_quaternions

#: Kernel and NumPy path evaluate the same formulas in another order: they may differ by the
#: computation's round-off, eps times its condition number, measured as the NumPy result's change
#: under relative perturbations of eps of the state (max over SAMPLES); allowed: FACTOR times that.
FACTOR = 10.0
SAMPLES = 4
#: Times at which the loads are compared: before the starts (0.02 s), inside the ramps and pulses,
#: after them (every branch of every time function; starts in [0.05, 0.1] s, durations [0.1, 0.2] s).
TIMES = (0.02, 0.12, 0.4)
#: Indentation of the touching contacts [m] (about 0.1-1 kN with the laws' examples).
ALPHA = 2e-5


def _time_functions(rng, k: int) -> TimeFunctions:
    """k functions cycling through every kind of ``TIME_FUNCTIONS``."""
    kinds = [TIME_FUNCTIONS[i % len(TIME_FUNCTIONS)] for i in range(k)]
    entries = [{"kind": kind, "offset": rng.normal(size=3), "amplitude": rng.normal(size=3), "frequency": rng.uniform(1, 5),
                "phase": rng.uniform(0, 6), "start": rng.uniform(0.05, 0.1), "duration": rng.uniform(0.1, 0.2)}
               for kind in kinds]
    return TimeFunctions.from_entries(entries)


def _pairs(rng, bodies, k):
    """k random (body, other) pairs among all bodies and ground, flexible ones included."""
    nb = bodies.n_bodies
    first = rng.integers(0, nb, k)
    second = (first + rng.integers(1, nb + 1, k)) % (nb + 1)
    return np.column_stack([first, second])


def _damped_springs(rng, bodies):
    pairs = _pairs(rng, bodies, 4)
    B_s, sides = _sides(rng, bodies, pairs)
    return SpringDamper(("d0", "d1", "d2", "d3"), pairs, B_s, rng.uniform(10, 100, 4), rng.uniform(0.5, 2, 4),
                        rng.uniform(0.1, 0.5, 4), sides)


def _loads(cls, rng, bodies):
    k = 2 * len(TIME_FUNCTIONS)
    pairs = _pairs(rng, bodies, k)
    B_s, sides = _sides(rng, bodies, pairs)
    body_frame = np.arange(k) % 2 == 1
    if cls is AppliedTorque:
        return AppliedTorque(tuple(f"t{i}" for i in range(k)), pairs[:, 0], np.zeros((k, 3)), body_frame,
                             _time_functions(rng, k))
    return AppliedForce(tuple(f"f{i}" for i in range(k)), pairs[:, 0], B_s[:, 0], body_frame, _time_functions(rng, k),
                        sides[0])


def _joint_coordinates(base, per_set: int = 1):
    """(joint sets, index, coordinate) covering every free coordinate of the base's framed joints."""
    sets, index, free = [], [], []
    for js in base.joints.joints:
        for j in range(min(js.n_joints, per_set)):
            for c in range(len(getattr(js, "FREE", ()))):
                sets.append(js)
                index.append(j)
                free.append(c)
    return tuple(sets), np.array(index), np.array(free)


def _joint_stops(rng, base, state):
    """Stops on every coordinate kind, around the coordinates' values at ``random_state``: each item
    inside, beyond its upper or below its lower limit (the cases of the piecewise law)."""
    sets, index, free = _joint_coordinates(base)
    k = len(sets)
    cfg = configuration(base, state)
    q = np.array([js.coordinates(cfg)[0][j, c] for js, j, c in zip(sets, index, free)])
    shift = np.array([(-1.0, 0.0, 1.0)[i % 3] for i in range(k)]) * 0.05
    return JointStop(tuple(f"stop{i}" for i in range(k)), sets, index, free, q - 0.02 + shift, q + 0.02 + shift,
                     rng.uniform(10, 100, k), rng.uniform(0.1, 2.0, k))


def _joint_motors(rng, base, state):
    sets, index, free = _joint_coordinates(base)
    k = len(sets)
    funcs = _time_functions(rng, k)
    return JointMotor(tuple(f"motor{i}" for i in range(k)), sets, index, free, funcs, rng.uniform(5, 50, k),
                      rng.uniform(0.1, 1.0, k), np.where(np.arange(k) % 3 == 2, rng.uniform(0.05, 0.2, k), np.inf))


def _drive_servos(rng, base, state):
    """Limited drives: every third at its capacity at ``state`` (a capacity below the servo's demand)."""
    sets, index, free = _joint_coordinates(base)
    k = len(sets)
    return DriveServo(tuple(f"servo{i}" for i in range(k)), sets, index, free, _time_functions(rng, k),
                      rng.uniform(5, 50, k), np.where(np.arange(k) % 3 == 2, rng.uniform(1e-3, 1e-2, k), np.inf))


#: Force elements beyond the gravity and springs of ``random_system``: one builder per element type,
#: from a random generator, the base system and the state the tests evaluate.
def _random_rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


#: Shape contacts of ``_shape_contacts``: per rigid body a shape against its own ground plane (groups
#: k and 3 + k), with a pair law of each kind: linear + bristle, Hertz from the materials + Stribeck,
#: Hunt-Crossley (fixed constant) + regularised Coulomb.
SHAPE_KINDS = (("box", (0.2, 0.1, 0.3)), ("sphere", (0.05,)), ("capsule", (0.04, 0.1)))


def _shape_contacts(rng, base, state):
    """Shape contacts (``Collisions``) against ground planes: a box on its bottom face tilted by 1e-4
    rad (four corners in, the reduction's merge and spread), a sphere (Hertz's factor from the
    materials), a capsule on its side (both end spheres), each a few ``ALPHA`` into its plane."""
    cfg = body_state(base, state.q, state.v, state.chart)
    nb = base.bodies.n_bodies
    rigid = [b for b in range(nb) if base.bodies.is_rigid[b]][: len(SHAPE_KINDS)]
    shapes, planes = [], []
    for g, (b, (kind, size)) in enumerate(zip(rigid, SHAPE_KINDS)):
        B_r, B_R = rng.normal(size=3) * 0.02, _random_rotation(rng)
        support = support_points(kind, size, np.zeros((0, 3)))
        shapes.append(Shape(f"s{g}", b, kind, size, B_r, B_R, support=support, group=g))
        R = cfg.pose.R_WB[b] @ B_R
        down = {"box": R[:, 2], "sphere": rng.normal(size=3), "capsule": R[:, 0]}[kind]  # capsule: axis z
        n = -(down + 1e-4 * rng.normal(size=3)) / np.linalg.norm(down)
        n /= np.linalg.norm(n)
        centres = cfg.pose.W_r[b] + (B_r + support[:, :3] @ B_R.T) @ cfg.pose.R_WB[b].T
        lowest = np.min(centres @ n - support[:, 3])
        planes.append(Shape(f"p{g}", nb, "plane", B_r=(lowest + 3 * ALPHA) * n, group=len(SHAPE_KINDS) + g, normal=n))
    G = 2 * len(SHAPE_KINDS)
    pair_law = -np.ones((G, G), int)
    for g in range(len(SHAPE_KINDS)):
        pair_law[g, len(SHAPE_KINDS) + g] = pair_law[len(SHAPE_KINDS) + g, g] = g
    laws = (PairLaw(Linear(2e5, 30.0), 20.0, Bristle(0.3, 0.5, 3.0, 2e4, 30.0, 0.4)),
            PairLaw(Hertz(1.0), 5.0, Stribeck(0.3, 0.5, 0.05, 0.7, 1e-3), hertz_modulus=2e9),
            PairLaw(HuntCrossley(1e8, 1.5, damping_factor=0.3), 0.0, RegularizedCoulomb(0.4, 1e-3)))
    return Collisions(tuple(shapes + planes), tuple(f"g{g}" for g in range(G)), pair_law, laws, nb)


ELEMENT_BUILDERS = {
    "shape contacts against planes (every friction law, Hertz from the materials)": _shape_contacts,
    "damped springs": lambda rng, base, state: _damped_springs(rng, base.bodies),
    "forces (every time function, world and body axes)": lambda rng, base, state: _loads(AppliedForce, rng, base.bodies),
    "torques (every time function, world and body axes)": lambda rng, base, state: _loads(AppliedTorque, rng, base.bodies),
    "stops on every kind of joint coordinate": _joint_stops,
    "motors on every kind of joint coordinate (saturated or not)": _joint_motors,
    "limited drives on every kind of joint coordinate (stalled or not)": _drive_servos,
}


def _touching(system, state, sides, alpha):
    """Normals (B axes) and radii putting each contact's sphere ``alpha`` into its surface at ``state``."""
    cfg = body_state(system, state.q, state.v, state.chart)
    d = sides[0].positions(cfg) - sides[1].positions(cfg)
    dist = np.linalg.norm(d, axis=1)
    n_W = d / dist[:, None]
    normal = np.einsum("kji,kj->ki", cfg.pose.R_WB[sides[1].body], n_W)
    return normal, dist + alpha


def _contacts(rng, system, state):
    """Located law contacts, one per registered law (touching, with a memory), plus one that is not
    touching; kinematic contacts, one touching and one not; a set of stepped-through contacts."""
    bodies = system.bodies
    laws = [EXAMPLES[name] for name in NORMAL_LAWS] + [EXAMPLES["hertz"]]
    models = ("law",) * len(laws) + ("rigid", "rigid")
    k = len(models)
    pairs = _pairs(rng, bodies, k)
    B_s, sides = _sides(rng, bodies, pairs)
    normal, radius = _touching(system, state, sides, rng.uniform(0.5, 2.0, k) * ALPHA)
    rigid = [all(b == bodies.n_bodies or bodies.is_rigid[b] for b in pair) and m == "law" for pair, m in zip(pairs, models)]
    # one of each friction law (the bristles' v_stick of the order of the random slips: both regimes weigh)
    kinds = [RegularizedCoulomb(0.4, 1e-3), Stribeck(0.3, 0.5, 0.05, 0.7, 1e-3), Bristle(0.3, 0.5, 3.0, 2e4, 30.0, 0.4)]
    friction = tuple(kinds[sum(rigid[:i]) % len(kinds)] if rigid[i] else None for i in range(k))
    assert {type(f) for f in friction if f is not None} == {type(f) for f in kinds}, "a friction law of each kind"
    located = ContactSet(tuple(f"c{i}" for i in range(k)), pairs, sides, normal, radius, models,
                         tuple(laws) + (None, None), damping=rng.uniform(0, 50, k), friction=friction)
    phases = []
    for i, law in enumerate(located.laws):
        touching = i not in (len(laws) - 1, k - 1)
        memory = None
        if law is not None:
            memory = law.update(law.onset(rng.uniform(0.2, 2.0)), ALPHA * rng.uniform(0.5, 3.0), 0.1)
        phases.append(ContactPhase(touching=touching, memory=memory))
    cfg = configuration(system, state)  # bristles: anchors 0.1 mm and 10 cm away (below and above the cap)
    gp = located.gap(cfg)
    planted = 0
    for i, f in enumerate(located.friction):
        if f is not None and f.stateful:
            s = rng.normal(size=3) * (1e-4 if planted % 2 == 0 else 0.1)
            planted += 1
            s -= (s @ gp.n[i]) * gp.n[i]
            phases[i] = dataclasses.replace(phases[i], anchor=located.anchor_at(cfg, gp, i, s))
    k2 = 3
    pairs2 = _pairs(rng, bodies, k2)
    B2, sides2 = _sides(rng, bodies, pairs2)
    normal2, radius2 = _touching(system, state, sides2, np.array([ALPHA, -ALPHA, 0.5 * ALPHA]))
    stepped = ContactSet(("s0", "s1", "s2"), pairs2, sides2, normal2, radius2, ("law",) * k2,
                         (EXAMPLES["linear"], EXAMPLES["hertz"], EXAMPLES["linear"]), damping=np.array([0.0, 0.0, 30.0]),
                         located=False)
    return (located, stepped), (tuple(phases), stepped.initial_phases())


def every_element_system(seed: int = 3, rotation: str = "euler_switching"):
    """(system, state) with every registered element type, on rigid bodies and flexible
    bars on floating frames (with geometric stiffening) and a fixed one
    (``tests.systems.random_system(flexible=True, stiffened=True)``); ``rotation`` "quaternion":
    the same system and state in Euler parameters of random norms (``tests.systems.with_quaternions``)."""
    rng = np.random.default_rng(seed)
    base = random_system(nb=9, flexible=True, seed=seed, kinds=tuple(JOINTS), stiffened=True)  # every joint type on rigid bodies
    state = random_state(base, seed=seed + 1)
    forces = base.forces + tuple(build(rng, base, state) for build in ELEMENT_BUILDERS.values())
    contacts, memory = _contacts(rng, base, state)
    rows = ContactRows(contacts[0], contacts[0].rigid_rows(), 0)
    joints = base.joints.joints + (drive_set(base, seed, pick={"prismatic": 0}), rows)  # (0, 2) closes a loop
    system = System(base.bodies, build_layout(joints, base.bodies), forces, base.rotation, contacts)
    n_aux = system.n_aux
    state = state.replace(w=rng.normal(size=n_aux), memory=memory)
    return with_quaternions(system, state, seed) if rotation == "quaternion" else (system, state)


@pytest.fixture(scope="module", params=["euler_switching", "quaternion"])
def setup(request):
    return every_element_system(rotation=request.param)


def test_the_system_exercises_every_piece(setup):
    system, state = setup
    data = K.kernel_for(system, Index1())
    assert data is not None, K.kernel_coverage(system, Index1())[1]
    for target, packed in ((compiled.force_piece, data.forces), (compiled.row_piece, data.rows)):
        classes = compiled.registered(target)
        assert len(packed) == len(classes)
        empty = [cls.__name__ for cls, d in zip(classes, packed) if d.i.shape[0] == 0 and d.f.shape[0] == 0]
        assert not empty, f"registered pieces with no item in the test system: {empty}"
    kinds = {fb.floating for fb in system.bodies.flexible}
    assert kinds == {True, False} and system.bodies.is_rigid.any()
    assert all(fb.bar.K_omega is not None for fb in system.bodies.flexible if fb.floating)


@pytest.mark.parametrize("formulation", [Index1(), Baumgarte(7.0, 12.0), Penalty(1e5, 1.0, 9.0), Projection()],
                         ids=lambda f: f.name)
def test_compiled_equals_numpy_right_hand_side(setup, formulation):
    system, state = setup
    assert set(FORMULATIONS) == {"index1", "baumgarte", "penalty", "projection", "ali3p"}
    # ALI3-P steps itself (tests/numerics/test_kernel_ali3p.py, on systems it covers: no flexible bodies or
    # contacts, which this one has); the field of its output frames is index-1's
    assert FORMULATIONS["ali3p"](ALI3P()) == FORMULATIONS["index1"](Index1())
    data = K.kernel_for(system, formulation)
    rhs = VectorField(system, formulation, state.chart, state.memory)
    for t in TIMES:
        ref = rhs(t, state.y)
        out = K.kernel_rhs(data, t, state.y, state.chart, state.memory)
        err = np.abs(out - ref)
        tol = FACTOR * _roundoff(rhs, t, state.y, ref)
        assert err.max() <= tol, f"t = {t}: worst entry {int(np.argmax(err))} of {len(ref)} off by {err.max():.3g} (tol {tol:.3g})"


#: The joint types with frames: their rows on sections of flexible bars turn with the sections.
FRAMED = [kind for kind, cls in JOINTS.items() if issubclass(cls, FramedJoint)]


@pytest.mark.parametrize("formulation", [Index1(), Baumgarte(7.0, 12.0)], ids=lambda f: f.name)
@pytest.mark.parametrize("kind", FRAMED)
def test_framed_joints_on_flexible_sections_equal_numpy(kind, formulation):
    """Joints with frames whose sides sit on sections of flexible bars (side 0, side 1, both; bars on
    floating and fixed frames; ``tests.systems.sections_tree``): the axes turn with the sections, which
    enters C, C_v (elastic columns) and gamma; Baumgarte's feedback adds C and C_v v to the comparison.
    Tolerance as above."""
    system = sections_tree(kind)
    state = random_state(system, seed=1)
    assert {js.type_name for js in system.joints.joints} == {kind} and all(js.on_flexible for js in system.joints.joints)
    data, why = K.kernel_coverage(system, formulation)
    assert data is not None, why
    rhs = VectorField(system, formulation, state.chart)
    t = TIMES[1]
    ref = rhs(t, state.y)
    err = np.abs(K.kernel_rhs(data, t, state.y, state.chart) - ref)
    tol = FACTOR * _roundoff(rhs, t, state.y, ref)
    assert err.max() <= tol, f"worst entry {int(np.argmax(err))} of {len(ref)} off by {err.max():.3g} (tol {tol:.3g})"


@pytest.mark.parametrize("kind", [k for k in FRAMED if JOINTS[k].FREE])
def test_drives_on_joints_at_flexible_sections_equal_numpy(kind):
    """Drives on every coordinate of joints on sections (``sections_tree``: the first three joints,
    side 0, both sides and side 1 on sections), position and velocity profiles, at every time of
    TIMES: the drive's axes turn with the sections, as the joints' do. Tolerance as above."""
    base = sections_tree(kind)
    drives = tuple(drive_set(base, seed=j, pick={kind: j}) for j in range(3))
    system = System(base.bodies, build_layout(base.joints.joints + drives, base.bodies), base.forces, base.rotation)
    state = random_state(system, seed=1).replace(w=np.zeros(system.n_aux))  # the drives' work in the ledger
    data, why = K.kernel_coverage(system, Index1())
    assert data is not None, why
    rhs = VectorField(system, Index1(), state.chart)
    for t in TIMES:
        ref = rhs(t, state.y)
        err = np.abs(K.kernel_rhs(data, t, state.y, state.chart) - ref)
        tol = FACTOR * _roundoff(rhs, t, state.y, ref)
        assert err.max() <= tol, f"t = {t}: entry {int(np.argmax(err))} of {len(ref)} off by {err.max():.3g} (tol {tol:.3g})"


def _roundoff(rhs, t, y, ref):
    """Round-off scale of ``rhs`` at ``y``: max |rhs(y (1 + eps s)) - rhs(y)| over random signs s, at
    least eps |rhs|."""
    eps = np.finfo(float).eps
    signs = np.random.default_rng(1).choice([-1.0, 1.0], size=(SAMPLES, len(y)))
    change = max(np.abs(rhs(t, y * (1 + eps * s)) - ref).max() for s in signs)
    return max(change, eps * np.abs(ref).max())


def test_the_comparison_can_fail(setup):
    """A wrong law parameter is caught: the test above compares the contact forces."""
    system, state = setup
    data = K.kernel_for(system, Index1())
    ref = K.kernel_rhs(data, TIMES[1], state.y, state.chart, state.memory)
    for d in data.forces:
        if d.i.shape[0] and "Hertz" in type(d).__name__:
            d.f[:, -1] *= 1.0 + 1e-6
    out = K.kernel_rhs(data, TIMES[1], state.y, state.chart, state.memory)
    assert np.abs(out - ref).max() > 1e3 * np.finfo(float).eps * np.abs(ref).max()


class _Uncompiled(ForceElement):
    """A force element without a compiled piece."""

    type_name = "uncompiled_test_element"

    def wrench(self, cfg):
        return np.zeros_like(cfg.pose.W_r), np.zeros_like(cfg.pose.W_r), None


def test_an_element_without_a_compiled_piece_falls_back_visibly():
    from viz3d.integrators import make_integrator
    from viz3d.simulate import Simulation

    base = random_system()
    system = System(base.bodies, base.joints, base.forces + (_Uncompiled(),), base.rotation)
    data, why = K.kernel_coverage(system, Index1())
    assert data is None and "uncompiled_test_element" in why
    sim = Simulation(system, random_state(system), make_integrator("rk4"), Index1(), 1e-3)
    assert sim.kernel_note.startswith("NumPy path") and "uncompiled_test_element" in sim.kernel_note
    assert Simulation(base, random_state(base), make_integrator("rk4"), Index1(), 1e-3).kernel_note == "compiled kernel"


def test_compiled_configuration_and_gaps_equal_numpy(setup):
    """What output frames take from the kernel (``KernelStepper.configuration``): every body's pose
    and twist, the elastic coordinates and every contact's gap, against ``body_state`` and
    ``ContactSet.gap``. Same formulas in another order: round-off of the positions' scale."""
    system, state = setup
    stepper = K.KernelStepper(K.kernel_for(system, Index1()), None)
    t = TIMES[1]
    cfg, gaps = stepper.configuration(t, state.y, state.chart)
    ref = body_state(system, state.q, state.v, state.chart, t)
    scale = 1.0 + np.abs(state.y).max()
    tol = 100 * np.finfo(float).eps * scale
    for got, want in ((cfg.pose.W_r, ref.pose.W_r), (cfg.pose.R_WB, ref.pose.R_WB), (cfg.twist.W_v, ref.twist.W_v),
                      (cfg.twist.B_omega, ref.twist.B_omega), (cfg.twist.W_omega, ref.twist.W_omega)):
        assert got.shape == want.shape and np.abs(got - want).max() <= tol
    for got, want in zip(cfg.eta + cfg.eta_dot, ref.eta + ref.eta_dot):
        np.testing.assert_array_equal(got, want)
    assert len(gaps) == len(system.contacts) == 2
    for gp, c in zip(gaps, system.contacts):
        want = c.gap(ref)
        for field in ("alpha", "alpha_dot", "n", "d", "point"):
            got, exp = getattr(gp, field), getattr(want, field)
            assert got.shape == exp.shape and np.abs(got - exp).max() <= tol, field


def test_sampled_energies_equal_numpy(setup):
    """Every registered energy piece is exercised and, with the rigid kinetic energy the kernel
    samples (``KernelStepper.sample``), equals the NumPy energies (``energy_terms``): potentials by
    their sign class (gravity and loads, the rest), to round-off of the energies' scale."""
    from viz3d.dynamics import energy_terms
    from viz3d.forces import Gravity

    system, state = setup
    data = K.kernel_for(system, Index1())
    assert data.energy_gap is None, data.energy_gap
    classes = compiled.registered(compiled.energy_piece)
    empty = [cls.__name__ for cls, d in zip(classes, data.energies) if d.i.shape[0] == 0]
    assert classes and not empty, f"registered energy pieces with no item in the test system: {empty}"
    stepper = K.KernelStepper(data, None)
    ts = np.array(TIMES, float)
    n = len(ts)
    s = stepper.sample(ts, np.repeat(state.y[None], n, 0), np.repeat(state.chart[None], n, 0), state.memory)
    for i, t in enumerate(ts):
        e = energy_terms(system, state.replace(t=float(t)))
        signed = sum(V for f, V in zip(system.forces, e.potentials) if isinstance(f, (Gravity, AppliedForce)))
        rigid = e.kinetic - sum(flexible_kinetic(fb, body_state(system, state.q, state.v, state.chart, t), k)
                                for k, fb in enumerate(system.bodies.flexible))
        scale = abs(e.kinetic) + sum(abs(V) for V in e.potentials)
        tol = 100 * np.finfo(float).eps * scale
        assert abs(s.T[i] - rigid) <= tol, (t, s.T[i], rigid)
        assert abs(s.V[i, 0] - signed) <= tol and abs(s.V[i, 1] - (sum(e.potentials) - signed)) <= tol, (t, s.V[i])


@pytest.mark.parametrize("method", ["dopri5", "dop853", "rk4"])
def test_compiled_runge_kutta_step_equals_the_stepwise_one(setup, method):
    """``ExplicitRK.step`` on a kernel field runs the whole step compiled (``CompiledField.rk_step``).
    Against the same tableau stepped from Python over the same compiled right-hand side (the NumPy
    one is compared above): the stage arguments are summed in the same order, so stages and state
    agree exactly; the error estimate (a dot product in another order) to round-off of its terms.
    rk4 on Euler parameters takes the group (Munthe-Kaas) step, compiled too; the stepwise field keeps
    the hooks (``retract``, ``dexpinv``) so that both take it, and there the stages' Euler parameters
    ``p0 (x) exp(u)`` are formed in another order (``turn_quaternion``, ``Quaternion.advance``): the end
    state agrees to the round-off of a step (``kernel_runs.step_roundoff`` times ``ROUNDOFF_FACTOR``),
    the first stage (``f0``, given) exactly."""
    from viz3d.integrators import make_integrator

    system, state = setup
    integrator = make_integrator(method)
    field = VectorField(system, Index1(), state.chart, state.memory)
    compiled_field = K.CompiledField(field, K.KernelStepper(K.kernel_for(system, Index1()), None))
    t, h = TIMES[1], 1e-4
    f0 = compiled_field(t, state.y)
    ref = integrator.step(_Stepwise(compiled_field), t, state.y, h, f0=f0)  # stage by stage
    out = integrator.step(compiled_field, t, state.y, h, f0=f0)
    if compiled_field.dexpinv is not None and not integrator.tableau.embedded:
        np.testing.assert_array_equal(out.stages[0], ref.stages[0])
        bound = ROUNDOFF_FACTOR * step_roundoff(system, state, Index1(), h, method)
        assert np.abs(out.y - ref.y).max() <= bound, (np.abs(out.y - ref.y).max(), bound)
    else:
        np.testing.assert_array_equal(out.stages, ref.stages)
        np.testing.assert_array_equal(out.y, ref.y)
    assert (out.error is None) == (ref.error is None) and (out.f1 is None) == (ref.f1 is None)
    if ref.error is not None:
        tab = integrator.tableau
        terms = h * np.abs(tab.b - tab.b_hat) @ np.abs(ref.stages)
        assert np.all(np.abs(out.error - ref.error) <= len(tab.b) * np.finfo(float).eps * terms)


def test_compiled_rows_and_multipliers_equal_numpy(setup):
    """What output frames take from the kernel for reactions and the violation
    (``KernelStepper.solved_rows``): multipliers, residuals and frame Jacobian blocks of every row,
    joints and kinematic contacts, against ``accelerations``; the multipliers to FACTOR times the
    round-off of the NumPy solve (measured as for the right-hand side)."""
    from viz3d.dynamics import accelerations

    system, state = setup
    stepper = K.KernelStepper(K.kernel_for(system, Index1()), None)
    t = TIMES[1]
    lam, C, J = stepper.solved_rows(t, state.y, state.chart, state.memory)
    acc = accelerations(system, Index1(), t, state.q, state.v, state.chart, state.memory)
    eps = np.finfo(float).eps
    assert np.abs(C - acc.rows.C).max() <= 100 * eps * (1 + np.abs(state.y).max())
    assert np.abs(J - acc.rows.J).max() <= 100 * eps * (1 + np.abs(acc.rows.J).max())
    signs = np.random.default_rng(2).choice([-1.0, 1.0], size=(SAMPLES, len(state.y)))
    change = max(np.abs(accelerations(system, Index1(), t, *system.split_y(state.y * (1 + eps * s))[:2], state.chart,
                                      state.memory).lam - acc.lam).max() for s in signs)
    assert np.abs(lam - acc.lam).max() <= FACTOR * max(change, eps * np.abs(acc.lam).max())


def test_the_kernel_reads_strided_and_integer_arrays_as_their_values(setup):
    """The compiled entries are looked up once, for the first call's argument types: a later state
    given as a strided view or another dtype is converted, not read as if it were C-contiguous
    float64 (which would be a wrong answer without an error)."""
    system, state = setup
    field = VectorField(system, Index1(), state.chart, state.memory)
    compiled_field = K.CompiledField(field, K.KernelStepper(K.kernel_for(system, Index1()), None))
    t = TIMES[1]
    ref = compiled_field(t, state.y)  # fixes the entry for contiguous float64
    strided = np.repeat(state.y, 2)[::2]
    assert not strided.flags.c_contiguous
    np.testing.assert_array_equal(compiled_field(t, strided), ref)
    stepper = compiled_field.stepper
    g = stepper.gaps(t, state.y, state.chart)
    np.testing.assert_array_equal(stepper.gaps(t, strided, np.asfortranarray(state.chart)), g)
    with pytest.raises(ValueError, match="C-contiguous"):
        K.KernelStepper(K.kernel_for(system, Index1()), make_rk4()).step(t, 1e-4, strided, state.chart.copy(),
                                                                          np.zeros(system.n_bodies, np.int64), 1e4)


def make_rk4():
    from viz3d.integrators.tableaus import RK4

    return RK4


class _Stepwise:
    """``field``'s evaluations and hooks without its compiled step (``rk_step``)."""

    def __init__(self, field):
        self.field, self.n_q, self.n_v = field, field.n_q, field.n_v
        self.retract, self.dexpinv = field.retract, field.dexpinv

    def __call__(self, t, y):
        return self.field(t, y)

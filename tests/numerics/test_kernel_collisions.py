"""Shape contacts (``[collision]``) in the compiled kernel (``viz3d.kernel.collisions``) against the NumPy
element (``viz3d.contact.collision.Collisions``), the reference.

* Right-hand sides at the same states (positions, velocities, contacts, stick anchors) agree to the
  computation's round-off: eps times its condition number, measured as the NumPy result's change under
  relative perturbations of eps of the state (``_roundoff``, as tests/numerics/test_kernel.py does).
  The contacts' depths are differences of positions ~0.1 m that leave ~1e-5 m, so that condition number
  is ~1e4: the accelerations of these scenes agree to ~1e-12 of their size, not to eps.
* Whole RK4 runs agree, trajectory and stick anchors, while contacts start (touch-down), slip, stick
  and end (lift-off). Per step the two right-hand sides differ by round-off (above), so the kernel's
  run is one of the runs whose states differ from the NumPy run's by round-off, and what that grows to
  is the flow's business: a box bouncing on its corners amplifies a change of eps in its initial
  state to 1e-12 m by its second touch-down and to 1e-3 m by 0.3 s (which corner lands first
  switches), a sliding box on its four corners keeps it at 1e-14 m. The run's own sensitivity is
  therefore measured: the NumPy run from initial positions and velocities changed by eps (relative,
  random signs) against the NumPy run (``_runs``); the kernel's run may differ from the NumPy run by ``ROUNDOFF_FACTOR``
  times that, or by the round-off the steps add up to without growth (``steps * eps * max|y|``),
  whichever is larger. The early frames, before any switch, are thus held to ~1e-12. The two paths
  may list a pair's contacts in another order where depths tie to round-off (a box flat on a plane):
  anchors are compared as sets, each matched by its contact's shapes and marks.
* What the kernel does not cover runs on NumPy and says why.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import viz3d
from viz3d import kernel as K
from viz3d.contact.collision import Collisions
from viz3d.dynamics import VectorField, body_state
from viz3d.scene.build import build, make_formulation, make_integrator_from
from viz3d.simulate import Simulation

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "physics"))
from systems import HOIST_RK4  # noqa: E402
from test_collision_bristle import K_STICK, V_STICK, _friction, _scene  # noqa: E402

#: Bristle friction of the box scenes: mu 0.4, mu_s 0.6, the anchor's move keeping 0.8 of the cap (eq. 3.49).
BRISTLE = _friction("bristle", 0.4, 0.6) + "\nstick_alpha = 0.8"
#: Allowed: this many times the measured round-off scale of the NumPy right-hand side.
ROUNDOFF_FACTOR = 10.0
SENSITIVITY_SAMPLES = 4
#: Anchors and marks of matched contacts [m], at least: the contact points' round-off (positions ~0.1 m)
#: grown as the trajectory's (the larger of this and the frame's tolerance on y applies).
ANCHOR_TOL = 1e-12


def _load(tmp_path, text: str, name: str = "scene"):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    scene = viz3d.load_scene(path)
    system, state = build(scene)
    return scene, system, state


def _simulation(scene, system, state, compiled: bool) -> Simulation:
    cfg = scene.data["sim"]
    return Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"], compiled=compiled)


def _collisions(system) -> tuple[int, Collisions]:
    k = next(i for i, e in enumerate(system.forces) if isinstance(e, Collisions))
    return k, system.forces[k]


def _roundoff(rhs, t, y, ref):
    """Round-off scale of ``rhs`` at ``y``: max |rhs(y (1 + eps s)) - rhs(y)| over random signs s, at
    least eps |rhs|."""
    eps = np.finfo(float).eps
    signs = np.random.default_rng(1).choice([-1.0, 1.0], size=(SENSITIVITY_SAMPLES, len(y)))
    change = max(np.abs(rhs(t, y * (1 + eps * s)) - ref).max() for s in signs)
    return max(change, eps * np.abs(ref).max())


def _assert_rhs_equal(system, form, data, s):
    rhs = VectorField(system, form, s.chart, s.memory, s.element_memory)
    ref = rhs(s.t, s.y)
    out = K.kernel_rhs(data, s.t, s.y, s.chart, s.memory, s.element_memory)
    err = np.abs(out - ref)
    tol = ROUNDOFF_FACTOR * _roundoff(rhs, s.t, s.y, ref)
    assert err.max() <= tol, f"t = {s.t}: entry {int(np.argmax(err))} of {len(ref)} off by {err.max():.3g} (tol {tol:.3g})"


def _numpy_state(scene, system, state, steps: int):
    sim = _simulation(scene, system, state, compiled=False)
    return sim.steps(steps), sim


# ---------------------------------------------------------------------------- right-hand sides


@pytest.mark.parametrize("regime, theta_deg, steps", [("stick", 20.0, 400), ("slip", 35.0, 400)])
def test_rhs_equals_numpy_with_bristle_anchors(tmp_path, regime, theta_deg, steps):
    """A box on its four corners on an incline, bristle friction, after ``steps`` NumPy steps: held
    (the anchors deflected, |v_t| below v_stick) or sliding (|v_t| well above v_stick, anchors moved
    along by eq. 3.49)."""
    theta = np.radians(theta_deg)
    scene, system, state = _load(tmp_path, _scene(theta, BRISTLE, 1.0))
    s, sim = _numpy_state(scene, system, state, steps)
    k, coll = _collisions(system)
    anchors = s.element_memory[k]
    cfg = body_state(system, s.q, s.v, s.chart, s.t)
    tc = coll.detect(cfg)
    deflection = np.linalg.norm(coll.deflection(cfg, tc, anchors), axis=1)
    speed = np.linalg.norm(coll.evaluate(cfg, memory=anchors)[5], axis=1)
    assert anchors.n == 4 and tc.m == 4
    if regime == "stick":
        assert np.all(speed < V_STICK) and np.all(deflection > 0.1 * np.sin(theta) * 9.81 / (4 * K_STICK))
    else:
        assert np.all(speed > 10 * V_STICK) and np.all(deflection > 0.0)
    data = K.kernel_for(system, sim.formulation)
    assert data is not None, K.kernel_coverage(system, sim.formulation)[1]
    _assert_rhs_equal(system, sim.formulation, data, s)
    _assert_rhs_equal(system, sim.formulation, data, s.replace(element_memory=(None,) * len(system.forces)))


SHAPES_ON_A_FLOOR = """[sim]\nt_end = 0.4\ndt = 2e-4\noutput_dt = 0.01\nintegrator = "rk4"\n
[[bodies]]\nname = "ball"\nshape = { type = "sphere", radius = 0.05 }\ndensity = 1000.0\nposition = [0.0, 0.0, 0.06]
velocity = [0.3, 0.0, -0.5]\nomega = [0.0, 4.0, 0.0]\n
[[bodies]]\nname = "capsule"\nshape = { type = "capsule", radius = 0.03, height = 0.12 }\ndensity = 1000.0
position = [0.3, 0.0, 0.04]\neuler_deg = [0.0, 90.0, 0.0]\nvelocity = [0.0, 0.2, -0.3]\n
[[bodies]]\nname = "puck"\nshape = { type = "cylinder", radius = 0.05, height = 0.04 }\ndensity = 1000.0
position = [-0.3, 0.0, 0.06]\neuler_deg = [0.0, 30.0, 0.0]\nvelocity = [-0.2, 0.0, 0.0]\nomega = [0.0, 0.0, 8.0]\n
[[bodies]]\nname = "block"\nshape = { type = "box", extents = [0.10, 0.08, 0.06] }\ndensity = 1000.0
position = [0.0, 0.3, 0.05]\neuler_deg = [20.0, 10.0, 0.0]\nvelocity = [0.0, 0.0, -0.2]\n
[collision]
groups = { ball = ["ball"], others = ["capsule", "puck", "block"] }
[[collision.ground]]\ntype = "plane"\nnormal = [0.05, 0.0, 1.0]
[[collision.pairs]]\ngroups = ["ball", "ground"]\nlaw = "hertz"\ndamping = 2.0\nmaterial1 = { E = 1e7, nu = 0.3 }
friction = "stribeck"\nmu = 0.3\nmu_static = 0.5\nstribeck_speed = 0.01\nviscous = 0.1\nslip_speed = 1e-3
[[collision.pairs]]\ngroups = ["others", "ground"]\nlaw = "hunt_crossley"\nstiffness = 2e4\nexponent = 1.0
damping_factor = 0.5\nfriction = "coulomb"\nmu = 0.4\nslip_speed = 1e-3
"""


def test_rhs_equals_numpy_on_every_shape_against_a_plane(tmp_path):
    """Sphere (Hertz from the materials), capsule (two end spheres), cylinder (rim points) and box
    (corners) bouncing on a tilted plane with Stribeck and Coulomb friction, at states where several
    of them touch."""
    scene, system, state = _load(tmp_path, SHAPES_ON_A_FLOOR)
    sim = _simulation(scene, system, state, compiled=False)
    data = K.kernel_for(system, sim.formulation)
    assert data is not None, K.kernel_coverage(system, sim.formulation)[1]
    _, coll = _collisions(system)
    touching = set()
    for _ in range(20):
        s = sim.steps(50)
        tc = coll.detect(body_state(system, s.q, s.v, s.chart, s.t))
        touching |= {int(b) for b in tc.body[:, 0]}
        _assert_rhs_equal(system, sim.formulation, data, s)
    assert touching == {0, 1, 2, 3}, touching


HOIST = Path(__file__).resolve().parents[2] / "scenes" / "anchor_hoist.toml"


#: The hoist starts with the anchor on its +-30 deg pin stop exactly: the stop's coordinate is 7e-18 rad
#: against its limit 0, where the stop's damping switches on (``JointStop.effort``: delta > 0), and the
#: two paths compute that coordinate differently at round-off, so one damps the anchor's first swing
#: and the other does not (6e-5 m/s after a step). The comparisons move the limit this far [rad] off
#: the tie; the stop then acts only where the anchor swings onto it.
STOP_SHIFT = 1e-9


def _hoist():
    import dataclasses

    from viz3d.forces import JointStop

    scene = viz3d.load_scene(HOIST, list(HOIST_RK4))  # (the compiled RK4 against NumPy)
    system, state = build(scene)
    forces = tuple(dataclasses.replace(e, upper=e.upper + STOP_SHIFT, lower=e.lower - STOP_SHIFT)
                   if isinstance(e, JointStop) else e for e in system.forces)
    return scene, dataclasses.replace(system, forces=forces), state


def test_rhs_equals_numpy_on_the_anchor_hoist():
    """Chain links (capsules) and the anchor's hulls (convex) on the bow's triangle meshes, Flores with
    Hertz stiffness and bristle friction: at the start (anchors just planted) and after 0.1 s of haul
    (anchors carried along, some contacts new)."""
    scene, system, state = _hoist()
    s, sim = _numpy_state(scene, system, state, 1)
    data = K.kernel_for(system, sim.formulation)
    assert data is not None, K.kernel_coverage(system, sim.formulation)[1]
    k, coll = _collisions(system)
    _assert_rhs_equal(system, sim.formulation, data, s)
    s = sim.steps(200)
    cfg = body_state(system, s.q, s.v, s.chart, s.t)
    tc = coll.detect(cfg)
    matched = coll.match(cfg, tc, s.element_memory[k])
    assert tc.m >= 2 and np.any(matched >= 0), (tc.m, matched)
    assert {system.forces[k].shapes[i].kind for i in tc.shape[:, 0]} >= {"capsule"}
    _assert_rhs_equal(system, sim.formulation, data, s)


# ---------------------------------------------------------------------------- whole runs


def _anchors_equal(a, b, where: str, tol: float):
    """Two ``StickAnchors`` hold the same anchors, in any order: each matched by its shapes and marks."""
    assert a.n == b.n, f"{where}: {a.n} anchors against {b.n}"
    used = set()
    for i in range(a.n):
        same = [j for j in range(b.n) if j not in used and np.array_equal(a.shape[i], b.shape[j])]
        assert same, f"{where}: anchor {i} of shapes {a.shape[i]} has no partner"
        j = min(same, key=lambda j: np.abs(a.mark[i] - b.mark[j]).max())
        used.add(j)
        assert np.abs(a.mark[i] - b.mark[j]).max() <= tol, f"{where}: mark {i}"
        assert np.abs(a.anchor[i] - b.anchor[j]).max() <= tol, f"{where}: anchor {i}"


def _runs(scene, system, state, frames: int, every: int):
    """The states after each of ``frames`` output frames of ``every`` steps, kernel and NumPy, and each
    frame's tolerance on the difference of their ``y`` (module docstring)."""
    out = []
    eps = np.finfo(float).eps
    sq, sv = (np.random.default_rng(2).choice([-1.0, 1.0], size=x.shape) for x in (state.q, state.v))
    perturbed = state.replace(q=state.q * (1 + eps * sq), v=state.v * (1 + eps * sv))
    for compiled, start in ((True, state), (False, state), (False, perturbed)):
        sim = _simulation(scene, system, start, compiled)
        assert sim.kernel_note == ("compiled kernel" if compiled else "NumPy path (compiled = false)"), sim.kernel_note
        got = []
        while len(got) < frames:
            got += sim.output_states(frames - len(got), every) if compiled else [sim.steps(every)]
        out.append(got)
    kernel, numpy_, perturbed = out
    tol = [ROUNDOFF_FACTOR * max(np.abs(p.y - b.y).max(), (f + 1) * every * eps * np.abs(b.y).max())
           for f, (p, b) in enumerate(zip(perturbed, numpy_))]
    return kernel, numpy_, tol


def _contacts_at(system, coll, s) -> int:
    return coll.detect(body_state(system, s.q, s.v, s.chart, s.t)).m


@pytest.mark.parametrize("case", ["drop_and_slide", "launch_and_stop"])
def test_rk4_run_equals_numpy_with_bristle_friction(tmp_path, case):
    """A box dropped 2 mm onto a 35 deg incline (touch-down, bounce, slip) or launched at 0.5 m/s on a
    level floor (slip, then stick): trajectory and stick anchors after every frame."""
    if case == "drop_and_slide":
        text = _scene(np.radians(35), BRISTLE, 1.0, lift=2e-3)
    else:
        text = _scene(0.0, BRISTLE, 1.0).replace("inertia", "velocity = [0.5, 0.0, 0.0]\ninertia")
    scene, system, state = _load(tmp_path, text)
    k, coll = _collisions(system)
    kernel, numpy_, tol = _runs(scene, system, state, 40, 50)  # 2000 steps, 0.4 s
    counts = [_contacts_at(system, coll, s) for s in numpy_]
    for a, b, tol_y in zip(kernel, numpy_, tol):
        assert a.t == b.t
        assert np.abs(a.y - b.y).max() <= tol_y, f"t = {a.t}: y off by {np.abs(a.y - b.y).max():.3g} (tol {tol_y:.3g})"
        _anchors_equal(a.element_memory[k], b.element_memory[k], f"t = {a.t}", max(ANCHOR_TOL, tol_y))
    if case == "drop_and_slide":
        assert counts[0] == 0 and max(counts) == 4, counts  # the contacts start during the run
        assert np.linalg.norm(numpy_[-1].v[:3]) > 0.5  # sliding
    else:
        assert np.abs(numpy_[-1].v[:3]).max() < V_STICK  # stopped, held by the bristles


def test_rk4_run_equals_numpy_while_contacts_start_and_end(tmp_path):
    """Four shapes bouncing on a plane (Hertz, Hunt-Crossley, Stribeck, Coulomb): the contact sets
    change (each body's count goes up and down to zero); trajectory after every frame."""
    scene, system, state = _load(tmp_path, SHAPES_ON_A_FLOOR)
    _, coll = _collisions(system)
    kernel, numpy_, tol = _runs(scene, system, state, 40, 50)
    ended = False
    last = None
    assert tol[0] < 1e-11  # (before any contact: held to round-off)
    for a, b, tol_y in zip(kernel, numpy_, tol):
        assert np.abs(a.y - b.y).max() <= tol_y, f"t = {a.t}: y off by {np.abs(a.y - b.y).max():.3g} (tol {tol_y:.3g})"
        tc = coll.detect(body_state(system, b.q, b.v, b.chart, b.t))
        bodies = set(tc.body[:, 0].tolist())
        ended |= last is not None and bool(last - bodies)
        last = bodies
    assert ended, "no body left the plane during the run"


def test_rk4_run_equals_numpy_on_the_anchor_hoist():
    """The anchor hoist's first 0.2 s (400 steps), trajectory and stick anchors after every frame."""
    scene, system, state = _hoist()
    k, _ = _collisions(system)
    kernel, numpy_, tol = _runs(scene, system, state, 8, 50)
    for a, b, tol_y in zip(kernel, numpy_, tol):
        assert np.abs(a.y - b.y).max() <= tol_y, f"t = {a.t}: y off by {np.abs(a.y - b.y).max():.3g} (tol {tol_y:.3g})"
        assert a.element_memory[k].n > 0
        _anchors_equal(a.element_memory[k], b.element_memory[k], f"t = {a.t}", max(ANCHOR_TOL, tol_y))


# ---------------------------------------------------------------------------- ALI3-P, and what stays on NumPy


@pytest.mark.slow  # compiles ALI3-P with shape contacts (~2 min of CPU cold): over the default suite's budget
def test_ali3p_holds_the_shape_contacts_and_renews_the_anchors_in_the_kernel(tmp_path):
    """ALI3-P with shape contacts and bristles runs in the kernel (``viz3d.kernel.ali3p``: the contacts held
    within a step, the anchors renewed after each step of its output frames): after two frames of five
    steps the state is within ``ali3p_agreement_bound`` of the NumPy path's, with the same anchors."""
    from kernel_runs import ali3p_agreement_bound

    scene, system, state = _load(tmp_path, _scene(0.0, BRISTLE, 0.01, method="ali3p"))
    cfg = scene.data["sim"]
    sim = _simulation(scene, system, state, compiled=True)
    assert sim.kernel_note == "compiled kernel" and sim.batches_frames
    end = sim.output_states(2, 5)[-1]
    ref = _simulation(scene, system, state, compiled=False)
    ref.steps(10)
    bound = ali3p_agreement_bound(system, state, make_formulation(cfg), 10, cfg["dt"])
    diff = np.abs(end.y - ref.state.y).max()
    assert diff <= bound, f"y after 10 steps: {diff:.2e} > {bound:.2e}"
    k, _ = _collisions(system)
    assert end.element_memory[k].n > 0
    _anchors_equal(end.element_memory[k], ref.state.element_memory[k], f"t = {end.t}", max(ANCHOR_TOL, bound))


def test_shape_pairs_without_a_compiled_narrow_phase_take_the_numpy_path_and_say_why(tmp_path):
    """Two boxes (or, where the narrow phase covers them, a box on a triangle mesh): a pair of shape kinds
    the compiled narrow phase does not cover runs on NumPy, and the note names the kinds."""
    from viz3d.contact import narrowphase

    pairs = [("box", "box"), ("box", "mesh"), ("cylinder", "mesh"), ("cylinder", "cylinder")]
    uncovered = [p for p in pairs if not narrowphase.covered(*p)]
    if not uncovered:
        pytest.skip("the narrow phase covers every pair kind tried")
    a, b = uncovered[0]
    ramp = (Path(__file__).resolve().parents[2] / "scenes" / "meshes" / "ramp.stl").as_posix()
    ground = ({"box": 'type = "box"\nextents = [1.0, 1.0, 0.1]\nposition = [0.0, 0.0, -0.05]',
               "cylinder": 'type = "cylinder"\nradius = 0.5\nheight = 0.1\nposition = [0.0, 0.0, -0.05]',
               "mesh": f'type = "mesh"\nfile = "{ramp}"'})[b]
    shape = {"box": 'type = "box", extents = [0.1, 0.1, 0.1]', "cylinder": 'type = "cylinder", radius = 0.05, height = 0.1'}[a]
    text = f"""[sim]\nt_end = 0.01\ndt = 1e-3\nintegrator = "rk4"\n
[[bodies]]\nname = "b"\nshape = {{ {shape} }}\nmass = 1.0\ninertia = [0.01, 0.01, 0.01]\nposition = [0.0, 0.0, 0.3]\n
[collision]
[[collision.ground]]\nname = "g"\n{ground}
[[collision.pairs]]\ngroups = ["bodies", "ground"]\nlaw = "linear"\nstiffness = 1e5
"""
    scene, system, state = _load(tmp_path, text)
    sim = _simulation(scene, system, state, compiled=True)
    assert sim.kernel_note.startswith("NumPy path") and f"{a!r} and {b!r}" in sim.kernel_note, sim.kernel_note
    sim.steps(3)


def test_only_systems_with_shape_contacts_carry_their_packed_data(tmp_path):
    """The shape contacts' packed data (``CollisionItems``: some 75 arrays, all passed at every call of
    the compiled field that takes the force elements) is in the kernel's tuples only for a system that
    has shape contacts (``Items.present_only``): a torque-free body's data holds none, and nothing to
    renew after a step (``memories`` None: the law contacts' stick anchors are the adaptive driver's
    ``replants``, not compiled into the other entries); the bristle box's holds it for forces,
    energies and memory."""
    from viz3d.formulation import Projection
    from viz3d.kernel.collisions import CollisionItems

    def classes(data):
        return [{type(d) for d in packed} for packed in (data.forces, data.energies, data.memories or ())]

    plain = K.kernel_for(build(viz3d.load_scene(Path(__file__).resolve().parents[2] / "scenes" / "torque_free.toml"))[0],
                         Projection())
    assert not any(CollisionItems in c for c in classes(plain)) and plain.memories is None
    scene, system, state = _load(tmp_path, _scene(0.0, BRISTLE, 0.01))
    assert all(CollisionItems in c for c in classes(K.kernel_for(system, Projection())))

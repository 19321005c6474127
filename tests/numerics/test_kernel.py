"""The compiled kernel computes what the NumPy reference computes, to round-off."""

import numpy as np
import pytest

import viz3d
from viz3d import kernel as K
from viz3d.dynamics import VectorField
from viz3d.formulation import Projection
from viz3d.integrators import make_integrator
from viz3d.integrators.tableaus import RK4
from viz3d.scene.build import build, make_formulation
from viz3d.simulate import Simulation, simulate_built

from conftest import SCENES, scene_files

#: The kernel evaluates the NumPy formulas in another order: they may differ by the computation's round-off,
#: eps times its condition number, which _roundoff measures as the NumPy result's change under relative
#: perturbations of eps of the state (max of SENSITIVITY_SAMPLES); allowed: this many times that.
#: (Seen: differences 0.03-0.7 of it, e.g. 1.4e-12 of 1.9e-12 on the stiff spring, whose k (l - l0) cancels.)
ROUNDOFF_FACTOR = 10.0
SENSITIVITY_SAMPLES = 4
#: After 300 RK4 steps of 5e-4 s, positions [m]: per-step differences of the right-hand side at most ~1e-12
#: relative (above) move positions by ~300 dt |v| 1e-12 ~ 1e-13 m; 1e-10 leaves 1e3 for the flow's growth
#: through a chart switch [seen ~1e-14].
STEP_TOL = 1e-10

#: Scenes of rigid bodies written as ordinary scenes (the impact shorthand has no sim.formulation key),
#: without shape contacts (tests/numerics/test_kernel_collisions.py has those: SHAPE_CONTACTS).
RIGID = [p for p in scene_files() if "[impactor]" not in p.read_text()
         and all(b["type"] == "rigid" for b in viz3d.load_scene(p).data["bodies"])
         and "collision" not in viz3d.load_scene(p).data]
SHAPE_CONTACTS = [p for p in scene_files() if "collision" in viz3d.load_scene(p).data]


@pytest.mark.parametrize("path", SHAPE_CONTACTS, ids=lambda p: p.stem)
def test_shape_contact_scenes_take_the_kernel_or_name_the_missing_narrow_phase(path):
    _, system, state, form = _setup(path)
    data, why = K.kernel_coverage(system, form)
    assert data is not None or "narrow phase" in why, why


def test_a_system_is_packed_once_for_all_its_runs():
    # build packs the model for the scene's formulation and keeps it with the system (a system without
    # joints: no initial projection packs it); runs of it reuse that packing (another formulation has
    # its own) and give the same trajectory each time.
    scene = viz3d.load_scene(SCENES / "torque_free.toml", {"sim.t_end": 0.05})
    system, state = viz3d.build(scene)
    form = make_formulation(scene.data["sim"])
    packed = dict(system.derived)  # (what build kept)
    data = K.kernel_for(system, form)
    assert data is not None and data in (v[0] for v in packed.values()), "build packs the model"
    assert K.kernel_for(system, make_formulation(scene.data["sim"])) is data
    assert K.kernel_for(system, make_formulation({**scene.data["sim"], "formulation": "baumgarte"})) is not data
    first, again = simulate_built(scene, system, state), simulate_built(scene, system, state)
    assert first.ok and again.n_steps == first.n_steps and again.n_rhs == first.n_rhs
    for name in ("t", "position", "rotation", "velocity", "omega", "energy_total"):
        assert np.array_equal(getattr(first, name), getattr(again, name)), name


@pytest.mark.parametrize("path", SHAPE_CONTACTS[:1], ids=lambda p: p.stem)
def test_shape_contacts_are_packed_for_each_run(path):
    # Their packed data holds each run's scratch and stick anchors: never shared.
    _, system, _, form = _setup(path)
    a, b = K.kernel_for(system, form), K.kernel_for(system, form)
    assert a is not None, K.kernel_coverage(system, form)[1]
    assert a is not b and K.kernel_for(system, form) is not a


def _setup(path, formulation="index1", overrides=None):
    scene = viz3d.load_scene(path, {"sim.formulation": formulation, **(overrides or {})})
    system, state = viz3d.build(scene)
    return scene, system, state, make_formulation(scene.data["sim"])


@pytest.mark.parametrize("formulation", ["index1", "baumgarte"])
@pytest.mark.parametrize("path", RIGID, ids=lambda p: p.stem)
def test_kernel_rhs_equals_numpy_rhs(path, formulation):
    _, system, state, form = _setup(path, formulation)
    data = K.kernel_for(system, form)
    assert data is not None
    y = state.y + 1e-3 * np.random.default_rng(0).normal(size=state.y.shape)
    if path.stem == "stiff_contact":  # put the ball 10 um into the floor, moving: the contact is active
        y[2] = 0.02 - 1e-5
    rhs = VectorField(system, form, state.chart)
    ref = rhs(0.37, y)
    out = K.kernel_rhs(data, 0.37, y, state.chart)
    assert np.abs(out - ref).max() <= ROUNDOFF_FACTOR * _roundoff(rhs, y, ref), "mismatch: rhs"


def _roundoff(rhs, y, ref, t=0.37):
    """Round-off scale of ``rhs`` at ``(t, y)``: max |rhs(t (1 + eps s_0), y (1 + eps s)) - rhs(t, y)| over
    random signs (s_0, s), at least eps |rhs|. The time is perturbed too: a drive's prescribed motion
    r(t) enters the rows (on the slider-crank, 1.3e-13 of an angular acceleration of 1.2e-7 comes from
    t alone; the positions' perturbations move it by 1e-22)."""
    eps = np.finfo(float).eps
    signs = np.random.default_rng(1).choice([-1.0, 1.0], size=(SENSITIVITY_SAMPLES, len(y) + 1))
    change = max(np.abs(rhs(t * (1 + eps * s[0]), y * (1 + eps * s[1:])) - ref).max() for s in signs)
    return max(change, eps * np.abs(ref).max())


#: Whole runs on both paths (below): the flow may amplify the right-hand side's differences by this
#: much over the run. The elastic modes oscillate (no growth of a perturbation's energy), the
#: mechanisms' kinematics are smooth away from their dead points: O(1), with 100 to spare [seen: 7e-15
#: and 1e-14 against bounds of 6e-11 and 3e-11].
RUN_GROWTH = 100.0


@pytest.mark.parametrize("scene", ["flexible_four_bar.toml", "flexible_slider_crank.toml"])
def test_flexible_mechanisms_run_on_the_kernel_as_on_the_numpy_path(scene):
    """Framed joints (revolute, universal) with sides on sections of flexible links: the kernel runs
    them, and the states of a run (adaptive dopri5, 10 samples of 1 ms) agree with the NumPy path's.
    Each evaluation may differ by ROUNDOFF_FACTOR times the right-hand side's round-off rho (measured
    as above, the largest over the NumPy path's samples); a dopri5 step adds h sum(b) = h times that,
    so over the run each entry of y differs by at most t_end ROUNDOFF_FACTOR rho, times the flow's
    growth RUN_GROWTH. The step-size controller sees error estimates that differ by about as little:
    the same steps are accepted and rejected. (These links bend in the mechanisms' plane: their
    sections turn about the joints' axes, where the turn's terms vanish; those are compared on random
    states in test_kernel_elements.)"""
    from viz3d.scene.build import make_controller, make_integrator_from

    t_end, n = 0.01, 10
    scene_ = viz3d.load_scene(SCENES / scene, {"sim.dt": t_end / n})
    cfg = scene_.data["sim"]
    sims = [Simulation(*viz3d.build(scene_), make_integrator_from(cfg), make_formulation(cfg), cfg["dt"],
                       controller=make_controller(cfg), compiled=compiled) for compiled in (True, False)]
    assert sims[0].kernel_note == "compiled kernel" and sims[1].kernel_note.startswith("NumPy path")
    states = [[sim.step() for _ in range(n)] for sim in sims]
    assert (sims[0].n_steps, sims[0].n_rejected, sims[0].n_rhs) == (sims[1].n_steps, sims[1].n_rejected, sims[1].n_rhs)
    fields = [(VectorField(sims[1].system, sims[1].formulation, s.chart), s) for s in states[1][::3]]
    rho = max(_roundoff(rhs, s.y, rhs(s.t, s.y), t=s.t) for rhs, s in fields)
    bound = RUN_GROWTH * t_end * ROUNDOFF_FACTOR * rho
    diff = max(np.abs(a.y - b.y).max() for a, b in zip(*states))
    assert diff <= bound, f"kernel and NumPy runs differ by {diff:.3g} (bound {bound:.3g})"


#: Outputs of those runs (below): the states agree to the bound above (< 1e-10), and joint angles,
#: rates, gauges and drive efforts are functions of them with derivatives of order 1 (angles of unit
#: axes; rates linear in the velocities; the effort a multiplier of a well-conditioned solve):
#: 1e-9, relative to each output's scale, leaves 10 for those derivatives.
OUTPUT_TOL = 1e-9


@pytest.mark.parametrize("scene", ["flexible_four_bar.toml", "flexible_slider_crank.toml"])
def test_flexible_mechanisms_outputs_sampled_in_the_kernel_equal_the_numpy_frames(scene):
    """Was: frames sampled in the kernel left the coordinates of joint sets with a joint on a
    flexible section NaN (the crank angle of the four-bar, whose main bearing shares its set with the
    rocker's pivot), where the NumPy frames had them. Every output agrees and is finite."""
    overrides = ["sim.t_end=0.01", "sim.output_dt=0.001"]
    a, b = (viz3d.simulate(SCENES / scene, overrides=overrides + [f"sim.compiled={c}"]) for c in ("true", "false"))
    assert a.scene["run"]["kernel"] == "compiled kernel" and b.scene["run"]["kernel"].startswith("NumPy path")
    keys = [k for k in ("joint_coordinates", "joint_coordinate_rates", "gauge_strain", "deflection", "drive_effort")
            if k in b.extras and np.size(b.extras[k])]
    assert "joint_coordinates" in keys and list(a.extras["joint_coordinate_names"]) == list(b.extras["joint_coordinate_names"])
    for key in keys:
        x, y = np.asarray(a.extras[key], float), np.asarray(b.extras[key], float)
        assert x.shape == y.shape and np.isfinite(x).all() and np.isfinite(y).all(), key
        assert np.abs(x - y).max() <= OUTPUT_TOL * max(1.0, np.abs(y).max()), key


def test_kernel_steps_equal_numpy_steps_through_chart_switches():
    _, system, state, form = _setup(SCENES / "top_through_vertical.toml")
    sim = Simulation(system, state, make_integrator("rk4"), form, 5e-4)
    for _ in range(300):
        sim.step()
    data = K.kernel_for(system, form)
    y, chart, switches = state.y.copy(), state.chart.copy(), np.zeros(system.n_bodies, np.int64)
    done, status = K.kernel_advance(data, RK4, 300, 0.0, 5e-4, y, chart, switches, 1e4)
    assert (done, status) == (300, K.OK)
    assert switches.sum() == sim.chart_switches.sum() >= 1
    R_np = system.rotation.matrix(system.split_q(sim.state.q)[1], sim.state.chart)
    R_k = system.rotation.matrix(system.split_q(y[: system.n_q])[1], chart)
    assert np.abs(R_np - R_k).max() < STEP_TOL
    assert np.abs(system.split_q(sim.state.q)[0] - system.split_q(y[: system.n_q])[0]).max() < STEP_TOL


def test_no_steps_leave_the_state_as_it_was_and_repeated_calls_continue_one_run():
    """``KernelStepper.step`` runs ``advance_frames`` as one frame of n steps: n = 0 steps nothing (that
    entry's ``every = 0`` samples given states instead: called so, it wrote into empty sample buffers),
    and a run taken in calls of 120 and 180 steps is the run of 300 taken at once, to the bit (the top is
    autonomous: the steps' times, summed differently, do not enter)."""
    _, system, state, form = _setup(SCENES / "top_through_vertical.toml")
    data = K.kernel_for(system, form)
    stepper = K.KernelStepper(data, RK4)
    y, chart, switches = state.y.copy(), state.chart.copy(), np.zeros(system.n_bodies, np.int64)
    assert stepper.step(0.0, 5e-4, y, chart, switches, 1e4, 0) == (0, K.OK)
    np.testing.assert_array_equal(y, state.y)
    np.testing.assert_array_equal(chart, state.chart)
    assert stepper.step(0.0, 5e-4, y, chart, switches, 1e4, 120) == (120, K.OK)
    assert stepper.step(120 * 5e-4, 5e-4, y, chart, switches, 1e4, 180) == (180, K.OK)
    y1, chart1, switches1 = state.y.copy(), state.chart.copy(), np.zeros(system.n_bodies, np.int64)
    assert K.kernel_advance(data, RK4, 300, 0.0, 5e-4, y1, chart1, switches1, 1e4) == (300, K.OK)
    np.testing.assert_array_equal(y, y1)
    np.testing.assert_array_equal(chart, chart1)
    np.testing.assert_array_equal(switches, switches1)


def test_kernel_reports_failures():
    _, system, state, form = _setup(SCENES / "top_through_vertical.toml", overrides={"sim.rotation": "euler_zxz"})
    data = K.kernel_for(system, form)
    y, chart = state.y.copy(), state.chart.copy()
    done, status = K.kernel_advance(data, RK4, 20000, 0.0, 5e-4, y, chart, np.zeros(1, np.int64), 1e4)
    assert status in (K.ROTATION, K.NONFINITE, K.SPEED) and done < 20000


def test_kernel_declines_what_it_does_not_cover():
    _, system, _, form = _setup(SCENES / "flexible_pendulum.toml", "ali3p")
    assert K.kernel_for(system, form) is None
    assert K.kernel_coverage(system, form)[1] == "ALI3-P with flexible bodies"


@pytest.mark.parametrize("rotation", ["euler_switching", "euler_zxz"])
def test_many_steps_in_one_call_equal_single_steps_and_fail_at_the_same_step(rotation):
    """``Simulation.steps(n)`` (one kernel call) against n ``step()`` calls: the same states, step
    counts and chart switches, and with plain Euler angles the same diagnosis at the same time."""
    from viz3d.diagnosis import SimulationFailure

    _, system, state, form = _setup(SCENES / "top_through_vertical.toml", overrides={"sim.rotation": rotation})
    runs = []
    for batched in (True, False):
        sim = Simulation(system, state, make_integrator("rk4"), form, 5e-4)
        status = "ok"
        try:
            for _ in range(30):
                sim.steps(20) if batched else [sim.step() for _ in range(20)]
        except SimulationFailure as exc:
            status = str(exc)
        runs.append((sim, status))
    (a, status_a), (b, status_b) = runs
    assert status_a == status_b
    assert (a.n_samples, a.n_steps) == (b.n_samples, b.n_steps)
    # a batch that fails is redone up to the failing step: those evaluations are counted too
    assert a.n_rhs == b.n_rhs if status_a == "ok" else a.n_rhs > b.n_rhs
    assert np.array_equal(a.chart_switches, b.chart_switches)
    assert a.state.t == b.state.t and np.array_equal(a.state.y, b.state.y)
    if rotation == "euler_zxz":
        assert "gimbal lock" in status_a and a.n_samples < 600, status_a
    else:
        assert status_a == "ok" and a.chart_switches.sum() >= 1


def test_fixed_steps_with_contacts_locate_every_event_on_the_compiled_path(tmp_path):
    """Was: fixed RK4 steps through the compiled kernel ran many steps in one call and never looked
    at the contacts, so a ball fell through a flexible beam with `ok` (0 contacts where the NumPy
    path finds the first one). Both paths now locate the same contact and give the same force, to
    the kernel's round-off grown over the run (STEP_TOL)."""
    text = (SCENES / "ball_on_flexible_beam.toml").read_text()
    fixed = tmp_path / "ball_on_beam_fixed_steps.toml"
    fixed.write_text("\n".join(line for line in text.splitlines() if not line.startswith(("rtol", "atol"))))
    runs = {}
    for compiled in (True, False):
        scene = viz3d.load_scene(fixed, {"sim.integrator": "rk4", "sim.dt": 5e-6, "sim.output_dt": 5e-5,
                                              "sim.t_end": 0.0205, "sim.compiled": compiled})
        runs[compiled] = viz3d.simulate(scene)
    for tr in runs.values():
        assert tr.ok, tr.status
        assert len(tr.extras["contacts"]) == 1
    a, b = (runs[c].extras for c in (True, False))
    np.testing.assert_allclose(a["contacts"], b["contacts"], rtol=STEP_TOL, atol=STEP_TOL)
    np.testing.assert_allclose(a["contact_force"], b["contact_force"], rtol=STEP_TOL, atol=STEP_TOL * np.abs(b["contact_force"]).max())


@pytest.mark.parametrize("rotation", ["euler_switching", "euler_zxz", "quaternion"])
def test_compiled_state_check_passes_exactly_what_check_state_passes(rotation):
    """Adaptive steps skip the NumPy ``check_state`` when the compiled ``state_ok`` passes: it must
    never pass a state the NumPy check refuses (non-finite values, speed, turn per step, plain Euler
    angles at the pole; Euler parameters of any norm), and pass the ordinary ones. Random states,
    half of them broken one way."""
    from viz3d.diagnosis import SimulationFailure, check_state

    scene = viz3d.load_scene(SCENES / "chain.toml", {"chain.n": 3, "sim.rotation": rotation})
    system, state = viz3d.build(scene)
    stepper = K.KernelStepper(K.kernel_for(system, make_formulation(scene.data["sim"])), None)
    rng = np.random.default_rng(5)
    nq, nf, nqb = system.n_q, system.n_frames, system.n_q_body
    outcomes = set()
    for trial in range(400):
        y = state.y.copy()
        y[:nq] += rng.normal(scale=2.0, size=nq)
        y[nq:nq + system.n_v] = rng.normal(scale=3.0, size=system.n_v)
        h = 10.0 ** rng.uniform(-4, -0.5)
        f = rng.integers(nf)
        kind = trial % 8
        if kind == 1:
            y[rng.integers(nq + system.n_v)] = rng.choice([np.nan, np.inf])
        elif kind == 2:
            y[nq + 6 * f] = 2e4  # beyond the speed limit below
        elif kind == 3 and rotation == "quaternion":
            y[nqb * f + 3:nqb * f + 7] *= 10.0 ** rng.uniform(-3, 3)  # p's rates scale with |p|
        elif kind == 3:
            y[nqb * f + 4] = rng.choice([0.0, np.pi, 1e-13, -1e-13])  # at the pole
        elif kind == 4 and rotation != "quaternion":
            y[nqb * f + 4] = -abs(y[nqb * f + 4])  # negative sin(theta): the signed rate map
        s = state.replace(q=y[:nq], v=y[nq:nq + system.n_v])
        try:
            with np.errstate(all="ignore"):  # the rate map divides by sin(theta) = 0 at the pole
                check_state(system, s, 1e4, h)
            numpy_ok = True
        except SimulationFailure:
            numpy_ok = False
        assert stepper.state_ok(s.y, h, 1e4) == numpy_ok, (trial, kind)
        outcomes.add(numpy_ok)
    assert outcomes == {True, False}


@pytest.mark.parametrize("scene,overrides", [
    ("top_through_vertical.toml", ["sim.rotation=euler_switching"]),   # chart switches inside the batches
    ("top_through_vertical.toml", ["sim.rotation=euler_zxz", "sim.formulation=index1"]),  # fails at gimbal lock mid-batch
    ("chain.toml", ["chain.n=5", "sim.formulation=projection"]),
    ("robot_arm.toml", ["sim.formulation=projection", "sim.t_end=2.0", "sim.output_dt=0.003"]),  # a sine drive: C(q, t); 3 chunks
], ids=["switching", "gimbal_lock", "chain_projection", "robot_arm"])
def test_a_run_without_sinks_takes_its_frames_in_batches_with_the_same_result(scene, overrides):
    """A headless run advances a chunk of output frames per kernel call (``Simulation.output_states``);
    with a sink it goes one frame per call. Same frames bit for bit, same status and diagnosis, same
    counters (a failed batch is redone up to the failure: its evaluations count, so only more)."""
    from viz3d.sink import NullSink

    path = SCENES / scene
    a = viz3d.simulate(path, overrides=overrides + ["sim.dt=5e-4"])
    b = viz3d.simulate(path, overrides=overrides + ["sim.dt=5e-4"], sinks=[NullSink()])
    assert a.status == b.status
    assert len(a.t) == len(b.t) > 3
    for key in ("t", "position", "rotation", "velocity", "omega", "energy_kinetic", "energy_potential",
                "constraint_violation"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    assert np.array_equal(a.chart_switches, b.chart_switches) and a.n_steps == b.n_steps
    assert a.n_rhs == b.n_rhs if a.status == "ok" else a.n_rhs >= b.n_rhs
    if "sim.rotation=euler_zxz" in overrides:
        assert "gimbal lock" in a.status


def test_an_entry_that_accepted_its_arguments_is_found_without_typing_them(monkeypatch):
    """A dispatcher holding no signature yet: the entry for the arguments' types is loaded or compiled,
    typed without numba's ``typeof`` of an array (``_argument_type``: numba's imports numpy.ma, some
    10 ms of a run's start). Holding one signature that has just taken the arguments: that signature
    is theirs, found without typing; holding two, the arguments are typed, and each finds its own."""
    numba = pytest.importorskip("numba")
    total = numba.njit(lambda a: a.sum())
    x, k = np.arange(3.0), np.arange(3)
    monkeypatch.setattr(total, "typeof_pyval", lambda a: pytest.fail("typed by numba"))
    entry = K._typed_entry(total, (x,))
    assert list(total.overloads) == [(numba.typeof(x),)] and entry is total.overloads[(numba.typeof(x),)].entry_point
    assert entry(x) == 3.0
    assert K._typed_entry(total, (x,), accepted=True)(x) == 3.0
    monkeypatch.undo()
    total(k)
    for a in (x, k):
        entry = K._typed_entry(total, (a,), accepted=True)
        assert entry is total.overloads[(numba.typeof(a),)].entry_point
    assert K._typed_entry(total, (x,), accepted=True) is not K._typed_entry(total, (k,), accepted=True)


def test_the_kernels_own_typing_of_its_arguments_is_numbas():
    """``_argument_type`` gives what numba's ``typeof`` gives (the signature a call would have been
    compiled for, and the key of the entry in numba's cache): the packed data of a top on a ball joint
    and of a chain (named tuples of arrays, tuples of them, None), arrays of every layout, dtype and
    writability, and numbers."""
    numba = pytest.importorskip("numba")
    d = numba.njit(lambda a: a)
    values = []
    for name in ("heavy_top", "chain"):
        system, _ = build(viz3d.load_scene(SCENES / f"{name}.toml"))
        data = K.kernel_for(system, Projection(1e-12))
        values += [getattr(data, f) for f in K.DATA_TUPLES] + list(K.KernelStepper(data, None).ws)
    a = np.arange(12.0).reshape(3, 4)
    readonly = a.copy()
    readonly.flags.writeable = False
    values += [a, a.T, a[:, ::2], a[0], readonly, np.zeros((0, 3)), np.zeros(2, np.int64), np.zeros(2, bool),
               np.zeros((2, 3, 3)), np.float64(2.0), 1.5, 3, True, None, (a, 1.0), (a, a), ()]
    for v in values:
        assert K._argument_type(d, v) == numba.typeof(v), v
def test_compiled_entries_are_found_once_per_argument_types_and_are_the_right_ones(monkeypatch):
    """Runs of scenes interleaved (a top on RK4; a spring on gen_alpha, whose run calls other compiled
    entries): after the first run of each, their compiled entries are found without numba's typing,
    and they give exactly what numba's own dispatch at every call gives."""
    scenes = [viz3d.load_scene(SCENES / "heavy_top.toml", {"sim.dt": 1e-3}),
              viz3d.load_scene(SCENES / "stiff_spring.toml", {"sim.dt": 1e-4}),
              viz3d.load_scene(SCENES / "heavy_top.toml", {"sim.dt": 1e-3})]
    runs = [viz3d.simulate(s, t_end=0.05) for s in scenes]
    typed = []
    typeof = K._typed_entry
    monkeypatch.setattr(K, "_typed_entry", lambda d, a, accepted=False: typed.append(d) or typeof(d, a, accepted))
    again = [viz3d.simulate(s, t_end=0.05) for s in scenes]
    assert typed == []
    monkeypatch.setattr(K, "_entry_point", lambda d, a, fingerprint=None, accepted=False: d)  # numba's own dispatch
    direct = [viz3d.simulate(s, t_end=0.05) for s in scenes]
    for a, b, c in zip(runs, again, direct):
        for name in ("position", "rotation", "omega", "reaction_force"):
            assert a.ok and np.array_equal(getattr(a, name), getattr(b, name)), name
            assert np.array_equal(getattr(a, name), getattr(c, name)), name

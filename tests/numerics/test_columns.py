"""Output frames sampled in the compiled kernel, a chunk at a time (``viz3d.columns``), equal the
NumPy reference frames (``viz3d.frames.frame_from_state`` with nothing from the kernel) to round-off,
on every shipped scene: rigid chains and their reactions, springs, law and kinematic contacts in and
out of touch (their forces, stored and dissipated energy), flexible bodies and gauges."""

from dataclasses import fields

import numpy as np
import pytest

import viz3d
from viz3d.columns import FrameColumns, StateLog
from viz3d.frames import frame_from_state
from viz3d.scene.build import make_controller, make_formulation, make_integrator_from
from viz3d.simulate import Simulation

from conftest import SCENES, scene_files

#: As in test_kernel: the two evaluate the same formulas in another order; their difference is
#: bounded by the computation's round-off, measured as the reference's change when the state is
#: perturbed by eps (relative, random signs); allowed this many times that, and at least
#: FLOOR_ULPS ulps of the largest entry of the quantity.
ROUNDOFF_FACTOR = 10.0
FLOOR_ULPS = 64
#: States compared per scene: every state with a contact acting, and this many more spread over the run.
SPREAD = 12
FIELDS = ("W_r", "R_WB", "W_v", "W_omega", "energy_kinetic", "energy_potential", "constraint_violation",
          "reaction_force")


def _run(path):
    scene = viz3d.load_scene(path)
    system, state = viz3d.build(scene)
    cfg = scene.data["sim"]
    sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"], cfg["blowup_speed"],
                     make_controller(cfg))
    if sim.kernel_sampler() is None:
        pytest.skip(f"{path.stem}: {sim.kernel_note}")
    t_end = min(cfg["t_end"], 0.12)  # past the first touch of every shipped contact scene
    states = [sim.state]
    while sim.state.t < t_end - 1e-12:
        sim.step()
        states += sim.drain_events(sim.state.t)
        states.append(sim.state)
    return sim, states


def _touching(sim, state) -> bool:
    if not sim.system.contacts:
        return False
    g = sim.kernel_sampler().gaps(state.t, state.y, state.chart)
    return bool((g[:, 0] > 0).any() or any(p.touching for ph in state.memory for p in ph))


def _reference(sim, states) -> FrameColumns:
    frames = [frame_from_state(sim.system, sim.formulation, s, (), sim.reference_energy) for s in states]
    return FrameColumns.from_frames(frames, sim.system.n_bodies, len(sim.system.joint_names))


def _perturbed(state, rng):
    eps = np.finfo(float).eps
    n_q, n_v = state.q.size, state.v.size
    y = state.y * (1 + eps * rng.choice([-1.0, 1.0], state.y.size))
    return state.replace(q=y[:n_q], v=y[n_q:n_q + n_v], w=y[n_q + n_v:])


SCENE_PATHS = scene_files()  # multibody scenes


@pytest.mark.parametrize("path", SCENE_PATHS, ids=lambda p: p.stem)
def test_sampled_frames_equal_the_numpy_frames(path):
    sim, states = _run(path)
    touching = [i for i, s in enumerate(states) if _touching(sim, s)]
    spread = np.linspace(0, len(states) - 1, SPREAD).round().astype(int).tolist()
    pick = sorted(set(touching + spread))
    chosen = [states[i] for i in pick]
    log = StateLog(sim)
    for s in chosen:
        log.record(s)
    got = log.columns()
    ref = _reference(sim, chosen)
    rng = np.random.default_rng(0)
    moved = [_reference(sim, [_perturbed(s, rng) for s in chosen]) for _ in range(2)]
    np.testing.assert_array_equal(got.t, ref.t)
    for name in FIELDS:
        _close(name, getattr(got, name), getattr(ref, name), [getattr(m, name) for m in moved], _scale(name, ref))
    assert set(got.scalars) == set(ref.scalars), set(got.scalars) ^ set(ref.scalars)
    for key in ref.scalars:
        _close(key, got.scalars[key], ref.scalars[key], [m.scalars[key] for m in moved], _scale(key, ref))
    if sim.system.contacts:
        assert touching, "no state with a contact acting: the contact path was not compared"


def _scale(name: str, ref: FrameColumns) -> float:
    """The magnitude whose round-off bounds quantity ``name``: differences of larger terms carry
    theirs (energies and the ledger's balance: every energy term; an indentation: the positions
    it subtracts), other quantities their own largest entry."""
    own = getattr(ref, name) if hasattr(ref, name) else ref.scalars[name]
    if name.startswith("energy"):
        terms = [ref.energy_kinetic, ref.energy_potential] + [v for k, v in ref.scalars.items() if k.startswith("energy/")]
        return float(np.max(np.sum([np.abs(x) for x in terms], axis=0)))
    if name.endswith("indentation"):
        return float(np.abs(ref.W_r).max() + np.abs(own).max())
    return float(np.abs(own).max(initial=0.0))


def _close(name, got, ref, moved, scale):
    """|got - ref| within the round-off bound, per frame (the first axis)."""
    assert got.shape == ref.shape, (name, got.shape, ref.shape)
    if not ref.size:
        return
    axes = tuple(range(1, ref.ndim))
    change = np.max([np.abs(m - ref).max(axis=axes) if axes else np.abs(m - ref) for m in moved], axis=0)
    floor = FLOOR_ULPS * np.finfo(float).eps * max(scale, np.finfo(float).tiny)
    bound = ROUNDOFF_FACTOR * np.maximum(change, floor)
    err = np.abs(got - ref).max(axis=axes) if axes else np.abs(got - ref)
    worst = int(np.argmax(err / bound))
    assert np.all(err <= bound), f"{name}: frame {worst} differs by {err[worst]:.3g} (> {bound[worst]:.3g})"


def test_a_check_that_fails_keeps_the_frames_up_to_the_failing_one():
    """A chunk whose check fails at its frame i keeps frames 0..i (the failing frame is the last)."""
    sim, states = _run(SCENES / "double_pendulum.toml")

    class Failure(Exception):
        frame = 4

    def check(cols, chunk):
        raise Failure()

    log = StateLog(sim, check)
    with pytest.raises(Failure):
        for s in states[:10]:
            log.record(s)
        log.flush()
    cols = log.columns(check=False)
    np.testing.assert_array_equal(cols.t, [s.t for s in states[:5]])


DRAWN = ("joint_points", "springs", "contact_points", "contact_forces")
#: Scenes whose frames draw joints, springs, contacts acting and deformed bars.
#: Scenes and what their frames must draw (the comparison is not empty).
DRAWING_SCENES = {"robot_arm": ("joint_points", "springs"), "flexible_four_bar": ("joint_points", "deformed", "stress"),
                  "bouncing_sphere": ("contact_points", "contact_forces"),
                  "pendulum_strikes_bar": ("joint_points", "deformed", "contact_points")}


@pytest.mark.parametrize("name", DRAWING_SCENES)
def test_sampled_drawings_equal_the_numpy_drawings(name):
    """The drawing of a frame built from the kernel's samples (``columns.frame_of``) equals the
    NumPy reference's (``frame_from_state``) to round-off, as the columns do."""
    from viz3d.columns import chunk_frames
    from viz3d.scene.visuals import flexible_drawings

    sim, states = _run(SCENES / f"{name}.toml")
    drawings = flexible_drawings(viz3d.load_scene(SCENES / f"{name}.toml"), sim.system)
    pick = sorted(set(np.linspace(0, len(states) - 1, SPREAD).round().astype(int).tolist()
                      + [i for i, s in enumerate(states) if _touching(sim, s)]))
    chosen = [states[i] for i in pick]
    _, frame_at = chunk_frames(sim, chosen, drawings)
    got = [frame_at(i).drawing for i in range(len(chosen))]
    rng = np.random.default_rng(1)
    ref, *moved = [[frame_from_state(sim.system, sim.formulation, s, drawings, sim.reference_energy).drawing
                    for s in batch] for batch in [chosen] + [[_perturbed(s, rng) for s in chosen] for _ in range(2)]]
    keys = list(DRAWN) + [f"deformed/{d.name}" for d in drawings] + [f"stress/{d.name}" for d in drawings
                                                                      if d.stress_rows is not None]

    def value(drawing, key):
        kind, _, sub = key.partition("/")
        return getattr(drawing, kind)[sub].astype(float) if sub else getattr(drawing, kind)

    def rows(drawings_, key):  # every frame's items (joints, contacts acting, vertices), one after another
        return np.concatenate([value(d, key) for d in drawings_])

    def moved_rows(m, key):  # a perturbed state at a touch's onset may draw a contact the state does not:
        return rows([d if value(d, key).shape == value(r, key).shape else r for d, r in zip(m, ref)], key)  # no estimate there

    for key in keys:
        assert [value(d, key).shape for d in got] == [value(d, key).shape for d in ref], f"{key}: other items drawn"
    drawn = {key: rows(ref, key) for key in keys}
    assert set(DRAWING_SCENES[name]) <= {k.partition("/")[0] for k, v in drawn.items() if v.size}, "not drawn"
    for key in keys:
        _close(key, rows(got, key), drawn[key], [moved_rows(m, key) for m in moved], float(np.abs(drawn[key]).max(initial=0.0)))


def test_an_interrupt_during_a_chunks_check_leaves_its_states_to_the_last_flush():
    """Ctrl-C while a chunk is checked: the interrupt waits for the check, the chunk's states stay
    pending, and the run's last (unchecked) flush keeps them: frames up to the stop."""
    import signal

    from viz3d.interrupts import InterruptGuard

    sim, states = _run(SCENES / "double_pendulum.toml")

    def check(cols, chunk):
        signal.raise_signal(signal.SIGINT)

    with InterruptGuard() as guard:
        log = StateLog(sim, check, hold=guard.held)
        for s in states[:10]:
            log.record(s)
        with pytest.raises(KeyboardInterrupt):
            log.flush()
        cols = log.columns(check=False)
    np.testing.assert_array_equal(cols.t, [s.t for s in states[:10]])


def test_a_chunk_keeps_the_samples_its_batch_was_stepped_with(monkeypatch):
    """A run's first chunk joins its first state (recorded before any step, without the kernel's
    samples) to frames the kernel sampled as it stepped them: only that state is sampled again (one
    ``KernelStepper.sample`` of one state), not the whole chunk, and the trajectory is the one of
    the whole chunk sampled again, bit for bit."""
    from viz3d.kernel import KernelStepper

    scene = viz3d.load_scene(SCENES / "chain.toml", ["chain.n=3", "sim.t_end=0.5"])
    sampled = []
    sample = KernelStepper.sample

    def counted(self, ts, *args):
        sampled.append(len(ts))
        return sample(self, ts, *args)

    monkeypatch.setattr(KernelStepper, "sample", counted)
    kept = viz3d.simulate(scene)
    assert sampled == [1], sampled
    monkeypatch.setattr(StateLog, "_sampled_pieces", lambda self: self.pieces)
    again = viz3d.simulate(scene)
    assert sampled[1:] == [len(again.t)], sampled
    for name in ("t", "position", "rotation", "velocity", "omega", "energy_kinetic", "energy_potential",
                 "constraint_violation", "reaction_force"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(again, name), err_msg=name)


#: (scene, overrides) run in chunks: the kernel's batched fixed steps (quaternions, projection) and
#: its adaptive steps, each over several chunks of ``CHUNK``.
CHUNKED = {"torque_free": ["sim.integrator=rk4", "sim.formulation=projection", "sim.rotation=quaternion",
                           "sim.dt=0.0025", "sim.output_dt=0.01", "sim.t_end=6"],
           "chain": ["chain.n=2", "sim.integrator=dop853", "sim.formulation=projection", "sim.dt=0.01",
                     "sim.rtol=1e-6", "sim.atol=1e-9", "sim.t_end=6"]}


def _chunks(monkeypatch, scene) -> tuple:
    """The trajectory of ``scene`` and the chunks its frames were computed in: (States, FrameColumns,
    the kernel's samples) each."""
    from viz3d import columns

    chunks = []
    sampled = columns._sampled

    def kept(sim, stepper, states):
        cols, s = sampled(sim, stepper, states)
        chunks.append((states, cols, s))
        return cols, s

    monkeypatch.setattr(columns, "_sampled", kept)
    traj = viz3d.simulate(scene)
    monkeypatch.setattr(columns, "_sampled", sampled)
    return traj, chunks


@pytest.mark.parametrize("name", CHUNKED)
def test_the_chunk_length_changes_nothing_in_the_run(monkeypatch, name):
    """A small system's run in one long chunk (``columns.chunk_length``) is its run in chunks of
    ``CHUNK`` (no byte allowance), bit for bit."""
    from viz3d import columns
    from viz3d.trajectory import ARRAY_FIELDS

    scene = viz3d.load_scene(SCENES / f"{name}.toml", CHUNKED[name])
    long, in_long = _chunks(monkeypatch, scene)
    monkeypatch.setattr(columns, "CHUNK_BYTES", 0)
    short, in_short = _chunks(monkeypatch, scene)
    assert len(long.t) > 2 * columns.CHUNK and len(in_long) == 1 and len(in_short) == -(-len(short.t) // columns.CHUNK)
    for key in ARRAY_FIELDS + ("status", "n_steps", "n_rhs"):
        np.testing.assert_array_equal(getattr(long, key), getattr(short, key), err_msg=key)
    assert long.extras.keys() == short.extras.keys()
    for key in long.extras:
        np.testing.assert_array_equal(long.extras[key], short.extras[key], err_msg=key)


@pytest.mark.parametrize("name", CHUNKED)
def test_a_chunk_holds_at_most_chunk_bytes(monkeypatch, name):
    """A full chunk longer than ``CHUNK`` (``columns.chunk_length``) holds at most ``CHUNK_BYTES`` of
    the kernel's samples, states and columns (all of their arrays, views counted again)."""
    from viz3d import columns

    monkeypatch.setattr(columns, "CHUNK_BYTES", 2**20)  # (chunks of 1365 and 510 frames)
    _, chunks = _chunks(monkeypatch, viz3d.load_scene(SCENES / f"{name}.toml", CHUNKED[name] + ["sim.t_end=20"]))
    states, cols, samples = chunks[0]
    assert len(states) > columns.CHUNK and len(chunks) > 1  # (a full chunk, over the minimum)
    held = (sum(a.nbytes for a in samples) + states.t.nbytes + states.Y.nbytes + states.chart.nbytes
            + sum(getattr(cols, f.name).nbytes for f in fields(cols) if f.name != "scalars")
            + sum(a.nbytes for a in cols.scalars.values()))
    assert held <= columns.CHUNK_BYTES, f"{held} bytes"


def test_frames_many_steps_apart_keep_chunks_of_chunk():
    """Frames ``CHUNK_STEPS / CHUNK`` steps apart or more come ``CHUNK`` at a time (a kernel call, which
    Ctrl-C waits for, takes no more steps than before); closer ones as many as take ``CHUNK_STEPS``,
    within ``CHUNK_BYTES``."""
    from viz3d import columns

    system, _ = viz3d.build(viz3d.load_scene(SCENES / "torque_free.toml"))
    far = columns.CHUNK_STEPS // columns.CHUNK
    assert columns.chunk_length(system, far) == columns.chunk_length(system, 100 * far) == columns.CHUNK
    assert columns.chunk_length(system, 4) == columns.CHUNK_STEPS // 4 < columns.chunk_length(system, 1)

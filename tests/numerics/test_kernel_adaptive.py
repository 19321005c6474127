"""The compiled adaptive driver (viz3d.kernel.adaptive) against the Python adaptive loop it replaces
(``Simulation._adaptive_samples`` / ``_event_steps``, still the path of the step after each contact
event, during law contacts with stateful friction and at failures): the same accepted and rejected
steps, evaluations, contact events (located by both, the driver's cut at the same time), chart
switches, contact memory and diagnoses, and the same states to round-off.

The two paths run the same compiled stages, and the kernel adds the controller's error norm in
numpy's order (``pairwise_sum``), so the steps agree to the last bit; only the dense output (a
polynomial of degree <= 7 summed in another order) and the NumPy projection and chart switch of the
Python path round differently.
"""

import dataclasses
import importlib
import math
import re
import tomllib

import numpy as np
import pytest

import viz3d
from viz3d.compiled import numba
from viz3d.events import ContactStepping
from viz3d.integrators.adaptive import Controller
from viz3d.kernel import KernelStepper
from viz3d.kernel.adaptive import pairwise_sum
from viz3d.scene.build import make_controller, make_formulation, make_integrator_from
from viz3d.scene.load import with_sim
from viz3d.simulate import Simulation, run

from conftest import SCENES

EPS = np.finfo(float).eps
#: A number in an event's text.
NUMBER = r"[-+]?\d+(\.\d*)?(e[-+]?\d+)?"
njit = numba.njit if numba is not None else (lambda fn: fn)
#: Round-off of a dense-output sample, relative to the largest value of the quantity over the run:
#: the two paths sum the (degree + 1) <= 8 terms of the step's polynomial in different orders, a
#: rounding per term each (the terms are at most the size of the state: they add up to the change
#: over a step), twice: 2 x 8 eps; and once more for the frame quantities computed from the state.
SAMPLE_ROUNDOFF = 3 * 8 * EPS
#: The Python path's NumPy projection and chart switch round differently from the compiled ones, and
#: the next steps carry that on: a difference of a few eps of the state, grown over the steps of a
#: short run (measured growth of a difference over 0.2 s of the flexible pendulum < 10).
STEPPED_ROUNDOFF = 100 * SAMPLE_ROUNDOFF
#: The heavy top (spherical joint off its centre of mass, Euler chart switches) with DOPRI5 at a
#: tolerance at which each step drifts off the joint by far more than round-off.
HEAVY_TOP_PROJECTION = ("sim.integrator=dopri5", "sim.formulation=projection", "sim.rtol=1e-5", "sim.atol=1e-7",
                        "sim.dt=0.01")
#: Scenes with shipped adaptive settings whose runs the kernel covers, and a short t_end [s]: a few
#: contact events each (flight, onset, law contact in the compiled driver, separation), or a swing.
SCENES_T_END = {"pendulum_strikes_bar": 4e-4, "impact_bronze_ball": 4e-4, "impact_free_bar": 1.6e-4,
                "bouncing_sphere": 0.08, "flexible_pendulum": 0.2, "ball_on_flexible_beam": 0.024}


def _run(name, t_end: float, compiled_driver: bool, overrides=(), controller: Controller | None = None,
         blowup_speed: float | None = None, monkeypatch=None, python_steps: list | None = None,
         handled: list | None = None):
    """A headless run (``simulate.run``) through the compiled adaptive driver or the Python adaptive loop;
    ``(sim, trajectory, kernel calls)``; the steps the Python loop takes with contacts
    (``Simulation._event_step``) counted into ``python_steps``, the contact events handled
    (``Simulation._handle_event``) into ``handled``. ``name``: a shipped scene or a path."""
    path = name if not isinstance(name, str) else SCENES / f"{name}.toml"
    scene = with_sim(viz3d.load_scene(path, list(overrides)), t_end=t_end)
    system, state = viz3d.build(scene)
    cfg = scene.data["sim"]
    sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"],
                     blowup_speed or cfg["blowup_speed"], controller or make_controller(cfg))
    calls = []
    adaptive = KernelStepper.adaptive
    monkeypatch.setattr(KernelStepper, "adaptive", lambda self, *a, **k: calls.append(1) or adaptive(self, *a, **k))
    event_step = Simulation._event_step
    counted = python_steps if python_steps is not None else []
    monkeypatch.setattr(Simulation, "_event_step", lambda self, *a: counted.append(1) or event_step(self, *a))
    handle = Simulation._handle_event
    events = handled if handled is not None else []
    monkeypatch.setattr(Simulation, "_handle_event", lambda self, *a: events.append(1) or handle(self, *a))
    if not compiled_driver:
        monkeypatch.setattr(Simulation, "_adaptive_kernel_covers", lambda self: False)
    traj = run(sim, scene)
    monkeypatch.undo()
    return sim, traj, len(calls)


def _assert_same_run(a, b, tol_factor):
    (sa, ta, calls), (sb, tb, calls_python) = a, b
    assert calls > 0 and calls_python == 0
    assert ta.status == tb.status
    assert (sa.n_steps, sa.n_rejected, sa.n_rhs) == (sb.n_steps, sb.n_rejected, sb.n_rhs), "mismatch: step counts"
    assert np.array_equal(sa.chart_switches, sb.chart_switches), "mismatch: chart switches"
    # frame times are on the grid or at events, located on the step's polynomial: its round-off
    np.testing.assert_allclose(ta.t, tb.t, rtol=tol_factor, atol=0, err_msg="mismatch: t")
    for field in ("position", "velocity", "omega", "euler"):
        x, y = getattr(ta, field), getattr(tb, field)
        bound = tol_factor * max(np.abs(y).max(), EPS)
        assert np.abs(x - y).max() <= bound, f"mismatch: {field}: {np.abs(x - y).max():.2e} > {bound:.2e}"
    if sb.contacts is not None:
        # the events' kinds and order (their texts without numbers: a separation speed is 0 to round-off,
        # 1.7e-16 m/s one way, 4.6e-69 m/s the other on impact_free_bar); their times below
        kinds = [[re.sub(NUMBER, "#", text) for _, text in log] for log in (sa.contacts.log, sb.contacts.log)]
        assert kinds[0] == kinds[1], "mismatch: events"
        t_a, t_b = np.array([t for t, _ in sa.contacts.log]), np.array([t for t, _ in sb.contacts.log])
        np.testing.assert_allclose(t_a, t_b, rtol=tol_factor, atol=0, err_msg="mismatch: event times")
        _assert_same_memory(sa, sb, tol_factor)


def _assert_same_memory(sa, sb, tol_factor):
    """The contacts' memory at the last accepted step: phases, law memory and onset records alike, the
    counts exactly, the sums over the contact's steps (error estimates of ``alpha_dot``, energy the
    numerics may have created, the balance after the last step) to round-off of the largest."""
    for sim in (sa, sb):
        sim._to_python()
    for phases_a, phases_b in zip(sa._inner.memory, sb._inner.memory, strict=True):
        for pa, pb in zip(phases_a, phases_b, strict=True):
            assert (pa.touching, pa.touches, pa.anchor is None) == (pb.touching, pb.touches, pb.anchor is None), \
                "mismatch: contact phase"
            if pa.anchor is not None:  # (B's axes, about the size of the body: round-off of that)
                np.testing.assert_allclose(pa.anchor, pb.anchor, rtol=0, atol=tol_factor * max(np.abs(pb.anchor).max(), EPS),
                                           err_msg="mismatch: stick anchor")
            assert (pa.onset is None) == (pb.onset is None), "mismatch: onset"
            if pa.onset is None:
                continue
            a, b = dataclasses.asdict(pa.onset), dataclasses.asdict(pb.onset)
            assert a["n_steps"] == b["n_steps"] and a["number"] == b["number"], "mismatch: steps of the contact"
            for key in ("velocity_error", "energy_error", "balance_now"):
                bound = tol_factor * max(abs(b[key]), abs(b["energy"]), EPS)
                if key == "energy_error" and sb.controller is None:
                    bound = max(bound, _summed_roundoff(b))
                assert abs(a[key] - b[key]) <= bound, f"mismatch: onset.{key}: {a[key]!r} vs {b[key]!r}"


def _summed_roundoff(onset: dict) -> float:
    """Round-off [J] of a fixed-step contact's ``energy_error``: the sum over its ``n_steps`` steps of
    the change of the ledger's balance, each balance a sum of the ledger's energies rounded apart on
    the two paths (the driver's ledgers of all recorded steps at once, the Python loop's one at a
    time): 2 balances x 2 eps of the energies' size (at onset, with the balance since) per step."""
    size = sum(abs(onset[key]) for key in ("energy", "signed_potential", "dissipated", "work_in", "balance_now"))
    return onset["n_steps"] * 4 * EPS * size


@pytest.mark.parametrize("name", sorted(SCENES_T_END))
def test_compiled_adaptive_takes_the_python_steps(name, monkeypatch):
    """Each shipped adaptive scene the kernel covers: the same steps, rejections, evaluations, events,
    contact memory and states to round-off, with and without the compiled driver; the compiled
    driver takes the steps of the law contacts and cuts its steps at the events (Python only the
    step right after each)."""
    python_steps, handled = [], []
    a = _run(name, SCENES_T_END[name], True, monkeypatch=monkeypatch, python_steps=python_steps, handled=handled)
    b = _run(name, SCENES_T_END[name], False, monkeypatch=monkeypatch)
    if name == "flexible_pendulum":
        assert a[0].n_rejected > 0  # the controller has rejections to reproduce
    else:
        assert len(b[0].contacts.log) >= 2  # contact events, located both ways
        # each event: the next step (its events start at a root); the one cut at it is the driver's
        assert len(python_steps) <= len(handled), f"{len(python_steps)} steps in Python, {len(handled)} events"
    # the scenes' default formulation projects after every step (a no-op without constraint rows)
    _assert_same_run(a, b, STEPPED_ROUNDOFF if a[0].formulation.name == "projection" else SAMPLE_ROUNDOFF)


@pytest.mark.parametrize("name, t_end, overrides, tol", [
    ("flexible_pendulum", 0.2, ("sim.integrator=dop853",), SAMPLE_ROUNDOFF),
    ("flexible_pendulum", 0.2, ("sim.formulation=projection",), STEPPED_ROUNDOFF),
    ("heavy_top", 1.0, HEAVY_TOP_PROJECTION, STEPPED_ROUNDOFF),
    ("flexible_pendulum", 0.2, ("sim.formulation=baumgarte",), SAMPLE_ROUNDOFF),
    # Euler parameters, normalised after each step and at each sample (NumPy and compiled round apart)
    ("flexible_pendulum", 0.2, ("sim.rotation=quaternion", "sim.formulation=index1"), STEPPED_ROUNDOFF),
    ("heavy_top", 1.0, HEAVY_TOP_PROJECTION + ("sim.rotation=quaternion",), STEPPED_ROUNDOFF),
    # a loose tolerance: the law contact's step bound (ContactStepping.step_bound) sets its steps
    ("bouncing_sphere", 0.08, ("sim.rtol=1e-3",), SAMPLE_ROUNDOFF)])
def test_compiled_adaptive_methods_and_formulations(name, t_end, overrides, tol, monkeypatch):
    """DOP853 (its continuous extension costs three evaluations per sampled step), the projection
    formulation (projected after every step and at every sample: the flexible pendulum's pin is
    linear in the coordinates, which the steps keep to round-off; the heavy top's spherical joint
    at a loose tolerance is not) and Baumgarte."""
    a = _run(name, t_end, True, overrides, monkeypatch=monkeypatch)
    b = _run(name, t_end, False, overrides, monkeypatch=monkeypatch)
    _assert_same_run(a, b, tol)
    if "sim.formulation=projection" in overrides:  # the state the next step starts from is on the joints
        tol_C = a[0].formulation.tol
        for sim in (a[0], b[0]):
            assert _inner_violation(sim) <= tol_C, f"max |C| at the last accepted step {_inner_violation(sim):.2e} m"


def _inner_violation(sim) -> float:
    """max |C| [m] at a run's last accepted step (ahead of its last sample: the adaptive state, handed
    back to the Python loop first when the kernel has it)."""
    sim._to_python()
    s = sim._inner
    return float(np.abs(sim._kernel.solved_rows(s.t, s.y, s.chart, s.memory)[1]).max())


#: rolling_ball on an adaptive method: a linear law contact from the start, regularised Coulomb friction
#: (no memory), the step bound of the law contact.
ROLLING = ("sim.integrator=dopri5", "sim.rtol=1e-6")


def test_law_contact_with_friction_in_the_compiled_driver(monkeypatch):
    """A rolling ball in contact throughout: every step in the compiled driver, its contact's books
    (steps, error sums) kept from the recorded steps as the Python loop keeps them after each step."""
    python_steps = []
    a = _run("rolling_ball", 0.05, True, ROLLING, monkeypatch=monkeypatch, python_steps=python_steps)
    b = _run("rolling_ball", 0.05, False, ROLLING, monkeypatch=monkeypatch)
    assert not python_steps and b[0].n_steps > 100
    assert b[0]._inner.memory[0][0].onset.n_steps == b[0].n_steps  # every step counted in the contact
    _assert_same_run(a, b, SAMPLE_ROUNDOFF)


def test_stateful_friction_steps_in_the_compiled_driver(monkeypatch, tmp_path):
    """Bristle friction moves its stick anchors after each step (``ContactStepping._replant``; in the
    driver the law contacts' ``replant_piece``), which changes the force: the driver moves them as
    the Python loop does, drops the field it would carry over when one moved, and records them for
    the books; the same steps, evaluations, anchors and states to round-off."""
    text = (SCENES / "rolling_ball.toml").read_text()
    path = tmp_path / "bristle_ball.toml"
    path.write_text(text.replace('friction = "coulomb"', 'friction = "bristle"\nmu_static = 0.06\nstick_speed = 1e-3\n'
                                                          'stick_stiffness = 1e4\nstick_damping = 200')
                    .replace("mu = 0.5", "mu = 0.05"))  # (it slides: the bristles break away every step)
    python_steps, moved = [], []
    anchors_moved = ContactStepping.anchors_moved
    monkeypatch.setattr(ContactStepping, "anchors_moved",
                        staticmethod(lambda a, b: moved.append(anchors_moved(a, b)) or moved[-1]))
    b = _run(path, 0.02, False, ROLLING, monkeypatch=monkeypatch)
    a = _run(path, 0.02, True, ROLLING, monkeypatch=monkeypatch, python_steps=python_steps)
    assert sum(moved) > 10, "the anchors must move on the Python loop's steps for the comparison to mean something"
    assert a[0]._inner.memory[0][0].anchor is not None and not python_steps  # in contact throughout: all in the driver
    _assert_same_run(a, b, SAMPLE_ROUNDOFF)


def test_contact_energies_of_a_calls_steps_are_each_steps(monkeypatch):
    """The ledgers of a driver call's recorded steps take the contacts' elastic energies of all the
    steps at once (``ContactSet.elastic_energy`` over a leading axis of states, each with its own
    stick anchors): on coin_drop's landing (48 contacts, Hertz with bristles whose anchors move)
    each step's equals the one-state call with that step's anchors in its phases, to the round-off
    of the energies (a power may round apart in numpy's array and scalar loops, by an ulp)."""
    from viz3d.contact.contacts import ContactSet, Gap
    from viz3d.events import anchor_rows, with_anchors
    from viz3d.kinematics import Pose

    energy, seen = ContactSet.elastic_energy, {"rows": 0, "moved": 0, "bristle": 0}

    def checked(self, cfg, phases, gp=None, pose=None, anchors=None):
        U = energy(self, cfg, phases, gp, pose, anchors)
        if gp is None or gp.alpha.ndim == 1:
            return U
        own = self.anchor_table(phases)
        for r in range(gp.alpha.shape[0]):
            phases_r = phases if anchors is None else tuple(
                p if p.anchor is None else dataclasses.replace(p, anchor=tuple(float(x) for x in anchors[r, i]))
                for i, p in enumerate(phases))
            gap_r = Gap(*(getattr(gp, f.name)[r] for f in dataclasses.fields(Gap)))
            one = energy(self, None, phases_r, gap_r, Pose(pose.W_r[r], pose.R_WB[r]))
            assert np.all(np.abs(U[r] - one) <= 4 * np.finfo(float).eps * np.abs(one)), (r, U[r] - one)
            seen["rows"] += 1
            seen["moved"] += anchors is not None and not np.array_equal(anchors[r], own, equal_nan=True)
            seen["bristle"] += any(p.anchor is not None and p.touching for p in phases) and bool(np.any(one > 0.0))
        return U

    ledgers = ContactStepping.ledgers

    def anchored(self, ts, Y, charts, memory, mems=None):  # each step's anchors: its memory's (``with_anchors``)
        for r in range(0 if mems is None else ts.shape[0]):
            memory_r = with_anchors(memory, mems[r], self._k0)
            for c, x, phases, phases_r in zip(self.system.contacts, self.kernel.data.contact_slices, memory, memory_r):
                np.testing.assert_array_equal(anchor_rows(c.anchor_table(phases), mems[r:r + 1, x])[0],
                                              c.anchor_table(phases_r))
        return ledgers(self, ts, Y, charts, memory, mems)

    monkeypatch.setattr(ContactSet, "elastic_energy", checked)
    monkeypatch.setattr(ContactStepping, "ledgers", anchored)
    sim, traj, _ = _run("coin_drop", 0.12, True, monkeypatch=monkeypatch)
    assert traj.ok and seen["rows"] > 100 and seen["moved"] > 10 and seen["bristle"] > 10, seen


#: Fixed-step runs with contacts (no controller: ``viz3d.integrators.adaptive.FixedSteps`` in the
#: driver), a scene, its t_end [s] and overrides: the box's four corners touch from the start (law
#: contacts with regularised Coulomb friction, the contacts' step bound below dt); the rolling ball
#: is in contact throughout, five samples a frame; the pendulum strikes the flexible bar with RK4
#: (onset and separation located inside fixed steps, each sample reached by a shortened step after them);
#: the coin falls and lands on its rim (48 contacts with bristle friction: their stick anchors move).
FIXED_STEPS = {"box_on_incline": (0.05, ()), "coin_drop": (0.12, ()),
               "pendulum_strikes_bar": (4e-4, ("sim.integrator=rk4",)),
               "rolling_ball": (0.05, ("sim.output_dt=5e-4",))}


@pytest.mark.parametrize("name", sorted(FIXED_STEPS))
def test_fixed_steps_with_contacts_take_the_compiled_driver(name, monkeypatch, tmp_path):
    """Fixed steps with contact events, as the Python loop takes them (``Simulation._event_step``):
    the same steps (dt within the contacts' bound, shortened to land on each sample and cut at the
    events), evaluations, events and contact books, the states to round-off; the driver takes them
    all but the step right after each event."""
    t_end, overrides = FIXED_STEPS[name]
    path = tmp_path / f"{name}.toml"  # (without its adaptive settings)
    path.write_text("\n".join(line for line in (SCENES / f"{name}.toml").read_text().splitlines()
                              if not line.startswith(("rtol", "atol"))))
    python_steps, handled = [], []
    a = _run(path, t_end, True, overrides, monkeypatch=monkeypatch, python_steps=python_steps, handled=handled)
    b = _run(path, t_end, False, overrides, monkeypatch=monkeypatch)
    assert a[0].controller is None and b[0].n_steps > 100
    assert len(b[0].contacts.log) >= (2 if name == "pendulum_strikes_bar" else 1)
    assert len(python_steps) <= len(handled), f"{len(python_steps)} steps in Python, {len(handled)} events"
    _assert_same_run(a, b, SAMPLE_ROUNDOFF)


#: Five samples per output frame of rolling_ball (dt 0.1 ms).
FRAMES_OF_5 = ("sim.output_dt=5e-4",)


def test_full_step_records(monkeypatch):
    """Room for one step record per call (``STEP_RECORDS``): calls during the law contact stop at full
    records (``FULL``, inside a frame: the good frames kept, their records redone) and the next
    records twice as many; the run is the Python loop's."""
    import importlib

    with pytest.MonkeyPatch.context() as mp:  # (``viz3d.simulate`` the attribute is the function)
        mp.setattr(importlib.import_module("viz3d.simulate"), "STEP_RECORDS", 1)
        a = _run("rolling_ball", 0.05, True, ROLLING + FRAMES_OF_5, monkeypatch=monkeypatch)
    b = _run("rolling_ball", 0.05, False, ROLLING + FRAMES_OF_5, monkeypatch=monkeypatch)
    assert a[0]._capacity > 1
    _assert_same_run(a, b, SAMPLE_ROUNDOFF)


def test_failed_contact_check_in_recorded_steps_is_diagnosed_as_in_python(monkeypatch):
    """A contact check that fails on a step the compiled driver took (the bouncing ball of
    tests/impact/test_contact_resolution.py without the step bound: the energy check): the same
    diagnosis, after the same frames and steps, as the Python loop's."""
    from viz3d.events import ContactStepping

    coarse = ("sim.rtol=1e-3", "sim.output_dt=2e-5")  # (at 1e-1 the check fails on the step after onset: Python's)
    python_steps = []
    with pytest.MonkeyPatch.context() as mp:  # (``_run`` undoes its own ``monkeypatch`` after each run)
        mp.setattr(ContactStepping, "step_bound", lambda self, state: np.inf)
        mp.setattr(ContactStepping, "_restitution_check", lambda self, *a, **k: None)
        a = _run("bouncing_sphere", 0.4, True, coarse, monkeypatch=monkeypatch, python_steps=python_steps)
        b = _run("bouncing_sphere", 0.4, False, coarse, monkeypatch=monkeypatch)
    assert "created by the integration" in b[1].status
    assert len(python_steps) < b[0].n_steps
    _assert_same_run(a, b, SAMPLE_ROUNDOFF)
    assert len(a[1].t) == len(b[1].t), "mismatch: frames kept"


def test_the_samples_after_an_event_go_to_the_driver_in_one_call(monkeypatch):
    """After an event inside an output frame the rest of the frame is one driver call, each sample a
    frame of the call (``Simulation.steps``), not one call per sample: coin_drop's landing (100 samples
    a frame, its 48 contacts bound the steps to about 3 a sample). A call ends at an event (then
    Python handles it and the next call goes on), at the end of the frames it was asked for, or when
    its step records are full (``STEP_RECORDS`` records: at least a quarter of them in samples); per
    sample it took 107 calls to 0.1 s. Nor is a call's work thrown away when it is cut at an event
    inside an output frame (``output_states``: the samples one a frame of the call), which took
    17 054 driver steps for 12 542 to 0.4 s."""
    from viz3d.kernel.adaptive import STEPS
    from viz3d.simulate import STEP_RECORDS

    taken, adaptive = [], KernelStepper.adaptive  # (the steps of every call, kept or not)
    monkeypatch.setattr(KernelStepper, "adaptive",
                        lambda self, carry, *a, **k: (adaptive(self, carry, *a, **k), taken.append(int(carry.counts[STEPS])))[0])
    handled, python_steps = [], []
    sim, traj, calls = _run("coin_drop", 0.1, True, monkeypatch=monkeypatch, handled=handled, python_steps=python_steps)
    assert traj.ok and handled and sim.n_samples == 1000
    bound = 2 * len(handled) + len(traj.t) + sim.n_steps // (STEP_RECORDS // 4)
    assert calls <= bound, (calls, bound)
    assert sum(taken) + len(python_steps) == sim.n_steps, "no call's steps thrown away and taken again"


def test_events_inside_output_frames(monkeypatch):
    """Five samples per output frame: a call that stops at an event inside a frame keeps the frames
    before it only, and the Python loop takes the rest of that frame (the kernel's work on it is
    neither counted nor kept)."""
    a = _run("ball_on_flexible_beam", 0.024, True, ("sim.output_dt=5e-4",), monkeypatch=monkeypatch)
    b = _run("ball_on_flexible_beam", 0.024, False, ("sim.output_dt=5e-4",), monkeypatch=monkeypatch)
    assert len(b[0].contacts.log) >= 2
    _assert_same_run(a, b, SAMPLE_ROUNDOFF)


#: Scenes whose contact events the compiled driver locates, one of each kind: restitution impacts (an
#: impulse at each onset: ``alpha`` rising through 0), the kinematic contact of the free bar (its
#: separation on the multiplier), an elastoplastic law (its maximum indentation on ``alpha_dot``),
#: law contacts with DOP853 (no FSAL stage: the field at the event is one more evaluation), and the
#: text of the event each must log.
LOCATED = {"restitution": ("bouncing_sphere", 0.4, ("contact.law=restitution",), "impulse"),
           "kinematic": ("impact_free_bar", 1.6e-4, (), "contact end (separation"),
           "elastoplastic": ("bouncing_sphere", 0.08, ("contact.law=linear_plastic", "contact.yield_stress=0.64e9"),
                             "maximum indentation"),
           "dop853": ("ball_on_flexible_beam", 0.024, ("sim.integrator=dop853",), "contact end (separation")}


@pytest.mark.parametrize("kind", sorted(LOCATED))
def test_events_located_in_the_compiled_driver(kind, monkeypatch):
    """Every kind of event function: the compiled driver locates the event on the step's interpolant
    and cuts its step there (Python takes only the step after each event), with the same steps,
    evaluations, event times and contact memory as the Python loop."""
    name, t_end, overrides, text = LOCATED[kind]
    python_steps, handled = [], []
    a = _run(name, t_end, True, overrides, monkeypatch=monkeypatch, python_steps=python_steps, handled=handled)
    b = _run(name, t_end, False, overrides, monkeypatch=monkeypatch)
    assert any(text in line for _, line in a[0].contacts.log), f"no {text!r} event"
    assert handled and len(python_steps) <= len(handled), f"{len(python_steps)} steps in Python"
    _assert_same_run(a, b, STEPPED_ROUNDOFF if a[0].formulation.name == "projection" else SAMPLE_ROUNDOFF)


def test_impact_time_of_a_dropped_ball(monkeypatch):
    """The ball of bouncing_sphere, dropped from rest through ``h`` under its weight ``F`` (a load,
    no gravity field), meets the plate at ``sqrt(2 h m / F)``: the compiled driver's cut. The motion
    is quadratic in t, which DOPRI5 and the cubic Hermite interpolant reproduce, so the time is off
    by the root finder's tolerance only (``brentq`` stops with the root inside ``xtol + rtol t``,
    ``xtol`` relative to the step cut, which is shorter than the impact time) and the round-off of
    the gap (a few eps of ``h``) over the impact speed; the impact speed ``sqrt(2 h F / m)`` by the
    time's error times the acceleration."""
    from viz3d.integrators.adaptive import EVENT_RTOL, EVENT_XTOL

    python_steps, handled = [], []
    sim, traj, _ = _run("bouncing_sphere", 0.07, True, ("contact.law=restitution",), monkeypatch=monkeypatch,
                        python_steps=python_steps, handled=handled)
    impactor = tomllib.loads((SCENES / "bouncing_sphere.toml").read_text())["impactor"]
    m, F, h = (impactor[key] for key in ("mass", "force", "gap"))
    t_hit, v_hit = math.sqrt(2 * h * m / F), math.sqrt(2 * h * F / m)
    assert handled and len(python_steps) <= len(handled)  # cut in the driver (Python: the steps after events)
    bound = EVENT_XTOL * t_hit + EVENT_RTOL * t_hit + 8 * EPS * h / v_hit
    assert abs(sim.contacts.records[0].t_start - t_hit) <= bound, f"{sim.contacts.records[0].t_start - t_hit:.2e} s"
    # the speed at the located time: off by the acceleration F / m times the time's error
    assert abs(sim.contacts.records[0].approach - v_hit) <= F / m * bound + 8 * EPS * v_hit


#: Restitution coefficients and drop heights [m] of the bouncing ball without a step bound.
BOUNCES = [(0.5, 0.02), (0.5, 0.05), (0.8, 0.02), (0.8, 0.05)]
#: Bounces before the end of those runs (which end half-way through the next flight).
N_BOUNCES = 5
#: Rounding of a step's end position per unit of ``|r0| + |r1| + h |v0| + h |v1|``: the Hermite
#: form's ``CUBIC_ROUNDOFF`` eps, doubled for DOPRI5's stage sum (its weights' magnitudes add up to
#: 1.65 of the step's velocity).
STEP_ROUNDING = 16 * EPS


def _bounces(e: float, h0: float, a: float, n: int) -> list[tuple[float, float]]:
    """(time [s], approach speed [m/s]) of the first ``n`` bounces of a ball dropped from rest through
    ``h0`` under the acceleration ``a``, restitution ``e``: ``t_1 = sqrt(2 h0 / a)``, ``V_1 = a t_1``,
    ``t_(k+1) = t_k + 2 e V_k / a``, ``V_(k+1) = e V_k``."""
    t, V, out = math.sqrt(2 * h0 / a), math.sqrt(2 * a * h0), []
    for _ in range(n):
        out.append((t, V))
        V *= e
        t += 2 * V / a
    return out


def _bounce_time_bounds(e: float, a: float, located: list[float]) -> list[float]:
    """Bound of each located bounce's time error from the errors ``located`` [s] of locating each
    (first order). A bounce located late by ``d`` starts the next flight ``V d`` below the plate at
    ``e (V + nu + a d)`` (``nu``: the approach speed's error), so the next bounce is late by
    ``tau + 2 e nu / a + (1 + 2 e - 1/e) d`` and meets the plate at ``e nu + a (e - 1/e) d`` more
    than ``e V`` (terms in ``a d^2`` are far below rounding)."""
    tau, nu, out = 0.0, 0.0, []
    for d in located:
        out.append(tau + d)
        tau, nu = tau + 2 * e * nu / a + abs(1 + 2 * e - 1 / e) * d, e * nu + a * abs(e - 1 / e) * d
    return out


@pytest.mark.parametrize("e, h0", BOUNCES)
def test_bounce_times_of_a_dropped_ball_without_a_step_bound(e, h0, monkeypatch):
    """Was: bouncing_sphere with restitution and no sim.max_step found 2 bounces of 5 in 0.4 s (both
    paths). Free flight is exact for DOPRI5, so its steps grow until a whole flight (the gap
    negative, then positive, then negative again) fits in one, whose ends showed nothing. Now each
    bounce of ``_bounces`` before the end is found, by the Python loop and the compiled driver alike
    (the same steps and events), at its closed-form time within ``_bounce_time_bounds`` of what
    locating each may be off by: ``brentq``'s stop (``EVENT_XTOL`` of the step it was located in,
    recorded, plus ``EVENT_RTOL`` of the time) and the rounding of the gap over the approach speed
    (the interpolant's at the root, ``CUBIC_ROUNDOFF`` eps of its terms there, and what the state
    carries: ``STEP_ROUNDING`` of every step over the length it took, positions at most the largest
    at a step's start and speeds at most the first impact's up to the last bounce)."""
    from viz3d.integrators.adaptive import CUBIC_ROUNDOFF, EVENT_RTOL, EVENT_XTOL

    impactor = tomllib.loads((SCENES / "bouncing_sphere.toml").read_text())["impactor"]
    accel = impactor["force"] / impactor["mass"]  # its weight as a load, no gravity field
    bounces = _bounces(e, h0, accel, N_BOUNCES + 1)
    t_end = (bounces[-2][0] + bounces[-1][0]) / 2
    overrides = ("contact.law=restitution", f"contact.restitution={e}", f"impactor.gap={h0}")
    simulate_module = importlib.import_module("viz3d.simulate")
    locate, steps = simulate_module.first_event, []

    def recorded(*args):
        hit = locate(*args)
        t0, y0, f0, t1, y1, f1 = args[-7:-1]  # (..., t0, y0, f0, t1, y1, f1, fresh)
        h = t1 - t0
        s = 1.0 if hit is None else (hit[1] - t0) / h  # where the interpolant's terms are taken
        basis = np.array([(1 + 2 * s) * (1 - s) ** 2, s * (1 - s) ** 2 * h, s * s * (3 - 2 * s), s * s * (1 - s) * h])
        terms = np.abs(np.stack([y0[:3], f0[:3], y1[:3], f1[:3]])) * basis[:, None]
        steps.append((h, s * h, float(np.abs(y0[:3]).max()), CUBIC_ROUNDOFF * EPS * float(terms.sum(axis=0).max()), hit))
        return hit

    monkeypatch.setattr(simulate_module, "first_event", recorded)
    b = _run("bouncing_sphere", t_end, False, overrides, monkeypatch=monkeypatch)  # (undoes the recording)
    a = _run("bouncing_sphere", t_end, True, overrides, monkeypatch=monkeypatch)
    _assert_same_run(a, b, STEPPED_ROUNDOFF if a[0].formulation.name == "projection" else SAMPLE_ROUNDOFF)
    V_1, r_max = bounces[0][1], max(r for _, _, r, _, _ in steps)
    carried = sum(STEP_ROUNDING * (2 * r_max + 2 * taken * V_1) for _, taken, _, _, _ in steps)
    hits = [(hit[1], h, at_root) for h, _, _, at_root, hit in steps if hit is not None]
    located = [EVENT_XTOL * h + EVENT_RTOL * t + (at_root + carried) / V for (t, h, at_root), (_, V) in zip(hits, bounces)]
    bounds = _bounce_time_bounds(e, accel, located)
    for sim in (a[0], b[0]):
        times = [r.t_start for r in sim.contacts.records if r.t_start <= t_end]
        assert len(times) == N_BOUNCES, f"{len(times)} bounces of {N_BOUNCES} before t = {t_end:.4g} s"
        for k, (t, (t_k, _), bound) in enumerate(zip(times, bounces, bounds)):
            assert abs(t - t_k) <= bound, f"bounce {k + 1}: {t - t_k:.3g} s off, bound {bound:.3g} s"


#: Interval between the samples of the runs ending near a bounce [s]: coarser than the scene's (only
#: the end matters), and the margin of their ends from the bounce, far above its location's error.
END_DT = 1e-4


@pytest.mark.parametrize("after", [False, True])
def test_a_run_ends_at_t_end_just_before_or_after_a_bounce(after, monkeypatch):
    """Was: adaptive steps went past t_end (free flight is exact for DOPRI5: without sim.max_step a
    step spans a whole flight) and the events inside them were handled: bouncing_sphere with
    restitution to 0.4 s reported a 6th contact at 0.4073 s, its contact report taken after t_end. Now
    the last step is clipped to end at t_end exactly (as ``solve_ivp``'s at ``t_bound``): a run
    ending one sample before the 6th bounce of ``_bounces`` has 5 contacts, one ending one sample
    after it 6, every event at or before t_end, its last frame and the state after its last step at
    t_end; the compiled driver and the Python loop alike (the same steps and events)."""
    impactor = tomllib.loads((SCENES / "bouncing_sphere.toml").read_text())["impactor"]
    contact = tomllib.loads((SCENES / "bouncing_sphere.toml").read_text())["contact"]
    bounces = _bounces(contact["restitution"], impactor["gap"], impactor["force"] / impactor["mass"], 6)
    n = math.ceil(bounces[5][0] / END_DT) if after else math.floor(bounces[5][0] / END_DT) - 1
    t_end = n * END_DT  # (a sample time: the run's samples are at multiples of END_DT)
    overrides = ("contact.law=restitution", f"sim.output_dt={END_DT}")  # (its dt: the sample interval)
    a = _run("bouncing_sphere", t_end, True, overrides, monkeypatch=monkeypatch)
    b = _run("bouncing_sphere", t_end, False, overrides, monkeypatch=monkeypatch)
    _assert_same_run(a, b, STEPPED_ROUNDOFF)
    for sim, traj, _ in (a, b):
        assert traj.status == "ok"
        assert traj.t[-1] == t_end, f"last frame at {traj.t[-1]!r} s, t_end {t_end!r} s"
        assert np.all(traj.extras["events_t"] <= t_end), f"events at {traj.extras['events_t']} s, t_end {t_end} s"
        assert int(traj.extras["contact_count"]) == (6 if after else 5)
        sim._to_python()
        assert sim._inner.t == t_end, f"last step ends at {sim._inner.t!r} s, t_end {t_end!r} s"


def test_step_size_underflow_is_diagnosed_as_in_python(monkeypatch):
    """A min_step the tolerance cannot be met above: the kernel stops at the underflow and the Python
    path writes the same diagnosis at the same time, after the same frames."""
    ctrl = Controller(rtol=1e-13, atol=1e-16, min_step=2e-4)
    a = _run("flexible_pendulum", 0.2, True, controller=ctrl, monkeypatch=monkeypatch)
    b = _run("flexible_pendulum", 0.2, False, controller=ctrl, monkeypatch=monkeypatch)
    assert "below min_step" in b[1].status
    _assert_same_run(a, b, SAMPLE_ROUNDOFF)


def test_blow_up_is_diagnosed_as_in_python(monkeypatch):
    """A speed limit the falling sphere exceeds before it lands (0.63 m/s after 0.02 m): the same
    diagnosis (body, time, speed) after the same frames."""
    a = _run("bouncing_sphere", 0.08, True, blowup_speed=0.3, monkeypatch=monkeypatch)
    b = _run("bouncing_sphere", 0.08, False, blowup_speed=0.3, monkeypatch=monkeypatch)
    assert "exceeds sim.blowup_speed" in b[1].status
    _assert_same_run(a, b, SAMPLE_ROUNDOFF)


@pytest.mark.parametrize("n", [1, 7, 8, 9, 128, 129, 200, 1003, 5000])
def test_pairwise_sum_adds_in_numpys_order(n):
    """The error norm's sum, bit for bit (numpy's pairwise order; a plain loop differs at n > 8)."""
    x = np.random.default_rng(n).standard_normal(n) ** 2
    assert _sum(x) == np.sum(x)


@njit
def _sum(x):
    return pairwise_sum(x, 0, x.shape[0])


def test_ledgers_of_recorded_steps_are_the_ledgers_one_by_one(monkeypatch):
    """``ContactStepping.ledgers`` (one kernel sample and the flexible bodies' energies over all the
    recorded steps of a call) against ``ContactStepping.ledger`` of each state (``energy_terms``,
    NumPy), at the steps' ends and at ``y - error``, on a floating flexible bar in a law contact.
    Each term is a sum of at most 6 + n_e products per body (the FFR quadratic forms), a few roundings
    each: (6 + n_e) eps of the sum of the terms' magnitudes, times 8."""
    from viz3d.events import ContactStepping, Ledger

    calls = []
    after_steps = ContactStepping.after_steps
    monkeypatch.setattr(ContactStepping, "after_steps",
                        lambda self, *a: calls.append((self, *(np.array(x) for x in a[1:]), a[0])) or after_steps(self, *a))
    sim = _run("pendulum_strikes_bar", 4e-4, True, monkeypatch=monkeypatch)[0]
    contacts, ts, Y, charts, errors, _, like = max(calls, key=lambda c: c[1].shape[0])
    assert ts.shape[0] > 10
    n_e = sum(fb.n for fb in sim.system.bodies.flexible)
    for Ys in (Y, Y - errors):
        batch = contacts.ledgers(ts, Ys, charts, like.memory)
        for r in range(ts.shape[0]):
            one = contacts.ledger(contacts.state_at(float(ts[r]), Ys[r], like.replace(chart=charts[r])))
            scale = sum(abs(getattr(one, f.name)) for f in dataclasses.fields(Ledger))
            for f in dataclasses.fields(Ledger):
                a, b = float(getattr(batch, f.name)[r]), float(getattr(one, f.name))
                assert abs(a - b) <= 8 * (6 + n_e) * EPS * scale, f"mismatch: {f.name} at step {r}: {a!r} vs {b!r}"

"""ALI3-P in the compiled kernel (``viz3d.kernel.ali3p``: each attempt of a step one compiled call) takes
the NumPy path's steps (``viz3d.ali3p``, the reference): the same Newton iterates, hence the same
evaluation counts, states that agree to Newton's stopping tolerance and round-off
(``kernel_runs.ali3p_agreement_bound``), and the same diagnosis when a step fails."""

import re

import numpy as np
import pytest
from kernel_runs import ali3p_runs_agree
from systems import ROD_I_O, ROD_L, ROD_M, THETA0, rod_on_a_stop

import viz3d
from viz3d import kernel as K
from viz3d.diagnosis import SimulationFailure
from viz3d.dynamics import body_state
from viz3d.formulation import Index1
from viz3d.integrators import make_integrator
from viz3d.scene.build import make_formulation
from viz3d.simulate import Simulation

from conftest import SCENES

#: Standard gravity [m/s^2] (the scenes' default).
G = 9.81
#: Steps compared (the NumPy path costs 1-30 ms a step).
N_STEPS = 40

#: Rigid ball joints and gravity (heavy top, Euler angles in charts; at dt = 0.01 s its iterations slow down
#: and switch to the exact tangent: 99 times in these steps), chains of 2, 10 and 50 links (banded rows;
#: also in Euler parameters), a driven mechanism (revolute, ball, universal, prismatic joints, a velocity
#: drive: C_t != 0 and the ledger's drive power).
CASES = [("heavy_top", {}), ("heavy_top", {"sim.dt": 0.01}), ("chain", {"chain.n": 2}), ("chain", {}),
         ("chain", {"sim.rotation": "quaternion"}), ("chain", {"chain.n": 50}), ("slider_crank", {})]


def _setup(name, overrides=None):
    scene = viz3d.load_scene(SCENES / f"{name}.toml", {"sim.formulation": "ali3p", "sim.integrator": "trapezoidal",
                                                       **(overrides or {})})
    system, state = viz3d.build(scene)
    return system, state, make_formulation(scene.data["sim"]), scene.data["sim"]["dt"]


@pytest.mark.parametrize("name, overrides", CASES, ids=lambda c: c if isinstance(c, str) else ",".join(map(str, c.values())))
def test_compiled_ali3p_takes_the_numpy_steps(name, overrides):
    system, state, form, dt = _setup(name, overrides)
    compiled, numpy = ali3p_runs_agree(system, state, form, N_STEPS, dt)
    assert compiled.n_steps == numpy.n_steps == N_STEPS
    # the same iterates: as many force and row evaluations (an iteration matrix that differs changes them:
    # twice its constraint term took 3385 against 206). Round-off may flip a stopping test that sits at
    # the tolerance (seen once over 200 steps of a 50-link chain, on another BLAS it may happen here):
    # one iteration's evaluations either way, never more than 2 % of them
    assert abs(compiled.n_rhs - numpy.n_rhs) <= max(2, 0.02 * numpy.n_rhs), (compiled.n_rhs, numpy.n_rhs)
    assert np.array_equal(compiled.state.chart, numpy.state.chart)


def test_a_failing_compiled_step_stops_with_the_numpy_diagnosis():
    """At alpha = 1e6 the multiplier updates of a 10-link chain converge too slowly: the second step fails
    with both tangents and at every halving; both paths stop there with the same diagnosis (time, step,
    the last update and constraint residual) after the same evaluations."""
    system, state, form, dt = _setup("chain", {"sim.ali3p_alpha": 1e6})
    failures = []
    for compiled in (True, False):
        sim = Simulation(system, state, make_integrator("trapezoidal"), form, dt, compiled=compiled)
        assert (sim.kernel_note == "compiled kernel") == compiled
        with pytest.raises(SimulationFailure) as failure:
            sim.steps(5)
        failures.append((str(failure.value), sim.n_steps, sim.n_rhs))
    (compiled_message, compiled_steps, compiled_rhs), (numpy_message, numpy_steps, numpy_rhs) = failures
    where = f"t = {dt:.6g} s: ALI3-P iteration did not converge in 40 iterations with h = {dt / 8:.3g} s (last update "
    assert compiled_message.startswith(where) and numpy_message.startswith(where), (compiled_message, numpy_message)
    # the last update and max |C| sit at round-off (1e-13, 1e-12 m): both named, not compared
    assert re.search(r"max \|C\| = \S+ m\); try a smaller sim.dt", compiled_message), compiled_message
    assert compiled_steps == numpy_steps == 1
    assert abs(compiled_rhs - numpy_rhs) <= max(2, 0.02 * numpy_rhs), (compiled_rhs, numpy_rhs)


def test_a_batched_call_that_stops_at_a_failing_step_keeps_its_steps_and_never_redoes_the_step():
    """The same chain: ``output_states`` asks for 5 steps in one call; the first converges and the second
    fails. The run stands after the first (its state to the bit as the single steps' one), and ``steps``
    goes on from the failed attempts: only their halvings are new calls (before: the batch was called a
    second time and the first attempts made a third time, 0.4 s each at the anchor hoist's flukes'
    stop). The diagnosis and evaluations are those of the single steps."""
    from viz3d.ali3p import MAX_HALVINGS
    from viz3d.kernel.ali3p import KernelALI3P

    system, state, form, dt = _setup("chain", {"sim.ali3p_alpha": 1e6})
    calls = []
    call = KernelALI3P._call

    def counted(self, *args):
        calls.append(args[3])  # (n_frames)
        return call(self, *args)

    runs = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(KernelALI3P, "_call", counted)
        for batched in (True, False):
            calls.clear()
            sim = Simulation(system, state, make_integrator("trapezoidal"), form, dt)
            if batched:
                assert sim.output_states(1, 5) == []
                assert (sim.n_samples, sim.n_steps, sim.state.t) == (1, 1, dt)
                assert sim.output_states(1, 4) == [] and len(calls) == 1  # it stands at the failure: no call
            else:
                sim.step()
            after_one = sim.state.y.copy()
            with pytest.raises(SimulationFailure) as failure:
                sim.steps(4)
            runs[batched] = (after_one, str(failure.value), sim.n_steps, sim.n_rhs, list(calls))
    (y_b, message_b, steps_b, rhs_b, calls_b), (y_s, message_s, steps_s, rhs_s, calls_s) = runs[True], runs[False]
    np.testing.assert_array_equal(y_b, y_s)
    assert message_b == message_s and (steps_b, rhs_b) == (steps_s, rhs_s) == (1, rhs_s)
    assert len(calls_b) == 1 + MAX_HALVINGS, calls_b  # the batch (its failed step's attempts), then the halvings
    assert len(calls_s) == 2 + MAX_HALVINGS, calls_s  # the first step, the failed one, the halvings


@pytest.mark.parametrize("name, why", [("flexible_pendulum", "ALI3-P with flexible bodies"),
                                       ("stiff_contact", "ALI3-P with contacts")])
def test_what_the_compiled_ali3p_does_not_cover_takes_the_numpy_path_and_says_why(name, why):
    system, state, form, dt = _setup(name)
    assert K.kernel_coverage(system, form) == (None, why)
    sim = Simulation(system, state, make_integrator("trapezoidal"), form, dt)
    assert sim.kernel_note == f"NumPy path, not covered by the compiled kernel: {why}"
    sim.step()
    assert sim.state.t == pytest.approx(dt)


@pytest.mark.parametrize("name, overrides", [("chain", {}), ("chain", {"sim.rotation": "quaternion"}),
                                             ("top_through_vertical", {}), ("slider_crank", {})],
                         ids=lambda c: c if isinstance(c, str) else ",".join(map(str, c.values())))
def test_a_run_of_compiled_steps_in_one_call_takes_the_single_steps(name, overrides):
    """``output_states`` takes a run's ALI3-P steps frame to frame in one compiled call each, with the checks,
    normalisation and chart switches between them in the kernel; ``step`` takes them one at a time (the
    compiled step, the rest in Python). The same compiled arithmetic: the same states to the last bit (the
    kernel normalises Euler parameters and switches charts by the NumPy formulas), counters and switches
    (the top through the vertical switches its chart once in these 0.2 s)."""
    system, state, form, dt = _setup(name, overrides)
    batched = Simulation(system, state, make_integrator("trapezoidal"), form, dt)
    single = Simulation(system, state, make_integrator("trapezoidal"), form, dt)
    assert batched.batches_frames and batched.kernel_note == "compiled kernel"
    states = batched.output_states(4, 100)
    assert len(states) == 4
    for k, s in enumerate(states):
        for _ in range(100):
            single.step()
        assert single.state.t == s.t
        np.testing.assert_array_equal(single.state.y, s.y, err_msg=f"y after frame {k}")
        np.testing.assert_array_equal(single.state.chart, s.chart, err_msg=f"chart after frame {k}")
    assert (batched.n_steps, batched.n_samples, batched.n_rhs) == (single.n_steps, single.n_samples, single.n_rhs)
    np.testing.assert_array_equal(batched.chart_switches, single.chart_switches)
    assert batched.chart_switches.sum() == (1 if name == "top_through_vertical" else 0)
    np.testing.assert_array_equal(batched._memory.lam, single._memory.lam)


#: The pendulum on a stop: ``systems.rod_on_a_stop`` with its stop at STOP (spring k [N m/rad], critical
#: damping), met 0.12 s after the release.
STOP, STOP_K, DT_STOP = np.radians(-30.0), 1e3, 1e-3


def _pendulum_on_a_stop(tmp_path):
    system, state, form, I_O = rod_on_a_stop(tmp_path, STOP - THETA0, STOP_K, 2 * np.sqrt(STOP_K * ROD_I_O), 1.0,
                                             DT_STOP)
    return system, state, form, DT_STOP, I_O


def test_stops_are_packed_for_each_ali3p_run_and_once_for_rk4(tmp_path):
    """The compiled ALI3-P writes the stops' held sides into their packed data within each step
    (``hold_piece``): under ALI3-P a system with stops is packed for each run (``model.per_run``), never
    shared by two runs; under RK4, which writes nothing there, once for all its runs."""
    system, _, form, _, _ = _pendulum_on_a_stop(tmp_path)
    a, b = K.kernel_for(system, form), K.kernel_for(system, form)
    assert a is not None and b is not None and a is not b
    rk4 = Index1()
    assert K.kernel_for(system, rk4) is K.kernel_for(system, rk4) is not None


def test_compiled_ali3p_holds_a_stop_as_the_numpy_steps_do(tmp_path):
    """A pendulum falls onto a joint stop (its side held within a step, ``JointStop.frozen``; the stop engages
    within a step, which the check at the converged point finds and re-solves): the compiled steps take the
    NumPy path's (states within ``ali3p_agreement_bound``, as many evaluations), and the stop holds: the
    rod enters it by less than the undamped bound ``w / omega_n`` (``w`` the rate at the stop from the
    weight's work, ``omega_n = sqrt(k / I_O)``) plus twice the static deflection ``m g (L/2) sin|STOP| / k`` (the peak of an
    undamped oscillator under a constant load)."""
    system, state, form, dt, I_O = _pendulum_on_a_stop(tmp_path)
    n = 200
    compiled, numpy = ali3p_runs_agree(system, state, form, n, dt)
    assert abs(compiled.n_rhs - numpy.n_rhs) <= max(2, 0.02 * numpy.n_rhs), (compiled.n_rhs, numpy.n_rhs)
    stop = next(e for e in system.forces if e.branches)
    sim = Simulation(system, state, make_integrator("trapezoidal"), form, dt)
    q = []
    for _ in range(n):
        sim.step()
        q.append(stop.coordinates(body_state(system, sim.state.q, sim.state.v, sim.state.chart, sim.state.t))[0][0])
    d = ROD_L / 2
    w = np.sqrt(2 * ROD_M * G * d * (np.cos(STOP) - np.cos(THETA0)) / I_O)
    depth = max(q) - (STOP - THETA0)
    assert 0.0 < depth <= w / np.sqrt(STOP_K / I_O) + 2 * ROD_M * G * d * np.sin(-STOP) / STOP_K, depth

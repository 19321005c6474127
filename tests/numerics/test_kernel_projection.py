"""The ``projection`` formulation in the compiled kernel (``viz3d.kernel.projection``) takes the
steps the NumPy path takes (``Projection.post_step``: ``viz3d.stabilization``), to round-off, and
leaves the joints closed to the projection's tolerance."""

import warnings

import numpy as np
import pytest
from kernel_runs import EPS, ROUNDOFF_FACTOR, SENSITIVITY_SAMPLES, agreement_bound, off_constraints, run, with_y

import viz3d
from viz3d import kernel as K
from viz3d.constraints import constraint_rows
from viz3d.diagnosis import SimulationFailure
from viz3d.dynamics import body_state
from viz3d.integrators import make_integrator
from viz3d.integrators.tableaus import RK4
from viz3d.scene.build import consistent_state, make_formulation
from viz3d.simulate import Simulation

from conftest import SCENES

#: The runs start this far off the constraints (random q and v offsets [m, rad, m/s, rad/s]): the first
#: projection has work to do, and a run that skips it keeps |C| ~ this, far above the tolerance.
OFF_CONSTRAINTS = 1e-6
#: RK4 steps compared and their length [s] (1e-3 s: the NumPy projection costs ~1-2 ms a step).
N_STEPS, DT = 100, 1e-3

#: Rigid ball joints (heavy top), a 10-link chain (banded rows), a driven mechanism (C_t != 0: the velocity
#: projection's explicit time rate, the drive's C(t)), a flexible body (elastic coordinates projected too).
SCENE_NAMES = ["heavy_top", "chain", "slider_crank", "flexible_pendulum"]


def _setup(name, overrides=None):
    scene = viz3d.load_scene(SCENES / f"{name}.toml", {"sim.formulation": "projection", **(overrides or {})})
    system, state = viz3d.build(scene)
    return system, off_constraints(state, OFF_CONSTRAINTS), make_formulation(scene.data["sim"])


def _run(system, state, form, n, compiled):
    return run(system, state, form, n, DT, compiled)


def _max_abs_C(system, s):
    return np.abs(constraint_rows(system.joints, body_state(system, s.q, s.v, s.chart, s.t), s.memory).C).max()


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_compiled_projection_takes_the_numpy_steps_and_closes_the_joints(name):
    """N steps both ways agree within N x (growth of a difference over N steps) x ROUNDOFF_FACTOR x (one step's
    round-off) (``kernel_runs.agreement_bound``); the compiled run's joints are closed to the projection's
    tolerance after every step."""
    system, state, form = _setup(name)
    assert K.kernel_coverage(system, form)[1] is None
    compiled = Simulation(system, state, make_integrator("rk4"), form, DT)
    assert compiled.kernel_note == "compiled kernel"
    worst_C = 0.0
    for _ in range(N_STEPS // 10):
        compiled.steps(10)  # in the kernel: ten steps in one call
        worst_C = max(worst_C, _max_abs_C(system, compiled.state))
    numpy = _run(system, state, form, N_STEPS, compiled=False)
    assert compiled.n_steps == numpy.n_steps == N_STEPS
    bound = agreement_bound(system, state, form, N_STEPS, DT)
    diff = np.abs(compiled.state.y - numpy.state.y).max()
    assert diff <= bound, f"mismatch: y after {N_STEPS} steps: {diff:.2e} > {bound:.2e}"
    assert np.array_equal(compiled.state.chart, numpy.state.chart)
    assert worst_C <= form.tol, f"max |C| after projection {worst_C:.2e} m > tol {form.tol:g} m"


#: Implicit steps compared (each costs a finite-difference Newton matrix on the NumPy path).
N_IMPLICIT = 20


@pytest.mark.parametrize("method", ["trapezoidal", "gen_alpha"])
@pytest.mark.parametrize("name", ["heavy_top", "chain"])
def test_steps_the_kernel_does_not_take_are_projected_in_it(name, method, monkeypatch):
    """Implicit methods step in Python on the compiled field; their end states are projected by the
    kernel (``Simulation._post_step``, once a step) and agree with the NumPy path's projections
    within the bound of ``kernel_runs.agreement_bound``; the joints are closed to the tolerance."""
    system, state, form = _setup(name)
    calls = []
    project = K.KernelStepper.project
    monkeypatch.setattr(K.KernelStepper, "project", lambda self, *a: calls.append(1) or project(self, *a))
    compiled = run(system, state, form, N_IMPLICIT, DT, compiled=True, method=method)
    monkeypatch.undo()
    assert compiled.kernel_note == "compiled kernel" and len(calls) == N_IMPLICIT
    numpy = run(system, state, form, N_IMPLICIT, DT, compiled=False, method=method)
    bound = agreement_bound(system, state, form, N_IMPLICIT, DT, method)
    diff = np.abs(compiled.state.y - numpy.state.y).max()
    assert diff <= bound, f"mismatch: y after {N_IMPLICIT} steps: {diff:.2e} > {bound:.2e}"
    assert _max_abs_C(system, compiled.state) <= form.tol


def test_projection_that_does_not_converge_stops_the_run_with_the_numpy_diagnosis():
    """A tolerance below round-off cannot be met: the kernel reports ``PROJECTION`` after the first step, and
    the run stops with the NumPy path's ``ProjectionError`` diagnosis, at the same time."""
    system, state, form = _setup("heavy_top", {"sim.projection_tol": 1e-300})
    data = K.kernel_for(system, form)
    y, chart = state.y.copy(), state.chart.copy()
    done, status = K.kernel_advance(data, RK4, 5, 0.0, DT, y, chart, np.zeros(system.n_bodies, np.int64), 1e4)
    assert (done, status) == (1, K.PROJECTION)
    messages = []
    for compiled in (True, False):
        with pytest.raises(SimulationFailure) as exc:
            _run(system, state, form, 5, compiled)
        messages.append(str(exc.value))
    head = [m.split(" = ")[:2] for m in messages]  # "t = 0.001 s: position projection left max |C|", value
    assert head[0] == head[1] and "position projection left max |C|" in messages[0], messages


def _initial_projection(system, state, tol, form):
    return consistent_state(system, state, "test", tol, form)


@pytest.mark.parametrize("name", SCENE_NAMES[:3])
def test_the_initial_state_projected_in_the_kernel_is_numpys_to_round_off(name, monkeypatch):
    """A run that steps in the kernel projects its initial state there (``scene.build.kernel_projection``,
    with the run's formulation, here index-1, whose steps project nothing): once, and to the NumPy projection's state
    within ROUNDOFF_FACTOR x that projection's round-off (eps times its condition number: its change under
    relative perturbations of eps of the state, at least eps |y|, as ``kernel_runs.step_roundoff``);
    the joints closed to the tolerance."""
    scene = viz3d.load_scene(SCENES / f"{name}.toml", {"sim.formulation": "index1"})
    system, state = viz3d.build(scene)
    form, tol = make_formulation(scene.data["sim"]), scene.data["sim"]["projection_tol"]
    assert form.name != "projection" and K.kernel_coverage(system, form)[1] is None
    start = off_constraints(state, OFF_CONSTRAINTS)
    calls = []
    project = K.KernelStepper.project

    def counted(self, *a):
        calls.append(project(self, *a))
        return calls[-1]

    monkeypatch.setattr(K.KernelStepper, "project", counted)
    with pytest.warns(UserWarning, match="projected onto the joints"):
        compiled = _initial_projection(system, start, tol, form)
    monkeypatch.undo()
    assert [ok for _, ok in calls] == [True], "the kernel's projection was not the one used"
    with pytest.warns(UserWarning, match="projected onto the joints"):
        numpy = _initial_projection(system, start, tol, None)
    signs = np.random.default_rng(1).choice([-1.0, 1.0], size=(SENSITIVITY_SAMPLES, start.y.size))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        change = max(np.abs(_initial_projection(system, with_y(system, start, start.y * (1 + EPS * s)), tol, None).y
                            - numpy.y).max() for s in signs)
    bound = ROUNDOFF_FACTOR * max(change, EPS * np.abs(numpy.y).max())
    diff = np.abs(compiled.y - numpy.y).max()
    assert diff <= bound, f"{name}: kernel and NumPy initial projections differ by {diff:.2e} > {bound:.2e}"
    assert _max_abs_C(system, compiled) <= tol


def test_the_kernel_correction_on_floating_flexible_bars_is_the_mass_orthogonal_one():
    """One Newton correction of the kernel's projection on the flexible four-bar, 1e-6 off its joints,
    against the dense minimum-M-norm correction ``-M^-1 C_v^T (C_v M^-1 C_v^T)^-1 C`` (which NumPy's
    equals to 4e-20): equal to round-off of the correction's size. (The projection factored the bars'
    mass blocks with the shape moments the field's velocity forces had left in the scratch - none at
    the start - so the rotation-elastic coupling of coordinates 1 and 3 was missing: they stayed put.)"""
    from dataclasses import replace

    from viz3d.constraints import dense_jacobian
    from viz3d.mass import dense_mass_matrix

    system, state, form = _setup("flexible_four_bar")
    cfg = body_state(system, state.q, np.zeros(system.n_v), state.chart, state.t)
    rows = constraint_rows(system.joints, cfg, state.memory)
    Cv, M = dense_jacobian(system, rows.J, rows.Je), dense_mass_matrix(system, cfg)
    exact = -np.linalg.solve(M, Cv.T @ np.linalg.solve(Cv @ np.linalg.solve(M, Cv.T), rows.C))
    data = K.kernel_for(system, form)
    stepper = K.KernelStepper(replace(data, model=data.model._replace(projection_tol=0.0, projection_iter=1)), None)
    y, _ = stepper.project(state.t, state.y.copy(), state.chart, state.memory)
    n_frames_q, n_frames_v = system.n_frames * system.n_q_body, 6 * system.n_frames
    d_eta = (y - state.y)[n_frames_q:system.n_q]
    scale = np.abs(exact).max()
    np.testing.assert_allclose(d_eta, exact[n_frames_v:], rtol=0, atol=1e3 * EPS * np.linalg.cond(M) * scale)

"""Adaptive rigid-body runs (sim.rtol with dopri5, dop853) against scipy's DOP853 on an
independent quaternion formulation of the heavy top (tests/references.py)."""

import numpy as np
import pytest

import viz3d
from viz3d.scene.build import make_controller, make_formulation, make_integrator_from
from viz3d.simulate import Simulation

from conftest import SCENES
from references import fixed_point_body

T_END = 0.5          # s of the heavy top
SAMPLE_DT = 0.01     # s between returned states (dense output)
#: Reference at scipy's tightest tolerance (100 eps): its error is below 1e-13 m.
REF_RTOL, REF_ATOL = 2.3e-14, 1e-15
#: Tolerances of the three runs per method, each 100x tighter.
RTOLS = {"dopri5": (1e-6, 1e-8, 1e-10), "dop853": (1e-6, 1e-8, 1e-10)}
#: |W_r| of the top's centre of mass: 0.15 m from the pivot at the world origin.
PIVOT_TO_G = 0.15    # m
#: atol of the runs per unit rtol.
ATOL_PER_RTOL = 1e-2
#: Tighter tolerances by this factor between the runs.
RTOL_FACTOR = 100.0
#: A controller of the error per step makes the global error proportional to rtol^(p/(p+1)) for an error
#: estimate of order p (Hairer, Norsett & Wanner I, sec. II.4, "tolerance proportionality"); p >= 1 gives
#: at least RTOL_FACTOR^(1/2) per run (observed 115-137 DOPRI5, 24-84 DOP853).
MIN_GAIN = RTOL_FACTOR ** 0.5


def _adaptive_run(method: str, rtol: float):
    # index-1: the controller alone (a projection after each step would also re-evaluate the FSAL stage)
    scene = viz3d.load_scene(SCENES / "heavy_top.toml", [f"sim.integrator={method}", f"sim.rtol={rtol}",
                                                         f"sim.atol={rtol * ATOL_PER_RTOL}", f"sim.dt={SAMPLE_DT}",
                                                         "sim.formulation=index1"])
    system, state = viz3d.build(scene)
    cfg = scene.data["sim"]
    sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"], cfg["blowup_speed"],
                     make_controller(cfg))
    t, W_r = [], []  # W_r: centre of mass [m]
    for _ in range(round(T_END / SAMPLE_DT)):
        sim.step()
        t.append(sim.state.t)
        W_r.append(system.split_q(sim.state.q)[0][0].copy())
    R0 = system.rotation.matrix(system.split_q(state.q)[1], state.chart)[0]
    _, _, rG = fixed_point_body(system.bodies.inertia[0], system.bodies.mass[0], [0.0, 0.0, PIVOT_TO_G], (0.0, 0.0, -9.81), R0,
                                R0 @ system.split_v(state.v)[1][0], np.array([0.0] + t), rtol=REF_RTOL, atol=REF_ATOL)
    return sim, np.array(t), float(np.abs(np.array(W_r) - rG[1:]).max())


@pytest.mark.parametrize("method", sorted(RTOLS))
def test_adaptive_error_falls_with_the_tolerance(method):
    runs = [_adaptive_run(method, rtol) for rtol in RTOLS[method]]
    errors = [err for _, _, err in runs]
    for (sim, t, err), rtol in zip(runs, RTOLS[method]):
        np.testing.assert_allclose(t, SAMPLE_DT * np.arange(1, len(t) + 1), rtol=1e-12)  # the sampling grid
        # every accepted step keeps its local error estimate below rtol |y| + atol: without growth along
        # the flow (0.5 s of a top), the global error is at most their sum (Hairer I, sec. II.3)
        bound = sim.n_steps * rtol * (PIVOT_TO_G + ATOL_PER_RTOL)
        assert err <= bound, (method, rtol, err, bound)
    assert all(a > MIN_GAIN * b for a, b in zip(errors, errors[1:])), (method, errors)
    assert np.allclose(np.divide(RTOLS[method][:-1], RTOLS[method][1:]), RTOL_FACTOR)
    steps = [sim.n_steps for sim, _, _ in runs]
    assert steps == sorted(steps) and steps[0] < steps[-1], steps   # tighter: more, shorter steps


def test_a_tolerance_driven_run_rejects_and_accepts_steps():
    """DOPRI5 at rtol 1e-8 on the heavy top: the controller rejects some trial steps (measured 14,
    2026-11-21) and accepts many more (304)."""
    sim, _, _ = _adaptive_run("dopri5", 1e-8)
    assert sim.n_rejected > 0
    assert sim.n_steps > 10 * sim.n_rejected
    # 6 evaluations per attempt, FSAL, plus the first-step estimate
    assert sim.n_rhs == pytest.approx(6 * (sim.n_steps + sim.n_rejected), abs=10)


def test_a_trial_step_the_field_cannot_evaluate_is_rejected_not_fatal():
    """A stage state outside the field's domain (``LinAlgError``: e.g. a flexible body's mass block
    no longer positive definite far along a too-long first step) rejects the trial step like a
    non-finite error; a field that cannot be evaluated at any step ends in ``StepSizeUnderflow``
    naming the failure."""
    from viz3d.integrators import make_integrator
    from viz3d.integrators.adaptive import Controller, StepSizeUnderflow, accepted_step

    def rhs(t, y):
        if t > 0.01:  # stages beyond 10 ms leave the domain
            raise np.linalg.LinAlgError("not positive definite")
        return -y

    y0, ctrl = np.array([1.0]), Controller(rtol=1e-8, atol=1e-12, min_step=1e-9)
    acc = accepted_step(rhs, 0.0, y0, rhs(0.0, y0), 1.0, make_integrator("dopri5"), ctrl)
    assert acc.n_rejected > 0 and acc.h <= 0.01
    assert abs(acc.res.y[0] - np.exp(-acc.h)) < 1e-9

    def never(t, y):
        if t > 0.0:
            raise np.linalg.LinAlgError("not positive definite")
        return -y

    with pytest.raises(StepSizeUnderflow, match="a stage's evaluation failed: not positive definite"):
        accepted_step(never, 0.0, y0, never(0.0, y0), 1.0, make_integrator("dopri5"), ctrl)


def test_a_spherical_rigid_impactor_on_a_free_bar_runs_like_the_flat_one():
    """The symptom: ``impact_free_bar`` with a spherical impactor and the rigid law stopped at t = 0
    with an internal LinAlgError (the first trial step, 50 ms long, deformed the bar until its mass
    block lost definiteness). With the rigid law the face's shape does not enter: the same rebound."""
    runs = [viz3d.simulate(SCENES / "impact_free_bar.toml", overrides) for overrides in
            (["impactor.shape=sphere", "contact.law=rigid"], [])]
    assert all(t.ok for t in runs), [t.status for t in runs]
    e = [float(t.extras["restitution"]) for t in runs]
    assert abs(e[0] - e[1]) <= 100 * 1e-8, e  # the runs' rtol 1e-8, 100x: the two step sequences differ

"""Euler parameters (``sim.rotation = "quaternion"``) in the compiled kernel: whole runs take the NumPy
path's steps to round-off (``kernel_runs.agreement_bound``), with the NumPy path's normalisation
between steps and, with ``projection``, its projections.

The right-hand side against NumPy on the system holding every element type (flexible bodies on
floating frames included): tests/numerics/test_kernel_elements.py, on both coordinate sets; the
compiled health check: test_kernel.py; accuracy against references nobody here wrote (the Jacobi
closed form of the torque-free body, scipy's DOP853 on the heavy top): test_oracles.py.
"""

import numpy as np
import pytest
from kernel_runs import EPS, agreement_bound, off_constraints, run

import viz3d
from viz3d.scene.build import make_formulation

from conftest import SCENES

#: RK4 steps compared, each of the scene's own sim.dt (0.1-0.2 s of motion).
N_STEPS = 200
#: The runs start this far off (random q and v offsets [m, -, m/s, rad/s]): |p| = 1 +- ~1e-6, so the first
#: normalisation moves p by far more than round-off, and the joints are open for the first projection.
OFF = 1e-6
#: |p| after a normalisation: p / |p| is within a few eps of the unit sphere (four products, a sum, a
#: square root and a division, each rounding by eps / 2 at most).
NORM_TOL = 4 * EPS

#: A top on a ball joint, a free body tumbling about its intermediate axis, a fast top passing the pole of
#: Euler angles, a 5-link chain (banded rows).
RUNS = {"heavy_top": {}, "torque_free": {}, "top_through_vertical": {}, "chain": {"chain.n": 5}}


def _setup(name, formulation):
    scene = viz3d.load_scene(SCENES / f"{name}.toml",
                             {**RUNS[name], "sim.rotation": "quaternion", "sim.formulation": formulation})
    system, state = viz3d.build(scene)
    return system, off_constraints(state, OFF), make_formulation(scene.data["sim"]), float(scene.data["sim"]["dt"])


@pytest.mark.parametrize("formulation", ["index1", "projection"])
@pytest.mark.parametrize("name", RUNS)
def test_kernel_runs_take_the_numpy_steps_with_unit_quaternions(name, formulation):
    system, state, form, dt = _setup(name, formulation)
    compiled = run(system, state, form, N_STEPS, dt, compiled=True)
    assert compiled.kernel_note == "compiled kernel"
    numpy = run(system, state, form, N_STEPS, dt, compiled=False)
    assert compiled.n_steps == numpy.n_steps == N_STEPS
    bound = agreement_bound(system, state, form, N_STEPS, dt)
    diff = np.abs(compiled.state.y - numpy.state.y).max()
    assert diff <= bound, f"mismatch: y after {N_STEPS} steps: {diff:.2e} > {bound:.2e}"
    p = system.split_q(compiled.state.q)[1]
    assert np.abs(np.linalg.norm(p, axis=1) - 1.0).max() <= NORM_TOL, "Euler parameters not normalised"

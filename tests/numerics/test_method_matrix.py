"""Integrators x formulations x rotation coordinates on one scene: every combination meant to
work runs; the ones that make no sense stop before running, saying why."""

import itertools

import numpy as np
import pytest

import viz3d
from viz3d.coordinates import ROTATIONS
from viz3d.formulation import FORMULATIONS
from viz3d.integrators import INTEGRATORS
from viz3d.methods import MethodError, method_overrides, parse_method
from viz3d.scene.schema import SceneError

from conftest import SCENES

T_END = 0.2  # s of the double pendulum
DT = 1e-3    # s (adaptive runs: the sampling interval is 0.01 s)
#: The default run's matrix: every method of each kind at least once, with the others varied.
SMALL_MATRIX = [
    *(f"{name}+index1+euler_switching" for name in INTEGRATORS),
    *(f"rk4+{name}+euler_switching" for name in FORMULATIONS if FORMULATIONS[name].integrator is None),
    *(f"ali3p+{name}" for name in ROTATIONS),
    *(f"gen_alpha+{name}" for name in ROTATIONS),
    "trapezoidal+penalty+quaternion", "dopri5+projection+quaternion", "dop853+baumgarte+euler_zxz",
    "gen_alpha+projection+euler_switching", "heun+penalty+euler_zxz",
]
#: Adaptive runs (sim.rtol) in the default matrix.
ADAPTIVE = ["dopri5+index1+quaternion", "dop853+projection+euler_switching"]
#: Bound on max |C| over 0.2 s for every working combination (explicit Euler with index-1
#: drifts most: 2.3e-4 m measured, 2026-11-21; second-order methods 3e-7 m); a combination whose
#: constraint forces are wrong drifts by centimetres.
MAX_C = 1e-3


def _valid(method: str) -> bool:
    try:
        parse_method(method)
        return True
    except MethodError:
        return False


FULL_MATRIX = [m for m in ("+".join(c) for c in itertools.product(INTEGRATORS, FORMULATIONS, ROTATIONS)) if _valid(m)]


def _run(method, extra=()):
    traj = viz3d.simulate(SCENES / "double_pendulum.toml", [f"sim.dt={DT}"] + method_overrides(method) + list(extra),
                          t_end=T_END)
    assert traj.status == "ok", f"{method}: {traj.status}"
    assert traj.t[-1] == pytest.approx(T_END)
    assert np.all(np.isfinite(traj.position)) and np.all(np.isfinite(traj.rotation))
    assert traj.max_constraint_violation < MAX_C, (method, traj.max_constraint_violation)
    return traj


@pytest.mark.parametrize("method", SMALL_MATRIX)
def test_small_matrix_of_methods_runs(method):
    _run(method)


@pytest.mark.parametrize("method", ADAPTIVE)
def test_adaptive_combinations_run_on_the_output_grid(method):
    traj = _run(method, ["sim.rtol=1e-8", "sim.atol=1e-10", "sim.dt=0.01"])
    np.testing.assert_allclose(traj.t, 0.01 * np.arange(len(traj.t)), atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("method", FULL_MATRIX)
def test_full_matrix_of_methods_runs(method):
    _run(method)


@pytest.mark.parametrize("overrides,key", [
    (["sim.formulation=ali3p"], "sim.integrator"),                         # scene default integrator rk4
    (["sim.formulation=ali3p", "sim.integrator=gen_alpha"], "sim.integrator"),
    (["sim.integrator=rk4", "sim.rtol=1e-6"], "sim.rtol"),
    (["sim.integrator=gen_alpha", "sim.rtol=1e-6"], "sim.rtol"),
])
def test_combinations_that_make_no_sense_stop_with_the_key_at_fault(overrides, key):
    with pytest.raises(SceneError, match=key) as err:
        viz3d.simulate(SCENES / "double_pendulum.toml", overrides, t_end=T_END)
    assert "double_pendulum.toml" in str(err.value)

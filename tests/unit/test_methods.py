"""Method strings ("ali3p+quaternion") and which combinations can run."""

import pytest

from viz3d.coordinates import ROTATIONS
from viz3d.formulation import FORMULATIONS
from viz3d.integrators import INTEGRATORS
from viz3d.methods import MethodError, check_combination, method_overrides, parse_method


def test_registries_hold_the_names_of_issue_5():
    assert {"euler", "heun", "rk4", "dopri5", "dop853", "trapezoidal", "gen_alpha"} <= set(INTEGRATORS)
    assert {"index1", "baumgarte", "projection", "penalty", "ali3p"} <= set(FORMULATIONS)
    assert {"euler_zxz", "euler_switching", "quaternion"} <= set(ROTATIONS)
    assert not (set(INTEGRATORS) & set(FORMULATIONS) or set(FORMULATIONS) & set(ROTATIONS)
                or set(INTEGRATORS) & set(ROTATIONS)), "a name must say which kind it is"


@pytest.mark.parametrize("method,expected", [
    ("rk4", {"sim.integrator": "rk4"}),
    ("dopri5+projection", {"sim.integrator": "dopri5", "sim.formulation": "projection"}),
    ("ali3p+quaternion", {"sim.formulation": "ali3p", "sim.rotation": "quaternion", "sim.integrator": "trapezoidal"}),
    (" quaternion + gen_alpha + penalty ", {"sim.rotation": "quaternion", "sim.integrator": "gen_alpha",
                                            "sim.formulation": "penalty"}),
])
def test_method_strings_set_scene_keys(method, expected):
    assert parse_method(method) == expected
    assert sorted(method_overrides(method)) == sorted(f"{k}={v}" for k, v in expected.items())


@pytest.mark.parametrize("method,match", [
    ("rk5", "rk4, dopri5, dop853, trapezoidal, gen_alpha"),       # lists the valid names
    ("rk4+dopri5", "at most one integrator"),
    ("ali3p+penalty", "at most one formulation"),
    ("", "'\\+'-joined names"),
    ("ali3p+rk4", "'trapezoidal' with sim.formulation = 'ali3p'"),
    ("gen_alpha+ali3p", "'trapezoidal' with sim.formulation = 'ali3p'"),
])
def test_bad_method_strings_say_what_is_valid(method, match):
    with pytest.raises(MethodError, match=match):
        parse_method(method)


def test_tolerances_need_an_embedded_error_estimate():
    check_combination("dopri5", "index1", "quaternion", rtol=1e-8)
    for name in ("rk4", "trapezoidal", "gen_alpha"):
        with pytest.raises(MethodError, match="sim.rtol.*dopri5, dop853"):
            check_combination(name, "index1", rtol=1e-8)

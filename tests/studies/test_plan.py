"""Study plans: grid axes (listed values, linear and log ranges), random samples reproducible from
their seed, their product, and flags refused with the flag's name and the expected form."""

from __future__ import annotations

import numpy as np
import pytest

from viz3d.studies.plan import PlanError, grid_points, parse_grid, parse_sample, plan_points


def test_grid_axes_list_values_and_ranges():
    assert parse_grid("sim.integrator=rk4, heun").values == ("rk4", "heun")
    assert parse_grid("contact.e=0.5,0.8").texts == ("0.5", "0.8")
    assert parse_grid("sim.dt=1e-3:4e-3:4").values == pytest.approx((1e-3, 2e-3, 3e-3, 4e-3))
    assert parse_grid("k=1e5:1e9:5:log").values == pytest.approx((1e5, 1e6, 1e7, 1e8, 1e9))
    assert parse_grid("n=3").values == (3,)


def test_the_grid_is_the_cartesian_product_first_key_slowest_and_samples_repeat_at_each_cell():
    keys, points = plan_points([parse_grid("a=1,2"), parse_grid("b=x,y")], [], 1, 0)
    assert keys == ("a", "b") and [p.values for p in points] == [(1, "x"), (1, "y"), (2, "x"), (2, "y")]
    assert points[1].overrides == ("a=1", "b=y")
    keys, points = plan_points([parse_grid("m=rk4,heun")], [parse_sample("k=loguniform(1e5, 1e9)")], 3, seed=7)
    assert keys == ("m", "k") and len(points) == 6
    draws = [p.values[1] for p in points]
    assert draws[:3] == draws[3:] and all(1e5 <= k <= 1e9 for k in draws)  # common random numbers
    again = plan_points([parse_grid("m=rk4,heun")], [parse_sample("k=loguniform(1e5, 1e9)")], 3, seed=7)[1]
    assert again == points
    assert points[0].overrides[1] == f"k={draws[0]!r}"


@pytest.mark.parametrize("spec, check", [
    ("uniform(0, 1)", lambda v: 0 <= v <= 1),
    ("normal(10, 0)", lambda v: v == 10.0),
    ("int(2, 4)", lambda v: isinstance(v, int) and 2 <= v <= 4),
    ("choice(rk4, heun)", lambda v: v in ("rk4", "heun")),
])
def test_each_distribution_draws_in_its_support(spec, check):
    d = parse_sample(f"key={spec}")
    assert all(check(v) for v in d.draw(np.random.default_rng(0), 50))


def test_grid_points_of_a_mapping():
    assert [p.overrides for p in grid_points({"ship.heel": [0.0, 4.0]})] == [("ship.heel=0.0",), ("ship.heel=4.0",)]


@pytest.mark.parametrize("flag, text, words", [
    ("--grid", "sim.dt", ["--grid", "key.path=V1,V2"]),
    ("--grid", "sim.dt=", ["--grid"]),
    ("--grid", "sim.dt=1:2:0", ["--grid", "N a positive integer"]),
    ("--grid", "k=0:1:3:log", ["A:B:N:log with A > 0"]),
    ("--sample", "k=gauss(0, 1)", ["--sample", "loguniform(low, high"]),
    ("--sample", "k=loguniform(0, 1)", ["--sample", "both > 0"]),
    ("--sample", "k=int(1.5, 3)", ["int(low, high (integers"]),
])
def test_bad_flags_are_refused_naming_the_flag_and_the_expected_form(flag, text, words):
    parse = parse_grid if flag == "--grid" else parse_sample
    with pytest.raises(PlanError) as err:
        parse(text)
    assert all(w in str(err.value) for w in words), str(err.value)


def test_a_key_twice_is_refused():
    with pytest.raises(PlanError, match="each key once"):
        plan_points([parse_grid("a=1,2")], [parse_sample("a=uniform(0, 1)")], 2, 0)

"""Scene validation: every error names the file, the key path and what was expected; overrides
and generators resolve as documented."""

import json

import pytest

import viz3d

from conftest import SCENES, scene_files

PENDULUM = """
[sim]
dt = 1e-3
t_end = 0.05

[[bodies]]
name = "rod"
shape = { type = "cylinder", radius = 0.02, height = 1.0 }
density = 1000.0
position = [0.0, 0.0, -0.5]

[[joints]]
name = "pivot"
body1 = "rod"
point = [0.0, 0.0, 0.0]
"""


@pytest.mark.parametrize("path", scene_files(), ids=lambda p: p.stem)
def test_shipped_scenes_validate(path):
    scene = viz3d.load_scene(path)
    assert scene.data["bodies"] and "impactor" not in scene.data  # the shorthand is expanded to bodies


@pytest.mark.parametrize("edit,key,expected", [
    (lambda s: s.replace("dt = 1e-3", "dt = -1e-3"), "sim.dt", "a positive number"),
    (lambda s: s.replace("dt = 1e-3", "dtt = 1e-3"), "sim.dtt", "unknown key"),
    (lambda s: s.replace('type = "cylinder"', 'type = "cone"'), "bodies[0].shape.type", "one of"),
    (lambda s: s.replace("radius = 0.02, ", ""), "bodies[0].shape.radius", "missing"),
    (lambda s: s.replace('body1 = "rod"', 'body1 = "rodd"'), "joints[0].body1", "a body name"),
    (lambda s: s.replace("position = [0.0, 0.0, -0.5]", "position = [0.0, -0.5]"), "bodies[0].position", "3 numbers"),
    (lambda s: s.replace("density = 1000.0", ""), "bodies[0].mass", "density"),
    (lambda s: s.replace("point = [0.0, 0.0, 0.0]", ""), "joints[0].point", "joint point"),
    (lambda s: s + '\n[sim2]\n', "sim2", "unknown key"),
    (lambda s: s.replace('name = "pivot"', 'name = "pivot"\ncolor = "red"'), "joints[0].color", "unknown key"),
    (lambda s: s + '\n[[bodies]]\nname = "rod"\nmass = 1.0\ninertia = [1, 1, 1]\nposition = [0, 0, 0]\n',
     "bodies[1].name", "not used before"),
    (lambda s: s.replace('integrator = "rk4"', "") + '', "", ""),  # no-op edit: must load
])
def test_errors_name_file_key_and_expectation(write_scene, edit, key, expected):
    path = write_scene(edit(PENDULUM))
    if not key:
        viz3d.load_scene(path)
        return
    with pytest.raises(viz3d.SceneError) as err:
        viz3d.load_scene(path)
    msg = str(err.value)
    assert str(path) in msg and f"{key}:" in msg and expected in msg, msg


def test_invalid_toml_names_the_file(write_scene):
    path = write_scene("[sim\n")
    with pytest.raises(viz3d.SceneError, match="valid TOML"):
        viz3d.load_scene(path)


def test_overrides_by_index_and_name_and_bare_strings(write_scene):
    path = write_scene(PENDULUM)
    scene = viz3d.load_scene(path, ["bodies.rod.density=2000", "sim.integrator=heun", "joints.0.point=[0, 0, 0.0]"])
    assert scene.data["bodies"][0]["density"] == 2000.0
    assert scene.data["sim"]["integrator"] == "heun"


def test_bad_override_is_reported_with_the_override(write_scene):
    path = write_scene(PENDULUM)
    with pytest.raises(viz3d.SceneError) as err:
        viz3d.load_scene(path, ["sim.integrator=rk5"])
    assert "--set sim.integrator=rk5" in str(err.value) and "sim.integrator" in str(err.value)
    with pytest.raises(viz3d.SceneError, match="bodies.nobody"):
        viz3d.load_scene(path, ["bodies.nobody.mass=1"])


def test_chain_generator_follows_chain_n():
    for n in (1, 3, 7):
        scene = viz3d.load_scene(SCENES / "chain.toml", [f"chain.n={n}"])
        assert len(scene.data["bodies"]) == n and len(scene.data["joints"]) == n


def test_trajectory_records_resolved_scene_with_overrides(write_scene):
    traj = viz3d.simulate(write_scene(PENDULUM), ["sim.integrator=heun"], t_end=0.01)
    meta = json.loads(traj.scene_json)
    assert meta["run"]["integrator"] == "heun" and meta["run"]["dt"] == 1e-3
    assert meta["run"]["overrides"] == ["sim.integrator=heun", "sim.t_end=0.01"]
    assert meta["scene"]["sim"]["t_end"] == 0.01
    assert meta["run"]["viz3d_version"] == viz3d.__version__
    assert traj.scene_json == json.dumps(meta, sort_keys=True)  # json's own text (the scene's part kept by the scene)

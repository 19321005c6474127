"""The hydrodynamics scenes (scenes/dam_reservoir.toml, scenes/dam_earthquake.toml): they load, check
and run headless through the command line; their arrays are the library's (``viz3d.hydro``) and meet
the references of hydro_refs.py within tolerances from the mathematics (the reported truncation
bounds, rounding of printed digits, eps times the size of the numbers); bad keys are refused naming
the file and the key."""

import numpy as np
import pytest
from hydro_refs import (
    BASE_PRESSURE_COEFFICIENT,
    CHOPRA_FORCE_COEFFICIENT,
    SEED_C,
    SEED_DEPTH,
    SEED_FIRST_CUTOFF,
    SEED_RHO,
    half_unit,
)

import viz3d
from viz3d.cli import main
from viz3d.hydro import Reservoir, cantilever_dam, frequency_response, fundamental_frequency, pressure, time_response
from viz3d.hydro.records import shipped_record, write_csv
from viz3d.hydro.reservoir import RIGID_FORCE_COEFFICIENT, SEED_EXAMPLE, added_mass
from viz3d.hydro.shapes import uniform
from viz3d.hydrostudy import harmonic_frames
from viz3d.scene.hydro import hydro_model

from conftest import SCENES, scene_files

RESERVOIR_SCENE, EARTHQUAKE_SCENE = SCENES / "dam_reservoir.toml", SCENES / "dam_earthquake.toml"
EPS = np.finfo(float).eps
#: Round-off allowance: this many eps of the largest number in a sum.
ROUNDOFF = 1e3


def _run(scene, tmp_path, *overrides):
    """``viz3d run`` into tmp_path: (exit code, the .npz's arrays)."""
    out = tmp_path / f"{scene.stem}.npz"
    argv = ["run", str(scene), "--out", str(out)]
    for o in overrides:
        argv += ["--set", o]
    code = main(argv)
    with np.load(out) as data:
        return code, dict(data)


def test_the_hydrodynamics_scenes_ship_and_are_of_their_kind():
    assert {p.stem for p in scene_files("hydro")} == {"dam_reservoir", "dam_earthquake"}
    assert all(viz3d.load_scene(p).kind == "hydro" for p in scene_files("hydro"))
    assert all(viz3d.load_scene(p).kind == "multibody" for p in scene_files())
    assert main(["check", str(RESERVOIR_SCENE), str(EARTHQUAKE_SCENE)]) == 0


def test_every_scene_file_starts_with_a_comment_header_with_its_commands():
    for path in scene_files("hydro"):
        head = path.read_text().split("[scene]")[0]
        assert all(line.startswith("#") for line in head.strip().splitlines())
        assert f"viz3d run scenes/{path.name}" in head and f"viz3d view scenes/{path.name}" in head


def test_dam_reservoir_run_is_the_seed_example_with_its_references(tmp_path, capsys):
    code, a = _run(RESERVOIR_SCENE, tmp_path)
    out = capsys.readouterr().out
    assert code == 0 and "status      ok" in out
    for name in ("pressure_profiles.png", "dynamic_stiffness.png"):
        assert (tmp_path / "dam_reservoir" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    h, rho = SEED_DEPTH, SEED_RHO
    water = Reservoir(SEED_RHO, SEED_DEPTH, SEED_C)
    assert list(a["profile_omegas"]) == [0.0, 20.0, 80.0] and a["omega"].max() == 80.0 and a["omega"].size == 400
    # the arrays are the library's, computed the same way
    p = pressure(water, uniform(h), a["profile_omegas"], a["y"], rtol=1e-8)
    np.testing.assert_array_equal(a["pressure"], p.value)
    assert int(a["pressure_n_terms"]) == p.n_terms and float(a["pressure_bound"]) == p.bound
    assert p.bound <= 1e-8 * rho * h  # the reported bound meets the scene's sweep.rtol
    # the incompressible base pressure at omega = 0: 8 G / pi^2 rho a h within the series bound
    scale = rho * h
    assert abs(a["pressure"][0, 0] - BASE_PRESSURE_COEFFICIENT * scale) <= p.bound + ROUNDOFF * EPS * scale
    # first cut-off pi c / 2h, printed 23.45
    assert a["cutoffs"][0] == pytest.approx(SEED_FIRST_CUTOFF, abs=half_unit(SEED_FIRST_CUTOFF, 2))
    # incompressible S = -omega^2 A with A = 0.5428 rho h^2 (14 zeta(3) / pi^3 within the S bound)
    omega, S_inc = a["omega"][1:], a["S_incompressible"][1:, 0, 0]
    A = -S_inc / omega**2
    bound_A = float(a["S_bound"]) / omega.max() ** 2
    assert np.abs(A - RIGID_FORCE_COEFFICIENT * rho * h**2).max() <= bound_A + ROUNDOFF * EPS * rho * h**2
    assert RIGID_FORCE_COEFFICIENT == pytest.approx(CHOPRA_FORCE_COEFFICIENT, abs=half_unit(0.5428, 4))
    # energy leaves the dam: Im S >= 0, zero (to the bound) below the first cut-off of a rigid bottom
    S = a["S"][:, 0, 0]
    below = a["omega"] < a["cutoffs"][0]
    assert np.all(S.imag >= -float(a["S_bound"])) and np.abs(S[below].imag).max() <= float(a["S_bound"])
    assert np.any(S[~below].imag > 1e3 * float(a["S_bound"]))


def test_incompressible_override_removes_cutoffs_and_frequency_dependence(tmp_path):
    code, a = _run(RESERVOIR_SCENE, tmp_path, "reservoir.sound_speed=inf")
    assert code == 0 and a["cutoffs"].size == 0
    bound = float(a["pressure_bound"])
    assert np.abs(a["pressure"] - a["pressure"][0]).max() <= 2 * bound + ROUNDOFF * EPS * SEED_RHO * SEED_DEPTH
    np.testing.assert_array_equal(a["S"], a["S_incompressible"])


def test_dam_earthquake_run_agrees_with_the_library_and_the_water_lowers_omega_1(tmp_path, capsys):
    code, a = _run(EARTHQUAKE_SCENE, tmp_path)
    out = capsys.readouterr().out
    assert code == 0 and "status      ok" in out
    assert (tmp_path / "dam_earthquake" / "time_response.png").is_file()
    assert list(a["dam_cases"]) == ["empty", "incompressible", "compressible"]
    dam, record = cantilever_dam(), shipped_record()
    waters = [None, Reservoir(SEED_RHO, SEED_DEPTH), SEED_EXAMPLE]
    expected = [fundamental_frequency(dam, w) for w in waters]
    np.testing.assert_array_equal(a["dam_fundamental"], expected)
    assert expected[0] > expected[1] > expected[2]  # Chopra: the water lowers omega_1, compressibility more
    for k, water in enumerate(waters):
        r = frequency_response(dam, water, a["omega"])
        np.testing.assert_array_equal(a["dam_crest_acceleration"][k], r.crest_acceleration)
        t = time_response(dam, water, record)
        np.testing.assert_array_equal(a["dam_crest_displacement_t"][k], t.crest_displacement)
        np.testing.assert_array_equal(a["dam_base_shear_t"][k], t.base_shear)
    np.testing.assert_array_equal(a["dam_ground_acceleration"], record.acceleration)


def test_static_base_shear_is_the_dam_mass_plus_the_rigid_wall_added_mass():
    """At omega = 0 the dam moves with the ground: base shear per unit a_g = its mass + 0.5428 rho h^2
    (incompressible water; the series bound of the uniform shape is at most rtol rho h^2)."""
    dam, water, rtol = cantilever_dam(), Reservoir(SEED_RHO, SEED_DEPTH), 1e-8
    V = frequency_response(dam, water, [0.0], rtol=rtol).base_shear[0]
    exact = dam.bar.mass + RIGID_FORCE_COEFFICIENT * SEED_RHO * SEED_DEPTH**2
    assert abs(V - exact) <= rtol * SEED_RHO * SEED_DEPTH**2 + ROUNDOFF * EPS * exact
    assert frequency_response(dam, None, [0.0]).base_shear[0] == pytest.approx(dam.bar.mass, rel=ROUNDOFF * EPS)


def test_a_combination_of_shapes_is_the_combination_of_their_pressures():
    """``pressure(..., combination=c)`` (one sum for a dam's responding modes) against the shapes'
    pressures one by one, within the sum of their bounds."""
    dam = cantilever_dam()
    from viz3d.hydro.dam import wetted_shapes

    shapes = wetted_shapes(dam, SEED_DEPTH)
    rng = np.random.default_rng(13)
    omega = np.array([5.0, 20.0, 30.0])
    c = rng.normal(size=(omega.size, shapes.n_shapes)) + 1j * rng.normal(size=(omega.size, shapes.n_shapes))
    y, x = np.linspace(0.0, SEED_DEPTH, 7), np.linspace(0.0, 150.0, 7)
    combined = pressure(SEED_EXAMPLE, shapes, omega, y, x, rtol=1e-6, combination=c)
    parts = [pressure(SEED_EXAMPLE, lambda yy, j=j: shapes(yy)[:, j], omega, y, x, rtol=1e-6) for j in range(shapes.n_shapes)]
    reference = sum(part.value * c[:, j:j + 1] for j, part in enumerate(parts))
    tol = combined.bound + float((np.abs(c) @ np.array([part.bound for part in parts])).max())
    assert np.abs(combined.value - reference).max() <= tol
    assert tol < 1e-3 * np.abs(reference).max()  # the check is not vacuous
    with pytest.raises(ValueError, match="combination"):
        pressure(SEED_EXAMPLE, shapes, omega, y, x, combination=c[:, :2])


def test_harmonic_frames_are_the_real_part_of_the_pressure_cycle():
    model = hydro_model(viz3d.load_scene(RESERVOIR_SCENE, ["view.n_x=5", "view.n_y=4"]))
    frames = harmonic_frames(model, 20.0)
    X, Y = np.meshgrid(model.view.x, model.view.y, indexing="ij")
    p = pressure(model.reservoir, uniform(SEED_DEPTH), [20.0], Y.ravel(), X.ravel(), rtol=model.view.rtol).value[0]
    n = model.view.frames_per_cycle
    assert frames.pressure.shape == (n, 5, 4)
    np.testing.assert_allclose(frames.pressure[0].ravel(), p.real, rtol=0, atol=ROUNDOFF * EPS * np.abs(p).max())
    np.testing.assert_allclose(frames.pressure[n // 4].ravel(), -p.imag, rtol=0, atol=ROUNDOFF * EPS * np.abs(p).max())
    # the water's force on the wall over the cycle: added mass times the unit acceleration
    A = added_mass(model.reservoir, uniform(SEED_DEPTH), [20.0], rtol=model.view.rtol).value[0, 0, 0]
    assert frames.shear[0] == pytest.approx(A.real, rel=ROUNDOFF * EPS)


BAD = [
    (RESERVOIR_SCENE, ["reservoir.sound_speed=-1"], "reservoir.sound_speed", "a positive number"),
    (RESERVOIR_SCENE, ["reservoir.sound_speed=nan"], "reservoir.sound_speed", "inf (incompressible water)"),
    (RESERVOIR_SCENE, ["reservoir.reflection=1.5"], "reservoir.reflection", "(-1, 1]"),
    (RESERVOIR_SCENE, ["reservoir.sound_speed=inf", "reservoir.reflection=0.5"], "reservoir.reflection", "rigid bottom"),
    (RESERVOIR_SCENE, ["reservoir.bogus=1"], "reservoir.bogus", "unknown key"),
    (RESERVOIR_SCENE, ["sweep.n_omega=0"], "sweep.n_omega", "an integer 1..20000"),
    (RESERVOIR_SCENE, ["sweep.profile_omegas=[-1]"], "sweep.profile_omegas", "frequencies >= 0"),
    (RESERVOIR_SCENE, ["sweep.rtol=1"], "sweep.rtol", "relative tolerance"),
    (RESERVOIR_SCENE, ["view.n_x=1"], "view.n_x", "an integer 2..200"),
    (RESERVOIR_SCENE, ["ground_motion.record=shipped"], "ground_motion", "a [dam] table"),
    (RESERVOIR_SCENE, ["bodies=1"], "bodies", "unknown key"),
    (EARTHQUAKE_SCENE, ["reservoir.depth=150"], "reservoir.depth", "at most dam.height"),
    (EARTHQUAKE_SCENE, ["dam.modes=1000"], "dam.modes", "an integer 1..60"),
    (EARTHQUAKE_SCENE, ["dam.theory=rod"], "dam.theory", "one of"),
    (EARTHQUAKE_SCENE, ["ground_motion.record=file"], "ground_motion.file", "a file with record = 'file'"),
    (EARTHQUAKE_SCENE, ["ground_motion.record=file", "ground_motion.file='/etc/passwd'"], "ground_motion.file",
     "a file inside"),
    (EARTHQUAKE_SCENE, ["ground_motion.record=file", "ground_motion.file='missing.csv'"], "ground_motion.file",
     "a readable ground-acceleration CSV"),
]


@pytest.mark.parametrize("scene, overrides, key, expected", BAD, ids=lambda v: v if isinstance(v, str) else None)
def test_bad_keys_are_refused_naming_file_and_key(scene, overrides, key, expected, capsys):
    argv = ["check", str(scene)]
    for o in overrides:
        argv += ["--set", o]
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert f"{scene.name}" in lines[0] and f": {key}: expected " in lines[0] and expected in lines[0], lines[0]


def test_multibody_flags_are_refused_for_a_hydro_scene(capsys):
    assert main(["run", str(RESERVOIR_SCENE), "--t-end", "1"]) == 2
    assert "--t-end: expected no --t-end for a hydro scene" in capsys.readouterr().err


def test_a_users_csv_record_is_read_from_the_scene_folder(tmp_path):
    scene = tmp_path / "dam.toml"
    scene.write_text(EARTHQUAKE_SCENE.read_text())
    record = shipped_record()
    write_csv(record, tmp_path / "quake.csv")
    model = hydro_model(viz3d.load_scene(scene, ["ground_motion.record=file", "ground_motion.file='quake.csv'",
                                                 "ground_motion.scale=2.0"]))
    assert model.record.dt == pytest.approx(record.dt, rel=1e-9)
    np.testing.assert_allclose(model.record.acceleration, 2.0 * record.acceleration, rtol=1e-9, atol=1e-12)
    bad = tmp_path / "bad.csv"
    bad.write_text("time,acceleration\n0,1\n0.01,x\n")
    with pytest.raises(viz3d.scene.schema.SceneError, match=r"ground_motion.file.*line 3"):
        hydro_model(viz3d.load_scene(scene, ["ground_motion.record=file", "ground_motion.file='bad.csv'"]))

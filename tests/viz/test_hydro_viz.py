"""Hydrodynamics scenes in the viewer and the recorder: the .rrd reads back with the entities and
values written; the viser viewer builds its scene and streams the section without a browser."""

import asyncio
import time
import urllib.request

import numpy as np
import pytest
from test_viewer import _collect

import viz3d
from viz3d.cli import main
from viz3d.hydrostudy import earthquake_frames, harmonic_frames, run
from viz3d.viz.hydro_recorder import write_recording
from viz3d.viz.hydro_viewer import HydroViewer
from viz3d.viz.hydro_visuals import pressure_colors, pressure_scale

from conftest import SCENES
from recording import entities, read_column, read_scalars

#: A coarse section keeps these tests at about a second each.
SMALL = ["view.n_x=6", "view.n_y=4"]


def test_recording_of_the_earthquake_reads_back(tmp_path):
    result = run(viz3d.load_scene(SCENES / "dam_earthquake.toml", SMALL + ["view.frame_dt=0.1"]))
    frames = earthquake_frames(result.model)
    path = write_recording(tmp_path / "quake.rrd", result, frames)
    found = entities(path)
    for entity in ("/world/section", "/world/dam", "/plots/crest_displacement", "/plots/base_shear", "/curves/S/real",
                   "/curves/S/imag", "/curves/crest_acceleration/compressible", "/profiles/omega_20/real"):
        assert (entity, False) in found, entity
    assert ("/world/water_surface", True) in found
    t, crest = read_scalars(path, "/plots/crest_displacement")
    np.testing.assert_allclose(t, frames.t, rtol=0, atol=1e-9)  # sim_time is stored in whole ns
    np.testing.assert_array_equal(crest[:, 0], frames.crest)
    _, shear = read_scalars(path, "/plots/base_shear")
    np.testing.assert_array_equal(shear[:, 0], frames.shear)
    keys, S = read_column(path, "/curves/S/real", "Scalars:scalars", timeline="omega_mrad_s")
    np.testing.assert_array_equal(np.round(keys * 1e9), np.round(1e3 * result.sweep.omega))  # read as ns: undo
    np.testing.assert_array_equal(S[:, 0], result.sweep.stiffness[:, -1, -1].real)
    _, colors = read_column(path, "/world/section", "Mesh3D:vertex_colors")
    k = len(frames.t) // 2
    packed = pressure_colors(frames.pressure[k].ravel(), pressure_scale(frames)).astype(np.uint32)
    rgba = (packed[:, 0] << 24) | (packed[:, 1] << 16) | (packed[:, 2] << 8) | 255
    np.testing.assert_array_equal(np.asarray(colors[k], dtype=np.uint32).ravel(), rgba)


def test_cli_run_records_the_harmonic_cycle_of_a_rigid_wall(tmp_path):
    rrd = tmp_path / "wall.rrd"
    assert main(["run", str(SCENES / "dam_reservoir.toml"), "--out", str(tmp_path / "wall.npz"), "--record", str(rrd),
                 *sum((["--set", s] for s in SMALL), [])]) == 0
    t, crest = read_scalars(rrd, "/plots/crest_displacement")
    omega = 20.0  # view.omega of the scene: a unit acceleration moves the wall by -cos(omega t) / omega^2
    np.testing.assert_allclose(crest[:, 0], -np.cos(omega * t) / omega**2, rtol=0, atol=1e-6 / omega**2)


def test_viewer_builds_the_section_and_streams_it_without_a_browser():
    result = run(viz3d.load_scene(SCENES / "dam_reservoir.toml", SMALL))
    viewer = HydroViewer(result, port=0)
    try:
        url = viewer.start()
        assert url.startswith("http://127.0.0.1:")
        assert b'id="root"' in urllib.request.urlopen(url, timeout=5).read()
        messages = asyncio.run(_collect(viewer.port, 1.0))
        names = {m.get("name") for m in messages}
        assert {"/section", "/dam", "/water_surface"} <= names, names
        shown = viewer.frames_shown
        viewer.change(omega=30.0, compressible=False, rtol=1e-6)
        assert viewer.frames.label == "omega 30 rad/s, incompressible"
        np.testing.assert_array_equal(viewer.frames.pressure, harmonic_frames(result.model, 30.0, False, 1e-6).pressure)
        deadline = time.monotonic() + 5
        while viewer.frames_shown < shown + 5 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert viewer.frames_shown >= shown + 5
    finally:
        viewer.stop()


def test_view_command_serves_a_hydro_scene_and_stops(capsys):
    assert main(["view", str(SCENES / "dam_reservoir.toml"), "--port", "0", "--duration", "0.5",
                 *sum((["--set", s] for s in SMALL), [])]) == 0
    assert "viz3d viewer: open http://127.0.0.1:" in capsys.readouterr().out


@pytest.mark.parametrize("flag, value", [("--port", "99999"), ("--speed", "0")])
def test_viewer_flags_are_checked_for_hydro_scenes_too(flag, value, capsys):
    assert main(["view", str(SCENES / "dam_reservoir.toml"), flag, value]) == 2
    assert f"argument {flag}: expected" in capsys.readouterr().err

"""Flexible links coloured by bending stress and their deflection gauges in the sinks: the rerun
recording carries per-vertex colours and the deflection plots; the live viewer streams the
stress-coloured tube and its "Colour by stress" toggle switches it to the plain mesh (a websocket
client flips the checkbox as a browser does)."""

import asyncio
import time

import msgspec
import numpy as np
import viser
import websockets
from test_viewer import CAMERA, _decode

import viz3d
from viz3d.realtime import SimRunner, make_driver
from viz3d.viz.colors import StressColors
from viz3d.viz.recorder_rerun import RerunRecorder
from viz3d.viz.viewer_viser import Viewer

from conftest import SCENES
from recording import read_column, read_scalars

SCENE = SCENES / "flexible_four_bar.toml"
LINKS = ("coupler", "rocker")


class _Frames:
    """A sink keeping every frame (to compare the recording with)."""

    frame_dt = 0.0

    def __init__(self):
        self.frames = []

    def open(self, visuals):
        self.visuals = visuals

    def log(self, frame):
        self.frames.append(frame)

    def event(self, t, text, level="info"):
        pass

    def close(self):
        pass


def test_live_plots_and_trajectory_carry_the_midspan_deflections():
    driver = make_driver(viz3d.load_scene(SCENE))
    panels = dict(driver.plots)
    assert panels["Deflection [m]"] == ("coupler sag", "rocker sag")
    frame = driver.frame()
    assert {"deflection/coupler_sag", "deflection/rocker_sag"} <= set(frame.scalars)
    assert set(frame.stress) == set(LINKS) and all(s.shape == (len(frame.deformed[k]),) for k, s in frame.stress.items())


def test_recording_carries_vertex_colours_of_the_stress_and_the_deflection_plots(tmp_path):
    path, memory = tmp_path / "fourbar.rrd", _Frames()
    traj = viz3d.simulate(SCENE, ["sim.t_end=0.01"], sinks=[RerunRecorder(path), memory])
    assert list(traj.extras["deflection_names"]) == ["coupler_sag", "rocker_sag"]
    t, w = read_scalars(path, "/plots/deflection/coupler_sag")
    k = np.searchsorted(t, traj.t - 1e-9)
    np.testing.assert_array_equal(w[k, 0], traj.extras["deflection"][:, 0])
    scale = memory.visuals.stress_scale
    assert scale == 20e6                                      # the scene's [display] stress_scale
    by_t = {round(f.t, 9): f for f in memory.frames}
    for link in LINKS:
        tc, packed = read_column(path, f"/world/{link}", "Mesh3D:vertex_colors")
        packed = packed.reshape(len(tc), -1).astype(np.uint32)      # rerun stores 0xRRGGBBAA
        colours = np.stack([(packed >> s) & 0xFF for s in (24, 16, 8)], axis=-1).astype(np.uint8)
        assert colours.shape[1] == len(memory.frames[0].deformed[link])
        for when, rgb in zip(tc, colours):
            expected = StressColors(scale)(by_t[round(when, 9)].stress[link])
            np.testing.assert_array_equal(rgb, expected)
        assert len(np.unique(colours[-1], axis=0)) > 2, "the bent link should show several colours"


async def _toggle_session(port: int, seconds: float) -> tuple[list, list]:
    """Messages before and after the client unticks "Colour by stress"."""
    before, after = [], []
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"],
                                  max_size=None) as ws:
        await ws.send(msgspec.msgpack.encode(CAMERA))
        box = None
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                msgs = _decode(await asyncio.wait_for(ws.recv(), timeout=0.1))["messages"]
            except asyncio.TimeoutError:
                continue
            (after if box and box.get("sent") else before).extend(msgs)
            if box is None:
                found = [m for m in before if m["type"] == "GuiCheckboxMessage" and m["props"]["label"] == "Colour by stress"]
                box = {"uuid": found[0]["uuid"]} if found else None
            tube_updates = [m for m in before if m["type"] == "SceneNodeUpdateMessage"
                            and m["name"] == "/deformables/coupler_stress" and "batched_colors" in m["updates"]]
            if box and not box.get("sent") and len(tube_updates) >= 3:
                await ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": box["uuid"],
                                                      "updates": {"value": False}}))
                box["sent"] = True
                end = time.monotonic() + 2.0
    return before, after


def test_viewer_draws_stress_coloured_links_and_toggles_to_plain_colour():
    viewer = Viewer(SimRunner(viz3d.load_scene(SCENE)), port=0)
    try:
        viewer.start()
        before, after = asyncio.run(_toggle_session(viewer.server.get_port(), 20.0))
    finally:
        viewer.stop()
    boxes = [m for m in before if m["type"] == "GuiCheckboxMessage" and m["props"]["label"] == "Colour by stress"]
    assert boxes and boxes[0]["value"] is True
    tubes = [m for m in before if m["type"] == "BatchedMeshesMessage" and m["name"] == "/deformables/coupler_stress"]
    assert tubes, "no stress-coloured tube"
    colours = [np.asarray(m["updates"]["batched_colors"]).reshape(-1, 3) for m in before
               if m["type"] == "SceneNodeUpdateMessage" and m["name"] == "/deformables/coupler_stress"
               and "batched_colors" in m["updates"]]
    assert len(colours) >= 3
    assert after, "the toggle was never sent (no tube updates arrived)"
    plain = [m for m in after if m["type"] == "SceneNodeUpdateMessage" and m["name"] == "/deformables/coupler"
             and "vertices" in m["updates"]]
    hidden = [m for m in after if m["type"] == "SetSceneNodeVisibilityMessage" and m["name"] == "/deformables/coupler_stress"
              and m["visible"] is False]
    assert plain and hidden, "unticking the box should switch the link to its plain mesh"
    assert not viewer.flags["stress"]

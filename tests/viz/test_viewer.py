"""Live viewer without a browser: HTTP page, a websocket client speaking viser's subprotocol,
meshes and changing poses arriving; the real-time runner obeying its commands."""

import asyncio
import threading
import time
import urllib.request

import msgspec
import numpy as np
import pytest
import viser
import websockets
import zstandard

import viz3d
from viz3d.realtime import SimRunner
from viz3d.viz.recorder_rerun import RerunRecorder
from viz3d.viz.viewer_viser import Viewer

from conftest import SCENES

CONNECT_SECONDS = 2.0


def _decode(frame: bytes) -> dict:
    """viser 1.1.1 wire format: [u64 raw length][u64 zstd length][zstd msgpack][binary buffers,
    each 8-byte aligned]; arrays in the messages are placeholders {"__binary_index", "dtype"}."""
    raw_len = int.from_bytes(frame[0:8], "little")
    comp_len = int.from_bytes(frame[8:16], "little")
    body = msgspec.msgpack.decode(zstandard.ZstdDecompressor().decompress(frame[16:16 + comp_len], max_output_size=raw_len))
    buffers, offset = [], 16 + comp_len
    for n in body.get("binaryBufferLengths", ()):
        offset += (8 - offset % 8) % 8
        buffers.append(frame[offset:offset + n])
        offset += n
    return _resolve(body, buffers)


def _resolve(obj, buffers):
    if isinstance(obj, dict):
        if "__binary_index" in obj and "dtype" in obj:
            return np.frombuffer(buffers[obj["__binary_index"]], dtype=obj["dtype"])
        return {k: _resolve(v, buffers) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_resolve(v, buffers) for v in obj]
    return obj


#: What a browser reports once its 3D view is up (viser counts a client as connected from it).
CAMERA = {"type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [3.0, 3.0, 3.0], "fov": 1.3,
          "near": 0.01, "far": 1000.0, "image_height": 800, "image_width": 1280, "look_at": [0.0, 0.0, 0.0],
          "up_direction": [0.0, 0.0, 1.0]}


async def _collect(port: int, seconds: float, camera: bool = False, until=None) -> list[dict]:
    """Messages a websocket client receives in ``seconds`` (or until ``until(messages)``); with
    ``camera``, it first reports a camera as a browser does."""
    out = []
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"],
                                  max_size=None) as ws:
        if camera:
            await ws.send(msgspec.msgpack.encode(CAMERA))
        end = time.monotonic() + seconds
        while time.monotonic() < end and not (until and until(out)):
            try:
                out.extend(_decode(await asyncio.wait_for(ws.recv(), timeout=0.1))["messages"])
            except asyncio.TimeoutError:
                continue
    return out


def _positions(value) -> np.ndarray:
    return np.asarray(value).reshape(-1, 3)


def wait_for(pred, timeout=5.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return False


def test_viewer_serves_page_and_streams_meshes_and_moving_poses():
    t0 = time.monotonic()
    scene = viz3d.load_scene(SCENES / "chain.toml", ["chain.n=5"])
    viewer = Viewer(SimRunner(scene), port=0)
    try:
        url = viewer.start()
        assert url.startswith("http://127.0.0.1:")
        assert b'id="root"' in urllib.request.urlopen(url, timeout=5).read()
        messages = asyncio.run(_collect(viewer.server.get_port(), CONNECT_SECONDS))
    finally:
        viewer.stop()
    meshes = [m for m in messages if m["type"] == "BatchedMeshesMessage"]
    assert any(m["name"].startswith("/bodies/") for m in meshes)
    poses = [_positions(m["updates"]["batched_positions"]) for m in messages
             if m["type"] == "SceneNodeUpdateMessage" and m["name"] == "/bodies/group0" and "batched_positions" in m["updates"]]
    assert len(poses) >= 10, f"only {len(poses)} pose updates in {CONNECT_SECONDS} s"
    assert poses[0].shape == (5, 3)
    reach = np.linalg.norm(np.array(poses) - np.array([0.0, 0.0, 1.2]), axis=2).max()
    assert reach < 5 * 0.1, "link positions outside the chain's reach"
    assert np.abs(poses[-1] - poses[0]).max() > 1e-3, "the chain did not move"
    assert time.monotonic() - t0 < 15


def _runner(name="double_pendulum", overrides=None, **kw):
    runner = SimRunner(viz3d.load_scene(SCENES / f"{name}.toml", overrides), **kw)
    runner.start()
    return runner


def test_runner_commands_pause_step_reset_and_switch_integrator():
    runner = _runner(playing=False)
    try:
        dt = runner.sim.dt
        runner.command("step")
        assert wait_for(lambda: runner.snapshot.frame.t == pytest.approx(dt))
        runner.command("play")
        assert wait_for(lambda: runner.snapshot.frame.t > 0.05)
        runner.command("pause")
        time.sleep(0.2)
        t_paused = runner.snapshot.frame.t
        time.sleep(0.3)
        assert runner.snapshot.frame.t == t_paused and not runner.snapshot.playing
        runner.command("integrator", "heun")
        runner.command("dt", 2e-4)
        own = runner.scene.data["sim"]["formulation"]  # the scene's (the default: projection)
        assert wait_for(lambda: runner.snapshot.settings == {"integrator": "heun", "dt": 2e-4, "formulation": own})
        assert runner.sim.integrator.name == "heun" and runner.sim.state.t == t_paused   # state kept
        runner.command("reset")
        assert wait_for(lambda: runner.snapshot.frame.t == 0.0)
        runner.command("integrator", "nope")
        assert wait_for(lambda: "nope" in runner.snapshot.status)
    finally:
        runner.stop()


def test_runner_keeps_requested_speed_and_reports_achieved_factor():
    runner = _runner("spherical_pendulum", speed=0.5)
    try:
        time.sleep(2.0)
        snap = runner.snapshot
        assert 0.8 < snap.frame.t < 1.2, snap.frame.t                 # 0.5 x 2 s of wall time
        assert snap.rtf == pytest.approx(0.5, abs=0.1)
    finally:
        runner.stop()


def test_runner_that_cannot_keep_up_reports_it_instead_of_stalling():
    runner = _runner("chain", {"sim.t_end": 1e3}, speed=50.0)  # 10 links at 50x: beyond this machine (~20x with the kernel)
    try:
        time.sleep(2.0)
        snap = runner.snapshot
        assert 0.0 < snap.rtf < 45.0 and snap.frame.t > 0.1
        assert wait_for(lambda: runner.snapshot.frame.t > snap.frame.t)  # still advancing
    finally:
        runner.stop()


def test_scene_switch_and_bad_scene(write_scene):
    runner = _runner(playing=False)
    try:
        runner.command("scene", str(SCENES / "heavy_top.toml"))
        assert wait_for(lambda: runner.snapshot.visuals.name == "heavy_top" and runner.snapshot.generation == 2)
        bad = write_scene("[sim]\ndt = -1\n")
        runner.command("scene", str(bad))
        assert wait_for(lambda: "sim.dt" in runner.snapshot.status)
        assert runner.snapshot.visuals.name == "heavy_top"               # kept the working scene
    finally:
        runner.stop()


def test_viewer_recording_is_closed_and_readable(tmp_path):
    from recording import read_scalars

    path = tmp_path / "view.rrd"
    runner = _runner("spherical_pendulum", sinks=[RerunRecorder(path)])
    time.sleep(1.0)
    runner.stop()
    t, e = read_scalars(path, "/plots/energy/total")
    assert len(t) > 100 and np.all(np.diff(t) > 0)


def test_impact_scene_runs_live_and_streams_the_deforming_bar():
    scene = viz3d.load_scene(SCENES / "impact_clamped_bar.toml")
    runner = SimRunner(scene)
    assert runner.speed == pytest.approx(2e-5)             # the scene's [display] speed
    viewer = Viewer(runner, port=0)
    try:
        viewer.start()
        messages = asyncio.run(_collect(viewer.server.get_port(), CONNECT_SECONDS))
        snap = runner.snapshot
    finally:
        viewer.stop()
    assert 5e-6 < snap.frame.t < 1e-4                          # about 2e-5 x 2 s of wall time
    gauges = [g["name"] for g in scene.data["gauges"]]
    assert [title for title, _ in snap.plots] == ["Energy [J]", "Contact force [N]", "Energy ledger [J]", "Gauge strain [-]"]
    assert snap.history.shape[1] == 1 + 3 + 1 + 3 + len(gauges)  # t, 3 energies, contact force, 3 ledger terms, gauges
    bars = [np.asarray(m["updates"]["vertices"]).reshape(-1, 3) for m in messages
            if m["type"] == "SceneNodeUpdateMessage" and m["name"] == "/deformables/bar" and "vertices" in m["updates"]]
    assert len(bars) >= 5 and np.abs(bars[-1] - bars[0]).max() > 1e-6  # the struck end moves (amplified)


def test_switch_between_multibody_and_impact_scenes():
    runner = _runner(playing=False)
    try:
        runner.command("scene", str(SCENES / "bouncing_sphere.toml"))
        assert wait_for(lambda: runner.snapshot.settings == {} and runner.snapshot.plots[1][0] == "Contact force [N]")
        runner.command("integrator", "heun")
        assert wait_for(lambda: "adaptive steps with contact events keep their own" in runner.snapshot.status)
        runner.command("scene", str(SCENES / "heavy_top.toml"))
        assert wait_for(lambda: "integrator" in runner.snapshot.settings and runner.snapshot.generation == 3)
    finally:
        runner.stop()


# ---------------------------------------------------------------- issue 8: start, camera, plots, speed


def _last(messages, kind, key, initial=None):
    """The value ``key`` of the last message of type ``kind`` (optionally with that ``initial`` flag)."""
    found = [m[key] for m in messages if m["type"] == kind and (initial is None or m.get("initial") == initial)]
    assert found, f"no {kind} received"
    return np.asarray(found[-1], float)


def test_run_waits_for_the_first_client_then_starts():
    runner = SimRunner(viz3d.load_scene(SCENES / "chain.toml", ["chain.n=5"]))
    viewer = Viewer(runner, port=0)
    try:
        viewer.start()
        assert wait_for(lambda: runner.snapshot.waiting), "the runner does not say it waits for a client"
        time.sleep(0.5)
        assert runner.snapshot.frame.t == 0.0 and runner.snapshot.waiting   # nothing simulated unseen
        assert wait_for(lambda: "waiting for a browser" in viewer.status.content), viewer.status.content
        asyncio.run(_collect(viewer.server.get_port(), 0.5))                # a plain websocket client counts
        assert wait_for(lambda: runner.snapshot.frame.t > 0.0) and not runner.snapshot.waiting
    finally:
        viewer.stop()


def test_paused_viewer_stays_paused_when_a_client_connects():
    runner = SimRunner(viz3d.load_scene(SCENES / "double_pendulum.toml"), playing=False)
    viewer = Viewer(runner, port=0)
    try:
        viewer.start()
        asyncio.run(_collect(viewer.server.get_port(), 0.5))
        assert wait_for(lambda: not runner.snapshot.waiting)
        time.sleep(0.3)
        assert runner.snapshot.frame.t == 0.0 and not runner.snapshot.playing
    finally:
        viewer.stop()


def _sphere_in_view(position, look_at, fov, centre, radius):
    """(angle of the sphere's far edge from the view axis, its angular radius) [rad]."""
    axis, to_centre = look_at - position, centre - position
    off_axis = np.arccos(np.clip(axis @ to_centre / np.linalg.norm(axis) / np.linalg.norm(to_centre), -1, 1))
    half = np.arcsin(min(1.0, radius / np.linalg.norm(to_centre)))
    return off_axis + half, half


def test_camera_frames_the_whole_reach_of_a_hanging_chain():
    n, link = 50, 0.1
    viewer = Viewer(SimRunner(viz3d.load_scene(SCENES / "chain.toml", [f"chain.n={n}"])), port=0)
    try:
        viewer.start()
        assert wait_for(lambda: viewer.frames_shown > 0)
        messages = asyncio.run(_collect(viewer.server.get_port(), 0.5))
    finally:
        viewer.stop()
    position = _last(messages, "SetCameraPositionMessage", "position")
    look_at = _last(messages, "SetCameraLookAtMessage", "look_at")
    fov = float(_last(messages, "SetCameraFovMessage", "fov"))
    anchor, reach = np.array([0.0, 0.0, 1.2]), n * link          # the chain can hang straight down
    edge, half = _sphere_in_view(position, look_at, fov, anchor, reach)
    assert edge <= 0.5 * fov + 1e-6, "part of the chain's reach is out of view"
    assert half >= 0.8 * 0.5 * fov, f"the chain's reach fills only {half / (0.5 * fov):.0%} of the view"


def test_scene_change_reframes_connected_browsers():
    from viz3d.scene.build import build
    from viz3d.scene.visuals import scene_visuals
    from viz3d.viz.viewer_viser import CAMERA_FOV, camera_framing

    chain = viz3d.load_scene(SCENES / "chain.toml")
    position, look_at = camera_framing(scene_visuals(chain, build(chain)[0]), CAMERA_FOV)
    runner = SimRunner(viz3d.load_scene(SCENES / "double_pendulum.toml"))
    viewer = Viewer(runner, port=0)

    def moved(out):  # this client's own camera (not the initial one) now looks at the chain
        looks = [m["look_at"] for m in out if m["type"] == "SetCameraLookAtMessage" and not m.get("initial")]
        return bool(looks) and np.allclose(looks[-1], look_at, atol=1e-6)

    try:
        viewer.start()
        switch = threading.Timer(0.8, lambda: runner.command("scene", str(chain.path)))
        switch.start()
        messages = asyncio.run(_collect(viewer.server.get_port(), 30.0, camera=True, until=moved))
        switch.join()
    finally:
        viewer.stop()
    assert moved(messages), "the connected client's camera was not moved to the new scene"
    np.testing.assert_allclose(_last(messages, "SetCameraPositionMessage", "position", initial=False), position,
                               atol=1e-6)


def test_plot_values_get_a_unit_prefix_so_axis_labels_stay_short():
    runner = SimRunner(viz3d.load_scene(SCENES / "impact_clamped_bar.toml"), speed=2e-4)
    viewer = Viewer(runner, port=0)
    try:
        viewer.start()
        asyncio.run(_collect(viewer.server.get_port(), 0.2))
        assert wait_for(lambda: runner.snapshot.history[:, 4].max() > 2e3, timeout=30)   # force above 2 kN
        assert wait_for(lambda: viewer.plots[1].title == "Contact force [kN]"), viewer.plots[1].title
        force = viewer.plots[1].data[1]
        assert 1.0 < np.max(np.abs(force)) < 1000.0
        assert viewer.plots[1].series[0]["label"] in ("t [µs]", "t [ms]")
        assert np.max(viewer.plots[1].data[0]) < 1000.0
    finally:
        viewer.stop()


def test_plot_scale_picks_an_engineering_prefix():
    from viz3d.viz.viewer_viser import unit_scale, with_prefix

    assert unit_scale(39157.0) == (1e-3, "k")
    assert unit_scale(5.0) == (1.0, "") and unit_scale(0.0) == (1.0, "")
    assert unit_scale(2.0e-8) == (1e9, "n") and unit_scale(4e-4) == (1e6, "µ")
    assert with_prefix("Contact force [N]", "k") == "Contact force [kN]"
    assert with_prefix("Gauge strain [-]", "µ") == "Gauge strain [1e-6]"
    assert with_prefix("Energy [J]", "") == "Energy [J]" and with_prefix("Count", "k") == "Count [x 1e3]"


def test_scene_switch_keeps_the_new_scene_speed_exactly():
    runner = SimRunner(viz3d.load_scene(SCENES / "double_pendulum.toml"))
    viewer = Viewer(runner, port=0)
    try:
        viewer.start()
        runner.command("scene", str(SCENES / "impact_bronze_ball.toml"))
        assert wait_for(lambda: viewer._generation == 2, timeout=60)   # building the bar takes seconds
        time.sleep(0.3)
        assert runner.speed == 5e-5 and runner.snapshot.speed == 5e-5   # not 10 ** -4.3 from the slider
    finally:
        viewer.stop()


@pytest.mark.parametrize("speed", [10.0, 1e-9])
def test_any_positive_speed_is_accepted_by_the_speed_control(speed):
    runner = SimRunner(viz3d.load_scene(SCENES / "double_pendulum.toml"), speed=speed)
    viewer = Viewer(runner, port=0)   # the log10-speed slider used to refuse values outside [-6, 0.6]
    try:
        viewer.start()
        assert wait_for(lambda: viewer.frames_shown > 0)
        assert runner.speed == speed and viewer.speed.min <= np.log10(speed) <= viewer.speed.max
    finally:
        viewer.stop()


def test_posts_are_streamed_as_static_meshes():
    viewer = Viewer(SimRunner(viz3d.load_scene(SCENES / "robot_arm.toml")), port=0)
    try:
        viewer.start()
        assert wait_for(lambda: viewer.frames_shown > 0)
        messages = asyncio.run(_collect(viewer.server.get_port(), 0.5))
    finally:
        viewer.stop()
    posts = [m for m in messages if m["type"] == "MeshMessage" and m["name"] == "/statics/posts"]
    assert posts, "no post drawn"
    z = np.asarray(posts[-1]["props"]["vertices"]).reshape(-1, 3)[:, 2]
    assert z.min() == pytest.approx(0.0, abs=1e-6) and z.max() >= 1.8


def test_adaptive_scene_shows_its_own_integrator_and_step_greyed_out():
    """An adaptive run keeps its own settings: the controls show them (not rk4 at 1 ms), disabled."""
    scene = viz3d.load_scene(SCENES / "flexible_slider_crank.toml")
    sim = scene.data["sim"]
    assert sim["integrator"] != "rk4" and "rtol" in sim
    runner = SimRunner(scene)
    viewer = Viewer(runner, port=0)
    try:
        viewer.start()
        assert wait_for(lambda: viewer.integrator.disabled, timeout=30)   # set when the first frame is shown
        assert viewer.integrator.value == sim["integrator"] and viewer.dt.value == sim["dt"]
        assert viewer.integrator.disabled and viewer.dt.disabled and viewer.stabilization.disabled
        assert viewer.stabilization.value == {v: k for k, v in viewer._stab.items()}[sim["formulation"]]
    finally:
        viewer.stop()


def test_links_that_leave_the_run_are_streamed_at_scale_zero(write_scene):
    from departing import HAUL

    viewer = Viewer(SimRunner(viz3d.load_scene(write_scene(HAUL))), port=0)

    def scales(messages):
        return [np.asarray(m["updates"]["batched_scales"]).reshape(-1) for m in messages
                if m["type"] == "SceneNodeUpdateMessage" and m["name"].startswith("/bodies/")
                and m["updates"].get("batched_scales") is not None]

    try:
        viewer.start()
        messages = asyncio.run(_collect(viewer.server.get_port(), 10.0, camera=True,
                                        until=lambda out: any((s == 0).sum() >= 2 for s in scales(out))))
    finally:
        viewer.stop()
    shown = [s for s in scales(messages) if s.size == 6]  # the links' batch (the winch has its own)
    assert shown, "no scale updates: no link left the run within 10 s"
    assert (shown[0] == 0).sum() == 1 and (shown[-1] == 0).sum() == 2  # link0 at 0.51 s, then link1 at 0.91 s
    assert all(set(s.tolist()) <= {0.0, 1.0} for s in shown)


def test_a_defect_in_the_runner_pauses_it_with_the_error_as_its_status(monkeypatch):
    """An unexpected exception (here from a plot's reader) stops the live run with a diagnosis on show,
    not a frozen view reading "ok"; commands are still served (Reset)."""
    from viz3d.realtime import Driver

    values = Driver.plot_values

    def failing(self, frame):
        if frame.t > 0.05:
            raise KeyError("stowage/hawse_tension")
        return values(self, frame)

    monkeypatch.setattr(Driver, "plot_values", failing)
    runner = _runner()
    try:
        assert wait_for(lambda: "internal error" in runner.snapshot.status)
        snap = runner.snapshot
        assert not snap.playing and "KeyError" in snap.status and "t = " in snap.status
        runner.command("reset")
        assert wait_for(lambda: runner.snapshot.frame.t == 0.0)
    finally:
        runner.stop()

"""Live viser viewer of a hydrodynamics scene: the dam and a vertical section of its reservoir
coloured by pressure (vertex colours), animated through the harmonic cycle or the earthquake.

Controls: play/pause, motion (harmonic cycle or, with a dam and a record, the earthquake), omega,
compressible water on/off, and the series tolerance (the terms it takes are shown). A control
change recomputes the frames on a worker thread (``viz3d.hydrostudy``); the display loop only
shows the latest frames. Server, address checks and camera framing are the multibody viewer's
(``viz3d.viz.viewer_viser``).
"""

from __future__ import annotations

import math
import threading
import time
from types import SimpleNamespace

import numpy as np

from viz3d.hydrostudy import HydroRun, SectionFrames, earthquake_frames, harmonic_frames
from viz3d.viz.hydro_visuals import CONCRETE_COLOR, WATER_COLOR, geometry, pressure_colors, pressure_scale
from viz3d.viz.viewer_viser import CAMERA_FOV, camera_framing, check_address, wait_until

#: Display rate [Hz]; log10 tolerance range of the control.
DISPLAY_RATE = 30.0
RTOL_RANGE = (-10.0, -1.0)
MOTIONS = {"harmonic": "harmonic cycle", "earthquake": "earthquake record"}


class HydroViewer:
    """Serve the study ``result`` (``viz3d.hydrostudy.run``) on ``host``:``port`` (``ServeError`` if it
    cannot be served; the real port is ``port``, the page ``url``). ``speed``: simulated seconds per
    wall-clock second."""

    def __init__(self, result: HydroRun, host: str = "127.0.0.1", port: int = 8080, speed: float = 1.0,
                 playing: bool = True):
        import viser

        check_address(host, port)
        model = result.model
        self.model, self.result, self.speed, self.playing = model, result, speed, playing
        self._lock, self._stop = threading.Lock(), threading.Event()
        self.settings = {"motion": "harmonic", "omega": model.view.omega, "compressible": model.reservoir.compressible,
                         "rtol": model.view.rtol}
        self.frames = self.compute(self.settings)
        self.server = viser.ViserServer(host=host, port=port, label="viz3d", verbose=False)
        try:
            self.port = self.server.get_port()
            self.url = f"http://{f'[{host}]' if ':' in host else host}:{self.port}"
            self.frames_shown, self.time = 0, 0.0
            self._build_gui()
            self._build_scene()
        except BaseException:
            self.server.stop()
            raise
        self._thread = threading.Thread(target=self._loop, name="viz3d-hydro-display", daemon=True)

    # ------------------------------------------------------------------ frames

    def compute(self, settings: dict) -> SectionFrames:
        """The frames of ``settings`` (motion, omega, compressible, rtol)."""
        if settings["motion"] == "earthquake":
            return earthquake_frames(self.model, settings["compressible"], settings["rtol"])
        return harmonic_frames(self.model, settings["omega"], settings["compressible"], settings["rtol"])

    def change(self, **settings) -> None:
        """Recompute the frames with changed settings (on the calling thread; GUI callbacks run on
        viser's pool) and show them from the next display tick."""
        new = {**self.settings, **settings}
        self.status.content = "**computing...**"
        frames = self.compute(new)
        with self._lock:
            self.settings, self.frames, self.time = new, frames, 0.0
            self._p_max = pressure_scale(frames)

    # ------------------------------------------------------------------ scene and GUI

    def _build_scene(self) -> None:
        scene, frames = self.server.scene, self.frames
        self.geometry = geometry(self.model, frames)
        g = self.geometry
        self._p_max = pressure_scale(frames)
        scene.add_mesh_simple("/water_surface", g.surface_vertices, g.surface_faces, color=tuple(WATER_COLOR[:3].tolist()),
                              opacity=WATER_COLOR[3] / 255, side="double")
        self.dam = scene.add_mesh_simple("/dam", g.dam_at(frames.face[0]), g.dam_faces,
                                         color=tuple(CONCRETE_COLOR.tolist()), flat_shading=True)
        lo = np.minimum(g.section_vertices.min(axis=0), g.dam_vertices.min(axis=0))
        hi = np.maximum(g.section_vertices.max(axis=0), g.dam_vertices.max(axis=0))
        position, look_at = camera_framing(SimpleNamespace(bounds=(lo, hi), reach=np.zeros((0, 4))), CAMERA_FOV)
        self.server.initial_camera.fov = CAMERA_FOV
        self.server.initial_camera.position, self.server.initial_camera.look_at = tuple(position), tuple(look_at)
        self.server.initial_camera.far = max(self.server.initial_camera.far, 4.0 * float(np.linalg.norm(position - look_at)))
        self.show(0)

    def _build_gui(self) -> None:
        gui, m = self.server.gui, self.model
        self.status = gui.add_markdown("**viz3d**")
        with gui.add_folder("Animation"):
            play = gui.add_button("Play / Pause")
            motions = ("harmonic", "earthquake") if m.dam is not None and m.record is not None else ("harmonic",)
            self.motion = gui.add_dropdown("Motion", motions, initial_value="harmonic")
            self.omega = gui.add_slider("omega [rad/s]", min=0.0, max=float(m.omega.max()), step=0.5,
                                        initial_value=float(self.settings["omega"]))
            self.compressible = gui.add_checkbox("Compressible", initial_value=self.settings["compressible"],
                                                 disabled=not m.reservoir.compressible)
            self.rtol = gui.add_slider("log10 tolerance", min=RTOL_RANGE[0], max=RTOL_RANGE[1], step=0.5,
                                       initial_value=round(math.log10(self.settings["rtol"]) * 2) / 2)
        play.on_click(lambda _: setattr(self, "playing", not self.playing))
        self.motion.on_update(lambda _: self.change(motion=self.motion.value))
        self.omega.on_update(lambda _: self.change(omega=float(self.omega.value)))
        self.compressible.on_update(lambda _: self.change(compressible=bool(self.compressible.value)))
        self.rtol.on_update(lambda _: self.change(rtol=10.0 ** float(self.rtol.value)))
        self._build_plot()

    def _build_plot(self) -> None:
        import viser.uplot as up

        sweep = self.result.sweep
        k = sweep.shape_names.index("uniform")
        S = sweep.stiffness[:, k, k] / 1e9
        S = np.where(np.isfinite(S), S, np.nan)
        self.server.gui.add_uplot(
            data=(sweep.omega, S.real, S.imag),
            series=(up.Series(label="omega [rad/s]"), up.Series(label="Re S", stroke="blue", width=2),
                    up.Series(label="Im S", stroke="red", width=2)),
            title="S(omega) of the uniform wall [GN/m]", scales={"x": {"time": False}}, aspect=1.6)

    # ------------------------------------------------------------------ display

    def show(self, k: int) -> None:
        """Draw frame ``k`` of the current frames."""
        with self._lock:
            frames, p_max = self.frames, self._p_max
        k = k % frames.t.size
        colors = pressure_colors(frames.pressure[k].ravel(), p_max)
        mesh = _colored_mesh(self.geometry.section_vertices, self.geometry.section_faces, colors)
        with self.server.atomic():
            self.server.scene.add_mesh_trimesh("/section", mesh)
            self.dam.vertices = self.geometry.dam_at(frames.face[k]).astype(np.float32)
        self.status.content = (f"**{self.model.name}**: {frames.label}; t = {frames.t[k]:.3f} s  \n"
                               f"{frames.n_terms} series terms; |p| up to {p_max / 1e3:.4g} kPa; crest "
                               f"{1e3 * frames.crest[k]:+.3f} mm")
        self.frames_shown += 1

    def _frame_index(self) -> int:
        """The frame at the animation time (frames loop)."""
        with self._lock:
            t, frames = self.time, self.frames
        period = frames.t[-1] + (frames.t[1] - frames.t[0] if frames.t.size > 1 else 1.0)
        return int(np.searchsorted(frames.t, t % period, side="right") - 1)

    def _loop(self) -> None:
        while not self._stop.is_set():
            tick = time.perf_counter()
            if self.playing:
                with self._lock:
                    self.time += self.speed / DISPLAY_RATE
            self.show(self._frame_index())
            time.sleep(max(0.0, 1.0 / DISPLAY_RATE - (time.perf_counter() - tick)))

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> str:
        self._thread.start()
        return self.url

    def wait(self, timeout: float | None = None) -> None:
        """Block until ``timeout`` [s] (None: forever), Ctrl-C, or ``stop``."""
        wait_until(self._stop, timeout)

    def stop(self) -> None:
        self._stop.set()
        if self._thread.ident is not None:
            self._thread.join(timeout=5.0)
        self.server.stop()


def _colored_mesh(vertices: np.ndarray, faces: np.ndarray, colors: np.ndarray):
    """A trimesh with per-vertex colours (viser draws vertex colours of GLB meshes)."""
    import trimesh

    rgba = np.column_stack([colors, np.full(len(colors), 255, dtype=np.uint8)])
    return trimesh.Trimesh(vertices, faces, vertex_colors=rgba, process=False)

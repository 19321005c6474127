"""Live viser viewer: draws the runner's latest frame at the display rate and wires the GUI.

Bodies with the same geometry are drawn as one batched mesh (one array update per frame for the
whole batch), so a 50-link chain costs a handful of messages per frame. GUI callbacks run on
viser's thread pool; they only enqueue commands for the simulation thread (``SimRunner``) and
never touch the simulation. viser's ``wxyz`` quaternion order is produced here only.

The run is held until the first client connects (what nobody watched is not simulated). Every
client's camera is pointed at the scene's box and the reach of what hangs from ground joints,
from a distance where that fits the field of view, when it connects and when the scene changes.
Plots are drawn in a unit with an SI prefix chosen so tick labels stay short (uPlot prints
"40,000" or rounds 2e-8 to "0" otherwise).

Flexible bodies are drawn coloured by their surface bending stress (``StressTube``; the "Colour by
stress" toggle switches to their plain colour). viser 1.1.1's ``add_mesh_simple`` takes one colour
per mesh; a GLB carries vertex colours, but a changed GLB is parsed again in the browser and its
node drawn empty until the parse ends (a flicker every frame), so a tube's facets are instances of
one unit quad in a batched mesh, which takes a colour per instance.
"""

from __future__ import annotations

import errno
import math
import socket
import threading
import time
from pathlib import Path

import numpy as np

from viz3d.frames import DeformableVisual, Frame, SceneVisuals
from viz3d.realtime import DISPLAY_RATE, SimRunner, Snapshot
from viz3d.rotations import quat_from_matrix
from viz3d.viz.colors import StressColors

#: Plot refresh rate [Hz] and window [s of simulated time].
PLOT_RATE = 8.0
PLOT_WINDOW = 10.0
AXIS_COLORS = np.array([[220, 50, 50], [50, 170, 50], [50, 90, 220]], dtype=np.uint8)
#: GUI labels of the formulations (names from the runner's ``options``).
STABILIZATION_LABELS = {"index1": "none (index-1)", "baumgarte": "Baumgarte", "projection": "projection"}
#: Camera: vertical field of view [rad], direction from the scene towards it, and the margin on
#: the distance at which the scene's bounding sphere exactly fills the field of view.
CAMERA_FOV = math.radians(60.0)
VIEW_DIRECTION = np.array([0.9, -1.3, 0.7]) / np.linalg.norm([0.9, -1.3, 0.7])
FRAME_MARGIN = 1.1
#: Range of the log10-speed control (widened to hold any requested speed).
SPEED_RANGE = (-6.0, 0.6)
#: SI prefixes of plot units, by power of ten.
PREFIXES = {-12: "p", -9: "n", -6: "µ", -3: "m", 0: "", 3: "k", 6: "M", 9: "G", 12: "T"}
#: Width of the plots' y axis [CSS px]: room for a label such as "-1,000".
Y_AXIS_SIZE = 60
#: The facet of a stress-coloured tube: a unit square in its xy plane, centred on its origin.
QUAD_VERTICES = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]], np.float32)
QUAD_FACES = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
#: Show-folder checkboxes: flag -> label.
FLAG_LABELS = {"frames": "Frames", "joints": "Joints", "springs": "Springs", "forces": "Forces",
               "stress": "Colour by stress"}


class ServeError(OSError):
    """The viewer cannot serve on the requested address: the message names it and the OS reason,
    ``flag`` the command-line flag at fault ("--host" or "--port")."""

    def __init__(self, message: str, flag: str = "--host"):
        super().__init__(message)
        self.flag = flag


def check_address(host: str, port: int) -> None:
    """Raise ``ServeError`` unless a server socket can be bound on ``host``.

    viser's constructor retries the next port on any ``OSError`` and never returns when every
    attempt fails (a host that is not an address of this machine), so this is checked first. A
    busy ``port`` is accepted: viser then serves on the next free one (``Viewer.port``).
    """
    try:
        infos = socket.getaddrinfo(host or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (socket.gaierror, UnicodeError) as exc:
        raise ServeError(f"cannot serve on host {host!r}: {getattr(exc, 'strerror', None) or exc}") from None
    except OverflowError:
        raise ServeError(f"port {port} is not a port number (0..65535)", "--port") from None
    for family, kind, proto, _, address in infos:
        with socket.socket(family, kind, proto) as sock:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as asyncio's server does
            try:
                sock.bind(address)
            except OSError as exc:
                if exc.errno == errno.EADDRINUSE and port < 65535:
                    continue
                flag = "--port" if exc.errno in (errno.EACCES, errno.EADDRINUSE) else "--host"
                raise ServeError(f"cannot serve on host {host!r}, port {port}: {exc.strerror or exc}", flag) from None


def view_sphere(visuals: SceneVisuals) -> tuple[np.ndarray, float]:
    """Centre [m] and radius [m] of a sphere holding the scene's box and every reach sphere."""
    lo, hi = np.asarray(visuals.bounds, float)
    reach = np.asarray(visuals.reach, float).reshape(-1, 4)
    box_lo = np.minimum(lo, (reach[:, :3] - reach[:, 3:]).min(axis=0, initial=np.inf))
    box_hi = np.maximum(hi, (reach[:, :3] + reach[:, 3:]).max(axis=0, initial=-np.inf))
    centre = 0.5 * (box_lo + box_hi)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    radius = max(np.max(np.linalg.norm(corners - centre, axis=1)),
                 np.max(np.linalg.norm(reach[:, :3] - centre, axis=1) + reach[:, 3], initial=0.0))
    return centre, float(max(radius, 1e-3))


def camera_framing(visuals: SceneVisuals, fov: float = CAMERA_FOV) -> tuple[np.ndarray, np.ndarray]:
    """Camera ``(position, look_at)`` [m] from which ``view_sphere`` fills a vertical field of view
    ``fov`` [rad] (with ``FRAME_MARGIN``), seen from ``VIEW_DIRECTION``."""
    centre, radius = view_sphere(visuals)
    distance = FRAME_MARGIN * radius / math.sin(0.5 * fov)
    return centre + distance * VIEW_DIRECTION, centre


def time_unit(t_end: float) -> tuple[float, str]:
    """Scale and SI prefix of the times shown for a run of duration ``t_end`` [s]: seconds for
    runs of 10 ms and longer, else the prefix that makes ``t_end`` at least 1 (an impact's µs)."""
    return (1.0, "") if t_end >= 1e-2 else unit_scale(t_end)


def unit_scale(peak: float) -> tuple[float, str]:
    """``(factor, prefix)``: values up to ``peak`` (>= 0) times ``factor`` lie in [1, 1000)."""
    if not (math.isfinite(peak) and peak > 0):
        return 1.0, ""
    power = int(min(12, max(-12, 3 * math.floor(math.log10(peak) / 3))))
    return 10.0 ** -power, PREFIXES[power]


def with_prefix(title: str, prefix: str) -> str:
    """``title`` ("Contact force [N]") with its unit prefixed ("Contact force [kN]"); a unitless
    quantity ("[-]") gets the power of ten instead ("[1e-6]")."""
    if not prefix:
        return title
    power = next(k for k, v in PREFIXES.items() if v == prefix)
    head, bracket, unit = title.rpartition(" [")
    if not (bracket and unit.endswith("]")):
        return f"{title} [x 1e{power}]"
    unit = unit[:-1]
    return f"{head} [{prefix}{unit}]" if unit not in ("-", "") else f"{head} [1e{power}]"


class StressTube:
    """A deformable tube drawn coloured by stress: each facet between two neighbouring sections and
    two neighbouring ring points (zero-width facets of repeated ring points left out) is an instance
    of ``QUAD_VERTICES`` in one batched mesh, placed at its corners' mean, turned to its mean axial
    and ring edges, scaled to their lengths (a rectangle: exact for an undeformed tube, a facet of
    a bent one is a trapezoid whose sides differ by its width times the bend between sections) and
    coloured by its corners' mean stress. Per frame: four arrays, whatever the facet count."""

    def __init__(self, scene, d: DeformableVisual, visible: bool):
        m = d.ring
        P = np.asarray(d.vertices, float).reshape(-1, m, 3)
        j = np.arange(m)
        width = np.linalg.norm(P[:, (j + 1) % m] - P[:, j], axis=2).max(axis=0)         # (m,) [m]
        j = j[width > 1e-6 * width.max()]
        i = np.arange(len(P) - 1)[:, None]
        #: (Q, 4) vertex indices of each facet: (i, j), (i, j + 1), (i + 1, j), (i + 1, j + 1)
        self.corners = np.stack([i * m + j, i * m + (j + 1) % m, (i + 1) * m + j, (i + 1) * m + (j + 1) % m],
                                axis=-1).reshape(-1, 4)
        q = len(self.corners)
        self.handle = scene.add_batched_meshes_simple(
            f"/deformables/{d.name}_stress", QUAD_VERTICES, QUAD_FACES, np.tile([1.0, 0.0, 0.0, 0.0], (q, 1)),
            np.zeros((q, 3)), batched_scales=np.ones((q, 3)), batched_colors=np.tile(d.color, (q, 1)), lod="off",
            side="double", visible=visible)

    def show(self, vertices: np.ndarray, stress: np.ndarray, colors: StressColors) -> None:
        """Place and colour the facets from the tube's vertices (V, 3) [m] and stresses (V,) [Pa]."""
        p = np.asarray(vertices, float)[self.corners]                                    # (Q, 4, 3)
        along = 0.5 * (p[:, 2] - p[:, 0] + p[:, 3] - p[:, 1])
        across = 0.5 * (p[:, 1] - p[:, 0] + p[:, 3] - p[:, 2])
        a = np.maximum(np.linalg.norm(along, axis=1), 1e-12)
        ex = along / a[:, None]
        across -= np.sum(across * ex, axis=1)[:, None] * ex
        b = np.maximum(np.linalg.norm(across, axis=1), 1e-12)
        ey = across / b[:, None]
        R = np.stack([ex, ey, np.cross(ex, ey)], axis=2)                                 # columns: facet axes
        h = self.handle
        h.batched_positions = p.mean(axis=1).astype(np.float32)
        h.batched_wxyzs = quat_from_matrix(R).astype(np.float32)
        h.batched_scales = np.column_stack([a, b, np.ones_like(a)]).astype(np.float32)
        h.batched_colors = colors(np.asarray(stress, float)[self.corners].mean(axis=1))


class SceneNodes:
    """The viser scene-tree nodes of one scene, updated from frames."""

    def __init__(self, server, visuals: SceneVisuals):
        self.server, self.visuals = server, visuals
        scene = server.scene
        scene.reset()
        lo, hi = visuals.bounds
        centre, radius = view_sphere(visuals)
        size = float(max(2.0, 2.5 * np.max(hi - lo), 3.0 * radius))
        scene.add_grid("/ground", width=size, height=size, plane="xy", cell_size=_nice(size / 20),
                       section_size=_nice(size / 4), position=(centre[0], centre[1], min(0.0, lo[2])))
        self.groups = self._add_bodies(visuals)
        self._left = False  # a body has left the run: the batches' scales are sent from then on
        for st in visuals.statics:
            scene.add_mesh_simple(f"/statics/{st.name}", st.vertices, st.faces, color=tuple(int(c) for c in st.color))
        s, w = visuals.length_scale, visuals.thickness
        nj = len(visuals.joint_names)
        self.frames = scene.add_line_segments("/frames", np.zeros((3 * len(visuals.bodies), 2, 3), np.float32),
                                              colors=np.tile(AXIS_COLORS, (len(visuals.bodies), 1))[:, None, :].repeat(2, 1),
                                              thickness=0.15 * w, visible=False)
        self.joints = self._add_joints(nj, 0.7 * w) if nj else None
        self.springs = (scene.add_line_segments("/springs", np.zeros((len(visuals.spring_names), 2, 3), np.float32),
                                                colors=(70, 70, 70), thickness=0.15 * w) if visuals.spring_names else None)
        self.forces = (scene.add_arrows("/forces", np.zeros((nj, 2, 3), np.float32), colors=(200, 30, 30),
                                        shaft_radius=0.2 * w, head_radius=0.5 * w, head_length=0.15 * s, visible=False)
                       if nj else None)
        self.deformables = {d.name: scene.add_mesh_simple(f"/deformables/{d.name}", d.vertices, d.faces,
                                                         color=tuple(int(c) for c in d.color))
                            for d in visuals.deformables}
        self.stress_tubes = {d.name: StressTube(scene, d, visible=False) for d in visuals.deformables if d.ring}
        self.stress_colors = StressColors(visuals.stress_scale)
        self.contacts = scene.add_arrows("/contacts", np.zeros((1, 2, 3), np.float32), colors=(220, 30, 30),
                                         shaft_radius=0.3 * w, head_radius=0.7 * w, head_length=0.2 * s, visible=False)
        self.peak_force = 0.0
        self.camera = camera_framing(visuals, CAMERA_FOV)
        server.initial_camera.fov = CAMERA_FOV              # for clients that connect later
        server.initial_camera.position = tuple(self.camera[0])
        server.initial_camera.look_at = tuple(self.camera[1])
        far = 4.0 * float(np.linalg.norm(self.camera[0] - self.camera[1]))
        if far > server.initial_camera.far:
            server.initial_camera.far = far

    def frame_client(self, client) -> None:
        """Point a connected client's camera at the scene (viser lists a client, and calls its
        connect callbacks, once the client has reported its camera)."""
        position, look_at = self.camera
        client.camera.fov = CAMERA_FOV
        client.camera.position = position   # moves look_at along: set look_at after it
        client.camera.look_at = look_at

    def _add_bodies(self, visuals: SceneVisuals) -> list[tuple[object, np.ndarray]]:
        groups: dict[str, list[int]] = {}
        for i, b in enumerate(visuals.bodies):
            if b.vertices.size:  # a flexible body has no rigid mesh: it is a deformable
                groups.setdefault(b.group, []).append(i)
        out = []
        for k, members in enumerate(groups.values()):
            b = visuals.bodies[members[0]]
            colors = np.array([visuals.bodies[i].color for i in members], dtype=np.uint8)
            handle = self.server.scene.add_batched_meshes_simple(
                f"/bodies/group{k}", b.vertices, b.faces, np.tile([1.0, 0.0, 0.0, 0.0], (len(members), 1)),
                np.zeros((len(members), 3)), batched_colors=colors)
            out.append((handle, np.array(members)))
        return out

    def _add_joints(self, nj: int, radius: float):
        import trimesh

        ball = trimesh.creation.icosphere(subdivisions=2, radius=radius)
        return self.server.scene.add_batched_meshes_simple(
            "/joints", ball.vertices, ball.faces, np.tile([1.0, 0.0, 0.0, 0.0], (nj, 1)), np.zeros((nj, 3)),
            batched_colors=np.full((nj, 3), 40, dtype=np.uint8))

    def show(self, frame: Frame, flags: dict) -> None:
        """Push one frame (inside one ``atomic`` block so poses never split across messages)."""
        gone = np.isnan(frame.W_r[:, 0])  # bodies that have left the run (viz3d.departures): drawn at scale 0
        W_r = np.where(gone[:, None], 0.0, frame.W_r)
        R_WB = np.where(gone[:, None, None], np.eye(3), frame.R_WB)
        wxyz = quat_from_matrix(R_WB)
        self._left = self._left or bool(gone.any())
        with self.server.atomic():
            for handle, idx in self.groups:
                handle.batched_positions = W_r[idx].astype(np.float32)
                handle.batched_wxyzs = wxyz[idx].astype(np.float32)
                if self._left:
                    handle.batched_scales = (~gone[idx]).astype(np.float32)
            if flags["frames"]:
                ell = np.array([b.radius for b in self.visuals.bodies])[:, None, None] * 1.2 * ~gone[:, None, None]
                tips = W_r[:, None, :] + ell * np.swapaxes(R_WB, 1, 2)
                seg = np.stack([np.repeat(W_r, 3, axis=0), tips.reshape(-1, 3)], axis=1)
                self.frames.points = seg.astype(np.float32)
            self.frames.visible = flags["frames"]
            held = ~np.isnan(frame.joint_points[:, 0])  # (joints that left with a body: NaN)
            points = np.where(held[:, None], frame.joint_points, 0.0)
            if self.joints is not None:
                self.joints.batched_positions = points.astype(np.float32)
                if self._left:
                    self.joints.batched_scales = held.astype(np.float32)
                self.joints.visible = flags["joints"]
            if self.springs is not None:
                self.springs.points = frame.springs.astype(np.float32)
                self.springs.visible = flags["springs"]
            if self.forces is not None:
                vec = np.where(held[:, None], frame.reaction_force, 0.0) * (2.0 * self.visuals.length_scale
                                                                           / self.visuals.force_scale)
                self.forces.points = np.stack([points, points + vec], axis=1).astype(np.float32)
                self.forces.visible = flags["forces"]
            self._show_deformables(frame, flags["stress"])
            self._show_contacts(frame, flags["forces"])

    def _show_deformables(self, frame: Frame, by_stress: bool) -> None:
        """Deformed meshes, each as its stress-coloured tube (``by_stress``, when the frame has its
        stresses) or in its plain colour; only what is shown is updated."""
        if by_stress:
            self.stress_colors.observe(frame.stress.values())
        for name, handle in self.deformables.items():
            tube = self.stress_tubes.get(name)
            coloured = by_stress and tube is not None and name in frame.stress
            if coloured:
                tube.show(frame.deformed[name], frame.stress[name], self.stress_colors)
            else:
                handle.vertices = frame.deformed[name]
            handle.visible = not coloured
            if tube is not None:
                tube.handle.visible = coloured

    def _show_contacts(self, frame: Frame, visible: bool) -> None:
        """Contact forces as arrows ending at the contact point; the largest force so far draws
        three length scales."""
        if not len(frame.contact_points):
            self.contacts.visible = False
            return
        self.peak_force = max(self.peak_force, float(np.max(np.linalg.norm(frame.contact_forces, axis=1))))
        vec = frame.contact_forces * (3.0 * self.visuals.length_scale / self.peak_force)
        self.contacts.points = np.stack([frame.contact_points - vec, frame.contact_points], axis=1).astype(np.float32)
        self.contacts.visible = visible


def _nice(x: float) -> float:
    """A round number (1, 2 or 5 times a power of ten) near ``x``."""
    e = 10.0 ** np.floor(np.log10(x))
    return float(min((1, 2, 5, 10), key=lambda m: abs(m * e - x)) * e)


class Viewer:
    """The live viewer: a viser server, a ``SimRunner`` and a display loop.

    Parameters
    ----------
    runner : SimRunner
    host, port : str, int
        Where to serve (port 0 picks a free port, a busy one the next free one; the real one is
        ``port`` and in ``url``). ``ServeError`` if ``host`` cannot be served on.
    scenes_dir : Path
        Directory listed by the scene picker.
    wait_for_client : bool
        Hold the run until the first client (a browser, or any websocket client of viser's
        protocol) connects; ``runner.playing`` then decides whether it plays.
    """

    def __init__(self, runner: SimRunner, host: str = "127.0.0.1", port: int = 8080, scenes_dir: Path | None = None,
                 display_rate: float = DISPLAY_RATE, wait_for_client: bool = True):
        import viser

        check_address(host, port)
        self.runner, self.display_rate = runner, display_rate
        if wait_for_client:
            runner.command("wait")
        self.server = viser.ViserServer(host=host, port=port, label="viz3d", verbose=False)
        try:
            self.port = self.server.get_port()
            self.url = f"http://{f'[{host}]' if ':' in host else host}:{self.port}"
            self.scenes_dir = scenes_dir or runner.scene.path.parent
            self.flags = {"frames": False, "joints": True, "springs": True, "forces": False, "stress": True}
            self.frames_shown = 0
            self._stop = threading.Event()
            self._nodes: SceneNodes | None = None
            self._generation = -1
            self._echo = False      # True while the display sets controls itself (not a user's change)
            self._plot_units: list[tuple[str, str]] = []
            self._build_gui()
            _on_any_connection(self.server, lambda: runner.command("connected"))
            self.server.on_client_connect(self._frame_client)
        except BaseException:
            self.server.stop()
            raise
        self._thread = threading.Thread(target=self._loop, name="viz3d-display", daemon=True)

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> str:
        if not self.runner.is_alive():
            self.runner.start()
        self._thread.start()
        return self.url

    def stop(self) -> None:
        self._stop.set()
        if self._thread.ident is not None:
            self._thread.join(timeout=5.0)
        self.runner.stop()
        self.server.stop()

    def wait(self, timeout: float | None = None) -> None:
        """Block until ``timeout`` [s] has passed (None: forever), Ctrl-C, or ``stop`` from another thread."""
        wait_until(self._stop, timeout)

    # ------------------------------------------------------------------ clients

    def _frame_client(self, client) -> None:
        nodes = self._nodes
        if nodes is not None:
            nodes.frame_client(client)

    # ------------------------------------------------------------------ GUI

    def _build_gui(self) -> None:
        gui, cmd = self.server.gui, self.runner.command
        snap = self.runner.snapshot
        self.status = gui.add_markdown("**viz3d**")
        with gui.add_folder("Simulation"):
            self.play = gui.add_button("Play / Pause", icon=None)
            step = gui.add_button("Step")
            reset = gui.add_button("Reset")
            log_speed = _log_speed(self.runner.speed)
            self.speed = gui.add_slider("log10 speed", min=min(SPEED_RANGE[0], log_speed),
                                        max=max(SPEED_RANGE[1], log_speed), step=0.1, initial_value=log_speed,
                                        hint="simulated seconds per wall-clock second, as a power of ten")
            settings = self._shown_settings(snap)
            self.integrator = gui.add_dropdown("Integrator", self.runner.options["integrator"],
                                               initial_value=settings["integrator"])
            self.dt = gui.add_number("dt [s]", initial_value=float(settings["dt"]), min=1e-7, step=1e-5)
            self._stab = {STABILIZATION_LABELS.get(f, f): f for f in self.runner.options["formulation"]}
            label = {v: k for k, v in self._stab.items()}[settings["formulation"]]
            self.stabilization = gui.add_dropdown("Stabilization", tuple(self._stab), initial_value=label)
            scenes = tuple(sorted(p.stem for p in self.scenes_dir.glob("*.toml") if _is_multibody(p)))
            current = self.runner.scene.path.stem
            self.scene = gui.add_dropdown("Scene", scenes if current in scenes else (current, *scenes), initial_value=current)
        with gui.add_folder("Show"):
            boxes = {key: gui.add_checkbox(FLAG_LABELS[key], initial_value=val) for key, val in self.flags.items()}
        self.plots: list = []

        def user(fn):
            """A control callback that ignores the display's own settings of the control (viser
            calls callbacks on programmatic changes too: a rounded echo would change the run)."""
            return lambda _: None if self._echo else fn()

        self.play.on_click(lambda _: cmd("toggle"))
        step.on_click(lambda _: cmd("step"))
        reset.on_click(lambda _: cmd("reset"))
        self.speed.on_update(user(lambda: cmd("speed", 10.0 ** self.speed.value)))
        self.integrator.on_update(user(lambda: cmd("integrator", self.integrator.value)))
        self.dt.on_update(user(lambda: cmd("dt", self.dt.value)))
        self.stabilization.on_update(user(lambda: cmd("formulation", self._stab[self.stabilization.value])))
        self.scene.on_update(user(lambda: self._pick_scene(self.scene.value)))
        for key, box in boxes.items():
            box.on_update(lambda _, key=key, box=box: self.flags.__setitem__(key, box.value))

    def _pick_scene(self, stem: str) -> None:
        path = self.scenes_dir / f"{stem}.toml"
        if path != self.runner.scene.path:
            self.runner.command("scene", str(path))

    # ------------------------------------------------------------------ display loop

    def _loop(self) -> None:
        next_plot, shown = 0.0, None
        while not self._stop.is_set():
            tick = time.perf_counter()
            snap = self.runner.snapshot
            if snap is not None:
                if snap is not shown:  # a snapshot is shown once (the runner publishes at most at this rate)
                    self._show(snap)
                    shown = snap
                if tick >= next_plot:
                    self._plots(snap)
                    next_plot = tick + 1.0 / PLOT_RATE
            time.sleep(max(0.0, 1.0 / self.display_rate - (time.perf_counter() - tick)))

    def _show(self, snap: Snapshot) -> None:
        if snap.generation != self._generation:
            self._nodes = SceneNodes(self.server, snap.visuals)
            for client in self.server.get_clients().values():
                self._nodes.frame_client(client)
            self._generation = snap.generation
            self._sync_controls(snap)
        self._nodes.show(snap.frame, self.flags)
        self.frames_shown += 1

    def _shown_settings(self, snap: Snapshot) -> dict:
        """The integrator, step and formulation the controls show: the run's when it can change them,
        else (greyed out) the scene's own, e.g. an adaptive run's dopri5 (impact scenes have none)."""
        from viz3d.scene.spec import SIM

        sim = self.runner.scene.data.get("sim", {})
        return {**{k: sim.get(k, SIM.fields[k].default) for k in ("integrator", "dt", "formulation")},
                **snap.settings}

    def _sync_controls(self, snap: Snapshot) -> None:
        """Match the controls to a newly loaded scene: its plots, its speed, what can be changed."""
        self._echo = True
        try:
            if self.scene.value != self.runner.scene.path.stem and self.runner.scene.path.stem in self.scene.options:
                self.scene.value = self.runner.scene.path.stem
            fixed_steps = bool(snap.settings)  # adaptive runs with contact events keep their own settings
            for handle in (self.integrator, self.dt, self.stabilization):
                handle.disabled = not fixed_steps
            settings = self._shown_settings(snap)
            self.integrator.value, self.dt.value = settings["integrator"], float(settings["dt"])
            log_speed = _log_speed(snap.speed)
            self.speed.min, self.speed.max = min(SPEED_RANGE[0], log_speed), max(SPEED_RANGE[1], log_speed)
            self.speed.value = log_speed
        finally:
            self._echo = False
        self._build_plots(snap.plots)

    def _build_plots(self, spec) -> None:
        import viser.uplot as up

        for handle in self.plots:
            handle.remove()
        colors = ("red", "blue", "black", "green", "purple", "orange")
        self.plots, self._plot_units = [], []
        for title, labels in spec:
            series = (up.Series(label="t [s]"),) + tuple(
                up.Series(label=lab, stroke=colors[i % len(colors)], width=2) for i, lab in enumerate(labels))
            self.plots.append(self.server.gui.add_uplot(
                data=tuple(np.zeros(1) for _ in series), series=series, title=title,
                scales={"x": {"time": False}}, axes=({}, {"size": Y_AXIS_SIZE}), aspect=1.6))
            self._plot_units.append(("", ""))

    def _plots(self, snap: Snapshot) -> None:
        h = snap.history
        if len(h) == 0:
            return
        h = h[h[:, 0] >= h[-1, 0] - PLOT_WINDOW]
        # the time unit from the run's duration: an impact's microseconds get a prefix (uPlot shows 2e-4 as "0")
        t_scale, t_prefix = time_unit(snap.t_end)
        col = 1
        for k, (handle, (title, labels)) in enumerate(zip(self.plots, snap.plots)):
            values = h[:, col:col + len(labels)]
            scale, prefix = unit_scale(float(np.max(np.abs(values))))
            if self._plot_units[k] != (t_prefix, prefix):   # a new unit: relabel before new data
                self._plot_units[k] = (t_prefix, prefix)
                handle.title = with_prefix(title, prefix)
                handle.series = ({**handle.series[0], "label": f"t [{t_prefix}s]"}, *handle.series[1:])
            handle.data = (h[:, 0] * t_scale, *(values[:, i] * scale for i in range(len(labels))))
            col += len(labels)
        self.status.content = _status(snap)


def _is_multibody(path: Path) -> bool:
    """Whether the scene picker offers ``path`` (this viewer runs multibody scenes; hydrodynamics
    scenes have their own, ``viz3d.viz.hydro_viewer``; unreadable files stay listed and fail when picked)."""
    from viz3d.scene.load import kind_of_file
    from viz3d.scene.schema import SceneError

    try:
        return kind_of_file(path) == "multibody"
    except SceneError:
        return True


def wait_until(stop: threading.Event, timeout: float | None = None) -> None:
    """Block until ``timeout`` [s] has passed (None: forever), Ctrl-C, or ``stop`` is set."""
    end = time.monotonic() + (math.inf if timeout is None else timeout)
    try:
        while not stop.is_set() and time.monotonic() < end:
            time.sleep(min(0.2, max(0.0, end - time.monotonic())))
    except KeyboardInterrupt:
        pass


def _status(snap: Snapshot) -> str:
    """The panel's status lines."""
    state = ("waiting for a browser to connect" if snap.waiting else "playing" if snap.playing else "paused")
    status = "" if snap.status == "ok" else f"  \n**{snap.status}**"
    scale, prefix = time_unit(snap.t_end)
    t_txt = f"{scale * snap.frame.t:.4g} {prefix}s"
    return (f"**{snap.visuals.name}** &nbsp; t = {t_txt} &nbsp; ({state}, speed {snap.speed:.3g}x)"
            f"  \nreal-time factor achieved: **{snap.rtf:.2f}**{status}")


def _log_speed(speed: float) -> float:
    """The speed control's value: log10 of ``speed``, to its 0.1 step."""
    return round(math.log10(speed), 1)


def _on_any_connection(server, callback) -> None:
    """Call ``callback()`` when any websocket client of viser's protocol connects, a browser or
    a script. viser's own ``on_client_connect`` waits for the client's first camera report
    (0.5-1 s after a browser connects here; never, for a script), so this hooks the websocket
    server's connection callback instead (viser 1.1.1: ``ViserServer._websock_server``)."""
    websock = getattr(server, "_websock_server", None)
    if websock is None:  # a viser without it: its client connection is the next best moment
        server.on_client_connect(lambda _client: callback())
        return
    websock.on_client_connect(lambda _connection: callback())

"""Live viser viewer: draws the runner's latest frame at the display rate and wires the GUI.

Bodies with the same geometry are drawn as one batched mesh (one array update per frame for the
whole batch), so a 50-link chain costs a handful of messages per frame. GUI callbacks run on
viser's thread pool; they only enqueue commands for the simulation thread (``SimRunner``) and
never touch the simulation. viser's ``wxyz`` quaternion order is produced here only.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np

from viz3d.frames import Frame, SceneVisuals
from viz3d.realtime import DISPLAY_RATE, SimRunner, Snapshot
from viz3d.rotations import quat_from_matrix

#: Plot refresh rate [Hz] and window [s of simulated time].
PLOT_RATE = 8.0
PLOT_WINDOW = 10.0
AXIS_COLORS = np.array([[220, 50, 50], [50, 170, 50], [50, 90, 220]], dtype=np.uint8)
#: GUI labels of the formulations (names from the runner's ``options``).
STABILIZATION_LABELS = {"index1": "none (index-1)", "baumgarte": "Baumgarte", "projection": "projection"}


class SceneNodes:
    """The viser scene-tree nodes of one scene, updated from frames."""

    def __init__(self, server, visuals: SceneVisuals):
        self.server, self.visuals = server, visuals
        scene = server.scene
        scene.reset()
        lo, hi = visuals.bounds
        size = float(max(2.0, 2.5 * np.max(hi - lo)))
        scene.add_grid("/ground", width=size, height=size, plane="xy", cell_size=_nice(size / 20),
                       section_size=_nice(size / 4), position=(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), min(0.0, lo[2])))
        self.groups = self._add_bodies(visuals)
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
        self.contacts = scene.add_arrows("/contacts", np.zeros((1, 2, 3), np.float32), colors=(220, 30, 30),
                                         shaft_radius=0.3 * w, head_radius=0.7 * w, head_length=0.2 * s, visible=False)
        self.peak_force = 0.0
        extent = float(max(0.3, np.max(hi - lo)))
        server.initial_camera.position = tuple(0.5 * (lo + hi) + np.array([0.9, -1.3, 0.7]) * extent)
        server.initial_camera.look_at = tuple(0.5 * (lo + hi))

    def _add_bodies(self, visuals: SceneVisuals) -> list[tuple[object, np.ndarray]]:
        groups: dict[str, list[int]] = {}
        for i, b in enumerate(visuals.bodies):
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
        wxyz = quat_from_matrix(frame.R_WB)
        with self.server.atomic():
            for handle, idx in self.groups:
                handle.batched_positions = frame.W_r[idx].astype(np.float32)
                handle.batched_wxyzs = wxyz[idx].astype(np.float32)
            if flags["frames"]:
                ell = np.array([b.radius for b in self.visuals.bodies])[:, None, None] * 1.2
                tips = frame.W_r[:, None, :] + ell * np.swapaxes(frame.R_WB, 1, 2)
                seg = np.stack([np.repeat(frame.W_r, 3, axis=0), tips.reshape(-1, 3)], axis=1)
                self.frames.points = seg.astype(np.float32)
            self.frames.visible = flags["frames"]
            if self.joints is not None:
                self.joints.batched_positions = frame.joint_points.astype(np.float32)
                self.joints.visible = flags["joints"]
            if self.springs is not None:
                self.springs.points = frame.springs.astype(np.float32)
                self.springs.visible = flags["springs"]
            if self.forces is not None:
                vec = frame.reaction_force * (2.0 * self.visuals.length_scale / self.visuals.force_scale)
                self.forces.points = np.stack([frame.joint_points, frame.joint_points + vec], axis=1).astype(np.float32)
                self.forces.visible = flags["forces"]
            for name, handle in self.deformables.items():
                handle.vertices = frame.deformed[name]
            self._show_contacts(frame, flags["forces"])

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
        Where to serve (port 0 picks a free port; the real one is in ``url``).
    scenes_dir : Path
        Directory listed by the scene picker.
    """

    def __init__(self, runner: SimRunner, host: str = "127.0.0.1", port: int = 8080, scenes_dir: Path | None = None,
                 display_rate: float = DISPLAY_RATE):
        import viser

        self.runner, self.display_rate = runner, display_rate
        self.server = viser.ViserServer(host=host, port=port, label="viz3d", verbose=False)
        self.url = f"http://{host}:{self.server.get_port()}"
        self.scenes_dir = scenes_dir or runner.scene.path.parent
        self.flags = {"frames": False, "joints": True, "springs": True, "forces": False}
        self.frames_shown = 0
        self._stop = threading.Event()
        self._nodes: SceneNodes | None = None
        self._generation = -1
        self._build_gui()
        self._thread = threading.Thread(target=self._loop, name="viz3d-display", daemon=True)

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> str:
        if not self.runner.is_alive():
            self.runner.start()
        self._thread.start()
        return self.url

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.runner.stop()
        self.server.stop()

    def wait(self) -> None:
        """Block until Ctrl-C (or ``stop`` from another thread)."""
        try:
            while not self._stop.is_set():
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass

    # ------------------------------------------------------------------ GUI

    def _build_gui(self) -> None:
        gui, cmd = self.server.gui, self.runner.command
        snap = self.runner.snapshot
        self.status = gui.add_markdown("**viz3d**")
        with gui.add_folder("Simulation"):
            self.play = gui.add_button("Play / Pause", icon=None)
            step = gui.add_button("Step")
            reset = gui.add_button("Reset")
            self.speed = gui.add_slider("log10 speed", min=-6.0, max=0.6, step=0.1,
                                        initial_value=round(float(np.log10(self.runner.speed)), 1),
                                        hint="simulated seconds per wall-clock second, as a power of ten")
            settings = {"integrator": "rk4", "dt": 1e-3, "formulation": "index1", **snap.settings}  # impact: none
            self.integrator = gui.add_dropdown("Integrator", self.runner.options["integrator"],
                                               initial_value=settings["integrator"])
            self.dt = gui.add_number("dt [s]", initial_value=float(settings["dt"]), min=1e-7, step=1e-5)
            self._stab = {STABILIZATION_LABELS.get(f, f): f for f in self.runner.options["formulation"]}
            label = {v: k for k, v in self._stab.items()}[settings["formulation"]]
            self.stabilization = gui.add_dropdown("Stabilization", tuple(self._stab), initial_value=label)
            scenes = tuple(sorted(p.stem for p in self.scenes_dir.glob("*.toml")))
            current = self.runner.scene.path.stem
            self.scene = gui.add_dropdown("Scene", scenes if current in scenes else (current, *scenes), initial_value=current)
        with gui.add_folder("Show"):
            boxes = {key: gui.add_checkbox(key.capitalize(), initial_value=val) for key, val in self.flags.items()}
        self.plots: list = []

        self.play.on_click(lambda _: cmd("toggle"))
        step.on_click(lambda _: cmd("step"))
        reset.on_click(lambda _: cmd("reset"))
        self.speed.on_update(lambda _: cmd("speed", 10.0 ** self.speed.value))
        self.integrator.on_update(lambda _: cmd("integrator", self.integrator.value))
        self.dt.on_update(lambda _: cmd("dt", self.dt.value))
        self.stabilization.on_update(lambda _: cmd("formulation", self._stab[self.stabilization.value]))
        self.scene.on_update(lambda _: self._pick_scene(self.scene.value))
        for key, box in boxes.items():
            box.on_update(lambda _, key=key, box=box: self.flags.__setitem__(key, box.value))

    def _pick_scene(self, stem: str) -> None:
        path = self.scenes_dir / f"{stem}.toml"
        if path != self.runner.scene.path:
            self.runner.command("scene", str(path))

    # ------------------------------------------------------------------ display loop

    def _loop(self) -> None:
        next_plot = 0.0
        while not self._stop.is_set():
            tick = time.perf_counter()
            snap = self.runner.snapshot
            if snap is not None:
                self._show(snap)
                if tick >= next_plot:
                    self._plots(snap)
                    next_plot = tick + 1.0 / PLOT_RATE
            time.sleep(max(0.0, 1.0 / self.display_rate - (time.perf_counter() - tick)))

    def _show(self, snap: Snapshot) -> None:
        if snap.generation != self._generation:
            self._nodes = SceneNodes(self.server, snap.visuals)
            self._generation = snap.generation
            self._sync_controls(snap)
        self._nodes.show(snap.frame, self.flags)
        self.frames_shown += 1

    def _sync_controls(self, snap: Snapshot) -> None:
        """Match the controls to a newly loaded scene: its plots, its speed, what can be changed."""
        if self.scene.value != self.runner.scene.path.stem and self.runner.scene.path.stem in self.scene.options:
            self.scene.value = self.runner.scene.path.stem
        rigid = snap.kind == "rigid"
        for handle in (self.integrator, self.dt, self.stabilization):
            handle.disabled = not rigid
        if rigid:
            self.integrator.value, self.dt.value = snap.settings["integrator"], float(snap.settings["dt"])
        self.speed.value = round(float(np.log10(snap.speed)), 1)
        self._build_plots(snap.plots)

    def _build_plots(self, spec) -> None:
        import viser.uplot as up

        for handle in self.plots:
            handle.remove()
        colors = ("red", "blue", "black", "green", "purple", "orange")
        self.plots = []
        for title, labels in spec:
            series = (up.Series(label="t [s]"),) + tuple(
                up.Series(label=lab, stroke=colors[i % len(colors)], width=2) for i, lab in enumerate(labels))
            self.plots.append(self.server.gui.add_uplot(
                data=tuple(np.zeros(1) for _ in series), series=series, title=title,
                scales={"x": {"time": False}}, aspect=1.6))

    def _plots(self, snap: Snapshot) -> None:
        h = snap.history
        if len(h) == 0:
            return
        window = PLOT_WINDOW if snap.kind == "rigid" else np.inf
        h = h[h[:, 0] >= h[-1, 0] - window]
        col = 1
        for handle, (_, labels) in zip(self.plots, snap.plots):
            handle.data = (h[:, 0], *(h[:, col + i] for i in range(len(labels))))
            col += len(labels)
        state = "playing" if snap.playing else "paused"
        status = "" if snap.status == "ok" else f"  \n**{snap.status}**"
        t_txt = f"{snap.frame.t:.3f} s" if snap.kind == "rigid" else f"{1e6 * snap.frame.t:.1f} us"
        self.status.content = (f"**{snap.visuals.name}** &nbsp; t = {t_txt} &nbsp; ({state}, speed {snap.speed:.3g}x)"
                               f"  \nreal-time factor achieved: **{snap.rtf:.2f}**{status}")

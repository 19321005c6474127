"""Real-time driver of the live viewer (the simulation side; the display is viz/viewer_viser.py).

A thread advances a scene in (scaled) real time, takes commands from GUI callbacks through a
queue, and publishes the latest ``Frame``.

The runner never waits for the display: it steps until simulated time catches up with
``speed x`` wall time (or a frame's worth of wall time is spent), publishes a frame at most at
the display rate, and measures the real-time factor it actually achieves. When it cannot keep
up, it drops the backlog instead of stalling, and the achieved factor shows it.
"""

from __future__ import annotations

import queue
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viz3d.diagnosis import SimulationFailure
from viz3d.formulation import FORMULATIONS
from viz3d.frames import Frame, SceneVisuals, frame_from_state
from viz3d.integrators import INTEGRATORS, make_integrator
from viz3d.scene.build import build, make_formulation
from viz3d.scene.load import Scene, load_scene
from viz3d.scene.schema import SceneError
from viz3d.scene.visuals import scene_visuals
from viz3d.simulate import Simulation

#: Frames published per second of wall time [Hz].
DISPLAY_RATE = 60.0
#: Length of the plot history kept (frames).
HISTORY = 1200
#: Window over which the achieved real-time factor is measured [s of wall time].
RTF_WINDOW = 1.0
#: A backlog larger than this [s of wall time] is dropped (the runner cannot keep up).
MAX_LAG = 0.25


@dataclass
class Snapshot:
    """What the display reads (replaced as a whole, never mutated after publication)."""

    generation: int                      # increases when the scene (visuals) changes
    visuals: SceneVisuals
    frame: Frame
    playing: bool
    speed: float
    rtf: float                           # achieved real-time factor
    status: str
    settings: dict
    history: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))  # t, T, V, E, |C|


class SimRunner(threading.Thread):
    """Background thread owning the simulation. Use ``command(name, value)`` from any thread.

    Commands: ``play``, ``pause``, ``toggle``, ``step``, ``reset``, ``speed`` (float),
    ``integrator`` (name), ``dt`` (float), ``formulation`` (name), ``scene`` (path), ``stop``.
    """

    #: Names the GUI may offer, per setting.
    options = {"integrator": tuple(INTEGRATORS), "formulation": tuple(FORMULATIONS)}

    def __init__(self, scene: Scene, speed: float = 1.0, playing: bool = True, sinks=(),
                 display_rate: float = DISPLAY_RATE, pause_at_end: bool = True):
        super().__init__(name="viz3d-sim", daemon=True)
        self.pause_at_end = pause_at_end
        self.commands: queue.Queue = queue.Queue()
        self.speed, self.playing, self.display_rate = speed, playing, display_rate
        self.sinks = list(sinks)
        self.generation = 0
        self.snapshot: Snapshot | None = None
        self._history: deque = deque(maxlen=HISTORY)
        self._rtf_samples: deque = deque()
        self._stopped = threading.Event()
        self._load(scene)

    # ------------------------------------------------------------------ public

    def command(self, name: str, value=None) -> None:
        self.commands.put((name, value))

    def stop(self, timeout: float = 5.0) -> None:
        self.command("stop")
        self._stopped.wait(timeout)

    def run(self) -> None:
        try:
            while self._drain():
                if self.playing:
                    self._advance()
                else:
                    time.sleep(1.0 / self.display_rate)
                    self._publish(force=False)
        finally:
            self._close_sinks()
            self._stopped.set()

    # ------------------------------------------------------------------ scene and settings

    def _load(self, scene: Scene, settings: dict | None = None) -> None:
        settings = settings or {k: scene.data["sim"][k] for k in ("integrator", "dt", "formulation")}
        data = dict(scene.data)
        data["sim"] = {**scene.data["sim"], **settings}
        self.scene = Scene(scene.path, data, scene.overrides)
        self.system, state = build(self.scene)
        self.visuals = scene_visuals(self.scene, self.system)
        self.settings = settings
        self.status = "ok"
        self.generation += 1
        self._history.clear()
        self._make_sim(state)
        self._open_sinks()
        self._publish(force=True)

    def _make_sim(self, state) -> None:
        cfg = {**self.scene.data["sim"], **self.settings}
        self.formulation = make_formulation(cfg)
        self.sim = Simulation(self.system, state, make_integrator(cfg["integrator"]), self.formulation,
                              float(cfg["dt"]), cfg["blowup_speed"])
        self._rebase()

    def _rebase(self) -> None:
        self._wall_ref, self._sim_ref = time.perf_counter(), self.sim.state.t
        self._rtf_samples.clear()

    def _open_sinks(self) -> None:
        for s in self.sinks:
            s.open(self.visuals)

    def _end_recording(self, why: str) -> None:
        """Sinks record one run: a reset or a scene change ends it (the file stays complete)."""
        if self.sinks:
            self._close_sinks()
            self.sinks = []
            self.status = f"recording closed ({why} at t = {self.sim.state.t:.4g} s)"

    def _close_sinks(self) -> None:
        for s in self.sinks:
            try:
                s.event(self.sim.state.t, f"status: {self.status}", "info" if self.status == "ok" else "error")
            finally:
                s.close()

    # ------------------------------------------------------------------ commands

    def _drain(self) -> bool:
        """Apply queued commands; False on ``stop``."""
        while True:
            try:
                name, value = self.commands.get_nowait()
            except queue.Empty:
                return True
            if name == "stop":
                return False
            try:
                self._apply(name, value)
            except (SceneError, KeyError, ValueError) as exc:
                self.status = f"error: {exc}"
            self._publish(force=True)

    def _apply(self, name: str, value) -> None:
        if name in ("play", "pause", "toggle"):
            self.playing = {"play": True, "pause": False, "toggle": not self.playing}[name]
            self._rebase()
        elif name == "step":
            self.playing = False
            self._step_once()
        elif name == "reset":
            self._end_recording("reset")
            self._make_sim(build(self.scene)[1])
            self.status, self.pause_at_end = "ok", True
            self._history.clear()
        elif name == "speed":
            self.speed = float(value)
            self._rebase()
        elif name in ("integrator", "dt", "formulation"):
            make_integrator(value) if name == "integrator" else None
            self.settings = {**self.settings, name: float(value) if name == "dt" else value}
            if name == "dt" and not self.settings["dt"] > 0:
                raise ValueError(f"dt must be positive, got {value}")
            self._make_sim(self.sim.state)
        elif name == "scene":
            scene = load_scene(Path(value))  # a bad file raises here and keeps the current scene
            self._end_recording("scene change")
            self._load(scene)
        else:
            raise KeyError(f"unknown command {name!r}")

    # ------------------------------------------------------------------ stepping

    def _step_once(self) -> bool:
        try:
            self.sim.step()
        except SimulationFailure as exc:
            self.status, self.playing = str(exc), False
            return False
        if any(s.full_rate for s in self.sinks):
            frame = frame_from_state(self.system, self.formulation, self.sim.state)
            for s in self.sinks:
                if s.full_rate:
                    s.log(frame)
        return True

    def _advance(self) -> None:
        t_end = self.scene.data["sim"]["t_end"]
        if self.pause_at_end and self.sim.state.t >= t_end - 1e-12:
            self.playing, self.pause_at_end = False, False
            self.status = f"reached t_end = {t_end:g} s (Play continues, Reset restarts)"
            self._publish(force=True)
            return
        now = time.perf_counter()
        target = self._sim_ref + self.speed * (now - self._wall_ref)
        budget_end = now + 1.0 / self.display_rate
        while self.sim.state.t < target and time.perf_counter() < budget_end and self.commands.empty():
            if not self._step_once():
                break
        now = time.perf_counter()
        if target - self.sim.state.t > self.speed * MAX_LAG:  # cannot keep up: drop the backlog
            self._wall_ref, self._sim_ref = now, self.sim.state.t
        self._rtf_samples.append((now, self.sim.state.t))
        while self._rtf_samples and now - self._rtf_samples[0][0] > RTF_WINDOW:
            self._rtf_samples.popleft()
        self._publish(force=False)
        if self.sim.state.t >= target:
            time.sleep(min(1.0 / self.display_rate, max(0.0, (self.sim.state.t - target) / max(self.speed, 1e-9))))

    def _rtf(self) -> float:
        if len(self._rtf_samples) < 2:
            return 0.0
        (w0, t0), (w1, t1) = self._rtf_samples[0], self._rtf_samples[-1]
        return (t1 - t0) / (w1 - w0) if w1 > w0 else 0.0

    def _publish(self, force: bool) -> None:
        now = time.perf_counter()
        last = getattr(self, "_last_publish", -np.inf)
        if not force and now - last < 1.0 / self.display_rate:
            return
        self._last_publish = now
        frame = frame_from_state(self.system, self.formulation, self.sim.state)
        if not self._history or frame.t > self._history[-1][0]:
            self._history.append((frame.t, frame.energy_kinetic, frame.energy_potential, frame.energy_total,
                                  frame.constraint_violation))
        self.snapshot = Snapshot(self.generation, self.visuals, frame, self.playing, self.speed, self._rtf(),
                                 self.status, dict(self.settings), np.array(self._history))

"""Real-time driver of the live viewer (the simulation side; the display is viz/viewer_viser.py).

A thread advances a scene in (scaled) real time, takes commands from GUI callbacks through a
queue, and publishes the latest ``Frame``. The runner never waits for the display: it advances
until simulated time catches up with ``speed x`` wall time (or a frame's worth of wall time is
spent), publishes a frame at most at the display rate, and measures the real-time factor it
actually achieves. When it cannot keep up, it drops the backlog instead of stalling, and the
achieved factor shows it. A viewer can hold the run until someone watches (``wait``, then
``connected``): nothing is simulated and the wall clock does not start before that.

Two drivers share one interface: ``RigidDriver`` (multibody scenes, fixed steps of a
``Simulation``) and ``ImpactDriver`` (impact scenes, the event-driven ``ImpactStepper``).
"""

from __future__ import annotations

import math
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
from viz3d.scene.build import build, make_formulation, make_integrator_from
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


# ---------------------------------------------------------------------------- drivers


class RigidDriver:
    """A multibody scene advanced by fixed steps (settings: integrator, dt, formulation)."""

    kind = "rigid"
    #: (title, series labels) of the live plots; ``plot_values`` returns them flattened.
    plots = (("Energy [J]", ("kinetic", "potential", "total")), ("Constraint violation [m]", ("max |C|",)))

    def __init__(self, scene: Scene, sinks=()):
        self.scene, self.sinks = scene, list(sinks)
        self.settings = {k: scene.data["sim"][k] for k in ("integrator", "dt", "formulation")}
        self.system, state = build(scene)
        self.visuals = scene_visuals(scene, self.system)
        self.speed = 1.0
        self._make_sim(state)

    def _make_sim(self, state, settings: dict | None = None) -> None:
        """A fixed-step simulation from ``state`` with ``settings`` (default: the current ones);
        the driver changes only if it can be built (a refused combination leaves it as it was)."""
        settings = self.settings if settings is None else settings
        cfg = {**self.scene.data["sim"], **settings}
        self.sim = Simulation(self.system, state, make_integrator_from(cfg), make_formulation(cfg), float(cfg["dt"]),
                              cfg["blowup_speed"], compiled=cfg["compiled"])
        self.settings = settings

    @property
    def formulation(self):
        return self.sim.formulation

    @property
    def t(self) -> float:
        return self.sim.state.t

    @property
    def t_end(self) -> float:
        return self.scene.data["sim"]["t_end"]

    def advance(self, t_target: float, deadline: float, commands: queue.Queue) -> None:
        """Step until ``t_target`` [s], the wall-clock ``deadline`` or a pending command."""
        full = [s for s in self.sinks if s.full_rate]
        while self.sim.state.t < t_target and time.perf_counter() < deadline and commands.empty():
            self.sim.step()
            if full:
                frame = self.frame()
                for s in full:
                    s.log(frame)

    def step_once(self) -> None:
        self.advance(self.t + 0.5 * self.sim.dt, math.inf, queue.Queue())

    def frame(self) -> Frame:
        return frame_from_state(self.system, self.formulation, self.sim.state)

    def plot_values(self, frame: Frame) -> tuple[float, ...]:
        return frame.energy_kinetic, frame.energy_potential, frame.energy_total, frame.constraint_violation

    def reset(self) -> None:
        self._make_sim(build(self.scene)[1])

    def configure(self, name: str, value) -> None:
        if name == "integrator":
            make_integrator(value)  # KeyError lists the valid names
        if name == "dt" and not float(value) > 0:
            raise ValueError(f"dt must be positive, got {value}")
        if name not in self.settings:
            raise KeyError(f"{name!r} is not a setting of a multibody scene")
        self._make_sim(self.sim.state, {**self.settings, name: float(value) if name == "dt" else value})


class ImpactDriver:
    """An impact scene advanced by the event-driven stepper, one output interval at a time."""

    kind = "impact"
    plots = (("Contact force [N]", ("force",)),
             ("Energy ledger [J]", ("impactor kinetic", "bar kinetic", "bar strain", "dissipated")))
    settings: dict = {}

    def __init__(self, scene: Scene, sinks=()):
        from viz3d.impact.build import build_impact
        from viz3d.impact.display import geometry, impact_visuals

        self.scene, self.sinks = scene, list(sinks)
        self.setup = build_impact(scene)
        self.geo = geometry(scene, self.setup)
        self.visuals = impact_visuals(scene, self.setup, self.geo)
        self.speed = scene.data["display"]["speed"]
        self.reset()

    def reset(self) -> None:
        from viz3d.impact.engine import ImpactStepper
        from viz3d.integrators.adaptive import Controller

        cfg = self.scene.data["sim"]
        self.stepper = ImpactStepper(self.setup.problem, cfg["output_dt"],
                                     Controller(cfg["rtol"], cfg["atol"], cfg.get("max_step", np.inf)), self._sample)
        self.stepper.samples = self.stepper.samples[-1:]

    def _sample(self, sample) -> None:
        if hasattr(self, "stepper"):
            self.stepper.samples = self.stepper.samples[-2:]  # live: keep only the latest
        if self.sinks:
            frame = self._frame(sample)
            for s in self.sinks:
                s.log(frame)

    @property
    def t(self) -> float:
        return self.stepper.t

    @property
    def t_end(self) -> float:
        return self.scene.data["sim"]["t_end"]

    def advance(self, t_target: float, deadline: float, commands: queue.Queue) -> None:
        dt = self.scene.data["sim"]["output_dt"]
        while self.t < t_target - 1e-15 and time.perf_counter() < deadline and commands.empty():
            self.stepper.advance(min(t_target, self.t + dt))
            if self.stepper.status != "ok":
                raise SimulationFailure(self.stepper.status)

    def step_once(self) -> None:
        self.advance(self.t + self.scene.data["sim"]["output_dt"], math.inf, queue.Queue())

    def _frame(self, sample) -> Frame:
        from viz3d.impact.display import impact_frame

        d = self.scene.data
        return impact_frame(self.setup, self.geo, sample, d["impactor"]["gap"], d["display"]["amplification"])

    def frame(self) -> Frame:
        return self._frame(self.stepper.last_sample)

    def plot_values(self, frame: Frame) -> tuple[float, ...]:
        s = frame.scalars
        return (s["contact/force"], s["energy/impactor_kinetic"], s["energy/bar_kinetic"], s["energy/bar_strain"],
                s["energy/dissipated"])

    def configure(self, name: str, value) -> None:
        raise KeyError(f"{name!r} cannot be changed for an impact scene (adaptive stepping with event location)")


def make_driver(scene: Scene, sinks=()):
    return ImpactDriver(scene, sinks) if scene.kind == "impact" else RigidDriver(scene, sinks)


# ---------------------------------------------------------------------------- the runner


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
    kind: str = "rigid"
    plots: tuple = ()
    history: np.ndarray = field(default_factory=lambda: np.zeros((0, 1)))  # t, then the plot series
    waiting: bool = False                # held until a client connects (``wait`` / ``connected``)


class SimRunner(threading.Thread):
    """Background thread owning the simulation. Use ``command(name, value)`` from any thread.

    Commands: ``play``, ``pause``, ``toggle``, ``step``, ``reset``, ``speed`` (float),
    ``integrator`` (name), ``dt`` (float), ``formulation`` (name), ``scene`` (path), ``stop``;
    ``wait`` holds the run (no stepping, wall clock not started) until ``connected`` (a viewer
    sends it when its first client connects; ``playing`` then decides whether it runs).
    """

    #: Names the GUI may offer, per setting.
    options = {"integrator": tuple(INTEGRATORS), "formulation": tuple(FORMULATIONS)}

    def __init__(self, scene: Scene, speed: float | None = None, playing: bool = True, sinks=(),
                 display_rate: float = DISPLAY_RATE, pause_at_end: bool = True):
        super().__init__(name="viz3d-sim", daemon=True)
        self.pause_at_end = pause_at_end
        self.commands: queue.Queue = queue.Queue()
        self.playing, self.display_rate = playing, display_rate
        self.waiting = False
        self.sinks = list(sinks)
        self.generation = 0
        self.snapshot: Snapshot | None = None
        self._history: deque = deque(maxlen=HISTORY)
        self._rtf_samples: deque = deque()
        self._stopped = threading.Event()
        self._load(scene, speed)

    # ------------------------------------------------------------------ public

    @property
    def scene(self) -> Scene:
        return self.driver.scene

    @property
    def sim(self):
        """The rigid ``Simulation`` (multibody scenes only)."""
        return self.driver.sim

    def command(self, name: str, value=None) -> None:
        self.commands.put((name, value))

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread; a runner that was never started closes its sinks here."""
        if self.ident is None:
            if not self._stopped.is_set():
                self._close_sinks()
                self._stopped.set()
            return
        self.command("stop")
        self._stopped.wait(timeout)

    def run(self) -> None:
        try:
            while self._drain():
                if self.playing and not self.waiting:
                    self._advance()
                else:
                    time.sleep(1.0 / self.display_rate)
                    self._publish(force=False)
        finally:
            self._close_sinks()
            self._stopped.set()

    # ------------------------------------------------------------------ scene and settings

    def _load(self, scene: Scene, speed: float | None = None) -> None:
        self.driver = make_driver(scene, self.sinks)
        self.speed = speed if speed is not None else self.driver.speed
        self.status = "ok"
        self.generation += 1
        self._history.clear()
        for s in self.sinks:
            s.open(self.driver.visuals)
        self._rebase()
        self._publish(force=True)

    def _rebase(self) -> None:
        self._wall_ref, self._sim_ref = time.perf_counter(), self.driver.t
        self._rtf_samples.clear()

    def _end_recording(self, why: str) -> None:
        """Sinks record one run: a reset or a scene change ends it (the file stays complete)."""
        if self.sinks:
            self._close_sinks()
            self.sinks = []
            self.driver.sinks = []
            self.status = f"recording closed ({why} at t = {self.driver.t:.4g} s)"

    def _close_sinks(self) -> None:
        for s in self.sinks:
            try:
                s.event(self.driver.t, f"status: {self.status}", "info" if self.status == "ok" else "error")
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
        if name == "wait":
            self.waiting = True
        elif name == "connected":
            if self.waiting:
                self.waiting = False
                self._rebase()  # the wall clock starts now
        elif name in ("play", "pause", "toggle"):
            self.playing = {"play": True, "pause": False, "toggle": not self.playing}[name]
            self._rebase()
        elif name == "step":
            self.playing = False
            self._guarded(self.driver.step_once)
        elif name == "reset":
            self._end_recording("reset")
            self.driver.reset()
            self.status, self.pause_at_end = "ok", True
            self._history.clear()
            self._rebase()
        elif name == "speed":
            self.speed = float(value)
            self._rebase()
        elif name in ("integrator", "dt", "formulation"):
            self.driver.configure(name, value)
            self._rebase()
        elif name == "scene":
            scene = load_scene(Path(value))  # a bad file raises here and keeps the current scene
            self._end_recording("scene change")
            self._load(scene)
        else:
            raise KeyError(f"unknown command {name!r}")

    # ------------------------------------------------------------------ stepping

    def _guarded(self, fn, *args) -> bool:
        try:
            fn(*args)
        except SimulationFailure as exc:
            self.status, self.playing = str(exc), False
            return False
        return True

    def _advance(self) -> None:
        d = self.driver
        if self.pause_at_end and d.t >= d.t_end - 1e-12 * max(1.0, d.t_end):
            self.playing, self.pause_at_end = False, False
            self.status = f"reached t_end = {d.t_end:g} s (Play continues, Reset restarts)"
            self._publish(force=True)
            return
        now = time.perf_counter()
        target = self._sim_ref + self.speed * (now - self._wall_ref)
        if self.pause_at_end:
            target = min(target, d.t_end)
        self._guarded(d.advance, target, now + 1.0 / self.display_rate, self.commands)
        now = time.perf_counter()
        if target - d.t > self.speed * MAX_LAG:  # cannot keep up: drop the backlog
            self._wall_ref, self._sim_ref = now, d.t
        self._rtf_samples.append((now, d.t))
        while self._rtf_samples and now - self._rtf_samples[0][0] > RTF_WINDOW:
            self._rtf_samples.popleft()
        self._publish(force=False)
        if d.t >= target:
            time.sleep(min(1.0 / self.display_rate, max(0.0, (d.t - target) / max(self.speed, 1e-12))))

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
        d = self.driver
        frame = d.frame()
        if not self._history or frame.t > self._history[-1][0]:
            self._history.append((frame.t, *d.plot_values(frame)))
        self.snapshot = Snapshot(self.generation, d.visuals, frame, self.playing, self.speed, self._rtf(), self.status,
                                 dict(d.settings), d.kind, d.plots, np.array(self._history), self.waiting)

"""Real-time driver of the live viewer (the simulation side; the display is viz/viewer_viser.py).

A thread advances a scene in (scaled) real time, takes commands from GUI callbacks through a
queue, and publishes the latest ``Frame``. The runner never waits for the display: it advances
until simulated time catches up with ``speed x`` wall time (or a frame's worth of wall time is
spent), publishes a frame at most at the display rate, and measures the real-time factor it
actually achieves. A backlog of up to ``MAX_LAG`` (a costly stretch: a step that fails and is
halved at a contact or a stop) is won back at the runner's spare speed; a larger one means it cannot
keep up, and it is dropped instead of stalling: the achieved factor shows it. A viewer can hold the
run until someone watches (``wait``, then ``connected``): nothing is simulated and the wall clock
does not start before that.

One ``Driver`` advances any scene through its ``Simulation`` (fixed steps, or adaptive steps
with contact events).
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from viz3d.columns import FrameColumns, chunk_frames
from viz3d.departures import Departures
from viz3d.diagnosis import RunComplete, SimulationFailure
from viz3d.formulation import FORMULATIONS
from viz3d.frames import Frame, SceneVisuals
from viz3d.integrators import INTEGRATORS, make_integrator
from viz3d.scene.build import build, make_controller, make_formulation, make_integrator_from
from viz3d.scene.load import Scene, load_scene
from viz3d.scene.schema import SceneError
from viz3d.scene.visuals import flexible_drawings, live_plots, scene_visuals
from viz3d.simulate import Simulation, run_checks
from viz3d.sink import FRAME_SLACK, frame_due

#: Frames published per second of wall time [Hz].
DISPLAY_RATE = 60.0
#: Length of the plot history kept (frames).
HISTORY = 1200
#: Window over which the achieved real-time factor is measured [s of wall time].
RTF_WINDOW = 1.0
#: A backlog larger than this [s of wall time] is dropped (the runner cannot keep up); a smaller one is
#: won back (the anchor hoist's step at the flukes' stop fails and is halved: 0.4 s for 1 ms).
MAX_LAG = 1.0
#: While the simulation lags behind its target, the frames it publishes (a kernel sample, the
#: checks; and the display's drawing and pose updates of each, which hold the interpreter while the
#: kernel waits) take at most this share of the wall time: fewer frames, more steps ...
FRAME_SHARE = 0.1
#: ... but no fewer frames than this per second [Hz].
MIN_FRAME_RATE = 10.0
#: Steps to an instant are rounded up from this much [steps] below it: a step count a hair over
#: an integer from round-off must not carry a batch past the instant (one more call instead).
BATCH_SLACK = 1e-6


# ---------------------------------------------------------------------------- drivers


class Driver:
    """A scene advanced by a ``Simulation``, one frame interval at a time (settings: integrator,
    dt, formulation, for fixed-step runs; an adaptive run with contact events keeps its own).

    What it plots comes from the system, never from a kind of scene: energies, then the contact
    forces when there are contacts, else the constraint violation, and the energy ledger with contacts
    or drives."""

    def __init__(self, scene: Scene, sinks=()):
        self.scene, self.sinks = scene, list(sinks)
        sim = scene.data["sim"]
        self.settings = {} if "rtol" in sim else {k: sim[k] for k in ("integrator", "dt", "formulation")}
        self.system, state = build(scene)
        self.visuals = scene_visuals(scene, self.system)
        self.speed = float(scene.data["display"]["speed"])
        self.plots, self._series = plot_series(self.system)
        self._make_sim(state)

    def _make_sim(self, state, settings: dict | None = None, departures: Departures | None = None) -> None:
        """A simulation from ``state`` with ``settings`` (default: the current ones) and the departures
        so far (a state of a later generation of the system: ``viz3d.departures``; default: the scene's,
        none yet); the driver changes only if it can be built (a refused combination leaves it as it was)."""
        settings = self.settings if settings is None else settings
        cfg = {**self.scene.data["sim"], **settings}
        departures = Departures.of(self.scene, self.system) if departures is None else departures
        system = self.system if departures is None else departures.current.system
        self.sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), float(cfg["dt"]),
                              cfg["blowup_speed"], make_controller(cfg), compiled=cfg["compiled"], departures=departures)
        self._check = run_checks(self.sim, self.scene)[0]
        self._drawings = flexible_drawings(self.scene, self.system)
        self._last_t: dict[int, float] = {}  # the time of each sink's last frame [s] (default: the start)
        self._t0 = state.t
        self._step_cost: float | None = None  # wall time of a step on the last call [s]
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
        """Step until ``t_target`` [s], the wall-clock ``deadline`` or a pending command; sinks with a
        ``frame_dt`` get a frame whenever it has passed (``viz3d.sink.frame_due``) and every contact
        event's.

        The steps go several at a time through the batched path of a headless run
        (``Simulation.output_states``: one kernel call, no Python per step), as many as reach
        ``t_target`` or the next instant a sink wants, and as fit in the wall time left at the cost
        of a step measured on the last call; the simulated states are those of single steps."""
        sinks = [s for s in self.sinks if s.frame_dt is not None]
        states, takers = [], []  # the instants some sink wants, and which sinks
        while self.sim.state.t < t_target and time.perf_counter() < deadline and commands.empty():
            self._take(self._batch(t_target, deadline, sinks))
            for event in self.sim.drain_events(self.sim.state.t):
                states.append(event)
                takers.append(sinks)
            due = [s for s in sinks if frame_due(s, self.sim.state.t, self._last_t.get(id(s), self._t0))]
            for s in due:
                self._last_t[id(s)] = self.sim.state.t
            if due:
                states.append(self.sim.state)
                takers.append(due)
        if states:  # their frames in one chunk (viz3d.columns.chunk_frames), in time order
            frame_at = chunk_frames(self.sim, states, self._drawings)[1]
            for i, to in enumerate(takers):
                for s in to:
                    s.log(frame_at(i))

    def _batch(self, t_target: float, deadline: float, sinks: list) -> int:
        """Steps for the next call: to ``t_target`` or the next sink's instant, whichever comes
        first, and no more than fit before ``deadline`` at ``_step_cost`` (one before it is known)."""
        sim = self.sim
        if not sim.batches_frames or self._step_cost is None:
            return 1
        t_next = min([t_target] + [self._last_t.get(id(s), self._t0) + s.frame_dt - FRAME_SLACK for s in sinks])
        n = math.ceil((t_next - sim.state.t) / sim.dt - BATCH_SLACK)  # (rounded down a hair: never past t_next)
        fits = (deadline - time.perf_counter()) / max(self._step_cost, 1e-12)  # (inf without a deadline)
        return max(1, n if fits >= n else math.floor(fits))

    def _take(self, n: int) -> None:
        """``n`` steps: through ``Simulation.output_states`` when it batches them, else (and for the
        diagnosis of a step that fails in the batch) ``Simulation.steps``; ``_step_cost`` measured."""
        sim, goal, start = self.sim, self.sim.n_samples + n, time.perf_counter()
        if n > 1 and sim.batches_frames:
            sim.output_states(1, n)
        if sim.n_samples < goal:
            sim.steps(goal - sim.n_samples)
        self._step_cost = (time.perf_counter() - start) / n

    def step_once(self) -> None:
        self.advance(self.t + 0.5 * self.sim.dt, math.inf, queue.Queue())

    def frame(self) -> Frame:
        """The current state's frame (``viz3d.columns.chunk_frames``)."""
        return chunk_frames(self.sim, [self.sim.state], self._drawings)[1](0)

    def check(self, frame: Frame) -> None:
        """The run's frame checks (``viz3d.simulate.run_checks``) on a frame of the current state:
        ``SimulationFailure`` (a drive over its capacity, a violation, energy growth) or
        ``RunComplete`` (an anchor seated) as a headless run would stop."""
        self._check(FrameColumns.from_frames([frame], self.system.n_bodies, len(self.system.joint_names)),
                    [self.sim.state])

    def plot_values(self, frame: Frame) -> tuple[float, ...]:
        return tuple(f(frame) for f in self._series)

    def reset(self) -> None:
        self._make_sim(build(self.scene)[1])

    def configure(self, name: str, value) -> None:
        if name not in self.settings:
            why = "adaptive steps with contact events keep their own" if not self.settings else "not a setting"
            raise KeyError(f"{name!r} cannot be changed here ({why})")
        if name == "integrator":
            make_integrator(value)  # KeyError lists the valid names
        if name == "dt" and not float(value) > 0:
            raise ValueError(f"dt must be positive, got {value}")
        self._make_sim(self.sim.state, {**self.settings, name: float(value) if name == "dt" else value},
                       self.sim.departures)


def plot_series(system) -> tuple[tuple, tuple]:
    """The live plots ``((title, labels), ...)`` and, flattened, a reader of each series from a frame."""
    plots = [("Energy [J]", ("kinetic", "potential", "total"))]
    series = [lambda f: f.energy_kinetic, lambda f: f.energy_potential, lambda f: f.energy_total]
    names = [n for c in system.contacts for n in c.names]
    if names:
        plots.append(("Contact force [N]", tuple(names)))
        series += [lambda f, n=n: f.scalars.get(f"contact/{n}/force", np.nan) for n in names]
    else:
        plots.append(("Constraint violation [m]", ("max |C|",)))
        series.append(lambda f: f.constraint_violation)
    if system.has_ledger:
        ledger = ("strain", "dissipated", "work_in")
        plots.append(("Energy ledger [J]", ledger))
        series += [lambda f, k=k: f.scalars.get(f"energy/{k}", np.nan) for k in ledger]
    drives = system.drive_names
    if drives:  # the windlass's hauling force, a crank's torque
        plots.append(("Drive effort [N or N m]", tuple(drives)))
        series += [lambda f, n=n: f.scalars.get(f"drive/{n}/effort", np.nan) for n in drives]
    panels: dict[str, list[str]] = {}  # output elements: gauges on several bars share one panel
    for out in system.outputs:
        panels.setdefault(out.plot[0], []).extend(out.keys)
    for title, keys in panels.items():
        plots.append((title, tuple(k.split("/")[-1].replace("_", " ") for k in keys)))
        series += [lambda f, k=k: f.scalars.get(k, np.nan) for k in keys]
    for e in system.forces:  # shape contacts, water, joint stops: the element's own plot
        for title, key in live_plots(e):
            plots.append((title, (key.split("/")[-1].replace("_", " "),)))
            series.append(lambda f, key=key: f.scalars.get(key, np.nan))
    return tuple(plots), tuple(series)


def make_driver(scene: Scene, sinks=()) -> Driver:
    return Driver(scene, sinks)


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
    t_end: float = 1.0                   # the scene's duration [s] (sets the time unit shown)
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
        self._behind = False                 # the last advance ended short of its target
        self._frame_cost = 0.0               # wall time of the last published frame [s]
        self._stopped = threading.Event()
        self._load(scene, speed)

    # ------------------------------------------------------------------ public

    @property
    def scene(self) -> Scene:
        return self.driver.scene

    @property
    def sim(self):
        """The driver's ``Simulation``."""
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
                try:
                    if self.playing and not self.waiting:
                        self._advance()
                    else:
                        time.sleep(1.0 / self.display_rate)
                        self._publish(force=False)
                except Exception as exc:  # a defect: the run stops with it on show (as a headless run's status)
                    self._internal_error(exc)
        finally:
            self._close_sinks()
            self._stopped.set()

    def _internal_error(self, exc: Exception) -> None:
        """Pause with the error as the status, shown at once (the last frame kept), and print its
        traceback once; commands (Reset, another scene) are still served."""
        status = f"stopped by an internal error at t = {self.driver.t:.6g} s: {type(exc).__name__}: {exc}"
        if status != self.status:
            import traceback

            traceback.print_exc()
        self.status, self.playing = status, False
        if self.snapshot is not None:
            self.snapshot = replace(self.snapshot, status=status, playing=False)

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
        self._behind = False

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
        self._behind = d.t < target
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
        if not force and now - last < self._frame_interval():
            return
        self._last_publish = now
        d = self.driver
        frame = d.frame()
        if self.playing:
            try:
                d.check(frame)
            except (SimulationFailure, RunComplete) as exc:  # stops as a headless run would (Play goes on)
                self.status, self.playing = str(exc), False
        if not self._history or frame.t > self._history[-1][0]:
            self._history.append((frame.t, *d.plot_values(frame)))
        self.snapshot = Snapshot(self.generation, d.visuals, frame, self.playing, self.speed, self._rtf(), self.status,
                                 dict(d.settings), d.t_end, d.plots, np.array(self._history), self.waiting)
        self._frame_cost = time.perf_counter() - now

    def _frame_interval(self) -> float:
        """Wall time between published frames [s]: ``1 / display_rate``, longer while the run lags
        behind and frames would take more than ``FRAME_SHARE`` of the wall time (at most
        ``1 / MIN_FRAME_RATE``)."""
        interval = 1.0 / self.display_rate
        if self._behind:
            interval = min(max(interval, self._frame_cost / FRAME_SHARE), max(interval, 1.0 / MIN_FRAME_RATE))
        return interval

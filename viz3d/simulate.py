"""Running a system in time: ``Simulation`` (one fixed step at a time) and ``simulate`` (a whole
headless run into a ``Trajectory``).

A run that fails stops at once with a diagnosis in ``Trajectory.status``; the frames computed so
far are kept. Ctrl-C likewise ends the run with status "interrupted ..." and keeps the frames.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from viz3d.constraints import SingularConstraintError, constraint_rows
from viz3d.diagnosis import SimulationFailure, check_state, check_violation, redundant_joints
from viz3d.dynamics import VectorField, body_state
from viz3d.frames import Frame, frame_from_state
from viz3d.integrators import Integrator, make_integrator
from viz3d.rotations import euler_from_matrix
from viz3d.scene.build import build, make_formulation
from viz3d.scene.load import Scene, load_scene
from viz3d.stabilization import ProjectionError
from viz3d.system import State, System
from viz3d.trajectory import Trajectory
from viz3d.viz.sink import Sink

#: Output interval when the scene gives none [s].
DEFAULT_OUTPUT_DT = 0.01
#: Show a progress bar when a run is projected to take longer than this [s] of wall time.
PROGRESS_AFTER = 2.0


class Simulation:
    """Advance a ``System`` from a ``State`` by fixed steps; used by ``simulate`` and the viewer.

    Parameters
    ----------
    system, state : System, State
    integrator : Integrator
    formulation : Index1, Baumgarte or Projection
    dt : float
        Step [s].
    blowup_speed : float
        Speed [m/s] above which the run is declared diverged.

    Attributes
    ----------
    state : State
        Current state.
    chart_switches : ndarray of int, shape (nb,)
    n_steps, n_rhs : int
        Steps taken and vector-field evaluations so far.
    """

    def __init__(self, system: System, state: State, integrator: Integrator, formulation, dt: float,
                 blowup_speed: float = 1e4):
        self.system, self.state = system, state
        self.integrator, self.formulation, self.dt = integrator, formulation, dt
        self.blowup_speed = blowup_speed
        self.chart_switches = np.zeros(system.n_bodies, dtype=int)
        self.t0, self.n_steps, self.n_rhs = state.t, 0, 0

    def step(self) -> State:
        """Take one step; raise ``SimulationFailure`` with a diagnosis if the run cannot go on."""
        s, system = self.state, self.system
        rhs = VectorField(system, self.formulation, s.chart)
        try:
            with np.errstate(all="ignore"):
                y = self.integrator.step(rhs, s.t, s.y, self.dt).y
            new = State(self.t0 + (self.n_steps + 1) * self.dt, y[: system.n_q], y[system.n_q:], s.chart)
            new = self.formulation.post_step(system, new)
        except SingularConstraintError:
            raise SimulationFailure(self._singular_message(s)) from None
        except ProjectionError as exc:
            raise SimulationFailure(f"t = {s.t + self.dt:.6g} s: {exc}") from None
        finally:
            self.n_rhs += rhs.n_evals
        check_state(system, new, self.blowup_speed, self.dt)
        self.state = self._rechart(new)
        self.n_steps += 1
        return self.state

    def _rechart(self, state: State) -> State:
        W_r, theta = self.system.split_q(state.q)
        theta, chart, switched = self.system.rotation.rechart(theta, state.chart)
        if not np.any(switched):
            return state
        self.chart_switches += switched
        return state.replace(q=self.system.join_q(W_r, theta), chart=chart)

    def _singular_message(self, s: State) -> str:
        pose, twist = body_state(self.system, s.q, s.v, s.chart)
        names = redundant_joints(self.system, constraint_rows(self.system.joints, pose, twist).J)
        who = f"joints {', '.join(map(repr, names))} are redundant or degenerate" if names else "constraint matrix lost rank"
        return f"t = {s.t:.6g} s: singular constraint Jacobian: {who}"


class FrameRecorder:
    """Collects output frames of a run into a ``Trajectory``."""

    def __init__(self, system: System):
        self.system = system
        self.frames: list[Frame] = []

    def record(self, frame: Frame) -> None:
        self.frames.append(frame)

    def trajectory(self, status: str, scene_json: str, chart_switches, **cost) -> Trajectory:
        b, fr = self.system.bodies, self.frames
        nb, nj = b.n_bodies, len(self.system.joint_names)

        def stack(key, shape):
            return np.array([getattr(f, key) for f in fr], dtype=float).reshape((len(fr),) + shape)

        kinetic, potential = stack("energy_kinetic", ()), stack("energy_potential", ())
        rotation = stack("R_WB", (nb, 3, 3))
        return Trajectory(
            t=stack("t", ()), body_names=np.array(b.names), mass=b.mass.copy(), inertia_body=b.inertia.copy(),
            position=stack("W_r", (nb, 3)), rotation=rotation, euler=euler_from_matrix(rotation),
            velocity=stack("W_v", (nb, 3)), omega=stack("W_omega", (nb, 3)), energy_kinetic=kinetic,
            energy_potential=potential, energy_total=kinetic + potential,
            constraint_violation=stack("constraint_violation", ()),
            joint_names=np.array(self.system.joint_names, dtype=str), reaction_force=stack("reaction_force", (nj, 3)),
            chart_switches=np.asarray(chart_switches, int), status=status, scene_json=scene_json, **cost)


def with_sim(scene: Scene, **changes) -> Scene:
    """A copy of ``scene`` with ``sim`` keys changed (``None`` values ignored), recorded as overrides."""
    changes = {k: v for k, v in changes.items() if v is not None}
    if not changes:
        return scene
    data = json.loads(json.dumps(scene.data))
    data["sim"].update(changes)
    return dataclasses.replace(scene, data=data, overrides=scene.overrides + tuple(f"sim.{k}={v}" for k, v in changes.items()))


def simulate(scene: Scene | str | Path, overrides=None, *, t_end: float | None = None, dt: float | None = None,
             progress: bool = False, sinks: Sequence[Sink] = ()) -> Trajectory:
    """Run a scene headless and return its ``Trajectory``.

    Parameters
    ----------
    scene : Scene, or a path to a scene file
    overrides : "key.path=value" strings or mapping (only with a path)
    t_end, dt : float, optional
        Override ``sim.t_end`` and ``sim.dt`` [s].
    progress : bool
        Draw a progress bar on stderr when the run is projected to take over 2 s.
    sinks : sequence of Sink
        Consumers of the run's frames (e.g. ``RerunRecorder``); opened and closed here.
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene, overrides)
    elif overrides:
        raise ValueError("overrides apply when loading: use load_scene(path, overrides)")
    if scene.kind == "impact":
        from viz3d.impact.run import simulate_impact

        return simulate_impact(scene, t_end=t_end, sinks=sinks, progress=progress)
    scene = with_sim(scene, t_end=t_end, dt=dt)
    system, state = build(scene)
    sim_cfg = scene.data["sim"]
    formulation = make_formulation(sim_cfg)
    sim = Simulation(system, state, make_integrator(sim_cfg["integrator"]), formulation, sim_cfg["dt"],
                     sim_cfg["blowup_speed"])
    return run(sim, scene, formulation, progress, sinks)


def run(sim: Simulation, scene: Scene, formulation, progress: bool = False, sinks: Sequence[Sink] = ()) -> Trajectory:
    """Drive ``sim`` to ``sim.t_end``: frames every ``output_dt`` into the trajectory, and to
    the ``sinks`` (after every step for full-rate sinks)."""
    cfg = scene.data["sim"]
    n_steps = max(1, math.ceil(cfg["t_end"] / cfg["dt"] - 1e-9))
    every = max(1, round(cfg.get("output_dt", max(DEFAULT_OUTPUT_DT, cfg["dt"])) / cfg["dt"]))
    recorder = FrameRecorder(sim.system)
    full_rate = any(s.full_rate for s in sinks)
    bar = ProgressBar(n_steps) if progress else None
    status, wall0 = "ok", time.perf_counter()
    emitter = _Emitter(sim, formulation, recorder, sinks, cfg["blowup_violation"])
    try:
        emitter.open(scene)
        emitter.emit(output=True)
        for n in range(1, n_steps + 1):
            sim.step()
            output = n % every == 0 or n == n_steps
            if output or full_rate:
                emitter.emit(output)
            if bar is not None:
                bar.update(n)
    except SimulationFailure as exc:
        status = str(exc)
    except KeyboardInterrupt:
        status = f"interrupted at t = {sim.state.t:.6g} s"
    finally:
        if bar is not None:
            bar.close()
        emitter.close(status)
    wall = time.perf_counter() - wall0
    return recorder.trajectory(status, scene_json(scene, sim), sim.chart_switches, wall_time=wall,
                               n_steps=sim.n_steps, n_rhs=sim.n_rhs)


class _Emitter:
    """Computes frames and hands them to the trajectory recorder and the sinks."""

    def __init__(self, sim, formulation, recorder, sinks, blowup_violation):
        self.sim, self.formulation, self.recorder, self.sinks = sim, formulation, recorder, list(sinks)
        self.blowup_violation = blowup_violation
        self.opened: list[Sink] = []

    def open(self, scene: Scene) -> None:
        if self.sinks:
            from viz3d.scene.visuals import scene_visuals

            visuals = scene_visuals(scene, self.sim.system)
            for s in self.sinks:
                s.open(visuals)
                self.opened.append(s)

    def emit(self, output: bool) -> None:
        frame = frame_from_state(self.sim.system, self.formulation, self.sim.state)
        if output:
            self.recorder.record(frame)
        for s in self.sinks:
            if output or s.full_rate:
                s.log(frame)
        check_violation(self.sim.system, self.sim.state, frame.constraint_violation, self.blowup_violation)

    def close(self, status: str) -> None:
        for s in self.opened:
            try:
                s.event(self.sim.state.t, f"status: {status}", "info" if status == "ok" else "error")
            finally:
                s.close()


def scene_json(scene: Scene, sim: Simulation) -> str:
    """The resolved scene plus what produced the run (version, integrator, step, source)."""
    from viz3d import __version__

    cfg = scene.data["sim"]
    meta = {"viz3d_version": __version__, "integrator": cfg["integrator"], "dt": cfg["dt"],
            "formulation": cfg["formulation"], "rotation": cfg["rotation"], "source": str(scene.path),
            "overrides": list(scene.overrides),
            "conservative": all(e.conservative for e in sim.system.forces)}
    return json.dumps({"scene": scene.data, "run": meta}, sort_keys=True)


class ProgressBar:
    """A one-line stderr progress bar that appears only for runs projected to exceed 2 s."""

    def __init__(self, total: int, stream=None):
        self.total, self.stream = total, stream or sys.stderr
        self.enabled = stream is not None or self.stream.isatty()  # no bar in logs and pipes
        self.start = time.perf_counter()
        self.shown, self.last = False, 0.0

    def update(self, n: int) -> None:
        now = time.perf_counter()
        if not self.enabled or now - self.last < 0.2:
            return
        self.last = now
        elapsed = now - self.start
        eta = elapsed / n * (self.total - n)
        if not self.shown and elapsed + eta < PROGRESS_AFTER:
            return
        self.shown = True
        frac = n / self.total
        bar = "#" * int(30 * frac)
        self.stream.write(f"\r[{bar:<30}] {100 * frac:5.1f}%  {elapsed:6.1f} s elapsed, {eta:6.1f} s left")
        self.stream.flush()

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()

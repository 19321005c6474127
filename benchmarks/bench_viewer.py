"""What the live viewer costs while the simulation runs (a benchmark, not a test).

    python benchmarks/bench_viewer.py [--n 10,50] [--seconds 6]
    python benchmarks/bench_viewer.py --scene scenes/anchor_hoist.toml [--seconds 25] [--warmup 5]
        [--speed 1000] [--no-forces] [--repeat 1] [--out docs/bench_viewer.md]

Without ``--scene``: the viewer on the `chain` scene with N links; a websocket client that speaks
viser's protocol (what a browser receives) counts pose updates of the link batch per second of
wall time, alongside the simulation's achieved real-time factor. One table row per N.

With ``--scene``: the viewer on that scene (its default method and links, contact and reaction
arrows shown unless ``--no-forces``) with the same client connected, run at ``--speed`` (a speed
it cannot reach measures what it can do: the achieved factor is then its capacity; ``--speed 1``
whether it holds real time). After ``--warmup`` s of wall time, over ``--seconds`` s:

* the achieved real-time factor (simulated time advanced / wall time) over ``[t_a, t_b]``, and the
  process's CPU time per simulated second (all its threads; on a loaded machine the wall time
  also holds the waits for a core, the CPU time less so);
* display updates per second: frames pushed by the display loop, pose updates and plot updates
  received by the client;
* the wall time of each part of the work, per simulation step: kernel stepping, the runner's
  published frames (frame, checks, plot values, snapshot), and the display thread's (pose
  updates, the frame's drawing, contact arrows, plots);

then the headless run (``viz3d.simulate``, the path of ``viz3d run``) of the same scene from t = 0,
timed over the same interval ``[t_a, t_b]`` (its wall time at t_a and t_b interpolated between
its kernel calls), so the viewer's overhead is a ratio of two runs of one process, minutes apart.
``--repeat`` repeats the pair. Quote ``uptime`` with the numbers (printed).
"""

from __future__ import annotations

import argparse
import asyncio
import datetime
import functools
import multiprocessing
import os
import threading
import time
from collections import defaultdict
from functools import cached_property
from pathlib import Path

import msgspec
import numpy as np
import viser
import websockets
import zstandard

import viz3d
from viz3d.frames import Frame
from viz3d.realtime import Driver, SimRunner
from viz3d.simulate import Simulation, simulate
from viz3d.viz.viewer_viser import SceneNodes, Viewer

ROOT = Path(__file__).resolve().parents[1]


def _messages(frame: bytes) -> list:
    raw_len, comp_len = int.from_bytes(frame[0:8], "little"), int.from_bytes(frame[8:16], "little")
    body = zstandard.ZstdDecompressor().decompress(frame[16:16 + comp_len], max_output_size=raw_len)
    return msgspec.msgpack.decode(body)["messages"]


def _is_pose(m: dict, node: str | None = "/bodies/group0") -> bool:
    return (m["type"] == "SceneNodeUpdateMessage" and "batched_positions" in m["updates"]
            and (node is None or m["name"] == node))


async def _count(port: int, seconds: float, warmup: float = 1.0, node: str | None = "/bodies/group0") -> dict:
    """Pose updates of ``node`` (None: of any batched mesh, counted once per websocket frame) and
    plot updates a client receives over ``seconds`` after ``warmup`` [s]."""
    n = {"poses": 0, "plots": 0}
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"],
                                  max_size=None) as ws:
        start = time.monotonic() + warmup
        end = start + seconds
        while time.monotonic() < end:
            try:
                frame = await asyncio.wait_for(ws.recv(), timeout=0.1)
            except asyncio.TimeoutError:
                continue
            if time.monotonic() < start:
                continue
            messages = _messages(frame)
            n["poses"] += (any(_is_pose(m, None) for m in messages) if node is None
                           else sum(1 for m in messages if _is_pose(m, node)))
            n["plots"] += sum(1 for m in messages if m["type"] == "GuiUpdateMessage" and "data" in m["updates"])
    return n


# ---------------------------------------------------------------------------- timing the parts


class Clock:
    """Wall time [s] and calls per named part, the outermost call per thread only (a part that
    calls itself, e.g. ``Simulation.steps`` calling ``step``, counts once)."""

    def __init__(self):
        self.wall, self.calls = defaultdict(float), defaultdict(int)
        self._depth = threading.local()

    def reset(self) -> None:
        self.wall.clear()
        self.calls.clear()

    def wrap(self, owner, name: str, part: str) -> None:
        fn = getattr(owner, name)

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            depth = getattr(self._depth, part, 0)
            setattr(self._depth, part, depth + 1)
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                setattr(self._depth, part, depth)
                if depth == 0:
                    self.wall[part] += time.perf_counter() - t0
                    self.calls[part] += 1

        setattr(owner, name, timed)

    def wrap_drawing(self) -> None:
        """``Frame.drawing`` (a cached property: evaluated once per frame, where first read)."""
        draw = Frame.drawing.func

        def drawing(frame):
            t0 = time.perf_counter()
            try:
                return draw(frame)
            finally:
                self.wall["drawing"] += time.perf_counter() - t0
                self.calls["drawing"] += 1

        prop = cached_property(drawing)
        prop.__set_name__(Frame, "drawing")
        Frame.drawing = prop


#: The parts timed: (owner, method, part). Kernel stepping is every way the runner and the
#: headless run advance a ``Simulation``.
PARTS = ((Simulation, "step", "kernel"), (Simulation, "steps", "kernel"), (Simulation, "output_states", "kernel"),
         (Driver, "advance", "advance"), (SimRunner, "_publish", "publish"), (Driver, "frame", "frame"),
         (Driver, "check", "check"), (Driver, "plot_values", "plot values"),
         (SceneNodes, "show", "show"), (SceneNodes, "_show_contacts", "contact arrows"), (Viewer, "_plots", "plots"))
#: How the parts nest, for the table: (part, thread, what it is).
ROWS = (("kernel", "simulation", "kernel stepping (Simulation.step / steps / output_states)"),
        ("advance", "simulation", "Driver.advance in all (stepping, events, sinks' frames)"),
        ("publish", "simulation", "SimRunner._publish in all (frame, checks, plot values, snapshot)"),
        ("frame", "simulation", "  its frame (Driver.frame: a kernel sample of one state, the contacts' scalars)"),
        ("check", "simulation", "  its checks (Driver.check: run_checks on the frame)"),
        ("plot values", "simulation", "  its plot values"),
        ("show", "display", "SceneNodes.show in all (pose updates, arrows)"),
        ("drawing", "display", "  the frame's drawing (joint points, contact points and forces)"),
        ("contact arrows", "display", "  contact arrows"),
        ("plots", "display", "Viewer._plots (8 Hz)"))


def instrument() -> Clock:
    clock = Clock()
    for owner, name, part in PARTS:
        clock.wrap(owner, name, part)
    clock.wrap_drawing()
    return clock


# ---------------------------------------------------------------------------- one measurement


def _uptime() -> str:
    return "load average: " + ", ".join(f"{x:.2f}" for x in os.getloadavg())


def _client(port: int, seconds: float, warmup: float, out) -> None:
    """The websocket client, in its own process (as a browser is: its decoding takes no time from
    the viewer's interpreter); its counts go to the queue ``out``."""
    out.put(asyncio.run(_count(port, seconds, warmup, node=None)))


def measure_viewer(path: Path, seconds: float, warmup: float, speed: float, forces: bool, clock: Clock) -> dict:
    """The viewer on ``path`` with a client connected, over ``seconds`` after ``warmup`` [s] of
    simulation (which starts when the client connects)."""
    runner = SimRunner(viz3d.load_scene(path), speed=speed)
    viewer = Viewer(runner, port=0)
    viewer.flags["forces"] = forces
    viewer.start()
    context = multiprocessing.get_context("spawn")
    counts = context.Queue()
    client = context.Process(target=_client, args=(viewer.server.get_port(), seconds, warmup, counts))
    client.start()
    try:
        while runner.waiting or runner.snapshot.waiting:
            time.sleep(0.01)
        time.sleep(warmup)
        clock.reset()
        wall0, cpu0, t_a = time.perf_counter(), time.process_time(), runner.driver.t
        steps0, shown0 = runner.sim.n_steps, viewer.frames_shown
        time.sleep(seconds)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        t_b, steps, shown = runner.driver.t, runner.sim.n_steps - steps0, viewer.frames_shown - shown0
        parts = {k: (clock.wall[k], clock.calls[k]) for k in clock.wall}
        got = counts.get(timeout=seconds + 60)
        status = runner.snapshot.status
    finally:
        client.join(timeout=10)
        viewer.stop()
    return {"t_a": t_a, "t_b": t_b, "wall": wall, "rtf": (t_b - t_a) / wall, "cpu": cpu / (t_b - t_a), "steps": steps,
            "pushed_hz": shown / wall, "poses_hz": got["poses"] / seconds, "plots_hz": got["plots"] / seconds,
            "parts": parts, "status": status}


def measure_headless(path: Path, t_a: float, t_b: float) -> dict:
    """The headless run of ``path`` to ``t_b``: its wall time over ``[t_a, t_b]``, interpolated
    between the times its kernel calls return (the run's frames come a chunk at a time)."""
    stamps = [(time.perf_counter(), time.process_time(), 0.0)]
    step = Simulation.output_states

    def stamped(sim, *args, **kwargs):
        out = step(sim, *args, **kwargs)
        stamps.append((time.perf_counter(), time.process_time(), sim.state.t))
        return out

    Simulation.output_states = stamped
    try:
        traj = simulate(path, t_end=t_b)
    finally:
        Simulation.output_states = step
    wall, cpu, t = np.array(stamps).T
    wall_a, wall_b = np.interp([t_a, t_b], t, wall)
    cpu_a, cpu_b = np.interp([t_a, t_b], t, cpu)
    return {"wall": wall_b - wall_a, "rtf": (t_b - t_a) / (wall_b - wall_a), "cpu": (cpu_b - cpu_a) / (t_b - t_a),
            "status": traj.status}


def scene_report(path: Path, seconds: float, warmup: float, speed: float, forces: bool, repeat: int) -> str:
    clock = instrument()
    lines = [f"`{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}`, "
             f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, viewer at --speed {speed:g}, "
             f"contact and reaction arrows {'on' if forces else 'off'}, "
             "one websocket client of viser's protocol (its own process).",
             "", "| pair | load before | viewer: sim interval [s] | viewer: real-time factor | headless, same interval: "
             "real-time factor | viewer / headless | CPU per simulated second [s]: viewer, headless, ratio | "
             "frames pushed [Hz] | pose updates received [Hz] | plot updates received [Hz] | load after |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    splits = []
    for k in range(repeat):
        before = _uptime()
        v = measure_viewer(path, seconds, warmup, speed, forces, clock)
        h = measure_headless(path, v["t_a"], v["t_b"])
        after = _uptime()
        lines.append(f"| {k + 1} | {before.split(': ')[1]} | {v['t_a']:.2f}-{v['t_b']:.2f} | {v['rtf']:.3f} | "
                     f"{h['rtf']:.3f} | {v['rtf'] / h['rtf']:.3f} | {v['cpu']:.3f}, {h['cpu']:.3f}, {v['cpu'] / h['cpu']:.3f} | "
                     f"{v['pushed_hz']:.1f} | {v['poses_hz']:.1f} | "
                     f"{v['plots_hz']:.1f} | {after.split(': ')[1]} |")
        print(lines[-1], flush=True)
        if v["status"] != "ok" or h["status"] != "ok":
            lines.append(f"|  | statuses: viewer {v['status']!r}, headless {h['status']!r} | | | | | | | | | |")
        splits.append(v)
    lines += ["", "Where the viewer's wall time went (last pair), per simulation step "
              f"({splits[-1]['steps']} steps, {splits[-1]['wall']:.1f} s of wall):", "",
              "| part | thread | wall per step [µs] | calls per second | share of the wall time |", "|---|---|---|---|---|"]
    v = splits[-1]
    for part, thread, what in ROWS:
        wall, calls = v["parts"].get(part, (0.0, 0))
        lines.append(f"| {what} | {thread} | {1e6 * wall / max(v['steps'], 1):.1f} | {calls / v['wall']:.1f} | "
                     f"{100 * wall / v['wall']:.1f} % |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------- the chain table


def measure_chain(n_links: int, seconds: float) -> dict:
    scene = viz3d.load_scene(ROOT / "scenes" / "chain.toml", [f"chain.n={n_links}", "sim.t_end=1000"])
    runner = SimRunner(scene)
    viewer = Viewer(runner, port=0)
    viewer.start()
    try:
        t0, shown0 = runner.snapshot.frame.t, viewer.frames_shown
        wall0 = time.monotonic()
        got = asyncio.run(_count(viewer.server.get_port(), seconds))
        wall = time.monotonic() - wall0
        return {"n": n_links, "received_hz": got["poses"] / seconds, "pushed_hz": (viewer.frames_shown - shown0) / wall,
                "rtf": runner.snapshot.rtf, "sim_s": runner.snapshot.frame.t - t0}
    finally:
        viewer.stop()


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", type=Path, help="a scene file: measure the viewer on it against the headless run")
    p.add_argument("--n", default="10,50", help="chain table: comma-separated link counts")
    p.add_argument("--seconds", type=float, default=None, help="measured wall time [s] (chain 6, scene 25)")
    p.add_argument("--warmup", type=float, default=5.0, help="scene: wall time before measuring [s]")
    p.add_argument("--speed", type=float, default=1000.0, help="scene: the viewer's speed (default: all it can)")
    p.add_argument("--no-forces", dest="forces", action="store_false", help="scene: contact and reaction arrows off")
    p.add_argument("--repeat", type=int, default=1, help="scene: viewer/headless pairs")
    p.add_argument("--out", type=Path, help="scene: also write the tables to this markdown file")
    args = p.parse_args(argv)
    print(_uptime())
    if args.scene is not None:
        report = scene_report(args.scene.resolve(), args.seconds or 25.0, args.warmup, args.speed, args.forces, args.repeat)
        print(report)
        print(_uptime())
        if args.out is not None:
            args.out.write_text(f"# bench_viewer: {args.scene.stem}\n\n`python benchmarks/bench_viewer.py --scene "
                                f"{args.scene} --speed {args.speed:g}`\n\n{report}\n")
        return
    print("| links | pose updates received by a client [Hz] | frames pushed [Hz] | achieved real-time factor |")
    print("|---|---|---|---|")
    for n in args.n.split(","):
        r = measure_chain(int(n), args.seconds or 6.0)
        print(f"| {r['n']} | {r['received_hz']:.1f} | {r['pushed_hz']:.1f} | {r['rtf']:.2f} |", flush=True)


if __name__ == "__main__":
    main()

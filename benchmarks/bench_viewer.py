"""Display rate of the live viewer while the simulation runs (a benchmark, not a test).

    python benchmarks/bench_viewer.py [--n 50] [--seconds 6]

Starts the viewer on the `chain` scene with N links, connects a websocket client that speaks
viser's protocol (what a browser receives), and counts pose updates of the link batch per second
of wall time, alongside the simulation's achieved real-time factor. Prints one table row per N.
"""

from __future__ import annotations

import argparse
import asyncio
import time
from pathlib import Path

import msgspec
import viser
import websockets
import zstandard

import viz3d
from viz3d.realtime import SimRunner
from viz3d.viz.viewer_viser import Viewer

ROOT = Path(__file__).resolve().parents[1]


def _messages(frame: bytes) -> list:
    raw_len, comp_len = int.from_bytes(frame[0:8], "little"), int.from_bytes(frame[8:16], "little")
    body = zstandard.ZstdDecompressor().decompress(frame[16:16 + comp_len], max_output_size=raw_len)
    return msgspec.msgpack.decode(body)["messages"]


async def _count(port: int, seconds: float, warmup: float = 1.0) -> tuple[int, float]:
    n = 0
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"],
                                  max_size=None) as ws:
        start = time.monotonic() + warmup
        end = start + seconds
        while time.monotonic() < end:
            try:
                frame = await asyncio.wait_for(ws.recv(), timeout=0.1)
            except asyncio.TimeoutError:
                continue
            if time.monotonic() >= start:
                n += sum(1 for m in _messages(frame) if m["type"] == "SceneNodeUpdateMessage"
                         and m["name"] == "/bodies/group0" and "batched_positions" in m["updates"])
    return n, seconds


def measure(n_links: int, seconds: float) -> dict:
    scene = viz3d.load_scene(ROOT / "scenes" / "chain.toml", [f"chain.n={n_links}", "sim.t_end=1000"])
    runner = SimRunner(scene)
    viewer = Viewer(runner, port=0)
    viewer.start()
    try:
        t0, shown0 = runner.snapshot.frame.t, viewer.frames_shown
        wall0 = time.monotonic()
        updates, span = asyncio.run(_count(viewer.server.get_port(), seconds))
        wall = time.monotonic() - wall0
        return {"n": n_links, "received_hz": updates / span, "pushed_hz": (viewer.frames_shown - shown0) / wall,
                "rtf": runner.snapshot.rtf, "sim_s": runner.snapshot.frame.t - t0}
    finally:
        viewer.stop()


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", default="10,50", help="comma-separated link counts")
    p.add_argument("--seconds", type=float, default=6.0)
    args = p.parse_args(argv)
    print("| links | pose updates received by a client [Hz] | frames pushed [Hz] | achieved real-time factor |")
    print("|---|---|---|---|")
    for n in args.n.split(","):
        r = measure(int(n), args.seconds)
        print(f"| {r['n']} | {r['received_hz']:.1f} | {r['pushed_hz']:.1f} | {r['rtf']:.2f} |", flush=True)


if __name__ == "__main__":
    main()

"""What drawing flexible links coloured by bending stress costs per frame (a benchmark, not a test).

    python benchmarks/bench_stress_colours.py [--repeat 300] [--chart docs/bench_stress_colours.png]

On the flexible four-bar at t = 0.05 s (two links, tubes of 41 sections x 12 ring points, 160
facets each): the whole frame (``frame_from_state`` with drawings), the drawing's vertices and its
vertex stresses, the colour map, and per link the viewer's updates: the plain mesh
(``MeshHandle.vertices``), the stress-coloured tube (``StressTube.show``: four batched-mesh arrays)
and, for comparison, the GLB a vertex-coloured ``add_mesh_trimesh`` node would need (trimesh export;
rejected: a changed GLB is parsed again in the browser and its node drawn empty meanwhile). No
client is connected (messages are queued, not sent). Prints a table of medians and writes a bar chart.
"""

from __future__ import annotations

import argparse
import queue
import time
from pathlib import Path

import numpy as np

import viz3d
from viz3d.dynamics import body_state
from viz3d.realtime import make_driver
from viz3d.viz.colors import StressColors
from viz3d.viz.viewer_viser import StressTube

ROOT = Path(__file__).resolve().parents[1]


def _median_ms(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def measure(repeat: int) -> list[tuple[str, float]]:
    import trimesh
    import viser

    driver = make_driver(viz3d.load_scene(ROOT / "scenes" / "flexible_four_bar.toml"))
    driver.advance(0.05, time.perf_counter() + 600.0, queue.Queue())
    frame, state = driver.frame(), driver.sim.state
    cfg = body_state(driver.system, state.q, state.v, state.chart, state.t)
    drawing, deformable = driver._drawings[0], driver.visuals.deformables[0]
    colors = StressColors(driver.visuals.stress_scale)
    V, sigma = frame.deformed[deformable.name], frame.stress[deformable.name]
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        mesh = server.scene.add_mesh_simple("/plain", deformable.vertices, deformable.faces)
        tube = StressTube(server.scene, deformable, visible=True)

        def glb():
            trimesh.Trimesh(V, deformable.faces, vertex_colors=colors(sigma), process=False).export(file_type="glb")

        return [("whole frame (2 links)", _median_ms(driver.frame, repeat)),
                ("drawing vertices (1 link)", _median_ms(lambda: drawing.vertices(cfg), repeat)),
                ("drawing stresses (1 link)", _median_ms(lambda: drawing.stresses(cfg), repeat)),
                ("colour map (1 link, 492 vertices)", _median_ms(lambda: colors(sigma), repeat)),
                ("viewer: plain mesh vertices (1 link)", _median_ms(lambda: setattr(mesh, "vertices", V), repeat)),
                ("viewer: stress tube, 160 facets (1 link)", _median_ms(lambda: tube.show(V, sigma, colors), repeat)),
                ("rejected: GLB with vertex colours (1 link)", _median_ms(glb, repeat))]
    finally:
        server.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=300)
    parser.add_argument("--chart", type=Path, default=None, help="write a bar chart here (PNG)")
    args = parser.parse_args()
    rows = measure(args.repeat)
    width = max(len(name) for name, _ in rows)
    print(f"{'what':<{width}}  median [ms]")
    for name, ms in rows:
        print(f"{name:<{width}}  {ms:10.4f}")
    if args.chart:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(8, 3.5))
        ax.barh([n for n, _ in rows][::-1], [ms for _, ms in rows][::-1], color="#4e79a7")
        ax.set_xscale("log")
        ax.set_xlabel("median time per frame [ms]")
        ax.set_title("Flexible four-bar: cost of stress colours per frame")
        fig.tight_layout()
        fig.savefig(args.chart, dpi=120)
        print(f"chart: {args.chart}")


if __name__ == "__main__":
    main()

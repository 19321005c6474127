"""The Python share of viz3d's whole runs on bench_peers' small problems (issue 14; a benchmark, not a test).

    python benchmarks/bench_overhead.py [--repeat 30]

Each configuration is built as ``bench_peers.viz3d_run`` builds it (``build`` before the clock), then
``simulate_built`` is timed, best of ``--repeat`` after a warm-up; "kernel" is the time inside the
compiled calls (``viz3d.kernel.KernelStepper._call``, the entry lookup and argument unboxing included)
of that best run, "Python" the rest. Configurations: the torque-free body (RK4, projection,
quaternions, dt = 1/300 s, 20 s), the 2-link chain (DOP853, projection, rtol 10^-4.5, 1 s), the
heavy top (10 s) and the top through the vertical (3 s) (DOP853, projection, rtol 1e-3).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from bench_peers import DIVISIONS, OUTPUT_DT, PROBLEMS, RTOLS, VIZ3D

from viz3d import kernel
from viz3d.bench import ATOL_FACTOR
from viz3d.scene.build import build
from viz3d.scene.load import load_scene, with_sim
from viz3d.simulate import simulate_built

SCENES = Path(__file__).resolve().parents[1] / "scenes"
#: name -> (scene file, problem overrides, bench_peers configuration, level, simulated time [s])
CASES = {
    "torque_free": (PROBLEMS["torque_free"][0], [], "rk4+projection+quaternion", 1, PROBLEMS["torque_free"][2]),
    "chain N=2": ("chain.toml", ["chain.n=2"], "dop853+projection", 3, 1.0),
    "heavy_top": (PROBLEMS["heavy_top"][0], [], "dop853+projection", 0, PROBLEMS["heavy_top"][2]),
    "top_through_vertical": (PROBLEMS["top_through_vertical"][0], [], "dop853+projection", 0,
                             PROBLEMS["top_through_vertical"][2]),
}


def scene_of(case: str):
    """The scene of ``case`` with the overrides ``bench_peers.viz3d_run`` gives it."""
    path, problem, config, level, t_end = CASES[case]
    over, adaptive = VIZ3D[config]
    if adaptive:
        rtol = RTOLS[level]
        over = over + [f"sim.dt={OUTPUT_DT!r}", f"sim.rtol={rtol!r}", f"sim.atol={rtol * ATOL_FACTOR!r}"]
    else:
        over = over + [f"sim.dt={OUTPUT_DT / DIVISIONS[level]!r}"]
    return with_sim(load_scene(SCENES / path, problem + over + [f"sim.output_dt={OUTPUT_DT!r}"]), t_end=t_end)


def measure(case: str, repeat: int) -> tuple[float, float, int]:
    """Best whole run of ``case`` [s], the time inside compiled calls of that run [s], its frames."""
    scene = scene_of(case)
    inside = [0.0]
    call = kernel.KernelStepper._call

    def timed(self, dispatcher, *args):
        t0 = time.perf_counter()
        try:
            return call(self, dispatcher, *args)
        finally:
            inside[0] += time.perf_counter() - t0

    kernel.KernelStepper._call = timed
    try:
        runs = []
        for k in range(repeat + 1):  # (the first: warm-up)
            system, state = build(scene)
            inside[0] = 0.0
            t0 = time.perf_counter()
            traj = simulate_built(scene, system, state)
            if k:
                runs.append((time.perf_counter() - t0, inside[0]))
    finally:
        kernel.KernelStepper._call = call
    wall, compiled = min(runs)
    return wall, compiled, len(traj.t)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=30)
    args = ap.parse_args(argv)
    print(f"load average {'/'.join(f'{x:.1f}' for x in os.getloadavg())}")
    print("| run | frames | whole [ms] | kernel [ms] | Python [ms] |\n|---|---|---|---|---|")
    for case in CASES:
        wall, compiled, frames = measure(case, args.repeat)
        print(f"| {case} | {frames} | {1e3 * wall:.3f} | {1e3 * compiled:.3f} | {1e3 * (wall - compiled):.3f} |")


if __name__ == "__main__":
    main()

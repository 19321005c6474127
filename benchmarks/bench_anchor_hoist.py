"""What the anchor hoist costs, against real time (a benchmark, not a test).

    python benchmarks/bench_anchor_hoist.py [--t 2.0] [--out docs/bench_anchor_hoist.png]

Runs the first ``--t`` seconds of ``scenes/anchor_hoist.toml`` (the anchor hanging from the rim, the
windlass ramping up; the same contacts and bodies as the whole haul) with: the scene's method (RK4 +
Baumgarte, dt = 5e-4 s) in the compiled kernel and on the NumPy path (``sim.compiled = false``),
ALI3-P on the trapezoidal rule at dt = 2e-3 s (NumPy: the kernel leaves ALI3-P with shape contacts
to it), and all with a coarser chain (``ship.link_tolerance`` so that each simulated link is two
real ones). For each: the path the run took, the number of bodies, the steps, the wall time per
step and per simulated second, the real-time factor (simulated / wall), the mean hauling force (to
see that the variants agree), and the share of one NumPy force-and-constraint evaluation spent
finding contacts. The kernel's compile time is kept out: each kernel variant runs once for
``--warm`` simulated seconds first (numba's cache makes later processes start warm). Prints a
Markdown table and writes a bar chart. Wall-clock times on this machine: compare the rows of one
run with each other, and quote ``uptime``'s load with them.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from bench_collision import best_of  # (benchmarks/ is the script's folder: on sys.path)

import viz3d

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "anchor_hoist.toml"
ALI3P = ["sim.formulation=ali3p", "sim.integrator=trapezoidal", "sim.dt=2e-3", "sim.ali3p_alpha=1e12",
         "sim.projection_tol=1e-8"]
NUMPY = ["sim.compiled=false"]
COARSE = ["ship.link_tolerance=0.2"]
VARIANTS = {
    "rk4 + baumgarte, dt 5e-4": [],
    "rk4 + baumgarte, dt 5e-4, NumPy": NUMPY,
    "ali3p, dt 2e-3": ALI3P,
    "rk4 + baumgarte, 2 links each": COARSE,
    "rk4 + baumgarte, 2 links each, NumPy": COARSE + NUMPY,
    "ali3p, 2 links each": COARSE + ALI3P,
}


def detection_share(scene) -> float:
    """Time of finding the shape contacts (``Collisions._detect``: ``detect`` keeps its last answer, so
    timing it again would time that look-up) over one whole force-and-constraint evaluation."""
    from viz3d.contact.collision import Collisions
    from viz3d.dynamics import accelerations, body_state
    from viz3d.scene.build import build, make_formulation

    system, state = build(scene)
    formulation = make_formulation(scene.data["sim"])
    col = next(e for e in system.forces if isinstance(e, Collisions))
    cfg = body_state(system, state.q, state.v, state.chart, 0.0)

    whole = best_of(lambda: accelerations(system, formulation, 0.0, state.q, state.v, state.chart), 30)
    return best_of(lambda: col._detect(cfg), 30) / whole  # (detect itself keeps its last answer per cfg)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--t", type=float, default=2.0, help="simulated seconds per variant")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_anchor_hoist.png")
    p.add_argument("--warm", type=float, default=0.05, help="simulated seconds of a warm-up run per kernel variant")
    args = p.parse_args()
    rows = []
    for name, sets in VARIANTS.items():
        if sets is not NUMPY and not set(NUMPY) <= set(sets):  # compile (or load) the kernel outside the timing
            viz3d.simulate(viz3d.load_scene(SCENE, [f"sim.t_end={args.warm}", *sets]))
        scene = viz3d.load_scene(SCENE, [f"sim.t_end={args.t}", *sets])
        t0 = time.perf_counter()
        traj = viz3d.simulate(scene)
        wall = time.perf_counter() - t0
        sim = float(traj.t[-1])
        effort = traj.extras["drive_effort"][:, 0]
        late = effort[traj.t >= 0.5]
        path = "kernel" if json.loads(str(traj.scene_json))["run"]["kernel"] == "compiled kernel" else "NumPy"
        rows.append((name, path, len(traj.body_names), traj.n_steps, 1e6 * wall / max(traj.n_steps, 1),
                     wall / sim if sim > 0 else np.inf, sim / wall, float(late.mean()) / 1e3 if late.size else np.nan,
                     detection_share(scene), traj.status))
    print("| variant | path | bodies | steps | wall per step [us] | wall per simulated s [s] | real-time factor "
          "| mean hauling force [kN] | detect / NumPy evaluation | status |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]:.0f} | {r[5]:.2f} | {r[6]:.3f} | {r[7]:.1f} | {r[8]:.2f} "
              f"| {r[9][:60]} |")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 3.6))
    ax.barh([r[0] for r in rows], [r[6] for r in rows], color=["#4e79a7" if r[1] == "kernel" else "#bab0ac" for r in rows])
    ax.axvline(1.0, color="k", lw=1, ls="--", label="real time")
    ax.set_xlabel("real-time factor (simulated s per wall s)")
    ax.set_title(f"anchor_hoist, first {args.t:g} s")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

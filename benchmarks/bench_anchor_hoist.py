"""What the anchor hoist costs, against real time (a benchmark, not a test).

    python benchmarks/bench_anchor_hoist.py [--t 2.0] [--out docs/bench_anchor_hoist.png]

Runs the first ``--t`` seconds of ``scenes/anchor_hoist.toml`` (the anchor hanging from the rim, the
windlass ramping up; the same contacts and bodies as the whole haul) with: the scene's method (RK4 +
Baumgarte, dt = 5e-4 s), ALI3-P on the trapezoidal rule at dt = 2e-3 s, and both with a coarser
chain (``ship.link_tolerance`` so that each simulated link is two real ones). For each: the number
of bodies, the steps, the wall time per simulated second, the real-time factor (simulated / wall),
the mean hauling force (to see that the variants agree), and the share of one force-and-constraint
evaluation spent finding contacts. Prints a Markdown table and writes a bar chart. Wall-clock
times on this machine: compare the rows of one run with each other.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from bench_collision import best_of  # (benchmarks/ is the script's folder: on sys.path)

import viz3d

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "anchor_hoist.toml"
VARIANTS = {
    "rk4 + baumgarte, dt 5e-4": [],
    "ali3p, dt 2e-3": ["sim.formulation=ali3p", "sim.integrator=trapezoidal", "sim.dt=2e-3", "sim.ali3p_alpha=1e12",
                       "sim.projection_tol=1e-8"],
    "rk4 + baumgarte, 2 links each": ["ship.link_tolerance=0.2"],
    "ali3p, 2 links each": ["ship.link_tolerance=0.2", "sim.formulation=ali3p", "sim.integrator=trapezoidal",
                            "sim.dt=2e-3", "sim.ali3p_alpha=1e12", "sim.projection_tol=1e-8"],
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
    return best_of(lambda: col._detect(cfg), 30) / whole


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--t", type=float, default=2.0, help="simulated seconds per variant")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_anchor_hoist.png")
    args = p.parse_args()
    rows = []
    for name, sets in VARIANTS.items():
        scene = viz3d.load_scene(SCENE, [f"sim.t_end={args.t}", *sets])
        t0 = time.perf_counter()
        traj = viz3d.simulate(scene)
        wall = time.perf_counter() - t0
        sim = float(traj.t[-1])
        effort = traj.extras["drive_effort"][:, 0]
        late = effort[traj.t >= 0.5]
        rows.append((name, len(traj.body_names), traj.n_steps, wall / sim if sim > 0 else np.inf, sim / wall,
                     float(late.mean()) / 1e3 if late.size else np.nan, detection_share(scene), traj.status))
    print("| variant | bodies | steps | wall per simulated s [s] | real-time factor | mean hauling force [kN] "
          "| detect / evaluation | status |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]:.2f} | {r[4]:.3f} | {r[5]:.1f} | {r[6]:.2f} | {r[7][:60]} |")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.barh([r[0] for r in rows], [r[4] for r in rows], color="#4e79a7")
    ax.axvline(1.0, color="k", lw=1, ls="--", label="real time")
    ax.set_xlabel("real-time factor (simulated s per wall s)")
    ax.set_title(f"anchor_hoist, first {args.t:g} s")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

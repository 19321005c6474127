"""Cost of the `chain` scene against its number of links (a benchmark, not a test).

    python benchmarks/bench_chain.py [--n 2,5,10,20,50] [--t-end 0.5] [--out docs/bench_chain.png]

For each N: build the chain, run RK4 through the NumPy reference path (``compiled=False``; the
compiled kernel is timed by bench_mujoco.py) at the scene's step for ``t_end`` simulated seconds
(no output frames inside the timed loop), and report time per step, per RHS evaluation and per
simulated second, the real-time factor, and which solver the constraint layout chose. Prints a
Markdown table and writes a log-log chart. Times are wall-clock on this machine; compare rows of
one run with each other, not with other machines.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import viz3d
from viz3d.integrators import make_integrator
from viz3d.scene.build import make_formulation
from viz3d.simulate import Simulation

ROOT = Path(__file__).resolve().parents[1]


def measure(n: int, t_end: float, repeats: int = 3) -> dict:
    scene = viz3d.load_scene(ROOT / "scenes" / "chain.toml", [f"chain.n={n}"])
    system, state = viz3d.build(scene)
    cfg = scene.data["sim"]
    steps = max(1, round(t_end / cfg["dt"]))
    best = np.inf
    for _ in range(repeats):
        sim = Simulation(system, state, make_integrator(cfg["integrator"]), make_formulation(cfg), cfg["dt"],
                         compiled=False)
        t0 = time.perf_counter()
        for _ in range(steps):
            sim.step()
        best = min(best, time.perf_counter() - t0)
    per_step = best / steps
    return {"n": n, "dt": cfg["dt"], "steps": steps, "us_step": 1e6 * per_step, "us_rhs": 1e6 * best / sim.n_rhs,
            "s_per_sim_s": per_step / cfg["dt"], "rtf": cfg["dt"] / per_step,
            "solver": f"banded kd={system.joints.kd}" if system.joints.banded else "dense"}


def table(rows: list[dict]) -> str:
    head = ("| links | dt [s] | us/step | us/RHS | wall s per simulated s | real-time factor | solver |\n"
            "|---|---|---|---|---|---|---|")
    lines = [f"| {r['n']} | {r['dt']:g} | {r['us_step']:.0f} | {r['us_rhs']:.0f} | {r['s_per_sim_s']:.3f} | {r['rtf']:.2f} "
             f"| {r['solver']} |" for r in rows]
    return "\n".join([head, *lines])


def chart(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = np.array([r["n"] for r in rows])
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(n, [r["us_step"] for r in rows], "o-", label="viz3d RK4, time per step")
    ax.loglog(n, [r["us_rhs"] for r in rows], "s--", label="viz3d, time per RHS evaluation")
    ax.set_xlabel("links N")
    ax.set_ylabel("wall time [us]")
    ax.set_title("chain scene: cost against size (RK4, ball joints)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", default="2,5,10,20,50", help="comma-separated link counts")
    p.add_argument("--t-end", type=float, default=0.5, help="simulated seconds per measurement")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_chain.png")
    args = p.parse_args(argv)
    rows = [measure(int(n), args.t_end) for n in args.n.split(",")]
    print(table(rows))
    chart(rows, args.out)
    print(f"\nchart: {args.out}")


if __name__ == "__main__":
    main()

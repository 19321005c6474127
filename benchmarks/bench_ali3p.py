"""ALI3-P's cost per step on the `chain` scene against the number of links and the penalty factor,
on the compiled kernel's path (``viz3d.kernel.ali3p``: one compiled call per step) and the NumPy
one, with RK4 steps in the kernel on the same chain as the yardstick (a benchmark, not a test).

    python benchmarks/bench_ali3p.py [--n 2,10,50,100,200] [--alpha 1e9,1e10] [--paths kernel,numpy,rk4]
                                     [--out docs/bench_ali3p.png]

For each (N, alpha, path): the trapezoidal ALI3-P steps of ``t_end`` simulated seconds at the
scene's dt (no output frames but the run's own), the best wall time per step of ``repeats`` runs
(the whole run: building, its frames and trajectory included), the run's force and constraint
evaluations per step (``Trajectory.n_rhs / n_steps``: the Newton iterations, the grouped finite
differences when a tangent is rebuilt, the projections' one and the initial accelerations; the
same on both paths, which take the same iterates), and the largest constraint violation. The
``rk4`` path (alpha does not apply; run once per N) is RK4 with the ``projection`` formulation
through the kernel, batched from frame to frame. Runs that fail are reported with their status.
Prints a Markdown table (the NumPy/kernel ratio, the kernel step in RK4 steps) and writes log-log
charts of the wall time per step and per evaluation (one Newton iteration, or one column group of a
tangent); compare the rows of one run with each other.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import viz3d

ROOT = Path(__file__).resolve().parents[1]


def measure(n: int, alpha: float, path: str, t_end: float, repeats: int) -> dict:
    method = (["sim.formulation=projection", "sim.integrator=rk4"] if path == "rk4" else
              ["sim.formulation=ali3p", "sim.integrator=trapezoidal", f"sim.ali3p_alpha={alpha}"])
    best, traj = np.inf, None
    for _ in range(repeats):
        scene = viz3d.load_scene(ROOT / "scenes" / "chain.toml", [f"chain.n={n}", *method,
                                                                    f"sim.compiled={str(path != 'numpy').lower()}"])
        t0 = time.perf_counter()
        traj = viz3d.simulate(scene, t_end=t_end)
        best = min(best, (time.perf_counter() - t0) / max(traj.n_steps, 1))
    return {"n": n, "alpha": alpha, "path": path, "ms": 1e3 * best, "evals": traj.n_rhs / max(traj.n_steps, 1),
            "violation": traj.max_constraint_violation, "status": traj.status}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", default="2,10,50,100,200")
    p.add_argument("--alpha", default="1e9,1e10")
    p.add_argument("--paths", default="kernel,numpy,rk4")
    p.add_argument("--t-end", type=float, default=0.02)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_ali3p.png")
    args = p.parse_args(argv)
    rows = []
    paths = args.paths.split(",")
    for alpha in (float(a) for a in args.alpha.split(",")):
        for n in (int(x) for x in args.n.split(",")):
            if alpha < 1e10 and n > 100:
                continue  # tens of iterations a step and worse: minutes per point
            for path in paths:
                if path == "rk4" and any(r["n"] == n and r["path"] == "rk4" for r in rows):
                    continue  # alpha does not apply
                rows.append(measure(n, alpha, path, args.t_end, args.repeats))
                r = rows[-1]
                print(f"  N={n:4d} alpha={alpha:.0e} {path:6s}: {r['ms']:8.3f} ms/step, {r['evals']:6.1f} "
                      f"evaluations/step, max |C| {r['violation']:.1e} m, {r['status'][:40]}", flush=True)
    print("\n| links | alpha | path | ms/step (wall) | NumPy / kernel | kernel / RK4 | evaluations/step | max abs C [m] "
          "| status |")
    print("|---:|---:|---|---:|---:|---:|---:|---:|---|")
    for r in rows:
        numpy_ = [o for o in rows if (o["n"], o["alpha"], o["path"]) == (r["n"], r["alpha"], "numpy")]
        rk4 = [o for o in rows if (o["n"], o["path"]) == (r["n"], "rk4")]
        ratio = f"{numpy_[0]['ms'] / r['ms']:.1f}" if r["path"] == "kernel" and numpy_ else ""
        per_rk4 = f"{r['ms'] / rk4[0]['ms']:.1f}" if r["path"] == "kernel" and rk4 else ""
        alpha = "" if r["path"] == "rk4" else f"{r['alpha']:.0e}"
        print(f"| {r['n']} | {alpha} | {r['path']} | {r['ms']:.3f} | {ratio} | {per_rk4} | {r['evals']:.1f} | "
              f"{r['violation']:.1e} | {'ok' if r['status'] == 'ok' else 'failed'} |")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax_e) = plt.subplots(1, 2, figsize=(11, 4.2))
    n = np.array(sorted({r["n"] for r in rows}), float)
    for k, alpha in enumerate(sorted({r["alpha"] for r in rows if r["path"] != "rk4"})):
        for path, style in (("kernel", "o-"), ("numpy", "s--")):
            sel = [r for r in rows if r["alpha"] == alpha and r["path"] == path and r["status"] == "ok"]
            if sel:
                x = [r["n"] for r in sel]
                kw = dict(color=f"C{k}", label=f"{path}, alpha = {alpha:.0e}")
                ax.loglog(x, [r["ms"] for r in sel], style, **kw)
                ax_e.loglog(x, [r["ms"] / r["evals"] for r in sel], style, **kw)
    sel = [r for r in rows if r["path"] == "rk4" and r["status"] == "ok"]
    if sel:
        kw = dict(color="0.4", label="RK4 + projection, kernel")
        ax.loglog([r["n"] for r in sel], [r["ms"] for r in sel], "^-.", **kw)
        ax_e.loglog([r["n"] for r in sel], [r["ms"] / r["evals"] for r in sel], "^-.", **kw)
    for a, scale, what in ((ax, 0.02, "step"), (ax_e, 0.005, "evaluation (Newton iteration)")):
        a.loglog(n, scale * n, "k:", label="O(N)")
        a.set_xlabel("links")
        a.set_ylabel(f"wall time per {what} [ms]")
        a.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.suptitle("ALI3-P (trapezoidal) on the chain: compiled kernel (one call a step, band LU) and NumPy path")
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""viz3d against MuJoCo on the same N-link ball-joint chain, in one run (a benchmark, not a test).

    pip install -e '.[peers]'   # optional (MuJoCo): without it only viz3d is measured
    python benchmarks/bench_mujoco.py [--n 2,5,10,20,50] [--t-end 1.0] [--out docs/bench_mujoco.png]

Both simulators get the identical physical model (``peers.mujoco_xml``, shared with
bench_peers.py): the `chain` scene's capsule links (mass and inertia computed by viz3d, given to
MuJoCo as explicit <inertial>), ball joints at the link ends, gravity, the same initial rigid
rotation about the anchor, RK4 at the same step, no contacts. Accuracy: every run's link centres
of mass at t_end are compared with a reference, the viz3d RK4 solution at dt/16 (its own
self-convergence is printed; MuJoCo at dt/16 must agree with it, which checks that the two models
are the same). Time per step is the best of three.
Columns: viz3d with NumPy (the reference implementation), viz3d with the compiled kernel
(viz3d.kernel, numba), MuJoCo; errors in metres. "Equal accuracy": viz3d is also run at the step
whose error matches MuJoCo's (RK4's h^4 scaling picks it; the error actually reached is printed),
and the wall time per simulated second of both is compared.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from peers import mujoco_model, mujoco_reset, rigid_tree

import viz3d
from viz3d.integrators import make_integrator
from viz3d.integrators.tableaus import RK4
from viz3d.kernel import kernel_advance, kernel_for
from viz3d.scene.build import make_formulation
from viz3d.simulate import Simulation

ROOT = Path(__file__).resolve().parents[1]
DT = 5e-4


def chain(n: int):
    scene = viz3d.load_scene(ROOT / "scenes" / "chain.toml", [f"chain.n={n}"])
    system, state = viz3d.build(scene)
    tree = rigid_tree(scene, viz3d.simulate(scene, t_end=0.01))  # the peers' model, from the first frame
    return tree, system, state, make_formulation(scene.data["sim"])


def positions_kernel(system, state, formulation, dt: float, t_end: float):
    data = kernel_for(system, formulation)
    y, chart = state.y.copy(), state.chart.copy()
    steps = round(t_end / dt)
    done, status = kernel_advance(data, RK4, steps, 0.0, dt, y, chart, np.zeros(system.n_bodies, np.int64), 1e6)
    assert status == 0 and done == steps, status
    return system.split_q(y[: system.n_q])[0].copy()


def time_kernel(system, state, formulation, steps: int) -> float:
    data = kernel_for(system, formulation)
    best = np.inf
    for _ in range(3):
        y, chart = state.y.copy(), state.chart.copy()
        t0 = time.perf_counter()
        kernel_advance(data, RK4, steps, 0.0, DT, y, chart, np.zeros(system.n_bodies, np.int64), 1e6)
        best = min(best, time.perf_counter() - t0)
    return best / steps


def time_numpy(system, state, formulation, steps: int) -> float:
    best = np.inf
    for _ in range(2):
        sim = Simulation(system, state, make_integrator("rk4"), formulation, DT, compiled=False)
        t0 = time.perf_counter()
        for _ in range(steps):
            sim.step()
        best = min(best, time.perf_counter() - t0)
    return best / steps


def positions_mujoco(tree, dt: float, t_end: float):
    """Centres of mass of the links at ``t_end`` in MuJoCo (RK4, step ``dt``), world [m]."""
    mujoco, model, data = mujoco_model(tree, dt)
    mujoco.mj_step(model, data, nstep=round(t_end / dt))
    mujoco.mj_forward(model, data)
    return data.xipos[[model.body(f"b{i}").id for i in range(len(tree.mass))]].copy()


def time_mujoco(tree, steps: int) -> float:
    mujoco, model, data = mujoco_model(tree, DT)
    best = np.inf
    for _ in range(3):
        mujoco_reset(tree, model, data)
        t0 = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(model, data)
        best = min(best, time.perf_counter() - t0)
    return best / steps


def measure(n: int, t_end: float, steps: int) -> dict:
    tree, system, state, form = chain(n)
    ref = positions_kernel(system, state, form, DT / 16, t_end)
    ref8 = positions_kernel(system, state, form, DT / 8, t_end)
    row = {"n": n, "ref_self": float(np.abs(ref8 - ref).max()),
           "err_viz3d": float(np.abs(positions_kernel(system, state, form, DT, t_end) - ref).max()),
           "us_numpy": 1e6 * time_numpy(system, state, form, min(steps, 400)),
           "us_kernel": 1e6 * time_kernel(system, state, form, steps)}
    try:
        row["err_mujoco"] = float(np.abs(positions_mujoco(tree, DT, t_end) - ref).max())
        row["mujoco_vs_ref"] = float(np.abs(positions_mujoco(tree, DT / 16, t_end) - ref).max())
        row["us_mujoco"] = 1e6 * time_mujoco(tree, steps)
    except ImportError:
        return row
    # equal accuracy: the viz3d step whose error matches MuJoCo's (global RK4 error ~ h^4), run and measured
    ratio = (row["err_mujoco"] / row["err_viz3d"]) ** 0.25
    dt_eq = DT * min(1.0, ratio)
    dt_eq = t_end / np.ceil(t_end / dt_eq)
    row["dt_eq"] = dt_eq
    row["err_eq"] = float(np.abs(positions_kernel(system, state, form, dt_eq, t_end) - ref).max())
    # cost per simulated second at equal accuracy [us of wall time per ms of simulated time]
    row["cost_eq_viz3d"] = row["us_kernel"] / dt_eq * 1e-3
    row["cost_eq_mujoco"] = row["us_mujoco"] / DT * 1e-3
    return row


def table(rows: list[dict]) -> str:
    head = ("| links | viz3d NumPy us/step | viz3d kernel us/step | MuJoCo us/step | kernel / MuJoCo (equal dt) | "
            "viz3d error [m] | MuJoCo error [m] | viz3d dt for MuJoCo's error [s] | its error [m] | "
            "kernel / MuJoCo (equal accuracy) | MuJoCo(dt/16) vs reference [m] | reference self-convergence [m] |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|")
    lines = []
    nan = float("nan")
    for r in rows:
        mj = r.get("us_mujoco", nan)
        eq = r.get("cost_eq_viz3d", nan) / r.get("cost_eq_mujoco", nan)
        lines.append(f"| {r['n']} | {r['us_numpy']:.0f} | {r['us_kernel']:.1f} | {mj:.1f} | {r['us_kernel'] / mj:.2f} | "
                     f"{r['err_viz3d']:.1e} | {r.get('err_mujoco', nan):.1e} | {r.get('dt_eq', nan):.3g} | "
                     f"{r.get('err_eq', nan):.1e} | {eq:.2f} | {r.get('mujoco_vs_ref', nan):.1e} | {r['ref_self']:.1e} |")
    return "\n".join([head, *lines])


def chart(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [r["n"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(n, [r["us_numpy"] for r in rows], "o-", label="viz3d, NumPy path")
    ax.loglog(n, [r["us_kernel"] for r in rows], "s-", label="viz3d, compiled kernel")
    if "us_mujoco" in rows[0]:
        ax.loglog(n, [r["us_mujoco"] for r in rows], "^-", label=f"MuJoCo {_mujoco_version()}")
    if "cost_eq_viz3d" in rows[0]:
        ax.loglog(n, [r["cost_eq_viz3d"] * DT * 1e3 for r in rows], "s--",
                  label="viz3d kernel at MuJoCo's accuracy (per MuJoCo step)")
    ax.set_xlabel("links N")
    ax.set_ylabel("wall time per RK4 step [us]")
    ax.set_title(f"ball-joint chain, RK4, dt = {DT:g} s (same model, same machine, one run)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def _mujoco_version() -> str:
    try:
        import mujoco

        return mujoco.__version__
    except ImportError:
        return "(not installed)"


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", default="2,5,10,20,50")
    p.add_argument("--t-end", type=float, default=1.0, help="simulated time for the accuracy comparison [s]")
    p.add_argument("--steps", type=int, default=4000, help="steps timed per measurement")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_mujoco.png")
    args = p.parse_args(argv)
    rows = [measure(int(n), args.t_end, args.steps) for n in args.n.split(",")]
    print(table(rows))
    chart(rows, args.out)
    print(f"\nchart: {args.out}")


if __name__ == "__main__":
    main()
